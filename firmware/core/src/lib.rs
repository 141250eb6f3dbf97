//! The sync board's sequencer core: the same code runs on the STM32 and in
//! hil-sim.
//!
//! ```text
//! bytes --link::Link::receive--> Dispatcher --CommitPlan--> ScanPlan::validate
//!                                    |                        -> EdgeTable::compile
//!                                    +--Arm/Start/Abort--> Sequencer --TriggerHardware-->
//!                                                          timers (edges), captures (feedback)
//! Link::poll --> Sequencer::poll: feedback check, end of scan --> events --> tx
//! ```
//!
//! How a board drives the core (calls, order, time base): `API.md` next to
//! this crate's `Cargo.toml`.
#![cfg_attr(not(test), no_std)]
#![warn(missing_docs)]

pub mod edge_table;
pub mod feedback;
pub mod hardware;
pub mod link;
pub mod sequencer;
pub mod window_check;

pub use edge_table::{Edge, EdgeTable};
pub use hardware::{Capture, TriggerHardware};
pub use link::{Dispatcher, Link};
pub use sequencer::Sequencer;
