//! [`FitReport`]: the `fit.json` contract.
//!
//! ```json
//! {
//!   "structure": "paper3", "method": "lsq", "seed": 1,
//!   "window": [0, 99], "sequence": [0, 99],
//!   "parameters": [
//!     {"bond": {"between": ["a", "b"]}, "name": "length", "value": 40.0, "std_error": 0.01, ...},
//!     {"bond": {"at": "b", "between": ["a", "c"]}, "name": "rest_cos", "value": -0.5,
//!      "std_error": 0.001, "rest_angle_deg": 120.0, "rest_angle_std_error_deg": 0.07, ...}
//!   ],
//!   "costs": {"one_step_window": .., "one_step_sequence": .., "multi_step_window": {..}, "multi_step_sequence": {..}},
//!   "history": [..], "settings": {..}, "seconds": 0.05, "warnings": [..]
//! }
//! ```
//! `bond` holds the bond's keys exactly as the structure file writes them; `name` is the
//! scene-file key of the value (`length`, `stiffness`, `rest_cos`). Costs are in px² (one-step:
//! squared distance errors; multi-step: squared position errors, with their RMS in px).

use physfit_model::Scene;
use serde::Serialize;

use crate::{BondRef, MultiStepFit, ParameterKind, Problem};

/// A bond's keys as the scene file writes them.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(untagged)]
pub enum BondKeys {
    /// A spring: `{"between": [i, j]}`.
    Spring {
        /// The two particle ids.
        between: [String; 2],
    },
    /// A torsion: `{"at": i, "between": [j, k]}`.
    Torsion {
        /// The centre particle id.
        at: String,
        /// The two end particle ids.
        between: [String; 2],
    },
}

impl BondKeys {
    /// The keys of `bond` in `structure`.
    pub fn of(structure: &Scene, bond: BondRef) -> BondKeys {
        let id = |p: physfit_model::ParticleId| structure.particles[p.index()].id.clone();
        match bond {
            BondRef::Spring(k) => {
                let s = &structure.springs[k];
                BondKeys::Spring {
                    between: [id(s.ends[0]), id(s.ends[1])],
                }
            }
            BondRef::Torsion(k) => {
                let t = &structure.torsions[k];
                BondKeys::Torsion {
                    at: id(t.center),
                    between: [id(t.ends[0]), id(t.ends[1])],
                }
            }
        }
    }

    /// The same bond in another scene (ends in either order), if it has it.
    pub fn find_in(&self, scene: &Scene) -> Option<BondRef> {
        let same =
            |a: &[String; 2], b: [&str; 2]| (a[0] == b[0] && a[1] == b[1]) || (a[0] == b[1] && a[1] == b[0]);
        let id = |p: physfit_model::ParticleId| scene.particles[p.index()].id.as_str();
        match self {
            BondKeys::Spring { between } => scene
                .springs
                .iter()
                .position(|s| same(between, [id(s.ends[0]), id(s.ends[1])]))
                .map(BondRef::Spring),
            BondKeys::Torsion { at, between } => scene
                .torsions
                .iter()
                .position(|t| id(t.center) == at && same(between, [id(t.ends[0]), id(t.ends[1])]))
                .map(BondRef::Torsion),
        }
    }
}

/// One fitted value.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ParameterReport {
    /// The bond, by its scene-file keys.
    pub bond: BondKeys,
    /// The value's scene-file key: `length` (px), `stiffness`, or `rest_cos`.
    pub name: &'static str,
    /// The fitted value (px for lengths; energy/px² for spring stiffness; energy for torsion
    /// stiffness; dimensionless for rest cosines).
    pub value: f64,
    /// Standard error from the fit's residuals (`null` when it could not be computed).
    pub std_error: Option<f64>,
    /// Cramer-Rao bound of the standard deviation at the measured track noise.
    pub cramer_rao: Option<f64>,
    /// For a rest cosine: the rest angle, degrees.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub rest_angle_deg: Option<f64>,
    /// For a rest cosine: the rest angle's standard error, degrees.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub rest_angle_std_error_deg: Option<f64>,
    /// False when the motion does not determine this value.
    pub identifiable: bool,
    /// The true value, after [`FitReport::compare_truth`].
    #[serde(skip_serializing_if = "Option::is_none")]
    pub truth: Option<f64>,
    /// `(value - truth) / |truth|`, after [`FitReport::compare_truth`].
    #[serde(skip_serializing_if = "Option::is_none")]
    pub relative_error: Option<f64>,
    /// For a rest cosine: fitted minus true rest angle, degrees.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub angle_error_deg: Option<f64>,
    /// The value in SI units, when a scale is known (see [`FitReport::add_si`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub value_si: Option<f64>,
    /// The standard error in SI units, when a scale is known.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub std_error_si: Option<f64>,
    /// The SI unit: `m` for lengths, `N/m` for spring stiffness, `J` for torsion stiffness
    /// (masses taken as kg).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub unit_si: Option<String>,
}

impl ParameterReport {
    /// The value's unit: `px` (lengths), `energy/px^2` (spring stiffness, that is mass/s²),
    /// `energy` (torsion stiffness, mass px²/s²) or `1` (rest cosines).
    pub fn unit(&self) -> &'static str {
        match (&self.bond, self.name) {
            (_, "length") => "px",
            (BondKeys::Spring { .. }, "stiffness") => "energy/px^2",
            (BondKeys::Torsion { .. }, "stiffness") => "energy",
            _ => "1",
        }
    }

    /// `value ± error unit` rounded to the error, with the SI value beside it when known.
    pub fn text(&self) -> String {
        let mut s = crate::units::format_quantity(self.value, self.std_error, self.unit());
        if let (Some(v), Some(u)) = (self.value_si, &self.unit_si) {
            s.push_str(&format!(
                " ({})",
                crate::units::format_quantity(v, self.std_error_si, u)
            ));
        }
        s
    }
}

/// Costs of the fitted model.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct FitCosts {
    /// The paper's one-step cost over the analysed window, px².
    pub one_step_window: f64,
    /// The one-step cost over the whole tracked sequence, px².
    pub one_step_sequence: f64,
    /// Multi-step position cost over the window, from the fitted start state.
    pub multi_step_window: MultiStepFit,
    /// Multi-step position cost over the whole sequence, from the fitted start state (the
    /// paper's external cost: how well the model extrapolates).
    pub multi_step_sequence: MultiStepFit,
}

/// Parameter errors against a ground truth.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct TruthComparison {
    /// Largest `|relative error|`.
    pub max_relative_error: f64,
    /// Median `|relative error|`.
    pub median_relative_error: f64,
    /// The parameter with the largest error, e.g. `spring a-b stiffness`.
    pub worst: String,
    /// Largest rest-angle error, degrees (0 without torsions).
    pub max_angle_error_deg: f64,
}

/// Everything `fit.json` holds (see the module doc).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct FitReport {
    /// The structure's name.
    pub structure: String,
    /// The method that produced the values (`lsq`, `anneal`, `ga`, `ga-local`; `auto` says
    /// which it used in `method_used`).
    pub method: String,
    /// The method that produced the final values.
    pub method_used: String,
    /// Seed of the random solvers.
    pub seed: u64,
    /// Analysed frames `[A, B]` (inclusive).
    pub window: [usize; 2],
    /// Tracked frames `[first, last]` (inclusive).
    pub sequence: [usize; 2],
    /// Every fitted value.
    pub parameters: Vec<ParameterReport>,
    /// Costs of the fitted model.
    pub costs: FitCosts,
    /// Best cost after each iteration or generation (the solver's own cost: one-step px² for
    /// the paper's solvers, multi-step px² for lsq).
    pub history: Vec<f64>,
    /// Iterations or generations run.
    pub iteration_count: usize,
    /// Cost evaluations (simulations) made.
    pub cost_count: usize,
    /// Measured track noise, px.
    pub track_noise: f64,
    /// Residual standard deviation of the multi-step fit over the window, px.
    pub residual_sigma: f64,
    /// Solver settings, as given.
    pub settings: serde_json::Value,
    /// Wall time, s.
    pub seconds: f64,
    /// What the data or the fit could not do, in words.
    pub warnings: Vec<String>,
    /// Errors against a ground truth, after [`FitReport::compare_truth`].
    #[serde(skip_serializing_if = "Option::is_none")]
    pub truth: Option<TruthComparison>,
    /// The scale and mass unit of the SI values, when a scale is known.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub units: Option<crate::units::Units>,
}

impl FitReport {
    /// Adds SI values beside every parameter (`value_si`, `std_error_si`, `unit_si`) and the
    /// `units` note, at scale `metres_per_px`, m/px, with the structure's masses as kg.
    pub fn add_si(&mut self, metres_per_px: f64) {
        for p in &mut self.parameters {
            if let Some((v, e, u)) = crate::units::to_si(p.value, p.std_error, p.unit(), metres_per_px) {
                p.value_si = Some(v);
                p.std_error_si = e;
                p.unit_si = Some(u.to_string());
            }
        }
        self.units = Some(crate::units::Units::new(metres_per_px));
    }

    /// The parameter list of a fit.
    pub fn parameter_reports(
        problem: &Problem,
        params: &[f64],
        std_errors: Option<&[f64]>,
        cramer_rao: Option<&[f64]>,
        unidentifiable: &[usize],
    ) -> Vec<ParameterReport> {
        problem
            .layout
            .parameters
            .iter()
            .enumerate()
            .map(|(i, p)| {
                let std_error = std_errors.map(|s| s[i]).filter(|v| v.is_finite());
                let (angle, angle_err) = if p.kind == ParameterKind::RestCos {
                    let (a, e) = crate::rest_angle_degrees(params[i], std_error.unwrap_or(f64::NAN));
                    (Some(a), Some(e).filter(|e| e.is_finite()))
                } else {
                    (None, None)
                };
                ParameterReport {
                    bond: BondKeys::of(&problem.structure, p.bond),
                    name: p.kind.key(),
                    value: params[i],
                    std_error,
                    cramer_rao: cramer_rao.map(|s| s[i]).filter(|v| v.is_finite()),
                    rest_angle_deg: angle,
                    rest_angle_std_error_deg: angle_err,
                    identifiable: !unidentifiable.contains(&i),
                    truth: None,
                    relative_error: None,
                    angle_error_deg: None,
                    value_si: None,
                    std_error_si: None,
                    unit_si: None,
                }
            })
            .collect()
    }

    /// Adds each parameter's error against `truth` (a scene with the same bonds, every value
    /// given): relative error, and for rest cosines the rest-angle error in degrees; and a
    /// summary. Parameters whose bond or value `truth` lacks are left without.
    pub fn compare_truth(&mut self, truth: &Scene) {
        let mut rel = Vec::new();
        let mut worst = (0.0, String::new());
        let mut max_angle: f64 = 0.0;
        for p in &mut self.parameters {
            let Some(bond) = p.bond.find_in(truth) else {
                continue;
            };
            let t = match (bond, p.name) {
                (BondRef::Spring(k), "length") => truth.springs[k].rest_length,
                (BondRef::Spring(k), _) => truth.springs[k].stiffness,
                (BondRef::Torsion(k), "rest_cos") => truth.torsions[k].rest_cos,
                (BondRef::Torsion(k), _) => truth.torsions[k].stiffness,
            };
            let Some(t) = t else {
                continue;
            };
            let e = (p.value - t) / t.abs().max(f64::MIN_POSITIVE);
            p.truth = Some(t);
            p.relative_error = Some(e);
            if p.name == "rest_cos" {
                let a = p.value.clamp(-1.0, 1.0).acos().to_degrees() - t.clamp(-1.0, 1.0).acos().to_degrees();
                p.angle_error_deg = Some(a);
                max_angle = max_angle.max(a.abs());
            }
            if e.abs() >= worst.0 {
                let label = match &p.bond {
                    BondKeys::Spring { between } => {
                        format!("spring {}-{} {}", between[0], between[1], p.name)
                    }
                    BondKeys::Torsion { at, between } => {
                        format!("torsion {}-{}-{} {}", between[0], at, between[1], p.name)
                    }
                };
                worst = (e.abs(), label);
            }
            rel.push(e.abs());
        }
        if rel.is_empty() {
            self.truth = None;
            return;
        }
        rel.sort_by(|a, b| a.total_cmp(b));
        let median = if rel.len() % 2 == 1 {
            rel[rel.len() / 2]
        } else {
            0.5 * (rel[rel.len() / 2 - 1] + rel[rel.len() / 2])
        };
        self.truth = Some(TruthComparison {
            max_relative_error: worst.0,
            median_relative_error: median,
            worst: worst.1,
            max_angle_error_deg: max_angle,
        });
    }
}
