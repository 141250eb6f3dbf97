//! Underwater scanning (issue 18, seed 002): fringes seen through water are
//! attenuated, blurred by forward scatter and washed out by a backscatter
//! veil. This module restores them before the unchanged phase decoding.
//!
//! Seed 002's degradation operator is `D(I) = I * h_g + n_g` (a Gaussian
//! forward-scatter PSF and backscatter noise); the twin's water adds a
//! smooth additive veil and a smooth gain (Beer-Lambert attenuation along
//! the path). The classical restorer inverts what is linear in that model:
//!
//! ```text
//! phase-shift set (NaN / saturated pixels flagged, filled from their block for the transform)
//!   -> Wiener deconvolution with the Gaussian PSF, one filter for every frame,
//!      mirror-padded FFT, constant noise-to-signal ratio
//!   -> veil: per-block low percentile of the set's per-pixel minimum
//!      (above a dark frame when there is one), bilinear, subtracted from every frame
//!   -> restored set, flagged pixels NaN
//! ```
//!
//! Beside it: [`learned`] (seed 002's networks, run on tract), [`edges`]
//! (decoded pixels within the blur of a silhouette, which no restoration
//! separates from the other side, left out after decoding) and [`score`].
//! Refraction at the port is the triangulation's concern
//! (`triangulation::flat_port`); a per-pixel attenuation gain is not here
//! (it needs the depth the scan has not measured yet).

pub mod edges;
pub mod learned;
pub mod restore;
pub mod score;

pub use restore::{
    restore_classical, ClassicalRestorer, RestoreError, RestoreParams, Restored, Veil,
};
