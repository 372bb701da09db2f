//! [`Diagnosis`]: the `report.json` contract of `physfit diagnose`.
//!
//! ```json
//! {
//!   "structure": "hanging", "seed": 1, "window": [0, 299], "sequence": [0, 299],
//!   "track_noise": 0.08, "holdout": {"fraction": 0.25, "block_frames": 19, "held_out": [[19, 37], ...]},
//!   "findings": [{"effect": "gravity", "label": "uniform field (gravity)",
//!                 "parameters": [{"name": "gravity_x", "value": 0.3, "std_error": 0.4, "unit": "px/s^2"}, ...],
//!                 "seen": {"particles": ["b", "c"], "springs": [], "frames": [[0, 299]], "text": "..."},
//!                 "evidence": {"held_out_cost_before": 812.0, "held_out_cost_after": 41.0, "score": 9100.0, ...}}],
//!   "rejected": [{"effect": "drag", "label": "linear drag", "round": 1, "screen_score": 0.7, ...}],
//!   "localisation": {...}, "base": {...}, "final": {...}, "residuals": {...}
//! }
//! ```
//! Costs are in px² (one-step: squared distance errors over pairs at most two bonds apart;
//! multi-step: squared position errors from a fitted start state, with their RMS in px).

use physfit_model::{Scene, Vec2};
use serde::Serialize;

use crate::MultiStepFit;

/// One fitted value of a finding.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct FittedValue {
    /// Name (scene-file key where there is one: `drag`, `damping`, `length`, `stiffness`,
    /// `restitution`; `gravity_x`/`gravity_y`; a wall's `normal_x`/`normal_y`/`offset`; a
    /// tether's `anchor_x`/`anchor_y`).
    pub name: String,
    /// Value, in `unit`.
    pub value: f64,
    /// Standard error from the final fit's Jacobian and residuals (`null` if not computed).
    pub std_error: Option<f64>,
    /// Unit, e.g. `px/s^2`, `1/s`, `mass/s`, `px`.
    pub unit: String,
    /// The value in SI units, when a scale is known (see [`Diagnosis::add_si`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub value_si: Option<f64>,
    /// The standard error in SI units, when a scale is known.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub std_error_si: Option<f64>,
    /// The SI unit, e.g. `m/s^2`, `1/s`, `kg/s`, `m`, `N/m` (masses taken as kg).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub unit_si: Option<String>,
}

impl FittedValue {
    /// A value in `unit` without SI values.
    pub fn new(name: impl Into<String>, value: f64, std_error: Option<f64>, unit: impl Into<String>) -> Self {
        FittedValue {
            name: name.into(),
            value,
            std_error,
            unit: unit.into(),
            value_si: None,
            std_error_si: None,
            unit_si: None,
        }
    }

    /// Fills the SI values at scale `metres_per_px`, m/px (dimensionless values get none).
    pub fn add_si(&mut self, metres_per_px: f64) {
        if let Some((v, e, u)) = crate::units::to_si(self.value, self.std_error, &self.unit, metres_per_px) {
            self.value_si = Some(v);
            self.std_error_si = e;
            self.unit_si = Some(u.to_string());
        }
    }

    /// `value ± error unit` rounded to the error, with the SI value beside it when known:
    /// `gravity_y = 1770 ± 5 px/s^2 (9.73 ± 0.03 m/s^2)`.
    pub fn text(&self) -> String {
        let mut s = format!(
            "{} = {}",
            self.name,
            crate::units::format_quantity(self.value, self.std_error, &self.unit)
        );
        if let (Some(v), Some(u)) = (self.value_si, &self.unit_si) {
            if *u != self.unit {
                s.push_str(&format!(
                    " ({})",
                    crate::units::format_quantity(v, self.std_error_si, u)
                ));
            }
        }
        s
    }
}

/// Where a finding was seen.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct Seen {
    /// Particles that carry the effect (ids).
    pub particles: Vec<String>,
    /// Springs that carry it (`[id, id]`; added springs included).
    pub springs: Vec<[String; 2]>,
    /// Frame ranges `[first, last]` where it acts (whole window for smooth forces, the bounce
    /// frames for a wall).
    pub frames: Vec<[usize; 2]>,
    /// Image region `[x_min, y_min, x_max, y_max]`, px, where it acts.
    pub region: Option<[f64; 4]>,
    /// In words.
    pub text: String,
}

/// Why a term was accepted (or not): its held-out costs and scores.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Evidence {
    /// Weak-form screening score: held-out weak-form residual explained, over the held-out
    /// residual variance (`null` for walls, proposed from jolts instead).
    pub screen_score: Option<f64>,
    /// Score test on the fitted frames: the multi-step cost one Gauss-Newton step with the
    /// term would remove, over the noise variance (`null` for walls).
    pub score_test: Option<f64>,
    /// Multi-step cost of the model without the term on the held-out frames, px² (`null` if
    /// the term was not verified by a multi-step fit).
    pub held_out_cost_before: Option<f64>,
    /// Multi-step cost with the term, on the held-out frames, px².
    pub held_out_cost_after: Option<f64>,
    /// Residual variance used to normalise (the larger of the fitted residual variance and
    /// the squared track noise), px².
    pub noise_variance: Option<f64>,
    /// Penalty: parameters added times `ln(held-out residual count)`.
    pub penalty: f64,
    /// Multi-step cost of the model without the term on the fitted frames, px² (`null` for
    /// walls, which act only where they are met, or without held-out frames).
    pub fitted_cost_before: Option<f64>,
    /// The same with the term, px².
    pub fitted_cost_after: Option<f64>,
    /// Penalty on the fitted frames: parameters added times `ln(fitted residual count)`.
    pub fitted_penalty: f64,
    /// `(before - after) / noise_variance - penalty` on the held-out frames, or the same on
    /// the fitted frames when smaller ([`Evidence::score_on`] its own variance); accepted
    /// when positive and best.
    pub score: Option<f64>,
    /// Number of parameters the term adds.
    pub parameter_count: usize,
    /// The term judged from other observed start states (`null` when it was not judged:
    /// only a round's best candidates are).
    pub transfer: Option<Transfer>,
}

/// A candidate simulated from observed start states it was not fitted from, with and without
/// it (see `docs/diagnosis.md`, "Transfer").
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Transfer {
    /// Frames the segments start at (absolute).
    pub starts: Vec<usize>,
    /// Frames simulated after each start.
    pub segment_frames: usize,
    /// Position RMS over the segments without the candidate, px.
    pub rms_without: f64,
    /// The same with it, px.
    pub rms_with: f64,
    /// The RMS the start states' and the tracks' noise alone would give, px.
    pub rms_noise: f64,
    /// Share of the candidate's predicted change on the segments that the tracks confirm (1:
    /// all of it, 0: none); `null` when it changes nothing there.
    pub fraction: Option<f64>,
    /// Standard error of `fraction` from the noise.
    pub fraction_std_error: Option<f64>,
    /// The model's launch memory without the candidate (one frame's response to a halved
    /// launch velocity over free flight's; `null` when no start moves measurably).
    pub launch_memory_without: Option<f64>,
    /// The same with it.
    pub launch_memory_with: Option<f64>,
    /// True when the candidate transfers (the fraction above one half by `TRANSFER_Z`
    /// standard errors), false when it fits one path only (below one half by as much, over
    /// all segments or on one of them, or forgetting its launch within a frame), `null` when
    /// the segments cannot tell.
    pub transfers: Option<bool>,
    /// Each segment's figures.
    pub segments: Vec<SegmentTransfer>,
    /// In words.
    pub text: String,
}

impl Transfer {
    /// Returns true if and only if the candidate fits one path only (`transfers` false).
    pub fn fails(&self) -> bool {
        self.transfers == Some(false)
    }
}

/// One transfer segment (see [`Transfer`]).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SegmentTransfer {
    /// Frame it starts at (absolute).
    pub start: usize,
    /// Frames simulated after the start.
    pub frames: usize,
    /// Position RMS without the candidate, px.
    pub rms_without: f64,
    /// Position RMS with it, px.
    pub rms_with: f64,
    /// Share of the candidate's change the tracks confirm there (`null`: no change).
    pub fraction: Option<f64>,
    /// Its standard error from the noise.
    pub fraction_std_error: Option<f64>,
}

impl SegmentTransfer {
    /// Returns true if and only if the tracks contradict the candidate's change on this
    /// segment: the fraction below one half by `TRANSFER_Z` standard errors (its cost rises
    /// with the candidate beyond what noise explains).
    pub fn contradicts(&self) -> bool {
        match (self.fraction, self.fraction_std_error) {
            (Some(b), Some(e)) => b + super::transfer::TRANSFER_Z * e < 0.5,
            _ => false,
        }
    }
}

impl Evidence {
    /// `(before - after) / variance - penalty`: the held-out cost the term removes in units
    /// of `variance` (px²), less its penalty; `None` when a cost is missing or not finite.
    ///
    /// A smooth term must also pay for itself on the frames it was fitted to: the smaller of
    /// that score and the held-out one is returned. Multi-step residuals on held-out frames are
    /// correlated (each is propagated from one fitted start state), so a term that barely
    /// changes the fit can still move them by many variances; a term the fitted frames do not
    /// ask for is noise fitted twice.
    pub fn score_on(&self, variance: f64) -> Option<f64> {
        let gain = |before: Option<f64>, after: Option<f64>, penalty: f64| match (before, after) {
            (Some(b), Some(a)) if b.is_finite() && a.is_finite() => Some((b - a) / variance - penalty),
            _ => None,
        };
        let held = gain(self.held_out_cost_before, self.held_out_cost_after, self.penalty)?;
        match gain(
            self.fitted_cost_before,
            self.fitted_cost_after,
            self.fitted_penalty,
        ) {
            Some(fitted) => Some(held.min(fitted)),
            None => Some(held),
        }
    }
}

/// A finding the tracks cannot decide: not identified, and the model without it plus a
/// smooth track bias of the same size explains the tracks about as well.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Undecided {
    /// The finding as it was fitted (with `identified` false and its note).
    pub finding: Finding,
    /// Multi-step sum of squares over the analysed frames with the finding, px².
    pub cost_with: f64,
    /// The same without the finding, px².
    pub cost_without: f64,
    /// Without the finding, plus a polynomial track bias in time, px² (for a finding
    /// resampled frames do not keep: `cost_without`, the bias of no parameters).
    pub cost_bias: f64,
    /// Degrees of freedom the bias adds (at least the finding's parameter count; 0 for a
    /// finding resampled frames do not keep).
    pub bias_parameters: usize,
    /// Residual variance the costs are judged in, px².
    pub variance: f64,
    /// Why the finding left the model.
    pub text: String,
}

/// An effect accepted in an earlier round and taken out later: replaced by a better
/// explanation (a swap), or made redundant by the effects that joined after it.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Replaced {
    /// Effect name, as in [`Finding::effect`].
    pub effect: String,
    /// Readable label.
    pub label: String,
    /// Round in which it had been accepted.
    pub added_round: usize,
    /// Round in which it was taken out.
    pub round: usize,
    /// Labels of the effects that replaced it (empty: removed as redundant).
    pub by: Vec<String>,
    /// Why, when it was not replaced during the search (the final refit on every frame).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub reason: Option<String>,
}

/// How many seeds of the search found one finding.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SeedAgreement {
    /// The finding's label (a second wall's `wall 2`, ...).
    pub label: String,
    /// Seeds whose diagnosis found it.
    pub seeds: usize,
}

/// The diagnosis repeated with other seeds of its search (`physfit diagnose --seeds N`).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Stability {
    /// Seeds run, this diagnosis's first.
    pub seeds: Vec<u64>,
    /// This diagnosis's findings, with how many seeds found each.
    pub findings: Vec<SeedAgreement>,
    /// Findings of other seeds that this diagnosis does not hold, with how many found each.
    pub elsewhere: Vec<SeedAgreement>,
    /// True when every seed found exactly these findings.
    pub same_findings: bool,
}

/// How the greedy search ended.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct SearchSummary {
    /// Rounds run.
    pub rounds: usize,
    /// Why it stopped, in words.
    pub stop_reason: String,
}

/// One particle's share of the final residual.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct VerdictParticle {
    /// Particle id.
    pub particle: String,
    /// Its multi-step RMS under the final model, px.
    pub rms: f64,
    /// `rms` over the track noise.
    pub rms_over_noise: f64,
}

/// The final model against the track noise (see `docs/diagnosis.md`, "The verdict").
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct Verdict {
    /// True when the final multi-step RMS is within `threshold` track noises.
    pub explained: bool,
    /// The final model's multi-step RMS over the sequence, px.
    pub rms: f64,
    /// The track noise compared with, px (the measured noise; for exact tracks a floor of a
    /// millionth of the data's length scale).
    pub noise: f64,
    /// `rms / noise`.
    pub ratio: f64,
    /// The largest `ratio` that counts as explained.
    pub threshold: f64,
    /// Each particle's final residual.
    pub particles: Vec<VerdictParticle>,
    /// Frame runs `[first, last]` whose residual exceeds `threshold` noises.
    pub frames: Vec<[usize; 2]>,
    /// What the final residual looks like, in words.
    pub pattern: String,
    /// The verdict in words: `explained to the noise level: ...` or `not explained: X px RMS
    /// against a noise of Y px ...`.
    pub text: String,
}

/// An accepted effect.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Finding {
    /// `gravity`, `drag`, `quadratic_drag`, `spring_damping`, `wall` or `missing_spring`.
    pub effect: String,
    /// Readable label naming the particles or spring, e.g. `missing spring a-c`.
    pub label: String,
    /// True for a spring to a fixed point outside the structure (a tether or pivot).
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub tether: bool,
    /// Fitted values with standard errors (final joint refit).
    pub parameters: Vec<FittedValue>,
    /// Where it was seen.
    pub seen: Seen,
    /// Why it was accepted.
    pub evidence: Evidence,
    /// Greedy round (1-based) in which it was accepted.
    pub round: usize,
    /// False when some fitted value is not identified by the tracks (standard error above
    /// its value, or a tether's anchor running off; see `note`).
    pub identified: bool,
    /// What the tracks do not determine and the simpler equivalent, or how a value was held
    /// (a tether taken as rigid); `null` when there is nothing to say.
    pub note: Option<String>,
    /// Share of bootstrap resamples of the frames (blocks of one test window) in which the
    /// finding still removes more cost than its penalty, both fits held fixed: 1 when every
    /// part of the recording supports it, near 1/2 or below when it rests on a few frames
    /// (`null` when the model without it could not be fitted).
    pub inclusion_rate: Option<f64>,
}

impl Finding {
    /// For a uniform field: its strength `g = |(gravity_x, gravity_y)|`, px/s², with
    /// a standard error propagated from theirs (their covariance left out), and its SI value
    /// when theirs are known. `None` for other effects.
    pub fn field_strength(&self) -> Option<FittedValue> {
        let get = |name: &str| self.parameters.iter().find(|p| p.name == name);
        let (x, y) = (get("gravity_x")?, get("gravity_y")?);
        let strength = |gx: f64, gy: f64, ex: Option<f64>, ey: Option<f64>| {
            let g = gx.hypot(gy);
            let e = match (ex, ey) {
                (Some(ex), Some(ey)) if g > 0.0 => Some((gx * ex).hypot(gy * ey) / g),
                _ => None,
            };
            (g, e)
        };
        let (g, e) = strength(x.value, y.value, x.std_error, y.std_error);
        let mut out = FittedValue::new("g", g, e, x.unit.clone());
        if let (Some(vx), Some(vy), Some(u)) = (x.value_si, y.value_si, &x.unit_si) {
            let (g, e) = strength(vx, vy, x.std_error_si, y.std_error_si);
            out.value_si = Some(g);
            out.std_error_si = e;
            out.unit_si = Some(u.clone());
        }
        Some(out)
    }
}

/// A candidate that did not earn its place, with its best scores.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RejectedCandidate {
    /// Effect name, as in [`Finding::effect`].
    pub effect: String,
    /// Readable label.
    pub label: String,
    /// Round (1-based) of its last evaluation.
    pub round: usize,
    /// Its scores in that round.
    pub evidence: Evidence,
    /// Why it was rejected, when it improved the fit but failed transfer: `fits one path
    /// only: ...` with the transfer figures (`null` otherwise: it did not pay for its
    /// parameters).
    pub reason: Option<String>,
}

/// Costs of one model on the whole tracked sequence.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct ModelCosts {
    /// One-step cost, px² (the paper's: predicted vs observed distances of pairs at most two
    /// bonds apart, one frame ahead from the observed state).
    pub one_step: f64,
    /// Multi-step cost from the start state that suits the model best (fitted).
    pub multi_step: MultiStepFit,
}

/// Summary of a fitted model (base or final).
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct ModelSummary {
    /// Effects in the model (names).
    pub effects: Vec<String>,
    /// Number of fitted parameters (bonds plus effects).
    pub parameter_count: usize,
    /// Costs on the whole tracked sequence.
    pub costs: ModelCosts,
    /// Residual RMS of the fit over the analysed window, px.
    pub window_rms: f64,
}

/// How the frames were split for scoring.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct Holdout {
    /// Fraction of frames held out.
    pub fraction: f64,
    /// Frames per block.
    pub block_frames: usize,
    /// Held-out frame ranges `[first, last]` (absolute).
    pub held_out: Vec<[usize; 2]>,
    /// Weak-form test window, frames.
    pub test_window: usize,
}

/// A particle's residual summary (base model).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ParticleResidual {
    /// Particle id.
    pub particle: String,
    /// RMS multi-step position residual, px.
    pub position_rms: f64,
    /// `position_rms` over the track noise.
    pub position_rms_over_noise: f64,
    /// RMS residual acceleration (weak form, observed minus predicted), px/s².
    pub acceleration_rms: f64,
    /// RMS of the residual acceleration that track noise alone produces, px/s².
    pub acceleration_noise: f64,
    /// Mean residual acceleration `[ax, ay]`, px/s².
    pub mean_acceleration: [f64; 2],
    /// Direction of the mean residual, degrees from +x towards +y (image: y down, so 90 is
    /// straight down).
    pub direction_deg: f64,
    /// Correlation of the residual acceleration with the velocity (-1: always against the
    /// motion, as drag is).
    pub velocity_correlation: f64,
    /// True when the residual is beyond what track noise explains.
    pub significant: bool,
    /// `steady bias`, `slow trend`, `against the motion`, `isolated jolts`, `oscillating`,
    /// `accumulated drift` (positions off while each window's acceleration is within noise:
    /// a small force adding up), or `noise`.
    pub pattern: String,
    /// Image region `[x_min, y_min, x_max, y_max]` where its residual exceeds three noise
    /// levels.
    pub region: Option<[f64; 4]>,
}

/// A spring's residual summary (base model).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct BondResidual {
    /// The spring's ends.
    pub between: [String; 2],
    /// RMS of observed minus predicted length, px.
    pub length_rms: f64,
    /// `length_rms` over the noise of a distance (`sqrt(2)` track noise).
    pub length_rms_over_noise: f64,
    /// RMS relative residual acceleration along the bond, px/s².
    pub along_acceleration_rms: f64,
    /// Same, from track noise alone, px/s².
    pub along_acceleration_noise: f64,
    /// True when beyond noise.
    pub significant: bool,
}

/// Where the base model and the recording disagree.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct Localisation {
    /// Per particle.
    pub particles: Vec<ParticleResidual>,
    /// Per spring.
    pub bonds: Vec<BondResidual>,
    /// Frame ranges `[first, last]` where some particle's position residual exceeds three
    /// noise levels.
    pub frames: Vec<[usize; 2]>,
    /// The impulsive events found (bounces).
    pub jolts: Vec<super::jolts::Jolt>,
    /// Runs of frames where a particle is held against the field (a contact the model
    /// cannot simulate: a shelf, a floor it rests on); see `docs/diagnosis.md`.
    pub supports: Vec<super::support::Support>,
    /// Summary sentences.
    pub summary: Vec<String>,
}

/// Per-frame residual series (observed minus predicted, px) for plots.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct ResidualSeries {
    /// Particle ids (the inner index).
    pub particles: Vec<String>,
    /// Absolute frame indices (the outer index).
    pub frames: Vec<usize>,
    /// Base model: `before[f][p]` = `[dx, dy]` or `null` where untracked.
    pub before: Vec<Vec<Option<[f64; 2]>>>,
    /// Final model.
    pub after: Vec<Vec<Option<[f64; 2]>>>,
}

/// Observed and multi-step predicted positions over the tracked sequence, for pictures of
/// "the base and the diagnosed model against the observed tracks". Each model's prediction is
/// its simulation from the start state that fits it best over the whole sequence (the same
/// runs that give [`ModelSummary::costs`]'s multi-step cost and [`ResidualSeries`]), so
/// `observed - predicted` is the residual series. Positions are image pixels (x right, y
/// down, pixel centres at integer coordinates).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Predictions {
    /// Absolute frame indices (the outer index of every series), the tracked sequence's.
    pub frames: Vec<usize>,
    /// Particle ids of the structure (the inner index), pinned ones included.
    pub particles: Vec<String>,
    /// Tracked positions, px: `observed[f][p]`, `None` where the particle is not tracked.
    pub observed: Vec<Vec<Option<Vec2>>>,
    /// The base model's (structure alone) multi-step prediction, px: `base[f][p]`, `None`
    /// before the first completely tracked frame (where the simulation starts) or where the
    /// model could not be simulated.
    pub base: Vec<Vec<Option<Vec2>>>,
    /// The diagnosed model's (structure plus findings) multi-step prediction, px, as `base`.
    pub final_model: Vec<Vec<Option<Vec2>>>,
}

/// The diagnosis (the content of `report.json`; the diagnosed scene is [`Diagnosis::final_scene`]).
#[derive(Clone, Debug, Serialize)]
pub struct Diagnosis {
    /// Structure name.
    pub structure: String,
    /// Seed used (holdout phase, noise replicas).
    pub seed: u64,
    /// Analysed frames `[A, B]`.
    pub window: [usize; 2],
    /// Tracked frames `[first, last]`.
    pub sequence: [usize; 2],
    /// Track noise measured from the tracks, px per coordinate.
    pub track_noise: f64,
    /// The frame split used for scoring.
    pub holdout: Holdout,
    /// Accepted effects, in order of acceptance.
    pub findings: Vec<Finding>,
    /// Candidates that did not earn their place.
    pub rejected: Vec<RejectedCandidate>,
    /// Where the base model's residuals live.
    pub localisation: Localisation,
    /// The base model (structure alone).
    pub base: ModelSummary,
    /// The diagnosed model (structure plus findings).
    #[serde(rename = "final")]
    pub final_model: ModelSummary,
    /// Residual series before and after.
    pub residuals: ResidualSeries,
    /// The final model against the track noise.
    pub verdict: Verdict,
    /// Effects accepted and later taken out (swapped for a better explanation or made
    /// redundant).
    pub replaced: Vec<Replaced>,
    /// Findings the tracks cannot decide ("not enough data"), taken out of the model.
    pub undecided: Vec<Undecided>,
    /// How the greedy search ended.
    pub search: SearchSummary,
    /// What went wrong or was worked around.
    pub warnings: Vec<String>,
    /// The findings of other seeds of the search, when asked for (`--seeds`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub stability: Option<Stability>,
    /// Wall time, s.
    pub seconds: f64,
    /// The scale and mass unit of the SI values, when a scale is known (see
    /// [`Diagnosis::add_si`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub units: Option<crate::units::Units>,
    /// The diagnosed model as a scene: fitted values, `[physics]`, added springs and fixed
    /// particles; frame-0 state from the fit. Saved by the CLI as `fitted.toml`.
    #[serde(skip)]
    pub final_scene: Scene,
    /// Observed and predicted positions per frame for plots (not in `report.json`: the
    /// residual series carry the same information there); `None` if the models could not be
    /// simulated over the sequence.
    #[serde(skip)]
    pub predictions: Option<Predictions>,
}

impl Diagnosis {
    /// Adds SI values beside every fitted value (`value_si`, `std_error_si`, `unit_si`) and
    /// the `units` note, at scale `metres_per_px`, m/px, with the structure's masses as kg.
    pub fn add_si(&mut self, metres_per_px: f64) {
        for f in self
            .findings
            .iter_mut()
            .chain(self.undecided.iter_mut().map(|u| &mut u.finding))
        {
            for v in &mut f.parameters {
                v.add_si(metres_per_px);
            }
        }
        self.units = Some(crate::units::Units::new(metres_per_px));
    }

    /// The names of the accepted effects, in order.
    pub fn effect_names(&self) -> Vec<&str> {
        self.findings.iter().map(|f| f.effect.as_str()).collect()
    }
}
