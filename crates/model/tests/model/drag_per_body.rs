//! Drag per body (issue 22): `F = -b v - c |v| v` with `b`, `c` not scaled by the mass,
//! shared (`physics.body_drag`, `body_quadratic_drag`) or a particle's own.

use physfit_model::{simulate, IntegratorKind, Model, Scene, State, Vec2};

use crate::common::{params, FPS};

#[test]
fn a_shared_body_drag_decays_each_velocity_at_b_over_its_mass() {
    // Masses 1, 4 and 2 in one medium b = 2 mass/s: rates 2, 0.5 and (own b = 3) 1.5 /s.
    let mut model = Model::default();
    for m in [1.0, 4.0, 2.0] {
        model.add_particle(m, false);
    }
    model.physics.body_drag = 2.0;
    model.particles.particles[2].body_drag = Some(3.0);
    let rates = [2.0, 0.5, 1.5];
    let v0 = [
        Vec2::new(300.0, -40.0),
        Vec2::new(-120.0, 90.0),
        Vec2::new(10.0, 200.0),
    ];
    let x0 = vec![Vec2::new(0.0, 0.0), Vec2::new(100.0, 0.0), Vec2::new(0.0, 100.0)];
    let initial = State::new(x0.clone(), v0.to_vec());
    for kind in [IntegratorKind::Verlet, IntegratorKind::Euler] {
        let rec = simulate(&model, &initial, &params(kind), 200);
        // Measured at 1.99 s (rate 2 /s): Verlet 6.6e-7, Euler 2.0e-3 relative.
        let tol = if kind == IntegratorKind::Verlet {
            2e-6
        } else {
            5e-3
        };
        for k in [1, 100, 199] {
            let t = k as f64 / FPS;
            for p in 0..3 {
                let decay = (-rates[p] * t).exp();
                let v = rec.velocities[k * 3 + p];
                assert!(
                    (v - v0[p] * decay).norm() <= tol * v0[p].norm() * decay,
                    "{kind:?} particle {p} frame {k}: |v| {} vs {}",
                    v.norm(),
                    v0[p].norm() * decay
                );
                let x = x0[p] + v0[p] * ((1.0 - decay) / rates[p]);
                assert!((rec.frame(k)[p] - x).norm() <= tol * v0[p].norm() / rates[p]);
            }
        }
    }
}

#[test]
fn quadratic_body_drag_gives_the_terminal_speed_sqrt_m_g_over_c() {
    // Falling from rest: v = v_t tanh(g t / v_t) with v_t = sqrt(m g / c). Two masses share
    // c, so the heavier falls faster (per-mass drag would give them one terminal speed).
    let (g, c) = (1000.0, 0.01);
    let mut model = Model::default();
    model.add_particle(2.0, false);
    model.add_particle(0.5, false);
    model.physics.gravity = Vec2::new(0.0, g);
    model.physics.body_quadratic_drag = c;
    let initial = State::at_rest(vec![Vec2::new(0.0, 0.0), Vec2::new(50.0, 0.0)]);
    let rec = simulate(&model, &initial, &params(IntegratorKind::Verlet), 301);
    for (p, m) in [2.0, 0.5].into_iter().enumerate() {
        let vt = (m * g / c).sqrt();
        for k in [10, 100, 300] {
            let t = k as f64 / FPS;
            let exact = vt * (g * t / vt).tanh();
            let v = rec.velocities[k * 2 + p];
            assert!(v.x.abs() < 1e-12);
            assert!(
                (v.y - exact).abs() < 1e-6 * vt,
                "mass {m} frame {k}: {} vs {exact}",
                v.y
            );
        }
        // At 3 s both are at their terminal speed (447.2 and 223.6 px/s) to 1e-5.
        let last = rec.velocities[300 * 2 + p].y;
        assert!((last - vt).abs() < 1e-5 * vt, "mass {m}: {last} vs {vt}");
    }
}

const SCENE: &str = r#"
[recording]
fps = 100.0
frames = 50

[[particles]]
id = "light"
mass = 1.0
position = [10.0, 20.0]
velocity = [100.0, 0.0]

[[particles]]
id = "heavy"
mass = 4.0
position = [10.0, 80.0]
velocity = [100.0, 0.0]
body_drag = 0.75
body_quadratic_drag = 0.0015

[physics]
body_drag = 0.5
body_quadratic_drag = 0.002
"#;

#[test]
fn body_drag_keys_are_read_written_back_and_dropped_from_a_structure() {
    let scene = Scene::from_toml_str(SCENE, "s.toml").unwrap();
    assert_eq!(
        (scene.physics.body_drag, scene.physics.body_quadratic_drag),
        (0.5, 0.002)
    );
    assert_eq!(scene.particles[0].body_drag, None);
    assert_eq!(
        (
            scene.particles[1].body_drag,
            scene.particles[1].body_quadratic_drag
        ),
        (Some(0.75), Some(0.0015))
    );
    let text = scene.to_toml_string().unwrap();
    let back = Scene::from_toml_str(&text, "back.toml").unwrap();
    assert_eq!(format!("{back:?}"), format!("{scene:?}"), "written as:\n{text}");
    // The written scene simulates as the original (fitted.toml renders the same motion).
    let run = |s: &Scene| {
        simulate(
            &s.model().unwrap(),
            &s.initial_state(),
            &s.integration_parameters(),
            50,
        )
    };
    assert_eq!(run(&scene), run(&back));
    let structure = scene.structure();
    assert!(structure
        .particles
        .iter()
        .all(|p| p.body_drag.is_none() && p.body_quadratic_drag.is_none()));
    assert!(!structure
        .model()
        .map(|m| m.has_velocity_dependent_forces())
        .unwrap_or(true));
}

#[test]
fn bad_body_drag_values_are_named_with_their_key_and_value() {
    for (from, to, expected) in [
        (
            "body_drag = 0.5",
            "body_drag = -0.5",
            "physics.body_drag is -0.5; it must be zero or positive",
        ),
        (
            "body_quadratic_drag = 0.002",
            "body_quadratic_drag = nan",
            "physics.body_quadratic_drag is NaN; it must be a finite number",
        ),
        (
            "body_drag = 0.75",
            "body_drag = -2.0",
            "particle \"heavy\" body_drag is -2; it must be zero or positive",
        ),
        (
            "body_quadratic_drag = 0.0015",
            "body_quadratic_drag = 1e300",
            "particle \"heavy\" body_quadratic_drag is 1e300; it must be at most 1e12 in magnitude",
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
