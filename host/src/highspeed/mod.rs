//! High-speed 3D from one colour long exposure (seed 001, TFCMFPP): the DMD shows
//! 24 binary fringes (8 directions x R, G, B LEDs) inside one camera exposure;
//! the decoder recovers each pattern's fringe, its absolute phase and its depth,
//! so one camera frame gives 24 depth maps, one per pattern instant.
//!
//! - [`set`]: the pattern set (frequencies, LEDs, projection order, DMD frames);
//! - [`demux`]: the analytic multi-carrier demultiplexer (crosstalk and zero-order
//!   removal, carrier demodulation with windows sized from the carriers, then
//!   spatial-frequency decomposition by cancelling each pattern's siblings);
//! - [`zocr`]: ZOCR-Net, the seed's first network, in place of the
//!   demultiplexer's analytic crosstalk and zero-order removal;
//! - [`fdd`]: FDD-Net, the seed's third network in a compact residual form:
//!   every pattern's demodulated phase corrected from all 24 basebands;
//! - [`learned`]: what the learned stages share (loading, set checks);
//! - [`decode`]: PDM unwrapping along each pixel's epipolar segment and per-instant
//!   depth.
//!
//! The seed's second network (spatial-frequency decomposition) is not
//! built: the demultiplexer does its job by formula (carrier demodulation by
//! each pattern's reference phase, then sibling cancellation).

mod consensus;
pub mod crosstalk;
pub mod decode;
pub mod demux;
pub mod fdd;
pub mod learned;
pub mod set;
pub mod zocr;

pub use crosstalk::crosstalk_from_flats;
pub use decode::{Decoded, Decoder, DecoderConfig, InstantMap, MAX_SAMPLES};
pub use demux::{Demultiplexed, Demultiplexer, DemuxOptions, Window, ZeroOrderRemoved};
pub use fdd::FddNet;
pub use learned::LearnedStage;
pub use set::{PatternSet, SetPattern};
pub use zocr::ZocrNet;

/// What can go wrong decoding a high-speed exposure.
#[derive(Debug, thiserror::Error)]
pub enum HighSpeedError {
    /// The pattern set cannot be used (periods, DMD size).
    #[error("high-speed pattern set: {why}")]
    BadPatternSet {
        /// Why.
        why: String,
    },
    /// A decoder setting is out of range.
    #[error("high-speed decoder: {why}")]
    BadConfig {
        /// Why.
        why: String,
    },
    /// An image of the wrong size.
    #[error("{what}: expected {}x{} pixels, got {}x{}", expected.0, expected.1, got.0, got.1)]
    WrongSize {
        /// Which image.
        what: String,
        /// (width, height) expected.
        expected: (usize, usize),
        /// (width, height) given.
        got: (usize, usize),
    },
    /// An exposure has a channel count other than three.
    #[error("colour exposure: expected 3 channels (R, G, B), got {got}")]
    NotColour {
        /// Channels given.
        got: usize,
    },
    /// NaN or infinite pixel values.
    #[error("colour exposure holds NaN or infinite values")]
    NotFinite,
    /// Too many pixels clipped to decode the exposure.
    #[error("colour exposure saturated: {:.1} % of pixels clip in some channel (limit {:.1} %); shorten the exposure or dim the LEDs", share * 100.0, limit * 100.0)]
    Saturated {
        /// Share of saturated pixels.
        share: f64,
        /// The decoder's limit.
        limit: f64,
    },
    /// The colour crosstalk matrix cannot be inverted.
    #[error("colour crosstalk matrix is singular or not finite")]
    BadCrosstalk,
    /// The learned stage's network cannot be loaded or run.
    #[error(transparent)]
    Model(#[from] crate::infer::ModelError),
}
