//! Identification: every bond's parameters from trajectories, by the paper's annealing and
//! genetic algorithms and by linear least squares refined on the multi-step cost.
//!
//! This crate owns the path from a *structure* (a [`physfit_model::Scene`] whose bond values
//! are unknown) and its tracks ([`physfit_tracks::TrackTable`]) to a *fitted model* (the same
//! scene with every value filled in) and a [`FitReport`] (the `fit.json` contract): values,
//! standard errors, Cramer-Rao bounds, identifiability warnings and costs.
//!
//! * [`Observations`]: the tracks as positions per frame, with velocity estimates and the
//!   measured track noise;
//! * [`Problem`] and [`Layout`]: which values are unknown, their bounds and scales, and the map
//!   from a parameter vector to a [`physfit_model::Model`];
//! * costs: the paper's [`OneStepCost`] (global and local) and the [`MultiStepCost`] that
//!   judges every fit;
//! * solvers: [`linear_estimate`] (weak-form least squares) then [`refine`] (multi-step
//!   Levenberg-Marquardt over parameters and start state), and the paper's
//!   [`solvers::anneal`], [`solvers::genetic`], [`solvers::genetic_local`];
//! * [`uncertainty`]: standard errors and unidentifiable parameters;
//! * [`fit`]: all of it behind one call, choosing by [`Method`].
//!
//! # Example
//! ```
//! use physfit_identify::{fit, FitOptions, Method};
//! use physfit_model::{simulate, Scene};
//! use physfit_tracks::{TrackPoint, TrackTable};
//! let truth = Scene::from_toml_str(r#"
//!     [recording]
//!     fps = 100.0
//!     frames = 60
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
//! // Tracks of the true motion, then a fit of the structure (values removed) to them.
//! let rec = simulate(&truth.model().unwrap(), &truth.initial_state(), &truth.integration_parameters(), 60);
//! let points = (0..60)
//!     .flat_map(|k| rec.frame(k).iter().zip(["a", "b"]).map(move |(x, id)| TrackPoint::new(k, id, x.x, x.y)).collect::<Vec<_>>())
//!     .collect();
//! let options = FitOptions { method: Method::Lsq, ..FitOptions::default() };
//! let result = fit(&truth.structure(), &TrackTable { points }, &options, &()).unwrap();
//! let spring = &result.fitted.springs[0];
//! assert!((spring.rest_length.unwrap() - 40.0).abs() < 1e-6);
//! assert!((spring.stiffness.unwrap() - 100.0).abs() < 1e-6);
//! ```

mod cost;
pub mod diagnose;
mod driven;
pub use diagnose::{
    diagnose, diagnose_observations, scene_costs, DiagnoseOptions, Diagnosis, Effect, Finding,
};
mod error;
mod fit;
mod layout;
mod lm;
mod lsq;
mod multi_step;
mod observations;
mod one_step;
mod patches;
mod problem;
mod refine;
mod report;
pub mod solvers;
mod sparse_cholesky;
#[cfg(test)]
mod testutil;
mod uncertainty;
pub mod units;

pub use cost::{CostFunction, LocalCostFunction, Observer, SolverOutcome};
pub use error::IdentifyError;
pub use fit::{fit, fit_observations, FitOptions, FitResult, Method};
pub use layout::{
    layout_for, stiffness_scales, BondGenes, BondRef, Layout, Parameter, ParameterKind, StiffnessScales,
};
pub use lm::{jacobian, levenberg_marquardt, LmOptions, LmOutcome, Residuals};
pub use lsq::{default_test_window, linear_estimate, LinearEstimate};
// Tuning constants the diagnosis shares (crate-private: not options a user sets).
pub(crate) use lsq::TEST_EXPONENT;
pub use multi_step::{MultiStepCost, MultiStepFit};
pub use observations::Observations;
pub(crate) use observations::VELOCITY_FIT_POINTS;
pub use one_step::{neighbour_pairs, LocalSplit, OneStepCost};
pub use patches::{fit_start_state_by_size, refine_by_size, refine_in_patches, PatchRefinement};
pub use problem::Problem;
pub use refine::{fit_start_state, refine, RefineOptions, Refinement};
pub use report::{BondKeys, FitCosts, FitReport, ParameterReport, TruthComparison};
pub use uncertainty::{rest_angle_degrees, uncertainty, Uncertainty};
