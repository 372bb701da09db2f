//! Constraints: ropes (distance constraints) and rails (motion along a line), enforced by
//! projection after each integration substep.
//!
//! A key design decision made in this module is that a constraint is not a force: a rope
//! written as a stiff spring makes a fit ill-conditioned (issue 22), so the integrator
//! takes an unconstrained substep and then projects, RATTLE-like (Andersen 1983,
//! J. Comput. Phys. 52, 24): the positions are moved back onto the constraint along its
//! direction at the *start* of the substep, weighted by inverse mass (SHAKE's choice,
//! Ryckaert et al. 1977), the velocities take that displacement over `dt` as an impulse,
//! and the velocity component along the constraint at the *end* of the substep is then
//! removed. A fixed particle has infinite mass: it never moves. Several constraints are
//! swept in turn (Gauss-Seidel) until every one holds to [`TOLERANCE`] of its length.

use crate::{ParticleId, ParticleSet, State, Vec2};

/// Largest relative violation `|d - L| / L` a projection leaves (swept up to
/// [`MAX_SWEEPS`] times).
pub const TOLERANCE: f64 = 1e-12;

/// Most Gauss-Seidel sweeps over the constraints per substep.
pub const MAX_SWEEPS: usize = 50;

/// An inextensible rope of length `length` (px) between two particles: their distance never
/// exceeds it; unless `slack`, it never falls below it either (a rigid rod).
#[derive(Clone, Debug, PartialEq)]
pub struct Rope {
    /// The two particles (either may be fixed: a rope to a fixed point).
    pub ends: [ParticleId; 2],
    /// Length `L`, px (> 0).
    pub length: f64,
    /// True if and only if the rope goes slack when the ends come closer than `L`.
    pub slack: bool,
}

/// A rail: particle `particle` moves along the line through `point` (px) with unit
/// `direction`, with Coulomb friction `friction` against the rail's normal impulse.
#[derive(Clone, Debug, PartialEq)]
pub struct Rail {
    /// The particle held on the rail.
    pub particle: ParticleId,
    /// A point of the rail line, px.
    pub point: Vec2,
    /// Unit direction of the line.
    pub direction: Vec2,
    /// Coulomb friction coefficient `mu` (dimensionless, 0 = frictionless): over a substep
    /// the speed along the rail loses at most `mu` times the normal velocity change the rail
    /// imposed, as at a wall ([`crate::Wall::apply_friction`]): a cart pressed on the rail
    /// by `m g_n` slides with deceleration `mu g_n` and sticks while pushed by at most that.
    pub friction: f64,
}

impl Rail {
    /// A rail through `point` along `direction` (normalised here; kept bit for bit when
    /// already of unit length to rounding). Returns `None` for a zero or non-finite direction.
    pub fn new(particle: ParticleId, point: Vec2, direction: Vec2) -> Option<Rail> {
        let n = direction.norm();
        if !(n > 0.0 && n.is_finite()) {
            return None;
        }
        let direction = if (n - 1.0).abs() <= 4.0 * f64::EPSILON {
            direction
        } else {
            direction / n
        };
        Some(Rail {
            particle,
            point,
            direction,
            friction: 0.0,
        })
    }

    /// This rail with Coulomb friction coefficient `mu` (dimensionless).
    pub fn with_friction(self, mu: f64) -> Rail {
        Rail { friction: mu, ..self }
    }

    /// Unit normal of the rail line.
    fn normal(&self) -> Vec2 {
        Vec2::new(-self.direction.y, self.direction.x)
    }
}

/// Inverse mass of particle `k`, 1/mass (0 for a fixed particle).
fn inverse_mass(particles: &ParticleSet, k: usize) -> f64 {
    let p = &particles.particles[k];
    if p.fixed {
        0.0
    } else {
        1.0 / p.mass
    }
}

/// Projects `state` (the end of a substep of `dt` s that started at positions `x_old`, px)
/// onto the ropes and rails, positions then velocities, as the module doc says, then applies
/// the rails' friction. `rails_dv` is a buffer (resized here, so no allocation once sized).
pub fn project(
    particles: &ParticleSet,
    ropes: &[Rope],
    rails: &[Rail],
    x_old: &[Vec2],
    state: &mut State,
    dt: f64,
    rails_dv: &mut Vec<[f64; 2]>,
) {
    // Each rail's normal velocity change over the substep and the time since the particle
    // crossed the line, s (for its friction).
    rails_dv.clear();
    rails_dv.resize(rails.len(), [0.0, f64::NAN]);
    for _ in 0..MAX_SWEEPS {
        let mut worst = 0.0f64;
        for rope in ropes {
            worst = worst.max(project_rope_position(particles, rope, x_old, state, dt));
        }
        for (rail, dv) in rails.iter().zip(rails_dv.iter_mut()) {
            project_rail_position(particles, rail, state, dt, dv);
        }
        if worst <= TOLERANCE {
            break;
        }
    }
    for _ in 0..MAX_SWEEPS {
        let mut worst = 0.0f64;
        for rope in ropes {
            worst = worst.max(project_rope_velocity(particles, rope, state));
        }
        for (rail, dv) in rails.iter().zip(rails_dv.iter_mut()) {
            let k = rail.particle.index();
            if !particles.particles[k].fixed {
                let n = rail.normal();
                let v = &mut state.velocities[k];
                let vn = v.dot(&n);
                *v -= n * vn;
                dv[0] -= vn;
            }
        }
        if worst <= TOLERANCE {
            break;
        }
    }
    for (rail, &[dv, tau]) in rails.iter().zip(rails_dv.iter()) {
        let tau = if tau.is_nan() { 0.5 * dt } else { tau };
        apply_rail_friction(particles, rail, state, dv.abs(), tau);
    }
}

/// Moves the positions of `state` onto the ropes and rails, velocities untouched: the start
/// of a substep that violates a constraint (a scene's frame 0 a little off, a fitted start)
/// is settled first, so that the projection after the substep takes only the substep's own
/// drift as an impulse (a violation of 0.05 px would otherwise become 100 px/s at 2000
/// substeps a second). Returns true if and only if it moved a position.
pub fn settle(particles: &ParticleSet, ropes: &[Rope], rails: &[Rail], state: &mut State) -> bool {
    let mut moved = false;
    for _ in 0..MAX_SWEEPS {
        let mut worst = 0.0f64;
        for rope in ropes {
            let [i, j] = [rope.ends[0].index(), rope.ends[1].index()];
            let (wi, wj) = (inverse_mass(particles, i), inverse_mass(particles, j));
            let d = state.positions[j] - state.positions[i];
            let dist = d.norm();
            let violation = (dist - rope.length) / rope.length;
            if wi + wj == 0.0
                || dist == 0.0
                || (rope.slack && violation <= 0.0)
                || violation.abs() <= TOLERANCE
            {
                continue;
            }
            let shift = d * ((rope.length - dist) / (dist * (wi + wj)));
            state.positions[i] -= shift * wi;
            state.positions[j] += shift * wj;
            worst = worst.max(violation.abs());
            moved = true;
        }
        for rail in rails {
            let k = rail.particle.index();
            let n = rail.normal();
            let off = (state.positions[k] - rail.point).dot(&n);
            if !particles.particles[k].fixed && off != 0.0 {
                state.positions[k] -= n * off;
                moved = true;
            }
        }
        if worst <= TOLERANCE {
            break;
        }
    }
    moved
}

/// Coulomb friction along a rail (the wall's law, `physics::coulomb_friction`, across the
/// rail's normal): the speed along it loses `min(mu dv_n, |v_t|)`, `dv_n`
/// (px/s) the normal velocity change the rail imposed over the substep; the position moves
/// back by the change times `tau` (s), the time since the particle left the line, as at a
/// wall's resting contact ([`crate::Wall::apply_friction`]: `dt / 2` for Verlet, `dt` for
/// semi-implicit Euler), so that a particle held by static friction does not creep.
fn apply_rail_friction(particles: &ParticleSet, rail: &Rail, state: &mut State, dv_n: f64, tau: f64) {
    let k = rail.particle.index();
    if rail.friction == 0.0 || particles.particles[k].fixed {
        return;
    }
    let (x, v) = (&mut state.positions[k], &mut state.velocities[k]);
    crate::physics::coulomb_friction(rail.normal(), rail.friction, x, v, dv_n, tau);
}

/// Moves a rope's ends so that their distance is `L` (or at most `L` when slack) along its
/// direction at the start of the substep; returns the relative violation found.
fn project_rope_position(
    particles: &ParticleSet,
    rope: &Rope,
    x_old: &[Vec2],
    state: &mut State,
    dt: f64,
) -> f64 {
    let [i, j] = [rope.ends[0].index(), rope.ends[1].index()];
    let (wi, wj) = (inverse_mass(particles, i), inverse_mass(particles, j));
    let w = wi + wj;
    let d = state.positions[j] - state.positions[i];
    let dist = d.norm();
    let violation = (dist - rope.length) / rope.length;
    if w == 0.0 || (rope.slack && violation <= 0.0) || violation.abs() <= TOLERANCE {
        return 0.0;
    }
    // Solve |d + sigma u0| = L for the root nearest zero, u0 the direction at the start.
    let r0 = x_old[j] - x_old[i];
    let u0 = if r0.norm() > 0.0 { r0 / r0.norm() } else { d / dist };
    let b = d.dot(&u0);
    let disc = b * b - dist * dist + rope.length * rope.length;
    let (u, sigma) = if disc >= 0.0 {
        (
            u0,
            if b >= 0.0 {
                -b + disc.sqrt()
            } else {
                -b - disc.sqrt()
            },
        )
    } else {
        // The substep turned the rope too far for its old direction: project along the new.
        (d / dist, rope.length - dist)
    };
    let (di, dj) = (u * (-sigma * wi / w), u * (sigma * wj / w));
    state.positions[i] += di;
    state.positions[j] += dj;
    state.velocities[i] += di / dt;
    state.velocities[j] += dj / dt;
    violation.abs()
}

/// Removes the rope's stretching rate (taut ropes and rods; a slack rope only while its
/// ends separate at full length); returns the relative rate removed, 1/s per px/s scale.
fn project_rope_velocity(particles: &ParticleSet, rope: &Rope, state: &mut State) -> f64 {
    let [i, j] = [rope.ends[0].index(), rope.ends[1].index()];
    let (wi, wj) = (inverse_mass(particles, i), inverse_mass(particles, j));
    let w = wi + wj;
    let d = state.positions[j] - state.positions[i];
    let dist = d.norm();
    if w == 0.0 || dist == 0.0 || (rope.slack && dist < rope.length * (1.0 - 1e-9)) {
        return 0.0;
    }
    let u = d / dist;
    let rate = (state.velocities[j] - state.velocities[i]).dot(&u);
    if rope.slack && rate <= 0.0 {
        return 0.0;
    }
    state.velocities[i] += u * (rate * wi / w);
    state.velocities[j] -= u * (rate * wj / w);
    let scale = state.velocities[i].norm() + state.velocities[j].norm();
    if scale > 0.0 {
        rate.abs() / scale
    } else {
        0.0
    }
}

/// Puts a rail's particle back on its line, the displacement over `dt` taken as an impulse;
/// adds that impulse's normal velocity change (px/s, signed along the rail's normal) to
/// `dv[0]` and, the first time the particle is found off the line, the time since it left
/// it (`off / v_n`, clamped to `[0, dt]`) to `dv[1]`.
fn project_rail_position(
    particles: &ParticleSet,
    rail: &Rail,
    state: &mut State,
    dt: f64,
    dv: &mut [f64; 2],
) {
    let k = rail.particle.index();
    if particles.particles[k].fixed {
        return;
    }
    let n = rail.normal();
    let off = (state.positions[k] - rail.point).dot(&n);
    let vn = state.velocities[k].dot(&n);
    if dv[1].is_nan() && off != 0.0 && vn * off > 0.0 {
        dv[1] = (off / vn).clamp(0.0, dt);
    }
    state.positions[k] -= n * off;
    state.velocities[k] -= n * (off / dt);
    dv[0] -= off / dt;
}
