//! Per-point normals by PCA over the k nearest neighbours.

use nalgebra::{Matrix3, SymmetricEigen, Vector3};

use super::{cell_knn, check_finite, FusionError};

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
    cell_knn::map_neighbourhoods(points, k, |i, neighbours| {
        let normal = pca_normal(points, neighbours);
        if normal.dot(&(sensor_origin - points[i])) < 0.0 {
            -normal
        } else {
            normal
        }
    })
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
    smallest_eigenvector(&cov)
}

/// Unit eigenvector of the smallest eigenvalue of the symmetric `m`: the
/// eigenvalue in closed form (the trigonometric solution of the cubic), the
/// vector as the longest cross product of two rows of `m - lambda I`, which
/// span the plane it is normal to. Twice as fast as the iterative
/// [`SymmetricEigen`], which stays the answer when the closed form is
/// ill-conditioned (the two smallest eigenvalues nearly equal: a line or a
/// blob rather than a surface patch).
fn smallest_eigenvector(m: &Matrix3<f64>) -> Vector3<f64> {
    let off = m[(0, 1)].powi(2) + m[(0, 2)].powi(2) + m[(1, 2)].powi(2);
    let q = m.trace() / 3.0;
    let spread = (m[(0, 0)] - q).powi(2) + (m[(1, 1)] - q).powi(2) + (m[(2, 2)] - q).powi(2);
    let p = ((spread + 2.0 * off) / 6.0).sqrt();
    if p > 0.0 {
        let b = (m - Matrix3::from_diagonal_element(q)) / p;
        let phi = (b.determinant() / 2.0).clamp(-1.0, 1.0).acos() / 3.0;
        let lambda = q + 2.0 * p * (phi + 2.0 * std::f64::consts::FRAC_PI_3).cos();
        let r = m - Matrix3::from_diagonal_element(lambda);
        let (r0, r1, r2) = (
            r.row(0).transpose(),
            r.row(1).transpose(),
            r.row(2).transpose(),
        );
        let best = [r0.cross(&r1), r0.cross(&r2), r1.cross(&r2)]
            .into_iter()
            .max_by(|a, b| a.norm_squared().total_cmp(&b.norm_squared()))
            .expect("three candidates");
        // Well-conditioned when the rows' plane is well defined: the cross
        // product is not tiny beside the rows themselves (scale-free).
        let rows = r0
            .norm_squared()
            .max(r1.norm_squared())
            .max(r2.norm_squared());
        if best.norm_squared() > 1e-6 * rows * rows {
            return best.normalize();
        }
    }
    let eig = SymmetricEigen::new(*m);
    eig.eigenvectors.column(eig.eigenvalues.imin()).normalize()
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

    /// The closed form gives the iterative solver's vector (up to sign) on
    /// random covariances of flat, round and degenerate neighbourhoods.
    #[test]
    fn closed_form_matches_the_iterative_eigenvector() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        for case in 0..3000 {
            // Eigenvalues from a flat patch (one tiny) to nearly isotropic,
            // including exact repeats, in a random orientation.
            let mut values = [
                rng.random_range(0.5..2.0),
                rng.random_range(0.3..2.0),
                rng.random_range(0.0..0.1) * [0.0, 1e-6, 1.0][case % 3],
            ];
            if case % 7 == 0 {
                values[1] = values[0];
            }
            let rotation = nalgebra::Rotation3::from_scaled_axis(Vector3::new(
                rng.random_range(-3.0..3.0),
                rng.random_range(-3.0..3.0),
                rng.random_range(-3.0..3.0),
            ));
            let scale: f64 = 10f64.powi(rng.random_range(-10..2));
            let m = rotation.matrix()
                * Matrix3::from_diagonal(&Vector3::from(values))
                * rotation.matrix().transpose()
                * scale;
            let got = smallest_eigenvector(&m);
            let want = rotation.matrix().column(2).into_owned();
            assert!((got.norm() - 1.0).abs() < 1e-12, "case {case}");
            assert!(
                got.dot(&want).abs() > 1.0 - 1e-9,
                "case {case}: {got} vs {want} ({values:?}, scale {scale})"
            );
        }
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
