//! Accuracy against the DIGITAL TWIN's ground truth (hil_sim::twin renders: ray-cast
//! scenes, defocused 8-bit DMD fringes, shot + read + quantisation noise of a 12-bit
//! sensor), reconstructed with the twin's true devices converted by
//! `calibration::from_twin`. Every figure is printed; run with
//! `cargo test -p slscan --test twin_accuracy -- --nocapture`.
//! (The formula-based tests in `accuracy.rs` test the kernels in isolation.)

use std::f64::consts::{PI, TAU};
use std::sync::Arc;

use hil_sim::twin::scenes::CHECKERBOARD;
use hil_sim::twin::scenes::{built_in, Detail, SPHERE_CENTRE_DISTANCE_M, SPHERE_RADII_M};
use hil_sim::twin::{
    BitDepth, Exposure, Frame, Fringe, Pattern, ProjectorTimeline, Renderer, SensorModel,
};
use nalgebra::Point3;
use slscan::calibration::board::Target;
use slscan::calibration::head::{calibrate_head, HeadOptions};
use slscan::calibration::rodrigues::rotation_angle_between;
use slscan::calibration::{Head, PinholeModel, Pose};
use slscan::fit::fit_sphere;
use slscan::phase::{phase_noise_crb, wrap_pi, PhaseShift};
use slscan::raster::Raster;
use slscan::reconstruct::{ReconstructConfig, Reconstruction, Reconstructor};
use slscan::sim::calibration::from_twin::{head_from_twin, pose_from_twin};
use slscan::sim::calibration::twin_head::{self, TwinHead};
use slscan::unwrap::PixelStatus;

/// Small renders: a 320x240 camera and a 640x400 DMD keep the suite fast on 2 cores.
const DETAIL: Detail = Detail {
    camera: (320, 240),
    projector: (640, 400),
};
const STEPS: usize = 4;
/// Heterodyne periods, DMD pixels, finest first (beat 1320 px > the 640 px DMD).
const PERIODS: [f64; 3] = [20.0, 22.0, 24.0];
/// Pattern on and shutter open for 0.7 ms: about 5600 e- on a white patch at 0.5 m
/// (full well 10 ke-), so nothing saturates.
const EXPOSURE_S: f64 = 0.7e-3;

/// A scene's camera-0 renderer, its truth, and head 0 (the twin's true devices).
struct Twin {
    renderer: Renderer,
    projectors: usize,
    head: Head,
    truth: Frame,
}

fn timelines(pattern: Arc<Pattern>, projectors: usize) -> Vec<ProjectorTimeline> {
    let mut t = vec![ProjectorTimeline::single(pattern, 0.0, EXPOSURE_S)];
    t.extend((1..projectors).map(|_| ProjectorTimeline::dark()));
    t
}

fn exposure() -> Exposure {
    Exposure {
        start_s: 0.0,
        end_s: EXPOSURE_S,
    }
}

fn twin(scene_name: &str) -> Twin {
    let (scene, rig) = built_in(scene_name, &DETAIL).unwrap();
    let renderer = Renderer::new(&scene, &rig, 0, 0.0).unwrap();
    let (w, h) = DETAIL.projector;
    let flat = Arc::new(Pattern::flat(w, h, 0.5));
    let projectors = rig.projectors.len();
    let truth = renderer
        .frame(
            &timelines(flat, projectors),
            exposure(),
            &SensorModel::ideal(),
            0,
        )
        .unwrap();
    Twin {
        renderer,
        projectors,
        head: head_from_twin(&rig, 0, 0, "A").unwrap(),
        truth,
    }
}

/// `STEPS` column-fringe frames per period, noisy mono12 renders, in Reconstructor order.
fn fringe_frames(t: &Twin, periods: &[f64], seed: u64) -> Vec<Raster<f32>> {
    let (w, h) = DETAIL.projector;
    let mut frames = Vec::new();
    for (k, &period_px) in periods.iter().enumerate() {
        for n in 0..STEPS {
            let fringe = Fringe {
                period_px,
                angle_rad: 0.0,
                shift_rad: TAU * n as f64 / STEPS as f64,
            };
            let pattern = Arc::new(Pattern::fringe(w, h, &fringe, BitDepth::Eight));
            let (image, _) = t
                .renderer
                .image(
                    &timelines(pattern, t.projectors),
                    exposure(),
                    &SensorModel::mono12(),
                    seed * 1000 + (k * STEPS + n) as u64,
                )
                .unwrap();
            let (iw, ih) = (image.width as usize, image.height as usize);
            frames.push(Raster::from_vec(iw, ih, image.data).unwrap());
        }
    }
    frames
}

/// True absolute phase of the finest period at every pixel (NaN where not lit).
fn true_phase(t: &Twin, period_px: f64) -> Vec<f32> {
    t.truth.truth.absolute_phase(
        0,
        &Fringe {
            period_px,
            angle_rad: 0.0,
            shift_rad: 0.0,
        },
    )
}

#[test]
fn wrapped_phase_error_is_within_1_1_of_the_cramer_rao_bound_on_the_twin_plane() {
    let t = twin("plane");
    let sensor = SensorModel::mono12();
    let period_px = PERIODS[0];
    let frames = fringe_frames(&t, &[period_px], 1);
    let refs: Vec<&Raster<f32>> = frames.iter().collect();
    let out = PhaseShift::new(STEPS)
        .unwrap()
        .wrapped_phase(&refs)
        .unwrap();
    let want = true_phase(&t, period_px);
    let saturated = &t.truth.truth.saturated;
    let (mut sum_ratio2, mut sum_e2, mut sum_crb2, mut n) = (0.0f64, 0.0, 0.0, 0usize);
    for i in 0..want.len() {
        let b = f64::from(out.modulation.data[i]);
        if !want[i].is_finite() || saturated[i] || b < 0.05 {
            continue;
        }
        // Mean signal = measured background; output units -> electrons.
        let mean_e = f64::from(out.background.data[i]) * sensor.full_well_e / sensor.gain;
        let crb = phase_noise_crb(sensor.output_sigma(mean_e), STEPS, b);
        let e = f64::from(wrap_pi(out.phase.data[i] - want[i]));
        sum_ratio2 += (e / crb).powi(2);
        sum_e2 += e * e;
        sum_crb2 += crb * crb;
        n += 1;
    }
    let ratio = (sum_ratio2 / n as f64).sqrt();
    let rms_e = (sum_e2 / n as f64).sqrt();
    let rms_crb = (sum_crb2 / n as f64).sqrt();
    println!(
        "twin plane, {STEPS}-step, period {period_px} px: RMS wrapped-phase error {:.5} rad, \
         RMS CRB {:.5} rad, RMS(error/CRB) = {ratio:.4} over {n} pixels",
        rms_e, rms_crb
    );
    assert!(n > 320 * 240 / 2, "only {n} lit pixels");
    // Within 1.1x of the bound, and not far below it (which would mean a broken test).
    assert!((0.9..=1.1).contains(&ratio), "ratio {ratio}");
}

/// Columns, `PERIODS`, and the noise of a mid-grey mono12 pixel (about 3000 e-).
fn reconstruct_config() -> ReconstructConfig {
    let mut config = ReconstructConfig::new(PERIODS.to_vec());
    config.noise_sigma = SensorModel::mono12().output_sigma(3000.0) as f32;
    config
}

/// Reconstructs camera 0 of a scene with its true head (columns, `PERIODS`).
fn reconstruct(t: &Twin, seed: u64) -> Reconstruction {
    let frames = fringe_frames(t, &PERIODS, seed);
    let refs: Vec<&Raster<f32>> = frames.iter().collect();
    Reconstructor::from_head(&t.head, reconstruct_config())
        .unwrap()
        .reconstruct(&refs, None)
        .unwrap()
}

#[test]
fn heterodyne_unwrapping_makes_no_order_errors_on_valid_pixels_of_built_in_scenes() {
    for (k, name) in ["plane", "spheres", "prism", "large-part"]
        .into_iter()
        .enumerate()
    {
        let t = twin(name);
        let rec = reconstruct(&t, 10 + k as u64);
        let want = true_phase(&t, PERIODS[0]);
        let (mut lit, mut valid, mut wrong, mut valid_unlit) = (0, 0, 0, 0);
        for (i, p) in rec.pixels.iter().enumerate() {
            let ok = p.status == PixelStatus::Valid;
            if want[i].is_finite() {
                lit += 1;
            }
            if !ok {
                continue;
            }
            valid += 1;
            if !want[i].is_finite() {
                valid_unlit += 1;
            } else if (f64::from(p.phase_u) - f64::from(want[i])).abs() > PI {
                wrong += 1;
            }
        }
        println!(
            "  statuses: masked {} unreliable {} unreached {}",
            rec.count(PixelStatus::Masked),
            rec.count(PixelStatus::Unreliable),
            rec.count(PixelStatus::Unreached)
        );
        println!(
            "twin {name} (camera 0): {valid} valid pixels of {lit} lit, {wrong} wrong fringe \
             orders, {valid_unlit} valid but unlit (shadowed) pixels"
        );
        assert_eq!(wrong, 0, "{name}: wrong fringe orders");
        assert_eq!(valid_unlit, 0, "{name}: shadowed pixels passed as valid");
        // Dim walls (albedo 0.2..0.4 behind the parts) are rightly refused as too noisy to
        // unwrap; the bright plane must be nearly all valid, every scene must give points.
        assert!(valid > 2000, "{name}: only {valid} valid pixels");
        if name == "plane" {
            assert!(valid as f64 > 0.95 * lit as f64, "{name}: {valid} of {lit}");
        }
    }
}

/// Valid reconstructed points on scene object `k`, with their pixel indices.
fn object_points(
    rec: &Reconstruction,
    objects: &[u16],
    k: usize,
) -> (Vec<usize>, Vec<Point3<f64>>) {
    rec.pixels
        .iter()
        .enumerate()
        .filter(|(i, p)| p.status == PixelStatus::Valid && usize::from(objects[*i]) == k)
        .map(|(i, p)| {
            (
                i,
                Point3::new(p.point_m[0], p.point_m[1], p.point_m[2]).cast(),
            )
        })
        .unzip()
}

/// The physical noise limit of pixel `i`'s point along its ray, metres: the CRB phase
/// noise at the pixel's own modulation and its own signal's sensor noise (shot, read
/// and quantisation noise of its background level), carried into metres as the
/// pipeline's `sigma_m` is (which assumes one mid-grey noise level, `config_sigma`,
/// for every pixel).
fn ray_noise_limit_m(rec: &Reconstruction, i: usize, config_sigma: f64) -> f64 {
    let sensor = SensorModel::mono12();
    let p = rec.pixels.get(i);
    let mean_e = f64::from(p.background) * sensor.full_well_e / sensor.gain;
    f64::from(p.sigma_m) * sensor.output_sigma(mean_e) / config_sigma
}

#[test]
fn calibration_spheres_fit_at_the_noise_limit_to_their_true_radii_and_centre_distance() {
    let t = twin("spheres");
    let objects = t.truth.truth.object();
    let (scene, rig) = built_in("spheres", &DETAIL).unwrap();
    // The reconstruction is in the head (camera) frame: carry the twin's truth into it.
    let to_head = pose_from_twin(&rig.cameras[0].model.world_from_device);
    let truth_m = &t.truth.truth.geometry.point_m;
    let config_sigma = f64::from(reconstruct_config().noise_sigma);
    let rec = reconstruct(&t, 30);
    let mut fits = Vec::new();
    for (k, &radius_m) in SPHERE_RADII_M.iter().enumerate() {
        let (pixels, pts) = object_points(&rec, objects, k);
        let fit = fit_sphere(&pts).unwrap();
        let centre_true = to_head.apply(&Point3::from(scene.objects[k].pose.translation.vector));
        // Per point: error along the ray against the twin's surface point, and the noise
        // limit along the ray and along the sphere's normal (what the fit RMSE measures).
        let (mut err2, mut err_sum, mut ratio2, mut limit_normal2) = (0.0, 0.0, 0.0, 0.0);
        for (&i, p) in pixels.iter().zip(&pts) {
            let w = truth_m[i];
            let truth = to_head.apply(&Point3::new(w[0], w[1], w[2]).cast());
            let e = p.coords.norm() - truth.coords.norm();
            let limit = ray_noise_limit_m(&rec, i, config_sigma);
            let cos = (p - fit.centre_m)
                .normalize()
                .dot(&p.coords.normalize())
                .abs();
            err2 += e * e;
            err_sum += e;
            ratio2 += (e / limit).powi(2);
            limit_normal2 += (limit * cos).powi(2);
        }
        let n = pts.len() as f64;
        let (err_rms, err_mean) = ((err2 / n).sqrt(), err_sum / n);
        let ratio = (ratio2 / n).sqrt();
        let limit_m = (limit_normal2 / n).sqrt();
        let centre_um = (fit.centre_m - centre_true).norm() * 1e6;
        println!(
            "sphere {}: {} points, radius {:.4} mm (true {:.4}, error {:+.1} um), centre error \
             {centre_um:.1} um; fit RMSE {:.1} um vs noise limit {:.1} um (ratio {:.3}); error \
             along the ray vs truth {:.1} um RMS, mean {:+.1} um, RMS(error / limit) {ratio:.3}",
            k + 1,
            pts.len(),
            fit.radius_m * 1e3,
            radius_m * 1e3,
            (fit.radius_m - radius_m) * 1e6,
            fit.rms_m * 1e6,
            limit_m * 1e6,
            fit.rms_m / limit_m,
            err_rms * 1e6,
            err_mean * 1e6
        );
        assert!(pts.len() > 500, "sphere {k}: {} points", pts.len());
        // Noise-limited: the fit RMSE is the physical limit's, the per-point errors are
        // the predicted noise, and their mean shows no bias beyond its standard error.
        assert!((0.9..1.1).contains(&(fit.rms_m / limit_m)), "sphere {k}");
        assert!((0.9..1.1).contains(&ratio), "sphere {k}: {ratio}");
        assert!(
            err_mean.abs() < 4.0 * err_rms / n.sqrt(),
            "sphere {k}: bias {err_mean}"
        );
        assert!(centre_um < 150.0, "sphere {k} centre off by {centre_um} um");
        fits.push(fit);
    }
    let d = (fits[0].centre_m - fits[1].centre_m).norm();
    println!(
        "centre distance {:.4} mm (true {:.4}, error {:+.1} um)",
        d * 1e3,
        SPHERE_CENTRE_DISTANCE_M * 1e3,
        (d - SPHERE_CENTRE_DISTANCE_M) * 1e6
    );

    // Radii and centre distance over noise seeds: their spread is the noise's, their mean
    // must be zero within its standard error (a calibration or model bias would show).
    let seeds = 30..38u64;
    let mut errors_um = vec![Vec::new(); 3];
    for seed in seeds.clone() {
        let rec = reconstruct(&t, seed);
        let fits: Vec<_> = (0..2)
            .map(|k| fit_sphere(&object_points(&rec, objects, k).1).unwrap())
            .collect();
        for k in 0..2 {
            errors_um[k].push((fits[k].radius_m - SPHERE_RADII_M[k]) * 1e6);
        }
        let d = (fits[0].centre_m - fits[1].centre_m).norm();
        errors_um[2].push((d - SPHERE_CENTRE_DISTANCE_M) * 1e6);
    }
    for (what, e) in ["radius 1", "radius 2", "centre distance"]
        .iter()
        .zip(&errors_um)
    {
        let n = e.len() as f64;
        let mean = e.iter().sum::<f64>() / n;
        let std = (e.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
        println!(
            "{what} error over seeds {seeds:?}: mean {mean:+.1} um, std {std:.1} um, worst {:.1} um",
            e.iter().fold(0.0f64, |m, v| m.max(v.abs()))
        );
        assert!(mean.abs() < 3.5 * std / n.sqrt(), "{what}: bias {mean} um");
        assert!(
            std < 60.0 && e.iter().all(|v| v.abs() < 150.0),
            "{what}: {e:?}"
        );
    }
}

/// Rotation angle (degrees) and translation distance (mm) between two poses.
fn pose_error(a: &Pose, b: &Pose) -> (f64, f64) {
    (
        rotation_angle_between(&a.rotation, &b.rotation).to_degrees(),
        (a.translation_m - b.translation_m).norm() * 1e3,
    )
}

fn print_device(what: &str, got: &PinholeModel, truth: &PinholeModel) {
    let (g, t) = (got.intrinsics, truth.intrinsics);
    let (gd, td) = (got.distortion, truth.distortion);
    println!(
        "{what}: fx {:.2} (true {:.2}) fy {:.2} ({:.2}) cx {:.2} ({:.2}) cy {:.2} ({:.2}) | \
         k1 {:+.4} ({:+.4}) k2 {:+.4} ({:+.4}) p1 {:+.5} ({:+.5}) p2 {:+.5} ({:+.5})",
        g.fx,
        t.fx,
        g.fy,
        t.fy,
        g.cx,
        t.cx,
        g.cy,
        t.cy,
        gd.k1,
        td.k1,
        gd.k2,
        td.k2,
        gd.p1,
        td.p1,
        gd.p2,
        td.p2
    );
}

#[test]
fn head_calibration_from_twin_checkerboard_views_recovers_the_true_devices() {
    let detail = Detail {
        camera: (640, 480),
        projector: (1280, 800),
    };
    let sim = TwinHead::standard(12, &detail);
    let captures = sim.render(&SensorModel::mono12(), 5, true).unwrap();
    let target = Target::Checkerboard(twin_head::board());
    let cal = calibrate_head(
        "A",
        &target,
        &captures,
        &sim.projector_spec(),
        &HeadOptions::default(),
    )
    .unwrap();
    let stage = &cal.camera;
    println!(
        "{} of {} views used; reprojection RMS: camera {:.4} px, projector {:.4} px, pair {:.4} px",
        stage.names.len(),
        captures.len(),
        stage.calibration.rms_px,
        cal.projector.rms_px,
        cal.pair.rms_px
    );
    for (name, why) in &stage.skipped {
        println!("skipped {name}: {why}");
    }
    print_device("camera   ", &cal.head.camera, &sim.truth.camera);
    print_device("projector", &cal.head.projector, &sim.truth.projector);

    // Detected corners against the twin's true corner pixels.
    let camera_truth = &sim.rig.cameras[0].model;
    let (mut sum2, mut n, mut flipped) = (0.0, 0usize, 0usize);
    let mut worst_view = (0.0f64, 0.0f64);
    let mut mean_err = [0.0f64; 2];
    for (name, corners) in stage.names.iter().zip(&stage.corners_px) {
        let v: usize = name.trim_start_matches("view_").parse().unwrap();
        let truth: Vec<[f64; 2]> = CHECKERBOARD
            .corners_px(&sim.world_from_board[v], camera_truth)
            .into_iter()
            .map(|c| c.unwrap())
            .collect();
        let err2 = |rev: bool| -> f64 {
            corners
                .iter()
                .enumerate()
                .map(|(i, c)| {
                    let t = truth[if rev { truth.len() - 1 - i } else { i }];
                    (c.x - t[0]).powi(2) + (c.y - t[1]).powi(2)
                })
                .sum()
        };
        let (direct, reversed) = (err2(false), err2(true));
        let rev = reversed < direct;
        for (i, c) in corners.iter().enumerate() {
            let t = truth[if rev { truth.len() - 1 - i } else { i }];
            mean_err[0] += c.x - t[0];
            mean_err[1] += c.y - t[1];
        }
        flipped += usize::from(rev);
        sum2 += direct.min(reversed);
        n += corners.len();
        // The recovered view pose against the truth numbered the same way.
        let k = stage.names.iter().position(|m| m == name).unwrap();
        let want = if rev {
            sim.flipped_board_pose(v)
        } else {
            sim.board_pose(v)
        };
        let (deg, mm) = pose_error(&stage.calibration.board_poses[k], &want);
        worst_view = (worst_view.0.max(deg), worst_view.1.max(mm));
    }
    let corner_rms = (sum2 / n as f64).sqrt();
    println!(
        "mean corner offset detected - true: ({:+.4}, {:+.4}) px",
        mean_err[0] / n as f64,
        mean_err[1] / n as f64
    );
    println!(
        "corner detection vs twin truth: {corner_rms:.4} px RMS over {n} corners \
         ({flipped} views numbered from the far corner)"
    );
    println!(
        "view poses vs truth: worst rotation {:.4} deg, worst translation {:.3} mm",
        worst_view.0, worst_view.1
    );
    let (deg, mm) = pose_error(&cal.head.projector.pose, &sim.truth.projector.pose);
    println!("camera->projector pose vs truth: rotation {deg:.4} deg, translation {mm:.3} mm");

    // Bounds for 12 views of a board covering about a third of the image, rendered with
    // 4x4 rays per pixel (area-integrating pixels), measured: corners 0.032 px RMS, focal
    // lengths within 0.05 %, principal points within 0.3 px, view poses within 0.02 deg
    // / 0.35 mm, camera -> projector within 0.02 deg / 0.07 mm. One aliased ray per
    // pixel (`pixel_samples = 1`) gives 0.16 px corners, fx -0.43 % and cy +6 px: it
    // fails these bounds. Projector reprojection 0.046 px; 0.091 px with plain
    // least-squares local homographies (no outlier rejection), which fails too.
    assert_eq!(stage.names.len(), captures.len(), "every view detected");
    assert!(corner_rms < 0.06, "corners {corner_rms} px");
    assert!(
        stage.calibration.rms_px < 0.06 && cal.projector.rms_px < 0.07,
        "reprojection RMS camera {} px, projector {} px",
        stage.calibration.rms_px,
        cal.projector.rms_px
    );
    for (got, truth) in [
        (&cal.head.camera, &sim.truth.camera),
        (&cal.head.projector, &sim.truth.projector),
    ] {
        let (g, t) = (got.intrinsics, truth.intrinsics);
        assert!(
            (g.fx / t.fx - 1.0).abs() < 0.002 && (g.fy / t.fy - 1.0).abs() < 0.002,
            "{g:?} vs {t:?}"
        );
        assert!(
            (g.cx - t.cx).abs() < 1.5 && (g.cy - t.cy).abs() < 1.5,
            "{g:?} vs {t:?}"
        );
        assert!((got.distortion.k1 - truth.distortion.k1).abs() < 0.005);
    }
    assert!(worst_view.0 < 0.1 && worst_view.1 < 1.5, "{worst_view:?}");
    assert!(
        deg < 0.1 && mm < 0.3,
        "camera->projector off by {deg} deg, {mm} mm"
    );
}
