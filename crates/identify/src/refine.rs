//! The fast exact solver, stage 2: refinement of every parameter *and* the start state by
//! Levenberg-Marquardt on the multi-step position residuals (multiple shooting reduced to one
//! shot over the analysed window).
//!
//! The unknowns are the bond parameters, the positions and the velocities of the free particles
//! at the anchor frame (the first completely tracked frame). The residuals are the differences
//! between simulated and tracked positions at every frame (px), simulated with the structure's
//! substeps and integrator, so the estimate is unbiased whatever the frame rate and, for
//! Gaussian track noise, is the maximum-likelihood estimate: it reaches the Cramer-Rao bound,
//! which windows restarted from noisy observed states do not.
//!
//! Three things keep the shot in the right valley:
//! * long shots have narrow basins (a 1 % error in a frequency is a phase error that grows with
//!   every period), so the span is grown progressively: about three typical periods first,
//!   then doubled until it covers the window, each stage starting from the previous one;
//! * the stages work in *product coordinates* (`S L` and `T M` instead of `L` and `M`, in
//!   which forces are linear), where the self-stress directions of over-braced objects are
//!   straight instead of curved valleys; a last short polish in the natural coordinates gives
//!   the Jacobian for [`crate::uncertainty`];
//! * the Levenberg-Marquardt steps carry geodesic acceleration ([`crate::LmOptions`]).
//!
//! Measured on `paper8` (36 unknowns, 80 frames, 0.05 px noise, 40 noise draws): every draw
//! reaches a cost below that of the true parameters, and the RMS error of each parameter is
//! 0.8 to 1.3 times its Cramer-Rao bound.

use std::time::Instant;

use nalgebra::DMatrix;
use physfit_model::{State, Vec2};
use serde::Serialize;

use crate::{
    levenberg_marquardt, stiffness_scales, IdentifyError, LmOptions, MultiStepCost, MultiStepFit,
    Observations, Observer, ParameterKind, Problem,
};

/// Settings of [`refine`].
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RefineOptions {
    /// Most Levenberg-Marquardt iterations per span stage.
    pub max_iterations: usize,
    /// First span in typical oscillation periods.
    pub first_span_periods: f64,
    /// Factor by which each stage's span grows until it covers the window (> 1).
    pub span_growth: f64,
    /// Carry the Jacobian between iterations by secant updates ([`LmOptions::secant_updates`]);
    /// the final Jacobian is still taken by finite differences.
    pub secant_updates: bool,
    /// Unknowns (parameters plus four per free particle) above which `lsq` refines in
    /// patches ([`crate::refine_by_size`]). Default 400. The patch settings appear in a
    /// report's options only when they differ from their defaults.
    #[serde(skip_serializing_if = "is_default_patch_limit")]
    pub patch_limit: usize,
    /// Free particles per patch core. Default 8.
    #[serde(skip_serializing_if = "is_default_core_size")]
    pub core_size: usize,
    /// Passes over the patches (at least 1): the first drives each ring along its tracks,
    /// every later one along the paths the neighbouring patches simulated in the pass before
    /// (smooth, where the tracks carry their noise into the forces). On a 4 x 4 lattice at
    /// 0.05 px noise the RMS error in units of the whole-object fit's standard errors was 7.3
    /// after one pass, 3.9 after two, under 2.7 after three (the whole-object fit: 0.9).
    /// Default 3.
    #[serde(skip_serializing_if = "is_default_passes")]
    pub passes: usize,
}

/// Default of [`RefineOptions::patch_limit`].
const PATCH_LIMIT: usize = 400;
/// Default of [`RefineOptions::core_size`].
const CORE_SIZE: usize = 8;
/// Default of [`RefineOptions::passes`].
const PASSES: usize = 3;

fn is_default_patch_limit(v: &usize) -> bool {
    *v == PATCH_LIMIT
}

fn is_default_core_size(v: &usize) -> bool {
    *v == CORE_SIZE
}

fn is_default_passes(v: &usize) -> bool {
    *v == PASSES
}

impl Default for RefineOptions {
    fn default() -> Self {
        RefineOptions {
            max_iterations: 40,
            first_span_periods: 3.0,
            span_growth: 2.0,
            secant_updates: true,
            patch_limit: PATCH_LIMIT,
            core_size: CORE_SIZE,
            passes: PASSES,
        }
    }
}

/// The refined fit.
#[derive(Clone, Debug)]
pub struct Refinement {
    /// Refined parameter vector.
    pub params: Vec<f64>,
    /// Refined state at the anchor frame (positions px, velocities px/s).
    pub initial_state: State,
    /// Absolute index of the anchor frame.
    pub anchor_frame: usize,
    /// Jacobian of the residuals at the optimum: columns are the parameters, then the free
    /// particles' anchor positions (x, y each), then their anchor velocities.
    pub jacobian: DMatrix<f64>,
    /// Position residuals at the optimum, px.
    pub residuals: Vec<f64>,
    /// Multi-step cost at the optimum over the whole analysed window.
    pub fit: MultiStepFit,
    /// Cost (px²) after each iteration, all stages in order.
    pub history: Vec<f64>,
    /// Levenberg-Marquardt iterations over all stages.
    pub iteration_count: usize,
    /// Simulations run (Jacobian columns included).
    pub cost_count: usize,
    /// Spans (frames) of the successive stages.
    pub spans: Vec<usize>,
    /// Wall time, s.
    pub seconds: f64,
    /// For a refinement done patch by patch ([`crate::refine_in_patches`]): each patch's own
    /// refinement, whose Jacobians give the uncertainty (`jacobian` is then empty). Empty for
    /// a whole-object refinement.
    pub patches: Vec<crate::PatchRefinement>,
}

/// Packs parameters and a state into one vector (free particles only).
fn pack(params: &[f64], state: &State, free: &[usize]) -> Vec<f64> {
    let mut z = params.to_vec();
    for &p in free {
        z.extend([state.positions[p].x, state.positions[p].y]);
    }
    for &p in free {
        z.extend([state.velocities[p].x, state.velocities[p].y]);
    }
    z
}

/// Unpacks [`pack`]'s vector onto `template` (which holds the pinned particles' state).
fn unpack(z: &[f64], dim: usize, template: &State, free: &[usize]) -> (Vec<f64>, State) {
    let mut s = template.clone();
    let nf = free.len();
    for (k, &p) in free.iter().enumerate() {
        s.positions[p] = Vec2::new(z[dim + 2 * k], z[dim + 2 * k + 1]);
        s.velocities[p] = Vec2::new(z[dim + 2 * nf + 2 * k], z[dim + 2 * nf + 2 * k + 1]);
    }
    (z[..dim].to_vec(), s)
}

/// The *product coordinates* of the refinement: for a bond with both values unknown, the
/// rest length `L` is replaced by `S L` and the rest cosine `M` by `T M`. Forces are linear in
/// these at fixed positions, so the weakly determined directions of over-braced objects
/// (self-stresses, where rest lengths and cosines trade against each other) are straight lines
/// rather than the curved valleys they are in `(L, S)` and `(M, T)`, where Levenberg-Marquardt
/// crawls.
struct ProductCoordinates {
    /// `(rest index, stiffness index)` of each bond with both values unknown.
    pairs: Vec<(usize, usize)>,
}

impl ProductCoordinates {
    fn new(problem: &Problem) -> ProductCoordinates {
        let pairs = problem
            .layout
            .bonds
            .iter()
            .filter(|b| b.params.len() == 2)
            .filter_map(|b| {
                let kind = |i: usize| problem.layout.parameters[i].kind;
                let rest = b
                    .params
                    .iter()
                    .copied()
                    .find(|&i| matches!(kind(i), ParameterKind::RestLength | ParameterKind::RestCos))?;
                let stiff = b.params.iter().copied().find(|&i| i != rest)?;
                Some((rest, stiff))
            })
            .collect();
        ProductCoordinates { pairs }
    }

    fn products(&self, params: &[f64]) -> Vec<f64> {
        let mut t = params.to_vec();
        for &(r, s) in &self.pairs {
            t[r] = params[r] * params[s];
        }
        t
    }

    fn natural(&self, problem: &Problem, theta: &[f64]) -> Vec<f64> {
        let mut p = theta.to_vec();
        for &(r, s) in &self.pairs {
            let b = problem.layout.parameters[r].bounds;
            let stiff = theta[s].max(f64::MIN_POSITIVE);
            p[r] = (theta[r] / stiff).clamp(b[0], b[1]);
        }
        p
    }

    /// The Jacobian `j` of residuals in product coordinates (parameters, then state columns)
    /// as the Jacobian in natural coordinates at `params`: by the chain rule through
    /// `theta_r = p_r p_s`, column `r` is scaled by `p_s` and column `s` gains `p_r` times
    /// column `r`.
    fn jacobian_in_natural(&self, mut j: DMatrix<f64>, params: &[f64]) -> DMatrix<f64> {
        for &(r, s) in &self.pairs {
            let (rest, stiffness) = (params[r], params[s]);
            let dr = j.column(r).clone_owned();
            j.column_mut(s).axpy(rest, &dr, 1.0);
            j.column_mut(r).scale_mut(stiffness);
        }
        j
    }

    /// Bounds and typical magnitudes of the product coordinates.
    fn bounds(&self, problem: &Problem) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
        let ps = &problem.layout.parameters;
        let mut lower: Vec<f64> = ps.iter().map(|p| p.bounds[0]).collect();
        let mut upper: Vec<f64> = ps.iter().map(|p| p.bounds[1]).collect();
        let mut typical: Vec<f64> = ps.iter().map(|p| p.scale).collect();
        for &(r, s) in &self.pairs {
            let hi = ps[s].bounds[1] * ps[r].bounds[1].abs().max(ps[r].bounds[0].abs());
            lower[r] = if ps[r].kind == ParameterKind::RestCos {
                -hi
            } else {
                0.0
            };
            upper[r] = hi;
            typical[r] = ps[s].scale * ps[r].scale;
        }
        (lower, upper, typical)
    }
}

/// Refines `start` (and the observed anchor state) by Levenberg-Marquardt on the multi-step
/// residuals over `observations` (see the module doc).
pub fn refine(
    problem: &Problem,
    observations: &Observations,
    start: &[f64],
    options: &RefineOptions,
    observer: &dyn Observer,
) -> Result<Refinement, IdentifyError> {
    refine_with(
        problem,
        observations,
        start,
        None,
        true,
        options,
        observer,
        &|obs| MultiStepCost::new(problem.clone(), obs),
    )
}

/// Where a refinement of a nearly identical problem ended (the patches' later passes start
/// from the one before).
#[derive(Clone, Debug)]
pub(crate) struct WarmStart {
    /// The start state it found at the anchor.
    pub state: State,
    /// Its Jacobian there (natural coordinates), carried forward by secant updates.
    pub jacobian: DMatrix<f64>,
}

/// As [`refine`], with the multi-step cost of a span of observations made by `cost_for`.
/// From a `warm` start the span is not grown: only the last stage, in natural coordinates, is
/// run, from the warm start's Jacobian (secant updates, [`crate::LmOptions`]). Unless
/// `exact_jacobian`, the returned Jacobian may be a secant estimate.
#[allow(clippy::too_many_arguments)]
pub(crate) fn refine_with(
    problem: &Problem,
    observations: &Observations,
    start: &[f64],
    warm: Option<&WarmStart>,
    exact_jacobian: bool,
    options: &RefineOptions,
    observer: &dyn Observer,
    cost_for: &dyn Fn(&Observations) -> Result<MultiStepCost, IdentifyError>,
) -> Result<Refinement, IdentifyError> {
    let t0 = Instant::now();
    let full = cost_for(observations)?;
    let anchor = full.anchor();
    let anchor_frame = full.anchor_frame();
    let free = full.free_particles().to_vec();
    let dim = problem.dimension();
    let mut state = warm.map_or_else(|| full.observed_anchor_state(), |w| w.state.clone());
    let mut params = start.to_vec();
    problem.layout.clamp(&mut params);

    let omega = stiffness_scales(&problem.structure, observations).omega;
    let period = std::f64::consts::TAU / omega * observations.fps;
    let remaining = observations.frame_count() - anchor;
    let mut span = ((options.first_span_periods * period).ceil() as usize)
        .max(20)
        .min(remaining);
    // The stages in product coordinates (none from a warm start); the polish covers the window.
    let mut stages = Vec::new();
    while warm.is_none() {
        // A stage nearly as long as the window is no easier than the window itself.
        if 4 * span >= 3 * remaining {
            stages.push(remaining);
            break;
        }
        stages.push(span);
        let grown = (span as f64 * options.span_growth.max(1.1)).ceil() as usize;
        span = grown.max(span + 1).min(remaining);
    }

    let coords = ProductCoordinates::new(problem);
    let (mut lower, mut upper, mut typical) = coords.bounds(problem);
    let fps = observations.fps;
    lower.resize(dim + 4 * free.len(), f64::NEG_INFINITY);
    upper.resize(dim + 4 * free.len(), f64::INFINITY);
    typical.extend(std::iter::repeat(1.0).take(2 * free.len()));
    typical.extend(std::iter::repeat(fps).take(2 * free.len()));
    let mut natural_lower: Vec<f64> = problem.layout.parameters.iter().map(|p| p.bounds[0]).collect();
    let mut natural_upper: Vec<f64> = problem.layout.parameters.iter().map(|p| p.bounds[1]).collect();
    let mut natural_typical: Vec<f64> = problem.layout.parameters.iter().map(|p| p.scale).collect();
    natural_lower.extend_from_slice(&lower[dim..]);
    natural_upper.extend_from_slice(&upper[dim..]);
    natural_typical.extend_from_slice(&typical[dim..]);
    // The product-coordinate stages need not confirm their convergence: the polish does,
    // when an exact Jacobian is asked for.
    let lm = LmOptions {
        max_iterations: options.max_iterations,
        secant_updates: options.secant_updates,
        confirm_convergence: false,
        ..LmOptions::default()
    };

    let mut history = Vec::new();
    let mut iteration_count = 0;
    let mut cost_count = 0;
    // The Jacobian the polish starts from: the warm start's, or the last product-coordinate
    // stage's in natural coordinates. (Never taken as the final one: a null direction, such
    // as the stiffness of a spring that never stretches, is exactly null only in a Jacobian
    // differenced in natural coordinates.)
    let mut handed: Option<DMatrix<f64>> = warm.map(|w| w.jacobian.clone());
    for (stage, &span) in stages.iter().enumerate() {
        let is_last = stage + 1 == stages.len();
        let cost = if is_last {
            full.clone()
        } else {
            let first = anchor_frame;
            let obs = observations.restrict(first, first + span - 1)?;
            cost_for(&obs)?
        };
        let template = state.clone();
        let f = |z: &[f64], out: &mut Vec<f64>| {
            let (theta, s) = unpack(z, dim, &template, &free);
            cost.residuals(&coords.natural(problem, &theta), &s, out)
        };
        let z0 = pack(&coords.products(&params), &state, &free);
        let outcome =
            levenberg_marquardt(&f, &z0, &lower, &upper, &typical, &lm, observer).ok_or_else(|| {
                IdentifyError::NoFiniteCost {
                    method: "lsq refinement".into(),
                    detail: format!(
                        "the simulation from the linear estimate is not finite over frames {}..{}",
                        anchor_frame,
                        anchor_frame + span
                    ),
                }
            })?;
        history.extend(outcome.history.iter().skip(usize::from(stage > 0)));
        iteration_count += outcome.iterations;
        cost_count += outcome.evaluations;
        let (theta, s) = unpack(&outcome.x, dim, &template, &free);
        params = coords.natural(problem, &theta);
        state = s;
        if is_last && options.secant_updates {
            handed = Some(coords.jacobian_in_natural(outcome.jacobian, &params));
        }
    }
    // A last polish in the natural coordinates gives the Jacobian the uncertainty needs.
    let template = state.clone();
    let f = |z: &[f64], out: &mut Vec<f64>| {
        let (p, s) = unpack(z, dim, &template, &free);
        full.residuals(&p, &s, out)
    };
    let z0 = pack(&params, &state, &free);
    let polish = LmOptions {
        max_iterations: 10,
        confirm_convergence: exact_jacobian,
        ..lm.clone()
    };
    let bounds = (&natural_lower[..], &natural_upper[..], &natural_typical[..]);
    let outcome =
        crate::lm::levenberg_marquardt_from(&f, &z0, bounds.0, bounds.1, bounds.2, &polish, observer, handed);
    let mut outcome = outcome.ok_or_else(|| IdentifyError::NoFiniteCost {
        method: "lsq refinement".into(),
        detail: "the refined model's simulation is not finite".into(),
    })?;
    history.extend(outcome.history.iter().skip(1));
    iteration_count += outcome.iterations;
    cost_count += outcome.evaluations;
    if !outcome.jacobian_exact && exact_jacobian {
        if let Some(j) = crate::jacobian(
            &f,
            &outcome.x,
            &outcome.residuals,
            bounds.0,
            bounds.1,
            bounds.2,
            polish.fd_step,
        ) {
            outcome.jacobian = j;
            cost_count += outcome.x.len();
        }
    }
    let (p, s) = unpack(&outcome.x, dim, &template, &free);
    params = p;
    state = s;
    let fit = full.evaluate_from(&params, &state);
    Ok(Refinement {
        params,
        initial_state: state,
        anchor_frame,
        jacobian: outcome.jacobian,
        residuals: outcome.residuals,
        fit,
        history,
        iteration_count,
        cost_count,
        spans: if stages.is_empty() {
            vec![remaining]
        } else {
            stages
        },
        seconds: t0.elapsed().as_secs_f64(),
        patches: Vec::new(),
    })
}

/// Fits only the start state (positions and velocities of the free particles at the anchor)
/// for fixed parameters `params`, by Levenberg-Marquardt on the multi-step residuals over
/// `observations`; returns it as a [`Refinement`] whose Jacobian covers parameters and state
/// (for [`crate::uncertainty`]). This is how a model found by another solver is judged fairly:
/// simulated from the start state that suits it best rather than from a noisy observed one.
///
/// This is the whole-object fit; [`crate::fit_start_state_by_size`] works patch by patch on
/// large structures.
pub fn fit_start_state(
    problem: &Problem,
    observations: &Observations,
    params: &[f64],
    options: &RefineOptions,
) -> Result<Refinement, IdentifyError> {
    fit_start_state_with(problem, observations, params, None, options, &|obs| {
        MultiStepCost::new(problem.clone(), obs)
    })
}

/// As [`fit_start_state`], with the multi-step cost made by `cost_for`, from the `warm`
/// start state where given (else the observed one).
pub(crate) fn fit_start_state_with(
    problem: &Problem,
    observations: &Observations,
    params: &[f64],
    warm: Option<&State>,
    options: &RefineOptions,
    cost_for: &dyn Fn(&Observations) -> Result<MultiStepCost, IdentifyError>,
) -> Result<Refinement, IdentifyError> {
    let t0 = Instant::now();
    let full = cost_for(observations)?;
    let free = full.free_particles().to_vec();
    let dim = problem.dimension();
    let template = warm.cloned().unwrap_or_else(|| full.observed_anchor_state());
    let fps = observations.fps;
    let nf = free.len();
    let mut typical = vec![1.0; 2 * nf];
    typical.extend(std::iter::repeat(fps).take(2 * nf));
    let lower = vec![f64::NEG_INFINITY; 4 * nf];
    let upper = vec![f64::INFINITY; 4 * nf];
    let state_only = |z: &[f64], out: &mut Vec<f64>| {
        let mut all = params.to_vec();
        all.extend_from_slice(z);
        let (p, s) = unpack(&all, dim, &template, &free);
        full.residuals(&p, &s, out)
    };
    let z0 = pack(&[], &template, &free);
    // Its Jacobian is not the one returned (that one covers the parameters too, below).
    let lm = LmOptions {
        max_iterations: options.max_iterations,
        secant_updates: options.secant_updates,
        confirm_convergence: true,
        ..LmOptions::default()
    };
    let outcome =
        levenberg_marquardt(&state_only, &z0, &lower, &upper, &typical, &lm, &()).ok_or_else(|| {
            IdentifyError::NoFiniteCost {
                method: "start-state fit".into(),
                detail: "the model's simulation from the observed state is not finite".into(),
            }
        })?;
    let mut z = params.to_vec();
    z.extend_from_slice(&outcome.x);
    let (p, state) = unpack(&z, dim, &template, &free);
    let all = |z: &[f64], out: &mut Vec<f64>| {
        let (p, s) = unpack(z, dim, &template, &free);
        full.residuals(&p, &s, out)
    };
    let mut lower_all: Vec<f64> = problem.layout.parameters.iter().map(|p| p.bounds[0]).collect();
    let mut upper_all: Vec<f64> = problem.layout.parameters.iter().map(|p| p.bounds[1]).collect();
    let mut typical_all: Vec<f64> = problem.layout.parameters.iter().map(|p| p.scale).collect();
    lower_all.extend(lower);
    upper_all.extend(upper);
    typical_all.extend(typical);
    let jacobian = crate::jacobian(
        &all,
        &z,
        &outcome.residuals,
        &lower_all,
        &upper_all,
        &typical_all,
        lm.fd_step,
    )
    .unwrap_or_else(|| DMatrix::zeros(outcome.residuals.len(), z.len()));
    let fit = full.evaluate_from(&p, &state);
    Ok(Refinement {
        params: p,
        initial_state: state,
        anchor_frame: full.anchor_frame(),
        jacobian,
        residuals: outcome.residuals,
        fit,
        history: outcome.history,
        iteration_count: outcome.iterations,
        cost_count: outcome.evaluations + z.len(),
        spans: vec![observations.frame_count() - full.anchor()],
        seconds: t0.elapsed().as_secs_f64(),
        patches: Vec::new(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::linear_estimate;
    use crate::testutil::{max_relative_error, paper3, paper5, record, Timing};

    #[test]
    fn linear_stage_plus_refinement_is_exact_on_exact_data() {
        for truth in [paper3(Timing::default()), paper5(Timing::default())] {
            let rec = record(&truth);
            // Velocities from the positions alone, as from real tracks.
            let obs = Observations::from_positions(
                truth.particles.iter().map(|p| p.id.clone()).collect(),
                vec![false; truth.particles.len()],
                truth.recording.fps,
                0,
                (0..rec.frame_count())
                    .map(|k| rec.frame(k).iter().map(|&x| Some(x)).collect())
                    .collect(),
            );
            let problem = Problem::new(&truth.structure(), &obs).unwrap();
            let est = linear_estimate(&problem, &obs, None).unwrap();
            let r = refine(&problem, &obs, &est.params, &RefineOptions::default(), &()).unwrap();
            let x = problem.params_of(&truth).unwrap();
            let (err, i) = max_relative_error(&r.params, &x);
            assert!(
                err < 1e-3,
                "{}: {} off by {:.4}%",
                truth.name,
                problem.parameter_label(i),
                err * 100.0
            );
            assert!(r.fit.rms < 1e-6);
        }
    }
}
