//! [`genetic`] and [`genetic_local`]: the paper's real-coded genetic algorithm, global and
//! local.
//!
//! BMVC 1994 section 3-3 (`MODEL.md` section 4). An individual is the parameter vector itself
//! (real values, not a bit string). The initial population is drawn at random within ranges
//! derived from the data. Each generation:
//! 1. the population is sorted by cost;
//! 2. crossover: the worst `crossover` fraction is erased and rebuilt bond by bond, each
//!    bond's couple `(L, S)` or `(M, T)` copied together from a parent drawn among the
//!    survivors with a rank bias toward the better ones;
//! 3. mutation: for each parameter, about `mutation * population` individuals drawn from the
//!    worst 95% have that parameter multiplied by `1 + noise` (standard deviation: the
//!    mutation temperature, which shrinks with the square root of the best cost's fall, since
//!    a quadratic cost falls with the square of the parameter error); a second mutation sets a
//!    spring's rest length to one of the distances observed between its two particles;
//! 4. elitism: the best `elite` fraction is neither erased nor mutated, so the best cost never
//!    rises.
//!
//! The local version (the paper's "local cost functions") sorts the population once per
//! region (particle) by that region's local cost and runs steps 2-3 per region on that
//! region's bonds only, so a bond is selected on how well it explains its own neighbourhood
//! rather than the whole object; the global cost (the sum of the local costs) picks the elite
//! and the best individual. The number of generations then hardly grows with the object.
//!
//! Costs of changed individuals are evaluated in parallel (rayon); every random draw comes
//! sequentially from one seeded `ChaCha8Rng`, so a seed gives the same outcome whatever the
//! thread count.

use super::stopping::Stagnation;
use super::{check_option, finite_observed, is_rest_length, observed_range, parameter_bonds, sane, SolverError};
use crate::{BondGenes, CostFunction, Layout, LocalCostFunction, Observer, Parameter, ParameterKind, SolverOutcome};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// Settings of [`genetic`] and [`genetic_local`]. Proportions are fractions of the population
/// (dimensionless); temperatures are relative standard deviations (dimensionless).
///
/// Build it from [`GaOptions::default`] (the paper's values) and check it with
/// [`GaOptions::validate`]; the solvers bring out-of-range values into range rather than fail.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct GaOptions {
    /// Number of individuals (the paper: 100-200); >= 4. Default 150.
    pub population: usize,
    /// Proportion `pc` of the population erased and rebuilt by crossover each generation (the
    /// paper: 30-60%); in [0, 1). Default 0.5.
    pub crossover: f64,
    /// Proportion `pm` of mutations: each parameter is mutated in about
    /// `mutation * population` individuals per generation (the paper: 1-5%); in [0, 1].
    /// Default 0.03.
    pub mutation: f64,
    /// Proportion of rest-length mutations: each spring's rest length is reset to one of its
    /// observed distances in about `rest_length_mutation * population` individuals per
    /// generation; in [0, 1]. Default 0.03.
    pub rest_length_mutation: f64,
    /// Proportion of the best individuals (by global cost) that are never erased or mutated;
    /// in (0, 0.5]. At least one individual is always kept. Default 0.05.
    pub elite: f64,
    /// Rank bias of parent selection, >= 1: a parent is the survivor of rank
    /// `floor(count * u^selection_pressure)` for `u` uniform in [0, 1) (rank 0 the best), so
    /// 1 is unbiased and 2 makes the best half supply about 71% of the genes. Default 2.
    pub selection_pressure: f64,
    /// Maximum number of generations. Default 400.
    pub generations: usize,
    /// Initial mutation temperature: the standard deviation of the multiplicative noise
    /// `1 + noise`; finite and > 0. Default 0.1.
    pub mutation_temperature: f64,
    /// Smallest mutation temperature, reached as the cost falls (the temperature is
    /// `mutation_temperature * sqrt(best_cost / initial_best_cost)`, per region in the local
    /// version, floored here); in (0, mutation_temperature]. Setting it equal to
    /// `mutation_temperature` keeps the temperature constant. Default 1e-3.
    pub min_mutation_temperature: f64,
    /// Width of the initial stiffness draw: stiffnesses start log-uniform in
    /// `[scale / stiffness_range, scale * stiffness_range]`; finite and >= 1. Default 100.
    pub stiffness_range: f64,
    /// The search stops as soon as the best cost is at or below this. Default 0.
    pub target_cost: f64,
    /// The search stops after this many generations without the best cost improving by more
    /// than `stagnation_tolerance` (relative); 0 never stops on stagnation. Default 80.
    pub stagnation: usize,
    /// Relative decrease of the best cost that counts as an improvement; >= 0. Default 1e-9.
    pub stagnation_tolerance: f64,
}

impl Default for GaOptions {
    fn default() -> Self {
        GaOptions {
            population: 150,
            crossover: 0.5,
            mutation: 0.03,
            rest_length_mutation: 0.03,
            elite: 0.05,
            selection_pressure: 2.0,
            generations: 400,
            mutation_temperature: 0.1,
            min_mutation_temperature: 1e-3,
            stiffness_range: 100.0,
            target_cost: 0.0,
            stagnation: 80,
            stagnation_tolerance: 1e-9,
        }
    }
}

impl GaOptions {
    /// Checks every option's range; the error names the first option out of range.
    pub fn validate(&self) -> Result<(), SolverError> {
        let fraction = |x: f64| (0.0..=1.0).contains(&x);
        check_option("population", self.population as f64, self.population >= 4, ">= 4")?;
        check_option(
            "crossover",
            self.crossover,
            (0.0..1.0).contains(&self.crossover),
            "in [0, 1)",
        )?;
        check_option("mutation", self.mutation, fraction(self.mutation), "in [0, 1]")?;
        check_option(
            "rest_length_mutation",
            self.rest_length_mutation,
            fraction(self.rest_length_mutation),
            "in [0, 1]",
        )?;
        check_option("elite", self.elite, self.elite > 0.0 && self.elite <= 0.5, "in (0, 0.5]")?;
        check_option(
            "selection_pressure",
            self.selection_pressure,
            self.selection_pressure.is_finite() && self.selection_pressure >= 1.0,
            "finite and >= 1",
        )?;
        check_option(
            "mutation_temperature",
            self.mutation_temperature,
            self.mutation_temperature.is_finite() && self.mutation_temperature > 0.0,
            "finite and > 0",
        )?;
        check_option(
            "min_mutation_temperature",
            self.min_mutation_temperature,
            self.min_mutation_temperature > 0.0 && self.min_mutation_temperature <= self.mutation_temperature,
            "in (0, mutation_temperature]",
        )?;
        check_option(
            "stiffness_range",
            self.stiffness_range,
            self.stiffness_range.is_finite() && self.stiffness_range >= 1.0,
            "finite and >= 1",
        )?;
        check_option("target_cost", self.target_cost, !self.target_cost.is_nan(), "a number")?;
        check_option(
            "stagnation_tolerance",
            self.stagnation_tolerance,
            self.stagnation_tolerance.is_finite() && self.stagnation_tolerance >= 0.0,
            "finite and >= 0",
        )
    }

    /// A copy with every out-of-range value replaced by the nearest admissible one (or the
    /// default), so that the solvers never fail on their options.
    fn sanitized(&self) -> GaOptions {
        let d = GaOptions::default();
        let in_or = |x: f64, lo: f64, hi: f64, default: f64| if x >= lo && x <= hi { x } else { default };
        let mutation_temperature = if self.mutation_temperature.is_finite() && self.mutation_temperature > 0.0 {
            self.mutation_temperature
        } else {
            d.mutation_temperature
        };
        GaOptions {
            population: self.population.max(4),
            crossover: in_or(self.crossover, 0.0, 0.999, d.crossover),
            mutation: in_or(self.mutation, 0.0, 1.0, d.mutation),
            rest_length_mutation: in_or(self.rest_length_mutation, 0.0, 1.0, d.rest_length_mutation),
            elite: in_or(self.elite, f64::MIN_POSITIVE, 0.5, d.elite),
            selection_pressure: in_or(self.selection_pressure, 1.0, 1e6, d.selection_pressure),
            generations: self.generations,
            mutation_temperature,
            min_mutation_temperature: in_or(
                self.min_mutation_temperature,
                f64::MIN_POSITIVE,
                mutation_temperature,
                d.min_mutation_temperature.min(mutation_temperature),
            ),
            stiffness_range: in_or(self.stiffness_range, 1.0, f64::MAX, d.stiffness_range),
            target_cost: if self.target_cost.is_nan() { d.target_cost } else { self.target_cost },
            stagnation: self.stagnation,
            stagnation_tolerance: in_or(self.stagnation_tolerance, 0.0, f64::MAX, d.stagnation_tolerance),
        }
    }
}

/// The paper's global genetic algorithm on `cost`, over the parameter vector described by
/// `layout`, with a seeded `ChaCha8Rng` (same seed, same outcome, whatever the thread count).
///
/// `history[g]` is the best cost after generation `g + 1` (never rising, by elitism);
/// `cost_count` counts every evaluation, the initial population's included (an individual
/// left unchanged by a generation is not evaluated again).
pub fn genetic(
    cost: &dyn CostFunction,
    layout: &Layout,
    options: &GaOptions,
    seed: u64,
    observer: &dyn Observer,
) -> SolverOutcome {
    run(Fitness::Global(cost), layout, options, seed, observer)
}

/// The paper's local genetic algorithm: as [`genetic`], but each region `r` of `cost` sorts
/// the population by its own local cost, and crossover and mutation for `r` act only on the
/// bonds holding a parameter of [`LocalCostFunction::region_parameters`]`(r)`; the global
/// cost (the sum of the local costs) chooses the elite and the best individual.
///
/// Regions are processed in order within a generation, each sorted by the local costs the
/// generation started with, so a bond shared by several regions can be rebuilt and mutated by
/// each of them. One call of [`LocalCostFunction::local_costs`] counts as one cost
/// evaluation. With no regions it is the global algorithm.
pub fn genetic_local(
    cost: &dyn LocalCostFunction,
    layout: &Layout,
    options: &GaOptions,
    seed: u64,
    observer: &dyn Observer,
) -> SolverOutcome {
    let fitness = if cost.region_count() == 0 { Fitness::Whole(cost) } else { Fitness::Local(cost) };
    run(fitness, layout, options, seed, observer)
}

/// What sorts the population: one global cost, or one local cost per region.
#[derive(Clone, Copy)]
enum Fitness<'a> {
    /// A single cost.
    Global(&'a dyn CostFunction),
    /// Per-region local costs.
    Local(&'a dyn LocalCostFunction),
    /// A local cost function with no regions, used through its global cost.
    Whole(&'a dyn LocalCostFunction),
}

impl Fitness<'_> {
    /// Number of sorting criteria (1 for a global cost).
    fn region_count(&self) -> usize {
        match self {
            Fitness::Local(c) => c.region_count().max(1),
            Fitness::Global(_) | Fitness::Whole(_) => 1,
        }
    }

    /// Writes the sorting costs of `x` into `out` (length [`Fitness::region_count`]).
    fn evaluate(&self, x: &[f64], out: &mut [f64]) {
        match self {
            Fitness::Global(c) => out[0] = c.cost(x),
            Fitness::Whole(c) => out[0] = c.cost(x),
            Fitness::Local(c) => c.local_costs(x, out),
        }
    }
}

/// A bond's unknowns, copied together by crossover.
struct Gene {
    /// Parameter indices.
    params: Vec<usize>,
    /// The rest length's parameter index and the spring's finite observed distances (px),
    /// for the rest-length mutation.
    rest_length: Option<(usize, Vec<f64>)>,
}

/// What one sorting criterion acts on.
struct Region {
    /// Parameters mutated for this region.
    params: Vec<usize>,
    /// Genes (bonds) rebuilt by this region's crossover.
    genes: Vec<usize>,
}

/// The population with its cached costs.
struct Population {
    /// Parameter vectors.
    genomes: Vec<Vec<f64>>,
    /// Sorting costs, `regions` per individual, individual-major.
    locals: Vec<f64>,
    /// Global cost per individual (sum of its local costs).
    global: Vec<f64>,
    /// True if and only if the individual changed since its costs were computed.
    dirty: Vec<bool>,
}

impl Population {
    /// Evaluates every changed individual in parallel; returns how many were evaluated.
    fn evaluate(&mut self, fitness: Fitness<'_>, regions: usize) -> usize {
        let count = self.dirty.iter().filter(|&&d| d).count();
        self.genomes
            .par_iter()
            .zip(self.locals.par_chunks_mut(regions))
            .zip(self.global.par_iter_mut())
            .zip(self.dirty.par_iter_mut())
            .for_each(|(((x, local), global), dirty)| {
                if *dirty {
                    fitness.evaluate(x, local);
                    local.iter_mut().for_each(|c| *c = sane(*c));
                    *global = sane(local.iter().sum());
                    *dirty = false;
                }
            });
        count
    }

    /// Index of the individual with the lowest global cost (the first on ties).
    fn best(&self) -> usize {
        (0..self.global.len())
            .min_by(|&a, &b| self.global[a].total_cmp(&self.global[b]).then(a.cmp(&b)))
            .unwrap_or(0)
    }
}

/// The gene list: every bond of the layout, then a single-parameter gene for any parameter no
/// bond claims.
fn genes(layout: &Layout) -> Vec<Gene> {
    let d = layout.dimension();
    let mut genes: Vec<Gene> = layout
        .bonds
        .iter()
        .map(|bond| {
            let params: Vec<usize> = bond.params.iter().copied().filter(|&p| p < d).collect();
            let rest_length = params.iter().copied().find(|&p| is_rest_length(layout, p)).and_then(|p| {
                let observed: Vec<f64> = finite_observed(bond).filter(|&v| v > 0.0).collect();
                (!observed.is_empty()).then_some((p, observed))
            });
            Gene { params, rest_length }
        })
        .filter(|g| !g.params.is_empty())
        .collect();
    let owner = parameter_bonds(layout);
    genes.extend((0..d).filter(|&p| owner[p].is_none()).map(|p| Gene {
        params: vec![p],
        rest_length: None,
    }));
    genes
}

/// Region `params`' region: those parameters and every gene holding one of them.
fn region(genes: &[Gene], params: &[usize]) -> Region {
    Region {
        params: params.to_vec(),
        genes: (0..genes.len()).filter(|&g| genes[g].params.iter().any(|p| params.contains(p))).collect(),
    }
}

/// `x` clamped into a parameter's bounds (never panics on inverted bounds).
fn clamp_to(info: &Parameter, x: f64) -> f64 {
    x.max(info.bounds[0]).min(info.bounds[1])
}

/// A uniform draw in `[lo, hi]`.
fn uniform(rng: &mut ChaCha8Rng, lo: f64, hi: f64) -> f64 {
    lo + (hi - lo) * rng.gen::<f64>()
}

/// A random initial value for one parameter, from the data: rest lengths uniform over the
/// observed distances widened by 10%, rest cosines uniform over the observed cosines widened
/// by 0.1, stiffnesses log-uniform over `[scale / range, scale * range]`; then clamped into
/// bounds.
fn random_value(info: &Parameter, bond: Option<&BondGenes>, range: f64, rng: &mut ChaCha8Rng) -> f64 {
    let observed = bond.and_then(observed_range);
    let x = match info.kind {
        ParameterKind::RestLength => {
            let [lo, hi] = observed.map_or([0.5 * info.scale, 1.5 * info.scale], |[a, b]| [0.9 * a, 1.1 * b]);
            uniform(rng, lo, hi)
        }
        ParameterKind::RestCos => {
            let [lo, hi] = observed.map_or([-1.0, 1.0], |[a, b]| [a - 0.1, b + 0.1]);
            uniform(rng, lo.max(-1.0), hi.min(1.0))
        }
        ParameterKind::SpringStiffness | ParameterKind::TorsionStiffness => {
            let u = uniform(rng, -1.0, 1.0);
            if info.scale.is_finite() && info.scale > 0.0 {
                info.scale * range.powf(u)
            } else {
                // No scale from the data: fall back on the bounds (or 1 if they are open).
                let [lo, hi] = info.bounds;
                if lo.is_finite() && hi.is_finite() {
                    lo + (hi - lo) * 0.5 * (u + 1.0)
                } else {
                    1.0
                }
            }
        }
    };
    clamp_to(info, x)
}

/// How many draws to make for an expected count `expected` (floor, plus one with the
/// fractional part's probability).
fn draw_count(rng: &mut ChaCha8Rng, expected: f64) -> usize {
    let whole = expected.floor();
    whole as usize + usize::from(rng.gen::<f64>() < expected - whole)
}

/// The mutation of one value: `x (1 + t noise)`, with `|x|` floored at `floor` so that a value
/// at zero (a stiffness on its bound, a rest cosine near 0) can still move.
fn mutate(x: f64, t: f64, floor: f64, noise: f64) -> f64 {
    x + t * noise * x.abs().max(floor)
}

/// The genetic algorithm proper, for either fitness.
struct Engine<'a> {
    layout: &'a Layout,
    options: GaOptions,
    genes: Vec<Gene>,
    regions: Vec<Region>,
    /// Per parameter, the smallest magnitude a multiplicative mutation acts on.
    mutation_floor: Vec<f64>,
}

impl Engine<'_> {
    /// Steps 2-4 of one generation (the sort of step 1 included), given each region's
    /// mutation temperature.
    fn breed(&self, pop: &mut Population, rng: &mut ChaCha8Rng, temperature: &[f64]) {
        let n = pop.genomes.len();
        let regions = self.regions.len();
        let elite_count = ((self.options.elite * n as f64).ceil() as usize).clamp(1, n - 1);
        let erase_count = ((self.options.crossover * n as f64).round() as usize).min(n - elite_count);
        let mut global_order: Vec<usize> = (0..n).collect();
        global_order.sort_by(|&a, &b| pop.global[a].total_cmp(&pop.global[b]).then(a.cmp(&b)));
        let mut elite = vec![false; n];
        for &i in &global_order[..elite_count] {
            elite[i] = true;
        }
        let per_parameter = self.options.mutation * n as f64;
        let per_rest_length = self.options.rest_length_mutation * n as f64;
        for (r, region) in self.regions.iter().enumerate() {
            let order = if regions == 1 {
                global_order.clone()
            } else {
                let mut order: Vec<usize> = (0..n).collect();
                order.sort_by(|&a, &b| {
                    pop.locals[a * regions + r]
                        .total_cmp(&pop.locals[b * regions + r])
                        .then(pop.global[a].total_cmp(&pop.global[b]))
                        .then(a.cmp(&b))
                });
                order
            };

            // Crossover: the worst non-elite individuals are rebuilt gene by gene from survivors.
            let mut erased = vec![false; n];
            let children: Vec<usize> =
                order.iter().rev().copied().filter(|&i| !elite[i]).take(erase_count).collect();
            for &c in &children {
                erased[c] = true;
            }
            let parents: Vec<usize> = order.iter().copied().filter(|&i| !erased[i]).collect();
            for &child in &children {
                for &g in &region.genes {
                    let u: f64 = rng.gen();
                    let rank = ((parents.len() as f64 * u.powf(self.options.selection_pressure)) as usize)
                        .min(parents.len() - 1);
                    let parent = parents[rank];
                    for &p in &self.genes[g].params {
                        pop.genomes[child][p] = pop.genomes[parent][p];
                    }
                }
                pop.dirty[child] = true;
            }

            // Mutation: individuals outside this region's best 5% and outside the global elite.
            let candidates: Vec<usize> = order[elite_count..].iter().copied().filter(|&i| !elite[i]).collect();
            if candidates.is_empty() {
                continue;
            }
            for &p in &region.params {
                for _ in 0..draw_count(rng, per_parameter) {
                    let i = candidates[rng.gen_range(0..candidates.len())];
                    let noise: f64 = rng.sample(StandardNormal);
                    let x = mutate(pop.genomes[i][p], temperature[r], self.mutation_floor[p], noise);
                    pop.genomes[i][p] = clamp_to(&self.layout.parameters[p], x);
                    pop.dirty[i] = true;
                }
            }
            for &g in &region.genes {
                let Some((p, observed)) = &self.genes[g].rest_length else { continue };
                for _ in 0..draw_count(rng, per_rest_length) {
                    let i = candidates[rng.gen_range(0..candidates.len())];
                    let x = observed[rng.gen_range(0..observed.len())];
                    pop.genomes[i][*p] = clamp_to(&self.layout.parameters[*p], x);
                    pop.dirty[i] = true;
                }
            }
        }
    }
}

/// Each region's mutation temperature: `t0 sqrt(best / reference)` within `[t_min, t0]`,
/// where `reference` is the region's first finite, positive best local cost.
fn temperatures(pop: &Population, reference: &mut [f64], options: &GaOptions) -> Vec<f64> {
    let regions = reference.len();
    (0..regions)
        .map(|r| {
            let best = (0..pop.global.len()).map(|i| pop.locals[i * regions + r]).fold(f64::INFINITY, f64::min);
            if !(reference[r].is_finite() && reference[r] > 0.0) && best.is_finite() && best > 0.0 {
                reference[r] = best;
            }
            let ratio = if reference[r].is_finite() && reference[r] > 0.0 && best.is_finite() {
                (best / reference[r]).sqrt()
            } else {
                1.0
            };
            (options.mutation_temperature * ratio)
                .clamp(options.min_mutation_temperature, options.mutation_temperature)
        })
        .collect()
}

/// Runs the genetic algorithm with either fitness.
fn run(fitness: Fitness<'_>, layout: &Layout, options: &GaOptions, seed: u64, observer: &dyn Observer) -> SolverOutcome {
    let options = options.sanitized();
    let d = layout.dimension();
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let genes = genes(layout);
    let all: Vec<usize> = (0..d).collect();
    let regions: Vec<Region> = match fitness {
        Fitness::Local(c) => (0..c.region_count())
            .map(|r| {
                let params: Vec<usize> = c.region_parameters(r).iter().copied().filter(|&p| p < d).collect();
                region(&genes, &params)
            })
            .collect(),
        Fitness::Global(_) | Fitness::Whole(_) => vec![region(&genes, &all)],
    };
    let region_count = fitness.region_count();
    let owner = parameter_bonds(layout);
    let n = options.population;
    let genomes: Vec<Vec<f64>> = (0..n)
        .map(|_| {
            layout
                .parameters
                .iter()
                .enumerate()
                .map(|(p, info)| {
                    let bond = owner[p].map(|b| &layout.bonds[b]);
                    random_value(info, bond, options.stiffness_range, &mut rng)
                })
                .collect()
        })
        .collect();
    let mut pop = Population {
        genomes,
        locals: vec![0.0; n * region_count],
        global: vec![0.0; n],
        dirty: vec![true; n],
    };
    let mut outcome = SolverOutcome {
        cost_count: pop.evaluate(fitness, region_count),
        ..SolverOutcome::default()
    };
    let mut best = pop.best();
    outcome.best_cost = pop.global[best];
    let mutation_floor = layout
        .parameters
        .iter()
        .map(|info| {
            let scale = if info.scale.is_finite() { info.scale.abs() } else { 1.0 };
            match info.kind {
                // Cosines cross zero, where a purely multiplicative change is stuck.
                ParameterKind::RestCos => scale,
                _ => 0.01 * scale,
            }
        })
        .collect();
    let engine = Engine {
        layout,
        options: options.clone(),
        genes,
        regions,
        mutation_floor,
    };
    let mut reference = vec![f64::NAN; region_count];
    let mut stagnation = Stagnation::new(options.stagnation, options.stagnation_tolerance, outcome.best_cost);
    if d > 0 && outcome.best_cost > options.target_cost {
        for generation in 0..options.generations {
            let temperature = temperatures(&pop, &mut reference, &options);
            engine.breed(&mut pop, &mut rng, &temperature);
            outcome.cost_count += pop.evaluate(fitness, region_count);
            best = pop.best();
            outcome.best_cost = pop.global[best];
            outcome.history.push(outcome.best_cost);
            outcome.iteration_count = generation + 1;
            observer.observe(generation, outcome.best_cost);
            let stagnated = stagnation.record(outcome.best_cost);
            if outcome.best_cost <= options.target_cost || stagnated {
                break;
            }
        }
    }
    outcome.best = pop.genomes.swap_remove(best);
    outcome
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::solvers::testing::*;

    #[test]
    fn validate_names_the_bad_option() {
        assert!(GaOptions::default().validate().is_ok());
        let cases = [
            (GaOptions { population: 2, ..Default::default() }, "population"),
            (GaOptions { crossover: 1.0, ..Default::default() }, "crossover"),
            (GaOptions { mutation: -0.1, ..Default::default() }, "mutation"),
            (GaOptions { elite: 0.0, ..Default::default() }, "elite"),
            (GaOptions { selection_pressure: 0.5, ..Default::default() }, "selection_pressure"),
            (GaOptions { min_mutation_temperature: 0.2, ..Default::default() }, "min_mutation_temperature"),
        ];
        for (options, name) in cases {
            let err = options.validate().unwrap_err();
            assert!(err.to_string().contains(name), "{err} should name {name}");
        }
    }
}
