//! Ground truth of a rendered frame: depth, points, normals, each
//! projector's DMD coordinates (hence absolute phase in any direction), and
//! the shadow / occlusion / overlap / saturation masks. The geometry part
//! is shared with the renderer's cache (no per-frame copy).

use std::sync::Arc;

use super::cache::{CameraGeometry, Illum};
use super::pattern::Fringe;

/// Per-pixel truth of one camera frame (row-major, NaN where undefined).
#[derive(Clone, Debug)]
pub struct Truth {
    /// Geometry at mid-exposure: depth, points, normals, object ids,
    /// projector coordinates, lighting states, overlap.
    pub geometry: Arc<CameraGeometry>,
    /// Saturated in any channel (noise-free signal at full scale).
    pub saturated: Vec<bool>,
}

impl Truth {
    /// Image width, pixels.
    pub fn width(&self) -> u32 {
        self.geometry.width
    }

    /// Image height, pixels.
    pub fn height(&self) -> u32 {
        self.geometry.height
    }

    /// z of the surface point in the camera frame, metres (NaN: none).
    pub fn depth_m(&self) -> &[f32] {
        &self.geometry.depth_m
    }

    /// World surface point, metres.
    pub fn point_m(&self) -> &[[f32; 3]] {
        &self.geometry.point_m
    }

    /// World unit normal.
    pub fn normal(&self) -> &[[f32; 3]] {
        &self.geometry.normal
    }

    /// Object index, u16::MAX where no surface.
    pub fn object(&self) -> &[u16] {
        &self.geometry.object
    }

    /// Number of projectors.
    pub fn projectors(&self) -> usize {
        self.geometry.projectors.len()
    }

    /// DMD coordinate (u, v) of each pixel's surface point in projector
    /// `p`, pixel centres at integers (defined even where shadowed).
    pub fn projector_uv_px(&self, p: usize) -> &[[f32; 2]] {
        &self.geometry.projectors[p].uv_px
    }

    /// Lighting state of each pixel by projector `p`.
    pub fn illum(&self, p: usize) -> &[Illum] {
        &self.geometry.projectors[p].illum
    }

    /// Lit by two or more projectors (the aliased overlap of seed 000).
    pub fn overlap(&self) -> &[bool] {
        &self.geometry.overlap
    }

    /// Absolute phase of `fringe` (shift ignored) seen through projector
    /// `projector` at every pixel, radians; NaN where the pixel is not lit by it.
    pub fn absolute_phase(&self, projector: usize, fringe: &Fringe) -> Vec<f32> {
        self.projector_uv_px(projector)
            .iter()
            .zip(self.illum(projector))
            .map(|(uv, il)| {
                if *il == Illum::Lit {
                    fringe.phase_at(uv[0] as f64, uv[1] as f64) as f32
                } else {
                    f32::NAN
                }
            })
            .collect()
    }

    /// Pixels with no surface (background).
    pub fn no_surface_mask(&self) -> Vec<bool> {
        self.object().iter().map(|&o| o == u16::MAX).collect()
    }

    /// Pixels whose surface projector `projector` cannot light (shadow or back-facing).
    pub fn shadow_mask(&self, projector: usize) -> Vec<bool> {
        self.illum(projector)
            .iter()
            .map(|&i| matches!(i, Illum::Shadowed | Illum::BackFacing))
            .collect()
    }
}
