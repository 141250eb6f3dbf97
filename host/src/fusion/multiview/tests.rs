//! Multi-view registration on synthetic rings of heads with known poses.

use super::*;
use crate::fusion::icp::register;
use crate::fusion::synthetic::{perturbed, pose_error};
use nalgebra::{Matrix3, Rotation3};
use rand::SeedableRng;
use rand_distr::{Distribution, StandardNormal};

/// Depth noise of every point along its camera ray, metres.
const NOISE_M: f64 = 50e-6;
/// Where the part sits in the ring's frame, and the ring's radius, metres.
const CENTRE_M: [f64; 3] = [0.0, 0.0, 0.5];
const RING_M: f64 = 0.5;

/// A closed, star-shaped bumpy part about 120 x 170 x 120 mm: its
/// distance from the centre along unit direction `u`, metres. Bumps of
/// 30-60 mm wavelength pin all six degrees of freedom of any overlap.
fn radius_m(u: &Vector3<f64>) -> f64 {
    0.06 * (1.0 + 0.3 * u.y * u.y + 0.15 * u.x * u.z)
        + 0.006 * (5.0 * u.x + 2.0 * u.y).sin() * (4.0 * u.z).cos()
        + 0.005 * (7.0 * u.y - 3.0 * u.z).sin()
        + 0.004 * (6.0 * u.x + 5.0 * u.z).cos()
}

fn surface(u: &Vector3<f64>) -> Vector3<f64> {
    Vector3::from(CENTRE_M) + radius_m(u) * u
}

/// Outward unit normal: the gradient of |p - c| - radius((p - c) / |p - c|).
fn normal(p: &Vector3<f64>) -> Vector3<f64> {
    let f = |q: Vector3<f64>| {
        let d = q - Vector3::from(CENTRE_M);
        d.norm() - radius_m(&d.normalize())
    };
    let h = 1e-7;
    Vector3::from_fn(|a, _| {
        let mut e = Vector3::zeros();
        e[a] = h;
        (f(p + e) - f(p - e)) / (2.0 * h)
    })
    .normalize()
}

/// World <- head k for `heads` heads evenly on the ring, aimed at the centre.
fn head_pose(k: usize, heads: usize) -> Isometry3<f64> {
    let phi = std::f64::consts::TAU * k as f64 / heads as f64;
    let c = Vector3::from(CENTRE_M);
    let eye = c + RING_M * Vector3::new(phi.sin(), 0.0, -phi.cos());
    let z = (c - eye).normalize();
    let y = Vector3::y();
    let x = y.cross(&z);
    let r = Rotation3::from_matrix_unchecked(Matrix3::from_columns(&[x, y, z]));
    Isometry3::from_parts(Translation3::from(eye), UnitQuaternion::from(r))
}

/// K clouds, each in its head's frame: the part's surface points that
/// face the head within 75 degrees of incidence (about 150 degrees of
/// its girth, so neighbours 90 or 120 degrees apart overlap), with
/// noise along the ray. Returns the clouds and the true poses
/// (head 0's frame <- head k's frame).
fn ring(heads: usize, samples: usize, seed: u64) -> (Vec<PointCloud>, Vec<Isometry3<f64>>) {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    let world: Vec<(Vector3<f64>, Vector3<f64>)> = (0..samples)
        .map(|i| {
            let y = 1.0 - 2.0 * (i as f64 + 0.5) / samples as f64;
            let rho = (1.0 - y * y).sqrt();
            let a = golden * i as f64;
            let p = surface(&Vector3::new(rho * a.cos(), y, rho * a.sin()));
            (p, normal(&p))
        })
        .collect();
    let to_head0 = head_pose(0, heads).inverse();
    let mut clouds = Vec::new();
    let mut truth = Vec::new();
    for k in 0..heads {
        let pose = head_pose(k, heads);
        let eye = pose.translation.vector;
        let points = world
            .iter()
            .filter(|(p, n)| n.dot(&(eye - p).normalize()) > 75f64.to_radians().cos())
            .map(|(p, _)| {
                let g: f64 = StandardNormal.sample(&mut rng);
                let noisy = p + NOISE_M * g * (p - eye).normalize();
                pose.inverse_transform_point(&Point3::from(noisy)).coords
            })
            .collect();
        clouds.push(PointCloud::from_points(points));
        truth.push(to_head0 * pose);
    }
    (clouds, truth)
}

/// The part's centre in head 0's frame, where pose errors are measured.
fn centre_in_head0(heads: usize) -> Vector3<f64> {
    head_pose(0, heads)
        .inverse_transform_point(&Point3::from(Vector3::from(CENTRE_M)))
        .coords
}

/// Head k's truth moved by 1-2 degrees about an oblique axis through
/// the part and 3-5 mm (different for each head); head 0 untouched.
fn perturb(truth: &[Isometry3<f64>], centre: &Vector3<f64>) -> Vec<Isometry3<f64>> {
    truth
        .iter()
        .enumerate()
        .map(|(k, t)| {
            if k == 0 {
                return *t;
            }
            let f = k as f64;
            perturbed(
                t,
                centre,
                &Vector3::new(0.3 * f, -0.8, 0.5 - 0.2 * f),
                1.0 + 0.3 * f,
                &Vector3::new(1.0, -f, 0.5 * f),
                0.002 + 0.001 * f,
            )
        })
        .collect()
}

fn params() -> MultiViewParams {
    MultiViewParams {
        icp: IcpParams {
            initial_gate_m: 0.02,
            final_gate_m: 0.002,
            ..IcpParams::default()
        },
        normals_k: 10,
    }
}

fn check_recovery(heads: usize) {
    let (clouds, truth) = ring(heads, 60_000, 11);
    let centre = centre_in_head0(heads);
    let initial = perturb(&truth, &centre);
    let result = register_views(&clouds, &initial, &params()).unwrap();
    println!(
        "ring of {heads}, points per head {:?}:\n{result}",
        clouds.iter().map(PointCloud::len).collect::<Vec<_>>()
    );
    assert!(result.converged, "{result}");
    for (k, v) in result.views.iter().enumerate() {
        let (rot_deg, trans_m) = pose_error(&v.pose, &truth[k], &centre);
        let (start_deg, start_m) = pose_error(&initial[k], &truth[k], &centre);
        println!(
            "head {k}: start {start_deg:.3} deg / {:.3} mm -> error {rot_deg:.5} deg / {:.2} um",
            start_m * 1e3,
            trans_m * 1e6
        );
        // Each pose rests on thousands of residuals, but the overlaps are
        // strips of a rounded part whose weakest direction (a turn about
        // its long axis) only its bumps pin: the pose is good to below
        // one point's noise at the part's centre, and 0.01 deg moves its
        // far side (60 mm out) by 10 um. (Measured: up to 0.007 deg and
        // 22 um; the same from the true poses as from the perturbed ones,
        // so it is the noise's, not a stop short of the minimum.)
        assert!(
            rot_deg < 0.01 && trans_m < NOISE_M,
            "head {k}: {rot_deg} deg {trans_m} m"
        );
        // The correction undoes the perturbation.
        assert!(
            (v.rotation_correction_deg - start_deg).abs() < 0.01,
            "head {k}"
        );
    }
    assert_eq!(result.views[0].pose, initial[0]);
    // Every neighbouring pair overlaps; its residual is at most two
    // points' noise (sigma * sqrt 2 = 71 um), less for points seen
    // obliquely (noise along the ray, residual along the normal); a
    // misregistration would add to it.
    for p in result.pairs.iter().filter(|p| p.inliers > 0) {
        assert!(p.overlap_rmse_m < NOISE_M * 2f64.sqrt(), "{p:?}");
    }
    for h in 0..heads {
        let next = (h + 1) % heads;
        let pair = (h.min(next), h.max(next));
        assert!(
            result
                .pairs
                .iter()
                .any(|p| p.heads == pair && p.inliers > 1000),
            "{pair:?}"
        );
    }
    // One merged cloud: fewer points than the heads together (the
    // overlaps merged), more than any one head.
    let merge = MergeParams {
        radius_m: 1e-3,
        rule: super::super::DuplicateRule::WeightedMean,
        default_sigma_m: NOISE_M as f32,
    };
    let (merged, reports) = merge_views(&clouds, &result, &merge).unwrap();
    let total: usize = clouds.iter().map(PointCloud::len).sum();
    assert_eq!(reports.len(), heads - 1);
    assert!(merged.len() < total && clouds.iter().all(|c| merged.len() > c.len()));
}

#[test]
fn three_heads_perturbed_by_degrees_and_millimetres_are_recovered() {
    check_recovery(3);
}

#[test]
fn four_heads_perturbed_by_degrees_and_millimetres_are_recovered() {
    check_recovery(4);
}

/// Chaining pairwise ICP round the ring adds each link's error; the
/// closing link (last head against head 0) then carries the sum. The
/// joint solution weighs the closing overlap like any other. Over a few
/// noise draws, the closing link's error is smaller jointly.
#[test]
fn the_ring_closes_better_jointly_than_by_chained_pairwise_icp() {
    let heads = 4;
    let centre = centre_in_head0(heads);
    let (mut joint2, mut chain2) = (0.0, 0.0);
    for seed in 0..3 {
        // Sparse clouds: the links' errors are large enough to add up visibly.
        let (clouds, truth) = ring(heads, 8_000, 100 + seed);
        let initial = perturb(&truth, &centre);
        let joint = register_views(&clouds, &initial, &params()).unwrap();
        let mut chained = vec![initial[0]];
        for k in 1..heads {
            let mut target = clouds[k - 1].clone();
            target.normals = Some(estimate_normals(&target.points, 10, &Vector3::zeros()).unwrap());
            let guess = initial[k - 1].inverse() * initial[k];
            let link = register(&clouds[k], &target, &guess, &params().icp).unwrap();
            chained.push(chained[k - 1] * link.transform);
        }
        let last = heads - 1;
        let err = |pose: &Isometry3<f64>| {
            let (deg, m) = pose_error(pose, &truth[last], &centre);
            // Displacement at 60 mm from the centre, the part's radius.
            m + deg.to_radians() * 0.06
        };
        let (j, c) = (err(&joint.views[last].pose), err(&chained[last]));
        println!(
            "seed {seed}: closing-link error joint {:.2} um, chained {:.2} um",
            j * 1e6,
            c * 1e6
        );
        joint2 += j * j;
        chain2 += c * c;
    }
    let (joint, chain) = ((joint2 / 3.0).sqrt(), (chain2 / 3.0).sqrt());
    println!(
        "RMS closing-link error: joint {:.2} um, chained {:.2} um",
        joint * 1e6,
        chain * 1e6
    );
    assert!(joint < chain, "joint {joint} m, chained {chain} m");
}

#[test]
fn a_head_that_overlaps_no_other_is_refused_by_name() {
    let (clouds, truth) = ring(3, 8_000, 5);
    let mut initial = truth.clone();
    // Head 2 placed a metre off: it overlaps nobody.
    initial[2] = Isometry3::translation(1.0, 0.0, 0.0) * initial[2];
    match register_views(&clouds, &initial, &params()) {
        Err(MultiViewError::Disconnected {
            unreached, edges, ..
        }) => {
            assert_eq!(unreached, vec![2]);
            assert_eq!(edges, vec![(0, 1)]);
        }
        other => panic!("{other:?}"),
    }
    assert!(matches!(
        register_views(&clouds[..1], &initial[..1], &params()),
        Err(MultiViewError::ViewCount { views: 1, poses: 1 })
    ));
    assert!(matches!(
        register_views(&clouds, &initial[..2], &params()),
        Err(MultiViewError::ViewCount { views: 3, poses: 2 })
    ));
}

#[test]
fn an_unfinished_registration_says_so_with_its_last_step() {
    let (clouds, truth) = ring(3, 8_000, 6);
    let initial = perturb(&truth, &centre_in_head0(3));
    let p = MultiViewParams {
        icp: IcpParams {
            max_iterations: 2,
            ..params().icp
        },
        ..params()
    };
    let result = register_views(&clouds, &initial, &p).unwrap();
    assert!(!result.converged);
    assert_eq!(result.iterations, 2);
    assert!(result.last_step_translation_m > p.icp.convergence_translation_m);
    assert!(result
        .to_string()
        .starts_with("did not converge in 2 iterations: last step"));
}
