//! Ropes and rails (issue 22): constraints projected after each substep, against the
//! pendulum's period, free fall until a slack rope catches, and a slide along a rail.

use physfit_model::{simulate, IntegratorKind, Model, Rail, Rope, Scene, State, Vec2};

use crate::common::{params, FPS};

/// A bob of mass 1 on a rope of length `length` from a fixed pivot at (200, 50), under
/// g = 1000 px/s² down, released at rest `angle` rad from the vertical.
fn pendulum(length: f64, angle: f64, slack: bool) -> (Model, State) {
    let mut model = Model::default();
    let pivot = model.add_particle(1.0, true);
    let bob = model.add_particle(1.0, false);
    model.physics.gravity = Vec2::new(0.0, 1000.0);
    model.physics.ropes.push(Rope {
        ends: [pivot, bob],
        length,
        slack,
    });
    let p = Vec2::new(200.0, 50.0);
    let state = State::at_rest(vec![p, p + Vec2::new(angle.sin(), angle.cos()) * length]);
    (model, state)
}

#[test]
fn a_pendulum_on_a_rope_swings_with_period_two_pi_sqrt_l_over_g() {
    let (l, g, angle): (f64, f64, f64) = (150.0, 1000.0, 0.05);
    let small = 2.0 * std::f64::consts::PI * (l / g).sqrt();
    // The amplitude's correction, 1 + angle^2 / 16 (2.4339 against 2.4335 s).
    let finite = small * (1.0 + angle * angle / 16.0);
    for kind in [IntegratorKind::Verlet, IntegratorKind::Euler] {
        let (model, initial) = pendulum(l, angle, false);
        let rec = simulate(&model, &initial, &params(kind), 750);
        // Downward crossings of the vertical (x = 200, moving left), interpolated.
        let xs: Vec<f64> = (0..750).map(|k| rec.frame(k)[1].x - 200.0).collect();
        let crossings: Vec<f64> = (1..750)
            .filter(|&k| xs[k - 1] > 0.0 && xs[k] <= 0.0)
            .map(|k| (k as f64 - 1.0 + xs[k - 1] / (xs[k - 1] - xs[k])) / FPS)
            .collect();
        assert!(crossings.len() >= 3, "{crossings:?}");
        let period = (crossings[crossings.len() - 1] - crossings[0]) / (crossings.len() - 1) as f64;
        // Measured: Verlet 2.4338473 s, Euler 2.4338473 s against 2.4334672 (small angle,
        // 0.016 % off) and 2.4338474 (with the amplitude's correction, 4e-8 off).
        assert!(
            (period - small).abs() < 0.005 * small,
            "{kind:?}: period {period} s vs 2 pi sqrt(L / g) = {small}"
        );
        assert!(
            (period - finite).abs() < 1e-5 * finite,
            "{kind:?}: period {period} s vs {finite}"
        );
        // The rope never stretches, and the pivot never moves.
        for k in 0..750 {
            let d = (rec.frame(k)[1] - rec.frame(k)[0]).norm();
            assert!((d - l).abs() < 1e-9 * l, "{kind:?} frame {k}: length {d}");
            assert!((rec.frame(k)[0] - Vec2::new(200.0, 50.0)).norm() == 0.0);
        }
        if kind == IntegratorKind::Verlet {
            // Energy (kinetic plus field) is kept to 1e-5 of the swing's (measured 4.2e-7).
            let swing = 1000.0 * l * (1.0 - angle.cos());
            let e0 = model.total_energy(&rec.state(0));
            let drift = (0..750)
                .map(|k| (model.total_energy(&rec.state(k)) - e0).abs())
                .fold(0.0, f64::max);
            assert!(drift < 1e-5 * swing, "energy drift {drift} of {swing}");
        }
    }
}

#[test]
fn a_slack_rope_lets_the_bob_fall_freely_until_it_is_taut() {
    // Bob 75 px below the pivot on a 150 px slack rope: free fall for sqrt(2 * 75 / g) =
    // 0.387 s, then the rope catches it (inelastically: the radial speed is taken away).
    let (model, initial) = pendulum(150.0, 0.0, true);
    let mut initial = initial;
    initial.positions[1] = Vec2::new(200.0, 125.0);
    let rec = simulate(&model, &initial, &params(IntegratorKind::Verlet), 60);
    let t_catch = (2.0 * 75.0 / 1000.0f64).sqrt();
    for k in 0..60 {
        let t = k as f64 / FPS;
        let (x, v) = (rec.frame(k)[1], rec.velocities[2 * k + 1]);
        if t < t_catch - 0.01 {
            // Verlet is exact in free fall.
            assert!(
                (x.y - (125.0 + 500.0 * t * t)).abs() < 1e-9,
                "frame {k}: y {}",
                x.y
            );
        } else if t > t_catch + 0.01 {
            assert!((x - Vec2::new(200.0, 200.0)).norm() < 1e-9, "frame {k}: {x:?}");
            assert!(v.norm() < 1e-9, "frame {k}: v {v:?}");
        }
        assert!((x - rec.frame(k)[0]).norm() <= 150.0 * (1.0 + 1e-12));
    }
    // A rigid rod (not slack) holds the bob at 75 px: it never falls.
    let (mut rod, _) = pendulum(75.0, 0.0, false);
    rod.physics.ropes[0].slack = false;
    let held = simulate(&rod, &initial, &params(IntegratorKind::Verlet), 60);
    assert!((held.frame(59)[1] - Vec2::new(200.0, 125.0)).norm() < 1e-9);
}

#[test]
fn a_particle_on_a_tilted_rail_slides_at_g_sin_angle() {
    // Rail through (50, 50) descending at 30 degrees; g = 1000 px/s² down: 500 px/s² along.
    let mut model = Model::default();
    let cart = model.add_particle(2.0, false);
    model.physics.gravity = Vec2::new(0.0, 1000.0);
    let dir = Vec2::new(30f64.to_radians().cos(), 30f64.to_radians().sin());
    model
        .physics
        .rails
        .push(Rail::new(cart, Vec2::new(50.0, 50.0), dir * 3.0).unwrap());
    // It starts on the rail moving along it at 40 px/s, plus a kick across it that the
    // rail takes away at once.
    let normal = Vec2::new(-dir.y, dir.x);
    let initial = State::new(vec![Vec2::new(50.0, 50.0)], vec![dir * 40.0 + normal * 25.0]);
    for kind in [IntegratorKind::Verlet, IntegratorKind::Euler] {
        let rec = simulate(&model, &initial, &params(kind), 50);
        // Verlet is exact under the constant along-rail force (79.625 px at 0.49 s to
        // 1e-12); Euler is off by a t dt / 2 (0.061 px there).
        let tol = if kind == IntegratorKind::Verlet { 1e-9 } else { 0.1 };
        for k in 1..50 {
            let t = k as f64 / FPS;
            let x = rec.frame(k)[0];
            let along = (x - Vec2::new(50.0, 50.0)).dot(&dir);
            let across = (x - Vec2::new(50.0, 50.0)).dot(&normal);
            assert!(
                across.abs() < 1e-9,
                "{kind:?} frame {k}: {across} px off the rail"
            );
            let exact = 40.0 * t + 250.0 * t * t;
            assert!(
                (along - exact).abs() < tol,
                "{kind:?} frame {k}: {along} vs {exact}"
            );
            assert!(rec.velocities[k].dot(&normal).abs() < 1e-9);
        }
    }
}

const SCENE: &str = r#"
[recording]
fps = 100.0
frames = 60

[[particles]]
id = "pivot"
mass = 1.0
position = [200.0, 50.0]
fixed = true

[[particles]]
id = "bob"
mass = 1.0
position = [207.49, 199.81]

[[particles]]
id = "cart"
mass = 2.0
position = [50.0, 300.0]
velocity = [30.0, 0.0]

[physics]
gravity = [0.0, 1000.0]

[[physics.ropes]]
between = ["pivot", "bob"]
length = 150.0
slack = true

[[physics.rails]]
particle = "cart"
point = [0.0, 300.0]
direction = [1.0, 0.0]
friction = 0.01
"#;

#[test]
fn rope_and_rail_keys_are_read_written_back_and_bad_values_are_named() {
    let scene = Scene::from_toml_str(SCENE, "s.toml").unwrap();
    assert_eq!(scene.physics.ropes.len(), 1);
    assert!(scene.physics.ropes[0].slack);
    let text = scene.to_toml_string().unwrap();
    let back = Scene::from_toml_str(&text, "back.toml").unwrap();
    assert_eq!(format!("{back:?}"), format!("{scene:?}"), "written as:\n{text}");
    let run = |s: &Scene| {
        simulate(
            &s.model().unwrap(),
            &s.initial_state(),
            &s.integration_parameters(),
            60,
        )
    };
    let rec = run(&back);
    assert_eq!(run(&scene), rec);
    // The cart stays on its horizontal rail under gravity, 30 px/s slowed at 10 px/s² for
    // 0.59 s.
    let x = 50.0 + 30.0 * 0.59 - 5.0 * 0.59 * 0.59;
    assert!((rec.frame(59)[2] - Vec2::new(x, 300.0)).norm() < 1e-9);
    for (from, to, expected) in [
        (
            "length = 150.0",
            "length = 0.0",
            "rope pivot-bob length is 0; it must be positive",
        ),
        (
            "length = 150.0",
            "length = inf",
            "rope pivot-bob length is inf; it must be a finite number",
        ),
        (
            "between = [\"pivot\", \"bob\"]",
            "between = [\"pivot\", \"bobby\"]",
            "rope pivot-bobby names particle \"bobby\", which is not defined",
        ),
        (
            "between = [\"pivot\", \"bob\"]",
            "between = [\"bob\", \"bob\"]",
            "rope bob-bob names particle \"bob\" twice",
        ),
        (
            "direction = [1.0, 0.0]",
            "direction = [0.0, 0.0]",
            "physics.rails[0].direction is 0; it must be of non-zero length",
        ),
        (
            "friction = 0.01",
            "friction = -1.0",
            "physics.rails[0].friction is -1; it must be zero or positive",
        ),
        (
            "particle = \"cart\"",
            "particle = \"car\"",
            "rail car names particle \"car\", which is not defined",
        ),
    ] {
        let text = SCENE.replace(from, to);
        assert_ne!(text, SCENE);
        match Scene::from_toml_str(&text, "s.toml") {
            Err(e) => assert_eq!(e.to_string(), format!("s.toml: {expected}")),
            Ok(_) => panic!("accepted {to}"),
        }
    }
}

/// Distance a cart set on a rail descending at `angle` rad (g = 1000 px/s² down) with
/// speed `v0` along it travels down the rail in `frames` frames, with friction `mu`.
fn slide_on_rail(angle: f64, mu: f64, v0: f64, frames: usize, kind: IntegratorKind) -> Vec<f64> {
    let mut model = Model::default();
    let cart = model.add_particle(1.5, false);
    model.physics.gravity = Vec2::new(0.0, 1000.0);
    let dir = Vec2::new(angle.cos(), angle.sin());
    let p0 = Vec2::new(100.0, 300.0);
    model
        .physics
        .rails
        .push(Rail::new(cart, p0, dir).unwrap().with_friction(mu));
    let rec = simulate(
        &model,
        &State::new(vec![p0], vec![dir * v0]),
        &params(kind),
        frames,
    );
    (0..frames).map(|k| (rec.frame(k)[0] - p0).dot(&dir)).collect()
}

#[test]
fn a_cart_on_a_rail_with_friction_stops_after_v0_squared_over_2_mu_g_and_sticks() {
    // Level rail, mu 0.3, 150 px/s: 37.5 px in 0.5 s, then at rest.
    for kind in [IntegratorKind::Verlet, IntegratorKind::Euler] {
        let run = slide_on_rail(0.0, 0.3, 150.0, 101, kind);
        // Measured: Verlet 37.5 px to 1e-11, Euler 37.4625 (first order).
        let tol = if kind == IntegratorKind::Verlet {
            1e-9
        } else {
            0.05
        };
        for (k, d) in run.iter().enumerate() {
            let t = k as f64 / FPS;
            let exact = if t < 0.5 { 150.0 * t - 150.0 * t * t } else { 37.5 };
            assert!((d - exact).abs() < tol, "{kind:?} frame {k}: {d} vs {exact}");
        }
        // On a 20 degree slope, mu 0.5 > tan 20 holds a cart at rest: not a nanometre in 1 s.
        let held = slide_on_rail(20f64.to_radians(), 0.5, 0.0, 101, kind);
        assert!(
            held.iter().all(|d| d.abs() < 1e-9),
            "{kind:?}: crept {:?}",
            held[100]
        );
    }
    // mu 0.2 on that slope: g (sin - mu cos) t^2 / 2 = 77.04 px in 1 s.
    let angle = 20f64.to_radians();
    let slid = slide_on_rail(angle, 0.2, 0.0, 101, IntegratorKind::Verlet)[100];
    let exact = 500.0 * (angle.sin() - 0.2 * angle.cos());
    assert!((slid - exact).abs() < 1e-6 * exact, "slid {slid} vs {exact}");
}

#[test]
fn a_start_off_the_constraints_is_settled_without_a_velocity_kick() {
    // The bob starts 0.5 px beyond its 150 px slack rope and the cart 0.5 px off its rail,
    // with no field: they are put back, the bob stays at rest (0.5 px over one 0.5 ms
    // substep taken as an impulse would throw it inwards at 1000 px/s, which a slack rope
    // does not take back) and the cart keeps its speed.
    let (mut model, mut initial) = pendulum(150.0, 0.3, true);
    model.physics.gravity = Vec2::zeros();
    let cart = model.add_particle(2.0, false);
    model.physics.rails.push(
        Rail::new(cart, Vec2::new(0.0, 300.0), Vec2::new(1.0, 0.0))
            .unwrap()
            .with_friction(0.4),
    );
    let bob = initial.positions[1];
    initial.positions[1] = bob + (bob - initial.positions[0]).normalize() * 0.5;
    initial.positions.push(Vec2::new(20.0, 300.5));
    initial.velocities.push(Vec2::new(10.0, 0.0));
    let rec = simulate(&model, &initial, &params(IntegratorKind::Verlet), 20);
    for k in 1..20 {
        assert!(
            (rec.frame(k)[1] - bob).norm() < 1e-9,
            "frame {k}: {:?}",
            rec.frame(k)[1]
        );
        assert!(rec.velocities[3 * k + 1].norm() < 1e-9);
        // The cart keeps its 10 px/s: no normal load, so no friction.
        let t = k as f64 / FPS;
        assert!((rec.frame(k)[2] - Vec2::new(20.0 + 10.0 * t, 300.0)).norm() < 1e-9);
        assert!((rec.velocities[3 * k + 2] - Vec2::new(10.0, 0.0)).norm() < 1e-9);
    }
}
