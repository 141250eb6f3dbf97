//! `slscan register A.ply B.ply`: point-to-plane ICP of cloud B onto cloud A
//! (PLY files from any tool), from an initial guess (a two-head rig file's
//! head-to-head pose, a 4x4 matrix, or none); prints and writes the B -> A
//! transform with its fitness and overlap RMSE.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context};
use nalgebra::{Isometry3, Matrix3, Matrix4, Rotation3, Translation3, UnitQuaternion, Vector3};
use serde::Serialize;
use slscan::calibration::read_rig;
use slscan::fusion::{estimate_normals, register, IcpParams, IcpResult, PointCloud};
use slscan::io::ply_read::{read_ply, PlyCloud};
use slscan::io::write_atomically;

/// The clouds, their unit and the initial guess (shared with `slscan fuse`).
#[derive(clap::Args)]
pub struct RegistrationArgs {
    /// The fixed cloud (target), PLY (ASCII or binary).
    pub a: PathBuf,
    /// The moving cloud (source), PLY.
    pub b: PathBuf,
    /// Length unit of the files' coordinates (and of --initial-matrix).
    #[arg(long, value_enum, default_value_t = Unit::M)]
    pub unit: Unit,
    /// Initial B -> A guess: a two-head rig file (its head_to_head pose, A -> B, inverted).
    #[arg(long, value_name = "RIG.json", conflicts_with = "initial_matrix")]
    pub initial_rig: Option<PathBuf>,
    /// Initial B -> A guess: a JSON 4x4 row-major matrix (`[[..],[..],[..],[0,0,0,1]]`,
    /// translation in --unit).
    #[arg(long, value_name = "MATRIX.json")]
    pub initial_matrix: Option<PathBuf>,
    /// Correspondence gate of the first iteration, mm: more than the initial
    /// guess's worst displacement over the overlap.
    #[arg(long, default_value_t = 20.0)]
    pub max_distance_mm: f64,
    /// Gate the schedule narrows to, mm: a few point spacings.
    #[arg(long, default_value_t = 2.0)]
    pub final_distance_mm: f64,
    /// Neighbours for the target's normals when its file has none.
    #[arg(long, default_value_t = 12)]
    pub normals_k: usize,
}

/// Coordinate units.
#[derive(Clone, Copy, Debug, clap::ValueEnum)]
pub enum Unit {
    /// Metres.
    M,
    /// Millimetres.
    Mm,
}

impl Unit {
    /// Metres per unit.
    pub fn metres(self) -> f64 {
        match self {
            Unit::M => 1.0,
            Unit::Mm => 1e-3,
        }
    }
}

/// Options of `slscan register`.
#[derive(clap::Args)]
pub struct Args {
    #[command(flatten)]
    clouds: RegistrationArgs,
    /// Write the transform here (JSON: 4x4 matrix in metres, rotation in
    /// degrees, translation in mm, fitness, overlap RMSE).
    #[arg(long, value_name = "FILE")]
    out: Option<PathBuf>,
}

/// The two clouds read and B registered onto A.
pub struct Registered {
    /// Cloud A (with normals).
    pub a: PlyCloud,
    /// Cloud B as read.
    pub b: PlyCloud,
    /// The registration.
    pub icp: IcpResult,
}

/// Reads both clouds, estimates A's normals when its file has none and
/// registers B onto A.
pub fn register_clouds(args: &RegistrationArgs) -> anyhow::Result<Registered> {
    let unit = args.unit.metres();
    let gates = [args.max_distance_mm, args.final_distance_mm];
    if gates.iter().any(|g| !(g.is_finite() && *g > 0.0)) || gates[1] > gates[0] {
        bail!("--max-distance-mm and --final-distance-mm must be positive, the final no larger");
    }
    // Before reading megabytes of points: the guess must be usable.
    let initial = initial_guess(args, unit)?;
    let read = |p: &Path| read_ply(p, unit).with_context(|| format!("reading {}", p.display()));
    let mut a = read(&args.a)?;
    let b = read(&args.b)?;
    if a.cloud.normals.is_none() {
        let normals = estimate_normals(&a.cloud.points, args.normals_k, &Vector3::zeros())
            .with_context(|| format!("normals of {}", args.a.display()))?;
        a.cloud.normals = Some(normals);
    }
    let params = IcpParams {
        initial_gate_m: args.max_distance_mm * 1e-3,
        final_gate_m: args.final_distance_mm * 1e-3,
        ..IcpParams::default()
    };
    let icp = register(&b.cloud, &a.cloud, &initial, &params)
        .context("registering B onto A (did not converge)")?;
    if !icp.converged {
        bail!(
            "registration did not converge in {} iterations: fitness {:.3}, overlap RMSE {:.1} um, \
             correction {:.4} deg / {:.1} um; check the initial guess and --max-distance-mm",
            icp.iterations,
            icp.fitness,
            icp.overlap_rmse_m * 1e6,
            icp.rotation_correction_deg,
            icp.translation_correction_m * 1e6
        );
    }
    Ok(Registered { a, b, icp })
}

/// The B -> A guess of the options (identity without one).
fn initial_guess(args: &RegistrationArgs, unit_m: f64) -> anyhow::Result<Isometry3<f64>> {
    if let Some(path) = &args.initial_rig {
        let rig = read_rig(path).with_context(|| format!("reading {}", path.display()))?;
        let Some(a_to_b) = rig.head_to_head() else {
            bail!("{}: no head_to_head pose (a one-head rig)", path.display());
        };
        return Ok(a_to_b.to_isometry().inverse());
    }
    if let Some(path) = &args.initial_matrix {
        let text =
            std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
        let rows: [[f64; 4]; 4] = serde_json::from_str(&text)
            .with_context(|| format!("{}: not a JSON 4x4 matrix", path.display()))?;
        return isometry_of(&rows, unit_m).with_context(|| path.display().to_string());
    }
    Ok(Isometry3::identity())
}

/// A row-major 4x4 rigid transform (translation in `unit_m` metres).
fn isometry_of(rows: &[[f64; 4]; 4], unit_m: f64) -> anyhow::Result<Isometry3<f64>> {
    let m = Matrix4::from_fn(|i, j| rows[i][j]);
    if m.iter().any(|v| !v.is_finite()) {
        bail!("the matrix has a non-finite entry");
    }
    if (m.fixed_view::<1, 4>(3, 0) - nalgebra::RowVector4::new(0.0, 0.0, 0.0, 1.0)).norm() > 1e-9 {
        bail!("the last row is not 0 0 0 1");
    }
    let r: Matrix3<f64> = m.fixed_view::<3, 3>(0, 0).into();
    if (r.transpose() * r - Matrix3::identity()).norm() > 1e-6 || r.determinant() < 0.0 {
        bail!("the upper-left 3x3 is not a rotation");
    }
    let t = Vector3::new(m[(0, 3)], m[(1, 3)], m[(2, 3)]) * unit_m;
    let rotation = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(r));
    Ok(Isometry3::from_parts(Translation3::from(t), rotation))
}

/// What `register` prints and writes.
#[derive(Serialize)]
struct TransformReport {
    /// B -> A, row-major, metres.
    matrix_b_to_a_m: [[f64; 4]; 4],
    rotation_deg: f64,
    rotation_axis: [f64; 3],
    translation_mm: [f64; 3],
    correction_rotation_deg: f64,
    correction_translation_um: f64,
    fitness: f64,
    overlap_rmse_um: f64,
    inliers: usize,
    iterations: usize,
    converged: bool,
}

fn report(icp: &IcpResult) -> TransformReport {
    let t = &icp.transform;
    let m = t.to_homogeneous();
    let axis = t
        .rotation
        .axis()
        .map_or([0.0, 0.0, 1.0], |a| [a.x, a.y, a.z]);
    TransformReport {
        matrix_b_to_a_m: [0, 1, 2, 3].map(|i| [0, 1, 2, 3].map(|j| m[(i, j)])),
        rotation_deg: t.rotation.angle().to_degrees(),
        rotation_axis: axis,
        translation_mm: (t.translation.vector * 1e3).into(),
        correction_rotation_deg: icp.rotation_correction_deg,
        correction_translation_um: icp.translation_correction_m * 1e6,
        fitness: icp.fitness,
        overlap_rmse_um: icp.overlap_rmse_m * 1e6,
        inliers: icp.inliers,
        iterations: icp.iterations,
        converged: icp.converged,
    }
}

/// Prints the registration of `r` for people.
pub fn print_registration(r: &Registered) {
    let rep = report(&r.icp);
    println!(
        "A: {} points, B: {} points; B -> A: rotation {:.6} deg about ({:.4}, {:.4}, {:.4}), translation ({:.4}, {:.4}, {:.4}) mm",
        r.a.cloud.points.len(),
        r.b.cloud.points.len(),
        rep.rotation_deg,
        rep.rotation_axis[0],
        rep.rotation_axis[1],
        rep.rotation_axis[2],
        rep.translation_mm[0],
        rep.translation_mm[1],
        rep.translation_mm[2]
    );
    println!(
        "fitness {:.4} ({} inliers), overlap RMSE {:.2} um, {} iterations, correction of the guess {:.4} deg / {:.1} um",
        rep.fitness,
        rep.inliers,
        rep.overlap_rmse_um,
        rep.iterations,
        rep.correction_rotation_deg,
        rep.correction_translation_um
    );
}

/// Runs `slscan register`.
pub fn run(args: Args) -> anyhow::Result<()> {
    // An earlier transform must not pass for this run's when it fails.
    if let Some(path) = &args.out {
        slscan::io::outputs::OutputSet::new([path.clone()]).clear()?;
    }
    let registered = register_clouds(&args.clouds)?;
    print_registration(&registered);
    if let Some(path) = &args.out {
        let json = serde_json::to_vec_pretty(&report(&registered.icp))?;
        write_atomically(path, |w| w.write_all(&json))
            .with_context(|| format!("writing {}", path.display()))?;
        println!("wrote {}", path.display());
    }
    Ok(())
}

/// Cloud B moved into A's frame.
pub fn moved_b(r: &Registered) -> PointCloud {
    r.b.cloud.transformed(&r.icp.transform)
}
