//! Stiff springs and tethers, whose oscillation is faster than the weak form's test
//! functions see: the weak form tells a soft stiffness or none, and a multi-step fit started
//! there stops in another basin (each frequency the recording holds a whole number of
//! periods of is one). Their stiffness is taken from the oscillation they make (module
//! `oscillation`). Drawn from fixed seeds over stiffnesses, masses, frame rates, lengths of
//! recording and noise.

use rand::{Rng, SeedableRng};

use super::*;

const TETHER: &str = "tether of p0 to a fixed point";

/// Two particles joined by a soft spring, `p0` also tied to a fixed pivot out of the
/// structure by a stiff tether, released stretched by 0.2-1 px so that the tether rings;
/// drawn from `seed`.
fn tethered_pair(seed: u64) -> (Scene, Scene) {
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
    let fps: f64 = rng.gen_range(50.0..150.0);
    let frames = rng.gen_range(150..300);
    let stiffness: f64 = rng.gen_range(1500.0..5000.0);
    let m0: f64 = rng.gen_range(1.0..2.0);
    let length: f64 = rng.gen_range(150.0..300.0);
    let angle: f64 = rng.gen_range(-0.5..0.5);
    // Released stretched, so that the tether rings.
    let stretch: f64 = rng.gen_range(0.2..1.0);
    let pivot = [80.0 + length * angle.sin(), 80.0 + length * angle.cos()];
    let p0: [f64; 2] = [80.0, 80.0];
    let p1: [f64; 2] = [
        80.0 + rng.gen_range(30.0..50.0),
        80.0 + rng.gen_range(-10.0..10.0),
    ];
    let v0 = [rng.gen_range(-25.0..25.0), rng.gen_range(-25.0..25.0)];
    let text = |hidden: bool| {
        let pivot_text = if hidden {
            String::new()
        } else {
            format!(
                r#"
                [[particles]]
                id = "pivot"
                mass = 1.0
                position = [{}, {}]
                fixed = true
                [[springs]]
                between = ["p0", "pivot"]
                length = {}
                stiffness = {stiffness}
                "#,
                pivot[0],
                pivot[1],
                length - stretch
            )
        };
        format!(
            r#"
            name = "tethered-pair"
            [recording]
            fps = {fps}
            frames = {frames}
            substeps = 10
            [[particles]]
            id = "p0"
            mass = {m0}
            position = [{}, {}]
            velocity = [{}, {}]
            [[particles]]
            id = "p1"
            mass = 1.0
            position = [{}, {}]
            velocity = [{}, {}]
            [[springs]]
            between = ["p0", "p1"]
            length = {}
            stiffness = 3.0
            {pivot_text}
            "#,
            p0[0],
            p0[1],
            v0[0],
            v0[1],
            p1[0],
            p1[1],
            v0[0],
            v0[1],
            ((p1[0] - p0[0]).powi(2) + (p1[1] - p0[1]).powi(2)).sqrt() * 0.9,
        )
    };
    truth_and_structure(&text(false), &text(true))
}

/// The truth scene from `truth`'s text, and the structure from `hidden`'s (the truth without
/// its concealed bond) with every bond's values unknown.
fn truth_and_structure(truth: &str, hidden: &str) -> (Scene, Scene) {
    let parse = |t: &str| Scene::from_toml_str(t, "stiff").unwrap_or_else(|e| panic!("{e}"));
    let mut structure = parse(hidden);
    for s in &mut structure.springs {
        s.rest_length = None;
        s.stiffness = None;
    }
    (parse(truth), structure)
}

/// Diagnoses `truth`'s tracks (noise 0.01 px, `pivot` untracked) against `structure` and
/// checks that it names exactly the finding `label`, whose stiffness is within 1 % of
/// `truth`'s spring `spring`, and that the verdict says explained.
fn check_stiff(name: &str, truth: &Scene, structure: &Scene, label: &str, spring: usize, seed: u64) {
    let c = diagnose_case_at(name, truth.clone(), structure, 0.01, seed);
    eprintln!("{name}: {}", c.d.verdict.text);
    c.names_exactly(&[label]);
    assert!(c.d.verdict.explained, "{name}: {}", c.d.verdict.text);
    let want = truth.springs[spring].stiffness.unwrap_or(f64::NAN);
    let got = c.value(label, "stiffness");
    assert!(
        (got - want).abs() <= 0.01 * want,
        "{name}: stiffness {got:.1}, truth {want:.1}"
    );
}

#[test]
fn stiff_tethers_take_the_stiffness_of_their_oscillation() {
    for seed in 0..4u64 {
        let (truth, structure) = tethered_pair(seed);
        check_stiff(
            &format!("tethered pair {seed}"),
            &truth,
            &structure,
            TETHER,
            1,
            seed,
        );
    }
}

/// Three particles in a row joined by two soft springs, `p0` and `p2` also joined by a stiff
/// spring the structure leaves out, released stretched by 0.2-1 px so that it rings; drawn
/// from `seed`.
fn ringing_triple(seed: u64) -> (Scene, Scene) {
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
    let fps: f64 = rng.gen_range(50.0..150.0);
    let frames = rng.gen_range(150..300);
    let stiffness: f64 = rng.gen_range(1500.0..5000.0);
    let gap: f64 = rng.gen_range(30.0..50.0);
    let stretch: f64 = rng.gen_range(0.2..1.0);
    let v: [f64; 3] = [
        rng.gen_range(-20.0..20.0),
        rng.gen_range(-20.0..20.0),
        rng.gen_range(-5.0..5.0),
    ];
    let text = |hidden: bool| {
        let extra = if hidden {
            String::new()
        } else {
            format!(
                r#"
                [[springs]]
                between = ["p0", "p2"]
                length = {}
                stiffness = {stiffness}
                "#,
                2.0 * gap - stretch
            )
        };
        format!(
            r#"
            name = "ringing-triple"
            [recording]
            fps = {fps}
            frames = {frames}
            substeps = 10
            [[particles]]
            id = "p0"
            mass = 1.0
            position = [60.0, 80.0]
            velocity = [{}, {}]
            [[particles]]
            id = "p1"
            mass = 1.3
            position = [{}, 80.0]
            velocity = [{}, {}]
            [[particles]]
            id = "p2"
            mass = 1.6
            position = [{}, 80.0]
            velocity = [{}, {}]
            [[springs]]
            between = ["p0", "p1"]
            length = {}
            stiffness = 3.0
            [[springs]]
            between = ["p1", "p2"]
            length = {}
            stiffness = 4.0
            {extra}
            "#,
            v[0],
            v[1],
            60.0 + gap,
            v[0],
            v[1] + v[2],
            60.0 + 2.0 * gap,
            v[0],
            v[1] - v[2],
            gap * 0.9,
            gap * 1.1,
        )
    };
    truth_and_structure(&text(false), &text(true))
}

#[test]
fn stiff_missing_springs_take_the_stiffness_of_their_oscillation() {
    for seed in 0..4u64 {
        let (truth, structure) = ringing_triple(seed);
        let name = format!("ringing triple {seed}");
        check_stiff(&name, &truth, &structure, "missing spring p0-p2", 2, seed);
    }
}
