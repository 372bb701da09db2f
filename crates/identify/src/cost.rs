//! The cost interface every solver runs against.
//!
//! A key design decision made in this crate is to keep *what is fitted* separate from *how*:
//! a problem exposes a [`CostFunction`] (and, for the paper's local genetic algorithm, a
//! [`LocalCostFunction`]) over a flat parameter vector described by a [`crate::Layout`];
//! the annealer, the genetic algorithms and the least-squares solver only ever see these.

/// A scalar cost over a flat parameter vector (lower is better).
pub trait CostFunction: Sync {
    /// Length of the parameter vector.
    fn dimension(&self) -> usize;

    /// The cost at `params`; `f64::INFINITY` where the model cannot be evaluated
    /// (a simulation that diverged, say).
    fn cost(&self, params: &[f64]) -> f64;
}

/// A cost that splits into per-region (per-particle) local costs whose sum is the global cost,
/// each depending only on a subset of the parameters (the paper's local cost).
pub trait LocalCostFunction: CostFunction {
    /// Number of regions (one per particle in the paper's scheme).
    fn region_count(&self) -> usize;

    /// Indices of the parameters region `r`'s local cost depends on.
    fn region_parameters(&self, r: usize) -> &[usize];

    /// Writes every region's local cost at `params` into `out` (length
    /// [`LocalCostFunction::region_count`]). Their sum equals [`CostFunction::cost`].
    fn local_costs(&self, params: &[f64], out: &mut [f64]);
}

/// Receives a solver's progress (for progress bars and logs). `()` ignores it.
pub trait Observer: Sync {
    /// Called once per iteration or generation with the best cost so far.
    fn observe(&self, iteration: usize, best_cost: f64);
}

impl Observer for () {
    fn observe(&self, _iteration: usize, _best_cost: f64) {}
}

/// What a solver returns.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct SolverOutcome {
    /// The best parameter vector found.
    pub best: Vec<f64>,
    /// Its cost.
    pub best_cost: f64,
    /// Best cost after each iteration or generation.
    pub history: Vec<f64>,
    /// Iterations (annealing steps, generations, LM iterations) run.
    pub iteration_count: usize,
    /// Cost evaluations made.
    pub cost_count: usize,
}
