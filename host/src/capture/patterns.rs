//! The projector images a capture description stands for, in its frame order: what a
//! projector of that family shows (for `slscan patterns` users and the twin's tests of
//! each family).

use super::{CaptureSpec, Frames, FringeSet, GraySet, ProjectorAxis};
use crate::raster::Raster;
use crate::unwrap::gray_code::binary_to_gray;

/// Every frame of `spec` for a projector of `width` x `height` pixels, in [0, 1].
pub fn projector_images(spec: &CaptureSpec, width: u32, height: u32) -> Vec<Raster<f32>> {
    let (w, h) = (width as usize, height as usize);
    let mut out = Vec::with_capacity(spec.frame_count());
    for element in &spec.sequence {
        match element {
            Frames::Fringes(set) => out.extend(fringe_images(set, w, h)),
            Frames::Gray(set) => out.extend(gray_images(set, w, h)),
            Frames::White => out.push(Raster::filled(w, h, 1.0)),
            Frames::Black => out.push(Raster::filled(w, h, 0.0)),
        }
    }
    out
}

/// The coordinate of pixel (x, y) along an axis.
fn along(axis: ProjectorAxis, x: usize, y: usize) -> f64 {
    match axis {
        ProjectorAxis::Column => x as f64,
        ProjectorAxis::Row => y as f64,
    }
}

/// `I_n = 1/2 + 1/2 cos(s_p 2 pi u / P + psi_0 + s_d 2 pi n / N)`, period-major.
fn fringe_images(set: &FringeSet, w: usize, h: usize) -> Vec<Raster<f32>> {
    let tau = std::f64::consts::TAU;
    let mut out = Vec::with_capacity(set.frames());
    for &period in &set.periods_px {
        for n in 0..set.steps {
            let shift = f64::from(set.shift_sign) * tau * n as f64 / set.steps as f64;
            out.push(Raster::from_fn(w, h, |x, y| {
                let psi = f64::from(set.phase_sign) * tau * along(set.axis, x, y) / period
                    + set.phase_offset_rad;
                (0.5 + 0.5 * (psi + shift).cos()) as f32
            }));
        }
    }
    out
}

/// Bit `b` (MSB first) of `gray(floor(u / block))`, each followed by its inverse when
/// the set has them.
fn gray_images(set: &GraySet, w: usize, h: usize) -> Vec<Raster<f32>> {
    let mut out = Vec::with_capacity(set.frames());
    for b in 0..set.bits {
        let shift = set.bits - 1 - b;
        let bit = |x: usize, y: usize| {
            let block = along(set.axis, x, y) as u32 / set.block_px;
            (binary_to_gray(block) >> shift) & 1 == 1
        };
        out.push(Raster::from_fn(w, h, |x, y| f32::from(u8::from(bit(x, y)))));
        if set.inverse {
            out.push(Raster::from_fn(w, h, |x, y| {
                f32::from(u8::from(!bit(x, y)))
            }));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::capture::presets::{Preset, PresetOptions};

    #[test]
    fn images_match_the_frame_count_and_the_slmaster_phase() {
        let spec = Preset::SinusCompleGray
            .spec(&PresetOptions::default(), (256, 64))
            .unwrap();
        let images = projector_images(&spec, 256, 64);
        assert_eq!(images.len(), spec.frame_count());
        // Frame 0 is cos(2 pi (u mod P) / P - pi): darkest at u = 0, brightest at P / 2.
        assert!(*images[0].at(0, 0) < 1e-6);
        assert!((*images[0].at(16, 0) - 1.0).abs() < 1e-6);
    }
}
