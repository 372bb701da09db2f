//! The foundation's scenes, rendered clean and with noise: every particle found in every
//! frame under its own name, no identity switch, and the RMS error per axis under
//! trackpy's figures for the (smaller, fainter) discs.

use physfit_model::{simulate, RenderSettings};
use physfit_track::TrackOptions;

use crate::common::{assert_followed, load_scene, render_to, track, TempDir, Truth};

/// Frames rendered of each scene.
const FRAMES: usize = 60;

fn check_scene(file: &str) {
    let scene = load_scene(file);
    let model = scene.model().expect("scene model");
    let rec = simulate(
        &model,
        &scene.initial_state(),
        &scene.integration_parameters(),
        FRAMES,
    );
    let names: Vec<String> = scene.particles.iter().map(|p| p.id.clone()).collect();
    let truth = Truth::from_recording(names, &rec, FRAMES);
    // trackpy's RMS per axis for radius-4 discs of amplitude 200 at noise 0 and 5.
    for (noise, target) in [(0.0, 0.004), (5.0, 0.014)] {
        let settings = RenderSettings {
            noise,
            ..scene.render.clone()
        };
        let dir = TempDir::new(file);
        render_to(&truth, &settings, dir.path());
        let options = TrackOptions {
            named_start: Some(
                scene
                    .particles
                    .iter()
                    .map(|p| (p.id.clone(), [p.position.x, p.position.y]))
                    .collect(),
            ),
            ..TrackOptions::default()
        };
        let out = track(dir.path(), &options);
        println!("{file} noise {noise}: {}", out.stats);
        let s = assert_followed(
            &format!("{file} noise {noise}"),
            &out,
            &truth.table(settings.width, settings.height),
        );
        println!(
            "{file} noise {noise}: rms x {:.5} y {:.5} px, max {:.4} px, {} split, {} bridged, switches {}",
            s.rms_x, s.rms_y, s.max_error, out.stats.split_count, out.stats.interpolated_count, s.id_switches
        );
        assert!(
            s.rms_x < target && s.rms_y < target,
            "{file} noise {noise}: rms {} {} px, target {target}",
            s.rms_x,
            s.rms_y
        );
        assert!(
            out.stats.ambiguities.is_empty(),
            "{file} noise {noise}: {:?}",
            out.stats.ambiguities
        );
    }
}

#[test]
fn paper3_is_followed_exactly() {
    check_scene("paper3.toml");
}

#[test]
fn paper5_is_followed_exactly() {
    check_scene("paper5.toml");
}

#[test]
fn paper8_is_followed_exactly() {
    check_scene("paper8.toml");
}

#[test]
fn chain_is_followed_exactly() {
    check_scene("chain.toml");
}

#[test]
fn softbody_floor_is_followed_exactly() {
    check_scene("softbody-floor.toml");
}
