//! The greedy search: screen every candidate effect in the weak form, verify the most
//! promising by multi-step fits scored on held-out frames, accept the best while it earns its
//! place.
//!
//! **Screening.** With the bond columns and the accepted effects' columns, each smooth
//! candidate's columns are added and the weak-form system is solved on the fitted rows; its
//! screen score is the held-out weak-form residual it removes over the held-out residual
//! variance. A tether's anchor is searched (grid, then pattern search) on the fitted rows.
//! Walls are proposed from jolts instead (see [`super::jolts`]).
//!
//! **Verification.** The best few candidates (and every proposed wall) are fitted by
//! multi-step least squares on the fitted frames, bond values and all effects together, from
//! the weak-form joint estimate (and from the current fit plus the new term, keeping the
//! better). A candidate's score is the multi-step cost it removes on the held-out frames,
//! over the residual variance (never below the squared track noise), minus `k ln N` for its
//! `k` parameters and `N` held-out residuals (the Bayesian information criterion's
//! penalty). The best positive score is accepted; the search stops when none is positive.

use physfit_model::{Scene, State, Vec2};

use super::effect::{Effect, WeakShape};
use super::family::{DataScales, Family};
use super::jolts::{Jolt, WallGuess};
use super::oscillation;
use super::report::Evidence;
use super::shooting::{fit_shot, Shot, ShotFit};
use super::weak::{residuals, solve, WeakForm};
use crate::Observations;

/// Most smooth candidates verified by multi-step fits per round.
pub const VERIFIED_PER_ROUND: usize = 3;

/// Least screen score, per parameter, for a smooth candidate to be verified.
pub const SCREEN_PER_PARAMETER: f64 = 2.0;

/// Factors on a bond stiffness's parameter scale the base fit also starts from where the
/// weak form cannot tell the stiffness (see [`Context::base_fit`]): a decade and two below,
/// one above.
pub const BASE_STIFFNESS_FACTORS: [f64; 3] = [0.1, 0.01, 10.0];

/// Factors on a tether's anchor distance tried by [`Context::along_tether`].
/// Negative: the anchor on the other side of the particle, at the same distance, the tether
/// compressed where it was stretched (a stiff tether pulls nearly alike from either side).
pub const ALONG_TETHER_FACTORS: [f64; 5] = [0.5, 0.75, 1.5, 2.5, -1.0];

/// An anchor farther than this many data length scales from its particle is also tried at
/// [`ALONG_TETHER_SCALES`] length scales by [`Context::along_tether`].
pub const ALONG_TETHER_FAR: f64 = 8.0;

/// Anchor distances, in data length scales, tried for a far anchor.
pub const ALONG_TETHER_SCALES: [f64; 3] = [1.0, 2.0, 4.0];

/// Most passes of [`Context::along_tether`] per tether.
pub const ALONG_TETHER_PASSES: usize = 3;

/// Distances of a ringing tether's trial anchors from its particle's mean position, in
/// length scales of the data (see [`Context::ringing_tether`]).
pub const RING_ANCHOR_SCALES: [f64; 1] = [4.0];

/// How many times stiffer than the weak form's value a spring's stiffness heard in the
/// oscillation of its length must be to start the base fit from it.
pub const HEARD_STIFFER: f64 = 1.5;

/// Most pairs of effects (the field with another candidate) verified per round.
pub const VERIFIED_PAIRS_PER_ROUND: usize = 2;

/// A fit explains the tracks when its residual variance is at most this many times the
/// squared track noise (its RMS within twice the noise): the localisation's significance
/// rule, applied to the whole fit.
pub const EXPLAINED_VARIANCE_RATIO: f64 = 4.0;

/// Most missing-spring pairs screened (the nearest pairs first).
pub const MAX_PAIRS: usize = 200;

/// Most particles screened for a tether.
pub const MAX_TETHERS: usize = 24;

/// Levenberg-Marquardt iterations per span stage.
pub const SHOT_ITERATIONS: usize = 40;

/// The fitted state of the search: a family and its fit on the fitted frames.
#[derive(Clone, Debug)]
pub struct Current {
    /// Structure plus accepted effects.
    pub family: Family,
    /// Its multi-step fit on the fitted frames.
    pub fit: ShotFit,
    /// Multi-step cost on the held-out frames, px².
    pub held_cost: f64,
}

/// A candidate for one round.
#[derive(Clone, Debug)]
pub struct Proposal {
    /// The effect.
    pub effect: Effect,
    /// Initial parameters of the effect.
    pub init: Vec<f64>,
    /// Weak-form screen score (`None` for walls).
    pub screen: Option<f64>,
    /// Multi-step score test (`None` for walls or before it is computed).
    pub score_test: Option<f64>,
    /// For walls: the jolts it explains.
    pub jolts: Vec<Jolt>,
}

/// A particle's ring in its residual (see [`Context::rings`]).
#[derive(Clone, Debug)]
pub struct Ring {
    /// The particle (structure index).
    pub particle: usize,
    /// Angular frequency, rad/s.
    pub omega: f64,
    /// Unit direction of the ring's line.
    pub direction: Vec2,
    /// Amplitude along that line, px.
    pub amplitude: f64,
    /// The particle's mean observed position, px.
    pub mean: Vec2,
}

/// A verified candidate (one effect, or a wall with a smooth effect).
#[derive(Clone, Debug)]
pub struct Verified {
    /// The proposals, in the order their effects were appended.
    pub proposals: Vec<Proposal>,
    /// The fitted state with it (when the fit ran).
    pub current: Option<Current>,
    /// Its scores.
    pub evidence: Evidence,
    /// The index of an accepted effect this candidate replaces (a swap), if any.
    pub removes: Option<usize>,
}

/// Everything the search needs about the data.
pub struct Context<'a> {
    /// Analysed observations.
    pub obs: &'a Observations,
    /// Weak-form system (bond columns inside).
    pub weak: &'a WeakForm,
    /// Shot over the analysed frames with the fitted-frame mask.
    pub shot: &'a Shot<'a>,
    /// Held-out frame mask.
    pub held: &'a [bool],
    /// Observed start state at the anchor.
    pub start: &'a State,
    /// Data scales.
    pub scales: &'a DataScales,
}

impl Context<'_> {
    fn train_rows(&self) -> Vec<usize> {
        (0..self.weak.rows.len())
            .filter(|&r| self.weak.rows[r].train)
            .collect()
    }

    fn held_rows(&self) -> Vec<usize> {
        (0..self.weak.rows.len())
            .filter(|&r| self.weak.rows[r].held)
            .collect()
    }

    /// `k ln N` for `k` parameters, with `N` the fitted residuals of `current`.
    pub fn train_penalty(&self, current: &Current, k: usize) -> f64 {
        k as f64 * (current.fit.residual_count.max(2) as f64).ln()
    }

    /// Held-out residual count of the multi-step cost.
    pub fn held_count(&self, family: &Family) -> usize {
        let obs = self.obs;
        (0..obs.frame_count())
            .filter(|&k| self.held[k] && k >= self.shot.anchor)
            .map(|k| {
                family
                    .free
                    .iter()
                    .filter(|&&p| obs.positions[k][p].is_some())
                    .count()
                    * 2
            })
            .sum()
    }

    /// Mean distance between two particles over the analysed frames.
    fn mean_distance(&self, a: usize, b: usize) -> f64 {
        let d: Vec<f64> = self
            .obs
            .positions
            .iter()
            .filter_map(|f| Some((f[b]? - f[a]?).norm()))
            .collect();
        if d.is_empty() {
            1.0
        } else {
            d.iter().sum::<f64>() / d.len() as f64
        }
    }

    /// The weak-form columns of every effect of `family` at `params` (tether anchors from the
    /// parameters).
    fn effect_columns(&self, family: &Family, params: &[f64]) -> Vec<Vec<Vec<f64>>> {
        family
            .effects
            .iter()
            .enumerate()
            .map(|(k, &e)| {
                let o = family.effect_offset(k);
                let anchor = matches!(e, Effect::Tether { .. }).then(|| Vec2::new(params[o], params[o + 1]));
                self.weak.effect_columns(family, e, anchor)
            })
            .collect()
    }

    /// Effect parameters from weak-form coefficients.
    fn effect_params(
        &self,
        effect: Effect,
        theta: &[f64],
        anchor: Option<Vec2>,
        fallback: &[f64],
    ) -> Vec<f64> {
        let spring = |theta: &[f64], fallback_length: f64| {
            let (s, sl) = (theta[0], theta[1]);
            if s > 0.0 && (sl / s).is_finite() && sl / s > 0.0 {
                [sl / s, s]
            } else {
                [fallback_length, self.scales.stiffness * 1e-3]
            }
        };
        match effect.weak_shape() {
            Some(WeakShape::Field) => theta.to_vec(),
            Some(WeakShape::Coefficient) => vec![theta[0].max(0.0)],
            Some(WeakShape::Spring { a, b }) => spring(theta, self.mean_distance(a, b)).to_vec(),
            Some(WeakShape::Tether { particle }) => {
                let a = anchor.unwrap_or_else(Vec2::zeros);
                let mean = {
                    let xs: Vec<Vec2> = self.obs.positions.iter().filter_map(|f| f[particle]).collect();
                    xs.iter().sum::<Vec2>() / xs.len().max(1) as f64
                };
                let [l, s] = spring(theta, (a - mean).norm());
                vec![a.x, a.y, l, s]
            }
            None => fallback.to_vec(),
        }
    }

    /// The weak-form joint estimate of `family`'s parameters (bond values and every smooth
    /// effect; walls keep `params`' values), solved on the fitted rows.
    pub fn joint_estimate(&self, family: &Family, params: &[f64]) -> Vec<f64> {
        self.joint_estimate_holding(family, params, family.effects.len())
    }

    /// [`Context::joint_estimate`] with the effects from index `held_from` on held at
    /// `params`' values: their forces are taken off the weak form's right-hand side and the
    /// bond values and the other effects solved beside them. An effect whose force the weak
    /// form hardly sees (a stiff tether's tension shows only through stretches of the order
    /// of the noise) otherwise leaves its work to the bonds, which then start a multi-step fit
    /// far from the valley where that effect explains the tracks.
    pub fn joint_estimate_holding(&self, family: &Family, params: &[f64], held_from: usize) -> Vec<f64> {
        let weak = self.weak;
        let cols = self.effect_columns(family, params);
        let mut all: Vec<&[f64]> = weak.bond_columns().iter().map(|c| c.as_slice()).collect();
        for c in &cols[..held_from.min(cols.len())] {
            all.extend(c.iter().map(|v| v.as_slice()));
        }
        let mut rhs = weak.rhs.clone();
        for (k, &e) in family.effects.iter().enumerate().skip(held_from) {
            let o = family.effect_offset(k);
            let coefficients = weak_coefficients(e, &params[o..o + e.parameter_count()]);
            for (column, c) in cols[k].iter().zip(coefficients) {
                for (r, v) in rhs.iter_mut().zip(column) {
                    *r -= c * v;
                }
            }
        }
        let theta = solve(&all, &rhs, &self.train_rows());
        let nb = weak.bond_column_count();
        let fallback_bonds = family
            .problem
            .as_ref()
            .map_or_else(Vec::new, |p| p.initial_guess());
        let mut out = weak.bond_parameters(family, &theta[..nb], &fallback_bonds);
        let mut t = nb;
        for (k, &e) in family.effects.iter().enumerate() {
            let o = family.effect_offset(k);
            let current = &params[o..o + e.parameter_count()];
            if k >= held_from {
                out.extend_from_slice(current);
                continue;
            }
            let anchor = matches!(e, Effect::Tether { .. }).then(|| Vec2::new(current[0], current[1]));
            let width = cols[k].len();
            out.extend(self.effect_params(e, &theta[t..t + width], anchor, current));
            t += width;
        }
        out
    }

    /// The weak-form columns of the bond values followed by `effects`' (each effect's columns,
    /// from [`Context::effect_columns`]).
    fn base_columns<'c>(&'c self, effects: &'c [Vec<Vec<f64>>]) -> Vec<&'c [f64]> {
        let mut base: Vec<&[f64]> = self.weak.bond_columns().iter().map(|c| c.as_slice()).collect();
        for c in effects {
            base.extend(c.iter().map(|v| v.as_slice()));
        }
        base
    }

    /// The rows screens are scored on: the held-out rows, or the fitted rows without any.
    fn judge_rows(&self) -> Vec<usize> {
        let held = self.held_rows();
        if held.is_empty() {
            self.train_rows()
        } else {
            held
        }
    }

    /// The weak-form system of `cols` solved on the fitted rows: the squared residual on the
    /// `judge` rows and the solution.
    fn screen_cost(&self, cols: &[&[f64]], judge: &[usize]) -> (f64, Vec<f64>) {
        let theta = solve(cols, &self.weak.rhs, &self.train_rows());
        let r = residuals(cols, &theta, &self.weak.rhs);
        (judge.iter().map(|&i| r[i] * r[i]).sum::<f64>(), theta)
    }

    /// A smooth candidate's weak-form columns beside `base`, with a tether's anchor searched
    /// against `base`; `None` for an effect that is not smooth or has no columns.
    fn candidate_columns(
        &self,
        family: &Family,
        base: &[&[f64]],
        effect: Effect,
    ) -> Option<(Option<Vec2>, Vec<Vec<f64>>)> {
        if !effect.is_smooth() {
            return None;
        }
        let anchor = match effect {
            Effect::Tether { particle } => Some(self.search_anchor(family, base, particle)),
            _ => None,
        };
        let extra = self.weak.effect_columns(family, effect, anchor);
        (!extra.is_empty()).then_some((anchor, extra))
    }

    /// Screens every smooth candidate not in `current` (see the module doc), best first.
    pub fn screen(&self, current: &Current, candidates: &[Effect]) -> Vec<Proposal> {
        let family = &current.family;
        let cols = self.effect_columns(family, &current.fit.params);
        let base = self.base_columns(&cols);
        let judge = self.judge_rows();
        let ssr = |cols: &[&[f64]]| self.screen_cost(cols, &judge);
        let (before, _) = ssr(&base);
        let mut out = Vec::new();
        for &effect in candidates {
            if family.effects.contains(&effect) {
                continue;
            }
            let Some((anchor, extra)) = self.candidate_columns(family, &base, effect) else {
                continue;
            };
            let mut all = base.clone();
            all.extend(extra.iter().map(|v| v.as_slice()));
            let (after, theta) = ssr(&all);
            let variance = (after / judge.len().max(1) as f64).max(f64::MIN_POSITIVE);
            let score = (before - after) / variance;
            let init = self.effect_params(effect, &theta[base.len()..], anchor, &[]);
            out.push(Proposal {
                effect,
                init,
                screen: Some(score),
                score_test: None,
                jolts: Vec::new(),
            });
        }
        out.sort_by(|a, b| {
            let key = |p: &Proposal| p.screen.unwrap_or(0.0) / p.effect.parameter_count() as f64;
            key(b).total_cmp(&key(a))
        });
        out
    }

    /// Screens every smooth candidate together with `partner`, an effect that may explain
    /// little alone and everything with another (a field with a tether is a pendulum; a field
    /// with drag), in the weak form as [`Context::screen`] does: the pair's columns are solved
    /// together and a tether's anchor is searched with the partner's columns present. Each
    /// entry holds the partner's proposal then the candidate's, both carrying the pair's
    /// screen score; best first by score per parameter. Empty when `current` has the partner.
    /// Only pairs that work together are kept: the pair must remove more of the held-out
    /// weak-form residual than the better of its two members alone by
    /// [`SCREEN_PER_PARAMETER`] residual variances per parameter the other member adds (a
    /// tether alone is judged at the pair's anchor).
    pub fn screen_pairs(
        &self,
        current: &Current,
        candidates: &[Effect],
        partner: Effect,
    ) -> Vec<Vec<Proposal>> {
        let family = &current.family;
        if family.effects.contains(&partner) || !partner.is_smooth() {
            return Vec::new();
        }
        let weak = self.weak;
        let cols = self.effect_columns(family, &current.fit.params);
        let base = self.base_columns(&cols);
        let judge = self.judge_rows();
        let ssr = |cols: &[&[f64]]| self.screen_cost(cols, &judge);
        let (before, _) = ssr(&base);
        let partner_cols = weak.effect_columns(family, partner, None);
        if partner_cols.is_empty() {
            return Vec::new();
        }
        let mut with_partner = base.clone();
        with_partner.extend(partner_cols.iter().map(|v| v.as_slice()));
        let np = with_partner.len();
        let (partner_after, _) = ssr(&with_partner);
        let mut out = Vec::new();
        for &effect in candidates {
            if effect == partner || family.effects.contains(&effect) {
                continue;
            }
            let Some((anchor, extra)) = self.candidate_columns(family, &with_partner, effect) else {
                continue;
            };
            let mut all = with_partner.clone();
            all.extend(extra.iter().map(|v| v.as_slice()));
            let (after, theta) = ssr(&all);
            let variance = (after / judge.len().max(1) as f64).max(f64::MIN_POSITIVE);
            let score = (before - after) / variance;
            if !score.is_finite() {
                continue;
            }
            let mut alone = base.clone();
            alone.extend(extra.iter().map(|v| v.as_slice()));
            let (single_after, _) = ssr(&alone);
            let added = if partner_after <= single_after {
                effect.parameter_count()
            } else {
                partner.parameter_count()
            };
            let synergy = (partner_after.min(single_after) - after) / variance;
            if synergy.is_nan() || synergy <= SCREEN_PER_PARAMETER * added as f64 {
                continue;
            }
            let proposal = |e: Effect, init: Vec<f64>| Proposal {
                effect: e,
                init,
                screen: Some(score),
                score_test: None,
                jolts: Vec::new(),
            };
            out.push(vec![
                proposal(
                    partner,
                    self.effect_params(partner, &theta[base.len()..np], None, &[]),
                ),
                proposal(effect, self.effect_params(effect, &theta[np..], anchor, &[])),
            ]);
        }
        let key = |v: &Vec<Proposal>| {
            let k: usize = v.iter().map(|p| p.effect.parameter_count()).sum();
            v[0].screen.unwrap_or(0.0) / k.max(1) as f64
        };
        out.sort_by(|a, b| key(b).total_cmp(&key(a)));
        out
    }

    /// A field and a taut tether on `particle` (a pendulum), started from the path's
    /// geometry rather than the weak form: the weak form sees a stiff tether's tension only
    /// through stretches of the order of the track noise (its `S d` column is then mostly
    /// noise), and proposes a far, soft anchor instead. Here the anchor is the centre of the
    /// circle that best fits the particle's tracked positions (algebraic fit), the length its
    /// radius, the field the least-squares fit of the tangential accelerations (second
    /// differences less the current model's, along the circle: a taut tether's tension has
    /// no tangential part), and the stiffness the one that stretches the tether by one track
    /// noise under the field (kept where the integration is stable). Returns the proposals
    /// (field, tether) and the circle's RMS misfit over its radius; `None` when the path is no
    /// arc (too few points, a line, an anchor on the path).
    pub fn circle_pair(&self, current: &Current, particle: usize) -> Option<(Vec<Proposal>, f64)> {
        let obs = self.obs;
        let family = &current.family;
        if family.effects.contains(&Effect::Gravity) || family.effects.contains(&Effect::Tether { particle })
        {
            return None;
        }
        let (centre, radius, misfit) = self.circle_of(particle)?;
        // The field from the tangential accelerations, the current model's removed.
        let model = family.model(&current.fit.params, None);
        let dt = obs.frame_dt();
        let mut a = nalgebra::Matrix2::<f64>::zeros();
        let mut b = nalgebra::Vector2::<f64>::zeros();
        for k in 1..obs.frame_count().saturating_sub(1) {
            let (Some(p0), Some(p1), Some(p2)) = (
                obs.positions[k - 1].get(particle).copied().flatten(),
                obs.positions[k].get(particle).copied().flatten(),
                obs.positions[k + 1].get(particle).copied().flatten(),
            ) else {
                continue;
            };
            let mut known = Vec2::zeros();
            if let Some(st) = obs.state(k) {
                let mut st = st;
                let _ = family.model(&current.fit.params, Some(&mut st));
                let mut acc = vec![Vec2::zeros(); model.particle_count()];
                model.accelerations(&st, &mut acc);
                known = acc.get(particle).copied().unwrap_or_else(Vec2::zeros);
            }
            let acc = (p2 - 2.0 * p1 + p0) / (dt * dt) - known;
            let u = (p1 - centre) / (p1 - centre).norm().max(f64::MIN_POSITIVE);
            let t = Vec2::new(-u.y, u.x);
            let tv = nalgebra::Vector2::new(t.x, t.y);
            a += tv * tv.transpose();
            b += tv * acc.dot(&t);
        }
        let g = a.try_inverse()? * b;
        let field = Vec2::new(g[0], g[1]);
        if !(field.x.is_finite() && field.y.is_finite()) {
            return None;
        }
        let mass = family.structure.particles.get(particle).map_or(1.0, |p| p.mass);
        let stable = stable_stiffness(&family.structure, mass);
        let sigma = super::search::noise_floor(obs.noise, self.scales.length);
        let stiffness = (mass * field.norm() / (2.0 * sigma))
            .min(stable)
            .max(self.scales.stiffness * 1e-3);
        let proposal = |effect: Effect, init: Vec<f64>| Proposal {
            effect,
            init,
            screen: None,
            score_test: None,
            jolts: Vec::new(),
        };
        Some((
            vec![
                proposal(Effect::Gravity, vec![field.x, field.y]),
                proposal(
                    Effect::Tether { particle },
                    vec![centre.x, centre.y, radius, stiffness],
                ),
            ],
            misfit,
        ))
    }

    /// The circle that best fits `particle`'s tracked positions (algebraic fit): its centre,
    /// radius (px) and RMS misfit over the radius; `None` when the path is no swinging arc
    /// (see [`Context::arc_of`]; and no swing: the angle about the centre must turn back at an
    /// interior frame, by more than five track noises on both sides, as a pendulum's does
    /// every half period and a tumbling body's curved path need not).
    pub fn circle_of(&self, particle: usize) -> Option<(Vec2, f64, f64)> {
        let arc = self.arc_of(particle)?;
        let obs = self.obs;
        let angles: Vec<f64> = (0..obs.frame_count())
            .filter_map(|k| obs.positions[k].get(particle).copied()?)
            .map(|x| (x.x - arc.centre.x).atan2(arc.centre.y - x.y))
            .collect();
        let turn = 5.0 * noise_floor(obs.noise, self.scales.length) / arc.radius;
        let last = angles.len() - 1;
        let swings = |extreme: usize| {
            extreme > 0
                && extreme < last
                && (angles[extreme] - angles[0]).abs() > turn
                && (angles[extreme] - angles[last]).abs() > turn
        };
        let (imax, imin) = angles.iter().enumerate().fold((0, 0), |(a, b), (k, v)| {
            (
                if *v > angles[a] { k } else { a },
                if *v < angles[b] { k } else { b },
            )
        });
        if !(swings(imax) || swings(imin)) {
            return None;
        }
        Some((arc.centre, arc.radius, arc.misfit / arc.radius))
    }

    /// The circle that best fits `particle`'s tracked positions (Kasa's algebraic fit) and
    /// the straight line that does (principal axis); `None` for fewer than six points, a
    /// centre within the path's spread or a circle misfit above a tenth of that spread.
    pub fn arc_of(&self, particle: usize) -> Option<Arc> {
        let obs = self.obs;
        let xs: Vec<Vec2> = (0..obs.frame_count())
            .filter_map(|k| obs.positions[k].get(particle).copied()?)
            .collect();
        if xs.len() < 6 {
            return None;
        }
        let mean = xs.iter().sum::<Vec2>() / xs.len() as f64;
        // Kasa fit: x² + y² = 2 a x + 2 b y + c, centred on the mean for conditioning.
        let mut m = nalgebra::Matrix3::<f64>::zeros();
        let mut r = nalgebra::Vector3::<f64>::zeros();
        let mut scatter = nalgebra::Matrix2::<f64>::zeros();
        for x in &xs {
            let d = x - mean;
            let row = nalgebra::Vector3::new(2.0 * d.x, 2.0 * d.y, 1.0);
            m += row * row.transpose();
            r += row * d.norm_squared();
            scatter += d * d.transpose();
        }
        let sol = m.try_inverse()? * r;
        let centre = mean + Vec2::new(sol[0], sol[1]);
        let radius2 = sol[2] + sol[0] * sol[0] + sol[1] * sol[1];
        if !(radius2 > 0.0 && radius2.is_finite()) {
            return None;
        }
        let radius = radius2.sqrt();
        let n = xs.len() as f64;
        let misfit = (xs
            .iter()
            .map(|x| ((x - centre).norm() - radius).powi(2))
            .sum::<f64>()
            / n)
            .sqrt();
        let line_misfit = (scatter.symmetric_eigen().eigenvalues.min().max(0.0) / n).sqrt();
        let extent = xs.iter().map(|x| (x - mean).norm()).fold(0.0, f64::max);
        // An arc: the particle stays off its centre, and the circle fits far better than the
        // particle's own spread.
        (radius > extent && misfit < 0.1 * extent).then_some(Arc {
            centre,
            radius,
            misfit,
            line_misfit,
        })
    }

    /// A tether alone on `particle`, started from the circle its path follows (see
    /// [`Context::arc_of`]): the anchor at the centre; the length and stiffness from the weak
    /// form at that anchor where it gives a stiffer tether than the next estimate, else the
    /// length the radius and the stiffness the one that stretches the tether by one track
    /// noise under the mean centripetal pull (kept where the integration is stable). A tether turning a free particle round bends
    /// its path by far more than the noise while its tension, balancing the centripetal
    /// acceleration, shows in the weak form only through stretches of the order of the noise
    /// (the weak form then proposes a near, soft anchor). Returns the proposal and the
    /// circle's RMS misfit over its radius; `None` when the path is no arc or no more curved
    /// than the noise (the line's RMS misfit below five track noises) or the circle does not
    /// explain the bend (its misfit above a third of the line's).
    pub fn circle_tether(&self, current: &Current, particle: usize) -> Option<(Proposal, f64)> {
        let family = &current.family;
        if family.effects.contains(&Effect::Tether { particle }) {
            return None;
        }
        let arc = self.arc_of(particle)?;
        let sigma = noise_floor(self.obs.noise, self.scales.length);
        if !(arc.line_misfit > 5.0 * sigma && arc.misfit < arc.line_misfit / 3.0) {
            return None;
        }
        let speeds: Vec<f64> = (0..self.obs.frame_count())
            .filter_map(|k| self.obs.velocities.get(k)?.get(particle).copied()?)
            .map(|v| v.norm_squared())
            .collect();
        let mean_square_speed = speeds.iter().sum::<f64>() / speeds.len().max(1) as f64;
        let mass = family.structure.particles.get(particle).map_or(1.0, |p| p.mass);
        let stable = stable_stiffness(&family.structure, mass);
        let centripetal = (mass * mean_square_speed / arc.radius / (2.0 * sigma))
            .min(stable)
            .max(self.scales.stiffness * 1e-3);
        // The weak form at the circle's centre: the tension's two columns solved linearly
        // beside the current model's.
        let effect = Effect::Tether { particle };
        let cols = self.effect_columns(family, &current.fit.params);
        let mut all = self.base_columns(&cols);
        let base_len = all.len();
        let extra = self.weak.effect_columns(family, effect, Some(arc.centre));
        all.extend(extra.iter().map(|v| v.as_slice()));
        let theta = solve(&all, &self.weak.rhs, &self.train_rows());
        let weak = self.effect_params(effect, &theta[base_len..], Some(arc.centre), &[]);
        if std::env::var_os("PHYSFIT_DEBUG").is_some() {
            eprintln!("   circle tether weak form {weak:?}, centripetal {centripetal}");
        }
        let (length, stiffness) = if weak[3] > centripetal && weak[3] <= stable && weak[2] > 0.0 {
            (weak[2], weak[3])
        } else {
            (arc.radius, centripetal)
        };
        Some((
            Proposal {
                effect,
                init: vec![arc.centre.x, arc.centre.y, length, stiffness],
                screen: None,
                score_test: None,
                jolts: Vec::new(),
            },
            arc.misfit / arc.radius,
        ))
    }

    /// A tether the tracks cannot tell from an inextensible one, taken as rigid: with a field
    /// in the model, effect `k` of `with` (a tether) is refitted with its stiffness held at
    /// the value that stretches it by a tenth of the track noise under the field (no more
    /// than the integration keeps stable), from the fit's anchor with the length at its
    /// stretched value and from the circle of the particle's path. The rigid fit is returned
    /// when the cost it adds (held-out frames; fitted ones without them), in units of the
    /// fit's residual variance, is below one parameter's penalty `ln N`: the elastic
    /// tether's stiffness then does not pay for itself.
    pub fn rigid_tether(&self, with: &Current, k: usize) -> Option<Current> {
        let family = &with.family;
        let Effect::Tether { particle } = *family.effects.get(k)? else {
            return None;
        };
        if family.is_pinned(k, 3) {
            return None;
        }
        let g = family.effects.iter().position(|e| *e == Effect::Gravity)?;
        let go = family.effect_offset(g);
        let field = Vec2::new(with.fit.params[go], with.fit.params[go + 1]).norm();
        let o = family.effect_offset(k);
        let p: Vec<f64> = with.fit.params[o..o + 4].to_vec();
        let mass = family.structure.particles.get(particle).map_or(1.0, |q| q.mass);
        let stable = stable_stiffness(&family.structure, mass);
        let sigma = noise_floor(self.obs.noise, self.scales.length);
        let rigid = (mass * field / (2.0 * 0.1 * sigma)).min(stable);
        if !(rigid > p[3] && p[3] > 0.0 && field > 0.0) {
            return None;
        }
        let mut pinned = family.clone();
        pinned.pins.push((k, 3, rigid));
        let stretch = |s: f64| mass * field / (2.0 * s);
        let mut start = with.fit.params.clone();
        start[o + 2] = (p[2] + stretch(p[3]) - stretch(rigid)).max(1e-3);
        start[o + 3] = rigid;
        let mut best = self.fit(&pinned, &start, &with.fit.state, true);
        if let Some((centre, radius, _)) = self.circle_of(particle) {
            let mut circle = start.clone();
            circle[o] = centre.x;
            circle[o + 1] = centre.y;
            circle[o + 2] = (radius - stretch(rigid)).max(1e-3);
            keep_better(&mut best, self.fit(&pinned, &circle, &with.fit.state, false));
        }
        let best = best?;
        let held = self.held_count(family);
        let (n, added) = if held > 0 {
            (held, best.held_cost - with.held_cost)
        } else {
            (
                with.fit.residual_count,
                best.fit.sum_squares - with.fit.sum_squares,
            )
        };
        let variance = self.noise_variance(with);
        (added.is_finite() && added / variance < (n.max(2) as f64).ln()).then_some(best)
    }

    /// `chosen` with each tether it adds to `current` refitted along its line (see
    /// [`Context::along_tether`]; also at the noise level, where the mirror image and a far
    /// anchor fit nearly alike), its evidence
    /// against `current` updated (the transfer judgement kept).
    pub fn refine_tethers(&self, current: &Current, chosen: &mut Verified) {
        let Some(mut best) = chosen.current.clone() else {
            return;
        };
        let mut improved = false;
        for k in current.family.effects.len()..best.family.effects.len() {
            // Along its line, then stiffer, then along its line again from a stiffer fit: a
            // stiff tether's pull turns with the anchor's distance.
            for round in 0..2 {
                // Again from each better fit (a few times): the valley is long.
                for _ in 0..ALONG_TETHER_PASSES {
                    let Some(better) = self.along_tether(&best, k, &ALONG_TETHER_FACTORS) else {
                        break;
                    };
                    best = better;
                    improved = true;
                }
                if round > 0 || self.at_noise_level(&best) {
                    break;
                }
                let Some(better) = self.stiffer_tether(&best, k) else {
                    break;
                };
                best = better;
                improved = true;
            }
        }
        if improved {
            let transfer = chosen.evidence.transfer.take();
            let mut evidence = self.evidence(current, Some(&best), &chosen.proposals);
            evidence.transfer = transfer;
            chosen.evidence = evidence;
            chosen.current = Some(best);
        }
    }

    /// The ring of each free particle in its residual under `current` (module
    /// `oscillation`): the strongest oscillation of either component faster than the weak
    /// form's test window resolves (a period under the window), along one line (the minor
    /// axis of its ellipse under a third of the major). A stiff bond the model lacks rings
    /// along itself, and its mean pull is balanced by the motion's, so neither the weak form
    /// nor the path's arc shows it. Empty at the noise level.
    pub fn rings(&self, current: &Current) -> Vec<Ring> {
        let family = &current.family;
        if self.at_noise_level(current) {
            return Vec::new();
        }
        let Some(trajectory) = self
            .shot
            .trajectory(family, &current.fit.params, &current.fit.state)
        else {
            return Vec::new();
        };
        let fps = self.obs.fps;
        let (low, high) = self.ring_band();
        let mut out = Vec::new();
        for &particle in &family.free {
            let mut times = Vec::new();
            let mut residual = [Vec::new(), Vec::new()];
            let mut sum = Vec2::zeros();
            for (k, predicted) in trajectory.iter().enumerate() {
                let (Some(x), Some(o)) = (
                    predicted.as_ref().map(|x| x[particle]),
                    self.obs.positions[k][particle],
                ) else {
                    continue;
                };
                times.push(k as f64 / fps);
                residual[0].push(o.x - x.x);
                residual[1].push(o.y - x.y);
                sum += o;
            }
            let mean = sum / times.len().max(1) as f64;
            let ring = residual
                .iter()
                .filter_map(|r| {
                    oscillation::strongest_frequencies(&times, r, low, high, 1)
                        .first()
                        .copied()
                })
                .filter_map(|omega| {
                    let [(ax, bx), (ay, by)] =
                        [&residual[0], &residual[1]].map(|r| oscillation::amplitudes(&times, r, omega));
                    // The ellipse's axes: the singular values of [[ax, bx], [ay, by]].
                    let svd = nalgebra::Matrix2::new(ax, bx, ay, by).svd(true, false);
                    let u = svd.u?;
                    let (major, minor) = (svd.singular_values[0], svd.singular_values[1]);
                    (minor < major / 3.0).then(|| Ring {
                        particle,
                        omega,
                        direction: Vec2::new(u[(0, 0)], u[(1, 0)]),
                        amplitude: major,
                        mean,
                    })
                })
                .max_by(|a, b| a.amplitude.total_cmp(&b.amplitude));
            out.extend(ring);
        }
        out
    }

    /// Tethers on a ringing particle (see [`Context::rings`]), the strongest ring of a
    /// particle without one: its anchor lies on the ring's line, on either side (a proposal
    /// for each, [`RING_ANCHOR_SCALES`] length scales from the particle's mean position),
    /// its stiffness is `m ω² / 2`. Returned with the ring's amplitude (px).
    pub fn ringing_tether(&self, current: &Current, rings: &[Ring]) -> Option<(Vec<Proposal>, f64)> {
        let family = &current.family;
        let ring = rings
            .iter()
            .filter(|r| !family.effects.contains(&Effect::Tether { particle: r.particle }))
            .max_by(|a, b| a.amplitude.total_cmp(&b.amplitude))?;
        let mass = family
            .structure
            .particles
            .get(ring.particle)
            .map_or(1.0, |p| p.mass);
        let stiffness = (mass * ring.omega * ring.omega / 2.0).min(stable_stiffness(&family.structure, mass));
        let proposals = RING_ANCHOR_SCALES
            .iter()
            .flat_map(|&scale| [scale, -scale])
            .map(|scale| {
                let distance = scale * self.scales.length;
                let anchor = ring.mean + ring.direction * distance;
                Proposal {
                    effect: Effect::Tether {
                        particle: ring.particle,
                    },
                    init: vec![anchor.x, anchor.y, distance.abs(), stiffness],
                    screen: None,
                    score_test: None,
                    jolts: Vec::new(),
                }
            })
            .collect();
        Some((proposals, ring.amplitude))
    }

    /// A missing spring between two ringing particles (see [`Context::rings`]) not joined
    /// by the structure or the model: both ring at one frequency (within the periodogram's
    /// resolution), and the distance between them rings with at least half the larger
    /// particle amplitude, as the two ends of a stiff spring do. Its stiffness is
    /// `μ ω² / 2` (`μ` the reduced mass), its length the mean distance. Returned with the
    /// distance's ring amplitude (px); the strongest such pair.
    pub fn ringing_spring(&self, current: &Current, rings: &[Ring]) -> Option<(Proposal, f64)> {
        let family = &current.family;
        let structure = &family.structure;
        let fps = self.obs.fps;
        let span = self.obs.frame_count() as f64 / fps;
        let resolution = std::f64::consts::TAU / span.max(f64::MIN_POSITIVE);
        let joined = |a: usize, b: usize| {
            structure.springs.iter().any(|sp| {
                let [i, j] = [sp.ends[0].index(), sp.ends[1].index()];
                (i == a && j == b) || (i == b && j == a)
            }) || family.effects.iter().any(|e| {
                matches!(*e, Effect::MissingSpring { a: i, b: j } if (i == a && j == b) || (i == b && j == a))
            })
        };
        let mut best: Option<(Proposal, f64)> = None;
        for (i, ra) in rings.iter().enumerate() {
            for rb in &rings[i + 1..] {
                let (a, b) = (ra.particle.min(rb.particle), ra.particle.max(rb.particle));
                if (ra.omega - rb.omega).abs() > resolution || joined(a, b) {
                    continue;
                }
                let omega = 0.5 * (ra.omega + rb.omega);
                let (times, distances) = self.series(|x| Some((x[b]? - x[a]?).norm()));
                let (c, s) = oscillation::amplitudes(&times, &distances, omega);
                let amplitude = c.hypot(s);
                if amplitude < 0.5 * ra.amplitude.max(rb.amplitude) {
                    continue;
                }
                let inverse = |p: usize| structure.particles.get(p).map_or(1.0, |q| 1.0 / q.mass);
                let mu = 1.0 / (inverse(a) + inverse(b));
                let stiffness = (mu * omega * omega / 2.0).min(stable_stiffness(&family.structure, mu));
                let length = distances.iter().sum::<f64>() / distances.len().max(1) as f64;
                if best.as_ref().map_or(true, |(_, x)| amplitude > *x) {
                    let proposal = Proposal {
                        effect: Effect::MissingSpring { a, b },
                        init: vec![length, stiffness],
                        screen: None,
                        score_test: None,
                        jolts: Vec::new(),
                    };
                    best = Some((proposal, amplitude));
                }
            }
        }
        best
    }

    /// The band of angular frequencies (rad/s) in which a ring is listened for: from the
    /// fastest the weak form's test window resolves (it tells slower ones) to just under the
    /// Nyquist rate `π fps`.
    fn ring_band(&self) -> (f64, f64) {
        let fps = self.obs.fps;
        let resolved = std::f64::consts::TAU * fps / self.weak.window.max(1) as f64;
        (resolved, 0.95 * std::f64::consts::PI * fps)
    }

    /// Times (s) and values of `value` at each frame where it has one.
    fn series(&self, value: impl Fn(&[Option<Vec2>]) -> Option<f64>) -> (Vec<f64>, Vec<f64>) {
        let fps = self.obs.fps;
        self.obs
            .positions
            .iter()
            .enumerate()
            .filter_map(|(k, x)| Some((k as f64 / fps, value(x)?)))
            .unzip()
    }

    /// Mean observed position of `particle`, px; `None` when it is never tracked.
    fn mean_position(&self, particle: usize) -> Option<Vec2> {
        let xs: Vec<Vec2> = self.obs.positions.iter().filter_map(|f| f[particle]).collect();
        (!xs.is_empty()).then(|| xs.iter().sum::<Vec2>() / xs.len() as f64)
    }

    /// The stiffness `μ ω² / 2` of `structure`'s spring `k` from the strongest oscillation
    /// of its length over the recording faster than the weak form's test window resolves
    /// (module `oscillation`; `μ` the ends' reduced mass,
    /// the free end's mass when the other is fixed), up to what the integration keeps
    /// stable; `None` when no oscillation is heard.
    fn heard_spring_stiffness(&self, structure: &Scene, k: usize) -> Option<f64> {
        let spring = structure.springs.get(k)?;
        let [a, b] = spring.ends.map(|e| e.0 as usize);
        let (pa, pb) = (structure.particles.get(a)?, structure.particles.get(b)?);
        let inverse = |p: &physfit_model::scene::ParticleSpec| if p.fixed { 0.0 } else { 1.0 / p.mass };
        let mu = 1.0 / (inverse(pa) + inverse(pb));
        let (times, lengths) = self.series(|x| {
            let xa = x[a].or(pa.fixed.then_some(pa.position))?;
            let xb = x[b].or(pb.fixed.then_some(pb.position))?;
            Some((xb - xa).norm())
        });
        let span = times.last()? - times.first()?;
        let (resolved, high) = self.ring_band();
        let low = (4.0 * std::f64::consts::TAU / span.max(f64::MIN_POSITIVE)).max(resolved);
        let w = *oscillation::strongest_frequencies(&times, &lengths, low, high, 1).first()?;
        (mu.is_finite() && mu > 0.0).then(|| (mu * w * w / 2.0).min(stable_stiffness(structure, mu)))
    }

    /// Effect `k` of `with`, a tether, refitted from stiffer starts: the stiffness
    /// `m ω² / 2` of each of the three strongest oscillations of its particle's distance
    /// from the anchor (module `oscillation`) faster than the fitted tether's and than the
    /// weak form's test window resolves, up to what the
    /// integration keeps stable, the rest length changed to keep the pull at the particle's
    /// mean position. A stiff tether's radial oscillation is a narrow basin in the
    /// stiffness: started a few times too soft or too stiff, the fit stops in another
    /// (seed 95 of `physfit bench diagnose`: from 3 and 10 times the soft fit's 410 it
    /// stops at 1243 and 4169; from the oscillation's 3294 at the truth, 3291). Returns the
    /// best such fit when it beats `with` on the fitted frames.
    fn stiffer_tether(&self, with: &Current, k: usize) -> Option<Current> {
        let family = &with.family;
        let Effect::Tether { particle } = *family.effects.get(k)? else {
            return None;
        };
        if family.is_pinned(k, 3) {
            return None;
        }
        let o = family.effect_offset(k);
        let p = &with.fit.params;
        let (anchor, length, stiffness) = (Vec2::new(p[o], p[o + 1]), p[o + 2], p[o + 3]);
        let mean = self.mean_position(particle)?;
        if stiffness.is_nan() || stiffness <= 0.0 {
            return None;
        }
        let distance = (anchor - mean).norm();
        let mass = family.structure.particles.get(particle).map_or(1.0, |q| q.mass);
        let stable = stable_stiffness(&family.structure, mass);
        let (times, distances) = self.series(|x| Some((x[particle]? - anchor).norm()));
        let now = (2.0 * stiffness / mass).sqrt();
        let (resolved, high) = self.ring_band();
        let heard =
            oscillation::strongest_frequencies(&times, &distances, (1.2 * now).max(resolved), high, 3);
        let mut best: Option<Current> = None;
        for w in heard {
            let stiffer = mass * w * w / 2.0;
            let factor = stiffer / stiffness;
            if stiffer > stable || factor <= 1.0 {
                continue;
            }
            let mut start = p.clone();
            // The same pull at the mean position: `S' (D - L') = S (D - L)`.
            start[o + 2] = (distance - (distance - length) / factor).max(1e-3);
            start[o + 3] = stiffer;
            // First with the stiffness held, the anchor and length free: from a soft fit's
            // anchor, a free stiffness slides back towards its basin before they move.
            let mut held = family.clone();
            held.pins.push((k, 3, stiffer));
            let state = match self.fit(&held, &start, &with.fit.state, true) {
                Some(h) => {
                    start = h.fit.params;
                    h.fit.state
                }
                None => with.fit.state.clone(),
            };
            let Some(fit) = self.fit(family, &start, &state, true) else {
                continue;
            };
            if std::env::var_os("PHYSFIT_DEBUG").is_some() {
                eprintln!(
                    "   stiffer tether {k}: stiffness {stiffness:.1} x {factor}: cost {:.4} (from {:.4}), stiffness {:.1}",
                    fit.fit.sum_squares, with.fit.sum_squares, fit.fit.params[o + 3]
                );
            }
            let bar = best.as_ref().map_or(with.fit.sum_squares, |b| b.fit.sum_squares);
            if fit.fit.sum_squares < bar {
                best = Some(fit);
            }
        }
        best
    }

    /// Effect `k` of `with`, a tether, refitted from anchors moved along the line from its
    /// particle's mean position through the fitted anchor, either side of the particle (the
    /// rest length changed to keep the pull at the mean position):
    /// a stiff tether fixes the direction of its pull well but the anchor's distance poorly,
    /// since moving the anchor out and lengthening the tether changes only how the pull turns
    /// as the particle moves, so a fit can stop in that valley far from the anchor. Returns
    /// the best such fit when it beats `with` on the fitted frames.
    fn along_tether(&self, with: &Current, k: usize, factors: &[f64]) -> Option<Current> {
        let family = &with.family;
        let Effect::Tether { particle } = *family.effects.get(k)? else {
            return None;
        };
        let o = family.effect_offset(k);
        let mean = self.mean_position(particle)?;
        let p = &with.fit.params;
        let anchor = Vec2::new(p[o], p[o + 1]);
        let distance = (anchor - mean).norm();
        if !(distance > 0.0 && distance.is_finite()) {
            return None;
        }
        let direction = (anchor - mean) / distance;
        // An anchor run off far beyond the data (many times its length scale) is also tried
        // at the data's own scale: the valley is long, and factors of its distance step
        // through it slowly.
        let scale = self.scales.length;
        let mut all: Vec<f64> = factors.to_vec();
        if distance > ALONG_TETHER_FAR * scale {
            all.extend(ALONG_TETHER_SCALES.iter().map(|s| s * scale / distance));
        }
        let mut best: Option<Current> = None;
        for &factor in &all {
            let mut start = p.clone();
            let moved = mean + direction * (distance * factor);
            start[o] = moved.x;
            start[o + 1] = moved.y;
            // The same pull at the mean position: `L' = |f| D + sign(f) (L - D)`.
            start[o + 2] = (distance * factor.abs() + factor.signum() * (p[o + 2] - distance)).max(1e-3);
            let Some(fit) = self.fit(family, &start, &with.fit.state, true) else {
                continue;
            };
            if std::env::var_os("PHYSFIT_DEBUG").is_some() {
                eprintln!(
                    "   along tether {k}: distance {distance:.1} x {factor}: cost {:.4} (from {:.4})",
                    fit.fit.sum_squares, with.fit.sum_squares
                );
            }
            let bar = best.as_ref().map_or(with.fit.sum_squares, |b| b.fit.sum_squares);
            if fit.fit.sum_squares < bar {
                best = Some(fit);
            }
        }
        best
    }

    /// The anchor of a tether on `particle` that best explains the fitted rows, with the
    /// tether's stiffness and rest length solved linearly at each trial anchor.
    fn search_anchor(&self, family: &Family, base: &[&[f64]], particle: usize) -> Vec2 {
        let weak = self.weak;
        let train = self.train_rows();
        let xs: Vec<Vec2> = self.obs.positions.iter().filter_map(|f| f[particle]).collect();
        let mean = xs.iter().sum::<Vec2>() / xs.len().max(1) as f64;
        let extent = xs
            .iter()
            .map(|x| (x - mean).norm())
            .fold(0.0, f64::max)
            .max(self.scales.length * 0.25)
            .max(5.0);
        let cost = |a: Vec2| {
            let mut all = base.to_vec();
            let extra = weak.effect_columns(family, Effect::Tether { particle }, Some(a));
            all.extend(extra.iter().map(|v| v.as_slice()));
            let theta = solve(&all, &weak.rhs, &train);
            let r = residuals(&all, &theta, &weak.rhs);
            train.iter().map(|&i| r[i] * r[i]).sum::<f64>()
        };
        let mut best = (f64::INFINITY, mean);
        for radius in [0.5, 1.0, 2.0, 4.0, 8.0] {
            for k in 0..16 {
                let angle = std::f64::consts::TAU * k as f64 / 16.0;
                let a = mean + Vec2::new(angle.cos(), angle.sin()) * (radius * extent);
                let c = cost(a);
                if c < best.0 {
                    best = (c, a);
                }
            }
        }
        let mut step = extent * 0.25;
        let mut moves = 0;
        while step > 0.05 && moves < 60 {
            moves += 1;
            let mut moved = false;
            for d in [
                Vec2::new(step, 0.0),
                Vec2::new(-step, 0.0),
                Vec2::new(0.0, step),
                Vec2::new(0.0, -step),
            ] {
                let a = best.1 + d;
                let c = cost(a);
                if c < best.0 {
                    best = (c, a);
                    moved = true;
                }
            }
            if !moved {
                step *= 0.5;
            }
        }
        best.1
    }

    /// The structure alone fitted on the fitted frames, from the weak-form joint estimate.
    /// Bond stiffnesses the weak form cannot tell (it gives them no positive value, and they
    /// start at their parameter's scale) are also started at [`BASE_STIFFNESS_FACTORS`] times
    /// that scale unless the first fit is at the noise level: a multi-step fit of a coupled
    /// oscillation has narrow basins in its stiffnesses. It also starts from `given`'s bond
    /// values (a fit over every frame, such as `physfit run`'s), when given. The best fit on
    /// the fitted frames is kept.
    pub fn base_fit(&self, family: &Family, given: Option<&Scene>) -> Option<Current> {
        let params = self.joint_estimate(family, &[]);
        let mut best = self.fit(family, &params, self.start, false);
        let Some(problem) = &family.problem else {
            return best;
        };
        if let Some(given) = given.and_then(|scene| problem.params_of(scene)) {
            if given.len() == params.len() && !best.as_ref().is_some_and(|b| self.at_noise_level(b)) {
                keep_better(&mut best, self.fit(family, &given, self.start, false));
            }
        }
        let guess = problem.initial_guess();
        let untold: Vec<usize> = problem
            .layout
            .parameters
            .iter()
            .enumerate()
            .filter(|(i, p)| {
                matches!(
                    p.kind,
                    crate::ParameterKind::SpringStiffness | crate::ParameterKind::TorsionStiffness
                ) && params.get(*i) == guess.get(*i)
            })
            .map(|(i, _)| i)
            .collect();
        // Stiff springs oscillate faster than the weak form's test functions see, which
        // then tells a soft value or none: they are also started from the oscillation of
        // their length, where that is faster.
        let mut heard = params.clone();
        for (i, parameter) in problem.layout.parameters.iter().enumerate() {
            if let (crate::BondRef::Spring(k), crate::ParameterKind::SpringStiffness) =
                (parameter.bond, parameter.kind)
            {
                if let Some(stiffness) = self.heard_spring_stiffness(&family.structure, k) {
                    if stiffness > HEARD_STIFFER * params[i] {
                        heard[i] = stiffness;
                    }
                }
            }
        }
        if heard != params && !best.as_ref().is_some_and(|b| self.at_noise_level(b)) {
            keep_better(&mut best, self.fit(family, &heard, self.start, false));
        }
        if untold.is_empty() {
            return best;
        }
        for factor in BASE_STIFFNESS_FACTORS {
            if best.as_ref().is_some_and(|b| self.at_noise_level(b)) {
                break;
            }
            let mut start = params.clone();
            for &i in &untold {
                start[i] *= factor;
            }
            keep_better(&mut best, self.fit(family, &start, self.start, false));
        }
        best
    }

    /// Fits `family` from `params` and `state` on the fitted frames (`warm`: see
    /// [`fit_shot`]).
    pub fn fit(&self, family: &Family, params: &[f64], state: &State, warm: bool) -> Option<Current> {
        let t0 = std::time::Instant::now();
        let fit = fit_shot(
            self.shot,
            family,
            params,
            state,
            self.scales,
            SHOT_ITERATIONS,
            warm,
            &(),
        )?;
        if std::env::var_os("PHYSFIT_DEBUG").is_some() {
            eprintln!(
                "  fit {:?}: {:.2}s, {} its, cost {:.3}",
                family.effects,
                t0.elapsed().as_secs_f64(),
                fit.iterations,
                fit.sum_squares
            );
        }
        let (held_cost, _) = self.shot.cost_on(family, &fit.params, &fit.state, self.held);
        Some(Current {
            family: family.clone(),
            fit,
            held_cost,
        })
    }

    /// Returns true if and only if the fit's residual variance is within twice the squared
    /// track noise (nothing left for another start to find).
    pub fn at_noise_level(&self, current: &Current) -> bool {
        let p = current.family.dim() + 4 * current.family.free.len();
        let n = current.fit.residual_count;
        n > p && current.fit.sum_squares / ((n - p) as f64) <= 2.0 * self.obs.noise * self.obs.noise
    }

    /// Residual variance of a fit (never below the squared track noise), px².
    pub fn noise_variance(&self, current: &Current) -> f64 {
        let p = current.family.dim() + 4 * current.family.free.len();
        let n = current.fit.residual_count;
        let fitted = if n > p {
            current.fit.sum_squares / (n - p) as f64
        } else {
            f64::INFINITY
        };
        fitted.max(self.obs.noise * self.obs.noise)
    }

    /// Returns true if and only if the fit's residual variance is within
    /// [`EXPLAINED_VARIANCE_RATIO`] times the squared track noise (see [`noise_floor`]).
    pub fn explained(&self, current: &Current) -> bool {
        let p = current.family.dim() + 4 * current.family.free.len();
        let n = current.fit.residual_count;
        let floor = noise_floor(self.obs.noise, self.scales.length);
        n > p && current.fit.sum_squares / ((n - p) as f64) <= EXPLAINED_VARIANCE_RATIO * floor * floor
    }

    /// `current` without its effect `k` and those that act through it (see
    /// [`Family::removed_with`]): the family without them and the fit's values without their
    /// parameters (not refitted; the held-out cost is kept).
    pub fn without(&self, current: &Current, k: usize) -> Current {
        let family = &current.family;
        let mut params = current.fit.params.clone();
        // Decreasing order: each drain leaves the earlier offsets in place.
        for j in family.removed_with(k) {
            let o = family.effect_offset(j);
            params.drain(o..o + family.effects[j].parameter_count());
        }
        let mut fit = current.fit.clone();
        fit.params = params;
        Current {
            family: family.without_effect(k),
            fit,
            held_cost: current.held_cost,
        }
    }

    /// A swap: `proposals` verified in `current` without its effect `removed`, and scored
    /// against `current` itself (the parameters the swap adds less those it removes).
    pub fn verify_swap(&self, current: &Current, removed: usize, proposals: &[Proposal]) -> Verified {
        let reduced = self.without(current, removed);
        let mut v = self.verify(&reduced, proposals);
        let k_removed = current.family.effects[removed].parameter_count();
        let mut evidence = self.evidence(current, v.current.as_ref(), proposals);
        let held = self.held_count(&current.family);
        let n = if held > 0 {
            held
        } else {
            current.fit.residual_count
        };
        // A swap pays for one parameter more than it adds net: the choice of which effect
        // to take out is itself fitted (and an effect swapped for itself, refitted, must
        // gain that much to be worth a round).
        evidence.penalty += (1.0 - k_removed as f64) * (n.max(2) as f64).ln();
        evidence.fitted_penalty += (1.0 - k_removed as f64) * (current.fit.residual_count.max(2) as f64).ln();
        evidence.score = evidence.noise_variance.and_then(|var| evidence.score_on(var));
        v.evidence = evidence;
        v.removes = Some(removed);
        v
    }

    /// Swaps: an accepted smooth effect of `current` may be a poor stand-in for a better
    /// explanation (a far tether imitating a pendulum's field and tether): each is taken out,
    /// the best single candidate and pair screened in its place, and verified against
    /// `current` (see [`Context::verify_swap`]).
    pub fn verify_swaps(&self, current: &Current, candidates: &[Effect]) -> Vec<Verified> {
        let mut out = Vec::new();
        for k in 0..current.family.effects.len() {
            let removed = current.family.effects[k];
            if !removed.is_smooth() {
                continue;
            }
            let reduced = self.without(current, k);
            let mut options: Vec<Vec<Proposal>> = Vec::new();
            if let Some(p) = self
                .screen(&reduced, candidates)
                .into_iter()
                .find(|p| p.screen.is_some_and(|s| s > 0.0))
            {
                options.push(vec![p]);
            }
            if let Some(pair) = self
                .screen_pairs(&reduced, candidates, Effect::Gravity)
                .into_iter()
                .find(|p| p[0].screen.is_some_and(|s| s > 0.0))
            {
                options.push(pair);
            }
            for o in options {
                let v = self.verify_swap(current, k, &o);
                if std::env::var_os("PHYSFIT_DEBUG").is_some() {
                    let effects: Vec<Effect> = o.iter().map(|p| p.effect).collect();
                    eprintln!("   swap {removed:?} -> {effects:?}: {:?}", v.evidence);
                }
                out.push(v);
            }
        }
        out
    }

    /// Sorts `verified` best first. Candidates are ranked against each other on one
    /// yardstick: the held-out cost each removes over the smallest residual variance among
    /// them, minus its penalty (each candidate's own score divides by its own residual
    /// variance, which favours the one with more parameters, a distant tether imitating a
    /// uniform field, by far more than its penalty when the cost removed is large). An
    /// explanation that fits at the noise level with a positive score ranks above every one
    /// that does not, whatever their scores (a far tether imitating a field can remove much
    /// cost and still leave a residual many times the noise).
    pub fn rank(&self, verified: &mut [Verified]) {
        let common = verified
            .iter()
            .filter_map(|v| v.evidence.noise_variance)
            .fold(f64::INFINITY, f64::min);
        let rank = |v: &Verified| {
            v.evidence
                .score
                .and(v.evidence.score_on(common))
                .unwrap_or(f64::NEG_INFINITY)
        };
        let fits = |v: &Verified| {
            v.evidence.score.is_some_and(|s| s > 0.0) && v.current.as_ref().is_some_and(|c| self.explained(c))
        };
        verified.sort_by(|a, b| fits(b).cmp(&fits(a)).then(rank(b).total_cmp(&rank(a))));
    }

    /// Multi-step verification of proposals (one effect, or a wall with a smooth effect
    /// that needs it) against `current`: fitted from the current fit plus the proposals'
    /// starting values and from the weak-form joint estimate, keeping the better fit.
    pub fn verify(&self, current: &Current, proposals: &[Proposal]) -> Verified {
        self.verify_with(current, proposals, true)
    }

    /// [`Context::verify`], with a tether's stiffer starts (see
    /// [`Context::stiffer_tether`]) only when `stiffen`: they cost six multi-step fits, and
    /// are passed over once another candidate fits to the noise level.
    pub fn verify_with(&self, current: &Current, proposals: &[Proposal], stiffen: bool) -> Verified {
        let effects: Vec<Effect> = current
            .family
            .effects
            .iter()
            .copied()
            .chain(proposals.iter().map(|p| p.effect))
            .collect();
        let family = current.family.with_effects(effects);
        let mut warm = current.fit.params.clone();
        for p in proposals {
            warm.extend_from_slice(&p.init);
        }
        // Both starts unless the first already fits to the noise: the current fit may be a
        // poor optimum when a strong term is missing.
        let mut best = self.fit(&family, &warm, &current.fit.state, true);
        // Proposals started from the path's geometry (no screen score) are also held while
        // the bonds are estimated beside them (see `joint_estimate_holding`).
        let geometric = proposals
            .iter()
            .all(|p| p.screen.is_none() && p.effect.is_smooth());
        let held_from = if geometric {
            vec![family.effects.len(), current.family.effects.len()]
        } else {
            vec![family.effects.len()]
        };
        for from in held_from {
            if best.as_ref().is_some_and(|b| self.at_noise_level(b)) {
                break;
            }
            let joint = self.joint_estimate_holding(&family, &warm, from);
            keep_better(&mut best, self.fit(&family, &joint, self.start, false));
        }
        // A stiff tether oscillates faster than the weak form's test functions see: its
        // stiffness is also started from the oscillation it makes.
        for k in (current.family.effects.len()..family.effects.len()).filter(|_| stiffen) {
            let Some(b) = best.as_ref() else { break };
            if self.at_noise_level(b) {
                break;
            }
            if matches!(family.effects[k], Effect::Tether { .. }) {
                let stiffer = self.stiffer_tether(b, k);
                keep_better(&mut best, stiffer);
            }
        }
        let evidence = self.evidence(current, best.as_ref(), proposals);
        Verified {
            proposals: proposals.to_vec(),
            current: best,
            evidence,
            removes: None,
        }
    }

    /// The evidence of `with` (current plus the proposals) against `current`.
    pub fn evidence(&self, current: &Current, with: Option<&Current>, proposals: &[Proposal]) -> Evidence {
        let k: usize = proposals.iter().map(|p| p.effect.parameter_count()).sum();
        let n_held = self.held_count(&current.family);
        let (before, after, n) = if n_held > 0 {
            (current.held_cost, with.map(|w| w.held_cost), n_held)
        } else {
            (
                current.fit.sum_squares,
                with.map(|w| w.fit.sum_squares),
                current.fit.residual_count,
            )
        };
        let variance = with.map(|w| self.noise_variance(w));
        // Smooth terms act on every frame, so must pay on the fitted ones too; a wall acts
        // only where it is met, which may be in held-out frames alone.
        let smooth = n_held > 0 && proposals.iter().all(|p| p.effect.is_smooth());
        let first = proposals.first();
        let mut evidence = Evidence {
            screen_score: first.and_then(|p| p.screen),
            score_test: first.and_then(|p| p.score_test),
            held_out_cost_before: Some(before),
            held_out_cost_after: after,
            noise_variance: variance,
            penalty: k as f64 * (n.max(2) as f64).ln(),
            fitted_cost_before: smooth.then_some(current.fit.sum_squares),
            fitted_cost_after: with.filter(|_| smooth).map(|w| w.fit.sum_squares),
            fitted_penalty: self.train_penalty(current, k),
            score: None,
            parameter_count: k,
            transfer: None,
        };
        evidence.score = variance.and_then(|v| evidence.score_on(v));
        evidence
    }
}

/// Replaces `best` by `b` when `b` fits the fitted frames better (or `best` is `None`).
/// The stiffest spring on a mass `mass` that `structure`'s integration keeps stable,
/// `m / (4 dt²)` with `dt` its substep (s).
fn stable_stiffness(structure: &Scene, mass: f64) -> f64 {
    let substep = structure.integration_parameters().dt();
    0.25 * mass / (substep * substep)
}

fn keep_better(best: &mut Option<Current>, b: Option<Current>) {
    if let Some(b) = b {
        if best
            .as_ref()
            .map_or(true, |a| b.fit.sum_squares < a.fit.sum_squares)
        {
            *best = Some(b);
        }
    }
}

/// The coefficients of an effect's weak-form columns at its parameters (the inverse of
/// [`Context::effect_params`]): a field's components; drag and dashpot values; a spring's or
/// tether's `S` and `S L`; none for a wall.
fn weak_coefficients(effect: Effect, params: &[f64]) -> Vec<f64> {
    match effect.weak_shape() {
        Some(WeakShape::Field | WeakShape::Coefficient) => params.to_vec(),
        Some(WeakShape::Spring { .. }) => vec![params[1], params[1] * params[0]],
        Some(WeakShape::Tether { .. }) => vec![params[3], params[3] * params[2]],
        None => Vec::new(),
    }
}

/// Frames a particle must stay within the noise of one place to count as at rest.
const REST_FRAMES: usize = 3;

/// Returns true if and only if some free particle of `obs` comes to rest after moving, as
/// dry friction stops it: [`REST_FRAMES`] consecutive steps each within three noises of
/// zero (`3 sqrt(2) sigma`, the noise of a step), after a step of more than ten.
pub fn seen_to_stop(obs: &Observations) -> bool {
    let step_noise = 2f64.sqrt() * noise_floor(obs.noise, 1.0);
    (0..obs.fixed.len()).filter(|&p| !obs.fixed[p]).any(|p| {
        let mut moved = false;
        let mut still = 0;
        for w in obs.positions.windows(2) {
            let Some(step) = w[0][p].zip(w[1][p]).map(|(a, b)| (b - a).norm()) else {
                still = 0;
                continue;
            };
            if step > 10.0 * step_noise {
                moved = true;
                still = 0;
            } else if step <= 3.0 * step_noise {
                still += 1;
                if moved && still >= REST_FRAMES {
                    return true;
                }
            } else {
                still = 0;
            }
        }
        false
    })
}

/// The track noise used as a yardstick, px: the measured noise, or where the tracks are exact
/// (a simulation's, noise 0) a millionth of the data's length scale (a fit converges no
/// closer than that).
pub fn noise_floor(noise: f64, length: f64) -> f64 {
    let floor = 1e-6 * length.max(1.0);
    if noise.is_finite() {
        noise.max(floor)
    } else {
        floor
    }
}

/// Every smooth candidate for `family`'s structure. The dry friction of a surface under the
/// motion is one only where the structure gives no field (given a field in the image plane,
/// the recording is seen from the side, and dry friction acts at walls and rails: their
/// own candidates) and some particle is seen to come to rest ([`seen_to_stop`]): its
/// constant deceleration otherwise stands in for whatever slows a swing or a flight (on
/// the real pendulum, 6.4 +- 2.0 px/s^2 beside the field and the tether).
pub fn smooth_candidates(family: &Family, obs: &Observations) -> Vec<Effect> {
    let s = &family.structure;
    let mut out = vec![Effect::Gravity, Effect::Drag, Effect::QuadraticDrag];
    if s.physics.gravity.norm() == 0.0 && seen_to_stop(obs) {
        out.push(Effect::SurfaceFriction);
    }
    if !s.springs.is_empty() {
        out.push(Effect::SpringDamping);
    }
    if s.springs.len() >= 2 {
        out.extend((0..s.springs.len()).map(|spring| Effect::SpringDashpot { spring }));
    }
    let n = s.particles.len();
    let joined = |a: usize, b: usize| {
        s.springs.iter().any(|sp| {
            let [i, j] = [sp.ends[0].index(), sp.ends[1].index()];
            (i == a && j == b) || (i == b && j == a)
        })
    };
    let mut pairs = Vec::new();
    for a in 0..n {
        for b in a + 1..n {
            if (s.particles[a].fixed && s.particles[b].fixed) || joined(a, b) {
                continue;
            }
            let d: Vec<f64> = obs
                .positions
                .iter()
                .filter_map(|f| Some((f[b]? - f[a]?).norm()))
                .collect();
            if d.is_empty() {
                continue;
            }
            pairs.push((d.iter().sum::<f64>() / d.len() as f64, a, b));
        }
    }
    pairs.sort_by(|x, y| x.0.total_cmp(&y.0));
    out.extend(
        pairs
            .into_iter()
            .take(MAX_PAIRS)
            .map(|(_, a, b)| Effect::MissingSpring { a, b }),
    );
    out.extend(
        family
            .free
            .iter()
            .take(MAX_TETHERS)
            .map(|&particle| Effect::Tether { particle }),
    );
    out
}

/// Wall proposals not yet accepted.
pub fn wall_proposals(guesses: &[WallGuess]) -> Vec<Proposal> {
    guesses
        .iter()
        .map(|g| Proposal {
            effect: Effect::Wall,
            init: g.params.to_vec(),
            screen: None,
            score_test: None,
            jolts: g.jolts.clone(),
        })
        .collect()
}

/// A circle fitted to one particle's tracked path, beside the straight line fitted to it.
#[derive(Clone, Copy, Debug)]
pub struct Arc {
    /// The circle's centre (px).
    pub centre: Vec2,
    /// The circle's radius (px).
    pub radius: f64,
    /// RMS distance of the tracked positions from the circle (px).
    pub misfit: f64,
    /// RMS distance of the tracked positions from their principal axis (px).
    pub line_misfit: f64,
}
