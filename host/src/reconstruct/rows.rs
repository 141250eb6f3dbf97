//! The per-row stages of the pipeline, each a loop over a whole row so that it
//! vectorises: decode and unwrap ([`TemporalDecoder`](crate::unwrap::temporal::TemporalDecoder)'s
//! row functions: phase per period, heterodyne), finish (ray/plane triangulation, status,
//! noise, organised output).
//!
//! [`super::Reconstructor::reconstruct`] runs all three per row while the row is in
//! cache; [`super::Reconstructor::reconstruct_staged`] runs each over the whole image
//! for the bench's breakdown. Both call these functions, so they agree bit for bit.

use super::maps::RowMut;
use super::Reconstructor;
use crate::phase::Sample;
use crate::simd::simd_run;
use crate::triangulation::ColumnHits;
use crate::unwrap::temporal::DecodedRow;
use crate::unwrap::PixelStatus;

/// One row's projector coordinates and what triangulating them gave.
#[derive(Default)]
pub(super) struct Projected {
    /// Projector column per pixel (NaN: nothing to triangulate).
    column: Vec<f32>,
    /// Projector row per pixel (two directions only).
    row: Vec<f32>,
    hits: ColumnHits,
}

/// Per-task buffers of the fused pass (allocated once per rayon job, not per row).
#[derive(Default)]
pub(super) struct Scratch {
    pub u: DecodedRow,
    pub v: DecodedRow,
    projected: Projected,
}

impl Reconstructor {
    /// Triangulates one unwrapped row (`first_index` = index of its first pixel) into the
    /// organised output; returns the number of valid pixels.
    #[inline(always)]
    pub(super) fn finish_row(
        &self,
        first_index: usize,
        u: &DecodedRow,
        v: Option<&DecodedRow>,
        projected: &mut Projected,
        out: RowMut<'_>,
    ) -> usize {
        if let Some(v) = v {
            return self.finish_row_two_rays(first_index, u, v, projected, out);
        }
        let Projected {
            column: scratch_column,
            hits,
            ..
        } = projected;
        let width = out.status.len();
        let p0 = self.config.periods_px[0] as f32;
        let tau = std::f32::consts::TAU;
        let extent = self.triangulator.projector().width_px as f32 - 0.5;
        let (min_mod, min_reliable) = (self.config.min_modulation, self.min_reliable_modulation);
        let px_per_rad = p0 / tau;
        // Projector column per pixel; NaN where there is nothing to triangulate, so a
        // pixel has a point exactly when it is valid.
        scratch_column.clear();
        scratch_column.extend((0..width).map(|x| {
            let c = u.absolute[x] * px_per_rad;
            let b = u.min_modulation[x];
            if b >= min_reliable && b >= min_mod && c >= -0.5 && c <= extent {
                c
            } else {
                f32::NAN
            }
        }));
        self.triangulator
            .intersect_columns(first_index, scratch_column, hits);
        // CRB phase noise of the finest period -> projector pixels, times metres per pixel.
        let sigma_px_times_b = self.noise_times_crb * p0 / tau;
        // Every slice cut to the row's length, so the loop has no bounds checks and
        // vectorises (selects only: the status is one of three constants).
        let (b_min, absolute) = (&u.min_modulation[..width], &u.absolute[..width]);
        let (b0, background) = (&u.modulation[..width], &u.background[..width]);
        let [hx, hy, hz] = &hits.point_m;
        let (hx, hy, hz) = (&hx[..width], &hy[..width], &hz[..width]);
        let (depth, range_per_px) = (&hits.depth_m[..width], &hits.range_per_px[..width]);
        let RowMut {
            status,
            phase_u,
            point_m: [px, py, pz],
            depth_m,
            sigma_m,
            modulation,
            background: out_background,
        } = out;
        let (status, phase_u, depth_m, sigma_m) = (
            &mut status[..width],
            &mut phase_u[..width],
            &mut depth_m[..width],
            &mut sigma_m[..width],
        );
        let (px, py, pz) = (&mut px[..width], &mut py[..width], &mut pz[..width]);
        let (modulation, out_background) = (&mut modulation[..width], &mut out_background[..width]);
        let mut valid = 0;
        for x in 0..width {
            let b = b_min[x];
            // As `direction_phase`: NaN modulation fails both comparisons.
            let usable = b >= min_mod;
            let reliable = usable & (b >= min_reliable);
            let hit = !depth[x].is_nan();
            status[x] = if hit {
                PixelStatus::Valid
            } else if usable {
                PixelStatus::Unreliable
            } else {
                PixelStatus::Masked
            };
            phase_u[x] = if reliable { absolute[x] } else { f32::NAN };
            (px[x], py[x], pz[x]) = (hx[x], hy[x], hz[x]);
            depth_m[x] = depth[x];
            // NaN without a point (`range_per_px` is NaN there).
            let sigma_px = sigma_px_times_b * self.noise_scale(background[x]) / b0[x];
            sigma_m[x] = range_per_px[x] * sigma_px;
            modulation[x] = b;
            out_background[x] = background[x];
            valid += usize::from(hit);
        }
        valid
    }

    /// [`Reconstructor::finish_row`] with both directions: ray / ray, as whole-row loops
    /// that vectorise ([`crate::triangulation::Triangulator::intersect_two_rays_row`]).
    /// A pixel's status is that of the first direction that fails (columns first).
    #[inline(always)]
    fn finish_row_two_rays(
        &self,
        first_index: usize,
        u: &DecodedRow,
        v: &DecodedRow,
        projected: &mut Projected,
        out: RowMut<'_>,
    ) -> usize {
        let width = out.status.len();
        let p0 = self.config.periods_px[0] as f32;
        let tau = std::f32::consts::TAU;
        let px_per_rad = p0 / tau;
        let projector = self.triangulator.projector();
        let (last_u, last_v) = (
            projector.width_px as f32 - 0.5,
            projector.height_px as f32 - 0.5,
        );
        let (min_mod, min_reliable) = (self.config.min_modulation, self.min_reliable_modulation);
        // Usable (modulation above the mask) and reliable (order noise, heterodyne), per
        // direction; `&`, not `&&`, and NaN fails every comparison.
        let usable = |d: &DecodedRow, x: usize| d.min_modulation[x] >= min_mod;
        let reliable = |d: &DecodedRow, x: usize| {
            usable(d, x) & (d.min_modulation[x] >= min_reliable) & !d.absolute[x].is_nan()
        };
        let Projected { column, row, hits } = projected;
        column.clear();
        row.clear();
        for x in 0..width {
            let (c, r) = (u.absolute[x] * px_per_rad, v.absolute[x] * px_per_rad);
            let on_dmd = (c >= -0.5) & (c <= last_u) & (r >= -0.5) & (r <= last_v);
            let ok = reliable(u, x) & reliable(v, x) & on_dmd;
            column.push(if ok { c } else { f32::NAN });
            row.push(if ok { r } else { f32::NAN });
        }
        self.triangulator
            .intersect_two_rays_row(first_index, column, row, hits);
        let sigma_px_times_b = self.noise_times_crb * px_per_rad;
        let RowMut {
            status,
            phase_u,
            point_m: [px, py, pz],
            depth_m,
            sigma_m,
            modulation,
            background,
        } = out;
        let mut valid = 0;
        for x in 0..width {
            let (rel_u, rel_v) = (reliable(u, x), reliable(v, x));
            let hit = !hits.depth_m[x].is_nan();
            status[x] = if !usable(u, x) {
                PixelStatus::Masked
            } else if !rel_u {
                PixelStatus::Unreliable
            } else if !usable(v, x) {
                PixelStatus::Masked
            } else if !rel_v || !hit {
                PixelStatus::Unreliable
            } else {
                PixelStatus::Valid
            };
            phase_u[x] = if rel_u & rel_v {
                u.absolute[x]
            } else {
                f32::NAN
            };
            (px[x], py[x], pz[x]) = (hits.point_m[0][x], hits.point_m[1][x], hits.point_m[2][x]);
            depth_m[x] = hits.depth_m[x];
            // The column's CRB figure: an upper bound, the two-ray solution also uses
            // the row. NaN without a point.
            let sigma_px = sigma_px_times_b * self.noise_scale(u.background[x]) / u.modulation[x];
            sigma_m[x] = hits.range_per_px[x] * sigma_px;
            modulation[x] = u.min_modulation[x].min(v.min_modulation[x]);
            background[x] = u.background[x];
            valid += usize::from(hit);
        }
        valid
    }

    /// All three stages for one row of the fused pass, each built for `self.simd` (one
    /// dispatch per stage: a closure holding all three is too large for LLVM to inline
    /// into the AVX2 function).
    pub(super) fn fused_row<T: Sample>(
        &self,
        y: usize,
        frames_u: &[&crate::raster::Raster<T>],
        frames_v: Option<&[&crate::raster::Raster<T>]>,
        scale: f32,
        scratch: &mut Scratch,
        out: RowMut<'_>,
    ) -> usize {
        let width = out.status.len();
        let span = y * width..(y + 1) * width;
        let rows: Vec<&[T]> = frames_u.iter().map(|f| &f.data[span.clone()]).collect();
        let simd = self.simd;
        let (du, dv) = (&self.decoder_u, &self.decoder_v);
        simd_run!(simd, du.decode_row(&rows, scale, &mut scratch.u));
        simd_run!(simd, du.unwrap_row(&mut scratch.u));
        if let Some(fv) = frames_v {
            let rows: Vec<&[T]> = fv.iter().map(|f| &f.data[span.clone()]).collect();
            simd_run!(simd, dv.decode_row(&rows, scale, &mut scratch.v));
            simd_run!(simd, dv.unwrap_row(&mut scratch.v));
        }
        let v = frames_v.map(|_| &scratch.v);
        let projected = &mut scratch.projected;
        simd_run!(
            simd,
            self.finish_row(y * width, &scratch.u, v, projected, out)
        )
    }
}
