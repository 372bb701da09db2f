//! [`fit`]: from a structure and its tracks to a fitted scene and a [`FitReport`].
//!
//! Methods: the weak-form least squares refined by multi-step Levenberg-Marquardt (`lsq`, fast
//! and exact), the paper's simulated annealing (`anneal`) and genetic algorithms (`ga`,
//! `ga-local`) on the one-step cost, and `auto`: `lsq`, falling back to the local genetic
//! algorithm followed by the same refinement where the refined fit is poor (its residual RMS
//! above three times the measured track noise), keeping whichever extrapolates better.
//!
//! Whatever the method, the result is judged the same way: the start state is fitted for the
//! final parameters (so a model is not blamed for a noisy observed start), then the one-step
//! and multi-step costs are computed over the window and the whole sequence, and the
//! uncertainty of every parameter from the multi-step Jacobian.

use std::str::FromStr;
use std::time::Instant;

use physfit_model::{step_frame, Scene, State, StepScratch};
use physfit_tracks::TrackTable;
use serde::{Deserialize, Serialize};

use crate::solvers::{anneal, genetic, genetic_local, AnnealOptions, GaOptions};
use crate::{
    fit_start_state_by_size, linear_estimate, refine_by_size, uncertainty, CostFunction, FitCosts, FitReport,
    IdentifyError, LocalSplit, MultiStepCost, Observations, Observer, OneStepCost, Problem, RefineOptions,
    Refinement,
};

/// How the parameters are searched for.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Method {
    /// Least squares, falling back to the local genetic algorithm where the fit is poor.
    #[default]
    Auto,
    /// Weak-form linear least squares refined by multi-step Levenberg-Marquardt.
    Lsq,
    /// The paper's simulated annealing on the one-step cost.
    Anneal,
    /// The paper's global genetic algorithm on the one-step cost.
    Ga,
    /// The paper's local genetic algorithm on the one-step cost.
    GaLocal,
}

impl Method {
    /// The method's name on the command line and in reports.
    pub fn name(self) -> &'static str {
        match self {
            Method::Auto => "auto",
            Method::Lsq => "lsq",
            Method::Anneal => "anneal",
            Method::Ga => "ga",
            Method::GaLocal => "ga-local",
        }
    }
}

impl std::fmt::Display for Method {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Method {
    type Err = IdentifyError;
    fn from_str(s: &str) -> Result<Method, IdentifyError> {
        [
            Method::Auto,
            Method::Lsq,
            Method::Anneal,
            Method::Ga,
            Method::GaLocal,
        ]
        .into_iter()
        .find(|m| m.name() == s)
        .ok_or_else(|| {
            IdentifyError::InvalidOption(format!(
                "unknown method `{s}` (expected auto, lsq, anneal, ga or ga-local)"
            ))
        })
    }
}

/// Settings of [`fit`]. `FitOptions::default()` holds the paper's values.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct FitOptions {
    /// The search method.
    pub method: Method,
    /// Seed of the random solvers (same seed, same result).
    pub seed: u64,
    /// Analysed frames `(A, B)`, inclusive; all tracked frames when `None`.
    pub window: Option<(usize, usize)>,
    /// Genetic algorithms' population (the paper: 100-200). Overrides `ga.population`.
    pub population: usize,
    /// Genetic algorithms' maximum generations. Overrides `ga.generations`.
    pub generations: usize,
    /// Annealing settings.
    pub anneal: AnnealOptions,
    /// Genetic algorithm settings (population and generations from the fields above).
    pub ga: GaOptions,
    /// Least-squares refinement settings.
    pub refine: RefineOptions,
    /// Weak-form test window, frames (`None`: from the data).
    pub test_window: Option<usize>,
    /// Levenberg-Marquardt iterations that polish the result of `anneal`, `ga` and `ga-local`
    /// on the cost they searched (0: report the search's own best). Default 50.
    pub polish_iterations: usize,
}

impl Default for FitOptions {
    fn default() -> Self {
        let ga = GaOptions::default();
        FitOptions {
            method: Method::Auto,
            seed: 1,
            window: None,
            population: ga.population,
            generations: ga.generations,
            anneal: AnnealOptions::default(),
            ga,
            refine: RefineOptions::default(),
            test_window: None,
            polish_iterations: 50,
        }
    }
}

/// The outcome of [`fit`].
#[derive(Clone, Debug)]
pub struct FitResult {
    /// The structure with every value filled in, and its particles' positions and velocities
    /// at frame 0 set to the fitted motion's: it simulates and renders again.
    pub fitted: Scene,
    /// The report (`fit.json`).
    pub report: FitReport,
    /// The fitted state at the anchor frame.
    pub anchor_state: State,
    /// Absolute index of the anchor frame.
    pub anchor_frame: usize,
}

/// What one search produced before judging.
struct Solved {
    params: Vec<f64>,
    refinement: Option<Refinement>,
    history: Vec<f64>,
    iteration_count: usize,
    cost_count: usize,
    method_used: Method,
    warnings: Vec<String>,
}

/// Fits `structure`'s unknown bond values to `tracks` (see the module doc).
pub fn fit(
    structure: &Scene,
    tracks: &TrackTable,
    options: &FitOptions,
    observer: &dyn Observer,
) -> Result<FitResult, IdentifyError> {
    let sequence = Observations::from_tracks(tracks, structure, None)?;
    fit_observations(structure, &sequence, options, observer)
}

/// As [`fit`], from observations of the whole tracked sequence.
pub fn fit_observations(
    structure: &Scene,
    sequence: &Observations,
    options: &FitOptions,
    observer: &dyn Observer,
) -> Result<FitResult, IdentifyError> {
    let t0 = Instant::now();
    let obs = match options.window {
        Some((a, b)) => sequence.restrict(a, b)?,
        None => sequence.clone(),
    };
    let problem = Problem::new(structure, &obs)?;
    obs.require_frames(options.method.name(), 3)?;
    let mut ga = options.ga.clone();
    ga.population = options.population;
    ga.generations = options.generations;

    let solved = match options.method {
        Method::Lsq => solve_lsq(&problem, &obs, options, observer)?,
        Method::Anneal | Method::Ga | Method::GaLocal => {
            solve_paper(&problem, &obs, options.method, &ga, options, observer)?
        }
        Method::Auto => solve_auto(&problem, &obs, &ga, options, observer)?,
    };

    // Judge: fitted start state, costs, uncertainty.
    let refinement = match solved.refinement {
        Some(r) => r,
        None => fit_start_state_by_size(&problem, &obs, &solved.params, &options.refine)?,
    };
    let params = refinement.params.clone();
    let unc = uncertainty(&problem, &refinement, obs.noise);
    let anchor_frame = refinement.anchor_frame;
    let state = refinement.initial_state.clone();
    let one_step_window = OneStepCost::with_problem(problem.clone(), &obs)
        .map(|c| c.cost(&params))
        .unwrap_or(f64::NAN);
    let one_step_sequence = OneStepCost::with_problem(problem.clone(), sequence)
        .map(|c| c.cost(&params))
        .unwrap_or(f64::NAN);
    let window_cost = MultiStepCost::new(problem.clone(), &obs)?.with_anchor(anchor_frame - obs.first_frame);
    let sequence_cost =
        MultiStepCost::new(problem.clone(), sequence)?.with_anchor(anchor_frame - sequence.first_frame);
    let costs = FitCosts {
        one_step_window,
        one_step_sequence,
        multi_step_window: window_cost.evaluate_from(&params, &state),
        multi_step_sequence: sequence_cost.evaluate_from(&params, &state),
    };

    let mut warnings = obs.warnings.clone();
    warnings.extend(solved.warnings);
    warnings.extend(unc.warnings.iter().cloned());
    let mut fitted = problem.fitted_scene(&params);
    if let Some(s0) = state_at_frame_zero(&problem, &params, &state, anchor_frame) {
        for (p, spec) in fitted.particles.iter_mut().enumerate() {
            if !spec.fixed {
                spec.position = s0.positions[p];
                spec.velocity = s0.velocities[p];
            }
        }
    } else {
        warnings.push("the fitted motion could not be run back to frame 0; particle start positions are the structure's".into());
    }
    let settings = settings_json(options, &ga);
    let mut report = FitReport {
        structure: structure.name.clone(),
        method: options.method.name().into(),
        method_used: solved.method_used.name().into(),
        seed: options.seed,
        window: [obs.first_frame, obs.last_frame()],
        sequence: [sequence.first_frame, sequence.last_frame()],
        parameters: FitReport::parameter_reports(
            &problem,
            &params,
            Some(&unc.std_errors),
            Some(&unc.cramer_rao),
            &unc.unidentifiable,
        ),
        costs,
        history: solved.history,
        iteration_count: solved.iteration_count,
        cost_count: solved.cost_count,
        track_noise: obs.noise,
        residual_sigma: unc.residual_sigma,
        settings,
        seconds: t0.elapsed().as_secs_f64(),
        warnings,
        truth: None,
        units: None,
    };
    if let Some(m) = structure.recording.metres_per_px {
        report.add_si(m);
    }
    Ok(FitResult {
        fitted,
        report,
        anchor_state: state,
        anchor_frame,
    })
}

fn settings_json(options: &FitOptions, ga: &GaOptions) -> serde_json::Value {
    let mut v = serde_json::json!({
        "method": options.method.name(),
        "seed": options.seed,
        "window": options.window.map(|(a, b)| [a, b]),
    });
    let lsq = serde_json::json!({ "test_window": options.test_window, "refine": options.refine });
    match options.method {
        Method::Lsq => v["lsq"] = lsq,
        Method::Anneal => {
            v["anneal"] = serde_json::to_value(&options.anneal).unwrap_or_default();
            v["polish_iterations"] = options.polish_iterations.into();
        }
        Method::Ga | Method::GaLocal if options.polish_iterations > 0 => {
            v["ga"] = serde_json::to_value(ga).unwrap_or_default();
            v["polish_iterations"] = options.polish_iterations.into();
        }
        Method::Ga | Method::GaLocal => v["ga"] = serde_json::to_value(ga).unwrap_or_default(),
        Method::Auto => {
            v["lsq"] = lsq;
            v["ga"] = serde_json::to_value(ga).unwrap_or_default();
        }
    }
    v
}

/// Runs the fitted model from the anchor back to frame 0 (velocities reversed).
fn state_at_frame_zero(
    problem: &Problem,
    params: &[f64],
    anchor: &State,
    anchor_frame: usize,
) -> Option<State> {
    let model = problem.model(params);
    let stepping = problem.integration_parameters();
    let mut s = anchor.clone();
    s.velocities.iter_mut().for_each(|v| *v = -*v);
    let mut scratch = StepScratch::new(s.len());
    for _ in 0..anchor_frame {
        step_frame(&model, &stepping, &mut s, &mut scratch);
    }
    s.velocities.iter_mut().for_each(|v| *v = -*v);
    let finite = s
        .positions
        .iter()
        .chain(&s.velocities)
        .all(|v| v.x.is_finite() && v.y.is_finite());
    finite.then_some(s)
}

fn solve_lsq(
    problem: &Problem,
    obs: &Observations,
    options: &FitOptions,
    observer: &dyn Observer,
) -> Result<Solved, IdentifyError> {
    let est = linear_estimate(problem, obs, options.test_window)?;
    let r = refine_by_size(problem, obs, &est.params, &options.refine, observer)?;
    Ok(Solved {
        params: r.params.clone(),
        history: r.history.clone(),
        iteration_count: r.iteration_count,
        cost_count: r.cost_count + 1,
        refinement: Some(r),
        method_used: Method::Lsq,
        warnings: est.warnings,
    })
}

fn solve_paper(
    problem: &Problem,
    obs: &Observations,
    method: Method,
    ga: &GaOptions,
    options: &FitOptions,
    observer: &dyn Observer,
) -> Result<Solved, IdentifyError> {
    let mut cost = OneStepCost::with_problem(problem.clone(), obs)?;
    if method == Method::GaLocal {
        cost = cost.with_split(LocalSplit::OwnPrediction);
    }
    let layout = &problem.layout;
    let mut outcome = match method {
        Method::Anneal => anneal(
            &cost,
            layout,
            &problem.initial_guess(),
            &options.anneal,
            options.seed,
            observer,
        ),
        Method::Ga => genetic(&cost, layout, ga, options.seed, observer),
        _ => genetic_local(&cost, layout, ga, options.seed, observer),
    };
    if !outcome.best_cost.is_finite() || outcome.best.len() != problem.dimension() {
        return Err(IdentifyError::NoFiniteCost {
            method: method.name().into(),
            detail: format!("{} cost evaluations", outcome.cost_count),
        });
    }
    if options.polish_iterations > 0 {
        if let Some(p) = cost.polish(&outcome.best, options.polish_iterations, observer) {
            if p.best_cost <= outcome.best_cost {
                outcome.best = p.best;
                outcome.best_cost = p.best_cost;
            }
            outcome.history.extend(p.history);
            outcome.iteration_count += p.iteration_count;
            outcome.cost_count += p.cost_count;
        }
    }
    Ok(Solved {
        params: outcome.best,
        refinement: None,
        history: outcome.history,
        iteration_count: outcome.iteration_count,
        cost_count: outcome.cost_count,
        method_used: method,
        warnings: Vec::new(),
    })
}

fn solve_auto(
    problem: &Problem,
    obs: &Observations,
    ga: &GaOptions,
    options: &FitOptions,
    observer: &dyn Observer,
) -> Result<Solved, IdentifyError> {
    let first = solve_lsq(problem, obs, options, observer);
    // A good fit leaves residuals at the measured track noise.
    let poor = |r: &Refinement| r.fit.rms.partial_cmp(&(3.0 * obs.noise)) != Some(std::cmp::Ordering::Less);
    let mut warnings = Vec::new();
    match &first {
        Ok(s) => match &s.refinement {
            Some(r) if !poor(r) => return first,
            Some(r) => warnings.push(format!(
                "least squares left {:.3} px RMS against {:.3} px track noise; tried the local genetic algorithm too",
                r.fit.rms, obs.noise
            )),
            None => {}
        },
        Err(e) => warnings.push(format!("least squares failed ({e}); used the local genetic algorithm")),
    }
    let global = solve_paper(problem, obs, Method::GaLocal, ga, options, observer)?;
    let refined = refine_by_size(problem, obs, &global.params, &options.refine, observer);
    let candidate = match refined {
        Ok(r) => Solved {
            params: r.params.clone(),
            history: global.history.iter().chain(&r.history).copied().collect(),
            iteration_count: global.iteration_count + r.iteration_count,
            cost_count: global.cost_count + r.cost_count,
            refinement: Some(r),
            method_used: Method::GaLocal,
            warnings: Vec::new(),
        },
        Err(_) => global,
    };
    let score = |s: &Solved| s.refinement.as_ref().map_or(f64::INFINITY, |r| r.fit.sum_squares);
    let mut best = match first {
        Ok(f) if score(&f) <= score(&candidate) => f,
        _ => candidate,
    };
    best.warnings.splice(0..0, warnings);
    Ok(best)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testutil::{paper3, paper5, paper8, scene_from, tracks, Timing};

    fn lsq() -> FitOptions {
        FitOptions {
            method: Method::Lsq,
            ..FitOptions::default()
        }
    }

    #[test]
    fn lsq_recovers_paper_objects_within_one_percent_at_005_px_noise() {
        // 200 frames: enough that each parameter's Cramer-Rao bound is well below 1%.
        let timing = Timing {
            frames: 200,
            ..Timing::default()
        };
        for truth in [paper3(timing), paper5(timing)] {
            let t = tracks(&truth, 0.05, 7);
            let mut r = fit(&truth.structure(), &t, &lsq(), &()).unwrap();
            r.report.compare_truth(&truth);
            let cmp = r.report.truth.clone().unwrap();
            assert!(
                cmp.max_relative_error < 0.01,
                "{}: {} off by {:.3}%",
                truth.name,
                cmp.worst,
                cmp.max_relative_error * 100.0
            );
            // Each error is what the reported standard error says it should be.
            for p in &r.report.parameters {
                let err = (p.value - p.truth.unwrap()).abs();
                assert!(
                    err < 4.0 * p.std_error.unwrap(),
                    "{:?} {}: error {err} vs std error {:?}",
                    p.bond,
                    p.name,
                    p.std_error
                );
            }
            // The residuals are at the noise level, and the measured noise is right.
            assert!(
                (r.report.residual_sigma - 0.05).abs() < 0.01,
                "sigma {}",
                r.report.residual_sigma
            );
            assert!(
                (r.report.track_noise - 0.05).abs() < 0.015,
                "noise {}",
                r.report.track_noise
            );
            // The fitted scene simulates back onto the tracks.
            let rec = crate::testutil::record(&r.fitted);
            let truth_rec = crate::testutil::record(&truth);
            let worst = (0..rec.frame_count())
                .flat_map(|k| {
                    rec.frame(k)
                        .iter()
                        .zip(truth_rec.frame(k))
                        .map(|(a, b)| (a - b).norm())
                        .collect::<Vec<_>>()
                })
                .fold(0.0, f64::max);
            assert!(worst < 0.1, "fitted scene drifts {worst} px from the truth");
        }
    }

    #[test]
    fn lsq_recovers_paper8_from_exact_trajectories() {
        let truth = paper8(Timing {
            frames: 80,
            ..Timing::default()
        });
        let t = tracks(&truth, 0.0, 0);
        let mut r = fit(&truth.structure(), &t, &lsq(), &()).unwrap();
        r.report.compare_truth(&truth);
        let cmp = r.report.truth.clone().unwrap();
        assert!(
            cmp.max_relative_error < 1e-3,
            "{} off by {:.4}%",
            cmp.worst,
            cmp.max_relative_error * 100.0
        );
    }

    #[test]
    fn standard_errors_shrink_as_the_recording_lengthens() {
        let mut previous: Option<Vec<f64>> = None;
        for frames in [60, 240] {
            let truth = paper3(Timing {
                frames,
                ..Timing::default()
            });
            let r = fit(&truth.structure(), &tracks(&truth, 0.05, 11), &lsq(), &()).unwrap();
            let se: Vec<f64> = r.report.parameters.iter().map(|p| p.std_error.unwrap()).collect();
            if let Some(prev) = &previous {
                for ((a, b), p) in prev.iter().zip(&se).zip(&r.report.parameters) {
                    assert!(b < &(0.8 * a), "{:?} {}: {a} -> {b}", p.bond, p.name);
                }
            }
            previous = Some(se);
        }
    }

    #[test]
    fn a_spring_that_never_stretches_is_flagged() {
        // paper3 plus a pair drifting together at its spring's rest length: that spring's
        // stiffness has no effect on the motion.
        let base = paper3(Timing::default());
        let mut raw = base.to_file();
        let truth3 = scene_from(
            "pair",
            &[(1.0, [300.0, 300.0]), (1.0, [330.0, 300.0])],
            &[(0, 1, 30.0, 40.0)],
            &[],
            Timing::default(),
        )
        .to_file();
        for (k, mut p) in truth3.particles.into_iter().enumerate() {
            p.id = format!("q{k}");
            p.velocity = Some([5.0, -3.0]);
            raw.particles.push(p);
        }
        let mut s = truth3.springs[0].clone();
        s.between = ["q0".into(), "q1".into()];
        raw.springs.push(s);
        let truth = Scene::from_file(raw).unwrap();
        let r = fit(&truth.structure(), &tracks(&truth, 0.0, 0), &lsq(), &()).unwrap();
        let flagged: Vec<_> = r
            .report
            .parameters
            .iter()
            .filter(|p| !p.identifiable)
            .map(|p| (p.bond.clone(), p.name))
            .collect();
        assert_eq!(flagged.len(), 1, "{flagged:?}");
        assert_eq!(flagged[0].1, "stiffness");
        assert!(matches!(&flagged[0].0, crate::BondKeys::Spring { between } if between[0] == "q0"));
        assert!(
            r.report
                .warnings
                .iter()
                .any(|w| w.contains("spring q0-q1 stiffness") && w.contains("not identifiable")),
            "{:?}",
            r.report.warnings
        );
        // Everything else is still found.
        let mut rep = r.report.clone();
        rep.compare_truth(&truth);
        for p in rep.parameters.iter().filter(|p| p.identifiable) {
            assert!(p.relative_error.unwrap().abs() < 1e-3, "{:?} {}", p.bond, p.name);
        }
    }

    #[test]
    fn fit_names_the_untracked_particle_and_refuses_a_structure_with_nothing_unknown() {
        let truth = paper3(Timing::default());
        let mut t = tracks(&truth, 0.0, 0);
        t.points.retain(|p| p.particle != "p2");
        let e = fit(&truth.structure(), &t, &lsq(), &()).unwrap_err();
        assert!(e.to_string().contains("\"p2\""), "{e}");
        let e = fit(&truth, &tracks(&truth, 0.0, 0), &lsq(), &()).unwrap_err();
        assert_eq!(e, IdentifyError::NoUnknowns);
    }

    #[test]
    fn report_json_has_the_contract_keys() {
        let truth = paper3(Timing {
            frames: 60,
            ..Timing::default()
        });
        let mut r = fit(&truth.structure(), &tracks(&truth, 0.0, 0), &lsq(), &()).unwrap();
        r.report.compare_truth(&truth);
        let v = serde_json::to_value(&r.report).unwrap();
        let p = &v["parameters"];
        assert_eq!(p.as_array().unwrap().len(), 6);
        assert_eq!(p[0]["bond"], serde_json::json!({"between": ["p0", "p1"]}));
        assert_eq!(p[0]["name"], "length");
        assert_eq!(
            p[4]["bond"],
            serde_json::json!({"at": "p1", "between": ["p0", "p2"]})
        );
        assert_eq!(p[4]["name"], "rest_cos");
        assert!((p[4]["rest_angle_deg"].as_f64().unwrap() - 120.0).abs() < 0.01);
        assert!(p[4]["angle_error_deg"].as_f64().unwrap().abs() < 0.01);
        for key in [
            "one_step_window",
            "one_step_sequence",
            "multi_step_window",
            "multi_step_sequence",
        ] {
            assert!(!v["costs"][key].is_null(), "{key}");
        }
        // The fitted scene is complete and renders again.
        assert_eq!(r.fitted.unknown_count(), 0);
        assert!(r.fitted.model().is_ok());
    }

    #[test]
    fn methods_parse_by_name_and_unknown_names_are_errors() {
        for m in [
            Method::Auto,
            Method::Lsq,
            Method::Anneal,
            Method::Ga,
            Method::GaLocal,
        ] {
            assert_eq!(m.name().parse::<Method>().unwrap(), m);
        }
        let e = "simplex".parse::<Method>().unwrap_err().to_string();
        assert!(e.contains("simplex") && e.contains("ga-local"), "{e}");
    }

    #[test]
    fn paper_solvers_are_judged_on_their_own_cost_and_auto_keeps_a_good_lsq() {
        let truth = paper3(Timing {
            frames: 60,
            ..Timing::default()
        });
        let t = tracks(&truth, 0.0, 0);
        let mut options = FitOptions {
            method: Method::Anneal,
            ..FitOptions::default()
        };
        options.anneal.iterations = 300;
        let r = fit(&truth.structure(), &t, &options, &()).unwrap();
        assert_eq!(r.report.method_used, "anneal");
        // The report's one-step cost is the annealer's best cost: same cost, same parameters.
        let best = *r.report.history.last().unwrap();
        assert!(
            (r.report.costs.one_step_window - best).abs() <= 1e-12 * best.abs(),
            "{} vs {best}",
            r.report.costs.one_step_window
        );
        // Auto on exact data: least squares fits to rounding, no fallback needed.
        let r = fit(&truth.structure(), &t, &FitOptions::default(), &()).unwrap();
        assert_eq!(r.report.method_used, "lsq");
        assert!(r.report.costs.multi_step_sequence.rms < 1e-6);
    }
}
