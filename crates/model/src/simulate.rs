//! Simulating a model over a recording: one sampled state per frame.

use crate::integrator::step_frame_continued;
use crate::{IntegrationParameters, Model, State, StepScratch, Vec2};

/// Positions of every particle at every frame of a simulated recording.
#[derive(Clone, Debug, PartialEq)]
pub struct Recording {
    /// Number of particles per frame.
    pub particle_count: usize,
    /// Positions, px, frame-major: frame `k`'s positions are
    /// `positions[k * particle_count..(k + 1) * particle_count]`.
    pub positions: Vec<Vec2>,
    /// Velocities, px/s, laid out as `positions`.
    pub velocities: Vec<Vec2>,
}

impl Recording {
    /// Number of frames.
    pub fn frame_count(&self) -> usize {
        self.positions.len().checked_div(self.particle_count).unwrap_or(0)
    }

    /// Positions at frame `k`, px.
    ///
    /// # Panics
    /// If `k` is not below [`Recording::frame_count`].
    pub fn frame(&self, k: usize) -> &[Vec2] {
        &self.positions[k * self.particle_count..(k + 1) * self.particle_count]
    }

    /// The first sample whose position or velocity is not finite, as (frame, particle index),
    /// frame-major: where a simulation blew up. `None` when every number is finite.
    pub fn first_non_finite(&self) -> Option<(usize, usize)> {
        let finite = |v: &Vec2| v.x.is_finite() && v.y.is_finite();
        let k = self
            .positions
            .iter()
            .zip(&self.velocities)
            .position(|(x, v)| !(finite(x) && finite(v)))?;
        let n = self.particle_count.max(1);
        Some((k / n, k % n))
    }

    /// Full state (positions and velocities) at frame `k`.
    ///
    /// # Panics
    /// If `k` is not below [`Recording::frame_count`].
    pub fn state(&self, k: usize) -> State {
        let r = k * self.particle_count..(k + 1) * self.particle_count;
        State::new(self.positions[r.clone()].to_vec(), self.velocities[r].to_vec())
    }
}

/// Simulates `model` from `initial` (the state at frame 0) and samples `frames` frames
/// (frame 0 included), `params.substeps` integration substeps apart.
pub fn simulate(model: &Model, initial: &State, params: &IntegrationParameters, frames: usize) -> Recording {
    simulate_with(model, initial, params, frames, |_, _| {})
}

/// As [`simulate`], calling `observer(frame, state)` on every sampled frame.
pub fn simulate_with(
    model: &Model,
    initial: &State,
    params: &IntegrationParameters,
    frames: usize,
    mut observer: impl FnMut(usize, &State),
) -> Recording {
    let n = initial.len();
    let mut positions = Vec::with_capacity(n * frames);
    let mut velocities = Vec::with_capacity(n * frames);
    let mut state = initial.clone();
    let mut scratch = StepScratch::new(n);
    for k in 0..frames {
        if k > 0 {
            step_frame_continued(model, params, &mut state, &mut scratch);
        }
        observer(k, &state);
        positions.extend_from_slice(&state.positions);
        velocities.extend_from_slice(&state.velocities);
    }
    Recording {
        particle_count: n,
        positions,
        velocities,
    }
}
