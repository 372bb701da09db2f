//! The score (Lagrange multiplier) test of a candidate effect on the multi-step fit.
//!
//! At the current fit (residuals `r`, Jacobian `J` over every fitted unknown, bond values,
//! accepted effects and start state), a candidate enters the forces linearly near zero
//! (a field, a drag or dashpot coefficient, a spring's `S` and `S L`), so its columns `C`
//! are finite differences of the residuals at a tiny value. Projected orthogonally to `J`
//! (`C' = C - J (J^T J)^+ J^T C`), one Gauss-Newton step with the term removes
//! `r^T C' (C'^T C')^-1 C'^T r` of the cost: divided by the noise variance this is the score
//! statistic, which for small effects equals the likelihood-ratio statistic without fitting.
//! It ranks candidates far more sharply than the weak form, because the multi-step residual
//! accumulates a small force's effect over the whole recording. The step itself is the
//! candidate's starting value. Terms bounded at zero (drag, dashpots, stiffness) score zero
//! when the step is negative.

use nalgebra::{DMatrix, DVector};
use physfit_model::Vec2;
use rayon::prelude::*;

use super::effect::{Effect, WeakShape};
use super::search::{Context, Current, Proposal};

/// Relative size of the finite-difference perturbation (times the parameter's typical value).
const FD_RELATIVE: f64 = 1e-5;

/// The projector data of the current fit.
struct Nuisance {
    /// Column-scaled Jacobian.
    js: DMatrix<f64>,
    /// Pseudo-inverse of `js^T js`.
    pinv: DMatrix<f64>,
    r: DVector<f64>,
}

fn nuisance(ctx: &Context<'_>, current: &Current) -> Option<Nuisance> {
    let mut r = Vec::new();
    if !ctx.shot.residuals(
        &current.family,
        &current.fit.params,
        &current.fit.state,
        usize::MAX,
        &mut r,
    ) {
        return None;
    }
    let j = &current.fit.jacobian;
    if j.nrows() != r.len() {
        return None;
    }
    let mut js = j.clone();
    for c in 0..js.ncols() {
        let n = js.column(c).norm();
        if n > 0.0 {
            js.column_mut(c).scale_mut(1.0 / n);
        }
    }
    let eig = (js.transpose() * &js).symmetric_eigen();
    let lmax = eig.eigenvalues.iter().fold(0.0f64, |a, &b| a.max(b));
    let n = js.ncols();
    let mut pinv = DMatrix::zeros(n, n);
    for (k, &l) in eig.eigenvalues.iter().enumerate() {
        if l > 1e-12 * lmax {
            let v = eig.eigenvectors.column(k);
            pinv += v * v.transpose() / l;
        }
    }
    Some(Nuisance {
        js,
        pinv,
        r: DVector::from_vec(r),
    })
}

/// Residual columns of `effect` (per unit of its linear parameters) at the current fit.
fn effect_columns(
    ctx: &Context<'_>,
    current: &Current,
    effect: Effect,
    anchor: Option<Vec2>,
    r0: &DVector<f64>,
) -> Option<Vec<DVector<f64>>> {
    let effects: Vec<Effect> = current.family.effects.iter().copied().chain([effect]).collect();
    let family = current.family.with_effects(effects);
    let typical = family.typical(ctx.scales);
    let o = family.effect_offset(family.effects.len() - 1);
    let eps: Vec<f64> = typical[o..].iter().map(|t| t * FD_RELATIVE).collect();
    let run = |values: &[f64]| -> Option<DVector<f64>> {
        let mut p = current.fit.params.clone();
        p.extend_from_slice(values);
        let mut r = Vec::new();
        ctx.shot
            .residuals(&family, &p, &current.fit.state, usize::MAX, &mut r)
            .then(|| DVector::from_vec(r))
    };
    let diff = |a: &DVector<f64>, b: &DVector<f64>, h: f64| (a - b) / h;
    let shape = effect.weak_shape()?;
    match shape {
        WeakShape::Field => {
            let h = eps[0];
            Some(vec![diff(&run(&[h, 0.0])?, r0, h), diff(&run(&[0.0, h])?, r0, h)])
        }
        WeakShape::Coefficient => {
            let h = eps[0];
            Some(vec![diff(&run(&[h])?, r0, h)])
        }
        WeakShape::Spring { .. } | WeakShape::Tether { .. } => {
            // Force 2 S d u - 2 (S L) u: at stiffness h, rest length 0 gives h times the `S`
            // column; rest length 1 minus rest length 0 gives h times the `S L` column.
            let h = *eps.last()?;
            let prefix: Vec<f64> = match shape {
                WeakShape::Tether { .. } => {
                    let a = anchor?;
                    vec![a.x, a.y]
                }
                _ => Vec::new(),
            };
            let with = |l: f64| {
                let mut v = prefix.clone();
                v.extend([l, h]);
                run(&v)
            };
            let r_l0 = with(0.0)?;
            let r_l1 = with(1.0)?;
            Some(vec![diff(&r_l0, r0, h), diff(&r_l1, &r_l0, h)])
        }
    }
}

/// Computes every proposal's score test (and replaces its starting values with the
/// Gauss-Newton step where the test ran).
pub fn score_tests(ctx: &Context<'_>, current: &Current, proposals: &mut [Proposal]) {
    let Some(nu) = nuisance(ctx, current) else { return };
    let variance = ctx.noise_variance(current);
    let results: Vec<Option<(f64, Vec<f64>)>> = proposals
        .par_iter()
        .map(|p| {
            let anchor = match p.effect {
                Effect::Tether { .. } => Some(Vec2::new(*p.init.first()?, *p.init.get(1)?)),
                _ => None,
            };
            let cols = effect_columns(ctx, current, p.effect, anchor, &nu.r)?;
            let c = DMatrix::from_columns(&cols);
            let jtc = nu.js.transpose() * &c;
            let ctc = c.transpose() * &c - jtc.transpose() * &nu.pinv * &jtc;
            let jtr = nu.js.transpose() * &nu.r;
            let ctr = c.transpose() * &nu.r - jtc.transpose() * &nu.pinv * &jtr;
            let step = -ctc.clone().pseudo_inverse(1e-12 * ctc.norm()).ok()? * &ctr;
            let gain = -(ctr.transpose() * &step)[(0, 0)];
            let mut score = (gain / variance).max(0.0);
            let values: Vec<f64> = match p.effect.weak_shape()? {
                WeakShape::Field => vec![step[0], step[1]],
                WeakShape::Coefficient => {
                    if step[0] < 0.0 {
                        score = 0.0;
                    }
                    vec![step[0].max(0.0)]
                }
                WeakShape::Spring { .. } | WeakShape::Tether { .. } => {
                    let (s, sl) = (step[0], step[1]);
                    if s <= 0.0 || sl / s <= 0.0 || !(sl / s).is_finite() {
                        score = 0.0;
                        p.init.clone()
                    } else {
                        let mut v: Vec<f64> = anchor.map_or_else(Vec::new, |a| vec![a.x, a.y]);
                        v.extend([sl / s, s]);
                        v
                    }
                }
            };
            Some((score, values))
        })
        .collect();
    for (p, res) in proposals.iter_mut().zip(results) {
        if let Some((score, values)) = res {
            p.score_test = Some(score);
            if score > 0.0 {
                p.init = values;
            }
        }
    }
}
