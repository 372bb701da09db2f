//! The solvers on the paper's objects, simulated the paper's way (one semi-implicit Euler step
//! per frame, so the one-step cost is exactly zero at the truth) and fitted with the one-step
//! cost from the exact recording.

use super::*;
use crate::testutil::{max_relative_error, paper3, paper5, record, Timing};
use crate::{Observations, OneStepCost};
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
