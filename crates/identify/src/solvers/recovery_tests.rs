//! The solvers on the paper's objects, simulated the paper's way (one semi-implicit Euler step
//! per frame, so the one-step cost is exactly zero at the truth) and fitted with the one-step
//! cost from the exact recording.

use super::*;
use crate::testutil::{max_relative_error, paper3, paper5, paper8, record, Timing};
use crate::{CostFunction, LocalCostFunction, Observations, OneStepCost};
use physfit_model::{IntegratorKind, Scene};

/// The one-step cost of `truth`'s structure over its own recording, and the true parameters.
fn problem(truth: &Scene) -> (OneStepCost, Vec<f64>) {
    let obs = Observations::from_recording(&record(truth), truth, 0);
    let cost = OneStepCost::new(&truth.structure(), &obs).expect("valid problem");
    let x_true = cost.problem().params_of(truth).expect("complete truth");
    (cost, x_true)
}

/// The paper's timing: 100 frames per second, one Euler step per frame.
fn paper_timing(frames: usize) -> Timing {
    Timing {
        frames,
        substeps: 1,
        integrator: IntegratorKind::Euler,
        ..Timing::default()
    }
}

#[test]
fn anneal_recovers_the_three_particle_object_within_one_percent() {
    // 2 springs + 1 torsion, 6 unknowns, 50 frames (the paper: 50-100, errors "typically < 5%").
    let (cost, x_true) = problem(&paper3(paper_timing(50)));
    let start = cost.problem().initial_guess();
    for seed in 0..3 {
        let out = anneal(&cost, cost.layout(), &start, &AnnealOptions::default(), seed, &());
        let (err, at) = max_relative_error(&out.best, &x_true);
        assert!(err < 0.01, "seed {seed}: parameter {at} off by {:.2}%", 100.0 * err);
    }
}

#[test]
fn genetic_recovers_the_five_particle_object_within_five_percent() {
    // 4 springs + 3 torsions, 14 unknowns, 50 frames, population 150.
    let (cost, x_true) = problem(&paper5(paper_timing(50)));
    let options = GaOptions {
        population: 150,
        generations: 600,
        ..Default::default()
    };
    let out = genetic(&cost, cost.layout(), &options, 0, &());
    let (err, at) = max_relative_error(&out.best, &x_true);
    assert!(err < 0.05, "parameter {at} off by {:.2}%", 100.0 * err);
    assert!(out.history.windows(2).all(|w| w[1] <= w[0]));
}

#[test]
fn local_genetic_recovers_the_five_particle_object_within_five_percent() {
    let (cost, x_true) = problem(&paper5(paper_timing(50)));
    let out = genetic_local(&cost, cost.layout(), &GaOptions::default(), 1, &());
    let (err, at) = max_relative_error(&out.best, &x_true);
    assert!(err < 0.05, "parameter {at} off by {:.2}%", 100.0 * err);
}

/// A chain of `n` particles like the paper's 5-particle object: springs between neighbours,
/// a torsion at every interior particle, started out of equilibrium.
fn chain(n: usize, timing: Timing) -> Scene {
    let particles: Vec<(f64, [f64; 2])> = (0..n)
        .map(|k| (1.0 + 0.1 * (k % 3) as f64, [100.0 + 38.0 * k as f64, 110.0 + if k % 2 == 0 { -9.0 } else { 9.0 } + (k % 3) as f64]))
        .collect();
    let springs: Vec<(usize, usize, f64, f64)> =
        (0..n - 1).map(|k| (k, k + 1, 40.0 + 2.0 * (k % 3) as f64, 45.0 + 8.0 * (k % 4) as f64)).collect();
    let torsions: Vec<(usize, usize, usize, f64, f64)> =
        (1..n - 1).map(|k| (k, k - 1, k + 1, -0.75 - 0.05 * (k % 3) as f64, 40000.0 + 10000.0 * (k % 3) as f64)).collect();
    crate::testutil::scene_from("chain", &particles, &springs, &torsions, timing)
}

#[test]
#[ignore = "measurement"]
fn measure_chains() {
    for n in [8, 12] {
        let (cost, x_true) = problem(&chain(n, paper_timing(50)));
        let sizes: Vec<usize> = (0..n).map(|r| cost.region_parameters(r).len()).collect();
        for local in [true] {
            let mut line = format!("chain {n} ({} params, regions {sizes:?}) local {local}:", x_true.len());
            for gens in [300, 800] {
                let options = GaOptions { generations: gens, stagnation: 0, ..Default::default() };
                let t = std::time::Instant::now();
                let out = if local { genetic_local(&cost, cost.layout(), &options, 0, &()) } else { genetic(&cost, cost.layout(), &options, 0, &()) };
                line += &format!(" g{gens} {:.2}% ({} evals, {:.1}s)", 100.0 * max_relative_error(&out.best, &x_true).0, out.cost_count, t.elapsed().as_secs_f64());
            }
            eprintln!("{line}");
        }
    }
}

#[test]
#[ignore = "measurement"]
fn measure8() {
    let (cost, x_true) = problem(&paper8(paper_timing(80)));
    let kinds: Vec<_> = cost.layout().parameters.iter().map(|p| p.kind).collect();
    let errs = |x: &[f64]| -> Vec<f64> { x.iter().zip(&x_true).zip(&kinds).map(|((v, t), k)| if *k == crate::ParameterKind::RestCos { ((v - t) * 1000.0).round() / 1000.0 } else { (((v - t) / t) * 1000.0).round() / 1000.0 }).collect() };
    eprintln!("regions {:?}", (0..8).map(|r| cost.region_parameters(r).len()).collect::<Vec<_>>());
    eprintln!("cost at truth {:e}", cost.cost(&x_true));
    for local in [false, true] {
        let options = GaOptions { generations: 1500, stagnation: 0, ..Default::default() };
        let t = std::time::Instant::now();
        let out = if local { genetic_local(&cost, cost.layout(), &options, 0, &()) } else { genetic(&cost, cost.layout(), &options, 0, &()) };
        eprintln!("paper8 local {local}: cost {:e} h300 {:e} h1000 {:e} {:?}\n errs {:?}", out.best_cost, out.history[299], out.history[999], t.elapsed(), errs(&out.best));
    }
}

#[test]
#[ignore = "measurement"]
fn measure() {
    for frames in [50, 100] {
        let (cost, x_true) = problem(&paper3(paper_timing(frames)));
        for seed in 0..4 {
            let t = std::time::Instant::now();
            let out = anneal(&cost, cost.layout(), &cost.problem().initial_guess(), &AnnealOptions::default(), seed, &());
            eprintln!("paper3 {frames} anneal seed {seed}: steps {} evals {} cost {:e} err {:?} {:?}", out.iteration_count, out.cost_count, out.best_cost, max_relative_error(&out.best, &x_true), t.elapsed());
        }
        let (cost, x_true) = problem(&paper5(paper_timing(frames)));
        for local in [false, true] {
            for seed in 0..4 {
                let mut line = format!("paper5 {frames} local {local} seed {seed}:");
                for gens in [100, 200, 300, 400, 600, 1000] {
                    let options = GaOptions { generations: gens, stagnation: 0, ..Default::default() };
                    let out = if local { genetic_local(&cost, cost.layout(), &options, seed, &()) } else { genetic(&cost, cost.layout(), &options, seed, &()) };
                    line += &format!(" g{gens} {:.3}% ({} evals)", 100.0 * max_relative_error(&out.best, &x_true).0, out.cost_count);
                }
                eprintln!("{line}");
            }
        }
    }
    let (cost, x_true) = problem(&paper8(paper_timing(80)));
    for seed in 0..2 {
        let t = std::time::Instant::now();
        let out = genetic(&cost, cost.layout(), &GaOptions::default(), seed, &());
        eprintln!("paper8 80 ga seed {seed}: gens {} evals {} cost {:e} err {:?} {:?}", out.iteration_count, out.cost_count, out.best_cost, max_relative_error(&out.best, &x_true), t.elapsed());
        let t = std::time::Instant::now();
        let out = genetic_local(&cost, cost.layout(), &GaOptions::default(), seed, &());
        eprintln!("paper8 80 local seed {seed}: gens {} evals {} cost {:e} err {:?} {:?}", out.iteration_count, out.cost_count, out.best_cost, max_relative_error(&out.best, &x_true), t.elapsed());
    }
}
