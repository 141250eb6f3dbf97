//! One cloud from two registered ones, without doubled surfaces in the overlap.
//!
//! Each point of B looks for its nearest point of A. Those within the
//! merge radius are duplicates of that A point: the A point and all its
//! duplicates become one output point (a quality-weighted mean, or the best
//! of them). A keeps its sampling in the overlap, so the fused cloud has one
//! point per surface sample there; B points with no A point near them are
//! kept as they are.

use nalgebra::Vector3;
use rayon::prelude::*;

use super::{build_tree, morton_order, nearest_within, FusionError, PointCloud};

/// How duplicates in the overlap become one point.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DuplicateRule {
    /// Mean weighted by `1 / sigma^2`; the fused sigma is
    /// `(sum 1 / sigma^2)^(-1/2)` (the duplicates are taken as independent
    /// measurements of one surface sample).
    WeightedMean,
    /// The duplicate with the lowest sigma, unchanged.
    KeepBest,
}

/// Settings of [`merge_clouds`].
#[derive(Debug, Clone, PartialEq)]
pub struct MergeParams {
    /// A point of B within this distance of a point of A is a duplicate,
    /// metres. About the sampling pitch of A.
    pub radius_m: f64,
    /// What to do with duplicates.
    pub rule: DuplicateRule,
    /// Sigma assumed for a cloud that carries no quality, metres.
    pub default_sigma_m: f32,
}

/// Counts from [`merge_clouds`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MergeReport {
    /// Points of A in.
    pub points_a: usize,
    /// Points of B in.
    pub points_b: usize,
    /// Points of A that had at least one duplicate in B.
    pub a_in_overlap: usize,
    /// Points of B merged into a point of A.
    pub b_merged: usize,
    /// Points of B kept on their own.
    pub b_kept: usize,
    /// Points out (`points_a + b_kept`).
    pub output_points: usize,
}

/// Merges `b` into `a`; both must be in the same frame (apply the ICP
/// transform to `b` first). Normals are kept when both clouds have them;
/// quality is always output (missing quality reads as `default_sigma_m`).
pub fn merge_clouds(
    a: &PointCloud,
    b: &PointCloud,
    params: &MergeParams,
) -> Result<(PointCloud, MergeReport), FusionError> {
    merge_clouds_indexed(a, b, params).map(|(cloud, report, _)| (cloud, report))
}

/// [`merge_clouds`], also returning which points of `b` were kept on their
/// own: the output is A's points in A's order, then those, in this order
/// (so per-point data the merge does not carry, such as colour, follows).
pub fn merge_clouds_indexed(
    a: &PointCloud,
    b: &PointCloud,
    params: &MergeParams,
) -> Result<(PointCloud, MergeReport, Vec<usize>), FusionError> {
    if !(params.radius_m.is_finite() && params.radius_m > 0.0) {
        return Err(FusionError::BadParameter {
            name: "radius_m",
            value: params.radius_m,
            expected: "finite and > 0",
        });
    }
    let sigma = params.default_sigma_m;
    if !(sigma.is_finite() && sigma > 0.0) {
        return Err(FusionError::BadParameter {
            name: "default_sigma_m",
            value: f64::from(sigma),
            expected: "finite and > 0",
        });
    }
    a.validate("a")?;
    b.validate("b")?;
    if a.is_empty() {
        return Err(FusionError::TooFewPoints {
            cloud: "a",
            points: 0,
            min: 1,
        });
    }
    let sigma_of = |cloud: &PointCloud, i: usize| cloud.quality.as_ref().map_or(sigma, |q| q[i]);

    // Nearest A point of every B point, if within the radius.
    let tree = build_tree(&a.points)?;
    let radius2 = params.radius_m * params.radius_m;
    let order = morton_order(&b.points);
    let found: Vec<Option<usize>> = order
        .par_iter()
        .map(|&i| nearest_within(&tree, &b.points[i], radius2).map(|(j, _)| j))
        .collect();
    let mut owner = vec![None; b.len()];
    for (&i, f) in order.iter().zip(found) {
        owner[i] = f;
    }

    // Start from A as it is; fold each duplicate into its owner.
    let mut fused = Fused::from_cloud(a, &sigma_of, params.rule);
    let keep_normals = a.normals.is_some() && b.normals.is_some();
    let mut kept = Vec::new();
    for (i, o) in owner.iter().enumerate() {
        let normal = b.normals.as_ref().map(|n| n[i]);
        match o {
            Some(j) => fused.absorb(*j, &b.points[i], normal, sigma_of(b, i)),
            None => kept.push(i),
        }
    }
    let a_in_overlap = fused.duplicates.iter().filter(|&&d| d > 0).count();
    let mut out = fused.finish(keep_normals);
    for &i in &kept {
        out.points.push(b.points[i]);
        if let Some(normals) = out.normals.as_mut() {
            normals.push(b.normals.as_ref().expect("keep_normals")[i]);
        }
        if let Some(q) = out.quality.as_mut() {
            q.push(sigma_of(b, i));
        }
    }
    let report = MergeReport {
        points_a: a.len(),
        points_b: b.len(),
        a_in_overlap,
        b_merged: b.len() - kept.len(),
        b_kept: kept.len(),
        output_points: out.len(),
    };
    Ok((out, report, kept))
}

/// Running per-A-point state while duplicates are folded in.
struct Fused {
    rule: DuplicateRule,
    /// WeightedMean: sum of w * p; KeepBest: the best point.
    point: Vec<Vector3<f64>>,
    /// WeightedMean: sum of w * n; KeepBest: the best normal.
    normal: Vec<Vector3<f64>>,
    /// WeightedMean: sum of w = 1 / sigma^2; KeepBest: best 1 / sigma^2.
    weight: Vec<f64>,
    duplicates: Vec<u32>,
}

impl Fused {
    fn from_cloud(
        a: &PointCloud,
        sigma_of: &dyn Fn(&PointCloud, usize) -> f32,
        rule: DuplicateRule,
    ) -> Self {
        let weight: Vec<f64> = (0..a.len())
            .map(|i| 1.0 / f64::from(sigma_of(a, i)).powi(2))
            .collect();
        let scale = |v: &Vector3<f64>, w: f64| match rule {
            DuplicateRule::WeightedMean => v * w,
            DuplicateRule::KeepBest => *v,
        };
        let point = a
            .points
            .iter()
            .zip(&weight)
            .map(|(p, w)| scale(p, *w))
            .collect();
        let normal = match &a.normals {
            Some(n) => n.iter().zip(&weight).map(|(v, w)| scale(v, *w)).collect(),
            None => vec![Vector3::zeros(); a.len()],
        };
        Self {
            rule,
            point,
            normal,
            weight,
            duplicates: vec![0; a.len()],
        }
    }

    fn absorb(&mut self, j: usize, p: &Vector3<f64>, n: Option<Vector3<f64>>, sigma_m: f32) {
        let w = 1.0 / f64::from(sigma_m).powi(2);
        let n = n.unwrap_or_else(Vector3::zeros);
        self.duplicates[j] += 1;
        match self.rule {
            DuplicateRule::WeightedMean => {
                self.point[j] += w * p;
                // Normals from the two heads agree in sign: both face their
                // camera, and both cameras see the same side of the surface.
                self.normal[j] += w * n;
                self.weight[j] += w;
            }
            DuplicateRule::KeepBest => {
                if w > self.weight[j] {
                    self.point[j] = *p;
                    self.normal[j] = n;
                    self.weight[j] = w;
                }
            }
        }
    }

    fn finish(self, keep_normals: bool) -> PointCloud {
        let mean = self.rule == DuplicateRule::WeightedMean;
        let points = self
            .point
            .iter()
            .zip(&self.weight)
            .map(|(p, w)| if mean { p / *w } else { *p })
            .collect();
        let normals = keep_normals.then(|| {
            self.normal
                .iter()
                .map(|n| n.try_normalize(0.0).unwrap_or(*n))
                .collect()
        });
        let quality = self
            .weight
            .iter()
            .map(|w| (1.0 / w.sqrt()) as f32)
            .collect();
        PointCloud {
            points,
            normals,
            quality: Some(quality),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fusion::synthetic::{height_m, two_head_scene, STANDOFF_M};
    use rand::SeedableRng;
    use rand_distr::{Distribution, StandardNormal};

    const NOISE_M: f64 = 50e-6;

    fn registered_scene(points_per_head: usize) -> (PointCloud, PointCloud) {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let scene = two_head_scene(points_per_head, NOISE_M, || StandardNormal.sample(&mut rng));
        let b = scene.b.transformed(&scene.b_to_a_m);
        (scene.a, b)
    }

    fn strip(cloud: &PointCloud, x0: f64, x1: f64) -> Vec<usize> {
        (0..cloud.len())
            .filter(|&i| (x0..x1).contains(&cloud.points[i].x))
            .collect()
    }

    fn rms_height_error(cloud: &PointCloud, idx: &[usize]) -> f64 {
        let sum: f64 = idx
            .iter()
            .map(|&i| {
                let p = cloud.points[i];
                (p.z - STANDOFF_M - height_m(p.x, p.y)).powi(2)
            })
            .sum();
        (sum / idx.len() as f64).sqrt()
    }

    #[test]
    fn overlap_keeps_one_point_per_sample_and_averages_noise() {
        // 20k points on 75 x 100 mm: pitch about 0.6 mm.
        let (a, b) = registered_scene(20_000);
        let params = MergeParams {
            radius_m: 0.6e-3,
            rule: DuplicateRule::WeightedMean,
            default_sigma_m: 1e-4,
        };
        let (out, report) = merge_clouds(&a, &b, &params).unwrap();
        println!("{report:?}");
        assert_eq!(report.output_points, out.len());
        assert_eq!(report.output_points, report.points_a + report.b_kept);
        assert_eq!(report.b_merged + report.b_kept, report.points_b);
        // Inside the overlap (away from its edges) the fused cloud has A's
        // density, not A's plus B's.
        let (inner_a, inner_out) = (strip(&a, -0.01, 0.01), strip(&out, -0.01, 0.01));
        let excess = inner_out.len() as f64 / inner_a.len() as f64 - 1.0;
        assert!(excess < 0.05, "{} vs {}", inner_out.len(), inner_a.len());
        // Away from the overlap nothing changes.
        assert_eq!(strip(&out, 0.02, 0.07).len(), strip(&b, 0.02, 0.07).len());
        // Averaging two independent measurements lowers the depth error
        // against the analytic surface (ideal: 1/sqrt(2) = 0.71).
        let (raw, fused) = (
            rms_height_error(&a, &inner_a),
            rms_height_error(&out, &inner_out),
        );
        println!(
            "height rms raw {:.1} um, fused {:.1} um",
            raw * 1e6,
            fused * 1e6
        );
        assert!(fused < 0.85 * raw, "raw {raw} fused {fused}");
        let q = out.quality.as_ref().unwrap();
        assert!(inner_out.iter().all(|&i| q[i] <= NOISE_M as f32 * 1.0001));
    }

    #[test]
    fn keep_best_takes_the_lower_sigma() {
        let a = PointCloud {
            points: vec![Vector3::zeros(), Vector3::x()],
            normals: None,
            quality: Some(vec![1e-4, 1e-4]),
        };
        let b = PointCloud {
            points: vec![Vector3::new(1e-5, 0.0, 0.0), Vector3::new(0.0, 5.0, 0.0)],
            normals: None,
            quality: Some(vec![1e-5, 1e-5]),
        };
        let params = MergeParams {
            radius_m: 1e-4,
            rule: DuplicateRule::KeepBest,
            default_sigma_m: 1e-4,
        };
        let (out, report) = merge_clouds(&a, &b, &params).unwrap();
        assert_eq!(
            out.points,
            vec![b.points[0], a.points[1], b.points[1]],
            "{report:?}"
        );
        assert_eq!(out.quality.unwrap(), vec![1e-5, 1e-4, 1e-5]);
        let mean = MergeParams {
            rule: DuplicateRule::WeightedMean,
            ..params
        };
        let (out, _) = merge_clouds(&a, &b, &mean).unwrap();
        // weights 1 : 100 -> x = 100e-5 / 101
        assert!((out.points[0].x - 1e-3 / 101.0).abs() < 1e-15);
    }

    #[test]
    fn bad_input_is_an_error() {
        let a = PointCloud::from_points(vec![Vector3::zeros()]);
        let mut b = PointCloud::from_points(vec![Vector3::new(f64::NAN, 0.0, 0.0)]);
        let params = MergeParams {
            radius_m: 1e-3,
            rule: DuplicateRule::WeightedMean,
            default_sigma_m: 1e-4,
        };
        assert!(matches!(
            merge_clouds(&a, &b, &params),
            Err(FusionError::NonFinite {
                cloud: "b",
                index: 0
            })
        ));
        b.points[0].x = 0.0;
        let zero = MergeParams {
            radius_m: 0.0,
            ..params.clone()
        };
        assert!(matches!(
            merge_clouds(&a, &b, &zero),
            Err(FusionError::BadParameter {
                name: "radius_m",
                ..
            })
        ));
        assert!(matches!(
            merge_clouds(&PointCloud::default(), &b, &params),
            Err(FusionError::TooFewPoints { cloud: "a", .. })
        ));
    }
}
