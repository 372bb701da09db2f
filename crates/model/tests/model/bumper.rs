//! Spring bumpers (issue 22): a wall with a one-sided spring `S s^2` and dashpot `c` at its
//! line, penetration allowed, against the damped oscillator's contact time and restitution.

use physfit_model::{step, IntegratorKind, Potential, Scene, State, StepScratch, Vec2, Wall};

use crate::common::single;

/// Substep length, s (2000 substeps a second, as 100 fps with 20 substeps).
const DT: f64 = 5e-4;

/// What a mass `m` hitting a bumper (stiffness `s`, damping `c`) along its normal at
/// `speed` px/s does: (contact time s, rebound speed px/s, deepest penetration px, largest
/// drift of the total energy while `c = 0`). The crossings of the line are interpolated
/// linearly between substeps.
fn hit_bumper(m: f64, s: f64, c: f64, speed: f64, kind: IntegratorKind) -> (f64, f64, f64, f64) {
    let mut model = single(m);
    let normal = Vec2::new(-0.6, -0.8);
    let wall = Wall::new(Vec2::new(300.0, 300.0), normal, 0.0)
        .unwrap()
        .with_bumper(s, c);
    model.physics.walls.push(wall.clone());
    // Start 10.3 px out, moving in, with some sliding along the wall (which a bumper keeps).
    let tangent = Vec2::new(0.8, -0.6);
    let mut state = State::new(
        vec![Vec2::new(300.0, 300.0) + normal * 10.3],
        vec![normal * -speed + tangent * 40.0],
    );
    let e0 = model.total_energy(&state);
    let mut scratch = StepScratch::default();
    let (mut t_in, mut t_out, mut depth, mut drift) = (None, None, 0.0f64, 0.0f64);
    for n in 0..4000 {
        let s_before = wall.signed_distance(state.positions[0]);
        step(&model, kind, DT, &mut state, &mut scratch);
        let s_after = wall.signed_distance(state.positions[0]);
        let t_cross = (n as f64 + s_before / (s_before - s_after)) * DT;
        if s_before >= 0.0 && s_after < 0.0 && t_in.is_none() {
            t_in = Some(t_cross);
        }
        if s_before < 0.0 && s_after >= 0.0 && t_in.is_some() {
            t_out = Some(t_cross);
            break;
        }
        depth = depth.max(-s_after);
        drift = drift.max((model.total_energy(&state) - e0).abs() / e0);
        let vt = state.velocities[0].dot(&tangent);
        assert!(
            (vt - 40.0).abs() < 1e-9,
            "the bumper changed the sliding speed to {vt}"
        );
    }
    let contact = t_out.expect("left the bumper") - t_in.expect("hit the bumper");
    let rebound = state.velocities[0].dot(&normal);
    // The bumper's spring is in the potential: energy is m v^2 / 2 plus S s^2.
    assert!(model.energy(&state.positions) >= 0.0);
    (contact, rebound, depth, drift)
}

#[test]
fn an_undamped_bumper_holds_a_mass_for_pi_over_omega_and_returns_its_speed() {
    // m = 2, S = 500 (k = 2 S = 1000 mass/s²): omega = sqrt(k / m) = 22.36 rad/s, contact
    // pi / omega = 0.14050 s, deepest v / omega = 4.472 px at 100 px/s.
    let (m, s, v): (f64, f64, f64) = (2.0, 500.0, 100.0);
    let omega = (2.0 * s / m).sqrt();
    for kind in [IntegratorKind::Verlet, IntegratorKind::Euler] {
        let (contact, rebound, depth, drift) = hit_bumper(m, s, 0.0, v, kind);
        let exact = std::f64::consts::PI / omega;
        // Measured: Verlet 2e-7 relative in contact time, 3e-7 in speed; Euler 1e-5 and 2e-3.
        let tol = if kind == IntegratorKind::Verlet {
            1e-5
        } else {
            5e-3
        };
        assert!(
            (contact - exact).abs() < tol * exact,
            "{kind:?}: contact {contact} s vs {exact}"
        );
        assert!(
            (rebound - v).abs() < tol * v,
            "{kind:?}: rebound {rebound} vs {v}"
        );
        assert!(
            (depth - v / omega).abs() < 0.01 * v / omega,
            "{kind:?}: depth {depth} vs {}",
            v / omega
        );
        if kind == IntegratorKind::Verlet {
            // Measured 2.7e-5: Verlet's bounded energy error, of order (omega dt)^2 / 4.
            assert!(drift < 1e-4, "energy drift {drift:e}");
        }
    }
    // The contact line moves with the impact speed: twice as fast, twice as deep.
    let (_, _, deeper, _) = hit_bumper(m, s, 0.0, 2.0 * v, IntegratorKind::Verlet);
    assert!((deeper - 2.0 * v / omega).abs() < 0.01 * v / omega);
}

#[test]
fn a_damped_bumper_returns_exp_of_minus_zeta_pi_over_sqrt_one_minus_zeta2() {
    // zeta = c / (2 sqrt(k m)) = 0.1 and 0.3 with k = 2 S = 1000, m = 2.
    let (m, s, v): (f64, f64, f64) = (2.0, 500.0, 100.0);
    let k = 2.0 * s;
    for zeta in [0.1f64, 0.3] {
        let c = 2.0 * zeta * (k * m).sqrt();
        let (contact, rebound, _, _) = hit_bumper(m, s, c, v, IntegratorKind::Verlet);
        let root = (1.0 - zeta * zeta).sqrt();
        let e = (-zeta * std::f64::consts::PI / root).exp();
        let t = std::f64::consts::PI / ((k / m).sqrt() * root);
        let wall = Wall::new(Vec2::zeros(), Vec2::new(0.0, -1.0), 1.0)
            .unwrap()
            .with_bumper(s, c);
        assert!((wall.bumper_restitution(m) - e).abs() < 1e-12);
        assert!(wall
            .bumper_contact_time(m)
            .is_some_and(|w| (w - t).abs() < 1e-12 * t));
        // Measured: zeta 0.1, e 0.72829 against 0.72925 and contact 0.1412036 against
        // 0.1412041 s; zeta 0.3, e 0.37122 against 0.37233. The dashpot's force jumps at the
        // line, inside a substep: e is off by about c v dt / (2 m) / v = 1e-3.
        assert!(
            (rebound / v - e).abs() < 2e-3,
            "zeta {zeta}: e {} vs {e}",
            rebound / v
        );
        assert!(
            (contact - t).abs() < 1e-4 * t,
            "zeta {zeta}: contact {contact} vs {t}"
        );
    }
}

const SCENE: &str = r#"
[recording]
fps = 100.0
frames = 40

[[particles]]
id = "cart"
mass = 2.0
position = [100.0, 50.0]
velocity = [-100.0, 0.0]

[[physics.walls]]
point = [80.0, 0.0]
normal = [1.0, 0.0]
stiffness = 500.0
damping = 4.5

[[physics.walls]]
point = [0.0, 60.0]
normal = [0.0, -1.0]
restitution = 0.5
"#;

#[test]
fn bumper_keys_are_read_written_back_and_bad_combinations_are_named() {
    let scene = Scene::from_toml_str(SCENE, "s.toml").unwrap();
    let bumper = &scene.physics.walls[0];
    assert!(bumper.is_bumper() && !scene.physics.walls[1].is_bumper());
    assert_eq!(
        (bumper.stiffness.to_bits(), bumper.damping.to_bits()),
        (500f64.to_bits(), 4.5f64.to_bits())
    );
    let text = scene.to_toml_string().unwrap();
    let back = Scene::from_toml_str(&text, "back.toml").unwrap();
    assert_eq!(format!("{back:?}"), format!("{scene:?}"), "written as:\n{text}");
    let run = |s: &Scene| {
        physfit_model::simulate(
            &s.model().unwrap(),
            &s.initial_state(),
            &s.integration_parameters(),
            40,
        )
    };
    let rec = run(&back);
    assert_eq!(run(&scene), rec);
    // The cart went into the bumper (past x = 80) and came back out.
    assert!(rec.positions.iter().any(|x| x.x < 79.0) && rec.frame(39)[0].x > 80.0);
    let wall0 = "stiffness = 500.0\ndamping = 4.5";
    for (from, to, expected) in [
        (wall0, "stiffness = -5.0", "physics.walls[0].stiffness is -5; it must be zero or positive"),
        (
            wall0,
            "stiffness = 500.0\nrestitution = 0.5",
            "physics.walls[0].restitution is 0.5; it must be absent on a spring bumper (a wall with stiffness): its stiffness and damping set the rebound",
        ),
        (
            wall0,
            "stiffness = 500.0\nfriction = 0.2",
            "physics.walls[0].friction is 0.2; it must be zero on a spring bumper (a wall with stiffness)",
        ),
        (
            wall0,
            "damping = 4.5",
            "physics.walls[0] has no restitution: a rigid wall needs one (a spring bumper has a stiffness instead)",
        ),
        (
            "restitution = 0.5",
            "restitution = 0.5\ndamping = 3.0",
            "physics.walls[1].damping is 3; it must be zero on a rigid wall (give the wall a stiffness to make it a bumper)",
        ),
        (wall0, "stiffness = 500.0\ndamping = nan", "physics.walls[0].damping is NaN; it must be a finite number"),
    ] {
        let text = SCENE.replace(from, to);
        assert_ne!(text, SCENE);
        match Scene::from_toml_str(&text, "s.toml") {
            Err(e) => assert_eq!(e.to_string(), format!("s.toml: {expected}")),
            Ok(_) => panic!("accepted {to}"),
        }
    }
}
