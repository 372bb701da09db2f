//! End-to-end tests of the `physfit` binary: one test binary, one module per stage.

mod render;
mod util;
