//! Multi-view registration: every head's pose refined at once (issue 21).
//!
//! ```text
//! K clouds (each in its own head frame) + initial poses world <- head k
//!   (world = head 0's frame; head 0 stays fixed)
//!   --overlap graph at the initial poses (pairs with enough correspondences)--
//!   --refused unless every head is linked to head 0--
//!   --joint point-to-plane ICP: per iteration, nearest-neighbour pairs of
//!     every overlapping pair in both directions, robust weights per pair,
//!     ONE Gauss-Newton system of 6(K-1) unknowns--> poses, per-pair overlap
//!     RMSE, per-head correction and fitness
//!   --merge::merge_clouds, head by head--> one cloud in head 0's frame
//! ```
//!
//! Why jointly: registering each head onto its neighbour and chaining the
//! transforms adds each pair's error to the next, and the error of the
//! chain shows up as a step where the ring closes (the last head against
//! the first). Here every overlap pulls on both of its heads in the same
//! least-squares problem, so the closing overlap counts as much as any
//! other and the error is spread over the ring instead of piled at its end.
//!
//! Conventions follow [`super::icp`]: point-to-plane residuals
//! `r = n . (q - t)` against the target's normal, gated nearest neighbours
//! with a gate that halves from `initial_gate_m` to `final_gate_m`, a robust
//! kernel whose scale is the MAD of each pair's residuals (and, new here,
//! pairs whose normals disagree by more than 60 degrees dropped), the rotation
//! linearised about the centroid of the correspondences (so rotation and
//! translation do not couple through a lever arm half a metre long), and
//! the same convergence, divergence and degeneracy rules.

use nalgebra::{
    DMatrix, DVector, Isometry3, Point3, Translation3, UnitQuaternion, Vector3, Vector6,
};
use rayon::prelude::*;

use super::icp::IcpParams;
use super::merge::{merge_clouds, MergeParams, MergeReport};
use super::normals::estimate_normals;
use super::robust::mad_scale;
use super::{
    build_tree, morton_order, nearest_within, shape_agreement, FusionError, PointCloud,
    ShapeAgreement, Tree, AGREEMENT_CELL_M,
};

/// Settings of [`register_views`].
#[derive(Debug, Clone, PartialEq)]
pub struct MultiViewParams {
    /// Gates, robust kernel, convergence and divergence limits, as for
    /// pairwise ICP; `min_correspondences` is per overlapping pair (fewer
    /// at the initial poses and the pair is not an edge of the graph).
    pub icp: IcpParams,
    /// Neighbours per normal (PCA) for clouds that come without normals.
    pub normals_k: usize,
}

impl Default for MultiViewParams {
    fn default() -> Self {
        Self {
            icp: IcpParams::default(),
            normals_k: 10,
        }
    }
}

/// What went wrong in multi-view registration.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MultiViewError {
    /// Fewer than two clouds, or a pose count that does not match.
    #[error(
        "{views} clouds and {poses} initial poses: need as many poses as clouds, and >= 2 clouds"
    )]
    ViewCount {
        /// Clouds given.
        views: usize,
        /// Poses given.
        poses: usize,
    },
    /// Some heads share no overlap, directly or through other heads, with
    /// head 0: nothing fixes their pose in head 0's frame.
    #[error("heads {unreached:?} are not linked to head 0 by overlaps of >= {min} correspondences within {gate_m} m (overlapping pairs: {edges:?})")]
    Disconnected {
        /// Heads with no chain of overlaps to head 0.
        unreached: Vec<usize>,
        /// The pairs that did overlap.
        edges: Vec<(usize, usize)>,
        /// Correspondences a pair needs.
        min: usize,
        /// Gate they were counted within, metres.
        gate_m: f64,
    },
    /// A cloud, a parameter or the solution itself failed (as in pairwise ICP).
    #[error(transparent)]
    Fusion(#[from] FusionError),
}

/// One head's result.
#[derive(Debug, Clone, PartialEq)]
pub struct ViewReport {
    /// Refined pose, head 0's frame <- this head's frame.
    pub pose: Isometry3<f64>,
    /// `pose * initial^-1`: what registration changed, in head 0's frame.
    pub correction: Isometry3<f64>,
    /// Rotation angle of `correction`, degrees.
    pub rotation_correction_deg: f64,
    /// How far `correction` moves the centroid of this head's inlier
    /// points, metres (as [`super::IcpResult::translation_correction_m`]).
    pub translation_correction_m: f64,
    /// Fraction of this head's points with an inlier correspondence in
    /// some other head's cloud at the final poses.
    pub fitness: f64,
}

/// One overlapping pair's agreement at the final poses.
#[derive(Debug, Clone, PartialEq)]
pub struct PairReport {
    /// The two heads (lower index first).
    pub heads: (usize, usize),
    /// Inlier pairs, both directions counted.
    pub inliers: usize,
    /// RMS point-to-plane residual of the inliers, metres (NaN without inliers).
    pub overlap_rmse_m: f64,
    /// How well the two clouds agree in shape over the overlap (`None`
    /// when no cell of it has enough points), as for two heads.
    pub agreement: Option<ShapeAgreement>,
}

/// What [`register_views`] found.
#[derive(Debug, Clone, PartialEq)]
pub struct MultiViewResult {
    /// Per head, in input order (head 0's correction is the identity).
    pub views: Vec<ViewReport>,
    /// Per overlapping pair of the graph.
    pub pairs: Vec<PairReport>,
    /// Iterations run.
    pub iterations: usize,
    /// True when every head's update fell below the convergence thresholds
    /// at the final gate before the iteration limit.
    pub converged: bool,
    /// Largest rotation of any head in the last update, degrees.
    pub last_step_rotation_deg: f64,
    /// Largest translation of any head in the last update, metres.
    pub last_step_translation_m: f64,
}

impl MultiViewResult {
    /// The refined poses, head 0's frame <- head k's frame.
    pub fn poses(&self) -> Vec<Isometry3<f64>> {
        self.views.iter().map(|v| v.pose).collect()
    }
}

impl std::fmt::Display for MultiViewResult {
    /// A few lines for a person: per head and per pair, in mm, um and degrees.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if self.converged {
            writeln!(f, "converged in {} iterations", self.iterations)?;
        } else {
            writeln!(
                f,
                "did not converge in {} iterations: last step {:.5} deg / {:.4} mm",
                self.iterations,
                self.last_step_rotation_deg,
                self.last_step_translation_m * 1e3
            )?;
        }
        for (k, v) in self.views.iter().enumerate() {
            writeln!(
                f,
                "head {k}: correction {:.4} deg / {:.4} mm, fitness {:.3}",
                v.rotation_correction_deg,
                v.translation_correction_m * 1e3,
                v.fitness
            )?;
        }
        for p in &self.pairs {
            if p.inliers == 0 {
                writeln!(
                    f,
                    "heads {}-{}: no inlier pairs at the final gate",
                    p.heads.0, p.heads.1
                )?;
                continue;
            }
            writeln!(
                f,
                "heads {}-{}: overlap RMSE {:.2} um over {} pairs",
                p.heads.0,
                p.heads.1,
                p.overlap_rmse_m * 1e6,
                p.inliers
            )?;
        }
        Ok(())
    }
}

/// Cosine of the largest angle between the normals of a correspondence
/// (60 degrees). Each head's normals face its own camera, so the two sides
/// of one surface agree; a thin part's two faces lie closer than the
/// initial gate and face opposite ways, and without this test the far
/// face's points would pull a head through the part.
const MIN_NORMAL_COS: f64 = 0.5;

/// A cloud prepared once: points, normals and kd-tree, in its own frame.
struct View {
    points: Vec<Vector3<f64>>,
    normals: Vec<Vector3<f64>>,
    tree: Tree,
}

/// One gated correspondence in head 0's frame.
struct Corr {
    /// Source point moved to head 0's frame.
    x: Vector3<f64>,
    /// Target normal in head 0's frame.
    m: Vector3<f64>,
    /// Point-to-plane residual, metres.
    r: f64,
    /// Index of the source point in its cloud.
    source: usize,
}

/// Registers `clouds` (each in its own head frame, the camera at the
/// origin: normals that are missing are estimated facing it) starting from
/// `initial[k]` = head 0's frame <- head k's frame. Head 0 stays where
/// `initial[0]` puts it; every other pose is refined at once.
pub fn register_views(
    clouds: &[PointCloud],
    initial: &[Isometry3<f64>],
    params: &MultiViewParams,
) -> Result<MultiViewResult, MultiViewError> {
    let k = clouds.len();
    if k < 2 || initial.len() != k {
        return Err(MultiViewError::ViewCount {
            views: k,
            poses: initial.len(),
        });
    }
    let p = &params.icp;
    p.validate()?;
    let views = clouds
        .iter()
        .map(|c| prepare(c, params))
        .collect::<Result<Vec<_>, _>>()?;
    let edges = overlap_graph(&views, initial, p);
    check_connected(k, &edges, p)?;

    let mut poses = initial.to_vec();
    let mut gate = p.initial_gate_m;
    let (mut iterations, mut converged) = (0, false);
    let (mut last_deg, mut last_m) = (f64::NAN, f64::NAN);
    while iterations < p.max_iterations {
        let coarse = gate > p.final_gate_m;
        let pairs = gather(&views, &poses, &edges, gate, coarse, p);
        let update = solve(&pairs, k, p).ok_or(FusionError::Degenerate {
            iteration: iterations,
        })?;
        (last_deg, last_m) = (0.0, 0.0);
        for (h, u) in update.iter().enumerate() {
            poses[h] = u * poses[h];
            last_deg = f64::max(last_deg, u.rotation.angle().to_degrees());
            last_m = f64::max(last_m, u.translation.vector.norm());
            check_divergence(&poses[h], &initial[h], iterations, p)?;
        }
        iterations += 1;
        tracing::debug!(iterations, gate, last_deg, last_m, "multi-view icp");
        let small = last_deg < p.convergence_rotation_deg && last_m < p.convergence_translation_m;
        if small && !coarse {
            converged = true;
            break;
        }
        gate = (gate * 0.5).max(p.final_gate_m);
    }
    Ok(report(
        &views, initial, poses, &edges, gate, iterations, converged, last_deg, last_m, p,
    ))
}

/// Points, normals (estimated facing the camera at the frame's origin when
/// missing) and kd-tree of one cloud.
fn prepare(cloud: &PointCloud, params: &MultiViewParams) -> Result<View, FusionError> {
    cloud.validate("view")?;
    if cloud.len() < params.icp.min_correspondences {
        return Err(FusionError::TooFewPoints {
            cloud: "view",
            points: cloud.len(),
            min: params.icp.min_correspondences,
        });
    }
    let normals = match &cloud.normals {
        Some(n) => n.clone(),
        None => estimate_normals(&cloud.points, params.normals_k, &Vector3::zeros())?,
    };
    // Z-order: neighbouring queries stay in the same kd-tree leaves.
    let order = morton_order(&cloud.points);
    let points: Vec<Vector3<f64>> = order.iter().map(|&i| cloud.points[i]).collect();
    let normals: Vec<Vector3<f64>> = order.iter().map(|&i| normals[i]).collect();
    let tree = build_tree(&points)?;
    Ok(View {
        points,
        normals,
        tree,
    })
}

/// Pairs (i < j) with at least `min_correspondences` points of one within
/// the initial gate of the other, at the initial poses.
fn overlap_graph(views: &[View], poses: &[Isometry3<f64>], p: &IcpParams) -> Vec<(usize, usize)> {
    let mut edges = Vec::new();
    for i in 0..views.len() {
        for j in i + 1..views.len() {
            let n = correspondences(views, poses, i, j, p.initial_gate_m, usize::MAX)
                .len()
                .max(correspondences(views, poses, j, i, p.initial_gate_m, usize::MAX).len());
            if n >= p.min_correspondences {
                edges.push((i, j));
            }
        }
    }
    edges
}

fn check_connected(
    k: usize,
    edges: &[(usize, usize)],
    p: &IcpParams,
) -> Result<(), MultiViewError> {
    let mut reached = vec![false; k];
    reached[0] = true;
    let mut grew = true;
    while grew {
        grew = false;
        for &(a, b) in edges {
            if reached[a] != reached[b] {
                reached[a] = true;
                reached[b] = true;
                grew = true;
            }
        }
    }
    let unreached: Vec<usize> = (0..k).filter(|&h| !reached[h]).collect();
    if unreached.is_empty() {
        return Ok(());
    }
    Err(MultiViewError::Disconnected {
        unreached,
        edges: edges.to_vec(),
        min: p.min_correspondences,
        gate_m: p.initial_gate_m,
    })
}

/// Gated nearest-neighbour pairs of head `i`'s points in head `j`'s cloud,
/// in head 0's frame; at most `max_points` source points (an even
/// subsample in Z-order).
fn correspondences(
    views: &[View],
    poses: &[Isometry3<f64>],
    i: usize,
    j: usize,
    gate: f64,
    max_points: usize,
) -> Vec<Corr> {
    let (src, dst) = (&views[i], &views[j]);
    // Head i's points into head j's frame, where j's tree was built.
    let j_from_i = poses[j].inverse() * poses[i];
    let turn = j_from_i.rotation;
    let stride = src.points.len().div_ceil(max_points.max(1)).max(1);
    let gate2 = gate * gate;
    (0..src.points.len())
        .into_par_iter()
        .step_by(stride)
        .filter_map(|s| {
            let q = j_from_i
                .transform_point(&Point3::from(src.points[s]))
                .coords;
            let (t, _) = nearest_within(&dst.tree, &q, gate2)?;
            let n = dst.normals[t];
            if n.dot(&(turn * src.normals[s])) < MIN_NORMAL_COS {
                return None;
            }
            let r = n.dot(&(q - dst.points[t]));
            Some(Corr {
                x: poses[j].transform_point(&Point3::from(q)).coords,
                m: poses[j].transform_vector(&n),
                r,
                source: s,
            })
        })
        .collect()
}

/// Every edge's correspondences in both directions, with the robust scale
/// of each edge: `(i, j, scale, pairs)` with `i` the source.
type Gathered = Vec<(usize, usize, f64, Vec<Corr>)>;

fn gather(
    views: &[View],
    poses: &[Isometry3<f64>],
    edges: &[(usize, usize)],
    gate: f64,
    coarse: bool,
    p: &IcpParams,
) -> Gathered {
    let max_points = if coarse {
        p.coarse_max_points
    } else {
        usize::MAX
    };
    let mut out = Vec::new();
    for &(a, b) in edges {
        let ab = correspondences(views, poses, a, b, gate, max_points);
        let ba = correspondences(views, poses, b, a, gate, max_points);
        // One scale per overlap: both directions see the same two surfaces.
        let scale = mad_scale(
            ab.iter().chain(&ba).map(|c| c.r.abs()).collect(),
            p.min_scale_m,
        );
        // An overlap that shrank below the minimum under the narrowing gate
        // no longer says much; the solve refuses if that leaves a head free.
        if ab.len() + ba.len() >= p.min_correspondences {
            out.push((a, b, scale, ab));
            out.push((b, a, scale, ba));
        }
    }
    out
}

/// One Gauss-Newton step for every head but 0: the left-multiplied updates.
///
/// With `x` the source point and `m` the target normal in head 0's frame,
/// moving head `i` by a small (omega_i, tau_i) and head `j` by (omega_j,
/// tau_j), both rotating about the correspondences' centroid `c`, changes
/// the residual by `J . (xi_i - xi_j)`, `J = [(x - c) x m, m]`: the target
/// point and its normal move with head `j`, and the normal's turn cancels
/// the target point's lever arm to first order.
fn solve(pairs: &Gathered, heads: usize, p: &IcpParams) -> Option<Vec<Isometry3<f64>>> {
    let (wsum, xsum) = pairs
        .iter()
        .flat_map(|e| {
            let (scale, corr) = (e.2, &e.3);
            corr.iter().map(move |c| {
                let w = p.robust.weight(c.r, scale);
                (w, w * c.x)
            })
        })
        .fold((0.0, Vector3::zeros()), |a, b| (a.0 + b.0, a.1 + b.1));
    if wsum <= 0.0 {
        return None;
    }
    let centre = xsum / wsum;
    let n = 6 * (heads - 1);
    let mut h = DMatrix::<f64>::zeros(n, n);
    let mut g = DVector::<f64>::zeros(n);
    for (i, j, scale, corr) in pairs {
        let (ata, atb) = corr
            .par_iter()
            .fold(
                || (nalgebra::Matrix6::<f64>::zeros(), Vector6::<f64>::zeros()),
                |(mut ata, mut atb), c| {
                    let w = p.robust.weight(c.r, *scale);
                    if w > 0.0 {
                        let a = (c.x - centre).cross(&c.m);
                        let jac = Vector6::new(a.x, a.y, a.z, c.m.x, c.m.y, c.m.z);
                        ata += w * jac * jac.transpose();
                        atb += (w * c.r) * jac;
                    }
                    (ata, atb)
                },
            )
            .reduce(
                || (nalgebra::Matrix6::zeros(), Vector6::zeros()),
                |a, b| (a.0 + b.0, a.1 + b.1),
            );
        // d r / d xi_i = J, d r / d xi_j = -J; head 0 has no unknowns.
        let block = |k: usize| (k > 0).then(|| 6 * (k - 1));
        for (u, su) in [(block(*i), 1.0), (block(*j), -1.0)] {
            let Some(u) = u else { continue };
            let mut gu = g.rows_mut(u, 6);
            gu -= su * atb;
            for (v, sv) in [(block(*i), 1.0), (block(*j), -1.0)] {
                let Some(v) = v else { continue };
                let mut hb = h.view_mut((u, v), (6, 6));
                hb += (su * sv) * ata;
            }
        }
    }
    // As in pairwise ICP: a direction the overlaps do not see (a head
    // linked only through a plane, or by no pair at all) is refused.
    let eig = h.clone().symmetric_eigenvalues();
    let informative = eig.min() > 1e-12 * eig.max();
    if !informative {
        return None;
    }
    let x = h.cholesky()?.solve(&g);
    if !x.iter().all(|v| v.is_finite()) {
        return None;
    }
    let mut updates = vec![Isometry3::identity()];
    for k in 1..heads {
        let s = x.rows(6 * (k - 1), 6);
        let rotation = UnitQuaternion::from_scaled_axis(Vector3::new(s[0], s[1], s[2]));
        let tau = Vector3::new(s[3], s[4], s[5]);
        // y' = R (y - c) + c + tau
        let t = centre - rotation * centre + tau;
        updates.push(Isometry3::from_parts(Translation3::from(t), rotation));
    }
    Some(updates)
}

fn check_divergence(
    pose: &Isometry3<f64>,
    initial: &Isometry3<f64>,
    iteration: usize,
    p: &IcpParams,
) -> Result<(), FusionError> {
    let correction = pose * initial.inverse();
    let rotation_deg = correction.rotation.angle().to_degrees();
    let translation_m = correction.translation.vector.norm();
    let finite = rotation_deg.is_finite() && translation_m.is_finite();
    if !finite
        || rotation_deg > p.max_correction_rotation_deg
        || translation_m > p.max_correction_translation_m
    {
        return Err(FusionError::Diverged {
            iteration,
            rotation_deg,
            translation_m,
        });
    }
    Ok(())
}

/// Figures at the final poses and the last gate.
#[allow(clippy::too_many_arguments)]
fn report(
    views: &[View],
    initial: &[Isometry3<f64>],
    poses: Vec<Isometry3<f64>>,
    edges: &[(usize, usize)],
    gate: f64,
    iterations: usize,
    converged: bool,
    last_step_rotation_deg: f64,
    last_step_translation_m: f64,
    p: &IcpParams,
) -> MultiViewResult {
    let gathered = gather(views, &poses, edges, gate, false, p);
    let k = views.len();
    let mut matched: Vec<Vec<bool>> = views.iter().map(|v| vec![false; v.points.len()]).collect();
    let mut centroid = vec![(Vector3::zeros(), 0usize); k];
    let mut pairs: Vec<PairReport> = edges
        .iter()
        .map(|&heads| PairReport {
            heads,
            inliers: 0,
            overlap_rmse_m: 0.0,
            agreement: None,
        })
        .collect();
    let mut residuals: Vec<Vec<(Vector3<f64>, f64)>> = vec![Vec::new(); edges.len()];
    for (i, j, scale, corr) in &gathered {
        let key = ((*i).min(*j), (*i).max(*j));
        // Every gathered pair comes from an edge, so this always finds it.
        let Some(e) = pairs.iter().position(|r| r.heads == key) else {
            continue;
        };
        for c in corr {
            if p.robust.weight(c.r, *scale) > 0.0 {
                pairs[e].inliers += 1;
                pairs[e].overlap_rmse_m += c.r * c.r;
                residuals[e].push((c.x, c.r));
                matched[*i][c.source] = true;
                centroid[*i].0 += c.x;
                centroid[*i].1 += 1;
            }
        }
    }
    for (r, residuals) in pairs.iter_mut().zip(&residuals) {
        r.agreement = shape_agreement(residuals, AGREEMENT_CELL_M, gate);
        // No inliers left at the final gate (heads whose rims came within
        // the initial gate only): no figure, rather than a perfect 0.
        r.overlap_rmse_m = if r.inliers == 0 {
            f64::NAN
        } else {
            (r.overlap_rmse_m / r.inliers as f64).sqrt()
        };
    }
    let views = (0..k)
        .map(|h| {
            let correction = poses[h] * initial[h].inverse();
            let c = Point3::from(centroid[h].0 / centroid[h].1.max(1) as f64);
            let before = correction.inverse_transform_point(&c);
            ViewReport {
                pose: poses[h],
                correction,
                rotation_correction_deg: correction.rotation.angle().to_degrees(),
                translation_correction_m: (c - before).norm(),
                fitness: matched[h].iter().filter(|&&m| m).count() as f64 / matched[h].len() as f64,
            }
        })
        .collect();
    MultiViewResult {
        views,
        pairs,
        iterations,
        converged,
        last_step_rotation_deg,
        last_step_translation_m,
    }
}

/// One cloud in head 0's frame: head 0's cloud, then each other head's
/// moved by its refined pose and merged in turn ([`merge_clouds`]: a point
/// within the merge radius of one already there joins it).
pub fn merge_views(
    clouds: &[PointCloud],
    result: &MultiViewResult,
    params: &MergeParams,
) -> Result<(PointCloud, Vec<MergeReport>), MultiViewError> {
    if clouds.len() != result.views.len() || clouds.is_empty() {
        return Err(MultiViewError::ViewCount {
            views: clouds.len(),
            poses: result.views.len(),
        });
    }
    let mut merged = clouds[0].transformed(&result.views[0].pose);
    let mut reports = Vec::new();
    for (cloud, view) in clouds.iter().zip(&result.views).skip(1) {
        let (m, r) = merge_clouds(&merged, &cloud.transformed(&view.pose), params)?;
        merged = m;
        reports.push(r);
    }
    Ok((merged, reports))
}

#[cfg(test)]
mod tests;
