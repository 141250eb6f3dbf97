//! Triangulation: camera rays against projector planes (one phase direction) or
//! projector rays (both directions), with per-point predicted noise.
//!
//! [`Triangulator::new`] does the expensive part once per camera: it undistorts every
//! camera pixel into a world ray and expresses that ray in the projector frame. Per frame,
//! a projector column `u` then costs a handful of multiply-adds:
//!
//! ```text
//! camera ray  X(s) = C + s d                    (world, |d| = 1)
//! projector   X_p(s) = q + s e,  q = R_p C + t_p, e = R_p d
//! column u -> x_n = (u - cx)/fx (undistorted);  plane X_p.x = x_n X_p.z
//! s = (x_n q.z - q.x) / (e.x - x_n e.z)
//! ```
//!
//! With projector distortion the column is no plane; the solution is refined by fixed-point
//! iteration on the undistorted `x_n` given the current `y_n` (converges in 2-3 rounds for
//! realistic lenses). Two directions (`u`, `v`) use the least-squares closest point of the
//! camera ray and the projector ray.

use nalgebra::{Point3, Vector3};
use rayon::prelude::*;

use crate::calibration::{CameraModel, ProjectorModel};

/// Which projector coordinate a phase map measures.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ProjectorAxis {
    /// Column `u` (phase grows along projector x).
    Column,
    /// Row `v` (phase grows along projector y).
    Row,
}

/// Precomputed per-pixel geometry of one camera-projector pair.
#[derive(Clone, Debug)]
pub struct Triangulator {
    camera: CameraModel,
    projector: ProjectorModel,
    width: usize,
    height: usize,
    /// World ray direction per camera pixel; NaN where undistortion failed.
    rays: Vec<[f32; 3]>,
    /// The same ray in the projector frame (`e = R_p d`).
    rays_proj: Vec<[f32; 3]>,
    /// Camera-frame depth per unit ray length (`Z_c = s * depth_per_m`).
    depth_per_m: Vec<f32>,
    centre: [f32; 3],
    q: [f32; 3],
    projector_distorted: bool,
}

/// One triangulated point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Triangulated {
    /// Position, metres, world frame.
    pub point_m: Point3<f32>,
    /// Distance along the camera ray, metres.
    pub range_m: f32,
    /// Depth along the camera's optical axis, metres.
    pub depth_m: f32,
}

impl Triangulator {
    /// Precomputes rays for every camera pixel (parallel; the costly step).
    pub fn new(camera: &CameraModel, projector: &ProjectorModel) -> Self {
        let (width, height) = (camera.width_px as usize, camera.height_px as usize);
        let rp = projector.pose.rotation;
        let centre = camera.centre_m();
        let q = projector.pose.apply(&centre);
        let per_pixel: Vec<([f32; 3], [f32; 3], f32)> = (0..width * height)
            .into_par_iter()
            .map(|i| {
                let (u, v) = ((i % width) as f64, (i / width) as f64);
                match camera.pixel_to_normalised(u, v) {
                    Some((x, y)) => {
                        let cam_dir = Vector3::new(x, y, 1.0);
                        let norm = cam_dir.norm();
                        let d = camera.pose.rotation.transpose() * cam_dir / norm;
                        let e = rp * d;
                        (to_f32(&d), to_f32(&e), (1.0 / norm) as f32)
                    }
                    None => ([f32::NAN; 3], [f32::NAN; 3], f32::NAN),
                }
            })
            .collect();
        let mut rays = Vec::with_capacity(per_pixel.len());
        let mut rays_proj = Vec::with_capacity(per_pixel.len());
        let mut depth_per_m = Vec::with_capacity(per_pixel.len());
        for (d, e, z) in per_pixel {
            rays.push(d);
            rays_proj.push(e);
            depth_per_m.push(z);
        }
        Self {
            camera: *camera,
            projector: *projector,
            width,
            height,
            rays,
            rays_proj,
            depth_per_m,
            centre: to_f32(&centre.coords),
            q: to_f32(&q.coords),
            projector_distorted: !projector.distortion.is_zero(),
        }
    }

    /// Camera image size `(width, height)`.
    pub fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    /// The camera this was built for.
    pub fn camera(&self) -> &CameraModel {
        &self.camera
    }

    /// The projector this was built for.
    pub fn projector(&self) -> &ProjectorModel {
        &self.projector
    }

    /// Intersects camera pixel `index`'s ray with the projector plane of coordinate
    /// `coord_px` along `axis`. `None` when the ray is parallel to the plane, the point is
    /// behind either device, or the pixel has no ray.
    #[inline]
    pub fn intersect(
        &self,
        index: usize,
        axis: ProjectorAxis,
        coord_px: f32,
    ) -> Option<Triangulated> {
        let k = &self.projector.intrinsics;
        let (a, f, c) = match axis {
            ProjectorAxis::Column => (0, k.fx as f32, k.cx as f32),
            ProjectorAxis::Row => (1, k.fy as f32, k.cy as f32),
        };
        let e = self.rays_proj[index];
        let xd = (coord_px - c) / f;
        let mut xn = xd;
        let mut s = self.solve(e, a, xn)?;
        if self.projector_distorted {
            for _ in 0..4 {
                let p = [
                    self.q[0] + s * e[0],
                    self.q[1] + s * e[1],
                    self.q[2] + s * e[2],
                ];
                if p[2] <= 0.0 {
                    return None;
                }
                let other = p[1 - a] / p[2];
                xn = self.undistort_along(a, xd, xn, other);
                s = self.solve(e, a, xn)?;
            }
        }
        let d = self.rays[index];
        Some(Triangulated {
            point_m: Point3::new(
                self.centre[0] + s * d[0],
                self.centre[1] + s * d[1],
                self.centre[2] + s * d[2],
            ),
            range_m: s,
            depth_m: s * self.depth_per_m[index],
        })
    }

    /// `s` for plane `x_n` along projector axis `a` (0 = x, 1 = y).
    #[inline]
    fn solve(&self, e: [f32; 3], a: usize, xn: f32) -> Option<f32> {
        let den = e[a] - xn * e[2];
        let s = (xn * self.q[2] - self.q[a]) / den;
        // In front of the camera and of the projector.
        (s > 0.0 && s.is_finite() && self.q[2] + s * e[2] > 0.0).then_some(s)
    }

    /// Undistorted coordinate along axis `a` whose distorted value is `target`, given the
    /// other undistorted coordinate: 1-D Newton from `start`.
    fn undistort_along(&self, a: usize, target: f32, start: f32, other: f32) -> f32 {
        let dist = &self.projector.distortion;
        let eval = |t: f64| {
            let (x, y) = if a == 0 {
                (t, f64::from(other))
            } else {
                (f64::from(other), t)
            };
            let (dx, dy) = dist.distort(x, y);
            if a == 0 {
                dx
            } else {
                dy
            }
        };
        let mut t = f64::from(start);
        for _ in 0..8 {
            let h = 1e-7;
            let f = eval(t) - f64::from(target);
            let df = (eval(t + h) - eval(t - h)) / (2.0 * h);
            if df.abs() < 1e-12 {
                break;
            }
            t -= f / df;
            if f.abs() < 1e-12 {
                break;
            }
        }
        t as f32
    }

    /// `|d range / d coord_px|` at a solution: how far the point moves along the ray per
    /// projector pixel (metres per pixel). Times the phase-derived `sigma_px`, it is the
    /// predicted standard deviation of the point along the ray.
    #[inline]
    pub fn range_per_px(&self, index: usize, axis: ProjectorAxis, coord_px: f32) -> f32 {
        let k = &self.projector.intrinsics;
        let (a, f, c) = match axis {
            ProjectorAxis::Column => (0, k.fx as f32, k.cx as f32),
            ProjectorAxis::Row => (1, k.fy as f32, k.cy as f32),
        };
        let e = self.rays_proj[index];
        let xn = (coord_px - c) / f;
        let den = e[a] - xn * e[2];
        ((self.q[2] * e[a] - self.q[a] * e[2]) / (den * den) / f).abs()
    }

    /// Least-squares point of the camera ray and the projector ray through `(u, v)`:
    /// the midpoint of the shortest segment between them, and that segment's length
    /// (metres; a consistency measure). `None` for parallel rays or points behind.
    pub fn intersect_two_rays(&self, index: usize, u: f64, v: f64) -> Option<(Triangulated, f32)> {
        let proj_ray = self.projector.pixel_ray(u, v)?;
        let d = self.rays[index];
        let d = Vector3::new(f64::from(d[0]), f64::from(d[1]), f64::from(d[2]));
        let c = Vector3::new(
            f64::from(self.centre[0]),
            f64::from(self.centre[1]),
            f64::from(self.centre[2]),
        );
        let (s, t, gap) = closest_points(&c, &d, &proj_ray.origin_m.coords, &proj_ray.direction)?;
        if s <= 0.0 || t <= 0.0 {
            return None;
        }
        let p = (c + d * s + proj_ray.origin_m.coords + proj_ray.direction * t) * 0.5;
        let range = (p - c).norm();
        Some((
            Triangulated {
                point_m: Point3::new(p.x as f32, p.y as f32, p.z as f32),
                range_m: range as f32,
                depth_m: (range as f32) * self.depth_per_m[index],
            },
            gap as f32,
        ))
    }
}

/// Parameters `(s, t)` of the closest points of lines `a + s da` and `b + t db`, and their
/// distance; `None` when the lines are (nearly) parallel.
pub fn closest_points(
    a: &Vector3<f64>,
    da: &Vector3<f64>,
    b: &Vector3<f64>,
    db: &Vector3<f64>,
) -> Option<(f64, f64, f64)> {
    let w = a - b;
    let (aa, ab, bb) = (da.dot(da), da.dot(db), db.dot(db));
    let (aw, bw) = (da.dot(&w), db.dot(&w));
    let den = aa * bb - ab * ab;
    if den.abs() < 1e-12 * aa * bb {
        return None;
    }
    let s = (ab * bw - bb * aw) / den;
    let t = (aa * bw - ab * aw) / den;
    let gap = ((a + da * s) - (b + db * t)).norm();
    Some((s, t, gap))
}

fn to_f32(v: &Vector3<f64>) -> [f32; 3] {
    [v.x as f32, v.y as f32, v.z as f32]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calibration::{Distortion, PinholeModel, Pose};
    use nalgebra::Rotation3;

    fn rig(distorted: bool) -> (CameraModel, ProjectorModel) {
        let mut camera = PinholeModel::ideal(64, 48, 80.0);
        camera.distortion = Distortion {
            k1: -0.1,
            k2: 0.02,
            p1: 0.001,
            p2: 0.0,
            k3: 0.0,
        };
        let mut projector = PinholeModel::ideal(200, 150, 220.0);
        let centre = Vector3::new(0.15, 0.02, 0.0);
        let rotation = *Rotation3::from_euler_angles(0.02, -0.3, 0.01).matrix();
        projector.pose = Pose {
            rotation,
            translation_m: -(rotation * centre),
        };
        if distorted {
            projector.distortion = Distortion {
                k1: 0.05,
                k2: -0.01,
                p1: 0.0005,
                p2: -0.0003,
                k3: 0.0,
            };
        }
        (camera, projector)
    }

    #[test]
    fn recovers_points_from_their_projector_coordinates() {
        for distorted in [false, true] {
            let (camera, projector) = rig(distorted);
            let tri = Triangulator::new(&camera, &projector);
            for &(x, y, depth) in &[(10usize, 10usize, 0.5f64), (32, 24, 0.6), (60, 40, 0.45)] {
                let ray = camera.pixel_ray(x as f64, y as f64).unwrap();
                let truth = ray.origin_m + ray.direction * depth;
                let px = projector.project(&truth).unwrap();
                let i = y * 64 + x;
                let a = tri
                    .intersect(i, ProjectorAxis::Column, px.x as f32)
                    .unwrap();
                let b = tri.intersect(i, ProjectorAxis::Row, px.y as f32).unwrap();
                let (c, gap) = tri.intersect_two_rays(i, px.x, px.y).unwrap();
                for (name, got) in [("column", a), ("row", b), ("two rays", c)] {
                    let err = (got.point_m.cast::<f64>() - truth).norm();
                    assert!(err < 2e-5, "{name} distorted={distorted}: {err} m");
                }
                assert!(gap < 1e-6);
                assert!((f64::from(a.range_m) - depth).abs() < 2e-5);
            }
        }
    }

    #[test]
    fn range_derivative_matches_finite_difference() {
        let (camera, projector) = rig(false);
        let tri = Triangulator::new(&camera, &projector);
        let i = 20 * 64 + 30;
        let ray = camera.pixel_ray(30.0, 20.0).unwrap();
        let u = projector
            .project(&(ray.origin_m + ray.direction * 0.5))
            .unwrap()
            .x as f32;
        let a = tri.intersect(i, ProjectorAxis::Column, u - 0.5).unwrap();
        let b = tri.intersect(i, ProjectorAxis::Column, u + 0.5).unwrap();
        let fd = (b.range_m - a.range_m).abs();
        let an = tri.range_per_px(i, ProjectorAxis::Column, u);
        assert!((fd - an).abs() < 0.01 * an, "{fd} vs {an}");
    }

    #[test]
    fn parallel_lines_have_no_closest_point() {
        let a = Vector3::new(0.0, 0.0, 0.0);
        let d = Vector3::new(0.0, 0.0, 1.0);
        assert!(closest_points(&a, &d, &Vector3::new(1.0, 0.0, 0.0), &d).is_none());
    }
}
