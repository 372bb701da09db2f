//! Scene files: the TOML contract between physfit's stages, validated into a [`Scene`].
//!
//! A *scene* has every value; a *structure* is a scene with bond values and `[physics]` left
//! out (topology, masses, frame-0 positions); a *fitted model* is a structure with the values
//! filled in, itself a scene that renders.

mod compare;
mod error;
mod file;

pub use compare::{compare_scenes, effects_beyond, SceneComparison, ValueComparison};
pub use error::{SceneError, SceneProblem};
pub use file::{
    Colour, ParticleFile, PhysicsFile, RailFile, RecordingFile, RenderSettings, RopeFile, RulerFile,
    SceneFile, SpringFile, TorsionFile, WallFile,
};

use std::collections::HashMap;
use std::path::Path;

use crate::{
    IntegrationParameters, IntegratorKind, Model, Particle, ParticleId, ParticleSet, Physics, Rail, Rope,
    Spring, State, Torsion, Vec2, Wall,
};

/// Default integration substeps per frame when `[recording]` gives none.
pub const DEFAULT_SUBSTEPS: u32 = 20;

/// Timing of a recording.
#[derive(Clone, Debug, PartialEq)]
pub struct RecordingSettings {
    /// Frames per second; frame `k` is at `t = k / fps`.
    pub fps: f64,
    /// Number of frames.
    pub frames: usize,
    /// Integration substeps per frame.
    pub substeps: u32,
    /// Integration scheme.
    pub integrator: IntegratorKind,
    /// The image scale, m/px (from `metres_per_px` or the ruler); `None` = unknown.
    pub metres_per_px: Option<f64>,
}

/// A particle as a scene describes it.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ParticleSpec {
    /// Unique id.
    pub id: String,
    /// Mass.
    pub mass: f64,
    /// Position at frame 0, px.
    pub position: Vec2,
    /// Velocity at frame 0, px/s.
    pub velocity: Vec2,
    /// Pinned.
    pub fixed: bool,
    /// This body's own linear drag coefficient, mass/s (`None` = `physics.body_drag`).
    pub body_drag: Option<f64>,
    /// This body's own quadratic drag coefficient, mass/px (`None` =
    /// `physics.body_quadratic_drag`).
    pub body_quadratic_drag: Option<f64>,
}

/// A spring as a scene describes it: values may be unknown (`None`).
#[derive(Clone, Debug, PartialEq)]
pub struct SpringSpec {
    /// The two particles.
    pub ends: [ParticleId; 2],
    /// Rest length `L`, px.
    pub rest_length: Option<f64>,
    /// Stiffness `S`.
    pub stiffness: Option<f64>,
    /// Per-spring dashpot coefficient, mass/s.
    pub damping: Option<f64>,
}

/// A torsion as a scene describes it: values may be unknown (`None`).
#[derive(Clone, Debug, PartialEq)]
pub struct TorsionSpec {
    /// Centre particle `i`.
    pub center: ParticleId,
    /// End particles `j`, `k`.
    pub ends: [ParticleId; 2],
    /// Rest cosine `M`.
    pub rest_cos: Option<f64>,
    /// Angular stiffness `T`.
    pub stiffness: Option<f64>,
}

/// A validated scene (or structure, or fitted model).
#[derive(Clone, Debug, PartialEq)]
pub struct Scene {
    /// Scene name.
    pub name: String,
    /// Timing.
    pub recording: RecordingSettings,
    /// Drawing settings (defaults where the file gives none).
    pub render: RenderSettings,
    /// True if and only if the file had a `[render]` table (kept when written back).
    pub has_render_table: bool,
    /// Particles, in file order; `ParticleId(k)` is `particles[k]`.
    pub particles: Vec<ParticleSpec>,
    /// Springs, in file order.
    pub springs: Vec<SpringSpec>,
    /// Torsions, in file order.
    pub torsions: Vec<TorsionSpec>,
    /// Extra physics (all off when the file has no `[physics]`).
    pub physics: Physics,
}

/// Largest magnitude of any number in a scene (positions, px; velocities, px/s; bond and
/// physics values): beyond it a simulation overflows long before it means anything.
pub const MAX_MAGNITUDE: f64 = 1e12;

/// Largest frame rate, frames/s.
pub const MAX_FPS: f64 = 1e7;

/// Most integration substeps per frame.
pub const MAX_SUBSTEPS: u32 = 100_000;

/// Smallest mass.
pub const MIN_MASS: f64 = 1e-12;

/// Checks that every value is finite and at most [`MAX_MAGNITUDE`] in magnitude.
fn check_finite(key: impl Fn() -> String, values: &[f64]) -> Result<(), SceneProblem> {
    if let Some(&value) = values.iter().find(|v| !v.is_finite()) {
        return Err(SceneProblem::NonFinite { key: key(), value });
    }
    match values.iter().find(|v| v.abs() > MAX_MAGNITUDE) {
        Some(&value) => Err(SceneProblem::OutOfRange {
            key: key(),
            value,
            allowed: "at most 1e12 in magnitude",
        }),
        None => Ok(()),
    }
}

fn check_range(
    key: impl FnOnce() -> String,
    value: f64,
    ok: bool,
    allowed: &'static str,
) -> Result<(), SceneProblem> {
    if ok {
        Ok(())
    } else {
        Err(SceneProblem::OutOfRange {
            key: key(),
            value,
            allowed,
        })
    }
}

/// Checks that `value` is finite, at most [`MAX_MAGNITUDE`] and not negative.
fn check_non_negative(key: impl Fn() -> String, value: f64) -> Result<(), SceneProblem> {
    check_finite(&key, &[value])?;
    check_range(key, value, value >= 0.0, "zero or positive")
}

fn v2(a: [f64; 2]) -> Vec2 {
    Vec2::new(a[0], a[1])
}

fn a2(v: Vec2) -> [f64; 2] {
    [v.x, v.y]
}

/// Returns true if and only if `v` is +0.0 exactly (not -0.0): the value of an absent key.
fn is_plus_zero(v: f64) -> bool {
    v.to_bits() == 0
}

fn is_plus_zero2(v: Vec2) -> bool {
    is_plus_zero(v.x) && is_plus_zero(v.y)
}

/// The scale given by `[recording]`, m/px: `metres_per_px`, or the ruler's length over its
/// length in px; giving both is an error.
fn scale_of(rec: &RecordingFile) -> Result<Option<f64>, SceneProblem> {
    match (rec.metres_per_px, &rec.ruler) {
        (Some(_), Some(_)) => Err(SceneProblem::TwoScales),
        (Some(m), None) => {
            check_finite(|| "recording.metres_per_px".into(), &[m])?;
            check_range(|| "recording.metres_per_px".into(), m, m > 0.0, "positive")?;
            Ok(Some(m))
        }
        (None, Some(r)) => {
            check_finite(
                || "recording.ruler".into(),
                &[r.from[0], r.from[1], r.to[0], r.to[1], r.length_m],
            )?;
            check_range(
                || "recording.ruler.length_m".into(),
                r.length_m,
                r.length_m > 0.0,
                "positive",
            )?;
            let px = (r.to[0] - r.from[0]).hypot(r.to[1] - r.from[1]);
            check_range(
                || "recording.ruler (from-to distance, px)".into(),
                px,
                px > 0.0,
                "positive (two different points)",
            )?;
            Ok(Some(r.length_m / px))
        }
        (None, None) => Ok(None),
    }
}

impl Scene {
    /// Reads and validates a scene file.
    pub fn load(path: &Path) -> Result<Scene, SceneError> {
        let text = std::fs::read_to_string(path).map_err(|source| SceneError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        let mut scene = Scene::from_toml_str(&text, &path.display().to_string())?;
        if scene.name.is_empty() {
            scene.name = path
                .file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_default();
        }
        Ok(scene)
    }

    /// Parses and validates scene text; `file` names it in errors.
    pub fn from_toml_str(text: &str, file: &str) -> Result<Scene, SceneError> {
        let raw: SceneFile = toml::from_str(text).map_err(|e| {
            let start = e.span().map(|s| s.start);
            let (line, column) = start.map(|s| line_column(text, s)).unwrap_or((1, 1));
            let mut message = e.message().to_string();
            // The parser names a bad value by position only: name its key too.
            if let Some(key) = start.and_then(|s| key_of_value_at(text, s)) {
                message = format!("{message} (key `{key}`)");
            }
            SceneError::Parse {
                file: file.to_string(),
                line,
                column,
                message,
            }
        })?;
        Scene::from_file(raw).map_err(|problem| SceneError::Invalid {
            file: file.to_string(),
            problem,
        })
    }

    /// Validates the raw file form.
    pub fn from_file(raw: SceneFile) -> Result<Scene, SceneProblem> {
        let rec = &raw.recording;
        check_finite(|| "recording.fps".into(), &[rec.fps])?;
        check_range(
            || "recording.fps".into(),
            rec.fps,
            rec.fps > 0.0 && rec.fps <= MAX_FPS,
            "positive and at most 1e7 frames/s",
        )?;
        check_range(
            || "recording.frames".into(),
            rec.frames as f64,
            rec.frames >= 1,
            "at least 1",
        )?;
        let substeps = rec.substeps.unwrap_or(DEFAULT_SUBSTEPS);
        check_range(
            || "recording.substeps".into(),
            substeps as f64,
            (1..=MAX_SUBSTEPS).contains(&substeps),
            "from 1 to 100000",
        )?;
        let metres_per_px = scale_of(rec)?;
        let render = raw.render.clone().unwrap_or_default();
        check_finite(|| "render.radius".into(), &[render.radius])?;
        check_range(
            || "render.radius".into(),
            render.radius,
            render.radius > 0.0,
            "positive",
        )?;
        check_finite(|| "render.noise".into(), &[render.noise])?;
        check_range(
            || "render.noise".into(),
            render.noise,
            render.noise >= 0.0,
            "zero or positive",
        )?;
        check_finite(|| "render.blur".into(), &[render.blur])?;
        check_range(
            || "render.blur".into(),
            render.blur,
            render.blur >= 0.0,
            "zero or positive",
        )?;
        for (key, v) in [("render.width", render.width), ("render.height", render.height)] {
            check_range(|| key.into(), v as f64, v >= 1, "at least 1")?;
        }

        if raw.particles.is_empty() {
            return Err(SceneProblem::NoParticles);
        }
        let mut index = HashMap::new();
        let mut particles = Vec::with_capacity(raw.particles.len());
        for (k, p) in raw.particles.iter().enumerate() {
            if p.id.is_empty() {
                return Err(SceneProblem::EmptyId(k));
            }
            if index.insert(p.id.clone(), ParticleId(k as u32)).is_some() {
                return Err(SceneProblem::DuplicateId(p.id.clone()));
            }
            check_finite(|| format!("particle \"{}\" mass", p.id), &[p.mass])?;
            if p.mass < MIN_MASS {
                return Err(SceneProblem::NonPositiveMass {
                    id: p.id.clone(),
                    mass: p.mass,
                });
            }
            check_finite(|| format!("particle \"{}\" position", p.id), &p.position)?;
            let velocity = p.velocity.unwrap_or([0.0, 0.0]);
            check_finite(|| format!("particle \"{}\" velocity", p.id), &velocity)?;
            for (key, v) in [
                ("body_drag", p.body_drag),
                ("body_quadratic_drag", p.body_quadratic_drag),
            ] {
                if let Some(v) = v {
                    check_non_negative(|| format!("particle \"{}\" {key}", p.id), v)?;
                }
            }
            particles.push(ParticleSpec {
                id: p.id.clone(),
                mass: p.mass,
                position: v2(p.position),
                velocity: v2(velocity),
                fixed: p.fixed,
                body_drag: p.body_drag,
                body_quadratic_drag: p.body_quadratic_drag,
            });
        }
        let resolve = |bond: &dyn Fn() -> String, ids: &[&String]| -> Result<Vec<ParticleId>, SceneProblem> {
            let mut out: Vec<ParticleId> = Vec::with_capacity(ids.len());
            for id in ids {
                let pid = *index.get(*id).ok_or_else(|| SceneProblem::MissingParticle {
                    bond: bond(),
                    id: (*id).clone(),
                })?;
                if out.contains(&pid) {
                    return Err(SceneProblem::RepeatedParticle {
                        bond: bond(),
                        id: (*id).clone(),
                    });
                }
                out.push(pid);
            }
            Ok(out)
        };

        let mut springs = Vec::with_capacity(raw.springs.len());
        for s in &raw.springs {
            let name = || spring_name(&s.between);
            let ends = resolve(&name, &[&s.between[0], &s.between[1]])?;
            for (key, v) in [
                ("length", s.length),
                ("stiffness", s.stiffness),
                ("damping", s.damping),
            ] {
                if let Some(v) = v {
                    check_finite(|| format!("{} {key}", name()), &[v])?;
                }
            }
            springs.push(SpringSpec {
                ends: [ends[0], ends[1]],
                rest_length: s.length,
                stiffness: s.stiffness,
                damping: s.damping,
            });
        }

        let mut torsions = Vec::with_capacity(raw.torsions.len());
        for t in &raw.torsions {
            let name = || torsion_name(&t.at, &t.between);
            let ids = resolve(&name, &[&t.at, &t.between[0], &t.between[1]])?;
            for (key, v) in [("rest_cos", t.rest_cos), ("stiffness", t.stiffness)] {
                if let Some(v) = v {
                    check_finite(|| format!("{} {key}", name()), &[v])?;
                }
            }
            if let Some(m) = t.rest_cos {
                check_range(
                    || format!("{} rest_cos", name()),
                    m,
                    (-1.0..=1.0).contains(&m),
                    "in [-1, 1]",
                )?;
            }
            torsions.push(TorsionSpec {
                center: ids[0],
                ends: [ids[1], ids[2]],
                rest_cos: t.rest_cos,
                stiffness: t.stiffness,
            });
        }

        let physics = match &raw.physics {
            None => Physics::default(),
            Some(ph) => physics_from_file(ph, &resolve)?,
        };

        Ok(Scene {
            name: raw.name.clone().unwrap_or_default(),
            recording: RecordingSettings {
                fps: rec.fps,
                frames: rec.frames,
                substeps,
                integrator: rec.integrator.unwrap_or_default(),
                metres_per_px,
            },
            render,
            has_render_table: raw.render.is_some(),
            particles,
            springs,
            torsions,
            physics,
        })
    }

    /// The raw file form, ready to serialise. Unknown values stay absent.
    pub fn to_file(&self) -> SceneFile {
        let id = |p: ParticleId| self.particles[p.index()].id.clone();
        let ph = &self.physics;
        // Absent keys read back as +0.0, so only +0.0 may be left out (-0.0 is written) for
        // the file to read back bit for bit.
        let nz = |v: f64| if is_plus_zero(v) { None } else { Some(v) };
        let physics = if is_plus_zero2(ph.gravity)
            && is_plus_zero(ph.drag)
            && is_plus_zero(ph.quadratic_drag)
            && is_plus_zero(ph.spring_damping)
            && is_plus_zero(ph.body_drag)
            && is_plus_zero(ph.body_quadratic_drag)
            && is_plus_zero(ph.surface_friction)
            && ph.walls.is_empty()
            && ph.ropes.is_empty()
            && ph.rails.is_empty()
        {
            None
        } else {
            Some(PhysicsFile {
                gravity: if is_plus_zero2(ph.gravity) {
                    None
                } else {
                    Some(a2(ph.gravity))
                },
                drag: nz(ph.drag),
                quadratic_drag: nz(ph.quadratic_drag),
                spring_damping: nz(ph.spring_damping),
                body_drag: nz(ph.body_drag),
                body_quadratic_drag: nz(ph.body_quadratic_drag),
                surface_friction: nz(ph.surface_friction),
                walls: ph
                    .walls
                    .iter()
                    .map(|w| WallFile {
                        point: a2(w.point),
                        normal: a2(w.normal),
                        restitution: (!w.is_bumper()).then_some(w.restitution),
                        friction: nz(w.friction),
                        stiffness: nz(w.stiffness),
                        damping: nz(w.damping),
                    })
                    .collect(),
                ropes: ph
                    .ropes
                    .iter()
                    .map(|r| RopeFile {
                        between: [id(r.ends[0]), id(r.ends[1])],
                        length: r.length,
                        slack: r.slack,
                    })
                    .collect(),
                rails: ph
                    .rails
                    .iter()
                    .map(|r| RailFile {
                        particle: id(r.particle),
                        point: a2(r.point),
                        direction: a2(r.direction),
                        friction: nz(r.friction),
                    })
                    .collect(),
            })
        };
        SceneFile {
            name: Some(self.name.clone()),
            recording: RecordingFile {
                fps: self.recording.fps,
                frames: self.recording.frames,
                substeps: Some(self.recording.substeps),
                integrator: Some(self.recording.integrator),
                metres_per_px: self.recording.metres_per_px,
                ruler: None,
            },
            render: if self.has_render_table {
                Some(self.render.clone())
            } else {
                None
            },
            particles: self
                .particles
                .iter()
                .map(|p| ParticleFile {
                    id: p.id.clone(),
                    mass: p.mass,
                    position: a2(p.position),
                    velocity: if is_plus_zero2(p.velocity) {
                        None
                    } else {
                        Some(a2(p.velocity))
                    },
                    fixed: p.fixed,
                    body_drag: p.body_drag,
                    body_quadratic_drag: p.body_quadratic_drag,
                })
                .collect(),
            springs: self
                .springs
                .iter()
                .map(|s| SpringFile {
                    between: [id(s.ends[0]), id(s.ends[1])],
                    length: s.rest_length,
                    stiffness: s.stiffness,
                    damping: s.damping,
                })
                .collect(),
            torsions: self
                .torsions
                .iter()
                .map(|t| TorsionFile {
                    at: id(t.center),
                    between: [id(t.ends[0]), id(t.ends[1])],
                    rest_cos: t.rest_cos,
                    stiffness: t.stiffness,
                })
                .collect(),
            physics,
        }
    }

    /// The scene as TOML text.
    pub fn to_toml_string(&self) -> Result<String, SceneError> {
        toml::to_string(&self.to_file()).map_err(|e| SceneError::Serialize(e.to_string()))
    }

    /// Writes the scene to `path` atomically (a temporary file renamed into place).
    pub fn save(&self, path: &Path) -> Result<(), SceneError> {
        let text = self.to_toml_string()?;
        crate::write_atomic(path, text.as_bytes()).map_err(|source| SceneError::Io {
            path: path.to_path_buf(),
            source,
        })
    }

    /// The structure of this scene: same topology, masses and frame-0 positions, and its
    /// constraints (`physics.ropes`, `physics.rails`: what holds the particles, as bonds do);
    /// bond values, per-spring damping, per-particle drag and the rest of `[physics]`
    /// removed.
    pub fn structure(&self) -> Scene {
        let mut s = self.clone();
        for p in &mut s.particles {
            p.body_drag = None;
            p.body_quadratic_drag = None;
        }
        for sp in &mut s.springs {
            sp.rest_length = None;
            sp.stiffness = None;
            sp.damping = None;
        }
        for t in &mut s.torsions {
            t.rest_cos = None;
            t.stiffness = None;
        }
        s.physics = Physics {
            ropes: self.physics.ropes.clone(),
            rails: self.physics.rails.clone(),
            ..Physics::default()
        };
        s
    }

    /// Number of unknown bond values (absent `length`, `stiffness`, `rest_cos`).
    pub fn unknown_count(&self) -> usize {
        self.springs
            .iter()
            .map(|s| s.rest_length.is_none() as usize + s.stiffness.is_none() as usize)
            .sum::<usize>()
            + self
                .torsions
                .iter()
                .map(|t| t.rest_cos.is_none() as usize + t.stiffness.is_none() as usize)
                .sum::<usize>()
    }

    /// Index of the particle with this id.
    pub fn particle_id(&self, id: &str) -> Option<ParticleId> {
        self.particles
            .iter()
            .position(|p| p.id == id)
            .map(|k| ParticleId(k as u32))
    }

    /// The spring's display name, e.g. `spring p0-p1`.
    pub fn spring_label(&self, k: usize) -> String {
        let s = &self.springs[k];
        spring_name(&[
            self.particles[s.ends[0].index()].id.clone(),
            self.particles[s.ends[1].index()].id.clone(),
        ])
    }

    /// The torsion's display name, e.g. `torsion p0-p1-p2` (centre in the middle).
    pub fn torsion_label(&self, k: usize) -> String {
        let t = &self.torsions[k];
        let id = |p: ParticleId| self.particles[p.index()].id.clone();
        torsion_name(&id(t.center), &[id(t.ends[0]), id(t.ends[1])])
    }

    /// The model with every value, or an error naming the first unknown value.
    pub fn model(&self) -> Result<Model, SceneProblem> {
        let particles = ParticleSet {
            particles: self
                .particles
                .iter()
                .map(|p| Particle {
                    mass: p.mass,
                    fixed: p.fixed,
                    body_drag: p.body_drag,
                    body_quadratic_drag: p.body_quadratic_drag,
                })
                .collect(),
        };
        let mut springs = Vec::with_capacity(self.springs.len());
        for (k, s) in self.springs.iter().enumerate() {
            let need = |v: Option<f64>, key| {
                v.ok_or_else(|| SceneProblem::UnknownValue {
                    bond: self.spring_label(k),
                    key,
                })
            };
            let mut spring = Spring::new(
                s.ends[0],
                s.ends[1],
                need(s.rest_length, "length")?,
                need(s.stiffness, "stiffness")?,
            );
            spring.damping = s.damping;
            springs.push(spring);
        }
        let mut torsions = Vec::with_capacity(self.torsions.len());
        for (k, t) in self.torsions.iter().enumerate() {
            let need = |v: Option<f64>, key| {
                v.ok_or_else(|| SceneProblem::UnknownValue {
                    bond: self.torsion_label(k),
                    key,
                })
            };
            torsions.push(Torsion::new(
                t.center,
                t.ends[0],
                t.ends[1],
                need(t.rest_cos, "rest_cos")?,
                need(t.stiffness, "stiffness")?,
            ));
        }
        Ok(Model {
            particles,
            springs,
            torsions,
            physics: self.physics.clone(),
        })
    }

    /// The state at frame 0.
    pub fn initial_state(&self) -> State {
        State::new(
            self.particles.iter().map(|p| p.position).collect(),
            self.particles
                .iter()
                .map(|p| if p.fixed { Vec2::zeros() } else { p.velocity })
                .collect(),
        )
    }

    /// Time stepping of the recording.
    pub fn integration_parameters(&self) -> IntegrationParameters {
        IntegrationParameters {
            frame_dt: 1.0 / self.recording.fps,
            substeps: self.recording.substeps,
            integrator: self.recording.integrator,
        }
    }
}

/// Resolves the particle ids a bond or constraint (named by the first argument) lists.
type Resolve<'a> = dyn Fn(&dyn Fn() -> String, &[&String]) -> Result<Vec<ParticleId>, SceneProblem> + 'a;

fn physics_from_file(ph: &PhysicsFile, resolve: &Resolve) -> Result<Physics, SceneProblem> {
    let mut out = Physics::default();
    if let Some(g) = ph.gravity {
        check_finite(|| "physics.gravity".into(), &g)?;
        out.gravity = v2(g);
    }
    for (key, v, slot) in [
        ("physics.drag", ph.drag, &mut out.drag),
        (
            "physics.quadratic_drag",
            ph.quadratic_drag,
            &mut out.quadratic_drag,
        ),
        (
            "physics.spring_damping",
            ph.spring_damping,
            &mut out.spring_damping,
        ),
    ] {
        if let Some(v) = v {
            check_finite(|| key.into(), &[v])?;
            *slot = v;
        }
    }
    for (key, v, slot) in [
        ("physics.body_drag", ph.body_drag, &mut out.body_drag),
        (
            "physics.body_quadratic_drag",
            ph.body_quadratic_drag,
            &mut out.body_quadratic_drag,
        ),
        (
            "physics.surface_friction",
            ph.surface_friction,
            &mut out.surface_friction,
        ),
    ] {
        if let Some(v) = v {
            check_non_negative(|| key.into(), v)?;
            *slot = v;
        }
    }
    for (k, w) in ph.walls.iter().enumerate() {
        out.walls.push(wall_from_file(k, w)?);
    }
    for r in &ph.ropes {
        let name = || format!("rope {}-{}", r.between[0], r.between[1]);
        let ends = resolve(&name, &[&r.between[0], &r.between[1]])?;
        check_finite(|| format!("{} length", name()), &[r.length])?;
        check_range(
            || format!("{} length", name()),
            r.length,
            r.length > 0.0,
            "positive",
        )?;
        out.ropes.push(Rope {
            ends: [ends[0], ends[1]],
            length: r.length,
            slack: r.slack,
        });
    }
    for (k, r) in ph.rails.iter().enumerate() {
        let key = |name: &str| format!("physics.rails[{k}].{name}");
        let ids = resolve(&|| format!("rail {}", r.particle), &[&r.particle])?;
        check_finite(|| key("point"), &r.point)?;
        check_finite(|| key("direction"), &r.direction)?;
        let direction = v2(r.direction);
        let mut rail = Rail::new(ids[0], v2(r.point), direction).ok_or_else(|| SceneProblem::OutOfRange {
            key: key("direction"),
            value: direction.norm(),
            allowed: "of non-zero length",
        })?;
        if let Some(mu) = r.friction {
            check_non_negative(|| key("friction"), mu)?;
            rail = rail.with_friction(mu);
        }
        out.rails.push(rail);
    }
    Ok(out)
}

/// Validates `[[physics.walls]]` entry `k`: a rigid wall (restitution, optional friction)
/// or a spring bumper (stiffness, optional damping; no restitution or friction).
fn wall_from_file(k: usize, w: &WallFile) -> Result<Wall, SceneProblem> {
    let key = |name: &str| format!("physics.walls[{k}].{name}");
    check_finite(|| key("point"), &w.point)?;
    check_finite(|| key("normal"), &w.normal)?;
    let stiffness = w.stiffness.unwrap_or(0.0);
    check_non_negative(|| key("stiffness"), stiffness)?;
    let bumper = stiffness > 0.0;
    let restitution = match (w.restitution, bumper) {
        (Some(e), false) => {
            check_finite(|| key("restitution"), &[e])?;
            check_range(|| key("restitution"), e, (0.0..=1.0).contains(&e), "in [0, 1]")?;
            e
        }
        (None, false) => return Err(SceneProblem::NoWallRestitution(k)),
        (Some(e), true) => return Err(SceneProblem::OutOfRange {
            key: key("restitution"),
            value: e,
            allowed:
                "absent on a spring bumper (a wall with stiffness): its stiffness and damping set the rebound",
        }),
        (None, true) => 0.0,
    };
    let mut wall =
        Wall::new(v2(w.point), v2(w.normal), restitution).ok_or(SceneProblem::ZeroWallNormal(k))?;
    if let Some(mu) = w.friction {
        check_non_negative(|| key("friction"), mu)?;
        check_range(
            || key("friction"),
            mu,
            !bumper || mu == 0.0,
            "zero on a spring bumper (a wall with stiffness)",
        )?;
        wall = wall.with_friction(mu);
    }
    if let Some(c) = w.damping {
        check_non_negative(|| key("damping"), c)?;
        check_range(
            || key("damping"),
            c,
            bumper || c == 0.0,
            "zero on a rigid wall (give the wall a stiffness to make it a bumper)",
        )?;
    }
    if bumper {
        wall = wall.with_bumper(stiffness, w.damping.unwrap_or(0.0));
    }
    Ok(wall)
}

/// A spring's display name from its two ids: `spring a-b`.
pub fn spring_name(between: &[String; 2]) -> String {
    format!("spring {}-{}", between[0], between[1])
}

/// A torsion's display name: `torsion j-i-k` with the centre `i` in the middle.
pub fn torsion_name(at: &str, between: &[String; 2]) -> String {
    format!("torsion {}-{}-{}", between[0], at, between[1])
}

/// The key of a `key = value` line when `offset` points into the value, else `None`.
fn key_of_value_at(text: &str, offset: usize) -> Option<&str> {
    let offset = offset.min(text.len());
    let line_start = text.get(..offset)?.rfind('\n').map_or(0, |k| k + 1);
    let before = text.get(line_start..offset)?;
    let (key, _) = before.split_once('=')?;
    let key = key.trim();
    let bare = |c: char| c.is_ascii_alphanumeric() || c == '_' || c == '-' || c == '.' || c == '"';
    (!key.is_empty() && key.chars().all(bare)).then_some(key)
}

fn line_column(text: &str, offset: usize) -> (usize, usize) {
    let before = &text[..offset.min(text.len())];
    let line = before.matches('\n').count() + 1;
    let column = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
    (line, column)
}
