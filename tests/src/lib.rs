//! `hvs-tests`: cross-crate tests of hvs-depth. The tests live in `tests/tests/`; this library
//! only holds helpers they share: the location of the workspace root, the sample models (re-exported from `hvs_shared::test_support`),
//! [`sim::SimHead`] (the firmware loop on the host, `hvs_host::sim::head`, re-exported for the
//! robustness tests and the fuzz targets) and the fuzz targets' checks ([`fuzz`]), replayed by
//! the normal test suite.

pub mod fuzz;
pub use hvs_host::sim::head as sim;

use hvs_shared::runtime::blob::ModelBlob;
use std::path::PathBuf;

/// The workspace root (where `memory.x` and `Cargo.toml` live).
pub fn workspace_root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).parent().expect("tests/ has a parent").to_path_buf()
}

/// Parses `ORIGIN = 0x..., LENGTH = ...K` of a named region in a GNU ld `MEMORY` block.
pub fn memory_region(memory_x: &str, name: &str) -> Option<(u32, u32)> {
    let line = memory_x.lines().find(|l| {
        let t = l.trim_start();
        t.starts_with(name) && t[name.len()..].trim_start().starts_with(':')
    })?;
    let origin = line.split("ORIGIN").nth(1)?.split('=').nth(1)?.split(',').next()?.trim();
    let origin =
        u32::from_str_radix(origin.trim_start_matches("0x").trim_start_matches("0X"), 16).ok()?;
    let len = line.split("LENGTH").nth(1)?.split('=').nth(1)?.trim();
    let len = if let Some(k) = len.strip_suffix('K') {
        k.trim().parse::<u32>().ok()? * 1024
    } else if let Some(m) = len.strip_suffix('M') {
        m.trim().parse::<u32>().ok()? * 1024 * 1024
    } else {
        parse_int(len)?
    };
    Some((origin, len))
}

fn parse_int(s: &str) -> Option<u32> {
    match s.strip_prefix("0x") {
        Some(h) => u32::from_str_radix(h, 16).ok(),
        None => s.parse().ok(),
    }
}

pub use hvs_shared::test_support::{
    sample_default_model, sample_default_posture_model, sample_model, sample_posture_model,
    sample_posture_model_hidden,
};

/// The bytes of `blob` as written into a weight slot (no trailing erased bytes).
pub fn blob_bytes(blob: &ModelBlob) -> Vec<u8> {
    let mut buf = vec![0u8; hvs_shared::runtime::blob::MAX_BLOB_LEN];
    let n = blob.encode(&mut buf).expect("a valid blob encodes");
    buf.truncate(n);
    buf
}
