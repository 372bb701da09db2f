//! The integrators: energy drift, momentum, determinism, convergence order, and independence
//! from the scratch buffer's history.

use physfit_model::{
    simulate, step, step_frame, step_frame_prescribed, step_prescribed, IntegrationParameters,
    IntegratorKind, Model, State, StepScratch, Vec2, Wall,
};

use crate::common::{max_distance, momentum, paper8};

/// The default timing of a scene: 100 fps, 20 substeps.
fn default_params(integrator: IntegratorKind) -> IntegrationParameters {
    IntegrationParameters {
        frame_dt: 0.01,
        substeps: 20,
        integrator,
    }
}

/// Largest `|E(t) - E(0)| / E(0)` over `frames` frames, and the same at the last frame.
fn energy_drift(model: &Model, initial: &State, params: &IntegrationParameters, frames: usize) -> (f64, f64) {
    let e0 = model.total_energy(initial);
    let mut worst: f64 = 0.0;
    let mut last = 0.0;
    physfit_model::simulate_with(model, initial, params, frames, |_, s| {
        last = (model.total_energy(s) - e0).abs() / e0.abs();
        worst = worst.max(last);
    });
    (worst, last)
}

#[test]
fn verlet_energy_drift_over_1000_frames_is_below_1e_4() {
    let (model, initial) = paper8();
    // The test is only meaningful if the object really moves and deforms.
    let rec = simulate(&model, &initial, &default_params(IntegratorKind::Verlet), 1000);
    let spread = max_distance(rec.frame(0), rec.frame(999));
    assert!(spread > 5.0, "the object barely moved ({spread} px)");
    let potential = physfit_model::Potential::energy(&model, &initial.positions);
    assert!(
        potential > 0.1 * model.total_energy(&initial),
        "bonds start loaded"
    );

    let (worst, last) = energy_drift(&model, &initial, &default_params(IntegratorKind::Verlet), 1000);
    let (euler_worst, euler_last) =
        energy_drift(&model, &initial, &default_params(IntegratorKind::Euler), 1000);
    eprintln!(
        "paper8, 1000 frames at 100 fps x 20 substeps: relative energy error Verlet max {worst:.3e} \
         (final {last:.3e}), semi-implicit Euler max {euler_worst:.3e} (final {euler_last:.3e})"
    );
    assert!(worst < 1e-4, "Verlet relative energy drift {worst:e}");
}

#[test]
fn momentum_of_a_free_object_is_conserved() {
    let (mut model, initial) = paper8();
    // Dashpots are internal forces too: equal and opposite, so momentum still holds.
    model.physics.spring_damping = 0.5;
    model.springs[3].damping = Some(2.0);
    for kind in [IntegratorKind::Verlet, IntegratorKind::Euler] {
        let rec = simulate(&model, &initial, &default_params(kind), 500);
        let p0 = momentum(&model, &initial);
        let scale: f64 = model
            .particles
            .particles
            .iter()
            .zip(&initial.velocities)
            .map(|(p, v)| p.mass * v.norm())
            .sum();
        for k in [1, 100, 499] {
            let p = momentum(&model, &rec.state(k));
            assert!(
                (p - p0).norm() <= 1e-9 * scale,
                "{kind:?} frame {k}: momentum {p:?} vs {p0:?}"
            );
        }
    }
}

/// Every piece of physics on at once.
fn everything_on() -> (Model, State) {
    let (mut model, initial) = paper8();
    model.physics.gravity = Vec2::new(3.0, 400.0);
    model.physics.drag = 0.2;
    model.physics.quadratic_drag = 1e-4;
    model.physics.spring_damping = 0.3;
    model.springs[0].damping = Some(1.0);
    model
        .physics
        .walls
        .push(Wall::new(Vec2::new(0.0, 330.0), Vec2::new(0.1, -1.0), 0.8).unwrap());
    model
        .physics
        .walls
        .push(Wall::new(Vec2::new(150.0, 0.0), Vec2::new(1.0, 0.0), 0.5).unwrap());
    model.particles.particles[2].fixed = true;
    (model, initial)
}

#[test]
fn two_runs_are_bitwise_identical() {
    let (model, initial) = everything_on();
    for kind in [IntegratorKind::Verlet, IntegratorKind::Euler] {
        let a = simulate(&model, &initial, &default_params(kind), 400);
        let b = simulate(&model, &initial, &default_params(kind), 400);
        let bits = |r: &physfit_model::Recording| -> Vec<u64> {
            r.positions
                .iter()
                .chain(&r.velocities)
                .flat_map(|v| [v.x.to_bits(), v.y.to_bits()])
                .collect()
        };
        assert_eq!(bits(&a), bits(&b), "{kind:?} runs differ");
        // And the walls were hit, so the event law is part of what is compared.
        let lowest = (0..400)
            .flat_map(|k| a.frame(k).iter().map(|x| x.y).collect::<Vec<_>>())
            .fold(0.0, f64::max);
        assert!(
            lowest > 300.0,
            "the object never reached the floor (lowest y {lowest})"
        );
    }
}

#[test]
fn simulate_equals_step_frame_by_frame_and_step_by_step() {
    // The simulator's cached accelerations must change nothing: compare bitwise with stepping
    // by hand through the public functions.
    let (model, initial) = everything_on();
    for kind in [IntegratorKind::Verlet, IntegratorKind::Euler] {
        let params = default_params(kind);
        let rec = simulate(&model, &initial, &params, 50);
        let mut by_frame = initial.clone();
        let mut by_step = initial.clone();
        let mut scratch = StepScratch::default();
        for k in 1..50 {
            step_frame(&model, &params, &mut by_frame, &mut scratch);
            for _ in 0..params.substeps {
                step(&model, kind, params.dt(), &mut by_step, &mut scratch);
            }
            for (a, b) in [(&by_frame, &rec.state(k)), (&by_step, &rec.state(k))] {
                for (p, q) in a
                    .positions
                    .iter()
                    .zip(&b.positions)
                    .chain(a.velocities.iter().zip(&b.velocities))
                {
                    assert_eq!(
                        [p.x.to_bits(), p.y.to_bits()],
                        [q.x.to_bits(), q.y.to_bits()],
                        "{kind:?} frame {k}"
                    );
                }
            }
        }
    }
}

/// Regression: the scratch buffer used to carry the acceleration of the last state it
/// stepped into the next call, so one-step prediction from an observed state (or with another
/// model) silently started from the wrong acceleration.
#[test]
fn issue_step_ignores_what_the_scratch_last_held() {
    let (model, a) = paper8();
    let mut other_model = model.clone();
    other_model.springs[0].stiffness *= 3.0;
    let mut b = a.clone();
    b.positions[0].x += 7.0;
    for kind in [IntegratorKind::Verlet, IntegratorKind::Euler] {
        let mut fresh = b.clone();
        step(&model, kind, 1e-3, &mut fresh, &mut StepScratch::default());
        // Same scratch after stepping another state, and after stepping another model.
        let mut scratch = StepScratch::default();
        step(&model, kind, 1e-3, &mut a.clone(), &mut scratch);
        let mut reused = b.clone();
        step(&model, kind, 1e-3, &mut reused, &mut scratch);
        assert_eq!(
            reused, fresh,
            "{kind:?}: state history leaked through the scratch"
        );
        step(&other_model, kind, 1e-3, &mut b.clone(), &mut scratch);
        let mut reused = b.clone();
        step(&model, kind, 1e-3, &mut reused, &mut scratch);
        assert_eq!(
            reused, fresh,
            "{kind:?}: model history leaked through the scratch"
        );
        // step_frame too.
        let params = default_params(kind);
        let mut fresh = b.clone();
        step_frame(&model, &params, &mut fresh, &mut StepScratch::default());
        let mut reused = b.clone();
        step_frame(&other_model, &params, &mut a.clone(), &mut scratch);
        step_frame(&model, &params, &mut reused, &mut scratch);
        assert_eq!(
            reused, fresh,
            "{kind:?}: step_frame history leaked through the scratch"
        );
    }
}

/// Positions after `frames` frames at `substeps` substeps per 10 ms frame.
fn end_positions(
    model: &Model,
    initial: &State,
    kind: IntegratorKind,
    substeps: u32,
    frames: usize,
) -> Vec<Vec2> {
    let params = IntegrationParameters {
        frame_dt: 0.01,
        substeps,
        integrator: kind,
    };
    simulate(model, initial, &params, frames + 1)
        .frame(frames)
        .to_vec()
}

/// Error of each substep count against a fine Verlet reference, and the ratios of successive
/// errors (substeps doubling).
fn convergence(model: &Model, initial: &State, kind: IntegratorKind) -> (Vec<f64>, Vec<f64>) {
    let frames = 30;
    let reference = end_positions(model, initial, IntegratorKind::Verlet, 5120, frames);
    let errors: Vec<f64> = [4, 8, 16, 32]
        .iter()
        .map(|&s| max_distance(&end_positions(model, initial, kind, s, frames), &reference))
        .collect();
    let ratios = errors.windows(2).map(|w| w[0] / w[1]).collect();
    (errors, ratios)
}

#[test]
fn verlet_converges_at_second_order_and_euler_at_first_to_the_same_trajectory() {
    let (conservative, initial) = paper8();
    let (mut dissipative, _) = paper8();
    dissipative.physics.drag = 0.5;
    dissipative.physics.quadratic_drag = 2e-3;
    dissipative.physics.spring_damping = 0.4;
    dissipative.physics.gravity = Vec2::new(0.0, 300.0);
    for (label, model) in [
        ("conservative", &conservative),
        ("drag + dashpots + gravity", &dissipative),
    ] {
        let (v_err, v_ratio) = convergence(model, &initial, IntegratorKind::Verlet);
        let (e_err, e_ratio) = convergence(model, &initial, IntegratorKind::Euler);
        eprintln!(
            "{label}: Verlet errors {v_err:?} ratios {v_ratio:?}; Euler errors {e_err:?} ratios {e_ratio:?}"
        );
        for r in &v_ratio {
            assert!(
                (3.4..4.6).contains(r),
                "{label}: Verlet error ratio {r} when substeps double, expected ~4"
            );
        }
        for r in &e_ratio {
            assert!(
                (1.7..2.3).contains(r),
                "{label}: Euler error ratio {r} when substeps double, expected ~2"
            );
        }
        // Both reach the same trajectory.
        assert!(v_err[3] < 1e-3 && e_err[3] < 0.5, "{label}: {v_err:?} {e_err:?}");
    }
}

#[test]
fn a_boundary_prescribed_along_its_own_motion_leaves_the_rest_unchanged() {
    // Cut particles 5, 6 and 7 of the braced ring loose from the integrator and drive them
    // along the motion they had in the whole simulation: every other particle must move as in
    // the whole simulation, to rounding, with both schemes (dashpots included: the prescribed
    // velocities enter their forces).
    let (mut model, initial) = paper8();
    model.springs[3].damping = Some(1.5);
    let driven = [5usize, 6, 7];
    for kind in [IntegratorKind::Verlet, IntegratorKind::Euler] {
        let dt = 0.01 / 20.0;
        let mut whole = initial.clone();
        let mut scratch = StepScratch::new(whole.len());
        let mut states = vec![whole.clone()];
        for _ in 0..400 {
            step(&model, kind, dt, &mut whole, &mut scratch);
            states.push(whole.clone());
        }
        let mut cut = model.clone();
        for &p in &driven {
            cut.particles.particles[p].fixed = true;
        }
        let mut state = initial.clone();
        for (s, next) in states.iter().skip(1).enumerate() {
            let mut prescribe = |st: &mut State| {
                for &p in &driven {
                    st.positions[p] = next.positions[p];
                    st.velocities[p] = next.velocities[p];
                }
            };
            step_prescribed(&cut, kind, dt, &mut state, &mut scratch, &mut prescribe);
            let worst = (0..state.len())
                .map(|p| (state.positions[p] - next.positions[p]).norm())
                .fold(0.0, f64::max);
            assert!(worst < 1e-9, "{kind:?}, substep {}: {worst:e} px", s + 1);
        }
        let moved = max_distance(&states[0].positions, &states[400].positions);
        assert!(moved > 1.0, "{kind:?}: the object barely moved ({moved} px)");
        // A frame of 20 substeps at a time, the acceleration carried between substeps.
        let frame = IntegrationParameters {
            frame_dt: 20.0 * dt,
            substeps: 20,
            integrator: kind,
        };
        let mut state = initial.clone();
        for f in 0..20 {
            step_frame_prescribed(&cut, &frame, &mut state, &mut scratch, &mut |s, st| {
                let at = &states[20 * f + s as usize];
                for &p in &driven {
                    st.positions[p] = at.positions[p];
                    st.velocities[p] = at.velocities[p];
                }
            });
            let next = &states[20 * (f + 1)];
            let worst = (0..state.len())
                .map(|p| (state.positions[p] - next.positions[p]).norm())
                .fold(0.0, f64::max);
            assert!(worst < 1e-9, "{kind:?}, frame {}: {worst:e} px", f + 1);
        }
    }
}
