//! One pixel at a time, in plain arithmetic: the reference the row passes are held to,
//! and the path of callers with single correspondences.

use nalgebra::{Point3, Vector3};

use super::{ProjectorAxis, Triangulated, Triangulator};

impl Triangulator {
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
