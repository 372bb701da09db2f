//! The spring-bumper candidate (issue 22): a wall whose contact is a one-sided spring of
//! stiffness `S` (energy/px², energy `S s^2` beyond the line, no 1/2) and dashpot `c`
//! (mass/s) instead of an instantaneous bounce ([`physfit_model::Wall::with_bumper`]).
//!
//! **What shows it.** A rigid wall turns every centre round on one line; a bumper lets a
//! centre in by `v / w` at impact speed `v` (`w = sqrt(2 S / m)`, zero damping) and holds it
//! for `pi / w` s, so the turning point moves with the impact speed and the contact spans
//! frames. It is offered only in place of an accepted rigid wall ([`Effect::Wall`]), as a
//! swap that pays one parameter more (a bumper has four, a wall three).
//!
//! **Why a staged start.** The multi-step fit over the whole recording, started from the
//! stiffness the penetrations give (about 8 % off), stopped at 64-2753 px² where the truth's
//! start reaches the noise (0.07 px²): each bounce's timing moves with the stiffness, so the
//! cost is far from convex in the stiffness and the line. The start is instead fitted on
//! short windows around each contact (the rigid wall's deepest tracked frames, `±`
//! [`WINDOW_HALF`] frames), each window simulated from its own fitted start state, the rest
//! of the model held:
//!
//! 1. a log grid over the stiffness (contact times from a quarter frame to the window); at
//!    each, the line is started from the deepest tracked centres and their impact speeds
//!    (`depth + v / w` in from it) and the damping from the rigid wall's restitution `e`
//!    (`zeta = -ln e / sqrt(pi^2 + ln^2 e)`, `c = 2 zeta sqrt(2 S m)`), then both are fitted
//!    with the wall's direction, the other effects' parameters (a field) and the window
//!    states: the windows' cost profiled over the stiffness;
//!    the best grid point is refined by a golden-section search in `ln S` between its
//!    neighbours;
//! 2. from there, all four of the bumper's parameters with the rest;
//! 3. the rigid wall refitted on the same windows (its three parameters with the rest),
//!    first: where it fits them to the noise (cost within `N + 2 ln N` variances for `N`
//!    residuals) no bumper can pass the gate below without fitting below the noise, and
//!    steps 1-2 are skipped.
//!
//! The candidate is proposed only when the bumper removes more than `2 ln N` noise variances
//! of the windows' cost `N` residuals) against the rigid wall: a rigid bounce, which a stiff
//! bumper can only imitate, gains nothing there. The swap is then fitted over the whole
//! recording from that start and judged like every other candidate.

use physfit_model::{State, Vec2, Wall};

use super::effect::{bumper_from_params, wall_from_params, Effect};
use super::family::Family;
use super::search::{noise_floor, Context, Current, Proposal, Verified};
use crate::{levenberg_marquardt, LmOptions, Observations};

/// Frames simulated on each side of a contact's deepest tracked frame.
pub const WINDOW_HALF: usize = 8;

/// Points of the stiffness grid (log-spaced).
const GRID_POINTS: usize = 25;

/// Golden-section steps refining the stiffness between the best grid point's neighbours
/// (the bracket shrinks to `0.618^n` of its log-width, a factor 1.78: 0.6 % for 10).
const GOLDEN_STEPS: usize = 10;

/// Noise variances per residual count's `ln` the bumper must remove from the windows' cost
/// against the rigid wall to be proposed (one for its extra parameter, one of margin for a
/// window fit's local optimum).
const GATE_LN_N: f64 = 2.0;

/// One contact with a wall seen in the tracks.
#[derive(Clone, Debug, PartialEq)]
pub struct Contact {
    /// Particle (structure index).
    pub particle: usize,
    /// Frame offset of the deepest tracked centre.
    pub frame: usize,
    /// Signed distance of that centre from the wall's line, px (negative beyond it).
    pub depth: f64,
    /// Largest normal approach speed over the frames before it, px/s.
    pub speed: f64,
    /// First and last frame offsets of the window simulated around it.
    pub window: (usize, usize),
}

/// The contacts of `free` particles with `wall` in `obs`: frames whose tracked centre is the
/// nearest to the line within two frames each side, approached and left by more than five
/// track noises a frame, and within the approach's frame of travel plus five noises of the
/// line, or, once such a clear bounce is seen, within `2 WINDOW_HALF / pi` of the fastest
/// clear bounce's frame of travel (a bumper softer than that holds a centre longer than the
/// windows: the slower impacts turn that far in from the faster ones' line).
pub fn contacts_on(obs: &Observations, free: &[usize], wall: &Wall) -> Vec<Contact> {
    let frames = obs.frame_count();
    let near = 5.0 * obs.noise;
    // (contact, its own frame of travel)
    let mut found: Vec<(Contact, f64)> = Vec::new();
    for &p in free {
        let s: Vec<Option<f64>> = (0..frames)
            .map(|k| obs.positions[k][p].map(|x| wall.signed_distance(x)))
            .collect();
        for k in 2..frames.saturating_sub(2) {
            let Some(d) = s[k] else { continue };
            let around: Option<Vec<f64>> = (k - 2..=k + 2).map(|j| s[j]).collect();
            let Some(around) = around else { continue };
            if around.iter().enumerate().any(|(i, &v)| i != 2 && v <= d) {
                continue;
            }
            let step = |j: usize| Some(s[j]? - s[j + 1]?);
            let drop = (k.saturating_sub(4)..k).filter_map(step).fold(0.0, f64::max);
            let rise = (k..(k + 4).min(frames - 1))
                .filter_map(|j| step(j).map(|v| -v))
                .fold(0.0, f64::max);
            if drop <= near || rise <= near {
                continue;
            }
            let contact = Contact {
                particle: p,
                frame: k,
                depth: d,
                speed: drop * obs.fps,
                window: (k.saturating_sub(WINDOW_HALF), (k + WINDOW_HALF).min(frames - 1)),
            };
            found.push((contact, drop));
        }
    }
    let fastest = found
        .iter()
        .filter(|(c, drop)| c.depth <= drop + near)
        .map(|(_, drop)| *drop)
        .fold(0.0, f64::max);
    let reach = 2.0 * WINDOW_HALF as f64 / std::f64::consts::PI * fastest;
    found
        .into_iter()
        .filter(|(c, drop)| c.depth <= drop.max(reach) + near)
        .map(|(c, _)| c)
        .collect()
}

/// The damping ratio of a restitution `e` (`-ln e / sqrt(pi^2 + ln^2 e)`; 1 for `e <= 0`).
fn damping_ratio(e: f64) -> f64 {
    if e <= 0.0 {
        return 1.0;
    }
    let l = e.min(1.0).ln();
    -l / (std::f64::consts::PI.powi(2) + l * l).sqrt()
}

/// Short simulations around contacts: `family` at `params` from each window's start state.
struct Windows<'c, 'a> {
    ctx: &'c Context<'a>,
    family: &'c Family,
    contacts: &'c [Contact],
}

impl Windows<'_, '_> {
    /// Variables per window: position and velocity of each free particle.
    fn per_window(&self) -> usize {
        4 * self.family.free.len()
    }

    /// The observed start state of each window (`None` if a window starts untracked).
    fn observed_states(&self) -> Option<Vec<State>> {
        self.contacts
            .iter()
            .map(|c| self.ctx.obs.state(c.window.0))
            .collect()
    }

    /// Window start states with the free particles' positions and velocities from `z`.
    fn states(&self, template: &[State], z: &[f64]) -> Vec<State> {
        let per = self.per_window();
        template
            .iter()
            .enumerate()
            .map(|(w, s)| {
                let mut s = s.clone();
                for (i, &p) in self.family.free.iter().enumerate() {
                    let v = &z[w * per + 4 * i..w * per + 4 * i + 4];
                    s.positions[p] = Vec2::new(v[0], v[1]);
                    s.velocities[p] = Vec2::new(v[2], v[3]);
                }
                s
            })
            .collect()
    }

    /// Position residuals of every window's free tracked particles (px) into `out`.
    fn residuals(&self, params: &[f64], states: &[State], out: &mut Vec<f64>) -> bool {
        out.clear();
        let obs = self.ctx.obs;
        for (c, s) in self.contacts.iter().zip(states) {
            let ok =
                self.ctx
                    .shot
                    .simulate_from(self.family, params, s, c.window.0, c.window.1 + 1, |k, x| {
                        for &p in &self.family.free {
                            if let Some(o) = obs.positions[k][p] {
                                let e = x[p] - o;
                                if !(e.x.is_finite() && e.y.is_finite()) {
                                    return false;
                                }
                                out.push(e.x);
                                out.push(e.y);
                            }
                        }
                        true
                    });
            if !ok {
                return false;
            }
        }
        true
    }

    /// Fits the parameters at `slots` of `params` (within `bounds`, typical sizes `typical`)
    /// and every window's start state: the fitted parameters and states, the cost (px²) and
    /// the residual count.
    fn fit(
        &self,
        params: &[f64],
        slots: &[usize],
        bounds: &[[f64; 2]],
        typical: &[f64],
        template: &[State],
    ) -> Option<(Vec<f64>, Vec<State>, f64, usize)> {
        let mut z0: Vec<f64> = slots.iter().map(|&i| params[i]).collect();
        for s in template {
            for &p in &self.family.free {
                let (x, v) = (s.positions[p], s.velocities[p]);
                z0.extend([x.x, x.y, v.x, v.y]);
            }
        }
        let m = slots.len();
        let length = self.ctx.scales.length;
        let speed = length / self.ctx.scales.time;
        let mut lower: Vec<f64> = bounds.iter().map(|b| b[0]).collect();
        let mut upper: Vec<f64> = bounds.iter().map(|b| b[1]).collect();
        let mut scale: Vec<f64> = typical.to_vec();
        for _ in 0..template.len() * self.family.free.len() {
            lower.extend([f64::NEG_INFINITY; 4]);
            upper.extend([f64::INFINITY; 4]);
            scale.extend([length, length, speed, speed]);
        }
        let unpack = |z: &[f64]| {
            let mut q = params.to_vec();
            for (j, &i) in slots.iter().enumerate() {
                q[i] = z[j];
            }
            (q, self.states(template, &z[m..]))
        };
        let f = |z: &[f64], out: &mut Vec<f64>| {
            let (q, states) = unpack(z);
            self.residuals(&q, &states, out)
        };
        let options = LmOptions {
            max_iterations: 60,
            tolerance: 1e-10,
            ..LmOptions::default()
        };
        let r = levenberg_marquardt(&f, &z0, &lower, &upper, &scale, &options, &())?;
        let (q, states) = unpack(&r.x);
        Some((q, states, r.cost, r.residuals.len()))
    }
}

/// A point of the windows' cost profile over the stiffness: the cost (px²), the parameters
/// and the window start states fitted there.
type Profiled = (f64, Vec<f64>, Vec<State>);

fn debug() -> bool {
    std::env::var_os("PHYSFIT_DEBUG").is_some()
}

/// What the windows around a wall's contacts say of a bumper there.
#[derive(Clone, Debug)]
pub struct BumperEvidence {
    /// The bumper's start `[normal_angle, offset, stiffness, damping]`.
    pub init: Vec<f64>,
    /// The windows' cost with the bumper and with the rigid wall refitted on them, px².
    pub costs: [f64; 2],
    /// Residual count of the windows.
    pub residual_count: usize,
    /// The contacts.
    pub contacts: Vec<Contact>,
}

/// The bumper's evidence at the accepted rigid wall, effect `k` of `current` (see the module
/// doc), or `None` when no contact is seen or a window cannot be simulated.
pub fn bumper_evidence(ctx: &Context<'_>, current: &Current, k: usize) -> Option<BumperEvidence> {
    let family = &current.family;
    let o = family.effect_offset(k);
    let rigid_params = current.fit.params.get(o..o + 3)?.to_vec();
    let wall = wall_from_params(&rigid_params)?;
    let contacts: Vec<Contact> = contacts_on(ctx.obs, &family.free, &wall)
        .into_iter()
        .filter(|c| ctx.obs.state(c.window.0).is_some())
        .collect();
    if contacts.is_empty() {
        return None;
    }
    let mass = |p: usize| family.structure.particles[p].mass;
    let mean_mass = contacts.iter().map(|c| mass(c.particle)).sum::<f64>() / contacts.len() as f64;
    let zeta = damping_ratio(rigid_params[2]);
    // The bumper in the rigid wall's place (the wall's parameters out, the bumper's at the end).
    let reduced = family.without_effect(k);
    let mut effects = reduced.effects.clone();
    effects.push(Effect::Bumper);
    let bumper_family = reduced.with_effects(effects);
    let mut base: Vec<f64> = current.fit.params.clone();
    base.drain(o..o + 3);
    let b = base.len();
    let at = |s: f64| -> Vec<f64> {
        let line: f64 = contacts
            .iter()
            .map(|c| c.depth + c.speed / (2.0 * s / mass(c.particle)).sqrt())
            .sum::<f64>()
            / contacts.len() as f64;
        let c = 2.0 * zeta * (2.0 * s * mean_mass).sqrt();
        let mut q = base.clone();
        q.extend([rigid_params[0], rigid_params[1] + line, s, c]);
        q
    };
    let windows = Windows {
        ctx,
        family: &bumper_family,
        contacts: &contacts,
    };
    let observed = windows.observed_states()?;
    // The other effects' parameters are fitted on the windows too: a field or a wall
    // direction that the rigid fit bent to absorb the bumper would otherwise decide the
    // windows' cost.
    let others = |fam: &Family, skip: usize| -> Vec<usize> {
        (0..fam.effects.len())
            .filter(|&j| j != skip)
            .flat_map(|j| {
                let o = fam.effect_offset(j);
                o..o + fam.effects[j].parameter_count()
            })
            .collect()
    };
    let slot_ranges = |fam: &Family, slots: &[usize]| {
        let (lower, upper) = fam.bounds();
        let typical = fam.typical(ctx.scales);
        let bounds: Vec<[f64; 2]> = slots.iter().map(|&i| [lower[i], upper[i]]).collect();
        let typical: Vec<f64> = slots.iter().map(|&i| typical[i]).collect();
        (bounds, typical)
    };
    let last = bumper_family.effects.len() - 1;
    // 0. The rigid wall refitted on the windows, its three parameters with the rest. Where
    // it fits them to the noise (cost within `N + 2 ln N` variances) no bumper can remove
    // the gate's `2 ln N` without fitting below the noise: the profile is not computed.
    let rigid = Windows {
        ctx,
        family,
        contacts: &contacts,
    };
    let mut slots = vec![o, o + 1, o + 2];
    slots.extend(others(family, k));
    let (bounds, typical) = slot_ranges(family, &slots);
    let (_, _, rigid_cost, n) = rigid.fit(&current.fit.params, &slots, &bounds, &typical, &observed)?;
    let floor = noise_floor(ctx.obs.noise, ctx.scales.length);
    let ln_n = (n.max(2) as f64).ln();
    if rigid_cost <= (n as f64 + GATE_LN_N * ln_n) * floor * floor {
        if debug() {
            eprintln!(
                "   bumper at wall effect {k}: the rigid wall fits {} contact window(s) to the noise ({rigid_cost:.4} px² over {n} residuals)",
                contacts.len()
            );
        }
        return None;
    }
    // 1. The stiffness grid: contact times `pi / w` from a quarter frame to the window; the
    // line and damping started from the stiffness, and fitted with the wall's direction, the
    // other effects and the window states (the windows' cost profiled over the stiffness).
    let dt = ctx.obs.frame_dt();
    let (w_lo, w_hi) = (
        std::f64::consts::PI / (WINDOW_HALF as f64 * dt),
        4.0 * std::f64::consts::PI / dt,
    );
    let (s_lo, s_hi) = (0.5 * mean_mass * w_lo * w_lo, 0.5 * mean_mass * w_hi * w_hi);
    let mut grid_slots = vec![b, b + 1, b + 3];
    grid_slots.extend(others(&bumper_family, last));
    let (bounds, typical) = slot_ranges(&bumper_family, &grid_slots);
    // The line's shift in from the deepest centres at stiffness `s`.
    let shift = |s: f64| at(s)[b + 1] - rigid_params[1];
    // The windows' cost at stiffness `s`, fitted from `at(s)` and the observed states, or
    // from a neighbouring fit `from` (its line moved by the change of `v / w`, its damping
    // kept at the same damping ratio): the inner fits then end in one basin, and the profile
    // is smooth enough for the golden section.
    let profile = |s: f64, from: Option<&Profiled>| {
        let (q, states) = match from {
            Some((_, q0, states0)) => {
                let mut q = q0.clone();
                let s0 = q0[b + 2];
                q[b + 1] += shift(s) - shift(s0);
                q[b + 2] = s;
                q[b + 3] *= (s / s0).sqrt();
                (q, states0.clone())
            }
            None => (at(s), observed.clone()),
        };
        let mut typical = typical.clone();
        typical[2] = q[b + 3].max(1e-3 * (2.0 * s * mean_mass).sqrt());
        let fitted = windows.fit(&q, &grid_slots, &bounds, &typical, &states);
        if debug() {
            eprintln!(
                "    bumper profile S {s:.1}: windows cost {:?} px²",
                fitted.as_ref().map(|f| f.2)
            );
        }
        fitted.map(|(q, states, cost, _)| (cost, q, states))
    };
    let grid: Vec<f64> = (0..GRID_POINTS)
        .map(|i| s_lo * (s_hi / s_lo).powf(i as f64 / (GRID_POINTS - 1) as f64))
        .collect();
    let costs: Vec<Option<Profiled>> = grid.iter().map(|&s| profile(s, None)).collect();
    let (i, _) = costs
        .iter()
        .enumerate()
        .filter_map(|(i, c)| Some((i, c.as_ref()?.0)))
        .min_by(|a, b| a.1.total_cmp(&b.1))?;
    // Golden-section search in log S between the best grid point's neighbours: the grid's
    // step (a factor 1.33) is too coarse a start for the whole-recording fit.
    let (mut lo, mut hi) = (
        grid[i.saturating_sub(1)].ln(),
        grid[(i + 1).min(GRID_POINTS - 1)].ln(),
    );
    let mut best = costs[i].clone()?;
    let golden = 0.5 * (5f64.sqrt() - 1.0);
    let cost_at = |x: f64, best: &mut Profiled| {
        profile(x.exp(), Some(&*best)).map_or(f64::INFINITY, |p| {
            let c = p.0;
            if c < best.0 {
                *best = p;
            }
            c
        })
    };
    let mut x1 = hi - golden * (hi - lo);
    let mut x2 = lo + golden * (hi - lo);
    let mut f1 = cost_at(x1, &mut best);
    let mut f2 = cost_at(x2, &mut best);
    for _ in 0..GOLDEN_STEPS {
        if f1 < f2 {
            hi = x2;
            (x2, f2) = (x1, f1);
            x1 = hi - golden * (hi - lo);
            f1 = cost_at(x1, &mut best);
        } else {
            lo = x1;
            (x1, f1) = (x2, f2);
            x2 = lo + golden * (hi - lo);
            f2 = cost_at(x2, &mut best);
        }
    }
    let (_, q, states) = best;
    // 2. The bumper's four parameters with the rest, from the best grid point.
    let mut slots = vec![b, b + 1, b + 2, b + 3];
    slots.extend(others(&bumper_family, last));
    let (bounds, mut typical) = slot_ranges(&bumper_family, &slots);
    typical[2] = q[b + 2];
    typical[3] = (2.0 * q[b + 2] * mean_mass).sqrt();
    let (q, _, bumper_cost, n) = windows.fit(&q, &slots, &bounds, &typical, &states)?;
    Some(BumperEvidence {
        init: q[b..].to_vec(),
        costs: [bumper_cost, rigid_cost],
        residual_count: n,
        contacts,
    })
}

/// Spring bumpers in place of accepted rigid walls, verified as swaps against `current` (see
/// [`Context::verify_swap`]), where the contact windows show one (see the module doc). Not
/// offered while the model has friction at a wall (a swap reorders the walls it indexes).
pub fn bumper_swaps(ctx: &Context<'_>, current: &Current) -> Vec<Verified> {
    let family = &current.family;
    if family
        .effects
        .iter()
        .any(|e| matches!(e, Effect::WallFriction { .. }))
    {
        return Vec::new();
    }
    let debug = std::env::var_os("PHYSFIT_DEBUG").is_some();
    let floor = noise_floor(ctx.obs.noise, ctx.scales.length);
    let mut out = Vec::new();
    for (k, &e) in family.effects.iter().enumerate() {
        if e != Effect::Wall {
            continue;
        }
        let Some(evidence) = bumper_evidence(ctx, current, k) else {
            continue;
        };
        let gain = (evidence.costs[1] - evidence.costs[0]) / (floor * floor);
        let gate = GATE_LN_N * (evidence.residual_count.max(2) as f64).ln();
        if debug {
            eprintln!(
                "   bumper at wall effect {k}: {} contact(s), windows cost {:.3} against rigid {:.3} px² (gain {gain:.1}, gate {gate:.1}), start {:?}",
                evidence.contacts.len(),
                evidence.costs[0],
                evidence.costs[1],
                evidence.init
            );
        }
        if gain <= gate {
            continue;
        }
        let proposal = Proposal {
            effect: Effect::Bumper,
            init: evidence.init,
            screen: None,
            score_test: None,
            jolts: Vec::new(),
        };
        let v = ctx.verify_swap(current, k, &[proposal]);
        if debug {
            eprintln!("   swap wall -> bumper: {:?}", v.evidence);
        }
        out.push(v);
    }
    out
}

/// The "where it was seen" text of a bumper `wall` (stiffness and damping) met by a particle
/// of mean mass `mass` at `contacts`: the deepest centres beyond its line and their impact
/// speeds, the slowest and fastest.
pub fn bumper_seen_text(wall: &Wall, mass: f64, contacts: &[Contact]) -> String {
    let depth = |c: &Contact| -c.depth;
    let mut parts = Vec::new();
    let slowest = contacts.iter().min_by(|a, b| a.speed.total_cmp(&b.speed));
    let fastest = contacts.iter().max_by(|a, b| a.speed.total_cmp(&b.speed));
    if let (Some(a), Some(b)) = (slowest, fastest) {
        parts.push(format!(
            "{} contact(s) where the turning point moves with the impact speed: {:.2} px beyond the line at {:.1} px/s, {:.2} px at {:.1} px/s",
            contacts.len(),
            depth(a),
            a.speed,
            depth(b),
            b.speed
        ));
    }
    let time = wall
        .bumper_contact_time(mass)
        .map_or_else(|| "overdamped".to_string(), |t| format!("contact time {t:.4} s"));
    parts.push(format!(
        "a spring bumper S = {:.1} energy/px^2, c = {:.3} mass/s ({time}, restitution {:.3})",
        wall.stiffness,
        wall.damping,
        wall.bumper_restitution(mass)
    ));
    parts.join(": ")
}

/// The bumper of `params` (`[normal_angle, offset, stiffness, damping]`) and the contacts of
/// `family`'s free particles with it, measured against its line.
pub fn bumper_contacts(obs: &Observations, family: &Family, params: &[f64]) -> (Option<Wall>, Vec<Contact>) {
    let Some(wall) = bumper_from_params(params) else {
        return (None, Vec::new());
    };
    let contacts = contacts_on(obs, &family.free, &wall);
    (Some(wall), contacts)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_damping_ratio_gives_back_the_restitution() {
        for e in [0.1, 0.5, 0.8, 0.99] {
            let zeta = damping_ratio(e);
            let back = (-zeta * std::f64::consts::PI / (1.0 - zeta * zeta).sqrt()).exp();
            assert!((back - e).abs() < 1e-12, "{e}: {back}");
        }
        assert!((damping_ratio(1.0)).abs() < 1e-15);
        assert!((damping_ratio(0.0) - 1.0).abs() < 1e-15);
    }
}
