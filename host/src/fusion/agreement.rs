//! How well two registered clouds agree in shape, which needs no truth:
//! after the best rigid fit, the point-to-plane residuals of a rigidly
//! misplaced but correct pair of clouds are noise with zero mean
//! everywhere; a wrong focal length or projector model bends one cloud
//! against the other, so the residual's local mean varies across the
//! overlap. Averaging it over cells of the overlap leaves that systematic
//! part and divides the noise by the square root of the cell's points.

use std::collections::HashMap;

use nalgebra::Vector3;

/// The overlap's systematic disagreement.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShapeAgreement {
    /// Cells of the overlap with enough points.
    pub cells: usize,
    /// RMS over cells of the cell's mean signed residual, metres.
    pub cell_mean_rms_m: f64,
    /// What noise alone would give for that figure, metres.
    pub noise_rms_m: f64,
    /// The systematic part: `sqrt(cell_mean_rms^2 - noise_rms^2)` (0 when
    /// noise explains it), metres.
    pub systematic_rms_m: f64,
}

/// Points a cell needs to count.
const MIN_CELL_POINTS: usize = 50;

/// [`ShapeAgreement`] of `residuals` (position, signed residual in metres)
/// over cubic cells of `cell_m`; residuals beyond `gate_m` are left out as
/// mismatched pairs. `None` when no cell has enough points.
pub fn shape_agreement(
    residuals: &[(Vector3<f64>, f64)],
    cell_m: f64,
    gate_m: f64,
) -> Option<ShapeAgreement> {
    // Per cell: count, sum r, sum r^2.
    let mut cells: HashMap<[i64; 3], (usize, f64, f64)> = HashMap::new();
    for (p, r) in residuals {
        if !(r.is_finite() && r.abs() <= gate_m) {
            continue;
        }
        let key = [0, 1, 2].map(|k| (p[k] / cell_m).floor() as i64);
        let c = cells.entry(key).or_insert((0, 0.0, 0.0));
        c.0 += 1;
        c.1 += r;
        c.2 += r * r;
    }
    let (mut n, mut mean2, mut noise2) = (0usize, 0.0, 0.0);
    for &(count, sum, sum2) in cells.values() {
        if count < MIN_CELL_POINTS {
            continue;
        }
        let m = sum / count as f64;
        let var = (sum2 / count as f64 - m * m).max(0.0);
        n += 1;
        mean2 += m * m;
        // The variance of a cell mean under noise alone.
        noise2 += var / count as f64;
    }
    if n == 0 {
        return None;
    }
    let (mean2, noise2) = (mean2 / n as f64, noise2 / n as f64);
    Some(ShapeAgreement {
        cells: n,
        cell_mean_rms_m: mean2.sqrt(),
        noise_rms_m: noise2.sqrt(),
        systematic_rms_m: (mean2 - noise2).max(0.0).sqrt(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_distr::StandardNormal;

    fn residuals(bend_m: f64, seed: u64) -> Vec<(Vector3<f64>, f64)> {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        (0..40_000)
            .map(|i| {
                let p = Vector3::new((i % 200) as f64 * 5e-4, (i / 200) as f64 * 5e-4, 0.5);
                let noise: f64 = rng.sample::<f64, _>(StandardNormal) * 100e-6;
                // A bend: zero mean over the patch, varying across it.
                let systematic = bend_m * (p.x / 0.1 * std::f64::consts::TAU).sin();
                (p, noise + systematic)
            })
            .collect()
    }

    #[test]
    fn noise_alone_reads_as_agreement_and_a_bend_as_its_size() {
        let flat = shape_agreement(&residuals(0.0, 1), 0.01, 2e-3).unwrap();
        assert_eq!(flat.cells, 100);
        assert!(flat.systematic_rms_m < 10e-6, "{flat:?}");
        assert!((flat.noise_rms_m - 100e-6 / 20.0).abs() < 1e-6, "{flat:?}");
        // A sine of amplitude 100 um: RMS 71 um (less a little for cell averaging).
        let bent = shape_agreement(&residuals(100e-6, 2), 0.01, 2e-3).unwrap();
        assert!(
            bent.systematic_rms_m > 55e-6 && bent.systematic_rms_m < 75e-6,
            "{bent:?}"
        );
        assert!(shape_agreement(&[], 0.01, 2e-3).is_none());
    }
}
