//! Held-out de-aliasing samples from the twin as plain data: the same
//! samples `hil-sim dataset aliased` writes (one (seed, index) gives the
//! same sample, written or rendered here), so the Rust side measures the
//! networks on data with the exact identity of a training set's folder.

use hil_sim::twin::dataset::{
    aliased_rig, aliased_sample, AliasedPeriods, DatasetKind, DatasetSpec,
};
use hil_sim::twin::TwinError;

use crate::calibration::RigCalibration;
use crate::raster::Raster;
use crate::scan::aliasing::FlatFields;

/// One camera's aliased capture and its truth.
#[derive(Clone, Debug)]
pub struct AliasedSample {
    /// The camera (head 0 = A, 1 = B).
    pub camera: usize,
    /// Noisy aliased frames, period-major (`K x N`).
    pub frames: Vec<Raster<f32>>,
    /// Noisy flat fields.
    pub flat: FlatFields,
    /// Noise-free frames of ambient + the own projector alone.
    pub clean_own: Vec<Raster<f32>>,
    /// Own projector's DMD column per pixel (NaN where it does not light it).
    pub own_u_px: Vec<f32>,
    /// Lit by both projectors (the twin's truth).
    pub overlap: Vec<bool>,
    /// Sensor noise scale (1 = the simulated scan's).
    pub noise_scale: f64,
    /// Fringe periods, DMD pixels.
    pub periods_px: Vec<f64>,
    /// The rig the dataset renders with (its scenes move, the rig does
    /// not), as the twin's true devices: what the epipolar de-aliaser needs.
    pub calibration: RigCalibration,
}

/// Which held-out samples: seed, count, camera and DMD size, noise range.
#[derive(Clone, Copy, Debug)]
pub struct AliasedSet {
    /// Dataset seed.
    pub seed: u64,
    /// Camera size (width, height).
    pub camera_px: (u32, u32),
    /// DMD size (width, height).
    pub projector_px: (u32, u32),
    /// Noise scale range.
    pub noise_scale: (f64, f64),
}

/// Sample `index` of `set`, both cameras.
pub fn held_out(set: &AliasedSet, index: usize) -> Result<Vec<AliasedSample>, TwinError> {
    let spec = DatasetSpec {
        kind: DatasetKind::Aliased,
        count: index + 1,
        seed: set.seed,
        width: set.camera_px.0,
        height: set.camera_px.1,
        projector: set.projector_px,
        turbidity: None,
        periods: AliasedPeriods::Scan,
        noise_scale: set.noise_scale,
    };
    let (stacks, noise_scale, capture) = aliased_sample(&spec, index)?;
    let calibration = super::truth::twin_calibration(&aliased_rig(&spec), 2);
    let (w, h) = (set.camera_px.0 as usize, set.camera_px.1 as usize);
    let raster = |data: &Vec<f32>| Raster {
        width: w,
        height: h,
        data: data.clone(),
    };
    Ok(stacks
        .iter()
        .map(|st| {
            // The dataset's flats are (dark, own, other); the scan's (dark, A, B).
            let (lit_a, lit_b) = if st.camera == 0 {
                (&st.flats[1], &st.flats[2])
            } else {
                (&st.flats[2], &st.flats[1])
            };
            AliasedSample {
                camera: st.camera,
                frames: st.aliased.iter().map(raster).collect(),
                flat: FlatFields {
                    dark: raster(&st.flats[0]),
                    lit_a: raster(lit_a),
                    lit_b: raster(lit_b),
                },
                clean_own: st.clean_own.iter().map(raster).collect(),
                own_u_px: st.own_u_px.clone(),
                overlap: st.overlap.clone(),
                noise_scale,
                periods_px: capture.periods_px.clone(),
                calibration: calibration.clone(),
            }
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// hil-sim cannot depend on slscan, so the dataset's scan periods are
    /// written twice; this keeps the two the same.
    #[test]
    fn the_datasets_scan_periods_are_the_scans() {
        for dmd in [912, 1280, 1920] {
            assert_eq!(
                AliasedPeriods::Scan.periods_px(dmd),
                crate::scan::dealias_periods_px(dmd)
            );
        }
    }
}
