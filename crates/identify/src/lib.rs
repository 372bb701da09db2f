//! Identification: every bond's parameters from trajectories, by the paper's annealing and
//! genetic algorithms and by linear least squares refined on the multi-step cost.

mod cost;
mod error;
mod layout;
mod observations;
mod one_step;
mod problem;
#[cfg(test)]
mod testutil;
pub mod solvers;

pub use cost::{CostFunction, LocalCostFunction, Observer, SolverOutcome};
pub use error::IdentifyError;
pub use layout::{
    layout_for, stiffness_scales, BondGenes, BondRef, Layout, Parameter, ParameterKind, StiffnessScales,
    STIFFNESS_BOUND_FACTOR,
};
pub use observations::{Observations, VELOCITY_FIT_POINTS};
pub use one_step::{neighbour_pairs, OneStepCost};
pub use problem::Problem;
