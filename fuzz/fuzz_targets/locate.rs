//! Fuzz target `locate`: the check is `hvs_tests::fuzz::locate` (documented there), shared with the
//! replay of kept inputs in `tests/tests/fuzz_regressions.rs`.
//! Run: `cd fuzz && cargo +nightly fuzz run locate -- -max_total_time=60` (see docs/ROBUSTNESS.md).
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| hvs_tests::fuzz::locate(data));
