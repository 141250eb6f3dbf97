//! Camera pixel -> projector pixel, for placing each camera pixel's optimal
//! level on the DMD. Where the full-intensity fringes decoded, the pixel's
//! triangulated point is projected into the calibrated projector (the column
//! comes from the phase, the row from the calibration, so column fringes
//! suffice). Saturated pixels have no phase: each 8-connected cluster of
//! them is mapped by a homography fitted to the decoded pixels of a ring
//! around it (seed 003, eq. 17: the contour just outside the cluster).

use nalgebra::{Matrix3, Point3, SMatrix, SymmetricEigen, Vector3};
use rayon::prelude::*;

use crate::calibration::PinholeModel;
use crate::raster::Raster;
use crate::reconstruct::PixelMaps;
use crate::unwrap::PixelStatus;

/// A camera pixel with no projector position.
pub const UNMAPPED: [f32; 2] = [f32::NAN, f32::NAN];

/// Whether a mapping entry holds a position.
pub fn is_mapped(uv: &[f32; 2]) -> bool {
    uv[0].is_finite() && uv[1].is_finite()
}

/// `(u, v)` projector pixel per camera pixel from the valid points of a
/// reconstruction (in the head's frame), [`UNMAPPED`] elsewhere and where
/// the point falls outside the DMD.
pub fn from_points(pixels: &PixelMaps, projector: &PinholeModel) -> Raster<[f32; 2]> {
    let data = (0..pixels.len())
        .into_par_iter()
        .map(|i| {
            if pixels.status[i] != PixelStatus::Valid {
                return UNMAPPED;
            }
            let p = Point3::new(
                f64::from(pixels.point_m[0][i]),
                f64::from(pixels.point_m[1][i]),
                f64::from(pixels.point_m[2][i]),
            );
            match projector.project(&p) {
                Some(uv) if projector.contains(&uv) => [uv.x as f32, uv.y as f32],
                _ => UNMAPPED,
            }
        })
        .collect();
    Raster {
        width: pixels.width,
        height: pixels.height,
        data,
    }
}

/// What [`fill_clusters`] did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ClusterFill {
    /// Clusters of pixels that needed a position.
    pub clusters: usize,
    /// Pixels mapped by their cluster's homography.
    pub filled_px: usize,
    /// Pixels left unmapped (ring too small, or the homography misfits it).
    pub unmapped_px: usize,
}

/// Fewest ring pixels a cluster's homography is fitted to.
const MIN_RING_PX: usize = 8;

/// Maps the pixels of `needs` that have no position: each 8-connected
/// cluster of them by a homography fitted to the mapped pixels within
/// `ring_px` (Chebyshev distance) of it. A cluster whose ring has fewer than
/// 8 mapped pixels, or whose fitted homography misses them by more than
/// `max_rms_px` projector pixels RMS (the surface under it is far from
/// planar), stays unmapped: masked, not guessed.
pub fn fill_clusters(
    uv: &mut Raster<[f32; 2]>,
    needs: &Raster<bool>,
    ring_px: usize,
    max_rms_px: f64,
) -> ClusterFill {
    let (w, h) = uv.size();
    let open: Vec<bool> = needs
        .data
        .iter()
        .zip(&uv.data)
        .map(|(&n, q)| n && !is_mapped(q))
        .collect();
    // 0: not seen; k + 1: pixel of cluster k, or ring pixel last claimed by it.
    let mut label = vec![0u32; w * h];
    let mut ring_mark = vec![0u32; w * h];
    let mut fill = ClusterFill::default();
    let mut stack = Vec::new();
    for start in 0..w * h {
        if label[start] != 0 || !open[start] {
            continue;
        }
        fill.clusters += 1;
        let id = fill.clusters as u32;
        let mut members = Vec::new();
        label[start] = id;
        stack.push(start);
        while let Some(i) = stack.pop() {
            members.push(i);
            let (x, y) = ((i % w) as isize, (i / w) as isize);
            for (dx, dy) in NEIGHBOURS_8 {
                let (nx, ny) = (x + dx, y + dy);
                if nx < 0 || ny < 0 || nx >= w as isize || ny >= h as isize {
                    continue;
                }
                let j = ny as usize * w + nx as usize;
                if label[j] == 0 && open[j] {
                    label[j] = id;
                    stack.push(j);
                }
            }
        }
        let mut ring = Vec::new();
        let r = ring_px as isize;
        for &i in &members {
            let (x, y) = ((i % w) as isize, (i / w) as isize);
            for ny in (y - r).max(0)..=(y + r).min(h as isize - 1) {
                for nx in (x - r).max(0)..=(x + r).min(w as isize - 1) {
                    let j = ny as usize * w + nx as usize;
                    if ring_mark[j] != id && is_mapped(&uv.data[j]) {
                        ring_mark[j] = id;
                        ring.push(j);
                    }
                }
            }
        }
        let pairs: Vec<([f64; 2], [f64; 2])> = ring
            .iter()
            .map(|&j| {
                let q = uv.data[j];
                (
                    [(j % w) as f64, (j / w) as f64],
                    [f64::from(q[0]), f64::from(q[1])],
                )
            })
            .collect();
        let homography = (pairs.len() >= MIN_RING_PX)
            .then(|| fit_homography(&pairs))
            .flatten()
            .filter(|hm| rms_error(hm, &pairs) <= max_rms_px);
        match homography {
            Some(hm) => {
                for &i in &members {
                    uv.data[i] = apply(&hm, [(i % w) as f64, (i / w) as f64])
                        .map_or(UNMAPPED, |p| [p[0] as f32, p[1] as f32]);
                    if is_mapped(&uv.data[i]) {
                        fill.filled_px += 1;
                    } else {
                        fill.unmapped_px += 1;
                    }
                }
            }
            None => fill.unmapped_px += members.len(),
        }
    }
    fill
}

const NEIGHBOURS_8: [(isize, isize); 8] = [
    (-1, -1),
    (0, -1),
    (1, -1),
    (-1, 0),
    (1, 0),
    (-1, 1),
    (0, 1),
    (1, 1),
];

/// Similarity that moves `points` to their centroid with mean distance
/// sqrt(2) (Hartley's normalisation, which keeps the DLT well conditioned).
fn normaliser(points: impl Iterator<Item = [f64; 2]> + Clone) -> Matrix3<f64> {
    let n = points.clone().count().max(1) as f64;
    let (sx, sy) = points
        .clone()
        .fold((0.0, 0.0), |(a, b), p| (a + p[0], b + p[1]));
    let (cx, cy) = (sx / n, sy / n);
    let mean = points
        .map(|p| ((p[0] - cx).powi(2) + (p[1] - cy).powi(2)).sqrt())
        .sum::<f64>()
        / n;
    let s = if mean > 0.0 {
        std::f64::consts::SQRT_2 / mean
    } else {
        1.0
    };
    Matrix3::new(s, 0.0, -s * cx, 0.0, s, -s * cy, 0.0, 0.0, 1.0)
}

/// The homography `H` with `to ~ H from` that minimises the algebraic error
/// (normalised DLT: the eigenvector of `A^T A` with the smallest eigenvalue).
/// `None` when the points are degenerate (collinear, coincident).
pub fn fit_homography(pairs: &[([f64; 2], [f64; 2])]) -> Option<Matrix3<f64>> {
    if pairs.len() < 4 {
        return None;
    }
    let t_from = normaliser(pairs.iter().map(|p| p.0));
    let t_to = normaliser(pairs.iter().map(|p| p.1));
    let mut ata = SMatrix::<f64, 9, 9>::zeros();
    for (from, to) in pairs {
        let a = t_from * Vector3::new(from[0], from[1], 1.0);
        let b = t_to * Vector3::new(to[0], to[1], 1.0);
        let rows = [
            [-a.x, -a.y, -1.0, 0.0, 0.0, 0.0, b.x * a.x, b.x * a.y, b.x],
            [0.0, 0.0, 0.0, -a.x, -a.y, -1.0, b.y * a.x, b.y * a.y, b.y],
        ];
        for r in rows {
            let v = SMatrix::<f64, 9, 1>::from_row_slice(&r);
            ata += v * v.transpose();
        }
    }
    let eig = SymmetricEigen::new(ata);
    let (k, _) = eig
        .eigenvalues
        .iter()
        .enumerate()
        .min_by(|a, b| a.1.total_cmp(b.1))?;
    let mut sorted: Vec<f64> = eig.eigenvalues.iter().copied().collect();
    sorted.sort_by(f64::total_cmp);
    // A second (near-)zero eigenvalue: the points do not pin one homography.
    if sorted[1] <= 1e-9 * sorted[8].max(1e-300) {
        return None;
    }
    let hv = eig.eigenvectors.column(k);
    let hn = Matrix3::new(
        hv[0], hv[1], hv[2], hv[3], hv[4], hv[5], hv[6], hv[7], hv[8],
    );
    let h = t_to.try_inverse()? * hn * t_from;
    let scale = h[(2, 2)];
    (scale.abs() > 1e-300 && h.iter().all(|v| v.is_finite())).then(|| h / scale)
}

/// `H p`, dehomogenised; `None` at infinity.
pub fn apply(h: &Matrix3<f64>, p: [f64; 2]) -> Option<[f64; 2]> {
    let q = h * Vector3::new(p[0], p[1], 1.0);
    (q.z.abs() > 1e-12).then(|| [q.x / q.z, q.y / q.z])
}

/// RMS transfer error of `h` over `pairs`, in `to` units.
fn rms_error(h: &Matrix3<f64>, pairs: &[([f64; 2], [f64; 2])]) -> f64 {
    let sum: f64 = pairs
        .iter()
        .map(|(from, to)| {
            apply(h, *from).map_or(f64::INFINITY, |q| {
                (q[0] - to[0]).powi(2) + (q[1] - to[1]).powi(2)
            })
        })
        .sum();
    (sum / pairs.len() as f64).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn truth() -> Matrix3<f64> {
        Matrix3::new(1.9, 0.12, 30.0, -0.05, 2.1, 12.0, 2e-4, -1e-4, 1.0)
    }

    #[test]
    fn homography_is_recovered_from_exact_pairs() {
        let h = truth();
        let pairs: Vec<_> = (0..5)
            .flat_map(|i| (0..4).map(move |j| [10.0 + 17.0 * i as f64, 5.0 + 11.0 * j as f64]))
            .map(|p| (p, apply(&h, p).unwrap()))
            .collect();
        let got = fit_homography(&pairs).unwrap();
        assert!(rms_error(&got, &pairs) < 1e-8);
        let q = apply(&got, [55.5, 20.25]).unwrap();
        let want = apply(&h, [55.5, 20.25]).unwrap();
        assert!((q[0] - want[0]).abs() < 1e-8 && (q[1] - want[1]).abs() < 1e-8);
        // Collinear points pin nothing.
        let line: Vec<_> = (0..10)
            .map(|i| ([i as f64, 2.0 * i as f64], [i as f64, 0.0]))
            .collect();
        assert!(fit_homography(&line).is_none());
    }

    #[test]
    fn a_saturated_hole_is_filled_from_its_ring_and_a_tiny_ring_is_left_unmapped() {
        let h = truth();
        let (w, hgt) = (40, 30);
        let mut uv = Raster::from_fn(w, hgt, |x, y| {
            let p = apply(&h, [x as f64, y as f64]).unwrap();
            [p[0] as f32, p[1] as f32]
        });
        let want = uv.clone();
        // A 6 x 5 hole (saturated pixels), plus one lone pixel in a corner
        // whose ring holds 3 mapped pixels only.
        let mut needs = Raster::filled(w, hgt, false);
        for y in 10..15 {
            for x in 20..26 {
                uv.data[y * w + x] = UNMAPPED;
                needs.data[y * w + x] = true;
            }
        }
        for (x, y) in [(0, 0), (1, 0), (0, 1)] {
            needs.data[y * w + x] = true;
            uv.data[y * w + x] = UNMAPPED;
        }
        let fill = fill_clusters(&mut uv, &needs, 1, 0.01);
        assert_eq!(fill.clusters, 2);
        assert_eq!(fill.filled_px, 30);
        assert_eq!(fill.unmapped_px, 3);
        for i in 0..w * hgt {
            if is_mapped(&uv.data[i]) {
                assert!((uv.data[i][0] - want.data[i][0]).abs() < 1e-3);
                assert!((uv.data[i][1] - want.data[i][1]).abs() < 1e-3);
            }
        }
        assert!(!is_mapped(&uv.data[0]));
    }

    #[test]
    fn a_ring_on_a_non_planar_surface_is_refused() {
        // The ring's positions follow no homography (a fold): misfit.
        let (w, h) = (20, 20);
        let mut uv = Raster::from_fn(w, h, |x, y| {
            let fold = (x as f32 - 10.0).abs() * 3.0;
            [x as f32 + fold, y as f32 + fold * fold * 0.2]
        });
        let mut needs = Raster::filled(w, h, false);
        for y in 8..12 {
            for x in 8..12 {
                uv.data[y * w + x] = UNMAPPED;
                needs.data[y * w + x] = true;
            }
        }
        let fill = fill_clusters(&mut uv, &needs, 3, 0.5);
        assert_eq!(fill.unmapped_px, 16);
        assert_eq!(fill.filled_px, 0);
    }
}
