//! Fuzz target `frame_decode`: the check is `hvs_tests::fuzz::frame_decode` (documented there), shared with the
//! replay of kept inputs in `tests/tests/fuzz_regressions.rs`.
//! Run: `cd fuzz && cargo +nightly fuzz run frame_decode -- -max_total_time=60` (see docs/ROBUSTNESS.md).
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| hvs_tests::fuzz::frame_decode(data));
