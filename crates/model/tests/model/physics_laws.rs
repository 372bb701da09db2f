//! Each piece of physics against its closed-form answer.

use physfit_model::{
    dashpot_force_on_i, simulate, step, IntegratorKind, Model, ParticleId, Physics, Spring, SpringGeometry,
    State, StepScratch, Torsion, Vec2, Wall,
};
use proptest::prelude::*;

use crate::common::{paper8, params, single, FPS};

#[test]
fn free_fall_follows_x0_plus_v0_t_plus_half_g_t2() {
    let mut model = single(2.0);
    let g = Vec2::new(5.0, 981.0);
    model.physics.gravity = g;
    let (x0, v0) = (Vec2::new(100.0, 50.0), Vec2::new(30.0, -200.0));
    let initial = State::new(vec![x0], vec![v0]);
    let frames = 200;
    let verlet = simulate(&model, &initial, &params(IntegratorKind::Verlet), frames);
    let euler = simulate(&model, &initial, &params(IntegratorKind::Euler), frames);
    let dt = params(IntegratorKind::Euler).dt();
    for k in 0..frames {
        let t = k as f64 / FPS;
        let exact = x0 + v0 * t + g * (0.5 * t * t);
        // Velocity Verlet is exact under a constant acceleration.
        assert!((verlet.frame(k)[0] - exact).norm() < 1e-9, "frame {k}");
        assert!((verlet.velocities[k] - (v0 + g * t)).norm() < 1e-9);
        // Semi-implicit Euler is off by exactly g t dt / 2 (it uses the end-of-step velocity).
        let euler_exact = exact + g * (0.5 * t * dt);
        assert!((euler.frame(k)[0] - euler_exact).norm() < 1e-9, "Euler frame {k}");
    }
}

#[test]
fn linear_drag_decays_velocity_exponentially() {
    let mut model = single(3.0);
    let drag = 1.5;
    model.physics.drag = drag;
    let (x0, v0) = (Vec2::new(10.0, 20.0), Vec2::new(400.0, -150.0));
    let initial = State::new(vec![x0], vec![v0]);
    for kind in [IntegratorKind::Verlet, IntegratorKind::Euler] {
        let rec = simulate(&model, &initial, &params(kind), 300);
        // Verlet is second order, Euler first: dt = 0.5 ms, drag dt = 7.5e-4.
        let tol = if kind == IntegratorKind::Verlet {
            1e-6
        } else {
            1e-3
        };
        for k in [1, 50, 299] {
            let t = k as f64 / FPS;
            let decay = (-drag * t).exp();
            let v = rec.velocities[k];
            assert!(
                (v - v0 * decay).norm() <= tol * v0.norm(),
                "{kind:?} frame {k}: v {v:?}"
            );
            let x = x0 + v0 * ((1.0 - decay) / drag);
            assert!(
                (rec.frame(k)[0] - x).norm() <= tol * v0.norm() / drag,
                "{kind:?} frame {k}"
            );
        }
    }
}

#[test]
fn quadratic_drag_follows_its_closed_form() {
    // Along a fixed direction: v' = -k v^2, so v = v0 / (1 + k v0 t) and
    // x = x0 + ln(1 + k v0 t) / k.
    let mut model = single(0.5);
    let k = 0.01;
    model.physics.quadratic_drag = k;
    let dir = Vec2::new(3.0, 4.0) / 5.0;
    let (x0, speed) = (Vec2::new(5.0, 5.0), 500.0);
    let initial = State::new(vec![x0], vec![dir * speed]);
    for kind in [IntegratorKind::Verlet, IntegratorKind::Euler] {
        let rec = simulate(&model, &initial, &params(kind), 200);
        // k v0 = 5 /s is a fast decay: Verlet's O(dt^2) error is then a few 1e-6.
        let tol = if kind == IntegratorKind::Verlet {
            1e-5
        } else {
            3e-3
        };
        for f in [1, 20, 199] {
            let t = f as f64 / FPS;
            let v = speed / (1.0 + k * speed * t);
            assert!(
                (rec.velocities[f] - dir * v).norm() <= tol * v,
                "{kind:?} frame {f}: {:?} vs {v}",
                rec.velocities[f].norm()
            );
            let x = x0 + dir * ((1.0 + k * speed * t).ln() / k);
            assert!(
                (rec.frame(f)[0] - x).norm() <= tol * (x - x0).norm(),
                "{kind:?} frame {f}: error {:e} of {:e}",
                (rec.frame(f)[0] - x).norm(),
                (x - x0).norm()
            );
        }
    }
}

/// Two particles joined by a dashpot-only spring (zero stiffness) with coefficient `c`.
fn dashpot_pair(c: f64) -> Model {
    let mut m = Model::default();
    let a = m.add_particle(1.0, false);
    let b = m.add_particle(2.0, false);
    let mut s = Spring::new(a, b, 10.0, 0.0);
    s.damping = Some(c);
    m.springs.push(s);
    m
}

#[test]
fn dashpot_force_is_c_times_the_stretching_rate_along_the_bond() {
    let c = 3.0;
    let model = dashpot_pair(c);
    let x = vec![Vec2::new(1.0, 2.0), Vec2::new(4.0, 6.0)];
    let v = vec![Vec2::new(-2.0, 1.0), Vec2::new(5.0, 3.0)];
    let mut f = vec![Vec2::zeros(); 2];
    model.forces(&State::new(x.clone(), v.clone()), &mut f);
    // u = (3, 4) / 5, (v_j - v_i) . u = (7 * 3 + 2 * 4) / 5 = 5.8: F_i = 3 * 5.8 * u.
    let u = Vec2::new(0.6, 0.8);
    let expected = u * (c * 5.8);
    assert!((f[0] - expected).norm() < 1e-12, "{:?}", f[0]);
    assert!((f[1] + expected).norm() < 1e-12);
    let direct = dashpot_force_on_i(SpringGeometry::new(x[0], x[1]), v[1] - v[0], c);
    assert!((direct - expected).norm() < 1e-12);
    // Sliding sideways (perpendicular to the bond) is not damped.
    let side = vec![Vec2::zeros(), Vec2::new(-4.0, 3.0)];
    model.forces(&State::new(x, side), &mut f);
    assert!(f[0].norm() < 1e-12 && f[1].norm() < 1e-12);
}

/// Relative extension `r(t) = d(t) - L` of a damped two-body oscillator released at rest
/// with extension `a`: reduced mass mu, `mu r'' = -2 S r - c r'`.
fn damped_extension(a: f64, stiffness: f64, c: f64, mu: f64, t: f64) -> f64 {
    let w0 = (2.0 * stiffness / mu).sqrt();
    let gamma = c / (2.0 * mu);
    let wd = (w0 * w0 - gamma * gamma).sqrt();
    a * (-gamma * t).exp() * ((wd * t).cos() + gamma / wd * (wd * t).sin())
}

/// Extension of a 1 + 2 mass spring (S = 50, L = 40) released 8 px stretched.
fn simulated_extension(model: &Model, kind: IntegratorKind, frames: usize) -> Vec<f64> {
    let initial = State::at_rest(vec![Vec2::new(100.0, 100.0), Vec2::new(148.0, 100.0)]);
    let rec = simulate(model, &initial, &params(kind), frames);
    (0..frames)
        .map(|k| (rec.frame(k)[1] - rec.frame(k)[0]).norm() - 40.0)
        .collect()
}

fn oscillator(global: f64, own: Option<f64>) -> Model {
    let mut m = dashpot_pair(0.0);
    m.springs[0].stiffness = 50.0;
    m.springs[0].rest_length = 40.0;
    m.springs[0].damping = own;
    m.physics.spring_damping = global;
    m
}

#[test]
fn damped_two_body_oscillator_matches_the_analytic_frequency_and_decay() {
    let mu = 1.0 * 2.0 / 3.0;
    let c = 1.2;
    let model = oscillator(c, None);
    let ext = simulated_extension(&model, IntegratorKind::Verlet, 300);
    for (k, r) in ext.iter().enumerate() {
        let exact = damped_extension(8.0, 50.0, c, mu, k as f64 / FPS);
        assert!((r - exact).abs() < 2e-3, "frame {k}: extension {r} vs {exact}");
    }
    // And the undamped oscillator does not decay: the dashpot is what decays it.
    let undamped = simulated_extension(&oscillator(0.0, None), IntegratorKind::Verlet, 300);
    let peak = |e: &[f64]| e[200..].iter().fold(0.0f64, |m, r| m.max(r.abs()));
    assert!(
        peak(&undamped) > 7.9 && peak(&ext) < 0.6 * 8.0,
        "{} {}",
        peak(&undamped),
        peak(&ext)
    );
}

#[test]
fn per_spring_damping_overrides_the_global_value() {
    let mu = 2.0 / 3.0;
    for (global, own, effective) in [
        (5.0, Some(0.6), 0.6),
        (0.0, Some(1.0), 1.0),
        (3.0, Some(0.0), 0.0),
    ] {
        for kind in [IntegratorKind::Verlet, IntegratorKind::Euler] {
            let ext = simulated_extension(&oscillator(global, own), kind, 200);
            let tol = if kind == IntegratorKind::Verlet { 2e-3 } else { 0.1 };
            for (k, r) in ext.iter().enumerate() {
                let exact = damped_extension(8.0, 50.0, effective, mu, k as f64 / FPS);
                assert!(
                    (r - exact).abs() < tol,
                    "{kind:?} global {global} own {own:?}: frame {k}: {r} vs {exact} (c = {effective})"
                );
            }
        }
    }
}

/// A ball dropped from `h` px above a floor at y = 400 (y down, so the normal is (0, -1))
/// under gravity g, with horizontal speed `vx`. Returns every substep's state.
fn drop_ball(restitution: f64, h: f64, g: f64, vx: f64, kind: IntegratorKind, substeps: usize) -> Vec<State> {
    let mut model = single(1.0);
    model.physics.gravity = Vec2::new(0.0, g);
    model
        .physics
        .walls
        .push(Wall::new(Vec2::new(0.0, 400.0), Vec2::new(0.0, -1.0), restitution).unwrap());
    let mut state = State::new(vec![Vec2::new(50.0, 400.0 - h)], vec![Vec2::new(vx, 0.0)]);
    let dt = params(kind).dt();
    let mut scratch = StepScratch::default();
    let mut out = vec![state.clone()];
    for _ in 0..substeps {
        step(&model, kind, dt, &mut state, &mut scratch);
        out.push(state.clone());
    }
    out
}

#[test]
fn a_dropped_ball_rebounds_with_the_restitution_and_keeps_its_tangential_velocity() {
    let (h, g, vx): (f64, f64, f64) = (100.0, 1000.0, 37.0);
    let t_hit = (2.0 * h / g).sqrt();
    let v_hit = (2.0 * g * h).sqrt();
    for kind in [IntegratorKind::Verlet, IntegratorKind::Euler] {
        for e in [1.0, 0.7, 0.3] {
            let dt = params(kind).dt();
            // Up to just before the second impact.
            let t_end = t_hit + 1.9 * e * v_hit / g;
            let states = drop_ball(e, h, g, vx, kind, (t_end / dt) as usize);
            for (n, s) in states.iter().enumerate() {
                let (x, v) = (s.positions[0], s.velocities[0]);
                assert!(
                    x.y <= 400.0,
                    "{kind:?} e {e}: substep {n} ends below the floor at y {}",
                    x.y
                );
                assert!((v.x - vx).abs() < 1e-12, "tangential velocity changed to {}", v.x);
                let t = n as f64 * dt;
                if t > t_hit + 2.0 * dt {
                    // After the bounce: rising at e v_hit, decelerated by g.
                    let exact = -e * v_hit + g * (t - t_hit);
                    // (The plain mirror law, blind to the acceleration during the
                    // substep, was off by up to (1 + e) g dt: 2.2e-3 v_hit here.)
                    let tol = if kind == IntegratorKind::Verlet {
                        1e-4
                    } else {
                        5e-3
                    };
                    assert!(
                        (v.y - exact).abs() < tol * v_hit,
                        "{kind:?} e {e} t {t}: vy {} vs {exact}",
                        v.y
                    );
                }
            }
            // The rebound's apex: e^2 h above the floor (the last states are past it).
            let height = 400.0
                - states
                    .iter()
                    .skip_while(|s| s.velocities[0].y >= 0.0)
                    .fold(400.0f64, |m, s| m.min(s.positions[0].y));
            // Measured: Verlet within 1e-6 relative (the mirror law: 2.6e-3 to 5.5e-3),
            // Euler within 5e-3 (its own first-order error).
            let tol = if kind == IntegratorKind::Verlet {
                1e-5
            } else {
                5e-3
            };
            assert!(
                (height - e * e * h).abs() < tol * h,
                "{kind:?} e {e}: apex {height} vs {}",
                e * e * h
            );
        }
    }
}

#[test]
fn an_inelastic_ball_comes_to_rest_on_the_floor_never_below_it() {
    let states = drop_ball(0.0, 50.0, 1000.0, 0.0, IntegratorKind::Verlet, 4000);
    assert!(states.iter().all(|s| s.positions[0].y <= 400.0));
    let last = &states[states.len() - 1];
    assert!(
        (last.positions[0].y - 400.0).abs() < 1e-3 && last.velocities[0].norm() < 1.0,
        "{last:?}"
    );
}

#[test]
fn a_tilted_wall_reflects_the_normal_velocity_and_keeps_the_tangential() {
    // A wall through (200, 200) facing up-left; a particle coasting into it (no forces), so
    // the motion is exact and the bounce law can be checked to rounding.
    let normal = Vec2::new(-1.0, -2.0).normalize();
    let tangent = Vec2::new(-normal.y, normal.x);
    let e = 0.6;
    let mut model = single(1.0);
    model
        .physics
        .walls
        .push(Wall::new(Vec2::new(200.0, 200.0), Vec2::new(-1.0, -2.0), e).unwrap());
    let v0 = normal * -80.0 + tangent * 25.0;
    // Start 20.3 px from the wall: the impact falls inside a substep.
    let x0 = Vec2::new(200.0, 200.0) + normal * 20.3;
    let t_hit = 20.3 / 80.0;
    for kind in [IntegratorKind::Verlet, IntegratorKind::Euler] {
        let rec = simulate(&model, &State::new(vec![x0], vec![v0]), &params(kind), 60);
        for k in 0..60 {
            let t = k as f64 / FPS;
            let (x, v) = (rec.frame(k)[0], rec.velocities[k]);
            let (vn, vt) = (v.dot(&normal), v.dot(&tangent));
            assert!((vt - 25.0).abs() < 1e-9, "{kind:?} frame {k}: tangential {vt}");
            let s = model.physics.walls[0].signed_distance(x);
            assert!(s >= 0.0);
            if t > t_hit {
                assert!((vn - 80.0 * e).abs() < 1e-9, "{kind:?} frame {k}: normal {vn}");
                assert!(
                    (s - 80.0 * e * (t - t_hit)).abs() < 1e-9,
                    "{kind:?} frame {k}: distance {s}"
                );
            } else {
                assert!((vn + 80.0).abs() < 1e-9 && (s - 80.0 * (t_hit - t)).abs() < 1e-9);
            }
        }
    }
}

#[test]
fn fixed_particles_never_move() {
    let (mut model, mut initial) = paper8();
    model.physics.gravity = Vec2::new(0.0, 500.0);
    model.physics.drag = 0.3;
    model.physics.spring_damping = 1.0;
    model.particles.particles[0].fixed = true;
    model.particles.particles[5].fixed = true;
    // Even when handed a velocity (an observed state, say).
    initial.velocities[0] = Vec2::new(40.0, -30.0);
    for kind in [IntegratorKind::Verlet, IntegratorKind::Euler] {
        let rec = simulate(&model, &initial, &params(kind), 200);
        for k in 0..200 {
            for p in [0, 5] {
                let x = rec.frame(k)[p];
                let x0 = initial.positions[p];
                assert_eq!(
                    [x.x.to_bits(), x.y.to_bits()],
                    [x0.x.to_bits(), x0.y.to_bits()],
                    "{kind:?} frame {k}"
                );
            }
        }
        assert!(
            rec.velocities[rec.velocities.len() - 8].norm() == 0.0,
            "a fixed particle ends with no velocity"
        );
    }
}

/// Which extra physics a random combination turns on.
#[derive(Clone, Debug)]
struct Combination {
    gravity: Option<(f64, f64)>,
    drag: Option<f64>,
    quadratic_drag: Option<f64>,
    spring_damping: Option<f64>,
    own_damping: Option<f64>,
    walls: Option<f64>,
    fixed: Option<usize>,
    euler: bool,
}

fn combination() -> impl Strategy<Value = Combination> {
    (
        prop::option::of((-500.0..500.0, -1500.0..1500.0)),
        prop::option::of(0.0..5.0),
        prop::option::of(0.0..0.01),
        prop::option::of(0.0..3.0),
        prop::option::of(0.0..3.0),
        prop::option::of(0.0..=1.0),
        prop::option::of(0usize..8),
        any::<bool>(),
    )
        .prop_map(
            |(gravity, drag, quadratic_drag, spring_damping, own_damping, walls, fixed, euler)| Combination {
                gravity,
                drag,
                quadratic_drag,
                spring_damping,
                own_damping,
                walls,
                fixed,
                euler,
            },
        )
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]
    #[test]
    fn any_combination_of_physics_runs_finite_and_inside_the_walls(c in combination()) {
        let (mut model, initial) = paper8();
        let mut physics = Physics::default();
        if let Some((gx, gy)) = c.gravity { physics.gravity = Vec2::new(gx, gy); }
        physics.drag = c.drag.unwrap_or(0.0);
        physics.quadratic_drag = c.quadratic_drag.unwrap_or(0.0);
        physics.spring_damping = c.spring_damping.unwrap_or(0.0);
        model.springs[2].damping = c.own_damping;
        if let Some(e) = c.walls {
            // A box around the ring, one side tilted.
            for (p, n) in [((150.0, 150.0), (1.0, 0.2)), ((150.0, 150.0), (0.0, 1.0)), ((360.0, 360.0), (-1.0, 0.0)), ((360.0, 360.0), (0.0, -1.0))] {
                physics.walls.push(Wall::new(Vec2::new(p.0, p.1), Vec2::new(n.0, n.1), e).unwrap());
            }
        }
        model.physics = physics;
        if let Some(p) = c.fixed { model.particles.particles[p].fixed = true; }
        model.torsions.push(Torsion::new(ParticleId(1), ParticleId(2), ParticleId(6), 0.0, 500.0));
        let kind = if c.euler { IntegratorKind::Euler } else { IntegratorKind::Verlet };
        let rec = simulate(&model, &initial, &params(kind), 300);
        for (k, (x, v)) in rec.positions.iter().zip(&rec.velocities).enumerate() {
            prop_assert!(x.x.is_finite() && x.y.is_finite() && v.x.is_finite() && v.y.is_finite(), "sample {k}");
            for w in &model.physics.walls {
                prop_assert!(w.signed_distance(*x) >= -1e-9, "sample {k} at {x:?} behind a wall");
            }
        }
    }
}
