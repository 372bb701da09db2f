//! [`anneal`]: the paper's simulated annealing with a two-dimensional temperature.
//!
//! BMVC 1994 section 3-2 (`MODEL.md` section 4): at each step every parameter of one group
//! is perturbed by Gaussian noise whose standard deviation is the group's temperature; a
//! better set replaces the current one, a worse one is kept with the Metropolis probability
//! `exp(-dCost / cost_temperature)`; the temperature falls exponentially. Two temperatures,
//! one for the springs `(L, S)` and one for the torsions `(M, T)`, are annealed alternately
//! (the paper's "two-dimensional temperature", which did slightly better than one).
//! Rest lengths start at the observed mean distances, the other parameters at the caller's
//! start point.

use super::stopping::Stagnation;
use super::{check_option, observed_mean, parameter_bonds, sane, SolverError};
use crate::{CostFunction, Layout, Observer, ParameterKind, SolverOutcome};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use serde::{Deserialize, Serialize};

/// Settings of [`anneal`]. Temperatures are dimensionless: a temperature `t` perturbs
/// parameter `i` by Gaussian noise of standard deviation `t * layout.parameters[i].scale`
/// (so in px for rest lengths, in cosine units for rest cosines, in stiffness units for
/// stiffnesses).
///
/// Build it from [`AnnealOptions::default`] and check it with [`AnnealOptions::validate`];
/// [`anneal`] brings out-of-range values into range rather than failing.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct AnnealOptions {
    /// Initial temperature of the spring parameters (rest lengths and stiffnesses), as a
    /// fraction of each parameter's scale; > 0. Default 0.2.
    pub spring_temperature: f64,
    /// Initial temperature of the torsion parameters (rest cosines and angular stiffnesses),
    /// as a fraction of each parameter's scale; > 0. Default 0.2.
    pub torsion_temperature: f64,
    /// Factor a temperature is multiplied by after each step that perturbs its group
    /// (exponential cooling); in (0, 1). Default 0.999: with the alternation each temperature
    /// falls by about 2e4 over the default 20 000 steps.
    pub cooling: f64,
    /// Metropolis acceptance, > 0. The cost temperature of a step is
    /// `acceptance * best_cost * t / t0`, where `best_cost` is the best cost so far and
    /// `t / t0` the perturbed group's temperature over its initial value: at the start a worse
    /// set costing `acceptance * best_cost` more than the current one is kept with probability
    /// `1/e`, and the cost temperature cools with the parameter temperature. Tying it to the
    /// best cost makes it independent of the cost's units and of the data's size. Default 0.1.
    pub acceptance: f64,
    /// Temperature (fraction of scale) below which a group counts as frozen; the search stops
    /// when every group is frozen; > 0 and below the initial temperatures. Default 1e-5.
    pub min_temperature: f64,
    /// Maximum number of steps (one cost evaluation each). Default 20 000.
    pub iterations: usize,
    /// The search stops as soon as the best cost is at or below this. Default 0.
    pub target_cost: f64,
    /// The search stops after this many steps without the best cost improving by more than
    /// `stagnation_tolerance` (relative); 0 never stops on stagnation. Default 2000.
    pub stagnation: usize,
    /// Relative decrease of the best cost that counts as an improvement; >= 0. Default 1e-9.
    pub stagnation_tolerance: f64,
}

impl Default for AnnealOptions {
    fn default() -> Self {
        AnnealOptions {
            spring_temperature: 0.2,
            torsion_temperature: 0.2,
            cooling: 0.999,
            acceptance: 0.1,
            min_temperature: 1e-5,
            iterations: 20_000,
            target_cost: 0.0,
            stagnation: 2000,
            stagnation_tolerance: 1e-9,
        }
    }
}

impl AnnealOptions {
    /// Checks every option's range; the error names the first option out of range.
    pub fn validate(&self) -> Result<(), SolverError> {
        let positive = |x: f64| x.is_finite() && x > 0.0;
        check_option(
            "spring_temperature",
            self.spring_temperature,
            positive(self.spring_temperature),
            "finite and > 0",
        )?;
        check_option(
            "torsion_temperature",
            self.torsion_temperature,
            positive(self.torsion_temperature),
            "finite and > 0",
        )?;
        check_option(
            "cooling",
            self.cooling,
            self.cooling > 0.0 && self.cooling < 1.0,
            "in (0, 1)",
        )?;
        check_option(
            "acceptance",
            self.acceptance,
            positive(self.acceptance),
            "finite and > 0",
        )?;
        check_option(
            "min_temperature",
            self.min_temperature,
            positive(self.min_temperature)
                && self.min_temperature < self.spring_temperature.min(self.torsion_temperature),
            "> 0 and below both initial temperatures",
        )?;
        super::stopping::check_stopping_options(self.target_cost, self.stagnation_tolerance)
    }

    /// A copy with every out-of-range value replaced by the nearest admissible one (or the
    /// default), so that [`anneal`] never fails on its options.
    fn sanitized(&self) -> AnnealOptions {
        let d = AnnealOptions::default();
        let positive_or = |x: f64, default: f64| if x.is_finite() && x > 0.0 { x } else { default };
        let spring_temperature = positive_or(self.spring_temperature, d.spring_temperature);
        let torsion_temperature = positive_or(self.torsion_temperature, d.torsion_temperature);
        let coldest = spring_temperature.min(torsion_temperature);
        let min_temperature = positive_or(self.min_temperature, d.min_temperature).min(coldest * 0.5);
        AnnealOptions {
            spring_temperature,
            torsion_temperature,
            cooling: if self.cooling > 0.0 && self.cooling < 1.0 {
                self.cooling
            } else {
                d.cooling
            },
            acceptance: positive_or(self.acceptance, d.acceptance),
            min_temperature,
            iterations: self.iterations,
            target_cost: if self.target_cost.is_nan() {
                d.target_cost
            } else {
                self.target_cost
            },
            stagnation: self.stagnation,
            stagnation_tolerance: if self.stagnation_tolerance.is_finite() && self.stagnation_tolerance >= 0.0
            {
                self.stagnation_tolerance
            } else {
                d.stagnation_tolerance
            },
        }
    }
}

/// The starting point of the annealing: rest lengths at their bond's mean observed distance,
/// every other parameter from `start` (or its scale where `start` is too short), clamped into
/// bounds.
fn initial_point(layout: &Layout, start: &[f64]) -> Vec<f64> {
    let owner = parameter_bonds(layout);
    let mut x: Vec<f64> = layout
        .parameters
        .iter()
        .enumerate()
        .map(|(i, info)| {
            let observed = match (info.kind, owner[i]) {
                (ParameterKind::RestLength, Some(b)) => observed_mean(&layout.bonds[b]),
                _ => None,
            };
            observed
                .or_else(|| start.get(i).copied().filter(|v| v.is_finite()))
                .unwrap_or(info.scale)
        })
        .collect();
    layout.clamp(&mut x);
    x
}

/// Simulated annealing of `cost` over the parameter vector described by `layout`, from
/// `start` (rest lengths are reset to their observed mean distance), with a seeded
/// `ChaCha8Rng` (same seed, same outcome).
///
/// Each step perturbs every parameter of one group (the springs' on even steps, the
/// torsions' on odd ones; the non-empty group every step if the other is empty) by
/// `N(0, (t * scale)^2)`, clamps the candidate into the layout's bounds (every evaluated
/// point is admissible), evaluates it, accepts it by the Metropolis rule described at
/// [`AnnealOptions::acceptance`] and cools that group's temperature by
/// [`AnnealOptions::cooling`]. The best set ever evaluated is returned; `history[k]` is the
/// best cost after step `k + 1`, and `cost_count` counts the start point's evaluation too.
pub fn anneal(
    cost: &dyn CostFunction,
    layout: &Layout,
    start: &[f64],
    options: &AnnealOptions,
    seed: u64,
    observer: &dyn Observer,
) -> SolverOutcome {
    let options = options.sanitized();
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut current = initial_point(layout, start);
    let mut current_cost = sane(cost.cost(&current));
    let mut outcome = SolverOutcome {
        best: current.clone(),
        best_cost: current_cost,
        history: Vec::new(),
        iteration_count: 0,
        cost_count: 1,
    };
    let groups: Vec<Vec<usize>> = [
        [ParameterKind::RestLength, ParameterKind::SpringStiffness],
        [ParameterKind::RestCos, ParameterKind::TorsionStiffness],
    ]
    .iter()
    .map(|kinds| {
        (0..layout.dimension())
            .filter(|&i| kinds.contains(&layout.parameters[i].kind))
            .collect()
    })
    .collect();
    let initial_temperature = [options.spring_temperature, options.torsion_temperature];
    let mut temperature = initial_temperature;
    let active: Vec<usize> = (0..groups.len()).filter(|&g| !groups[g].is_empty()).collect();
    if active.is_empty() || outcome.best_cost <= options.target_cost {
        return outcome;
    }
    let mut stagnation = Stagnation::new(
        options.stagnation,
        options.stagnation_tolerance,
        outcome.best_cost,
    );
    let mut candidate = current.clone();
    for step in 0..options.iterations {
        let g = active[step % active.len()];
        candidate.copy_from_slice(&current);
        for &i in &groups[g] {
            let noise: f64 = rng.sample(StandardNormal);
            candidate[i] += temperature[g] * layout.parameters[i].scale * noise;
        }
        layout.clamp(&mut candidate);
        let candidate_cost = sane(cost.cost(&candidate));
        outcome.cost_count += 1;
        let increase = candidate_cost - current_cost;
        let accept = if increase <= 0.0 {
            true
        } else {
            let cost_temperature =
                options.acceptance * outcome.best_cost * temperature[g] / initial_temperature[g];
            // A zero best cost (or an infinite candidate) leaves nothing worth a worse move.
            let p = if cost_temperature > 0.0 && increase.is_finite() {
                (-increase / cost_temperature).exp()
            } else {
                0.0
            };
            rng.gen::<f64>() < p
        };
        if accept {
            std::mem::swap(&mut current, &mut candidate);
            current_cost = candidate_cost;
            if current_cost < outcome.best_cost {
                outcome.best.copy_from_slice(&current);
                outcome.best_cost = current_cost;
            }
        }
        temperature[g] *= options.cooling;
        outcome.history.push(outcome.best_cost);
        outcome.iteration_count = step + 1;
        observer.observe(step, outcome.best_cost);
        let frozen = active.iter().all(|&g| temperature[g] < options.min_temperature);
        let stagnated = stagnation.record(outcome.best_cost);
        if outcome.best_cost <= options.target_cost || frozen || stagnated {
            break;
        }
    }
    outcome
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::solvers::testing::*;

    fn start_at_scales(toy: &Toy) -> Vec<f64> {
        toy.layout.parameters.iter().map(|p| p.scale).collect()
    }

    #[test]
    fn recovers_quadratic_couples_of_a_three_particle_object() {
        // 2 springs + 1 torsion: the paper's 3-particle object, 6 unknowns.
        let toy = Toy::new(2, 1, Shape::Quadratic);
        let out = anneal(
            &toy,
            &toy.layout,
            &start_at_scales(&toy),
            &AnnealOptions::default(),
            1,
            &(),
        );
        assert!(
            toy.max_error(&out.best) < 1e-3,
            "max error {}",
            toy.max_error(&out.best)
        );
    }

    #[test]
    fn recovers_rosenbrock_couples_within_two_percent() {
        // A curved valley per bond: the correlated (L, S) couple of a spring under a one-step cost.
        let toy = Toy::new(2, 1, Shape::Rosenbrock);
        for seed in 0..3 {
            let out = anneal(
                &toy,
                &toy.layout,
                &start_at_scales(&toy),
                &AnnealOptions::default(),
                seed,
                &(),
            );
            assert!(
                toy.max_error(&out.best) < 0.02,
                "seed {seed}: max error {}",
                toy.max_error(&out.best)
            );
        }
    }

    #[test]
    fn same_seed_is_bitwise_identical_and_another_seed_differs() {
        let toy = Toy::new(2, 1, Shape::Rosenbrock);
        let options = AnnealOptions {
            iterations: 3000,
            ..Default::default()
        };
        let start = start_at_scales(&toy);
        let a = anneal(&toy, &toy.layout, &start, &options, 7, &());
        let b = anneal(&toy, &toy.layout, &start, &options, 7, &());
        let c = anneal(&toy, &toy.layout, &start, &options, 8, &());
        assert_eq!(bits(&a.best), bits(&b.best));
        assert_eq!(bits(&a.history), bits(&b.history));
        assert_eq!(a.cost_count, b.cost_count);
        assert_ne!(bits(&a.history), bits(&c.history));
    }

    #[test]
    fn every_evaluated_point_is_within_bounds_and_counted() {
        let mut toy = Toy::new(2, 1, Shape::Quadratic);
        // The first stiffness's optimum lies above its upper bound: the answer must sit on it.
        let upper = 0.8 * toy.truth[1];
        toy.layout.parameters[1].bounds = [0.0, upper];
        let checked = Checked::new(&toy);
        let recorder = Recorder::default();
        let out = anneal(
            &checked,
            &toy.layout,
            &start_at_scales(&toy),
            &AnnealOptions::default(),
            3,
            &recorder,
        );
        assert!(!checked.out_of_bounds.load(std::sync::atomic::Ordering::Relaxed));
        assert_eq!(
            out.cost_count,
            checked.evaluations.load(std::sync::atomic::Ordering::Relaxed)
        );
        assert!(
            (out.best[1] - upper).abs() < 1e-3 * upper,
            "{} vs bound {upper}",
            out.best[1]
        );
        // The observer saw every step, and the history never rises.
        let seen = recorder.0.lock().map(|v| v.len()).unwrap_or(0);
        assert_eq!(seen, out.iteration_count);
        assert!(out.history.windows(2).all(|w| w[1] <= w[0]));
    }

    #[test]
    fn rest_lengths_start_at_the_observed_mean_and_others_at_start() {
        let toy = Toy::new(2, 1, Shape::Quadratic);
        let start: Vec<f64> = toy
            .layout
            .parameters
            .iter()
            .enumerate()
            .map(|(i, p)| 0.5 * p.scale + 0.01 * i as f64)
            .collect();
        let options = AnnealOptions {
            iterations: 0,
            ..Default::default()
        };
        let out = anneal(&toy, &toy.layout, &start, &options, 0, &());
        for bond in &toy.layout.bonds {
            let mean = bond.observed.iter().sum::<f64>() / bond.observed.len() as f64;
            let [l, s] = [bond.params[0], bond.params[1]];
            if matches!(bond.bond, crate::BondRef::Spring(_)) {
                assert!((out.best[l] - mean).abs() < 1e-12);
            } else {
                assert!((out.best[l] - start[l]).abs() < 1e-12);
            }
            assert!((out.best[s] - start[s]).abs() < 1e-12);
        }
        assert_eq!(out.cost_count, 1);
    }

    #[test]
    fn stops_on_target_and_on_stagnation() {
        let toy = Toy::new(2, 1, Shape::Quadratic);
        let start = start_at_scales(&toy);
        let options = AnnealOptions {
            target_cost: 1e-2,
            ..Default::default()
        };
        let out = anneal(&toy, &toy.layout, &start, &options, 4, &());
        assert!(out.best_cost <= 1e-2);
        assert!(out.history[..out.iteration_count - 1].iter().all(|&c| c > 1e-2));
        assert!(out.iteration_count < options.iterations);

        let flat = Flat(toy.layout.dimension());
        let options = AnnealOptions {
            stagnation: 50,
            ..Default::default()
        };
        let out = anneal(&flat, &toy.layout, &start, &options, 4, &());
        assert_eq!(out.iteration_count, 50);
        assert_eq!(out.cost_count, 51);
    }

    #[test]
    fn validate_names_the_bad_option() {
        assert!(AnnealOptions::default().validate().is_ok());
        let cases = [
            AnnealOptions {
                spring_temperature: 0.0,
                ..Default::default()
            },
            AnnealOptions {
                torsion_temperature: -1.0,
                ..Default::default()
            },
            AnnealOptions {
                cooling: 1.0,
                ..Default::default()
            },
            AnnealOptions {
                acceptance: f64::NAN,
                ..Default::default()
            },
            AnnealOptions {
                min_temperature: 0.5,
                ..Default::default()
            },
        ];
        let names = [
            "spring_temperature",
            "torsion_temperature",
            "cooling",
            "acceptance",
            "min_temperature",
        ];
        for (options, name) in cases.iter().zip(names) {
            let err = options.validate().unwrap_err();
            assert!(err.to_string().contains(name), "{err} should name {name}");
        }
    }
}
