//! Fuzz target `rig_json`: the check is `hvs_tests::fuzz::rig_json` (documented there), shared with the
//! replay of kept inputs in `tests/tests/fuzz_regressions.rs`.
//! Run: `cd fuzz && cargo +nightly fuzz run rig_json -- -max_total_time=60` (see docs/ROBUSTNESS.md).
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| hvs_tests::fuzz::rig_json(data));
