//! [`OneStepCost`]: the paper's one-step-prediction cost, global and local (MODEL.md section 4).
//!
//! # API note for solver writers
//!
//! ```text
//! let cost = OneStepCost::new(&structure, &observations)?;   // Result<_, IdentifyError>
//! let layout: &Layout = cost.layout();                        // bounds, scales, bond genes
//! let x0: Vec<f64> = cost.problem().initial_guess();          // observed-mean L and M, stiffness = scale
//! cost.cost(&x) -> f64          // CostFunction: px^2, INFINITY if a prediction is not finite
//! cost.region_count()           // LocalCostFunction: one region per particle
//! cost.region_parameters(p)     // indices of the parameters region p depends on
//! cost.local_costs(&x, &mut out) // out.len() == region_count(); out.iter().sum() == cost(&x), bit for bit
//! cost.problem().fitted_scene(&x) / .model(&x)                // parameter vector -> Scene / Model
//! ```
//! `Parameter::bounds` are wide safety limits (stiffness up to `1e4 * scale`): draw random
//! stiffnesses around `Parameter::scale` (log-uniformly, say), not uniformly in the bounds.
//! `cost` and `local_costs` are `&self`, allocation-light and sequential: evaluate individuals in
//! parallel from the caller. Cost per call ~ frames x substeps x bonds.
//!
//! # Definition
//!
//! For every frame `t` of the window whose predecessor `t - 1` is completely observed, the
//! observed state at `t - 1` (tracked positions, velocities from local polynomial fits, see
//! [`crate::Observations`]) is advanced by one frame (`recording.substeps` substeps of the
//! structure's integrator, through [`physfit_model::step_frame`]) with the candidate parameters,
//! and each predicted inter-particle distance is compared with the observed one:
//!
//! ```text
//! Cost = sum_t sum_{(i,j) in pairs} (d_pred,t,ij - d_obs,t,ij)^2        (px^2)
//! ```
//!
//! The pairs are every pair of particles at most two bonds apart in the bond graph (a spring
//! joins its ends; a torsion joins its three particles pairwise): bonded pairs and second
//! neighbours. Pairs whose distance is not observed at `t` are left out.
//!
//! **Local cost.** Particle `p`'s local cost is half the sum of the terms of the pairs that
//! contain `p` (its pairs with its first and second neighbours). Every pair term is split
//! evenly between its two particles, so the local costs sum exactly to the global cost. Region
//! `p`'s parameters are those of the bonds that touch `p` or one of its first and second
//! neighbours: with one substep per frame, a pair's predicted distance depends only on the bonds
//! touching its two particles. With several substeps per frame, influence spreads one bond per
//! substep, so a local cost depends weakly on bonds further out; the locality is then the paper's
//! approximation, not exact.
//!
//! **Own-prediction split** ([`LocalSplit::OwnPrediction`], what the local genetic algorithm
//! uses). The split above spreads each particle's local cost over the bonds of a wide
//! neighbourhood: on a densely braced object (the paper's 8-particle ring) nearly every local
//! cost depends on nearly every bond, and sorting by it selects bonds on what other bonds did.
//! In the own-prediction split only particle `p` is advanced: its predicted position is compared
//! with the *observed* positions of its first and second neighbours,
//!
//! ```text
//! Local_p = sum_t sum_{q within two bonds of p} (|x_pred,t,p - x_obs,t,q| - d_obs,t,pq)^2
//! ```
//!
//! With one integration step per frame, particle `p`'s predicted position depends only on the
//! forces on `p`, i.e. on the bonds that touch `p`: region `p`'s parameters are exactly those
//! bonds. The global cost is the sum of these local costs (each pair counted once from each
//! end); it is zero at the truth under the same conditions as the paired cost.
//!
//! The cost is the paper's; it is biased when a frame holds several integration steps (the
//! observed velocity at `t - 1` is an average, not the integrator's state) and when positions
//! are noisy (noisy velocities). [`crate::MultiStepCost`] is the unbiased judge.

use physfit_model::{step_frame, IntegrationParameters, Scene, State, StepScratch};

use physfit_model::Vec2;

use crate::{CostFunction, IdentifyError, Layout, LocalCostFunction, Observations, Problem};

/// How the one-step cost is split into per-particle local costs (see the module doc).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum LocalSplit {
    /// Every particle is advanced and each pair's squared distance error is split half and
    /// half between its two particles (the paper's global cost).
    #[default]
    Pairs,
    /// Only the region's own particle is advanced, and its predicted distances to the observed
    /// positions of its neighbours within two bonds are compared: a local cost that depends
    /// only on the bonds touching the particle (exactly, at one integration step per frame).
    OwnPrediction,
}

/// The paper's one-step-prediction cost over an analysed window (see the module doc).
#[derive(Clone, Debug)]
pub struct OneStepCost {
    problem: Problem,
    stepping: IntegrationParameters,
    /// Pairs `[a, b]`, `a < b`, at most two bonds apart.
    pairs: Vec<[usize; 2]>,
    /// For each used transition: the observed state at `t - 1` and the observed distance of
    /// each pair at `t` (`NaN` where unobserved).
    transitions: Vec<(State, Vec<f64>)>,
    /// Observed positions at `t` of each transition (for the own-prediction split).
    targets: Vec<Vec<Option<Vec2>>>,
    region_params: Vec<Vec<usize>>,
    /// Each particle's neighbours within two bonds.
    within2: Vec<Vec<usize>>,
    particle_count: usize,
    split: LocalSplit,
}

/// Every pair of particles at most two bonds apart, and each particle's neighbours within two bonds.
pub fn neighbour_pairs(structure: &Scene) -> (Vec<[usize; 2]>, Vec<Vec<usize>>) {
    let n = structure.particles.len();
    let mut adj = vec![Vec::new(); n];
    let mut link = |a: usize, b: usize| {
        if !adj[a].contains(&b) {
            adj[a].push(b);
            adj[b].push(a);
        }
    };
    for s in &structure.springs {
        link(s.ends[0].index(), s.ends[1].index());
    }
    for t in &structure.torsions {
        let [i, j, k] = [t.center.index(), t.ends[0].index(), t.ends[1].index()];
        link(i, j);
        link(i, k);
        link(j, k);
    }
    let mut within2 = vec![Vec::new(); n];
    for p in 0..n {
        let mut set: Vec<usize> = Vec::new();
        for &q in &adj[p] {
            set.push(q);
            set.extend(adj[q].iter().copied());
        }
        set.sort_unstable();
        set.dedup();
        set.retain(|&q| q != p);
        within2[p] = set;
    }
    let mut pairs = Vec::new();
    for (p, near) in within2.iter().enumerate() {
        for &q in near {
            if q > p {
                pairs.push([p, q]);
            }
        }
    }
    (pairs, within2)
}

impl OneStepCost {
    /// The one-step cost of `structure`'s unknown values over `observations`' frames, with the
    /// layout of [`crate::layout_for`]. Needs at least two consecutive complete frames.
    pub fn new(structure: &Scene, observations: &Observations) -> Result<OneStepCost, IdentifyError> {
        OneStepCost::with_problem(Problem::new(structure, observations)?, observations)
    }

    /// As [`OneStepCost::new`] for an already built problem (the same structure and layout).
    pub fn with_problem(problem: Problem, observations: &Observations) -> Result<OneStepCost, IdentifyError> {
        let structure = &problem.structure;
        let n = structure.particles.len();
        let (pairs, within2) = neighbour_pairs(structure);
        let mut transitions = Vec::new();
        let mut targets = Vec::new();
        for k in 1..observations.frame_count() {
            let Some(state) = observations.state(k - 1) else {
                continue;
            };
            let pos = &observations.positions[k];
            targets.push(pos.clone());
            let observed: Vec<f64> = pairs
                .iter()
                .map(|&[a, b]| match (pos[a], pos[b]) {
                    (Some(xa), Some(xb)) => (xb - xa).norm(),
                    _ => f64::NAN,
                })
                .collect();
            transitions.push((state, observed));
        }
        if transitions.is_empty() {
            return Err(IdentifyError::TooFewFrames {
                method: "the one-step cost".into(),
                need: 2,
                have: observations.complete_frame_count(),
            });
        }
        let stepping = structure.integration_parameters();
        let mut cost = OneStepCost {
            problem,
            stepping,
            pairs,
            transitions,
            targets,
            region_params: Vec::new(),
            within2,
            particle_count: n,
            split: LocalSplit::Pairs,
        };
        cost.region_params = cost.regions();
        Ok(cost)
    }

    /// The same cost split into local costs as `split` says (see the module doc); the global
    /// cost is the sum of the local costs either way.
    pub fn with_split(mut self, split: LocalSplit) -> OneStepCost {
        self.split = split;
        self.region_params = self.regions();
        self
    }

    /// How the cost is split into local costs.
    pub fn split(&self) -> LocalSplit {
        self.split
    }

    /// Each region's parameters: for [`LocalSplit::Pairs`], the bonds touching the particle or
    /// one within two bonds of it; for [`LocalSplit::OwnPrediction`], the bonds touching it.
    fn regions(&self) -> Vec<Vec<usize>> {
        (0..self.particle_count)
            .map(|p| {
                let mut near = match self.split {
                    LocalSplit::Pairs => self.within2[p].clone(),
                    LocalSplit::OwnPrediction => Vec::new(),
                };
                near.push(p);
                let mut params: Vec<usize> = self
                    .problem
                    .layout
                    .bonds
                    .iter()
                    .filter(|b| b.particles.iter().any(|q| near.contains(q)))
                    .flat_map(|b| b.params.iter().copied())
                    .collect();
                params.sort_unstable();
                params.dedup();
                params
            })
            .collect()
    }

    /// The parameter layout.
    pub fn layout(&self) -> &Layout {
        &self.problem.layout
    }

    /// The problem (structure, layout, parameter vector -> model).
    pub fn problem(&self) -> &Problem {
        &self.problem
    }

    /// The compared pairs `[a, b]` (particle indices, `a < b`).
    pub fn pairs(&self) -> &[[usize; 2]] {
        &self.pairs
    }

    /// Number of one-frame predictions the cost sums over.
    pub fn transition_count(&self) -> usize {
        self.transitions.len()
    }

    /// The residuals of the cost (px): each term's distance error, in a fixed order, so that
    /// the cost is their sum of squares. Returns false if and only if a prediction was not
    /// finite. For least-squares polishing of a solver's result on the same cost.
    pub fn residuals(&self, params: &[f64], out: &mut Vec<f64>) -> bool {
        out.clear();
        match self.split {
            LocalSplit::Pairs => self.for_each_error(params, |_, e| out.push(e)),
            LocalSplit::OwnPrediction => self.own_prediction_errors(params, |_, e| out.push(e)),
        }
    }

    /// Polishes `start` by Levenberg-Marquardt on [`OneStepCost::residuals`] (at most
    /// `max_iterations` Jacobians), within the layout's bounds: the local descent that follows
    /// a global search on the same cost. The population of a genetic algorithm finds the valley
    /// but crawls along its floor when the cost is ill-conditioned (on the paper's 8-particle
    /// ring the one-step cost's curvature spans eight orders of magnitude: the ring's angles
    /// trade against each other); Gauss-Newton steps do not. `None` if the cost cannot be
    /// evaluated at `start`.
    pub fn polish(
        &self,
        start: &[f64],
        max_iterations: usize,
        observer: &dyn crate::Observer,
    ) -> Option<crate::SolverOutcome> {
        let ps = &self.problem.layout.parameters;
        let lower: Vec<f64> = ps.iter().map(|p| p.bounds[0]).collect();
        let upper: Vec<f64> = ps.iter().map(|p| p.bounds[1]).collect();
        let typical: Vec<f64> = ps.iter().map(|p| p.scale).collect();
        let options = crate::LmOptions {
            max_iterations,
            ..crate::LmOptions::default()
        };
        let f = |x: &[f64], out: &mut Vec<f64>| self.residuals(x, out);
        let o = crate::levenberg_marquardt(&f, start, &lower, &upper, &typical, &options, observer)?;
        Some(crate::SolverOutcome {
            best_cost: self.cost(&o.x),
            best: o.x,
            history: o.history.into_iter().skip(1).collect(),
            iteration_count: o.iterations,
            cost_count: o.evaluations,
        })
    }

    /// Calls `term(pair_index, squared_error)` for every compared pair and frame; returns false
    /// if and only if a prediction was not finite.
    fn for_each_term(&self, params: &[f64], mut term: impl FnMut(usize, f64)) -> bool {
        self.for_each_error(params, |q, e| term(q, e * e))
    }

    /// Steps every transition from its observed state with `params` and calls
    /// `visit(transition_index, predicted_state)`; stops and returns false as soon as
    /// `visit` does (a prediction that was not finite).
    fn for_each_prediction(&self, params: &[f64], mut visit: impl FnMut(usize, &State) -> bool) -> bool {
        let model = self.problem.model(params);
        let mut scratch = StepScratch::new(self.particle_count);
        let mut state = State::default();
        for (t, (start, _)) in self.transitions.iter().enumerate() {
            state.clone_from(start);
            scratch.invalidate();
            step_frame(&model, &self.stepping, &mut state, &mut scratch);
            if !visit(t, &state) {
                return false;
            }
        }
        true
    }

    /// Calls `term(pair_index, distance_error)` for every compared pair and frame; returns
    /// false if and only if a prediction was not finite.
    fn for_each_error(&self, params: &[f64], mut term: impl FnMut(usize, f64)) -> bool {
        self.for_each_prediction(params, |t, state| {
            let x = &state.positions;
            for (q, (&[a, b], &d_obs)) in self.pairs.iter().zip(&self.transitions[t].1).enumerate() {
                if d_obs.is_nan() {
                    continue;
                }
                let e = (x[b] - x[a]).norm() - d_obs;
                if !e.is_finite() {
                    return false;
                }
                term(q, e);
            }
            true
        })
    }

    /// Calls `term(particle, distance_error)` for each own-prediction term; false if a
    /// prediction was not finite.
    fn own_prediction_errors(&self, params: &[f64], mut term: impl FnMut(usize, f64)) -> bool {
        self.for_each_prediction(params, |t, state| {
            let target = &self.targets[t];
            for (p, near) in self.within2.iter().enumerate() {
                let (Some(xp_obs), xp) = (target[p], state.positions[p]) else {
                    continue;
                };
                for &q in near {
                    let Some(xq) = target[q] else {
                        continue;
                    };
                    let e = (xp - xq).norm() - (xp_obs - xq).norm();
                    if !e.is_finite() {
                        return false;
                    }
                    term(p, e);
                }
            }
            true
        })
    }
}

impl CostFunction for OneStepCost {
    fn dimension(&self) -> usize {
        self.problem.dimension()
    }

    /// Defined as the sum (in region order) of [`LocalCostFunction::local_costs`], so the
    /// two agree to the last bit.
    fn cost(&self, params: &[f64]) -> f64 {
        let mut local = vec![0.0; self.particle_count];
        self.local_costs(params, &mut local);
        local.iter().sum()
    }
}

impl LocalCostFunction for OneStepCost {
    fn region_count(&self) -> usize {
        self.particle_count
    }

    fn region_parameters(&self, r: usize) -> &[usize] {
        &self.region_params[r]
    }

    fn local_costs(&self, params: &[f64], out: &mut [f64]) {
        out.iter_mut().for_each(|c| *c = 0.0);
        let ok = match self.split {
            LocalSplit::Pairs => {
                let pairs = &self.pairs;
                self.for_each_term(params, |q, e2| {
                    let [a, b] = pairs[q];
                    out[a] += 0.5 * e2;
                    out[b] += 0.5 * e2;
                })
            }
            LocalSplit::OwnPrediction => self.own_prediction_errors(params, |p, e| out[p] += e * e),
        };
        if !ok {
            out.iter_mut().for_each(|c| *c = f64::INFINITY);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testutil::{paper5, record, Timing};
    use physfit_model::IntegratorKind;

    #[test]
    fn global_cost_is_the_sum_of_local_costs() {
        let truth = paper5(Timing::default());
        let rec = record(&truth);
        let obs = Observations::from_recording(&rec, &truth, 0);
        let cost = OneStepCost::new(&truth.structure(), &obs).unwrap();
        assert_eq!(cost.dimension(), 14);
        assert_eq!(cost.region_count(), 5);
        let x0 = cost.problem().initial_guess();
        for scale in [1.0, 0.7, 1.3] {
            let x: Vec<f64> = x0.iter().map(|v| v * scale).collect();
            let mut local = vec![0.0; 5];
            cost.local_costs(&x, &mut local);
            let total = cost.cost(&x);
            assert!(total > 0.0);
            assert_eq!(local.iter().sum::<f64>().to_bits(), total.to_bits());
        }
    }

    #[test]
    fn a_region_depends_only_on_bonds_near_its_particle() {
        let truth = crate::testutil::lattice(
            5,
            Timing {
                frames: 10,
                ..Timing::default()
            },
        );
        let obs = Observations::from_recording(&record(&truth), &truth, 0);
        let cost = OneStepCost::new(&truth.structure(), &obs).unwrap();
        let layout = cost.layout();
        // Corner particle 0: the spring between particles 23 and 24 (far corner) is out of reach.
        let far = layout
            .bonds
            .iter()
            .find(|b| b.particles == vec![23, 24])
            .map(|b| b.params[0])
            .unwrap();
        assert!(!cost.region_parameters(0).contains(&far));
        assert!(cost.region_parameters(24).contains(&far));
        // Changing that far spring leaves corner 0's local cost unchanged (one substep would make
        // this exact; with 20 substeps influence needs more bonds than the lattice has between them
        // to vanish, so only require it to be much smaller than the change at the far corner).
        let x = cost.problem().params_of(&truth).unwrap();
        let mut y = x.clone();
        y[far + 1] *= 1.5;
        let (mut a, mut b) = (vec![0.0; 25], vec![0.0; 25]);
        cost.local_costs(&x, &mut a);
        cost.local_costs(&y, &mut b);
        assert!(
            (b[0] - a[0]).abs() < 1e-3 * (b[24] - a[24]).abs(),
            "{} vs {}",
            b[0] - a[0],
            b[24] - a[24]
        );
    }

    #[test]
    fn zero_at_the_truth_for_one_euler_step_per_frame() {
        let timing = Timing {
            substeps: 1,
            integrator: IntegratorKind::Euler,
            ..Timing::default()
        };
        let truth = paper5(timing);
        let obs = Observations::from_recording(&record(&truth), &truth, 0);
        let cost = OneStepCost::new(&truth.structure(), &obs).unwrap();
        let x_true = cost.problem().params_of(&truth).unwrap();
        let c_true = cost.cost(&x_true);
        assert!(c_true < 1e-18, "cost at truth {c_true}");
        let mut x = x_true.clone();
        x[1] *= 1.1;
        assert!(cost.cost(&x) > 1e6 * c_true.max(1e-24));
        // The structure's substeps are honoured: at 20 substeps the same data mismatch.
        let other = paper5(Timing::default());
        let cost20 = OneStepCost::new(&other.structure(), &obs).unwrap();
        assert!(cost20.cost(&x_true) > 1e3 * c_true.max(1e-24));
    }

    #[test]
    fn own_prediction_regions_hold_exactly_the_bonds_touching_their_particle() {
        let timing = Timing {
            substeps: 1,
            integrator: IntegratorKind::Euler,
            frames: 40,
            ..Timing::default()
        };
        let truth = crate::testutil::paper8(timing);
        let obs = Observations::from_recording(&record(&truth), &truth, 0);
        let cost = OneStepCost::new(&truth.structure(), &obs)
            .unwrap()
            .with_split(LocalSplit::OwnPrediction);
        assert_eq!(cost.split(), LocalSplit::OwnPrediction);
        let x = cost.problem().params_of(&truth).unwrap();
        // Zero at the truth, and the residuals are the cost's terms.
        assert!(cost.cost(&x) < 1e-18, "{}", cost.cost(&x));
        let layout = cost.layout().clone();
        for (b, bond) in layout.bonds.iter().enumerate() {
            for p in 0..cost.region_count() {
                let holds = bond.params.iter().all(|i| cost.region_parameters(p).contains(i));
                assert_eq!(holds, bond.particles.contains(&p), "bond {b}, particle {p}");
            }
            // Moving the bond changes exactly the local costs of the particles it touches.
            let mut y = x.clone();
            for &i in &bond.params {
                y[i] *= 1.05;
            }
            let mut local = vec![0.0; cost.region_count()];
            cost.local_costs(&y, &mut local);
            for (p, &c) in local.iter().enumerate() {
                if bond.particles.contains(&p) {
                    assert!(c > 1e-10, "bond {b} does not move particle {p}'s cost");
                } else {
                    assert!(c < 1e-20, "bond {b} moves particle {p}'s cost by {c}");
                }
            }
            let mut r = Vec::new();
            assert!(cost.residuals(&y, &mut r));
            let sum: f64 = r.iter().map(|e| e * e).sum();
            assert!((sum - cost.cost(&y)).abs() <= 1e-12 * sum);
        }
    }
}
