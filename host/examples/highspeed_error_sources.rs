//! Where the high-speed mode's depth error on the twin comes from: the same
//! `spheres` scan (640x480, one frame, twin-truth calibration) with the
//! twin's imperfections removed one by one, each instant's signed depth
//! error (decoded minus true camera z) as percentiles over the object's
//! decoded pixels. One variant shows the set as sinusoidal grey fringes
//! (the DMD cannot at 5 kHz; the twin can) to tell the square waves'
//! share; the last table is each instant's depth change per radian of its
//! phase at the image centre, to read phase errors as depth.
//!
//! ```sh
//! cargo run --release -p slscan --example highspeed_error_sources
//! ```

use std::sync::Arc;

use anyhow::Context;

use hil_sim::twin::scenes::{built_in, Detail};
use hil_sim::twin::sensor::Channels;
use hil_sim::twin::TwinRig;
use nalgebra::Point3;
use slscan::board::{ClientConfig, ScanOutcome};
use slscan::calibration::Head;
use slscan::highspeed::PatternSet;
use slscan::raster::Raster;
use slscan::rig::{Board, Camera, Led, Projector, RigError};
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
    /// The patterns as sinusoidal grey fringes instead of the DMD's binary ones.
    grey: bool,
    /// The demultiplexer's window leak (its default is 0.01).
    leak: f64,
}

/// The simulated rig with each binary fringe it is given swapped for the
/// grey sinusoid it was cut from (same phase, same LED).
struct GreyFringes<'a> {
    rig: &'a mut SimRig,
    set: PatternSet,
}

impl Board for GreyFringes<'_> {
    fn run_plan(&mut self, plan: &protocol::ScanPlan) -> Result<ScanOutcome, RigError> {
        self.rig.run_plan(plan)
    }
}

impl Projector for GreyFringes<'_> {
    fn dmd_size_px(&self, head: usize) -> Result<(u32, u32), RigError> {
        self.rig.dmd_size_px(head)
    }
    fn load_sequence(&mut self, head: usize, patterns: &[Raster<f32>]) -> Result<(), RigError> {
        self.rig.load_sequence(head, patterns)
    }
    fn load_coloured_sequence(
        &mut self,
        head: usize,
        patterns: &[Raster<f32>],
        leds: &[Led],
    ) -> Result<(), RigError> {
        // The 24-pattern set is the only sequence of this length; the LED
        // flats (3 frames) pass unchanged.
        if patterns.len() != self.set.patterns().len() {
            return self.rig.load_coloured_sequence(head, patterns, leds);
        }
        let grey = self.set.grey_frames();
        self.rig.load_coloured_sequence(head, &grey, leds)
    }
}

impl Camera for GreyFringes<'_> {
    fn image_size_px(&self, head: usize) -> Result<(u32, u32), RigError> {
        self.rig.image_size_px(head)
    }
    fn take_frames(&mut self, head: usize) -> Result<Vec<Raster<f32>>, RigError> {
        self.rig.take_frames(head)
    }
    fn take_colour_frames(&mut self, head: usize) -> Result<Vec<[Raster<f32>; 3]>, RigError> {
        self.rig.take_colour_frames(head)
    }
}

fn main() -> anyhow::Result<()> {
    // (name, noise-free sensor, projector in focus, no crosstalk, grey fringes, window leak)
    let variants = [
        ("as built", false, false, false, false, 0.01),
        ("noise-free float sensor", true, false, false, false, 0.01),
        ("+ projector in focus", true, true, false, false, 0.01),
        ("+ no colour crosstalk", true, true, true, false, 0.01),
        ("+ sinusoidal grey fringes", true, true, true, true, 0.01),
        (
            "as built, sinusoidal grey fringes",
            false,
            false,
            false,
            true,
            0.01,
        ),
        (
            "as built, window leak 0.05",
            false,
            false,
            false,
            false,
            0.05,
        ),
        ("as built, window leak 0.2", false, false, false, false, 0.2),
    ]
    .map(
        |(name, noise_free, sharp_projector, no_crosstalk, grey, leak)| Variant {
            name,
            noise_free,
            sharp_projector,
            no_crosstalk,
            grey,
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
    println!("\n| instant (direction, LED) | depth per radian of phase at the image centre, 0.48 m, mm |");
    println!("|---|---|");
    for (pattern, mm) in depth_per_radian()? {
        println!("| {pattern} | {mm:.2} |");
    }
    Ok(())
}

/// Per pattern: how far the surface at the centre pixel moves, at 0.48 m
/// (the decoder's reference depth), for one radian of that pattern's phase.
fn depth_per_radian() -> anyhow::Result<Vec<(String, f64)>> {
    let defaults = SimHighSpeedConfig::new("spheres");
    let detail = Detail {
        camera: defaults.camera_px,
        projector: defaults.projector_px,
    };
    let (_, rig) = built_in("spheres", &detail)?;
    let calibration = twin_calibration(&rig, 1);
    let head: &Head = &calibration.heads[0];
    let set = PatternSet::seed001((detail.projector.0, detail.projector.1))?;
    let camera = &head.camera;
    let (u, v) = (
        f64::from(camera.width_px) / 2.0,
        f64::from(camera.height_px) / 2.0,
    );
    let (x, y) = camera
        .pixel_to_normalised(u, v)
        .context("centre pixel does not undistort")?;
    let dz = 1e-4;
    // The camera-frame point at depth z on the centre ray, in the world.
    let at = |z: f64| {
        let d = camera.pose.inverse();
        d.apply(&Point3::new(x * z, y * z, z))
    };
    let (near, far) = (
        head.projector.project(&at(0.48)),
        head.projector.project(&at(0.48 + dz)),
    );
    let (Some(near), Some(far)) = (near, far) else {
        anyhow::bail!("the centre pixel's point is behind the projector");
    };
    Ok(set
        .patterns()
        .iter()
        .map(|p| {
            let dphi =
                PatternSet::phase_at(p, far.x, far.y) - PatternSet::phase_at(p, near.x, near.y);
            let name = format!(
                "{} ({}, {})",
                p.index,
                p.direction,
                ["R", "G", "B"][p.colour]
            );
            (name, 1e3 * dz / dphi.abs())
        })
        .collect())
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
    let result = if variant.grey {
        let mut grey = GreyFringes {
            rig: &mut sim,
            set: PatternSet::seed001((detail.projector.0, detail.projector.1))?,
        };
        run_high_speed(&mut grey, &config, &calibration, None, &mut |_| {})?
    } else {
        run_high_speed(&mut sim, &config, &calibration, None, &mut |_| {})?
    };
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
