//! Costs and standard errors of a fitted [`Family`]: the paper's one-step cost, the
//! multi-step cost from the best start state, and parameter standard errors from a
//! multi-step Jacobian.

use nalgebra::DMatrix;
use physfit_model::{step_frame, StepScratch};

use super::family::{DataScales, Family};
use super::report::ModelCosts;
use super::shooting::{fit_state, Shot, ShotFit};
use crate::{neighbour_pairs, MultiStepFit, Observations};

/// The paper's one-step cost of `family` at `params` over `obs` (pairs at most two bonds
/// apart in the structure, so that models with and without added springs compare alike), px².
pub fn one_step_cost(family: &Family, params: &[f64], obs: &Observations) -> f64 {
    let (pairs, _) = neighbour_pairs(&family.structure);
    let stepping = family.structure.integration_parameters();
    let mut total = 0.0;
    let mut scratch = StepScratch::default();
    for k in 1..obs.frame_count() {
        let Some(mut state) = obs.state(k - 1) else {
            continue;
        };
        // Added fixed particles (tether anchors) join the state as the model expects.
        let model = family.model(params, Some(&mut state));
        scratch.invalidate();
        step_frame(&model, &stepping, &mut state, &mut scratch);
        for &[a, b] in &pairs {
            if let (Some(xa), Some(xb)) = (obs.positions[k][a], obs.positions[k][b]) {
                let e = (state.positions[b] - state.positions[a]).norm() - (xb - xa).norm();
                total += e * e;
            }
        }
    }
    if total.is_finite() {
        total
    } else {
        f64::INFINITY
    }
}

/// The whole-sequence costs of `family` at `params`: one-step, and multi-step from the start
/// state fitted over `sequence` (from `warm`, a state at an absolute frame, when that frame
/// is the sequence's anchor; else from the observed state).
pub fn model_costs(
    family: &Family,
    params: &[f64],
    sequence: &Observations,
    scales: &DataScales,
    warm: Option<(&physfit_model::State, usize)>,
) -> (ModelCosts, Option<(ShotFit, usize)>) {
    let one_step = one_step_cost(family, params, sequence);
    let Ok(shot) = Shot::new(sequence, family, None) else {
        return (
            ModelCosts {
                one_step,
                multi_step: MultiStepFit {
                    sum_squares: f64::INFINITY,
                    rms: f64::INFINITY,
                    residual_count: 0,
                },
            },
            None,
        );
    };
    // Start from the window fit's state when the sequence starts at the same frame.
    let (start, is_warm) = match warm {
        Some((state, frame)) if frame == sequence.first_frame + shot.anchor => (state.clone(), true),
        _ => (shot.observed_state(), false),
    };
    let fit = fit_state(&shot, family, params, &start, scales, is_warm);
    let multi_step = match &fit {
        Some(f) => MultiStepFit {
            sum_squares: f.sum_squares,
            rms: (f.sum_squares / f.residual_count.max(1) as f64).sqrt(),
            residual_count: f.residual_count,
        },
        None => MultiStepFit {
            sum_squares: f64::INFINITY,
            rms: f64::INFINITY,
            residual_count: 0,
        },
    };
    (ModelCosts { one_step, multi_step }, fit.map(|f| (f, shot.anchor)))
}

/// Standard errors of the first `dim` unknowns of a least-squares fit with Jacobian `j`
/// (all unknowns as columns) and residual sum of squares `ssr`: `sigma^2 (J^T J)^-1` with
/// `sigma^2 = ssr / (rows - columns)`, by a column-scaled eigen-decomposition (directions
/// with eigenvalues below `1e-14` of the largest are left out; a parameter mostly in them
/// gets `None`).
pub fn standard_errors(j: &DMatrix<f64>, ssr: f64, dim: usize) -> Vec<Option<f64>> {
    let (m, n) = (j.nrows(), j.ncols());
    if m <= n || n == 0 {
        return vec![None; dim];
    }
    let sigma2 = ssr / (m - n) as f64;
    let norms: Vec<f64> = (0..n).map(|c| j.column(c).norm()).collect();
    let mut js = j.clone();
    for (c, &s) in norms.iter().enumerate() {
        if s > 0.0 {
            js.column_mut(c).scale_mut(1.0 / s);
        }
    }
    let eig = (js.transpose() * &js).symmetric_eigen();
    let lmax = eig.eigenvalues.iter().fold(0.0f64, |a, &b| a.max(b));
    let mut var = vec![0.0; n];
    let mut null = vec![0.0; n];
    for (k, &l) in eig.eigenvalues.iter().enumerate() {
        let v = eig.eigenvectors.column(k);
        for c in 0..n {
            if l > 1e-14 * lmax {
                var[c] += v[c] * v[c] / l;
            } else {
                null[c] += v[c] * v[c];
            }
        }
    }
    (0..dim.min(n))
        .map(|c| (norms[c] > 0.0 && null[c] < 0.5).then(|| (var[c] * sigma2).sqrt() / norms[c]))
        .collect()
}

/// The whole-sequence costs of a complete scene (every value known: a ground truth, or a
/// diagnosed `fitted.toml`) on `tracks`, judged as the diagnosis judges its models: the
/// one-step cost, and the multi-step cost from the start state that suits the scene best
/// (fitted, forward from the first completely tracked frame).
pub fn scene_costs(
    scene: &physfit_model::Scene,
    tracks: &physfit_tracks::TrackTable,
) -> Result<ModelCosts, crate::IdentifyError> {
    let sequence = Observations::from_tracks(tracks, scene, None)?;
    let family = Family::new(scene, &sequence)?;
    if family.problem.is_some() {
        return Err(crate::IdentifyError::InvalidOption(format!(
            "scene \"{}\" has unknown bond values; its costs need every value",
            scene.name
        )));
    }
    let scales = DataScales::of(scene, &sequence);
    Ok(model_costs(&family, &[], &sequence, &scales, None).0)
}
