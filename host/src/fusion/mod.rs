//! Fusion of the two heads' point clouds into one.
//!
//! ```text
//! cloud A (target) --normals::estimate_normals--> normals of A
//! cloud B (source) --icp::register(initial = calibration extrinsic)--> IcpResult.transform
//! A, T * B --merge::merge_clouds--> one cloud, one point per surface sample in the overlap
//! ```
//!
//! [`fuse_heads`] runs the three steps; [`synthetic`] builds a two-head
//! scene with known truth for tests and `benches/icp.rs`.
//!
//! Points are `f64` here: ICP accumulates normal equations over a million
//! points and we want micrometre agreement; the PLY writer narrows to `f32`.

mod cell_knn;
pub mod icp;
pub mod merge;
pub mod multiview;
mod nearest_cache;
pub mod normals;
pub mod robust;
pub mod synthetic;

use nalgebra::{Isometry3, Point3, Vector3};
use rayon::prelude::*;

pub mod agreement;
pub use agreement::{shape_agreement, ShapeAgreement};
pub use icp::{register, IcpParams, IcpResult, IcpTarget, RobustKernel};
pub use merge::{merge_clouds, merge_clouds_indexed, DuplicateRule, MergeParams, MergeReport};
pub use multiview::{
    merge_views, register_views, MultiViewError, MultiViewParams, MultiViewResult, PairReport,
    ViewReport,
};
pub use normals::estimate_normals;

/// A point cloud in metres, with optional per-point normals and quality.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PointCloud {
    /// Positions in metres.
    pub points: Vec<Vector3<f64>>,
    /// Unit normals, one per point, if known.
    pub normals: Option<Vec<Vector3<f64>>>,
    /// Predicted depth standard deviation in metres, one per point (lower is better).
    pub quality: Option<Vec<f32>>,
}

impl PointCloud {
    /// A cloud of bare points.
    pub fn from_points(points: Vec<Vector3<f64>>) -> Self {
        Self {
            points,
            normals: None,
            quality: None,
        }
    }

    /// Number of points.
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// True when the cloud has no points.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// Checks that the optional columns match the point count and that every
    /// value is finite (and every quality positive).
    pub fn validate(&self, cloud: &'static str) -> Result<(), FusionError> {
        check_finite(cloud, &self.points)?;
        if let Some(normals) = &self.normals {
            check_len(cloud, "normals", self.points.len(), normals.len())?;
            check_finite(cloud, normals)?;
        }
        if let Some(quality) = &self.quality {
            check_len(cloud, "quality", self.points.len(), quality.len())?;
            if let Some(index) = quality.iter().position(|s| !(s.is_finite() && *s > 0.0)) {
                return Err(FusionError::BadQuality {
                    cloud,
                    index,
                    sigma_m: quality[index],
                });
            }
        }
        Ok(())
    }

    /// The cloud moved by `transform` (normals rotated, quality kept).
    pub fn transformed(&self, transform: &Isometry3<f64>) -> Self {
        let points = self
            .points
            .iter()
            .map(|p| transform.transform_point(&Point3::from(*p)).coords)
            .collect();
        let normals = self.normals.as_ref().map(|normals| {
            normals
                .iter()
                .map(|n| transform.transform_vector(n))
                .collect()
        });
        Self {
            points,
            normals,
            quality: self.quality.clone(),
        }
    }
}

/// Settings of [`fuse_heads`].
#[derive(Debug, Clone, PartialEq)]
pub struct FuseParams {
    /// Neighbours per normal (PCA), typically 10-20.
    pub normals_k: usize,
    /// Camera centre of head A in A's frame (the origin for a camera frame).
    pub sensor_a_m: Vector3<f64>,
    /// Registration settings.
    pub icp: IcpParams,
    /// Overlap merge settings.
    pub merge: MergeParams,
}

/// What [`fuse_heads`] produced.
#[derive(Debug, Clone, PartialEq)]
pub struct FusedClouds {
    /// One cloud in head A's frame.
    pub cloud: PointCloud,
    /// The registration of B onto A (corrections, RMSE, fitness).
    pub icp: IcpResult,
    /// Point counts of the merge.
    pub merge: MergeReport,
    /// The points of B kept on their own, in the cloud's order after A's.
    pub b_kept: Vec<usize>,
    /// How well the registered clouds agree in shape (`None` when their
    /// overlap has no cell with enough points).
    pub agreement: Option<ShapeAgreement>,
}

/// Cell size of [`FusedClouds::agreement`]: a few per cent of a part, so a
/// bend shows across cells while each cell holds hundreds of points.
pub const AGREEMENT_CELL_M: f64 = 0.01;

/// The whole fusion step: normals of A (unless it has them), ICP of B onto
/// A from the calibrated `b_to_a_initial`, then one merged cloud in A's frame.
pub fn fuse_heads(
    a: &PointCloud,
    b: &PointCloud,
    b_to_a_initial: &Isometry3<f64>,
    params: &FuseParams,
) -> Result<FusedClouds, FusionError> {
    a.validate("a")?;
    b.validate("b")?;
    let with_normals;
    let target = if a.normals.is_some() {
        a
    } else {
        with_normals = PointCloud {
            normals: Some(estimate_normals(
                &a.points,
                params.normals_k,
                &params.sensor_a_m,
            )?),
            ..a.clone()
        };
        &with_normals
    };
    b.validate("source")?;
    let prepared = IcpTarget::new(target)?;
    let icp = prepared.register(&b.points, b_to_a_initial, &params.icp)?;
    let gate = params.icp.final_gate_m;
    let agreement = shape_agreement(
        &prepared.signed_residuals(&b.points, &icp.transform, gate),
        AGREEMENT_CELL_M,
        gate,
    );
    let (cloud, merge, b_kept) =
        merge_clouds_indexed(a, &b.transformed(&icp.transform), &params.merge)?;
    Ok(FusedClouds {
        cloud,
        icp,
        merge,
        b_kept,
        agreement,
    })
}

/// What can go wrong while registering or merging clouds.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FusionError {
    /// A cloud has fewer points than the algorithm needs.
    #[error("cloud {cloud} has {points} points; at least {min} are needed")]
    TooFewPoints {
        /// Which cloud ("source", "target", "a", "b").
        cloud: &'static str,
        /// Points it has.
        points: usize,
        /// Points needed.
        min: usize,
    },
    /// A coordinate or normal component is NaN or infinite.
    #[error("cloud {cloud} has a non-finite value at point {index}")]
    NonFinite {
        /// Which cloud.
        cloud: &'static str,
        /// Index of the first offending point.
        index: usize,
    },
    /// A per-point column has the wrong length.
    #[error("cloud {cloud}: {field} has {got} entries for {expected} points")]
    LengthMismatch {
        /// Which cloud.
        cloud: &'static str,
        /// Which column ("normals", "quality").
        field: &'static str,
        /// Point count.
        expected: usize,
        /// Column length.
        got: usize,
    },
    /// A quality (depth sigma) is not a positive finite number.
    #[error("cloud {cloud}: quality {sigma_m} m at point {index} is not positive and finite")]
    BadQuality {
        /// Which cloud.
        cloud: &'static str,
        /// Index of the point.
        index: usize,
        /// The offending sigma in metres.
        sigma_m: f32,
    },
    /// The target cloud carries no normals, but point-to-plane ICP needs them.
    #[error("cloud {cloud} has no normals; call estimate_normals first")]
    MissingNormals {
        /// Which cloud.
        cloud: &'static str,
    },
    /// A parameter is out of its range.
    #[error("parameter {name} = {value} is out of range ({expected})")]
    BadParameter {
        /// Parameter name.
        name: &'static str,
        /// Its value.
        value: f64,
        /// What it must be.
        expected: &'static str,
    },
    /// Too few source points found a target point within the gate: the
    /// clouds do not overlap under the current transform.
    #[error("only {correspondences} correspondences within {gate_m} m at iteration {iteration}; need {min}")]
    NoOverlap {
        /// Correspondences found.
        correspondences: usize,
        /// Correspondences needed.
        min: usize,
        /// Gate distance in metres.
        gate_m: f64,
        /// ICP iteration (0-based).
        iteration: usize,
    },
    /// The normal equations are singular: the overlap does not constrain all
    /// six degrees of freedom (a plane, a cylinder...).
    #[error(
        "degenerate geometry at iteration {iteration}: the overlap does not constrain all 6 DOF"
    )]
    Degenerate {
        /// ICP iteration (0-based).
        iteration: usize,
    },
    /// The estimate left the basin of the initial guess or became non-finite.
    #[error("ICP diverged at iteration {iteration}: correction {rotation_deg:.2} deg / {:.1} mm from the initial guess", translation_m * 1e3)]
    Diverged {
        /// ICP iteration (0-based).
        iteration: usize,
        /// Rotation away from the initial guess, degrees.
        rotation_deg: f64,
        /// Translation away from the initial guess, metres.
        translation_m: f64,
    },
    /// The kd-tree could not be built.
    #[error("kd-tree construction failed: {0}")]
    KdTree(String),
}

fn check_finite(cloud: &'static str, values: &[Vector3<f64>]) -> Result<(), FusionError> {
    match values.iter().position(|v| !v.iter().all(|c| c.is_finite())) {
        Some(index) => Err(FusionError::NonFinite { cloud, index }),
        None => Ok(()),
    }
}

fn check_len(
    cloud: &'static str,
    field: &'static str,
    expected: usize,
    got: usize,
) -> Result<(), FusionError> {
    if expected == got {
        Ok(())
    } else {
        Err(FusionError::LengthMismatch {
            cloud,
            field,
            expected,
            got,
        })
    }
}

/// The kd-tree type used for all neighbour searches in fusion.
pub(crate) type Tree = kiddo::ImmutableKdTree<f64, 3>;

/// Builds a kd-tree over `points`; items are point indices.
pub(crate) fn build_tree(points: &[Vector3<f64>]) -> Result<Tree, FusionError> {
    let coords: Vec<[f64; 3]> = points.iter().map(|p| [p.x, p.y, p.z]).collect();
    Tree::new_from_slice(&coords).map_err(|e| FusionError::KdTree(format!("{e:?}")))
}

/// Nearest point of `tree` to `q` within squared distance `max_dist2`, as
/// (index, squared distance). The radius bound matters: an unbounded
/// nearest-one search from a point far outside the other cloud (most of a
/// partial scan lies outside the overlap) visits a large part of the tree.
pub(crate) fn nearest_within(
    tree: &Tree,
    q: &Vector3<f64>,
    max_dist2: f64,
) -> Option<(usize, f64)> {
    let one = std::num::NonZeroUsize::MIN;
    tree.query(&[q.x, q.y, q.z])
        .nearest_n::<kiddo::SquaredEuclidean<f64>>(one)
        .within(max_dist2)
        .execute()
        .first()
        .map(|nn| (nn.item as usize, nn.distance))
}

/// Indices of `points` in Z-order (Morton order) of their bounding box.
/// Querying a kd-tree in this order keeps consecutive queries in the same
/// leaves, so a million-point tree stays in cache; in the order the points
/// come (a quasi-random sample, or rows of two cameras) it does not.
pub(crate) fn morton_order(points: &[Vector3<f64>]) -> Vec<usize> {
    MortonKeys::of(points)
        .sorted
        .into_iter()
        .map(|(_, i)| i)
        .collect()
}

/// Finest Morton level: 21 bits per axis fill a u64 key.
pub(crate) const MORTON_LEVELS: u32 = 21;

/// Every point's Morton key over the cloud's bounding cube, sorted: at level
/// `l` (0..=21) a key's top `3 l` bits name its cell of side `extent / 2^l`,
/// so the points of each cell, at every level, are contiguous.
pub(crate) struct MortonKeys {
    /// Lowest corner of the bounding box.
    pub lo: Vector3<f64>,
    /// Longest side of the bounding box (the cube's side), metres.
    pub extent: f64,
    /// (key, point index), ascending.
    pub sorted: Vec<(u64, usize)>,
}

impl MortonKeys {
    /// Keys of `points` (finite), sorted.
    pub fn of(points: &[Vector3<f64>]) -> MortonKeys {
        let (lo, hi) = points.iter().fold(
            (Vector3::repeat(f64::MAX), Vector3::repeat(f64::MIN)),
            |(lo, hi), p| (lo.inf(p), hi.sup(p)),
        );
        let extent = (hi - lo).max().max(f64::MIN_POSITIVE);
        let keys = MortonKeys {
            lo,
            extent,
            sorted: Vec::new(),
        };
        let mut sorted: Vec<(u64, usize)> = points
            .par_iter()
            .map(|p| keys.key(&keys.cell(p)))
            .zip(0..points.len())
            .collect();
        sorted.par_sort_unstable();
        MortonKeys { sorted, ..keys }
    }

    /// The finest-level cell (21-bit integer coordinates) holding `p`.
    pub fn cell(&self, p: &Vector3<f64>) -> [u64; 3] {
        let max = ((1u64 << MORTON_LEVELS) - 1) as f64;
        let q = |v: f64, lo: f64| (((v - lo) / self.extent) * max) as u64;
        [q(p.x, self.lo.x), q(p.y, self.lo.y), q(p.z, self.lo.z)]
    }

    /// The Morton key of integer cell coordinates (each under 2^21).
    pub fn key(&self, c: &[u64; 3]) -> u64 {
        spread_bits(c[0]) | spread_bits(c[1]) << 1 | spread_bits(c[2]) << 2
    }
}

/// The low 21 bits of `v` spread to every third bit.
fn spread_bits(v: u64) -> u64 {
    let mut x = v & 0x1f_ffff;
    x = (x | x << 32) & 0x1f_0000_0000_ffff;
    x = (x | x << 16) & 0x1f_0000_ff00_00ff;
    x = (x | x << 8) & 0x100f_00f0_0f00_f00f;
    x = (x | x << 4) & 0x10c3_0c30_c30c_30c3;
    x = (x | x << 2) & 0x1249_2492_4924_9249;
    x
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Translation3, UnitQuaternion};

    #[test]
    fn validate_reports_nan_and_bad_columns() {
        let mut cloud = PointCloud::from_points(vec![Vector3::zeros(), Vector3::x()]);
        assert_eq!(cloud.validate("a"), Ok(()));
        cloud.quality = Some(vec![1e-5]);
        assert!(matches!(
            cloud.validate("a"),
            Err(FusionError::LengthMismatch { got: 1, .. })
        ));
        cloud.quality = Some(vec![1e-5, -1.0]);
        assert!(matches!(
            cloud.validate("a"),
            Err(FusionError::BadQuality { index: 1, .. })
        ));
        cloud.quality = None;
        cloud.points[1].y = f64::NAN;
        assert_eq!(
            cloud.validate("a"),
            Err(FusionError::NonFinite {
                cloud: "a",
                index: 1
            })
        );
    }

    #[test]
    fn fuse_heads_registers_and_merges_the_synthetic_rig() {
        use rand::SeedableRng;
        use rand_distr::{Distribution, StandardNormal};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(9);
        let scene = synthetic::two_head_scene(20_000, 20e-6, || StandardNormal.sample(&mut rng));
        let initial = synthetic::perturbed(
            &scene.b_to_a_m,
            &scene.centre_m,
            &Vector3::new(-0.2, 0.5, 0.9),
            1.0,
            &Vector3::new(0.0, 1.0, 1.0),
            0.002,
        );
        let params = FuseParams {
            normals_k: 10,
            sensor_a_m: Vector3::zeros(),
            icp: IcpParams {
                final_gate_m: 0.002,
                ..IcpParams::default()
            },
            merge: MergeParams {
                radius_m: 0.6e-3,
                rule: DuplicateRule::WeightedMean,
                default_sigma_m: 20e-6,
            },
        };
        let fused = fuse_heads(&scene.a, &scene.b, &initial, &params).unwrap();
        let (rot_deg, trans_m) =
            synthetic::pose_error(&fused.icp.transform, &scene.b_to_a_m, &scene.centre_m);
        assert!(
            rot_deg < 0.01 && trans_m < 10e-6,
            "{rot_deg} deg {trans_m} m"
        );
        assert_eq!(fused.cloud.len(), fused.merge.output_points);
        assert!(fused.merge.b_merged > 5000, "{:?}", fused.merge);
        // Every fused point lies on the analytic surface within noise.
        let worst = fused
            .cloud
            .points
            .iter()
            .map(|p| (p.z - synthetic::STANDOFF_M - synthetic::height_m(p.x, p.y)).abs())
            .fold(0.0, f64::max);
        assert!(worst < 150e-6, "worst height error {worst} m");
    }

    #[test]
    fn morton_order_is_a_permutation_along_the_z_curve() {
        assert_eq!(spread_bits(0b111), 0b1001001);
        let pts: Vec<Vector3<f64>> = [(1, 1), (0, 0), (1, 0), (0, 1)]
            .iter()
            .map(|&(x, y)| Vector3::new(x as f64, y as f64, 0.0))
            .collect();
        // Z-curve over the unit square: (0,0) (1,0) (0,1) (1,1).
        assert_eq!(morton_order(&pts), vec![1, 2, 3, 0]);
    }

    proptest::proptest! {
        /// Z-order is a permutation, and sorted by the interleaved key
        /// computed the slow way (bit by bit).
        #[test]
        fn morton_order_sorts_by_the_interleaved_key(
            coords in proptest::collection::vec((0u32..1024, 0u32..1024, 0u32..1024), 1..100)
        ) {
            let pts: Vec<Vector3<f64>> = coords
                .iter()
                .map(|&(x, y, z)| Vector3::new(x as f64, y as f64, z as f64))
                .collect();
            let order = morton_order(&pts);
            let mut seen = order.clone();
            seen.sort_unstable();
            proptest::prop_assert_eq!(seen, (0..pts.len()).collect::<Vec<_>>());
            let lo = pts.iter().fold(Vector3::repeat(f64::MAX), |lo, p| lo.inf(p));
            let hi = pts.iter().fold(Vector3::repeat(f64::MIN), |hi, p| hi.sup(p));
            let extent = (hi - lo).max().max(f64::MIN_POSITIVE);
            let slow_key = |p: &Vector3<f64>| {
                let c = |v: f64, l: f64| (((v - l) / extent) * 2_097_151.0) as u64;
                let (x, y, z) = (c(p.x, lo.x), c(p.y, lo.y), c(p.z, lo.z));
                (0..21).fold(0u64, |k, b| {
                    k | ((x >> b) & 1) << (3 * b) | ((y >> b) & 1) << (3 * b + 1) | ((z >> b) & 1) << (3 * b + 2)
                })
            };
            for w in order.windows(2) {
                proptest::prop_assert!(slow_key(&pts[w[0]]) <= slow_key(&pts[w[1]]));
            }
        }
    }

    #[test]
    fn transformed_moves_points_and_rotates_normals() {
        let mut cloud = PointCloud::from_points(vec![Vector3::new(1.0, 0.0, 0.0)]);
        cloud.normals = Some(vec![Vector3::new(1.0, 0.0, 0.0)]);
        let t = Isometry3::from_parts(
            Translation3::new(0.0, 0.0, 2.0),
            UnitQuaternion::from_axis_angle(&Vector3::z_axis(), std::f64::consts::FRAC_PI_2),
        );
        let moved = cloud.transformed(&t);
        assert!((moved.points[0] - Vector3::new(0.0, 1.0, 2.0)).norm() < 1e-12);
        assert!((moved.normals.unwrap()[0] - Vector3::new(0.0, 1.0, 0.0)).norm() < 1e-12);
    }
}
