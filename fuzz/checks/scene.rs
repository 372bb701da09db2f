//! Scene text through the parser and validation, then a short simulation of a scene that
//! validated: no panic; a validated scene starts from a finite state, saves to text that
//! validates again, and a simulation that leaves the finite numbers is caught by
//! `Recording::first_non_finite` (the check `simulate` and `render` make).

use physfit_model::{simulate, Scene};

/// Frames simulated: enough for a few steps of every force, few enough to stay fast.
const FRAMES: usize = 4;

/// Panics when `data` breaks the property above.
pub fn check(data: &[u8]) {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let Ok(scene) = Scene::from_toml_str(text, "fuzz.toml") else {
        return;
    };
    let saved = scene.to_toml_string().expect("a validated scene saves");
    if let Err(e) = Scene::from_toml_str(&saved, "saved.toml") {
        panic!("a validated scene saves to text that does not validate: {e}\n{saved}");
    }
    let initial = scene.initial_state();
    let finite = |v: &physfit_model::Vec2| v.x.is_finite() && v.y.is_finite();
    assert!(
        initial.positions.iter().chain(&initial.velocities).all(finite),
        "a validated scene with a non-finite initial state"
    );
    let Ok(model) = scene.model() else {
        return;
    };
    let params = scene.integration_parameters();
    // Substeps cost time: a few frames of a scene at the substep limit stay within a second.
    let frames = FRAMES.min(scene.recording.frames);
    let recording = simulate(&model, &initial, &params, frames);
    assert_eq!(recording.frame_count(), frames);
    let all_finite = recording
        .positions
        .iter()
        .chain(&recording.velocities)
        .all(finite);
    assert_eq!(all_finite, recording.first_non_finite().is_none());
}
