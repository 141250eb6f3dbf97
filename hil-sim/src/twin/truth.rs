//! Ground truth of a rendered frame: depth, points, normals, each
//! projector's DMD coordinates (hence absolute phase in any direction), and
//! the shadow / occlusion / overlap / saturation masks.

use super::cache::{CameraGeometry, Illum};
use super::pattern::Fringe;

/// Per-pixel truth of one camera frame (row-major, NaN where undefined).
#[derive(Clone, Debug)]
pub struct Truth {
    /// Width, pixels.
    pub width: u32,
    /// Height, pixels.
    pub height: u32,
    /// z of the surface point in the camera frame, metres.
    pub depth_m: Vec<f32>,
    /// World surface point, metres.
    pub point_m: Vec<[f32; 3]>,
    /// World unit normal.
    pub normal: Vec<[f32; 3]>,
    /// Object index, u16::MAX where no surface.
    pub object: Vec<u16>,
    /// Per projector: DMD coordinate (u, v) of the surface point, pixel
    /// centres at integers (defined even where shadowed; NaN off the surface).
    pub projector_uv_px: Vec<Vec<[f32; 2]>>,
    /// Per projector: lighting state.
    pub illum: Vec<Vec<Illum>>,
    /// Lit by two or more projectors (the aliased overlap of seed 000).
    pub overlap: Vec<bool>,
    /// Saturated in any channel (noise-free signal at full scale).
    pub saturated: Vec<bool>,
}

impl Truth {
    /// Truth from cached geometry and the saturation mask of a frame.
    pub fn from_geometry(g: &CameraGeometry, saturated: Vec<bool>) -> Truth {
        let n = g.depth_m.len();
        let overlap = (0..n)
            .map(|i| {
                g.projectors
                    .iter()
                    .filter(|p| p.illum[i] == Illum::Lit)
                    .count()
                    >= 2
            })
            .collect();
        Truth {
            width: g.width,
            height: g.height,
            depth_m: g.depth_m.clone(),
            point_m: g.point_m.clone(),
            normal: g.normal.clone(),
            object: g.object.clone(),
            projector_uv_px: g.projectors.iter().map(|p| p.uv_px.clone()).collect(),
            illum: g.projectors.iter().map(|p| p.illum.clone()).collect(),
            overlap,
            saturated,
        }
    }

    /// Absolute phase of `fringe` (shift ignored) seen through projector
    /// `projector` at every pixel, radians; NaN where the pixel is not lit by it.
    pub fn absolute_phase(&self, projector: usize, fringe: &Fringe) -> Vec<f32> {
        self.projector_uv_px[projector]
            .iter()
            .zip(&self.illum[projector])
            .map(|(uv, il)| {
                if *il == Illum::Lit {
                    fringe.phase_at(uv[0] as f64, uv[1] as f64) as f32
                } else {
                    f32::NAN
                }
            })
            .collect()
    }

    /// Pixels with no surface (background / occluded from everything).
    pub fn no_surface_mask(&self) -> Vec<bool> {
        self.object.iter().map(|&o| o == u16::MAX).collect()
    }

    /// Pixels whose surface projector `projector` cannot light (shadow or back-facing).
    pub fn shadow_mask(&self, projector: usize) -> Vec<bool> {
        self.illum[projector]
            .iter()
            .map(|&i| matches!(i, Illum::Shadowed | Illum::BackFacing))
            .collect()
    }
}
