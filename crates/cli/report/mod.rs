//! The report layer of `physfit`: the pictures and documents a run leaves behind.
//!
//! A report directory holds `report.md` (a short lab note with PNG pictures beside it), `report.html` (the same
//! note as ONE self-contained page, every picture inlined as a `data:` URI), `report.json` (the machine-readable
//! summary) and the pictures themselves:
//!
//! - [`line_chart`]: time-series charts (residuals per particle over time, cost history on a log axis);
//! - [`trajectory_plot`]: observed tracks with the predicted trajectories of one or two models drawn over them,
//!   optionally over a faded frame of the recording, with located mismatches circled;
//! - [`overlay_frame`]: a frame of the input with detections, fading track tails and predicted positions drawn on it.
//!
//! Coordinates follow the project's convention: image pixels, x right, y down, pixel centres at integer coordinates.
//! Text is drawn with DejaVu Sans embedded in the binary (`assets/fonts/`), so no picture depends on system fonts.
//! Every file is written atomically (`physfit_model::write_atomic`).
//!
//! A key design decision: the report *formats* go through one small `Exporter` trait (hyperfine's
//! `src/export/mod.rs`), each implementation turning the same [`ReportDocument`] into the bytes of one file, so
//! `report.md`, `report.html` and `report.json` can never drift apart in content; the pictures are separate free
//! functions because each kind takes different data.

mod chart;
mod colour;
mod export;
mod font;
mod html;
mod legend;
mod markdown;
mod overlay;
mod png;
mod trajectory;

pub use chart::{line_chart, LineChart, LineStyle, Series};
pub use export::{write_reports, HtmlExporter, JsonExporter, MarkdownExporter, ReportDocument};
pub use html::markdown_to_html_page;
pub use markdown::{markdown_image, markdown_table};
pub use overlay::{overlay_frame, Overlay, Prediction, Tail};
pub use png::write_png;
pub use trajectory::{trajectory_plot, Mismatch, ModelPaths, Track, TrajectoryPlot};
