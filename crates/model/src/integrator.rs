//! Time integration: the paper's semi-implicit Euler and velocity Verlet, with substeps.
//!
//! A key design decision made in this module is that an integrator owns no model state: it
//! advances a [`State`] by one substep of a [`Model`], using a caller-owned scratch buffer, so
//! the same model can be stepped from many states in parallel (the identifier does this) with
//! no allocation on the hot path. Walls are applied after each substep, as singular events.

use crate::{Model, State, Vec2};
use serde::{Deserialize, Serialize};

/// Which integration scheme advances the model.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum IntegratorKind {
    /// The paper's semi-implicit (symplectic) Euler: `v += dt a(x, v); x += dt v`.
    Euler,
    /// Velocity Verlet (second order, symplectic for conservative forces).
    #[default]
    Verlet,
}

/// Time stepping settings of a recording.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IntegrationParameters {
    /// Time between frames, s (`1 / fps`).
    pub frame_dt: f64,
    /// Integration substeps per frame (at least 1).
    pub substeps: u32,
    /// The scheme.
    pub integrator: IntegratorKind,
}

impl IntegrationParameters {
    /// The substep length `frame_dt / substeps`, s.
    pub fn dt(&self) -> f64 {
        self.frame_dt / self.substeps.max(1) as f64
    }
}

/// Reusable buffers for stepping a model of a given size.
#[derive(Clone, Debug, Default)]
pub struct StepScratch {
    acc: Vec<Vec2>,
    acc_new: Vec<Vec2>,
    v_old: Vec<Vec2>,
    /// Acceleration at the current state, cached between Verlet substeps when valid.
    acc_valid: bool,
}

impl StepScratch {
    /// Scratch for `n` particles.
    pub fn new(n: usize) -> Self {
        StepScratch {
            acc: vec![Vec2::zeros(); n],
            acc_new: vec![Vec2::zeros(); n],
            v_old: vec![Vec2::zeros(); n],
            acc_valid: false,
        }
    }

    /// Marks the cached acceleration stale (call after changing the state or model by hand).
    pub fn invalidate(&mut self) {
        self.acc_valid = false;
    }
}

/// Advances `state` by one substep `dt` (s) with the chosen scheme.
pub fn step(model: &Model, kind: IntegratorKind, dt: f64, state: &mut State, scratch: &mut StepScratch) {
    let n = state.len();
    if scratch.acc.len() != n {
        *scratch = StepScratch::new(n);
    }
    match kind {
        IntegratorKind::Euler => {
            model.accelerations(state, &mut scratch.acc);
            for ((x, v), a) in state.positions.iter_mut().zip(state.velocities.iter_mut()).zip(&scratch.acc) {
                *v += a * dt;
                *x += *v * dt;
            }
            scratch.acc_valid = false;
        }
        IntegratorKind::Verlet => {
            if !scratch.acc_valid {
                model.accelerations(state, &mut scratch.acc);
            }
            scratch.v_old.copy_from_slice(&state.velocities);
            for ((x, v), a) in state.positions.iter_mut().zip(state.velocities.iter_mut()).zip(&scratch.acc) {
                *x += *v * dt + a * (0.5 * dt * dt);
                // Velocity predicted to first order: conservative forces do not read it, and
                // for drag and dashpots it keeps the scheme second-order accurate.
                *v += a * dt;
            }
            model.accelerations(state, &mut scratch.acc_new);
            for ((v, v0), (a0, a1)) in state
                .velocities
                .iter_mut()
                .zip(&scratch.v_old)
                .zip(scratch.acc.iter().zip(&scratch.acc_new))
            {
                *v = v0 + (a0 + a1) * (0.5 * dt);
            }
            std::mem::swap(&mut scratch.acc, &mut scratch.acc_new);
            // With velocity-dependent forces a(x, v_pred) is not a(x, v): recompute next time.
            scratch.acc_valid = !model.physics.has_dissipation();
        }
    }
    if model.apply_walls(state) > 0 {
        scratch.acc_valid = false;
    }
}

/// Advances `state` by one frame: `params.substeps` substeps of `params.dt()`.
pub fn step_frame(model: &Model, params: &IntegrationParameters, state: &mut State, scratch: &mut StepScratch) {
    let dt = params.dt();
    for _ in 0..params.substeps.max(1) {
        step(model, params.integrator, dt, state, scratch);
    }
}
