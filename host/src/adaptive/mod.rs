//! Adaptive projection for surfaces whose brightness spans more than the
//! sensor's range (seed 003): polished metal saturates where dark or black
//! parts starve. A few flood exposures measure each camera pixel's response,
//! one full-intensity fringe set maps camera pixels to projector pixels, and
//! the scan then projects fringes whose intensity is chosen per projector
//! pixel, at an exposure chosen for the whole view.
//!
//! ```text
//! 7 grey floods ──response::fit_response──> per camera pixel: gain b1 (reflectivity x kt),
//!                                           offset b2 (ambient + interreflections)
//! b1, b2 ──exposure::choose_exposure──> exposure scale s (dark parts up, highlights holdable)
//! b1, b2, s ──response::optimal_level──> L_opt per camera pixel (I = s (b1 L + b2) = target)
//! full fringes ──Reconstructor──> points ──mapping::camera_to_projector──> (u, v) per pixel;
//!   saturated clusters: (u, v) from a homography fitted to their unsaturated ring
//! L_opt at (u, v) ──projector_map::projector_levels──> L_opt per DMD pixel (min, grown)
//! ──fringes::adapted_fringes──> A = (L_opt + L_min) / 2, B = (L_opt - L_min) / 2
//! adapted scan ──edges::mark_level_steps──> pixels over a level step unreliable
//! ```
//!
//! [`hdr::adapt`] runs the whole step (floods and the full set's
//! reconstruction in, patterns out); `crate::scan::capture` runs the
//! exposures around it: 7 + 12 + 12 = 31 images for three periods x 4 steps.

pub mod colour;
pub mod edges;
pub mod exposure;
pub mod fringes;
pub mod hdr;
pub mod mapping;
pub mod projector_map;
pub mod response;

/// What can make an adaptation impossible (bad preliminary images or
/// parameters). Pixels that cannot be adapted are not errors: they are
/// counted and masked.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum AdaptiveError {
    /// Another number of flood images than flood levels.
    #[error("{got} flood images for {levels} flood levels")]
    FloodCount {
        /// Images given.
        got: usize,
        /// Levels projected.
        levels: usize,
    },
    /// Another number of Gray-code matching images than the DMD's codes need.
    #[error("{got} matching images, the DMD's Gray codes need {need}")]
    MatchingCount {
        /// Images given.
        got: usize,
        /// Images the codes need.
        need: usize,
    },
    /// Too few or unusable flood levels.
    #[error("flood levels {levels:?}: need 2 to 16 levels in [0, 1], at least 2 of them distinct")]
    FloodLevels {
        /// The levels given.
        levels: Vec<f32>,
    },
    /// A flood image is not the size of the first.
    #[error("flood image {index} is {got:?} but flood 0 is {expected:?} (width, height)")]
    FloodSize {
        /// Index of the offending image.
        index: usize,
        /// Size of image 0.
        expected: (usize, usize),
        /// Its size.
        got: (usize, usize),
    },
    /// The phase reconstruction used for the mapping is not the floods' size.
    #[error(
        "the fringe reconstruction is {got:?} but the floods are {expected:?} (width, height)"
    )]
    MappingSize {
        /// Flood size.
        expected: (usize, usize),
        /// Reconstruction size.
        got: (usize, usize),
    },
    /// A parameter outside its range.
    #[error("adaptation parameter {name} = {value} is outside {range}")]
    Parameter {
        /// Which.
        name: &'static str,
        /// Its value.
        value: f64,
        /// Its valid range, in words.
        range: &'static str,
    },
}
