//! The random recordings of `physfit bench diagnose`: for each seed a complete physfit scene
//! (the truth), its structure (the truth less the concealed effects, bond values and
//! `[physics]`: what `physfit run` writes as `structure.toml`) and what was concealed, with the
//! true values.
//!
//! Everything is drawn from one `StdRng` seeded with the recording's seed, so a seed always
//! gives the same recording. Scales are relative to the recording (its duration
//! `T = (frames - 1) / fps`, the particle spacing, the typical speed), never tuned to a scene:
//!
//! * timing: 24-240 frames/s and 10-600 frames, both log-uniform (`small`: at most 150 frames);
//! * look: disc radius 3-20 px, pixel noise 0-10 grey levels, bright on dark or dark on light;
//! * object: 1-10 particles (`small`: 1-4) of mass 0.5-2, as free particles (at most three), a
//!   chain, a triangulated strip or a random connected graph, with torsions at some joints half
//!   of the time; spacing 1.2-2.5 times `max(3.2 r, 2 r + 10, 24)` px; springs with an oscillation
//!   period of 8 frames to `T` (at most 40 times 8 frames), log-uniform, and rest lengths
//!   within 8 % of the start distances, so that they oscillate;
//! * start velocity: a travel of 10-300 px over `T` (log-uniform) in any direction, a spin of
//!   up to that speed at the object's rim, and up to 20 % of it per particle and coordinate;
//! * concealed effects: none (15 %), one (40 %) or two (45 %) of the seven [`Kind`]s, each
//!   magnitude log-uniform over two decades relative to the recording: a field whose
//!   displacement `|g| T^2 / 2` is 3-300 px, in any direction; linear drag with `c T` of
//!   0.02-2; quadratic drag with `c v T` of 0.02-2 (`v` the typical speed, start and
//!   field's together); dashpots on every spring with a damping ratio of 0.005-0.5; a missing
//!   spring between two particles the structure does not join, 0.01-1 times the structure's
//!   stiffness; a tether from one particle to a fixed point 1.5-5 times `max(2 size, 4 r + 20)`
//!   px away, against the field when there is one (a pendulum, stretched 0.05-5 px by the
//!   object's weight), else in any direction with a radial period of 8 frames to `T`; a wall
//!   the motion reaches 30-90 % of its way towards, facing the field within 17 degrees (a
//!   floor) three times in four when there is a field, restitution 0.5-0.95.
//!
//! A draw is kept when it is physically sensible, judged on the truth's own simulation:
//! positions finite; no two discs (the fixed point's included) closer than `2 r + 2` px in
//! any frame; with two particles or more, none moving in one frame more than half their
//! smallest distance (linking would be ambiguous for any tracker); integration stable with at
//! most [`motion::MAX_SUBSTEPS`] substeps; a frame of at most 1200 px a side and 8e7 pixel-frames
//! (`small`: 640 px and 1.5e7). Otherwise the object, its motion and every magnitude are drawn
//! again from the same generator (the effect classes are kept, so their mix stays as drawn),
//! at most [`MAX_DRAWS`] times. The frame is fitted around the motion with a margin of
//! `r + 6` px, at least 160 px a side, the motion in its middle; the fixed point of a tether
//! may be in view (drawn as a disc) or not.

mod concealed;
mod effects;
mod motion;
mod object;

pub use concealed::{class_label, Concealed, Kind};
pub use motion::Regime;

use anyhow::bail;
use physfit_model::scene::RecordingSettings;
use physfit_model::{Colour, IntegratorKind, RenderSettings, Scene, Vec2};
use rand::rngs::StdRng;
use rand::seq::SliceRandom;
use rand::{Rng, SeedableRng};

use concealed::concealed_of;

/// Most draws tried for one seed before it is given up.
pub const MAX_DRAWS: usize = 400;
/// Id of a tether's fixed point in the truth scene (never in the structure).
const PIVOT: &str = "pivot";
/// Smallest frame side, px: room for the background around the object.
const MIN_SIDE: f64 = 160.0;

/// One drawn recording.
#[derive(Clone, Debug)]
pub struct Drawn {
    /// The complete scene rendered (every effect in).
    pub truth: Scene,
    /// What the diagnosis is given: the truth less the concealed effects, bond values and
    /// physics.
    pub structure: Scene,
    /// The concealed effects, in [`Kind`] order.
    pub concealed: Vec<Concealed>,
    /// What kind of recording it is.
    pub regime: Regime,
}

impl Drawn {
    /// The concealed classes.
    pub fn kinds(&self) -> Vec<Kind> {
        self.concealed.iter().map(Concealed::kind).collect()
    }
}

/// Draws recording `seed`; `small` caps it at 4 particles and 150 frames (the test seeds).
///
/// # Errors
///
/// When no physically sensible recording came out of [`MAX_DRAWS`] draws.
pub fn draw(seed: u64, small: bool) -> anyhow::Result<Drawn> {
    let mut rng = StdRng::seed_from_u64(seed);
    let kinds = draw_kinds(&mut rng);
    for rejected in 0..MAX_DRAWS {
        if let Some(mut drawn) = draw_once(&mut rng, &kinds, seed, small) {
            drawn.regime.rejected_draws = rejected;
            return Ok(drawn);
        }
    }
    bail!(
        "seed {seed}: no physically sensible recording concealing {} in {MAX_DRAWS} draws",
        class_label(&kinds)
    )
}

/// None (15 %), one (40 %) or two (45 %) distinct classes, sorted.
fn draw_kinds(rng: &mut StdRng) -> Vec<Kind> {
    let u: f64 = rng.gen();
    let count = if u < 0.15 {
        0
    } else if u < 0.55 {
        1
    } else {
        2
    };
    let mut all = Kind::ALL.to_vec();
    all.shuffle(rng);
    all.truncate(count);
    all.sort();
    all
}

/// A number log-uniform in `[a, b]` (`a` when `b <= a`).
fn log_uniform(rng: &mut StdRng, a: f64, b: f64) -> f64 {
    if b <= a {
        return a;
    }
    rng.gen_range(a.ln()..b.ln()).exp()
}

/// The unit vector at angle `a` (rad, from +x towards +y).
fn unit(a: f64) -> Vec2 {
    Vec2::new(a.cos(), a.sin())
}

/// `v` turned by `a` rad.
fn turned(v: Vec2, a: f64) -> Vec2 {
    let (s, c) = a.sin_cos();
    Vec2::new(c * v.x - s * v.y, s * v.x + c * v.y)
}

/// One draw of everything but the classes; `None` when it is not physically sensible.
fn draw_once(rng: &mut StdRng, kinds: &[Kind], seed: u64, small: bool) -> Option<Drawn> {
    let mut object = object::draw_object(rng, kinds, small)?;
    let hidden = effects::conceal(rng, kinds, &mut object)?;
    let substeps = motion::substeps_needed(&object.particles, &object.springs, &object.torsions, object.fps)?;
    let n = object.moving;
    let mut truth = Scene {
        name: format!("bench-diagnose-{seed}"),
        recording: RecordingSettings {
            fps: object.fps,
            frames: object.frames,
            substeps,
            integrator: IntegratorKind::Verlet,
            metres_per_px: None,
        },
        render: RenderSettings::default(),
        has_render_table: true,
        particles: object.particles,
        springs: object.springs,
        torsions: object.torsions,
        physics: hidden.physics,
    };
    if kinds.contains(&Kind::Wall) {
        let wall = effects::place_wall(rng, &truth, n)?;
        truth.physics.walls.push(wall);
    }

    // The frame around the motion; the recording is judged as it will be rendered.
    let local = motion::simulate(&truth)?;
    let radius = object.radius;
    let margin = radius + 6.0;
    let (low, high) = motion::extent(&local, n)?;
    let size_px = (high - low)
        .add_scalar(2.0 * margin)
        .map(|v| v.max(MIN_SIDE).ceil());
    // The motion in the middle of the frame.
    let shift = (size_px - (high - low)) / 2.0 - low;
    let (max_side, max_pixel_frames) = if small { (640.0, 1.5e7) } else { (1200.0, 8e7) };
    if size_px.max() > max_side || size_px.x * size_px.y * object.frames as f64 > max_pixel_frames {
        return None;
    }
    for p in &mut truth.particles {
        p.position += shift;
    }
    for w in &mut truth.physics.walls {
        w.point += shift;
    }
    let bright = rng.gen_bool(0.5);
    let (dim, light) = (rng.gen_range(10..60u8), rng.gen_range(170..250u8));
    truth.render = RenderSettings {
        width: size_px.x as u32,
        height: size_px.y as u32,
        radius,
        background: Colour::Grey(if bright { dim } else { light }),
        foreground: Colour::Grey(if bright { light } else { dim }),
        noise: object.noise,
        blur: 0.0,
        seed,
    };
    let recording = motion::simulate(&truth)?;
    let mut regime = motion::judge_motion(&truth, &recording, n)?;
    regime.topology = object.topology;
    regime.springs = object.edges.len();
    regime.torsions = truth.torsions.len();

    let concealed: Vec<Concealed> = kinds
        .iter()
        .map(|&k| concealed_of(k, &truth, hidden.missing.as_ref(), hidden.tethered.as_deref()))
        .collect::<Option<_>>()?;
    let bare = concealed.iter().fold(truth.clone(), |s, c| c.remove_from(&s));
    Some(Drawn {
        structure: bare.structure(),
        truth,
        concealed,
        regime,
    })
}

#[cfg(test)]
mod tests {
    use super::concealed::remove_particle;
    use super::*;
    use physfit_model::scene::{ParticleSpec, SpringSpec};
    use physfit_model::{ParticleId, Physics};

    #[test]
    fn a_seed_always_draws_the_same_recording() {
        for seed in [1, 2, 3] {
            let (a, b) = (draw(seed, true).unwrap(), draw(seed, true).unwrap());
            assert_eq!(a.truth, b.truth);
            assert_eq!(a.concealed, b.concealed);
        }
    }

    #[test]
    fn the_structure_is_the_truth_less_what_was_concealed() {
        for seed in 1..=40 {
            let d = draw(seed, true).unwrap();
            let s = &d.structure;
            assert!(
                s.particles.iter().all(|p| !p.fixed && p.id != PIVOT),
                "seed {seed}"
            );
            assert_eq!(s.physics, Physics::default(), "seed {seed}");
            assert_eq!(s.unknown_count(), 2 * (s.springs.len() + s.torsions.len()));
            let extra = usize::from(d.kinds().contains(&Kind::MissingSpring))
                + usize::from(d.kinds().contains(&Kind::Tether));
            assert_eq!(d.truth.springs.len(), s.springs.len() + extra, "seed {seed}");
            assert!(d.truth.model().is_ok());
            assert!(d.regime.frames >= 10 && d.regime.frames <= 150);
        }
    }

    #[test]
    fn removing_a_tether_renumbers_the_bonds_after_its_pivot() {
        let mut s = draw(5, true).unwrap().truth;
        s.particles.insert(
            0,
            ParticleSpec {
                id: PIVOT.into(),
                mass: 1.0,
                position: Vec2::zeros(),
                velocity: Vec2::zeros(),
                fixed: true,
                ..Default::default()
            },
        );
        for sp in &mut s.springs {
            sp.ends.iter_mut().for_each(|e| e.0 += 1);
        }
        let before = s.springs.len();
        s.springs.push(SpringSpec {
            ends: [ParticleId(0), ParticleId(1)],
            rest_length: Some(10.0),
            stiffness: Some(1.0),
            damping: None,
        });
        remove_particle(&mut s, PIVOT);
        assert_eq!(s.springs.len(), before);
        assert!(s.model().is_ok());
    }
}
