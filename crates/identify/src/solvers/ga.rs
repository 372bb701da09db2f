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
//!    mutation temperature, see [`MutationSchedule`]); a second mutation sets a spring's rest
//!    length to one of the distances observed between its two particles;
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
use super::{
    check_option, finite_observed, is_rest_length, observed_mean, observed_range, parameter_bonds, sane,
    SolverError,
};
use crate::{
    BondGenes, CostFunction, Layout, LocalCostFunction, Observer, Parameter, ParameterKind, SolverOutcome,
};
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
    /// Maximum number of generations. Default 1000.
    pub generations: usize,
    /// Largest mutation temperature: the standard deviation of the multiplicative noise
    /// `1 + noise`; finite and > 0. Default 0.3.
    pub mutation_temperature: f64,
    /// Smallest mutation temperature; in (0, mutation_temperature]. Setting it equal to
    /// `mutation_temperature` keeps the temperature constant. Default 1e-4.
    pub min_mutation_temperature: f64,
    /// How the temperature of a mutation is chosen between the two above. Default
    /// [`MutationSchedule::Spread`].
    pub schedule: MutationSchedule,
    /// Width of the initial stiffness draw: stiffnesses start log-uniform in
    /// `[scale / stiffness_range, scale * stiffness_range]`; finite and >= 1. Default 100.
    pub stiffness_range: f64,
    /// The search stops as soon as the best cost is at or below this. Default 0.
    pub target_cost: f64,
    /// The search stops after this many generations without the best cost improving by more
    /// than `stagnation_tolerance` (relative); 0 never stops on stagnation. Default 100.
    pub stagnation: usize,
    /// Relative decrease of the best cost that counts as an improvement; >= 0. Default 1e-9.
    pub stagnation_tolerance: f64,
    /// Mutates a bond with both values unknown in its *pre-stress coordinates*: a stiffness
    /// `K` is mutated keeping the bond's mean force `K (g_mean - R)` (`g_mean` its observed
    /// mean distance or cosine, `R` its rest value), and a rest value by mutating its offset
    /// `g_mean - R` from the observed mean. The force `K (g - R)` of a bond that moves a little
    /// about `g_mean` is set by these two almost independently, whereas a plain mutation of `K`
    /// also changes the mean force by `dK (g_mean - R)`: the couple `(R, K)` is then a narrow
    /// diagonal valley that mutations along the axes cross instead of following. Default true.
    pub prestress_mutation: bool,
    /// Fraction of the children rebuilt by crossover that also take a *differential* step: the
    /// difference of two random survivors (over the region's parameters), times a factor
    /// uniform in [0.4, 0.9]. It moves along the directions the population is spread in, which
    /// for a sloppy cost are its long valleys; in [0, 1]. Default 0.5.
    pub differential: f64,
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
            generations: 1000,
            mutation_temperature: 0.3,
            min_mutation_temperature: 1e-4,
            schedule: MutationSchedule::Spread,
            stiffness_range: 100.0,
            target_cost: 0.0,
            stagnation: 100,
            stagnation_tolerance: 1e-9,
            prestress_mutation: true,
            differential: 0.5,
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
        check_option(
            "elite",
            self.elite,
            self.elite > 0.0 && self.elite <= 0.5,
            "in (0, 0.5]",
        )?;
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
        super::stopping::check_stopping_options(self.target_cost, self.stagnation_tolerance)
    }

    /// A copy with every out-of-range value replaced by the nearest admissible one (or the
    /// default), so that the solvers never fail on their options.
    fn sanitized(&self) -> GaOptions {
        let d = GaOptions::default();
        let in_or = |x: f64, lo: f64, hi: f64, default: f64| if x >= lo && x <= hi { x } else { default };
        let mutation_temperature = if self.mutation_temperature.is_finite() && self.mutation_temperature > 0.0
        {
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
            schedule: self.schedule,
            stiffness_range: in_or(self.stiffness_range, 1.0, f64::MAX, d.stiffness_range),
            target_cost: if self.target_cost.is_nan() {
                d.target_cost
            } else {
                self.target_cost
            },
            stagnation: self.stagnation,
            stagnation_tolerance: in_or(self.stagnation_tolerance, 0.0, f64::MAX, d.stagnation_tolerance),
            prestress_mutation: self.prestress_mutation,
            differential: in_or(self.differential, 0.0, 1.0, d.differential),
        }
    }
}

/// How a mutation's temperature (the standard deviation of its multiplicative noise) is chosen.
///
/// The paper lets the temperature "decrease under the control of the cost function" but warns
/// it should not be decreased as systematically as in annealing. On the paper's 5-particle
/// object (one-step cost, exact data) the cost is far more sensitive to rest lengths than to
/// stiffnesses: at the optimum the curvature per unit relative error differs by about 4e4
/// between them. A single temperature that follows the cost shrinks to suit the rest lengths
/// and then moves the stiffnesses too little: [`MutationSchedule::FollowCost`] left 10-50%
/// errors after 400 generations where [`MutationSchedule::Spread`] reaches under 2% in 1000.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum MutationSchedule {
    /// Each mutation draws its temperature log-uniformly between `min_mutation_temperature`
    /// and `mutation_temperature`, so every scale of step is always tried (a temperature that
    /// never decreases systematically, for parameters of very different sensitivities).
    #[default]
    Spread,
    /// The temperature is `mutation_temperature * sqrt(best / first_best)` (per region in the
    /// local version), within `[min_mutation_temperature, mutation_temperature]`: the cost is
    /// quadratic in the parameter error near the optimum, so the square root tracks the error.
    FollowCost,
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
/// A region's parameters may include bonds its local cost barely depends on (a particle's
/// one-step cost reaches the bonds of its second neighbours' neighbours); selecting a bond on
/// such a cost is selecting it on noise. So, once, at the best initial individual, each bond is
/// moved by 10% and kept only in the regions (among those holding it) whose local cost moves
/// at least half as much as the most affected one's: one extra evaluation per bond. On chains
/// of 8 and 12 particles under the one-step cost this cut the error after 800 generations from
/// 112% and 161% to 12% and 48%.
///
/// Regions are processed in order within a generation, each sorted by the local costs the
/// generation started with, so a bond shared by several regions can be rebuilt by each of
/// them; a parameter shared by `k` regions gets `1/k` of its mutations from each, so it is
/// mutated as often as in the global version. One call of
/// [`LocalCostFunction::local_costs`] counts as one cost evaluation. With no regions it is the
/// global algorithm.
pub fn genetic_local(
    cost: &dyn LocalCostFunction,
    layout: &Layout,
    options: &GaOptions,
    seed: u64,
    observer: &dyn Observer,
) -> SolverOutcome {
    let fitness = if cost.region_count() == 0 {
        Fitness::Whole(cost)
    } else {
        Fitness::Local(cost)
    };
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
    /// For a bond with both values unknown: its rest value's and stiffness's parameter indices
    /// and its observed mean geometry (px or cosine), for the pre-stress mutation.
    couple: Option<Couple>,
}

/// A bond's rest value and stiffness, with its observed mean geometry.
#[derive(Clone, Copy)]
struct Couple {
    rest: usize,
    stiffness: usize,
    mean: f64,
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
            let rest_length = params
                .iter()
                .copied()
                .find(|&p| is_rest_length(layout, p))
                .and_then(|p| {
                    let observed: Vec<f64> = finite_observed(bond).filter(|&v| v > 0.0).collect();
                    (!observed.is_empty()).then_some((p, observed))
                });
            let kind = |p: usize| layout.parameters[p].kind;
            let rest = params
                .iter()
                .copied()
                .find(|&p| matches!(kind(p), ParameterKind::RestLength | ParameterKind::RestCos));
            let stiffness = params.iter().copied().find(|&p| {
                matches!(
                    kind(p),
                    ParameterKind::SpringStiffness | ParameterKind::TorsionStiffness
                )
            });
            let couple = match (rest, stiffness, observed_mean(bond)) {
                (Some(rest), Some(stiffness), Some(mean)) => Some(Couple {
                    rest,
                    stiffness,
                    mean,
                }),
                _ => None,
            };
            Gene {
                params,
                rest_length,
                couple,
            }
        })
        .filter(|g| !g.params.is_empty())
        .collect();
    let owner = parameter_bonds(layout);
    genes.extend((0..d).filter(|&p| owner[p].is_none()).map(|p| Gene {
        params: vec![p],
        rest_length: None,
        couple: None,
    }));
    genes
}

/// Region `params`' region: those parameters and every gene holding one of them.
fn region(genes: &[Gene], params: &[usize]) -> Region {
    Region {
        params: params.to_vec(),
        genes: (0..genes.len())
            .filter(|&g| genes[g].params.iter().any(|p| params.contains(p)))
            .collect(),
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
    /// Per parameter, the number of regions that mutate it (at least 1).
    param_regions: Vec<f64>,
    /// Per gene, the number of regions that hold it (at least 1).
    gene_regions: Vec<f64>,
    /// Per parameter, the gene holding it.
    couple_of: Vec<Option<usize>>,
}

impl Engine<'_> {
    /// Mutates parameter `p` of `genome` with temperature `t` and standard normal `noise`:
    /// multiplicatively, or in pre-stress coordinates (see [`GaOptions::prestress_mutation`]).
    fn mutate_parameter(&self, genome: &mut [f64], p: usize, t: f64, noise: f64) {
        let params = &self.layout.parameters;
        let couple = if self.options.prestress_mutation {
            self.couple_of[p].map(|g| (g, self.genes[g].couple))
        } else {
            None
        };
        match couple {
            Some((_, Some(c))) if c.stiffness == p => {
                // K' = K (1 + t n), rest value moved so that K (g_mean - R) is unchanged.
                let k = genome[p];
                let k_new = clamp_to(&params[p], mutate(k, t, self.mutation_floor[p], noise));
                genome[p] = k_new;
                if k_new > 0.0 && k > 0.0 {
                    let offset = (c.mean - genome[c.rest]) * k / k_new;
                    genome[c.rest] = clamp_to(&params[c.rest], c.mean - offset);
                }
            }
            Some((_, Some(c))) if c.rest == p => {
                // The offset from the observed mean, multiplicatively (floored like the value).
                let offset = c.mean - genome[p];
                let moved = mutate(offset, t, self.mutation_floor[p], noise);
                genome[p] = clamp_to(&params[p], c.mean - moved);
            }
            _ => {
                genome[p] = clamp_to(&params[p], mutate(genome[p], t, self.mutation_floor[p], noise));
            }
        }
    }

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
            if region.genes.is_empty() {
                continue;
            }
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
            let children: Vec<usize> = order
                .iter()
                .rev()
                .copied()
                .filter(|&i| !elite[i])
                .take(erase_count)
                .collect();
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
                if parents.len() >= 2 && rng.gen::<f64>() < self.options.differential {
                    // Difference of two survivors, over this region's parameters: a step along
                    // the directions the surviving population is spread in (its valleys).
                    let a = parents[rng.gen_range(0..parents.len())];
                    let mut b = parents[rng.gen_range(0..parents.len())];
                    if b == a {
                        b = parents[(parents.iter().position(|&i| i == a).unwrap_or(0) + 1) % parents.len()];
                    }
                    let f = 0.4 + 0.5 * rng.gen::<f64>();
                    for &p in &region.params {
                        let x = pop.genomes[child][p] + f * (pop.genomes[a][p] - pop.genomes[b][p]);
                        pop.genomes[child][p] = clamp_to(&self.layout.parameters[p], x);
                    }
                }
                pop.dirty[child] = true;
            }

            // Mutation: individuals outside this region's best 5% and outside the global elite.
            let candidates: Vec<usize> = order[elite_count..]
                .iter()
                .copied()
                .filter(|&i| !elite[i])
                .collect();
            if candidates.is_empty() {
                continue;
            }
            for &p in &region.params {
                for _ in 0..draw_count(rng, per_parameter / self.param_regions[p]) {
                    let i = candidates[rng.gen_range(0..candidates.len())];
                    let noise: f64 = rng.sample(StandardNormal);
                    let t = match self.options.schedule {
                        MutationSchedule::Spread => {
                            let u: f64 = rng.gen();
                            let o = &self.options;
                            o.mutation_temperature
                                * (o.min_mutation_temperature / o.mutation_temperature).powf(u)
                        }
                        MutationSchedule::FollowCost => temperature[r],
                    };
                    self.mutate_parameter(&mut pop.genomes[i], p, t, noise);
                    pop.dirty[i] = true;
                }
            }
            for &g in &region.genes {
                let Some((p, observed)) = &self.genes[g].rest_length else {
                    continue;
                };
                for _ in 0..draw_count(rng, per_rest_length / self.gene_regions[g]) {
                    let i = candidates[rng.gen_range(0..candidates.len())];
                    let x = observed[rng.gen_range(0..observed.len())];
                    pop.genomes[i][*p] = clamp_to(&self.layout.parameters[*p], x);
                    pop.dirty[i] = true;
                }
            }
        }
    }
}

/// The regions each gene is selected in: among the regions whose parameters hold it, those
/// whose local cost responds to it at least half as much as the most responsive one.
///
/// A local cost can depend, weakly, on many bonds (the one-step cost of a particle reaches the
/// bonds of its second neighbours' neighbours); selecting a bond on a cost it barely moves is
/// selecting it on noise. The response is measured once, at `x` (the initial best), by moving
/// each gene by 10% (or by its mutation floor): one evaluation per gene. Returns the narrowed
/// regions and the number of evaluations made.
fn narrow_regions(
    cost: &dyn LocalCostFunction,
    layout: &Layout,
    genes: &[Gene],
    regions: &[Region],
    x: &[f64],
    floor: &[f64],
) -> (Vec<Region>, usize) {
    let r_count = regions.len();
    let mut base = vec![0.0; r_count];
    cost.local_costs(x, &mut base);
    let responses: Vec<Vec<f64>> = genes
        .par_iter()
        .map(|gene| {
            let mut y = x.to_vec();
            for &p in &gene.params {
                let info = &layout.parameters[p];
                let step = 0.1 * x[p].abs().max(floor[p]);
                let up = clamp_to(info, x[p] + step);
                // On an upper bound, move down instead.
                y[p] = if up - x[p] < 0.5 * step {
                    clamp_to(info, x[p] - step)
                } else {
                    up
                };
            }
            let mut out = vec![0.0; r_count];
            cost.local_costs(&y, &mut out);
            out.iter().zip(&base).map(|(a, b)| (a - b).abs()).collect()
        })
        .collect();
    let mut narrowed: Vec<Region> = (0..r_count)
        .map(|_| Region {
            params: Vec::new(),
            genes: Vec::new(),
        })
        .collect();
    for (g, response) in responses.iter().enumerate() {
        let holders: Vec<usize> = (0..r_count).filter(|&r| regions[r].genes.contains(&g)).collect();
        let strongest = holders
            .iter()
            .map(|&r| response[r])
            .filter(|v| v.is_finite())
            .fold(0.0, f64::max);
        for &r in &holders {
            let keep = strongest <= 0.0 || !response[r].is_finite() || response[r] >= 0.5 * strongest;
            if keep {
                narrowed[r].genes.push(g);
                narrowed[r].params.extend(
                    genes[g]
                        .params
                        .iter()
                        .copied()
                        .filter(|p| regions[r].params.contains(p)),
                );
            }
        }
    }
    (narrowed, genes.len() + 1)
}

/// Each region's mutation temperature: `t0 sqrt(best / reference)` within `[t_min, t0]`,
/// where `reference` is the region's first finite, positive best local cost.
fn temperatures(pop: &Population, reference: &mut [f64], options: &GaOptions) -> Vec<f64> {
    let regions = reference.len();
    (0..regions)
        .map(|r| {
            let best = (0..pop.global.len())
                .map(|i| pop.locals[i * regions + r])
                .fold(f64::INFINITY, f64::min);
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
fn run(
    fitness: Fitness<'_>,
    layout: &Layout,
    options: &GaOptions,
    seed: u64,
    observer: &dyn Observer,
) -> SolverOutcome {
    let options = options.sanitized();
    let d = layout.dimension();
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let genes = genes(layout);
    let all: Vec<usize> = (0..d).collect();
    let regions: Vec<Region> = match fitness {
        Fitness::Local(c) => (0..c.region_count())
            .map(|r| {
                let params: Vec<usize> = c
                    .region_parameters(r)
                    .iter()
                    .copied()
                    .filter(|&p| p < d)
                    .collect();
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
    let mutation_floor: Vec<f64> = layout
        .parameters
        .iter()
        .map(|info| {
            let scale = if info.scale.is_finite() {
                info.scale.abs()
            } else {
                1.0
            };
            match info.kind {
                // Cosines cross zero, where a purely multiplicative change is stuck.
                ParameterKind::RestCos => scale,
                _ => 0.01 * scale,
            }
        })
        .collect();
    let regions = if let (Fitness::Local(c), true) = (fitness, regions.len() > 1) {
        let (narrowed, evaluations) =
            narrow_regions(c, layout, &genes, &regions, &pop.genomes[best], &mutation_floor);
        outcome.cost_count += evaluations;
        narrowed
    } else {
        regions
    };
    // Overlapping regions would mutate a shared parameter once per region: divide each
    // region's share so that every parameter gets `mutation * population` mutations per
    // generation in all, as in the global version.
    let mut param_regions = vec![0.0f64; d];
    let mut gene_regions = vec![0.0f64; genes.len()];
    for region in &regions {
        region.params.iter().for_each(|&p| param_regions[p] += 1.0);
        region.genes.iter().for_each(|&g| gene_regions[g] += 1.0);
    }
    let mut couple_of = vec![None; d];
    for (g, gene) in genes.iter().enumerate() {
        for &p in &gene.params {
            couple_of[p] = Some(g);
        }
    }
    let engine = Engine {
        layout,
        options: options.clone(),
        genes,
        regions,
        mutation_floor,
        param_regions: param_regions.into_iter().map(|c| c.max(1.0)).collect(),
        gene_regions: gene_regions.into_iter().map(|c| c.max(1.0)).collect(),
        couple_of,
    };
    let mut reference = vec![f64::NAN; region_count];
    let mut stagnation = Stagnation::new(
        options.stagnation,
        options.stagnation_tolerance,
        outcome.best_cost,
    );
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

    use std::sync::atomic::Ordering;

    fn in_pool<T: Send>(threads: usize, f: impl FnOnce() -> T + Send) -> T {
        match rayon::ThreadPoolBuilder::new().num_threads(threads).build() {
            Ok(pool) => pool.install(f),
            Err(e) => panic!("cannot build a {threads}-thread pool: {e}"),
        }
    }

    #[test]
    fn global_recovers_quadratic_couples_of_a_five_particle_sized_problem() {
        // 4 springs + 3 torsions: the paper's 5-particle object, 14 unknowns.
        let toy = Toy::new(4, 3, Shape::Quadratic);
        for schedule in [MutationSchedule::Spread, MutationSchedule::FollowCost] {
            let options = GaOptions {
                target_cost: 1e-7,
                schedule,
                ..Default::default()
            };
            let out = genetic(&toy, &toy.layout, &options, 1, &());
            assert!(out.best_cost <= 1e-7, "{schedule:?}: cost {}", out.best_cost);
            assert!(
                toy.max_error(&out.best) < 1e-3,
                "{schedule:?}: max error {}",
                toy.max_error(&out.best)
            );
            // The reported best cost is the best vector's.
            assert_eq!(out.best_cost.to_bits(), toy.cost(&out.best).to_bits());
        }
    }

    #[test]
    fn local_recovers_a_separable_problem_of_24_regions() {
        let toy = Toy::new(16, 8, Shape::Quadratic);
        let options = GaOptions {
            target_cost: 1e-7,
            ..Default::default()
        };
        let out = genetic_local(&toy, &toy.layout, &options, 2, &());
        assert!(
            toy.max_error(&out.best) < 1e-3,
            "max error {}",
            toy.max_error(&out.best)
        );
    }

    #[test]
    fn recovers_rosenbrock_couples_within_five_percent() {
        // A curved valley per bond is hard for mutations along the axes; the local version
        // needs fewer generations because it selects each couple on its own valley.
        let toy = Toy::new(2, 1, Shape::Rosenbrock);
        let options = GaOptions {
            generations: 1000,
            stagnation: 0,
            ..Default::default()
        };
        for local in [false, true] {
            let out = if local {
                genetic_local(&toy, &toy.layout, &options, 3, &())
            } else {
                genetic(&toy, &toy.layout, &options, 3, &())
            };
            assert!(
                toy.max_error(&out.best) < 0.05,
                "local {local}: max error {}",
                toy.max_error(&out.best)
            );
        }
    }

    #[test]
    fn elitism_the_best_cost_never_rises() {
        let toy = Toy::new(4, 3, Shape::Rosenbrock);
        let options = GaOptions {
            generations: 150,
            stagnation: 0,
            ..Default::default()
        };
        for local in [false, true] {
            let recorder = Recorder::default();
            let out = if local {
                genetic_local(&toy, &toy.layout, &options, 4, &recorder)
            } else {
                genetic(&toy, &toy.layout, &options, 4, &recorder)
            };
            assert_eq!(out.history.len(), 150);
            assert!(
                out.history.windows(2).all(|w| w[1] <= w[0]),
                "local {local}: the best cost rose"
            );
            assert!(out.history[149] < out.history[0]);
            let seen = recorder.0.lock().map(|v| v.clone()).unwrap_or_default();
            let expected: Vec<(usize, f64)> = out.history.iter().copied().enumerate().collect();
            assert_eq!(seen, expected);
        }
    }

    #[test]
    fn same_seed_is_bitwise_identical_whatever_the_thread_count() {
        let toy = Toy::new(6, 2, Shape::Rosenbrock);
        let options = GaOptions {
            generations: 40,
            stagnation: 0,
            ..Default::default()
        };
        for local in [false, true] {
            let run = |seed: u64| {
                if local {
                    genetic_local(&toy, &toy.layout, &options, seed, &())
                } else {
                    genetic(&toy, &toy.layout, &options, seed, &())
                }
            };
            let a = in_pool(1, || run(11));
            let b = in_pool(2, || run(11));
            let c = in_pool(2, || run(12));
            assert_eq!(bits(&a.best), bits(&b.best));
            assert_eq!(bits(&a.history), bits(&b.history));
            assert_eq!(a.cost_count, b.cost_count);
            assert_ne!(bits(&a.history), bits(&c.history));
        }
    }

    #[test]
    fn every_evaluated_point_is_within_bounds_and_counted() {
        let mut toy = Toy::new(4, 3, Shape::Quadratic);
        // The first stiffness's optimum lies above its upper bound, the first rest cosine's
        // below its lower one: the answer must sit on those bounds.
        let upper = 0.8 * toy.truth[1];
        toy.layout.parameters[1].bounds = [0.0, upper];
        let m = toy.layout.bonds[4].params[0];
        let lower = toy.truth[m] + 0.05;
        toy.layout.parameters[m].bounds = [lower, 1.0];
        let options = GaOptions {
            generations: 300,
            ..Default::default()
        };
        for local in [false, true] {
            let checked = Checked::new(&toy);
            let out = if local {
                genetic_local(&checked, &toy.layout, &options, 5, &())
            } else {
                genetic(&checked, &toy.layout, &options, 5, &())
            };
            assert!(!checked.out_of_bounds.load(Ordering::Relaxed));
            assert_eq!(out.cost_count, checked.evaluations.load(Ordering::Relaxed));
            assert!(
                (out.best[1] - upper).abs() < 1e-3 * upper,
                "{} vs bound {upper}",
                out.best[1]
            );
            assert!(
                (out.best[m] - lower).abs() < 1e-3,
                "{} vs bound {lower}",
                out.best[m]
            );
        }
    }

    #[test]
    fn the_initial_population_is_drawn_from_the_data() {
        let toy = Toy::new(4, 3, Shape::Quadratic);
        let options = GaOptions {
            generations: 0,
            population: 40,
            ..Default::default()
        };
        for seed in 0..20 {
            let out = genetic(&toy, &toy.layout, &options, seed, &());
            assert_eq!(out.cost_count, 40);
            for bond in &toy.layout.bonds {
                let lo = bond.observed.iter().copied().fold(f64::INFINITY, f64::min);
                let hi = bond.observed.iter().copied().fold(f64::NEG_INFINITY, f64::max);
                let [v, s] = [out.best[bond.params[0]], out.best[bond.params[1]]];
                if matches!(bond.bond, crate::BondRef::Spring(_)) {
                    assert!(
                        v >= 0.9 * lo && v <= 1.1 * hi,
                        "rest length {v} outside [{lo}, {hi}] +-10%"
                    );
                } else {
                    assert!(
                        v >= lo - 0.1 && v <= hi + 0.1,
                        "rest cosine {v} outside [{lo}, {hi}] +-0.1"
                    );
                }
                let scale = toy.layout.parameters[bond.params[1]].scale;
                assert!(
                    s >= scale / 100.0 && s <= scale * 100.0,
                    "stiffness {s} vs scale {scale}"
                );
            }
        }
    }

    /// Generations and cost evaluations the local and the global GA need to bring `toy` to a
    /// cost of 1e-7 per bond.
    fn effort(toy: &Toy, seed: u64) -> [(bool, usize, usize); 2] {
        let options = GaOptions {
            target_cost: 1e-7 * toy.layout.bonds.len() as f64,
            generations: 600,
            stagnation: 0,
            ..Default::default()
        };
        let l = genetic_local(toy, &toy.layout, &options, seed, &());
        let g = genetic(toy, &toy.layout, &options, seed, &());
        [l, g].map(|o| {
            (
                o.best_cost <= options.target_cost,
                o.iteration_count,
                o.cost_count,
            )
        })
    }

    #[test]
    fn local_beats_global_on_24_regions_and_its_generations_stay_flat() {
        let [(small_ok, small_gens, _), _] = effort(&Toy::new(6, 2, Shape::Quadratic), 6);
        let [(local_ok, local_gens, local_evals), (_, global_gens, global_evals)] =
            effort(&Toy::new(16, 8, Shape::Quadratic), 6);
        eprintln!("8 regions: local {small_gens} gens; 24 regions: local {local_gens} gens {local_evals} evals, global {global_gens} gens {global_evals} evals");
        assert!(small_ok && local_ok);
        assert!(
            local_evals < global_evals,
            "local {local_evals} evaluations, global {global_evals}"
        );
        // Three times the regions, at most twice the generations (the paper: about the same).
        assert!(
            local_gens <= 2 * small_gens,
            "{local_gens} generations for 24 regions, {small_gens} for 8"
        );
    }

    #[test]
    fn stops_on_stagnation() {
        let flat = Flat(6);
        let toy = Toy::new(2, 1, Shape::Quadratic);
        let options = GaOptions {
            stagnation: 7,
            ..Default::default()
        };
        let out = genetic(&flat, &toy.layout, &options, 0, &());
        assert_eq!(out.iteration_count, 7);
    }

    #[test]
    fn validate_names_the_bad_option() {
        assert!(GaOptions::default().validate().is_ok());
        let cases = [
            (
                GaOptions {
                    population: 2,
                    ..Default::default()
                },
                "population",
            ),
            (
                GaOptions {
                    crossover: 1.0,
                    ..Default::default()
                },
                "crossover",
            ),
            (
                GaOptions {
                    mutation: -0.1,
                    ..Default::default()
                },
                "mutation",
            ),
            (
                GaOptions {
                    elite: 0.0,
                    ..Default::default()
                },
                "elite",
            ),
            (
                GaOptions {
                    selection_pressure: 0.5,
                    ..Default::default()
                },
                "selection_pressure",
            ),
            (
                GaOptions {
                    min_mutation_temperature: 0.5,
                    ..Default::default()
                },
                "min_mutation_temperature",
            ),
        ];
        for (options, name) in cases {
            let err = options.validate().unwrap_err();
            assert!(err.to_string().contains(name), "{err} should name {name}");
        }
    }
}
