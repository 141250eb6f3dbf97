//! Hardware-in-the-loop simulator for the scanner.
//!
//! (Being written: simulated board behind a pseudo-terminal, simulated
//! devices, the digital twin.)
#![warn(missing_docs)]
pub mod twin;
