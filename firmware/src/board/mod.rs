//! Everything chip-specific, one module per board; the rest of the firmware
//! sees only what [`g474`] (re-exported as `active`) hands out.
//!
//! A second board (e.g. an STM32H7 Nucleo) is a sibling folder with the same
//! four files (clocks, pins, timers, capture) and one more `cfg` line here;
//! `main.rs`, the USB link and the sequencer task do not change.

pub mod g474;

pub use g474 as active;
