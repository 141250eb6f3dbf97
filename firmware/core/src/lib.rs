//! The sync board's sequencer core: the same code runs on the STM32 and in hil-sim.
//!
//! (Being written: edge tables, sequencer state machine, link dispatch.)
#![cfg_attr(not(test), no_std)]
#![warn(missing_docs)]
