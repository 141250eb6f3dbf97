//! The pinhole + Brown-Conrady model shared by cameras and projectors.
//!
//! Conventions (OpenCV's, so that numbers can be compared with `cv::calibrateCamera`):
//! a world point `X_w` maps to the device frame by `X_d = R X_w + t` (metres);
//! the normalised coordinates `x = X_d/Z_d`, `y = Y_d/Z_d` are distorted by
//!
//! ```text
//! r2 = x^2 + y^2,  radial = 1 + k1 r2 + k2 r2^2 + k3 r2^3
//! xd = x radial + 2 p1 x y + p2 (r2 + 2 x^2)
//! yd = y radial + p1 (r2 + 2 y^2) + 2 p2 x y
//! ```
//!
//! and land on pixel `u = fx xd + cx`, `v = fy yd + cy`, with pixel centres at
//! integer coordinates and the origin at the top-left pixel's centre.
//! A projector is the same model run backwards: its "pixel" is the DMD mirror.

use nalgebra::{Isometry3, Matrix3, Point3, Translation3, UnitQuaternion, Vector2, Vector3};

/// Focal lengths and principal point, in pixels.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Intrinsics {
    /// Focal length along x, pixels.
    pub fx: f64,
    /// Focal length along y, pixels.
    pub fy: f64,
    /// Principal point x, pixels.
    pub cx: f64,
    /// Principal point y, pixels.
    pub cy: f64,
}

/// Brown-Conrady lens distortion with OpenCV's five coefficients.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Distortion {
    /// Radial, r^2 term.
    pub k1: f64,
    /// Radial, r^4 term.
    pub k2: f64,
    /// Tangential (decentring) 1.
    pub p1: f64,
    /// Tangential (decentring) 2.
    pub p2: f64,
    /// Radial, r^6 term.
    pub k3: f64,
}

/// A rigid transform from one frame to another: `x_to = rotation * x_from + translation_m`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pose {
    /// Proper rotation matrix (orthonormal, determinant +1).
    pub rotation: Matrix3<f64>,
    /// Translation, metres.
    pub translation_m: Vector3<f64>,
}

/// A pinhole device (camera or projector) with distortion, image size and pose.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PinholeModel {
    /// Image (or DMD) width, pixels.
    pub width_px: u32,
    /// Image (or DMD) height, pixels.
    pub height_px: u32,
    /// Focal lengths and principal point.
    pub intrinsics: Intrinsics,
    /// Lens distortion.
    pub distortion: Distortion,
    /// World -> device transform.
    pub pose: Pose,
}

/// A camera: a [`PinholeModel`] whose pixels see the scene.
pub type CameraModel = PinholeModel;
/// A projector: a [`PinholeModel`] whose pixels (DMD mirrors) light the scene.
pub type ProjectorModel = PinholeModel;

/// A ray in world coordinates: `origin_m + s * direction` for `s > 0`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray {
    /// Centre of projection of the device, metres, world frame.
    pub origin_m: Point3<f64>,
    /// Unit direction, world frame.
    pub direction: Vector3<f64>,
}

impl Pose {
    /// The identity transform.
    pub fn identity() -> Self {
        Self {
            rotation: Matrix3::identity(),
            translation_m: Vector3::zeros(),
        }
    }

    /// Applies the transform to a point.
    pub fn apply(&self, p: &Point3<f64>) -> Point3<f64> {
        Point3::from(self.rotation * p.coords + self.translation_m)
    }

    /// The inverse transform (`to -> from`).
    pub fn inverse(&self) -> Self {
        let rt = self.rotation.transpose();
        Self {
            rotation: rt,
            translation_m: -(rt * self.translation_m),
        }
    }

    /// As an isometry (the rotation re-orthonormalised through a quaternion).
    pub fn to_isometry(&self) -> Isometry3<f64> {
        Isometry3::from_parts(
            Translation3::from(self.translation_m),
            UnitQuaternion::from_matrix(&self.rotation),
        )
    }

    /// An isometry as a pose.
    pub fn from_isometry(t: &Isometry3<f64>) -> Self {
        Self {
            rotation: *t.rotation.to_rotation_matrix().matrix(),
            translation_m: t.translation.vector,
        }
    }

    /// `self` after `first`: maps `a -> c` when `first: a -> b` and `self: b -> c`.
    pub fn compose(&self, first: &Pose) -> Self {
        Self {
            rotation: self.rotation * first.rotation,
            translation_m: self.rotation * first.translation_m + self.translation_m,
        }
    }

    /// Largest entry of `|R^T R - I|` plus `|det R - 1|`: 0 for a proper rotation.
    pub fn rotation_defect(&self) -> f64 {
        let r = &self.rotation;
        let ortho = (r.transpose() * r - Matrix3::identity()).abs().max();
        ortho + (r.determinant() - 1.0).abs()
    }
}

impl Distortion {
    /// No distortion.
    pub fn none() -> Self {
        Self::default()
    }

    /// Whether all coefficients are zero (then undistortion is the identity).
    pub fn is_zero(&self) -> bool {
        self.k1 == 0.0 && self.k2 == 0.0 && self.p1 == 0.0 && self.p2 == 0.0 && self.k3 == 0.0
    }

    /// Distorts normalised coordinates (see the module doc).
    pub fn distort(&self, x: f64, y: f64) -> (f64, f64) {
        let r2 = x * x + y * y;
        let radial = 1.0 + r2 * (self.k1 + r2 * (self.k2 + r2 * self.k3));
        let xd = x * radial + 2.0 * self.p1 * x * y + self.p2 * (r2 + 2.0 * x * x);
        let yd = y * radial + self.p1 * (r2 + 2.0 * y * y) + 2.0 * self.p2 * x * y;
        (xd, yd)
    }

    /// Inverts [`Distortion::distort`] by Newton's method.
    ///
    /// Returns `None` where the iteration does not converge to 1e-12 (far outside the
    /// region where the polynomial is monotonic): such pixels have no trustworthy ray.
    pub fn undistort(&self, xd: f64, yd: f64) -> Option<(f64, f64)> {
        if self.is_zero() {
            return Some((xd, yd));
        }
        let (mut x, mut y) = (xd, yd);
        for _ in 0..50 {
            let (fx, fy) = self.distort(x, y);
            let (ex, ey) = (fx - xd, fy - yd);
            if ex.abs() < 1e-13 && ey.abs() < 1e-13 {
                return Some((x, y));
            }
            let j = self.jacobian(x, y);
            let det = j[0] * j[3] - j[1] * j[2];
            if !det.is_finite() || det.abs() < 1e-12 {
                return None;
            }
            x -= (j[3] * ex - j[1] * ey) / det;
            y -= (-j[2] * ex + j[0] * ey) / det;
        }
        let (fx, fy) = self.distort(x, y);
        ((fx - xd).abs() < 1e-12 && (fy - yd).abs() < 1e-12).then_some((x, y))
    }

    /// d(xd, yd)/d(x, y) as `[dxd/dx, dxd/dy, dyd/dx, dyd/dy]`.
    pub fn jacobian(&self, x: f64, y: f64) -> [f64; 4] {
        let r2 = x * x + y * y;
        let radial = 1.0 + r2 * (self.k1 + r2 * (self.k2 + r2 * self.k3));
        // d radial / d r2
        let dradial = self.k1 + r2 * (2.0 * self.k2 + 3.0 * self.k3 * r2);
        let dxdx = radial + x * dradial * 2.0 * x + 2.0 * self.p1 * y + 6.0 * self.p2 * x;
        let dxdy = x * dradial * 2.0 * y + 2.0 * self.p1 * x + 2.0 * self.p2 * y;
        let dydx = y * dradial * 2.0 * x + 2.0 * self.p1 * x + 2.0 * self.p2 * y;
        let dydy = radial + y * dradial * 2.0 * y + 6.0 * self.p1 * y + 2.0 * self.p2 * x;
        [dxdx, dxdy, dydx, dydy]
    }
}

impl PinholeModel {
    /// An undistorted device at the world origin looking down +z.
    pub fn ideal(width_px: u32, height_px: u32, focal_px: f64) -> Self {
        Self {
            width_px,
            height_px,
            intrinsics: Intrinsics {
                fx: focal_px,
                fy: focal_px,
                cx: (f64::from(width_px) - 1.0) / 2.0,
                cy: (f64::from(height_px) - 1.0) / 2.0,
            },
            distortion: Distortion::none(),
            pose: Pose::identity(),
        }
    }

    /// Centre of projection in world coordinates, metres.
    pub fn centre_m(&self) -> Point3<f64> {
        Point3::from(-(self.pose.rotation.transpose() * self.pose.translation_m))
    }

    /// Projects a world point to a pixel; `None` behind the device (`Z_d <= 0`).
    ///
    /// The pixel may lie outside the image; callers that need it inside check
    /// [`PinholeModel::contains`].
    pub fn project(&self, world_m: &Point3<f64>) -> Option<Vector2<f64>> {
        let d = self.pose.apply(world_m);
        if d.z <= 0.0 {
            return None;
        }
        Some(self.normalised_to_pixel(d.x / d.z, d.y / d.z))
    }

    /// Undistorted normalised coordinates `(x, y)` -> pixel.
    pub fn normalised_to_pixel(&self, x: f64, y: f64) -> Vector2<f64> {
        let (xd, yd) = self.distortion.distort(x, y);
        let k = &self.intrinsics;
        Vector2::new(k.fx * xd + k.cx, k.fy * yd + k.cy)
    }

    /// Pixel -> undistorted normalised coordinates `(x, y)` (the ray `(x, y, 1)` in the
    /// device frame); `None` where undistortion does not converge.
    pub fn pixel_to_normalised(&self, u: f64, v: f64) -> Option<(f64, f64)> {
        let k = &self.intrinsics;
        self.distortion
            .undistort((u - k.cx) / k.fx, (v - k.cy) / k.fy)
    }

    /// [`Self::pixel_to_normalised`] of every pixel, row-major (NaN where
    /// undistortion does not converge), on all cores.
    pub fn normalised_grid(&self) -> Vec<[f64; 2]> {
        use rayon::prelude::*;
        let width = self.width_px as usize;
        (0..width * self.height_px as usize)
            .into_par_iter()
            .map(|i| {
                self.pixel_to_normalised((i % width) as f64, (i / width) as f64)
                    .map_or([f64::NAN; 2], |(x, y)| [x, y])
            })
            .collect()
    }

    /// The world ray through pixel `(u, v)`; `None` where undistortion does not converge.
    pub fn pixel_ray(&self, u: f64, v: f64) -> Option<Ray> {
        let (x, y) = self.pixel_to_normalised(u, v)?;
        let dir = self.pose.rotation.transpose() * Vector3::new(x, y, 1.0);
        Some(Ray {
            origin_m: self.centre_m(),
            direction: dir.normalize(),
        })
    }

    /// Whether a pixel position lies on the sensor (within half a pixel of the edge pixels).
    pub fn contains(&self, pixel: &Vector2<f64>) -> bool {
        pixel.x >= -0.5
            && pixel.y >= -0.5
            && pixel.x < f64::from(self.width_px) - 0.5
            && pixel.y < f64::from(self.height_px) - 0.5
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Rotation3;

    #[test]
    fn pose_and_isometry_agree_on_points() {
        let t = Isometry3::new(Vector3::new(0.1, -0.2, 0.3), Vector3::new(0.2, 0.1, -0.3));
        let p = Pose::from_isometry(&t);
        let x = Point3::new(0.3, 0.4, 0.5);
        assert!((p.apply(&x) - t * x).norm() < 1e-12);
        assert!((p.to_isometry() * x - t * x).norm() < 1e-12);
    }

    fn lens() -> Distortion {
        Distortion {
            k1: -0.12,
            k2: 0.05,
            p1: 0.001,
            p2: -0.0007,
            k3: -0.01,
        }
    }

    #[test]
    fn undistort_inverts_distort() {
        let d = lens();
        for &(x, y) in &[(0.0, 0.0), (0.3, -0.2), (-0.45, 0.35), (0.1, 0.5)] {
            let (xd, yd) = d.distort(x, y);
            let (ux, uy) = d.undistort(xd, yd).expect("converges");
            assert!((ux - x).abs() < 1e-10 && (uy - y).abs() < 1e-10, "{x} {y}");
        }
    }

    #[test]
    fn jacobian_matches_finite_differences() {
        let d = lens();
        let (x, y, h) = (0.31, -0.22, 1e-6);
        let j = d.jacobian(x, y);
        let (ax, ay) = d.distort(x + h, y);
        let (bx, by) = d.distort(x - h, y);
        let (cx, cy) = d.distort(x, y + h);
        let (ex, ey) = d.distort(x, y - h);
        let num = [
            (ax - bx) / (2.0 * h),
            (cx - ex) / (2.0 * h),
            (ay - by) / (2.0 * h),
            (cy - ey) / (2.0 * h),
        ];
        for i in 0..4 {
            assert!((j[i] - num[i]).abs() < 1e-7, "{i}: {} vs {}", j[i], num[i]);
        }
    }

    #[test]
    fn projection_of_pixel_ray_returns_the_pixel() {
        let mut cam = PinholeModel::ideal(640, 480, 800.0);
        cam.distortion = lens();
        cam.pose = Pose {
            rotation: *Rotation3::from_euler_angles(0.1, -0.2, 0.05).matrix(),
            translation_m: Vector3::new(0.02, -0.01, 0.3),
        };
        for &(u, v) in &[(10.0, 20.0), (320.0, 240.0), (630.5, 470.25)] {
            let ray = cam.pixel_ray(u, v).expect("ray");
            let p = ray.origin_m + ray.direction * 0.5;
            let px = cam.project(&p).expect("in front");
            assert!((px.x - u).abs() < 1e-8 && (px.y - v).abs() < 1e-8, "{px}");
        }
    }

    #[test]
    fn points_behind_the_device_do_not_project() {
        let cam = PinholeModel::ideal(64, 48, 50.0);
        assert!(cam.project(&Point3::new(0.0, 0.0, -1.0)).is_none());
        assert!(cam.project(&Point3::new(0.0, 0.0, 0.0)).is_none());
    }

    #[test]
    fn pose_inverse_and_compose() {
        let p = Pose {
            rotation: *Rotation3::from_euler_angles(0.3, 0.1, -0.4).matrix(),
            translation_m: Vector3::new(0.1, 0.2, -0.3),
        };
        let id = p.compose(&p.inverse());
        assert!(id.rotation_defect() < 1e-12);
        assert!((id.rotation - Matrix3::identity()).abs().max() < 1e-12);
        assert!(id.translation_m.norm() < 1e-12);
        assert!(p.rotation_defect() < 1e-12);
    }
}
