//! Noise-free reference frames the pictures put beside what a scan
//! captured and decoded: a head's camera seeing DMD patterns of its own
//! projector alone, every other projector dark.

use std::sync::Arc;

use hil_sim::twin::{Exposure, Pattern, ProjectorTimeline, Renderer, Rig, Scene, TwinError};

use crate::raster::Raster;
use crate::scan::plan::display_s;

/// Head `head`'s camera frames of DMD `patterns` (values in [0, 1]), each
/// shown by its own projector alone for one standard display time,
/// noise-free, in `rig`'s medium: what a de-aliaser or a restorer should
/// give back. One renderer serves every pattern (its set-up is most of a
/// frame's time).
pub fn own_projector_frames(
    scene: &Scene,
    rig: &Rig,
    head: usize,
    patterns: &[&Raster<f32>],
) -> Result<Vec<Raster<f32>>, TwinError> {
    let renderer = Renderer::new(scene, rig, head, 0.0)?;
    let exposure = Exposure {
        start_s: 0.0,
        end_s: display_s(),
    };
    patterns
        .iter()
        .map(|pattern| {
            let grey: Vec<u8> = pattern
                .data
                .iter()
                .map(|v| (v.clamp(0.0, 1.0) * 255.0).round() as u8)
                .collect();
            let pattern = Pattern::from_u8(pattern.width as u32, pattern.height as u32, &grey)?;
            let shown: Vec<ProjectorTimeline> = (0..rig.projectors.len())
                .map(|p| {
                    let on = if p == head {
                        Arc::new(pattern.clone())
                    } else {
                        Arc::new(Pattern::flat(pattern.width, pattern.height, 0.0))
                    };
                    ProjectorTimeline::single(on, 0.0, exposure.end_s)
                })
                .collect();
            let image = renderer
                .frame(&shown, exposure, &super::scan::sim_sensor(), 0)?
                .clean;
            Ok(Raster {
                width: image.width as usize,
                height: image.height as usize,
                data: image.data,
            })
        })
        .collect()
}
