//! The particle model shared by every physfit stage.
//!
//! An object is a set of point masses ([`ParticleSet`]) joined by extension springs
//! ([`Spring`], `E = S (d - L)^2`) and torsional springs ([`Torsion`], `E = T (c - M)^2`),
//! each counted once per bond, as in the 1994 paper restated in `MODEL.md`. Forces are the
//! analytic gradients of [`Potential`] implementations, written once here: the renderer's
//! simulator and the identifier's costs both call them. [`Physics`] adds what the paper left
//! out (uniform field, drag, dashpots, walls), each off unless a scene turns it on.
//!
//! Units: pixels (x right, y down, pixel centres at integer coordinates), seconds, and a
//! mass unit of the scene's choosing; frame `k` of a recording is at `t = k / fps`.
//!
//! # Example
//! ```
//! use physfit_model::{simulate, Scene};
//! let scene = Scene::from_toml_str(r#"
//!     [recording]
//!     fps = 100.0
//!     frames = 10
//!     [[particles]]
//!     id = "a"
//!     mass = 1.0
//!     position = [0.0, 0.0]
//!     [[particles]]
//!     id = "b"
//!     mass = 1.0
//!     position = [50.0, 0.0]
//!     [[springs]]
//!     between = ["a", "b"]
//!     length = 40.0
//!     stiffness = 100.0
//! "#, "example.toml").unwrap();
//! let model = scene.model().unwrap();
//! let rec = simulate(&model, &scene.initial_state(), &scene.integration_parameters(), 10);
//! // The stretched spring pulls the two particles together, symmetrically.
//! assert!(rec.frame(9)[0].x > 0.0);
//! assert!((rec.frame(9)[0].x + rec.frame(9)[1].x - 50.0).abs() < 1e-9);
//! ```

pub mod constraint;
mod integrator;
mod model;
mod particle;
mod physics;
mod potential;
#[cfg(test)]
mod proptest_utils;
pub mod scene;
mod simulate;
mod spring;
mod state;
mod torsion;

/// A 2-D vector in image coordinates (px, or px/s, or px/s²).
pub type Vec2 = nalgebra::Vector2<f64>;

pub use constraint::{Rail, Rope};
pub use integrator::{
    step, step_frame, step_frame_prescribed, step_prescribed, IntegrationParameters, IntegratorKind,
    StepScratch,
};
pub use model::{body_drag_force, dashpot_force_on_i, Model};
pub use particle::{Particle, ParticleId, ParticleSet};
/// Atomic file output (the one implementation lives in physfit-tracks, the lowest crate).
pub use physfit_tracks::write_atomic;
pub use physics::{Physics, Wall};
pub use potential::Potential;
pub use scene::{Colour, RenderSettings, Scene, SceneError, SceneProblem};
pub use simulate::{simulate, simulate_with, Recording};
pub use spring::{Spring, SpringGeometry, MIN_SEPARATION};
pub use state::State;
pub use torsion::{Torsion, TorsionGeometry};
