//! [`refine_in_patches`]: the multi-step refinement of large structures, one patch at a time.
//!
//! The whole-object refinement ([`crate::refine`]) differentiates a simulation of the whole
//! object with respect to every unknown: its cost grows as unknowns x bonds x frames, and its
//! uncertainty needs the eigen-decomposition of a dense matrix of all unknowns, so it grows as
//! the square of the object's size or faster. Beyond [`RefineOptions::patch_limit`] unknowns the object is
//! instead cut into patches:
//!
//! * the free particles are split into *cores* of about [`RefineOptions::core_size`] neighbours (grown
//!   breadth-first over the bonds);
//! * a core's patch is the core, its *halo* (the free neighbours of the core, simulated and
//!   compared too, so that loops of bonds closing just outside the core are still seen from
//!   both sides), every bond of a core or halo particle, and the *ring* of particles those
//!   bonds reach beyond;
//! * the ring is pinned in the patch's model and *driven* along cubic splines through its
//!   tracked positions ([`physfit_model::step_prescribed`]), first along the tracks, then
//!   (for [`RefineOptions::passes`] - 1 more passes) along the paths the neighbouring patches simulated; the
//!   start state of core and halo and the patch's bond values are refined by
//!   [`crate::refine`]'s machinery on their positions;
//! * each bond takes its values from the patch whose core holds its first free particle (a
//!   torsion's centre first), and their standard errors from that patch's Jacobian;
//! * the Jacobians are carried between iterations by secant updates, and a later pass starts
//!   from the state and the Jacobian the patch reached in the pass before, so a patch costs
//!   about one finite-difference Jacobian in the first pass and one in the last (which the
//!   uncertainty needs), and a few dozen simulations in between.
//!
//! Every patch has the same size whatever the object's, so the work grows in proportion to
//! the number of bonds, and the patches run in parallel. The price is statistical: the ring
//! is driven by noisy tracks rather than estimated, so a bond near a core's edge is known a
//! little less well than a whole-object fit would know it (on exact data both are exact).

use nalgebra::DMatrix;
use physfit_model::{ParticleId, Scene, State, Vec2};
use rayon::prelude::*;
use std::time::Instant;

use crate::refine::{fit_start_state_with, refine_with, WarmStart};
use crate::{
    BondRef, IdentifyError, MultiStepCost, Observations, Observer, Problem, RefineOptions, Refinement,
};

/// One patch's refinement: its problem (the patch's particles, core first, then the ring), its
/// refinement, and which of its parameters it decides for the whole (`(patch index, whole
/// index)` pairs).
#[derive(Clone, Debug)]
pub struct PatchRefinement {
    /// The patch's problem.
    pub problem: Problem,
    /// The patch's refinement (Jacobian over its own unknowns).
    pub refinement: Refinement,
    /// `(parameter in the patch, parameter in the whole)` for the bonds this patch decides.
    pub owned: Vec<(usize, usize)>,
}

/// A core, its ring and its bonds, in whole-structure indices.
struct Patch {
    /// Core particles, then halo particles, then ring particles.
    particles: Vec<usize>,
    core_count: usize,
    /// Core and halo particles (simulated; the rest is the driven ring).
    simulated: usize,
    springs: Vec<usize>,
    torsions: Vec<usize>,
}

/// The particles of each bond, springs then torsions (a torsion's centre first).
fn bond_particles(structure: &Scene) -> Vec<Vec<usize>> {
    let springs = structure
        .springs
        .iter()
        .map(|s| s.ends.iter().map(|e| e.index()).collect());
    let torsions = structure.torsions.iter().map(|t| {
        [t.center, t.ends[0], t.ends[1]]
            .iter()
            .map(|e| e.index())
            .collect()
    });
    springs.chain(torsions).collect()
}

/// Cuts the structure into patches (see the module doc).
fn partition(structure: &Scene, free: &[bool], core_size: usize) -> Vec<Patch> {
    let n = structure.particles.len();
    let bonds = bond_particles(structure);
    let mut neighbours = vec![Vec::new(); n];
    let mut bonds_of = vec![Vec::new(); n];
    for (b, ps) in bonds.iter().enumerate() {
        for &p in ps {
            bonds_of[p].push(b);
            neighbours[p].extend(ps.iter().copied().filter(|&q| q != p));
        }
    }
    let mut core_of = vec![usize::MAX; n];
    let mut cores: Vec<Vec<usize>> = Vec::new();
    for seed in 0..n {
        if !free[seed] || core_of[seed] != usize::MAX {
            continue;
        }
        let c = cores.len();
        let mut core = vec![seed];
        core_of[seed] = c;
        let mut head = 0;
        while head < core.len() && core.len() < core_size {
            let p = core[head];
            head += 1;
            for &q in &neighbours[p] {
                if core.len() < core_size && free[q] && core_of[q] == usize::MAX {
                    core_of[q] = c;
                    core.push(q);
                }
            }
        }
        cores.push(core);
    }
    let spring_count = structure.springs.len();
    cores
        .into_iter()
        .map(|core| {
            let core_count = core.len();
            let mut particles = core.clone();
            let mut in_patch = vec![false; n];
            core.iter().for_each(|&p| in_patch[p] = true);
            // The halo: free neighbours of the core, simulated and compared but not decided.
            for &p in &core {
                for &q in &neighbours[p] {
                    if free[q] && !in_patch[q] {
                        in_patch[q] = true;
                        particles.push(q);
                    }
                }
            }
            let simulated = particles.len();
            let mut bond_set: Vec<usize> = particles[..simulated]
                .iter()
                .flat_map(|&p| bonds_of[p].iter().copied())
                .collect();
            bond_set.sort_unstable();
            bond_set.dedup();
            for &b in &bond_set {
                for &q in &bonds[b] {
                    if !in_patch[q] {
                        in_patch[q] = true;
                        particles.push(q);
                    }
                }
            }
            let (springs, torsions): (Vec<usize>, Vec<usize>) =
                bond_set.iter().partition(|&&b| b < spring_count);
            Patch {
                particles,
                core_count,
                simulated,
                springs,
                torsions: torsions.into_iter().map(|b| b - spring_count).collect(),
            }
        })
        .collect()
}

/// The patch's structure (ring pinned) and observations, in patch indices; the ring's
/// positions from `ring_paths` where given (`[frame][particle]`, whole indices).
fn patch_problem(
    structure: &Scene,
    obs: &Observations,
    patch: &Patch,
    ring_paths: Option<&[Vec<Vec2>]>,
) -> (Scene, Observations) {
    let mut local = vec![u32::MAX; structure.particles.len()];
    for (i, &p) in patch.particles.iter().enumerate() {
        local[p] = i as u32;
    }
    let id = |p: ParticleId| ParticleId(local[p.index()]);
    let mut scene = structure.clone();
    scene.name = format!(
        "{} (patch around {})",
        structure.name, structure.particles[patch.particles[0]].id
    );
    scene.particles = patch
        .particles
        .iter()
        .enumerate()
        .map(|(i, &p)| {
            let mut spec = structure.particles[p].clone();
            spec.fixed |= i >= patch.simulated;
            spec
        })
        .collect();
    scene.springs = patch
        .springs
        .iter()
        .map(|&s| {
            let mut spec = structure.springs[s].clone();
            spec.ends = spec.ends.map(id);
            spec
        })
        .collect();
    scene.torsions = patch
        .torsions
        .iter()
        .map(|&t| {
            let mut spec = structure.torsions[t].clone();
            spec.center = id(spec.center);
            spec.ends = spec.ends.map(id);
            spec
        })
        .collect();
    let pick = |rows: &Vec<Vec<Option<Vec2>>>| -> Vec<Vec<Option<Vec2>>> {
        rows.iter()
            .map(|f| patch.particles.iter().map(|&p| f[p]).collect())
            .collect()
    };
    let mut sub = obs.clone();
    sub.particle_ids = patch
        .particles
        .iter()
        .map(|&p| obs.particle_ids[p].clone())
        .collect();
    sub.fixed = scene.particles.iter().map(|p| p.fixed).collect();
    sub.positions = pick(&obs.positions);
    if let Some(paths) = ring_paths {
        for (k, frame) in sub.positions.iter_mut().enumerate() {
            for (i, &p) in patch.particles.iter().enumerate().skip(patch.simulated) {
                frame[i] = Some(paths[k][p]);
            }
        }
    }
    sub.velocities = pick(&obs.velocities);
    sub.warnings.clear();
    (scene, sub)
}

/// Returns true if and only if the unknowns (parameters plus four per free particle) exceed
/// `options.patch_limit`.
fn needs_patches(problem: &Problem, observations: &Observations, options: &RefineOptions) -> bool {
    let free = observations.fixed.iter().filter(|f| !**f).count();
    problem.dimension() + 4 * free > options.patch_limit
}

/// Refines `start` as `lsq` does: the whole object ([`crate::refine`]) up to [`RefineOptions::patch_limit`]
/// unknowns (parameters plus four per free particle), patch by patch
/// ([`refine_in_patches`]) beyond.
pub fn refine_by_size(
    problem: &Problem,
    observations: &Observations,
    start: &[f64],
    options: &RefineOptions,
    observer: &dyn Observer,
) -> Result<Refinement, IdentifyError> {
    if needs_patches(problem, observations, options) {
        refine_in_patches(problem, observations, start, options, observer)
    } else {
        crate::refine(problem, observations, start, options, observer)
    }
}

/// Refines `start` (and the observed start state) patch by patch (see the module doc). The
/// result's Jacobian is empty; its [`Refinement::patches`] hold each patch's, which
/// [`crate::uncertainty`] reads.
pub fn refine_in_patches(
    problem: &Problem,
    observations: &Observations,
    start: &[f64],
    options: &RefineOptions,
    observer: &dyn Observer,
) -> Result<Refinement, IdentifyError> {
    in_patches(problem, observations, start, options, observer, false)
}

/// As [`crate::fit_start_state`] (the start state fitted for fixed parameters `params`, the
/// Jacobian over both for the uncertainty): on the whole object up to [`RefineOptions::patch_limit`]
/// unknowns, patch by patch beyond (as [`refine_in_patches`], with each patch's parameters
/// held), so that judging a model found by another solver grows with the number of bonds too.
pub fn fit_start_state_by_size(
    problem: &Problem,
    observations: &Observations,
    params: &[f64],
    options: &RefineOptions,
) -> Result<Refinement, IdentifyError> {
    if needs_patches(problem, observations, options) {
        in_patches(problem, observations, params, options, &(), true)
    } else {
        crate::fit_start_state(problem, observations, params, options)
    }
}

/// The patch-by-patch fit: the parameters and start state refined, or with `hold_params` only
/// the start state.
fn in_patches(
    problem: &Problem,
    observations: &Observations,
    start: &[f64],
    options: &RefineOptions,
    observer: &dyn Observer,
    hold_params: bool,
) -> Result<Refinement, IdentifyError> {
    let t0 = Instant::now();
    let structure = &problem.structure;
    let free: Vec<bool> = observations.fixed.iter().map(|f| !f).collect();
    let patches = partition(structure, &free, options.core_size);
    let whole = MultiStepCost::new(problem.clone(), observations)?;
    let mut state = whole.observed_anchor_state();
    let anchor_frame = whole.anchor_frame();
    let bonds = bond_particles(structure);
    let spring_count = structure.springs.len();
    // The patch deciding each bond: the core of its first free particle.
    let mut core_of = vec![usize::MAX; structure.particles.len()];
    for (c, patch) in patches.iter().enumerate() {
        patch.particles[..patch.core_count]
            .iter()
            .for_each(|&p| core_of[p] = c);
    }
    let owner: Vec<usize> = bonds
        .iter()
        .map(|ps| ps.iter().find(|&&p| free[p]).map_or(usize::MAX, |&p| core_of[p]))
        .collect();
    let whole_index = problem.layout.parameter_index();
    // One pass: every patch refined from `start`, its ring driven along `ring_paths` (the
    // tracks where `None`); also returns each core's simulated path.
    type Solved = Option<(PatchRefinement, Vec<Vec<Vec2>>)>;
    let pass = |start: &[f64],
                ring_paths: Option<&[Vec<Vec2>]>,
                warm: Option<(&State, &[Option<PatchRefinement>])>,
                last: bool|
     -> Vec<Result<Solved, IdentifyError>> {
        patches
            .par_iter()
            .enumerate()
            .map(|(c, patch)| {
                let (scene, sub_obs) = patch_problem(structure, observations, patch, ring_paths);
                let sub = match Problem::new(&scene, &sub_obs) {
                    Ok(sub) => sub,
                    // Every bond of this core is known: nothing to refine here.
                    Err(IdentifyError::NoUnknowns) => return Ok(None),
                    Err(e) => return Err(e),
                };
                // Patch parameter -> whole parameter, and whether this patch decides it.
                let mut map = Vec::with_capacity(sub.dimension());
                let mut owned = Vec::new();
                for (i, q) in sub.layout.parameters.iter().enumerate() {
                    let (bond, b) = match q.bond {
                        BondRef::Spring(k) => (BondRef::Spring(patch.springs[k]), patch.springs[k]),
                        BondRef::Torsion(k) => (
                            BondRef::Torsion(patch.torsions[k]),
                            spring_count + patch.torsions[k],
                        ),
                    };
                    // The patch's unknowns are the whole's, under the same bonds.
                    let Some(&g) = whole_index.get(&(bond, q.kind)) else {
                        return Err(IdentifyError::NoUnknowns);
                    };
                    map.push(g);
                    if owner[b] == c {
                        owned.push((i, g));
                    }
                }
                let sub_start: Vec<f64> = map.iter().map(|&g| start[g]).collect();
                let cost_for =
                    |o: &Observations| MultiStepCost::new(sub.clone(), o)?.with_driven_pinned_particles();
                let cost = cost_for(&sub_obs)?;
                // Later passes start from the state the patches found before (and, refining,
                // from this patch's Jacobian).
                let before = warm.and_then(|(whole, parts)| Some((whole, parts[c].as_ref()?)));
                let warm_state = before.map(|(whole, _)| {
                    let mut state = cost.observed_anchor_state();
                    for (i, &p) in patch.particles[..patch.simulated].iter().enumerate() {
                        state.positions[i] = whole.positions[p];
                        state.velocities[i] = whole.velocities[p];
                    }
                    state
                });
                let refinement = if hold_params {
                    fit_start_state_with(
                        &sub,
                        &sub_obs,
                        &sub_start,
                        warm_state.as_ref(),
                        options,
                        &cost_for,
                    )?
                } else {
                    let warm = warm_state.zip(before).map(|(state, (_, part))| WarmStart {
                        state,
                        jacobian: part.refinement.jacobian.clone(),
                    });
                    refine_with(
                        &sub,
                        &sub_obs,
                        &sub_start,
                        warm.as_ref(),
                        last,
                        options,
                        &(),
                        &cost_for,
                    )?
                };
                let path = cost
                    .trajectory(&refinement.params, &refinement.initial_state)
                    .unwrap_or_default();
                Ok(Some((
                    PatchRefinement {
                        problem: sub,
                        refinement,
                        owned,
                    },
                    path,
                )))
            })
            .collect()
    };
    let mut params = start.to_vec();
    let (mut first_cost, mut last_cost, mut iterations, mut evaluations) = (0.0, 0.0, 0, 0);
    let mut ring_paths: Option<Vec<Vec<Vec2>>> = None;
    // Each patch's refinement in the last pass, which the next one starts from (its state
    // and Jacobian).
    let mut parts: Vec<Option<PatchRefinement>> = (0..patches.len()).map(|_| None).collect();
    let passes = options.passes.max(1);
    for round in 0..passes {
        let warm = (round > 0).then_some((&state, &parts[..]));
        let solved = pass(&params, ring_paths.as_deref(), warm, round + 1 == passes);
        let mut paths: Vec<Vec<Vec2>> = observations
            .positions
            .iter()
            .map(|f| f.iter().map(|x| x.unwrap_or_else(Vec2::zeros)).collect())
            .collect();
        last_cost = 0.0;
        for (c, (patch, result)) in patches.iter().zip(solved).enumerate() {
            let Some((part, path)) = result? else {
                parts[c] = None;
                continue;
            };
            for &(i, g) in &part.owned {
                params[g] = part.refinement.params[i];
            }
            if part.refinement.anchor_frame == anchor_frame {
                for (i, &p) in patch.particles[..patch.core_count].iter().enumerate() {
                    state.positions[p] = part.refinement.initial_state.positions[i];
                    state.velocities[p] = part.refinement.initial_state.velocities[i];
                }
            }
            if path.len() == paths.len() {
                for (k, frame) in path.iter().enumerate() {
                    for (i, &p) in patch.particles[..patch.core_count].iter().enumerate() {
                        paths[k][p] = frame[i];
                    }
                }
            }
            if round == 0 {
                first_cost += part.refinement.history.first().copied().unwrap_or(0.0);
            }
            last_cost += part.refinement.history.last().copied().unwrap_or(0.0);
            iterations += part.refinement.iteration_count;
            evaluations += part.refinement.cost_count;
            parts[c] = Some(part);
        }
        ring_paths = Some(paths);
    }
    observer.observe(iterations, last_cost);
    let fit = whole.evaluate_from(&params, &state);
    let parts: Vec<PatchRefinement> = parts.into_iter().flatten().collect();
    Ok(Refinement {
        params,
        initial_state: state,
        anchor_frame,
        jacobian: DMatrix::zeros(0, 0),
        residuals: Vec::new(),
        fit,
        history: vec![first_cost, last_cost],
        iteration_count: iterations,
        cost_count: evaluations,
        spans: parts
            .first()
            .map_or_else(Vec::new, |p| p.refinement.spans.clone()),
        seconds: t0.elapsed().as_secs_f64(),
        patches: parts,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testutil::{lattice, record, tracks, Timing};
    use crate::{linear_estimate, refine, uncertainty, ParameterKind};

    /// Largest error over the parameters, relative except for rest cosines (absolute: the
    /// lattice's are 0), and where.
    fn largest_error(problem: &Problem, fitted: &[f64], truth: &[f64]) -> (f64, usize) {
        fitted
            .iter()
            .zip(truth)
            .zip(&problem.layout.parameters)
            .map(|((a, b), q)| match q.kind {
                ParameterKind::RestCos => (a - b).abs(),
                _ => ((a - b) / b).abs(),
            })
            .enumerate()
            .fold((0.0, 0), |(m, i), (k, e)| if e > m { (e, k) } else { (m, i) })
    }

    fn lattice_problem(side: usize, sigma: f64, seed: u64) -> (Problem, Observations, Vec<f64>) {
        let truth = lattice(
            side,
            Timing {
                frames: 100,
                ..Timing::default()
            },
        );
        let structure = truth.structure();
        let obs = if sigma > 0.0 {
            Observations::from_tracks(&tracks(&truth, sigma, seed), &structure, None).expect("tracks")
        } else {
            Observations::from_recording(&record(&truth), &truth, 0)
        };
        let problem = Problem::new(&structure, &obs).expect("problem");
        let x = problem.params_of(&truth).expect("truth");
        (problem, obs, x)
    }

    #[test]
    fn patches_cover_every_free_particle_once_and_every_bond() {
        let truth = lattice(7, Timing::default());
        let free = vec![true; truth.particles.len()];
        let core_size = RefineOptions::default().core_size;
        let patches = partition(&truth, &free, core_size);
        let mut cores: Vec<usize> = patches
            .iter()
            .flat_map(|p| p.particles[..p.core_count].to_vec())
            .collect();
        cores.sort_unstable();
        assert_eq!(cores, (0..49).collect::<Vec<_>>());
        assert!(patches.iter().all(|p| p.core_count <= core_size));
        let mut springs: Vec<usize> = patches.iter().flat_map(|p| p.springs.clone()).collect();
        springs.sort_unstable();
        springs.dedup();
        assert_eq!(springs.len(), truth.springs.len());
    }

    #[test]
    fn patch_refinement_is_exact_on_exact_data() {
        // A 6 x 6 lattice (85 bonds): each patch's ring is driven along its exact track, so
        // the patches must recover the truth as the whole-object refinement does.
        let (problem, obs, x) = lattice_problem(6, 0.0, 0);
        let est = linear_estimate(&problem, &obs, None).expect("linear");
        let (before, _) = largest_error(&problem, &est.params, &x);
        let r =
            refine_in_patches(&problem, &obs, &est.params, &RefineOptions::default(), &()).expect("patches");
        let (err, at) = largest_error(&problem, &r.params, &x);
        assert!(
            err < 1e-5 && err < before / 10.0,
            "{} off by {:.2e} (linear stage {:.2e})",
            problem.parameter_label(at),
            err,
            before
        );
        assert!(r.fit.rms < 1e-4, "whole-object multi-step RMS {} px", r.fit.rms);
    }

    #[test]
    fn start_state_fitted_in_patches_holds_the_parameters_and_matches_the_whole_fit() {
        // 0.05 px noise on a 4 x 4 lattice, parameters held at the truth: the patches fit the
        // start state as the whole-object fit does, and their standard errors are close.
        let (problem, obs, x) = lattice_problem(4, 0.05, 5);
        let options = RefineOptions::default();
        let whole = crate::fit_start_state(&problem, &obs, &x, &options).expect("whole");
        let patched = in_patches(&problem, &obs, &x, &options, &(), true).expect("patches");
        assert!(!patched.patches.is_empty(), "the patches were used");
        assert_eq!(patched.params, x, "parameters held");
        let worst = whole
            .initial_state
            .positions
            .iter()
            .zip(&patched.initial_state.positions)
            .map(|(a, b)| (a - b).norm())
            .fold(0.0, f64::max);
        assert!(worst < 0.05, "start positions differ by up to {worst:.3} px");
        assert!(
            patched.fit.rms < 1.2 * whole.fit.rms,
            "multi-step RMS {} px in patches, {} px whole",
            patched.fit.rms,
            whole.fit.rms
        );
        let (uw, up) = (
            uncertainty(&problem, &whole, obs.noise),
            uncertainty(&problem, &patched, obs.noise),
        );
        for (i, (a, b)) in up.std_errors.iter().zip(&uw.std_errors).enumerate() {
            assert!(
                a.is_finite() && *a >= 0.5 * b && *a <= 5.0 * b,
                "{}: standard error {a:.3e} in patches, {b:.3e} whole",
                problem.parameter_label(i)
            );
        }
    }

    #[test]
    fn patch_refinement_is_near_the_whole_object_fit_with_noise() {
        // 0.05 px noise on a 4 x 4 lattice (33 bonds): the patches' errors and standard errors
        // must stay close to the whole-object refinement's.
        let (problem, obs, x) = lattice_problem(4, 0.05, 3);
        let est = linear_estimate(&problem, &obs, None).expect("linear");
        let whole = refine(&problem, &obs, &est.params, &RefineOptions::default(), &()).expect("whole");
        let patched =
            refine_in_patches(&problem, &obs, &est.params, &RefineOptions::default(), &()).expect("patches");
        let (uw, up) = (
            uncertainty(&problem, &whole, obs.noise),
            uncertainty(&problem, &patched, obs.noise),
        );
        let rms = |p: &[f64], se: &[f64]| {
            (p.iter()
                .zip(&x)
                .zip(se)
                .map(|((a, b), s)| ((a - b) / s).powi(2))
                .sum::<f64>()
                / p.len() as f64)
                .sqrt()
        };
        // Errors in units of the whole fit's standard errors.
        let (ew, ep) = (
            rms(&whole.params, &uw.std_errors),
            rms(&patched.params, &uw.std_errors),
        );
        assert!(
            ep < 3.0 * ew.max(1.0),
            "RMS error / whole-fit standard error: patches {ep:.2}, whole {ew:.2}"
        );
        for (i, (a, b)) in up.std_errors.iter().zip(&uw.std_errors).enumerate() {
            assert!(
                a.is_finite() && *a >= 0.5 * b && *a <= 5.0 * b,
                "{}: standard error {a:.3e} in patches, {b:.3e} whole",
                problem.parameter_label(i)
            );
        }
    }
}
