//! Multi-step ("shooting") fits of a model [`Family`] to the tracks: simulate from a start
//! state at the anchor frame forward over the analysed frames and compare positions, with
//! the bond values, the effects' parameters and the start state all fitted by
//! Levenberg-Marquardt ([`crate::levenberg_marquardt`]).
//!
//! Unlike [`crate::MultiStepCost`], the simulation only runs forward (drag, dashpots and
//! walls are not time-reversible), and a frame mask selects which frames' residuals count, so
//! that frames held out of a fit are still simulated through but not fitted. As in
//! [`crate::refine`], the span is grown progressively (three typical periods, then doubled)
//! because long shots have narrow basins.

use nalgebra::DMatrix;
use physfit_model::{step_frame, IntegrationParameters, State, StepScratch, Vec2};

use super::family::{DataScales, Family};
use crate::{levenberg_marquardt, IdentifyError, LmOptions, Observations, Observer};

/// Simulation against the tracks over a frame mask.
#[derive(Clone, Debug)]
pub struct Shot<'a> {
    /// The observations compared against.
    pub obs: &'a Observations,
    /// Offset of the anchor frame (first completely tracked frame).
    pub anchor: usize,
    /// `mask[k]`: frame offset `k`'s residuals count.
    pub mask: Vec<bool>,
    /// The structure's time stepping.
    pub stepping: IntegrationParameters,
}

/// A fitted model and start state.
#[derive(Clone, Debug)]
pub struct ShotFit {
    /// Bond then effect parameters.
    pub params: Vec<f64>,
    /// Fitted state of the structure's particles at the anchor.
    pub state: State,
    /// Sum of squared position residuals over the masked frames, px².
    pub sum_squares: f64,
    /// Number of residuals (coordinates).
    pub residual_count: usize,
    /// Jacobian of the residuals over parameters then start state.
    pub jacobian: DMatrix<f64>,
    /// Levenberg-Marquardt iterations run.
    pub iterations: usize,
}

impl<'a> Shot<'a> {
    /// A shot over `obs` with the frames of `mask` fitted (all frames when `None`).
    pub fn new(
        obs: &'a Observations,
        family: &Family,
        mask: Option<Vec<bool>>,
    ) -> Result<Shot<'a>, IdentifyError> {
        let anchor =
            (0..obs.frame_count())
                .find(|&k| obs.is_complete(k))
                .ok_or(IdentifyError::TooFewFrames {
                    method: "the diagnosis".into(),
                    need: 1,
                    have: 0,
                })?;
        Ok(Shot {
            obs,
            anchor,
            mask: mask.unwrap_or_else(|| vec![true; obs.frame_count()]),
            stepping: family.structure.integration_parameters(),
        })
    }

    /// The observed state at the anchor, with every pinned particle at the mean of its
    /// tracked positions (a pinned particle does not move: averaging removes its track noise).
    pub fn observed_state(&self) -> State {
        let mut s = self.obs.state(self.anchor).unwrap_or_default();
        for (p, x) in s.positions.iter_mut().enumerate() {
            if self.obs.fixed.get(p).copied().unwrap_or(false) {
                let tracked: Vec<Vec2> = self.obs.positions.iter().filter_map(|f| f[p]).collect();
                if !tracked.is_empty() {
                    *x = tracked.iter().sum::<Vec2>() / tracked.len() as f64;
                }
            }
        }
        s
    }

    /// As [`Shot::simulate_from`], from the anchor.
    fn simulate(
        &self,
        family: &Family,
        params: &[f64],
        initial: &State,
        end: usize,
        visit: impl FnMut(usize, &[Vec2]) -> bool,
    ) -> bool {
        self.simulate_from(family, params, initial, self.anchor, end, visit)
    }

    /// Simulates `family` at `params` from `initial` at frame offset `from` up to offset `end`
    /// (exclusive), calling `visit(offset, positions)` at each frame; false if it stops.
    pub fn simulate_from(
        &self,
        family: &Family,
        params: &[f64],
        initial: &State,
        from: usize,
        end: usize,
        mut visit: impl FnMut(usize, &[Vec2]) -> bool,
    ) -> bool {
        let mut state = initial.clone();
        let model = family.model(params, Some(&mut state));
        let mut scratch = StepScratch::new(state.len());
        for k in from..end.min(self.obs.frame_count()) {
            if k > from {
                step_frame(&model, &self.stepping, &mut state, &mut scratch);
            }
            if !visit(k, &state.positions) {
                return false;
            }
        }
        true
    }

    /// Position residuals (predicted minus tracked, px) of the masked frames before `end`.
    pub fn residuals(
        &self,
        family: &Family,
        params: &[f64],
        initial: &State,
        end: usize,
        out: &mut Vec<f64>,
    ) -> bool {
        out.clear();
        let obs = self.obs;
        self.simulate(family, params, initial, end, |k, x| {
            if !self.mask[k] {
                return true;
            }
            for &p in &family.free {
                if let Some(o) = obs.positions[k][p] {
                    let e = x[p] - o;
                    if !(e.x.is_finite() && e.y.is_finite()) {
                        return false;
                    }
                    out.push(e.x);
                    out.push(e.y);
                }
            }
            true
        })
    }

    /// Predicted positions of the structure's particles at every frame offset from the anchor
    /// on (`None` before it); `None` if the simulation is not finite.
    pub fn trajectory(
        &self,
        family: &Family,
        params: &[f64],
        initial: &State,
    ) -> Option<Vec<Option<Vec<Vec2>>>> {
        let n = family.structure.particles.len();
        let mut out = vec![None; self.obs.frame_count()];
        let ok = self.simulate(family, params, initial, usize::MAX, |k, x| {
            out[k] = Some(x[..n].to_vec());
            x.iter().all(|v| v.x.is_finite() && v.y.is_finite())
        });
        ok.then_some(out)
    }

    /// Sum of squared residuals over the frames where `select[k]` (and the particle is
    /// tracked), with their count; infinite (count 0) if the simulation fails.
    pub fn cost_on(&self, family: &Family, params: &[f64], initial: &State, select: &[bool]) -> (f64, usize) {
        match self.frame_costs(family, params, initial) {
            Some(costs) => costs
                .iter()
                .zip(select)
                .filter(|(_, &s)| s)
                .fold((0.0, 0), |(sum, count), (c, _)| (sum + c.0, count + c.1)),
            None => (f64::INFINITY, 0),
        }
    }

    /// Per frame offset: the sum of squared position residuals of the free tracked particles,
    /// px², and their number of coordinates (zero before the anchor); `None` if the simulation
    /// is not finite.
    pub fn frame_costs(&self, family: &Family, params: &[f64], initial: &State) -> Option<Vec<(f64, usize)>> {
        let obs = self.obs;
        let mut out = vec![(0.0, 0); obs.frame_count()];
        let ok = self.simulate(family, params, initial, usize::MAX, |k, x| {
            for &p in &family.free {
                if let Some(o) = obs.positions[k][p] {
                    let e = (x[p] - o).norm_squared();
                    if !e.is_finite() {
                        return false;
                    }
                    out[k].0 += e;
                    out[k].1 += 2;
                }
            }
            true
        });
        ok.then_some(out)
    }
}

/// Fits parameters and start state by Levenberg-Marquardt, over progressively longer spans
/// from a cold start (`warm` false: a start that may be far off), over the whole window at
/// once from a warm one (a previous fit's values). Returns `None` if the model cannot be
/// simulated from the start.
#[allow(clippy::too_many_arguments)]
pub fn fit_shot(
    shot: &Shot<'_>,
    family: &Family,
    params0: &[f64],
    state0: &State,
    scales: &DataScales,
    max_iterations: usize,
    warm: bool,
    observer: &dyn Observer,
) -> Option<ShotFit> {
    fit_spans(
        shot,
        family,
        params0,
        state0,
        scales,
        max_iterations,
        false,
        warm,
        observer,
    )
}

/// Fits only the start state for fixed `params` (how a given model is judged fairly), cold
/// or warm as [`fit_shot`].
pub fn fit_state(
    shot: &Shot<'_>,
    family: &Family,
    params: &[f64],
    state0: &State,
    scales: &DataScales,
    warm: bool,
) -> Option<ShotFit> {
    fit_spans(shot, family, params, state0, scales, 30, true, warm, &())
}

#[allow(clippy::too_many_arguments)]
fn fit_spans(
    shot: &Shot<'_>,
    family: &Family,
    params0: &[f64],
    state0: &State,
    scales: &DataScales,
    max_iterations: usize,
    state_only: bool,
    warm: bool,
    observer: &dyn Observer,
) -> Option<ShotFit> {
    let frames = shot.obs.frame_count();
    let remaining = frames - shot.anchor;
    let period = std::f64::consts::TAU / scales.omega.max(1e-9) * shot.obs.fps;
    // Spans start at three periods (at least 20 frames), never beyond the recording.
    let mut span = ((3.0 * period).ceil() as usize).max(20).min(remaining.max(1));
    let mut spans = Vec::new();
    if warm {
        span = remaining;
    }
    loop {
        spans.push(span);
        if span >= remaining {
            break;
        }
        span = (span * 2).min(remaining);
    }
    let (mut lower, mut upper) = family.bounds();
    let mut typical = family.typical(scales);
    let nf = family.free.len();
    lower.resize(family.dim() + 4 * nf, f64::NEG_INFINITY);
    upper.resize(family.dim() + 4 * nf, f64::INFINITY);
    typical.extend(std::iter::repeat(1.0).take(2 * nf));
    typical.extend(std::iter::repeat(shot.obs.fps).take(2 * nf));
    let skip = if state_only { family.dim() } else { 0 };
    let (lower, upper, typical) = (&lower[skip..], &upper[skip..], &typical[skip..]);
    let lm = LmOptions {
        max_iterations,
        ..LmOptions::default()
    };
    let params0: Vec<f64> = params0.to_vec();
    let mut z = family.pack(&params0, state0)[skip..].to_vec();
    for (k, v) in z.iter_mut().enumerate() {
        *v = v.clamp(lower[k], upper[k]);
    }
    let full = |z: &[f64]| -> Vec<f64> {
        if state_only {
            let mut all = params0.clone();
            all.extend_from_slice(z);
            all
        } else {
            z.to_vec()
        }
    };
    let mut last = None;
    let mut iterations = 0;
    for &span in &spans {
        let end = shot.anchor + span;
        let f = |z: &[f64], out: &mut Vec<f64>| {
            let (p, s) = family.unpack(&full(z), state0);
            shot.residuals(family, &p, &s, end, out)
        };
        let outcome = levenberg_marquardt(&f, &z, lower, upper, typical, &lm, observer)?;
        iterations += outcome.iterations;
        z = outcome.x.clone();
        last = Some(outcome);
    }
    let outcome = last?;
    let (params, state) = family.unpack(&full(&z), state0);
    Some(ShotFit {
        params,
        state,
        sum_squares: outcome.cost,
        residual_count: outcome.residuals.len(),
        jacobian: outcome.jacobian,
        iterations,
    })
}
