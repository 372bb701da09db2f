//! The `png_reader` fuzz target: the property of `fuzz/checks/png_reader.rs`, which the stable test
//! `tests/fuzz_regressions.rs` runs on every saved input.
#![no_main]

#[path = "../checks/png_reader.rs"]
mod check;

libfuzzer_sys::fuzz_target!(|data: &[u8]| check::check(data));
