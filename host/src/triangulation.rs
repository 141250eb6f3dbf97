//! Triangulation: camera rays against projector planes (one phase direction) or
//! projector rays (both directions), with per-point predicted noise.
//!
//! [`Triangulator::new`] does the expensive part once per camera: it undistorts every
//! camera pixel (stored as normalised coordinates, 8 bytes a pixel, so the per-frame pass
//! reads little). Per frame, a projector column `u` then costs a handful of multiply-adds
//! ([`Triangulator::intersect_columns`] does a whole row, vectorised, in the camera frame):
//!
//! ```text
//! camera ray  X(s) = C + s d                    (world, |d| = 1)
//! projector   X_p(s) = q + s e,  q = R_p C + t_p, e = R_p d
//! column u -> x_n = (u - cx)/fx (undistorted);  plane X_p.x = x_n X_p.z
//! s = (x_n q.z - q.x) / (e.x - x_n e.z)
//! ```
//!
//! With projector distortion the column is no plane. The row path
//! ([`Triangulator::intersect_columns`]) starts from a first-order inverse of the distortion
//! and takes two Newton steps on the depth along the camera ray (analytic derivative, vectorised);
//! the single-pixel [`Triangulator::intersect`] refines by fixed-point iteration on the
//! undistorted `x_n` given the current `y_n`. Two directions (`u`, `v`) use the least-squares closest point of the
//! camera ray and the projector ray.

use nalgebra::{Matrix3, Point3, Vector3};
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

/// Newton steps on the depth in [`Triangulator::intersect_columns`] for a distorted
/// projector, after a first-order start (the convergence is quadratic; the test
/// `distorted_rows_match_an_f64_reference` shows two reach the f32 limit for k1 = 0.1).
const DISTORTED_NEWTON_STEPS: usize = 2;

/// Newton steps undistorting a projector pixel in [`Triangulator::intersect_two_rays_row`],
/// after a first-order start (the test `two_ray_rows_match_the_f64_path` covers k1 = 0.1).
const TWO_RAY_UNDISTORT_STEPS: usize = 3;

/// Precomputed per-pixel geometry of one camera-projector pair.
#[derive(Clone, Debug)]
pub struct Triangulator {
    camera: CameraModel,
    projector: ProjectorModel,
    width: usize,
    height: usize,
    /// Undistorted normalised camera coordinates `(x, y)` per pixel (the ray is
    /// `m = (x, y, 1)` in the camera frame); NaN where undistortion failed. 8 bytes per
    /// pixel: the per-frame passes read this, so it is kept small.
    normalised: Vec<[f32; 2]>,
    /// Camera frame -> world rotation (`R_c^T`), rows.
    cam_to_world: [[f32; 3]; 3],
    /// Camera frame -> projector frame rotation (`R_p R_c^T`), rows.
    cam_to_proj: [[f32; 3]; 3],
    centre: [f32; 3],
    q: [f32; 3],
    /// Projector frame -> world rotation (`R_p^T`), rows.
    proj_to_world: [[f32; 3]; 3],
    /// Projector centre, world.
    proj_centre: [f32; 3],
    projector_distorted: bool,
}

/// Per-pixel outputs of [`Triangulator::intersect_columns`], one entry per pixel of a run
/// (NaN where there is no point). Reused between runs to avoid allocation.
#[derive(Clone, Debug, Default)]
pub struct ColumnHits {
    /// World x, y, z, metres.
    pub point_m: [Vec<f32>; 3],
    /// Depth along the camera axis, metres.
    pub depth_m: Vec<f32>,
    /// `|d range / d u|`, metres per projector pixel (see [`Triangulator::range_per_px`]).
    pub range_per_px: Vec<f32>,
    /// Scratch of [`Triangulator::intersect_two_rays_row`]: undistorted normalised
    /// projector coordinates.
    projector_xy: [Vec<f32>; 2],
}

impl ColumnHits {
    /// Sizes every output for a run of `len` pixels.
    pub fn resize(&mut self, len: usize) {
        for v in self
            .point_m
            .iter_mut()
            .chain([&mut self.depth_m, &mut self.range_per_px])
        {
            v.resize(len, f32::NAN);
        }
    }
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
    /// Undistorts every camera pixel once (parallel; the costly step).
    pub fn new(camera: &CameraModel, projector: &ProjectorModel) -> Self {
        let (width, height) = (camera.width_px as usize, camera.height_px as usize);
        let centre = camera.centre_m();
        let q = projector.pose.apply(&centre);
        let normalised: Vec<[f32; 2]> = (0..width * height)
            .into_par_iter()
            .map(|i| {
                let (u, v) = ((i % width) as f64, (i / width) as f64);
                match camera.pixel_to_normalised(u, v) {
                    Some((x, y)) => [x as f32, y as f32],
                    None => [f32::NAN; 2],
                }
            })
            .collect();
        let rows = |m: &Matrix3<f64>| {
            let mut r = [[0.0f32; 3]; 3];
            for (i, row) in r.iter_mut().enumerate() {
                for (j, v) in row.iter_mut().enumerate() {
                    *v = m[(i, j)] as f32;
                }
            }
            r
        };
        let cam_to_world = camera.pose.rotation.transpose();
        Self {
            camera: *camera,
            projector: *projector,
            width,
            height,
            normalised,
            cam_to_world: rows(&cam_to_world),
            cam_to_proj: rows(&(projector.pose.rotation * cam_to_world)),
            centre: to_f32(&centre.coords),
            q: to_f32(&q.coords),
            proj_to_world: rows(&projector.pose.rotation.transpose()),
            proj_centre: to_f32(&projector.centre_m().coords),
            projector_distorted: !projector.distortion.is_zero(),
        }
    }

    /// Pixel `index`'s unit world ray `d`, the same ray in the projector frame `e`, and
    /// the camera depth per metre along it (`1 / |m|`).
    #[inline]
    fn ray(&self, index: usize) -> ([f32; 3], [f32; 3], f32) {
        let [x, y] = self.normalised[index];
        let inv_norm = 1.0 / (x * x + y * y + 1.0).sqrt();
        let rotate = |r: &[[f32; 3]; 3]| {
            let mut out = [0.0f32; 3];
            for (o, row) in out.iter_mut().zip(r) {
                *o = (row[0] * x + row[1] * y + row[2]) * inv_norm;
            }
            out
        };
        (
            rotate(&self.cam_to_world),
            rotate(&self.cam_to_proj),
            inv_norm,
        )
    }

    /// Intersects a run of pixels (`first_index ..`, one per entry of `column_px`) with
    /// the projector column planes `column_px` (NaN gives no point); fills `out` with the
    /// results of [`Triangulator::intersect`] and [`Triangulator::range_per_px`].
    ///
    /// For an undistorted projector this is the closed form in the camera frame, branch
    /// free so that it vectorises: with `m = (x, y, 1)`, `a = (R_pc m).x`,
    /// `b = (R_pc m).z` and `x_n = (u - cx) / fx`, the depth is
    /// `Z = (x_n q.z - q.x) / (a - x_n b)` and the point `C + Z R_c^T m`. A distorted
    /// projector refines that depth by Newton steps, still vectorised (see
    /// `intersect_columns_distorted`); the results agree with [`Triangulator::intersect`].
    ///
    /// # Panics
    /// If the run extends past the last camera pixel (a caller bug, not bad data).
    #[inline(always)]
    pub fn intersect_columns(&self, first_index: usize, column_px: &[f32], out: &mut ColumnHits) {
        let len = column_px.len();
        out.resize(len);
        let rays = &self.normalised[first_index..first_index + len];
        if self.projector_distorted {
            self.intersect_columns_distorted(rays, column_px, out);
            return;
        }
        let k = &self.projector.intrinsics;
        let (inv_fx, cx) = ((1.0 / k.fx) as f32, k.cx as f32);
        let (rp, rw, c, q) = (&self.cam_to_proj, &self.cam_to_world, self.centre, self.q);
        let [px, py, pz] = &mut out.point_m;
        let (px, py, pz) = (&mut px[..len], &mut py[..len], &mut pz[..len]);
        let (depth, rpp) = (&mut out.depth_m[..len], &mut out.range_per_px[..len]);
        for i in 0..len {
            let [x, y] = rays[i];
            let a = rp[0][0] * x + rp[0][1] * y + rp[0][2];
            let b = rp[2][0] * x + rp[2][1] * y + rp[2][2];
            let xn = (column_px[i] - cx) * inv_fx;
            let den = a - xn * b;
            let z = (xn * q[2] - q[0]) / den;
            // In front of the camera and of the projector (NaN fails both).
            let ok = z > 0.0 && z < f32::INFINITY && q[2] + z * b > 0.0;
            let z = if ok { z } else { f32::NAN };
            [px[i], py[i], pz[i]] = point_on_ray(c, rw, x, y, z);
            depth[i] = z;
            rpp[i] = if ok {
                metres_per_column(q, (x * x + y * y + 1.0).sqrt(), a, b, den, inv_fx)
            } else {
                f32::NAN
            };
        }
    }

    /// [`Triangulator::intersect_columns`] for a distorted projector, still one branch-free
    /// loop over the run (struct-of-arrays, f32) so that it vectorises.
    ///
    /// Start from the closed-form depth `Z0` of the undistorted plane through the target
    /// `t = (u - cx) / fx`, move to the plane of the first-order inverse distortion
    /// (`x_n = t - dx(t, y_n(Z0))`), then take [`DISTORTED_NEWTON_STEPS`] Newton steps on the depth
    /// `Z` along the camera ray for `F(Z) = distort_x(x_n(Z), y_n(Z)) - t`, where
    /// `(x_n, y_n)` is the projection of `C + Z R_c^T m` (a projective function of `Z`:
    /// `x_n = (q.x + Z g.x) / (q.z + Z g.z)` with `g = R_pc m`), with the analytic
    /// derivative by the chain rule. Each step needs one reciprocal and ~40 multiply-adds.
    /// A point is kept only when every iterate lies in front of both devices and the last
    /// step was small (the iteration converged).
    #[inline(always)]
    fn intersect_columns_distorted(
        &self,
        rays: &[[f32; 2]],
        column_px: &[f32],
        out: &mut ColumnHits,
    ) {
        let len = column_px.len();
        // Same length as `column_px`, so the loop has no bounds checks and vectorises.
        let rays = &rays[..len];
        let k = &self.projector.intrinsics;
        let (inv_fx, cx) = ((1.0 / k.fx) as f32, k.cx as f32);
        let dist = &self.projector.distortion;
        let (k1, k2, k3) = (dist.k1 as f32, dist.k2 as f32, dist.k3 as f32);
        let (p1, p2) = (dist.p1 as f32, dist.p2 as f32);
        let (rp, rw, c, q) = (&self.cam_to_proj, &self.cam_to_world, self.centre, self.q);
        let [px, py, pz] = &mut out.point_m;
        let (px, py, pz) = (&mut px[..len], &mut py[..len], &mut pz[..len]);
        let (depth, rpp) = (&mut out.depth_m[..len], &mut out.range_per_px[..len]);
        for i in 0..len {
            let [x, y] = rays[i];
            let gx = rp[0][0] * x + rp[0][1] * y + rp[0][2];
            let gy = rp[1][0] * x + rp[1][1] * y + rp[1][2];
            let gz = rp[2][0] * x + rp[2][1] * y + rp[2][2];
            let t = (column_px[i] - cx) * inv_fx;
            let den = gx - t * gz;
            let z0 = (t * q[2] - q[0]) / den;
            // Non-short-circuit `&` throughout: no branches, so the loop vectorises.
            let mut ok = (z0 > 0.0) & (z0 < f32::INFINITY) & (q[2] + z0 * gz > 0.0);
            // Start: the plane of the first-order inverse distortion `x_n = t - dx(t, y_n)`
            // at that depth's `y_n` (error ~ the square of the distortion; saves steps).
            let yn0 = (q[1] + z0 * gy) / (q[2] + z0 * gz);
            let r2 = t * t + yn0 * yn0;
            let shift =
                t * r2 * (k1 + r2 * (k2 + r2 * k3)) + 2.0 * p1 * t * yn0 + p2 * (r2 + 2.0 * t * t);
            let xs = t - shift;
            let mut z = (xs * q[2] - q[0]) / (gx - xs * gz);
            ok &= (z > 0.0) & (z < f32::INFINITY) & (q[2] + z * gz > 0.0);
            let mut step = 0.0f32;
            for _ in 0..DISTORTED_NEWTON_STEPS {
                let w = 1.0 / (q[2] + z * gz);
                let xn = (q[0] + z * gx) * w;
                let yn = (q[1] + z * gy) * w;
                let r2 = xn * xn + yn * yn;
                let radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
                let d_radial = k1 + r2 * (2.0 * k2 + 3.0 * k3 * r2);
                let f = xn * radial + 2.0 * p1 * xn * yn + p2 * (r2 + 2.0 * xn * xn) - t;
                // d distort_x / d x_n and / d y_n.
                let fxn = radial + 2.0 * xn * xn * d_radial + 2.0 * p1 * yn + 6.0 * p2 * xn;
                let fyn = 2.0 * xn * yn * d_radial + 2.0 * p1 * xn + 2.0 * p2 * yn;
                // d x_n / dZ and d y_n / dZ of the projective map.
                let slope = (fxn * (gx - xn * gz) + fyn * (gy - yn * gz)) * w;
                step = f / slope;
                z -= step;
                ok &= (z > 0.0) & (z < f32::INFINITY) & (q[2] + z * gz > 0.0);
            }
            // Converged: the error before the last step was about that step, and Newton
            // squares it (relative error ~ step^2 / Z^2 <= ~1e-6 here, the f32 noise in
            // practice); a diverging iteration fails.
            ok &= step.abs() <= 1e-3 * z;
            let z = if ok { z } else { f32::NAN };
            [px[i], py[i], pz[i]] = point_on_ray(c, rw, x, y, z);
            depth[i] = z;
            // As [`Triangulator::range_per_px`]: the undistorted plane's derivative at `t`.
            rpp[i] = if ok {
                metres_per_column(q, (x * x + y * y + 1.0).sqrt(), gx, gz, den, inv_fx)
            } else {
                f32::NAN
            };
        }
    }

    /// [`Triangulator::intersect_two_rays`] for a run of pixels (`first_index ..`, one
    /// per entry of `u_px`) with projector pixel `(u_px[i], v_px[i])` each (NaN gives no
    /// point): two branch-free f32 loops, so that they vectorise. The projector pixel is
    /// undistorted from a first-order start by [`TWO_RAY_UNDISTORT_STEPS`] Newton steps on
    /// the 2x2 Jacobian (exact no-ops without distortion) and refused unless that
    /// converged; the point is the midpoint of the shortest segment between the camera
    /// and projector rays. `out.range_per_px` is the column figure of
    /// [`Triangulator::range_per_px`] (an upper bound: the two-ray solution also uses the
    /// row).
    ///
    /// # Panics
    /// If the run extends past the last camera pixel or `v_px` is shorter than `u_px`.
    #[inline(always)]
    pub fn intersect_two_rays_row(
        &self,
        first_index: usize,
        u_px: &[f32],
        v_px: &[f32],
        out: &mut ColumnHits,
    ) {
        let len = u_px.len();
        out.resize(len);
        let rays = &self.normalised[first_index..first_index + len];
        let v_px = &v_px[..len];
        let k = &self.projector.intrinsics;
        let (inv_fx, inv_fy) = ((1.0 / k.fx) as f32, (1.0 / k.fy) as f32);
        let (cx, cy) = (k.cx as f32, k.cy as f32);
        let dist = &self.projector.distortion;
        let (k1, k2, k3) = (dist.k1 as f32, dist.k2 as f32, dist.k3 as f32);
        let (p1, p2) = (dist.p1 as f32, dist.p2 as f32);
        let distort = |x: f32, y: f32| {
            let r2 = x * x + y * y;
            let radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
            (
                x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x),
                y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y,
            )
        };
        let (rw, rp, rq) = (&self.cam_to_world, &self.cam_to_proj, &self.proj_to_world);
        let (c, pc, q) = (self.centre, self.proj_centre, self.q);
        // Projector centre minus camera centre: the same for every pixel.
        let (gx, gy, gz) = (pc[0] - c[0], pc[1] - c[1], pc[2] - c[2]);
        let [px, py, pz] = &mut out.point_m;
        let (px, py, pz) = (&mut px[..len], &mut py[..len], &mut pz[..len]);
        let (depth, rpp) = (&mut out.depth_m[..len], &mut out.range_per_px[..len]);
        // Two loops of plain scalars (no arrays, no branches), each small enough that it
        // vectorises: as one loop the AVX2 build stayed scalar (with spills) and made the
        // whole two-direction pass ~1.5x slower than the SSE2 build.
        // First the projector pixels -> undistorted normalised coordinates.
        let [xs, ys] = &mut out.projector_xy;
        xs.resize(len, 0.0);
        ys.resize(len, 0.0);
        let (xs, ys) = (&mut xs[..len], &mut ys[..len]);
        for i in 0..len {
            let (xd, yd) = ((u_px[i] - cx) * inv_fx, (v_px[i] - cy) * inv_fy);
            let (fx, fy) = distort(xd, yd);
            let (mut xn, mut yn) = (xd - (fx - xd), yd - (fy - yd));
            for _ in 0..TWO_RAY_UNDISTORT_STEPS {
                let r2 = xn * xn + yn * yn;
                let radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
                let d_radial = k1 + r2 * (2.0 * k2 + 3.0 * k3 * r2);
                let (fx, fy) = distort(xn, yn);
                let (ex, ey) = (fx - xd, fy - yd);
                let jxx = radial + 2.0 * xn * xn * d_radial + 2.0 * p1 * yn + 6.0 * p2 * xn;
                let jxy = 2.0 * xn * yn * d_radial + 2.0 * p1 * xn + 2.0 * p2 * yn;
                let jyy = radial + 2.0 * yn * yn * d_radial + 6.0 * p1 * yn + 2.0 * p2 * xn;
                let inv_det = 1.0 / (jxx * jyy - jxy * jxy);
                xn -= (jyy * ex - jxy * ey) * inv_det;
                yn -= (jxx * ey - jxy * ex) * inv_det;
            }
            let (fx, fy) = distort(xn, yn);
            // Converged to well under a thousandth of a projector pixel, else NaN (and
            // NaN stays NaN).
            let ok = ((fx - xd).abs() <= 1e-6) & ((fy - yd).abs() <= 1e-6);
            xs[i] = if ok { xn } else { f32::NAN };
            ys[i] = if ok { yn } else { f32::NAN };
        }
        // Then the rays and their closest points.
        for i in 0..len {
            let [x, y] = rays[i];
            let norm = (x * x + y * y + 1.0).sqrt();
            let inv_norm = 1.0 / norm;
            // Camera ray (world, unit).
            let dx = (rw[0][0] * x + rw[0][1] * y + rw[0][2]) * inv_norm;
            let dy = (rw[1][0] * x + rw[1][1] * y + rw[1][2]) * inv_norm;
            let dz = (rw[2][0] * x + rw[2][1] * y + rw[2][2]) * inv_norm;
            let (xn, yn) = (xs[i], ys[i]);
            let xd = (u_px[i] - cx) * inv_fx;
            // Projector ray (world, unit).
            let ex = rq[0][0] * xn + rq[0][1] * yn + rq[0][2];
            let ey = rq[1][0] * xn + rq[1][1] * yn + rq[1][2];
            let ez = rq[2][0] * xn + rq[2][1] * yn + rq[2][2];
            let inv_e = 1.0 / (ex * ex + ey * ey + ez * ez).sqrt();
            let (ex, ey, ez) = (ex * inv_e, ey * inv_e, ez * inv_e);
            // Closest points of C + s d and P + t e in the cross-product form: with the
            // rays ~10 degrees apart, `1 - (d.e)^2` would lose 5 of f32's 7 digits.
            let (nx, ny, nz) = (dy * ez - dz * ey, dz * ex - dx * ez, dx * ey - dy * ex);
            let den = nx * nx + ny * ny + nz * nz;
            // (g x e).n and (g x d).n.
            let ge = (gy * ez - gz * ey) * nx + (gz * ex - gx * ez) * ny + (gx * ey - gy * ex) * nz;
            let gd = (gy * dz - gz * dy) * nx + (gz * dx - gx * dz) * ny + (gx * dy - gy * dx) * nz;
            let inv_den = 1.0 / den;
            let (s, t) = (ge * inv_den, gd * inv_den);
            // Not (nearly) parallel, in front of both devices (NaN fails).
            let ok =
                (den > 1e-6) & (s > 0.0) & (t > 0.0) & (s < f32::INFINITY) & (t < f32::INFINITY);
            // Midpoint of the shortest segment, relative to the camera centre.
            let mx = 0.5 * (dx * s + gx + ex * t);
            let my = 0.5 * (dy * s + gy + ey * t);
            let mz = 0.5 * (dz * s + gz + ez * t);
            let range = (mx * mx + my * my + mz * mz).sqrt();
            px[i] = if ok { c[0] + mx } else { f32::NAN };
            py[i] = if ok { c[1] + my } else { f32::NAN };
            pz[i] = if ok { c[2] + mz } else { f32::NAN };
            depth[i] = if ok { range * inv_norm } else { f32::NAN };
            // As `range_per_px` for the column (plane through the distorted column).
            let a = rp[0][0] * x + rp[0][1] * y + rp[0][2];
            let b = rp[2][0] * x + rp[2][1] * y + rp[2][2];
            rpp[i] = if ok {
                metres_per_column(q, norm, a, b, a - xd * b, inv_fx)
            } else {
                f32::NAN
            };
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
        let (d, e, depth_per_m) = self.ray(index);
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
        Some(Triangulated {
            point_m: Point3::new(
                self.centre[0] + s * d[0],
                self.centre[1] + s * d[1],
                self.centre[2] + s * d[2],
            ),
            range_m: s,
            depth_m: s * depth_per_m,
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
        let (_, e, _) = self.ray(index);
        let xn = (coord_px - c) / f;
        let den = e[a] - xn * e[2];
        ((self.q[2] * e[a] - self.q[a] * e[2]) / (den * den) / f).abs()
    }

    /// Least-squares point of the camera ray and the projector ray through `(u, v)`:
    /// the midpoint of the shortest segment between them, and that segment's length
    /// (metres; a consistency measure). `None` for parallel rays or points behind.
    pub fn intersect_two_rays(&self, index: usize, u: f64, v: f64) -> Option<(Triangulated, f32)> {
        let proj_ray = self.projector.pixel_ray(u, v)?;
        let (d, _, depth_per_m) = self.ray(index);
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
                depth_m: (range as f32) * depth_per_m,
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

/// The point at depth `z` on camera ray `m = (x, y, 1)`: `C + z R_c^T m` (`rw` = `R_c^T`
/// rows), NaN for a NaN `z`. One pixel of the row loops; inlined so they vectorise.
#[inline(always)]
fn point_on_ray(c: [f32; 3], rw: &[[f32; 3]; 3], x: f32, y: f32, z: f32) -> [f32; 3] {
    // Written out, not `[0, 1, 2].map(..)`: the closure form stopped the loops vectorising.
    [
        c[0] + z * (rw[0][0] * x + rw[0][1] * y + rw[0][2]),
        c[1] + z * (rw[1][0] * x + rw[1][1] * y + rw[1][2]),
        c[2] + z * (rw[2][0] * x + rw[2][1] * y + rw[2][2]),
    ]
}

/// `|d range / d u|` (metres along camera ray `m` per projector column) at the column
/// plane `x_n`, with `norm = |m|`, `a`, `b` = `(R_pc m).x`, `(R_pc m).z` and
/// `den = a - x_n b`: `|m| dZ/du`, `dZ/dx_n = (q.z a - q.x b) / den^2`.
#[inline(always)]
fn metres_per_column(q: [f32; 3], norm: f32, a: f32, b: f32, den: f32, inv_fx: f32) -> f32 {
    norm * ((q[2] * a - q[0] * b) / (den * den) * inv_fx).abs()
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
    fn column_runs_match_the_pixel_path() {
        for distorted in [false, true] {
            let (camera, projector) = rig(distorted);
            let tri = Triangulator::new(&camera, &projector);
            let (w, h) = tri.size();
            let mut hits = ColumnHits::default();
            let mut checked = 0;
            for y in [0usize, 13, 47] {
                // Columns of points between 0.4 and 0.7 m, plus NaN and out-of-range ones.
                let u: Vec<f32> = (0..w)
                    .map(|x| {
                        let depth = 0.4 + 0.3 * ((x * 7 + y) % 11) as f64 / 10.0;
                        let ray = camera.pixel_ray(x as f64, y as f64).unwrap();
                        let px = projector.project(&(ray.origin_m + ray.direction * depth));
                        match (x % 9, px) {
                            (4, _) => f32::NAN,
                            (5, _) => 1e9,
                            (_, Some(px)) => px.x as f32,
                            (_, None) => f32::NAN,
                        }
                    })
                    .collect();
                tri.intersect_columns(y * w, &u, &mut hits);
                for (x, &ux) in u.iter().enumerate() {
                    let i = y * w + x;
                    let want = tri.intersect(i, ProjectorAxis::Column, ux);
                    let got = [hits.point_m[0][x], hits.point_m[1][x], hits.point_m[2][x]];
                    let Some(want) = want else {
                        assert!(got[0].is_nan() && hits.depth_m[x].is_nan(), "{x},{y}");
                        continue;
                    };
                    for a in 0..3 {
                        assert!(
                            (got[a] - want.point_m[a]).abs() < 2e-6,
                            "{x},{y}: {got:?} {want:?}"
                        );
                    }
                    assert!((hits.depth_m[x] - want.depth_m).abs() < 2e-6);
                    let r = tri.range_per_px(i, ProjectorAxis::Column, ux);
                    assert!(
                        (hits.range_per_px[x] - r).abs() < 1e-5 * r,
                        "{} vs {r}",
                        hits.range_per_px[x]
                    );
                    checked += 1;
                }
            }
            assert!(checked > 100, "{checked}");
            assert!(h > 47);
        }
    }

    /// The depth along pixel `index`'s stored ray whose projector column is `u_px`, in f64:
    /// Newton with a numerical derivative through [`PinholeModel::project`], from `start`,
    /// run to convergence (independent of the analytic f32 chain rule under test).
    fn reference_depth(tri: &Triangulator, index: usize, u_px: f64, start: f64) -> Option<f64> {
        let [x, y] = tri.normalised[index].map(f64::from);
        let m = tri.camera.pose.rotation.transpose() * Vector3::new(x, y, 1.0);
        let c = tri.camera.centre_m();
        let column = |z: f64| tri.projector.project(&(c + m * z)).map(|p| p.x - u_px);
        let mut z = start;
        for _ in 0..100 {
            let h = 1e-7 * z;
            let f = column(z)?;
            let slope = (column(z + h)? - column(z - h)?) / (2.0 * h);
            let step = f / slope;
            z -= step;
            if step.abs() < 1e-15 {
                break;
            }
        }
        (column(z)?.abs() < 1e-9).then_some(z)
    }

    /// A wide camera (sees the whole projector image at 0.3-1.2 m) and a projector with
    /// strong distortion (k1 = 0.1: ~3 % radial at the image corners).
    fn wide_rig() -> Triangulator {
        let (_, mut projector) = rig(false);
        let camera = PinholeModel::ideal(64, 48, 30.0);
        projector.distortion = Distortion {
            k1: 0.1,
            k2: -0.02,
            p1: 0.001,
            p2: -0.0005,
            k3: 0.0,
        };
        Triangulator::new(&camera, &projector)
    }

    /// The wide rig's camera pixel (row-major index) nearest the point `range_m` along
    /// projector pixel `(u, v)`'s ray, and that point; `None` off the camera image.
    fn camera_pixel_seeing(
        tri: &Triangulator,
        u: f64,
        v: f64,
        range_m: f64,
    ) -> Option<(usize, Point3<f64>)> {
        let ray = tri.projector.pixel_ray(u, v)?;
        let point = ray.origin_m + ray.direction * range_m;
        let pixel = tri.camera.project(&point)?;
        let (x, y) = (pixel.x.round(), pixel.y.round());
        let on_image = (0.0..64.0).contains(&x) && (0.0..48.0).contains(&y);
        on_image.then_some((y as usize * 64 + x as usize, point))
    }

    proptest::proptest! {
        /// Random points over the whole projector image (corners included) and depth range:
        /// the vectorised distorted row path agrees with the f64 solution within 2e-6 m.
        #[test]
        fn distorted_rows_match_an_f64_reference(
            u in 0.0f64..200.0,
            v in 0.0f64..150.0,
            range_m in 0.3f64..1.2,
        ) {
            let tri = wide_rig();
            let (camera, projector) = (tri.camera, tri.projector);
            let seen = camera_pixel_seeing(&tri, u, v, range_m);
            proptest::prop_assume!(seen.is_some());
            let (index, near) = seen.unwrap();
            // The point on this pixel's stored ray at about the same depth, and its column.
            let start = camera.pose.apply(&near).z;
            let [x, y] = tri.normalised[index].map(f64::from);
            let m = camera.pose.rotation.transpose() * Vector3::new(x, y, 1.0);
            let column = projector.project(&(camera.centre_m() + m * start)).unwrap().x as f32;
            let want_z = reference_depth(&tri, index, f64::from(column), start).unwrap();
            let want = camera.centre_m() + m * want_z;

            let mut hits = ColumnHits::default();
            tri.intersect_columns(index, &[column], &mut hits);
            let got = Vector3::new(hits.point_m[0][0], hits.point_m[1][0], hits.point_m[2][0]);
            let err = (got.cast::<f64>() - want.coords).norm();
            proptest::prop_assert!(err < 2e-6, "{u},{v} at {range_m} m: {err} m");
            proptest::prop_assert!((f64::from(hits.depth_m[0]) - want_z).abs() < 2e-6);
        }
    }

    proptest::proptest! {
        /// The vectorised two-ray row against the f64 per-pixel path, over the whole
        /// projector image of the strongly distorted wide rig: within 2e-6 m.
        #[test]
        fn two_ray_rows_match_the_f64_path(
            u in 0.0f64..200.0,
            v in 0.0f64..150.0,
            range_m in 0.3f64..1.2,
        ) {
            let tri = wide_rig();
            let seen = camera_pixel_seeing(&tri, u, v, range_m);
            proptest::prop_assume!(seen.is_some());
            let (index, _) = seen.unwrap();
            let (want, _) = tri.intersect_two_rays(index, u, v).unwrap();
            let mut hits = ColumnHits::default();
            tri.intersect_two_rays_row(index, &[u as f32], &[v as f32], &mut hits);
            let got = Vector3::new(hits.point_m[0][0], hits.point_m[1][0], hits.point_m[2][0]);
            let err = (got - want.point_m.coords).norm();
            proptest::prop_assert!(err < 2e-6, "{u},{v} at {range_m} m: {err} m");
            proptest::prop_assert!((hits.depth_m[0] - want.depth_m).abs() < 2e-6);
            let rpp = tri.range_per_px(index, ProjectorAxis::Column, u as f32);
            proptest::prop_assert!((hits.range_per_px[0] - rpp).abs() <= 1e-4 * rpp);
        }
    }

    #[test]
    fn two_ray_rows_refuse_what_has_no_point() {
        let tri = Triangulator::new(&rig(true).0, &rig(true).1);
        let mut hits = ColumnHits::default();
        // NaN coordinates, and a projector pixel whose ray points away from the camera's.
        tri.intersect_two_rays_row(
            0,
            &[f32::NAN, 100.0, -5.0e4],
            &[75.0, f32::NAN, 75.0],
            &mut hits,
        );
        for i in 0..3 {
            assert!(
                hits.point_m[0][i].is_nan() && hits.depth_m[i].is_nan(),
                "{i}: {hits:?}"
            );
            assert!(hits.range_per_px[i].is_nan());
        }
    }

    #[test]
    fn parallel_lines_have_no_closest_point() {
        let a = Vector3::new(0.0, 0.0, 0.0);
        let d = Vector3::new(0.0, 0.0, 1.0);
        assert!(closest_points(&a, &d, &Vector3::new(1.0, 0.0, 0.0), &d).is_none());
    }
}
