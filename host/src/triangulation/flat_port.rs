//! Triangulation through flat ports (issue 18): a camera and a projector in housings
//! that look into water through a flat window. Every ray bends at the window's two faces
//! (air -> glass -> water), so in-air pinhole models put each point at the wrong depth,
//! by an error that grows with the distance and that no fringe restoration removes.
//! Here the port is part of the model:
//!
//! ```text
//! camera pixel --undistort--> air ray --Snell at both faces--> water ray X(s) = o + s w
//! decoded column u ---------------------------------------.         |
//!                                                          v        v
//!   h(s) = (column of X(s) seen back through the projector's port) - u = 0,  s > 0
//! ```
//!
//! In water a projector column is a curved surface, not a plane, so the point is the
//! root of `h` along the camera's water ray: a secant iteration that starts from the
//! paraxial solution (the column plane of the port's virtual pinhole, below), each step
//! projecting `X(s)` back through the projector's port. That back-projection is itself a
//! 1-D root (the forward refraction problem): the path from the centre to a water point
//! `p` lies in the plane holding the port normal `n` through the centre and `p`, and the
//! air ray's slope `t = tan(theta_air)` against `n` solves
//!
//! ```text
//! a t + tau tan(theta_glass) + w tan(theta_water) = r,  sin(theta_x) = sin(theta_air) / n_x
//! ```
//!
//! (`a`, `tau`, `w`: the air, glass and water legs along `n`; `r`: `p`'s distance from the
//! normal axis), whose left side rises from 0 with `t`; it is solved by Newton's method
//! kept inside a bracket. For paraxial rays `tan(theta_x) = t / n_x` and a water point at
//! `(X, Z)` lies on the air slope `t = X / (c0 + Z / n_w)`, `c0 = a (1 - 1/n_w) +
//! tau (1/n_g - 1/n_w)`: a pinhole whose column planes are those of the starting guess.
//!
//! The port's inner face is the plane `n . p = distance_m * n_z` in the device frame (it
//! crosses the optical axis `distance_m` in front of the centre), the outer face lies
//! `thickness_m` further along `n`. A thickness of 0 is the digital twin's thin port.

use nalgebra::{Matrix3, Point3, Vector2, Vector3};
use rayon::prelude::*;

use crate::calibration::{CameraModel, PinholeModel, ProjectorModel};

/// Refractive index of common port glass (and of acrylic, 1.49), for thin ports where it
/// does not matter.
pub const GLASS_INDEX: f64 = 1.5;

/// Smallest `z` of a port normal: a port tilted more than 60 degrees from the optical axis
/// is refused (most of the field would graze it).
pub const MIN_NORMAL_Z: f64 = 0.5;

/// How far from unit length a port normal may be.
const NORMAL_TOLERANCE: f64 = 1e-9;

/// Newton/bisection steps of the back-projection through a port at most (Newton from the
/// paraxial start converges in 3 to 5; bisection fallbacks keep the bracket shrinking).
const AIM_STEPS: usize = 60;

/// Secant steps along the camera's water ray at most (4 to 6 are typical from the
/// paraxial start).
const SECANT_STEPS: usize = 30;

/// Column residual at which the secant iteration stops, projector pixels.
const STOP_PX: f64 = 1e-8;

/// Secant step along the camera's water ray below which the iteration stops, metres.
const STOP_M: f64 = 1e-10;

/// Largest column residual accepted for a triangulated point, projector pixels.
const MAX_RESIDUAL_PX: f64 = 1e-6;

/// A flat port (window) in front of a device, in the device frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FlatPort {
    /// Where the port's inner (air-side) face crosses the device's optical axis, metres in
    /// front of the centre of projection.
    pub distance_m: f64,
    /// Unit normal of the port, device frame, pointing into the water (`+z` for a port
    /// square to the optical axis).
    pub normal: Vector3<f64>,
    /// Glass thickness, metres; 0 for a thin port.
    pub thickness_m: f64,
    /// Refractive index of the glass (air = 1).
    pub glass_index: f64,
    /// Refractive index of the water beyond the port (air = 1).
    pub water_index: f64,
}

/// A port that cannot be used.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum FlatPortError {
    /// A number is NaN or infinite.
    #[error("port {field} is {value}, not a finite number")]
    NotFinite {
        /// Field name.
        field: &'static str,
        /// Its value.
        value: f64,
    },
    /// The port is not in front of the device.
    #[error("port distance_m {0} must be positive (the port lies in front of the device)")]
    Distance(f64),
    /// Negative glass thickness.
    #[error("port thickness_m {0} must be zero (a thin port) or positive")]
    Thickness(f64),
    /// An index below air's.
    #[error(
        "port {field} {value} must be at least 1 (denser than air, so that every air ray \
         enters the water)"
    )]
    Index {
        /// Field name.
        field: &'static str,
        /// Its value.
        value: f64,
    },
    /// A zero or non-unit normal.
    #[error("port normal {normal:?} must have unit length (it has {length})")]
    NormalLength {
        /// The normal given.
        normal: [f64; 3],
        /// Its length.
        length: f64,
    },
    /// A normal tilted too far from the optical axis.
    #[error(
        "port normal {normal:?} is tilted more than 60 degrees from the optical axis \
         (its z must be at least {MIN_NORMAL_Z})"
    )]
    NormalTilt {
        /// The normal given.
        normal: [f64; 3],
    },
    /// Not one projector column per camera pixel.
    #[error("{got} projector columns for a camera of {expected} pixels")]
    Columns {
        /// Camera pixels.
        expected: usize,
        /// Columns given.
        got: usize,
    },
}

/// A ray in water: where it leaves the port's outer face and its unit direction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WaterRay {
    /// Start on the port's outer face, metres.
    pub origin_m: Point3<f64>,
    /// Unit direction.
    pub direction: Vector3<f64>,
}

impl WaterRay {
    /// The point `s` metres along the ray.
    pub fn at(&self, s_m: f64) -> Point3<f64> {
        self.origin_m + self.direction * s_m
    }
}

/// Refracts the unit direction `dir` at a surface whose unit normal `normal` points the way
/// the light goes (`normal . dir > 0`), from index `n1` into `n2`, `eta = n1 / n2`
/// (Snell's law in vector form):
///
/// ```text
/// t = eta d + (cos_t - eta cos_i) n,  cos_i = n . d,  cos_t = sqrt(1 - eta^2 (1 - cos_i^2))
/// ```
///
/// `None` when the light does not reach the surface (`normal . dir <= 0`) or is totally
/// reflected.
///
/// ```
/// use nalgebra::Vector3;
/// use slscan::triangulation::flat_port::refract;
/// let z = Vector3::z();
/// // Square to the surface: no bending.
/// assert_eq!(refract(&z, &z, 1.0 / 1.33), Some(z));
/// // 30 degrees in air, sin(theta_water) = 0.5 / 1.33.
/// let d = Vector3::new(0.5, 0.0, 0.75f64.sqrt());
/// let t = refract(&d, &z, 1.0 / 1.33).unwrap();
/// assert!((t.x - 0.5 / 1.33).abs() < 1e-15 && (t.norm() - 1.0).abs() < 1e-15);
/// ```
pub fn refract(dir: &Vector3<f64>, normal: &Vector3<f64>, eta: f64) -> Option<Vector3<f64>> {
    let cos_i = normal.dot(dir);
    if cos_i <= 0.0 {
        return None;
    }
    let k = 1.0 - eta * eta * (1.0 - cos_i * cos_i);
    if k < 0.0 {
        return None;
    }
    Some(dir * eta + normal * (k.sqrt() - eta * cos_i))
}

impl FlatPort {
    /// A port with `normal` scaled to unit length, validated.
    pub fn new(
        distance_m: f64,
        normal: [f64; 3],
        thickness_m: f64,
        glass_index: f64,
        water_index: f64,
    ) -> Result<Self, FlatPortError> {
        let v = Vector3::from(normal);
        let length = v.norm();
        if !length.is_finite() || length < 1e-12 {
            return Err(FlatPortError::NormalLength { normal, length });
        }
        let port = Self {
            distance_m,
            normal: v / length,
            thickness_m,
            glass_index,
            water_index,
        };
        port.validate()?;
        Ok(port)
    }

    /// The digital twin's port: thin, square to the optical axis, `distance_m` in front.
    pub fn thin(distance_m: f64, water_index: f64) -> Result<Self, FlatPortError> {
        Self::new(distance_m, [0.0, 0.0, 1.0], 0.0, GLASS_INDEX, water_index)
    }

    /// Checks that every number is finite and physical and the normal a forward unit vector.
    pub fn validate(&self) -> Result<(), FlatPortError> {
        let n = self.normal;
        for (field, value) in [
            ("distance_m", self.distance_m),
            ("normal x", n.x),
            ("normal y", n.y),
            ("normal z", n.z),
            ("thickness_m", self.thickness_m),
            ("glass_index", self.glass_index),
            ("water_index", self.water_index),
        ] {
            if !value.is_finite() {
                return Err(FlatPortError::NotFinite { field, value });
            }
        }
        if self.distance_m <= 0.0 {
            return Err(FlatPortError::Distance(self.distance_m));
        }
        if self.thickness_m < 0.0 {
            return Err(FlatPortError::Thickness(self.thickness_m));
        }
        for (field, value) in [
            ("glass_index", self.glass_index),
            ("water_index", self.water_index),
        ] {
            if value < 1.0 {
                return Err(FlatPortError::Index { field, value });
            }
        }
        let normal = [n.x, n.y, n.z];
        let length = n.norm();
        if (length - 1.0).abs() > NORMAL_TOLERANCE {
            return Err(FlatPortError::NormalLength { normal, length });
        }
        if n.z < MIN_NORMAL_Z {
            return Err(FlatPortError::NormalTilt { normal });
        }
        Ok(())
    }

    /// Distance of the inner face from the centre along the normal, metres.
    fn inner_m(&self) -> f64 {
        self.distance_m * self.normal.z
    }

    /// Refracts a ray leaving the device centre along `dir` (device frame, any length)
    /// through both faces: the ray in water, device frame. `None` when it does not reach
    /// the port.
    pub fn refract_out(&self, dir: &Vector3<f64>) -> Option<WaterRay> {
        let n = &self.normal;
        let d = dir.try_normalize(0.0)?;
        let cos_i = n.dot(&d);
        if cos_i <= 0.0 {
            return None;
        }
        let inner = d * (self.inner_m() / cos_i);
        let in_glass = refract(&d, n, 1.0 / self.glass_index)?;
        let outer = inner + in_glass * (self.thickness_m / n.dot(&in_glass));
        let in_water = refract(&in_glass, n, self.glass_index / self.water_index)?;
        Some(WaterRay {
            origin_m: Point3::from(outer),
            direction: in_water,
        })
    }

    /// The unit air direction from the device centre whose path through the port reaches
    /// the water point `p` (device frame): the forward refraction problem. `None` when `p`
    /// is not beyond the port.
    pub fn aim(&self, p: &Point3<f64>) -> Option<Vector3<f64>> {
        self.aim_from(&p.coords, None).map(|(d, _)| d)
    }

    /// [`FlatPort::aim`], starting Newton's method from slope `start` when given (else
    /// from the paraxial slope); also returns the slope found, to start the next call.
    fn aim_from(&self, p: &Vector3<f64>, start: Option<f64>) -> Option<(Vector3<f64>, f64)> {
        let n = &self.normal;
        let (a, tau) = (self.inner_m(), self.thickness_m);
        let along = n.dot(p);
        let w = along - a - tau;
        if w.is_nan() || w <= 0.0 {
            return None;
        }
        let radial = p - n * along;
        let r = radial.norm();
        if r == 0.0 {
            return Some((*n, 0.0));
        }
        let (ng2, nw2) = (self.glass_index.powi(2), self.water_index.powi(2));
        // f(t) = a t + tau tan(theta_g) + w tan(theta_w) - r and f'(t), with
        // tan(theta_x) = s / sqrt(n_x^2 - s^2), s = sin(theta_air) = t / sqrt(1 + t^2).
        let eval = |t: f64| {
            let c = 1.0 / (1.0 + t * t).sqrt();
            let s = t * c;
            let (dg, dw) = ((ng2 - s * s).sqrt(), (nw2 - s * s).sqrt());
            let f = a * t + tau * s / dg + w * s / dw - r;
            let df = a + (tau * ng2 / (dg * dg * dg) + w * nw2 / (dw * dw * dw)) * c * c * c;
            (f, df)
        };
        // f(0) = -r < 0 and f(r / a) >= 0 (the glass and water legs only add).
        let (mut lo, mut hi) = (0.0, r / a);
        let paraxial = r / (a + tau / self.glass_index + w / self.water_index);
        let mut t = start.filter(|t| t.is_finite()).unwrap_or(paraxial);
        if !(t > lo && t < hi) {
            t = paraxial.clamp(lo, hi);
        }
        for _ in 0..AIM_STEPS {
            let (f, df) = eval(t);
            if f == 0.0 {
                break;
            }
            if f < 0.0 {
                lo = t;
            } else {
                hi = t;
            }
            let mut next = t - f / df;
            if !(next > lo && next < hi) {
                next = 0.5 * (lo + hi);
            }
            let step = (next - t).abs();
            t = next;
            // Newton's error after a step d is about (f'' / 2 f') d^2: below 1e-13 in the
            // slope (1e-10 projector pixels) once d <= 1e-7, so no step is taken to confirm.
            if step <= 1e-7 * (1.0 + t) {
                break;
            }
        }
        Some(((n + radial * (t / r)).normalize(), t))
    }
}

/// The water ray of pixel `(u, v)` of a device behind `port`, world frame; `None` where
/// the pixel has no ray or the ray misses the port.
pub fn pixel_ray(model: &PinholeModel, port: &FlatPort, u: f64, v: f64) -> Option<WaterRay> {
    let (x, y) = model.pixel_to_normalised(u, v)?;
    let local = port.refract_out(&Vector3::new(x, y, 1.0))?;
    let to_world = model.pose.inverse();
    Some(WaterRay {
        origin_m: to_world.apply(&local.origin_m),
        direction: to_world.rotation * local.direction,
    })
}

/// The pixel where a device behind `port` sees (or lights) the world point `p`; `None`
/// when `p` is not beyond the port. The pixel may lie off the image.
pub fn project(model: &PinholeModel, port: &FlatPort, p: &Point3<f64>) -> Option<Vector2<f64>> {
    let d = port.aim(&model.pose.apply(p))?;
    Some(model.normalised_to_pixel(d.x / d.z, d.y / d.z))
}

/// One point triangulated through the ports.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PortHit {
    /// Position, metres, world frame.
    pub point_m: Point3<f64>,
    /// Depth along the camera's optical axis (camera-frame z), metres.
    pub depth_m: f64,
}

/// A camera and a projector, each behind its own flat port, set up once: the camera's
/// undistorted pixel coordinates are computed in [`PortTriangulator::new`].
#[derive(Clone, Debug)]
pub struct PortTriangulator {
    camera: CameraModel,
    camera_port: FlatPort,
    projector: ProjectorModel,
    projector_port: FlatPort,
    width: usize,
    /// Undistorted normalised camera coordinates per pixel, NaN where there is no ray.
    normalised: Vec<[f64; 2]>,
    /// Camera frame -> world rotation.
    cam_to_world: Matrix3<f64>,
}

impl PortTriangulator {
    /// Validates both ports and undistorts every camera pixel (parallel).
    pub fn new(
        camera: &CameraModel,
        camera_port: &FlatPort,
        projector: &ProjectorModel,
        projector_port: &FlatPort,
    ) -> Result<Self, FlatPortError> {
        camera_port.validate()?;
        projector_port.validate()?;
        let width = camera.width_px as usize;
        let normalised = camera.normalised_grid();
        Ok(Self {
            camera: *camera,
            camera_port: *camera_port,
            projector: *projector,
            projector_port: *projector_port,
            width,
            normalised,
            cam_to_world: camera.pose.rotation.transpose(),
        })
    }

    /// Camera pixel `index`'s ray in water, world frame (`None`: no ray, or it misses the
    /// port).
    pub fn water_ray(&self, index: usize) -> Option<WaterRay> {
        let [x, y] = *self.normalised.get(index)?;
        if x.is_nan() {
            return None;
        }
        let local = self.camera_port.refract_out(&Vector3::new(x, y, 1.0))?;
        let centre = self.camera.centre_m();
        Some(WaterRay {
            origin_m: centre + self.cam_to_world * local.origin_m.coords,
            direction: self.cam_to_world * local.direction,
        })
    }

    /// Projector column of world point `p` seen back through the projector's port, and
    /// the air slope found (to start the next call).
    fn column(&self, p: &Point3<f64>, start: Option<f64>) -> Option<(f64, f64)> {
        let local = self.projector.pose.apply(p);
        let (d, t) = self.projector_port.aim_from(&local.coords, start)?;
        Some((
            self.projector.normalised_to_pixel(d.x / d.z, d.y / d.z).x,
            t,
        ))
    }

    /// Where camera pixel `index`'s water ray meets the water point that the projector
    /// lights with column `column_px`. `None` when the pixel has no ray, the iteration
    /// leaves the water in front of either port, or it does not settle to within
    /// 1e-6 px.
    pub fn intersect(&self, index: usize, column_px: f64) -> Option<PortHit> {
        if !column_px.is_finite() {
            return None;
        }
        let ray = self.water_ray(index)?;
        let (s0, slope0) = self
            .paraxial_start(&ray, column_px)
            .unwrap_or((0.5, f64::NAN));
        let mut aim_slope = None;
        let mut h = |s: f64| -> Option<f64> {
            let (c, t) = self.column(&ray.at(s), aim_slope)?;
            aim_slope = Some(t);
            Some(c - column_px)
        };
        let (mut s_prev, mut h_prev) = (s0, h(s0)?);
        // First step: Newton with the paraxial model's derivative; then secant steps.
        let mut s = s0 - h_prev / slope0;
        if !(s.is_finite() && s > 0.0) || s == s0 {
            s = s0 * (1.0 + 1e-4);
        }
        let mut hs = h(s)?;
        for _ in 0..SECANT_STEPS {
            if hs.abs() <= STOP_PX || hs == h_prev {
                break;
            }
            let mut next = s - hs * (s - s_prev) / (hs - h_prev);
            if !next.is_finite() {
                return None;
            }
            if next <= 0.0 {
                next = 0.5 * s;
            }
            // A last correction this small (|h| <= |dh/ds| STOP_M, ~1e-8 px) is taken
            // without evaluating h again: it saves one of about five evaluations.
            if (next - s).abs() <= STOP_M && hs.abs() <= MAX_RESIDUAL_PX {
                s = next;
                break;
            }
            (s_prev, h_prev) = (s, hs);
            s = next;
            hs = h(s)?;
        }
        if hs.abs() > MAX_RESIDUAL_PX {
            return None;
        }
        let point_m = ray.at(s);
        Some(PortHit {
            point_m,
            depth_m: self.camera.pose.apply(&point_m).z,
        })
    }

    /// Range along `ray` where it meets the column plane of the projector's paraxial
    /// virtual pinhole (see the module doc), ignoring projector distortion and port tilt,
    /// and that model's column change per metre along the ray there: the start of
    /// [`PortTriangulator::intersect`].
    fn paraxial_start(&self, ray: &WaterRay, column_px: f64) -> Option<(f64, f64)> {
        let port = &self.projector_port;
        let k = &self.projector.intrinsics;
        let xn = (column_px - k.cx) / k.fx;
        let (nw, a) = (port.water_index, port.inner_m());
        let c0 = a * (1.0 - 1.0 / nw) + port.thickness_m * (1.0 / port.glass_index - 1.0 / nw);
        let q = self.projector.pose.apply(&ray.origin_m);
        let e = self.projector.pose.rotation * ray.direction;
        // Plane n_w P.x - x_n P.z = x_n c0 n_w with P = q + s e.
        let s = (xn * (c0 * nw + q.z) - nw * q.x) / (nw * e.x - xn * e.z);
        if !(s.is_finite() && s > 0.0) {
            return None;
        }
        // x_n(P) = n_w P.x / (c0 n_w + P.z) along the ray.
        let p = q + e * s;
        let den = c0 * nw + p.z;
        let dxn_ds = nw * (e.x * den - p.x * e.z) / (den * den);
        Some((s, k.fx * dxn_ds))
    }

    /// Triangulates every camera pixel with its projector column (row-major, NaN: no
    /// column), in parallel: one entry per pixel.
    pub fn intersect_columns(
        &self,
        columns_px: &[f32],
    ) -> Result<Vec<Option<PortHit>>, FlatPortError> {
        if columns_px.len() != self.normalised.len() {
            return Err(FlatPortError::Columns {
                expected: self.normalised.len(),
                got: columns_px.len(),
            });
        }
        Ok(columns_px
            .par_iter()
            .enumerate()
            .map(|(i, &c)| self.intersect(i, f64::from(c)))
            .collect())
    }

    /// Camera image size `(width, height)`.
    pub fn size(&self) -> (usize, usize) {
        (self.width, self.normalised.len() / self.width.max(1))
    }
}

#[cfg(test)]
mod tests;
