//! Transfer: a candidate judged on paths it was not fitted to (issue 21).
//!
//! A multi-step fit frees the start state and every parameter over one path, so a wrong model
//! can trade its errors along that path (a start velocity a little off that a stiff tether
//! later corrects) and fit it closely. Restarted from the observed state at other frames it
//! cannot: a disguise fits one path only. Each judgement therefore simulates the model with
//! and without the candidate from [`TRANSFER_SEGMENTS`] observed start states spread over the
//! analysed frames (positions as tracked, velocities from the tracks' local cubic fits, see
//! [`crate::Observations`]), each over a segment of a few typical periods, and compares the
//! positions with the tracks.
//!
//! **The transfer fraction.** With `r0 = tracked - without` and `d = with - without` on the
//! segments, `beta = sum(r0 . d) / sum(d . d)` is the share of the candidate's predicted change
//! that the tracks confirm: 1 when the candidate is right, 0 when its change is not there
//! (the regression of the residual on the change). The transfer cost falls with the candidate
//! exactly when `beta > 1/2` (`cost_without - cost_with = (2 beta - 1) sum(d . d)`). Its noise
//! comes from the start states' and the tracks' noise: per coordinate the start position
//! carries `sigma^2`, the start velocity `sigma_v^2` (the observations' velocity noise), both
//! carried forward as in free flight (`e(t) = dx0 + dv0 t`, an upper bound for motion that
//! does not diverge), and each tracked position `sigma^2`, so
//! `var(sum(r0 . d)) = sum over coordinates of sigma^2 (sum d)^2 + sigma_v^2 (sum t d)^2 +
//! sigma^2 sum d^2`.
//!
//! **Launch memory.** A model whose velocity relaxes within a frame (a stiff tether balanced
//! by strong quadratic drag) follows a velocity field: it reproduces any one path from any
//! state on it, and forgets how it was launched. The memory is how much a halved launch
//! changes the model's travel over the second frame, over what free flight would
//! (`|dx_2 - dx_1| / (|dv_0| dt)`: `exp(-r dt)` about, for a velocity relaxing at rate `r`;
//! about 1 for forces whose time scales exceed a frame). A candidate that brings the memory
//! below one half (its velocity relaxing by half within a frame: dynamics the recording
//! cannot resolve) fits one path only.

use physfit_model::{State, Vec2};

use super::family::Family;
use super::report::{SegmentTransfer, Transfer};
use super::search::{noise_floor, Current, Verified};
use super::shooting::Shot;
use crate::VELOCITY_FIT_POINTS;

/// Observed start states simulated per judgement.
pub const TRANSFER_SEGMENTS: usize = 6;

/// Standard errors by which the transfer fraction must clear one half for a decision.
pub const TRANSFER_Z: f64 = 3.0;

/// Least launch memory of a model that resolves its own dynamics (see the module doc).
pub const LAUNCH_MEMORY: f64 = 0.5;

/// The observed start states and segment length a candidate's transfer is judged on.
#[derive(Clone, Debug)]
pub struct Segments {
    /// Frame offsets of the starts and the observed states there (structure particles).
    starts: Vec<(usize, State)>,
    /// For each start, the offset of the first excluded frame after it (the next contact),
    /// or the recording's end.
    smooth_ends: Vec<usize>,
    /// Frames simulated after each start.
    length: usize,
    /// Position noise per coordinate, px.
    sigma: f64,
    /// Velocity noise per coordinate of a start state, px/s.
    sigma_v: f64,
}

/// Predicted positions of the free particles on every segment: `[segment][frame][particle]`,
/// frame 0 the start.
type Predictions = Vec<Vec<Vec<Vec2>>>;

impl Segments {
    /// Up to [`TRANSFER_SEGMENTS`] starts spread evenly over the frames of `shot`, each where
    /// every particle is tracked over the velocity fit's frames and none of them is
    /// `excluded` (jolts, supports: a velocity across a bounce is no start state), with
    /// segments of `length` frames (fewer at the end of the recording); `length_scale` (px,
    /// the data's) sets the noise floor of exact tracks (see [`noise_floor`]). `None` when
    /// fewer than two starts qualify.
    pub fn new(shot: &Shot<'_>, excluded: &[bool], length: usize, length_scale: f64) -> Option<Segments> {
        let obs = shot.obs;
        let frames = obs.frame_count();
        let half = VELOCITY_FIT_POINTS / 2;
        let length = length.max(2);
        let template = shot.observed_state();
        let usable = |k: usize| {
            k >= half
                && k + half < frames
                && (k - half..=k + half).all(|j| {
                    !excluded.get(j).copied().unwrap_or(true) && obs.positions[j].iter().all(Option::is_some)
                })
                && obs.is_complete(k)
        };
        // The starts run from the first usable frame to the last that leaves half a segment.
        let last = frames.saturating_sub(1 + length / 2);
        let candidates: Vec<usize> = (0..=last).filter(|&k| usable(k)).collect();
        let (&lo, &hi) = (candidates.first()?, candidates.last()?);
        let mut starts: Vec<(usize, State)> = Vec::new();
        for i in 0..TRANSFER_SEGMENTS {
            let target = lo as f64 + (hi - lo) as f64 * i as f64 / (TRANSFER_SEGMENTS - 1) as f64;
            let Some(&k) = candidates
                .iter()
                .filter(|&&k| !starts.iter().any(|s| s.0 == k))
                .min_by(|a, b| {
                    (**a as f64 - target)
                        .abs()
                        .total_cmp(&(**b as f64 - target).abs())
                })
            else {
                break;
            };
            let Some(observed) = obs.state(k) else { continue };
            let mut state = template.clone();
            for (p, fixed) in obs.fixed.iter().enumerate() {
                if !fixed {
                    state.positions[p] = observed.positions[p];
                    state.velocities[p] = observed.velocities[p];
                }
            }
            starts.push((k, state));
        }
        starts.sort_by_key(|s| s.0);
        let smooth_ends = starts
            .iter()
            .map(|(k, _)| {
                (k + half..frames)
                    .find(|&j| excluded.get(j).copied().unwrap_or(true))
                    .unwrap_or(frames)
            })
            .collect();
        (starts.len() >= 2).then(|| Segments {
            starts,
            smooth_ends,
            length,
            sigma: noise_floor(obs.noise, length_scale),
            sigma_v: obs
                .velocity_noise
                .max(noise_floor(obs.noise, length_scale) * obs.fps),
        })
    }

    /// The end (exclusive offset) of segment `s`: `length` frames after its start, or up to
    /// the next contact unless `through_contacts`.
    fn end(&self, s: usize, through_contacts: bool) -> usize {
        let end = self.starts[s].0 + self.length + 1;
        if through_contacts {
            end
        } else {
            end.min(self.smooth_ends[s])
        }
    }

    /// The model's positions on every segment; `None` if a simulation fails.
    fn predict(
        &self,
        shot: &Shot<'_>,
        family: &Family,
        params: &[f64],
        through_contacts: bool,
    ) -> Option<Predictions> {
        let mut out = Vec::with_capacity(self.starts.len());
        for (s, (k, state)) in self.starts.iter().enumerate() {
            let mut frames = Vec::with_capacity(self.length + 1);
            let ok = shot.simulate_from(
                family,
                params,
                state,
                *k,
                self.end(s, through_contacts),
                |_, x| {
                    let free: Vec<Vec2> = family.free.iter().map(|&p| x[p]).collect();
                    let finite = free.iter().all(|v| v.x.is_finite() && v.y.is_finite());
                    frames.push(free);
                    finite
                },
            );
            if !ok {
                return None;
            }
            out.push(frames);
        }
        Some(out)
    }

    /// Launch memory of the model (see the module doc): the median over the starts whose
    /// launch speed exceeds three velocity noises; `None` where none does.
    fn memory(&self, shot: &Shot<'_>, family: &Family, params: &[f64]) -> Option<f64> {
        let dt = shot.obs.frame_dt();
        let mut memories: Vec<f64> = Vec::new();
        for (k, state) in &self.starts {
            let speed = family
                .free
                .iter()
                .map(|&p| state.velocities[p].norm_squared())
                .sum::<f64>()
                .sqrt();
            if speed <= 3.0 * self.sigma_v * (2.0 * family.free.len() as f64).sqrt() {
                continue;
            }
            let mut slow = state.clone();
            for &p in &family.free {
                slow.velocities[p] *= 0.5;
            }
            // Each free particle's travel over the second frame.
            let second_frame = |s: &State| {
                let mut x: Vec<Vec<Vec2>> = Vec::new();
                shot.simulate_from(family, params, s, *k, k + 3, |j, pos| {
                    if j > *k {
                        x.push(family.free.iter().map(|&p| pos[p]).collect());
                    }
                    true
                });
                match x.as_slice() {
                    [one, two] => two.iter().zip(one).map(|(b, a)| b - a).collect(),
                    _ => Vec::new(),
                }
            };
            let (a, b) = (second_frame(state), second_frame(&slow));
            if a.len() != family.free.len() || b.len() != a.len() {
                continue;
            }
            let moved = a
                .iter()
                .zip(&b)
                .map(|(u, v)| (u - v).norm_squared())
                .sum::<f64>()
                .sqrt();
            let m = moved / (0.5 * speed * dt);
            if m.is_finite() {
                memories.push(m);
            }
        }
        if memories.is_empty() {
            return None;
        }
        memories.sort_by(f64::total_cmp);
        Some(memories[memories.len() / 2])
    }

    /// The transfer of `with` (a candidate added to, or swapped into, `without`): see the
    /// module doc. A smooth candidate is judged up to the next contact (where it acts alone:
    /// a smooth force standing in for what happens at the bounces shows its change where it
    /// is not), a wall (`through_contacts`) over whole segments. `None` when a model cannot
    /// be simulated from the starts.
    pub fn judge(
        &self,
        shot: &Shot<'_>,
        without: &Current,
        with: &Current,
        through_contacts: bool,
    ) -> Option<Transfer> {
        let obs = shot.obs;
        let dt = obs.frame_dt();
        let p0 = self.predict(shot, &without.family, &without.fit.params, through_contacts)?;
        let p1 = self.predict(shot, &with.family, &with.fit.params, through_contacts)?;
        let free = &with.family.free;
        let (s2, v2) = (self.sigma * self.sigma, self.sigma_v * self.sigma_v);
        let mut tallies = Vec::with_capacity(self.starts.len());
        for (s, (k, _)) in self.starts.iter().enumerate() {
            let mut tally = Tally::default();
            for (q, &p) in free.iter().enumerate() {
                // Per coordinate: sum d, sum t d, sum d^2.
                let mut sums = [[0.0; 3]; 2];
                for j in 1..p0[s].len().min(p1[s].len()) {
                    let Some(o) = obs.positions[k + j][p] else {
                        continue;
                    };
                    let (a, b) = (p0[s][j][q], p1[s][j][q]);
                    let t = j as f64 * dt;
                    let (r0, d) = (o - a, b - a);
                    tally.cost0 += r0.norm_squared();
                    tally.cost1 += (o - b).norm_squared();
                    tally.expected += 2.0 * (2.0 * s2 + t * t * v2);
                    tally.count += 2;
                    tally.cross += r0.dot(&d);
                    tally.change += d.norm_squared();
                    for c in 0..2 {
                        sums[c][0] += d[c];
                        sums[c][1] += t * d[c];
                        sums[c][2] += d[c] * d[c];
                    }
                }
                for c in sums {
                    tally.variance += s2 * c[0] * c[0] + v2 * c[1] * c[1] + s2 * c[2];
                }
            }
            tallies.push((obs.first_frame + k, p0[s].len().saturating_sub(1), tally));
        }
        let total = tallies.iter().fold(Tally::default(), |a, (_, _, t)| a.plus(t));
        if total.count == 0 {
            return None;
        }
        let (fraction, std_error) = total.fraction();
        let per_segment: Vec<SegmentTransfer> = tallies
            .iter()
            .filter(|(_, _, t)| t.count > 0)
            .map(|(start, frames, t)| {
                let (fraction, fraction_std_error) = t.fraction();
                SegmentTransfer {
                    start: *start,
                    frames: *frames,
                    rms_without: t.rms(t.cost0),
                    rms_with: t.rms(t.cost1),
                    fraction,
                    fraction_std_error,
                }
            })
            .collect();
        let memory_without = self.memory(shot, &without.family, &without.fit.params);
        let memory_with = self.memory(shot, &with.family, &with.fit.params);
        let forgets = memory_with.is_some_and(|m| m < LAUNCH_MEMORY)
            && memory_without.map_or(true, |m| m >= LAUNCH_MEMORY);
        // A segment whose change the tracks contradict: the candidate helps elsewhere and
        // hurts there.
        let contradicted = per_segment.iter().find(|t| t.contradicts());
        let transfers = match (fraction, std_error) {
            _ if forgets || contradicted.is_some() => Some(false),
            (Some(b), Some(e)) if b - TRANSFER_Z * e > 0.5 => Some(true),
            (Some(b), Some(e)) if b + TRANSFER_Z * e < 0.5 => Some(false),
            _ => None,
        };
        let (rms0, rms1, rms_noise) = (
            total.rms(total.cost0),
            total.rms(total.cost1),
            total.rms(total.expected),
        );
        let share = |f: Option<f64>, e: Option<f64>| match (f, e) {
            (Some(b), Some(e)) => format!(
                "the tracks confirm {:.0} ± {:.0} % of its change",
                100.0 * b,
                100.0 * e
            ),
            _ => "it changes nothing there".into(),
        };
        let mut text = format!(
            "from {} observed start states over up to {} frames each{}: {rms1:.4} px RMS with it, {rms0:.4} px without \
             (start-state and track noise explain {rms_noise:.4} px); {}",
            per_segment.len(),
            self.length,
            if through_contacts { "" } else { " (to the next contact)" },
            share(fraction, std_error)
        );
        if let Some(t) = contradicted {
            text.push_str(&format!(
                "; but from frame {} ({} frames) {} ({:.4} px RMS with it, {:.4} without)",
                t.start,
                t.frames,
                share(t.fraction, t.fraction_std_error).replace("confirm", "confirm only"),
                t.rms_with,
                t.rms_without
            ));
        }
        if forgets {
            text.push_str(&format!(
                "; it forgets its launch within a frame (memory {:.2}, without it {})",
                memory_with.unwrap_or(0.0),
                memory_without.map_or_else(|| "not measured".into(), |m| format!("{m:.2}"))
            ));
        }
        Some(Transfer {
            starts: self.starts.iter().map(|s| obs.first_frame + s.0).collect(),
            segment_frames: self.length,
            rms_without: rms0,
            rms_with: rms1,
            rms_noise,
            fraction,
            fraction_std_error: std_error,
            launch_memory_without: memory_without,
            launch_memory_with: memory_with,
            transfers,
            segments: per_segment,
            text,
        })
    }
}

/// Sums over one segment's (or all segments') compared positions.
#[derive(Clone, Copy, Debug, Default)]
struct Tally {
    /// Squared residual without the candidate, px².
    cost0: f64,
    /// Squared residual with it, px².
    cost1: f64,
    /// Expected squared residual from the start states' and the tracks' noise, px².
    expected: f64,
    /// Residuals (coordinates) compared.
    count: usize,
    /// `sum(r0 . d)`, px².
    cross: f64,
    /// `sum(d . d)`, px².
    change: f64,
    /// Noise variance of `cross`, px⁴.
    variance: f64,
}

impl Tally {
    fn plus(self, o: &Tally) -> Tally {
        Tally {
            cost0: self.cost0 + o.cost0,
            cost1: self.cost1 + o.cost1,
            expected: self.expected + o.expected,
            count: self.count + o.count,
            cross: self.cross + o.cross,
            change: self.change + o.change,
            variance: self.variance + o.variance,
        }
    }

    /// RMS of a sum of squares over the compared residuals, px.
    fn rms(&self, sum: f64) -> f64 {
        (sum / self.count.max(1) as f64).sqrt()
    }

    /// The transfer fraction and its standard error; `None` when the change is nil.
    fn fraction(&self) -> (Option<f64>, Option<f64>) {
        let beta = self.cross / self.change;
        if self.change > 0.0 && beta.is_finite() {
            (Some(beta), Some(self.variance.sqrt() / self.change))
        } else {
            (None, None)
        }
    }
}

/// Most of a round's candidates judged by transfer (the best-ranked ones with a positive
/// score), so that a round simulates only a handful of segments.
pub const TRANSFER_JUDGED: usize = 3;

/// The index of the first of `verified` (ranked best first) whose score is positive and that
/// does not fail transfer against `current` (see [`Segments::judge`]); each candidate judged
/// gets its transfer in its evidence. Without segments, the first with a positive score.
pub fn first_that_transfers(
    segments: Option<&Segments>,
    shot: &Shot<'_>,
    current: &Current,
    verified: &mut [Verified],
) -> Option<usize> {
    let mut judged = 0;
    for (i, v) in verified.iter_mut().enumerate() {
        if !v.evidence.score.is_some_and(|s| s > 0.0) {
            continue;
        }
        let (Some(segments), Some(with)) = (segments, v.current.as_ref()) else {
            return Some(i);
        };
        if judged == TRANSFER_JUDGED {
            return None;
        }
        judged += 1;
        let wall = v.proposals.iter().any(|p| p.effect.acts_at_contacts());
        v.evidence.transfer = segments.judge(shot, current, with, wall);
        if std::env::var_os("PHYSFIT_DEBUG").is_some() {
            let effects: Vec<_> = v.proposals.iter().map(|p| p.effect).collect();
            eprintln!("   transfer {effects:?}: {:?}", v.evidence.transfer);
        }
        if !v.evidence.transfer.as_ref().is_some_and(Transfer::fails) {
            return Some(i);
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use physfit_model::Scene;
    use physfit_tracks::{TrackPoint, TrackTable};
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};

    use super::*;
    use crate::diagnose::effect::Effect;
    use crate::diagnose::family::DataScales;
    use crate::diagnose::shooting::fit_shot;
    use crate::testutil::tracks;
    use crate::Observations;

    /// The model `effects` fitted to all of `shot`'s frames from `params`.
    fn fitted(
        shot: &Shot<'_>,
        family0: &Family,
        effects: Vec<Effect>,
        params: &[f64],
        scales: &DataScales,
    ) -> Current {
        let family = family0.with_effects(effects);
        let fit = fit_shot(
            shot,
            &family,
            params,
            &shot.observed_state(),
            scales,
            40,
            false,
            &(),
        )
        .unwrap_or_else(|| panic!("{:?} cannot be fitted", family.effects));
        Current {
            family,
            fit,
            held_cost: 0.0,
        }
    }

    /// One particle `id` of unit mass at (100, `y`) px with `velocity` (px/s), no bonds,
    /// 240 frames at 60 frames/s, with the scene-file `physics` table's body.
    fn one_particle(id: &str, y: f64, velocity: [f64; 2], physics: &str) -> Scene {
        let text = format!(
            "name = \"{id}\"\nrecording = {{ fps = 60.0, frames = 240 }}\n\
             particles = [{{ id = \"{id}\", mass = 1.0, position = [100.0, {y}], velocity = {velocity:?} }}]\n\
             [physics]\n{physics}\n"
        );
        Scene::from_toml_str(&text, id).unwrap_or_else(|e| panic!("{e}"))
    }

    #[test]
    fn a_concealed_field_and_drag_transfer() {
        let truth = one_particle(
            "ball",
            300.0,
            [150.0, -400.0],
            "gravity = [0.0, 400.0]\ndrag = 0.5",
        );
        let structure = truth.structure();
        let t = tracks(&truth, 0.05, 3);
        let obs = Observations::from_tracks(&t, &structure, None).unwrap_or_else(|e| panic!("{e}"));
        let family0 = Family::new(&structure, &obs).unwrap_or_else(|e| panic!("{e}"));
        let scales = DataScales::of(&structure, &obs);
        let shot = Shot::new(&obs, &family0, None).unwrap_or_else(|e| panic!("{e}"));
        let segments =
            Segments::new(&shot, &vec![false; obs.frame_count()], 40, scales.length).expect("segments");
        let base = fitted(&shot, &family0, Vec::new(), &[], &scales);
        let field = fitted(&shot, &family0, vec![Effect::Gravity], &[0.0, 300.0], &scales);
        let both = fitted(
            &shot,
            &family0,
            vec![Effect::Gravity, Effect::Drag],
            &[0.0, 300.0, 0.1],
            &scales,
        );
        // The field alone is half the truth: it transfers, the tracks confirming more than
        // its change (the drag's share too).
        let t = segments.judge(&shot, &base, &field, false).expect("judged");
        assert_eq!(t.transfers, Some(true), "the field: {}", t.text);
        assert!(t.rms_with < t.rms_without, "the field: {}", t.text);
        // With the drag the model is the truth: all of its change is confirmed, and what is
        // left is what the start states' noise explains.
        let t = segments.judge(&shot, &field, &both, false).expect("judged");
        let (b, e) = (
            t.fraction.expect("fraction"),
            t.fraction_std_error.expect("error"),
        );
        assert_eq!(t.transfers, Some(true), "the drag: {}", t.text);
        assert!((b - 1.0).abs() < 4.0 * e, "the drag: {}", t.text);
        assert!(t.rms_with < 2.0 * t.rms_noise, "the drag: {}", t.text);
        assert!(
            t.segments.iter().all(|s| !s.contradicts()),
            "the drag: {}",
            t.text
        );
    }

    #[test]
    fn a_tether_with_strong_quadratic_drag_forgets_its_launch() {
        // A puck sliding to rest under dry friction (uniform deceleration 400 px/s^2), then
        // at rest: a stiff tether at the stop point with strong quadratic drag follows it.
        let structure = one_particle("puck", 200.0, [0.0, 0.0], "");
        let (x0, v0, a) = (Vec2::new(100.0, 200.0), Vec2::new(480.0, 180.0), 400.0);
        let stop = v0.norm() / a;
        let stop_point = x0 + v0 * (0.5 * stop);
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let normal = Normal::new(0.0, 0.05).unwrap_or_else(|e| panic!("{e}"));
        let points = (0..240)
            .map(|k| {
                let t = (k as f64 / 60.0).min(stop);
                let x = x0 + v0 * t - v0.normalize() * (0.5 * a * t * t);
                TrackPoint::new(
                    k,
                    "puck",
                    x.x + normal.sample(&mut rng),
                    x.y + normal.sample(&mut rng),
                )
            })
            .collect();
        let obs = Observations::from_tracks(&TrackTable { points }, &structure, None)
            .unwrap_or_else(|e| panic!("{e}"));
        let family0 = Family::new(&structure, &obs).unwrap_or_else(|e| panic!("{e}"));
        let scales = DataScales::of(&structure, &obs);
        let shot = Shot::new(&obs, &family0, None).unwrap_or_else(|e| panic!("{e}"));
        let segments =
            Segments::new(&shot, &vec![false; obs.frame_count()], 20, scales.length).expect("segments");
        let base = fitted(&shot, &family0, Vec::new(), &[], &scales);
        let disguise = fitted(
            &shot,
            &family0,
            vec![Effect::Tether { particle: 0 }, Effect::QuadraticDrag],
            &[stop_point.x, stop_point.y, 0.0, 1000.0, 2.5],
            &scales,
        );
        let rms = (disguise.fit.sum_squares / disguise.fit.residual_count as f64).sqrt();
        assert!(rms < 0.5, "the disguise fits the slide: {rms} px RMS");
        let t = segments.judge(&shot, &base, &disguise, false).expect("judged");
        assert_eq!(t.transfers, Some(false), "{}", t.text);
        assert!(
            t.launch_memory_with.is_some_and(|m| m < LAUNCH_MEMORY),
            "{}",
            t.text
        );
        assert!(t.text.contains("forgets its launch"), "{}", t.text);
    }
}
