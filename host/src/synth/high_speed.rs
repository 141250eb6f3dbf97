//! Formula-rendered high-speed exposures (seed 001's 24 patterns in one colour
//! exposure) for the decoder's tests and bench: a twin-like head and each LED's
//! eight sinusoidal fringes summed per camera channel.

use super::{render, stereo_rig, GroundTruth, Lighting};
use crate::calibration::{Head, PinholeModel};
use crate::highspeed::PatternSet;
use crate::raster::Raster;

/// The twin's single head at `width` x `height`: a camera 42 deg across and a
/// `dmd` projector 56 deg across, 0.12 m apart, both aimed at 0.5 m.
pub fn high_speed_head(width: u32, height: u32, dmd: (u32, u32)) -> Head {
    let camera = PinholeModel::ideal(
        width,
        height,
        0.5 * f64::from(width) / 21f64.to_radians().tan(),
    );
    let mut projector = PinholeModel::ideal(
        dmd.0,
        dmd.1,
        0.5 * f64::from(dmd.0) / 28f64.to_radians().tan(),
    );
    projector.intrinsics.cy = 0.5 * f64::from(dmd.1);
    let (camera, projector) = stereo_rig(camera, projector, 0.12, 0.5);
    Head {
        name: "A".into(),
        camera,
        projector,
        view_errors: vec![],
        port: None,
    }
}

/// Each LED's eight patterns summed in one exposure (R, G, B), scaled so the
/// brightest possible pixel stays below full scale; Gaussian noise `noise`.
pub fn high_speed_exposure(
    set: &PatternSet,
    truth: &GroundTruth,
    noise: f32,
    seed: u64,
) -> [Raster<f32>; 3] {
    let lighting = Lighting {
        ambient: 0.03,
        gain: 0.9,
        noise_sigma: noise,
    };
    [0, 1, 2].map(|c| {
        let pats: Vec<_> = set
            .patterns()
            .iter()
            .filter(|p| p.colour == c)
            .copied()
            .collect();
        let n = pats.len() as f64;
        render(
            truth,
            |u, v| {
                pats.iter()
                    .map(|p| 0.5 + 0.5 * PatternSet::phase_at(p, u, v).cos())
                    .sum::<f64>()
                    / n
            },
            &lighting,
            seed + c as u64,
        )
    })
}
