//! The scene file contract: validation errors name what is wrong, round trips are exact.

use physfit_model::scene::SceneProblem;
use physfit_model::{Colour, IntegratorKind, Scene, SceneError, Vec2};

const BASE: &str = r#"
[recording]
fps = 100.0
frames = 10

[[particles]]
id = "a"
mass = 1.0
position = [10.0, 20.0]

[[particles]]
id = "b"
mass = 2.0
position = [50.0, 20.0]

[[particles]]
id = "c"
mass = 1.5
position = [50.0, 60.0]

[[springs]]
between = ["a", "b"]
length = 40.0
stiffness = 10.0

[[torsions]]
at = "b"
between = ["a", "c"]
rest_cos = 0.0
stiffness = 100.0
"#;

/// The error of an invalid scene text, as displayed.
fn message(text: &str) -> String {
    match Scene::from_toml_str(text, "s.toml") {
        Ok(_) => panic!("scene accepted:\n{text}"),
        Err(e) => e.to_string(),
    }
}

/// The content problem of a scene that parses but is invalid.
fn problem(text: &str) -> SceneProblem {
    match Scene::from_toml_str(text, "s.toml") {
        Err(SceneError::Invalid { file, problem }) => {
            assert_eq!(file, "s.toml");
            problem
        }
        other => panic!("expected a content error, got {other:?}"),
    }
}

/// Line, column and message of a scene that does not parse.
fn parse_error(text: &str) -> (usize, usize, String) {
    match Scene::from_toml_str(text, "s.toml") {
        Err(SceneError::Parse {
            file,
            line,
            column,
            message,
        }) => {
            assert_eq!(file, "s.toml");
            (line, column, message)
        }
        other => panic!("expected a parse error, got {other:?}"),
    }
}

#[test]
fn the_base_scene_is_valid() {
    let scene = Scene::from_toml_str(BASE, "s.toml").unwrap();
    assert_eq!(scene.particles.len(), 3);
    assert_eq!(scene.recording.substeps, 20);
    assert_eq!(scene.recording.integrator, IntegratorKind::Verlet);
    assert_eq!(scene.unknown_count(), 0);
    let model = scene.model().unwrap();
    assert_eq!((model.springs.len(), model.torsions.len()), (1, 1));
}

#[test]
fn unknown_top_level_key_is_named_with_its_line_and_column() {
    let (line, column, msg) = parse_error(&BASE.replace("[recording]", "colour = 3\n[recording]"));
    assert_eq!((line, column), (2, 1));
    assert!(msg.contains("unknown field `colour`"), "{msg}");
}

#[test]
fn unknown_particle_key_is_named_with_its_line_and_column() {
    let text = BASE.replace("mass = 2.0", "mass = 2.0\ncharge = 1.0");
    let (line, column, msg) = parse_error(&text);
    assert_eq!((line, column), (14, 1));
    assert!(msg.contains("unknown field `charge`"), "{msg}");
    assert!(message(&text).starts_with("s.toml:14:1: unknown field `charge`"));
}

#[test]
fn unknown_physics_key_is_named_with_its_line_and_column() {
    let (line, column, msg) = parse_error(&format!("{BASE}\n[physics]\nfriction = 0.2\n"));
    assert_eq!((line, column), (33, 1));
    assert!(msg.contains("unknown field `friction`"), "{msg}");
}

#[test]
fn wrong_types_are_named_with_their_key_line_and_column() {
    let (line, column, msg) = parse_error(&BASE.replace("mass = 2.0", "mass = \"heavy\""));
    assert_eq!((line, column), (13, 8));
    assert!(
        msg.contains("invalid type: string \"heavy\"") && msg.contains("`mass`"),
        "{msg}"
    );
    let (line, column, msg) = parse_error(&BASE.replace("frames = 10", "frames = 2.5"));
    assert_eq!((line, column), (4, 10));
    assert!(msg.contains("2.5") && msg.contains("`frames`"), "{msg}");
    let (line, column, msg) = parse_error(&BASE.replace("frames = 10", "frames = 10\nintegrator = \"rk4\""));
    assert_eq!((line, column), (5, 14));
    assert!(msg.contains("rk4") && msg.contains("`integrator`"), "{msg}");
}

#[test]
fn syntax_errors_give_their_line_and_column() {
    let (line, column, _) = parse_error(&BASE.replace("stiffness = 10.0", "stiffness = = 10.0"));
    assert_eq!((line, column), (24, 13));
    let (line, _, msg) = parse_error(&BASE.replace("fps = 100.0\n", ""));
    assert_eq!(line, 2);
    assert!(msg.contains("missing field `fps`"), "{msg}");
}

#[test]
fn duplicate_ids_are_named() {
    let text = BASE.replace("id = \"c\"", "id = \"a\"");
    assert_eq!(problem(&text), SceneProblem::DuplicateId("a".into()));
    assert_eq!(message(&text), "s.toml: duplicate particle id \"a\"");
}

#[test]
fn a_bond_naming_a_missing_particle_is_named() {
    let text = BASE.replace("between = [\"a\", \"b\"]", "between = [\"a\", \"zed\"]");
    assert_eq!(
        message(&text),
        "s.toml: spring a-zed names particle \"zed\", which is not defined"
    );
    let text = BASE.replace("at = \"b\"", "at = \"q\"");
    assert_eq!(
        message(&text),
        "s.toml: torsion a-q-c names particle \"q\", which is not defined"
    );
}

#[test]
fn a_spring_naming_one_particle_twice_is_named() {
    let text = BASE.replace("between = [\"a\", \"b\"]", "between = [\"b\", \"b\"]");
    assert_eq!(
        problem(&text),
        SceneProblem::RepeatedParticle {
            bond: "spring b-b".into(),
            id: "b".into()
        }
    );
    assert_eq!(message(&text), "s.toml: spring b-b names particle \"b\" twice");
}

#[test]
fn a_torsion_needs_three_distinct_particles() {
    for (between, bond, id) in [
        ("[\"a\", \"b\"]", "torsion a-b-b", "b"),
        ("[\"c\", \"c\"]", "torsion c-b-c", "c"),
    ] {
        let text = BASE.replace("between = [\"a\", \"c\"]", &format!("between = {between}"));
        assert_eq!(
            message(&text),
            format!("s.toml: {bond} names particle \"{id}\" twice")
        );
    }
}

#[test]
fn non_positive_masses_are_named() {
    for mass in ["0.0", "-1.5"] {
        let text = BASE.replace("mass = 2.0", &format!("mass = {mass}"));
        let msg = message(&text);
        assert!(
            msg.starts_with("s.toml: particle \"b\" has mass") && msg.contains("must be positive"),
            "{msg}"
        );
        assert!(matches!(problem(&text), SceneProblem::NonPositiveMass { id, .. } if id == "b"));
    }
}

#[test]
fn non_finite_numbers_are_named() {
    let physics = format!("{BASE}\n[physics]\ngravity = [0.0, inf]\n");
    let wall =
        format!("{BASE}\n[[physics.walls]]\npoint = [0.0, 0.0]\nnormal = [nan, 1.0]\nrestitution = 0.5\n");
    for (text, key) in [
        (
            BASE.replace("[10.0, 20.0]", "[nan, 20.0]"),
            "particle \"a\" position is NaN",
        ),
        (
            BASE.replace("mass = 2.0", "mass = inf"),
            "particle \"b\" mass is inf",
        ),
        (
            BASE.replace(
                "position = [50.0, 60.0]",
                "position = [50.0, 60.0]\nvelocity = [-inf, 0.0]",
            ),
            "particle \"c\" velocity is -inf",
        ),
        (
            BASE.replace("stiffness = 10.0", "stiffness = nan"),
            "spring a-b stiffness is NaN",
        ),
        (
            BASE.replace("length = 40.0", "length = inf"),
            "spring a-b length is inf",
        ),
        (
            BASE.replace("rest_cos = 0.0", "rest_cos = nan"),
            "torsion a-b-c rest_cos is NaN",
        ),
        (
            BASE.replace("stiffness = 100.0", "stiffness = -inf"),
            "torsion a-b-c stiffness is -inf",
        ),
        (BASE.replace("fps = 100.0", "fps = nan"), "recording.fps is NaN"),
        (physics, "physics.gravity is inf"),
        (wall, "physics.walls[0].normal is NaN"),
    ] {
        let msg = message(&text);
        assert_eq!(msg, format!("s.toml: {key}; it must be a finite number"));
    }
}

#[test]
fn rest_cos_outside_minus_one_to_one_is_named() {
    for m in ["1.5", "-1.0000001"] {
        let msg = message(&BASE.replace("rest_cos = 0.0", &format!("rest_cos = {m}")));
        assert_eq!(
            msg,
            format!("s.toml: torsion a-b-c rest_cos is {m}; it must be in [-1, 1]")
        );
    }
    // The ends are allowed: straight and folded rest angles.
    for m in ["1.0", "-1.0"] {
        Scene::from_toml_str(
            &BASE.replace("rest_cos = 0.0", &format!("rest_cos = {m}")),
            "s.toml",
        )
        .unwrap();
    }
}

#[test]
fn a_wall_normal_of_zero_length_is_named() {
    let text = format!(
        "{BASE}\n[[physics.walls]]\npoint = [0.0, 100.0]\nnormal = [0.0, -1.0]\nrestitution = 0.5\n\
         [[physics.walls]]\npoint = [0.0, 0.0]\nnormal = [0.0, 0.0]\nrestitution = 0.5\n"
    );
    assert_eq!(problem(&text), SceneProblem::ZeroWallNormal(1));
    assert_eq!(message(&text), "s.toml: physics.walls[1].normal has zero length");
}

#[test]
fn out_of_range_settings_are_named() {
    let wall =
        format!("{BASE}\n[[physics.walls]]\npoint = [0.0, 0.0]\nnormal = [0.0, 1.0]\nrestitution = 1.5\n");
    for (text, expected) in [
        (wall, "physics.walls[0].restitution is 1.5; it must be in [0, 1]"),
        (
            BASE.replace("fps = 100.0", "fps = 0.0"),
            "recording.fps is 0; it must be positive and at most 1e7 frames/s",
        ),
        (
            BASE.replace("fps = 100.0", "fps = 1e308"),
            "recording.fps is 1e308; it must be at most 1e12 in magnitude",
        ),
        (
            BASE.replace("fps = 100.0", "fps = 1e8"),
            "recording.fps is 100000000; it must be positive and at most 1e7 frames/s",
        ),
        (
            BASE.replace("frames = 10", "frames = 10\nsubsteps = 0"),
            "recording.substeps is 0; it must be from 1 to 100000",
        ),
        (
            BASE.replace("frames = 10", "frames = 10\nsubsteps = 4000000000"),
            "recording.substeps is 4000000000; it must be from 1 to 100000",
        ),
    ] {
        assert_eq!(message(&text), format!("s.toml: {expected}"));
    }
    for (text, expected) in [
        (
            BASE.replace("mass = 1.0", "mass = 1e300"),
            "particle \"a\" mass is 1e300; it must be at most 1e12 in magnitude",
        ),
        (
            BASE.replace("mass = 1.0", "mass = 1e-20"),
            "particle \"a\" has mass 1e-20; masses must be positive, from 1e-12 to 1e12",
        ),
        (
            BASE.replace("position = [10.0, 20.0]", "position = [1e308, 20.0]"),
            "particle \"a\" position is 1e308; it must be at most 1e12 in magnitude",
        ),
        (
            BASE.replace("length = 40.0", "length = -2e16"),
            "spring a-b length is -2e16; it must be at most 1e12 in magnitude",
        ),
    ] {
        assert_eq!(message(&text), format!("s.toml: {expected}"));
    }
    let none = "particles = []\n[recording]\nfps = 10.0\nframes = 1\n";
    assert_eq!(problem(none), SceneProblem::NoParticles);
}

/// A scene using every key of the format, with awkward floats.
const EVERY_KEY: &str = r#"
name = "every key"

[recording]
fps = 29.97
frames = 120
substeps = 7
integrator = "euler"

[render]
width = 320
height = 240
radius = 3.25
background = 12
foreground = [250, 128, 3]
noise = 1.5
blur = 0.7
seed = 99

[[particles]]
id = "p0"
mass = 0.30000000000000004
position = [-0.0, 1e-300]
velocity = [12.5, -3.0000000000000004]
fixed = true

[[particles]]
id = "p1"
mass = 123456789.12345679
position = [100.1, 200.2]
velocity = [-0.0, 1.0]

[[particles]]
id = "p2"
mass = 1.0
position = [150.0, 170.0]
body_drag = 0.1
body_quadratic_drag = -0.0

[[springs]]
between = ["p0", "p1"]
length = 99.99999999999999
stiffness = 2.5e-7
damping = 0.125

[[springs]]
between = ["p1", "p2"]
length = 40.0
stiffness = 3.0

[[torsions]]
at = "p1"
between = ["p0", "p2"]
rest_cos = -0.9999999999999999
stiffness = 1e5

[physics]
gravity = [0.1, 981.0]
drag = 0.05
quadratic_drag = 1e-4
spring_damping = 0.3
body_drag = 0.30000000000000004
body_quadratic_drag = 2.5e-5
surface_friction = 12.5

[[physics.walls]]
point = [0.0, 480.0]
normal = [1.0, -3.0]
restitution = 0.8
friction = 0.45

[[physics.walls]]
point = [10.0, 0.0]
normal = [1.0, 0.0]
restitution = 0.0

[[physics.walls]]
point = [630.0, 0.0]
normal = [-1.0, 0.0]
stiffness = 123.5
damping = 0.7

[[physics.ropes]]
between = ["p0", "p2"]
length = 77.7
slack = true

[[physics.ropes]]
between = ["p2", "p1"]
length = 1e-3

[[physics.rails]]
particle = "p1"
point = [-0.0, 3.5]
direction = [0.6, 0.8]
friction = 0.125
"#;

#[test]
fn every_key_is_read() {
    let s = Scene::from_toml_str(EVERY_KEY, "every.toml").unwrap();
    assert_eq!(s.name, "every key");
    assert_eq!(
        (s.recording.frames, s.recording.substeps, s.recording.integrator),
        (120, 7, IntegratorKind::Euler)
    );
    assert!(s.has_render_table);
    assert_eq!((s.render.width, s.render.height, s.render.seed), (320, 240, 99));
    assert_eq!(
        (s.render.background, s.render.foreground),
        (Colour::Grey(12), Colour::Rgb([250, 128, 3]))
    );
    assert!(s.particles[0].fixed && !s.particles[1].fixed);
    assert_eq!(s.springs[0].damping.map(f64::to_bits), Some(0.125f64.to_bits()));
    assert_eq!(s.springs[1].damping, None);
    assert_eq!(s.physics.walls.len(), 3);
    assert!(s.physics.walls[2].is_bumper() && !s.physics.walls[0].is_bumper());
    // Normals are normalised on load.
    assert!((s.physics.walls[0].normal - Vec2::new(1.0, -3.0) / 10f64.sqrt()).norm() < 1e-15);
    let p = s.integration_parameters();
    assert!((p.frame_dt - 1.0 / 29.97).abs() < 1e-15 && p.substeps == 7);
    // The fixed particle starts at rest whatever velocity the file gives it.
    assert!(s.initial_state().velocities[0].norm() == 0.0);
}

/// Every float of a scene, bit for bit (Debug prints -0.0 and the shortest round-trip form).
fn fingerprint(s: &Scene) -> String {
    format!("{s:?}")
}

#[test]
fn writing_and_reading_back_gives_the_same_scene_bit_for_bit() {
    let scene = Scene::from_toml_str(EVERY_KEY, "every.toml").unwrap();
    let text = scene.to_toml_string().unwrap();
    let back = Scene::from_toml_str(&text, "back.toml").unwrap();
    assert_eq!(back, scene);
    assert_eq!(fingerprint(&back), fingerprint(&scene), "written as:\n{text}");
    assert!(
        fingerprint(&scene).contains("-0.0"),
        "the test should exercise negative zero"
    );
    // And writing again changes nothing.
    assert_eq!(back.to_toml_string().unwrap(), text);
}

#[test]
fn negative_zero_physics_survives_a_round_trip() {
    let mut scene = Scene::from_toml_str(BASE, "s.toml").unwrap();
    scene.physics.drag = -0.0;
    scene.physics.gravity = Vec2::new(-0.0, 0.0);
    let back = Scene::from_toml_str(&scene.to_toml_string().unwrap(), "s.toml").unwrap();
    assert_eq!(fingerprint(&back), fingerprint(&scene));
}

#[test]
fn a_structure_drops_values_and_physics_and_counts_them() {
    let scene = Scene::from_toml_str(EVERY_KEY, "every.toml").unwrap();
    let structure = scene.structure();
    assert_eq!(structure.unknown_count(), 2 * 2 + 2);
    assert!(structure
        .springs
        .iter()
        .all(|s| s.rest_length.is_none() && s.stiffness.is_none() && s.damping.is_none()));
    assert!(structure
        .torsions
        .iter()
        .all(|t| t.rest_cos.is_none() && t.stiffness.is_none()));
    // The constraints (ropes, rails) hold the particles as bonds do: kept, with the rest of
    // `[physics]` gone.
    assert!(!scene.physics.ropes.is_empty() && !scene.physics.rails.is_empty());
    assert_eq!(
        structure.physics,
        physfit_model::Physics {
            ropes: scene.physics.ropes.clone(),
            rails: scene.physics.rails.clone(),
            ..physfit_model::Physics::default()
        }
    );
    // Topology, masses, frame-0 state, timing and drawing are kept; a body's own drag is a
    // physics value and goes.
    let mut particles = scene.particles.clone();
    assert!(particles[2].body_drag.is_some());
    for p in &mut particles {
        p.body_drag = None;
        p.body_quadratic_drag = None;
    }
    assert_eq!(structure.particles, particles);
    assert_eq!(structure.recording, scene.recording);
    assert_eq!(structure.render, scene.render);
    assert_eq!(
        structure.springs.iter().map(|s| s.ends).collect::<Vec<_>>(),
        scene.springs.iter().map(|s| s.ends).collect::<Vec<_>>()
    );
    // A structure round-trips too, with no value keys written but the constraints'.
    let mut bare = structure.clone();
    bare.physics.ropes.clear();
    bare.physics.rails.clear();
    let text = bare.to_toml_string().unwrap();
    assert!(
        !text.contains("length") && !text.contains("rest_cos") && !text.contains("physics"),
        "{text}"
    );
    let text = structure.to_toml_string().unwrap();
    assert!(
        text.contains("[[physics.ropes]]") && text.contains("[[physics.rails]]") && !text.contains("gravity"),
        "{text}"
    );
    assert_eq!(
        fingerprint(&Scene::from_toml_str(&text, "s.toml").unwrap()),
        fingerprint(&structure)
    );
}

#[test]
fn model_of_a_structure_names_the_first_unknown_value() {
    let structure = Scene::from_toml_str(EVERY_KEY, "every.toml").unwrap().structure();
    let err = structure.model().unwrap_err();
    assert_eq!(
        err,
        SceneProblem::UnknownValue {
            bond: "spring p0-p1".into(),
            key: "length"
        }
    );
    assert_eq!(
        err.to_string(),
        "spring p0-p1 has no length: a scene to simulate needs every bond's values"
    );
    // With springs known, the torsion is named.
    let text = BASE.replace("stiffness = 100.0\n", "");
    let scene = Scene::from_toml_str(&text, "s.toml").unwrap();
    assert_eq!(scene.unknown_count(), 1);
    assert_eq!(
        scene.model().unwrap_err(),
        SceneProblem::UnknownValue {
            bond: "torsion a-b-c".into(),
            key: "stiffness"
        }
    );
}

/// A fresh empty folder under the test target's temporary directory.
fn fresh_dir(name: &str) -> std::path::PathBuf {
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("physfit-model-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn entries(dir: &std::path::Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

#[test]
fn save_is_atomic_overwrites_and_leaves_no_temporary_file() {
    let dir = fresh_dir("save");
    let path = dir.join("scene.toml");
    let mut scene = Scene::from_toml_str(EVERY_KEY, "every.toml").unwrap();
    scene.save(&path).unwrap();
    assert_eq!(entries(&dir), ["scene.toml"]);
    assert_eq!(fingerprint(&Scene::load(&path).unwrap()), fingerprint(&scene));
    // Overwrite with a different scene.
    scene.recording.frames = 7;
    scene.save(&path).unwrap();
    assert_eq!(entries(&dir), ["scene.toml"]);
    assert_eq!(Scene::load(&path).unwrap().recording.frames, 7);
    // A failed save reports the path and leaves nothing behind.
    let missing = dir.join("no-such-folder").join("scene.toml");
    let err = scene.save(&missing).unwrap_err();
    assert!(
        matches!(err, SceneError::Io { .. }) && err.to_string().contains("no-such-folder"),
        "{err}"
    );
    assert_eq!(entries(&dir), ["scene.toml"]);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn concurrent_saves_to_one_path_each_leave_a_whole_file() {
    let dir = fresh_dir("concurrent");
    let path = dir.join("scene.toml");
    let scene = Scene::from_toml_str(EVERY_KEY, "every.toml").unwrap();
    std::thread::scope(|s| {
        for _ in 0..4 {
            s.spawn(|| {
                for _ in 0..10 {
                    scene.save(&path).unwrap();
                }
            });
        }
    });
    assert_eq!(entries(&dir), ["scene.toml"]);
    assert_eq!(fingerprint(&Scene::load(&path).unwrap()), fingerprint(&scene));
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn load_names_the_file_and_defaults_the_name_to_its_stem() {
    let dir = fresh_dir("load");
    let path = dir.join("falling-ring.toml");
    std::fs::write(&path, BASE).unwrap();
    assert_eq!(Scene::load(&path).unwrap().name, "falling-ring");
    let bad = dir.join("bad.toml");
    std::fs::write(&bad, BASE.replace("mass = 2.0", "mass = 0.0")).unwrap();
    let msg = Scene::load(&bad).unwrap_err().to_string();
    assert!(
        msg.starts_with(&bad.display().to_string()) && msg.contains("\"b\""),
        "{msg}"
    );
    let err = Scene::load(&dir.join("absent.toml")).unwrap_err();
    assert!(
        matches!(err, SceneError::Io { .. }) && err.to_string().contains("absent.toml"),
        "{err}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn the_documented_example_is_valid_and_uses_every_key() {
    let doc =
        std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../../docs/scene-format.md")).unwrap();
    let start = doc
        .find("```toml\n")
        .expect("docs/scene-format.md has a toml example")
        + "```toml\n".len();
    let example = &doc[start..start + doc[start..].find("```").unwrap()];
    let scene = Scene::from_toml_str(example, "docs/scene-format.md").unwrap();
    assert_eq!(scene.unknown_count(), 0);
    let model = scene.model().unwrap();
    assert!(model.has_velocity_dependent_forces() && model.physics.walls.len() == 3);
    // Every key the writer knows appears in the example.
    let written = scene.to_toml_string().unwrap();
    for line in written.lines().filter(|l| l.contains(" = ")) {
        let key = line.split(" = ").next().unwrap();
        let used = example.lines().any(|l| l.starts_with(&format!("{key} = ")));
        assert!(used, "the example lacks `{key}`");
    }
    for table in [
        "[render]",
        "[physics]",
        "[[physics.walls]]",
        "[[physics.ropes]]",
        "[[physics.rails]]",
        "[[torsions]]",
    ] {
        assert!(example.contains(table));
    }
    // It simulates to finite positions, above the floor.
    let rec = physfit_model::simulate(
        &model,
        &scene.initial_state(),
        &scene.integration_parameters(),
        300,
    );
    assert!(rec.positions.iter().all(|x| x.x.is_finite() && x.y <= 230.0));
}

#[test]
fn the_scale_is_metres_per_px_or_a_ruler_but_not_both() {
    let with = |extra: &str| BASE.replace("frames = 10\n", &format!("frames = 10\n{extra}"));
    let s = Scene::from_toml_str(&with("metres_per_px = 0.002\n"), "s.toml").unwrap();
    assert_eq!(s.recording.metres_per_px, Some(0.002));
    assert_eq!(
        Scene::from_toml_str(BASE, "s.toml")
            .unwrap()
            .recording
            .metres_per_px,
        None
    );
    let ruler = "[recording.ruler]\nfrom = [0.0, 0.0]\nto = [30.0, 40.0]\nlength_m = 1.0\n";
    let text = BASE.replace("frames = 10\n", &format!("frames = 10\n\n{ruler}"));
    let s = Scene::from_toml_str(&text, "s.toml").unwrap();
    assert!((s.recording.metres_per_px.unwrap() - 0.02).abs() < 1e-15);
    // Written back as metres_per_px, read back the same.
    let back = Scene::from_toml_str(&s.to_toml_string().unwrap(), "s.toml").unwrap();
    assert_eq!(back.recording.metres_per_px, s.recording.metres_per_px);
    let both = text.replace("frames = 10\n", "frames = 10\nmetres_per_px = 0.1\n");
    assert!(matches!(problem(&both), SceneProblem::TwoScales));
    assert!(message(&with("metres_per_px = -1.0\n")).contains("recording.metres_per_px"));
    let flat = text.replace("to = [30.0, 40.0]", "to = [0.0, 0.0]");
    assert!(message(&flat).contains("recording.ruler"), "{}", message(&flat));
}
