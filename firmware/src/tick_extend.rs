//! Extending a short hardware counter value to the 64-bit board clock. Pure
//! arithmetic, shared by the TIM5 clock (32-bit) and the TIM3 captures
//! (16-bit); the host tests compile this file too
//! (tests/tests/firmware_parity.rs).

/// The 64-bit tick of a `bits`-wide counter value `low`, given `wraps`
/// counted so far and whether a wrap is flagged but not yet counted.
///
/// A pending wrap belongs to `low` only if `low` is in the lower half of
/// the range: a small value was latched after the wrap, a large one just
/// before it. That holds as long as the value is read within half a wrap
/// period of being latched (TIM3: 193 us, TIM5: 12.6 s), which the
/// interrupt priorities guarantee.
pub fn extend(wraps: u32, wrap_pending: bool, low: u32, bits: u32) -> u64 {
    let half = 1u64 << (bits - 1);
    let pending_applies = wrap_pending && u64::from(low) < half;
    let high = u64::from(wraps) + u64::from(pending_applies);
    (high << bits) | u64::from(low)
}
