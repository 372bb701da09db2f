//! Candidates from constraints (issue 22): a rail under a particle whose track stays on a
//! straight line, friction on that rail, and a rope in place of a spring whose length does
//! not change beyond the noise.
//!
//! **Rail.** A particle's tracked positions are fitted by a line (principal axis of their
//! scatter). When the spread across it is at the track noise (its RMS within
//! [`ON_LINE_NOISES`] times the measured noise `sigma`) while the particle moves along it
//! over at least [`ALONG_NOISES`] `sigma`, and the current model does not yet explain the
//! tracks, a rail is proposed on that line (`[normal_angle, offset]`, [`Effect::Rail`]).
//! The multi-step fit and the information criterion then judge it like any addition: on a
//! straight path that a field or a bond already explains, a rail removes no cost and does
//! not pay for its two parameters.
//!
//! **Friction on a rail.** Once a rail is in the model, the frames where its particle
//! slides along it (on the line, moving by more than five noises a frame before and after)
//! give the tracks' deceleration beyond the model's own acceleration along the rail, and the
//! model's push across it `g_n` (the wall's estimator, [`super::contact::sliding_on`], on
//! both sides of the line): Coulomb sliding decelerates by `mu g_n`, so the sums' ratio
//! starts `mu` when the deceleration exceeds three times its noise
//! ([`super::contact::sliding_mu`]).
//!
//! **Rope.** A tether (a spring to a fixed point) or an added spring between two particles
//! whose observed length (distance to the fitted anchor, or between the two tracks) stays
//! within [`ON_LINE_NOISES`] times its noise of its mean is offered a rigid rope of that
//! length as its simpler equivalent (one parameter fewer: no stiffness), taken when the
//! rope's refit on every frame is no worse than the spring's by more than the saved
//! parameter's `ln N` (see `simpler_equivalent` in the module above). A soft spring whose
//! length visibly changes is not offered one.

use physfit_model::{Vec2, Wall};

use super::contact::{sliding_mu, sliding_on, Sliding};
use super::effect::Effect;
use super::family::Family;
use super::search::{noise_floor, Context, Current, Proposal, Verified};
use crate::Observations;

/// A path "at the track noise" across a line (or a length "constant"): its RMS spread is
/// within this many track noises. The spread of pure noise has RMS `sigma` (relative
/// standard error `1 / sqrt(2 n)`, under 5 % for 200 frames), so twice that leaves room for
/// a noise estimate low by half while a path bent by more than a couple of noises fails.
pub const ON_LINE_NOISES: f64 = 2.0;

/// A rail is proposed only for a particle that moves along its line over at least this
/// many track noises (a particle at rest lies on every line through it).
pub const ALONG_NOISES: f64 = 20.0;

/// The principal line of a set of points.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LineFit {
    /// The points' centroid, px.
    pub point: Vec2,
    /// Unit direction of the largest spread.
    pub direction: Vec2,
    /// RMS distance of the points from the line, px.
    pub across_rms: f64,
    /// Range of the points' positions along the line, px.
    pub along_range: f64,
}

impl LineFit {
    /// The line's unit normal (the direction turned by +90 degrees).
    pub fn normal(&self) -> Vec2 {
        Vec2::new(-self.direction.y, self.direction.x)
    }
}

/// The mean of `points` (at least one) and the unit direction of their principal axis: the
/// eigenvector of their scatter `[[sxx, sxy], [sxy, syy]]` with the larger eigenvalue.
pub fn principal_axis(points: &[Vec2]) -> (Vec2, Vec2) {
    let point = points.iter().sum::<Vec2>() / points.len() as f64;
    let (mut sxx, mut sxy, mut syy) = (0.0, 0.0, 0.0);
    for p in points {
        let d = p - point;
        sxx += d.x * d.x;
        sxy += d.x * d.y;
        syy += d.y * d.y;
    }
    let angle = 0.5 * (2.0 * sxy).atan2(sxx - syy);
    (point, Vec2::new(angle.cos(), angle.sin()))
}

/// The principal line of `points` (the eigenvector of their scatter with the larger
/// eigenvalue); `None` for fewer than three points.
pub fn fit_line(points: &[Vec2]) -> Option<LineFit> {
    if points.len() < 3 {
        return None;
    }
    let n = points.len() as f64;
    let (point, direction) = principal_axis(points);
    let normal = Vec2::new(-direction.y, direction.x);
    let across: f64 = points.iter().map(|p| (p - point).dot(&normal).powi(2)).sum();
    let along = points.iter().map(|p| (p - point).dot(&direction));
    let (lo, hi) = along.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), a| {
        (lo.min(a), hi.max(a))
    });
    Some(LineFit {
        point,
        direction,
        across_rms: (across / n).sqrt(),
        along_range: hi - lo,
    })
}

/// The rail parameters `[normal_angle (rad), offset (px)]` of `line` (see [`Effect::Rail`]).
pub fn rail_params(line: &LineFit) -> [f64; 2] {
    let n = line.normal();
    [n.y.atan2(n.x), n.dot(&line.point)]
}

/// The tracked positions of particle `p`, px.
fn track_of(obs: &Observations, p: usize) -> Vec<Vec2> {
    obs.positions
        .iter()
        .filter_map(|f| f.get(p).copied().flatten())
        .collect()
}

/// Rail candidates for `current` (see the module doc): one per free particle whose track
/// lies on a line at the noise while moving along it, not yet on a rail (the structure's or
/// an added one), when the current model does not explain the tracks.
pub fn rail_proposals(ctx: &Context<'_>, current: &Current) -> Vec<Proposal> {
    if ctx.explained(current) {
        return Vec::new();
    }
    let obs = ctx.obs;
    let sigma = noise_floor(obs.noise, ctx.scales.length);
    let family = &current.family;
    let railed = |p: usize| {
        family.effects.contains(&Effect::Rail { particle: p })
            || family
                .structure
                .physics
                .rails
                .iter()
                .any(|r| r.particle.index() == p)
    };
    family
        .free
        .iter()
        .filter(|&&p| !railed(p))
        .filter_map(|&p| {
            let line = fit_line(&track_of(obs, p))?;
            let on = line.across_rms <= ON_LINE_NOISES * sigma && line.along_range >= ALONG_NOISES * sigma;
            on.then(|| Proposal {
                effect: Effect::Rail { particle: p },
                init: rail_params(&line).to_vec(),
                screen: None,
                score_test: None,
                jolts: Vec::new(),
            })
        })
        .collect()
}

/// The sliding of particle `particle` along its rail (effect `k` of `family`, at `params`):
/// the wall's estimator on both sides of the rail's line, kept to that particle's frames.
pub fn sliding_on_rail(obs: &Observations, family: &Family, params: &[f64], k: usize) -> Sliding {
    let Effect::Rail { particle } = family.effects[k] else {
        return Sliding::default();
    };
    let o = family.effect_offset(k);
    let n = Vec2::new(params[o].cos(), params[o].sin());
    let mut out = Sliding::default();
    for side in [n, -n] {
        let Some(wall) = Wall::new(n * params[o + 1], side, 0.0) else {
            continue;
        };
        let s = sliding_on(obs, family, params, &wall, &[particle]);
        out.frames.extend(s.frames);
        out.deceleration += s.deceleration;
        out.pressed += s.pressed;
    }
    out
}

/// Friction candidates: one per rail of `current` without friction yet whose particle's
/// sliding decelerates beyond noise (see the module doc), started from the measured `mu`.
pub fn rail_friction_proposals(obs: &Observations, current: &Current) -> Vec<Proposal> {
    let family = &current.family;
    let mut out = Vec::new();
    for (k, &e) in family.effects.iter().enumerate() {
        let Effect::Rail { particle } = e else { continue };
        if family.effects.contains(&Effect::RailFriction { particle }) {
            continue;
        }
        let sliding = sliding_on_rail(obs, family, &current.fit.params, k);
        if let Some(mu) = sliding_mu(obs, &sliding) {
            out.push(Proposal {
                effect: Effect::RailFriction { particle },
                init: vec![mu],
                screen: None,
                score_test: None,
                jolts: Vec::new(),
            });
        }
    }
    out
}

/// The rails proposed for `current` (see [`rail_proposals`]), each verified alone and, where
/// its particle, with the rail fitted, slides with a deceleration beyond noise, with friction
/// on it: verified from the rail's own fit (its bonds and start state too), with the evidence
/// of both against `current`. A rail without its friction can lose to an added field that
/// cancels the push across the rail with a drag in place of the friction, and the pair
/// started from `current`'s bonds (fitted without the rail) stops in a poor optimum.
pub fn verify_rails(ctx: &Context<'_>, current: &Current) -> Vec<Verified> {
    let mut out = Vec::new();
    for rail in rail_proposals(ctx, current) {
        let alone = ctx.verify(current, std::slice::from_ref(&rail));
        let Some(with) = alone.current.clone() else {
            out.push(alone);
            continue;
        };
        out.push(alone);
        let k = with.family.effects.len() - 1;
        let o = with.family.effect_offset(k);
        let fitted = Proposal {
            init: with.fit.params[o..o + 2].to_vec(),
            ..rail.clone()
        };
        let Effect::Rail { particle } = rail.effect else {
            continue;
        };
        if std::env::var_os("PHYSFIT_DEBUG").is_some() {
            let s = sliding_on_rail(ctx.obs, &with.family, &with.fit.params, k);
            eprintln!(
                "   rail of {particle} fitted to {:.4} px²: {} sliding frames, deceleration {:.1}, pressed {:.1}, mu {:?}",
                with.fit.sum_squares,
                s.frames.len(),
                s.deceleration,
                s.pressed,
                sliding_mu(ctx.obs, &s)
            );
        }
        for friction in rail_friction_proposals(ctx.obs, &with) {
            if friction.effect == (Effect::RailFriction { particle }) {
                let mut pair = ctx.verify(&with, std::slice::from_ref(&friction));
                pair.proposals = vec![fitted.clone(), friction];
                pair.evidence = ctx.evidence(current, pair.current.as_ref(), &pair.proposals);
                out.push(pair);
            }
        }
    }
    out
}

/// The ropes that could stand in for effect `k` of `current` (at `params`): for a tether, a
/// rope to the structure's fixed particle nearest its anchor (one parameter, where there is
/// one) and a rope from its anchor; for an added spring, a rope between its two particles;
/// each when its observed length (see the module doc) stays within [`ON_LINE_NOISES`]
/// times its noise of its mean, started from that mean length.
pub fn rope_for(ctx: &Context<'_>, family: &Family, params: &[f64], k: usize) -> Vec<Proposal> {
    let o = family.effect_offset(k);
    let structure = &family.structure;
    // An end: a particle (tracked, or a fixed one where the structure puts it) or a point.
    let ropes: Vec<(Effect, usize, End)> = match family.effects[k] {
        Effect::Tether { particle } => {
            let anchor = Vec2::new(params[o], params[o + 1]);
            let pivot = (0..structure.particles.len())
                .filter(|&q| structure.particles[q].fixed)
                .min_by(|&a, &b| {
                    let d = |q: usize| (structure.particles[q].position - anchor).norm();
                    d(a).total_cmp(&d(b))
                });
            pivot
                .map(|q| (Effect::Rope { a: particle, b: q }, particle, End::Particle(q)))
                .into_iter()
                .chain([(Effect::AnchoredRope { particle }, particle, End::Point(anchor))])
                .collect()
        }
        Effect::MissingSpring { a, b } => vec![(Effect::Rope { a, b }, a, End::Particle(b))],
        _ => Vec::new(),
    };
    ropes
        .into_iter()
        .filter_map(|(effect, particle, end)| {
            let length = constant_length(ctx, family, particle, end)?;
            let mut init = match end {
                End::Point(a) => vec![a.x, a.y],
                End::Particle(_) => Vec::new(),
            };
            init.push(length);
            Some(Proposal {
                effect,
                init,
                screen: None,
                score_test: None,
                jolts: Vec::new(),
            })
        })
        .collect()
}

/// The far end of a rope.
#[derive(Clone, Copy, Debug)]
enum End {
    /// One of the structure's particles.
    Particle(usize),
    /// A fixed point, px.
    Point(Vec2),
}

/// The mean observed distance (px) between `particle` and `end` when it stays within
/// [`ON_LINE_NOISES`] times its noise (the track noise of each moving end) of that mean.
fn constant_length(ctx: &Context<'_>, family: &Family, particle: usize, end: End) -> Option<f64> {
    let obs = ctx.obs;
    let sigma = noise_floor(obs.noise, ctx.scales.length);
    let structure = &family.structure;
    let at = |f: &[Option<Vec2>], q: usize| {
        f.get(q).copied().flatten().or_else(|| {
            structure.particles[q]
                .fixed
                .then(|| structure.particles[q].position)
        })
    };
    let lengths: Vec<f64> = obs
        .positions
        .iter()
        .filter_map(|f| {
            let y = match end {
                End::Point(a) => a,
                End::Particle(q) => at(f, q)?,
            };
            Some((at(f, particle)? - y).norm())
        })
        .collect();
    if lengths.len() < 3 {
        return None;
    }
    let n = lengths.len() as f64;
    let mean = lengths.iter().sum::<f64>() / n;
    let rms = (lengths.iter().map(|l| (l - mean).powi(2)).sum::<f64>() / n).sqrt();
    let moving = match end {
        End::Particle(q) if !structure.particles[q].fixed => 2.0,
        _ => 1.0,
    };
    (rms <= ON_LINE_NOISES * sigma * f64::sqrt(moving) && mean > 0.0).then_some(mean)
}

/// The "where it was seen" text of constraint effect `k` of `family` at `params`, with the
/// particle ids `id` (rail: its line and the track's spread across it; rail friction: the
/// sliding frames; rope: its length and the observed length's spread).
pub fn seen_text(
    obs: &Observations,
    family: &Family,
    params: &[f64],
    k: usize,
    id: &dyn Fn(usize) -> String,
) -> String {
    let o = family.effect_offset(k);
    let v = &params[o..o + family.effects[k].parameter_count()];
    match family.effects[k] {
        Effect::Rail { particle } => {
            let n = Vec2::new(v[0].cos(), v[0].sin());
            let points = track_of(obs, particle);
            let across = (points.iter().map(|x| (n.dot(x) - v[1]).powi(2)).sum::<f64>()
                / points.len().max(1) as f64)
                .sqrt();
            let line = fit_line(&points);
            format!(
                "{} stays on the line n.x = {:.2} px with n = ({:.4}, {:.4}) (direction {:.2} degrees, image axes, y down): {:.3} px RMS across it (track noise {:.3} px) while it moves {:.1} px along it",
                id(particle),
                v[1],
                n.x,
                n.y,
                (-n.x).atan2(n.y).to_degrees(),
                across,
                obs.noise,
                line.map_or(0.0, |l| l.along_range)
            )
        }
        Effect::RailFriction { particle } => {
            let rail = family
                .effects
                .iter()
                .position(|e| *e == Effect::Rail { particle });
            let sliding = rail.map(|r| sliding_on_rail(obs, family, params, r)).unwrap_or_default();
            let count = sliding.frames.len().max(1) as f64;
            format!(
                "{} frame(s) of {} sliding on its rail decelerate by {:.1} px/s^2 on average, pressed across it by {:.1} px/s^2: Coulomb friction mu = {:.4}",
                sliding.frames.len(),
                id(particle),
                sliding.deceleration / count,
                sliding.pressed / count,
                v[0]
            )
        }
        Effect::Rope { a, b } => format!(
            "the distance between {} and {} stays {:.2} px within the noise: a rigid rope (no stiffness to fit)",
            id(a),
            id(b),
            v[0]
        ),
        Effect::AnchoredRope { particle } => format!(
            "{} stays {:.2} px from a fixed point at ({:.1}, {:.1}) px, within the noise: a rigid rope (no stiffness to fit) to a point that is not among the structure's particles",
            id(particle),
            v[2],
            v[0],
            v[1]
        ),
        _ => String::new(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    #[test]
    fn a_noisy_straight_track_fits_its_line_and_a_bent_one_does_not() {
        for seed in 0..5u64 {
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
            let angle: f64 = rng.gen_range(-1.5..1.5);
            let sigma = 0.05;
            let d = Vec2::new(angle.cos(), angle.sin());
            let normal = Vec2::new(-d.y, d.x);
            let start = Vec2::new(100.0, 200.0);
            let gauss = |rng: &mut rand_chacha::ChaCha8Rng| {
                let (u, v): (f64, f64) = (rng.gen_range(1e-12..1.0), rng.gen_range(0.0..1.0));
                (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
            };
            let points: Vec<Vec2> = (0..200)
                .map(|k| {
                    let s = 80.0 * (k as f64 * 0.05).sin();
                    start + d * s + Vec2::new(gauss(&mut rng), gauss(&mut rng)) * sigma
                })
                .collect();
            let line = fit_line(&points).expect("a line");
            // Direction within 0.01 degrees, spread across at the noise.
            let turn = line.direction.dot(&normal).abs().asin().to_degrees();
            assert!(turn < 0.01, "seed {seed}: {turn} degrees");
            assert!(
                line.across_rms < 1.2 * sigma && line.across_rms > 0.8 * sigma,
                "{line:?}"
            );
            assert!(line.along_range > 150.0);
            let [a, offset] = rail_params(&line);
            let n = Vec2::new(a.cos(), a.sin());
            assert!((n.dot(&start) - offset).abs() < 0.02, "{offset}");
            // A parabola bowing by 10 noises is not on a line at the noise.
            let bent: Vec<Vec2> = points
                .iter()
                .enumerate()
                .map(|(k, x)| x + normal * (10.0 * sigma * ((k as f64 / 100.0) - 1.0).powi(2)))
                .collect();
            let line = fit_line(&bent).expect("a line");
            assert!(line.across_rms > ON_LINE_NOISES * sigma, "{line:?}");
        }
    }
}
