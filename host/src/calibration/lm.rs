//! A small dense Levenberg-Marquardt solver on nalgebra.
//!
//! Why our own and not the `levenberg-marquardt` crate: its current release
//! (0.15) is built on nalgebra 0.34 while the workspace uses 0.35, so it would
//! compile a second nalgebra (slow on our 2-core CI) and its matrices would not
//! be our matrices. Calibration problems here are small (at most a few hundred
//! parameters, a few thousand residuals), so a dense normal-equation solver with
//! Marquardt's diagonal scaling is enough, and a problem can supply a
//! block-sparse Jacobian of its own (see `bundle.rs`).

use nalgebra::{DMatrix, DVector};

/// A nonlinear least-squares problem: minimise `0.5 * |r(p)|^2`.
pub trait LeastSquaresProblem {
    /// Number of residuals `m`.
    fn residual_count(&self) -> usize;

    /// Writes the `m` residuals at `params` into `out`.
    fn residuals(&self, params: &DVector<f64>, out: &mut DVector<f64>);

    /// Writes the `m x n` Jacobian at `params` into `jac`.
    ///
    /// The default takes central differences over every parameter; problems
    /// whose residuals depend on few parameters each should override it.
    fn jacobian(&self, params: &DVector<f64>, jac: &mut DMatrix<f64>) {
        numeric_jacobian(self, params, jac);
    }
}

/// Step for central differences of parameter value `value`.
pub fn difference_step(value: f64) -> f64 {
    1e-6 * value.abs().max(1e-2)
}

/// Central-difference Jacobian of `problem` at `params` over all parameters.
pub fn numeric_jacobian<P: LeastSquaresProblem + ?Sized>(
    problem: &P,
    params: &DVector<f64>,
    jac: &mut DMatrix<f64>,
) {
    let m = problem.residual_count();
    let mut plus = DVector::zeros(m);
    let mut minus = DVector::zeros(m);
    let mut p = params.clone();
    for j in 0..params.len() {
        let h = difference_step(params[j]);
        p[j] = params[j] + h;
        problem.residuals(&p, &mut plus);
        p[j] = params[j] - h;
        problem.residuals(&p, &mut minus);
        p[j] = params[j];
        jac.set_column(j, &((&plus - &minus) / (2.0 * h)));
    }
}

/// Central-difference Jacobian of a problem made of independent blocks (views):
/// block `v` owns residual rows `offsets[v]..offsets[v + 1]`, which depend only on
/// the parameters `params_of(v)` and are computed by `block_residuals(params, v,
/// out)`. Entries outside each block's parameters are zero.
pub fn block_jacobian<I: Iterator<Item = usize>>(
    params: &DVector<f64>,
    offsets: &[usize],
    params_of: impl Fn(usize) -> I,
    block_residuals: impl Fn(&DVector<f64>, usize, &mut [f64]),
    jac: &mut DMatrix<f64>,
) {
    jac.fill(0.0);
    let mut q = params.clone();
    for v in 0..offsets.len().saturating_sub(1) {
        let (a, b) = (offsets[v], offsets[v + 1]);
        let mut plus = vec![0.0; b - a];
        let mut minus = vec![0.0; b - a];
        for j in params_of(v) {
            let h = difference_step(params[j]);
            q[j] = params[j] + h;
            block_residuals(&q, v, &mut plus);
            q[j] = params[j] - h;
            block_residuals(&q, v, &mut minus);
            q[j] = params[j];
            for (row, (x, y)) in plus.iter().zip(&minus).enumerate() {
                jac[(a + row, j)] = (x - y) / (2.0 * h);
            }
        }
    }
}

/// Stopping rules of [`minimise`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LmOptions {
    /// Most iterations (Jacobian evaluations).
    pub max_iterations: usize,
    /// Stop when an accepted step lowers the cost by less than this fraction.
    pub cost_rel_tol: f64,
    /// Stop when the step is smaller than this fraction of the parameter norm.
    pub step_rel_tol: f64,
    /// Initial damping relative to the mean diagonal of `J^T J`.
    pub initial_damping: f64,
}

impl Default for LmOptions {
    fn default() -> Self {
        Self {
            max_iterations: 100,
            cost_rel_tol: 1e-12,
            step_rel_tol: 1e-12,
            initial_damping: 1e-3,
        }
    }
}

/// Why [`minimise`] stopped.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Termination {
    /// The relative cost decrease fell below `cost_rel_tol`.
    CostConverged,
    /// The step fell below `step_rel_tol`.
    StepConverged,
    /// The cost is zero to machine precision.
    ZeroResidual,
    /// `max_iterations` was reached.
    MaxIterations,
    /// No damping made the cost decrease: the point is a minimum to precision.
    NoDecrease,
}

/// What [`minimise`] did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LmReport {
    /// Iterations run.
    pub iterations: usize,
    /// `0.5 * |r|^2` at the start.
    pub initial_cost: f64,
    /// `0.5 * |r|^2` at the end.
    pub final_cost: f64,
    /// Why it stopped.
    pub termination: Termination,
}

/// Errors of [`minimise`].
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum LmError {
    /// The residuals at the starting point are NaN or infinite.
    #[error("residuals are not finite at the starting point")]
    NonFiniteStart,
    /// The problem has fewer residuals than parameters.
    #[error("{residuals} residuals cannot determine {params} parameters")]
    Underdetermined {
        /// Residual count.
        residuals: usize,
        /// Parameter count.
        params: usize,
    },
}

fn cost(r: &DVector<f64>) -> f64 {
    0.5 * r.norm_squared()
}

/// `J^T J`, summing each pair of columns only over the rows where both can
/// be non-zero. A calibration's Jacobian is block-sparse (a view's pose
/// moves only that view's residuals), so most column pairs share no rows:
/// 15 views cost about a fiftieth of the dense product.
pub fn gram(jac: &DMatrix<f64>) -> DMatrix<f64> {
    let n = jac.ncols();
    // Per column, the rows from its first to its last non-zero entry.
    let spans: Vec<Option<(usize, usize)>> = (0..n)
        .map(|c| {
            let col = jac.column(c);
            let first = col.iter().position(|v| *v != 0.0)?;
            let last = col.iter().rposition(|v| *v != 0.0)?;
            Some((first, last + 1))
        })
        .collect();
    let mut out = DMatrix::zeros(n, n);
    for a in 0..n {
        let Some((a0, a1)) = spans[a] else { continue };
        for b in a..n {
            let Some((b0, b1)) = spans[b] else { continue };
            let (lo, hi) = (a0.max(b0), a1.min(b1));
            if lo >= hi {
                continue;
            }
            let dot = jac
                .view((lo, a), (hi - lo, 1))
                .dot(&jac.view((lo, b), (hi - lo, 1)));
            out[(a, b)] = dot;
            out[(b, a)] = dot;
        }
    }
    out
}

/// Minimises `problem` from `start`; returns the best parameters found.
pub fn minimise<P: LeastSquaresProblem + ?Sized>(
    problem: &P,
    start: DVector<f64>,
    options: &LmOptions,
) -> Result<(DVector<f64>, LmReport), LmError> {
    let m = problem.residual_count();
    let n = start.len();
    if m < n {
        return Err(LmError::Underdetermined {
            residuals: m,
            params: n,
        });
    }
    let mut params = start;
    let mut r = DVector::zeros(m);
    problem.residuals(&params, &mut r);
    let mut current = cost(&r);
    if !current.is_finite() {
        return Err(LmError::NonFiniteStart);
    }
    let initial_cost = current;
    let mut jac = DMatrix::zeros(m, n);
    let mut trial_r = DVector::zeros(m);
    let mut lambda = f64::NAN;
    let mut termination = Termination::MaxIterations;
    let mut iterations = 0;
    while iterations < options.max_iterations {
        iterations += 1;
        if current <= f64::EPSILON * f64::EPSILON {
            termination = Termination::ZeroResidual;
            break;
        }
        problem.jacobian(&params, &mut jac);
        let jtj = gram(&jac);
        let gradient = jac.tr_mul(&r);
        // Marquardt scaling: damp each parameter by its own curvature so that
        // focal lengths in pixels and distortion coefficients near 0.1 are
        // treated alike; a floor keeps unobserved parameters solvable.
        let diag: DVector<f64> = jtj.diagonal().map(|d| d.max(1e-12));
        if lambda.is_nan() {
            lambda = options.initial_damping;
        }
        let mut accepted = false;
        let mut converged = None;
        for _ in 0..30 {
            let mut a = jtj.clone();
            for i in 0..n {
                a[(i, i)] += lambda * diag[i];
            }
            let Some(chol) = a.cholesky() else {
                lambda *= 10.0;
                continue;
            };
            let step = chol.solve(&(-&gradient));
            let trial = &params + &step;
            problem.residuals(&trial, &mut trial_r);
            let trial_cost = cost(&trial_r);
            if trial_cost.is_finite() && trial_cost < current {
                let decrease = (current - trial_cost) / current;
                let step_small = step.norm() <= options.step_rel_tol * (params.norm() + 1e-12);
                params = trial;
                std::mem::swap(&mut r, &mut trial_r);
                current = trial_cost;
                lambda = (lambda / 3.0).max(1e-15);
                accepted = true;
                if decrease < options.cost_rel_tol {
                    converged = Some(Termination::CostConverged);
                } else if step_small {
                    converged = Some(Termination::StepConverged);
                }
                break;
            }
            lambda *= 4.0;
        }
        if let Some(t) = converged {
            termination = t;
            break;
        }
        if !accepted {
            termination = Termination::NoDecrease;
            break;
        }
    }
    Ok((
        params,
        LmReport {
            iterations,
            initial_cost,
            final_cost: current,
            termination,
        },
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gram_matches_the_dense_product_on_block_sparse_and_dense_matrices() {
        // Two shared columns over all rows, then two blocks of two columns
        // each touching only its own rows, and a column of zeros.
        let mut jac = DMatrix::<f64>::zeros(10, 7);
        for r in 0..10 {
            jac[(r, 0)] = (r as f64 * 0.7).sin();
            jac[(r, 1)] = 1.0 + r as f64;
            let block = if r < 5 { 2 } else { 4 };
            jac[(r, block)] = (r as f64).cos();
            jac[(r, block + 1)] = 0.5 - r as f64 * 0.1;
        }
        jac[(3, 2)] = 0.0; // A zero inside a span changes nothing.
        assert!((gram(&jac) - jac.tr_mul(&jac)).abs().max() < 1e-12);
        let dense = DMatrix::from_fn(6, 4, |r, c| ((r * 4 + c) as f64).sin());
        assert!((gram(&dense) - dense.tr_mul(&dense)).abs().max() < 1e-15);
    }

    /// Rosenbrock as least squares: r = (10 (y - x^2), 1 - x), minimum at (1, 1).
    struct Rosenbrock;

    impl LeastSquaresProblem for Rosenbrock {
        fn residual_count(&self) -> usize {
            2
        }
        fn residuals(&self, p: &DVector<f64>, out: &mut DVector<f64>) {
            out[0] = 10.0 * (p[1] - p[0] * p[0]);
            out[1] = 1.0 - p[0];
        }
    }

    #[test]
    fn finds_rosenbrock_minimum() {
        let start = DVector::from_vec(vec![-1.2, 1.0]);
        let (p, report) = minimise(&Rosenbrock, start, &LmOptions::default()).unwrap();
        assert!(
            (p[0] - 1.0).abs() < 1e-8 && (p[1] - 1.0).abs() < 1e-8,
            "{p}"
        );
        assert!(report.final_cost < 1e-16, "{report:?}");
    }

    /// Exponential fit y = a exp(b t) to exact data.
    struct ExpFit {
        t: Vec<f64>,
        y: Vec<f64>,
    }

    impl LeastSquaresProblem for ExpFit {
        fn residual_count(&self) -> usize {
            self.t.len()
        }
        fn residuals(&self, p: &DVector<f64>, out: &mut DVector<f64>) {
            for (i, (t, y)) in self.t.iter().zip(&self.y).enumerate() {
                out[i] = p[0] * (p[1] * t).exp() - y;
            }
        }
    }

    #[test]
    fn fits_exponential() {
        let t: Vec<f64> = (0..20).map(|i| i as f64 * 0.1).collect();
        let y = t.iter().map(|t| 2.5 * (-1.3 * t).exp()).collect();
        let problem = ExpFit { t, y };
        let start = DVector::from_vec(vec![1.0, 0.0]);
        let (p, _) = minimise(&problem, start, &LmOptions::default()).unwrap();
        assert!(
            (p[0] - 2.5).abs() < 1e-8 && (p[1] + 1.3).abs() < 1e-8,
            "{p}"
        );
    }

    #[test]
    fn rejects_underdetermined_and_nan() {
        let problem = ExpFit {
            t: vec![0.0],
            y: vec![1.0],
        };
        let start = DVector::from_vec(vec![1.0, 0.0]);
        assert_eq!(
            minimise(&problem, start, &LmOptions::default()).unwrap_err(),
            LmError::Underdetermined {
                residuals: 1,
                params: 2
            }
        );
        let problem = ExpFit {
            t: vec![0.0, 1.0],
            y: vec![f64::NAN, 1.0],
        };
        let start = DVector::from_vec(vec![1.0, 0.0]);
        assert_eq!(
            minimise(&problem, start, &LmOptions::default()).unwrap_err(),
            LmError::NonFiniteStart
        );
    }
}
