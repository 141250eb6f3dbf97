//! The whole-row passes the pipeline runs: one phase direction (column planes, with
//! Newton steps for a distorted projector) and two directions (closest points of the
//! camera and projector rays), each branch free so that it vectorises.

use super::{
    metres_per_column, point_on_ray, ColumnHits, Triangulator, DISTORTED_NEWTON_STEPS,
    TWO_RAY_UNDISTORT_STEPS,
};

impl Triangulator {
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
}
