//! The `track_table` fuzz target: the property of `fuzz/checks/track_table.rs`, which the stable test
//! `tests/fuzz_regressions.rs` runs on every saved input.
#![no_main]

#[path = "../checks/track_table.rs"]
mod check;

libfuzzer_sys::fuzz_target!(|data: &[u8]| check::check(data));
