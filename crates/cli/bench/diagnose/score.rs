//! Judging a diagnosis against the truth it was drawn from.
//!
//! **Detectability.** An effect too weak to show above the track noise cannot be demanded.
//! Its *separation* is the multi-step RMS, px, between the true centres and the truth less
//! that effect (every other effect kept), simulated from the start state that suits the
//! latter best (`physfit_identify::diagnose::scene_costs`, as the diagnosis judges its own
//! models): what no refit of the start state can hide. It is compared with the *position
//! noise*: the larger of the track noise the diagnosis measured (fourth differences) and the
//! tracks' RMS error per coordinate against the true centres. An effect is `detectable` above
//! [`DETECTABLE`] noises, `marginal` from [`MARGINAL`] to that, `undetectable` below. The bond
//! values are held at the truth's: an effect that the structure's own bonds can imitate (a
//! spring across a torsion) still counts as detectable.
//!
//! **Matching.** A finding matches a concealed effect of its class: `gravity` a field, `drag`,
//! `quadratic_drag`, `spring_damping` (on every spring or on one; every such finding
//! matches concealed dashpots), a `missing_spring` between the same two particles, a tether
//! (`missing_spring` with `tether`) of the same particle, a `wall` whose normal is within 25
//! degrees of the true one. A finding that matches nothing concealed is a *false addition*.
//!
//! **Verdict.** A recording is *exactly right* when every detectable effect is found and
//! nothing is falsely added (marginal and undetectable effects may be found or not). The
//! diagnosis is *unsure* when its verdict is "not explained" or it lists undecided findings
//! ("not enough data"); that is reported beside, never counted as right.

use std::path::Path;

use physfit_identify::diagnose::{scene_costs, Diagnosis, Finding};
use physfit_model::{Scene, Vec2};
use physfit_tracks::TrackTable;
use serde::Serialize;

use super::draw::{Concealed, Drawn};

/// Separation over noise above which an effect is demanded.
pub const DETECTABLE: f64 = 5.0;
/// Separation over noise below which an effect is undetectable.
pub const MARGINAL: f64 = 1.0;
/// Largest angle between a found wall's normal and the true one, degrees.
const WALL_ANGLE_DEG: f64 = 25.0;

/// How well an effect shows above the noise.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Detectability {
    /// Separation above [`DETECTABLE`] noises: must be found.
    Detectable,
    /// Between [`MARGINAL`] and [`DETECTABLE`] noises: may be found or not.
    Marginal,
    /// Below [`MARGINAL`] noises.
    Undetectable,
}

impl Detectability {
    /// From a separation over noise.
    pub fn of(ratio: f64) -> Detectability {
        if ratio > DETECTABLE {
            Detectability::Detectable
        } else if ratio >= MARGINAL {
            Detectability::Marginal
        } else {
            Detectability::Undetectable
        }
    }

    /// Its name in tables.
    pub fn name(self) -> &'static str {
        match self {
            Detectability::Detectable => "detectable",
            Detectability::Marginal => "marginal",
            Detectability::Undetectable => "undetectable",
        }
    }
}

/// A found value's error against the truth.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ParameterError {
    /// What is compared: `field`, `drag`, `stiffness`, `length`, `fixed point`, `line`,
    /// `restitution`...
    pub name: &'static str,
    /// The error: relative (a fraction) for magnitudes, px for positions, absolute for a
    /// restitution.
    pub value: f64,
    /// `relative`, `px` or `absolute`.
    pub unit: &'static str,
    /// In words, with the found and true values.
    pub text: String,
}

/// One concealed effect, judged.
#[derive(Clone, Debug, Serialize)]
pub struct EffectVerdict {
    /// The effect and its true values.
    pub concealed: Concealed,
    /// Multi-step RMS between the truth and the truth without it, px (see the module doc).
    pub separation: f64,
    /// `separation` over the position noise.
    pub ratio: f64,
    /// Its class of detectability.
    pub detectability: Detectability,
    /// The label of the finding that matched it, if any.
    pub found: Option<String>,
    /// True when it is among the diagnosis's undecided findings.
    pub undecided: bool,
    /// The matched finding's values against the truth, the primary one first (empty when
    /// not found).
    pub errors: Vec<ParameterError>,
}

/// A diagnosis against its truth.
#[derive(Clone, Debug, Serialize)]
pub struct Judgement {
    /// Every concealed effect.
    pub effects: Vec<EffectVerdict>,
    /// Labels of every finding, in order.
    pub found: Vec<String>,
    /// Labels of the findings that match nothing concealed.
    pub false_additions: Vec<String>,
    /// Labels of the undecided findings.
    pub undecided: Vec<String>,
    /// Inclusion rates (`Finding::inclusion_rate`) of the findings that match a concealed
    /// effect.
    pub inclusion_right: Vec<f64>,
    /// Inclusion rates of the false additions.
    pub inclusion_false: Vec<f64>,
    /// The position noise, px (see the module doc).
    pub noise: f64,
    /// Every detectable effect found and nothing falsely added.
    pub exactly_right: bool,
    /// Some detectable effect not found.
    pub missed: bool,
    /// Some finding matches nothing concealed.
    pub falsely_added: bool,
    /// Verdict "not explained", or undecided findings.
    pub unsure: bool,
    /// The diagnosis's verdict in words.
    pub verdict: String,
}

/// Judges diagnosis `d` of `drawn`, whose structure particles' true centres are `truth`
/// and whose tracks are off the truth by `track_error` px RMS per coordinate.
pub fn judge(drawn: &Drawn, d: &Diagnosis, truth: &TrackTable, track_error: f64) -> Judgement {
    let noise = finite_or(d.track_noise, 0.0).max(finite_or(track_error, 0.0));
    let mut used = vec![false; d.findings.len()];
    let centre = Vec2::new(
        drawn.truth.render.width as f64 / 2.0,
        drawn.truth.render.height as f64 / 2.0,
    );
    let effects: Vec<EffectVerdict> = drawn
        .concealed
        .iter()
        .map(|c| {
            let separation = separation(c, &drawn.truth, truth);
            let ratio = if noise > 0.0 {
                separation / noise
            } else {
                f64::INFINITY
            };
            let matched = d
                .findings
                .iter()
                .enumerate()
                .position(|(k, f)| !used[k] && matches(c, f));
            if let Some(k) = matched {
                used[k] = true;
            }
            let finding = matched.map(|k| &d.findings[k]);
            EffectVerdict {
                concealed: c.clone(),
                separation,
                ratio,
                detectability: Detectability::of(ratio),
                found: finding.map(|f| f.label.clone()),
                undecided: d.undecided.iter().any(|u| matches(c, &u.finding)),
                errors: finding.map_or_else(Vec::new, |f| parameter_errors(c, f, centre)),
            }
        })
        .collect();
    // Further dashpot findings belong to concealed dashpots too (one per spring, say).
    let false_additions: Vec<String> = d
        .findings
        .iter()
        .zip(&used)
        .filter(|(f, &u)| !u && !drawn.concealed.iter().any(|c| same_class_any_place(c, f)))
        .map(|(f, _)| f.label.clone())
        .collect();
    let rates = |matched: bool| -> Vec<f64> {
        d.findings
            .iter()
            .zip(&used)
            .filter(|(_, &u)| u == matched)
            .filter(|(f, _)| matched || false_additions.contains(&f.label))
            .filter_map(|(f, _)| f.inclusion_rate)
            .collect()
    };
    let (inclusion_right, inclusion_false) = (rates(true), rates(false));
    let missed = effects
        .iter()
        .any(|e| e.detectability == Detectability::Detectable && e.found.is_none());
    let falsely_added = !false_additions.is_empty();
    Judgement {
        found: d.findings.iter().map(|f| f.label.clone()).collect(),
        undecided: d.undecided.iter().map(|u| u.finding.label.clone()).collect(),
        inclusion_right,
        inclusion_false,
        noise,
        exactly_right: !missed && !falsely_added,
        missed,
        falsely_added,
        unsure: !d.verdict.explained || !d.undecided.is_empty(),
        verdict: d.verdict.text.clone(),
        false_additions,
        effects,
    }
}

fn finite_or(v: f64, or: f64) -> f64 {
    if v.is_finite() {
        v
    } else {
        or
    }
}

/// The effect's separation, px (see the module doc); the plain RMS difference of the two
/// simulations from the same start when the refit cannot be made, and infinity when neither
/// can be simulated.
fn separation(c: &Concealed, truth: &Scene, centres: &TrackTable) -> f64 {
    let without = c.remove_from(truth);
    if let Some(rms) = scene_costs(&without, centres)
        .ok()
        .map(|costs| costs.multi_step.rms)
        .filter(|r| r.is_finite())
    {
        return rms;
    }
    let run = |s: &Scene| crate::cmd::simulate_scene(s, Path::new(&s.name)).ok();
    match (run(truth), run(&without)) {
        (Some(a), Some(b)) => {
            let n = without.particles.iter().filter(|p| !p.fixed).count();
            let mut sum = 0.0;
            let mut count = 0usize;
            for k in 0..a.frame_count().min(b.frame_count()) {
                for (p, q) in a.frame(k)[..n].iter().zip(&b.frame(k)[..n]) {
                    sum += (p - q).norm_squared();
                    count += 2;
                }
            }
            let rms = (sum / count.max(1) as f64).sqrt();
            finite_or(rms, f64::INFINITY)
        }
        _ => f64::INFINITY,
    }
}

/// The value of a finding's parameter `name`.
fn value(f: &Finding, name: &str) -> Option<f64> {
    f.parameters.iter().find(|p| p.name == name).map(|p| p.value)
}

/// Returns true if and only if finding `f` names effect `c` (see the module doc).
fn matches(c: &Concealed, f: &Finding) -> bool {
    match c {
        Concealed::Field { .. } => f.effect == "gravity",
        Concealed::Drag { .. } => f.effect == "drag",
        Concealed::QuadraticDrag { .. } => f.effect == "quadratic_drag",
        Concealed::SpringDamping { .. } => f.effect == "spring_damping",
        Concealed::MissingSpring { between, .. } => {
            f.effect == "missing_spring"
                && !f.tether
                && f.seen.springs.first().is_some_and(|s| {
                    (s[0] == between[0] && s[1] == between[1]) || (s[0] == between[1] && s[1] == between[0])
                })
        }
        Concealed::Tether { particle, .. } => {
            f.effect == "missing_spring" && f.tether && f.seen.particles.first() == Some(particle)
        }
        Concealed::Wall { normal, .. } => {
            let found = Vec2::new(
                value(f, "normal_x").unwrap_or(0.0),
                value(f, "normal_y").unwrap_or(0.0),
            );
            f.effect == "wall"
                && found.dot(&Vec2::new(normal[0], normal[1])) > WALL_ANGLE_DEG.to_radians().cos()
        }
    }
}

/// Returns true if and only if `f` is of `c`'s class where the place does not matter (dashpots).
fn same_class_any_place(c: &Concealed, f: &Finding) -> bool {
    matches!(c, Concealed::SpringDamping { .. }) && f.effect == "spring_damping"
}

/// The matched finding's values against the truth, the primary one first: relative errors
/// for magnitudes (a field's as a vector), px for a tether's fixed point and for a wall's line
/// (its distance from the true line at the point of that line nearest the frame's centre
/// `centre`), the restitution's absolute error. Empty when the finding lacks a value.
fn parameter_errors(c: &Concealed, f: &Finding, centre: Vec2) -> Vec<ParameterError> {
    let relative = |name: &'static str, key: &str, truth: f64| {
        value(f, key).map(|found| ParameterError {
            name,
            value: (found - truth).abs() / truth.abs(),
            unit: "relative",
            text: format!("{name} {found:.4} (truth {truth:.4})"),
        })
    };
    let errors: Option<Vec<ParameterError>> = match c {
        Concealed::Field { gravity } => (|| {
            let g = Vec2::new(value(f, "gravity_x")?, value(f, "gravity_y")?);
            let t = Vec2::new(gravity[0], gravity[1]);
            Some(vec![ParameterError {
                name: "field",
                value: (g - t).norm() / t.norm(),
                unit: "relative",
                text: format!("field ({:.1}, {:.1}) (truth ({:.1}, {:.1}))", g.x, g.y, t.x, t.y),
            }])
        })(),
        Concealed::Drag { drag } => relative("drag", "drag", *drag).map(|e| vec![e]),
        Concealed::QuadraticDrag { quadratic_drag } => {
            relative("quadratic drag", "quadratic_drag", *quadratic_drag).map(|e| vec![e])
        }
        Concealed::SpringDamping { damping } => relative("damping", "damping", *damping).map(|e| vec![e]),
        Concealed::MissingSpring {
            length, stiffness, ..
        } => (|| {
            Some(vec![
                relative("stiffness", "stiffness", *stiffness)?,
                relative("length", "length", *length)?,
            ])
        })(),
        Concealed::Tether { anchor, length, .. } => (|| {
            let a = Vec2::new(value(f, "anchor_x")?, value(f, "anchor_y")?);
            Some(vec![
                ParameterError {
                    name: "fixed point",
                    value: (a - Vec2::new(anchor[0], anchor[1])).norm(),
                    unit: "px",
                    text: format!(
                        "fixed point ({:.1}, {:.1}) (truth ({:.1}, {:.1}))",
                        a.x, a.y, anchor[0], anchor[1]
                    ),
                },
                relative("length", "length", *length)?,
            ])
        })(),
        Concealed::Wall {
            normal,
            offset,
            restitution,
        } => (|| {
            let n = Vec2::new(normal[0], normal[1]);
            let on_line = centre - (n.dot(&centre) - offset) * n;
            let found = Vec2::new(value(f, "normal_x")?, value(f, "normal_y")?);
            let found_offset = value(f, "offset")?;
            let e = value(f, "restitution")?;
            Some(vec![
                ParameterError {
                    name: "line",
                    value: (found.dot(&on_line) - found_offset).abs(),
                    unit: "px",
                    text: format!(
                        "line n ({:.3}, {:.3}) . x = {found_offset:.1} (truth ({:.3}, {:.3}), {offset:.1})",
                        found.x, found.y, n.x, n.y
                    ),
                },
                ParameterError {
                    name: "restitution",
                    value: (e - restitution).abs(),
                    unit: "absolute",
                    text: format!("restitution {e:.3} (truth {restitution:.3})"),
                },
            ])
        })(),
    };
    errors.unwrap_or_default()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn detectability_classes_split_at_one_and_five_noises() {
        assert_eq!(Detectability::of(0.5), Detectability::Undetectable);
        assert_eq!(Detectability::of(1.0), Detectability::Marginal);
        assert_eq!(Detectability::of(5.0), Detectability::Marginal);
        assert_eq!(Detectability::of(5.1), Detectability::Detectable);
        assert_eq!(Detectability::of(f64::INFINITY), Detectability::Detectable);
    }
}
