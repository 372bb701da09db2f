//! Bounded Levenberg-Marquardt on a residual vector, with a finite-difference Jacobian whose
//! columns are evaluated in parallel.
//!
//! Marquardt's scaling (damping `lambda * diag(J^T J)`) makes the steps invariant to the units of
//! each variable; bounds are kept by projecting every trial point onto the box. Each Jacobian
//! column is an independent forward difference, computed in parallel and stored by index, so
//! the result does not depend on the thread count. Where a residual evaluation is a long
//! simulation, the Jacobian can instead be carried between iterations by Broyden's secant
//! update ([`LmOptions::secant_updates`]): one evaluation per iteration instead of one per
//! variable, with finite differences again only when a step fails and to confirm convergence.
//!
//! Why not a crate: the `levenberg-marquardt` crate (0.14, a MINPACK port on nalgebra) and
//! argmin's Gauss-Newton take a Jacobian from the caller and keep no bounds; neither carries
//! the Jacobian by secant updates. Measured once (2026-11-26, a scratch program outside the
//! repository, release, three runs on a shared two-core machine): fitting the five
//! parameters of a simulated three-mass spring chain (200 frames, 20 substeps) from the same
//! start, with the same forward differences, both reach the same cost; this solver takes 29
//! simulations and 3.2-4.2 ms, the crate 60 simulations and 8.7 ms (2.0-2.7 times as long;
//! the simulation count does not depend on the two cores this solver's Jacobian columns
//! use). The secant updates are what made the patch refinement of a 6 x 6 lattice go from
//! 4.5 s to 1.9 s, and the whole-object refinement of paper8 from 2218 to 248 simulations
//! (2026-11-24, docs/benchmarks.md).

use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;

use crate::Observer;

/// Settings of [`levenberg_marquardt`].
#[derive(Clone, Debug, PartialEq)]
pub struct LmOptions {
    /// Most Jacobian evaluations (outer iterations).
    pub max_iterations: usize,
    /// Stop when an accepted step lowers the cost by less than this fraction.
    pub tolerance: f64,
    /// Relative finite-difference step (times `max(|x|, typical)`).
    pub fd_step: f64,
    /// Adds the geodesic acceleration correction to each step (one more evaluation per trial).
    pub geodesic_acceleration: bool,
    /// Stop when an accepted step moves no variable by more than this fraction of
    /// `max(|x|, typical)` (converged to that precision; the Jacobian is then kept).
    pub step_tolerance: f64,
    /// Carry the Jacobian from one iteration to the next by Broyden's secant update instead of
    /// recomputing it by finite differences (one evaluation per iteration instead of one per
    /// variable). Finite differences are taken again whenever a step fails and to confirm
    /// convergence, so the returned Jacobian is a finite-difference one unless the iterations
    /// ran out ([`LmOutcome::jacobian_exact`]).
    pub secant_updates: bool,
    /// With secant updates, confirm convergence with a finite-difference Jacobian before
    /// stopping (off where a later stage confirms it anyway).
    pub confirm_convergence: bool,
}

impl Default for LmOptions {
    fn default() -> Self {
        LmOptions {
            max_iterations: 60,
            tolerance: 1e-6,
            fd_step: 1e-7,
            geodesic_acceleration: true,
            step_tolerance: 1e-9,
            secant_updates: false,
            confirm_convergence: true,
        }
    }
}

/// What [`levenberg_marquardt`] returns.
#[derive(Clone, Debug)]
pub struct LmOutcome {
    /// The best point found.
    pub x: Vec<f64>,
    /// Residuals at `x`.
    pub residuals: Vec<f64>,
    /// Jacobian of the residuals at `x` (rows: residuals, columns: variables).
    pub jacobian: DMatrix<f64>,
    /// Sum of squared residuals at `x`.
    pub cost: f64,
    /// Cost after each outer iteration (the first entry is the start).
    pub history: Vec<f64>,
    /// Outer iterations run.
    pub iterations: usize,
    /// Residual evaluations made (Jacobian columns included).
    pub evaluations: usize,
    /// False when `jacobian` is a secant (Broyden) estimate rather than finite differences (only
    /// with [`LmOptions::secant_updates`] when the iterations ran out or convergence was not
    /// confirmed).
    pub jacobian_exact: bool,
}

/// A residual function: writes the residuals at `x` into the vector; false if they cannot be
/// evaluated (a diverging simulation).
pub type Residuals<'a> = dyn Fn(&[f64], &mut Vec<f64>) -> bool + Sync + 'a;

/// Forward-difference Jacobian at `x` (residuals `r0`), columns in parallel.
/// `typical[j]` is variable `j`'s typical magnitude. Returns `None` if a column cannot be evaluated.
pub fn jacobian(
    f: &Residuals<'_>,
    x: &[f64],
    r0: &[f64],
    lower: &[f64],
    upper: &[f64],
    typical: &[f64],
    fd_step: f64,
) -> Option<DMatrix<f64>> {
    let m = r0.len();
    let cols: Vec<Option<Vec<f64>>> = (0..x.len())
        .into_par_iter()
        .map(|j| {
            let mut h = fd_step * x[j].abs().max(typical[j].abs()).max(f64::MIN_POSITIVE);
            if x[j] + h > upper[j] {
                h = -h;
            }
            if x[j] + h < lower[j] {
                // The box is narrower than the step: use what fits.
                h = (upper[j] - x[j]).max(lower[j] - x[j]);
                if h == 0.0 {
                    return Some(vec![0.0; m]);
                }
            }
            let mut xp = x.to_vec();
            xp[j] += h;
            let h = xp[j] - x[j];
            let mut r = Vec::with_capacity(m);
            if !f(&xp, &mut r) || r.len() != m {
                return None;
            }
            Some(r.iter().zip(r0).map(|(a, b)| (a - b) / h).collect())
        })
        .collect();
    let mut jac = DMatrix::zeros(m, x.len());
    for (j, col) in cols.into_iter().enumerate() {
        let col = col?;
        jac.column_mut(j).copy_from_slice(&col);
    }
    Some(jac)
}

/// Minimises `sum r(x)^2` over the box `[lower, upper]` from `x0` (Levenberg-Marquardt,
/// Marquardt scaling, projected steps). `typical` sets each variable's finite-difference
/// scale. Returns `None` if the residuals cannot be evaluated at the (clamped) start.
#[allow(clippy::too_many_arguments)]
pub fn levenberg_marquardt(
    f: &Residuals<'_>,
    x0: &[f64],
    lower: &[f64],
    upper: &[f64],
    typical: &[f64],
    options: &LmOptions,
    observer: &dyn Observer,
) -> Option<LmOutcome> {
    levenberg_marquardt_from(f, x0, lower, upper, typical, options, observer, None)
}

/// As [`levenberg_marquardt`], from the Jacobian `start` (residuals x variables) of a nearly
/// identical problem at `x0` where one is known, carried forward by secant updates
/// ([`LmOptions::secant_updates`]) from there.
#[allow(clippy::too_many_arguments)]
pub(crate) fn levenberg_marquardt_from(
    f: &Residuals<'_>,
    x0: &[f64],
    lower: &[f64],
    upper: &[f64],
    typical: &[f64],
    options: &LmOptions,
    observer: &dyn Observer,
    start: Option<DMatrix<f64>>,
) -> Option<LmOutcome> {
    let n = x0.len();
    let clamp = |x: &mut [f64]| {
        for ((v, lo), hi) in x.iter_mut().zip(lower).zip(upper) {
            *v = v.clamp(*lo, *hi);
        }
    };
    let mut x = x0.to_vec();
    clamp(&mut x);
    let mut r = Vec::new();
    if !f(&x, &mut r) {
        return None;
    }
    let sumsq = |r: &[f64]| r.iter().map(|e| e * e).sum::<f64>();
    let mut cost = sumsq(&r);
    let mut evaluations = 1;
    let mut history = vec![cost];
    let mut lambda = 1e-3;
    let mut iterations = 0;
    let mut jac = None;
    let secant = options.secant_updates || start.is_some();
    // The Jacobian for the next iteration when it is carried rather than recomputed.
    let mut carried = start.filter(|j| j.nrows() == r.len() && j.ncols() == n);
    let mut exact = true;
    // Residuals this small are rounding: nothing left to fit.
    let floor = 1e-26 * r.len() as f64;
    while iterations < options.max_iterations && cost > floor {
        iterations += 1;
        let j = match carried.take() {
            Some(j) => {
                exact = false;
                j
            }
            None => {
                let Some(j) = jacobian(f, &x, &r, lower, upper, typical, options.fd_step) else {
                    break;
                };
                evaluations += n;
                exact = true;
                j
            }
        };
        // Where the step starts, for the secant update.
        let before = secant.then(|| (x.clone(), DVector::from_column_slice(&r)));
        let jt = j.transpose();
        let h = &jt * &j;
        let g = &jt * DVector::from_column_slice(&r);
        let mut accepted = false;
        let mut gain = 0.0;
        let mut negligible = false;
        for _ in 0..12 {
            let mut a = h.clone();
            let mut damping = vec![0.0; n];
            for (k, d) in damping.iter_mut().enumerate() {
                *d = h[(k, k)].max(1e-300);
                a[(k, k)] += lambda * *d;
            }
            let Some(chol) = a.cholesky() else {
                lambda *= 10.0;
                continue;
            };
            let v = chol.solve(&(-&g));
            // Geodesic acceleration (Transtrum & Sethna 2012): the second-order correction
            // along `v` from one extra evaluation, which keeps the steps on the curved, narrow
            // valleys of sloppy models (poorly determined rest lengths and cosines) instead of
            // crawling across them.
            let mut step = v.clone();
            if options.geodesic_acceleration {
                let hh = 0.1;
                let xv: Vec<f64> = x.iter().zip(v.iter()).map(|(a, b)| a + hh * b).collect();
                let mut rv = Vec::with_capacity(r.len());
                evaluations += 1;
                if f(&xv, &mut rv) && rv.len() == r.len() {
                    let jv = &j * &v;
                    let rvv = DVector::from_iterator(
                        r.len(),
                        rv.iter()
                            .zip(&r)
                            .zip(jv.iter())
                            .map(|((p, q), jv)| (2.0 / hh) * ((p - q) / hh - jv)),
                    );
                    let acc = chol.solve(&(-(&jt * rvv)));
                    let norm =
                        |u: &DVector<f64>| u.iter().zip(&damping).map(|(a, d)| a * a * d).sum::<f64>().sqrt();
                    // A correction as large as the step itself is not a small curvature term
                    // (or is rounding noise, near an exact fit): take the plain step then.
                    if norm(&acc) <= 0.75 * norm(&v) {
                        step += acc * 0.5;
                    }
                }
            }
            let mut xn: Vec<f64> = x.iter().zip(step.iter()).map(|(a, b)| a + b).collect();
            clamp(&mut xn);
            let mut rn = Vec::with_capacity(r.len());
            evaluations += 1;
            if f(&xn, &mut rn) && rn.len() == r.len() {
                let cn = sumsq(&rn);
                if cn < cost {
                    gain = (cost - cn) / cost;
                    negligible =
                        xn.iter().zip(&x).zip(typical).all(|((a, b), t)| {
                            (a - b).abs() <= options.step_tolerance * b.abs().max(t.abs())
                        });
                    x = xn;
                    r = rn;
                    cost = cn;
                    lambda = (lambda / 3.0).max(1e-15);
                    accepted = true;
                    break;
                }
            }
            lambda *= 4.0;
        }
        if !accepted && !exact {
            // The carried Jacobian has gone stale: recompute it here and try again.
            continue;
        }
        history.push(cost);
        observer.observe(iterations, cost);
        let converged = gain < options.tolerance || negligible;
        if !exact && options.confirm_convergence && converged {
            // Converged as far as the carried Jacobian can tell: confirm with a recomputed one.
            continue;
        }
        if !accepted || converged {
            jac = Some(j);
            break;
        }
        if let Some((x_before, r_before)) = before {
            // Broyden: the rank-one change of J that makes it map this step onto the change
            // of the residuals it caused.
            let mut j = j;
            let step = DVector::from_iterator(n, x.iter().zip(&x_before).map(|(a, b)| a - b));
            let ss = step.norm_squared();
            if ss > 0.0 {
                let miss = DVector::from_column_slice(&r) - r_before - &j * &step;
                j.ger(1.0 / ss, &miss, &step, 1.0);
            }
            carried = Some(j);
        }
    }
    let jacobian = match (jac, carried) {
        (Some(j), _) => j,
        (None, Some(c)) => {
            exact = false;
            c
        }
        (None, None) => {
            evaluations += n;
            exact = true;
            jacobian(f, &x, &r, lower, upper, typical, options.fd_step)
                .unwrap_or_else(|| DMatrix::zeros(r.len(), n))
        }
    };
    Some(LmOutcome {
        x,
        residuals: r,
        jacobian,
        cost,
        history,
        iterations,
        evaluations,
        jacobian_exact: exact,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fits_an_exponential_within_bounds() {
        let ts: Vec<f64> = (0..30).map(|k| k as f64 * 0.1).collect();
        let f = |x: &[f64], out: &mut Vec<f64>| {
            out.clear();
            out.extend(
                ts.iter()
                    .map(|t| x[0] * (-x[1] * t).exp() - 3.0 * (-0.7 * t).exp()),
            );
            true
        };
        let o = levenberg_marquardt(
            &f,
            &[1.0, 0.1],
            &[0.0, 0.0],
            &[10.0, 10.0],
            &[1.0, 1.0],
            &LmOptions::default(),
            &(),
        )
        .unwrap();
        assert!(
            (o.x[0] - 3.0).abs() < 1e-8 && (o.x[1] - 0.7).abs() < 1e-8,
            "{:?}",
            o.x
        );
        // A bound that excludes the optimum is respected.
        let o = levenberg_marquardt(
            &f,
            &[1.0, 0.1],
            &[0.0, 0.0],
            &[2.0, 10.0],
            &[1.0, 1.0],
            &LmOptions::default(),
            &(),
        )
        .unwrap();
        assert!(o.x[0] <= 2.0 && o.x[0] > 1.9, "{:?}", o.x);
    }

    #[test]
    fn secant_updates_reach_the_same_optimum_with_fewer_evaluations() {
        // Three decaying exponentials' amplitudes and rates, from 20 % off, with a misfit.
        let ts: Vec<f64> = (0..80).map(|k| k as f64 * 0.05).collect();
        let truth = [1.0, 0.3, 2.0, 1.5, 3.0, 4.0];
        let model = |x: &[f64], t: f64| x.chunks(2).map(|p| p[0] * (-p[1] * t).exp()).sum::<f64>();
        let f = |x: &[f64], out: &mut Vec<f64>| {
            out.clear();
            out.extend(
                ts.iter()
                    .map(|&t| model(x, t) - model(&truth, t) + 0.01 * (7.0 * t).sin()),
            );
            true
        };
        let start: Vec<f64> = truth.iter().map(|v| v * 1.2).collect();
        let (lower, upper, typical) = (vec![0.0; 6], vec![20.0; 6], vec![1.0; 6]);
        let plain = LmOptions::default();
        let secant = LmOptions {
            secant_updates: true,
            ..LmOptions::default()
        };
        let a = levenberg_marquardt(&f, &start, &lower, &upper, &typical, &plain, &()).unwrap();
        let b = levenberg_marquardt(&f, &start, &lower, &upper, &typical, &secant, &()).unwrap();
        assert!(
            (b.cost - a.cost).abs() <= 1e-6 * a.cost,
            "costs {} (finite differences) and {} (secant)",
            a.cost,
            b.cost
        );
        assert!(b.jacobian_exact, "convergence is confirmed by finite differences");
        assert!(
            b.evaluations < a.evaluations,
            "{} evaluations with secant updates, {} without",
            b.evaluations,
            a.evaluations
        );
        // The returned Jacobian is the finite-difference one at the optimum.
        let fd = jacobian(&f, &b.x, &b.residuals, &lower, &upper, &typical, 1e-7).unwrap();
        assert!((&fd - &b.jacobian).abs().max() <= 1e-4 * fd.abs().max());
    }
}
