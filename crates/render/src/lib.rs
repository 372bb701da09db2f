//! Draws simulated recordings as camera-like image frames: the synthetic data physfit is
//! tested on.
//!
//! Each particle is a disc of the scene's radius (px), anti-aliased by its exact area coverage
//! of every pixel, in the foreground colour over the background; an optional Gaussian blur
//! (px) and additive Gaussian pixel noise (grey levels, seeded per frame) follow. Pixel
//! centres are at integer coordinates, x right, y down, as everywhere in physfit: an isolated
//! disc's intensity-weighted centroid is its true position. [`render_frame`] draws one frame,
//! [`render_frame_mut`] draws into reused buffers, and [`render_sequence`] writes a whole
//! [`physfit_model::Recording`] as numbered PNG files in parallel.
//!
//! # Example
//! ```
//! use physfit_model::{RenderSettings, Vec2};
//! use physfit_render::render_frame;
//! let settings = RenderSettings { width: 64, height: 48, ..RenderSettings::default() };
//! let frame = render_frame(&[Vec2::new(20.0, 30.0)], &settings, 0);
//! let grey = frame.as_luma8().unwrap();
//! assert_eq!(grey.get_pixel(20, 30)[0], 255); // disc centre: foreground
//! assert_eq!(grey.get_pixel(50, 10)[0], 0); // far away: background
//! ```

mod blur;
mod coverage;
mod error;
mod frame;
mod pixel;
mod sequence;

pub use coverage::add_disc as add_disc_coverage;
pub use error::RenderError;
pub use frame::{is_grey, render_frame, render_frame_mut, RenderScratch};
pub use sequence::{encode_png, frame_file_name, render_sequence, FRAME_NAME_DIGITS};
