//! The twin's water for a scan under water (issue 18): the preset of a
//! turbidity level behind thin flat ports, and the defaults a simulated water
//! scan takes from it (the restorer's PSF at a nominal working distance,
//! the exposure that makes up the round trip's attenuation).

use hil_sim::twin::{Medium, Rig, Scene, Turbidity as TwinTurbidity, TwinError, Water};

use crate::raster::Raster;
use crate::scan::plan::MAX_EXPOSURE_SCALE;
use crate::scan::underwater::Turbidity;

/// Every device's port sits this far in front of it (as in `hil-sim dataset
/// underwater`).
pub const PORT_DISTANCE_M: f64 = 0.03;

/// The working distance the defaults assume (the built-in scenes' parts sit
/// 0.45-0.55 m from the camera); not a scene's truth.
pub const NOMINAL_WORKING_DISTANCE_M: f64 = 0.5;

/// The twin's water of `level` behind [`PORT_DISTANCE_M`] ports.
pub fn twin_water(level: Turbidity) -> Water {
    let level = match level {
        Turbidity::T1 => TwinTurbidity::T1,
        Turbidity::T2 => TwinTurbidity::T2,
        Turbidity::T3 => TwinTurbidity::T3,
        Turbidity::T4 => TwinTurbidity::T4,
    };
    Water::preset(level, PORT_DISTANCE_M)
}

/// Puts the whole rig under `level` water: every device behind its port.
pub fn submerge(rig: &mut Rig, level: Turbidity) {
    rig.medium = Medium::Water(twin_water(level));
}

/// The forward-scatter PSF sigma the classical restorer assumes, camera
/// pixels: the level's rate times the nominal camera-side water path.
pub fn nominal_psf_sigma_px(level: Turbidity) -> f64 {
    twin_water(level).forward_sigma_px_per_m * (NOMINAL_WORKING_DISTANCE_M - PORT_DISTANCE_M)
}

/// The exposure, in standard exposures, that makes up the green band's
/// attenuation over the nominal round trip (out and back), at most the
/// plan's longest ([`MAX_EXPOSURE_SCALE`]; T4 stays about 3x short).
pub fn exposure_scale(level: Turbidity) -> f64 {
    let c = twin_water(level).attenuation_per_m[1];
    let path_m = 2.0 * (NOMINAL_WORKING_DISTANCE_M - PORT_DISTANCE_M);
    (c * path_m).exp().min(MAX_EXPOSURE_SCALE)
}

/// The same water with nothing but its refraction: no attenuation, forward
/// scatter or veil.
pub fn clear(water: &Water) -> Water {
    Water {
        attenuation_per_m: [0.0; 3],
        forward_sigma_px_per_m: 0.0,
        backscatter_fraction: 0.0,
        ..*water
    }
}

/// Head `head`'s camera frame of DMD `pattern` (values in [0, 1]) through
/// clear water, noise-free: the reference a restored frame is compared with
/// (the same pixel geometry as the scan's frames; an in-air frame differs by
/// the refraction, which no restoration undoes). `None` when the rig is not
/// under water.
pub fn clear_water_frame(
    scene: &Scene,
    rig: &Rig,
    head: usize,
    pattern: &Raster<f32>,
) -> Result<Option<Raster<f32>>, TwinError> {
    let Medium::Water(water) = &rig.medium else {
        return Ok(None);
    };
    let mut clear_rig = rig.clone();
    clear_rig.medium = Medium::Water(clear(water));
    let mut frames = super::reference::own_projector_frames(scene, &clear_rig, head, &[pattern])?;
    Ok(frames.pop())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn murkier_water_blurs_more_and_needs_longer_exposures_up_to_the_plans_limit() {
        let levels = [Turbidity::T1, Turbidity::T2, Turbidity::T3, Turbidity::T4];
        let sigmas = levels.map(nominal_psf_sigma_px);
        let scales = levels.map(exposure_scale);
        assert!(sigmas.windows(2).all(|w| w[0] < w[1]), "{sigmas:?}");
        assert!(scales.windows(2).all(|w| w[0] < w[1]), "{scales:?}");
        // T1: 2 px/m over 0.47 m; the round trip costs exp(0.6 * 0.94).
        assert!((sigmas[0] - 0.94).abs() < 1e-12);
        assert!((scales[0] - (0.6f64 * 0.94).exp()).abs() < 1e-12);
        assert_eq!(scales[3], MAX_EXPOSURE_SCALE);
    }
}
