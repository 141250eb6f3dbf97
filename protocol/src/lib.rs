//! The wire contract shared by the sync board and the host.
//!
//! (Being written: messages, COBS + CRC framing, `ScanPlan` validation.)
#![cfg_attr(not(feature = "std"), no_std)]
#![warn(missing_docs)]
