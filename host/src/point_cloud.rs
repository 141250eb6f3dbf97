//! Point clouds: points with optional normals, colour and per-point quality.

use crate::raster::Raster;

/// A point cloud in metres.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PointCloud {
    /// Positions, metres.
    pub points_m: Vec<[f32; 3]>,
    /// Unit normals, one per point.
    pub normals: Option<Vec<[f32; 3]>>,
    /// Colour (grey texture repeated, or RGB), one per point.
    pub colours: Option<Vec<[u8; 3]>>,
    /// Predicted standard deviation of each point along its camera ray, metres.
    pub quality_m: Option<Vec<f32>>,
}

impl PointCloud {
    /// Number of points.
    pub fn len(&self) -> usize {
        self.points_m.len()
    }

    /// Whether the cloud has no points.
    pub fn is_empty(&self) -> bool {
        self.points_m.is_empty()
    }
}

/// Normals of an organised cloud (one point per camera pixel, NaN where none) from
/// central differences on the pixel grid, turned to face the camera at `viewpoint`.
/// NaN where a neighbour is missing.
pub fn grid_normals(points: &Raster<[f32; 3]>, viewpoint: [f32; 3]) -> Raster<[f32; 3]> {
    use rayon::prelude::*;
    let (w, h) = points.size();
    let get = |x: usize, y: usize| points.data[y * w + x];
    let mut out = Raster::filled(w, h, [f32::NAN; 3]);
    out.data
        .par_chunks_mut(w.max(1))
        .enumerate()
        .for_each(|(y, row)| {
            for (x, n) in row.iter_mut().enumerate() {
                *n = grid_normal(&get, w, h, x, y, viewpoint);
            }
        });
    out
}

/// The normal at one pixel of an organised cloud given by `get(x, y)` (see
/// [`grid_normals`]).
#[inline]
pub fn grid_normal(
    get: &impl Fn(usize, usize) -> [f32; 3],
    w: usize,
    h: usize,
    x: usize,
    y: usize,
    viewpoint: [f32; 3],
) -> [f32; 3] {
    let nan = [f32::NAN; 3];
    let ok = |p: &[f32; 3]| p[0].is_finite();
    if x == 0 || y == 0 || x + 1 >= w || y + 1 >= h || !ok(&get(x, y)) {
        return nan;
    }
    let (l, r, u, d) = (get(x - 1, y), get(x + 1, y), get(x, y - 1), get(x, y + 1));
    if !(ok(&l) && ok(&r) && ok(&u) && ok(&d)) {
        return nan;
    }
    neighbour_normal([l, r, u, d], get(x, y), viewpoint)
}

/// The unit normal at point `p` from its left, right, up and down neighbours
/// (`(r - l) x (d - u)`), turned to face `viewpoint`; NaN when the cross product is zero.
/// Any NaN neighbour gives NaN.
#[inline]
pub fn neighbour_normal([l, r, u, d]: [[f32; 3]; 4], p: [f32; 3], viewpoint: [f32; 3]) -> [f32; 3] {
    let a = [r[0] - l[0], r[1] - l[1], r[2] - l[2]];
    let b = [d[0] - u[0], d[1] - u[1], d[2] - u[2]];
    let mut n = [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ];
    let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
    if len == 0.0 {
        return [f32::NAN; 3];
    }
    let to_view = [
        viewpoint[0] - p[0],
        viewpoint[1] - p[1],
        viewpoint[2] - p[2],
    ];
    let facing = n[0] * to_view[0] + n[1] * to_view[1] + n[2] * to_view[2];
    let scale = if facing < 0.0 { -1.0 / len } else { 1.0 / len };
    n.iter_mut().for_each(|c| *c *= scale);
    n
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn plane_normals_face_the_camera() {
        // Plane z = 1 + 0.5 x seen from the origin.
        let pts = Raster::from_fn(5, 5, |x, y| {
            let (px, py) = (x as f32 * 0.01, y as f32 * 0.01);
            [px, py, 1.0 + 0.5 * px]
        });
        let n = grid_normals(&pts, [0.0; 3]);
        let c = n.at(2, 2);
        let want = [0.5f32, 0.0, -1.0];
        let len = (0.25f32 + 1.0).sqrt();
        for k in 0..3 {
            assert!((c[k] - want[k] / len).abs() < 1e-5, "{c:?}");
        }
        assert!(n.at(0, 0)[0].is_nan());
    }
}
