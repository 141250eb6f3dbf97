//! The pipeline as separate whole-image passes, timed: the bench's breakdown of where
//! the time goes. Same row functions as the fused pass, so the results are identical.

use std::time::Instant;

use rayon::prelude::*;

use super::rows::Projected;
use super::{Directions, PixelMaps, ReconstructError, Reconstruction, Reconstructor, StageTimes};
use crate::phase::Sample;
use crate::point_cloud::PointCloud;
use crate::raster::Raster;
use crate::simd::simd_run;
use crate::unwrap::temporal::DecodedRow;

impl Reconstructor {
    /// The same stages as [`Reconstructor::reconstruct`] but as separate passes over the
    /// image, timed (for benches and profiling). Columns only.
    pub fn reconstruct_staged<T: Sample>(
        &self,
        frames_u: &[&Raster<T>],
    ) -> Result<(Reconstruction, StageTimes), ReconstructError> {
        if self.config.directions != Directions::Columns {
            return Err(ReconstructError::RowFrames {
                directions: self.config.directions,
                given: false,
            });
        }
        let (width, height) = self.check(frames_u, None)?;
        let scale = self.sample_scale::<T>();
        let mut times = StageTimes::default();

        let t = Instant::now();
        let mut decoded: Vec<DecodedRow> = (0..height)
            .into_par_iter()
            .map(|y| {
                let span = y * width..(y + 1) * width;
                let rows: Vec<&[T]> = frames_u.iter().map(|f| &f.data[span.clone()]).collect();
                let mut d = DecodedRow::default();
                simd_run!(self.simd, self.decoder_u.decode_row(&rows, scale, &mut d));
                d
            })
            .collect();
        times.phase_s = t.elapsed().as_secs_f64();

        let t = Instant::now();
        decoded
            .par_iter_mut()
            .for_each(|d| simd_run!(self.simd, self.decoder_u.unwrap_row(d)));
        times.unwrap_s = t.elapsed().as_secs_f64();

        let t = Instant::now();
        let mut pixels = PixelMaps::default();
        pixels.resize(width, height);
        let counts: Vec<usize> = pixels
            .rows_mut()
            .into_par_iter()
            .zip(&decoded)
            .enumerate()
            .map_init(Projected::default, |projected, (y, (row, d))| {
                simd_run!(
                    self.simd,
                    self.finish_row(y * width, d, None, projected, row)
                )
            })
            .collect();
        times.triangulate_s = t.elapsed().as_secs_f64();

        let t = Instant::now();
        let mut cloud = PointCloud::default();
        self.cloud_into(&pixels, &counts, &mut cloud);
        times.cloud_s = t.elapsed().as_secs_f64();
        Ok((Reconstruction { pixels, cloud }, times))
    }
}
