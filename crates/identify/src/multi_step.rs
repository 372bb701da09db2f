//! [`MultiStepCost`]: the multi-step ("external") cost that judges every fit.
//!
//! The model is simulated from one state (the *anchor*: by default the observed state at the
//! first completely tracked frame) forward to the last frame and backward to the first (by
//! reversing the velocities; the conservative integrators are time-reversible), with the
//! structure's substeps and integrator, and the predicted positions are compared with the
//! tracked ones:
//!
//! ```text
//! Cost = sum_frames sum_free particles |x_pred - x_obs|^2        (px^2)
//! RMS  = sqrt(Cost / number of compared coordinates)             (px)
//! ```
//!
//! This measures how well the model extrapolates the motion, which is what matters (MODEL.md
//! section 4, "external cost"). Unlike the one-step cost it is unbiased whatever the number of
//! substeps per frame; its only weakness is the start state: from a noisy observed state the
//! simulation drifts, which is why the least-squares refinement fits the start state too
//! ([`MultiStepCost::residuals`] takes it as an argument). With a *horizon* `h`, the simulation
//! is instead restarted from the observed state every `h` frames (windows of `h` frames).

use std::sync::Arc;

use physfit_model::{step_frame, step_frame_prescribed, IntegrationParameters, State, StepScratch, Vec2};
use serde::Serialize;

use crate::driven::{DrivenBoundary, SplinePath};

use crate::{CostFunction, IdentifyError, Observations, Problem};

/// Sum and RMS of the position errors of one simulation against the tracks.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct MultiStepFit {
    /// Sum of squared position errors, px².
    pub sum_squares: f64,
    /// Root mean square error per coordinate, px.
    pub rms: f64,
    /// Number of compared coordinates (two per tracked free particle per frame).
    pub residual_count: usize,
}

impl MultiStepFit {
    fn from_residuals(r: &[f64], ok: bool) -> MultiStepFit {
        if !ok {
            return MultiStepFit {
                sum_squares: f64::INFINITY,
                rms: f64::INFINITY,
                residual_count: r.len(),
            };
        }
        let sum_squares: f64 = r.iter().map(|e| e * e).sum();
        MultiStepFit {
            sum_squares,
            rms: (sum_squares / r.len().max(1) as f64).sqrt(),
            residual_count: r.len(),
        }
    }
}

/// The multi-step position cost over a span of frames (see the module doc).
#[derive(Clone, Debug)]
pub struct MultiStepCost {
    problem: Problem,
    stepping: IntegrationParameters,
    observations: Observations,
    anchor: usize,
    horizon: Option<usize>,
    free: Vec<usize>,
    /// Pinned particles driven along their tracks instead of held still (a cut boundary).
    driven: Option<Arc<DrivenBoundary>>,
}

impl MultiStepCost {
    /// The cost of simulating `problem`'s model against `observations`, anchored at the first
    /// completely tracked frame. Errors when no frame is completely tracked.
    pub fn new(problem: Problem, observations: &Observations) -> Result<MultiStepCost, IdentifyError> {
        let anchor = (0..observations.frame_count())
            .find(|&k| observations.is_complete(k))
            .ok_or_else(|| IdentifyError::TooFewFrames {
                method: "the multi-step cost".into(),
                need: 1,
                have: 0,
            })?;
        let free = (0..observations.particle_count())
            .filter(|&p| !observations.fixed[p])
            .collect();
        Ok(MultiStepCost {
            stepping: problem.integration_parameters(),
            problem,
            observations: observations.clone(),
            anchor,
            horizon: None,
            free,
            driven: None,
        })
    }

    /// The same cost with every pinned particle *driven* along a cubic spline through its
    /// tracked positions instead of held still: the boundary of a part cut out of a larger
    /// object ([`crate::refine_in_patches`]). Needs every pinned particle tracked in every frame.
    pub(crate) fn with_driven_pinned_particles(mut self) -> Result<MultiStepCost, IdentifyError> {
        let obs = &self.observations;
        let mut paths = Vec::new();
        for p in (0..obs.particle_count()).filter(|&p| obs.fixed[p]) {
            let points: Option<Vec<Vec2>> = obs.positions.iter().map(|f| f[p]).collect();
            let points = points.ok_or_else(|| IdentifyError::TooFewFrames {
                method: format!("driving particle {} along its track", obs.particle_ids[p]),
                need: obs.frame_count(),
                have: obs.positions.iter().filter(|f| f[p].is_some()).count(),
            })?;
            paths.push((p, SplinePath::new(points)));
        }
        let substeps = self.stepping.substeps.max(1) as usize;
        self.driven = Some(Arc::new(DrivenBoundary::new(&paths, obs.frame_count(), substeps)));
        Ok(self)
    }

    /// The same cost with the simulation restarted from the observed state every `frames`
    /// frames (at least 1) instead of run once from the anchor.
    pub fn with_horizon(mut self, frames: usize) -> MultiStepCost {
        self.horizon = Some(frames.max(1));
        self
    }

    /// The same cost anchored at offset `offset` (from the first observed frame; clamped to
    /// the last frame) instead of the first complete frame: for simulating from a fitted state.
    pub fn with_anchor(mut self, offset: usize) -> MultiStepCost {
        self.anchor = offset.min(self.observations.frame_count().saturating_sub(1));
        self
    }

    /// The problem.
    pub fn problem(&self) -> &Problem {
        &self.problem
    }

    /// The observations compared against.
    pub fn observations(&self) -> &Observations {
        &self.observations
    }

    /// Offset (from the first observed frame) of the anchor frame the simulation starts from.
    pub fn anchor(&self) -> usize {
        self.anchor
    }

    /// Absolute index of the anchor frame.
    pub fn anchor_frame(&self) -> usize {
        self.observations.first_frame + self.anchor
    }

    /// The observed state at the anchor (tracked positions, estimated velocities).
    pub fn observed_anchor_state(&self) -> State {
        self.observations.state(self.anchor).unwrap_or_default()
    }

    /// Indices of the free (not pinned) particles, whose positions are compared.
    pub fn free_particles(&self) -> &[usize] {
        &self.free
    }

    /// Number of residuals [`MultiStepCost::residuals`] writes.
    pub fn residual_count(&self) -> usize {
        let obs = &self.observations;
        (0..obs.frame_count())
            .map(|k| {
                self.free
                    .iter()
                    .filter(|&&p| obs.positions[k][p].is_some())
                    .count()
                    * 2
            })
            .sum()
    }

    /// Predicted positions at every observed frame (`[offset][particle]`, px), simulated from
    /// `initial` at the anchor forward and backward; `None` if the simulation stops being finite.
    pub fn trajectory(&self, params: &[f64], initial: &State) -> Option<Vec<Vec<Vec2>>> {
        let mut out = vec![Vec::new(); self.observations.frame_count()];
        let ok = self.simulate(params, initial, |k, x| {
            out[k] = x.to_vec();
            x.iter().all(|v| v.x.is_finite() && v.y.is_finite())
        });
        ok.then_some(out)
    }

    /// Writes the position residuals `x_pred - x_obs` (px; x then y, per tracked free particle,
    /// frames from the anchor forward, then backward) of a simulation from `initial` at the
    /// anchor into `out`. Returns false if and only if the simulation stopped being finite.
    pub fn residuals(&self, params: &[f64], initial: &State, out: &mut Vec<f64>) -> bool {
        out.clear();
        let obs = &self.observations;
        let free = &self.free;
        self.simulate(params, initial, |k, x| {
            for &p in free {
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

    /// Runs the simulation from `initial` at the anchor, calling `visit(offset, positions)` at
    /// each frame (forward from the anchor, then backward); stops early when `visit` says false.
    fn simulate(
        &self,
        params: &[f64],
        initial: &State,
        mut visit: impl FnMut(usize, &[Vec2]) -> bool,
    ) -> bool {
        let model = self.problem.model(params);
        let n = initial.len();
        let mut scratch = StepScratch::new(n);
        let mut state = initial.clone();
        let frames = self.observations.frame_count();
        // With a driven boundary, one frame is its substeps with the boundary prescribed at the
        // end of each (`direction` -1 runs backward in time with reversed velocities).
        let substeps = self.stepping.substeps.max(1) as usize;
        let advance = |state: &mut State, scratch: &mut StepScratch, from: usize, direction: f64| {
            let Some(paths) = &self.driven else {
                step_frame(&model, &self.stepping, state, scratch);
                return;
            };
            let scale = direction * self.observations.fps;
            step_frame_prescribed(&model, &self.stepping, state, scratch, &mut |s, st| {
                let i = if direction > 0.0 {
                    from * substeps + s as usize
                } else {
                    from * substeps - s as usize
                };
                for (p, x, v) in paths.at(i) {
                    st.positions[p] = x;
                    st.velocities[p] = v * scale;
                }
            });
        };
        for k in self.anchor..frames {
            if k > self.anchor {
                advance(&mut state, &mut scratch, k - 1, 1.0);
            }
            if !visit(k, &state.positions) {
                return false;
            }
        }
        if self.anchor > 0 {
            state = initial.clone();
            state.velocities.iter_mut().for_each(|v| *v = -*v);
            scratch.invalidate();
            for k in (0..self.anchor).rev() {
                advance(&mut state, &mut scratch, k + 1, -1.0);
                if !visit(k, &state.positions) {
                    return false;
                }
            }
        }
        true
    }

    /// The cost of a simulation from `initial` at the anchor.
    pub fn evaluate_from(&self, params: &[f64], initial: &State) -> MultiStepFit {
        let mut r = Vec::with_capacity(self.residual_count());
        let ok = self.residuals(params, initial, &mut r);
        MultiStepFit::from_residuals(&r, ok)
    }

    /// The cost from the observed anchor state, or, with a horizon, from the observed state at
    /// the start of each window (frames after the window starts are compared).
    pub fn evaluate(&self, params: &[f64]) -> MultiStepFit {
        let Some(h) = self.horizon else {
            return self.evaluate_from(params, &self.observed_anchor_state());
        };
        let obs = &self.observations;
        let model = self.problem.model(params);
        let mut scratch = StepScratch::new(obs.particle_count());
        let mut r = Vec::new();
        let mut start = self.anchor;
        while start + 1 < obs.frame_count() {
            let Some(mut state) = obs.state(start) else {
                start += 1;
                continue;
            };
            scratch.invalidate();
            let end = (start + h).min(obs.frame_count() - 1);
            for k in start + 1..=end {
                step_frame(&model, &self.stepping, &mut state, &mut scratch);
                for &p in &self.free {
                    if let Some(o) = obs.positions[k][p] {
                        let e = state.positions[p] - o;
                        if !(e.x.is_finite() && e.y.is_finite()) {
                            return MultiStepFit::from_residuals(&r, false);
                        }
                        r.push(e.x);
                        r.push(e.y);
                    }
                }
            }
            start = end;
        }
        MultiStepFit::from_residuals(&r, true)
    }
}

impl CostFunction for MultiStepCost {
    fn dimension(&self) -> usize {
        self.problem.dimension()
    }

    /// The sum of squared position errors (px²) of [`MultiStepCost::evaluate`].
    fn cost(&self, params: &[f64]) -> f64 {
        self.evaluate(params).sum_squares
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testutil::{paper3, record, Timing};

    #[test]
    fn zero_for_the_true_parameters_on_exact_data() {
        let truth = paper3(Timing::default());
        let obs = Observations::from_recording(&record(&truth), &truth, 0)
            .restrict(0, 99)
            .unwrap();
        let problem = Problem::new(&truth.structure(), &obs).unwrap();
        let x = problem.params_of(&truth).unwrap();
        // Anchored mid-sequence (a gap before it), so both directions are exercised.
        let mut gappy = obs.clone();
        gappy.positions[3][1] = None;
        gappy.velocities[3][1] = None;
        for k in 0..3 {
            gappy.velocities[k][0] = None;
        }
        let cost = MultiStepCost::new(problem.clone(), &gappy).unwrap();
        assert_eq!(cost.anchor(), 3 + 1);
        let fit = cost.evaluate(&x);
        assert!(fit.rms < 1e-9, "rms {} px", fit.rms);
        assert_eq!(fit.residual_count, 100 * 6 - 2);
        let mut y = x.clone();
        y[1] *= 1.05;
        assert!(cost.evaluate(&y).rms > 1e-3);
        let windows = MultiStepCost::new(problem, &obs).unwrap().with_horizon(10);
        assert!(windows.cost(&x) < 1e-15);
        assert!(windows.cost(&y) > 1e-6);
    }
}
