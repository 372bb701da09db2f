//! The paper's global search solvers: simulated annealing ([`anneal`]) and the real-coded
//! genetic algorithm, global ([`genetic`]) and local ([`genetic_local`]) (BMVC 1994, sections
//! 3-2 and 3-3; `MODEL.md` section 4).
//!
//! A key design decision made in this module is that a solver sees only a
//! [`CostFunction`](crate::CostFunction) (or [`LocalCostFunction`](crate::LocalCostFunction))
//! and the [`Layout`] of the parameter vector: what each entry is, its bounds and
//! typical scale, how entries pair into bonds and what the data say about each bond (observed
//! distances and cosines). Solvers never see particles or frames, so any cost built on the same
//! layout (one-step prediction, multi-step prediction, a test function) runs unchanged.
//!
//! Determinism: every random draw is made sequentially from one `ChaCha8Rng` seeded by the
//! caller; only cost evaluations run in parallel (rayon, genetic algorithms only), and their
//! results are stored by index. A seed therefore gives bitwise identical results whatever the
//! thread count.
//!
//! Stopping: every solver stops at its iteration or generation limit, when the best cost
//! reaches a target, or when the best cost has not improved (relatively, by more than a
//! tolerance) over a given number of iterations or generations.

mod anneal;
mod ga;
mod stopping;

pub use anneal::{anneal, AnnealOptions};
pub use ga::{genetic, genetic_local, GaOptions, MutationSchedule};

use crate::{BondGenes, Layout, ParameterKind};

/// An error in a solver's settings.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum SolverError {
    /// A solver option is outside its admissible range.
    #[error("solver option `{name}` = {value} is out of range: it must be {expected}")]
    InvalidOption {
        /// The option's field name.
        name: &'static str,
        /// The value given.
        value: f64,
        /// The admissible range, in words.
        expected: &'static str,
    },
}

/// Returns `Ok` if and only if `ok`, else an [`SolverError::InvalidOption`] naming `name`.
fn check_option(name: &'static str, value: f64, ok: bool, expected: &'static str) -> Result<(), SolverError> {
    if ok {
        Ok(())
    } else {
        Err(SolverError::InvalidOption {
            name,
            value,
            expected,
        })
    }
}

/// A cost as the solvers store it: NaN (a model that could not be evaluated) becomes +inf, so
/// that it sorts last and is never accepted.
fn sane(cost: f64) -> f64 {
    if cost.is_nan() {
        f64::INFINITY
    } else {
        cost
    }
}

/// For each parameter, the index in `layout.bonds` of the bond holding it (if any).
fn parameter_bonds(layout: &Layout) -> Vec<Option<usize>> {
    let mut owner = vec![None; layout.dimension()];
    for (b, bond) in layout.bonds.iter().enumerate() {
        for &p in &bond.params {
            if let Some(slot) = owner.get_mut(p) {
                *slot = Some(b);
            }
        }
    }
    owner
}

/// The finite observed values of a bond (distances in px for a spring, cosines for a torsion).
fn finite_observed(bond: &BondGenes) -> impl Iterator<Item = f64> + '_ {
    bond.observed.iter().copied().filter(|v| v.is_finite())
}

/// Mean of a bond's finite observed values, or `None` if it has none.
fn observed_mean(bond: &BondGenes) -> Option<f64> {
    let (sum, count) = finite_observed(bond).fold((0.0, 0usize), |(s, c), v| (s + v, c + 1));
    (count > 0).then(|| sum / count as f64)
}

/// `[min, max]` of a bond's finite observed values, or `None` if it has none.
fn observed_range(bond: &BondGenes) -> Option<[f64; 2]> {
    finite_observed(bond).fold(None, |acc, v| match acc {
        None => Some([v, v]),
        Some([lo, hi]) => Some([lo.min(v), hi.max(v)]),
    })
}

/// True if and only if the parameter is a spring's rest length.
fn is_rest_length(layout: &Layout, p: usize) -> bool {
    layout
        .parameters
        .get(p)
        .is_some_and(|info| info.kind == ParameterKind::RestLength)
}

#[cfg(test)]
pub(crate) mod testing;

#[cfg(test)]
mod recovery_tests;
