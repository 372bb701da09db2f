//! Issue 22: contacts and drag per body as diagnosis candidates, each concealed in a rendered
//! scene, tracked and diagnosed from the structure alone, found back within 5 % with nothing
//! else added, and the fitted scene rendered again.
//!
//! * A ball bounces along a floor with Coulomb friction: physfit must name the field, the
//!   floor and the friction at it. The friction, restitution and launch speed are drawn from
//!   fixed seeds; a frictionless ball gets no friction.
//! * A puck slides to rest on a floor the structure gives (with the field): physfit must name
//!   the friction alone; on a frictionless floor, nothing.
//! * Two bodies of masses 1 and 3 fly through one medium (`body_drag` or
//!   `body_quadratic_drag`, not scaled by the mass): physfit must name the field and that drag
//!   per body; the same pair under a drag per unit mass gets the per-mass drag.
//! * A pendulum on a rope listed in the structure: the field alone, `g / L` within 1 %.

use std::path::Path;

use physfit_model::scene::compare_scenes;
use physfit_model::Scene;
use serde_json::Value;

use crate::util::{physfit, tempdir, write};

/// Deterministic draws in `[lo, hi)` (a small linear congruential sequence: seeded and
/// dependency-free).
fn draw(seed: &mut u64, lo: f64, hi: f64) -> f64 {
    *seed = seed
        .wrapping_mul(6364136223846793005)
        .wrapping_add(1442695040888963407);
    lo + (*seed >> 11) as f64 / (1u64 << 53) as f64 * (hi - lo)
}

/// A rendered scene's head: its `name`, 100 frames/s for `frames` frames (10 substeps), a
/// `width` x `height` picture with particles of radius 5 px and noise 2 grey levels, seeded.
fn head(name: &str, frames: usize, width: u32, height: u32, seed: u64) -> String {
    format!(
        r#"name = "{name}"
[recording]
fps = 100.0
frames = {frames}
substeps = 10
[render]
width = {width}
height = {height}
radius = 5.0
background = 20
foreground = 235
noise = 2.0
seed = {seed}
"#
    )
}

/// A particle launched sideways at `vx` px/s from (60, `y`) px over a floor at y = 340 px
/// with restitution `e` and Coulomb friction `mu`, under a field of 1000 px/s², for `frames`
/// frames at 100 frames/s.
fn floor_scene(name: &str, frames: usize, y: f64, vx: f64, e: f64, mu: f64, seed: u64) -> String {
    let friction = if mu > 0.0 {
        format!("\nfriction = {mu}")
    } else {
        String::new()
    };
    ball_over_floor(
        name,
        100.0,
        frames,
        y,
        vx,
        &format!("restitution = {e}{friction}"),
        seed,
    )
}

/// A ball launched sideways at `vx` px/s from (60, `y`) px over a floor at y = 340 px under a
/// field of 1000 px/s², `frames` frames at `fps` frames/s: `floor` is the wall's contact keys
/// (a `restitution` and `friction`, or a bumper's `stiffness` and `damping`).
fn ball_over_floor(name: &str, fps: f64, frames: usize, y: f64, vx: f64, floor: &str, seed: u64) -> String {
    let head = head(name, frames, 480, 400, seed).replace("fps = 100.0", &format!("fps = {fps}"));
    format!(
        r#"{head}[[particles]]
id = "ball"
mass = 1.0
position = [60.0, {y}]
velocity = [{vx}, 0.0]
[physics]
gravity = [0.0, 1000.0]
[[physics.walls]]
point = [0.0, 340.0]
normal = [0.0, -1.0]
{floor}
"#
    )
}

/// Runs `physfit -q` with `args`, asserting success.
fn run(args: &[&dyn AsRef<std::ffi::OsStr>]) {
    let mut cmd = physfit();
    cmd.arg("-q");
    for a in args {
        cmd.arg(a);
    }
    cmd.assert().success();
}

/// Renders, tracks and diagnoses `scene` (from its structure alone) in `dir`: the truth, the
/// structure, `report.json` and the fitted scene.
fn diagnose_rendered(dir: &Path, scene: &str) -> (Scene, Scene, Value, Scene) {
    diagnose_rendered_from(dir, scene, Scene::structure)
}

/// [`diagnose_rendered`] from the structure `given` makes of the truth.
fn diagnose_rendered_from(
    dir: &Path,
    scene: &str,
    given: impl Fn(&Scene) -> Scene,
) -> (Scene, Scene, Value, Scene) {
    let path = write(dir, "scene.toml", scene);
    let out = dir.join("render");
    run(&[&"render", &path, &"--out", &out]);
    let tracks = out.join("tracks.csv");
    let structure = dir.join("given.toml");
    given(&Scene::load(&path).expect("scene"))
        .save(&structure)
        .expect("structure");
    run(&[
        &"track",
        &out.join("frames"),
        &"--out",
        &tracks,
        &"--structure",
        &structure,
    ]);
    let diag = dir.join("diag");
    run(&[&"diagnose", &tracks, &"--structure", &structure, &"--out", &diag]);
    let report: Value =
        serde_json::from_str(&std::fs::read_to_string(diag.join("report.json")).expect("report.json"))
            .expect("report.json is JSON");
    // The fitted scene renders again, its friction included.
    run(&[&"render", &diag.join("fitted.toml"), &"--out", &dir.join("again")]);
    (
        Scene::load(&path).expect("scene"),
        Scene::load(&structure).expect("structure"),
        report,
        Scene::load(&diag.join("fitted.toml")).expect("fitted.toml"),
    )
}

/// The scene's friction, drawn from `seed` (0 for the frictionless control), is diagnosed
/// back within 5 % with exactly the field, the floor and the friction found.
fn check_friction(seed: u64, frictionless: bool) {
    let mut s = seed;
    let mu = if frictionless {
        0.0
    } else {
        draw(&mut s, 0.05, 0.2)
    };
    let e = draw(&mut s, 0.6, 0.9);
    // The ball still slides after its first bounce (which takes `mu (1 + e) 400` px/s): a
    // friction that stops it at once is only bounded below by the tracks. Without friction
    // it stays in view for the 3 s.
    let vx = if frictionless {
        draw(&mut s, 60.0, 120.0)
    } else {
        mu * (1.0 + e) * 400.0 * draw(&mut s, 1.3, 1.8)
    };
    let dir = tempdir();
    // 80 px above the floor: it meets it at 400 px/s, 3 s.
    let scene = floor_scene("concealed-floor-friction", 300, 260.0, vx, e, mu, seed);
    let (truth, structure, report, fitted) = diagnose_rendered(dir.path(), &scene);
    let c = compare_scenes(&fitted, &truth, &structure);
    let friction = c
        .values
        .iter()
        .find(|v| v.item == "wall 1" && v.name == "friction");
    println!(
        "seed {seed}: mu {mu:.4}, e {e:.3}, vx {vx:.1} px/s: found {:?}, friction {:?}, verdict {}",
        c.effects_found,
        friction.map(|v| (v.fitted, v.relative_error)),
        report["verdict"]["text"]
    );
    assert!(c.missed.is_empty(), "missed {:?}", c.missed);
    assert!(c.spurious.is_empty(), "falsely added {:?}", c.spurious);
    let names: Vec<&str> = report["findings"]
        .as_array()
        .expect("findings")
        .iter()
        .filter_map(|f| f["effect"].as_str())
        .collect();
    if frictionless {
        assert!(friction.is_none(), "{:?}", c.values);
        assert!(!names.contains(&"wall_friction"), "{names:?}");
        return;
    }
    let error = friction
        .and_then(|v| v.relative_error)
        .expect("a fitted friction");
    assert!(error.abs() < 0.05, "friction {:?} against {mu}", friction);
    // Its own "where it was seen" text names the bounces that lost tangential speed.
    let found = report["findings"]
        .as_array()
        .and_then(|fs| fs.iter().find(|f| f["effect"] == "wall_friction"))
        .expect("a wall_friction finding");
    let text = found["seen"]["text"].as_str().unwrap_or_default();
    assert!(text.contains("bounce(s) on wall 1 lose"), "{text}");
}

#[test]
fn friction_at_a_floor_is_found_within_5_percent_seed_1() {
    check_friction(1, false);
}

#[test]
fn friction_at_a_floor_is_found_within_5_percent_seed_2() {
    check_friction(2, false);
}

#[test]
fn friction_at_a_floor_is_found_within_5_percent_seed_3() {
    check_friction(3, false);
}

#[test]
fn a_frictionless_floor_gets_no_friction() {
    check_friction(4, true);
}

/// Two bodies of masses 1 and 3 thrown towards each other under a field of 300 px/s² through
/// a medium given by `medium` (a `[physics]` line), 2 s at 100 frames/s.
fn medium_scene(medium: &str, seed: u64) -> String {
    let head = head("concealed-body-drag", 200, 480, 480, seed);
    format!(
        r#"{head}[[particles]]
id = "light"
mass = 1.0
position = [100.0, 80.0]
velocity = [120.0, -100.0]
[[particles]]
id = "heavy"
mass = 3.0
position = [300.0, 80.0]
velocity = [-120.0, -100.0]
[physics]
gravity = [0.0, 300.0]
{medium}
"#
    )
}

/// The medium `key = value` (drawn from `seed` in `[lo, hi)`) is diagnosed back within 5 %
/// on every body, with exactly the field and it found.
fn check_medium(seed: u64, key: &str, lo: f64, hi: f64) {
    let mut s = seed;
    let value = draw(&mut s, lo, hi);
    let dir = tempdir();
    let (truth, structure, report, fitted) =
        diagnose_rendered(dir.path(), &medium_scene(&format!("{key} = {value}"), seed));
    let c = compare_scenes(&fitted, &truth, &structure);
    println!(
        "seed {seed}: {key} {value:.6}: found {:?}, verdict {}",
        c.effects_found, report["verdict"]["text"]
    );
    assert!(c.missed.is_empty(), "missed {:?}", c.missed);
    assert!(c.spurious.is_empty(), "falsely added {:?}", c.spurious);
    let name = if key == "drag" { "drag" } else { key };
    let errors: Vec<f64> = c
        .values
        .iter()
        .filter(|v| v.name == name)
        .filter_map(|v| v.relative_error)
        .collect();
    println!("  {name} relative errors {errors:?}");
    assert!(!errors.is_empty(), "{:?}", c.values);
    assert!(errors.iter().all(|e| e.abs() < 0.05), "{errors:?}");
}

#[test]
fn linear_drag_per_body_is_found_within_5_percent() {
    check_medium(5, "body_drag", 0.3, 1.2);
}

#[test]
fn quadratic_drag_per_body_is_found_within_5_percent() {
    check_medium(6, "body_quadratic_drag", 0.001, 0.005);
}

#[test]
fn drag_per_unit_mass_on_bodies_of_different_masses_stays_per_mass() {
    check_medium(7, "drag", 0.2, 0.8);
}

/// A pendulum on a rope of length `length` px from a fixed pivot, released at 30 degrees,
/// under a field `g` px/s², 3 s at 100 frames/s.
fn rope_scene(g: f64, length: f64, seed: u64) -> String {
    let (s, c) = 30f64.to_radians().sin_cos();
    let head = head("rope-pendulum", 300, 400, 400, seed);
    format!(
        r#"{head}[[particles]]
id = "pivot"
mass = 1.0
position = [200.0, 60.0]
fixed = true
[[particles]]
id = "bob"
mass = 1.0
position = [{x}, {y}]
[physics]
gravity = [0.0, {g}]
[[physics.ropes]]
between = ["pivot", "bob"]
length = {length}
"#,
        x = 200.0 + length * s,
        y = 60.0 + length * c,
    )
}

#[test]
fn a_rope_in_the_structure_is_held_and_the_pendulum_gives_g_over_l_within_1_percent() {
    let seed = 8;
    let mut s = seed;
    let g = draw(&mut s, 300.0, 900.0);
    let length = draw(&mut s, 120.0, 250.0);
    let dir = tempdir();
    let (truth, structure, report, fitted) = diagnose_rendered(dir.path(), &rope_scene(g, length, seed));
    // The structure keeps the rope (a constraint, like a bond), so the fit holds it.
    assert_eq!(structure.physics.ropes, truth.physics.ropes);
    let c = compare_scenes(&fitted, &truth, &structure);
    let found = fitted.physics.gravity.norm();
    println!(
        "rope pendulum: g {g:.3}, L {length:.3}: found {:?}, g {found:.4}, g/L {:.5} against {:.5}, verdict {}",
        c.effects_found,
        found / length,
        g / length,
        report["verdict"]["text"]
    );
    assert_eq!(c.effects_found, ["gravity"]);
    assert!(c.missed.is_empty() && c.spurious.is_empty(), "{c:?}");
    assert!(
        (found / g - 1.0).abs() < 0.01,
        "g/L {} against {}",
        found / length,
        g / length
    );
}

/// A puck launched along the floor it rests on (restitution 0.5) with friction `mu` drawn
/// from `seed` (0 for the control; it stops after `v0^2 / (2 mu g)` px), 2 s, diagnosed back
/// within 5 % from a structure that gives the field and the floor (and nothing else added).
fn check_sliding(seed: u64, frictionless: bool) {
    let mut s = seed;
    let mu = if frictionless { 0.0 } else { draw(&mut s, 0.1, 0.4) };
    let v0 = draw(&mut s, 60.0, 200.0);
    let dir = tempdir();
    // The structure knows the field and the floor; the floor's friction is concealed.
    let given = |truth: &Scene| {
        let mut given = truth.structure();
        given.physics.gravity = truth.physics.gravity;
        given.physics.walls = truth
            .physics
            .walls
            .iter()
            .map(|w| w.clone().with_friction(0.0))
            .collect();
        given
    };
    let scene = floor_scene("sliding-puck", 200, 340.0, v0, 0.5, mu, seed);
    let (truth, given, _, fitted) = diagnose_rendered_from(dir.path(), &scene, given);
    let c = compare_scenes(&fitted, &truth, &given);
    let found = fitted.physics.walls.first().map(|w| w.friction);
    println!(
        "sliding seed {seed}: mu {mu:.4}, v0 {v0:.1} px/s (stops after {:.1} px): found {:?}, friction {found:?}",
        v0 * v0 / (2.0 * mu * 1000.0),
        c.effects_found
    );
    assert!(c.missed.is_empty(), "missed {:?}", c.missed);
    assert!(c.spurious.is_empty(), "falsely added {:?}", c.spurious);
    if !frictionless {
        let found = found.expect("the floor");
        assert!((found / mu - 1.0).abs() < 0.05, "friction {found} against {mu}");
    }
}

#[test]
fn sliding_to_rest_on_a_given_floor_gives_its_friction_within_5_percent() {
    check_sliding(9, false);
}

#[test]
fn sliding_on_a_frictionless_given_floor_adds_nothing() {
    check_sliding(10, true);
}

#[test]
fn sliding_to_rest_on_a_given_floor_gives_its_friction_within_5_percent_seed_11() {
    check_sliding(11, false);
}

/// [`ball_over_floor`] for 3 s: a ball dropped from (60, `y`) px at `fps` frames/s.
fn drop_scene(name: &str, fps: f64, y: f64, vx: f64, floor: &str, seed: u64) -> String {
    ball_over_floor(name, fps, (3.0 * fps).round() as usize, y, vx, floor, seed)
}

/// The report's effect names.
fn finding_names(report: &Value) -> Vec<String> {
    report["findings"]
        .as_array()
        .expect("findings")
        .iter()
        .filter_map(|f| f["effect"].as_str().map(String::from))
        .collect()
}

/// A ball bouncing on a spring bumper floor (unit mass) whose contact time (2.5-5 frames)
/// and restitution (0.6-0.85) are drawn from `seed`, dropped from 100-150 px (impacts from
/// 450-550 px/s down to a fifth of that): physfit must swap the rigid floor the bounces
/// first propose for the bumper, with its stiffness, damping and line within 5 %, and
/// nothing else but the field.
fn check_bumper(seed: u64) {
    let mut s = seed;
    let time = draw(&mut s, 0.025, 0.05);
    let e: f64 = draw(&mut s, 0.6, 0.85);
    let drop = draw(&mut s, 100.0, 150.0);
    let vx = draw(&mut s, 30.0, 70.0);
    // `e = exp(-zeta pi / sqrt(1 - zeta^2))`, the damped contact time `pi / (w sqrt(1 -
    // zeta^2))` with `w = sqrt(2 S / m)`, `c = 2 zeta sqrt(2 S m)`.
    let ln = e.ln();
    let zeta = -ln / (std::f64::consts::PI.powi(2) + ln * ln).sqrt();
    let w = std::f64::consts::PI / (time * (1.0 - zeta * zeta).sqrt());
    let (stiffness, damping) = (w * w / 2.0, 2.0 * zeta * w);
    let floor = format!("stiffness = {stiffness}\ndamping = {damping}");
    let dir = tempdir();
    let scene = drop_scene("concealed-bumper", 100.0, 340.0 - drop, vx, &floor, seed);
    let (truth, structure, report, fitted) = diagnose_rendered(dir.path(), &scene);
    let c = compare_scenes(&fitted, &truth, &structure);
    let value = |name: &str| {
        c.values
            .iter()
            .find(|v| v.item == "wall 1" && v.name == name)
            .cloned()
    };
    let impact = (2.0 * 1000.0 * drop).sqrt();
    let depth = impact / w;
    println!(
        "bumper seed {seed}: S {stiffness:.1}, c {damping:.3} (contact {time:.4} s, e {e:.3}), impact {impact:.1} px/s (deepest {depth:.2} px): found {:?}, S {:?}, c {:?}, line {:?}, verdict {}",
        c.effects_found,
        value("stiffness").map(|v| (v.fitted, v.relative_error)),
        value("damping").map(|v| (v.fitted, v.relative_error)),
        value("position").and_then(|v| v.error),
        report["verdict"]["text"]
    );
    assert!(c.missed.is_empty(), "missed {:?}", c.missed);
    assert!(c.spurious.is_empty(), "falsely added {:?}", c.spurious);
    for name in ["stiffness", "damping"] {
        let v = value(name).expect(name);
        let error = v.relative_error.expect("a relative error");
        assert!(error.abs() < 0.05, "{name} {v:?}");
    }
    // The line within 5 % of the deepest penetration at the first impact.
    let line = value("position").and_then(|v| v.error).expect("the line");
    assert!(line < 0.05 * depth, "line {line} px off, deepest {depth} px");
    let found = report["findings"]
        .as_array()
        .and_then(|fs| fs.iter().find(|f| f["effect"] == "bumper"))
        .expect("a bumper finding");
    let text = found["seen"]["text"].as_str().unwrap_or_default();
    assert!(
        text.contains("turning point moves with the impact speed"),
        "{text}"
    );
}

#[test]
fn a_spring_bumper_is_found_within_5_percent_seed_12() {
    check_bumper(12);
}

#[test]
fn a_spring_bumper_is_found_within_5_percent_seed_13() {
    check_bumper(13);
}

#[test]
fn a_spring_bumper_is_found_within_5_percent_seed_14() {
    check_bumper(14);
}

/// A ball bouncing on a rigid floor (restitution 0.5-0.9 and drop height 60-150 px drawn
/// from `seed`) at `fps` frames/s stays a rigid wall: the field and the wall, no bumper.
fn check_rigid_floor(seed: u64, fps: f64) {
    let mut s = seed;
    let e = draw(&mut s, 0.5, 0.9);
    let drop = draw(&mut s, 60.0, 150.0);
    let vx = draw(&mut s, 30.0, 70.0);
    let dir = tempdir();
    let scene = drop_scene(
        "rigid-floor",
        fps,
        340.0 - drop,
        vx,
        &format!("restitution = {e}"),
        seed,
    );
    let (truth, structure, report, fitted) = diagnose_rendered(dir.path(), &scene);
    let c = compare_scenes(&fitted, &truth, &structure);
    let names = finding_names(&report);
    println!(
        "rigid floor seed {seed} at {fps} frames/s: e {e:.3}, drop {drop:.1} px: found {:?}, findings {names:?}, verdict {}",
        c.effects_found, report["verdict"]["text"]
    );
    assert!(!names.iter().any(|n| n == "bumper"), "{names:?}");
    assert!(fitted.physics.walls.iter().all(|w| !w.is_bumper()));
    assert!(c.missed.is_empty() && c.spurious.is_empty(), "{c:?}");
}

#[test]
fn a_rigid_floor_at_100_frames_per_second_is_no_bumper() {
    check_rigid_floor(15, 100.0);
}

#[test]
fn a_rigid_floor_at_50_frames_per_second_is_no_bumper() {
    check_rigid_floor(16, 50.0);
}

#[test]
fn a_rigid_floor_at_240_frames_per_second_is_no_bumper() {
    check_rigid_floor(17, 240.0);
}

/// [`rope_scene`]'s pendulum, diagnosed from a structure without its rope (or field): it is
/// found as a rope with `g / L` within 1 % and its length within 5 %, and nothing else added.
fn check_unlisted_rope(seed: u64) {
    let mut s = seed;
    let g = draw(&mut s, 300.0, 900.0);
    let length = draw(&mut s, 120.0, 250.0);
    let dir = tempdir();
    let without_rope = |truth: &Scene| {
        let mut given = truth.structure();
        given.physics.ropes.clear();
        given
    };
    let (truth, given, report, fitted) =
        diagnose_rendered_from(dir.path(), &rope_scene(g, length, seed), without_rope);
    assert!(given.physics.ropes.is_empty());
    let c = compare_scenes(&fitted, &truth, &given);
    let found = fitted.physics.gravity.norm();
    let rope = fitted.physics.ropes.first().map(|r| r.length);
    let names = finding_names(&report);
    println!(
        "unlisted rope seed {seed}: g {g:.3}, L {length:.3}: findings {names:?}, g {found:.4}, rope {rope:?}, g/L {:.5} against {:.5}, verdict {}",
        found / rope.unwrap_or(f64::NAN),
        g / length,
        report["verdict"]["text"]
    );
    assert!(c.missed.is_empty(), "missed {:?}", c.missed);
    assert!(c.spurious.is_empty(), "falsely added {:?}", c.spurious);
    assert!(names.contains(&"rope".to_string()), "{names:?}");
    assert_eq!(fitted.physics.ropes.len(), 1, "{:?}", fitted.physics.ropes);
    let rope = rope.expect("a rope");
    assert!((rope / length - 1.0).abs() < 0.05, "rope {rope} against {length}");
    let ratio = found / rope / (g / length);
    assert!(
        (ratio - 1.0).abs() < 0.01,
        "g/L off by {:.3} %",
        100.0 * (ratio - 1.0)
    );
    // Its own "where it was seen" text.
    let text = seen_of(&report, "rope");
    assert!(text.contains("within the noise: a rigid rope"), "{text}");
}

/// The "where it was seen" text of `report`'s first finding named `effect`.
fn seen_of(report: &Value, effect: &str) -> String {
    report["findings"]
        .as_array()
        .and_then(|fs| fs.iter().find(|f| f["effect"] == effect))
        .and_then(|f| f["seen"]["text"].as_str())
        .unwrap_or_default()
        .to_string()
}

#[test]
fn an_unlisted_rope_is_found_as_a_rope_with_g_over_l_within_1_percent_seed_12() {
    check_unlisted_rope(12);
}

#[test]
fn an_unlisted_rope_is_found_as_a_rope_with_g_over_l_within_1_percent_seed_13() {
    check_unlisted_rope(13);
}

#[test]
fn an_unlisted_rope_is_found_as_a_rope_with_g_over_l_within_1_percent_seed_14() {
    check_unlisted_rope(14);
}

/// A cart on a rail at `angle` degrees (image axes, y down) through a fixed anchor at
/// (80, 150) px, pulled by a spring `S (d - L)^2` to it, released at rest `amplitude` px
/// beyond the spring's rest length, under a field of 500 px/s² down, with Coulomb friction
/// `mu` on the rail, 3 s at 100 frames/s.
fn rail_scene(angle: f64, stiffness: f64, rest: f64, amplitude: f64, mu: f64, seed: u64) -> String {
    let (s, c) = angle.to_radians().sin_cos();
    let head = head("cart-on-rail", 300, 480, 400, seed);
    let d = rest + amplitude;
    format!(
        r#"{head}[[particles]]
id = "anchor"
mass = 1.0
position = [80.0, 150.0]
fixed = true
[[particles]]
id = "cart"
mass = 1.0
position = [{x}, {y}]
[[springs]]
between = ["anchor", "cart"]
length = {rest}
stiffness = {stiffness}
[physics]
gravity = [0.0, 500.0]
[[physics.rails]]
particle = "cart"
point = [80.0, 150.0]
direction = [{c}, {s}]
friction = {mu}
"#,
        x = 80.0 + d * c,
        y = 150.0 + d * s,
    )
}

/// A cart on a rail (angle, spring and friction drawn from `seed`; no friction when
/// `frictionless`), diagnosed from a structure that gives the field and the spring but not
/// the rail: the rail is found with its direction within 1 degree, its line within a pixel,
/// the spring within 5 % and the friction within 5 %, and nothing else added.
fn check_rail(seed: u64, frictionless: bool) {
    let mut s = seed;
    let angle = draw(&mut s, -20.0, 20.0);
    let stiffness = draw(&mut s, 20.0, 60.0);
    let rest = draw(&mut s, 120.0, 180.0);
    let amplitude = draw(&mut s, 40.0, 90.0);
    let mu = if frictionless {
        0.0
    } else {
        draw(&mut s, 0.02, 0.1)
    };
    let dir = tempdir();
    // The structure knows the field (an air track's cart is weighed on a known g); the rail
    // is concealed.
    let given = |truth: &Scene| {
        let mut given = truth.structure();
        given.physics.gravity = truth.physics.gravity;
        given.physics.rails.clear();
        given
    };
    let scene = rail_scene(angle, stiffness, rest, amplitude, mu, seed);
    let (truth, given, report, fitted) = diagnose_rendered_from(dir.path(), &scene, given);
    assert!(given.physics.rails.is_empty());
    let c = compare_scenes(&fitted, &truth, &given);
    let value = |name: &str| c.values.iter().find(|v| v.item == "rail cart" && v.name == name);
    let names = finding_names(&report);
    println!(
        "rail seed {seed}: angle {angle:.3} deg, S {stiffness:.3}, L {rest:.2}, amplitude {amplitude:.1} px, mu {mu:.4}: findings {names:?}, direction {:?}, position {:?}, friction {:?}, verdict {}",
        value("direction").map(|v| (v.fitted, v.error)),
        value("position").and_then(|v| v.error),
        value("friction").map(|v| (v.fitted, v.relative_error)),
        report["verdict"]["text"]
    );
    assert!(c.missed.is_empty(), "missed {:?}", c.missed);
    assert!(c.spurious.is_empty(), "falsely added {:?}", c.spurious);
    let turn = value("direction")
        .and_then(|v| v.error)
        .expect("a rail direction");
    assert!(turn.abs() < 1.0, "rail direction off by {turn} degrees");
    let across = value("position").and_then(|v| v.error).expect("a rail position");
    assert!(across < 1.0, "rail line {across} px off");
    for v in c.values.iter().filter(|v| v.item.starts_with("spring")) {
        let e = v.relative_error.expect("a spring value");
        assert!(e.abs() < 0.05, "{v:?}");
    }
    let friction = value("friction");
    if frictionless {
        assert!(friction.is_none(), "{friction:?}");
        assert!(!names.contains(&"rail_friction".to_string()), "{names:?}");
    } else {
        let e = friction.and_then(|v| v.relative_error).expect("a friction");
        assert!(e.abs() < 0.05, "friction {friction:?} against {mu}");
        assert!(seen_of(&report, "rail_friction").contains("sliding on its rail decelerate"));
    }
    let text = seen_of(&report, "rail");
    assert!(text.contains("RMS across it"), "{text}");
}

#[test]
fn a_cart_on_an_unlisted_rail_is_found_with_its_friction_seed_15() {
    check_rail(15, false);
}

#[test]
fn a_cart_on_an_unlisted_rail_is_found_with_its_friction_seed_16() {
    check_rail(16, false);
}

#[test]
fn a_cart_on_an_unlisted_rail_is_found_with_its_friction_seed_17() {
    check_rail(17, false);
}

#[test]
fn a_cart_on_an_unlisted_frictionless_rail_gets_no_friction() {
    check_rail(18, true);
}

/// A particle thrown at (`vx`, `vy`) px/s from (60, 300) px under a field `g` px/s², 2 s at
/// 100 frames/s.
fn throw_scene(vx: f64, vy: f64, g: [f64; 2], seed: u64) -> String {
    let head = head("thrown", 200, 480, 400, seed);
    format!(
        r#"{head}[[particles]]
id = "ball"
mass = 1.0
position = [60.0, 300.0]
velocity = [{vx}, {vy}]
[physics]
gravity = [{gx}, {gy}]
"#,
        gx = g[0],
        gy = g[1],
    )
}

/// A thrown ball (free 2-D motion in a field) and a ball thrown along the field (a straight
/// path, the rail candidate's own shape), diagnosed from their structure: the field alone,
/// no rail.
fn check_free_motion(seed: u64, straight: bool) {
    let mut s = seed;
    // Within the picture for the 2 s: it turns back within 312 px, and is back past its
    // start no sooner than 2 s.
    let g = draw(&mut s, 100.0, 150.0);
    let speed = draw(&mut s, 150.0, 250.0);
    let scene = if straight {
        // Along x: thrown right against a field pointing left, it turns back.
        throw_scene(speed, 0.0, [-g, 0.0], seed)
    } else {
        throw_scene(0.5 * speed, -0.6 * speed, [0.0, g], seed)
    };
    let dir = tempdir();
    let (truth, structure, report, fitted) = diagnose_rendered(dir.path(), &scene);
    let c = compare_scenes(&fitted, &truth, &structure);
    let names = finding_names(&report);
    println!("free motion seed {seed} (straight {straight}): g {g:.2}, speed {speed:.1}: findings {names:?}");
    assert!(c.missed.is_empty(), "missed {:?}", c.missed);
    assert!(c.spurious.is_empty(), "falsely added {:?}", c.spurious);
    assert!(fitted.physics.rails.is_empty(), "{:?}", fitted.physics.rails);
}

#[test]
fn free_motion_in_a_field_gets_no_rail() {
    check_free_motion(19, false);
}

#[test]
fn a_straight_fall_along_the_field_gets_no_rail() {
    check_free_motion(20, true);
}

/// A bob on a soft spring (stiffness drawn from `seed`: it stretches by tens of pixels) to a
/// fixed pivot, swinging in a field, diagnosed from a structure without the spring: a
/// spring (a missing spring or a tether), not a rope.
fn check_soft_spring(seed: u64) {
    let mut s = seed;
    let g = draw(&mut s, 300.0, 600.0);
    let stiffness = draw(&mut s, 5.0, 10.0);
    let head = head("soft-spring", 300, 400, 400, seed);
    // Released at 30 degrees from the pivot, 40 px short of the hanging stretch.
    let hanging = 120.0 + g / (2.0 * stiffness);
    let d = hanging - 40.0;
    let (sn, cs) = 30f64.to_radians().sin_cos();
    let scene = format!(
        r#"{head}[[particles]]
id = "pivot"
mass = 1.0
position = [200.0, 40.0]
fixed = true
[[particles]]
id = "bob"
mass = 1.0
position = [{x}, {y}]
[[springs]]
between = ["pivot", "bob"]
length = 120.0
stiffness = {stiffness}
[physics]
gravity = [0.0, {g}]
"#,
        x = 200.0 + d * sn,
        y = 40.0 + d * cs,
    );
    let without_spring = |truth: &Scene| {
        let mut given = truth.structure();
        given.springs.clear();
        given
    };
    let dir = tempdir();
    let (truth, given, report, fitted) = diagnose_rendered_from(dir.path(), &scene, without_spring);
    let c = compare_scenes(&fitted, &truth, &given);
    let names = finding_names(&report);
    println!(
        "soft spring seed {seed}: g {g:.1}, S {stiffness:.3} (hangs {hanging:.1} px): findings {names:?}, verdict {}",
        report["verdict"]["text"]
    );
    assert!(c.missed.is_empty(), "missed {:?}", c.missed);
    assert!(c.spurious.is_empty(), "falsely added {:?}", c.spurious);
    assert!(names.contains(&"missing_spring".to_string()), "{names:?}");
    assert!(fitted.physics.ropes.is_empty(), "{:?}", fitted.physics.ropes);
}

#[test]
fn a_soft_spring_tether_stays_a_spring() {
    check_soft_spring(21);
}

/// Two pucks (masses 1 and 2) joined by a spring, launched across a table seen from above
/// with the table's dry friction `medium` (`surface_friction = a`, or a drag for the
/// control), 2.5 s at 100 frames/s: the launch speeds (150-250 px/s) and the spring are
/// drawn from `seed`.
fn table_scene(medium: &str, seed: u64) -> String {
    let mut s = seed;
    let stiffness = draw(&mut s, 20.0, 60.0);
    let (va, vb) = (draw(&mut s, 150.0, 250.0), draw(&mut s, 150.0, 250.0));
    let turn = draw(&mut s, -0.3, 0.3);
    let head = head("pucks-on-a-table", 250, 480, 400, seed);
    format!(
        r#"{head}[[particles]]
id = "a"
mass = 1.0
position = [80.0, 120.0]
velocity = [{ax}, {ay}]
[[particles]]
id = "b"
mass = 2.0
position = [80.0, 175.0]
velocity = [{bx}, {by}]
[[springs]]
between = ["a", "b"]
length = 50.0
stiffness = {stiffness}
[physics]
{medium}
"#,
        ax = va * turn.cos(),
        ay = va * turn.sin() + 40.0,
        bx = vb * 0.8,
        by = vb * 0.3,
    )
}

/// [`table_scene`] with its friction (150-400 px/s²) drawn from `seed`, diagnosed from the
/// structure alone: the surface's friction within 5 %, the spring within 5 %, and nothing
/// else added.
fn check_surface_friction(seed: u64) {
    let mut s = seed.wrapping_mul(31);
    let a = draw(&mut s, 150.0, 400.0);
    let dir = tempdir();
    let scene = table_scene(&format!("surface_friction = {a}"), seed);
    let (truth, structure, report, fitted) = diagnose_rendered(dir.path(), &scene);
    let c = compare_scenes(&fitted, &truth, &structure);
    let found = fitted.physics.surface_friction;
    println!(
        "surface friction seed {seed}: a {a:.3}: found {:?}, a {found:.4} ({:+.4} %), bonds {:?}, verdict {}",
        c.effects_found,
        100.0 * (found / a - 1.0),
        c.max_bond_relative_error,
        report["verdict"]["text"]
    );
    assert_eq!(c.effects_found, ["surface_friction"], "{:?}", c.values);
    assert!((found / a - 1.0).abs() < 0.05, "a {found} against {a}");
    assert!(
        c.max_bond_relative_error.is_some_and(|e| e < 0.05),
        "{:?}",
        c.values
    );
    let text = seen_of(&report, "surface_friction");
    assert!(text.contains("stays put once stopped"), "{text}");
}

#[test]
fn dry_friction_of_a_table_is_found_within_5_percent_seed_31() {
    check_surface_friction(31);
}

#[test]
fn dry_friction_of_a_table_is_found_within_5_percent_seed_32() {
    check_surface_friction(32);
}

#[test]
fn dry_friction_of_a_table_is_found_within_5_percent_seed_33() {
    check_surface_friction(33);
}

/// The same pucks slowed by a linear drag (1-3 /s), which never stops them, get the drag and
/// no dry friction.
#[test]
fn pucks_slowed_by_drag_get_no_dry_friction() {
    for seed in [34, 35] {
        let mut s = seed;
        let drag = draw(&mut s, 1.0, 3.0);
        let dir = tempdir();
        let scene = table_scene(&format!("drag = {drag}"), seed);
        let (truth, structure, report, fitted) = diagnose_rendered(dir.path(), &scene);
        let c = compare_scenes(&fitted, &truth, &structure);
        println!(
            "drag control seed {seed}: drag {drag:.4}: found {:?}, verdict {}",
            c.effects_found, report["verdict"]["text"]
        );
        assert_eq!(c.effects_found, ["drag"], "seed {seed}: {:?}", c.values);
    }
}

/// A puck slowing on a straight line across a table that leaves the view before it stops
/// (surface friction 150-300 px/s², launch 400-500 px/s) is, to the tracks, a field against
/// its motion: physfit finds the field and says in its note that the tracks cannot tell it
/// from a surface's friction; a ball thrown up that falls back on the same line (which
/// friction cannot do) gets no such note.
#[test]
fn a_straight_deceleration_is_a_field_said_to_be_friction_perhaps() {
    let note_of = |report: &Value| {
        report["findings"]
            .as_array()
            .and_then(|fs| fs.iter().find(|f| f["effect"] == "gravity"))
            .and_then(|f| f["note"].as_str())
            .unwrap_or_default()
            .to_string()
    };
    for seed in [41u64, 42] {
        let mut s = seed;
        let a = draw(&mut s, 150.0, 300.0);
        let speed = draw(&mut s, 400.0, 500.0);
        let head = head("slowing-puck", 90, 640, 400, seed).replace("fps = 100.0", "fps = 60.0");
        let scene = format!(
            "{head}[[particles]]\nid = \"puck\"\nmass = 1.0\nposition = [40.0, 100.0]\nvelocity = [{}, {}]\n[physics]\nsurface_friction = {a}\n",
            speed * 0.94,
            speed * 0.34
        );
        let dir = tempdir();
        let (_, _, report, fitted) = diagnose_rendered(dir.path(), &scene);
        let note = note_of(&report);
        println!(
            "slowing puck seed {seed}: a {a:.1}, field {:.3}: {note}",
            fitted.physics.gravity.norm()
        );
        assert!((fitted.physics.gravity.norm() / a - 1.0).abs() < 0.01);
        assert!(
            note.contains("cannot tell from the dry friction of a surface"),
            "{note}"
        );
    }
    let head = head("thrown-up", 120, 400, 400, 43);
    let scene = format!(
        "{head}[[particles]]\nid = \"ball\"\nmass = 1.0\nposition = [200.0, 350.0]\nvelocity = [0.0, -600.0]\n[physics]\ngravity = [0.0, 1000.0]\n"
    );
    let dir = tempdir();
    let (_, _, report, _) = diagnose_rendered(dir.path(), &scene);
    let note = note_of(&report);
    assert!(!note.contains("dry friction"), "{note}");
}
