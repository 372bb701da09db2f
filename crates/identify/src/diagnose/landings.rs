//! Landings: a particle that arrives at a line and then stays on it, resting or sliding (a
//! ball on a floor, a corner of a body pressed to a wall by a field), and the wall that holds
//! it.
//!
//! A wall that stops a particle rather than turning it round makes no jolt: the velocity
//! along the normal goes to about zero, not to its reverse, and a particle that chatters on
//! the wall under a strong field takes the wall's push as a steady force. Seen from the
//! positions alone, a landing at frame `k` is an approach (the step `x[k] - x[k-1]`, whose
//! normal part exceeds [`LANDING_THRESHOLD`] times its noise `sqrt(2) sigma` for track noise
//! `sigma`, and half the step: a gentle turn into straight motion is no landing) followed by
//! at least [`LANDING_FRAMES`] frames on a straight line, whose spread across it stays under
//! half that normal step, and which no particle's centre crosses. The walls are only
//! proposals: the multi-step fit confirms or refuses them.

use physfit_model::Vec2;

use super::constraints::principal_axis;
use super::jolts::{deepest_beyond, Jolt, WallGuess};
use crate::Observations;

/// An approach must exceed this many times its noise to make a landing.
pub const LANDING_THRESHOLD: f64 = 5.0;

/// Fewest frames on the line after the approach.
pub const LANDING_FRAMES: usize = 4;

/// Restitution a landing's wall starts from: the stop says only that it is well under 1.
const LANDING_RESTITUTION: f64 = 0.3;

/// A landing found by [`find_landings`]: the wall's guess and the approach's significance.
struct Landing {
    guess: WallGuess,
    significance: f64,
}

/// Walls from the landings of the free particles in `obs`, at most `limit`, the most
/// significant first (see the module doc).
pub fn landing_walls(obs: &Observations, limit: usize) -> Vec<WallGuess> {
    let mut landings: Vec<Landing> = (0..obs.particle_count())
        .filter(|&p| !obs.fixed[p])
        .filter_map(|p| best_landing(obs, p))
        .collect();
    landings.sort_by(|a, b| b.significance.total_cmp(&a.significance));
    landings.into_iter().take(limit).map(|l| l.guess).collect()
}

/// The most significant landing of particle `p`, if any.
fn best_landing(obs: &Observations, p: usize) -> Option<Landing> {
    let frames = obs.frame_count();
    let step_noise = 2f64.sqrt() * obs.noise.max(f64::MIN_POSITIVE);
    let fps = obs.fps;
    let at = |k: usize| obs.positions.get(k).and_then(|f| f[p]);
    let mut best: Option<Landing> = None;
    for k in 1..frames.saturating_sub(LANDING_FRAMES - 1) {
        let (Some(a), Some(b)) = (at(k - 1), at(k)) else {
            continue;
        };
        let step = b - a;
        if step.norm() < LANDING_THRESHOLD * step_noise {
            continue;
        }
        // The longest run from frame k that stays on its principal line.
        let mut run = Vec::new();
        let mut line = None;
        for j in k..frames {
            let Some(x) = at(j) else { break };
            run.push(x);
            if run.len() < LANDING_FRAMES {
                continue;
            }
            match on_a_line(&run, step) {
                Some(l) => line = Some(l),
                None => {
                    run.pop();
                    break;
                }
            }
        }
        let Some((n, offset, approach)) = line else {
            continue;
        };
        let significance = approach / step_noise;
        if significance < LANDING_THRESHOLD || a.dot(&n) <= offset {
            continue;
        }
        // No centre may cross the line by more than the run's scatter allows.
        let tolerance = (0.5 * approach).max(3.0 * obs.noise);
        if deepest_beyond(obs, n, offset) < -tolerance {
            continue;
        }
        if best.as_ref().is_some_and(|l| l.significance >= significance) {
            continue;
        }
        let before = step * fps;
        let last = run[run.len() - 1];
        let after = (last - b) * (fps / (run.len() - 1) as f64);
        best = Some(Landing {
            guess: WallGuess {
                params: [n.y.atan2(n.x), offset, LANDING_RESTITUTION],
                jolts: vec![Jolt::new(
                    p,
                    obs.first_frame + k - 1,
                    a,
                    before,
                    after,
                    after - before,
                    significance,
                )],
            },
            significance,
        });
    }
    best
}

/// The line `n . x = offset` under `run` when its points lie on a line within half the
/// normal part of the approach `step` (largest minus smallest distance across it), with `n`
/// pointing back against the approach; and that normal part (px). The line is the points'
/// principal line, or the one across the approach where the run barely moves along the wall
/// (its principal direction is then the chatter's). `None` when the points scatter more.
fn on_a_line(run: &[Vec2], step: Vec2) -> Option<(Vec2, f64, f64)> {
    let (_, axis) = principal_axis(run);
    // The normal of the principal line.
    let principal = Vec2::new(-axis.y, axis.x);
    let across_step = -step / step.norm().max(f64::MIN_POSITIVE);
    [principal, across_step]
        .into_iter()
        .filter_map(|normal| {
            let n = if normal.dot(&step) > 0.0 { -normal } else { normal };
            let approach = -n.dot(&step);
            let (lo, hi) = run
                .iter()
                .map(|x| n.dot(x))
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
                    (lo.min(v), hi.max(v))
                });
            (approach >= 0.5 * step.norm() && hi - lo <= 0.5 * approach).then_some((n, lo, approach, hi - lo))
        })
        .min_by(|a, b| a.3.total_cmp(&b.3))
        .map(|(n, offset, approach, _)| (n, offset, approach))
}
