//! The medium between devices and scene: air, or water seen through flat
//! ports (seed 002, eq. 1-6): Beer-Lambert attenuation along the path,
//! forward-scatter blur growing with distance, a backscatter veil, and
//! refraction at each device's port by Snell's law.
//!
//! Model limits, on purpose: the port is thin (no glass thickness), the
//! water fills everything beyond it, and the forward-scatter PSF is a
//! Gaussian whose sigma grows linearly with the camera-side water path.

use serde::{Deserialize, Serialize};

use super::error::{non_negative, positive, TwinError};
use super::geometry::{Ray, V3};

/// Named turbidity levels T1 (clear coastal) .. T4 (harbour water), as in
/// seed 002. The paper gives no coefficients (it used 4..7 mL of milk in
/// 13 L), so ours are chosen to span "slight veil" to "fringes barely
/// above the noise" at a 0.3-0.6 m working distance.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
pub enum Turbidity {
    /// Relatively clear water.
    T1,
    /// Mildly turbid nearshore water.
    T2,
    /// Highly turbid, sediment-rich water.
    T3,
    /// Extremely turbid water, strong backscatter.
    T4,
}

/// Optical parameters of water behind flat ports.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Water {
    /// Beam attenuation c = a + b per LED band (R, G, B), 1/m.
    pub attenuation_per_m: [f64; 3],
    /// Forward-scatter PSF sigma per metre of camera-side water path, camera pixels/m.
    pub forward_sigma_px_per_m: f64,
    /// Backscatter veil at infinite depth as a fraction of the mean projected irradiance.
    pub backscatter_fraction: f64,
    /// Backscatter build-up coefficient b_b: veil = fraction * (1 - exp(-b_b * path)), 1/m.
    pub backscatter_per_m: f64,
    /// Refractive index of the water (air = 1).
    pub refractive_index: f64,
    /// Distance of every device's flat port in front of its centre, along its z axis, metres.
    pub port_distance_m: f64,
}

impl Water {
    /// The preset of a turbidity level with ports `port_distance_m` in front of the devices.
    pub fn preset(level: Turbidity, port_distance_m: f64) -> Water {
        let (c, fwd, veil, bb) = match level {
            Turbidity::T1 => (0.6, 2.0, 0.003, 0.6),
            Turbidity::T2 => (1.2, 4.0, 0.008, 1.0),
            Turbidity::T3 => (2.2, 7.0, 0.015, 1.6),
            Turbidity::T4 => (3.5, 11.0, 0.025, 2.4),
        };
        // Milky water absorbs red a little more than green and blue.
        Water {
            attenuation_per_m: [1.25 * c, c, 1.1 * c],
            forward_sigma_px_per_m: fwd,
            backscatter_fraction: veil,
            backscatter_per_m: bb,
            refractive_index: 1.33,
            port_distance_m,
        }
    }

    /// Fraction of light per band left after `path_m` metres of water.
    pub fn transmittance(&self, path_m: f64) -> [f64; 3] {
        self.attenuation_per_m.map(|c| (-c * path_m).exp())
    }

    /// Veil strength (fraction of mean projected irradiance) for a camera water path.
    pub fn veil(&self, path_m: f64) -> f64 {
        self.backscatter_fraction * (1.0 - (-self.backscatter_per_m * path_m).exp())
    }

    /// Refracts a device-frame ray leaving the centre at the port: returns
    /// the ray in water (device frame), or None when it does not reach the port.
    pub fn refract_out(&self, dir_local: &V3) -> Option<Ray> {
        if dir_local.z <= 0.0 {
            return None;
        }
        let q = dir_local * (self.port_distance_m / dir_local.z);
        // Snell in vector form, normal -z facing the incoming ray.
        let eta = 1.0 / self.refractive_index;
        let cos_i = dir_local.z;
        let k = 1.0 - eta * eta * (1.0 - cos_i * cos_i);
        let t = eta * dir_local - (eta * cos_i - k.sqrt()) * V3::z();
        Some(Ray {
            origin: q,
            dir: t.normalize(),
        })
    }

    /// Where on the port (device frame) the refracted path from the centre
    /// to a water point `p_local` crosses it; None if the point is not beyond the port.
    pub fn port_crossing(&self, p_local: &V3) -> Option<V3> {
        let d = self.port_distance_m;
        if p_local.z <= d {
            return None;
        }
        let r = (p_local.x * p_local.x + p_local.y * p_local.y).sqrt();
        if r < 1e-15 {
            return Some(V3::new(0.0, 0.0, d));
        }
        let n = self.refractive_index;
        let h = p_local.z - d;
        // f(rho) = sin(theta_air) - n sin(theta_water) rises from <= 0 at 0 to >= 0 at r.
        let f = |rho: f64| {
            rho / (rho * rho + d * d).sqrt()
                - n * (r - rho) / ((r - rho) * (r - rho) + h * h).sqrt()
        };
        let (mut lo, mut hi) = (0.0, r);
        for _ in 0..64 {
            let mid = 0.5 * (lo + hi);
            if f(mid) < 0.0 {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        let rho = 0.5 * (lo + hi);
        Some(V3::new(p_local.x * rho / r, p_local.y * rho / r, d))
    }

    /// Rejects non-physical numbers.
    pub fn validate(&self) -> Result<(), TwinError> {
        for &c in &self.attenuation_per_m {
            non_negative("attenuation_per_m", c)?;
        }
        non_negative("forward_sigma_px_per_m", self.forward_sigma_px_per_m)?;
        non_negative("backscatter_fraction", self.backscatter_fraction)?;
        non_negative("backscatter_per_m", self.backscatter_per_m)?;
        positive("refractive_index", self.refractive_index)?;
        positive("port_distance_m", self.port_distance_m)?;
        Ok(())
    }
}

/// What the devices look through.
#[derive(Clone, Copy, Debug, PartialEq, Default, Serialize, Deserialize)]
pub enum Medium {
    /// Air: no attenuation, scatter or refraction.
    #[default]
    Air,
    /// Water behind flat ports.
    Water(Water),
}

impl Medium {
    /// Checks the water parameters (air is always valid).
    pub fn validate(&self) -> Result<(), TwinError> {
        match self {
            Medium::Air => Ok(()),
            Medium::Water(w) => w.validate(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn port_crossing_inverts_refraction() {
        let w = Water::preset(Turbidity::T2, 0.05);
        let dir = V3::new(0.2, -0.1, 1.0).normalize();
        let ray = w.refract_out(&dir).unwrap();
        let p = ray.at(0.4);
        let q = w.port_crossing(&p).unwrap();
        assert!((q - ray.origin).norm() < 1e-12, "{q} vs {}", ray.origin);
    }

    #[test]
    fn refraction_bends_towards_the_axis() {
        let w = Water::preset(Turbidity::T1, 0.05);
        let dir = V3::new(0.5, 0.0, 1.0).normalize();
        let ray = w.refract_out(&dir).unwrap();
        let sin_air = dir.x;
        let sin_water = ray.dir.x;
        assert!((sin_air - 1.33 * sin_water).abs() < 1e-12);
    }

    #[test]
    fn attenuation_grows_with_turbidity() {
        let t = |l| Water::preset(l, 0.05).transmittance(0.5)[1];
        assert!(t(Turbidity::T1) > t(Turbidity::T2));
        assert!(t(Turbidity::T3) > t(Turbidity::T4));
    }
}
