//! Compaction of the organised per-pixel result into a point cloud.

use rayon::prelude::*;

use super::PixelResult;
use crate::point_cloud::{grid_normal, PointCloud};
use crate::raster::Raster;
use crate::unwrap::PixelStatus;

/// Compacts valid pixels into a cloud (row-major order): rows are counted, then
/// filled in parallel into exactly sized arrays (normals straight from the grid).
pub(super) fn compact(
    pixels: &Raster<PixelResult>,
    with_normals: bool,
    view: [f32; 3],
) -> PointCloud {
    let (w, h) = pixels.size();
    let valid = |p: &PixelResult| p.status == PixelStatus::Valid;
    let counts: Vec<usize> = pixels
        .data
        .par_chunks(w.max(1))
        .map(|row| row.iter().filter(|p| valid(p)).count())
        .collect();
    let total: usize = counts.iter().sum();
    let mut points = vec![[0.0f32; 3]; total];
    let mut normals = vec![[0.0f32; 3]; if with_normals { total } else { 0 }];
    let mut colours = vec![[0u8; 3]; total];
    let mut quality = vec![0.0f32; total];
    // Split the outputs into one slice per row.
    let mut parts = Vec::with_capacity(h);
    let (mut p, mut n, mut c, mut q) = (
        points.as_mut_slice(),
        normals.as_mut_slice(),
        colours.as_mut_slice(),
        quality.as_mut_slice(),
    );
    for (y, &count) in counts.iter().enumerate() {
        let (p0, p1) = p.split_at_mut(count);
        let (n0, n1) = n.split_at_mut(if with_normals { count } else { 0 });
        let (c0, c1) = c.split_at_mut(count);
        let (q0, q1) = q.split_at_mut(count);
        parts.push((y, p0, n0, c0, q0));
        (p, n, c, q) = (p1, n1, c1, q1);
    }
    let get = |x: usize, y: usize| pixels.data[y * w + x].point_m;
    parts.into_par_iter().for_each(|(y, p, n, c, q)| {
        let row = &pixels.data[y * w..(y + 1) * w];
        let mut k = 0;
        for (x, px) in row.iter().enumerate() {
            if !valid(px) {
                continue;
            }
            p[k] = px.point_m;
            if !n.is_empty() {
                let normal = grid_normal(&get, w, h, x, y, view);
                n[k] = if normal[0].is_finite() {
                    normal
                } else {
                    [0.0; 3]
                };
            }
            c[k] = [(px.background.clamp(0.0, 1.0) * 255.0 + 0.5) as u8; 3];
            q[k] = px.sigma_m;
            k += 1;
        }
    });
    PointCloud {
        points_m: points,
        normals: with_normals.then_some(normals),
        colours: Some(colours),
        quality_m: Some(quality),
    }
}
