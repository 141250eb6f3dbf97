//! Hardware-in-the-loop simulator for the scanner.
//!
//! (Being written: simulated board behind a pseudo-terminal, simulated
//! devices, the digital twin.)
#![warn(missing_docs)]

pub mod board;
pub mod clock;
pub mod devices;
pub mod faults;
pub mod pty;
pub mod sim_hardware;
pub mod soak;
pub mod twin;
