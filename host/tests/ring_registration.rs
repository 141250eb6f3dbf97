//! Issue 21: scanning with more than two heads. The twin's `ring-3` and
//! `ring-4` scenes (a turbine-blade-like part inside a ring of three or
//! four heads, no two of which see it whole) are rendered head by head
//! (hil_sim::twin: ray-cast scene, defocused 8-bit DMD fringes, 12-bit
//! sensor noise), each head reconstructed on its own with the twin's true
//! devices (`calibration::from_twin`, as `twin_accuracy.rs` does), each
//! head's pose in head 0's frame disturbed by 1-2 degrees and 3-5 mm, then
//! registered by `fusion::register_views` (all poses at once, head 0 fixed)
//! and merged. Measured against the twin's per-pixel truth; prints a table
//! per scene. Run with
//! `cargo test -p slscan --test ring_registration -- --nocapture`.
//!
//! This is the reconstruction the scan pipeline does per head, driven here
//! without the board: `slscan scan --sim` does not yet plan more than two
//! heads, so the frames are rendered straight from the twin with one
//! projector on at a time (the sequential mode's lighting).

use std::f64::consts::TAU;
use std::sync::Arc;

use hil_sim::twin::ring_scenes::RingLayout;
use hil_sim::twin::scenes::{built_in, Detail};
use hil_sim::twin::{BitDepth, Exposure, Fringe, Pattern, ProjectorTimeline, SensorModel, TwinRig};
use nalgebra::{Isometry3, Point3, Vector3};
use slscan::fusion::synthetic::{perturbed, pose_error};
use slscan::fusion::{
    merge_views, register_views, DuplicateRule, IcpParams, MergeParams, MultiViewParams, PointCloud,
};
use slscan::raster::Raster;
use slscan::reconstruct::{ReconstructConfig, Reconstructor};
use slscan::scan::metrics::{coverage, point_error_m, samples, Sample};
use slscan::sim::calibration::from_twin::head_from_twin;
use slscan::sim::truth::ground_truth;
use slscan::unwrap::PixelStatus;

/// Coarse renders keep the suite quick on 2 cores: 1.2 mm per camera pixel at 0.5 m.
const DETAIL: Detail = Detail {
    camera: (320, 240),
    projector: (640, 400),
};
const STEPS: usize = 4;
/// Heterodyne periods, DMD pixels (beat 1320 px > the 640 px DMD).
const PERIODS: [f64; 3] = [20.0, 22.0, 24.0];
/// About 5600 e- on a white patch at 0.5 m: nothing saturates (as twin_accuracy.rs).
const EXPOSURE_S: f64 = 0.7e-3;
/// The work volume: a ball about the ring's centre, metres. It holds the
/// blade (half-diagonal 0.12 m) and none of the enclosure (1.2 m out).
const WORK_RADIUS_M: f64 = 0.2;

/// Head `h`'s `STEPS` x `PERIODS` column fringes, its projector alone on.
fn fringe_frames(twin: &TwinRig, h: usize, seed: u64) -> Vec<Raster<f32>> {
    let (w, hgt) = DETAIL.projector;
    let renderer = twin.renderer(h).unwrap();
    let projectors = twin.rig().projectors.len();
    let mut frames = Vec::new();
    for (k, &period_px) in PERIODS.iter().enumerate() {
        for n in 0..STEPS {
            let fringe = Fringe {
                period_px,
                angle_rad: 0.0,
                shift_rad: TAU * n as f64 / STEPS as f64,
            };
            let pattern = Arc::new(Pattern::fringe(w, hgt, &fringe, BitDepth::Eight));
            let timelines: Vec<ProjectorTimeline> = (0..projectors)
                .map(|p| {
                    if p == h {
                        ProjectorTimeline::single(pattern.clone(), 0.0, EXPOSURE_S)
                    } else {
                        ProjectorTimeline::dark()
                    }
                })
                .collect();
            let exposure = Exposure {
                start_s: 0.0,
                end_s: EXPOSURE_S,
            };
            let (image, _) = renderer
                .image(
                    &timelines,
                    exposure,
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

/// One head's cloud (its camera frame) and, per point, its error against
/// the true surface point of its pixel, metres.
struct HeadCloud {
    cloud: PointCloud,
    errors_m: Vec<f64>,
}

fn reconstruct_head(
    twin: &TwinRig,
    h: usize,
    head_from_world: &Isometry3<f64>,
    centre_m: [f64; 3],
) -> HeadCloud {
    let head = head_from_twin(twin.rig(), h, h, &format!("head-{h}")).unwrap();
    let mut config = ReconstructConfig::new(PERIODS.to_vec());
    // The noise of a mid-grey mono12 pixel (about 3000 e-), as twin_accuracy.rs.
    config.noise_sigma = SensorModel::mono12().output_sigma(3000.0) as f32;
    let frames = fringe_frames(twin, h, 40 + h as u64);
    let refs: Vec<&Raster<f32>> = frames.iter().collect();
    let rec = Reconstructor::from_head(&head, config)
        .unwrap()
        .reconstruct(&refs, None)
        .unwrap();
    let truth = twin.renderer(h).unwrap();
    let truth_m = &truth.geometry().point_m;
    // Where the blade's centre is in this head's frame: the rig's layout,
    // known to the user as the cell's work volume.
    let centre = (head_from_world * Point3::from(Vector3::from(centre_m))).coords;
    let (mut points, mut quality, mut errors_m) = (Vec::new(), Vec::new(), Vec::new());
    for (i, px) in rec.pixels.iter().enumerate() {
        let p = Vector3::new(px.point_m[0], px.point_m[1], px.point_m[2]).cast::<f64>();
        if px.status != PixelStatus::Valid || (p - centre).norm() > WORK_RADIUS_M {
            continue;
        }
        points.push(p);
        quality.push(px.sigma_m);
        // A valid point whose pixel sees no surface cannot be: count it as
        // a metre off so the RMSE shows it.
        errors_m.push(if truth_m[i][0].is_finite() {
            point_error_m(&px.point_m, &truth_m[i], head_from_world)
        } else {
            1.0
        });
    }
    HeadCloud {
        cloud: PointCloud {
            points,
            normals: None,
            quality: Some(quality),
        },
        errors_m,
    }
}

fn rms(v: &[f64]) -> f64 {
    (v.iter().map(|e| e * e).sum::<f64>() / v.len() as f64).sqrt()
}

fn in_frame(cloud: &PointCloud, pose: &Isometry3<f64>) -> Vec<Vector3<f64>> {
    cloud.transformed(pose).points
}

fn check_ring(scene_name: &str, layout: RingLayout) {
    let (scene, rig) = built_in(scene_name, &DETAIL).unwrap();
    let heads = rig.cameras.len();
    let twin = Arc::new(TwinRig::new(scene, rig).unwrap());
    let truth = ground_truth(&twin, heads).unwrap();
    // Head 0's frame is the common frame; true poses head 0 <- head k.
    let head0_from_world = truth.head_from_world(0);
    let true_pose: Vec<Isometry3<f64>> = (0..heads)
        .map(|h| head0_from_world * truth.head_from_world(h).inverse())
        .collect();
    let centre_m = layout.centre_m();
    let centre = (head0_from_world * Point3::from(Vector3::from(centre_m))).coords;

    let clouds: Vec<HeadCloud> = (0..heads)
        .map(|h| reconstruct_head(&twin, h, &truth.head_from_world(h), centre_m))
        .collect();
    // What any head could measure: every pixel of every camera that sees
    // the blade lit by its own projector, in head 0's frame.
    let surface: Vec<Sample> = truth
        .cameras
        .iter()
        .flat_map(|c| samples(c, &c.own_object, &head0_from_world))
        .collect();

    // Each head but 0 put 1-2 degrees (about an oblique axis through the
    // part) and 3-5 mm off its true pose, as an imprecise ring calibration.
    let initial: Vec<Isometry3<f64>> = true_pose
        .iter()
        .enumerate()
        .map(|(k, t)| {
            if k == 0 {
                return *t;
            }
            let f = k as f64;
            perturbed(
                t,
                &centre,
                &Vector3::new(0.3 * f, -0.8, 0.5 - 0.2 * f),
                1.0 + 0.3 * f,
                &Vector3::new(1.0, -f, 0.5 * f),
                0.002 + 0.001 * f,
            )
        })
        .collect();
    let params = MultiViewParams {
        icp: IcpParams {
            // Wider than the worst start displacement (5 mm + 2 deg x 70 mm).
            initial_gate_m: 0.02,
            // Under two point spacings (1.2 mm pixels). Measured: with 3 mm
            // ring-3's heads were left about 100 um and 0.03-0.04 deg off,
            // at this test's bound, and 30 um / 0.02 deg with 2 mm; ring-4's
            // go from 25 to 55-75 um, well inside it.
            final_gate_m: 0.002,
            // Steps below 5 % of one point's noise (about 200 um here, RMS
            // against truth) change nothing the figures can show.
            convergence_rotation_deg: 1e-3,
            convergence_translation_m: 10e-6,
            ..IcpParams::default()
        },
        normals_k: 10,
    };
    let views: Vec<PointCloud> = clouds.iter().map(|c| c.cloud.clone()).collect();
    let result = register_views(&views, &initial, &params).unwrap();
    let merge = MergeParams {
        radius_m: 0.6e-3,
        rule: DuplicateRule::WeightedMean,
        default_sigma_m: 50e-6,
    };
    let (fused, _) = merge_views(&views, &result, &merge).unwrap();

    // Per head: coverage at its registered pose, RMSE against its pixels'
    // truth, RMS overlap residual over the pairs it is in, correction.
    println!(
        "{scene_name}: {heads} heads, {} surface samples\n{result}",
        surface.len()
    );
    println!("head | points | coverage | RMSE vs truth um | overlap RMSE um | correction deg / mm | pose error deg / um");
    let mut head_cov = Vec::new();
    let mut head_rmse = Vec::new();
    for h in 0..heads {
        let v = &result.views[h];
        let cov = coverage(&in_frame(&views[h], &v.pose), &surface).unwrap();
        let rmse = rms(&clouds[h].errors_m);
        let (mut sum, mut n) = (0.0, 0usize);
        for p in result
            .pairs
            .iter()
            .filter(|p| p.inliers > 0 && (p.heads.0 == h || p.heads.1 == h))
        {
            sum += p.overlap_rmse_m.powi(2) * p.inliers as f64;
            n += p.inliers;
        }
        let overlap = (sum / n.max(1) as f64).sqrt();
        let (err_deg, err_m) = pose_error(&v.pose, &true_pose[h], &centre);
        println!(
            "{h:4} | {:6} | {cov:8.3} | {:16.1} | {:15.1} | {:8.3} / {:6.3} | {err_deg:.4} / {:.1}",
            views[h].len(),
            rmse * 1e6,
            overlap * 1e6,
            v.rotation_correction_deg,
            v.translation_correction_m * 1e3,
            err_m * 1e6
        );
        head_cov.push(cov);
        head_rmse.push(rmse);
    }
    let fused_cov = coverage(&fused.points, &surface).unwrap();
    println!("fused | {:6} | {fused_cov:8.3}", fused.len());
    for p in result.pairs.iter().filter(|p| p.inliers > 0) {
        println!(
            "pair {}-{}: overlap RMSE {:.1} um over {} pairs",
            p.heads.0,
            p.heads.1,
            p.overlap_rmse_m * 1e6,
            p.inliers
        );
    }

    assert!(result.converged, "{result}");
    // The noise of one point: the worst head's RMS error against truth.
    let point_noise_m = head_rmse.iter().copied().fold(0.0, f64::max);
    for h in 1..heads {
        let (err_deg, err_m) = pose_error(&result.views[h].pose, &true_pose[h], &centre);
        let (start_deg, _) = pose_error(&initial[h], &true_pose[h], &centre);
        // The correction undoes the disturbance: what is left moves the
        // blade's far end (0.1 m from the centre) by less than one point's
        // noise, since thousands of points pin the pose.
        assert!(
            err_m + err_deg.to_radians() * 0.1 < point_noise_m,
            "{scene_name} head {h}: {err_deg} deg, {err_m} m left (point noise {point_noise_m} m)"
        );
        // The correction's angle is the disturbance's, to the same bound:
        // a turn that moves the far end by one point's noise.
        let bound_deg = (point_noise_m / 0.1).to_degrees();
        let left_deg = (result.views[h].rotation_correction_deg - start_deg).abs();
        assert!(left_deg < bound_deg, "head {h}: {left_deg} deg");
    }
    // Overlap residuals are two points' noise (sqrt 2 sigma) projected on
    // the normal, at most: a misregistration would add to them.
    for p in result.pairs.iter().filter(|p| p.inliers > 0) {
        assert!(
            p.overlap_rmse_m < 2f64.sqrt() * point_noise_m,
            "{scene_name}: pair {:?} overlap RMSE {} m, point noise {point_noise_m} m",
            p.heads,
            p.overlap_rmse_m
        );
    }
    // Neighbours overlap: the ring is closed.
    for h in 0..heads {
        let next = (h + 1) % heads;
        let pair = (h.min(next), h.max(next));
        assert!(result.pairs.iter().any(|p| p.heads == pair), "{pair:?}");
    }
    // The fused cloud covers more than any head: every head adds what only it sees.
    for (h, &c) in head_cov.iter().enumerate() {
        assert!(
            fused_cov > c + 0.1,
            "{scene_name}: fused {fused_cov}, head {h} {c}"
        );
    }
}

/// Three heads 120 degrees apart register only because they look down
/// steeply (43 degrees, `RingLayout::THREE`) on a part with an upward,
/// curved face (the root dome). Two heads measure a point only where its
/// normal lies within about 70 degrees of both cameras and both projectors:
/// looking down 13 degrees as `ring-4` does, heads 0 and 1 shared a few
/// hundred points, the ring was a chain 0 - 2 - 1 and the joint solution
/// left along the blade's weakly seen screw direction (`Diverged` at the
/// first iteration, even from the true poses). From 43 degrees down every
/// pair shares the platform's, shroud's and dome's tops and the blade's
/// upward-tilted faces; the flat tops alone left the heads 37-50 degrees
/// down up to 2 mm and 0.5 deg off, slid and turned about the span, which
/// the dome pins.
/// `ring-4`'s neighbours, 90 degrees apart, overlap well from 13 degrees down.
#[test]
fn three_heads_around_a_blade_register_jointly_and_fuse_to_more_than_any_head() {
    check_ring("ring-3", RingLayout::THREE);
}

#[test]
fn four_heads_around_a_blade_register_jointly_and_fuse_to_more_than_any_head() {
    check_ring("ring-4", RingLayout::FOUR);
}
