//! Test recordings of particles in many styles, drawn independently of `physfit-render`,
//! with their truth and the Cramér-Rao bound of their position error.
//!
//! The crate owns [`Style`] (what a recording looks like: profile, radius 1.5-60 px, mixed
//! sizes, polarity, grey or colour, blur, pixel noise, an illumination gradient, vignetting,
//! exposure drift and a light background drifting in and out of saturation), drawn at random
//! over the whole range by [`Style::random`], and [`Sequence`], which draws a style's paths
//! (smooth random walks that keep apart and inside the frame), its 8-bit PNG frames
//! (`frame_00000.png`, ...) and its [`Truth`] (frame, particle, x, y in px: x right, y down,
//! pixel centres at integer coordinates). Each pixel is the integral of the particle's profile
//! over the pixel's area (see [`ParticleLook`]); [`PositionBound`] is the Cramér-Rao bound of
//! the per-axis position error. Everything is deterministic from the style's seed.
//!
//! The tracker's tests and `physfit bench track --sweep` use it; it depends on no physfit
//! crate, so a renderer bug cannot hide a tracker bug of the same shape.
//!
//! # Example
//!
//! ```
//! use physfit_synth::{Profile, Sequence, Style};
//!
//! let mut style = Style::random(3);
//! style.profile = Profile::Gaussian;
//! let seq = Sequence::new(style);
//! let dir = std::env::temp_dir().join(format!("physfit-synth-doc-{}", std::process::id()));
//! seq.write_frames(&dir).unwrap();
//! assert!(dir.join("frame_00000.png").exists());
//! let bound = seq.bound(); // px², per axis
//! assert!(bound.variance[0] >= 0.0);
//! std::fs::remove_dir_all(&dir).unwrap();
//! ```

mod blur;
mod bound;
mod error;
mod look;
mod motion;
mod sequence;
mod style;
mod truth;

pub use bound::{cramer_rao, PositionBound};
pub use error::SynthError;
pub use look::{add_particle, samples_per_axis, ParticleLook};
pub use motion::draw_paths;
pub use sequence::{frame_file_name, Sequence};
pub use style::{Lines, Polarity, Profile, Style};
pub use truth::Truth;
