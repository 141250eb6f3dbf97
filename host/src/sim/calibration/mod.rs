//! Calibration against the digital twin: the twin's true devices as rig
//! calibrations ([`from_twin`]), one head's board views rendered by the twin
//! ([`twin_head`], `slscan calibrate --sim`), and every head of a built-in
//! scene with its head-to-head pose from shared views ([`twin_scene`],
//! `slscan calibrate --sim --scene NAME`). The algorithms they feed are the
//! product's own, in `crate::calibration`.

pub mod from_twin;
pub mod twin_head;
pub mod twin_scene;
