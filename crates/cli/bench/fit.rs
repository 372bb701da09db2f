//! `physfit bench fit`: the paper's identification experiments beside `lsq`, the accuracy of
//! `lsq` against its own Cramer-Rao bound, and `lsq`'s scaling with the number of bonds.
//!
//! Experiments (BMVC 1994, MODEL.md section 4): `paper3` with simulated annealing, `paper5`
//! with the global genetic algorithm (population 150), `paper8` with the local genetic
//! algorithm (150 individuals, 80 frames), each on exact trajectories and with 0.05 px
//! Gaussian position noise, and `lsq` on the same data. Parameter errors are relative to the
//! scene's true values; the multi-step cost is over the whole simulated sequence (the paper's
//! external cost), from the fitted start state.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::Context;
use physfit_identify::solvers::{anneal, genetic, genetic_local, AnnealOptions, GaOptions};
use physfit_identify::{
    fit, linear_estimate, rest_angle_degrees, CostFunction, FitOptions, FitReport, LocalSplit, Method,
    Observations, OneStepCost, ParameterKind, Problem, SolverOutcome,
};
use physfit_model::scene::{ParticleFile, RecordingFile, SceneFile, SpringFile, TorsionFile};
use physfit_model::{IntegratorKind, Scene};
use physfit_tracks::{TrackPoint, TrackTable};

/// Position noise of the noisy runs, px.
const NOISE_PX: f64 = 0.05;

/// Seed of the noise draws and solvers.
const SEED: u64 = 1994;

/// Finds `scenes/<name>.toml` from the working directory or the package root.
fn scene_path(name: &str) -> PathBuf {
    let local = Path::new("scenes").join(format!("{name}.toml"));
    if local.exists() {
        local
    } else {
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("scenes")
            .join(format!("{name}.toml"))
    }
}

fn load(name: &str) -> anyhow::Result<Scene> {
    let path = scene_path(name);
    Scene::load(&path).with_context(|| format!("loading scene {}", path.display()))
}

/// The scene's simulated positions as tracks, with Gaussian noise `sigma` px (Box-Muller on a
/// splitmix64 stream from `seed`, so every run draws the same noise).
fn tracks(scene: &Scene, sigma: f64, seed: u64) -> anyhow::Result<TrackTable> {
    let rec = crate::cmd::simulate_scene(scene, &scene_path(&scene.name))?;
    let mut state = seed;
    let mut uniform = move || {
        state = state.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = state;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^= z >> 31;
        ((z >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    };
    let mut gauss = move || {
        let (u, v) = (uniform(), uniform());
        (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
    };
    let mut points = Vec::with_capacity(rec.positions.len());
    for k in 0..rec.frame_count() {
        for (p, x) in rec.frame(k).iter().enumerate() {
            let (dx, dy) = if sigma > 0.0 {
                (sigma * gauss(), sigma * gauss())
            } else {
                (0.0, 0.0)
            };
            points.push(TrackPoint::new(
                k,
                scene.particles[p].id.clone(),
                x.x + dx,
                x.y + dy,
            ));
        }
    }
    Ok(TrackTable { points })
}

/// One row of the experiments table.
struct Row {
    scene: String,
    data: String,
    method: String,
    report: FitReport,
}

fn run_one(truth: &Scene, data: &TrackTable, options: &FitOptions) -> anyhow::Result<FitReport> {
    let result =
        fit(&truth.structure(), data, options, &()).with_context(|| format!("fitting {}", truth.name))?;
    let mut report = result.report;
    report.compare_truth(truth);
    Ok(report)
}

fn pct(x: f64) -> String {
    if x < 1e-4 {
        format!("{:.1e} %", x * 100.0)
    } else {
        format!("{:.3} %", x * 100.0)
    }
}

/// The paper's experiments beside lsq.
pub fn experiments(quick: bool) -> anyhow::Result<String> {
    let generations = if quick { 60 } else { 400 };
    let cases: [(&str, Method, usize); 3] = [
        ("paper3", Method::Anneal, 100),
        ("paper5", Method::Ga, 100),
        ("paper8", Method::GaLocal, 80),
    ];
    let mut rows = Vec::new();
    for (name, method, window) in cases {
        let truth = load(name)?;
        let window = window.min(truth.recording.frames);
        for sigma in [0.0, NOISE_PX] {
            let data = tracks(&truth, sigma, SEED)?;
            let label = if sigma > 0.0 {
                format!("{sigma} px")
            } else {
                "exact".to_string()
            };
            for m in [method, Method::Lsq] {
                let mut options = FitOptions {
                    method: m,
                    seed: SEED,
                    window: Some((0, window - 1)),
                    population: 150,
                    generations,
                    ..FitOptions::default()
                };
                if quick {
                    options.anneal.iterations = 4000;
                }
                let report = run_one(&truth, &data, &options)?;
                rows.push(Row {
                    scene: name.into(),
                    data: label.clone(),
                    method: m.name().into(),
                    report,
                });
            }
        }
    }
    let mut out = String::from(
        "### Identification: the paper's experiments beside lsq\n\n\
         Window: first 100 frames (paper8: 80); errors relative to the scene's true values; \
         multi-step RMS over the whole sequence from the fitted start state.\n\n\
         | scene | data | method | iterations | cost evaluations | wall time | largest error | median error | largest rest-angle error | multi-step RMS, whole sequence |\n\
         |---|---|---|---:|---:|---:|---:|---:|---:|---:|\n",
    );
    for r in &rows {
        let t = r.report.truth.as_ref();
        out.push_str(&format!(
            "| {} | {} | {} | {} | {} | {:.3} s | {} ({}) | {} | {} | {:.3e} px |\n",
            r.scene,
            r.data,
            r.method,
            r.report.iteration_count,
            r.report.cost_count,
            r.report.seconds,
            t.map_or("-".into(), |t| pct(t.max_relative_error)),
            t.map_or("-".into(), |t| t.worst.clone()),
            t.map_or("-".into(), |t| pct(t.median_relative_error)),
            t.map_or("-".into(), |t| format!("{:.3} deg", t.max_angle_error_deg)),
            r.report.costs.multi_step_sequence.rms,
        ));
    }
    Ok(out)
}

/// `scene` re-recorded the paper's way: one semi-implicit Euler step per frame, `frames` frames.
fn paper_way(scene: &Scene, frames: usize) -> anyhow::Result<Scene> {
    let mut raw = scene.to_file();
    raw.recording.substeps = Some(1);
    raw.recording.integrator = Some(IntegratorKind::Euler);
    raw.recording.frames = frames;
    Scene::from_file(raw).map_err(|e| anyhow::anyhow!("{}: {e}", scene.name))
}

/// Exact observations (positions and the integrator's velocities) of `scene`'s recording.
fn exact_observations(scene: &Scene) -> anyhow::Result<Observations> {
    let rec = crate::cmd::simulate_scene(scene, &scene_path(&scene.name))?;
    Ok(Observations::from_recording(&rec, scene, 0))
}

/// A fit's parameters against the truth.
struct Errors {
    /// Largest and median relative error over every parameter (rest cosines included).
    largest: f64,
    median: f64,
    /// Largest rest-angle error, degrees.
    worst_angle: f64,
    /// Largest relative error of a stiffness or rest length, and its parameter.
    worst_value: (f64, usize),
    /// Stiffnesses and rest lengths within 5 %, rest angles within 4.5 degrees.
    within_5_percent: usize,
}

fn errors(problem: &Problem, x: &[f64], truth: &[f64]) -> Errors {
    let mut rel = Vec::with_capacity(x.len());
    let (mut worst_angle, mut worst_value, mut within_5_percent) = (0.0f64, (0.0, 0), 0);
    for (i, p) in problem.layout.parameters.iter().enumerate() {
        let e = ((x[i] - truth[i]) / truth[i].abs().max(1e-12)).abs();
        rel.push(e);
        if p.kind == ParameterKind::RestCos {
            let deg = (rest_angle_degrees(x[i], 0.0).0 - rest_angle_degrees(truth[i], 0.0).0).abs();
            worst_angle = worst_angle.max(deg);
            within_5_percent += usize::from(deg <= 4.5);
        } else {
            if e > worst_value.0 {
                worst_value = (e, i);
            }
            within_5_percent += usize::from(e <= 0.05);
        }
    }
    rel.sort_by(|a, b| a.total_cmp(b));
    Errors {
        largest: rel.last().copied().unwrap_or(0.0),
        median: rel.get(rel.len() / 2).copied().unwrap_or(0.0),
        worst_angle,
        worst_value,
        within_5_percent,
    }
}

/// The paper's solvers on the paper's own set-up: exact positions and velocities of a recording
/// made with one Euler step per frame (the one-step cost is then exactly zero at the truth),
/// the search alone and followed by its Levenberg-Marquardt polish on the same cost.
pub fn paper_setup(quick: bool) -> anyhow::Result<String> {
    let generations = if quick { 60 } else { 400 };
    let mut out = String::from(
        "\n### The paper's solvers the paper's way (one Euler step per frame, exact positions)\n\n\
         paper3: anneal (20k steps), paper5: ga, paper8: ga-local (own-prediction local costs); \
         population 150; 50 frames (paper8: 80). `+ polish`: up to 50 Levenberg-Marquardt iterations \
         on the same one-step cost from the search's best.\n\n\
         `within 5 %`: stiffnesses and rest lengths within 5 % of the truth, and rest angles within \
         5 % of a right angle (4.5 deg: a cosine's relative error means nothing near 90 deg).\n\n\
         | scene | solver | generations / steps | cost evaluations | wall time | one-step cost | largest error | median error | largest rest-angle error | largest stiffness or rest-length error | within 5 % |\n\
         |---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n",
    );
    for (name, method, frames) in [
        ("paper3", Method::Anneal, 50),
        ("paper5", Method::Ga, 50),
        ("paper8", Method::GaLocal, 80),
    ] {
        let truth = paper_way(&load(name)?, frames)?;
        let obs = exact_observations(&truth)?;
        let mut cost = OneStepCost::new(&truth.structure(), &obs)?;
        if method == Method::GaLocal {
            cost = cost.with_split(LocalSplit::OwnPrediction);
        }
        let x_true = cost.problem().params_of(&truth).context("truth")?;
        let ga = GaOptions {
            population: 150,
            generations,
            stagnation: 0,
            ..GaOptions::default()
        };
        let mut anneal_options = AnnealOptions::default();
        if quick {
            anneal_options.iterations = 4000;
        }
        let t0 = Instant::now();
        let found: SolverOutcome = match method {
            Method::Anneal => anneal(
                &cost,
                cost.layout(),
                &cost.problem().initial_guess(),
                &anneal_options,
                SEED,
                &(),
            ),
            Method::Ga => genetic(&cost, cost.layout(), &ga, SEED, &()),
            _ => genetic_local(&cost, cost.layout(), &ga, SEED, &()),
        };
        let search_time = t0.elapsed().as_secs_f64();
        let t1 = Instant::now();
        let polished = cost.polish(&found.best, 50, &()).unwrap_or_else(|| found.clone());
        let polish_time = t1.elapsed().as_secs_f64();
        for (label, o, time, gens, evals) in [
            (
                method.name().to_string(),
                &found,
                search_time,
                found.iteration_count,
                found.cost_count,
            ),
            (
                format!("{} + polish", method.name()),
                &polished,
                search_time + polish_time,
                found.iteration_count,
                found.cost_count + polished.cost_count,
            ),
        ] {
            let problem = cost.problem();
            let e = errors(problem, &o.best, &x_true);
            out.push_str(&format!(
                "| {name} | {label} | {gens} | {evals} | {time:.2} s | {:.2e} px² | {} | {} | {:.3} deg | {} ({}) | {} of {} |\n",
                cost.cost(&o.best),
                pct(e.largest),
                pct(e.median),
                e.worst_angle,
                pct(e.worst_value.0),
                problem.parameter_label(e.worst_value.1),
                e.within_5_percent,
                x_true.len(),
            ));
        }
    }
    Ok(out)
}

/// lsq's linear stage time and its errors against the reported Cramer-Rao bound over several
/// noise draws.
pub fn cramer_rao(quick: bool) -> anyhow::Result<String> {
    let draws = if quick { 3 } else { 40 };
    let mut out = format!(
        "\n### lsq at {NOISE_PX} px noise: accuracy against the reported Cramer-Rao bound ({draws} noise draws)\n\n\
         Ratio = RMS over draws of (error / Cramer-Rao bound reported by the fit); 1 is the bound. \
         With {draws} draws an RMS ratio has a relative spread of about {:.0}%.\n\n\
         | scene | frames | linear stage (median) | whole fit (median) | largest error | largest ratio | median ratio |\n\
         |---|---:|---:|---:|---:|---:|---:|\n",
        100.0 / (2.0 * draws as f64).sqrt()
    );
    let mut per_parameter = String::from(
        "\nPer parameter: RMS and mean of (error / bound) over the draws (a mean far from 0 is a bias; \
         its spread is about 1/sqrt(draws)).\n\n| scene | parameter | RMS ratio | mean ratio | bound |\n|---|---|---:|---:|---:|\n",
    );
    for name in ["paper3", "paper5", "paper8"] {
        let truth = load(name)?;
        let frames = if name == "paper8" { 80 } else { 100 }.min(truth.recording.frames);
        let mut ratio2: Vec<f64> = Vec::new();
        let mut ratio1: Vec<f64> = Vec::new();
        let mut bounds: Vec<f64> = Vec::new();
        let mut labels: Vec<String> = Vec::new();
        let mut linear_times = Vec::new();
        let mut fit_times = Vec::new();
        let mut worst: f64 = 0.0;
        for d in 0..draws {
            let data = tracks(&truth, NOISE_PX, SEED + d as u64)?;
            let obs = Observations::from_tracks(&data, &truth.structure(), Some((0, frames - 1)))?;
            let problem = Problem::new(&truth.structure(), &obs)?;
            let t0 = Instant::now();
            let _ = linear_estimate(&problem, &obs, None)?;
            linear_times.push(t0.elapsed().as_secs_f64());
            let options = FitOptions {
                method: Method::Lsq,
                window: Some((0, frames - 1)),
                ..FitOptions::default()
            };
            let report = run_one(&truth, &data, &options)?;
            fit_times.push(report.seconds);
            if let Some(t) = &report.truth {
                worst = worst.max(t.max_relative_error);
            }
            if ratio2.is_empty() {
                let n = report.parameters.len();
                ratio2 = vec![0.0; n];
                ratio1 = vec![0.0; n];
                bounds = vec![0.0; n];
                labels = report
                    .parameters
                    .iter()
                    .map(|p| match &p.bond {
                        physfit_identify::BondKeys::Spring { between } => {
                            format!("spring {}-{} {}", between[0], between[1], p.name)
                        }
                        physfit_identify::BondKeys::Torsion { at, between } => {
                            format!("torsion {}-{}-{} {}", between[0], at, between[1], p.name)
                        }
                    })
                    .collect();
            }
            for (k, p) in report.parameters.iter().enumerate() {
                if let (Some(t), Some(c)) = (p.truth, p.cramer_rao) {
                    ratio2[k] += ((p.value - t) / c).powi(2) / draws as f64;
                    ratio1[k] += (p.value - t) / c / draws as f64;
                    bounds[k] += c / draws as f64;
                }
            }
        }
        for k in 0..labels.len() {
            per_parameter.push_str(&format!(
                "| {name} | {} | {:.2} | {:+.2} | {:.3e} |\n",
                labels[k],
                ratio2[k].sqrt(),
                ratio1[k],
                bounds[k]
            ));
        }
        let mut ratios: Vec<f64> = ratio2.iter().map(|r| r.sqrt()).collect();
        ratios.sort_by(|a, b| a.total_cmp(b));
        linear_times.sort_by(|a, b| a.total_cmp(b));
        fit_times.sort_by(|a, b| a.total_cmp(b));
        out.push_str(&format!(
            "| {name} | {frames} | {:.2} ms | {:.3} s | {} | {:.2} | {:.2} |\n",
            linear_times[linear_times.len() / 2] * 1e3,
            fit_times[fit_times.len() / 2],
            pct(worst),
            ratios.last().copied().unwrap_or(f64::NAN),
            ratios.get(ratios.len() / 2).copied().unwrap_or(f64::NAN),
        ));
    }
    out.push_str(&per_parameter);
    Ok(out)
}

/// A square lattice of `side x side` particles: springs to the right and lower neighbours, a
/// torsion at each particle between them; displaced from rest so that it moves.
fn lattice(side: usize, frames: usize) -> anyhow::Result<Scene> {
    let spacing = 30.0;
    let id = |r: usize, c: usize| format!("n{r}_{c}");
    let mut particles = Vec::new();
    for r in 0..side {
        for c in 0..side {
            let jitter = (((r * 7 + c * 13) % 11) as f64 - 5.0) * 0.4;
            particles.push(ParticleFile {
                id: id(r, c),
                mass: 1.0 + 0.1 * ((r + c) % 3) as f64,
                position: [
                    50.0 + spacing * c as f64 + jitter,
                    50.0 + spacing * r as f64 - 0.5 * jitter,
                ],
                velocity: None,
                fixed: false,
                ..Default::default()
            });
        }
    }
    let mut springs = Vec::new();
    let mut torsions = Vec::new();
    for r in 0..side {
        for c in 0..side {
            if c + 1 < side {
                springs.push(SpringFile {
                    between: [id(r, c), id(r, c + 1)],
                    length: Some(spacing),
                    stiffness: Some(50.0 + ((r + c) % 5) as f64 * 5.0),
                    damping: None,
                });
            }
            if r + 1 < side {
                springs.push(SpringFile {
                    between: [id(r, c), id(r + 1, c)],
                    length: Some(spacing),
                    stiffness: Some(60.0 + ((r * c) % 4) as f64 * 5.0),
                    damping: None,
                });
            }
            if r + 1 < side && c + 1 < side {
                torsions.push(TorsionFile {
                    at: id(r, c),
                    between: [id(r, c + 1), id(r + 1, c)],
                    rest_cos: Some(0.0),
                    stiffness: Some(20000.0 + ((r + 2 * c) % 3) as f64 * 3000.0),
                });
            }
        }
    }
    let raw = SceneFile {
        name: Some(format!("lattice{}", side * side)),
        recording: RecordingFile {
            fps: 100.0,
            frames,
            substeps: Some(20),
            integrator: None,
            metres_per_px: None,
            ruler: None,
        },
        render: None,
        particles,
        springs,
        torsions,
        physics: None,
    };
    Scene::from_file(raw).map_err(|e| anyhow::anyhow!("lattice scene: {e}"))
}

/// lsq time against the number of bonds, on exact lattice trajectories.
pub fn scaling(quick: bool) -> anyhow::Result<String> {
    // The 32 x 32 lattice's refinement takes about two minutes on two cores: the full run
    // measures it, the quick one does not.
    let sides: &[usize] = if quick { &[3, 6] } else { &[3, 10, 32] };
    // Generations stay in the tens on every lattice (the paper's claim); a cap of 60 keeps
    // the 1024-particle run to about a minute.
    let cap = if quick { 30 } else { 60 };
    let refine_options = physfit_identify::RefineOptions::default();
    let mut out = format!(
        "\n### Scaling on lattices (exact trajectories, 100 frames, 20 substeps)\n\n\
         The linear stage is dense up to 200 unknowns, sparse Cholesky after a nested-dissection ordering beyond. The \
         refinement works on the whole object up to {patch_limit} unknowns (parameters and start state; its \
         finite-difference Jacobian costs unknowns x bonds x frames), in patches of {core} particles with a halo \
         and a driven ring beyond ({passes} passes). \
         *relative, rest cosines absolute. `ga-local`: the same lattice recorded the paper's way \
         (one Euler step per frame, 50 frames, exact), population 150; generations until the best \
         own-prediction cost is 100 times below the first generation's (at most {cap}).\n\n\
         `start-state fit`: the start state alone fitted for fixed parameters, as the models of \
         `anneal`, `ga` and `ga-local` are judged.\n\n\
         | particles | bonds | unknowns | linear stage | linear stage per bond | linear largest error* | refinement | refined largest error* | start-state fit | ga-local generations to 1/100 cost |\n\
         |---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n",
        patch_limit = refine_options.patch_limit,
        core = refine_options.core_size,
        passes = refine_options.passes,
    );
    for &side in sides {
        let truth = lattice(side, 100)?;
        let data = tracks(&truth, 0.0, SEED)?;
        let structure = truth.structure();
        let obs = Observations::from_tracks(&data, &structure, None)?;
        let problem = Problem::new(&structure, &obs)?;
        let x_true = problem.params_of(&truth).context("lattice truth")?;
        // Relative errors; rest cosines (true value 0 here) by their absolute error.
        let kinds: Vec<ParameterKind> = problem.layout.parameters.iter().map(|p| p.kind).collect();
        let rel = |x: &[f64]| {
            x.iter()
                .zip(&x_true)
                .zip(&kinds)
                .map(|((a, b), k)| {
                    if *k == ParameterKind::RestCos {
                        (a - b).abs()
                    } else {
                        ((a - b) / b.abs()).abs()
                    }
                })
                .fold(0.0, f64::max)
        };
        let t0 = Instant::now();
        let est = linear_estimate(&problem, &obs, None)?;
        let linear_time = t0.elapsed().as_secs_f64();
        // As `lsq` refines: the whole object up to `patch_limit` unknowns, in patches beyond.
        let t1 = Instant::now();
        let r = physfit_identify::refine_by_size(&problem, &obs, &est.params, &Default::default(), &())?;
        let refine_seconds = t1.elapsed().as_secs_f64();
        let refine_time = format!(
            "{:.2} s ({}, {:.0} ms per bond)",
            refine_seconds,
            if r.patches.is_empty() { "whole" } else { "patches" },
            refine_seconds * 1e3 / (truth.springs.len() + truth.torsions.len()) as f64
        );
        let refined_err = pct(rel(&r.params));
        // How the models of the other solvers are judged: the start state fitted for fixed
        // parameters (here the refined ones), whole or in patches as the refinement.
        let t2 = Instant::now();
        physfit_identify::fit_start_state_by_size(&problem, &obs, &r.params, &Default::default())?;
        let judge_seconds = t2.elapsed().as_secs_f64();
        let tg = Instant::now();
        let generations = {
            let paper = paper_way(&truth, 50)?;
            let obs = exact_observations(&paper)?;
            let cost = OneStepCost::new(&paper.structure(), &obs)?.with_split(LocalSplit::OwnPrediction);
            let ga = GaOptions {
                population: 150,
                generations: cap,
                stagnation: 0,
                ..GaOptions::default()
            };
            let o = genetic_local(&cost, cost.layout(), &ga, SEED, &());
            let first = o.history.first().copied().unwrap_or(f64::NAN);
            o.history
                .iter()
                .position(|&c| c <= 0.01 * first)
                .map_or(format!("> {cap}"), |g| (g + 1).to_string())
        };
        let ga_seconds = tg.elapsed().as_secs_f64();
        let bonds = truth.springs.len() + truth.torsions.len();
        out.push_str(&format!(
            "| {} | {} | {} | {:.1} ms | {:.1} us | {} | {} | {} | {:.2} s | {} ({:.1} s for {cap}) |\n",
            side * side,
            bonds,
            problem.dimension(),
            linear_time * 1e3,
            linear_time * 1e6 / bonds as f64,
            pct(rel(&est.params)),
            refine_time,
            refined_err,
            judge_seconds,
            generations,
            ga_seconds,
        ));
    }
    Ok(out)
}

/// Runs every identification benchmark and returns the Markdown tables.
pub fn run(quick: bool) -> anyhow::Result<String> {
    let mut out = experiments(quick)?;
    out.push_str(&paper_setup(quick)?);
    out.push_str(&cramer_rao(quick)?);
    out.push_str(&scaling(quick)?);
    Ok(out)
}
