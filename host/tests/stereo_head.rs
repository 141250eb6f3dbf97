//! The stereo head against the DIGITAL TWIN's ground truth: the `stereo-spheres` scene
//! (seed 001's two calibration spheres, two cameras 170 mm apart, one projector between
//! them) rendered through both cameras (defocused 8-bit DMD fringes, shot + read +
//! quantisation noise of a 12-bit sensor), each camera's projector column decoded with
//! the public API (4-step phase, 3-period heterodyne), matched and triangulated by
//! `stereo::StereoReconstructor` with the twin's true cameras. Every figure is printed:
//! `cargo test -p slscan --test stereo_head -- --nocapture`.

use std::f64::consts::{PI, TAU};
use std::sync::Arc;

use hil_sim::twin::scenes::{built_in, Detail, SPHERE_CENTRE_DISTANCE_M, SPHERE_RADII_M};
use hil_sim::twin::{
    BitDepth, Exposure, Frame, Fringe, Pattern, ProjectorTimeline, Renderer, SensorModel,
};
use nalgebra::{Matrix4, Point3, Vector4};
use slscan::fit::{fit_sphere, SphereFit};
use slscan::phase::PhaseShift;
use slscan::raster::Raster;
use slscan::sim::calibration::from_twin::{pose_from_twin, stereo_head_from_twin};
use slscan::stereo::{StereoConfig, StereoReconstructor};
use slscan::unwrap::heterodyne::Heterodyne;
use slscan::unwrap::PixelStatus;

/// Small renders: a 320x240 camera and a 640x400 DMD keep the suite fast on 2 cores.
const DETAIL: Detail = Detail {
    camera: (320, 240),
    projector: (640, 400),
};
const STEPS: usize = 4;
/// Heterodyne periods, DMD pixels, finest first (beat 1320 px > the 640 px DMD).
const PERIODS: [f64; 3] = [20.0, 22.0, 24.0];
/// As `twin_accuracy.rs`: about 5600 e- on a white patch at 0.5 m, nothing saturates.
const EXPOSURE_S: f64 = 0.7e-3;
/// Fringe orders are refused where their predicted noise exceeds pi / 5 (as
/// `ReconstructConfig::order_sigmas`).
const ORDER_SIGMAS: f64 = 5.0;

fn exposure() -> Exposure {
    Exposure {
        start_s: 0.0,
        end_s: EXPOSURE_S,
    }
}

fn shown(pattern: Pattern) -> Vec<ProjectorTimeline> {
    vec![ProjectorTimeline::single(
        Arc::new(pattern),
        0.0,
        EXPOSURE_S,
    )]
}

/// The noise of a mid-grey mono12 pixel (about 3000 e-), full-scale units.
fn mid_grey_sigma() -> f64 {
    SensorModel::mono12().output_sigma(3000.0)
}

/// One camera's decode: projector column (NaN where not decoded), smallest modulation
/// over the periods, background of the finest period.
struct Decoded {
    u: Raster<f32>,
    modulation: Raster<f32>,
    background: Raster<f32>,
}

/// Renders camera `camera`'s `PERIODS x STEPS` column fringes and decodes them.
fn decode(renderer: &Renderer, seed: u64) -> Decoded {
    let (w, h) = DETAIL.projector;
    let shift = PhaseShift::new(STEPS).unwrap();
    let mut wrapped = Vec::new();
    for (k, &period_px) in PERIODS.iter().enumerate() {
        let frames: Vec<Raster<f32>> = (0..STEPS)
            .map(|n| {
                let fringe = Fringe {
                    period_px,
                    angle_rad: 0.0,
                    shift_rad: TAU * n as f64 / STEPS as f64,
                };
                let pattern = Pattern::fringe(w, h, &fringe, BitDepth::Eight);
                let noise_seed = seed * 1000 + (k * STEPS + n) as u64;
                let (image, _) = renderer
                    .image(
                        &shown(pattern),
                        exposure(),
                        &(if std::env::var("STEREO_IDEAL").is_ok() {
                            SensorModel::ideal()
                        } else {
                            SensorModel::mono12()
                        }),
                        noise_seed,
                    )
                    .unwrap();
                let (iw, ih) = (image.width as usize, image.height as usize);
                Raster::from_vec(iw, ih, image.data).unwrap()
            })
            .collect();
        let refs: Vec<&Raster<f32>> = frames.iter().collect();
        wrapped.push(shift.wrapped_phase(&refs).unwrap());
    }
    let heterodyne = Heterodyne::new(&PERIODS, f64::from(w), PI / 2.0).unwrap();
    // Below this modulation a fringe order can be miscounted and still pass the residual
    // check: refused, as the projector-head pipeline refuses it.
    let sigma_phi_times_b = mid_grey_sigma() * (2.0 / STEPS as f64).sqrt();
    let min_b = (heterodyne.order_noise_gain() * sigma_phi_times_b * ORDER_SIGMAS / PI) as f32;
    let first = &wrapped[0];
    let modulation = Raster::from_fn(first.phase.width, first.phase.height, |x, y| {
        wrapped
            .iter()
            .map(|p| *p.modulation.at(x, y))
            .fold(f32::INFINITY, f32::min)
    });
    let mask = Raster {
        width: modulation.width,
        height: modulation.height,
        data: modulation.data.iter().map(|&b| b >= min_b).collect(),
    };
    let phases: Vec<&Raster<f32>> = wrapped.iter().map(|p| &p.phase).collect();
    let absolute = heterodyne.unwrap(&phases, Some(&mask)).unwrap();
    let to_px = (PERIODS[0] / TAU) as f32;
    let u = Raster {
        width: modulation.width,
        height: modulation.height,
        data: absolute
            .phase
            .data
            .iter()
            .zip(&absolute.status.data)
            .map(|(&p, &s)| {
                if s == PixelStatus::Valid {
                    p * to_px
                } else {
                    f32::NAN
                }
            })
            .collect(),
    };
    Decoded {
        u,
        modulation,
        background: first.background.clone(),
    }
}

fn config() -> StereoConfig {
    let noise = StereoConfig::coordinate_noise_px(mid_grey_sigma(), STEPS, PERIODS[0]);
    StereoConfig::new(PERIODS[0], noise)
}

/// Standard errors of a sphere fit's centre (3) and radius from the linearised least
/// squares `sigma^2 (J^T J)^-1`, residual sigma = the fit's RMS.
fn sphere_covariance(fit: &SphereFit, points: &[Point3<f64>]) -> Matrix4<f64> {
    let mut jtj = Matrix4::zeros();
    for p in points {
        let n = (p - fit.centre_m).normalize();
        let j = Vector4::new(-n.x, -n.y, -n.z, -1.0);
        jtj += j * j.transpose();
    }
    jtj.try_inverse().unwrap() * fit.rms_m.powi(2)
}

/// Views more oblique than this (cosine of the angle between the surface normal and
/// the line of sight) are left out of the exact test: there fringes foreshorten and
/// lose modulation, and a decode masks them; near the silhouette the coordinate
/// behaves like a square root, which no interpolation follows.
const MIN_VIEW_COS: f32 = 0.5;

/// The twin's exact projector column of every lit pixel of a camera at `centre_m`
/// (world) seen at most 60 degrees off its normal (modulation 1 there, 0 elsewhere).
fn exact_columns(renderer: &Renderer, centre_m: [f64; 3]) -> (Raster<f32>, Raster<f32>) {
    let (w, h) = DETAIL.projector;
    let frame = renderer
        .frame(
            &shown(Pattern::flat(w, h, 0.5)),
            exposure(),
            &SensorModel::ideal(),
            0,
        )
        .unwrap();
    let t = &frame.truth;
    let (cw, ch) = (t.width() as usize, t.height() as usize);
    let shadow = t.shadow_mask(0);
    let surface = t.no_surface_mask();
    let (points, normals) = (t.point_m(), t.normal());
    let seen = |i: usize| {
        let to_camera: [f32; 3] = std::array::from_fn(|k| centre_m[k] as f32 - points[i][k]);
        let len = to_camera.iter().map(|v| v * v).sum::<f32>().sqrt();
        let cos = (0..3).map(|k| normals[i][k] * to_camera[k]).sum::<f32>() / len;
        cos >= MIN_VIEW_COS
    };
    let lit: Vec<bool> = (0..cw * ch)
        .map(|i| !shadow[i] && !surface[i] && seen(i))
        .collect();
    let uv = t.projector_uv_px(0);
    let u = (0..cw * ch)
        .map(|i| if lit[i] { uv[i][0] } else { f32::NAN })
        .collect();
    let b = lit.iter().map(|&l| if l { 1.0 } else { 0.0 }).collect();
    (
        Raster::from_vec(cw, ch, u).unwrap(),
        Raster::from_vec(cw, ch, b).unwrap(),
    )
}

/// The geometry alone: with the twin's exact projector columns (no fringes, no noise)
/// matching, interpolation and triangulation must give the spheres to a micrometre
/// wherever both cameras see the surface within 60 degrees of its normal.
#[test]
fn exact_projector_columns_give_the_stereo_spheres_to_a_micrometre() {
    let (scene, rig) = built_in("stereo-spheres", &DETAIL).unwrap();
    let head = stereo_head_from_twin(&rig, 0, 1, "S").unwrap();
    let renderers: Vec<Renderer> = (0..2)
        .map(|c| Renderer::new(&scene, &rig, c, 0.0).unwrap())
        .collect();
    let [(lu, lb), (ru, rb)] = [0, 1].map(|c| {
        let centre = rig.cameras[c].model.world_from_device.translation.vector;
        exact_columns(&renderers[c], [centre.x, centre.y, centre.z])
    });
    let rec = StereoReconstructor::new(&head, config())
        .unwrap()
        .reconstruct(&lu, &lb, &ru, &rb)
        .unwrap();
    let (w, h) = DETAIL.projector;
    let truth = renderers[0]
        .frame(
            &shown(Pattern::flat(w, h, 0.5)),
            exposure(),
            &SensorModel::ideal(),
            0,
        )
        .unwrap();
    let to_head = pose_from_twin(&rig.cameras[0].model.world_from_device);
    let (objects, truth_m) = (truth.truth.object(), truth.truth.point_m());
    let mut centres = Vec::new();
    for (k, &radius_m) in SPHERE_RADII_M.iter().enumerate() {
        let (mut points, mut err2) = (Vec::new(), 0.0);
        for (i, p) in rec.pixels.iter().enumerate() {
            if p.status != PixelStatus::Valid || usize::from(objects[i]) != k {
                continue;
            }
            let p = Point3::new(p.point_m[0], p.point_m[1], p.point_m[2]).cast::<f64>();
            let t = truth_m[i];
            err2 += (p - to_head.apply(&Point3::new(t[0], t[1], t[2]).cast())).norm_squared();
            points.push(p);
        }
        let fit = fit_sphere(&points).unwrap();
        let rms_um = (err2 / points.len() as f64).sqrt() * 1e6;
        let radius_um = (fit.radius_m - radius_m) * 1e6;
        println!(
            "exact columns, sphere {}: {} valid points, point error {rms_um:.2} um RMS, radius \
             error {radius_um:+.2} um, fit RMSE {:.2} um",
            k + 1,
            points.len(),
            fit.rms_m * 1e6
        );
        assert!(points.len() > 500, "sphere {k}: {} points", points.len());
        assert!(rms_um < 1.0 && radius_um.abs() < 2.0, "sphere {k}");
        centres.push(fit.centre_m);
    }
    let d_um = ((centres[0] - centres[1]).norm() - SPHERE_CENTRE_DISTANCE_M) * 1e6;
    println!("exact columns: centre distance error {d_um:+.2} um");
    assert!(d_um.abs() < 2.0);
}

#[test]
fn stereo_spheres_fit_at_the_noise_limit_to_their_true_radii_and_centre_distance() {
    let (scene, rig) = built_in("stereo-spheres", &DETAIL).unwrap();
    let head = stereo_head_from_twin(&rig, 0, 1, "S").unwrap();
    let renderers: Vec<Renderer> = (0..2)
        .map(|c| Renderer::new(&scene, &rig, c, 0.0).unwrap())
        .collect();
    let (w, h) = DETAIL.projector;
    let truth: Frame = renderers[0]
        .frame(
            &shown(Pattern::flat(w, h, 0.5)),
            exposure(),
            &SensorModel::ideal(),
            0,
        )
        .unwrap();
    let [left, right] = [0, 1].map(|c| decode(&renderers[c], 40 + c as u64));
    let stereo = StereoReconstructor::new(&head, config()).unwrap();
    let rec = stereo
        .reconstruct(&left.u, &left.modulation, &right.u, &right.modulation)
        .unwrap();
    let r = stereo.rectification();
    println!(
        "stereo head: baseline {:.1} mm, rectified focal {:.1} px, rectified right grid {}x{}; \
         {} valid, {} unreliable, {} masked of {} left pixels",
        r.baseline_m() * 1e3,
        r.focal_px(),
        r.grid().width,
        r.grid().height,
        rec.count(PixelStatus::Valid),
        rec.count(PixelStatus::Unreliable),
        rec.count(PixelStatus::Masked),
        rec.pixels.len()
    );

    // The reconstruction is in the head (left camera) frame: carry the truth into it.
    let to_head = pose_from_twin(&rig.cameras[0].model.world_from_device);
    let objects = truth.truth.object();
    let truth_m = truth.truth.point_m();
    let sensor = SensorModel::mono12();
    let signal_sigma =
        |a: f32| sensor.output_sigma(f64::from(a) * sensor.full_well_e / sensor.gain);
    let s0 = mid_grey_sigma();
    let (rw, rh) = right.u.size();
    let mut fits = Vec::new();
    for (k, &radius_m) in SPHERE_RADII_M.iter().enumerate() {
        let (pixels, points): (Vec<usize>, Vec<Point3<f64>>) = rec
            .pixels
            .iter()
            .enumerate()
            .filter(|(i, p)| p.status == PixelStatus::Valid && usize::from(objects[*i]) == k)
            .map(|(i, p)| {
                (
                    i,
                    Point3::new(p.point_m[0], p.point_m[1], p.point_m[2]).cast(),
                )
            })
            .unzip();
        assert!(points.len() > 500, "sphere {k}: {} points", points.len());
        let fit = fit_sphere(&points).unwrap();
        let centre_true = to_head.apply(&Point3::from(scene.objects[k].pose.translation.vector));
        // Per point: the error along the left ray against the twin's surface point, and
        // the physical limit along the ray: the pipeline's sigma (mid-grey noise in both
        // cameras) rescaled to each camera's own signal noise at this point (the right
        // camera's read where the point projects).
        let (mut err2, mut err_sum, mut ratio2, mut limit_normal2) = (0.0, 0.0, 0.0, 0.0);
        for (&i, p) in pixels.iter().zip(&points) {
            let px = rec.pixels.get(i);
            let t = truth_m[i];
            let truth_point = to_head.apply(&Point3::new(t[0], t[1], t[2]).cast());
            let e = p.coords.norm() - truth_point.coords.norm();
            let q = head.right.project(p).unwrap();
            let (qx, qy) = (q.x.round() as usize, q.y.round() as usize);
            let j = qy.min(rh - 1) * rw + qx.min(rw - 1);
            let (bl, br) = (
                f64::from(left.modulation.data[i]),
                f64::from(right.modulation.data[j]),
            );
            let (sl, sr) = (
                signal_sigma(left.background.data[i]),
                signal_sigma(right.background.data[j]),
            );
            let scale = ((sl * sl / (bl * bl) + sr * sr / (br * br))
                / (s0 * s0 * (1.0 / (bl * bl) + 1.0 / (br * br))))
                .sqrt();
            let limit = f64::from(px.sigma_m) * scale;
            let cos = (p - fit.centre_m)
                .normalize()
                .dot(&p.coords.normalize())
                .abs();
            err2 += e * e;
            err_sum += e;
            ratio2 += (e / limit).powi(2);
            limit_normal2 += (limit * cos).powi(2);
        }
        let n = points.len() as f64;
        let (err_rms, err_mean) = ((err2 / n).sqrt(), err_sum / n);
        let ratio = (ratio2 / n).sqrt();
        let limit_m = (limit_normal2 / n).sqrt();
        let cov = sphere_covariance(&fit, &points);
        let radius_se = cov[(3, 3)].sqrt();
        let radius_error = fit.radius_m - radius_m;
        let centre_um = (fit.centre_m - centre_true).norm() * 1e6;
        println!(
            "sphere {}: {} valid points, radius {:.4} mm (true {:.4}, error {:+.1} um, fit \
             standard error {:.1} um), centre error {centre_um:.1} um; fit RMSE {:.1} um vs \
             noise limit {:.1} um (ratio {:.3}); error along the ray vs truth {:.1} um RMS, \
             mean {:+.2} um, RMS(error / limit) {ratio:.3}",
            k + 1,
            points.len(),
            fit.radius_m * 1e3,
            radius_m * 1e3,
            radius_error * 1e6,
            radius_se * 1e6,
            fit.rms_m * 1e6,
            limit_m * 1e6,
            fit.rms_m / limit_m,
            err_rms * 1e6,
            err_mean * 1e6
        );
        // The limit counts one right pixel's noise; the interpolations average right
        // pixels into a match (Catmull-Rom: sum of squared weights 0.41 to 1 per
        // resampling), so with equal noise in both cameras the measured noise lies
        // between about sqrt(1 / 2) = 0.71 of the limit and the limit (see
        // stereo::triangulate); 10 % above for the kernels' negative lobes.
        let band = 0.7..1.1;
        assert!(
            band.contains(&(fit.rms_m / limit_m)),
            "sphere {k}: fit RMSE / limit"
        );
        assert!(
            band.contains(&ratio),
            "sphere {k}: RMS(error / limit) {ratio}"
        );
        // No bias beyond the mean's standard error, radius within 4 standard errors.
        assert!(
            err_mean.abs() < 4.0 * err_rms / n.sqrt(),
            "sphere {k}: bias {err_mean}"
        );
        assert!(
            radius_error.abs() < 4.0 * radius_se,
            "sphere {k}: radius {radius_error}"
        );
        fits.push((fit, cov));
    }
    let ((a, ca), (b, cb)) = (fits[0], fits[1]);
    let d = (a.centre_m - b.centre_m).norm();
    let along = (a.centre_m - b.centre_m) / d;
    let var = |c: &Matrix4<f64>| (along.transpose() * c.fixed_view::<3, 3>(0, 0) * along)[0];
    let d_se = (var(&ca) + var(&cb)).sqrt();
    let d_error = d - SPHERE_CENTRE_DISTANCE_M;
    println!(
        "centre distance {:.4} mm (true {:.4}, error {:+.1} um, standard error {:.1} um)",
        d * 1e3,
        SPHERE_CENTRE_DISTANCE_M * 1e3,
        d_error * 1e6,
        d_se * 1e6
    );
    assert!(
        d_error.abs() < 4.0 * d_se,
        "centre distance off by {d_error} m"
    );
}
