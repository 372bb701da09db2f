//! The solvers on the paper's objects, simulated the paper's way (one semi-implicit Euler step
//! per frame, so the one-step cost is exactly zero at the truth) and fitted with the one-step
//! cost from the exact recording.

use super::*;
use crate::testutil::{max_relative_error, paper3, paper5, paper8, record, Timing};
use crate::{CostFunction, LocalSplit, Observations, OneStepCost};
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
        assert!(
            err < 0.01,
            "seed {seed}: parameter {at} off by {:.2}%",
            100.0 * err
        );
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

#[test]
fn local_genetic_then_polish_recovers_the_eight_particle_ring_within_five_percent() {
    // 8 springs + 10 torsions on 13 degrees of freedom (36 unknowns), 80 frames, 150
    // individuals, own-prediction local costs. The search alone leaves the ring's weakly
    // determined rest cosines tens of per cent off (the one-step cost's curvature spans eight
    // orders of magnitude); it has found the valley, and the polish on the same cost goes down it.
    let truth = paper8(paper_timing(80));
    let obs = Observations::from_recording(&record(&truth), &truth, 0);
    let cost = OneStepCost::new(&truth.structure(), &obs)
        .expect("valid problem")
        .with_split(LocalSplit::OwnPrediction);
    let x_true = cost.problem().params_of(&truth).expect("complete truth");
    let options = GaOptions {
        population: 150,
        generations: 100,
        ..Default::default()
    };
    let found = genetic_local(&cost, cost.layout(), &options, 1, &());
    let polished = cost.polish(&found.best, 50, &()).expect("finite cost");
    assert!(polished.best_cost <= found.best_cost);
    let (err, at) = max_relative_error(&polished.best, &x_true);
    assert!(
        err < 0.05,
        "{} off by {:.2}%",
        cost.problem().parameter_label(at),
        100.0 * err
    );
}

#[test]
fn local_genetic_own_prediction_beats_the_paired_split_on_the_ring() {
    // Same search budget, same seed: the narrow own-prediction regions bring the best cost far
    // lower than regions spread over the braced neighbourhood (the search alone, no polish).
    let truth = paper8(paper_timing(80));
    let obs = Observations::from_recording(&record(&truth), &truth, 0);
    let paired = OneStepCost::new(&truth.structure(), &obs).expect("valid problem");
    let own = paired.clone().with_split(LocalSplit::OwnPrediction);
    let x_true = own.problem().params_of(&truth).expect("complete truth");
    let options = GaOptions {
        population: 150,
        generations: 150,
        stagnation: 0,
        ..Default::default()
    };
    let a = genetic_local(&own, own.layout(), &options, 2, &());
    let b = genetic_local(&paired, paired.layout(), &options, 2, &());
    let (ea, _) = max_relative_error(&a.best, &x_true);
    let (eb, _) = max_relative_error(&b.best, &x_true);
    // Compare on one scale: the paired cost of both results.
    let (ca, cb) = (paired.cost(&a.best), paired.cost(&b.best));
    assert!(
        ca < cb,
        "paired cost: own-prediction {ca:.3e}, paired {cb:.3e} (errors {ea:.2}, {eb:.2})"
    );
}
