//! The formula-rendered set-up the accuracy and unwrapping tests share: a
//! 320x240 camera and a 912x1140 projector 0.15 m apart looking at 0.5 m,
//! Gaussian intensity noise of known sigma, and a tilted plane.

use nalgebra::{Point3, Vector3};
use slscan::calibration::{CameraModel, PinholeModel, ProjectorModel};
use slscan::synth::{self, Lighting, Surface};

/// Intensity noise of [`light`], frame units.
pub const SIGMA_I: f32 = 0.01;

/// The camera and projector.
pub fn rig() -> (CameraModel, ProjectorModel) {
    synth::stereo_rig(
        PinholeModel::ideal(320, 240, 800.0),
        PinholeModel::ideal(912, 1140, 1800.0),
        0.15,
        0.5,
    )
}

/// Ambient 0.1, gain 0.7, noise [`SIGMA_I`].
pub fn light() -> Lighting {
    Lighting {
        ambient: 0.1,
        gain: 0.7,
        noise_sigma: SIGMA_I,
    }
}

/// A plane at 0.5 m, tilted against the camera axis.
pub fn tilted_plane() -> Vec<Surface> {
    vec![Surface::Plane {
        point_m: Point3::new(0.0, 0.0, 0.5),
        normal: Vector3::new(0.15, 0.08, -1.0).normalize(),
    }]
}
