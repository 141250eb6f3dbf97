//! The organised result as one array per quantity (struct of arrays): the row pass fills
//! them and the cloud pass reads them with whole-row vector loads and stores, where an
//! array of 36-byte per-pixel structs made both passes scalar.

use rayon::prelude::*;

use super::PixelResult;
use crate::raster::Raster;
use crate::unwrap::PixelStatus;

/// One value per camera pixel in each map, row-major. [`PixelMaps::get`] gathers one
/// pixel's values as a [`PixelResult`].
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PixelMaps {
    /// Columns.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// Status after unwrapping and triangulation.
    pub status: Vec<PixelStatus>,
    /// Absolute phase of the finest column period (NaN unless valid).
    pub phase_u: Vec<f32>,
    /// Point x, y, z, metres (NaN unless valid).
    pub point_m: [Vec<f32>; 3],
    /// Depth along the camera axis, metres (NaN unless valid).
    pub depth_m: Vec<f32>,
    /// Predicted standard deviation along the ray, metres (NaN unless valid).
    pub sigma_m: Vec<f32>,
    /// Smallest modulation over the periods (and directions).
    pub modulation: Vec<f32>,
    /// Background A of the finest column period.
    pub background: Vec<f32>,
}

/// One row of every map, mutable: what the row pass writes.
pub(crate) struct RowMut<'a> {
    pub status: &'a mut [PixelStatus],
    pub phase_u: &'a mut [f32],
    pub point_m: [&'a mut [f32]; 3],
    pub depth_m: &'a mut [f32],
    pub sigma_m: &'a mut [f32],
    pub modulation: &'a mut [f32],
    pub background: &'a mut [f32],
}

impl PixelMaps {
    /// Number of pixels.
    pub fn len(&self) -> usize {
        self.status.len()
    }

    /// Whether there are no pixels.
    pub fn is_empty(&self) -> bool {
        self.status.is_empty()
    }

    /// `(width, height)`.
    pub fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    /// Leaves pixel `i` out after decoding: status [`PixelStatus::Unreliable`],
    /// point, phase, depth and sigma NaN (modulation and background stay:
    /// they were measured).
    pub fn mark_unreliable(&mut self, i: usize) {
        self.status[i] = PixelStatus::Unreliable;
        for map in self.point_m.iter_mut() {
            map[i] = f32::NAN;
        }
        self.phase_u[i] = f32::NAN;
        self.depth_m[i] = f32::NAN;
        self.sigma_m[i] = f32::NAN;
    }

    /// Pixel `i`'s values (row-major index).
    ///
    /// # Panics
    /// If `i` is out of range.
    pub fn get(&self, i: usize) -> PixelResult {
        PixelResult {
            phase_u: self.phase_u[i],
            status: self.status[i],
            point_m: [self.point_m[0][i], self.point_m[1][i], self.point_m[2][i]],
            depth_m: self.depth_m[i],
            sigma_m: self.sigma_m[i],
            modulation: self.modulation[i],
            background: self.background[i],
        }
    }

    /// Overwrites pixel `i`'s values with `from`'s (same size).
    ///
    /// # Panics
    /// If `i` is out of range of either.
    pub fn copy_pixel(&mut self, from: &PixelMaps, i: usize) {
        self.status[i] = from.status[i];
        self.phase_u[i] = from.phase_u[i];
        for (to, from) in self.point_m.iter_mut().zip(&from.point_m) {
            to[i] = from[i];
        }
        self.depth_m[i] = from.depth_m[i];
        self.sigma_m[i] = from.sigma_m[i];
        self.modulation[i] = from.modulation[i];
        self.background[i] = from.background[i];
    }

    /// Every pixel's values in row-major order.
    pub fn iter(&self) -> impl ExactSizeIterator<Item = PixelResult> + '_ {
        (0..self.len()).map(|i| self.get(i))
    }

    /// [`PixelMaps::iter`] in parallel.
    pub fn par_iter(&self) -> impl IndexedParallelIterator<Item = PixelResult> + '_ {
        (0..self.len()).into_par_iter().map(|i| self.get(i))
    }

    /// One map as a raster.
    pub fn raster<T: Copy>(&self, map: &[T]) -> Raster<T> {
        Raster {
            width: self.width,
            height: self.height,
            data: map.to_vec(),
        }
    }

    /// Sizes every map for `width x height` (contents unspecified: the row pass writes
    /// every element). Memory is only allocated where a map grows (see [`sized`]).
    pub(crate) fn resize(&mut self, width: usize, height: usize) {
        let len = width * height;
        (self.width, self.height) = (width, height);
        sized(&mut self.status, len, PixelStatus::Masked);
        for map in self.point_m.iter_mut().chain([
            &mut self.phase_u,
            &mut self.depth_m,
            &mut self.sigma_m,
            &mut self.modulation,
            &mut self.background,
        ]) {
            sized(map, len, 0.0);
        }
    }

    /// Every row of every map, for the row pass (after [`PixelMaps::resize`]).
    pub(crate) fn rows_mut(&mut self) -> Vec<RowMut<'_>> {
        let w = self.width.max(1);
        let [px, py, pz] = &mut self.point_m;
        let mut rows = Vec::with_capacity(self.height);
        let mut chunks = (
            self.phase_u.chunks_mut(w),
            [px.chunks_mut(w), py.chunks_mut(w), pz.chunks_mut(w)],
            self.depth_m.chunks_mut(w),
            self.sigma_m.chunks_mut(w),
            self.modulation.chunks_mut(w),
            self.background.chunks_mut(w),
        );
        // Every map has the same length, so the other chunks exist too.
        const SAME: &str = "maps of one length";
        for status in self.status.chunks_mut(w) {
            let [cx, cy, cz] = &mut chunks.1;
            rows.push(RowMut {
                status,
                phase_u: chunks.0.next().expect(SAME),
                point_m: [cx, cy, cz].map(|c| c.next().expect(SAME)),
                depth_m: chunks.2.next().expect(SAME),
                sigma_m: chunks.3.next().expect(SAME),
                modulation: chunks.4.next().expect(SAME),
                background: chunks.5.next().expect(SAME),
            });
        }
        rows
    }
}

pub(super) use crate::huge_pages::sized;
