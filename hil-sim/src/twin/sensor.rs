//! The camera sensor: LED bands to camera channels (crosstalk), photons to
//! electrons, Poisson shot noise, Gaussian read noise, gain, saturation,
//! gamma and 8/10/12-bit quantisation (seed 003: I = k t (r (Lp + Li) + La) + In).

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal, Poisson};
use rayon::prelude::*;

use super::error::{non_negative, positive, TwinError};

/// How the LED bands (R, G, B) reach the sensor's channels.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub enum Channels {
    /// A monochrome sensor with these band sensitivities.
    Mono([f64; 3]),
    /// A colour sensor: row c gives channel c's sensitivity to each band
    /// (off-diagonal terms are the crosstalk seed 001's ZOCR-Net removes).
    Rgb([[f64; 3]; 3]),
}

impl Channels {
    /// Number of output channels (1 or 3).
    pub fn count(&self) -> usize {
        match self {
            Channels::Mono(_) => 1,
            Channels::Rgb(_) => 3,
        }
    }

    /// Mixes band signals into channel signals.
    fn mix(&self, bands: [f32; 3], out: &mut [f32]) {
        match self {
            Channels::Mono(w) => {
                out[0] = (w[0] * bands[0] as f64 + w[1] * bands[1] as f64 + w[2] * bands[2] as f64)
                    as f32
            }
            Channels::Rgb(m) => {
                for (c, o) in out.iter_mut().enumerate() {
                    *o = (m[c][0] * bands[0] as f64
                        + m[c][1] * bands[1] as f64
                        + m[c][2] * bands[2] as f64) as f32;
                }
            }
        }
    }
}

/// A sensor's radiometric and noise model.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SensorModel {
    /// Band-to-channel sensitivities.
    pub channels: Channels,
    /// Electrons collected per twin unit of exposure (irradiance x seconds).
    pub electrons_per_unit: f64,
    /// Full-well capacity, electrons: the ADC full scale at gain 1.
    pub full_well_e: f64,
    /// Read noise, electrons RMS.
    pub read_noise_e: f64,
    /// Whether to draw Poisson shot noise.
    pub shot_noise: bool,
    /// Analogue gain (output = gain x electrons / full well before clipping).
    pub gain: f64,
    /// Display gamma: output = linear^(1/gamma); 1 = linear.
    pub gamma: f64,
    /// ADC bits (8, 10 or 12); 0 keeps floats unquantised.
    pub bits: u8,
}

/// A row-major image with 1 or 3 interleaved f32 channels.
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    /// Width, pixels.
    pub width: u32,
    /// Height, pixels.
    pub height: u32,
    /// Channels per pixel (1 or 3).
    pub channels: usize,
    /// Row-major interleaved values (in [0, 1] for sensor output).
    pub data: Vec<f32>,
}

impl Image {
    /// Value of channel `c` at pixel (x, y).
    pub fn at(&self, x: u32, y: u32, c: usize) -> f32 {
        self.data[(y as usize * self.width as usize + x as usize) * self.channels + c]
    }
}

impl SensorModel {
    /// A 12-bit monochrome machine-vision sensor (10 ke- full well, 6 e- read noise).
    pub fn mono12() -> SensorModel {
        SensorModel {
            // Equal thirds: a white LED triple reads like one band at full power.
            channels: Channels::Mono([1.0 / 3.0; 3]),
            electrons_per_unit: 1.0e7,
            full_well_e: 10_000.0,
            read_noise_e: 6.0,
            shot_noise: true,
            gain: 1.0,
            gamma: 1.0,
            bits: 12,
        }
    }

    /// An 8-bit colour sensor with Bayer-like channel crosstalk.
    pub fn colour8() -> SensorModel {
        SensorModel {
            channels: Channels::Rgb([[0.90, 0.12, 0.03], [0.10, 0.85, 0.10], [0.03, 0.15, 0.88]]),
            bits: 8,
            ..SensorModel::mono12()
        }
    }

    /// A noise-free linear float sensor (for checks against analytic answers).
    pub fn ideal() -> SensorModel {
        SensorModel {
            read_noise_e: 0.0,
            shot_noise: false,
            bits: 0,
            ..SensorModel::mono12()
        }
    }

    /// Rejects non-physical numbers.
    pub fn validate(&self) -> Result<(), TwinError> {
        positive("electrons_per_unit", self.electrons_per_unit)?;
        let weights: Vec<f64> = match self.channels {
            Channels::Mono(w) => w.to_vec(),
            Channels::Rgb(m) => m.iter().flatten().copied().collect(),
        };
        for w in weights {
            non_negative("channel sensitivity", w)?;
        }
        positive("full_well_e", self.full_well_e)?;
        non_negative("read_noise_e", self.read_noise_e)?;
        positive("gain", self.gain)?;
        positive("gamma", self.gamma)?;
        if ![0u8, 8, 10, 12, 16].contains(&self.bits) {
            return Err(TwinError::BadParameter {
                name: "bits",
                value: self.bits as f64,
                why: "must be 0, 8, 10, 12 or 16",
            });
        }
        Ok(())
    }

    /// Standard deviation of the output, in output units, for a mean signal
    /// of `mean_e` electrons (linear response, gamma 1, below saturation):
    /// shot + read noise through the gain, plus uniform quantisation noise.
    pub fn output_sigma(&self, mean_e: f64) -> f64 {
        let shot = if self.shot_noise {
            mean_e.max(0.0)
        } else {
            0.0
        };
        let scale = self.gain / self.full_well_e;
        let quant = if self.bits == 0 {
            0.0
        } else {
            1.0 / ((1u32 << self.bits) - 1) as f64
        };
        (scale * scale * (shot + self.read_noise_e * self.read_noise_e) + quant * quant / 12.0)
            .sqrt()
    }

    /// Mean electrons for a band exposure (twin units x s) of channel value `signal`.
    pub fn electrons(&self, signal: f32) -> f64 {
        signal as f64 * self.electrons_per_unit
    }

    /// Turns per-pixel band exposures (twin units x s) into the sensor image.
    /// With `noise_seed` None the image is noise-free (but still clipped,
    /// gamma-corrected and quantised). Also returns which pixels saturate
    /// (noise-free signal at or above full scale in any channel).
    pub fn expose(
        &self,
        width: u32,
        height: u32,
        bands: &[[f32; 3]],
        noise_seed: Option<u64>,
    ) -> (Image, Vec<bool>) {
        let nc = self.channels.count();
        let w = width as usize;
        let mut data = vec![0.0f32; bands.len() * nc];
        let mut sat = vec![false; bands.len()];
        let scale = self.gain / self.full_well_e;
        let levels = if self.bits == 0 {
            0.0
        } else {
            ((1u32 << self.bits) - 1) as f64
        };
        data.par_chunks_mut(w * nc)
            .zip(sat.par_chunks_mut(w))
            .enumerate()
            .for_each(|(y, (row, srow))| {
                // One generator per row, seeded from (seed, row): reproducible whatever the thread schedule.
                let mut rng = noise_seed.map(|s| {
                    ChaCha8Rng::seed_from_u64(s ^ (y as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15))
                });
                let read = Normal::new(0.0, self.read_noise_e.max(0.0))
                    .expect("read noise is validated finite");
                let mut ch = [0.0f32; 3];
                for x in 0..w {
                    self.channels.mix(bands[y * w + x], &mut ch[..nc]);
                    for c in 0..nc {
                        let mean_e = self.electrons(ch[c]).max(0.0);
                        if mean_e * scale >= 1.0 {
                            srow[x] = true;
                        }
                        let e = match rng.as_mut() {
                            None => mean_e,
                            Some(r) => {
                                let shot = if self.shot_noise {
                                    poisson(mean_e, r)
                                } else {
                                    mean_e
                                };
                                shot + read.sample(r)
                            }
                        };
                        let mut v = (e * scale).clamp(0.0, 1.0);
                        if self.gamma != 1.0 {
                            v = v.powf(1.0 / self.gamma);
                        }
                        if levels > 0.0 {
                            // v >= 0 here: add-half-and-truncate is round (no libm call).
                            v = ((v * levels + 0.5) as u32) as f64 / levels;
                        }
                        row[x * nc + c] = v as f32;
                    }
                }
            });
        (
            Image {
                width,
                height,
                channels: nc,
                data,
            },
            sat,
        )
    }
}

/// Poisson draw; above 100 expected electrons the Gaussian limit (same
/// mean and variance, relative skew <= 10 %, and read noise adds to it) is
/// used because it is several times faster per pixel.
fn poisson(mean: f64, rng: &mut impl Rng) -> f64 {
    if mean <= 0.0 {
        0.0
    } else if mean > 100.0 {
        mean + mean.sqrt() * rng.sample::<f64, _>(rand_distr::StandardNormal)
    } else {
        Poisson::new(mean).map(|p| p.sample(rng)).unwrap_or(mean)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn noise_statistics_match_the_model() {
        let s = SensorModel::mono12();
        let signal = 0.3f32 / s.electrons_per_unit as f32 * s.full_well_e as f32;
        let bands = vec![[signal; 3]; 200 * 200];
        let (img, _) = s.expose(200, 200, &bands, Some(5));
        let n = img.data.len() as f64;
        let mean = img.data.iter().map(|&v| v as f64).sum::<f64>() / n;
        let var = img
            .data
            .iter()
            .map(|&v| (v as f64 - mean).powi(2))
            .sum::<f64>()
            / (n - 1.0);
        assert!((mean - 0.3).abs() < 1e-3, "mean {mean}");
        let want = s.output_sigma(3000.0);
        assert!(
            (var.sqrt() / want - 1.0).abs() < 0.03,
            "sigma {} want {want}",
            var.sqrt()
        );
    }

    #[test]
    fn saturation_and_quantisation() {
        let s = SensorModel {
            bits: 8,
            ..SensorModel::ideal()
        };
        let full = (s.full_well_e / s.electrons_per_unit) as f32;
        let (img, sat) = s.expose(2, 1, &[[full; 3], [0.1 * full; 3]], None);
        assert_eq!(img.data[0], 1.0);
        assert!(sat[0] && !sat[1]);
        assert_eq!(img.data[1], (0.1f64 * 255.0).round() as f32 / 255.0);
    }

    #[test]
    fn same_seed_same_noise() {
        let s = SensorModel::mono12();
        let bands = vec![[1e-4; 3]; 64 * 8];
        assert_eq!(
            s.expose(64, 8, &bands, Some(9)).0,
            s.expose(64, 8, &bands, Some(9)).0
        );
        assert_ne!(
            s.expose(64, 8, &bands, Some(9)).0,
            s.expose(64, 8, &bands, Some(10)).0
        );
    }
}
