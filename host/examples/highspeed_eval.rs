//! Phase error of the analytic high-speed decoder (seed 001's 24-pattern colour
//! long exposure), stage by stage, on random twin scenes it has never seen:
//! wrapped-phase MAE against the twin's true phase, and for the whole decoder
//! the share of pixels unwrapped right and the depth error per instant.
//!
//! With `--zocr models/highspeed_zocr.onnx`, also seed 001's first network
//! (ZOCR-Net) in place of the analytic crosstalk and zero-order removal:
//! its own outputs against the twin's noise-free AC and zero order, beside
//! the formula's, and the whole decoder with it.
//!
//! With `--fdd models/highspeed_fdd.onnx`, also seed 001's third network
//! (FDD-Net) correcting the analytic demodulation's phases.
//!
//! The analytic decoder is also run with its demodulation refined once and
//! twice (`DemuxOptions::refinements`, the scan's `--demod-refinements`),
//! with one and two passes of sibling cancellation
//! (`DemuxOptions::cancellations`, `--sibling-cancellations`; with `--zocr`,
//! also after ZOCR-Net), and decoded again on carriers predicted from the
//! depth its patterns agree on (`DecoderConfig::consensus_passes`,
//! `--consensus-passes`), alone and after sibling cancellation.
//!
//! `cargo run --release -p slscan --example highspeed_eval -- [--count N] [--seed S] [--samples N] [--moving] [--zocr PATH] [--fdd PATH]`
//! (`--samples`: points on each pixel's epipolar segment, the decoder's default unless given;
//! `--moving`: the same scenes with their objects spinning or flying through the
//! exposure, each pattern measured against the scene at its own instant; the
//! first stage's AC and zero-order truths are then mid-exposure's, an approximation)

use std::path::PathBuf;

use anyhow::Context;
use hil_sim::twin::scenes::{single_head, Detail};
use slscan::highspeed::{
    crosstalk_from_flats, Decoder, DecoderConfig, DemuxOptions, FddNet, PatternSet,
    ZeroOrderRemoved, ZocrNet,
};
use slscan::phase::ftp::{ftp_phase, FringeAxis};
use slscan::raster::Raster;
use slscan::sim::high_speed_samples::{random_high_speed_sample, HighSpeedSample, SceneMotion};

/// Which learned stage a variant adds to the analytic decoder.
#[derive(Clone, Copy)]
enum Learned {
    No,
    Zocr,
    Fdd,
}

fn detail_size(detail: &Detail) -> (usize, usize) {
    (detail.camera.0 as usize, detail.camera.1 as usize)
}

/// Stage 1's outputs against the twin's noise-free AC and zero order.
#[derive(Default)]
struct Stage1 {
    ac_sq: f64,
    dc_sq: f64,
    truth_sq: f64,
    n: usize,
}

impl Stage1 {
    fn add(&mut self, out: &ZeroOrderRemoved, s: &HighSpeedSample) {
        for c in 0..3 {
            for i in 0..s.ac[c].len() {
                self.ac_sq += f64::from(out.fringes[c][i] - s.ac[c][i]).powi(2);
                self.dc_sq += f64::from(out.zero_order[c][i] - s.dc[c][i]).powi(2);
                self.truth_sq += f64::from(s.ac[c][i]).powi(2);
                self.n += 1;
            }
        }
    }
    fn rms(&self, sq: f64) -> f64 {
        (sq / self.n.max(1) as f64).sqrt()
    }
    fn ac_rmse(&self) -> f64 {
        self.rms(self.ac_sq)
    }
    fn dc_rmse(&self) -> f64 {
        self.rms(self.dc_sq)
    }
    fn truth_rms(&self) -> f64 {
        self.rms(self.truth_sq)
    }
}

/// Pixels whose surface moved more than 1 mm in depth between the first
/// and the last pattern's instants (or came into or out of view).
fn moved_pixels(s: &HighSpeedSample) -> Vec<bool> {
    let (first, last) = (&s.depth_m[0], &s.depth_m[s.depth_m.len() - 1]);
    first
        .iter()
        .zip(last)
        .map(|(a, b)| a.is_finite() != b.is_finite() || (a - b).abs() > 1e-3)
        .collect()
}

/// Per pixel, the city-block distance (pixels, capped at 255) to the nearest
/// depth edge of the middle instant's truth: a pixel next to one whose depth
/// differs by more than 1 %, or next to an unlit one (the image border is
/// not an edge). Two chamfer sweeps.
fn edge_distance(depth_m: &[f32], width: usize, height: usize) -> Vec<u8> {
    let z = |x: usize, y: usize| depth_m[y * width + x];
    let mut d: Vec<u8> = (0..width * height)
        .map(|i| {
            let (x, y) = (i % width, i / width);
            let here = z(x, y);
            let neighbours = [
                (x > 0).then(|| z(x - 1, y)),
                (x + 1 < width).then(|| z(x + 1, y)),
                (y > 0).then(|| z(x, y - 1)),
                (y + 1 < height).then(|| z(x, y + 1)),
            ];
            let edge = neighbours
                .iter()
                .flatten()
                .any(|&n| here.is_finite() != n.is_finite() || (n - here).abs() > 0.01 * here);
            if edge {
                0
            } else {
                u8::MAX
            }
        })
        .collect();
    for y in 0..height {
        for x in 0..width {
            let i = y * width + x;
            if x > 0 {
                d[i] = d[i].min(d[i - 1].saturating_add(1));
            }
            if y > 0 {
                d[i] = d[i].min(d[i - width].saturating_add(1));
            }
        }
    }
    for y in (0..height).rev() {
        for x in (0..width).rev() {
            let i = y * width + x;
            if x + 1 < width {
                d[i] = d[i].min(d[i + 1].saturating_add(1));
            }
            if y + 1 < height {
                d[i] = d[i].min(d[i + width].saturating_add(1));
            }
        }
    }
    d
}

/// Distance bands to the nearest depth edge ([`edge_distance`]), pixels.
const EDGE_BANDS: [(u8, u8, &str); 4] = [
    (0, 2, "0-2 px"),
    (3, 6, "3-6 px"),
    (7, 15, "7-15 px"),
    (16, u8::MAX, "16+ px"),
];

fn wrap(a: f32) -> f32 {
    let t = std::f32::consts::TAU;
    a - t * (a / t).round()
}

#[derive(Default)]
struct Tally {
    abs_err: f64,
    n: usize,
}

impl Tally {
    fn add(&mut self, wrapped: &[f32], truth: &[f32]) {
        self.add_where(wrapped, truth, |_| true);
    }
    fn add_where(&mut self, wrapped: &[f32], truth: &[f32], keep: impl Fn(usize) -> bool) {
        for (i, (w, t)) in wrapped.iter().zip(truth).enumerate() {
            if keep(i) && t.is_finite() && w.is_finite() {
                self.abs_err += f64::from(wrap(w - t).abs());
                self.n += 1;
            }
        }
    }
    fn mae(&self) -> f64 {
        self.abs_err / self.n.max(1) as f64
    }
}

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let arg = |name: &str, default: u64| -> anyhow::Result<u64> {
        match args.iter().position(|a| a == name) {
            Some(i) => args
                .get(i + 1)
                .context("missing value")?
                .parse()
                .with_context(|| name.to_string()),
            None => Ok(default),
        }
    };
    let count = arg("--count", 6)?;
    let seed = arg("--seed", 9001)?;
    let epipolar_samples = arg("--samples", DecoderConfig::default().samples as u64)? as usize;
    let zocr_path = match args.iter().position(|a| a == "--zocr") {
        Some(i) => Some(PathBuf::from(
            args.get(i + 1).context("--zocr needs a path")?,
        )),
        None => None,
    };
    let fdd_path = match args.iter().position(|a| a == "--fdd") {
        Some(i) => Some(PathBuf::from(
            args.get(i + 1).context("--fdd needs a path")?,
        )),
        None => None,
    };
    let motion = if args.iter().any(|a| a == "--moving") {
        SceneMotion::Moving
    } else {
        SceneMotion::Static
    };
    let detail = Detail::default();
    let set = PatternSet::seed001(detail.projector)?;
    let calibration = slscan::sim::truth::twin_calibration(&single_head(&detail), 1);
    let head = &calibration.heads[0];
    println!(
        "{count} random {} twin scenes (seed {seed}), {}x{} colour camera (8-bit), {}x{} DMD, 24 x 200 us in one 4.8 ms exposure",
        if motion == SceneMotion::Moving {
            "moving"
        } else {
            "static"
        },
        detail.camera.0, detail.camera.1, detail.projector.0, detail.projector.1
    );
    let samples: Vec<HighSpeedSample> = (0..count)
        .map(|i| random_high_speed_sample(&set, &detail, seed, i, motion))
        .collect::<Result<_, _>>()?;
    let moved: Vec<Vec<bool>> = samples.iter().map(moved_pixels).collect();
    let share = moved.iter().flatten().filter(|&&m| m).count() as f64
        / moved.iter().map(Vec::len).sum::<usize>().max(1) as f64;
    println!(
        "{:.1} % of the pixels' surfaces moved > 1 mm in depth over the exposure",
        100.0 * share
    );
    let zocr = zocr_path.map(|p| ZocrNet::load(&p, &set)).transpose()?;
    let fdd = fdd_path.map(|p| FddNet::load(&p, &set)).transpose()?;
    let flats0 = &samples[0].flats;
    let view = |l: usize| [&flats0[l][0][..], &flats0[l][1][..], &flats0[l][2][..]];
    let crosstalk = crosstalk_from_flats([view(0), view(1), view(2)], 0.995)?;
    println!("crosstalk measured from scene 0's three LED flats (channel <- LED): {crosstalk:.3}");
    // (name, reference carrier, crosstalk, zero-order removal, refinements, cancellations, consensus passes, holes settled, learned stage)
    let mut variants = vec![
        (
            "linear carrier (FTP-like), raw channels",
            false,
            false,
            false,
            0,
            0,
            0,
            false,
            Learned::No,
        ),
        (
            "linear carrier + crosstalk + zero-order removal",
            false,
            true,
            true,
            0,
            0,
            0,
            false,
            Learned::No,
        ),
        (
            "reference carrier, raw channels, zero-order removal",
            true,
            false,
            true,
            0,
            0,
            0,
            false,
            Learned::No,
        ),
        (
            "reference carrier + crosstalk, no zero-order removal",
            true,
            true,
            false,
            0,
            0,
            0,
            false,
            Learned::No,
        ),
        (
            "reference carrier + crosstalk + zero-order removal (analytic)",
            true,
            true,
            true,
            0,
            0,
            0,
            false,
            Learned::No,
        ),
        (
            "analytic, demodulated again by its own phase (1 refinement)",
            true,
            true,
            true,
            1,
            0,
            0,
            false,
            Learned::No,
        ),
        (
            "analytic, demodulated twice more (2 refinements)",
            true,
            true,
            true,
            2,
            0,
            0,
            false,
            Learned::No,
        ),
        (
            "analytic + sibling cancellation (stage 2: spatial-frequency decomposition, 1 pass)",
            true,
            true,
            true,
            0,
            1,
            0,
            false,
            Learned::No,
        ),
        (
            "analytic + consensus re-demodulation (1 pass)",
            true,
            true,
            true,
            0,
            0,
            1,
            false,
            Learned::No,
        ),
        (
            "analytic + consensus re-demodulation (2 passes)",
            true,
            true,
            true,
            0,
            0,
            2,
            false,
            Learned::No,
        ),
        (
            "analytic + sibling cancellation + consensus re-demodulation (1 pass each)",
            true,
            true,
            true,
            0,
            1,
            1,
            false,
            Learned::No,
        ),
        (
            "analytic + consensus re-demodulation (1 pass), holes at edges settled (settle_edges)",
            true,
            true,
            true,
            0,
            0,
            1,
            true,
            Learned::No,
        ),
        (
            "analytic + consensus re-demodulation (2 passes), holes at edges settled",
            true,
            true,
            true,
            0,
            0,
            2,
            true,
            Learned::No,
        ),
        (
            "analytic + sibling cancellation + consensus re-demodulation (1 pass each), holes at edges settled",
            true,
            true,
            true,
            0,
            1,
            1,
            true,
            Learned::No,
        ),
        (
            "analytic + sibling cancellation, 2 passes",
            true,
            true,
            true,
            0,
            2,
            0,
            false,
            Learned::No,
        ),
    ];
    if zocr.is_some() {
        variants.push((
            "reference carrier after ZOCR-Net (learned stage 1)",
            true,
            false,
            true,
            0,
            0,
            0,
            false,
            Learned::Zocr,
        ));
        variants.push((
            "ZOCR-Net + sibling cancellation (learned stage 1, stage 2 by formula)",
            true,
            false,
            true,
            0,
            1,
            0,
            false,
            Learned::Zocr,
        ));
    }
    if fdd.is_some() {
        variants.push((
            "reference carrier + crosstalk + zero-order removal + FDD-Net (learned stage 3)",
            true,
            true,
            true,
            0,
            0,
            0,
            false,
            Learned::Fdd,
        ));
    }
    // The shipped analytic decoder: stage 1's reference and the oracle's first pass.
    let analytic = Decoder::new(
        set.clone(),
        head,
        DecoderConfig {
            demux: DemuxOptions {
                crosstalk: Some(crosstalk),
                ..DemuxOptions::default()
            },
            samples: epipolar_samples,
            ..DecoderConfig::default()
        },
    )?;
    if let Some(net) = &zocr {
        let (w, h) = detail_size(&detail);
        let mut rows = [Stage1::default(), Stage1::default()];
        for s in &samples {
            let planes = [
                &s.channels[0].data[..],
                &s.channels[1].data,
                &s.channels[2].data,
            ];
            rows[0].add(&analytic.demultiplexer().remove_zero_order(planes), s);
            rows[1].add(&net.remove_zero_order(planes, w, h)?, s);
        }
        println!(
            "\nStage 1 against the twin's noise-free fringes and zero order (RMS of the true AC: {:.4} full scale)",
            rows[0].truth_rms()
        );
        println!("\n| zero-order and crosstalk removal | fringe (AC) RMSE | zero-order RMSE |");
        println!("|---|---|---|");
        for (name, r) in [
            "analytic (crosstalk matrix from flats, Gaussian low band)",
            "ZOCR-Net",
        ]
        .iter()
        .zip(&rows)
        {
            println!("| {name} | {:.4} | {:.4} |", r.ac_rmse(), r.dc_rmse());
        }
    }
    // Plain row FTP per pattern: each channel as if it held one fringe.
    let mut ftp = Tally::default();
    let probe = Decoder::new(set.clone(), head, DecoderConfig::default())?;
    for s in &samples {
        for (p, w) in set.patterns().iter().zip(probe.demultiplexer().windows()) {
            let period = 1.0 / f64::from(w.carrier[0].abs());
            if let Ok(out) = ftp_phase(&s.channels[p.colour], period, FringeAxis::X) {
                ftp.add(&out.phase.data, &s.phase[p.index]);
            }
        }
    }
    let edges: Vec<Vec<u8>> = samples
        .iter()
        .map(|s| {
            edge_distance(
                &s.depth_m[s.depth_m.len() / 2],
                detail.camera.0 as usize,
                detail.camera.1 as usize,
            )
        })
        .collect();
    let mut by_edge_rows = Vec::new();
    println!("\n| decoder | wrapped-phase MAE, rad | MAE where the surface moved | decoded, of lit | unwrapped right, of decoded | depth RMSE of those, um |");
    println!("|---|---|---|---|---|---|");
    println!(
        "| row FTP per pattern (slscan::phase::ftp) | {:.4} | | | | |",
        ftp.mae()
    );
    for (name, reference, xtalk, zero, refinements, cancellations, consensus, settle, learned) in
        variants
    {
        let config = DecoderConfig {
            demux: DemuxOptions {
                crosstalk: xtalk.then_some(crosstalk),
                zero_order_removal: zero,
                reference_demodulation: reference,
                refinements,
                cancellations,
                ..DemuxOptions::default()
            },
            consensus_passes: consensus,
            settle_edges: settle,
            samples: epipolar_samples,
            ..DecoderConfig::default()
        };
        let mut decoder = Decoder::new(set.clone(), head, config)?;
        match learned {
            Learned::No => {}
            Learned::Zocr => decoder = decoder.with_zocr(zocr.clone().context("no --zocr")?),
            Learned::Fdd => decoder = decoder.with_fdd(fdd.clone().context("no --fdd")?)?,
        }
        let (mut tally, mut tally_moved) = (Tally::default(), Tally::default());
        let mut by_edge: [Tally; EDGE_BANDS.len()] = Default::default();
        let (mut decoded, mut right, mut lit) = (0usize, 0usize, 0usize);
        let mut depth_sq = 0.0f64;
        for ((s, moved), edge) in samples.iter().zip(&moved).zip(&edges) {
            let out = decoder.decode([&s.channels[0], &s.channels[1], &s.channels[2]])?;
            for (m, instant) in out.instants.iter().enumerate() {
                tally.add(&out.fringes.wrapped[m], &s.phase[m]);
                tally_moved.add_where(&out.fringes.wrapped[m], &s.phase[m], |i| moved[i]);
                for (band, &(lo, hi, _)) in by_edge.iter_mut().zip(&EDGE_BANDS) {
                    band.add_where(&out.fringes.wrapped[m], &s.phase[m], |i| {
                        (lo..=hi).contains(&edge[i])
                    });
                }
                for i in 0..s.depth_m[m].len() {
                    let t = s.phase[m][i];
                    if !t.is_finite() {
                        continue;
                    }
                    lit += 1;
                    let a = instant.absolute_phase[i];
                    if a.is_finite() {
                        decoded += 1;
                        if (a - t).abs() < std::f32::consts::PI {
                            right += 1;
                            depth_sq += f64::from(instant.depth_m[i] - s.depth_m[m][i]).powi(2);
                        }
                    }
                }
            }
        }
        let moved_mae = if tally_moved.n > 0 {
            format!("{:.4}", tally_moved.mae())
        } else {
            "-".into()
        };
        println!(
            "| {name} | {:.4} | {moved_mae} | {:.3} | {:.4} | {:.1} |",
            tally.mae(),
            decoded as f64 / lit.max(1) as f64,
            right as f64 / decoded.max(1) as f64,
            1e6 * (depth_sq / right.max(1) as f64).sqrt()
        );
        by_edge_rows.push((name, by_edge));
    }
    // The ceiling of the consensus pass: one pass on carriers predicted from
    // the twin's true depth instead of the 24 depths' consensus (an oracle,
    // not a decoder: how much a better prediction could still give).
    let (mut oracle, mut oracle_by_edge) =
        (Tally::default(), <[Tally; EDGE_BANDS.len()]>::default());
    for (s, edge) in samples.iter().zip(&edges) {
        let planes = [
            &s.channels[0].data[..],
            &s.channels[1].data,
            &s.channels[2].data,
        ];
        // The first pass's demultiplexing (what the decoder's consensus
        // pass starts from), without its unwrapping, which the oracle does
        // not need: the LEDs' fringes kept for the second demodulation.
        let demux = analytic.demultiplexer();
        let cleaned = demux.remove_zero_order(planes);
        let led_fringes = cleaned.fringes.clone();
        let first = demux.demodulate_all(cleaned);
        let mut wrapped = first.wrapped;
        let middle = Raster {
            width: detail.camera.0 as usize,
            height: detail.camera.1 as usize,
            data: s.depth_m[s.depth_m.len() / 2].clone(),
        };
        let at = analytic.dmd_at_depths(&middle)?;
        demux.demodulate_at(&led_fringes, &at, &mut wrapped, &first.modulation);
        for (m, w) in wrapped.iter().enumerate() {
            oracle.add(w, &s.phase[m]);
            for (band, &(lo, hi, _)) in oracle_by_edge.iter_mut().zip(&EDGE_BANDS) {
                band.add_where(w, &s.phase[m], |i| (lo..=hi).contains(&edge[i]));
            }
        }
    }
    let oracle_name =
        "oracle: one consensus pass on the true depth of the middle instant (not a decoder)";
    println!("| {oracle_name} | {:.4} | | | | |", oracle.mae());
    by_edge_rows.push((oracle_name, oracle_by_edge));
    // Where the error sits: near the scenes' depth edges (object outlines,
    // shadows) or on smooth surface.
    let share: Vec<String> = (0..EDGE_BANDS.len())
        .map(|b| {
            format!(
                "{:.1} %",
                100.0 * by_edge_rows[0].1[b].n as f64
                    / by_edge_rows[0].1.iter().map(|t| t.n).sum::<usize>().max(1) as f64
            )
        })
        .collect();
    println!(
        "\nWrapped-phase MAE (rad) by distance to the nearest depth edge of the middle instant's truth (share of the first row's measured pixels: {})",
        share.join(", ")
    );
    let header: Vec<&str> = EDGE_BANDS.iter().map(|b| b.2).collect();
    println!("\n| decoder | {} |", header.join(" | "));
    println!("|---|{}", "---|".repeat(EDGE_BANDS.len()));
    for (name, by_edge) in &by_edge_rows {
        let cells: Vec<String> = by_edge.iter().map(|t| format!("{:.4}", t.mae())).collect();
        println!("| {name} | {} |", cells.join(" | "));
    }
    Ok(())
}
