//! Candidates at contacts and in a medium (issue 22): Coulomb friction at a wall that is met,
//! and drag per body (not scaled by the mass) where bodies of different masses share a medium.
//!
//! **Friction at a wall.** Once a wall is in the model (given by the structure or found from
//! the jolts), every bounce on it shows what friction does: Coulomb friction takes from the
//! tangential speed `|v_t|` at most `mu` times the normal velocity change `dv_n`
//! ([`physfit_model::Wall::apply_friction`], the one law in the model crate). Over the bounces
//! met on the wall (jolts whose impulse points into the allowed side, within a frame's travel
//! of the line), the tangential speed lost along the incoming tangential direction, summed,
//! over the normal velocity change, summed, starts `mu`; the candidate is proposed only when
//! that loss exceeds three times its noise (the jolt impulse's noise scale
//! `2 sigma fps / JOLT_FIT_POINTS` per coordinate, times the square root of the bounce count):
//! tangential kicks that *gain* speed (a spinning ball) are not friction. The multi-step fit,
//! the held-out score and the transfer through the bounces then judge it like a wall.
//!
//! **Drag per body.** `F = -b v` and `F = -c |v| v` on every free particle, shared, not scaled
//! by the mass. With every free mass equal it is the per-mass drag times that mass (the same
//! column in every fit), so it is tried only when the free masses differ, and only in place
//! of an accepted per-mass drag, as a swap that must pay one parameter more: offered beside
//! the per-mass drags it took their place on bench recordings whose truth was per-mass (3 of
//! 100: seeds 73, 79 and 97), whenever the two fitted about as well.

use physfit_model::{Vec2, Wall};

use super::effect::{wall_from_params, Effect};
use super::family::Family;
use super::jolts::{Jolt, JOLT_FIT_POINTS};
use super::search::{Context, Current, Proposal, Verified};
use crate::Observations;

/// Friction candidates: one per wall of the current model (the structure's and the accepted
/// ones, not bumpers, none with friction yet) whose bounces among `jolts` lose tangential
/// speed beyond noise, started from the measured ratio of tangential to normal change.
pub fn friction_proposals(obs: &Observations, current: &Current, jolts: &[Jolt]) -> Vec<Proposal> {
    let family = &current.family;
    let model = family.model(&current.fit.params, None);
    let mut out = Vec::new();
    for (k, wall) in model.physics.walls.iter().enumerate() {
        let has = family.effects.contains(&Effect::WallFriction { wall: k });
        if has || wall.is_bumper() || wall.friction > 0.0 {
            continue;
        }
        let sliding = sliding_on(obs, family, &current.fit.params, wall, &family.free);
        out.extend(friction_at(obs, wall, k, jolts, &sliding));
    }
    out
}

/// Particles sliding on a wall: frames whose centre lies within five track noises of the
/// line at that frame and both neighbours, and moves along it by more than five noises a
/// frame on each side; per frame, the tracks' tangential deceleration (second difference,
/// beyond the model's own acceleration) and the model's push into the wall `g_n`.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Sliding {
    /// `(particle, frame)` of each sliding frame (absolute frame index).
    pub frames: Vec<(usize, usize)>,
    /// Sum of the tangential decelerations, px/s².
    pub deceleration: f64,
    /// Sum of the pushes into the wall, px/s² (only frames pushed into it count).
    pub pressed: f64,
}

/// The sliding of `particles` (free particles of `family`) on `wall` under `params`' model
/// (see [`Sliding`]).
pub fn sliding_on(
    obs: &Observations,
    family: &Family,
    params: &[f64],
    wall: &Wall,
    particles: &[usize],
) -> Sliding {
    let model = family.model(params, None);
    let fps2 = obs.fps * obs.fps;
    let near = 5.0 * obs.noise;
    let mut out = Sliding::default();
    for k in 1..obs.frame_count().saturating_sub(1) {
        let Some(state) = obs.state(k) else { continue };
        let mut full = state.clone();
        let _ = family.model(params, Some(&mut full));
        let mut acc = vec![Vec2::zeros(); model.particle_count()];
        model.accelerations(&full, &mut acc);
        for &p in particles {
            let x = [k - 1, k, k + 1].map(|f| obs.positions[f][p]);
            let [Some(a), Some(b), Some(c)] = x else { continue };
            let on = [a, b, c].iter().all(|x| wall.signed_distance(*x).abs() <= near);
            let (before, after) = (tangential(b - a, wall.normal), tangential(c - b, wall.normal));
            let g_n = -acc[p].dot(&wall.normal);
            if !on || before.norm() <= near || after.norm() <= near || g_n <= 0.0 {
                continue;
            }
            let along = (before + after) / (before + after).norm();
            let observed = (c - 2.0 * b + a) * fps2;
            out.deceleration -= (observed - acc[p]).dot(&along);
            out.pressed += g_n;
            out.frames.push((p, obs.first_frame + k));
        }
    }
    out
}

/// Friction with each proposed wall not yet in the model (`walls`, at most the first three,
/// as the search verifies them): the wall and its friction, and with `field` as well (a floor,
/// its field and its friction are each useless to a multi-step fit without the others), for
/// the walls whose own bounces lose tangential speed beyond noise.
pub fn friction_with_walls(
    obs: &Observations,
    current: &Current,
    walls: &[Proposal],
    field: Option<&Proposal>,
) -> Vec<Vec<Proposal>> {
    let index = current
        .family
        .model(&current.fit.params, None)
        .physics
        .walls
        .len();
    let mut out = Vec::new();
    for guess in walls.iter().take(3) {
        let Some(wall) = wall_from_params(&guess.init) else {
            continue;
        };
        let Some(friction) = friction_at(obs, &wall, index, &guess.jolts, &Sliding::default()) else {
            continue;
        };
        out.push(vec![guess.clone(), friction.clone()]);
        if let Some(f) = field {
            out.push(vec![guess.clone(), f.clone(), friction]);
        }
    }
    out
}

/// Coulomb `mu` from `sliding`: its summed deceleration over its summed push, when that
/// deceleration exceeds three times its noise. Second differences of consecutive frames
/// telescope: a run of them sums to the difference of its end velocities, whose noise is
/// `2 sigma fps^2` per coordinate, so the noise is that times the square root of the number
/// of runs (consecutive sliding frames of one particle; a second difference alone, noise
/// `sqrt(6) sigma fps^2`, is bounded by it too).
pub fn sliding_mu(obs: &Observations, sliding: &Sliding) -> Option<f64> {
    let runs = sliding
        .frames
        .iter()
        .filter(|&&(p, k)| k == 0 || !sliding.frames.contains(&(p, k - 1)))
        .count();
    let noise = 6f64.sqrt() * obs.noise * obs.fps * obs.fps * (runs as f64).sqrt();
    let slides = sliding.pressed > 0.0 && sliding.deceleration > 3.0 * noise;
    slides.then(|| sliding.deceleration / sliding.pressed)
}

/// The friction candidate at `wall` (index `k` among the model's walls) from the bounces on
/// it among `jolts`, when their tangential loss exceeds three times its noise.
fn friction_at(
    obs: &Observations,
    wall: &Wall,
    k: usize,
    jolts: &[Jolt],
    sliding: &Sliding,
) -> Option<Proposal> {
    let dt = 1.0 / obs.fps;
    let impulse_noise = 2.0 * obs.noise * obs.fps / JOLT_FIT_POINTS as f64;
    let met: Vec<Jolt> = jolts
        .iter()
        .filter(|j| meets(j, wall.normal, wall.signed_distance(position(j)), dt, obs.noise))
        .cloned()
        .collect();
    let (loss, normal) = met.iter().fold((0.0, 0.0), |(l, n), j| {
        let (lost, dv_n) = tangential_loss(j, wall.normal);
        (l + lost, n + dv_n)
    });
    let bounces = !met.is_empty() && normal > 0.0 && loss > 3.0 * impulse_noise * (met.len() as f64).sqrt();
    let mu = if bounces {
        loss / normal
    } else {
        sliding_mu(obs, sliding)?
    };
    Some(Proposal {
        effect: Effect::WallFriction { wall: k },
        init: vec![mu],
        screen: None,
        score_test: None,
        jolts: met,
    })
}

/// The "where it was seen" text of friction `mu` at wall `wall` (0-based) whose bounces are
/// `met` and on which `sliding` slides, with the wall's unit `normal`.
pub fn friction_seen_text(wall: usize, mu: f64, normal: Vec2, met: &[Jolt], sliding: &Sliding) -> String {
    let (lost, dv_n) = met.iter().fold((0.0, 0.0), |(l, n), j| {
        let (lost, dv) = tangential_loss(j, normal);
        (l + lost, n + dv)
    });
    let before: f64 = met
        .iter()
        .map(|j| tangential(Vec2::from(j.before), normal).norm())
        .sum();
    let mut parts = Vec::new();
    if !met.is_empty() {
        parts.push(format!(
            "{} bounce(s) on wall {} lose {:.1} of {:.1} px/s of tangential speed in all, for {:.1} px/s of normal velocity change",
            met.len(),
            wall + 1,
            lost,
            before,
            dv_n
        ));
    }
    if !sliding.frames.is_empty() {
        let n = sliding.frames.len() as f64;
        parts.push(format!(
            "{} frame(s) sliding on wall {} decelerate by {:.1} px/s^2 on average, pushed into it by {:.1} px/s^2",
            sliding.frames.len(),
            wall + 1,
            sliding.deceleration / n,
            sliding.pressed / n
        ));
    }
    format!("{}: Coulomb friction mu = {mu:.3}", parts.join("; "))
}

/// Drag per body in place of an accepted drag per unit mass (linear for linear, quadratic for
/// quadratic), verified as swaps against `current` (see [`Context::verify_swap`]: the swap
/// pays one parameter's `ln N` more, so a drag per body must fit better, not as well), when
/// the free masses differ: with every free mass equal the two are the same force. Started
/// from the per-mass coefficient times the mean free mass.
pub fn body_drag_swaps(ctx: &Context<'_>, current: &Current) -> Vec<Verified> {
    let family = &current.family;
    let masses: Vec<f64> = family
        .free
        .iter()
        .map(|&p| family.structure.particles[p].mass)
        .collect();
    if masses.iter().all(|m| m.to_bits() == masses[0].to_bits()) {
        return Vec::new();
    }
    let mean = masses.iter().sum::<f64>() / masses.len() as f64;
    let mut out = Vec::new();
    for (k, &e) in family.effects.iter().enumerate() {
        let body = match e {
            Effect::Drag => Effect::BodyDrag,
            Effect::QuadraticDrag => Effect::BodyQuadraticDrag,
            _ => continue,
        };
        if family.effects.contains(&body) {
            continue;
        }
        let o = family.effect_offset(k);
        let proposal = Proposal {
            effect: body,
            init: vec![current.fit.params[o] * mean],
            screen: None,
            score_test: None,
            jolts: Vec::new(),
        };
        let v = ctx.verify_swap(current, k, &[proposal]);
        if std::env::var_os("PHYSFIT_DEBUG").is_some() {
            eprintln!("   swap {e:?} -> {body:?}: {:?}", v.evidence);
        }
        out.push(v);
    }
    out
}

/// The "where it was seen" text of a drag per body (`label`), with the free `masses`.
pub fn body_drag_seen_text(label: &str, masses: &[f64]) -> String {
    let lo = masses.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = masses.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    format!(
        "{label} acting throughout, against the motion, the same force at the same speed on bodies of masses {lo} to {hi}: the lighter slow faster (a drag per unit mass slows them alike)"
    )
}

fn position(j: &Jolt) -> Vec2 {
    Vec2::new(j.position[0], j.position[1])
}

/// The part of `v` across `normal`.
fn tangential(v: Vec2, normal: Vec2) -> Vec2 {
    v - normal * v.dot(&normal)
}

/// Returns true if and only if jolt `j` is a bounce on the wall with unit `normal`: its
/// impulse points into the allowed side, and its centre (at `distance` px from the line, the
/// frame before the bounce) is within the frame's travel along the normal (before and after)
/// plus five track noises of the line.
fn meets(j: &Jolt, normal: Vec2, distance: f64, dt: f64, noise: f64) -> bool {
    let (before, after) = (Vec2::from(j.before), Vec2::from(j.after));
    let travel = (before.dot(&normal).abs() + after.dot(&normal).abs()) * dt;
    Vec2::from(j.impulse).dot(&normal) > 0.0 && distance.abs() <= travel + 5.0 * noise
}

/// A bounce's tangential speed lost along its incoming tangential direction (negative for a
/// gain) and its normal velocity change, px/s.
fn tangential_loss(j: &Jolt, normal: Vec2) -> (f64, f64) {
    let (before, after) = (Vec2::from(j.before), Vec2::from(j.after));
    let vt = tangential(before, normal);
    let dv_n = (after - before).dot(&normal);
    let speed = vt.norm();
    if speed > 0.0 {
        ((before - after).dot(&(vt / speed)), dv_n)
    } else {
        (0.0, dv_n)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn jolt(before: [f64; 2], after: [f64; 2], y: f64) -> Jolt {
        Jolt {
            particle: 0,
            frame: 10,
            position: [0.0, y],
            before,
            after,
            impulse: [after[0] - before[0], after[1] - before[1]],
            significance: 50.0,
        }
    }

    #[test]
    fn a_bounce_losing_tangential_speed_reads_coulomb_mu() {
        // A floor (normal up, y down): 100 px/s along, 200 px/s into it; e = 0.8, mu = 0.2
        // takes 0.2 * 360 = 72 px/s of the tangential speed.
        let up = Vec2::new(0.0, -1.0);
        let j = jolt([100.0, 200.0], [28.0, -160.0], 298.0);
        let (lost, dv_n) = tangential_loss(&j, up);
        assert!((lost - 72.0).abs() < 1e-12 && (dv_n - 360.0).abs() < 1e-12);
        assert!(meets(&j, up, 300.0 - 298.0, 0.02, 0.01));
        // Too far from the line for one frame's travel (200 + 160 px/s over 0.02 s = 7.2 px).
        assert!(!meets(&j, up, 8.0, 0.02, 0.01));
        // A kick forward (a spinning ball) is a negative loss.
        let spun = jolt([100.0, 200.0], [130.0, -160.0], 298.0);
        assert!(tangential_loss(&spun, up).0 < 0.0);
        let text = friction_seen_text(0, 0.2, up, &[j], &Sliding::default());
        assert!(
            text.starts_with("1 bounce(s) on wall 1 lose 72.0 of 100.0 px/s"),
            "{text}"
        );
    }
}
