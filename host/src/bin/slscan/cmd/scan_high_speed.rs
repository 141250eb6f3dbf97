//! `slscan scan --mode high-speed`: seed 001's 24-pattern colour long exposure
//! on head A, decoded into 24 depth maps per camera frame.

use std::path::Path;

use slscan::scan::high_speed_output::HighSpeedReport;

/// What `scan --sim --mode high-speed` takes from the command line (the
/// hardware rig's scan is `scan::high_speed_hardware`).
#[cfg_attr(
    not(feature = "sim"),
    expect(dead_code, reason = "read by the simulated rig only")
)]
pub struct Options<'a> {
    /// Twin scene.
    pub scene: &'a str,
    /// Output folder.
    pub out: &'a Path,
    /// Camera size, pixels.
    pub camera_px: (u32, u32),
    /// Noise seed.
    pub seed: u64,
    /// Camera frames.
    pub frames: u32,
    /// `--projector-driver`: the DLPC driver and hil-sim's controller.
    pub projector_driver: Option<slscan::rig::dlpc::Controller>,
    /// `--compare-conventional`: also the 12-frame capture of the same motion.
    pub conventional: bool,
    /// `--zocr-model`: ZOCR-Net in place of the analytic first stage.
    pub zocr_model: Option<&'a Path>,
    /// `--fdd-model`: FDD-Net correcting the demodulated phases.
    pub fdd_model: Option<&'a Path>,
    /// `--demod-refinements`: demodulations after the first.
    pub demod_refinements: u32,
    /// `--sibling-cancellations`: passes of sibling cancellation.
    pub sibling_cancellations: u32,
    /// `--consensus-passes`: decodes on carriers predicted from the last.
    pub consensus_passes: u32,
    /// `--settle-edges`: the consensus's holes at depth edges settled.
    pub settle_edges: bool,
}

/// `--zocr-model`, loaded and checked against seed 001's set on a DMD of
/// `dmd_px` before anything else happens.
pub fn load_zocr(
    path: Option<&Path>,
    dmd_px: (u32, u32),
) -> anyhow::Result<Option<slscan::highspeed::ZocrNet>> {
    use anyhow::Context;
    let Some(path) = path else {
        return Ok(None);
    };
    let set = slscan::highspeed::PatternSet::seed001(dmd_px)?;
    let net = slscan::highspeed::ZocrNet::load(path, &set)
        .with_context(|| format!("--zocr-model {}", path.display()))?;
    Ok(Some(net))
}

/// `--fdd-model`, loaded and checked against seed 001's set on a DMD of
/// `dmd_px` before anything else happens.
pub fn load_fdd(
    path: Option<&Path>,
    dmd_px: (u32, u32),
) -> anyhow::Result<Option<slscan::highspeed::FddNet>> {
    use anyhow::Context;
    let Some(path) = path else {
        return Ok(None);
    };
    let set = slscan::highspeed::PatternSet::seed001(dmd_px)?;
    let net = slscan::highspeed::FddNet::load(path, &set)
        .with_context(|| format!("--fdd-model {}", path.display()))?;
    Ok(Some(net))
}

/// Runs the high-speed scan on the simulated rig and prints its summary.
pub fn run(options: &Options) -> anyhow::Result<()> {
    let report = scan_sim(options)?;
    print_summary(&report, options.out);
    Ok(())
}

#[cfg(feature = "sim")]
fn scan_sim(options: &Options) -> anyhow::Result<HighSpeedReport> {
    use anyhow::Context;
    use slscan::scan::high_speed_output::{remove_stale, write_high_speed};
    use slscan::sim::high_speed::{run_sim_high_speed, SimHighSpeedConfig};
    let mut config = SimHighSpeedConfig::new(options.scene);
    config.camera_px = options.camera_px;
    config.seed = options.seed;
    config.scan.frames = options.frames;
    config.projector_driver = options.projector_driver;
    config.conventional = options.conventional;
    config.scan.decoder.demux.refinements = options.demod_refinements;
    config.scan.decoder.demux.cancellations = options.sibling_cancellations;
    config.scan.decoder.consensus_passes = options.consensus_passes;
    config.scan.decoder.settle_edges = options.settle_edges;
    let failed = || {
        format!(
            "high-speed scan into {} failed; nothing written",
            options.out.display()
        )
    };
    remove_stale(options.out).with_context(failed)?;
    config.scan.zocr = load_zocr(options.zocr_model, config.projector_px).with_context(failed)?;
    config.scan.fdd = load_fdd(options.fdd_model, config.projector_px).with_context(failed)?;
    let mut bars = super::scan::Bars::new();
    let result = run_sim_high_speed(&config, &mut |p| bars.on(p)).with_context(failed)?;
    write_high_speed(options.out, &result, config.scan.decoder.depth_range_m).with_context(failed)
}

#[cfg(not(feature = "sim"))]
fn scan_sim(_: &Options) -> anyhow::Result<HighSpeedReport> {
    Err(super::no_simulator("scan --sim --mode high-speed"))
}

/// The scan's figures on the console.
pub fn print_summary(report: &HighSpeedReport, out: &Path) {
    println!(
        "high-speed scan of {}: {} camera frames at {:.0} Hz -> {} instants at {:.0} Hz ({} decoder{})",
        report.scene,
        report.frames,
        report.camera_rate_hz,
        report.instants.len(),
        report.pattern_rate_hz,
        report.decoder,
        match report.sibling_cancellations {
            0 => String::new(),
            n => format!(", {n} sibling cancellation pass(es)"),
        } + &match report.demodulation_refinements {
            0 => String::new(),
            n => format!(", {n} demodulation refinement(s)"),
        } + &match report.consensus_passes {
            0 => String::new(),
            n => format!(", {n} consensus pass(es)"),
        } + if report.settle_edges {
            ", holes at edges settled"
        } else {
            ""
        }
    );
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len().max(1) as f64;
    println!(
        "decode: {:.3} s per camera frame (mean)",
        mean(&report.decode_s)
    );
    let rmse: Vec<f64> = report
        .instants
        .iter()
        .filter_map(|i| i.truth.depth_rmse_um)
        .collect();
    if !rmse.is_empty() {
        let coverage: Vec<f64> = report
            .instants
            .iter()
            .filter_map(|i| i.truth.coverage)
            .collect();
        let mut sorted = rmse.clone();
        sorted.sort_by(f64::total_cmp);
        println!(
            "per instant against the truth at that instant: depth RMSE median {:.1} um (min {:.1}, max {:.1}), coverage mean {:.3}",
            sorted[sorted.len() / 2],
            sorted[0],
            sorted[sorted.len() - 1],
            mean(&coverage)
        );
        let mut interior: Vec<f64> = report
            .instants
            .iter()
            .filter_map(|i| i.truth.interior_depth_rmse_um)
            .filter(|r| r.is_finite())
            .collect();
        interior.sort_by(f64::total_cmp);
        if let (Some(lo), Some(hi)) = (interior.first(), interior.last()) {
            let medians: Vec<f64> = report
                .instants
                .iter()
                .filter_map(|i| i.truth.interior_depth_median_um)
                .collect();
            println!(
                "  object interiors (>= {} px from another object): depth RMSE median {:.1} um (min {lo:.1}, max {hi:.1}), median error mean {:.1} um",
                slscan::scan::high_speed::INTERIOR_MARGIN_PX,
                interior[interior.len() / 2],
                mean(&medians)
            );
        }
        for name in report
            .instants
            .iter()
            .flat_map(|i| i.truth.spheres.iter().map(|s| s.name.clone()))
            .collect::<std::collections::BTreeSet<_>>()
        {
            let fits: Vec<_> = report
                .instants
                .iter()
                .flat_map(|i| i.truth.spheres.iter().filter(|s| s.name == name))
                .collect();
            let whole: Vec<_> = fits.iter().map(|s| &s.whole).collect();
            let interior: Vec<_> = fits.iter().filter_map(|s| s.interior.as_ref()).collect();
            println!(
                "  sphere {name}: fitted at {} instants, {}; interior (>= {} px from another object) at {}, {} (medians over the instants)",
                fits.len(),
                fit_figures(&whole),
                slscan::scan::high_speed::INTERIOR_MARGIN_PX,
                interior.len(),
                fit_figures(&interior),
            );
        }
    }
    if let Some(c) = &report.conventional {
        let um = |v: Option<f64>| v.map_or("n/a".to_string(), |v| format!("{v:.1} um"));
        println!(
            "conventional capture of the same motion ({} frames in {:.1} ms at the same camera rate): coverage {}, depth RMSE {}, median {}, {} of {} points over 1 mm",
            c.frames,
            c.duration_ms,
            c.truth.coverage.map_or("n/a".to_string(), |v| format!("{v:.3}")),
            um(c.truth.depth_rmse_um),
            um(c.truth.depth_median_um),
            c.truth.over_1mm.unwrap_or(0),
            c.points
        );
    }
    println!("wrote {}", out.join("high_speed.ply").display());
}

/// Median fit RMSE, radius and centre errors of `fits` over the instants: a
/// cap too flat to fit gives a radius metres off, which a mean would show.
fn fit_figures(fits: &[&slscan::scan::high_speed_output::SphereFitReport]) -> String {
    if fits.is_empty() {
        return "no fit".into();
    }
    let median = |g: fn(&slscan::scan::high_speed_output::SphereFitReport) -> f64| {
        let mut v: Vec<f64> = fits.iter().map(|f| g(f)).collect();
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    format!(
        "fit RMSE {:.1} um, radius error {:+.1} um, centre error {:.1} um",
        median(|f| f.fit_rmse_um),
        median(|f| f.radius_error_um),
        median(|f| f.centre_error_um)
    )
}
