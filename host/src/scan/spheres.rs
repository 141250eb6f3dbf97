//! Spheres of known size in the truth (calibration spheres, the twin's or a
//! certified artefact's): each head's points on each sphere fitted with a
//! sphere, the fit's residual beside the physical noise limit, the radius
//! and centre errors, and the centre distance of the first two.

use nalgebra::{Isometry3, Point3, Vector3};

use super::truth::{CameraTruth, TrueSphere};
use crate::fit::fit_sphere;
use crate::reconstruct::Reconstruction;
use crate::unwrap::PixelStatus;

/// Fewer valid points on a sphere than this give no figures: the fit of a
/// small cap is ill-conditioned (a 112-point cap of the 20 mm boss of
/// `metal-part` fitted a 24 m sphere), no measurement.
pub const MIN_POINTS: usize = 500;

/// One head's fit of one true sphere.
#[derive(Clone, Debug, PartialEq)]
pub struct SphereFigures {
    /// The sphere's name in the truth.
    pub name: String,
    /// Valid points on it.
    pub points: usize,
    /// True radius, metres.
    pub true_radius_m: f64,
    /// Fitted radius, metres.
    pub radius_m: f64,
    /// The true centre, head frame, metres.
    pub true_centre_m: Point3<f64>,
    /// The fitted centre, head frame, metres.
    pub centre_m: Point3<f64>,
    /// RMS of the fit's radial residuals, metres.
    pub fit_rmse_m: f64,
    /// The physical limit of that residual: RMS over the points of each
    /// point's predicted sigma (phase-noise Cramer-Rao bound along its ray)
    /// carried onto the sphere's normal, metres.
    pub noise_limit_m: f64,
}

impl SphereFigures {
    /// Fitted minus true radius, metres.
    pub fn radius_error_m(&self) -> f64 {
        self.radius_m - self.true_radius_m
    }

    /// Fitted centre minus the true one, head frame, metres.
    pub fn centre_error_m(&self) -> Vector3<f64> {
        self.centre_m - self.true_centre_m
    }
}

/// Fits every sphere of `spheres` seen by `truth`'s camera in `recon` (the
/// head's calibrated frame; `head_from_world` carries the true centres
/// into it). Spheres with fewer than [`MIN_POINTS`] valid points, or whose
/// fit fails, are left out.
pub fn sphere_figures(
    recon: &Reconstruction,
    truth: &CameraTruth,
    spheres: &[TrueSphere],
    head_from_world: &Isometry3<f64>,
) -> Vec<SphereFigures> {
    spheres
        .iter()
        .filter_map(|sphere| one_sphere(recon, truth, sphere, head_from_world))
        .collect()
}

fn one_sphere(
    recon: &Reconstruction,
    truth: &CameraTruth,
    sphere: &TrueSphere,
    head_from_world: &Isometry3<f64>,
) -> Option<SphereFigures> {
    let (points, sigmas): (Vec<Point3<f64>>, Vec<f64>) = recon
        .pixels
        .iter()
        .zip(&truth.object)
        .filter(|(px, &o)| px.status == PixelStatus::Valid && o == sphere.object)
        .map(|(px, _)| {
            (
                Point3::from(px.point_m.map(f64::from)),
                f64::from(px.sigma_m),
            )
        })
        .unzip();
    if points.len() < MIN_POINTS {
        return None;
    }
    let fit = fit_sphere(&points)?;
    let centre_true = head_from_world * Point3::from(sphere.centre_m);
    // Each point's sigma is along its camera ray; the fit residual is along
    // the sphere's normal: cos of the angle between them.
    let limit2 = points
        .iter()
        .zip(&sigmas)
        .map(|(p, s)| {
            let cos = (p - fit.centre_m)
                .normalize()
                .dot(&p.coords.normalize())
                .abs();
            (s * cos).powi(2)
        })
        .sum::<f64>()
        / points.len() as f64;
    Some(SphereFigures {
        name: sphere.name.clone(),
        points: points.len(),
        true_radius_m: sphere.radius_m,
        radius_m: fit.radius_m,
        true_centre_m: centre_true,
        centre_m: fit.centre_m,
        fit_rmse_m: fit.rms_m,
        noise_limit_m: limit2.sqrt(),
    })
}

/// Fitted minus true distance between the centres of the first two spheres
/// one head fitted, metres (`None` with fewer than two).
pub fn centre_distance_error_m(figures: &[SphereFigures]) -> Option<f64> {
    let [a, b] = [figures.first()?, figures.get(1)?];
    Some((a.centre_m - b.centre_m).norm() - (a.true_centre_m - b.true_centre_m).norm())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::point_cloud::PointCloud;
    use crate::reconstruct::PixelMaps;

    /// A head whose pixels see two spheres, each point `radial_m` off its
    /// sphere along the sphere's normal, with predicted sigma `sigma_m`.
    fn two_spheres(radial_m: f64) -> (Reconstruction, CameraTruth, Vec<TrueSphere>) {
        let spheres = vec![
            TrueSphere {
                name: "left".into(),
                object: 0,
                centre_m: [-0.05, 0.0, 0.5],
                radius_m: 0.025,
            },
            TrueSphere {
                name: "right".into(),
                object: 1,
                centre_m: [0.05, 0.0, 0.5],
                radius_m: 0.02,
            },
        ];
        let (w, h) = (60, 30);
        let n = w * h;
        let mut maps = PixelMaps {
            width: w,
            height: h,
            status: vec![PixelStatus::Valid; n],
            phase_u: vec![0.0; n],
            point_m: [vec![0.0; n], vec![0.0; n], vec![0.0; n]],
            depth_m: vec![0.5; n],
            sigma_m: vec![10e-6; n],
            modulation: vec![0.5; n],
            background: vec![0.5; n],
        };
        let mut object = vec![u16::MAX; n];
        for (i, o) in object.iter_mut().enumerate() {
            let (col, row) = ((i % w) as f64, (i / w) as f64);
            let k = usize::from(col >= 30.0);
            let s = &spheres[k];
            // Points over the front cap of sphere k.
            let (theta, phi) = (0.9 * (col % 30.0 / 29.0 - 0.5), 0.9 * (row / 29.0 - 0.5));
            let n = Vector3::new(theta.sin(), phi.sin(), -(theta.cos() * phi.cos())).normalize();
            let sign = if i % 2 == 0 { 1.0 } else { -1.0 };
            let p = Vector3::from(s.centre_m) + n * (s.radius_m + sign * radial_m);
            for (axis, v) in [p.x, p.y, p.z].into_iter().enumerate() {
                maps.point_m[axis][i] = v as f32;
            }
            *o = s.object;
        }
        let recon = Reconstruction {
            pixels: maps,
            cloud: PointCloud::default(),
        };
        let truth = CameraTruth {
            width: w,
            height: h,
            camera_from_world: Isometry3::identity(),
            point_m: vec![[0.0; 3]; w * h],
            normal: vec![[0.0; 3]; w * h],
            object,
            own_object: vec![true; w * h],
            overlap: vec![false; w * h],
        };
        (recon, truth, spheres)
    }

    #[test]
    fn exact_points_give_exact_figures_and_noise_shows_in_the_residual() {
        let (recon, truth, spheres) = two_spheres(0.0);
        let f = sphere_figures(&recon, &truth, &spheres, &Isometry3::identity());
        assert_eq!(f.len(), 2);
        for s in &f {
            assert_eq!(s.points, 900);
            assert!(s.radius_error_m().abs() < 1e-7, "{s:?}");
            assert!(s.centre_error_m().norm() < 1e-7, "{s:?}");
            assert!(s.fit_rmse_m < 1e-7);
            // The sigma is along the ray; near the caps' centre the ray is the normal.
            assert!(s.noise_limit_m > 5e-6 && s.noise_limit_m <= 10e-6, "{s:?}");
        }
        assert!(centre_distance_error_m(&f).unwrap().abs() < 1e-7);
        let (recon, truth, spheres) = two_spheres(30e-6);
        let f = sphere_figures(&recon, &truth, &spheres, &Isometry3::identity());
        for s in &f {
            assert!((s.fit_rmse_m - 30e-6).abs() < 1e-6, "{s:?}");
        }
    }

    #[test]
    fn a_shifted_frame_moves_the_centres_not_the_distance() {
        let (recon, truth, spheres) = two_spheres(0.0);
        let shift = Isometry3::translation(0.001, 0.0, 0.0);
        let f = sphere_figures(&recon, &truth, &spheres, &shift);
        assert!((f[0].centre_error_m().x + 0.001).abs() < 1e-7);
        assert!(centre_distance_error_m(&f).unwrap().abs() < 1e-7);
    }

    #[test]
    fn a_sliver_gives_no_figures() {
        let (recon, mut truth, spheres) = two_spheres(0.0);
        for o in truth.object.iter_mut().skip(MIN_POINTS - 1) {
            *o = u16::MAX;
        }
        assert!(sphere_figures(&recon, &truth, &spheres, &Isometry3::identity()).is_empty());
    }
}
