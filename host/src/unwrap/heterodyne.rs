//! Multi-frequency heterodyne (beat) unwrapping for 2, 3, 4 ... periods.
//!
//! Adjacent periods beat: `phi_ab = wrap(phi_a - phi_b)` is the wrapped phase of the
//! frequency `1/P_a - 1/P_b`. Beating level by level leaves one phase whose period covers
//! the field; going back down, each level's fringe order is rounded from the level above
//! (`k = round((Phi_parent * f / f_parent - phi) / 2 pi)`). A pixel whose rounding
//! residual exceeds `max_residual_rad` at any level is marked unreliable.
//!
//! Periods as in the seeds: 100/110/120/130 px (000), 59/64/70 px (002), and the
//! three-pitch `W/(S+sqrt(S)+1), W/S, W/(S-sqrt(S))` of seed 004
//! ([`crate::patterns::three_pitch_periods_px`]).

use rayon::prelude::*;

use super::{check_temporal_inputs, fringe_order, AbsolutePhase, PixelStatus, UnwrapError};
use crate::raster::Raster;
use crate::simd::{simd_run, Simd};

/// Largest number of periods (a fixed bound keeps the per-pixel kernel on the stack).
pub const MAX_PERIODS: usize = 8;

/// A heterodyne unwrapper for one period set and field (set up once, used per pixel).
#[derive(Clone, Debug, PartialEq)]
pub struct Heterodyne {
    periods_px: Vec<f64>,
    /// Signed frequency (cycles/px) of node 0 at each level, level 0 first.
    chain_freq: Vec<f64>,
    /// Ratio `f_level / f_(level+1)` of node 0, per level below the top.
    ratios: Vec<f32>,
    /// Lowest phase the top beat takes over the field, radians.
    top_floor_rad: f32,
    max_residual_rad: f32,
    /// Largest standard deviation of a rounding estimate, in units of the (common)
    /// wrapped-phase noise: see [`Heterodyne::order_noise_gain`].
    order_noise_gain: f64,
}

impl Heterodyne {
    /// Sets up for `periods_px` (finest first; the result is the absolute phase of
    /// `periods_px[0]`) and a field of `range_px` projector pixels (`u` in `[0, range_px)`).
    ///
    /// `max_residual_rad` is the largest rounding residual accepted at any level
    /// (`pi/2` is a good default: it flags pixels long before orders are miscounted).
    pub fn new(
        periods_px: &[f64],
        range_px: f64,
        max_residual_rad: f64,
    ) -> Result<Self, UnwrapError> {
        let k = periods_px.len();
        if !(2..=MAX_PERIODS).contains(&k) {
            return Err(UnwrapError::NotEnoughInputs {
                method: "heterodyne",
                got: k,
                need: 2,
            });
        }
        let bad = || UnwrapError::BadPeriods {
            periods_px: periods_px.to_vec(),
        };
        if periods_px.iter().any(|p| !(p.is_finite() && *p > 0.0)) {
            return Err(bad());
        }
        // Beat tree of signed frequencies; node 0 of each level is the chain we unwrap.
        let mut level: Vec<f64> = periods_px.iter().map(|p| 1.0 / p).collect();
        let mut chain_freq = vec![level[0]];
        while level.len() > 1 {
            let next: Vec<f64> = level.windows(2).map(|w| w[0] - w[1]).collect();
            if next.iter().any(|f| f.abs() < 1e-12) {
                return Err(bad());
            }
            chain_freq.push(next[0]);
            level = next;
        }
        let top = *chain_freq.last().expect("at least one level");
        let unambiguous_px = 1.0 / top.abs();
        // Relative slack: beats like 16/18 -> 144 px come out as 143.99999999999994.
        if unambiguous_px < range_px * (1.0 - 1e-9) {
            return Err(UnwrapError::RangeTooShort {
                periods_px: periods_px.to_vec(),
                unambiguous_px,
                range_px,
            });
        }
        // Centre the field inside the top beat's period so both field edges keep a margin.
        let margin_px = ((unambiguous_px - range_px) / 2.0).max(0.0);
        let tau = std::f64::consts::TAU;
        let top_floor_rad = if top > 0.0 {
            tau * top * (-margin_px)
        } else {
            tau * top * (range_px + margin_px)
        };
        let ratios: Vec<f32> = chain_freq
            .windows(2)
            .map(|w| (w[0] / w[1]) as f32)
            .collect();
        // Track node 0 of each level as a combination of the input phases, so the noise of
        // every rounding estimate `ratio * Phi_(l+1) - phi_l` is known exactly.
        let mut nodes: Vec<Vec<f64>> = (0..k)
            .map(|j| (0..k).map(|i| f64::from(u8::from(i == j))).collect())
            .collect();
        let mut chain_coef = vec![nodes[0].clone()];
        while nodes.len() > 1 {
            nodes = nodes
                .windows(2)
                .map(|w| w[0].iter().zip(&w[1]).map(|(a, b)| a - b).collect())
                .collect();
            chain_coef.push(nodes[0].clone());
        }
        let order_noise_gain = (0..k - 1)
            .map(|l| {
                let r = f64::from(ratios[l]);
                chain_coef[l + 1]
                    .iter()
                    .zip(&chain_coef[l])
                    .map(|(up, here)| (r * up - here).powi(2))
                    .sum::<f64>()
                    .sqrt()
            })
            .fold(0.0, f64::max);
        Ok(Self {
            periods_px: periods_px.to_vec(),
            chain_freq,
            ratios,
            top_floor_rad: top_floor_rad as f32,
            max_residual_rad: max_residual_rad as f32,
            order_noise_gain,
        })
    }

    /// Standard deviation of the worst rounding estimate per unit of wrapped-phase noise
    /// (all periods equally noisy). A pixel with phase noise `sigma` miscounts an order
    /// with probability about `P(|N(0,1)| > pi / (gain * sigma))`; the residual check
    /// cannot see such errors, so callers reject pixels whose `gain * sigma` is too large
    /// (see [`crate::reconstruct::ReconstructConfig::order_sigmas`]).
    pub fn order_noise_gain(&self) -> f64 {
        self.order_noise_gain
    }

    /// The periods, projector pixels.
    pub fn periods_px(&self) -> &[f64] {
        &self.periods_px
    }

    /// Period of the top beat, projector pixels (the unambiguous range).
    pub fn beat_period_px(&self) -> f64 {
        1.0 / self.chain_freq.last().expect("levels").abs()
    }

    /// Absolute phase of `periods_px[0]` from one pixel's wrapped phases (same order as
    /// the periods); `None` when a rounding residual is too large.
    #[inline]
    pub fn unwrap_pixel(&self, wrapped: &[f32]) -> Option<f32> {
        let k = self.periods_px.len();
        let mut level = [0.0f32; MAX_PERIODS];
        level[..k].copy_from_slice(&wrapped[..k]);
        // chain[l] = wrapped phase of node 0 at level l.
        let mut chain = [0.0f32; MAX_PERIODS];
        chain[0] = level[0];
        for (l, slot) in chain.iter_mut().enumerate().take(k).skip(1) {
            for j in 0..k - l {
                level[j] = wrap_difference(level[j] - level[j + 1]);
            }
            *slot = level[0];
        }
        let tau = std::f32::consts::TAU;
        // Top: lift the wrapped phase into [floor, floor + 2 pi).
        let top = chain[k - 1];
        let mut absolute = top + tau * super::ceil_fast((self.top_floor_rad - top) / tau);
        for l in (0..k - 1).rev() {
            let estimate = absolute * self.ratios[l];
            let order = fringe_order(estimate, chain[l], self.max_residual_rad)?;
            absolute = chain[l] + tau * order;
        }
        Some(absolute)
    }

    /// [`Heterodyne::unwrap_pixel`] for a run of pixels: `wrapped[p * len + x]` is the
    /// wrapped phase of period p at pixel x (`len = absolute.len()`); `absolute[x]` gets
    /// the same value as `unwrap_pixel`, NaN where it gives `None`.
    ///
    /// Same operations in the same order as `unwrap_pixel`, but branch-free over tiles of
    /// pixels with the level loops outside, so the pixel loops vectorise.
    ///
    /// # Panics
    /// If `wrapped.len()` is not `periods x absolute.len()` (a caller bug, not bad data).
    #[inline(always)]
    pub fn unwrap_row(&self, wrapped: &[f32], absolute: &mut [f32]) {
        let k = self.periods_px.len();
        let len = absolute.len();
        assert_eq!(wrapped.len(), k * len, "one wrapped row per period");
        let mut rows: [&[f32]; MAX_PERIODS] = [&[]; MAX_PERIODS];
        for (p, row) in rows.iter_mut().take(k).enumerate() {
            *row = &wrapped[p * len..(p + 1) * len];
        }
        self.unwrap_rows(&rows[..k], absolute);
    }

    /// [`Heterodyne::unwrap_row`] with each period's row its own slice (`wrapped[p][x]`):
    /// the kernel of both the pipeline and [`Heterodyne::unwrap`], so they agree bit for
    /// bit.
    ///
    /// # Panics
    /// If there is not one row per period, each `absolute.len()` long.
    #[inline(always)]
    pub fn unwrap_rows(&self, wrapped: &[&[f32]], absolute: &mut [f32]) {
        const TILE: usize = 64;
        let k = self.periods_px.len();
        let len = absolute.len();
        assert!(
            wrapped.len() == k && wrapped.iter().all(|r| r.len() == len),
            "one wrapped row per period"
        );
        let tau = std::f32::consts::TAU;
        let max_residual = self.max_residual_rad;
        // Zeroed once per row, not per tile (4 KiB each: zeroing them per tile cost as much
        // as a tenth of the unwrap); each tile overwrites the first `k` entries it reads.
        let mut level = [[0.0f32; TILE]; MAX_PERIODS];
        let mut chain = [[0.0f32; TILE]; MAX_PERIODS];
        let mut x0 = 0;
        while x0 < len {
            let n = TILE.min(len - x0);
            for p in 0..k {
                level[p][..n].copy_from_slice(&wrapped[p][x0..x0 + n]);
            }
            chain[0] = level[0];
            for (l, slot) in chain.iter_mut().enumerate().take(k).skip(1) {
                for j in 0..k - l {
                    let (lo, hi) = level.split_at_mut(j + 1);
                    let (a, b) = (&mut lo[j][..n], &hi[0][..n]);
                    for x in 0..n {
                        a[x] = wrap_difference(a[x] - b[x]);
                    }
                }
                *slot = level[0];
            }
            let mut abs = [0.0f32; TILE];
            let top = &chain[k - 1];
            for x in 0..n {
                abs[x] = top[x] + tau * super::ceil_fast((self.top_floor_rad - top[x]) / tau);
            }
            for l in (0..k - 1).rev() {
                let ratio = self.ratios[l];
                let c = &chain[l];
                for x in 0..n {
                    // `fringe_order` without the early return: a refused pixel turns
                    // NaN, which every later level keeps (a NaN residual fails too).
                    let estimate = abs[x] * ratio;
                    let turns = (estimate - c[x]) * (1.0 / tau);
                    let order = super::round_fast(turns);
                    let residual = (turns - order) * tau;
                    abs[x] = if residual.abs() <= max_residual {
                        c[x] + tau * order
                    } else {
                        f32::NAN
                    };
                }
            }
            absolute[x0..x0 + n].copy_from_slice(&abs[..n]);
            x0 += n;
        }
    }

    /// Unwraps whole maps (same order as the periods). Pixels outside `mask` are
    /// [`PixelStatus::Masked`].
    ///
    /// Rayon over rows, each through [`Heterodyne::unwrap_rows`] built for the widest
    /// SIMD the CPU has: the pipeline's kernel, so a pixel gets the same bits as from
    /// [`Heterodyne::unwrap_pixel`].
    pub fn unwrap(
        &self,
        wrapped: &[&Raster<f32>],
        mask: Option<&Raster<bool>>,
    ) -> Result<AbsolutePhase, UnwrapError> {
        let mut out = AbsolutePhase {
            phase: Raster {
                width: 0,
                height: 0,
                data: Vec::new(),
            },
            status: Raster {
                width: 0,
                height: 0,
                data: Vec::new(),
            },
            period_px: self.periods_px[0],
        };
        self.unwrap_into(wrapped, mask, &mut out)?;
        Ok(out)
    }

    /// [`Heterodyne::unwrap`] into an existing result, reusing its buffers (no fresh
    /// memory to fault in). `out` is overwritten; on error it is left as it was.
    pub fn unwrap_into(
        &self,
        wrapped: &[&Raster<f32>],
        mask: Option<&Raster<bool>>,
        out: &mut AbsolutePhase,
    ) -> Result<(), UnwrapError> {
        let (width, height) =
            check_temporal_inputs("heterodyne", self.periods_px.len(), wrapped, mask)?;
        // Every element is written by the row pass; fresh memory is filled in parallel on
        // huge pages so its page faults are not one thread's serial cost.
        crate::huge_pages::sized(&mut out.phase.data, width * height, 0.0f32);
        crate::huge_pages::sized(&mut out.status.data, width * height, PixelStatus::Masked);
        (out.phase.width, out.phase.height) = (width, height);
        (out.status.width, out.status.height) = (width, height);
        out.period_px = self.periods_px[0];
        let simd = Simd::best();
        out.phase
            .data
            .par_chunks_mut(width.max(1))
            .zip(out.status.data.par_chunks_mut(width.max(1)))
            .enumerate()
            .for_each(|(y, (phase, status))| {
                let span = y * width..(y + 1) * width;
                let mut rows: [&[f32]; MAX_PERIODS] = [&[]; MAX_PERIODS];
                for (row, map) in rows.iter_mut().zip(wrapped) {
                    *row = &map.data[span.clone()];
                }
                let mask = mask.map(|m| &m.data[span]);
                simd_run!(simd, {
                    self.unwrap_rows(&rows[..wrapped.len()], phase);
                    status_row(phase, status, mask);
                });
            });
        Ok(())
    }
}

/// One row's status from its unwrapped phase (NaN: refused) and mask, the phase set to
/// NaN where masked. Selects only, so the loop vectorises.
#[inline(always)]
pub(crate) fn status_row(phase: &mut [f32], status: &mut [PixelStatus], mask: Option<&[bool]>) {
    let status = &mut status[..phase.len()];
    match mask {
        Some(mask) => {
            let mask = &mask[..phase.len()];
            for x in 0..phase.len() {
                let refused = phase[x].is_nan();
                status[x] = if !mask[x] {
                    PixelStatus::Masked
                } else if refused {
                    PixelStatus::Unreliable
                } else {
                    PixelStatus::Valid
                };
                phase[x] = if mask[x] { phase[x] } else { f32::NAN };
            }
        }
        None => {
            for x in 0..phase.len() {
                status[x] = if phase[x].is_nan() {
                    PixelStatus::Unreliable
                } else {
                    PixelStatus::Valid
                };
            }
        }
    }
}

/// Wraps the difference of two wrapped phases (in (-2 pi, 2 pi)) back into (-pi, pi]
/// without a division: this runs for every pixel and level.
#[inline(always)]
fn wrap_difference(d: f32) -> f32 {
    use std::f32::consts::{PI, TAU};
    if d > PI {
        d - TAU
    } else if d <= -PI {
        d + TAU
    } else {
        d
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::phase::wrap_pi;
    use std::f32::consts::{FRAC_PI_2, TAU};

    fn wrapped_at(periods: &[f64], u: f64) -> Vec<f32> {
        periods
            .iter()
            .map(|p| wrap_pi((TAU as f64 * u / p) as f32))
            .collect()
    }

    fn check_exact(periods: &[f64], range: f64) {
        let h = Heterodyne::new(periods, range, FRAC_PI_2 as f64).unwrap();
        let mut u = 0.0;
        while u < range - 0.5 {
            let got = h.unwrap_pixel(&wrapped_at(periods, u)).expect("reliable");
            let want = (TAU as f64 * u / periods[0]) as f32;
            assert!(
                (got - want).abs() < 2e-3 * want.abs().max(1.0),
                "{periods:?} u={u}: {got} vs {want}"
            );
            u += 0.37;
        }
    }

    #[test]
    fn seed_period_sets_unwrap_exactly() {
        check_exact(&[100.0, 110.0, 120.0, 130.0], 3072.0); // seed 000, 4 periods
        check_exact(&[59.0, 64.0, 70.0], 1024.0); // seed 002, 3 periods
        check_exact(&[16.0, 18.0], 144.0); // 2 periods
        let s = 64.0f64;
        let w = 912.0;
        let counts = [s + s.sqrt() + 1.0, s, s - s.sqrt()];
        let periods: Vec<f64> = counts.iter().map(|c| w / c).collect();
        check_exact(&periods, w); // seed 004 three-pitch
    }

    #[test]
    fn order_noise_gain_matches_hand_derivation() {
        // 2 periods: estimate = r (e0 - e1) - e0 -> sqrt((r - 1)^2 + r^2), r = P1/(P1 - P0)...
        let h = Heterodyne::new(&[20.0, 22.0], 200.0, 1.0).unwrap();
        let r = 11.0f64; // beat 220 px / 20 px
        assert!((h.order_noise_gain() - ((r - 1.0).powi(2) + r * r).sqrt()).abs() < 1e-4);
        // 3 periods 20/22/24: level 1 gives (r-1, -(2r-1), r) with r = 1320/220 = 6.
        let h = Heterodyne::new(&[20.0, 22.0, 24.0], 900.0, 1.0).unwrap();
        let top = (25.0f64 + 121.0 + 36.0).sqrt();
        assert!((h.order_noise_gain() - top.max(221.0f64.sqrt())).abs() < 1e-3);
    }

    #[test]
    fn corrupted_phase_is_flagged_not_guessed() {
        let periods = [100.0, 110.0, 120.0];
        let h = Heterodyne::new(&periods, 1000.0, FRAC_PI_2 as f64).unwrap();
        let mut w = wrapped_at(&periods, 400.0);
        w[1] = wrap_pi(w[1] + 1.4); // a strong local error on one frequency
        assert_eq!(h.unwrap_pixel(&w), None);
    }

    #[test]
    fn configuration_errors() {
        assert!(matches!(
            Heterodyne::new(&[100.0], 10.0, 1.0),
            Err(UnwrapError::NotEnoughInputs { .. })
        ));
        assert!(matches!(
            Heterodyne::new(&[100.0, 100.0], 10.0, 1.0),
            Err(UnwrapError::BadPeriods { .. })
        ));
        assert!(matches!(
            Heterodyne::new(&[100.0, 110.0], 2000.0, 1.0),
            Err(UnwrapError::RangeTooShort { .. })
        ));
        let h = Heterodyne::new(&[10.0, 11.0], 100.0, 1.0).unwrap();
        let a = Raster::filled(4, 4, 0.0f32);
        let b = Raster::filled(4, 5, 0.0f32);
        assert!(matches!(
            h.unwrap(&[&a], None),
            Err(UnwrapError::WrongInputCount { .. })
        ));
        assert!(matches!(
            h.unwrap(&[&a, &b], None),
            Err(UnwrapError::SizeMismatch { .. })
        ));
    }

    #[test]
    fn map_unwrap_respects_mask() {
        let periods = [20.0, 22.0];
        let h = Heterodyne::new(&periods, 200.0, FRAC_PI_2 as f64).unwrap();
        let maps: Vec<Raster<f32>> = (0..2)
            .map(|i| Raster::from_fn(200, 2, |x, _| wrapped_at(&periods, x as f64)[i]))
            .collect();
        let mask = Raster::from_fn(200, 2, |x, _| x != 7);
        let out = h.unwrap(&[&maps[0], &maps[1]], Some(&mask)).unwrap();
        assert_eq!(out.count(PixelStatus::Masked), 2);
        assert_eq!(out.count(PixelStatus::Valid), 398);
        assert!((out.projector_coordinate(150, 1).unwrap() - 150.0).abs() < 1e-3);
    }

    #[test]
    fn row_kernel_matches_pixel_kernel() {
        let periods = [100.0, 110.0, 120.0];
        let h = Heterodyne::new(&periods, 1920.0, FRAC_PI_2 as f64).unwrap();
        let len = 3000;
        // A ramp over the field plus a deterministic disturbance on some pixels so that
        // both accepted and refused pixels (and NaN input) are compared.
        let mut wrapped = vec![0.0f32; 3 * len];
        for x in 0..len {
            let u = x as f64 * 0.64;
            for (p, w) in wrapped_at(&periods, u).into_iter().enumerate() {
                let kick = if x % 7 == 3 { 1.3 * p as f32 } else { 0.0 };
                wrapped[p * len + x] = wrap_pi(w + kick);
            }
        }
        wrapped[5] = f32::NAN;
        let mut row = vec![0.0f32; len];
        h.unwrap_row(&wrapped, &mut row);
        let mut refused = 0;
        for x in 0..len {
            let w: Vec<f32> = (0..3).map(|p| wrapped[p * len + x]).collect();
            match h.unwrap_pixel(&w) {
                Some(v) => assert_eq!(v.to_bits(), row[x].to_bits(), "x={x}"),
                None => {
                    assert!(row[x].is_nan(), "x={x}");
                    refused += 1;
                }
            }
        }
        assert!(refused > 100 && refused < len / 2, "{refused}");
    }

    mod proptests {
        use super::super::*;
        use proptest::prelude::*;

        proptest! {
            #![proptest_config(ProptestConfig { cases: 64, ..ProptestConfig::default() })]
            #[test]
            fn row_kernel_is_the_pixel_kernel(
                k in 2usize..5,
                phases in proptest::collection::vec(-3.2f32..3.2, 4 * 70),
            ) {
                let periods = [20.0, 22.0, 24.5, 27.0];
                let h = Heterodyne::new(&periods[..k], 150.0, 1.2).unwrap();
                let len = 70;
                let wrapped = &phases[..k * len];
                let mut row = vec![0.0f32; len];
                h.unwrap_row(wrapped, &mut row);
                for x in 0..len {
                    let w: Vec<f32> = (0..k).map(|p| wrapped[p * len + x]).collect();
                    let want = h.unwrap_pixel(&w).unwrap_or(f32::NAN);
                    prop_assert_eq!(want.to_bits(), row[x].to_bits());
                }
            }

            #[test]
            fn map_api_is_the_pixel_kernel(
                k in 2usize..5,
                (width, height) in (1usize..90, 1usize..4),
                phases in proptest::collection::vec(-3.2f32..3.2, 4 * 89 * 3),
                masked in proptest::collection::vec(proptest::bool::weighted(0.2), 89 * 3),
                nan_at in 0usize..89 * 3,
                with_mask: bool,
            ) {
                // Whole maps through the row kernel (SIMD build, status pass) against the
                // per-pixel kernel: same bits where valid, NaN and the right status
                // elsewhere, NaN input refused.
                let periods = [20.0, 22.0, 24.5, 27.0];
                let h = Heterodyne::new(&periods[..k], 150.0, 1.2).unwrap();
                let len = width * height;
                let mut maps: Vec<Raster<f32>> = phases
                    .chunks(len)
                    .take(k)
                    .map(|c| Raster { width, height, data: c.to_vec() })
                    .collect();
                maps[k - 1].data[nan_at % len] = f32::NAN;
                let mask = Raster { width, height, data: masked[..len].iter().map(|m| !m).collect() };
                let refs: Vec<&Raster<f32>> = maps.iter().collect();
                let out = h.unwrap(&refs, with_mask.then_some(&mask)).unwrap();
                // Into a result of another size: the same maps.
                let stale = Raster::filled(5, 3, 0.5f32);
                let mut reused = h.unwrap(&vec![&stale; k], None).unwrap();
                h.unwrap_into(&refs, with_mask.then_some(&mask), &mut reused).unwrap();
                prop_assert_eq!(&reused.status, &out.status);
                prop_assert_eq!(
                    reused.phase.data.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
                    out.phase.data.iter().map(|v| v.to_bits()).collect::<Vec<_>>()
                );
                for i in 0..len {
                    let w: Vec<f32> = maps.iter().map(|m| m.data[i]).collect();
                    let (want, status) = if with_mask && !mask.data[i] {
                        (f32::NAN, PixelStatus::Masked)
                    } else {
                        match h.unwrap_pixel(&w) {
                            Some(v) => (v, PixelStatus::Valid),
                            None => (f32::NAN, PixelStatus::Unreliable),
                        }
                    };
                    prop_assert_eq!(out.status.data[i], status, "pixel {}", i);
                    prop_assert_eq!(out.phase.data[i].to_bits(), want.to_bits(), "pixel {}", i);
                }
            }
        }
    }
}
