//! Frame sample types: the decoder reads what cameras deliver (8- or 16-bit integers)
//! as well as `f32`, so a 12-frame set is 75-150 MB instead of 300 MB of floats.

/// A camera frame sample the phase decoder can read directly.
pub trait Sample: Copy + Send + Sync + 'static {
    /// The value of full white for the type (`1.0` for `f32`, `255` for `u8`, `65535`
    /// for `u16`); data using fewer bits (12-bit in `u16`) pass their own full scale.
    const FULL_SCALE: f32;
    /// The sample's value as `f32`, unscaled.
    fn to_f32(self) -> f32;
}

impl Sample for f32 {
    const FULL_SCALE: f32 = 1.0;
    #[inline(always)]
    fn to_f32(self) -> f32 {
        self
    }
}

impl Sample for u16 {
    const FULL_SCALE: f32 = 65535.0;
    #[inline(always)]
    fn to_f32(self) -> f32 {
        f32::from(self)
    }
}

impl Sample for u8 {
    const FULL_SCALE: f32 = 255.0;
    #[inline(always)]
    fn to_f32(self) -> f32 {
        f32::from(self)
    }
}
