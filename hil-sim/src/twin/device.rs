//! Cameras and projectors: pinhole intrinsics, OpenCV distortion
//! (k1 k2 p1 p2 k3) and poses, and the rig that holds them.
//!
//! Conventions: device frame x right, y down, z forward (OpenCV); pixel
//! centres at integer coordinates, x right, y down, origin at the centre of
//! the top-left pixel; poses are `world_from_device`, metres.

use nalgebra::Point3;
use serde::{Deserialize, Serialize};

use super::error::{positive, TwinError};
use super::geometry::{Pose, Ray, V3};
use super::medium::Medium;

/// Pinhole intrinsics in pixels, with the image size.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Intrinsics {
    /// Focal length along x, pixels.
    pub fx: f64,
    /// Focal length along y, pixels.
    pub fy: f64,
    /// Principal point x, pixels.
    pub cx: f64,
    /// Principal point y, pixels.
    pub cy: f64,
    /// Image width, pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
}

impl Intrinsics {
    /// Intrinsics with square pixels, a horizontal field of view and the
    /// principal point at the image centre.
    pub fn from_fov(width: u32, height: u32, hfov_deg: f64) -> Intrinsics {
        let f = 0.5 * width as f64 / (0.5 * hfov_deg.to_radians()).tan();
        Intrinsics {
            fx: f,
            fy: f,
            cx: 0.5 * (width as f64 - 1.0),
            cy: 0.5 * (height as f64 - 1.0),
            width,
            height,
        }
    }

    /// Rejects non-positive focal lengths, zero sizes and non-finite values.
    pub fn validate(&self) -> Result<(), TwinError> {
        positive("fx", self.fx)?;
        positive("fy", self.fy)?;
        positive("width", self.width as f64)?;
        positive("height", self.height as f64)?;
        if !(self.cx.is_finite() && self.cy.is_finite()) {
            return Err(TwinError::BadParameter {
                name: "cx/cy",
                value: self.cx + self.cy,
                why: "must be finite",
            });
        }
        Ok(())
    }
}

/// Lens distortion with OpenCV's names and model.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Distortion {
    /// Radial r^2 coefficient.
    pub k1: f64,
    /// Radial r^4 coefficient.
    pub k2: f64,
    /// Tangential coefficient 1.
    pub p1: f64,
    /// Tangential coefficient 2.
    pub p2: f64,
    /// Radial r^6 coefficient.
    pub k3: f64,
}

impl Distortion {
    /// Maps ideal normalised coordinates to distorted ones (OpenCV model).
    pub fn distort(&self, x: f64, y: f64) -> (f64, f64) {
        let r2 = x * x + y * y;
        let radial = 1.0 + r2 * (self.k1 + r2 * (self.k2 + r2 * self.k3));
        let xd = x * radial + 2.0 * self.p1 * x * y + self.p2 * (r2 + 2.0 * x * x);
        let yd = y * radial + self.p1 * (r2 + 2.0 * y * y) + 2.0 * self.p2 * x * y;
        (xd, yd)
    }

    /// Inverts `distort` by Newton's method on the 2x2 Jacobian
    /// (quadratic convergence: 3-5 steps reach 1e-14, i.e. 1e-11 px, for
    /// measurement lenses).
    pub fn undistort(&self, xd: f64, yd: f64) -> (f64, f64) {
        if *self == Distortion::default() {
            return (xd, yd);
        }
        let (mut x, mut y) = (xd, yd);
        for _ in 0..20 {
            let (fx, fy) = self.distort(x, y);
            let (ex, ey) = (fx - xd, fy - yd);
            if ex.abs() + ey.abs() < 1e-14 {
                break;
            }
            let r2 = x * x + y * y;
            let rad = 1.0 + r2 * (self.k1 + r2 * (self.k2 + r2 * self.k3));
            let drad = self.k1 + r2 * (2.0 * self.k2 + 3.0 * r2 * self.k3);
            let a = rad + 2.0 * x * x * drad + 2.0 * self.p1 * y + 6.0 * self.p2 * x;
            let b = 2.0 * x * y * drad + 2.0 * self.p1 * x + 2.0 * self.p2 * y;
            let d = rad + 2.0 * y * y * drad + 6.0 * self.p1 * y + 2.0 * self.p2 * x;
            let det = a * d - b * b;
            if det.abs() < 1e-12 {
                break;
            }
            x -= (d * ex - b * ey) / det;
            y -= (a * ey - b * ex) / det;
        }
        (x, y)
    }
}

/// A posed pinhole device with distortion: the shared model of cameras and projectors.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Pinhole {
    /// Intrinsics and image size.
    pub intrinsics: Intrinsics,
    /// Lens distortion.
    pub distortion: Distortion,
    /// Pose `world_from_device`.
    pub world_from_device: Pose,
}

impl Pinhole {
    /// Pixel (with distortion) of a world point, or None behind the device.
    pub fn project(&self, world_m: &V3) -> Option<[f64; 2]> {
        let p = self
            .world_from_device
            .inverse_transform_point(&Point3::from(*world_m));
        self.project_local(&p.coords)
    }

    /// Pixel of a point already in the device frame.
    pub fn project_local(&self, p: &V3) -> Option<[f64; 2]> {
        if p.z <= 0.0 {
            return None;
        }
        let (xd, yd) = self.distortion.distort(p.x / p.z, p.y / p.z);
        let k = &self.intrinsics;
        Some([k.fx * xd + k.cx, k.fy * yd + k.cy])
    }

    /// Unit ray direction in the device frame through pixel (x, y).
    pub fn local_dir(&self, x_px: f64, y_px: f64) -> V3 {
        let k = &self.intrinsics;
        let (xn, yn) = self
            .distortion
            .undistort((x_px - k.cx) / k.fx, (y_px - k.cy) / k.fy);
        V3::new(xn, yn, 1.0).normalize()
    }

    /// World ray through pixel (x, y), from the centre of projection.
    pub fn pixel_ray(&self, x_px: f64, y_px: f64) -> Ray {
        let d = self.world_from_device.rotation * self.local_dir(x_px, y_px);
        Ray {
            origin: self.world_from_device.translation.vector,
            dir: d,
        }
    }

    /// Centre of projection in the world, metres.
    pub fn centre(&self) -> V3 {
        self.world_from_device.translation.vector
    }

    /// Whether a (sub)pixel coordinate lies on the sensor/DMD, pixel centres
    /// at integers so the valid range is [-0.5, size - 0.5).
    pub fn contains(&self, px: [f64; 2]) -> bool {
        let k = &self.intrinsics;
        px[0] >= -0.5
            && px[1] >= -0.5
            && px[0] < k.width as f64 - 0.5
            && px[1] < k.height as f64 - 0.5
    }
}

/// A camera of the rig.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Camera {
    /// Name used in files and reports.
    pub name: String,
    /// Geometry.
    pub model: Pinhole,
}

/// A DMD projector of the rig.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Projector {
    /// Name used in files and reports.
    pub name: String,
    /// Geometry (intrinsics size = DMD size).
    pub model: Pinhole,
    /// Irradiance of a full-on pixel on a surface at `reference_distance_m`
    /// facing the projector, per LED band (R, G, B), in twin units per second.
    pub led_power: [f64; 3],
    /// Defocus: Gaussian blur of the displayed image, sigma in DMD pixels
    /// (what turns defocused binary patterns quasi-sinusoidal).
    pub defocus_sigma_px: f64,
    /// Intensity response to a displayed grey value g in [0, 1]: g^gamma.
    /// 1 for a DMD in pattern mode (time-multiplexed, linear); about 2.2
    /// when patterns go through a video input. Its harmonics are what the
    /// N-step choice of DESIGN.md must keep off the other head's bin.
    pub gamma: f64,
    /// Distance at which `led_power` is the irradiance, metres (inverse-square falloff).
    pub reference_distance_m: f64,
}

/// One or two heads: cameras and projectors, and the medium they look through.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Rig {
    /// Cameras, indexed by `render_exposure`'s camera index.
    pub cameras: Vec<Camera>,
    /// Projectors, in the order of the timelines passed to the renderer.
    pub projectors: Vec<Projector>,
    /// Air, or water behind flat ports.
    pub medium: Medium,
}

impl Rig {
    /// Checks every device's numbers.
    pub fn validate(&self) -> Result<(), TwinError> {
        for c in &self.cameras {
            c.model.intrinsics.validate()?;
        }
        for p in &self.projectors {
            p.model.intrinsics.validate()?;
            positive("reference_distance_m", p.reference_distance_m)?;
            super::error::non_negative("defocus_sigma_px", p.defocus_sigma_px)?;
            positive("projector gamma", p.gamma)?;
            for &l in &p.led_power {
                super::error::non_negative("led_power", l)?;
            }
        }
        self.medium.validate()
    }
}

/// A pose that puts a device at `eye_m` looking at `target_m` with image
/// "up" (-y) towards `up` (OpenCV frame: z forward, y down).
pub fn look_at(eye_m: V3, target_m: V3, up: V3) -> Pose {
    let z = (target_m - eye_m).normalize();
    let y = -(up - z * up.dot(&z)).normalize();
    // Right-handed: x = y cross z.
    let x = y.cross(&z);
    // Columns are the device axes expressed in the world.
    let m = nalgebra::Matrix3::from_columns(&[x, y, z]);
    let rot = nalgebra::UnitQuaternion::from_rotation_matrix(
        &nalgebra::Rotation3::from_matrix_unchecked(m),
    );
    Pose::from_parts(nalgebra::Translation3::from(eye_m), rot)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn undistort_inverts_distort() {
        let d = Distortion {
            k1: -0.2,
            k2: 0.05,
            p1: 0.001,
            p2: -0.002,
            k3: 0.01,
        };
        for &(x, y) in &[(0.1, 0.2), (-0.3, 0.25), (0.0, 0.0), (0.35, -0.3)] {
            let (xd, yd) = d.distort(x, y);
            let (xu, yu) = d.undistort(xd, yd);
            assert!(
                (xu - x).abs() < 1e-10 && (yu - y).abs() < 1e-10,
                "{x} {y} -> {xu} {yu}"
            );
        }
    }

    #[test]
    fn pixel_ray_reprojects_to_same_pixel() {
        let model = Pinhole {
            intrinsics: Intrinsics::from_fov(320, 240, 50.0),
            distortion: Distortion {
                k1: -0.1,
                k2: 0.02,
                p1: 0.0005,
                p2: 0.0,
                k3: 0.0,
            },
            world_from_device: look_at(
                V3::new(0.1, -0.2, 0.5),
                V3::zeros(),
                V3::new(0.0, 1.0, 0.0),
            ),
        };
        for &(x, y) in &[(0.0, 0.0), (160.3, 120.7), (319.0, 239.0)] {
            let r = model.pixel_ray(x, y);
            let p = model.project(&r.at(0.7)).unwrap();
            assert!((p[0] - x).abs() < 1e-7 && (p[1] - y).abs() < 1e-7);
        }
    }

    #[test]
    fn look_at_points_z_at_target_and_up_is_minus_y() {
        let pose = look_at(V3::new(0.0, 0.0, 1.0), V3::zeros(), V3::new(0.0, 1.0, 0.0));
        let z = pose.rotation * V3::z();
        assert!((z - V3::new(0.0, 0.0, -1.0)).norm() < 1e-12);
        let y = pose.rotation * V3::y();
        assert!((y - V3::new(0.0, -1.0, 0.0)).norm() < 1e-12);
        assert!(pose.rotation.to_rotation_matrix().matrix().determinant() > 0.0);
    }
}
