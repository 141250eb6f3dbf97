//! Compaction of the organised per-pixel maps into a point cloud, with grid normals.

use rayon::prelude::*;

use super::maps::{sized, PixelMaps};
use crate::point_cloud::PointCloud;
use crate::simd::{simd_run, Simd};
use crate::unwrap::PixelStatus;

/// Compacts valid pixels into a cloud (row-major order). `valid_per_row` (counted by the
/// pass that wrote the rows) sizes the arrays exactly; rows are then filled in parallel,
/// normals straight from the grid (the same as [`crate::point_cloud::grid_normal`], zero
/// where it has none), computed a whole row at a time so that they vectorise.
/// The arrays of `cloud` are reused (resized) where they are large enough.
pub(super) fn compact_into(
    maps: &PixelMaps,
    valid_per_row: &[usize],
    with_normals: bool,
    view: [f32; 3],
    simd: Simd,
    cloud: &mut PointCloud,
) {
    let (w, h) = maps.size();
    assert_eq!(valid_per_row.len(), h, "one count per row");
    let total: usize = valid_per_row.iter().sum();
    let mut points = std::mem::take(&mut cloud.points_m);
    sized(&mut points, total, [0.0; 3]);
    let mut normals = cloud.normals.take().unwrap_or_default();
    sized(&mut normals, if with_normals { total } else { 0 }, [0.0; 3]);
    let mut colours = cloud.colours.take().unwrap_or_default();
    sized(&mut colours, total, [0; 3]);
    let mut quality = cloud.quality_m.take().unwrap_or_default();
    sized(&mut quality, total, 0.0);
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
    let row = |map, y| row_of(map, w, y);
    let [mx, my, mz] = &maps.point_m;
    parts.into_par_iter().for_each_init(
        || [Vec::new(), Vec::new(), Vec::new()],
        |normal_row, (y, p, n, c, q)| {
            let here = [row(mx, y), row(my, y), row(mz, y)];
            // Normals need both neighbour rows; border rows and columns get none.
            if with_normals {
                for v in normal_row.iter_mut() {
                    v.clear();
                    v.resize(w, 0.0);
                }
                if y > 0 && y + 1 < h {
                    let up = [row(mx, y - 1), row(my, y - 1), row(mz, y - 1)];
                    let down = [row(mx, y + 1), row(my, y + 1), row(mz, y + 1)];
                    simd_run!(simd, grid_normal_row(here, up, down, view, normal_row));
                }
            }
            let (status, sigma) = (row_of(&maps.status, w, y), row(&maps.sigma_m, y));
            let background = row(&maps.background, y);
            let mut k = 0;
            for x in 0..w {
                if status[x] != PixelStatus::Valid {
                    continue;
                }
                p[k] = [here[0][x], here[1][x], here[2][x]];
                if with_normals {
                    n[k] = [normal_row[0][x], normal_row[1][x], normal_row[2][x]];
                }
                c[k] = [(background[x].clamp(0.0, 1.0) * 255.0 + 0.5) as u8; 3];
                q[k] = sigma[x];
                k += 1;
            }
            debug_assert_eq!(k, p.len(), "row {y}: count differs from the row pass");
        },
    );
    *cloud = PointCloud {
        points_m: points,
        normals: with_normals.then_some(normals),
        colours: Some(colours),
        quality_m: Some(quality),
    };
}

/// Row `y` of a `w`-wide map.
fn row_of<T>(map: &[T], w: usize, y: usize) -> &[T] {
    &map[y * w..(y + 1) * w]
}

/// The unit normals of one grid row from the points left/right (`here`) and above/below
/// (`up`, `down`), each as x, y, z rows: `(r - l) x (d - u)` turned to face `view`, as
/// [`crate::point_cloud::neighbour_normal`] but zero where that is NaN (a missing
/// neighbour, or a degenerate cross product). Columns 0 and `w - 1` are left as they are.
#[inline(always)]
fn grid_normal_row(
    here: [&[f32]; 3],
    up: [&[f32]; 3],
    down: [&[f32]; 3],
    view: [f32; 3],
    out: &mut [Vec<f32>; 3],
) {
    let w = here[0].len();
    if w < 3 {
        return;
    }
    // Cut to one length so that the loop has no bounds checks and vectorises.
    let [hx, hy, hz] = here.map(|r| &r[..w]);
    let [ux, uy, uz] = up.map(|r| &r[..w]);
    let [dx, dy, dz] = down.map(|r| &r[..w]);
    let [nx, ny, nz] = out;
    let (nx, ny, nz) = (&mut nx[..w], &mut ny[..w], &mut nz[..w]);
    for x in 1..w - 1 {
        let a = [
            hx[x + 1] - hx[x - 1],
            hy[x + 1] - hy[x - 1],
            hz[x + 1] - hz[x - 1],
        ];
        let b = [dx[x] - ux[x], dy[x] - uy[x], dz[x] - uz[x]];
        let n = [
            a[1] * b[2] - a[2] * b[1],
            a[2] * b[0] - a[0] * b[2],
            a[0] * b[1] - a[1] * b[0],
        ];
        let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
        let to_view = [view[0] - hx[x], view[1] - hy[x], view[2] - hz[x]];
        let facing = n[0] * to_view[0] + n[1] * to_view[1] + n[2] * to_view[2];
        let scale = if facing < 0.0 { -1.0 / len } else { 1.0 / len };
        let n = [n[0] * scale, n[1] * scale, n[2] * scale];
        // NaN (missing neighbour) or infinite (zero length) -> no normal.
        let ok = n[0].is_finite() & n[1].is_finite() & n[2].is_finite();
        nx[x] = if ok { n[0] } else { 0.0 };
        ny[x] = if ok { n[1] } else { 0.0 };
        nz[x] = if ok { n[2] } else { 0.0 };
    }
}
