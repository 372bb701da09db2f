//! Every scene in `scenes/` simulates to motion worth analysing: finite, in frame, discs never
//! overlapping, every bond visibly working, and (for conservative scenes) no energy drift.
//!
//! Each scene is a smoke test (like rapier's example scenes) and a promise to the later stages:
//! a tracker can see every particle separately and an identifier has signal in every bond.

use std::path::{Path, PathBuf};

use physfit_model::{simulate, Recording, Scene, TorsionGeometry};

/// Smallest spring length range over a recording, as a fraction of the rest length.
const MIN_STRETCH_FRACTION: f64 = 0.03;
/// Smallest spring length range over a recording, px (small springs still move visibly).
const MIN_STRETCH_PX: f64 = 2.0;
/// Smallest torsion angle range over a recording, degrees.
const MIN_BEND_DEGREES: f64 = 5.0;
/// Extra clear pixels required between two discs and between a disc and the image edge.
const CLEARANCE_PX: f64 = 1.0;
/// Relative energy drift allowed in a conservative scene (no drag, dashpots or walls), as a
/// fraction of the largest kinetic energy seen.
const MAX_ENERGY_DRIFT: f64 = 0.01;

fn scenes_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes")
}

fn scene_paths() -> Vec<PathBuf> {
    let mut paths: Vec<PathBuf> = std::fs::read_dir(scenes_dir())
        .expect("scenes/ folder")
        .map(|e| e.expect("directory entry").path())
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .collect();
    paths.sort();
    paths
}

/// Minimum and maximum of a sequence.
fn range(values: impl Iterator<Item = f64>) -> (f64, f64) {
    values.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
        (lo.min(v), hi.max(v))
    })
}

/// What is wrong with a scene's recording (empty when nothing is), plus a one-line summary.
fn check(scene: &Scene, rec: &Recording) -> (Vec<String>, String) {
    let mut problems = Vec::new();
    let n = rec.particle_count;
    let frames = rec.frame_count();
    let label = |k: usize| scene.particles[k].id.clone();

    if let Some(bad) = rec
        .positions
        .iter()
        .position(|p| !p.x.is_finite() || !p.y.is_finite())
    {
        problems.push(format!(
            "particle {} is not finite at frame {}",
            label(bad % n),
            bad / n
        ));
        return (problems, String::new());
    }

    let r = scene.render.radius;
    let margin = r + 2.0;
    let (w, h) = (scene.render.width as f64, scene.render.height as f64);
    for k in 0..n {
        let (x_lo, x_hi) = range((0..frames).map(|f| rec.frame(f)[k].x));
        let (y_lo, y_hi) = range((0..frames).map(|f| rec.frame(f)[k].y));
        if x_lo < margin || y_lo < margin || x_hi > w - 1.0 - margin || y_hi > h - 1.0 - margin {
            problems.push(format!(
                "particle {} leaves the frame margin of {margin} px: x {x_lo:.1}..{x_hi:.1}, y {y_lo:.1}..{y_hi:.1} \
                 in a {w}x{h} image",
                label(k)
            ));
        }
    }

    let min_gap = 2.0 * r + CLEARANCE_PX;
    let mut closest = f64::INFINITY;
    for a in 0..n {
        for b in a + 1..n {
            let (d, f) = (0..frames)
                .map(|f| ((rec.frame(f)[a] - rec.frame(f)[b]).norm(), f))
                .fold((f64::INFINITY, 0), |m, x| if x.0 < m.0 { x } else { m });
            closest = closest.min(d);
            if d <= min_gap {
                problems.push(format!(
                    "particles {} and {} come {d:.2} px apart at frame {f} (discs need > {min_gap} px)",
                    label(a),
                    label(b)
                ));
            }
        }
    }

    let mut stretch_px = (f64::INFINITY, 0.0f64);
    let mut stretch_pct = (f64::INFINITY, 0.0f64);
    for (k, s) in scene.springs.iter().enumerate() {
        let (i, j) = (s.ends[0].index(), s.ends[1].index());
        let (lo, hi) = range((0..frames).map(|f| (rec.frame(f)[i] - rec.frame(f)[j]).norm()));
        let rest = s.rest_length.unwrap_or(lo);
        let need = (MIN_STRETCH_FRACTION * rest).max(MIN_STRETCH_PX);
        stretch_px = (stretch_px.0.min(hi - lo), stretch_px.1.max(hi - lo));
        let pct = 100.0 * (hi - lo) / rest;
        stretch_pct = (stretch_pct.0.min(pct), stretch_pct.1.max(pct));
        if hi - lo < need {
            problems.push(format!(
                "{} (rest {rest} px) only ranges {lo:.2}..{hi:.2} px; needs a range of {need:.2} px",
                scene.spring_label(k)
            ));
        }
    }

    let mut bend = (f64::INFINITY, 0.0f64);
    for (k, t) in scene.torsions.iter().enumerate() {
        let [i, j, l] = [t.center.index(), t.ends[0].index(), t.ends[1].index()];
        let angle = |f: usize| {
            let x = rec.frame(f);
            TorsionGeometry::new(x[i], x[j], x[l])
                .cos
                .clamp(-1.0, 1.0)
                .acos()
                .to_degrees()
        };
        let (lo, hi) = range((0..frames).map(angle));
        bend = (bend.0.min(hi - lo), bend.1.max(hi - lo));
        if hi - lo < MIN_BEND_DEGREES {
            problems.push(format!(
                "{} only bends {lo:.1}..{hi:.1} degrees; needs a range of {MIN_BEND_DEGREES} degrees",
                scene.torsion_label(k)
            ));
        }
    }

    // A wall nobody reaches is dead weight: some disc must touch every wall.
    for (k, wall) in scene.physics.walls.iter().enumerate() {
        let nearest = rec
            .positions
            .iter()
            .map(|&x| wall.signed_distance(x))
            .fold(f64::INFINITY, f64::min);
        if nearest > r {
            problems.push(format!(
                "no disc ever touches physics.walls[{k}] (nearest centre {nearest:.1} px away)"
            ));
        }
    }

    let model = scene.model().expect("every value known");
    let conservative = !model.has_velocity_dependent_forces() && model.physics.walls.is_empty();
    let mut drift = 0.0;
    if conservative {
        let e0 = model.total_energy(&rec.state(0));
        let energies: Vec<f64> = (0..frames).map(|f| model.total_energy(&rec.state(f))).collect();
        let scale = (0..frames)
            .map(|f| model.kinetic_energy(&rec.state(f)))
            .fold(0.0, f64::max);
        drift = energies.iter().map(|e| (e - e0).abs()).fold(0.0, f64::max) / scale.max(f64::MIN_POSITIVE);
        if drift > MAX_ENERGY_DRIFT {
            problems.push(format!(
                "energy drifts by {:.3}% of the peak kinetic energy",
                100.0 * drift
            ));
        }
    }

    let mut summary = format!(
        "{:<26} {n:>3} particles {:>3} springs {:>3} torsions {frames:>4} frames; closest pair {closest:.1} px",
        scene.name,
        scene.springs.len(),
        scene.torsions.len(),
    );
    if !scene.springs.is_empty() {
        summary += &format!(
            "; spring ranges {:.1}..{:.1} px ({:.1}..{:.1}% of rest)",
            stretch_px.0, stretch_px.1, stretch_pct.0, stretch_pct.1
        );
    }
    if !scene.torsions.is_empty() {
        summary += &format!("; torsion ranges {:.1}..{:.1} deg", bend.0, bend.1);
    }
    let max_step = (1..frames)
        .flat_map(|f| (0..n).map(move |k| (f, k)))
        .map(|(f, k)| (rec.frame(f)[k] - rec.frame(f - 1)[k]).norm())
        .fold(0.0, f64::max);
    summary += &format!("; fastest {max_step:.1} px/frame");
    if conservative {
        summary += &format!("; energy drift {:.4}%", 100.0 * drift);
    }
    (problems, summary)
}

#[test]
fn every_scene_is_lively_in_frame_and_bounded() {
    let paths = scene_paths();
    assert!(!paths.is_empty(), "no scenes in {}", scenes_dir().display());
    let mut failures = Vec::new();
    for path in &paths {
        let scene = Scene::load(path).unwrap_or_else(|e| panic!("{e}"));
        let model = scene
            .model()
            .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        let rec = simulate(
            &model,
            &scene.initial_state(),
            &scene.integration_parameters(),
            scene.recording.frames,
        );
        let (problems, summary) = check(&scene, &rec);
        println!("{summary}");
        for p in problems {
            failures.push(format!("{}: {p}", path.display()));
        }
    }
    assert!(failures.is_empty(), "scene problems:\n{}", failures.join("\n"));
}

#[test]
fn the_canonical_scenes_have_their_structure() {
    // (file stem, particles, springs, torsions): the paper's three objects.
    let expected = [("paper3", 3, 2, 1), ("paper5", 5, 4, 3), ("paper8", 8, 8, 10)];
    for (stem, particles, springs, torsions) in expected {
        let path = scenes_dir().join(format!("{stem}.toml"));
        let scene = Scene::load(&path).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(
            (scene.particles.len(), scene.springs.len(), scene.torsions.len()),
            (particles, springs, torsions),
            "{}",
            path.display()
        );
        assert!(
            scene.physics == physfit_model::Physics::default(),
            "{stem}: the paper's model has no extra physics"
        );
    }
    let chain = Scene::load(&scenes_dir().join("chain.toml")).unwrap_or_else(|e| panic!("{e}"));
    assert!(chain.physics.gravity.y > 0.0 && chain.particles.iter().any(|p| p.fixed));
    let floor = Scene::load(&scenes_dir().join("softbody-floor.toml")).unwrap_or_else(|e| panic!("{e}"));
    assert!(floor.physics.gravity.y > 0.0);
    assert!(floor
        .physics
        .walls
        .iter()
        .any(|w| w.normal.y < -0.9 && w.restitution < 1.0));
    let lattice = Scene::load(&scenes_dir().join("lattice10.toml")).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(lattice.particles.len(), 100);
}
