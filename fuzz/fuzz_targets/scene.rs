//! The `scene` fuzz target: the property of `fuzz/checks/scene.rs`, which the stable test
//! `tests/fuzz_regressions.rs` runs on every saved input.
#![no_main]

#[path = "../checks/scene.rs"]
mod check;

libfuzzer_sys::fuzz_target!(|data: &[u8]| check::check(data));
