//! The digital twin: a physically based projector-camera renderer with
//! ground truth. Every accuracy figure and every training set of the
//! project comes from here.
//!
//! ```text
//! Scene (objects, materials, motion) ─┐
//! Rig (cameras, projectors, medium) ──┼─> Renderer::new      (ray casting, shadows,
//!                                     │    = CameraGeometry    projector coords: once per pose)
//! ProjectorTimeline per projector ────┴─> Renderer::exposed  (pattern look-ups, cheap)
//!   (TwinRig keeps one Renderer per camera while the scene is static)
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
//!
//! A simulated camera renders what the projectors actually showed while
//! its shutter was open:
//!
//! ```
//! use std::sync::Arc;
//! use hil_sim::twin::scenes::{built_in, Detail};
//! use hil_sim::twin::{Exposure, Pattern, ProjectorTimeline, Renderer, SensorModel};
//!
//! let detail = Detail { camera: (32, 24), projector: (40, 25) };
//! let (scene, rig) = built_in("plane", &detail)?;
//! let renderer = Renderer::new(&scene, &rig, 0, 0.0)?; // ray casting, once per pose
//! let white = Arc::new(Pattern::flat(40, 25, 1.0));
//! let shown = [ProjectorTimeline::single(white, 0.0, 1e-3)]; // on for 1 ms
//! let frame = renderer.frame(&shown, Exposure { start_s: 0.0, end_s: 2e-3 }, &SensorModel::mono12(), 42)?;
//! assert_eq!((frame.image.width, frame.image.height), (32, 24));
//! // The shutter stayed open 1 ms after the pattern went dark: the
//! // projector's light is exactly that of a 1 ms exposure.
//! let one_ms = renderer.exposed(&shown, Exposure { start_s: 0.0, end_s: 1e-3 })?;
//! assert_eq!(frame.exposed.per_projector, one_ms.per_projector);
//! # Ok::<(), hil_sim::twin::TwinError>(())
//! ```

// Band and axis loops (0..3) index several small arrays at once; zipped
// iterators would hide which component goes with which.
#![allow(clippy::needless_range_loop)]

pub mod aliased_stack;
pub mod cache;
pub mod dataset;
pub mod device;
pub mod error;
pub mod geometry;
mod huge_pages;
pub mod io;
pub mod medium;
pub mod mesh;
pub mod mesh_io;
pub mod pattern;
pub mod random_scene;
pub mod ray;
pub mod render;
pub mod ring_scenes;
pub mod scatter;
pub mod scene;
pub mod scenes;
pub mod sensor;
pub mod truth;
pub mod twin_rig;

pub use cache::{CameraGeometry, CameraRays, Illum};
pub use device::{look_at, Camera, Distortion, Intrinsics, Pinhole, Projector, Rig};
pub use error::TwinError;
pub use geometry::{Pose, Ray, Shape, V3};
pub use medium::{Medium, Turbidity, Water};
pub use mesh::Mesh;
pub use mesh_io::load_mesh;
pub use pattern::{BitDepth, Display, Exposure, Fringe, Pattern, ProjectorTimeline, Shown};
pub use render::{render_exposure, Exposed, Frame, Renderer, CALIBRATION_PIXEL_SAMPLES};
pub use scene::{Albedo, Checkerboard, Material, Motion, Object, Scene, Texture};
pub use sensor::{Channels, Image, SensorModel};
pub use truth::Truth;
pub use twin_rig::TwinRig;

#[cfg(test)]
mod analytic_tests;
#[cfg(test)]
mod behaviour_tests;
#[cfg(test)]
mod test_rig;
