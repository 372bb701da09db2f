//! Diagnosis: where the fitted model and the recording disagree, which physics the model left
//! out, and the model with it added (issue 5).
//!
//! A key design decision made in this module is to *screen* cheaply and *judge* expensively:
//!
//! 1. The frames are split into interleaved blocks; a fraction is **held out** of every fit.
//! 2. **Jolts** (bounces) are found in the tracks, as impulses the structure's smooth forces
//!    do not explain (module `jolts`); they propose walls, and their frames are left out of
//!    the smooth analysis.
//! 3. The **base fit** (structure alone: weak-form estimate, then multi-step least squares
//!    with the start state free) gives the residuals that are **localised** per particle, per
//!    bond and per frame against the noise measured from the tracks (module `localise`).
//! 4. **Greedy search** (module `search`): every candidate [`Effect`] is screened in the
//!    weak-form linear system (held-out rows) and by a score test on the multi-step fit
//!    (module `score_test`); the best few, and every proposed wall (alone and with the weak
//!    form's favourite force), are fitted by multi-step least squares with everything else,
//!    and scored by the held-out multi-step cost they remove over the noise variance, minus a
//!    `k ln N` penalty. The best positive score is accepted; repeat until none is positive.
//! 5. The accepted model is **refitted** on all analysed frames (warm start), with standard
//!    errors from its Jacobian, and written as a scene ([`Diagnosis::final_scene`]).
//!
//! `docs/diagnosis.md` describes the thresholds and the `report.json` contract.

mod bumper;
mod constraints;
mod contact;
mod costs;
mod effect;
mod family;
mod flights;
mod inclusion;
mod jolts;
mod landings;
mod localise;
mod oscillation;
mod outcome;
mod report;
mod score_test;
mod search;
mod shooting;
mod stability;
mod support;
#[cfg(test)]
mod tests;
mod transfer;
mod undecided;
mod verdict;
mod weak;

pub use costs::scene_costs;
pub use effect::Effect;
pub use jolts::Jolt;
pub use report::{
    BondResidual, Diagnosis, Evidence, Finding, FittedValue, Holdout, Localisation, ModelCosts, ModelSummary,
    ParticleResidual, Predictions, RejectedCandidate, Replaced, ResidualSeries, SearchSummary, SeedAgreement,
    Seen, SegmentTransfer, Stability, Transfer, Undecided, Verdict, VerdictParticle,
};
pub use stability::check_seeds;
pub use support::Support;
pub use verdict::EXPLAINED_RMS_RATIO;

use std::time::Instant;

use physfit_model::Scene;
use physfit_tracks::TrackTable;
use rand::{Rng, SeedableRng};
use serde::Serialize;

use crate::{IdentifyError, Observations, Observer};
use family::{DataScales, Family};
use search::{smooth_candidates, wall_proposals, Context, Current, Proposal};
use shooting::{Shot, ShotFit};
use weak::WeakForm;

/// Settings of [`diagnose`].
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct DiagnoseOptions {
    /// Seed (which blocks are held out, noise replicas for localisation).
    pub seed: u64,
    /// Analysed frames `(A, B)`, inclusive; all tracked frames when `None`.
    pub window: Option<(usize, usize)>,
    /// Fraction of frames held out of the fits for scoring, in `(0, 0.5]`.
    pub holdout_fraction: f64,
    /// Most effects added.
    pub max_effects: usize,
    /// Weak-form test window, frames (`None`: about one typical period).
    pub test_window: Option<usize>,
    /// A fit of the structure alone (its bond values; e.g. [`crate::fit`]'s, over every
    /// frame), from which the diagnosis's own base fit, a multi-step fit on the frames not
    /// held out, also starts (`None`: from the weak form's estimate alone).
    #[serde(skip)]
    pub base: Option<Scene>,
}

impl Default for DiagnoseOptions {
    fn default() -> Self {
        DiagnoseOptions {
            seed: 1,
            window: None,
            holdout_fraction: 0.25,
            max_effects: 6,
            test_window: None,
            base: None,
        }
    }
}

/// Diagnoses `structure` against `tracks` (see the module doc).
pub fn diagnose(
    structure: &Scene,
    tracks: &TrackTable,
    options: &DiagnoseOptions,
    observer: &dyn Observer,
) -> Result<Diagnosis, IdentifyError> {
    let sequence = Observations::from_tracks(tracks, structure, None)?;
    diagnose_observations(structure, &sequence, options, observer)
}

/// Most rounds repeated because a better fit of the current model was found on the way.
const MAX_RESTARTS: usize = 3;

/// Walls from clear jolts verified per round.
const MAX_WALLS_PER_ROUND: usize = 3;

/// Walls from faint jolts (see [`jolts::Scan::faint`]) verified per round, after the clear
/// ones.
const MAX_FAINT_WALLS_PER_ROUND: usize = 2;

/// Walls from end jolts (see [`jolts::Scan::ends`]) verified per round, after the faint ones.
const MAX_END_WALLS_PER_ROUND: usize = 1;

/// The smallest number of analysed frames the diagnosis accepts.
pub const MIN_DIAGNOSIS_FRAMES: usize = 10;

/// As [`diagnose`], from observations of the whole tracked sequence.
pub fn diagnose_observations(
    structure: &Scene,
    sequence: &Observations,
    options: &DiagnoseOptions,
    observer: &dyn Observer,
) -> Result<Diagnosis, IdentifyError> {
    diagnose_inner(structure, sequence, options, observer, &[])
}

/// The diagnosis; `held_before` are the supports that held particles before the window (the
/// window then starts at their release and is not trimmed again).
fn diagnose_inner(
    structure: &Scene,
    sequence: &Observations,
    options: &DiagnoseOptions,
    observer: &dyn Observer,
    held_before: &[Support],
) -> Result<Diagnosis, IdentifyError> {
    let t0 = Instant::now();
    if !(options.holdout_fraction > 0.0 && options.holdout_fraction <= 0.5) {
        return Err(IdentifyError::InvalidOption(format!(
            "holdout fraction {} is not in (0, 0.5]",
            options.holdout_fraction
        )));
    }
    let obs = match options.window {
        Some((a, b)) => sequence.restrict(a, b)?,
        None => sequence.clone(),
    };
    obs.require_frames("the diagnosis", MIN_DIAGNOSIS_FRAMES)?;
    let mut warnings = obs.warnings.clone();
    let family0 = Family::new(structure, &obs)?;
    let scales = DataScales::of(structure, &obs);
    let frames = obs.frame_count();

    // 1. Held-out blocks.
    let w = options.test_window.unwrap_or_else(|| test_window(&scales, &obs));
    let w = (w.max(4) + 1) & !1;
    let (mut held, mut holdout) = holdout_blocks(&obs, w, options, &[]);
    let train_mask: Vec<bool> = held.iter().map(|h| !h).collect();
    let mut shot = Shot::new(&obs, &family0, Some(train_mask))?;
    let start = shot.observed_state();

    // 2. Jolts, and the frames the smooth analysis leaves out: first without a model, then
    // with the structure's weak-form estimate removing its smooth forces.
    let exclusion = |jolts: &[jolts::Jolt]| {
        let mut excluded = vec![false; frames];
        for j in jolts {
            let k = j.frame - obs.first_frame;
            for e in &mut excluded[k.saturating_sub(1)..=(k + 2).min(frames - 1)] {
                *e = true;
            }
        }
        excluded
    };
    // The rough model (the structure and a uniform field, weak-form estimate) removes smooth
    // forces from the jolt test (an apex under gravity is no bounce) and gives the field the
    // support test needs; twice, the second time without the first pass's bounces and supports.
    // Faint and end jolts (in the gaps the means cannot reach) are also kept from this pass
    // without a model: a rough model whose field absorbs a bounce smears it.
    let free = jolts::scan_jolts(&obs, None);
    let rough = &free.jolts;
    let mut excluded = exclusion(rough);
    let mut jolt_list = Vec::new();
    let mut supports = Vec::new();
    let mut rough_field = physfit_model::Vec2::zeros();
    let mut faint = Vec::new();
    let mut ends = Vec::new();
    for _ in 0..2 {
        let weak = WeakForm::new(&family0, &obs, w, &excluded, &held);
        let (model_acc, field) = rough_model(&family0, &obs, &weak, &shot, &held, &start, &scales, &excluded);
        rough_field = field;
        let found = jolts::scan_jolts(&obs, Some(&model_acc));
        let jolt_scale = found.scale;
        jolt_list = found.jolts;
        faint = jolts::merge_jolts(found.faint, &free.faint);
        ends = jolts::merge_jolts(found.ends, &free.ends);
        excluded = exclusion(&jolt_list);
        supports = support::find_supports(&obs, &model_acc, field, &excluded);
        for s in &supports {
            for e in &mut excluded[s.frames[0] - obs.first_frame..=s.frames[1] - obs.first_frame] {
                *e = true;
            }
        }
        if std::env::var_os("PHYSFIT_DEBUG").is_some() {
            eprintln!(
                " rough jolts {}, jolts {} (scale {jolt_scale:.2} px/s), field {field:?}, supports {supports:?}",
                rough.len(),
                jolt_list.len()
            );
            for j in &jolt_list {
                eprintln!("   {j:?}");
            }
            for j in &faint {
                eprintln!("   faint {j:?}");
            }
        }
    }
    // A support from the first analysed frame: a simulation started there would fall through
    // it, so the analysis starts where the last such support releases its particle.
    let release = supports
        .iter()
        .filter(|s| s.frames[0] == obs.first_frame)
        .map(|s| s.frames[1])
        .max();
    if let (Some(release), true) = (release, held_before.is_empty()) {
        if obs.last_frame() + 1 >= release + MIN_DIAGNOSIS_FRAMES {
            let trimmed = DiagnoseOptions {
                window: Some((release, obs.last_frame())),
                ..options.clone()
            };
            let leading: Vec<Support> = supports
                .iter()
                .filter(|s| s.frames[0] == obs.first_frame)
                .cloned()
                .collect();
            let mut d = diagnose_inner(structure, sequence, &trimmed, observer, &leading)?;
            d.warnings.push(format!(
                "frames {}-{} left out: {} supported from the first frame (see the localisation); the analysis starts at frame {release}",
                obs.first_frame,
                release.saturating_sub(1),
                leading
                    .iter()
                    .map(|s| s.particle.as_str())
                    .collect::<Vec<_>>()
                    .join(", ")
            ));
            d.seconds = t0.elapsed().as_secs_f64();
            return Ok(d);
        }
    }
    for s in held_before.iter().rev() {
        supports.insert(0, s.clone());
    }
    // Held-out blocks that took every frame after a bounce would leave its wall to be fitted
    // from no frames: choose the blocks again, knowing the jolts.
    let jolt_offsets: Vec<usize> = jolt_list.iter().map(|j| j.frame - obs.first_frame).collect();
    if starves_a_jolt(&held, &jolt_offsets) {
        (held, holdout) = holdout_blocks(&obs, w, options, &jolt_offsets);
        shot.mask = held.iter().map(|h| !h).collect();
        if std::env::var_os("PHYSFIT_DEBUG").is_some() {
            eprintln!(
                " held-out blocks chosen again for jolts {jolt_offsets:?}: {:?}",
                holdout.held_out
            );
        }
    }
    let guesses = jolts::propose_walls(&jolt_list, &obs);
    let faint_guesses = jolts::propose_walls(&faint, &obs);
    let end_guesses = jolts::propose_walls(&ends, &obs);
    // Landings (a particle stopped on a line, not turned round) depend on the positions alone.
    let landing_guesses = landings::landing_walls(&obs, MAX_FAINT_WALLS_PER_ROUND);
    // Transfer segments: a few typical periods each (twice the test window), within half the
    // analysed frames.
    let segments = transfer::Segments::new(&shot, &excluded, (2 * w).min(frames / 2), scales.length);
    if std::env::var_os("PHYSFIT_DEBUG").is_some() {
        eprintln!(" test window {w}, transfer segments {segments:?}");
    }
    let weak = WeakForm::new(&family0, &obs, w, &excluded, &held);
    let ctx = Context {
        obs: &obs,
        weak: &weak,
        shot: &shot,
        held: &held,
        start: &start,
        scales: &scales,
    };

    // 3. Base fit on the fitted frames.
    let base = ctx
        .base_fit(&family0, options.base.as_ref())
        .ok_or_else(|| IdentifyError::NoFiniteCost {
            method: "diagnosis base fit".into(),
            detail: "the structure's model from the weak-form estimate cannot be simulated".into(),
        })?;
    observer.observe(0, base.fit.sum_squares);

    // 4. Greedy search.
    let candidates = smooth_candidates(&family0, &obs);
    let mut current = base.clone();
    let mut accepted: Vec<(Proposal, report::Evidence, usize)> = Vec::new();
    let mut rejected: Vec<report::RejectedCandidate> = Vec::new();
    let mut replaced: Vec<report::Replaced> = Vec::new();
    let mut guesses = guesses;
    let mut faint_guesses = faint_guesses;
    let mut end_guesses = end_guesses;
    let mut round = 0;
    let mut restarts = 0;
    let stop: String;
    // Swaps keep the count of effects: the rounds are bounded as well.
    let max_rounds = 2 * options.max_effects + MAX_RESTARTS + 1;
    loop {
        if accepted.len() >= options.max_effects {
            stop = format!("the most effects allowed ({}) were added", options.max_effects);
            break;
        }
        if round >= max_rounds {
            stop = format!("the most rounds allowed ({max_rounds}) were run");
            break;
        }
        round += 1;
        let debug = std::env::var_os("PHYSFIT_DEBUG").is_some();
        let tq = Instant::now();
        let mut screened = ctx.screen(&current, &candidates);
        if debug {
            eprintln!(" screen {:.2}s", tq.elapsed().as_secs_f64());
        }
        let tq = Instant::now();
        score_test::score_tests(&ctx, &current, &mut screened);
        if debug {
            eprintln!(" score tests {:.2}s", tq.elapsed().as_secs_f64());
        }
        let rank = |p: &Proposal| {
            p.score_test.unwrap_or(0.0) - ctx.train_penalty(&current, p.effect.parameter_count())
        };
        screened.sort_by(|a, b| rank(b).total_cmp(&rank(a)));
        if debug {
            for p in screened.iter().take(8) {
                eprintln!(
                    "   {:?} test {:?} screen {:?} init {:?}",
                    p.effect, p.score_test, p.screen, p.init
                );
            }
        }
        let mut to_verify: Vec<Vec<Proposal>> = Vec::new();
        for p in &screened {
            // Lenient gate: the score test is a local approximation of what the fit can gain.
            let gate = 0.5 * ctx.train_penalty(&current, p.effect.parameter_count());
            if p.score_test.is_some_and(|s| s > gate) && to_verify.len() < search::VERIFIED_PER_ROUND {
                to_verify.push(vec![p.clone()]);
            }
        }
        // The weak form's favourites too: the score test is only as good as the current fit,
        // which is poor when a strong term is missing. Walls are also tried with them: a wall
        // and a smooth force can each be useless to a multi-step fit without the other (a ball
        // under gravity falls through a floor), while the weak form leaves the bounces out.
        let mut by_screen: Vec<&Proposal> = screened
            .iter()
            .filter(|p| {
                p.screen
                    .is_some_and(|s| s > search::SCREEN_PER_PARAMETER * p.effect.parameter_count() as f64)
            })
            .collect();
        by_screen.sort_by(|a, b| {
            let key = |p: &Proposal| p.screen.unwrap_or(0.0) / p.effect.parameter_count() as f64;
            key(b).total_cmp(&key(a))
        });
        for p in by_screen.iter().take(search::VERIFIED_PER_ROUND - 1) {
            if !to_verify.iter().any(|v| v[0].effect == p.effect) {
                to_verify.push(vec![(*p).clone()]);
            }
        }
        // Jolts as the current model sees them (a missing smooth force makes false ones), less
        // those an accepted wall explains.
        if round > 1 {
            let model = current.family.model(&current.fit.params, None);
            let acc: Vec<Option<Vec<physfit_model::Vec2>>> = (0..frames)
                .map(|k| {
                    let s = obs.state(k)?;
                    let mut a = vec![physfit_model::Vec2::zeros(); model.particle_count()];
                    let mut st = s.clone();
                    let _ = current.family.model(&current.fit.params, Some(&mut st));
                    model.accelerations(&st, &mut a);
                    a.truncate(s.len());
                    Some(a)
                })
                .collect();
            let found = jolts::scan_jolts(&obs, Some(&acc));
            jolt_list = found.jolts;
            guesses = jolts::propose_walls(&jolt_list, &obs);
            faint_guesses = jolts::propose_walls(&jolts::merge_jolts(found.faint, &free.faint), &obs);
            end_guesses = jolts::propose_walls(&jolts::merge_jolts(found.ends, &free.ends), &obs);
        }
        let accepted_walls: Vec<[f64; 3]> = accepted
            .iter()
            .enumerate()
            .filter(|(_, (p, _, _))| p.effect.adds_wall())
            .filter_map(|(k, _)| {
                let o = current.family.effect_offset(k);
                current.fit.params.get(o..o + 3).map(|v| [v[0], v[1], v[2]])
            })
            .collect();
        let mut walls_left: Vec<Proposal> = wall_proposals(&guesses)
            .into_iter()
            .filter(|g| !accepted_walls.iter().any(|w| same_wall(w, &g.init, &scales)))
            .take(MAX_WALLS_PER_ROUND)
            .collect();
        // Faint bounces' walls (a poor smooth model's misfit hides them) and landings' after
        // the clear ones.
        let mut known: Vec<[f64; 3]> = accepted_walls
            .iter()
            .copied()
            .chain(walls_left.iter().filter_map(|w| w.init.get(..3)?.try_into().ok()))
            .collect();
        // Then one from a bounce at an end of the recording.
        for (guesses, cap) in [
            (
                [&faint_guesses[..], &landing_guesses[..]].concat(),
                MAX_FAINT_WALLS_PER_ROUND,
            ),
            (end_guesses.clone(), MAX_END_WALLS_PER_ROUND),
        ] {
            let mut taken = 0;
            for g in wall_proposals(&guesses) {
                if taken < cap && !known.iter().any(|w| same_wall(w, &g.init, &scales)) {
                    if debug {
                        eprintln!("   faint wall {:?}", g.init);
                    }
                    known.extend(g.init.get(..3).and_then(|w| <[f64; 3]>::try_from(w).ok()));
                    walls_left.push(g);
                    taken += 1;
                }
            }
        }
        // The field's proposal for walls: a floor and a field are each useless to a
        // multi-step fit without the other; the rough model's field starts it (the free
        // flights' where bounces spoil or empty the weak form).
        let field_proposal = (!current.family.effects.contains(&Effect::Gravity)).then(|| {
            let screened_field = screened.iter().find(|p| p.effect == Effect::Gravity);
            Proposal {
                effect: Effect::Gravity,
                init: vec![rough_field.x, rough_field.y],
                screen: screened_field.and_then(|p| p.screen),
                score_test: screened_field.and_then(|p| p.score_test),
                jolts: Vec::new(),
            }
        });
        for wall in &walls_left {
            to_verify.push(vec![wall.clone()]);
            for p in by_screen.iter().take(1) {
                to_verify.push(vec![wall.clone(), (*p).clone()]);
            }
            if let Some(f) = &field_proposal {
                if !by_screen.iter().take(1).any(|p| p.effect == Effect::Gravity) {
                    to_verify.push(vec![wall.clone(), f.clone()]);
                }
            }
        }
        // Friction at every wall met so far, and with the proposed ones (see `contact`).
        to_verify.extend(
            contact::friction_proposals(&obs, &current, &jolt_list)
                .into_iter()
                .map(|p| vec![p]),
        );
        to_verify.extend(contact::friction_with_walls(
            &obs,
            &current,
            &walls_left,
            field_proposal.as_ref(),
        ));
        // Rails under straight tracks (verified here, with their friction), and friction on
        // the accepted rails (see `constraints`).
        let rails = constraints::verify_rails(&ctx, &current);
        to_verify.extend(
            constraints::rail_friction_proposals(&obs, &current)
                .into_iter()
                .map(|p| vec![p]),
        );
        // Pairs that work only together (a field with a tether is a pendulum; a field with
        // drag): the weak form's best pairs are verified when they pass the screen's gate
        // (the weak form often cannot tell which partner a field needs: drag or dashpots).
        let pairs = ctx.screen_pairs(&current, &candidates, Effect::Gravity);
        for pair in pairs.iter().take(search::VERIFIED_PAIRS_PER_ROUND) {
            let k: usize = pair.iter().map(|p| p.effect.parameter_count()).sum();
            let per = pair[0].screen.unwrap_or(0.0) / k as f64;
            if per > search::SCREEN_PER_PARAMETER {
                to_verify.push(pair.clone());
            }
        }
        // A pendulum from the geometry of the most circular path (see `circle_pair`), for
        // particles a tether alone screens better than the field alone (a pendulum's field
        // alone explains nothing in the weak form, its tension balancing it; where the
        // field screens best, the motion is the field's and the pairs above cover it).
        let screen_of = |e: Effect| {
            screened
                .iter()
                .find(|p| p.effect == e)
                .and_then(|p| p.screen)
                .unwrap_or(f64::NEG_INFINITY)
        };
        let field_screen = screen_of(Effect::Gravity);
        let circles = current
            .family
            .free
            .iter()
            .filter(|&&p| screen_of(Effect::Tether { particle: p }) > field_screen)
            .filter_map(|&p| ctx.circle_pair(&current, p))
            .min_by(|a, b| a.1.total_cmp(&b.1));
        if let Some((pair, misfit)) = circles {
            if debug {
                eprintln!(
                    "   circle pair (misfit {misfit:.2e} of the radius): {:?} {:?}",
                    pair[0].init, pair[1].init
                );
            }
            to_verify.push(pair);
        }
        // A tether alone from the most circular bent path (see `circle_tether`).
        let circle_tether = current
            .family
            .free
            .iter()
            .filter_map(|&p| ctx.circle_tether(&current, p))
            .min_by(|a, b| a.1.total_cmp(&b.1));
        if let Some((tether, misfit)) = circle_tether {
            if debug {
                eprintln!(
                    "   circle tether (misfit {misfit:.2e} of the radius): {:?}",
                    tether.init
                );
            }
            if !to_verify
                .iter()
                .any(|v| v.len() == 1 && v[0].effect == tether.effect)
            {
                to_verify.push(vec![tether]);
            }
        }
        // Tethers and missing springs from the rings in the particles' residuals (see
        // `rings`).
        let rings = ctx.rings(&current);
        if let Some((tethers, amplitude)) = ctx.ringing_tether(&current, &rings) {
            if debug {
                let starts: Vec<&Vec<f64>> = tethers.iter().map(|t| &t.init).collect();
                eprintln!("   ringing tether (amplitude {amplitude:.3} px): {starts:?}");
            }
            to_verify.extend(tethers.into_iter().map(|t| vec![t]));
        }
        if let Some((spring, amplitude)) = ctx.ringing_spring(&current, &rings) {
            if debug {
                eprintln!(
                    "   ringing spring {:?} (amplitude {amplitude:.3} px): {:?}",
                    spring.effect, spring.init
                );
            }
            to_verify.push(vec![spring]);
        }
        if debug {
            for pair in pairs.iter().take(3) {
                eprintln!(
                    "   pair {:?}+{:?} screen {:?} init {:?} {:?}",
                    pair[0].effect, pair[1].effect, pair[0].screen, pair[0].init, pair[1].init
                );
            }
        }
        // Proposals from geometry or rings (no screen score), and tethers' stiffer starts, are
        // passed over once a candidate verified before them fits to the noise level: they are
        // there for what the weak form cannot see, and each costs several multi-step fits.
        let mut verified: Vec<search::Verified> = Vec::with_capacity(to_verify.len());
        for p in &to_verify {
            let geometric = p.iter().all(|q| q.screen.is_none() && q.effect.is_smooth());
            let fitted = verified
                .iter()
                .any(|v| v.current.as_ref().is_some_and(|c| ctx.at_noise_level(c)));
            if geometric && fitted {
                continue;
            }
            verified.push(ctx.verify_with(&current, p, !fitted));
        }
        verified.extend(rails);
        // Swaps: when no addition earns its place and the fit is still far from the noise, an
        // accepted smooth effect may be a poor stand-in for a better explanation (a far
        // tether imitating a pendulum's field and tether): each is taken out, the best single
        // and pair screened in its place, and verified against the current model.
        let addition_pays = verified.iter().any(|v| v.evidence.score.is_some_and(|s| s > 0.0));
        let swapped = !addition_pays && !ctx.explained(&current);
        if swapped {
            verified.extend(ctx.verify_swaps(&current, &candidates));
        }
        // Drag per body in place of an accepted per-mass drag (see `contact`).
        verified.extend(contact::body_drag_swaps(&ctx, &current));
        // A spring bumper in place of an accepted rigid wall (see `bumper`).
        verified.extend(bumper::bumper_swaps(&ctx, &current));
        if debug {
            for v in &verified {
                let effects: Vec<Effect> = v.proposals.iter().map(|p| p.effect).collect();
                eprintln!("   verified {effects:?}: {:?}", v.evidence);
            }
        }
        ctx.rank(&mut verified);
        // Record this round's losers (and unverified screened ones).
        let mut round_rejects: Vec<report::RejectedCandidate> = Vec::new();
        for p in &screened {
            if !to_verify.iter().any(|v| v.iter().any(|q| q.effect == p.effect)) {
                round_rejects.push(rejected_entry(&family0, p, None, round));
            }
        }
        // The best that transfers to other observed start states (see `transfer`).
        let mut chosen = transfer::first_that_transfers(segments.as_ref(), &shot, &current, &mut verified);
        // Additions that paid but fit one path only leave room for a swap, as when none pays.
        let one_path_only = verified
            .iter()
            .any(|v| v.evidence.transfer.as_ref().is_some_and(report::Transfer::fails));
        if chosen.is_none() && one_path_only && !swapped && !ctx.explained(&current) {
            let first = verified.len();
            verified.extend(ctx.verify_swaps(&current, &candidates));
            ctx.rank(&mut verified[first..]);
            chosen =
                transfer::first_that_transfers(segments.as_ref(), &shot, &current, &mut verified[first..])
                    .map(|i| first + i);
        }
        let best = chosen.map(|i| {
            let mut best = verified[i].clone();
            if best.removes.is_none() {
                ctx.refine_tethers(&current, &mut best);
            }
            best
        });
        let mut one_path = false;
        for (i, v) in verified.iter().enumerate() {
            let fails = v.evidence.transfer.as_ref().is_some_and(report::Transfer::fails);
            one_path |= fails;
            if Some(i) != chosen && (v.proposals.len() == 1 || fails) {
                for p in &v.proposals {
                    round_rejects.push(rejected_entry(&family0, p, Some(v.evidence.clone()), round));
                }
            }
        }
        let Some(best) = best else {
            merge_rejects(&mut rejected, round_rejects);
            stop = if ctx.explained(&current) {
                "the residual is at the noise level and no candidate earns its place".into()
            } else if one_path {
                "the candidates that fit better fit one path only (they fail transfer to other \
                 observed start states, see rejected); no other pays for its parameters"
                    .into()
            } else {
                "no candidate, alone, paired with the field or in place of an accepted effect, \
                 removes enough held-out cost to pay for its parameters"
                    .into()
            };
            break;
        };
        let Some(next) = best.current.clone() else {
            stop = "the best candidate's fit failed".into();
            break;
        };
        if let Some(k) = best.removes {
            // A swap: the replaced effect leaves, the new ones join.
            merge_rejects(&mut rejected, round_rejects);
            let (old, _, added) = accepted.remove(k);
            replaced.push(report::Replaced {
                effect: old.effect.name().into(),
                label: old.effect.label(&family0.structure),
                added_round: added,
                round,
                by: best
                    .proposals
                    .iter()
                    .map(|p| p.effect.label(&family0.structure))
                    .collect(),
                reason: None,
            });
            for p in &best.proposals {
                accepted.push((p.clone(), best.evidence.clone(), round));
            }
            let first_new = next.family.effects.len() - best.proposals.len();
            let next = rigid_tethers(&ctx, next, first_new);
            observer.observe(round, next.fit.sum_squares);
            current = next;
            prune(&ctx, &family0, &mut current, &mut accepted, &mut replaced, round);
            continue;
        }
        // Guard against a better optimum of the model without the terms: refit it from the
        // new fit's values (terms removed) and rescore.
        let mut evidence = best.evidence.clone();
        let o = next.family.effect_offset(current.family.effects.len());
        let without = next.fit.params[..o].to_vec();
        // Also at the noise level: a term worth a few variances there may be only the new
        // fit's better optimum of the shared values.
        let alt = ctx.fit(&current.family, &without, &next.fit.state, true);
        if let Some(alt) = alt {
            if alt.fit.sum_squares < current.fit.sum_squares {
                current = alt;
                evidence = ctx.evidence(&current, Some(&next), &best.proposals);
                evidence.transfer = best.evidence.transfer.clone();
            }
        }
        if !evidence.score.is_some_and(|s| s > 0.0) {
            // The model without the terms was only badly fitted: with its better fit, screen
            // again (a bounded number of times).
            merge_rejects(&mut rejected, round_rejects);
            restarts += 1;
            if restarts > MAX_RESTARTS {
                stop = "the current model's refits kept finding better optima of it".into();
                break;
            }
            continue;
        }
        merge_rejects(&mut rejected, round_rejects);
        for p in &best.proposals {
            accepted.push((p.clone(), evidence.clone(), round));
        }
        let next = rigid_tethers(&ctx, next, current.family.effects.len());
        observer.observe(round, next.fit.sum_squares);
        current = next;
        prune(&ctx, &family0, &mut current, &mut accepted, &mut replaced, round);
    }
    rejected.retain(|r| !accepted.iter().any(|(p, _, _)| rejected_matches(&family0, r, p)));

    // 5. Final refit on every analysed frame, and the base model's for comparison.
    let all_shot = Shot::new(&obs, &family0, None)?;
    let refit = |c: &Current| {
        shooting::fit_shot(
            &all_shot,
            &c.family,
            &c.fit.params,
            &c.fit.state,
            &scales,
            search::SHOT_ITERATIONS,
            true,
            &(),
        )
    };
    let mut final_fit = refit(&current).unwrap_or_else(|| {
        warnings
            .push("the final refit on all frames failed; the fit on the fitted frames is reported".into());
        current.fit.clone()
    });
    let base_fit = refit(&base).unwrap_or_else(|| base.fit.clone());
    let assemble = |family: &Family, fit: &ShotFit, accepted: &[(Proposal, report::Evidence, usize)]| {
        outcome::assemble(outcome::Inputs {
            structure,
            obs: &obs,
            sequence,
            scales: &scales,
            base_family: &family0,
            base_fit: &base_fit,
            final_family: family,
            final_fit: fit,
            anchor: all_shot.anchor,
            accepted,
            jolts: &jolt_list,
            supports: &supports,
            weak: &weak,
            seed: options.seed,
        })
    };
    // 6. Findings the tracks cannot decide leave the model (see `undecided`). First, one not
    // identified gives way to a simpler candidate that fits every frame as well, on the
    // information criterion (a far, soft tether on one particle standing in for a field).
    let mut undecided_list = Vec::new();
    let mut outcome = assemble(&current.family, &final_fit, &accepted);
    while let Some((k, simpler)) = simpler_equivalent(
        &ctx,
        &current,
        &final_fit,
        &outcome,
        &candidates,
        rough_field,
        &refit,
    ) {
        let (old, _, added) = accepted.remove(k);
        let (proposal, evidence, fit, family, reason) = simpler;
        if std::env::var_os("PHYSFIT_DEBUG").is_some() {
            eprintln!(" simpler equivalent: {:?} -> {:?}", old.effect, proposal.effect);
        }
        replaced.push(report::Replaced {
            effect: old.effect.name().into(),
            label: old.effect.label(&family0.structure),
            added_round: added,
            round: round + 1,
            by: vec![proposal.effect.label(&family0.structure)],
            reason: Some(reason),
        });
        accepted.push((proposal, evidence, round + 1));
        current = Current {
            family,
            fit: fit.clone(),
            held_cost: current.held_cost,
        };
        final_fit = fit;
        outcome = assemble(&current.family, &final_fit, &accepted);
    }
    loop {
        if outcome.findings.len() != current.family.effects.len() {
            break;
        }
        let n = final_fit.residual_count;
        let variance = final_variance(&current.family, &final_fit, obs.noise);
        let ln_n = (n.max(2) as f64).ln();
        let mut out: Option<(usize, Current, ShotFit, report::Undecided)> = None;
        for (k, f) in outcome.findings.iter().enumerate() {
            if f.identified || current.family.effects[k].adds_wall() || !variance.is_finite() {
                continue;
            }
            let held = Current {
                family: current.family.clone(),
                fit: final_fit.clone(),
                held_cost: 0.0,
            };
            let reduced = ctx.without(&held, k);
            let Some(fit) = refit(&reduced) else { continue };
            let width = current.family.effects[k].parameter_count();
            let Some((bias, added)) = undecided::bias_cost(&all_shot, &reduced.family, &fit, width) else {
                continue;
            };
            // The finding stays only if it beats the bias on the information criterion.
            let worth = (bias - final_fit.sum_squares) / variance - (width as f64 - added as f64) * ln_n;
            if worth.is_nan()
                || worth > 0.0
                || out.as_ref().is_some_and(|o| fit.sum_squares >= o.2.sum_squares)
            {
                continue;
            }
            let text = format!(
                "not enough data: {} is not identified, and a smooth track bias of {added} parameters \
                 (polynomials in time) added to the model without it leaves {bias:.4} px² where the \
                 finding leaves {:.4} px² (without either {:.4} px²): the tracks cannot tell the \
                 finding from a tracking bias; candidates: {} or a tracking bias",
                f.label, final_fit.sum_squares, fit.sum_squares, f.label
            );
            let entry = report::Undecided {
                finding: f.clone(),
                cost_with: final_fit.sum_squares,
                cost_without: fit.sum_squares,
                cost_bias: bias,
                bias_parameters: added,
                variance,
                text,
            };
            let mut reduced = reduced;
            reduced.fit = fit.clone();
            out = Some((k, reduced, fit, entry));
        }
        let Some((k, reduced, fit, entry)) = out else {
            break;
        };
        accepted.remove(k);
        current = reduced;
        final_fit = fit;
        undecided_list.push(entry);
        outcome = assemble(&current.family, &final_fit, &accepted);
    }
    // 7. How the evidence for each finding is spread over the frames (see `inclusion`); one
    // that, refitted on every frame, no longer pays for its parameters, or that resampled
    // frames do not keep, leaves the model, one at a time, and the rest are measured again.
    loop {
        let variance = final_variance(&current.family, &final_fit, obs.noise);
        if !variance.is_finite() || outcome.findings.len() != current.family.effects.len() {
            break;
        }
        let mut support = inclusion::inclusion_rates(
            &ctx,
            &all_shot,
            &current.family,
            &final_fit,
            variance,
            w,
            options.seed,
        );
        if std::env::var_os("PHYSFIT_DEBUG").is_some() {
            for (k, i) in support.iter().enumerate() {
                if let Some(i) = i {
                    eprintln!(" support {k}: worth {:.2}, inclusion {:.3}", i.worth, i.rate);
                }
            }
        }
        for (f, i) in outcome.findings.iter_mut().zip(&support) {
            f.inclusion_rate = i.as_ref().map(|i| i.rate);
        }
        let least = |key: &dyn Fn(&inclusion::Inclusion) -> f64, below: f64| {
            support
                .iter()
                .enumerate()
                .filter_map(|(k, i)| i.as_ref().map(|i| (k, key(i))))
                .filter(|(_, v)| *v < below)
                .min_by(|a, b| a.1.total_cmp(&b.1))
        };
        // First a finding that no longer pays for its parameters at all (`replaced`, with the
        // reason), then one that some resamples of the frames would leave out: it rests on a
        // few frames, "not enough data" (`undecided`); the least of each first.
        let worst = least(&|i| i.worth, 0.0);
        let weakest = least(&|i| i.rate, inclusion::INCLUSION_LEVEL);
        let Some((k, _)) = worst.or(weakest) else { break };
        let Some(out) = support[k].take() else { break };
        if let Some((_, worth)) = worst {
            let (old, _, added) = &accepted[k];
            replaced.push(report::Replaced {
                effect: old.effect.name().into(),
                label: old.effect.label(&family0.structure),
                added_round: *added,
                round: round + 1,
                by: Vec::new(),
                reason: Some(format!(
                    "refitted on every frame, it removes {:.1} residual variances less cost than its penalty",
                    -worth
                )),
            });
        } else if let Some((_, rate)) = weakest {
            let finding = outcome.findings[k].clone();
            let cost_without = out.without.fit.sum_squares;
            let text = format!(
                "not enough data: {} is kept by {:.0} % of {} resamples of the frames (blocks of {w} \
                 frames), under the {:.0} % a finding needs: it rests on a few frames; the model \
                 without it leaves {cost_without:.4} px² where it leaves {:.4} px²; candidates: {} \
                 or nothing",
                finding.label,
                100.0 * rate,
                inclusion::RESAMPLES,
                100.0 * inclusion::INCLUSION_LEVEL,
                final_fit.sum_squares,
                finding.label
            );
            undecided_list.push(report::Undecided {
                finding,
                cost_with: final_fit.sum_squares,
                cost_without,
                cost_bias: cost_without,
                bias_parameters: 0,
                variance,
                text,
            });
        }
        accepted.remove(k);
        current = out.without;
        final_fit = current.fit.clone();
        outcome = assemble(&current.family, &final_fit, &accepted);
    }
    let tq = Instant::now();
    if std::env::var_os("PHYSFIT_DEBUG").is_some() {
        eprintln!(
            " assemble {:.2}s (total {:.2}s)",
            tq.elapsed().as_secs_f64(),
            t0.elapsed().as_secs_f64()
        );
    }
    warnings.extend(outcome.warnings);
    let verdict = verdict::verdict(
        outcome.final_model.costs.multi_step.rms,
        obs.noise,
        scales.length,
        &outcome.residuals,
        &jolt_list,
    );
    let mut diagnosis = Diagnosis {
        structure: structure.name.clone(),
        seed: options.seed,
        window: [obs.first_frame, obs.last_frame()],
        sequence: [sequence.first_frame, sequence.last_frame()],
        track_noise: obs.noise,
        holdout,
        findings: outcome.findings,
        rejected,
        localisation: outcome.localisation,
        base: outcome.base,
        final_model: outcome.final_model,
        residuals: outcome.residuals,
        verdict,
        replaced,
        undecided: undecided_list,
        search: report::SearchSummary {
            rounds: round,
            stop_reason: stop,
        },
        warnings,
        stability: None,
        seconds: t0.elapsed().as_secs_f64(),
        units: None,
        final_scene: outcome.scene,
        predictions: outcome.predictions,
    };
    if let Some(m) = structure.recording.metres_per_px {
        diagnosis.add_si(m);
    }
    Ok(diagnosis)
}

/// `next` with each tether from effect `first_new` on taken as rigid where the tracks cannot
/// tell it from an inextensible one (see [`Context::rigid_tether`]).
fn rigid_tethers(ctx: &Context<'_>, mut next: Current, first_new: usize) -> Current {
    for k in first_new..next.family.effects.len() {
        if let Some(rigid) = ctx.rigid_tether(&next, k) {
            next = rigid;
        }
    }
    next
}

/// Backward elimination after a round: an effect accepted in an earlier round (or one of a
/// pair accepted in this round) that the others make redundant (the model refitted without it
/// loses less held-out cost, or less cost on the fitted frames, in units of the fit's
/// residual variance, than its `k ln N` penalty) is taken out, the most redundant first,
/// until every one pays for its parameters.
fn prune(
    ctx: &Context<'_>,
    family0: &Family,
    current: &mut Current,
    accepted: &mut Vec<(Proposal, report::Evidence, usize)>,
    replaced: &mut Vec<report::Replaced>,
    round: usize,
) {
    // Effects that joined together this round (a wall with the field) were judged only as a
    // pair: each must also pay for itself.
    let joined_now = accepted.iter().filter(|e| e.2 == round).count();
    while accepted.len() >= 2 {
        let held = ctx.held_count(&current.family);
        let (n, before) = if held > 0 {
            (held, current.held_cost)
        } else {
            (current.fit.residual_count, current.fit.sum_squares)
        };
        let variance = ctx.noise_variance(current);
        let mut worst: Option<(f64, usize, Current)> = None;
        for (k, entry) in accepted.iter().enumerate() {
            if entry.2 == round && joined_now < 2 {
                continue;
            }
            let reduced = ctx.without(current, k);
            let Some(fit) = ctx.fit(&reduced.family, &reduced.fit.params, &current.fit.state, true) else {
                continue;
            };
            let after = if held > 0 {
                fit.held_cost
            } else {
                fit.fit.sum_squares
            };
            let k_params: usize = (current.family.removed_with(k).iter())
                .map(|&j| current.family.effects[j].parameter_count())
                .sum();
            let held_worth = (after - before) / variance - k_params as f64 * (n.max(2) as f64).ln();
            // It must pay on the fitted frames too (see `Evidence::score_on`).
            let fitted_worth = (fit.fit.sum_squares - current.fit.sum_squares) / variance
                - ctx.train_penalty(current, k_params);
            let worth = if held > 0 && current.family.effects[k].is_smooth() {
                held_worth.min(fitted_worth)
            } else {
                held_worth
            };
            if std::env::var_os("PHYSFIT_DEBUG").is_some() {
                eprintln!(
                    "   prune {k}: held-out worth {held_worth:.2}, fitted-frame worth {fitted_worth:.2}"
                );
            }
            if worth.is_finite() && worth < 0.0 && worst.as_ref().map_or(true, |w| worth < w.0) {
                worst = Some((worth, k, fit));
            }
        }
        let Some((_, k, fit)) = worst else { return };
        // The effect and those that act through it (friction on its wall) go together.
        for j in current.family.removed_with(k) {
            let (old, _, added) = accepted.remove(j);
            replaced.push(report::Replaced {
                effect: old.effect.name().into(),
                label: old.effect.label(&family0.structure),
                added_round: added,
                round,
                by: Vec::new(),
                reason: None,
            });
        }
        *current = fit;
    }
}

/// A swap for a finding of `current`: a rigid rope for a spring whose length stays constant
/// within the noise (see `constraints::rope_for`), or, for a finding the tracks do not
/// identify, the simpler candidate (fewer parameters, screened best on the model without
/// it); taken when its refit on every frame (`refit`) is no worse than `final_fit` by more
/// than the parameters it saves are worth on the information criterion. Returns the
/// finding's index, and the candidate with its evidence, refit, family and the reason.
#[allow(clippy::type_complexity)]
fn simpler_equivalent(
    ctx: &Context<'_>,
    current: &Current,
    final_fit: &ShotFit,
    outcome: &outcome::Outcome,
    candidates: &[Effect],
    rough_field: physfit_model::Vec2,
    refit: &dyn Fn(&Current) -> Option<ShotFit>,
) -> Option<(usize, (Proposal, report::Evidence, ShotFit, Family, String))> {
    if outcome.findings.len() != current.family.effects.len() {
        return None;
    }
    let variance = final_variance(&current.family, final_fit, ctx.obs.noise);
    if !variance.is_finite() {
        return None;
    }
    let ln_n = (final_fit.residual_count.max(2) as f64).ln();
    let held = Current {
        family: current.family.clone(),
        fit: final_fit.clone(),
        held_cost: 0.0,
    };
    for (k, f) in outcome.findings.iter().enumerate() {
        let effect = current.family.effects[k];
        let width = effect.parameter_count();
        let reduced = ctx.without(&held, k);
        // Ropes in place of a spring of constant length; for a finding not identified, the
        // simpler candidate screened best without it.
        let mut options: Vec<(Proposal, &str)> = constraints::rope_for(ctx, &current.family, &final_fit.params, k)
            .into_iter()
            .map(|p| (p, "its length stays constant within the noise, and the candidate fits every frame as well without a stiffness"))
            .collect();
        if !f.identified && effect.is_smooth() {
            let screened = ctx
                .screen(&reduced, candidates)
                .into_iter()
                .filter(|p| p.effect.parameter_count() < width && p.effect != effect)
                .filter(|p| !reduced.family.effects.contains(&p.effect))
                .filter(|p| p.screen.is_some_and(|s| s > 0.0))
                .max_by(|a, b| a.screen.unwrap_or(0.0).total_cmp(&b.screen.unwrap_or(0.0)));
            if let Some(p) = screened {
                // A field also starts from the rough model's and from none (the screen's is
                // taken beside the finding it would replace, and both take in bounces that
                // are only faint).
                let mut starts = vec![p.clone()];
                if p.effect == Effect::Gravity {
                    for init in [rough_field, physfit_model::Vec2::zeros()] {
                        starts.push(Proposal {
                            init: vec![init.x, init.y],
                            ..p.clone()
                        });
                    }
                }
                let reason = "not identified by the tracks, and the candidate fits every frame as well with fewer parameters";
                options.extend(starts.into_iter().map(|p| (p, reason)));
            }
        }
        // The option worth the most on the information criterion (the least worth).
        let Some((p, v, with, fit, worth, reason)) = options
            .into_iter()
            .filter_map(|(p, reason)| {
                let v = ctx.verify(&reduced, std::slice::from_ref(&p));
                let with = v.current.clone()?;
                let fit = refit(&with)?;
                let saved = width as f64 - p.effect.parameter_count() as f64;
                let worth = (fit.sum_squares - final_fit.sum_squares) / variance - saved * ln_n;
                if std::env::var_os("PHYSFIT_DEBUG").is_some() {
                    eprintln!(
                        " simpler than {effect:?}: {:?} leaves {:.4} px² against {:.4} (worth {worth:.2})",
                        p.effect, fit.sum_squares, final_fit.sum_squares
                    );
                }
                Some((p, v, with, fit, worth, reason))
            })
            .min_by(|a, b| a.4.total_cmp(&b.4))
        else {
            continue;
        };
        if worth <= 0.0 {
            let reason = reason.replace("the candidate", &p.effect.label(&current.family.structure));
            return Some((k, (p, v.evidence, fit, with.family, reason)));
        }
    }
    None
}

/// Residual variance of a fit on every frame (px²): its sum of squares over the residuals
/// less the fitted unknowns (parameters and four start coordinates per free particle), at
/// least the squared track noise `noise` (px); infinite with no degrees of freedom left.
fn final_variance(family: &Family, fit: &ShotFit, noise: f64) -> f64 {
    let n = fit.residual_count;
    let p = family.dim() + 4 * family.free.len();
    if n > p {
        (fit.sum_squares / (n - p) as f64).max(noise * noise)
    } else {
        f64::INFINITY
    }
}

/// Returns true if and only if two walls' parameters (`[angle, offset, restitution]`) are
/// the same line within `WALL_GROUP_DEGREES` and a twentieth of the data's length scale.
fn same_wall(a: &[f64; 3], b: &[f64], scales: &DataScales) -> bool {
    let na = physfit_model::Vec2::new(a[0].cos(), a[0].sin());
    let nb = physfit_model::Vec2::new(b[0].cos(), b[0].sin());
    na.dot(&nb) > jolts::WALL_GROUP_DEGREES.to_radians().cos() && (a[1] - b[1]).abs() < 0.05 * scales.length
}

fn rejected_entry(
    structure_family: &Family,
    p: &Proposal,
    evidence: Option<report::Evidence>,
    round: usize,
) -> report::RejectedCandidate {
    let evidence = evidence.unwrap_or(report::Evidence {
        screen_score: p.screen,
        score_test: p.score_test,
        held_out_cost_before: None,
        held_out_cost_after: None,
        noise_variance: None,
        penalty: 0.0,
        fitted_cost_before: None,
        fitted_cost_after: None,
        fitted_penalty: 0.0,
        score: None,
        parameter_count: p.effect.parameter_count(),
        transfer: None,
    });
    let reason = evidence
        .transfer
        .as_ref()
        .filter(|t| t.fails())
        .map(|t| format!("fits one path only: {}", t.text));
    report::RejectedCandidate {
        effect: p.effect.name().into(),
        label: p.effect.label(&structure_family.structure),
        round,
        evidence,
        reason,
    }
}

fn rejected_matches(family: &Family, r: &report::RejectedCandidate, p: &Proposal) -> bool {
    r.label == p.effect.label(&family.structure) && p.effect != Effect::Wall
}

/// Keeps one entry per candidate (its latest round).
fn merge_rejects(all: &mut Vec<report::RejectedCandidate>, round: Vec<report::RejectedCandidate>) {
    for r in round {
        all.retain(|q| q.label != r.label || r.effect == "wall");
        all.push(r);
    }
}

/// About one typical oscillation period, within `[8, 64]` frames and the data.
fn test_window(scales: &DataScales, obs: &Observations) -> usize {
    let period = std::f64::consts::TAU / scales.omega.max(1e-9) * obs.fps;
    let w = if period.is_finite() {
        period.round() as usize
    } else {
        16
    };
    let max = (obs.frame_count() / 4).clamp(4, 64);
    w.clamp(8.min(max), max)
}

/// The held-out mask (by frame offset) and its description: blocks of at least `w + 2`
/// frames, about four held-out blocks, every `round(1 / fraction)`-th block held out, the
/// phase drawn from the seed. When that phase holds out every frame between two of the
/// jolts at offsets `jolts` (or between one and an end; see [`starves_a_jolt`]), the phase
/// that does not and holds out the most frames is taken instead, where there is one.
fn holdout_blocks(
    obs: &Observations,
    w: usize,
    options: &DiagnoseOptions,
    jolts: &[usize],
) -> (Vec<bool>, Holdout) {
    let frames = obs.frame_count();
    let cycle = (1.0 / options.holdout_fraction).round().max(2.0) as usize;
    let block = (w + 2).max((frames as f64 * options.holdout_fraction / 4.0).ceil() as usize);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(options.seed);
    // The first block keeps the start state constrained: never hold it out.
    let phases = cycle - 1;
    let seeded = rng.gen_range(0..phases);
    let mask = |phase: usize| {
        let mut held = vec![false; frames];
        let mut ranges = Vec::new();
        if frames >= 2 * block {
            let mut b = 1;
            while b * block < frames {
                if (b + phase) % cycle == 0 {
                    let lo = b * block;
                    let hi = ((b + 1) * block).min(frames) - 1;
                    for h in &mut held[lo..=hi] {
                        *h = true;
                    }
                    ranges.push([obs.first_frame + lo, obs.first_frame + hi]);
                }
                b += 1;
            }
        }
        (held, ranges)
    };
    // The seed's phase, or else of those that starve no jolt, the one holding out the most
    // frames (a truncated last block alone is a poor test), the first after the seed's on ties.
    let held_count = |held: &[bool]| held.iter().filter(|h| **h).count();
    let own = mask(seeded);
    let (held, ranges) = if starves_a_jolt(&own.0, jolts) {
        (1..phases)
            .map(|i| mask((seeded + i) % phases))
            .filter(|(held, _)| !starves_a_jolt(held, jolts))
            .reduce(|best, next| {
                if held_count(&next.0) > held_count(&best.0) {
                    next
                } else {
                    best
                }
            })
            .unwrap_or(own)
    } else {
        own
    };
    (
        held,
        Holdout {
            fraction: options.holdout_fraction,
            block_frames: block,
            held_out: ranges,
            test_window: w,
        },
    )
}

/// Fitted frames a stretch between jolts must keep: three positions give a velocity and an
/// acceleration, without which the fits cannot learn what a bounce did (its wall's line and
/// restitution).
const FITTED_BETWEEN_JOLTS: usize = 3;

/// Returns true if and only if the held-out mask `held` leaves fewer than
/// [`FITTED_BETWEEN_JOLTS`] fitted frames in a stretch between the jolts at offsets `jolts`
/// (or between one and an end of the recording) that has at least that many frames.
fn starves_a_jolt(held: &[bool], jolts: &[usize]) -> bool {
    if jolts.is_empty() {
        return false;
    }
    let mut cuts: Vec<usize> = jolts.iter().copied().filter(|&k| k < held.len()).collect();
    cuts.sort_unstable();
    cuts.dedup();
    let mut bounds = vec![0];
    bounds.extend(cuts.iter().map(|k| k + 1));
    let mut ends = cuts.clone();
    ends.push(held.len());
    bounds.iter().zip(&ends).any(|(&lo, &hi)| {
        hi >= lo + FITTED_BETWEEN_JOLTS && held[lo..hi].iter().filter(|h| !**h).count() < FITTED_BETWEEN_JOLTS
    })
}

/// The rough model's accelerations at every complete frame (px/s²) and its uniform field
/// (px/s²): the structure and a field, estimated together in the weak form; when bounces
/// leave the weak form too few fitted rows for that (fewer than twice its columns), the field
/// is the median of the free flights' accelerations instead (module `flights`).
#[allow(clippy::too_many_arguments)]
fn rough_model(
    family0: &Family,
    obs: &Observations,
    weak: &WeakForm,
    shot: &Shot<'_>,
    held: &[bool],
    start: &physfit_model::State,
    scales: &DataScales,
    excluded: &[bool],
) -> (Vec<Option<Vec<physfit_model::Vec2>>>, physfit_model::Vec2) {
    let family = family0.with_effects(vec![Effect::Gravity]);
    let params = Context {
        obs,
        weak,
        shot,
        held,
        start,
        scales,
    }
    .joint_estimate(&family, &vec![0.0; family.dim()]);
    let nb = family.bond_dim();
    let mut field = physfit_model::Vec2::new(params[nb], params[nb + 1]);
    let structure_model = family0.model(&params[..nb], None);
    let structure_acc: Vec<Option<Vec<physfit_model::Vec2>>> = (0..obs.frame_count())
        .map(|k| {
            let s = obs.state(k)?;
            let mut a = vec![physfit_model::Vec2::zeros(); s.len()];
            structure_model.accelerations(&s, &mut a);
            Some(a)
        })
        .collect();
    // The free flights' field replaces the weak form's where the weak form is short of
    // rows or disagrees with it by more than five of its standard errors (bounces the jolt
    // test missed spoil the weak form's windows, not the median).
    let train_rows = weak.rows.iter().filter(|r| r.train).count();
    if let Some((f, se)) = flights::field_from_flights(obs, &structure_acc, excluded) {
        let d = f - field;
        let disagree = d.x.abs() > 5.0 * se.x || d.y.abs() > 5.0 * se.y;
        if train_rows < 2 * (weak.bond_column_count() + 2) || disagree {
            field = f;
        }
    }
    let free: Vec<bool> = family0.structure.particles.iter().map(|p| !p.fixed).collect();
    let acc = structure_acc
        .into_iter()
        .map(|a| {
            a.map(|mut a| {
                for (p, v) in a.iter_mut().enumerate() {
                    if free.get(p).copied().unwrap_or(false) {
                        *v += field;
                    }
                }
                a
            })
        })
        .collect();
    (acc, field)
}
