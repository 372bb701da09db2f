//! Diagnosis on simulated tracks of the scenes in `scenes/` (and a tether scene built here),
//! with Gaussian position noise: each concealed effect is named exactly, with its values
//! within the issue's tolerances and a final multi-step cost at most 1.2 times the true
//! model's; clean scenes get nothing added.
//!
//! The default tests cover one seed of a few scenes (each a few seconds); the ignored ones
//! run every scene over three seeds (`cargo test -p physfit-identify -- --ignored`).

use std::path::PathBuf;

use physfit_model::{Scene, Vec2};
use physfit_tracks::TrackTable;

use super::*;
use crate::testutil::tracks;

/// Track noise of the simulated tracks, px.
const SIGMA: f64 = 0.08;

fn scene(name: &str) -> Scene {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../scenes")
        .join(format!("{name}.toml"));
    Scene::load(&path).unwrap_or_else(|e| panic!("{e}"))
}

/// The structure a concealed scene is diagnosed from: its structure, without the concealed
/// spring (by convention the last `[[springs]]` entry of a `*missing-spring*` scene).
fn structure_of(name: &str, truth: &Scene) -> Scene {
    let mut s = truth.structure();
    if name.contains("missing-spring") {
        s.springs.pop();
    }
    s
}

/// A chain whose end `a` is tied by a soft spring to a fixed point outside the image; the
/// structure lists only the chain.
fn tether_scene() -> (Scene, Scene) {
    let text = r#"
        name = "concealed-tether"
        [recording]
        fps = 100.0
        frames = 300
        substeps = 10
        [[particles]]
        id = "a"
        mass = 1.0
        position = [100.0, 200.0]
        velocity = [5.0, 40.0]
        [[particles]]
        id = "b"
        mass = 1.2
        position = [140.0, 210.0]
        velocity = [-10.0, -20.0]
        [[particles]]
        id = "c"
        mass = 1.0
        position = [176.0, 196.0]
        velocity = [0.0, 30.0]
        [[particles]]
        id = "pin"
        mass = 1.0
        position = [40.0, 130.0]
        fixed = true
        [[springs]]
        between = ["a", "b"]
        length = 41.0
        stiffness = 250.0
        [[springs]]
        between = ["b", "c"]
        length = 40.0
        stiffness = 280.0
        [[springs]]
        between = ["a", "pin"]
        length = 86.0
        stiffness = 4.0
        [[torsions]]
        at = "b"
        between = ["a", "c"]
        rest_cos = -0.9
        stiffness = 2500.0
    "#;
    let truth = Scene::from_toml_str(text, "tether").unwrap_or_else(|e| panic!("{e}"));
    let mut structure = truth.structure();
    structure.springs.pop();
    structure.particles.pop();
    (truth, structure)
}

/// A diagnosed case: truth, tracks, diagnosis.
struct Case {
    name: String,
    truth: Scene,
    tracks: TrackTable,
    d: Diagnosis,
}

fn diagnose_case(name: &str, truth: Scene, structure: &Scene, seed: u64) -> Case {
    diagnose_case_at(name, truth, structure, SIGMA, seed)
}

/// [`diagnose_case`] with track noise `sigma` (px).
fn diagnose_case_at(name: &str, truth: Scene, structure: &Scene, sigma: f64, seed: u64) -> Case {
    let mut t = tracks(&truth, sigma, seed);
    // Only the structure's particles are tracked (a concealed anchor is not).
    t.points.retain(|p| structure.particle_id(&p.particle).is_some());
    let options = DiagnoseOptions {
        seed,
        ..DiagnoseOptions::default()
    };
    let d = diagnose(structure, &t, &options, &()).unwrap_or_else(|e| panic!("{name}: {e}"));
    eprintln!(
        "{name} (seed {seed}, {:.1} s): {:?}; multi-step base {:.2} final {:.2} px^2",
        d.seconds,
        d.findings
            .iter()
            .map(|f| (
                f.label.as_str(),
                f.parameters.iter().map(|p| p.value).collect::<Vec<_>>()
            ))
            .collect::<Vec<_>>(),
        d.base.costs.multi_step.sum_squares,
        d.final_model.costs.multi_step.sum_squares
    );
    for line in &d.localisation.summary {
        eprintln!("   {line}");
    }
    Case {
        name: name.into(),
        truth,
        tracks: t,
        d,
    }
}

fn run(name: &str, seed: u64) -> Case {
    let truth = scene(name);
    let structure = structure_of(name, &truth);
    diagnose_case(name, truth, &structure, seed)
}

impl Case {
    /// Asserts the findings' labels are exactly `labels` (any order).
    fn names_exactly(&self, labels: &[&str]) -> &Self {
        let mut got: Vec<&str> = self.d.findings.iter().map(|f| f.label.as_str()).collect();
        let mut want = labels.to_vec();
        got.sort_unstable();
        want.sort_unstable();
        assert_eq!(got, want, "{}: findings", self.name);
        self
    }

    /// The finding labelled `label` and its parameter `name`.
    fn parameter(&self, label: &str, name: &str) -> (&Finding, &FittedValue) {
        let f = self
            .d
            .findings
            .iter()
            .find(|f| f.label == label)
            .unwrap_or_else(|| panic!("{}: no {label}", self.name));
        let p = f
            .parameters
            .iter()
            .find(|p| p.name == name)
            .unwrap_or_else(|| panic!("{}: {label} has no {name}", self.name));
        (f, p)
    }

    /// The value of parameter `name` of the finding labelled `label`.
    fn value(&self, label: &str, name: &str) -> f64 {
        let (_, p) = self.parameter(label, name);
        assert!(
            p.std_error.is_some_and(|e| e.is_finite() && e >= 0.0),
            "{}: {label} {name} has no standard error",
            self.name
        );
        p.value
    }

    /// Asserts `|value - truth| <= tolerance * |truth|`.
    fn close(&self, label: &str, name: &str, truth: f64, tolerance: f64) -> &Self {
        let v = self.value(label, name);
        assert!(
            (v - truth).abs() <= tolerance * truth.abs(),
            "{}: {label} {name} = {v}, truth {truth} (tolerance {}%)",
            self.name,
            tolerance * 100.0
        );
        self
    }

    /// Asserts the fitted field is within 2% of the truth (as a vector).
    fn gravity(&self) -> &Self {
        let g = Vec2::new(
            self.value("uniform field (gravity)", "gravity_x"),
            self.value("uniform field (gravity)", "gravity_y"),
        );
        let t = self.truth.physics.gravity;
        assert!(
            (g - t).norm() <= 0.02 * t.norm(),
            "{}: gravity {g:?}, truth {t:?}",
            self.name
        );
        self
    }

    /// Asserts the fitted wall is within 1 px of the true one where the particles met it, with
    /// its restitution within 0.1.
    fn wall(&self, k: usize) -> &Self {
        let truth = &self.truth.physics.walls[k];
        let f = self
            .d
            .findings
            .iter()
            .filter(|f| f.effect == "wall")
            .nth(k)
            .unwrap_or_else(|| panic!("{}: no wall {k}", self.name));
        let get = |name: &str| {
            f.parameters
                .iter()
                .find(|p| p.name == name)
                .map(|p| p.value)
                .unwrap_or(f64::NAN)
        };
        let n = Vec2::new(get("normal_x"), get("normal_y"));
        let offset = get("offset");
        let region = f
            .seen
            .region
            .unwrap_or_else(|| panic!("{}: wall without a region", self.name));
        for corner in [Vec2::new(region[0], region[1]), Vec2::new(region[2], region[3])] {
            let on_true = corner - truth.normal * truth.signed_distance(corner);
            let miss = (n.dot(&on_true) - offset).abs();
            assert!(
                miss <= 1.0,
                "{}: wall {k} is {miss:.3} px off at {on_true:?}",
                self.name
            );
        }
        assert!(
            n.dot(&truth.normal) > 0.999,
            "{}: wall normal {n:?}, truth {:?}",
            self.name,
            truth.normal
        );
        let e = get("restitution");
        assert!(
            (e - truth.restitution).abs() <= 0.1,
            "{}: restitution {e}, truth {}",
            self.name,
            truth.restitution
        );
        self
    }

    /// Asserts the final multi-step cost is at most 1.2 times the true model's on the same
    /// tracks, and below the base model's.
    fn cost_near_truth(&self) -> &Self {
        let truth = scene_costs(&self.truth, &self.tracks).unwrap_or_else(|e| panic!("{}: {e}", self.name));
        let fin = self.d.final_model.costs.multi_step.sum_squares;
        eprintln!(
            "{}: final multi-step {fin:.3} px^2, truth {:.3}",
            self.name, truth.multi_step.sum_squares
        );
        assert!(
            fin <= 1.2 * truth.multi_step.sum_squares,
            "{}: final {fin}, truth {}",
            self.name,
            truth.multi_step.sum_squares
        );
        assert!(fin <= self.d.base.costs.multi_step.sum_squares);
        self
    }
}

fn check_scene(name: &str, seed: u64) {
    let c = run(name, seed);
    let t = &c.truth;
    match name {
        "concealed-gravity" => {
            c.names_exactly(&["uniform field (gravity)"]).gravity();
        }
        "concealed-drag" => {
            c.names_exactly(&["linear drag"])
                .close("linear drag", "drag", t.physics.drag, 0.1);
        }
        "concealed-damping" => {
            c.names_exactly(&["dashpots on every spring"]).close(
                "dashpots on every spring",
                "damping",
                t.physics.spring_damping,
                0.1,
            );
        }
        "concealed-local-damping" => {
            let truth = t.springs[1].damping.unwrap_or(f64::NAN);
            c.names_exactly(&["dashpot on spring b-c"])
                .close("dashpot on spring b-c", "damping", truth, 0.1);
        }
        "concealed-missing-spring" => {
            let s = t.springs.last().unwrap_or_else(|| panic!("no spring"));
            c.names_exactly(&["missing spring a-d"])
                .close(
                    "missing spring a-d",
                    "length",
                    s.rest_length.unwrap_or(f64::NAN),
                    0.05,
                )
                .close(
                    "missing spring a-d",
                    "stiffness",
                    s.stiffness.unwrap_or(f64::NAN),
                    0.05,
                );
        }
        "concealed-wall" => {
            c.names_exactly(&["wall"]).wall(0);
        }
        "concealed-gravity-damping" => {
            c.names_exactly(&["uniform field (gravity)", "dashpots on every spring"])
                .gravity()
                .close(
                    "dashpots on every spring",
                    "damping",
                    t.physics.spring_damping,
                    0.1,
                );
        }
        "concealed-gravity-floor" => {
            c.names_exactly(&["uniform field (gravity)", "wall"])
                .gravity()
                .wall(0);
        }
        _ => {
            c.names_exactly(&[]);
        }
    }
    c.cost_near_truth();
}

#[test]
fn clean_scenes_add_nothing() {
    for name in ["clean-triangle", "clean-pendulum"] {
        check_scene(name, 1);
    }
}

#[test]
fn concealed_drag_is_named_with_its_coefficient() {
    check_scene("concealed-drag", 2);
}

#[test]
fn concealed_local_damping_is_found_on_its_spring() {
    check_scene("concealed-local-damping", 1);
}

#[test]
fn concealed_gravity_and_floor_are_found_together() {
    check_scene("concealed-gravity-floor", 1);
}

#[test]
fn a_tether_to_an_unlisted_fixed_point_is_found() {
    let (truth, structure) = tether_scene();
    let c = diagnose_case("concealed-tether", truth, &structure, 1);
    let label = "tether of a to a fixed point";
    c.names_exactly(&[label])
        .close(label, "length", 86.0, 0.05)
        .close(label, "stiffness", 4.0, 0.05);
    let anchor = Vec2::new(c.value(label, "anchor_x"), c.value(label, "anchor_y"));
    assert!(
        (anchor - Vec2::new(40.0, 130.0)).norm() < 2.0,
        "anchor {anchor:?}"
    );
    assert!(c.d.findings[0].tether);
    c.cost_near_truth();
    // The diagnosed scene adds the anchor as a fixed particle with its spring, and renders.
    let fitted = &c.d.final_scene;
    assert_eq!(fitted.particles.len(), structure.particles.len() + 1);
    assert!(fitted.particles.last().is_some_and(|p| p.fixed));
    assert_eq!(fitted.springs.len(), structure.springs.len() + 1);
}

#[test]
fn the_report_and_the_diagnosed_scene_round_trip() {
    let c = run("concealed-gravity-floor", 3);
    let json = serde_json::to_value(&c.d).unwrap_or_else(|e| panic!("{e}"));
    let findings = json["findings"].as_array().cloned().unwrap_or_default();
    let effects: Vec<&str> = findings.iter().filter_map(|f| f["effect"].as_str()).collect();
    assert!(
        effects.contains(&"gravity") && effects.contains(&"wall"),
        "{effects:?}"
    );
    for f in &findings {
        assert!(
            f["evidence"]["held_out_cost_after"].as_f64() < f["evidence"]["held_out_cost_before"].as_f64()
        );
        assert!(f["evidence"]["score"].as_f64().is_some_and(|s| s > 0.0));
    }
    assert!(
        json["final"]["costs"]["multi_step"]["sum_squares"].as_f64()
            < json["base"]["costs"]["multi_step"]["sum_squares"].as_f64()
    );
    assert!(json["final"]["costs"]["one_step"].as_f64().is_some());
    assert!(json.get("final_scene").is_none());
    // fitted.toml: the physics in the scene format's own keys, and it simulates again.
    let text = c.d.final_scene.to_toml_string().unwrap_or_else(|e| panic!("{e}"));
    assert!(
        text.contains("[physics]") && text.contains("gravity") && text.contains("[[physics.walls]]"),
        "{text}"
    );
    let back = Scene::from_toml_str(&text, "fitted.toml").unwrap_or_else(|e| panic!("{e}"));
    let costs = scene_costs(&back, &c.tracks).unwrap_or_else(|e| panic!("{e}"));
    assert!(
        costs.multi_step.rms < 2.0 * SIGMA,
        "the diagnosed scene re-simulates with {} px RMS",
        costs.multi_step.rms
    );
    // The base model's residuals are localised on both particles, with the bounces as jolts.
    let loc = &c.d.localisation;
    assert!(!loc.jolts.is_empty());
    assert!(loc.particles.iter().all(|p| p.position_rms_over_noise > 10.0));
    assert_eq!(c.d.residuals.before.len(), c.d.residuals.frames.len());
}

#[test]
fn invalid_options_are_rejected() {
    let truth = scene("clean-triangle");
    let t = tracks(&truth, SIGMA, 1);
    let options = DiagnoseOptions {
        holdout_fraction: 0.9,
        ..DiagnoseOptions::default()
    };
    let e = diagnose(&truth.structure(), &t, &options, &())
        .map(|_| ())
        .unwrap_err();
    assert!(e.to_string().contains("0.9"), "{e}");
}

#[test]
#[ignore = "every scene over three seeds: several minutes"]
fn every_scene_over_three_seeds() {
    let names = [
        "concealed-gravity",
        "concealed-drag",
        "concealed-damping",
        "concealed-local-damping",
        "concealed-missing-spring",
        "concealed-wall",
        "concealed-gravity-damping",
        "concealed-gravity-floor",
        "clean-chain",
        "clean-pendulum",
        "clean-triangle",
    ];
    for seed in 1..=3 {
        for name in names {
            check_scene(name, seed);
        }
    }
}

#[test]
#[ignore = "debugging aid"]
fn explore() {
    let names = std::env::var("DIAG_SCENES").unwrap_or_else(|_| "concealed-wall".into());
    let seed: u64 = std::env::var("DIAG_SEED")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(1);
    for name in names.split(',') {
        let _ = run(name, seed);
    }
}

/// A lone ball of unit mass thrown from `position` with `velocity` (px, px/s) under a
/// downward field `gravity` (px/s²) above a horizontal floor at `floor` (px) with
/// restitution `restitution`, recorded `frames` frames at `fps` (20 substeps a frame).
#[allow(clippy::too_many_arguments)]
fn ball_over_a_floor(
    name: &str,
    fps: f64,
    frames: usize,
    position: [f64; 2],
    velocity: [f64; 2],
    gravity: f64,
    floor: f64,
    restitution: f64,
) -> Scene {
    let text = format!(
        r#"
        name = "{name}"
        [recording]
        fps = {fps}
        frames = {frames}
        substeps = 20
        [[particles]]
        id = "ball"
        mass = 1.0
        position = [{}, {}]
        velocity = [{}, {}]
        [physics]
        gravity = [0.0, {gravity}]
        [[physics.walls]]
        point = [0.0, {floor}]
        normal = [0.0, -1.0]
        restitution = {restitution}
    "#,
        position[0], position[1], velocity[0], velocity[1]
    );
    Scene::from_toml_str(&text, name).unwrap_or_else(|e| panic!("{e}"))
}

#[test]
fn a_lone_ball_gets_its_field_and_floor() {
    // One particle, no bond: nothing to fit but the start state until effects are added.
    let truth = ball_over_a_floor("ball", 30.0, 90, [60.0, 80.0], [40.0, 0.0], 900.0, 330.0, 0.75);
    let c = diagnose_case("ball", truth.clone(), &truth.structure(), 1);
    c.names_exactly(&["uniform field (gravity)", "wall"])
        .gravity()
        .wall(0)
        .cost_near_truth();
}

/// A ball rolling along a shelf for the first `held` gaps, then falling under a field onto a
/// floor (the real bouncing-ball recording's story): the truth scene of the fall (from the
/// shelf's edge at frame `held`), and tracks with the rolling frames prepended.
fn shelf_ball(held: usize, sigma: f64, seed: u64) -> (Scene, TrackTable) {
    let fps = 29.97;
    let (x0, y0, vx) = (24.0, 16.0, 100.0);
    let frames = 87;
    let fall = ball_over_a_floor(
        "shelf-ball",
        fps,
        frames - held,
        [x0 + vx * held as f64 / fps, y0],
        [vx, 0.0],
        1600.0,
        360.0,
        0.6,
    );
    let mut t = tracks(&fall, sigma, seed);
    for p in &mut t.points {
        p.frame += held;
    }
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed ^ 0x5e1f);
    let normal = rand_distr::Normal::new(0.0, sigma).unwrap_or_else(|e| panic!("{e}"));
    use rand_distr::Distribution;
    for k in 0..held {
        t.points.push(physfit_tracks::TrackPoint::new(
            k,
            "ball",
            x0 + vx * k as f64 / fps + normal.sample(&mut rng),
            y0 + normal.sample(&mut rng),
        ));
    }
    t.points.sort_by_key(|p| p.frame);
    (fall, t)
}

#[test]
fn a_ball_held_on_a_shelf_is_analysed_from_its_release() {
    // Rolling for 5 frames, then a fall and bounces: the support is reported, the shelf
    // frames are left out (a simulation started on the shelf would fall through it), and the
    // fall still gives the field within 2% and the floor within 1 px.
    let held = 5;
    let (fall, tracks) = shelf_ball(held, SIGMA, 1);
    let d = diagnose(&fall.structure(), &tracks, &DiagnoseOptions::default(), &())
        .unwrap_or_else(|e| panic!("{e}"));
    let left_out = d
        .warnings
        .iter()
        .find(|w| w.contains("supported from the first frame"))
        .unwrap_or_else(|| panic!("no warning about the shelf frames: {:?}", d.warnings));
    assert!(left_out.starts_with("frames 0-"), "{left_out}");
    let start = d.window[0];
    assert!(
        (held.saturating_sub(1)..=held + 2).contains(&start),
        "the analysis starts at frame {start}, the ball leaves the shelf at {held}"
    );
    let case = Case {
        name: "shelf-ball".into(),
        truth: fall,
        tracks,
        d,
    };
    case.names_exactly(&["uniform field (gravity)", "wall"])
        .gravity()
        .wall(0);
}

#[test]
fn a_short_toss_of_eleven_frames_gets_its_field() {
    // The ball-toss recording's length: 11 frames, fewer than the 20 the first shooting span
    // asks for (that once panicked on a clamp whose minimum exceeded its maximum).
    let truth = ball_over_a_floor(
        "toss",
        15.15,
        11,
        [130.0, 200.0],
        [150.0, -600.0],
        4000.0,
        2000.0,
        0.5,
    );
    let c = diagnose_case("toss", truth.clone(), &truth.structure(), 1);
    c.names_exactly(&["uniform field (gravity)"]).gravity();
}

mod faint;
mod issue_21;
mod stiff;

/// The jolts `scan_jolts` sees, with no model, in `truth`'s tracks of its particle `ball`.
fn jolts_of_ball(truth: &Scene) -> Vec<Jolt> {
    let mut t = tracks(truth, SIGMA, 1);
    t.points.retain(|p| p.particle == "ball");
    let mut structure = truth.structure();
    structure.particles.retain(|p| p.id == "ball");
    structure.springs.clear();
    let obs = Observations::from_tracks(&t, &structure, None).unwrap_or_else(|e| panic!("{e}"));
    jolts::scan_jolts(&obs, None).jolts
}

#[test]
fn a_stiff_tether_turning_a_ball_round_makes_no_jolts() {
    // A radial oscillation of 16 frames' period (sqrt(2 S / m) = 55 /s at 137 frames/s) and
    // 12 px amplitude: the velocity reverses every 8 frames, smoothly; the means' jump is
    // hundreds of noises at each turn.
    let text = r#"
        name = "stiff-tether"
        recording = { fps = 137.0, frames = 200, substeps = 10 }
        particles = [
            { id = "ball", mass = 1.0, position = [100.0, 112.0], velocity = [20.0, 0.0] },
            { id = "pin", mass = 1.0, position = [100.0, 400.0], fixed = true },
        ]
        springs = [{ between = ["ball", "pin"], length = 300.0, stiffness = 1500.0 }]
    "#;
    let truth = Scene::from_toml_str(text, "stiff-tether").unwrap_or_else(|e| panic!("{e}"));
    let found = jolts_of_ball(&truth);
    // A turn in the last gap the means reach (frame 194 of 200) is cut short: its means' jump
    // is smaller, and the three local jumps allowed for a bounce a gap off leave it within
    // the noise at this track noise (0.08 px). Everywhere else the turns are no jolts.
    let inner: Vec<&Jolt> = found.iter().filter(|j| j.frame < 194).collect();
    assert!(inner.is_empty(), "smooth turns taken for bounces: {inner:?}");
    assert!(found.len() <= 1, "smooth turns taken for bounces: {found:?}");
    // The same ball bouncing off a floor: every bounce is still a jolt.
    let bounce = ball_over_a_floor(
        "bounce",
        137.0,
        200,
        [60.0, 80.0],
        [40.0, 0.0],
        900.0,
        200.0,
        0.75,
    );
    let found = jolts_of_ball(&bounce);
    assert!(found.len() >= 2, "bounces missed: {found:?}");
    // 21 frames, the bounce in the gap after frame 16: the means reach gap 15 at most, a gap
    // before the bounce, whose own local jump is not the impulse.
    let late = ball_over_a_floor("late", 84.0, 21, [60.0, 80.0], [0.0, 840.0], 0.0, 245.0, 0.75);
    let found = jolts_of_ball(&late);
    assert_eq!(found.len(), 1, "late bounce missed: {found:?}");
}

#[test]
fn a_shallow_bounce_at_speed_along_the_wall_proposes_the_wall() {
    // 300 px/s along the floor, 12 px/s into it: the impulse (18 px/s, about seven jolt
    // noise scales) is known in direction to about 8 degrees, and 8 degrees of 300 px/s
    // (40 px/s) hide the normal velocity's reversal; the line through the bounce, tilted as
    // much, would be crossed hundreds of px further on.
    let truth = ball_over_a_floor("shallow", 40.0, 85, [20.0, 296.0], [300.0, 12.0], 0.0, 300.0, 0.5);
    let found = jolts_of_ball(&truth);
    assert_eq!(found.len(), 1, "the bounce: {found:?}");
    let mut t = tracks(&truth, SIGMA, 1);
    t.points.retain(|p| p.particle == "ball");
    let obs = Observations::from_tracks(&t, &truth.structure(), None).unwrap_or_else(|e| panic!("{e}"));
    let walls = jolts::propose_walls(&found, &obs);
    assert_eq!(walls.len(), 1, "{walls:?}");
    let [angle, offset, _] = walls[0].params;
    let n = Vec2::new(angle.cos(), angle.sin());
    // The floor: n = (0, -1), n . x = -300 px; the normal within 2 degrees (the fan of
    // lines no centre crosses is 3.4 degrees wide), the line within 1 px at the bounce.
    assert!(
        n.dot(&Vec2::new(0.0, -1.0)) > 2f64.to_radians().cos(),
        "normal {n:?}"
    );
    let x = found[0].position[0];
    let y = (offset - n.x * x) / n.y;
    assert!(
        (y - 300.0).abs() < 1.0,
        "the line is at y = {y:.2} px at the bounce (x = {x:.1} px)"
    );
}

#[test]
fn held_out_blocks_never_take_every_frame_after_a_bounce() {
    // 28 frames, a bounce at frame 19: the last block (20-27) may not be all held out.
    let mut held = vec![false; 28];
    for h in &mut held[20..] {
        *h = true;
    }
    assert!(starves_a_jolt(&held, &[19]));
    assert!(!starves_a_jolt(&held, &[]));
    // Held out before the bounce, with 10 fitted frames on either side: fine.
    let mut held = vec![false; 28];
    for h in &mut held[10..19] {
        *h = true;
    }
    assert!(!starves_a_jolt(&held, &[19]));
    // A stretch of two frames between two bounces cannot keep three fitted frames: not
    // counted against the mask.
    let held = vec![false; 28];
    assert!(!starves_a_jolt(&held, &[10, 12]));
}

#[test]
fn every_finding_reports_its_inclusion_over_resampled_frames() {
    // A clear field over 200 frames: found, and kept by every resample of the frames.
    let truth = scene("concealed-gravity");
    let structure = truth.structure();
    let data = tracks(&truth, SIGMA, 7);
    let d = diagnose(&structure, &data, &DiagnoseOptions::default(), &()).expect("diagnosis");
    assert!(!d.findings.is_empty(), "nothing found");
    for f in &d.findings {
        let r = f.inclusion_rate.expect("an inclusion rate");
        assert!((0.0..=1.0).contains(&r), "{}: {r}", f.label);
        assert!(
            r > 0.95,
            "{}: a clear finding kept by only {r} of the resamples",
            f.label
        );
    }
}
