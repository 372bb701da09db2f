//! [`Uncertainty`]: standard errors, Cramer-Rao bounds and identifiability of a refined fit.
//!
//! At the optimum of the multi-step least squares the covariance of the estimate is
//! `sigma^2 (J^T J)^-1`, with `J` the Jacobian of the position residuals with respect to every
//! unknown (parameters *and* start state, so the start state's uncertainty is accounted for)
//! and `sigma` the position noise. Two noise levels are used:
//!
//! * the residual standard deviation `sqrt(SSR / (residuals - unknowns))`, which is what the fit
//!   itself says: this gives each parameter's **standard error**;
//! * the noise measured on the tracks (see [`crate::Observations::noise`]), independently of the
//!   model: this gives the **Cramer-Rao bound**, the smallest standard deviation any unbiased
//!   estimator could reach with that noise (for Gaussian noise the least-squares estimate
//!   reaches it).
//!
//! `J^T J` is decomposed after scaling its columns to unit norm. Directions with an eigenvalue
//! below [`NULL_EIGENVALUE`] of the largest are not identifiable from this motion: the
//! parameters with weight in them are named (for instance the stiffness of a spring that never
//! stretches, or the rest cosine of a torsion whose energy is flat). Parameters whose relative
//! standard error exceeds [`POORLY_DETERMINED`] are named as poorly determined.

use nalgebra::DMatrix;
use serde::Serialize;

use crate::{ParameterKind, Problem, Refinement};

/// Eigenvalue ratio (of the column-scaled `J^T J`) below which a direction is unidentifiable:
/// a singular value ratio of `1e-7`, where a forward-difference Jacobian stops being reliable.
pub(crate) const NULL_EIGENVALUE: f64 = 1e-14;

/// Relative standard error above which a parameter is reported as poorly determined.
pub(crate) const POORLY_DETERMINED: f64 = 0.25;

/// Uncertainty of every parameter of a refined fit.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Uncertainty {
    /// Residual standard deviation per coordinate, px.
    pub residual_sigma: f64,
    /// Track noise used for the Cramer-Rao bound, px.
    pub track_noise: f64,
    /// Standard error of each parameter (units of the parameter).
    pub std_errors: Vec<f64>,
    /// Cramer-Rao bound of each parameter's standard deviation at the track noise.
    pub cramer_rao: Vec<f64>,
    /// Singular values of the column-scaled Jacobian, largest first.
    pub singular_values: Vec<f64>,
    /// Indices of the parameters that the data cannot determine.
    pub unidentifiable: Vec<usize>,
    /// Indices of the parameters determined only to worse than a relative standard error of 0.25 (`POORLY_DETERMINED`).
    pub poorly_determined: Vec<usize>,
    /// One sentence per problem found, naming the bond as in the scene file.
    pub warnings: Vec<String>,
}

/// The uncertainty of `refinement`'s parameters, with `track_noise` (px) for the Cramer-Rao bound.
///
/// A refinement done in patches ([`crate::refine_in_patches`]) is judged patch by patch: each
/// parameter's standard error and bound come from the patch that decided it, the residual
/// standard deviation pools every patch's, and the singular values are all the patches'.
pub fn uncertainty(problem: &Problem, refinement: &Refinement, track_noise: f64) -> Uncertainty {
    if !refinement.patches.is_empty() {
        return patched_uncertainty(problem, refinement, track_noise);
    }
    let j = &refinement.jacobian;
    let (m, n) = (j.nrows(), j.ncols());
    let dim = problem.dimension();
    let ssr: f64 = refinement.residuals.iter().map(|r| r * r).sum();
    let residual_sigma = if m > n {
        (ssr / (m - n) as f64).sqrt()
    } else {
        f64::NAN
    };
    let norms: Vec<f64> = (0..n).map(|c| j.column(c).norm()).collect();
    let mut js = j.clone();
    for (c, &s) in norms.iter().enumerate() {
        if s > 0.0 {
            js.column_mut(c).scale_mut(1.0 / s);
        }
    }
    let h = js.transpose() * &js;
    let eig = h.symmetric_eigen();
    let lmax = eig.eigenvalues.iter().fold(0.0f64, |a, &b| a.max(b));
    let mut cov_unit = DMatrix::<f64>::zeros(n, n);
    let mut null_weight = vec![0.0; n];
    for (k, &l) in eig.eigenvalues.iter().enumerate() {
        let v = eig.eigenvectors.column(k);
        if l > NULL_EIGENVALUE * lmax {
            cov_unit += v * v.transpose() / l;
        } else {
            for (c, w) in null_weight.iter_mut().enumerate() {
                *w += v[c] * v[c];
            }
        }
    }
    let mut singular_values: Vec<f64> = eig.eigenvalues.iter().map(|l| l.max(0.0).sqrt()).collect();
    singular_values.sort_by(|a, b| b.total_cmp(a));
    let unit_sd: Vec<f64> = (0..dim)
        .map(|c| {
            if norms[c] > 0.0 {
                cov_unit[(c, c)].max(0.0).sqrt() / norms[c]
            } else {
                f64::INFINITY
            }
        })
        .collect();
    let std_errors: Vec<f64> = unit_sd.iter().map(|s| s * residual_sigma).collect();
    let cramer_rao: Vec<f64> = unit_sd.iter().map(|s| s * track_noise).collect();
    let flat: Vec<bool> = (0..dim)
        .map(|c| norms[c] == 0.0 || null_weight[c] > 0.5)
        .collect();
    let (unidentifiable, poorly_determined, warnings) =
        judge(problem, &refinement.params, &std_errors, &flat);
    Uncertainty {
        residual_sigma,
        track_noise,
        std_errors,
        cramer_rao,
        singular_values,
        unidentifiable,
        poorly_determined,
        warnings,
    }
}

/// [`uncertainty`] of a refinement done in patches.
fn patched_uncertainty(problem: &Problem, refinement: &Refinement, track_noise: f64) -> Uncertainty {
    let dim = problem.dimension();
    let mut std_errors = vec![f64::INFINITY; dim];
    let mut cramer_rao = vec![f64::INFINITY; dim];
    let mut flat = vec![false; dim];
    let mut singular_values: Vec<f64> = Vec::new();
    let (mut ssr, mut dof) = (0.0, 0usize);
    for part in &refinement.patches {
        let u = uncertainty(&part.problem, &part.refinement, track_noise);
        let r = &part.refinement;
        ssr += r.residuals.iter().map(|e| e * e).sum::<f64>();
        dof += r.residuals.len().saturating_sub(r.jacobian.ncols());
        singular_values.extend(&u.singular_values);
        for &(i, g) in &part.owned {
            std_errors[g] = u.std_errors[i];
            cramer_rao[g] = u.cramer_rao[i];
            flat[g] = u.unidentifiable.contains(&i);
        }
    }
    singular_values.sort_by(|a, b| b.total_cmp(a));
    let (unidentifiable, poorly_determined, warnings) =
        judge(problem, &refinement.params, &std_errors, &flat);
    Uncertainty {
        residual_sigma: if dof > 0 {
            (ssr / dof as f64).sqrt()
        } else {
            f64::NAN
        },
        track_noise,
        std_errors,
        cramer_rao,
        singular_values,
        unidentifiable,
        poorly_determined,
        warnings,
    }
}

/// The parameters the data cannot determine (`flat[c]`: no weight outside the null directions
/// of `J^T J`) and those determined only to worse than `POORLY_DETERMINED` (0.25) relative standard
/// error, with one sentence each naming the bond as in the scene file.
fn judge(
    problem: &Problem,
    params: &[f64],
    std_errors: &[f64],
    flat: &[bool],
) -> (Vec<usize>, Vec<usize>, Vec<String>) {
    let mut unidentifiable = Vec::new();
    let mut poorly_determined = Vec::new();
    let mut warnings = Vec::new();
    for c in 0..problem.dimension() {
        let value = params[c];
        let label = problem.parameter_label(c);
        let kind = problem.layout.parameters[c].kind;
        let why = match kind {
            ParameterKind::SpringStiffness => {
                "the spring's length hardly changes, so its force does not reveal its stiffness"
            }
            ParameterKind::RestLength => {
                "the spring's force is too weak or its length too steady to locate its rest length"
            }
            ParameterKind::TorsionStiffness => {
                "the torsion's angle hardly changes, so its stiffness is not revealed"
            }
            ParameterKind::RestCos => {
                "the torsion's energy is flat (too weak, or the angle too steady) to locate its rest angle"
            }
        };
        if flat[c] {
            unidentifiable.push(c);
            warnings.push(format!("{label} is not identifiable from this motion: {why}"));
        } else {
            let rel = std_errors[c] / value.abs().max(f64::MIN_POSITIVE);
            if rel > POORLY_DETERMINED {
                poorly_determined.push(c);
                warnings.push(format!(
                    "{label} = {value:.4e} is poorly determined (standard error {:.0}% of the value): {why}",
                    rel * 100.0
                ));
            }
        }
    }
    (unidentifiable, poorly_determined, warnings)
}

/// A rest angle in degrees from a rest cosine, with the standard error of the angle from that
/// of the cosine (`d theta = d M / sin theta`).
pub fn rest_angle_degrees(rest_cos: f64, cos_std_error: f64) -> (f64, f64) {
    let m = rest_cos.clamp(-1.0, 1.0);
    let angle = m.acos().to_degrees();
    let s = (1.0 - m * m).sqrt();
    // Near 0 or 180 degrees the cosine is flat in the angle: dM = theta^2 / 2.
    let err = if s > 1e-6 {
        (cos_std_error / s).to_degrees()
    } else {
        (2.0 * cos_std_error).sqrt().to_degrees()
    };
    (angle, err)
}
