//! Identification: every bond's parameters from trajectories, by the paper's annealing and
//! genetic algorithms and by linear least squares refined on the multi-step cost.

mod cost;
mod error;
mod fit;
mod layout;
mod lm;
mod lsq;
mod multi_step;
mod observations;
mod one_step;
mod problem;
mod refine;
mod report;
#[cfg(test)]
mod testutil;
mod uncertainty;
pub mod solvers;

pub use cost::{CostFunction, LocalCostFunction, Observer, SolverOutcome};
pub use error::IdentifyError;
pub use fit::{fit, fit_observations, FitOptions, FitResult, Method};
pub use layout::{
    layout_for, stiffness_scales, BondGenes, BondRef, Layout, Parameter, ParameterKind, StiffnessScales,
    STIFFNESS_BOUND_FACTOR,
};
pub use lm::{jacobian, levenberg_marquardt, LmOptions, LmOutcome, Residuals};
pub use lsq::{default_test_window, linear_estimate, LinearEstimate, DENSE_LIMIT, MIN_TEST_WINDOW, TEST_EXPONENT};
pub use multi_step::{MultiStepCost, MultiStepFit};
pub use observations::{Observations, VELOCITY_FIT_POINTS};
pub use one_step::{neighbour_pairs, OneStepCost};
pub use problem::Problem;
pub use report::{BondKeys, FitCosts, FitReport, ParameterReport, TruthComparison};
pub use refine::{fit_start_state, refine, RefineOptions, Refinement};
pub use uncertainty::{rest_angle_degrees, uncertainty, Uncertainty, NULL_EIGENVALUE, POORLY_DETERMINED};
