//! Hardware-in-the-loop simulator for the scanner: board, devices and scene
//! without hardware.
//!
//! ```text
//! serial client (slscan) --pty--> board (board-core's Link on a virtual
//!   170 MHz clock: sim_hardware + clock) --trigger edges--> devices
//!   (DMD projectors, cameras: latency, jitter) --feedback edges--> board
//!                                       |
//!   exposure windows + displayed patterns v
//! twin (scene + optics + sensor): render_exposure -> image + ground truth
//! ```
//!
//! - [`board`], [`pty`]: the simulated sync board served on a pseudo-terminal.
//! - [`clock`], [`sim_hardware`]: board-core's `TriggerHardware` on virtual time.
//! - [`devices`]: projector and camera timing models on the trigger lines.
//! - [`faults`]: dropped bytes, flipped bits, silence, missed triggers.
//! - [`soak`]: random valid plans through the sequencer, checked three ways.
//! - [`twin`]: the physically based projector-camera renderer with ground truth.
#![warn(missing_docs)]

pub mod board;
pub mod clock;
pub mod devices;
pub mod faults;
pub mod pty;
pub mod sim_hardware;
pub mod soak;
pub mod twin;
