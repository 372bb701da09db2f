//! Time integration: the paper's semi-implicit Euler and velocity Verlet, with substeps.
//!
//! A key design decision made in this module is that an integrator owns no model state: it
//! advances a [`State`] by one substep of a [`Model`], using a caller-owned scratch buffer, so
//! the same model can be stepped from many states in parallel (the identifier does this) with
//! no allocation on the hot path. Ropes and rails are projected after each substep
//! ([`crate::constraint`]), the surface's dry friction is applied
//! ([`crate::Physics::apply_surface_friction`]), then walls are applied, as singular events.

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
    /// Positions at the start of the substep (used only by models with constraints).
    x_old: Vec<Vec2>,
    /// Each rail's normal velocity change over the substep (models with rails only).
    rail_dv: Vec<[f64; 2]>,
    /// True if and only if `acc` holds the acceleration at the current state (reused only
    /// between the substeps of one [`step_frame`] call, where nobody else touches the state).
    acc_valid: bool,
}

impl StepScratch {
    /// Scratch for `n` particles.
    pub fn new(n: usize) -> Self {
        StepScratch {
            acc: vec![Vec2::zeros(); n],
            acc_new: vec![Vec2::zeros(); n],
            v_old: vec![Vec2::zeros(); n],
            x_old: Vec::new(),
            rail_dv: Vec::new(),
            acc_valid: false,
        }
    }

    /// Marks the cached acceleration stale. [`step`] and [`step_frame`] never reuse an
    /// acceleration across calls, so callers need not call this; it is kept for code that did.
    pub fn invalidate(&mut self) {
        self.acc_valid = false;
    }
}

/// Advances `state` by one substep `dt` (s) with the chosen scheme, then applies the walls.
///
/// Fixed particles keep their position and get zero velocity. The scratch is only a buffer:
/// `state` and `model` may change freely between calls (as in one-step prediction from
/// observed states), and the result depends only on `model`, `kind`, `dt` and `state`.
/// No allocation unless `scratch` was sized for a different particle count.
pub fn step(model: &Model, kind: IntegratorKind, dt: f64, state: &mut State, scratch: &mut StepScratch) {
    scratch.acc_valid = false;
    step_substep(model, kind, dt, state, scratch, None);
}

/// As [`step`], with the motion of some particles *prescribed* instead of integrated (the
/// boundary of a part of an object cut out of a larger one, driven along its observed track).
///
/// The prescribed particles must be `fixed` in `model`, so that the scheme leaves them alone;
/// the caller sets their positions and velocities at the start of the substep. `prescribe`
/// must set them to their values at the end of the substep (`dt` later): it is called once the
/// free particles' positions have advanced, before the forces at the end of the substep are
/// evaluated (so Verlet sees the boundary where it will be), and again after the substep's
/// velocity update. The free particles then move exactly as they would next to a boundary
/// following that motion.
pub fn step_prescribed(
    model: &Model,
    kind: IntegratorKind,
    dt: f64,
    state: &mut State,
    scratch: &mut StepScratch,
    prescribe: &mut dyn FnMut(&mut State),
) {
    scratch.acc_valid = false;
    step_substep(model, kind, dt, state, scratch, Some(prescribe));
}

/// As [`step_frame`], with the motion of some particles prescribed as in [`step_prescribed`]:
/// `prescribe(s, state)` sets them to their values at the end of substep `s` (1 to
/// `params.substeps`) of the frame. Between the frame's substeps the acceleration at the end
/// of one is reused as that at the start of the next (one force evaluation per Verlet
/// substep, where a sequence of [`step_prescribed`] calls makes two).
pub fn step_frame_prescribed(
    model: &Model,
    params: &IntegrationParameters,
    state: &mut State,
    scratch: &mut StepScratch,
    prescribe: &mut dyn FnMut(u32, &mut State),
) {
    scratch.acc_valid = false;
    let dt = params.dt();
    for s in 1..=params.substeps.max(1) {
        step_substep(
            model,
            params.integrator,
            dt,
            state,
            scratch,
            Some(&mut |st: &mut State| prescribe(s, st)),
        );
    }
}

/// One substep; reuses `scratch.acc` when `scratch.acc_valid` says it is the acceleration at
/// `state` (valid only inside [`step_frame`] and [`crate::simulate`]).
pub(crate) fn step_substep(
    model: &Model,
    kind: IntegratorKind,
    dt: f64,
    state: &mut State,
    scratch: &mut StepScratch,
    mut prescribe: Option<&mut dyn FnMut(&mut State)>,
) {
    let n = state.len();
    if scratch.acc.len() != n {
        *scratch = StepScratch::new(n);
    }
    debug_assert_eq!(model.particle_count(), n, "state and model sizes differ");
    let constrained = model.physics.has_constraints();
    if constrained {
        if model.settle_constraints(state) {
            scratch.acc_valid = false;
        }
        scratch.x_old.clone_from(&state.positions);
    }
    let particles = &model.particles.particles;
    match kind {
        IntegratorKind::Euler => {
            model.accelerations(state, &mut scratch.acc);
            let free = particles.iter().map(|p| !p.fixed);
            for (((x, v), a), free) in state
                .positions
                .iter_mut()
                .zip(state.velocities.iter_mut())
                .zip(&scratch.acc)
                .zip(free)
            {
                if free {
                    *v += a * dt;
                    *x += *v * dt;
                } else {
                    *v = Vec2::zeros();
                }
            }
            if let Some(f) = prescribe.as_mut() {
                f(state);
            }
            scratch.acc_valid = false;
        }
        IntegratorKind::Verlet => {
            let velocity_dependent = model.has_velocity_dependent_forces();
            if !scratch.acc_valid {
                model.accelerations(state, &mut scratch.acc);
            }
            scratch.v_old.copy_from_slice(&state.velocities);
            let free = particles.iter().map(|p| !p.fixed);
            for (((x, v), a), free) in state
                .positions
                .iter_mut()
                .zip(state.velocities.iter_mut())
                .zip(&scratch.acc)
                .zip(free)
            {
                if free {
                    *x += *v * dt + a * (0.5 * dt * dt);
                    // Velocity predicted to first order: conservative forces do not read it,
                    // and for drag and dashpots the trapezoidal correction below then makes
                    // the velocity update Heun's method, second order like the positions.
                    *v += a * dt;
                } else {
                    *v = Vec2::zeros();
                }
            }
            if let Some(f) = prescribe.as_mut() {
                f(state);
            }
            model.accelerations(state, &mut scratch.acc_new);
            for ((v, v0), (a0, a1)) in state
                .velocities
                .iter_mut()
                .zip(&scratch.v_old)
                .zip(scratch.acc.iter().zip(&scratch.acc_new))
            {
                // Fixed particles have a0 = a1 = 0 but possibly a nonzero v0: zeroed below.
                *v = v0 + (a0 + a1) * (0.5 * dt);
            }
            for (v, p) in state.velocities.iter_mut().zip(particles) {
                if p.fixed {
                    *v = Vec2::zeros();
                }
            }
            std::mem::swap(&mut scratch.acc, &mut scratch.acc_new);
            // With velocity-dependent forces a(x, v_pred) is not a(x, v): recompute next time.
            scratch.acc_valid = !velocity_dependent;
        }
    }
    if constrained {
        model.apply_constraints(&scratch.x_old, state, dt, &mut scratch.rail_dv);
        // The projection moved the positions the end acceleration was evaluated at.
        scratch.acc_valid = false;
    }
    if model.physics.surface_friction != 0.0 {
        let fixed = model.particles.particles.iter().map(|p| p.fixed);
        let tau = match kind {
            IntegratorKind::Verlet => 0.5 * dt,
            IntegratorKind::Euler => dt,
        };
        model.physics.apply_surface_friction(fixed, state, dt, tau);
        scratch.acc_valid = false;
    }
    // `scratch.acc` is the acceleration at the end of the substep (Verlet) or at its start
    // (Euler): either is the substep's acceleration to first order, all the event law needs.
    if model.apply_walls_in_substep(state, &scratch.acc, dt) > 0 {
        scratch.acc_valid = false;
    }
    if let Some(f) = prescribe {
        f(state);
    }
}

/// Advances `state` by one frame: `params.substeps` substeps of `params.dt()`.
///
/// As [`step`], the result depends only on the arguments, not on what `scratch` last held.
pub fn step_frame(
    model: &Model,
    params: &IntegrationParameters,
    state: &mut State,
    scratch: &mut StepScratch,
) {
    scratch.acc_valid = false;
    step_frame_continued(model, params, state, scratch);
}

/// As [`step_frame`], reusing the acceleration the previous call left in `scratch`; only for
/// callers that own `state` and `model` between calls (the simulator).
pub(crate) fn step_frame_continued(
    model: &Model,
    params: &IntegrationParameters,
    state: &mut State,
    scratch: &mut StepScratch,
) {
    let dt = params.dt();
    for _ in 0..params.substeps.max(1) {
        step_substep(model, params.integrator, dt, state, scratch, None);
    }
}
