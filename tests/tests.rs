//! End-to-end tests of the `physfit` binary: one test binary, one module per stage.

mod diagnose;
mod fit;
mod render;
mod track;
mod util;
