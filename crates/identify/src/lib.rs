//! Identification: every bond's parameters from trajectories, by the paper's annealing and
//! genetic algorithms and by linear least squares refined on the multi-step cost.

mod cost;
mod layout;

pub use cost::{CostFunction, LocalCostFunction, Observer, SolverOutcome};
pub use layout::{BondGenes, BondRef, Layout, Parameter, ParameterKind};
