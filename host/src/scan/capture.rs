//! Capture of the two heads' frames for each mode, and their reduction to
//! the plain N-step frames the per-head reconstruction reads.
//!
//! - sequential: head A alone, then head B alone (two board runs).
//! - simultaneous-multiplexed: one board run, both heads at once, N = 8
//!   steps per period, head A's shifts on temporal bin 1 and head B's on
//!   bin 2 ([`crate::demultiplex`]). Each camera's 8 samples per period are
//!   demultiplexed per pixel; its own head's (phase, modulation, background)
//!   is re-expressed as 4 equivalent 4-step frames (`A + B cos(phi + pi n/2)`,
//!   which the 4-step decoder returns exactly), so the unchanged
//!   reconstruction runs on them.
//! - simultaneous: one run, both heads show identical 4-step sequences at
//!   once; pixels lit by both projectors are aliased (see `mod.rs`).

use hil_sim::twin::TwinRig;
use protocol::HeadSet;

use super::{plan, twin_truth, Mode, Progress, ScanConfig, ScanError};
use crate::demultiplex::{phase_shift_rad, Demultiplexer, DemuxError, TemporalBins};
use crate::raster::Raster;
use crate::rig::{Board, Camera, Projector};

/// Frames ready for the 4-step (or N-step) reconstruction, per head.
pub struct Captured {
    /// Per head: what its camera took, in trigger order (for pictures).
    pub raw: Vec<Vec<Raster<f32>>>,
    /// Per head: period-major frames of `steps` shifts for the reconstruction.
    pub frames: Vec<Vec<Raster<f32>>>,
    /// Steps per period in `frames`.
    pub steps: usize,
    /// Phase-noise factor of `frames` relative to raw `steps`-step frames
    /// (demultiplexed 8 samples into 4 equivalent frames: sqrt(4/8)).
    pub noise_factor: f32,
}

/// Runs the board and cameras for `config.mode`.
pub fn capture<R: Board + Projector + Camera>(
    rig: &mut R,
    config: &ScanConfig,
    progress: &mut dyn FnMut(Progress),
) -> Result<Captured, ScanError> {
    match config.mode {
        Mode::Sequential => sequential(rig, config, progress),
        Mode::Simultaneous => simultaneous(rig, config, progress),
        Mode::SimultaneousMultiplexed => multiplexed(rig, config, progress),
    }
}

/// Patterns as the projector should receive them: pre-compensated for its
/// response when the config asks.
fn for_projector(mut patterns: Vec<Raster<f32>>, config: &ScanConfig) -> Vec<Raster<f32>> {
    if let Some(gamma) = config.precompensate_gamma {
        plan::precompensate_gamma(&mut patterns, gamma);
    }
    patterns
}

fn run(rig: &mut impl Board, plan: &protocol::ScanPlan, what: &str) -> Result<(), ScanError> {
    let outcome = rig.run_plan(plan)?;
    tracing::info!(
        run = what,
        start_tick = outcome.start_tick,
        worst_error_ticks = outcome.report.worst_error_ticks,
        "board ran the plan clean"
    );
    Ok(())
}

fn sequential<R: Board + Projector + Camera>(
    rig: &mut R,
    config: &ScanConfig,
    progress: &mut dyn FnMut(Progress),
) -> Result<Captured, ScanError> {
    let count = config.periods_px.len() * config.steps;
    let patterns = for_projector(
        plan::fringe_sequence(config.projector_px, &config.periods_px, config.steps),
        config,
    );
    let mut raw = Vec::new();
    for (h, heads) in [HeadSet::A, HeadSet::B].into_iter().enumerate() {
        let name = ["capture A", "capture B"][h];
        progress(Progress::Stage { name, total: 2 });
        rig.load_sequence(h, &patterns)?;
        run(rig, &plan::one_pattern_per_exposure(heads, count)?, name)?;
        progress(Progress::Step);
        raw.push(rig.take_frames(h)?);
        progress(Progress::Step);
        progress(Progress::Done);
    }
    Ok(Captured {
        frames: raw.clone(),
        raw,
        steps: config.steps,
        noise_factor: 1.0,
    })
}

fn simultaneous<R: Board + Projector + Camera>(
    rig: &mut R,
    config: &ScanConfig,
    progress: &mut dyn FnMut(Progress),
) -> Result<Captured, ScanError> {
    let count = config.periods_px.len() * config.steps;
    let patterns = for_projector(
        plan::fringe_sequence(config.projector_px, &config.periods_px, config.steps),
        config,
    );
    progress(Progress::Stage {
        name: "capture A+B",
        total: 3,
    });
    for h in 0..2 {
        rig.load_sequence(h, &patterns)?;
    }
    run(
        rig,
        &plan::one_pattern_per_exposure(HeadSet::BOTH, count)?,
        "A+B",
    )?;
    progress(Progress::Step);
    let mut raw = Vec::new();
    for h in 0..2 {
        raw.push(rig.take_frames(h)?);
        progress(Progress::Step);
    }
    progress(Progress::Done);
    Ok(Captured {
        frames: raw.clone(),
        raw,
        steps: config.steps,
        noise_factor: 1.0,
    })
}

fn multiplexed<R: Board + Projector + Camera>(
    rig: &mut R,
    config: &ScanConfig,
    progress: &mut dyn FnMut(Progress),
) -> Result<Captured, ScanError> {
    let bins = TemporalBins::design_default();
    let n = bins.steps();
    let count = config.periods_px.len() * n;
    progress(Progress::Stage {
        name: "capture A+B",
        total: 3,
    });
    for (h, bin) in [bins.bin_a(), bins.bin_b()].into_iter().enumerate() {
        let shifts: Vec<f64> = (0..n).map(|k| phase_shift_rad(bin, k, n)).collect();
        let patterns = for_projector(
            plan::shifted_fringes(config.projector_px, &config.periods_px, &shifts),
            config,
        );
        rig.load_sequence(h, &patterns)?;
    }
    run(
        rig,
        &plan::one_pattern_per_exposure(HeadSet::BOTH, count)?,
        "A+B multiplexed",
    )?;
    progress(Progress::Step);
    let demux = Demultiplexer::new(bins);
    let mut raw = Vec::new();
    let mut frames = Vec::new();
    for h in 0..2 {
        let taken = rig.take_frames(h)?;
        frames.push(demultiplexed_frames(&demux, &taken, h).map_err(|source| {
            ScanError::Demultiplex {
                head: twin_truth::HEAD_NAMES[h],
                source,
            }
        })?);
        raw.push(taken);
        progress(Progress::Step);
    }
    progress(Progress::Done);
    Ok(Captured {
        raw,
        frames,
        steps: 4,
        noise_factor: (4.0f32 / n as f32).sqrt(),
    })
}

/// Head `head`'s 4 equivalent frames per period from a camera's N samples
/// per period (period-major).
fn demultiplexed_frames(
    demux: &Demultiplexer,
    taken: &[Raster<f32>],
    head: usize,
) -> Result<Vec<Raster<f32>>, DemuxError> {
    let n = demux.bins().steps();
    let mut out = Vec::new();
    for period in taken.chunks(n) {
        let slices: Vec<&[f32]> = period.iter().map(|r| r.data.as_slice()).collect();
        let images = demux.frames(&slices)?;
        let own = if head == 0 {
            &images.head_a
        } else {
            &images.head_b
        };
        let (w, h) = period[0].size();
        for step in 0..4 {
            let shift = std::f32::consts::FRAC_PI_2 * step as f32;
            let data = images
                .background
                .iter()
                .zip(&own.phase_rad)
                .zip(&own.modulation)
                .map(|((a, phi), b)| a + b * (phi + shift).cos())
                .collect();
            out.push(Raster {
                width: w,
                height: h,
                data,
            });
        }
    }
    Ok(out)
}

/// Simultaneous mode with identical sequences: pixels lit by both
/// projectors see aliased fringes. With no de-aliaser yet they are masked
/// out (frames zeroed there, so the reconstruction masks them) using the
/// twin's TRUE overlap mask, with a loud PLACEHOLDER warning.
pub fn mask_aliased_overlap(
    captured: &mut Captured,
    twin: &TwinRig,
    warnings: &mut Vec<String>,
) -> Result<(), ScanError> {
    for (h, frames) in captured.frames.iter_mut().enumerate() {
        let renderer = twin.renderer(h)?;
        let g = renderer.geometry();
        // Widened by about 1 % of the image width (3 px at 320): defocus
        // and the other projector's light edge alias the pixels next to
        // the true overlap too.
        let radius = (g.width as usize).div_ceil(100);
        let overlap = &dilate(&g.overlap, g.width as usize, g.height as usize, radius);
        let masked = overlap.iter().filter(|&&o| o).count();
        let warning = format!(
            "PLACEHOLDER: simultaneous mode: camera {} has {masked} pixels lit by both projectors \
             (aliased fringes) or within {radius} px of them; they are MASKED OUT using the twin's truth overlap mask, since the \
             learned de-aliaser (seed 000) does not exist yet",
            twin_truth::HEAD_NAMES[h]
        );
        tracing::warn!("{warning}");
        warnings.push(warning);
        for f in frames.iter_mut() {
            for (v, &o) in f.data.iter_mut().zip(overlap) {
                if o {
                    // Zero modulation: the reconstruction masks the pixel.
                    *v = 0.0;
                }
            }
        }
    }
    Ok(())
}

/// `mask` grown by `radius` pixels (square neighbourhood).
fn dilate(mask: &[bool], width: usize, height: usize, radius: usize) -> Vec<bool> {
    let mut out = vec![false; mask.len()];
    for y in 0..height {
        for x in 0..width {
            if !mask[y * width + x] {
                continue;
            }
            for yy in y.saturating_sub(radius)..(y + radius + 1).min(height) {
                for xx in x.saturating_sub(radius)..(x + radius + 1).min(width) {
                    out[yy * width + xx] = true;
                }
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn demultiplexed_frames_decode_to_each_heads_own_phase() {
        let bins = TemporalBins::design_default();
        let demux = Demultiplexer::new(bins);
        let (phi_a, phi_b) = (0.7f64, -2.1f64);
        let taken: Vec<Raster<f32>> = (0..8)
            .map(|k| {
                let v = 0.4
                    + 0.2 * (phi_a + phase_shift_rad(1, k, 8)).cos()
                    + 0.1 * (phi_b + phase_shift_rad(2, k, 8)).cos();
                Raster::filled(2, 1, v as f32)
            })
            .collect();
        for (head, want) in [(0, phi_a), (1, phi_b)] {
            let f = demultiplexed_frames(&demux, &taken, head).unwrap();
            assert_eq!(f.len(), 4);
            let s: Vec<f64> = f.iter().map(|r| r.data[0] as f64).collect();
            // 4-step decode: atan2(-(I1 - I3), I0 - I2).
            let got = (-(s[1] - s[3])).atan2(s[0] - s[2]);
            assert!((got - want).abs() < 1e-5, "head {head}: {got} vs {want}");
        }
    }
}
