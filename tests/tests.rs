//! End-to-end tests of the `physfit` binary: one test binary, one module per stage.

mod bench_diagnose;
mod byte_identical;
mod diagnose;
mod fit;
mod fuzz_regressions;
mod getting_started;
mod issue_21;
mod issue_22;
mod real;
mod reliability;
mod render;
mod run;
mod tables;
mod track;
mod util;
mod video;
