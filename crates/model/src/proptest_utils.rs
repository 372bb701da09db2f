//! Strategies and finite-difference checks shared by the property tests of the force laws.
//!
//! Every conservative force is checked against central finite differences of its
//! [`Potential::energy`]. The comparison allows, per particle, a relative error of
//! [`GRADIENT_RELATIVE_TOLERANCE`] plus a floor made of the two errors finite differences
//! cannot avoid: truncation (`h^2 |E'''| / 6`, bounded from the bond's geometry) and rounding
//! (the energy is computed from coordinates of size `X` to a relative `eps`, so a difference
//! over `2 h` carries about `eps (|E| + X |grad E|) / h`).

use proptest::prelude::*;
use proptest::test_runner::TestCaseError;

use crate::{Model, ParticleId, Potential, Spring, Torsion, Vec2};

/// Relative agreement demanded between the analytic gradient and finite differences.
pub const GRADIENT_RELATIVE_TOLERANCE: f64 = 1e-6;

/// Safety factor on the rounding floor (an upper bound of a sum of a few roundings).
const ROUNDING_FACTOR: f64 = 4.0;

/// Central finite-difference gradient of `pot` at `x` with step `h` (px). The step actually
/// taken, `(x + h) - x`, is used in the quotient, so the representation of `x + h` costs
/// nothing.
pub fn finite_difference_gradient(pot: &dyn Potential, x: &[Vec2], h: f64) -> Vec<Vec2> {
    let mut y = x.to_vec();
    let mut out = vec![Vec2::zeros(); x.len()];
    for p in 0..x.len() {
        for c in 0..2 {
            let x0 = x[p][c];
            let up = x0 + h;
            let down = x0 - h;
            y[p][c] = up;
            let e_up = pot.energy(&y);
            y[p][c] = down;
            let e_down = pot.energy(&y);
            y[p][c] = x0;
            out[p][c] = (e_up - e_down) / (up - down);
        }
    }
    out
}

/// The analytic gradient of `pot` at `x`.
pub fn analytic_gradient(pot: &dyn Potential, x: &[Vec2]) -> Vec<Vec2> {
    let mut g = vec![Vec2::zeros(); x.len()];
    pot.add_gradient(x, &mut g);
    g
}

/// Checks the analytic gradient against finite differences with step `h`; `floor[p]` is the
/// absolute error (energy per px) finite differences may make on particle `p`. Returns the
/// worst error relative to the gradient's size (for reporting).
pub fn check_gradient(pot: &dyn Potential, x: &[Vec2], h: f64, floor: &[f64]) -> Result<f64, TestCaseError> {
    let g = analytic_gradient(pot, x);
    let fd = finite_difference_gradient(pot, x, h);
    let mut worst: f64 = 0.0;
    for p in 0..x.len() {
        let err = (g[p] - fd[p]).norm();
        let size = g[p].norm().max(fd[p].norm());
        let tol = GRADIENT_RELATIVE_TOLERANCE * size + floor[p];
        prop_assert!(
            err <= tol,
            "particle {p}: analytic {:?} vs finite differences {:?}: error {err:e} > tolerance {tol:e} \
             (floor {:e}, h {h:e})",
            g[p],
            fd[p],
            floor[p]
        );
        if size > 0.0 {
            worst = worst.max(err / size);
        }
    }
    Ok(worst)
}

/// Largest coordinate magnitude in `x`, px (sets the rounding error of positions).
pub fn coordinate_scale(x: &[Vec2]) -> f64 {
    x.iter().map(|v| v.x.abs().max(v.y.abs())).fold(1.0, f64::max)
}

/// Finite-difference error floor of a spring at each of its two ends, for step `h` and
/// coordinates up to `scale` px.
pub fn spring_floor(s: &Spring, x: &[Vec2], h: f64, scale: f64) -> f64 {
    let d = s.geometry(x).length;
    let ext = (d - s.rest_length).abs();
    let k = s.stiffness.abs();
    // E''' along a coordinate is at most 2 S (3 / d + |d - L| / d^2).
    let truncation = h * h / 6.0 * 2.0 * k * (3.0 / d + ext / (d * d));
    let rounding = ROUNDING_FACTOR * f64::EPSILON * (k * ext * ext + scale * 2.0 * k * (ext + d)) / h;
    2.0 * (truncation + rounding)
}

/// Finite-difference error floor of a torsion at each of its three particles, for step `h`
/// and coordinates up to `scale` px.
///
/// Near a straight or folded angle the gradient `2 T (c - M) dc/dx` is small because `dc/dx`
/// is (it goes as the sine of the angle): the floor follows it down, so such angles are
/// checked as tightly as any other.
pub fn torsion_floor(t: &Torsion, x: &[Vec2], h: f64, scale: f64) -> f64 {
    let [i, j, k] = t.particles().map(|p| x[p.index()]);
    let (a, b) = (j - i, k - i);
    let ell = a.norm().min(b.norm());
    // Cosine and sine of the angle, measured here rather than by the code under test.
    let cos = a.dot(&b) / (a.norm() * b.norm());
    let sin = (a.x * b.y - a.y * b.x).abs() / (a.norm() * b.norm());
    let dev = (cos - t.rest_cos).abs();
    let stiff = t.stiffness.abs();
    // Along a coordinate, with phi the angle: |c'| <= 2 sin(phi) / l (plus its change over the
    // stencil, h / l^2), |c''| <= 8 / l^2, |c'''| <= 48 / l^3, and
    // E''' = 2 T ((c - M) c''' + 3 c' c'').
    let sin_eff = sin + h / ell;
    let third = 2.0 * stiff * (48.0 * dev + 3.0 * 2.0 * sin_eff * 8.0) / ell.powi(3);
    let truncation = h * h / 6.0 * third;
    // The cosine rounds by a few eps, plus the coordinates' rounding turned by the angle.
    let dc = 4.0 * f64::EPSILON * (1.0 + scale * sin_eff / ell);
    let de = 2.0 * stiff * (dev + dc) * dc + f64::EPSILON * stiff * dev * dev;
    let rounding = ROUNDING_FACTOR * de / h;
    2.0 * (truncation + rounding)
}

/// Finite-difference error floors of a whole model (bonds plus the uniform field) per particle.
pub fn model_floor(model: &Model, x: &[Vec2], h: f64) -> Vec<f64> {
    let scale = coordinate_scale(x);
    let mut floor = vec![0.0; x.len()];
    for s in &model.springs {
        let f = spring_floor(s, x, h, scale);
        for p in s.ends {
            floor[p.index()] += f;
        }
    }
    for t in &model.torsions {
        let f = torsion_floor(t, x, h, scale);
        for p in t.particles() {
            floor[p.index()] += f;
        }
    }
    // The total energy is a sum: its rounding, of the order of eps times the sum of the
    // terms' sizes, reaches every particle's difference quotient, bonded to it or not.
    let field: f64 = model
        .particles
        .particles
        .iter()
        .map(|p| p.mass * model.physics.gravity.norm() * scale)
        .sum();
    let bonds: f64 = model.springs.iter().map(|s| s.energy(x).abs()).sum::<f64>()
        + model.torsions.iter().map(|t| t.energy(x).abs()).sum::<f64>();
    for f in &mut floor {
        *f += ROUNDING_FACTOR * f64::EPSILON * (field + bonds) / h;
    }
    floor
}

/// A unit vector at a uniformly drawn angle.
pub fn unit_vector() -> impl Strategy<Value = Vec2> {
    (0.0..std::f64::consts::TAU).prop_map(|a: f64| Vec2::new(a.cos(), a.sin()))
}

/// A point anywhere a recording could put it, px.
pub fn point() -> impl Strategy<Value = Vec2> {
    (-1000.0..1000.0, -1000.0..1000.0).prop_map(|(x, y)| Vec2::new(x, y))
}

/// A value drawn log-uniformly in `[lo, hi]` (both positive).
pub fn log_uniform(lo: f64, hi: f64) -> impl Strategy<Value = f64> {
    (lo.ln()..hi.ln()).prop_map(f64::exp)
}

/// A spring between particles 0 and 1 of length `length`, rest length within a factor 3 of
/// it (or zero), and positions for it.
pub fn spring_with_length(length: impl Strategy<Value = f64>) -> impl Strategy<Value = (Spring, Vec<Vec2>)> {
    (
        point(),
        unit_vector(),
        length,
        prop_oneof![Just(0.0), log_uniform(1.0 / 3.0, 3.0)],
        log_uniform(1e-3, 1e4),
    )
        .prop_map(|(xi, u, d, rest_factor, stiffness)| {
            let spring = Spring::new(ParticleId(0), ParticleId(1), rest_factor * d, stiffness);
            (spring, vec![xi, xi + u * d])
        })
}

/// The shape of the angle a torsion strategy draws.
#[derive(Clone, Copy, Debug)]
pub enum AngleKind {
    /// Any angle.
    Any,
    /// Within about `1e-6` of straight in cosine (`c` near -1), exactly straight included.
    NearStraight,
    /// Within about `1e-6` of folded in cosine (`c` near +1), exactly folded included.
    NearFolded,
}

/// A torsion centred on particle 0 between 1 and 2 with arms of 1 to 1000 px, at an angle of
/// the given kind, and positions for it. The rest cosine is anywhere in [-1, 1], the ends
/// included.
pub fn torsion_at(kind: AngleKind) -> impl Strategy<Value = (Torsion, Vec<Vec2>)> {
    // Half-angle offsets with 1 - cos(offset) up to 1e-6: |offset| <= sqrt(2e-6).
    let small = (2e-6f64).sqrt();
    let angle = match kind {
        AngleKind::Any => (0.0..std::f64::consts::PI).boxed(),
        AngleKind::NearStraight => prop_oneof![
            Just(std::f64::consts::PI),
            (-small..small).prop_map(|d| std::f64::consts::PI - d)
        ]
        .boxed(),
        AngleKind::NearFolded => prop_oneof![Just(0.0), (-small..small)].boxed(),
    };
    (
        point(),
        unit_vector(),
        angle,
        log_uniform(1.0, 1000.0),
        log_uniform(1.0, 1000.0),
        prop_oneof![Just(-1.0), Just(1.0), -1.0..=1.0],
        log_uniform(1e-2, 1e6),
    )
        .prop_map(|(xi, u, angle, dj, dk, rest_cos, stiffness)| {
            let (s, c) = angle.sin_cos();
            let uk = Vec2::new(u.x * c - u.y * s, u.x * s + u.y * c);
            let t = Torsion::new(ParticleId(0), ParticleId(1), ParticleId(2), rest_cos, stiffness);
            (t, vec![xi, xi + u * dj, xi + uk * dk])
        })
}

/// A random model of 3 to 8 particles (some fixed) with random springs, torsions and
/// gravity, and a configuration whose particles are all at least 2 px apart.
pub fn model_and_positions() -> impl Strategy<Value = (Model, Vec<Vec2>)> {
    (3usize..=8)
        .prop_flat_map(|n| {
            (
                prop::collection::vec((point(), log_uniform(0.1, 10.0), prop::bool::weighted(0.2)), n),
                prop::collection::vec(
                    (any::<u32>(), any::<u32>(), 0.0..2.0f64, log_uniform(1e-2, 1e3)),
                    0..12,
                ),
                prop::collection::vec(
                    (
                        any::<u32>(),
                        any::<u32>(),
                        any::<u32>(),
                        -1.0..=1.0f64,
                        log_uniform(1.0, 1e5),
                    ),
                    0..12,
                ),
                (-2000.0..2000.0f64, -2000.0..2000.0f64),
            )
        })
        .prop_filter_map("particles closer than 2 px", |(parts, springs, torsions, g)| {
            let n = parts.len();
            let x: Vec<Vec2> = parts.iter().map(|p| p.0 * 0.5).collect();
            for a in 0..n {
                for b in a + 1..n {
                    if (x[a] - x[b]).norm() < 2.0 {
                        return None;
                    }
                }
            }
            let mut model = Model::default();
            for p in &parts {
                model.add_particle(p.1, p.2);
            }
            let pick2 = |a: u32, b: u32| {
                let i = a as usize % n;
                let j = (i + 1 + b as usize % (n - 1)) % n;
                (i, j)
            };
            for (a, b, rest_factor, stiffness) in springs {
                let (i, j) = pick2(a, b);
                let d = (x[j] - x[i]).norm();
                model.springs.push(Spring::new(
                    ParticleId(i as u32),
                    ParticleId(j as u32),
                    rest_factor * d,
                    stiffness,
                ));
            }
            for (a, b, c, rest_cos, stiffness) in torsions {
                let (i, j) = pick2(a, b);
                let others: Vec<usize> = (0..n).filter(|&q| q != i && q != j).collect();
                let k = others[c as usize % others.len()];
                model.torsions.push(Torsion::new(
                    ParticleId(i as u32),
                    ParticleId(j as u32),
                    ParticleId(k as u32),
                    rest_cos,
                    stiffness,
                ));
            }
            model.physics.gravity = Vec2::new(g.0, g.1);
            Some((model, x))
        })
}

/// Smallest distance between two particles of `x`, px.
pub fn min_separation(x: &[Vec2]) -> f64 {
    let mut m = f64::INFINITY;
    for a in 0..x.len() {
        for b in a + 1..x.len() {
            m = m.min((x[a] - x[b]).norm());
        }
    }
    m
}
