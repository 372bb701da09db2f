//! Errors from reading and validating scene files.

use std::path::PathBuf;

/// A number as an error shows it: huge and tiny ones in exponent form (`1e308`, not 309 digits).
fn show(v: f64) -> String {
    if v != 0.0 && v.is_finite() && !(1e-6..1e15).contains(&v.abs()) {
        format!("{v:e}")
    } else {
        format!("{v}")
    }
}

/// What is wrong with a scene's content; each names the key or id at fault.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum SceneProblem {
    /// Two particles share an id.
    #[error("duplicate particle id \"{0}\"")]
    DuplicateId(String),
    /// A particle id is empty.
    #[error("particle {0} has an empty id")]
    EmptyId(usize),
    /// A bond names a particle that does not exist.
    #[error("{bond} names particle \"{id}\", which is not defined")]
    MissingParticle {
        /// The bond, as written.
        bond: String,
        /// The missing id.
        id: String,
    },
    /// A bond names the same particle more than once.
    #[error("{bond} names particle \"{id}\" twice")]
    RepeatedParticle {
        /// The bond, as written.
        bond: String,
        /// The repeated id.
        id: String,
    },
    /// A mass is zero, negative or below [`crate::scene::MIN_MASS`].
    #[error("particle \"{id}\" has mass {}; masses must be positive, from 1e-12 to 1e12", show(*.mass))]
    NonPositiveMass {
        /// Particle id.
        id: String,
        /// The mass given.
        mass: f64,
    },
    /// A number is NaN or infinite.
    #[error("{key} is {}; it must be a finite number", show(*.value))]
    NonFinite {
        /// The key, e.g. `particles "p0".position`.
        key: String,
        /// The value given.
        value: f64,
    },
    /// A value is outside its allowed range.
    #[error("{key} is {}; it must be {allowed}", show(*.value))]
    OutOfRange {
        /// The key.
        key: String,
        /// The value given.
        value: f64,
        /// The allowed range, in words.
        allowed: &'static str,
    },
    /// `[recording]` gives the scale twice (`metres_per_px` and a ruler).
    #[error("[recording] has both metres_per_px and [recording.ruler]: give one scale")]
    TwoScales,
    /// A wall's normal has zero length.
    #[error("physics.walls[{0}].normal has zero length")]
    ZeroWallNormal(usize),
    /// A rigid wall (no stiffness) gives no restitution.
    #[error("physics.walls[{0}] has no restitution: a rigid wall needs one (a spring bumper has a stiffness instead)")]
    NoWallRestitution(usize),
    /// A bond parameter is unknown where a value is needed (to simulate).
    #[error("{bond} has no {key}: a scene to simulate needs every bond's values")]
    UnknownValue {
        /// The bond, as written.
        bond: String,
        /// The missing key.
        key: &'static str,
    },
    /// The scene has no particles.
    #[error("the scene defines no particles")]
    NoParticles,
}

/// An error loading, validating or saving a scene file.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SceneError {
    /// The file could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The cause.
        #[source]
        source: std::io::Error,
    },
    /// The file is not valid TOML, or a key is unknown or of the wrong type.
    #[error("{file}:{line}:{column}: {message}")]
    Parse {
        /// The file (or `<string>`).
        file: String,
        /// 1-based line.
        line: usize,
        /// 1-based column.
        column: usize,
        /// What the parser said.
        message: String,
    },
    /// The file parsed but its content is invalid.
    #[error("{file}: {problem}")]
    Invalid {
        /// The file (or `<string>`).
        file: String,
        /// What is wrong.
        problem: SceneProblem,
    },
    /// The scene could not be serialised.
    #[error("cannot write scene: {0}")]
    Serialize(String),
}
