//! Cross-crate integration tests, built as one binary (as in ripgrep/tests).
//! Each module says what it covers.

mod dual_head;
mod estimated_calibration;
mod faults;
mod firmware_parity;
mod ring_scan;
mod scan_overlap;
mod single_head;
mod sync_chain;
