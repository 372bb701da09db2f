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

use physfit_model::{State, Vec2};

use super::effect::Effect;
use super::family::{DataScales, Family};
use super::jolts::WallGuess;
use super::report::Evidence;
use super::shooting::{fit_shot, Shot, ShotFit};
use super::weak::{residuals, solve, WeakForm};
use crate::Observations;

/// Most smooth candidates verified by multi-step fits per round.
pub const VERIFIED_PER_ROUND: usize = 3;

/// Least screen score, per parameter, for a smooth candidate to be verified.
pub const SCREEN_PER_PARAMETER: f64 = 2.0;

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
    pub jolts: Vec<usize>,
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
        match effect {
            Effect::Gravity => theta.to_vec(),
            Effect::Drag | Effect::QuadraticDrag | Effect::SpringDamping | Effect::SpringDashpot { .. } => {
                vec![theta[0].max(0.0)]
            }
            Effect::MissingSpring { a, b } => spring(theta, self.mean_distance(a, b)).to_vec(),
            Effect::Tether { particle } => {
                let a = anchor.unwrap_or_else(Vec2::zeros);
                let mean = {
                    let xs: Vec<Vec2> = self.obs.positions.iter().filter_map(|f| f[particle]).collect();
                    xs.iter().sum::<Vec2>() / xs.len().max(1) as f64
                };
                let [l, s] = spring(theta, (a - mean).norm());
                vec![a.x, a.y, l, s]
            }
            Effect::Wall => fallback.to_vec(),
        }
    }

    /// The weak-form joint estimate of `family`'s parameters (bond values and every smooth
    /// effect; walls keep `params`' values), solved on the fitted rows.
    pub fn joint_estimate(&self, family: &Family, params: &[f64]) -> Vec<f64> {
        let weak = self.weak;
        let cols = self.effect_columns(family, params);
        let mut all: Vec<&[f64]> = weak.bond_columns().iter().map(|c| c.as_slice()).collect();
        for c in &cols {
            all.extend(c.iter().map(|v| v.as_slice()));
        }
        let theta = solve(&all, &weak.rhs, &self.train_rows());
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
            let anchor = matches!(e, Effect::Tether { .. }).then(|| Vec2::new(current[0], current[1]));
            let width = cols[k].len();
            out.extend(self.effect_params(e, &theta[t..t + width], anchor, current));
            t += width;
        }
        out
    }

    /// Screens every smooth candidate not in `current` (see the module doc), best first.
    pub fn screen(&self, current: &Current, candidates: &[Effect]) -> Vec<Proposal> {
        let weak = self.weak;
        let train = self.train_rows();
        let held = self.held_rows();
        let family = &current.family;
        let cols = self.effect_columns(family, &current.fit.params);
        let mut base: Vec<&[f64]> = weak.bond_columns().iter().map(|c| c.as_slice()).collect();
        for c in &cols {
            base.extend(c.iter().map(|v| v.as_slice()));
        }
        // Score on held-out rows; without any, on the fitted rows.
        let judge: &[usize] = if held.is_empty() { &train } else { &held };
        let ssr = |cols: &[&[f64]]| {
            let theta = solve(cols, &weak.rhs, &train);
            let r = residuals(cols, &theta, &weak.rhs);
            (judge.iter().map(|&i| r[i] * r[i]).sum::<f64>(), theta)
        };
        let (before, _) = ssr(&base);
        let mut out = Vec::new();
        for &effect in candidates {
            if family.effects.contains(&effect) || !effect.is_smooth() {
                continue;
            }
            let anchor = match effect {
                Effect::Tether { particle } => Some(self.search_anchor(family, &base, particle)),
                _ => None,
            };
            let extra = weak.effect_columns(family, effect, anchor);
            if extra.is_empty() {
                continue;
            }
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

    /// Multi-step verification of proposals (one effect, or a wall with a smooth effect
    /// that needs it) against `current`: fitted from the current fit plus the proposals'
    /// starting values and from the weak-form joint estimate, keeping the better fit.
    pub fn verify(&self, current: &Current, proposals: &[Proposal]) -> Verified {
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
        if !best.as_ref().is_some_and(|b| self.at_noise_level(b)) {
            let joint = self.joint_estimate(&family, &warm);
            if let Some(b) = self.fit(&family, &joint, self.start, false) {
                if best
                    .as_ref()
                    .map_or(true, |a| b.fit.sum_squares < a.fit.sum_squares)
                {
                    best = Some(b);
                }
            }
        }
        let evidence = self.evidence(current, best.as_ref(), proposals);
        Verified {
            proposals: proposals.to_vec(),
            current: best,
            evidence,
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
        let first = proposals.first();
        let mut evidence = Evidence {
            screen_score: first.and_then(|p| p.screen),
            score_test: first.and_then(|p| p.score_test),
            held_out_cost_before: Some(before),
            held_out_cost_after: after,
            noise_variance: variance,
            penalty: k as f64 * (n.max(2) as f64).ln(),
            score: None,
            parameter_count: k,
        };
        evidence.score = variance.and_then(|v| evidence.score_on(v));
        evidence
    }
}

/// Every smooth candidate for `family`'s structure.
pub fn smooth_candidates(family: &Family, obs: &Observations) -> Vec<Effect> {
    let s = &family.structure;
    let mut out = vec![Effect::Gravity, Effect::Drag, Effect::QuadraticDrag];
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
