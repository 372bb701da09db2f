//! [`Stagnation`]: the "no improvement over N iterations" stopping rule shared by the solvers.

/// Validates the stopping options every solver shares: a target cost that is a number and a
/// stagnation tolerance (relative improvement, dimensionless) that is finite and not negative.
pub(super) fn check_stopping_options(
    target_cost: f64,
    stagnation_tolerance: f64,
) -> Result<(), super::SolverError> {
    super::check_option("target_cost", target_cost, !target_cost.is_nan(), "a number")?;
    super::check_option(
        "stagnation_tolerance",
        stagnation_tolerance,
        stagnation_tolerance.is_finite() && stagnation_tolerance >= 0.0,
        "finite and >= 0",
    )
}

/// Counts iterations since the best cost last improved by more than a relative tolerance.
#[derive(Clone, Debug)]
pub(super) struct Stagnation {
    /// Iterations without improvement that stop the search; 0 never stops.
    limit: usize,
    /// Relative decrease of the best cost that counts as an improvement.
    tolerance: f64,
    /// Best cost at the last improvement.
    reference: f64,
    /// Iterations since then.
    since: usize,
}

impl Stagnation {
    /// A counter starting from the best cost `initial`.
    pub(super) fn new(limit: usize, tolerance: f64, initial: f64) -> Self {
        Stagnation {
            limit,
            tolerance,
            reference: initial,
            since: 0,
        }
    }

    /// Records the best cost after one more iteration; returns true if and only if the search
    /// has now gone `limit` iterations without improving.
    pub(super) fn record(&mut self, best: f64) -> bool {
        let improved = if self.reference.is_finite() {
            best < self.reference - self.tolerance * self.reference.abs()
        } else {
            best < self.reference
        };
        if improved {
            self.reference = best;
            self.since = 0;
        } else {
            self.since += 1;
        }
        self.limit > 0 && self.since >= self.limit
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stops_after_limit_without_relative_improvement() {
        let mut s = Stagnation::new(3, 1e-3, 1.0);
        // Improvements smaller than 0.1 % do not count.
        assert!(!s.record(0.9999));
        assert!(!s.record(0.9998));
        assert!(s.record(0.9997));
    }

    #[test]
    fn an_improvement_resets_the_count_and_infinite_starts_improve() {
        let mut s = Stagnation::new(2, 1e-3, f64::INFINITY);
        assert!(!s.record(f64::INFINITY));
        assert!(!s.record(5.0));
        assert!(!s.record(5.0));
        assert!(s.record(5.0));
        let mut never = Stagnation::new(0, 0.0, 1.0);
        assert!((0..100).all(|_| !never.record(1.0)));
    }
}
