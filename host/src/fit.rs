//! Least-squares shape fits for accuracy reports: plane and sphere.

use nalgebra::{DMatrix, DVector, Matrix3, Point3, Vector3};

/// A fitted plane `n . p = d` and the RMS of point distances to it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlaneFit {
    /// Unit normal.
    pub normal: Vector3<f64>,
    /// Offset, metres.
    pub offset_m: f64,
    /// RMS distance of the points, metres.
    pub rms_m: f64,
}

/// A fitted sphere and the RMS of radial residuals.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SphereFit {
    /// Centre, metres.
    pub centre_m: Point3<f64>,
    /// Radius, metres.
    pub radius_m: f64,
    /// RMS of `|p - c| - r`, metres.
    pub rms_m: f64,
}

/// Total least-squares plane (smallest eigenvector of the scatter); `None` for < 3 points.
pub fn fit_plane(points: &[Point3<f64>]) -> Option<PlaneFit> {
    if points.len() < 3 {
        return None;
    }
    let n = points.len() as f64;
    let mean = points.iter().fold(Vector3::zeros(), |a, p| a + p.coords) / n;
    let scatter = points.iter().fold(Matrix3::zeros(), |a, p| {
        let d = p.coords - mean;
        a + d * d.transpose()
    });
    let eig = scatter.symmetric_eigen();
    let (i, _) = eig.eigenvalues.argmin();
    let normal = eig.eigenvectors.column(i).into_owned().normalize();
    let offset_m = normal.dot(&mean);
    let rms_m = (points
        .iter()
        .map(|p| (normal.dot(&p.coords) - offset_m).powi(2))
        .sum::<f64>()
        / n)
        .sqrt();
    Some(PlaneFit {
        normal,
        offset_m,
        rms_m,
    })
}

/// Geometric least-squares sphere: algebraic fit, then Gauss-Newton on `|p - c| - r`.
/// `None` for fewer than 4 points or a degenerate set.
pub fn fit_sphere(points: &[Point3<f64>]) -> Option<SphereFit> {
    if points.len() < 4 {
        return None;
    }
    // Algebraic: |p|^2 = 2 c.p + (r^2 - |c|^2), linear in (c, k).
    let m = points.len();
    let a = DMatrix::from_fn(m, 4, |i, j| if j < 3 { 2.0 * points[i][j] } else { 1.0 });
    let b = DVector::from_fn(m, |i, _| points[i].coords.norm_squared());
    let sol = a.svd(true, true).solve(&b, 1e-15).ok()?;
    let mut c = Vector3::new(sol[0], sol[1], sol[2]);
    let mut r = (sol[3] + c.norm_squared()).max(0.0).sqrt();
    for _ in 0..20 {
        let mut jtj = nalgebra::Matrix4::<f64>::zeros();
        let mut jtr = nalgebra::Vector4::<f64>::zeros();
        for p in points {
            let d = p.coords - c;
            let dist = d.norm();
            if dist == 0.0 {
                continue;
            }
            let res = dist - r;
            let g = -d / dist;
            let j = nalgebra::Vector4::new(g.x, g.y, g.z, -1.0);
            jtj += j * j.transpose();
            jtr += j * res;
        }
        let step = jtj.lu().solve(&(-jtr))?;
        c += Vector3::new(step[0], step[1], step[2]);
        r += step[3];
        if step.norm() < 1e-13 {
            break;
        }
    }
    let rms_m = (points
        .iter()
        .map(|p| ((p.coords - c).norm() - r).powi(2))
        .sum::<f64>()
        / m as f64)
        .sqrt();
    Some(SphereFit {
        centre_m: Point3::from(c),
        radius_m: r,
        rms_m,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exact_shapes_are_recovered() {
        let c = Point3::new(0.1, -0.05, 0.5);
        let pts: Vec<Point3<f64>> = (0..200)
            .map(|i| {
                let t = i as f64 * 0.1;
                let (th, ph) = (t.sin() * 1.2, t * 2.3);
                c + Vector3::new(th.cos() * ph.cos(), th.cos() * ph.sin(), -th.sin().abs()) * 0.025
            })
            .collect();
        let s = fit_sphere(&pts).unwrap();
        assert!((s.radius_m - 0.025).abs() < 1e-12 && (s.centre_m - c).norm() < 1e-12);
        let plane: Vec<Point3<f64>> = (0..50)
            .map(|i| Point3::new(i as f64 * 0.01, (i * 7 % 11) as f64 * 0.01, 0.3))
            .collect();
        let p = fit_plane(&plane).unwrap();
        assert!(p.rms_m < 1e-12 && (p.normal.z.abs() - 1.0).abs() < 1e-12);
        assert!(fit_sphere(&pts[..3]).is_none());
    }
}
