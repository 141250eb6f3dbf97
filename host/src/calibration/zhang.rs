//! Zhang's closed-form camera calibration (Zhang 2000, "A flexible new
//! technique for camera calibration"): intrinsics from the image of the
//! absolute conic seen through several board homographies, then each view's
//! pose from its homography. Distortion is left at zero here; `bundle.rs`
//! refines everything by Levenberg-Marquardt.

use nalgebra::{DMatrix, Matrix3, Point2};

use super::homography::{fit_homography, HomographyError};
use super::{Intrinsics, Pose};

/// The camera matrix `K` of `k` (zero skew).
pub fn camera_matrix(k: &Intrinsics) -> Matrix3<f64> {
    Matrix3::new(k.fx, 0.0, k.cx, 0.0, k.fy, k.cy, 0.0, 0.0, 1.0)
}

/// One view of a planar target: board points and where they were seen.
#[derive(Debug, Clone, PartialEq)]
pub struct PlanarView {
    /// Points on the board plane (z = 0), metres.
    pub board_m: Vec<Point2<f64>>,
    /// The same points in the image, pixels (same order).
    pub image_px: Vec<Point2<f64>>,
}

/// Errors of Zhang's closed form.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum ZhangError {
    /// Too few views to determine the intrinsics.
    #[error("Zhang's closed form needs >= {needed} board views, got {got}")]
    TooFewViews {
        /// Views given.
        got: usize,
        /// Views needed.
        needed: usize,
    },
    /// A view's homography could not be fitted.
    #[error("view {view}: {source}")]
    Homography {
        /// Index of the view.
        view: usize,
        /// Why.
        source: HomographyError,
    },
    /// The views do not determine a valid camera (e.g. all boards parallel).
    #[error("the board views do not determine the intrinsics (are the boards all parallel?)")]
    Degenerate,
}

/// Zhang's `v_ij` row of the constraint matrix from homography columns i, j.
fn v_row(h: &Matrix3<f64>, i: usize, j: usize) -> [f64; 6] {
    let (hi, hj) = (h.column(i), h.column(j));
    [
        hi[0] * hj[0],
        hi[0] * hj[1] + hi[1] * hj[0],
        hi[1] * hj[1],
        hi[2] * hj[0] + hi[0] * hj[2],
        hi[2] * hj[1] + hi[1] * hj[2],
        hi[2] * hj[2],
    ]
}

/// Intrinsics from homographies (normalised image coordinates), zero skew.
fn intrinsics_from_homographies(hs: &[Matrix3<f64>]) -> Option<Intrinsics> {
    let mut v = DMatrix::<f64>::zeros(2 * hs.len() + 1, 6);
    for (k, h) in hs.iter().enumerate() {
        let v12 = v_row(h, 0, 1);
        let v11 = v_row(h, 0, 0);
        let v22 = v_row(h, 1, 1);
        v.row_mut(2 * k).copy_from_slice(&v12);
        let diff: Vec<f64> = v11.iter().zip(&v22).map(|(a, b)| a - b).collect();
        v.row_mut(2 * k + 1).copy_from_slice(&diff);
    }
    // Zero skew: B12 = 0.
    v[(2 * hs.len(), 1)] = 1.0;
    let eig = v.tr_mul(&v).symmetric_eigen();
    let (imin, _) = eig
        .eigenvalues
        .iter()
        .enumerate()
        .min_by(|a, b| a.1.total_cmp(b.1))?;
    let b = eig.eigenvectors.column(imin);
    let (b11, b12, b22, b13, b23, b33) = (b[0], b[1], b[2], b[3], b[4], b[5]);
    let den = b11 * b22 - b12 * b12;
    let v0 = (b12 * b13 - b11 * b23) / den;
    let lambda = b33 - (b13 * b13 + v0 * (b12 * b13 - b11 * b23)) / b11;
    let alpha_sq = lambda / b11;
    let beta_sq = lambda * b11 / den;
    if !(alpha_sq > 0.0 && beta_sq > 0.0) {
        return None;
    }
    let alpha = alpha_sq.sqrt();
    let u0 = -b13 * alpha_sq / lambda;
    let k = Intrinsics {
        fx: alpha,
        fy: beta_sq.sqrt(),
        cx: u0,
        cy: v0,
    };
    [k.fx, k.fy, k.cx, k.cy]
        .iter()
        .all(|x| x.is_finite())
        .then_some(k)
}

/// Pose of the board from its homography `h` (board metres -> pixels).
pub fn pose_from_homography(k: &Intrinsics, h: &Matrix3<f64>) -> Option<Pose> {
    let kinv = camera_matrix(k).try_inverse()?;
    let a = kinv * h;
    let scale = 1.0 / a.column(0).norm();
    // The board must lie in front of the camera (t_z > 0).
    let sign = if a[(2, 2)] < 0.0 { -1.0 } else { 1.0 };
    let r1 = a.column(0) * scale * sign;
    let r2 = a.column(1) * scale * sign;
    let t = a.column(2) * scale * sign;
    let r3 = r1.cross(&r2);
    let approx = Matrix3::from_columns(&[r1, r2, r3]);
    // Nearest rotation in the Frobenius sense.
    let svd = approx.svd(true, true);
    let (u, vt) = (svd.u?, svd.v_t?);
    let mut r = u * vt;
    if r.determinant() < 0.0 {
        let mut u2 = u;
        u2.column_mut(2).neg_mut();
        r = u2 * vt;
    }
    let pose = Pose {
        rotation: r,
        translation_m: t,
    };
    pose.translation_m
        .iter()
        .all(|x| x.is_finite())
        .then_some(pose)
}

/// Closed-form intrinsics and per-view board poses (distortion ignored).
///
/// Each view pairs board points (metres, board plane z = 0) with their
/// detected pixels. `image_size` is the
/// sensor size in pixels; it conditions the arithmetic and supplies the
/// fallback principal point (the image centre, as OpenCV's initialisation)
/// when the views cannot determine it.
pub fn closed_form(
    views: &[PlanarView],
    image_size: (u32, u32),
) -> Result<(Intrinsics, Vec<Pose>), ZhangError> {
    if views.len() < 2 {
        return Err(ZhangError::TooFewViews {
            got: views.len(),
            needed: 2,
        });
    }
    let (w, h) = (image_size.0 as f64, image_size.1 as f64);
    let s = w.max(h);
    // Work in normalised pixels so that the constraint matrix is well scaled.
    let n = Matrix3::new(
        1.0 / s,
        0.0,
        -0.5 * w / s,
        0.0,
        1.0 / s,
        -0.5 * h / s,
        0.0,
        0.0,
        1.0,
    );
    let mut homographies = Vec::with_capacity(views.len());
    for (view, v) in views.iter().enumerate() {
        let hpx = fit_homography(&v.board_m, &v.image_px)
            .map_err(|source| ZhangError::Homography { view, source })?;
        homographies.push(hpx);
    }
    let normalised: Vec<Matrix3<f64>> = homographies.iter().map(|h| n * h).collect();
    let from_zhang = intrinsics_from_homographies(&normalised).map(|k| Intrinsics {
        fx: k.fx * s,
        fy: k.fy * s,
        cx: k.cx * s + 0.5 * w,
        cy: k.cy * s + 0.5 * h,
    });
    let inside = |k: &Intrinsics| k.cx > 0.0 && k.cx < w && k.cy > 0.0 && k.cy < h;
    let k = match from_zhang {
        Some(k) if inside(&k) => k,
        _ => focal_with_centred_principal_point(&normalised)
            .map(|f| Intrinsics {
                fx: f.0 * s,
                fy: f.1 * s,
                cx: 0.5 * w,
                cy: 0.5 * h,
            })
            .ok_or(ZhangError::Degenerate)?,
    };
    let poses = homographies
        .iter()
        .map(|h| pose_from_homography(&k, h).ok_or(ZhangError::Degenerate))
        .collect::<Result<Vec<_>, _>>()?;
    Ok((k, poses))
}

/// Focal lengths with the principal point fixed at the (normalised) origin:
/// the orthogonality constraints become linear in `1/fx^2`, `1/fy^2`.
fn focal_with_centred_principal_point(hs: &[Matrix3<f64>]) -> Option<(f64, f64)> {
    let mut a = DMatrix::<f64>::zeros(2 * hs.len(), 2);
    let mut b = nalgebra::DVector::<f64>::zeros(2 * hs.len());
    for (k, h) in hs.iter().enumerate() {
        let v12 = v_row(h, 0, 1);
        let v11 = v_row(h, 0, 0);
        let v22 = v_row(h, 1, 1);
        // With B = diag(1/fx^2, 1/fy^2, 1): rows [v0, v2] . (B11, B22) = -v5.
        a[(2 * k, 0)] = v12[0];
        a[(2 * k, 1)] = v12[2];
        b[2 * k] = -v12[5];
        a[(2 * k + 1, 0)] = v11[0] - v22[0];
        a[(2 * k + 1, 1)] = v11[2] - v22[2];
        b[2 * k + 1] = -(v11[5] - v22[5]);
    }
    let sol = a.svd(true, true).solve(&b, 1e-14).ok()?;
    (sol[0] > 0.0 && sol[1] > 0.0).then(|| (1.0 / sol[0].sqrt(), 1.0 / sol[1].sqrt()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calibration::rodrigues::{pose_from_rodrigues, rotation_angle_between};
    use nalgebra::{Point3, Vector3};

    fn board() -> Vec<Point2<f64>> {
        (0..6)
            .flat_map(|j| (0..9).map(move |i| Point2::new(i as f64 * 0.02, j as f64 * 0.02)))
            .collect()
    }

    fn project(k: &Intrinsics, pose: &Pose, p: &Point2<f64>) -> Point2<f64> {
        let c = pose.apply(&Point3::new(p.x, p.y, 0.0));
        Point2::new(k.fx * c.x / c.z + k.cx, k.fy * c.y / c.z + k.cy)
    }

    fn views() -> Vec<Pose> {
        [
            (0.2, -0.1, 0.05),
            (-0.25, 0.15, -0.1),
            (0.1, 0.3, 0.2),
            (-0.3, -0.2, 0.0),
        ]
        .iter()
        .map(|&(a, b, c)| {
            pose_from_rodrigues(&Vector3::new(a, b, c), &Vector3::new(-0.08, -0.05, 0.45))
        })
        .collect()
    }

    #[test]
    fn recovers_exact_intrinsics_and_poses() {
        let k = Intrinsics {
            fx: 820.0,
            fy: 810.0,
            cx: 330.0,
            cy: 236.0,
        };
        let b = board();
        let truth = views();
        let obs: Vec<PlanarView> = truth
            .iter()
            .map(|pose| PlanarView {
                board_m: b.clone(),
                image_px: b.iter().map(|p| project(&k, pose, p)).collect(),
            })
            .collect();
        let (est, poses) = closed_form(&obs, (640, 480)).unwrap();
        assert!(
            (est.fx - k.fx).abs() < 1e-6 && (est.fy - k.fy).abs() < 1e-6,
            "{est:?}"
        );
        assert!(
            (est.cx - k.cx).abs() < 1e-6 && (est.cy - k.cy).abs() < 1e-6,
            "{est:?}"
        );
        for (p, t) in poses.iter().zip(&truth) {
            assert!((p.translation_m - t.translation_m).norm() < 1e-9);
            assert!(rotation_angle_between(&p.rotation, &t.rotation) < 1e-9);
        }
    }

    #[test]
    fn one_view_is_too_few() {
        let b = board();
        assert_eq!(
            closed_form(
                &[PlanarView {
                    board_m: b.clone(),
                    image_px: b
                }],
                (640, 480)
            )
            .unwrap_err(),
            ZhangError::TooFewViews { got: 1, needed: 2 }
        );
    }
}
