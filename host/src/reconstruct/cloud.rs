//! Compaction of the organised per-pixel result into a point cloud.

use rayon::prelude::*;

use super::PixelResult;
use crate::point_cloud::{neighbour_normal, PointCloud};
use crate::raster::Raster;
use crate::unwrap::PixelStatus;

/// Compacts valid pixels into a cloud (row-major order). `valid_per_row` (counted by the
/// pass that wrote the rows) sizes the arrays exactly; rows are then filled in parallel,
/// normals straight from the grid (the same as [`crate::point_cloud::grid_normal`], zero
/// where it has none).
/// The arrays of `cloud` are reused (resized) where they are large enough.
pub(super) fn compact_into(
    pixels: &Raster<PixelResult>,
    valid_per_row: &[usize],
    with_normals: bool,
    view: [f32; 3],
    cloud: &mut PointCloud,
) {
    let (w, h) = pixels.size();
    assert_eq!(valid_per_row.len(), h, "one count per row");
    let total: usize = valid_per_row.iter().sum();
    let mut points = sized(std::mem::take(&mut cloud.points_m), total);
    let normals = cloud.normals.take().unwrap_or_default();
    let mut normals = sized(normals, if with_normals { total } else { 0 });
    let mut colours = sized(cloud.colours.take().unwrap_or_default(), total);
    let mut quality = sized(cloud.quality_m.take().unwrap_or_default(), total);
    // Split the outputs into one slice per row.
    let mut parts = Vec::with_capacity(h);
    let (mut p, mut n, mut c, mut q) = (
        points.as_mut_slice(),
        normals.as_mut_slice(),
        colours.as_mut_slice(),
        quality.as_mut_slice(),
    );
    for (y, &count) in valid_per_row.iter().enumerate() {
        let (p0, p1) = p.split_at_mut(count);
        let (n0, n1) = n.split_at_mut(if with_normals { count } else { 0 });
        let (c0, c1) = c.split_at_mut(count);
        let (q0, q1) = q.split_at_mut(count);
        parts.push((y, p0, n0, c0, q0));
        (p, n, c, q) = (p1, n1, c1, q1);
    }
    let row = |y: usize| &pixels.data[y * w..(y + 1) * w];
    parts.into_par_iter().for_each(|(y, p, n, c, q)| {
        let here = row(y);
        // Normals need both neighbour rows; border rows and columns get none.
        let around = (with_normals && y > 0 && y + 1 < h).then(|| (row(y - 1), row(y + 1)));
        let mut k = 0;
        for (x, px) in here.iter().enumerate() {
            if px.status != PixelStatus::Valid {
                continue;
            }
            p[k] = px.point_m;
            if with_normals {
                n[k] = match around {
                    Some((up, down)) if x > 0 && x + 1 < w => {
                        let neighbours = [
                            here[x - 1].point_m,
                            here[x + 1].point_m,
                            up[x].point_m,
                            down[x].point_m,
                        ];
                        let normal = neighbour_normal(neighbours, px.point_m, view);
                        if normal[0].is_finite() {
                            normal
                        } else {
                            [0.0; 3]
                        }
                    }
                    _ => [0.0; 3],
                };
            }
            c[k] = [(px.background.clamp(0.0, 1.0) * 255.0 + 0.5) as u8; 3];
            q[k] = px.sigma_m;
            k += 1;
        }
        debug_assert_eq!(k, p.len(), "row {y}: count differs from the row pass");
    });
    *cloud = PointCloud {
        points_m: points,
        normals: with_normals.then_some(normals),
        colours: Some(colours),
        quality_m: Some(quality),
    };
}

/// `v` with `len` elements (all overwritten by the caller): resized in place when its
/// allocation is large enough, else a fresh one on huge pages.
fn sized<T: Clone + Default>(mut v: Vec<T>, len: usize) -> Vec<T> {
    if v.capacity() >= len {
        v.resize(len, T::default());
        v
    } else {
        drop(v);
        crate::huge_pages::filled_vec(len, T::default())
    }
}
