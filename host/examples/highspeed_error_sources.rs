//! Where the high-speed mode's depth error on the twin comes from: the same
//! `spheres` scan (640x480, one frame, twin-truth calibration) with the
//! twin's imperfections removed one by one, each instant's signed depth
//! error (decoded minus true camera z) as percentiles over the object's
//! decoded pixels.
//!
//! ```sh
//! cargo run --release -p slscan --example highspeed_error_sources
//! ```

use std::sync::Arc;

use hil_sim::twin::scenes::{built_in, Detail};
use hil_sim::twin::sensor::Channels;
use hil_sim::twin::TwinRig;
use nalgebra::Point3;
use slscan::board::ClientConfig;
use slscan::scan::high_speed::{run_high_speed, HighSpeedConfig, InstantResult};
use slscan::sim::high_speed::{high_speed_sensor, SimHighSpeedConfig};
use slscan::sim::rig::{SimRig, SimRigConfig};
use slscan::sim::scan::sim_board_limits;
use slscan::sim::truth::{camera_truth_at, twin_calibration};

/// What is taken out of the twin.
#[derive(Clone, Copy)]
struct Variant {
    name: &'static str,
    noise_free: bool,
    sharp_projector: bool,
    no_crosstalk: bool,
    /// The demultiplexer's window leak (its default is 0.01).
    leak: f64,
}

fn main() -> anyhow::Result<()> {
    // (name, noise-free sensor, projector in focus, no crosstalk, window leak)
    let variants = [
        ("as built", false, false, false, 0.01),
        ("noise-free float sensor", true, false, false, 0.01),
        ("+ projector in focus", true, true, false, 0.01),
        ("+ no colour crosstalk", true, true, true, 0.01),
        ("as built, window leak 0.05", false, false, false, 0.05),
        ("as built, window leak 0.2", false, false, false, 0.2),
    ]
    .map(
        |(name, noise_free, sharp_projector, no_crosstalk, leak)| Variant {
            name,
            noise_free,
            sharp_projector,
            no_crosstalk,
            leak,
        },
    );
    println!("| twin | instant (direction, LED) | decoded px | signed depth error p5 / p25 / p50 / p75 / p95, um |");
    println!("|---|---|---|---|");
    for variant in variants {
        for (pattern, n, q) in signed_errors(variant)? {
            println!(
                "| {} | {pattern} | {n} | {:.0} / {:.0} / {:.0} / {:.0} / {:.0} |",
                variant.name, q[0], q[1], q[2], q[3], q[4]
            );
        }
    }
    Ok(())
}

/// Per instant: its name, decoded object pixels, error percentiles (um).
fn signed_errors(variant: Variant) -> anyhow::Result<Vec<(String, usize, [f64; 5])>> {
    let defaults = SimHighSpeedConfig::new("spheres");
    let detail = Detail {
        camera: defaults.camera_px,
        projector: defaults.projector_px,
    };
    let (scene, mut rig) = built_in("spheres", &detail)?;
    let mut sensor = high_speed_sensor();
    if variant.noise_free {
        sensor.read_noise_e = 0.0;
        sensor.shot_noise = false;
        sensor.bits = 0;
    }
    if variant.no_crosstalk {
        sensor.channels = Channels::Rgb([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]);
    }
    if variant.sharp_projector {
        rig.projectors
            .iter_mut()
            .for_each(|p| p.defocus_sigma_px = 0.0);
    }
    let calibration = twin_calibration(&rig, 1);
    let twin = Arc::new(TwinRig::new(scene, rig)?);
    let mut sim = SimRig::start(
        twin.clone(),
        SimRigConfig {
            board: defaults.board.clone(),
            client: ClientConfig {
                attempt_timeout: std::time::Duration::from_secs(2),
                attempts: 3,
            },
            sensor,
            noise_seed: defaults.seed,
            board_limits: sim_board_limits(None, 1),
        },
    )?;
    let mut config = HighSpeedConfig::new("spheres");
    config.frames = 1;
    config.decoder.demux.leak = variant.leak;
    let result = run_high_speed(&mut sim, &config, &calibration, None, &mut |_| {})?;
    result.frames[0]
        .instants
        .iter()
        .step_by(4)
        .map(|i| instant_errors(&twin, i))
        .collect()
}

fn instant_errors(
    twin: &TwinRig,
    instant: &InstantResult,
) -> anyhow::Result<(String, usize, [f64; 5])> {
    let truth = camera_truth_at(twin, 0, instant.time_s)?;
    let mut errors: Vec<f64> = instant
        .depth_m
        .data
        .iter()
        .enumerate()
        .filter(|&(i, z)| z.is_finite() && truth.own_object[i])
        .map(|(i, &z)| {
            let p = truth.point_m[i].map(f64::from);
            f64::from(z) - (truth.camera_from_world * Point3::from(p)).z
        })
        .collect();
    errors.sort_by(f64::total_cmp);
    let n = errors.len();
    let q = [0.05, 0.25, 0.5, 0.75, 0.95].map(|f| {
        errors
            .get(((n.max(1) - 1) as f64 * f) as usize)
            .map_or(f64::NAN, |e| e * 1e6)
    });
    let p = instant.pattern;
    Ok((
        format!(
            "{} ({}, {})",
            p.index,
            p.direction,
            ["R", "G", "B"][p.colour]
        ),
        n,
        q,
    ))
}
