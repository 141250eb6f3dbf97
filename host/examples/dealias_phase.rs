//! Wrapped-phase error of the simultaneous mode's de-aliased overlap against
//! the digital twin's true phase: per camera, on the pixels both projectors
//! light, the own fringe's phase (finest period) after analytic
//! de-aliasing, beside the aliased phase it replaced.
//!
//! `cargo run --release -p slscan --example dealias_phase [-- WIDTHxHEIGHT [SEED]]`

use std::sync::Arc;
use std::time::Instant;

use hil_sim::twin::scenes::{built_in, Detail};
use hil_sim::twin::TwinRig;
use slscan::dealias::{dealias_frames, AnalyticDealiaser, AnalyticParams};
use slscan::scan::aliasing::{camera_lighting, AliasParams};
use slscan::scan::{capture, dealias_periods_px, Mode};
use slscan::sim::rig::{SimRig, SimRigConfig};
use slscan::sim::scan::{sim_sensor, SimScanConfig};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let size = args.get(1).map_or("640x480", String::as_str);
    let (w, h) = size.split_once('x').ok_or("size is WIDTHxHEIGHT")?;
    let seed: u64 = args.get(2).map_or(Ok(1), |s| s.parse())?;
    let mut config = SimScanConfig::new("large-part");
    config.scan.mode = Mode::Simultaneous;
    config.scan.camera_px = (w.parse()?, h.parse()?);
    config.scan.periods_px = dealias_periods_px(config.scan.projector_px.0);
    let scan = &config.scan;
    let detail = Detail {
        camera: scan.camera_px,
        projector: scan.projector_px,
    };
    let (scene, rig) = built_in("large-part", &detail)?;
    let calibration = slscan::sim::truth::twin_calibration(&rig, 2);
    let twin = Arc::new(TwinRig::new(scene, rig)?);
    let mut sim = SimRig::start(
        twin.clone(),
        SimRigConfig {
            board: config.board.clone(),
            client: scan.client,
            sensor: sim_sensor(),
            noise_seed: seed,
            board_limits: protocol::BoardLimits::STM32G474,
        },
    )?;
    let mut captured = capture::capture(&mut sim, scan, &calibration, &mut |_| {})?;
    let solver = AnalyticDealiaser::new(
        &scan.periods_px,
        captured.steps,
        scan.projector_px.0,
        AnalyticParams::default(),
    )?;
    let flats = captured
        .flat
        .clone()
        .ok_or("simultaneous mode has flat fields")?;
    let period = scan.periods_px[0];
    println!(
        "large-part {size}, seed {seed}, periods {:?} px, 4 steps",
        scan.periods_px
    );
    for cam in 0..2 {
        let frames = &mut captured.frames[cam];
        let lit = camera_lighting(&flats[cam], cam, &AliasParams::default());
        let both = lit.lit.both();
        let aliased: Vec<f64> = (0..both.len()).map(|i| phase(frames, i)).collect();
        let start = Instant::now();
        let stats = dealias_frames(
            frames,
            &flats[cam],
            cam,
            &lit,
            &solver,
            scan.noise_sigma,
            scan.shot_noise_share,
        );
        let seconds = start.elapsed().as_secs_f64();
        let geometry = twin.renderer(cam)?;
        let uv = &geometry.geometry().projectors[cam].uv_px;
        let (mut before, mut after) = (Vec::new(), Vec::new());
        for i in (0..both.len()).filter(|&i| both[i] && uv[i][0].is_finite()) {
            let truth = std::f64::consts::TAU * f64::from(uv[i][0]) / period;
            before.push(wrap(aliased[i] - truth).abs());
            if frames.iter().any(|f| f.data[i] != 0.0) {
                after.push(wrap(phase(frames, i) - truth).abs());
            }
        }
        println!(
            "camera {}: {} overlap pixels; separated {} ({:.1} %), refused {} ill-posed, {} misfit, {} unsolved, {} inconsistent; {seconds:.2} s",
            ["A", "B"][cam],
            before.len(),
            after.len(),
            100.0 * after.len() as f64 / before.len().max(1) as f64,
            stats.ill_posed,
            stats.misfit,
            stats.unsolved,
            stats.inconsistent
        );
        println!("  aliased phase error:     {}", summary(&mut before));
        println!("  de-aliased phase error:  {}", summary(&mut after));
    }
    Ok(())
}

/// Wrapped phase of the finest period at pixel `i` (4-step decode).
fn phase(frames: &[slscan::raster::Raster<f32>], i: usize) -> f64 {
    let s: Vec<f64> = frames[..4].iter().map(|f| f64::from(f.data[i])).collect();
    (-(s[1] - s[3])).atan2(s[0] - s[2])
}

fn wrap(a: f64) -> f64 {
    let tau = std::f64::consts::TAU;
    a - tau * ((a + std::f64::consts::PI) / tau).floor()
}

fn summary(errors: &mut [f64]) -> String {
    if errors.is_empty() {
        return "no pixels".into();
    }
    errors.sort_by(f64::total_cmp);
    let n = errors.len();
    format!(
        "MAE {:.4} rad, p99 {:.4} rad, max {:.4} rad",
        errors.iter().sum::<f64>() / n as f64,
        errors[(n * 99) / 100],
        errors[n - 1]
    )
}
