//! Plane-to-image homographies by the normalised direct linear transform.
//!
//! Used for Zhang's closed form (board plane -> image) and for the local
//! homographies that carry camera corners into projector pixels.

use nalgebra::{DMatrix, Matrix3, Point2, Vector3};

/// Errors of [`fit_homography`].
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum HomographyError {
    /// Fewer than four correspondences, or the two lists differ in length.
    #[error("a homography needs >= 4 matched points, got {from} -> {to}")]
    TooFewPoints {
        /// Points in the source plane.
        from: usize,
        /// Points in the destination plane.
        to: usize,
    },
    /// The points are (nearly) collinear or not finite.
    #[error("the points are degenerate (collinear, coincident or not finite)")]
    Degenerate,
}

/// Similarity that moves `points` to centroid 0 and mean distance sqrt(2).
fn normaliser(points: &[Point2<f64>]) -> Option<Matrix3<f64>> {
    let n = points.len() as f64;
    let cx = points.iter().map(|p| p.x).sum::<f64>() / n;
    let cy = points.iter().map(|p| p.y).sum::<f64>() / n;
    let mean_dist = points
        .iter()
        .map(|p| ((p.x - cx).powi(2) + (p.y - cy).powi(2)).sqrt())
        .sum::<f64>()
        / n;
    if !(mean_dist.is_finite() && mean_dist > 1e-12) {
        return None;
    }
    let s = std::f64::consts::SQRT_2 / mean_dist;
    Some(Matrix3::new(
        s,
        0.0,
        -s * cx,
        0.0,
        s,
        -s * cy,
        0.0,
        0.0,
        1.0,
    ))
}

/// Fits `H` with `to ~ H * from` (homogeneous), least squares on the
/// normalised algebraic error; `H[(2, 2)] = 1`.
pub fn fit_homography(
    from: &[Point2<f64>],
    to: &[Point2<f64>],
) -> Result<Matrix3<f64>, HomographyError> {
    if from.len() < 4 || from.len() != to.len() {
        return Err(HomographyError::TooFewPoints {
            from: from.len(),
            to: to.len(),
        });
    }
    let t_from = normaliser(from).ok_or(HomographyError::Degenerate)?;
    let t_to = normaliser(to).ok_or(HomographyError::Degenerate)?;
    let mut a = DMatrix::<f64>::zeros(2 * from.len(), 9);
    for (i, (p, q)) in from.iter().zip(to).enumerate() {
        let p = t_from * Vector3::new(p.x, p.y, 1.0);
        let q = t_to * Vector3::new(q.x, q.y, 1.0);
        let (x, y, u, v) = (p.x, p.y, q.x / q.z, q.y / q.z);
        a.row_mut(2 * i)
            .copy_from_slice(&[-x, -y, -1.0, 0.0, 0.0, 0.0, u * x, u * y, u]);
        a.row_mut(2 * i + 1)
            .copy_from_slice(&[0.0, 0.0, 0.0, -x, -y, -1.0, v * x, v * y, v]);
    }
    // The null vector of A is the eigenvector of A^T A with the smallest
    // eigenvalue; A^T A is 9x9 whatever the point count (an SVD of A would
    // lose the null space when A has only 8 rows).
    let ata = a.tr_mul(&a);
    let eigen = ata.symmetric_eigen();
    let (imin, _) = eigen
        .eigenvalues
        .iter()
        .enumerate()
        .min_by(|a, b| a.1.total_cmp(b.1))
        .ok_or(HomographyError::Degenerate)?;
    let mut sorted: Vec<f64> = eigen.eigenvalues.iter().copied().collect();
    sorted.sort_by(f64::total_cmp);
    // A rank drop beyond one (collinear points) leaves two tiny eigenvalues.
    if sorted[1] <= 1e-10 * sorted[8] || sorted[1].is_nan() {
        return Err(HomographyError::Degenerate);
    }
    let h = eigen.eigenvectors.column(imin);
    let hn = Matrix3::new(h[0], h[1], h[2], h[3], h[4], h[5], h[6], h[7], h[8]);
    let t_to_inv = t_to.try_inverse().ok_or(HomographyError::Degenerate)?;
    let full = t_to_inv * hn * t_from;
    if full[(2, 2)].abs() < 1e-300 || !full.iter().all(|v| v.is_finite()) {
        return Err(HomographyError::Degenerate);
    }
    Ok(full / full[(2, 2)])
}

/// Applies `h` to `p` (homogeneous division included).
pub fn apply_homography(h: &Matrix3<f64>, p: Point2<f64>) -> Point2<f64> {
    let q = h * Vector3::new(p.x, p.y, 1.0);
    Point2::new(q.x / q.z, q.y / q.z)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn recovers_known_homography() {
        let h = Matrix3::new(1.2, 0.1, 30.0, -0.05, 0.9, 12.0, 1e-4, -2e-4, 1.0);
        let from: Vec<_> = (0..6)
            .flat_map(|i| (0..5).map(move |j| Point2::new(i as f64 * 20.0, j as f64 * 20.0)))
            .collect();
        let to: Vec<_> = from.iter().map(|&p| apply_homography(&h, p)).collect();
        let fit = fit_homography(&from, &to).unwrap();
        assert!((fit - h).abs().max() < 1e-9, "{fit}");
    }

    #[test]
    fn four_points_suffice() {
        let from = [
            Point2::new(0.0, 0.0),
            Point2::new(1.0, 0.0),
            Point2::new(1.0, 1.0),
            Point2::new(0.0, 1.0),
        ];
        let to = [
            Point2::new(10.0, 10.0),
            Point2::new(30.0, 12.0),
            Point2::new(28.0, 35.0),
            Point2::new(9.0, 30.0),
        ];
        let h = fit_homography(&from, &to).unwrap();
        for (p, q) in from.iter().zip(&to) {
            assert!((apply_homography(&h, *p) - q).norm() < 1e-9);
        }
    }

    #[test]
    fn rejects_collinear_and_short_input() {
        let from: Vec<_> = (0..5)
            .map(|i| Point2::new(i as f64, 2.0 * i as f64))
            .collect();
        assert_eq!(
            fit_homography(&from, &from).unwrap_err(),
            HomographyError::Degenerate
        );
        assert_eq!(
            fit_homography(&from[..3], &from[..3]).unwrap_err(),
            HomographyError::TooFewPoints { from: 3, to: 3 }
        );
    }
}
