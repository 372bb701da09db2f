//! The largest single-frame displacement seen in a recording, which bounds every gate.

/// The largest displacement a particle makes in one frame, measured from the recording:
/// the steps between consecutive points of a track each located alone in its own blob, over
/// the latest [`StepBound::KEPT`] of them.
#[derive(Clone, Debug, Default)]
pub(super) struct StepBound {
    steps: std::collections::VecDeque<f64>,
}

impl StepBound {
    /// Steps kept (the most recent).
    const KEPT: usize = 4096;
    /// Steps needed before a bound is given.
    const NEEDED: usize = 30;

    pub(super) fn push(&mut self, step: f64) {
        if step.is_finite() {
            if self.steps.len() == Self::KEPT {
                self.steps.pop_front();
            }
            self.steps.push_back(step);
        }
    }

    /// One and a half times the 90th percentile of the kept steps (robust to the odd wrong
    /// link, which a maximum is not), or `None` while fewer than [`StepBound::NEEDED`] steps
    /// were seen.
    pub(super) fn bound(&self) -> Option<f64> {
        if self.steps.len() < Self::NEEDED {
            return None;
        }
        let mut v: Vec<f64> = self.steps.iter().copied().collect();
        let k = (0.9 * (v.len() - 1) as f64).round() as usize;
        Some(1.5 * *v.select_nth_unstable_by(k, f64::total_cmp).1)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bound_follows_the_steps_and_ignores_a_few_wrong_links() {
        let mut b = StepBound::default();
        for k in 0..StepBound::NEEDED - 1 {
            b.push(3.0 * k as f64 / 100.0);
        }
        assert_eq!(b.bound(), None, "too few steps");
        let mut b = StepBound::default();
        // Steps spread evenly over 0..3 px, and three wrong links of 80 px.
        for k in 0..1000 {
            b.push(3.0 * k as f64 / 1000.0);
        }
        for _ in 0..3 {
            b.push(80.0);
        }
        b.push(f64::NAN);
        let bound = b.bound().expect("enough steps");
        assert!((bound - 1.5 * 2.7).abs() < 0.02, "bound {bound}");
        // Only the latest steps count.
        for _ in 0..StepBound::KEPT {
            b.push(1.0);
        }
        assert!((b.bound().expect("steps") - 1.5).abs() < 1e-12);
    }
}
