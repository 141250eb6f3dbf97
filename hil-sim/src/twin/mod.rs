//! The digital twin: a physically based projector-camera renderer with
//! ground truth. Every accuracy figure and every training set of the
//! project comes from here.
//!
//! ```text
//! Scene (objects, materials, motion) ─┐
//! Rig (cameras, projectors, medium) ──┼─> Renderer::new      (ray casting, shadows,
//!                                     │    = CameraGeometry    projector coords: once per pose)
//! ProjectorTimeline per projector ────┴─> Renderer::exposed  (pattern look-ups, cheap)
//!                                         -> SensorModel::expose (crosstalk, noise, ADC)
//!                                         -> Frame { image, clean, per_projector_clean, truth }
//! ```
//!
//! Conventions: metres and seconds; device frames x right, y down, z
//! forward; poses are `world_from_device`; pixel centres at integer
//! coordinates (x right, y down); fringe phase as in [`pattern`].
//! Radiometry is in "twin units": a full-on projector pixel on a white
//! diffuser at the projector's reference distance, facing it, gives
//! `led_power` units of signal per second (the 1/pi of a Lambertian BRDF is
//! folded into that unit).

// Band and axis loops (0..3) index several small arrays at once; zipped
// iterators would hide which component goes with which.
#![allow(clippy::needless_range_loop)]

pub mod cache;
pub mod dataset;
pub mod device;
pub mod error;
pub mod geometry;
pub mod io;
pub mod medium;
pub mod mesh;
pub mod mesh_io;
pub mod pattern;
pub mod random_scene;
pub mod render;
pub mod scatter;
pub mod scene;
pub mod scenes;
pub mod sensor;
pub mod truth;

pub use cache::{CameraGeometry, Illum};
pub use device::{look_at, Camera, Distortion, Intrinsics, Pinhole, Projector, Rig};
pub use error::TwinError;
pub use geometry::{Pose, Ray, Shape, V3};
pub use medium::{Medium, Turbidity, Water};
pub use mesh::Mesh;
pub use mesh_io::load_mesh;
pub use pattern::{BitDepth, Exposure, Fringe, Pattern, ProjectorTimeline, Shown};
pub use render::{render_exposure, Exposed, Frame, Renderer};
pub use scene::{Albedo, Checkerboard, Material, Motion, Object, Scene, Texture};
pub use sensor::{Channels, Image, SensorModel};
pub use truth::Truth;

#[cfg(test)]
mod analytic_tests;
#[cfg(test)]
mod behaviour_tests;
#[cfg(test)]
mod test_rig;
