//! Per-point normals by PCA over the k nearest neighbours.

use std::num::NonZeroUsize;

use kiddo::SquaredEuclidean;
use nalgebra::{Matrix3, SymmetricEigen, Vector3};
use rayon::prelude::*;

use super::{build_tree, check_finite, morton_order, FusionError, Tree};

/// Fewest neighbours that define a plane with some noise averaging.
pub const MIN_NEIGHBOURS: usize = 3;

/// Unit normal of every point: the eigenvector of the smallest eigenvalue of
/// the covariance of its `k` nearest neighbours (the point included),
/// flipped to face `sensor_origin` (the camera centre that saw the points,
/// so the sign is the visible side).
pub fn estimate_normals(
    points: &[Vector3<f64>],
    k: usize,
    sensor_origin: &Vector3<f64>,
) -> Result<Vec<Vector3<f64>>, FusionError> {
    if k < MIN_NEIGHBOURS {
        return Err(FusionError::BadParameter {
            name: "k",
            value: k as f64,
            expected: ">= 3",
        });
    }
    if points.len() < k {
        return Err(FusionError::TooFewPoints {
            cloud: "normals",
            points: points.len(),
            min: k,
        });
    }
    check_finite("normals", points)?;
    check_finite("sensor_origin", std::slice::from_ref(sensor_origin))?;
    let tree = build_tree(points)?;
    Ok(normals_with_tree(&tree, points, k, sensor_origin))
}

/// As [`estimate_normals`] with a tree already built over `points`
/// (`k >= 3`, `points.len() >= k`, finite input: checked by the caller).
pub(crate) fn normals_with_tree(
    tree: &Tree,
    points: &[Vector3<f64>],
    k: usize,
    sensor_origin: &Vector3<f64>,
) -> Vec<Vector3<f64>> {
    let k = NonZeroUsize::new(k).expect("k >= 3 checked by the caller");
    let order = morton_order(points);
    let found: Vec<Vector3<f64>> = order
        .par_iter()
        .map(|&i| {
            let p = &points[i];
            let neighbours = tree
                .query(&[p.x, p.y, p.z])
                .nearest_n::<SquaredEuclidean<f64>>(k)
                .execute();
            let idx: Vec<usize> = neighbours.iter().map(|n| n.item as usize).collect();
            let normal = pca_normal(points, &idx);
            if normal.dot(&(sensor_origin - p)) < 0.0 {
                -normal
            } else {
                normal
            }
        })
        .collect();
    let mut normals = vec![Vector3::zeros(); points.len()];
    for (&i, n) in order.iter().zip(found) {
        normals[i] = n;
    }
    normals
}

/// Smallest-variance direction of the points at `idx`.
fn pca_normal(points: &[Vector3<f64>], idx: &[usize]) -> Vector3<f64> {
    let n = idx.len() as f64;
    let mean = idx.iter().map(|&i| points[i]).sum::<Vector3<f64>>() / n;
    let cov = idx
        .iter()
        .map(|&i| {
            let d = points[i] - mean;
            d * d.transpose()
        })
        .sum::<Matrix3<f64>>()
        / n;
    let eig = SymmetricEigen::new(cov);
    let smallest = eig.eigenvalues.imin();
    eig.eigenvectors.column(smallest).normalize()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid(f: impl Fn(f64, f64) -> f64) -> Vec<Vector3<f64>> {
        let mut pts = Vec::new();
        for i in 0..40 {
            for j in 0..40 {
                let (x, y) = (i as f64 * 1e-3, j as f64 * 1e-3);
                pts.push(Vector3::new(x, y, f(x, y)));
            }
        }
        pts
    }

    #[test]
    fn plane_normals_face_the_sensor() {
        // Tilted plane z = 0.3 x + 0.1 y; its normal is (-0.3, -0.1, 1)/|.|.
        let pts = grid(|x, y| 0.3 * x + 0.1 * y);
        let truth = Vector3::new(-0.3, -0.1, 1.0).normalize();
        let up = estimate_normals(&pts, 8, &Vector3::new(0.0, 0.0, 1.0)).unwrap();
        let down = estimate_normals(&pts, 8, &Vector3::new(0.0, 0.0, -1.0)).unwrap();
        for (u, d) in up.iter().zip(&down) {
            assert!((u - truth).norm() < 1e-9, "{u}");
            assert!((d + truth).norm() < 1e-9, "{d}");
        }
    }

    #[test]
    fn sphere_normals_are_radial() {
        // Fibonacci sphere: even spacing (about 1.3 mm) without a grid.
        let (r, count) = (0.05, 20_000);
        let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
        let pts: Vec<Vector3<f64>> = (0..count)
            .map(|i| {
                let z = 1.0 - 2.0 * (i as f64 + 0.5) / count as f64;
                let rho = (1.0 - z * z).sqrt();
                let phi = golden * i as f64;
                r * Vector3::new(rho * phi.cos(), rho * phi.sin(), z)
            })
            .collect();
        // Seen from the centre: every normal points inward.
        let normals = estimate_normals(&pts, 10, &Vector3::zeros()).unwrap();
        let worst = pts
            .iter()
            .zip(&normals)
            .map(|(p, n)| n.angle(&-p.normalize()))
            .fold(0.0, f64::max);
        // The PCA plane is the tangent plane at the neighbourhood centroid,
        // a fraction of a pitch away: about pitch / (2 r) = 0.013 rad at worst.
        assert!(worst < 0.02, "worst normal error {worst} rad");
    }

    #[test]
    fn bad_input_is_an_error() {
        let mut pts = grid(|_, _| 0.0);
        let o = Vector3::z();
        assert!(matches!(
            estimate_normals(&pts, 2, &o),
            Err(FusionError::BadParameter { name: "k", .. })
        ));
        assert!(matches!(
            estimate_normals(&pts[..4], 5, &o),
            Err(FusionError::TooFewPoints { points: 4, .. })
        ));
        pts[7].x = f64::NAN;
        assert!(matches!(
            estimate_normals(&pts, 5, &o),
            Err(FusionError::NonFinite { index: 7, .. })
        ));
    }
}
