//! Point-to-plane ICP with robust weights.
//!
//! Each iteration: move the source by the current estimate, find each
//! source point's nearest target point (kd-tree, rayon), drop pairs farther
//! than the gate, weight the point-to-plane residuals `r = n . (q - t)` with
//! a robust kernel whose scale is the MAD of the residuals, solve the
//! linearised 6x6 normal equations and compose the small update. The gate
//! starts wide (the calibration guess may be millimetres off) and halves
//! each iteration down to its final value, so far pairs help at the start
//! and the fine result sees only the true overlap.

use nalgebra::{Isometry3, Matrix6, Point3, Translation3, UnitQuaternion, Vector3, Vector6};
use rayon::prelude::*;

use super::nearest_cache::NearestCache;
use super::robust::mad_scale;
pub use super::robust::RobustKernel;
use super::{build_tree, morton_order, nearest_within, FusionError, PointCloud, Tree};

/// Settings of [`register`].
#[derive(Debug, Clone, PartialEq)]
pub struct IcpParams {
    /// Iteration limit.
    pub max_iterations: usize,
    /// Correspondence gate at the first iteration, metres: larger than the
    /// worst expected displacement of the initial guess over the overlap.
    pub initial_gate_m: f64,
    /// Gate the schedule halves down to, metres: a few point spacings.
    pub final_gate_m: f64,
    /// Robust kernel on the point-to-plane residuals.
    pub robust: RobustKernel,
    /// Floor of the robust scale, metres (noise-free data would give 0).
    pub min_scale_m: f64,
    /// Converged when the update rotates less than this (degrees) ...
    pub convergence_rotation_deg: f64,
    /// ... and translates less than this (metres), at the final gate.
    pub convergence_translation_m: f64,
    /// Fewest gated correspondences accepted.
    pub min_correspondences: usize,
    /// Largest rotation away from the initial guess before we call it
    /// diverged, degrees.
    pub max_correction_rotation_deg: f64,
    /// Largest translation away from the initial guess, metres.
    pub max_correction_translation_m: f64,
    /// Most source points used until the estimate converges on them (the
    /// wide gates, then the first steps at the final gate); the final
    /// iterations use every point.
    pub coarse_max_points: usize,
}

impl Default for IcpParams {
    fn default() -> Self {
        Self {
            max_iterations: 50,
            initial_gate_m: 0.02,
            final_gate_m: 0.002,
            robust: RobustKernel::Tukey { c: 4.685 },
            min_scale_m: 1e-7,
            convergence_rotation_deg: 1e-4,
            convergence_translation_m: 1e-6,
            min_correspondences: 100,
            max_correction_rotation_deg: 15.0,
            max_correction_translation_m: 0.05,
            coarse_max_points: 50_000,
        }
    }
}

impl IcpParams {
    /// Rejects non-positive or non-finite limits and inconsistent gates.
    pub(crate) fn validate(&self) -> Result<(), FusionError> {
        let positive = [
            ("initial_gate_m", self.initial_gate_m),
            ("final_gate_m", self.final_gate_m),
            ("min_scale_m", self.min_scale_m),
            ("convergence_rotation_deg", self.convergence_rotation_deg),
            ("convergence_translation_m", self.convergence_translation_m),
            (
                "max_correction_rotation_deg",
                self.max_correction_rotation_deg,
            ),
            (
                "max_correction_translation_m",
                self.max_correction_translation_m,
            ),
        ];
        for (name, value) in positive {
            if !(value.is_finite() && value > 0.0) {
                return Err(FusionError::BadParameter {
                    name,
                    value,
                    expected: "finite and > 0",
                });
            }
        }
        if self.final_gate_m > self.initial_gate_m {
            return Err(FusionError::BadParameter {
                name: "final_gate_m",
                value: self.final_gate_m,
                expected: "<= initial_gate_m",
            });
        }
        if self.max_iterations == 0 {
            return Err(FusionError::BadParameter {
                name: "max_iterations",
                value: 0.0,
                expected: ">= 1",
            });
        }
        if self.coarse_max_points < self.min_correspondences {
            return Err(FusionError::BadParameter {
                name: "coarse_max_points",
                value: self.coarse_max_points as f64,
                expected: ">= min_correspondences",
            });
        }
        if self.min_correspondences < 6 {
            return Err(FusionError::BadParameter {
                name: "min_correspondences",
                value: self.min_correspondences as f64,
                expected: ">= 6",
            });
        }
        let threshold = match self.robust {
            RobustKernel::None => 1.0,
            RobustKernel::Huber { k } => k,
            RobustKernel::Tukey { c } => c,
        };
        if !(threshold.is_finite() && threshold > 0.0) {
            return Err(FusionError::BadParameter {
                name: "robust threshold",
                value: threshold,
                expected: "finite and > 0",
            });
        }
        Ok(())
    }
}

/// What [`register`] found.
#[derive(Debug, Clone, PartialEq)]
pub struct IcpResult {
    /// Source-to-target transform (apply it to the source cloud).
    pub transform: Isometry3<f64>,
    /// `transform * initial^-1`: what ICP changed in the calibration guess,
    /// expressed in the target frame.
    pub correction: Isometry3<f64>,
    /// Rotation angle of `correction`, degrees.
    pub rotation_correction_deg: f64,
    /// How far `correction` moves the centre of the overlap (the inliers'
    /// centroid), metres. Unlike `correction.translation`, this does not
    /// grow with the distance from the target frame's origin (the camera)
    /// times the rotation correction.
    pub translation_correction_m: f64,
    /// RMS point-to-plane residual of the inlier pairs at the final
    /// transform, metres.
    pub overlap_rmse_m: f64,
    /// Fraction of source points with an inlier correspondence (within the
    /// final gate and non-zero robust weight).
    pub fitness: f64,
    /// Inlier pairs at the final transform.
    pub inliers: usize,
    /// Iterations run.
    pub iterations: usize,
    /// True when the update fell below the convergence thresholds at the
    /// final gate before `max_iterations`.
    pub converged: bool,
}

impl std::fmt::Display for IcpResult {
    /// One line for a person: millimetres, micrometres and degrees.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "correction {:.4} deg / {:.4} mm, overlap RMSE {:.2} um, fitness {:.3}, {} iterations ({})",
            self.rotation_correction_deg,
            self.translation_correction_m * 1e3,
            self.overlap_rmse_m * 1e6,
            self.fitness,
            self.iterations,
            if self.converged { "converged" } else { "not converged" }
        )
    }
}

/// A target cloud prepared for registration: the kd-tree is built once and
/// reused by every [`IcpTarget::register`] call.
pub struct IcpTarget<'a> {
    points: &'a [Vector3<f64>],
    normals: &'a [Vector3<f64>],
    tree: Tree,
}

/// One gated source-target pair.
struct Pair {
    /// Source point moved by the current estimate.
    q: Vector3<f64>,
    /// Target normal.
    n: Vector3<f64>,
    /// Point-to-plane residual, metres.
    r: f64,
}

impl<'a> IcpTarget<'a> {
    /// Checks the target (finite, normals present) and builds its kd-tree.
    pub fn new(target: &'a PointCloud) -> Result<Self, FusionError> {
        target.validate("target")?;
        if target.len() < 6 {
            return Err(FusionError::TooFewPoints {
                cloud: "target",
                points: target.len(),
                min: 6,
            });
        }
        let normals = target
            .normals
            .as_deref()
            .ok_or(FusionError::MissingNormals { cloud: "target" })?;
        Ok(Self {
            points: &target.points,
            normals,
            tree: build_tree(&target.points)?,
        })
    }

    /// Registers `source` onto this target starting from `initial`.
    pub fn register(
        &self,
        source: &[Vector3<f64>],
        initial: &Isometry3<f64>,
        params: &IcpParams,
    ) -> Result<IcpResult, FusionError> {
        params.validate()?;
        super::check_finite("source", source)?;
        if source.len() < params.min_correspondences {
            return Err(FusionError::TooFewPoints {
                cloud: "source",
                points: source.len(),
                min: params.min_correspondences,
            });
        }
        // Statistics do not depend on the order; the cache does.
        let source: Vec<Vector3<f64>> = morton_order(source).iter().map(|&i| source[i]).collect();
        let source = source.as_slice();
        let mut transform = *initial;
        let mut gate = params.initial_gate_m;
        let mut converged = false;
        let mut iterations = 0;
        // Until the estimate has converged on an even subsample (every m-th
        // point in Z-order) it is coarse anyway: the wide gates and the first
        // steps at the final gate run on the subsample, and only the last
        // few iterations on every point.
        let mut coarse = source.len() > params.coarse_max_points;
        let mut nearest = NearestCache::new(source.len());
        while iterations < params.max_iterations {
            let stride = if coarse {
                source.len().div_ceil(params.coarse_max_points)
            } else {
                1
            };
            let pairs = self.pairs(
                source,
                stride,
                &mut nearest,
                &transform,
                gate,
                iterations,
                params,
            )?;
            let sigma = robust_scale(&pairs, params.min_scale_m);
            let update =
                solve_update(&pairs, sigma, params.robust).ok_or(FusionError::Degenerate {
                    iteration: iterations,
                })?;
            transform = update * transform;
            iterations += 1;
            check_divergence(&transform, initial, iterations - 1, params)?;
            let (step_deg, step_m) = (
                update.rotation.angle().to_degrees(),
                update.translation.vector.norm(),
            );
            tracing::debug!(
                iterations,
                gate,
                pairs = pairs.len(),
                sigma,
                step_deg,
                step_m,
                "icp"
            );
            let small = step_deg < params.convergence_rotation_deg
                && step_m < params.convergence_translation_m;
            if small && gate <= params.final_gate_m {
                if !coarse {
                    converged = true;
                    break;
                }
                coarse = false;
            }
            gate = (gate * 0.5).max(params.final_gate_m);
        }
        // Statistics at the transform we return, with the final gate.
        let pairs = self.pairs(
            source,
            1,
            &mut nearest,
            &transform,
            gate,
            iterations,
            params,
        )?;
        let sigma = robust_scale(&pairs, params.min_scale_m);
        let (mut sum_r2, mut inliers, mut centroid) = (0.0, 0usize, Vector3::zeros());
        for p in &pairs {
            if params.robust.weight(p.r, sigma) > 0.0 {
                sum_r2 += p.r * p.r;
                inliers += 1;
                centroid += p.q;
            }
        }
        let centroid = Point3::from(centroid / inliers.max(1) as f64);
        let correction = transform * initial.inverse();
        // The overlap centre before the correction was applied.
        let before = correction.inverse_transform_point(&centroid);
        Ok(IcpResult {
            transform,
            correction,
            rotation_correction_deg: correction.rotation.angle().to_degrees(),
            translation_correction_m: (centroid - before).norm(),
            overlap_rmse_m: (sum_r2 / inliers.max(1) as f64).sqrt(),
            fitness: inliers as f64 / source.len() as f64,
            inliers,
            iterations,
            converged,
        })
    }

    /// Each source point moved by `transform` that has a target point
    /// within `gate` metres: where it lies and its signed point-to-plane
    /// residual (metres), for checking how well the two clouds agree.
    pub fn signed_residuals(
        &self,
        source: &[Vector3<f64>],
        transform: &Isometry3<f64>,
        gate: f64,
    ) -> Vec<(Vector3<f64>, f64)> {
        let gate2 = gate * gate;
        source
            .par_iter()
            .filter_map(|p| {
                let q = transform.transform_point(&Point3::from(*p)).coords;
                let (j, _) = nearest_within(&self.tree, &q, gate2)?;
                Some((q, self.normals[j].dot(&(q - self.points[j]))))
            })
            .collect()
    }

    /// Nearest-target pairs within `gate` metres of every `stride`-th
    /// source point moved by `transform`; `nearest` remembers the searches
    /// of earlier iterations (same `source`).
    #[allow(clippy::too_many_arguments)]
    fn pairs(
        &self,
        source: &[Vector3<f64>],
        stride: usize,
        nearest: &mut NearestCache,
        transform: &Isometry3<f64>,
        gate: f64,
        iteration: usize,
        params: &IcpParams,
    ) -> Result<Vec<Pair>, FusionError> {
        let pairs = nearest.nearest_within(
            &self.tree,
            self.points,
            source,
            stride,
            transform,
            gate,
            |q, j| {
                let n = self.normals[j];
                Pair {
                    q,
                    n,
                    r: n.dot(&(q - self.points[j])),
                }
            },
        );
        if pairs.len() < params.min_correspondences {
            return Err(FusionError::NoOverlap {
                correspondences: pairs.len(),
                min: params.min_correspondences,
                gate_m: gate,
                iteration,
            });
        }
        Ok(pairs)
    }
}

/// Registers `source` onto `target` (which needs normals) from `initial`,
/// usually the calibrated head-to-head extrinsic.
pub fn register(
    source: &PointCloud,
    target: &PointCloud,
    initial: &Isometry3<f64>,
    params: &IcpParams,
) -> Result<IcpResult, FusionError> {
    source.validate("source")?;
    IcpTarget::new(target)?.register(&source.points, initial, params)
}

/// Robust scale of the pairs' residuals.
fn robust_scale(pairs: &[Pair], min_scale_m: f64) -> f64 {
    mad_scale(pairs.iter().map(|p| p.r.abs()).collect(), min_scale_m)
}

/// Solves the weighted, linearised point-to-plane problem for a small
/// rigid update. The rotation is taken about the pairs' centroid, which
/// decouples rotation from translation in the 6x6 system (the target frame
/// origin may be half a metre away at the camera).
fn solve_update(pairs: &[Pair], sigma: f64, kernel: RobustKernel) -> Option<Isometry3<f64>> {
    let (wsum, qsum) = pairs
        .par_iter()
        .map(|p| {
            let w = kernel.weight(p.r, sigma);
            (w, w * p.q)
        })
        .reduce(|| (0.0, Vector3::zeros()), |a, b| (a.0 + b.0, a.1 + b.1));
    if wsum <= 0.0 {
        return None;
    }
    let centre = qsum / wsum;
    let (ata, atb) = pairs
        .par_iter()
        .fold(
            || (Matrix6::<f64>::zeros(), Vector6::<f64>::zeros()),
            |(mut ata, mut atb), p| {
                let w = kernel.weight(p.r, sigma);
                if w > 0.0 {
                    let c = (p.q - centre).cross(&p.n);
                    let a = Vector6::new(c.x, c.y, c.z, p.n.x, p.n.y, p.n.z);
                    ata += w * a * a.transpose();
                    atb -= (w * p.r) * a;
                }
                (ata, atb)
            },
        )
        .reduce(
            || (Matrix6::zeros(), Vector6::zeros()),
            |a, b| (a.0 + b.0, a.1 + b.1),
        );
    // Reject a system whose weakest direction carries no information: a
    // plane leaves three DOF free, a cylinder one.
    let eig = ata.symmetric_eigenvalues();
    let informative = eig.min() > 1e-12 * eig.max();
    if !informative {
        return None;
    }
    let x = ata.cholesky()?.solve(&atb);
    if !x.iter().all(|v| v.is_finite()) {
        return None;
    }
    let rotation = UnitQuaternion::from_scaled_axis(Vector3::new(x[0], x[1], x[2]));
    let tau = Vector3::new(x[3], x[4], x[5]);
    // q' = R (q - c) + c + tau
    let t = centre - rotation * centre + tau;
    Some(Isometry3::from_parts(Translation3::from(t), rotation))
}

fn check_divergence(
    transform: &Isometry3<f64>,
    initial: &Isometry3<f64>,
    iteration: usize,
    params: &IcpParams,
) -> Result<(), FusionError> {
    let correction = transform * initial.inverse();
    let rotation_deg = correction.rotation.angle().to_degrees();
    let translation_m = correction.translation.vector.norm();
    let finite = rotation_deg.is_finite() && translation_m.is_finite();
    if !finite
        || rotation_deg > params.max_correction_rotation_deg
        || translation_m > params.max_correction_translation_m
    {
        return Err(FusionError::Diverged {
            iteration,
            rotation_deg,
            translation_m,
        });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fusion::normals::estimate_normals;
    use crate::fusion::synthetic::{perturbed, pose_error, two_head_scene, TwoHeadScene};
    use rand::SeedableRng;
    use rand_distr::{Distribution, StandardNormal};

    const NOISE_M: f64 = 20e-6;

    fn scene(points_per_head: usize) -> TwoHeadScene {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let mut scene =
            two_head_scene(points_per_head, NOISE_M, || StandardNormal.sample(&mut rng));
        scene.a.normals = Some(estimate_normals(&scene.a.points, 10, &Vector3::zeros()).unwrap());
        scene
    }

    fn start(scene: &TwoHeadScene) -> Isometry3<f64> {
        // 2 deg about an oblique axis through the scene centre plus 5 mm.
        perturbed(
            &scene.b_to_a_m,
            &scene.centre_m,
            &Vector3::new(0.3, -0.8, 0.5),
            2.0,
            &Vector3::new(1.0, -1.0, 0.5),
            0.005,
        )
    }

    fn params() -> IcpParams {
        IcpParams {
            initial_gate_m: 0.02,
            final_gate_m: 0.0015,
            ..IcpParams::default()
        }
    }

    fn check_recovery(points_per_head: usize) {
        let scene = scene(points_per_head);
        let initial = start(&scene);
        let (rot0, trans0) = pose_error(&initial, &scene.b_to_a_m, &scene.centre_m);
        let t0 = std::time::Instant::now();
        let result = register(&scene.b, &scene.a, &initial, &params()).unwrap();
        let elapsed = t0.elapsed();
        let (rot, trans) = pose_error(&result.transform, &scene.b_to_a_m, &scene.centre_m);
        // Worst displacement of any B point (frame-independent check).
        let worst_m = scene
            .b
            .points
            .iter()
            .map(|p| {
                let p = Point3::from(*p);
                (result.transform * p - scene.b_to_a_m * p).norm()
            })
            .fold(0.0, f64::max);
        println!(
            "{points_per_head} pts/head: start {rot0:.3} deg / {:.3} mm -> error {:.2e} deg / {:.3} um \
             (worst point {:.3} um); rmse {:.2} um, fitness {:.3}, {} iterations, converged {}, {:.2?}",
            trans0 * 1e3,
            rot,
            trans * 1e6,
            worst_m * 1e6,
            result.overlap_rmse_m * 1e6,
            result.fitness,
            result.iterations,
            result.converged,
            elapsed
        );
        println!("{result}");
        assert!(result.converged);
        // The start error was 2 deg and 5 mm at the scene centre, which is
        // near the overlap centre (x = 0).
        assert!(
            (result.translation_correction_m - 0.005).abs() < 5e-4,
            "{result}"
        );
        assert!(
            result.to_string().starts_with("correction 1.99"),
            "{result}"
        );
        assert!(rot < 0.01, "rotation error {rot} deg");
        assert!(trans < 10e-6, "translation error {trans} m");
        assert!(worst_m < 10e-6, "worst point error {worst_m} m");
        // The correction undoes the perturbation.
        assert!((result.rotation_correction_deg - 2.0).abs() < 0.01);
        // Overlap is 30 of 75 mm of each head: fitness near 0.4.
        assert!(
            result.fitness > 0.3 && result.fitness < 0.5,
            "{}",
            result.fitness
        );
        // Residual: two noisy points, sigma * sqrt(2), plus normal noise.
        assert!(
            result.overlap_rmse_m < 3.0 * NOISE_M,
            "{}",
            result.overlap_rmse_m
        );
    }

    #[test]
    fn recovers_2deg_5mm_error_on_50k_points() {
        check_recovery(50_000);
    }

    /// The full-size case of issue 7: `cargo test -p slscan --lib
    /// --release --lib
    /// recovers_2deg_5mm_error_on_1m_points -- --ignored --nocapture`.
    #[test]
    #[ignore = "1M + 1M points: run it with --release"]
    fn recovers_2deg_5mm_error_on_1m_points() {
        check_recovery(1_000_000);
    }

    #[test]
    fn bad_inputs_are_typed_errors() {
        let scene = scene(3000);
        let initial = start(&scene);
        let mut nan = scene.b.clone();
        nan.points[5].z = f64::NAN;
        assert!(matches!(
            register(&nan, &scene.a, &initial, &params()),
            Err(FusionError::NonFinite {
                cloud: "source",
                index: 5
            })
        ));
        let bare = PointCloud::from_points(scene.a.points.clone());
        assert!(matches!(
            register(&scene.b, &bare, &initial, &params()),
            Err(FusionError::MissingNormals { .. })
        ));
        let far = Isometry3::translation(1.0, 0.0, 0.0) * initial;
        assert!(matches!(
            register(&scene.b, &scene.a, &far, &params()),
            Err(FusionError::NoOverlap { iteration: 0, .. })
        ));
        let tiny = PointCloud::from_points(scene.b.points[..10].to_vec());
        assert!(matches!(
            register(&tiny, &scene.a, &initial, &params()),
            Err(FusionError::TooFewPoints { points: 10, .. })
        ));
        // A 5 mm start error cannot be corrected inside a 1 mm leash.
        let leash = IcpParams {
            max_correction_translation_m: 1e-3,
            ..params()
        };
        assert!(matches!(
            register(&scene.b, &scene.a, &initial, &leash),
            Err(FusionError::Diverged { iteration: 0, .. })
        ));
        let bad = IcpParams {
            final_gate_m: 1.0,
            ..params()
        };
        assert!(matches!(
            register(&scene.b, &scene.a, &initial, &bad),
            Err(FusionError::BadParameter {
                name: "final_gate_m",
                ..
            })
        ));
    }

    #[test]
    fn a_plane_is_degenerate() {
        let pts: Vec<Vector3<f64>> = (0..2500)
            .map(|i| Vector3::new((i % 50) as f64 * 1e-3, (i / 50) as f64 * 1e-3, 0.3))
            .collect();
        let mut target = PointCloud::from_points(pts.clone());
        target.normals = Some(vec![Vector3::new(0.0, 0.0, -1.0); pts.len()]);
        let source = PointCloud::from_points(pts);
        let initial = Isometry3::translation(0.0, 0.0, 1e-4);
        assert_eq!(
            register(&source, &target, &initial, &IcpParams::default()),
            Err(FusionError::Degenerate { iteration: 0 })
        );
    }
}
