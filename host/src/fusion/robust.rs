//! Robust weights for least squares: kernels and the MAD scale.

/// Robust weighting of the point-to-plane residuals. Thresholds are in units
/// of the robust scale `sigma = 1.4826 * median(|r|)` (floored at
/// [`IcpParams::min_scale_m`](super::IcpParams::min_scale_m)).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum RobustKernel {
    /// Plain least squares (every gated pair weight 1).
    None,
    /// Huber: weight 1 inside `k * sigma`, `k * sigma / |r|` outside.
    Huber {
        /// Threshold in scale units (1.345 is 95 % efficient on Gaussian noise).
        k: f64,
    },
    /// Tukey biweight: `(1 - (r / (c sigma))^2)^2` inside, 0 outside.
    Tukey {
        /// Threshold in scale units (4.685 is 95 % efficient on Gaussian noise).
        c: f64,
    },
}

impl RobustKernel {
    /// Weight of residual `r` when the robust scale is `sigma`.
    pub fn weight(self, r: f64, sigma: f64) -> f64 {
        match self {
            RobustKernel::None => 1.0,
            RobustKernel::Huber { k } => {
                let t = k * sigma;
                if r.abs() <= t {
                    1.0
                } else {
                    t / r.abs()
                }
            }
            RobustKernel::Tukey { c } => {
                let u = r / (c * sigma);
                if u.abs() < 1.0 {
                    (1.0 - u * u).powi(2)
                } else {
                    0.0
                }
            }
        }
    }
}

/// `1.4826 * median(|r|)`, the Gaussian-consistent MAD (residuals are
/// centred on zero at the solution), floored at `min_scale_m`.
pub(crate) fn mad_scale(mut abs_residuals: Vec<f64>, min_scale_m: f64) -> f64 {
    if abs_residuals.is_empty() {
        return min_scale_m;
    }
    let mid = abs_residuals.len() / 2;
    let (_, median, _) = abs_residuals.select_nth_unstable_by(mid, f64::total_cmp);
    (1.4826 * *median).max(min_scale_m)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn kernels_downweight_large_residuals() {
        let huber = RobustKernel::Huber { k: 1.345 };
        let tukey = RobustKernel::Tukey { c: 4.685 };
        assert_eq!(huber.weight(1.0, 1.0), 1.0);
        assert!((huber.weight(13.45, 1.0) - 0.1).abs() < 1e-12);
        assert_eq!(tukey.weight(0.0, 1.0), 1.0);
        assert_eq!(tukey.weight(5.0, 1.0), 0.0);
        assert!(tukey.weight(2.0, 1.0) < tukey.weight(1.0, 1.0));
        assert_eq!(RobustKernel::None.weight(1e9, 1.0), 1.0);
    }

    proptest::proptest! {
        /// The selection-based median equals the sorted reference.
        #[test]
        fn mad_scale_matches_a_sorted_median(abs in proptest::collection::vec(0.0f64..1.0, 1..200)) {
            let mut sorted = abs.clone();
            sorted.sort_by(f64::total_cmp);
            let reference = (1.4826 * sorted[sorted.len() / 2]).max(1e-9);
            proptest::prop_assert_eq!(mad_scale(abs, 1e-9), reference);
        }
    }

    #[test]
    fn mad_scale_of_a_gaussian_is_its_sigma() {
        // |N(0, 1)| quantiles at (i + 0.5) / n: median exactly 0.6745.
        let n = 1001;
        let abs: Vec<f64> = (0..n)
            .map(|i| 0.6745 * 2.0 * (i as f64 + 0.5) / n as f64)
            .collect();
        assert!((mad_scale(abs, 1e-9) - 1.4826 * 0.6745).abs() < 1e-3);
        assert_eq!(mad_scale(vec![0.0; 5], 1e-7), 1e-7);
    }
}
