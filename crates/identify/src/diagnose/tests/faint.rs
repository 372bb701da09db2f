//! Short recordings of a springy body, one of whose corners bounces off a wall under a field:
//! over 12-18 frames the weak form cannot tell springs that ring at most a few frames a
//! period, so the rough model's misfit hides the bounce from the means of the jolt test; the
//! local jump still holds it (a faint jolt, `jolts::Scan::faint`). Before, a tether
//! pulling the corner round stood in for the wall and was called explained (bench recordings
//! 9 and 25), or nothing was found. A soft, far tether on one particle (not identified) that
//! stood in for the field gives way to it (`simpler_equivalent`). Drawn from fixed seeds over frame rates, stiffnesses, masses, sizes, fields,
//! directions, restitutions and noise.

use rand::{Rng, SeedableRng};

use super::*;
use crate::testutil::record;

/// A triangle of three particles joined by three springs released 0-8 % off their rest
/// lengths (so that they ring), thrown towards a wall under a field that pushes it there; the
/// wall is placed where the nearest corner reaches it 4-7 frames in. Returns the truth and
/// the structure (the springs with unknown values, no physics).
fn springy_bounce(seed: u64) -> (Scene, Scene) {
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
    let fps: f64 = rng.gen_range(35.0..60.0);
    let frames: usize = rng.gen_range(12..19);
    let side: f64 = rng.gen_range(60.0..100.0);
    let angle: f64 = rng.gen_range(0.0..std::f64::consts::TAU);
    let n = Vec2::new(angle.cos(), angle.sin());
    let t = Vec2::new(-n.y, n.x);
    let g_along: f64 = rng.gen_range(100.0..400.0);
    let g_across: f64 = rng.gen_range(-100.0..100.0);
    let field = -n * g_along + t * g_across;
    let centre = Vec2::new(250.0, 250.0);
    let speed: f64 = rng.gen_range(120.0..250.0);
    let velocity = -n * speed + t * rng.gen_range(-60.0..60.0);
    let corners: Vec<Vec2> = (0..3)
        .map(|k| {
            let a = angle + std::f64::consts::PI + f64::from(k) * std::f64::consts::TAU / 3.0;
            centre + Vec2::new(a.cos(), a.sin()) * (side / 3f64.sqrt())
        })
        .collect();
    let mut particles = String::new();
    for (k, c) in corners.iter().enumerate() {
        particles += &format!(
            "[[particles]]\nid = \"p{k}\"\nmass = {}\nposition = [{}, {}]\nvelocity = [{}, {}]\n",
            rng.gen_range(0.8..1.2),
            c.x,
            c.y,
            velocity.x,
            velocity.y
        );
    }
    let mut springs = String::new();
    for (a, b) in [(0, 1), (1, 2), (0, 2)] {
        springs += &format!(
            "[[springs]]\nbetween = [\"p{a}\", \"p{b}\"]\nlength = {}\nstiffness = {}\n",
            side * rng.gen_range(0.92..1.08),
            rng.gen_range(100.0..300.0)
        );
    }
    let head =
        format!("name = \"springy-bounce\"\n[recording]\nfps = {fps}\nframes = {frames}\nsubsteps = 20\n");
    let physics = format!("[physics]\ngravity = [{}, {}]\n", field.x, field.y);
    let free = Scene::from_toml_str(&format!("{head}{particles}{springs}{physics}"), "free")
        .unwrap_or_else(|e| panic!("{e}"));
    // The wall: the line the nearest corner reaches at the chosen frame, never crossed before.
    let bounce = rng.gen_range(4..8);
    let rec = record(&free);
    let offset = (0..=bounce)
        .flat_map(|k| rec.frame(k).iter().map(|x| n.dot(x)).collect::<Vec<_>>())
        .fold(f64::INFINITY, f64::min);
    let point = n * offset;
    let wall = format!(
        "[[physics.walls]]\npoint = [{}, {}]\nnormal = [{}, {}]\nrestitution = {}\n",
        point.x,
        point.y,
        n.x,
        n.y,
        rng.gen_range(0.5..0.9)
    );
    let truth = Scene::from_toml_str(&format!("{head}{particles}{springs}{physics}{wall}"), "truth")
        .unwrap_or_else(|e| panic!("{e}"));
    let mut structure = truth.structure();
    for s in &mut structure.springs {
        s.rest_length = None;
        s.stiffness = None;
    }
    (truth, structure)
}

/// Asserts that `c` found exactly the field and the wall, with the field within three of its
/// standard errors of the truth (a dozen frames tell it to 2-15 %), and the wall as
/// [`Case::wall`] asks; or, failing that, that its verdict says "not explained". Returns true
/// when exactly right.
fn right_or_unsure(c: &Case) -> bool {
    let mut labels: Vec<&str> = c.d.findings.iter().map(|f| f.label.as_str()).collect();
    labels.sort_unstable();
    if labels != ["uniform field (gravity)", "wall"] {
        assert!(
            !c.d.verdict.explained,
            "{}: found {labels:?} and called it explained: {}",
            c.name, c.d.verdict.text
        );
        return false;
    }
    let field = "uniform field (gravity)";
    let (_, gx) = c.parameter(field, "gravity_x");
    let (_, gy) = c.parameter(field, "gravity_y");
    let error = gx
        .std_error
        .unwrap_or(f64::NAN)
        .hypot(gy.std_error.unwrap_or(f64::NAN));
    let miss = (Vec2::new(gx.value, gy.value) - c.truth.physics.gravity).norm();
    assert!(
        miss <= 3.0 * error,
        "{}: field ({}, {}) is {miss:.1} px/s^2 from the truth {:?}, standard error {error:.1}",
        c.name,
        gx.value,
        gy.value,
        c.truth.physics.gravity
    );
    c.wall(0);
    assert!(c.d.verdict.explained, "{}: {}", c.name, c.d.verdict.text);
    true
}

#[test]
fn a_faint_bounce_of_a_ringing_body_finds_its_wall() {
    let mut right = 0;
    for seed in 0..8u64 {
        let (truth, structure) = springy_bounce(seed);
        let sigma = 0.02 + 0.02 * seed as f64;
        let c = diagnose_case_at(&format!("springy bounce {seed}"), truth, &structure, sigma, seed);
        eprintln!("springy bounce {seed}: {}", c.d.verdict.text);
        right += usize::from(right_or_unsure(&c));
    }
    // Before the faint jolts and landings: 1 of 8 (seed 0), the other 7 "not explained".
    // Now 7: seed 6 finds the wall alone and says "not explained" (2.8 noises).
    assert!(right >= 7, "{right} of 8 exactly right");
}

/// A lone ball thrown under a field onto a floor, recorded so that its one bounce falls in
/// the last frame gap (even seeds) or the first (odd seeds), where the jolt test's means
/// cannot reach: drawn from `seed` over frame rates, fields, speeds and restitutions.
fn bounce_at_an_end(seed: u64) -> Scene {
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
    let fps: f64 = rng.gen_range(30.0..120.0);
    let gravity: f64 = rng.gen_range(500.0..3000.0);
    let restitution: f64 = rng.gen_range(0.5..0.9);
    let vx: f64 = rng.gen_range(-80.0..80.0);
    let floor = 400.0;
    let dt = 1.0 / fps;
    let frames: usize = rng.gen_range(20..40);
    // Where in its gap the ball meets the floor, as a fraction of the frame.
    let phase: f64 = rng.gen_range(0.2..0.8);
    let (position, velocity, frames) = if seed % 2 == 0 {
        // Dropped from rest so that it lands `phase` into gap `frames - 2`.
        let t = (frames as f64 - 2.0 + phase) * dt;
        ([100.0, floor - 0.5 * gravity * t * t], [vx, 0.0], frames)
    } else {
        // Falling at the speed of a drop from rest over `frames` frames, `phase` of a frame
        // before the floor.
        let v = gravity * frames as f64 * dt;
        let gap = v * phase * dt + 0.5 * gravity * (phase * dt).powi(2);
        ([100.0, floor - gap], [vx, v], frames)
    };
    ball_over_a_floor(
        "end bounce",
        fps,
        frames,
        position,
        velocity,
        gravity,
        floor,
        restitution,
    )
}

#[test]
fn a_bounce_in_the_first_or_last_frame_gap_finds_its_floor() {
    for seed in 0..4u64 {
        let truth = bounce_at_an_end(seed);
        let name = format!("end bounce {seed}");
        let c = diagnose_case_at(&name, truth.clone(), &truth.structure(), 0.02, seed);
        eprintln!("{name}: {}", c.d.verdict.text);
        c.names_exactly(&["uniform field (gravity)", "wall"]).gravity();
        let (_, ny) = c.parameter("wall", "normal_y");
        assert!(ny.value < -0.99, "{name}: floor normal_y {}", ny.value);
        assert!(c.d.verdict.explained, "{name}: {}", c.d.verdict.text);
    }
}
