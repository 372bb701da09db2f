//! The on-disk TOML form of a scene, exactly as written (ids by name, values optional).
//!
//! These key names are a contract read and written by other tools: see `docs/scene-format.md`.

use serde::{Deserialize, Serialize};

use crate::IntegratorKind;

/// A colour: a grey level 0..255, or `[r, g, b]`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum Colour {
    /// Grey level 0 (black) to 255 (white).
    Grey(u8),
    /// Red, green, blue, each 0..255.
    Rgb([u8; 3]),
}

impl Colour {
    /// The colour as `[r, g, b]`.
    pub fn rgb(self) -> [u8; 3] {
        match self {
            Colour::Grey(g) => [g, g, g],
            Colour::Rgb(c) => c,
        }
    }
}

/// How a scene is drawn (`[render]`); every key optional.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RenderSettings {
    /// Image width, px.
    pub width: u32,
    /// Image height, px.
    pub height: u32,
    /// Disc radius, px.
    pub radius: f64,
    /// Background colour.
    pub background: Colour,
    /// Disc colour.
    pub foreground: Colour,
    /// Standard deviation of additive Gaussian pixel noise, grey levels.
    pub noise: f64,
    /// Standard deviation of the Gaussian blur applied before noise, px (0 = none).
    pub blur: f64,
    /// Seed of the pixel noise.
    pub seed: u64,
}

impl Default for RenderSettings {
    fn default() -> Self {
        RenderSettings {
            width: 512,
            height: 512,
            radius: 5.0,
            background: Colour::Grey(0),
            foreground: Colour::Grey(255),
            noise: 0.0,
            blur: 0.0,
            seed: 1,
        }
    }
}

/// `[recording]`: timing of the recording.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RecordingFile {
    /// Frames per second; frame `k` is at `t = k / fps`.
    pub fps: f64,
    /// Number of frames.
    pub frames: usize,
    /// Integration substeps per frame (default 20).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub substeps: Option<u32>,
    /// Integration scheme (default `verlet`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub integrator: Option<IntegratorKind>,
    /// The image scale, m/px (absent = unknown; reports then give px only).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub metres_per_px: Option<f64>,
    /// The image scale as a ruler seen in the image (instead of `metres_per_px`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ruler: Option<RulerFile>,
}

/// `[recording.ruler]`: two points of the image a known distance apart.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RulerFile {
    /// One end, px (x right, y down).
    pub from: [f64; 2],
    /// The other end, px.
    pub to: [f64; 2],
    /// The distance between them, m.
    pub length_m: f64,
}

/// One `[[particles]]` entry.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ParticleFile {
    /// Unique id.
    pub id: String,
    /// Mass.
    pub mass: f64,
    /// Position at frame 0, px.
    pub position: [f64; 2],
    /// Velocity at frame 0, px/s (default zero).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub velocity: Option<[f64; 2]>,
    /// Pinned (default false).
    #[serde(default, skip_serializing_if = "is_false")]
    pub fixed: bool,
    /// This body's linear drag coefficient, mass/s (`F = -b v`; default
    /// `physics.body_drag`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub body_drag: Option<f64>,
    /// This body's quadratic drag coefficient, mass/px (`F = -c |v| v`; default
    /// `physics.body_quadratic_drag`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub body_quadratic_drag: Option<f64>,
}

fn is_false(b: &bool) -> bool {
    !*b
}

/// One `[[springs]]` entry.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SpringFile {
    /// The two particle ids.
    pub between: [String; 2],
    /// Rest length `L`, px; absent = unknown.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub length: Option<f64>,
    /// Stiffness `S`; absent = unknown.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stiffness: Option<f64>,
    /// Dashpot coefficient overriding `physics.spring_damping`, mass/s.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub damping: Option<f64>,
}

/// One `[[torsions]]` entry.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TorsionFile {
    /// The centre particle id `i`.
    pub at: String,
    /// The end particle ids `j` and `k`.
    pub between: [String; 2],
    /// Rest cosine `M`; absent = unknown.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rest_cos: Option<f64>,
    /// Angular stiffness `T`; absent = unknown.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stiffness: Option<f64>,
}

/// One `[[physics.walls]]` entry.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WallFile {
    /// A point on the wall, px.
    pub point: [f64; 2],
    /// Normal pointing into the allowed side (normalised on load).
    pub normal: [f64; 2],
    /// Restitution of the normal velocity, 0..1: required on a rigid wall, absent on a
    /// spring bumper.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub restitution: Option<f64>,
    /// Coulomb friction coefficient, dimensionless, >= 0 (absent = frictionless; rigid
    /// walls only).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub friction: Option<f64>,
    /// Bumper stiffness `S`, energy/px² (absent = a rigid wall): energy `S s^2` for a
    /// penetration `s < 0`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stiffness: Option<f64>,
    /// Bumper dashpot coefficient, mass/s (bumpers only).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub damping: Option<f64>,
}

/// One `[[physics.ropes]]` entry: an inextensible rope (or rod) between two particles.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RopeFile {
    /// The two particle ids (one may be a fixed particle: a rope to a fixed point).
    pub between: [String; 2],
    /// Length, px (> 0).
    pub length: f64,
    /// Slack when the ends come closer than `length` (default false: a rigid rod).
    #[serde(default, skip_serializing_if = "is_false")]
    pub slack: bool,
}

/// One `[[physics.rails]]` entry: a particle held on a line.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RailFile {
    /// The particle id.
    pub particle: String,
    /// A point of the line, px.
    pub point: [f64; 2],
    /// Direction of the line (normalised on load).
    pub direction: [f64; 2],
    /// Coulomb friction coefficient along the rail, dimensionless, >= 0 (absent = none).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub friction: Option<f64>,
}

/// `[physics]`: each key absent = effect off.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PhysicsFile {
    /// Uniform acceleration, px/s².
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gravity: Option<[f64; 2]>,
    /// Linear drag, 1/s.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub drag: Option<f64>,
    /// Quadratic drag, 1/px.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub quadratic_drag: Option<f64>,
    /// Global spring dashpot coefficient, mass/s.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub spring_damping: Option<f64>,
    /// Linear drag of every body without its own, mass/s (`F = -b v`, not per mass).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub body_drag: Option<f64>,
    /// Quadratic drag of every body without its own, mass/px (`F = -c |v| v`, not per mass).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub body_quadratic_drag: Option<f64>,
    /// Dry friction of the surface under the motion, px/s² (the deceleration `mu g`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub surface_friction: Option<f64>,
    /// Walls.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub walls: Vec<WallFile>,
    /// Ropes and rods (distance constraints).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub ropes: Vec<RopeFile>,
    /// Rails (particles held on lines).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub rails: Vec<RailFile>,
}

/// A whole scene file.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneFile {
    /// Scene name (default: the file's stem).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
    /// Timing.
    pub recording: RecordingFile,
    /// Drawing settings.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub render: Option<RenderSettings>,
    /// Point masses.
    pub particles: Vec<ParticleFile>,
    /// Extension springs.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub springs: Vec<SpringFile>,
    /// Torsional springs.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub torsions: Vec<TorsionFile>,
    /// Extra physics.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub physics: Option<PhysicsFile>,
}
