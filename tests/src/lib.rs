//! `hvs-tests`: cross-crate tests of hvs-depth. The tests live in `tests/tests/`; this library
//! only holds helpers they share: the location of the workspace root, a seeded sample model,
//! [`sim::SimHead`] (the firmware loop on the host for the robustness tests and the fuzz
//! targets) and the fuzz targets' checks ([`fuzz`]), replayed by the normal test suite.

pub mod fuzz;
pub mod sim;

use hvs_shared::blob::{Algorithm, InputKind, ModelBlob, OutputKind, Topology, TrainingMeta};
use hvs_shared::mlp::{param_count, Activation};
use hvs_shared::triangulate::Calibration;
use std::path::PathBuf;

/// The workspace root (where `memory.x` and `Cargo.toml` live).
pub fn workspace_root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("tests/ has a parent")
        .to_path_buf()
}

/// Parses `ORIGIN = 0x..., LENGTH = ...K` of a named region in a GNU ld `MEMORY` block.
pub fn memory_region(memory_x: &str, name: &str) -> Option<(u32, u32)> {
    let line = memory_x.lines().find(|l| {
        let t = l.trim_start();
        t.starts_with(name) && t[name.len()..].trim_start().starts_with(':')
    })?;
    let origin = line
        .split("ORIGIN")
        .nth(1)?
        .split('=')
        .nth(1)?
        .split(',')
        .next()?
        .trim();
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

/// A valid 4-5-3 blob with seeded weights (same seed, same bytes) and the scaling and input box
/// of case I's training set: not a trained model, but all that bit-for-bit comparisons and the
/// firmware's instruction count need.
pub fn sample_model(generation: u32, seed: u64) -> ModelBlob {
    let params = seeded_params(
        seed.wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407),
        param_count(4, 5, 3),
    );
    let v = |a: &[f32]| heapless::Vec::from_slice(a).unwrap();
    ModelBlob {
        generation,
        topology: Topology {
            inputs: InputKind::Stereo,
            hidden: 5,
            outputs: OutputKind::Xyz,
            output_activation: Activation::Linear,
        },
        in_offset: v(&[343.0, 240.0, 297.0, 240.0]),
        in_scale: v(&[1.0 / 30.0, 1.0 / 12.0, 1.0 / 30.0, 1.0 / 12.0]),
        out_offset: heapless::Vec::from_slice(&[0.0, 0.0, 115.0]).unwrap(),
        out_scale: heapless::Vec::from_slice(&[3.0, 2.0, 50.0]).unwrap(),
        params,
        in_min: v(&[325.0, 228.0, 279.0, 228.0]),
        in_max: v(&[361.0, 252.0, 315.0, 252.0]),
        meta: TrainingMeta {
            seed,
            train_hash: 0x1234_5678_9abc_def0,
            train_points: 72,
            train_error_pct: 0.5,
            algorithm: Algorithm::Lm,
            restarts: 1,
        },
        fallback: Some(Calibration::BUILT_IN),
        family: hvs_shared::blob::Family::THESIS,
        matcher: None,
    }
}

/// A valid posture-aware 9-8-3 blob (the four pixels and the five joint angles in degrees) with
/// seeded weights, built like [`sample_model`]: the larger blob for the fault-injection tests.
pub fn sample_posture_model(generation: u32, seed: u64) -> ModelBlob {
    let base = sample_model(generation, seed);
    let params = seeded_params(seed ^ 0x9e37_79b9_7f4a_7c15, param_count(9, 8, 3));
    let extend = |px: &[f32], joints: [f32; 5]| {
        let mut v: heapless::Vec<f32, { hvs_shared::blob::MAX_INPUTS }> =
            heapless::Vec::from_slice(px).unwrap();
        v.extend_from_slice(&joints).unwrap();
        v
    };
    ModelBlob {
        topology: Topology {
            inputs: InputKind::StereoJoints,
            hidden: 8,
            ..base.topology
        },
        in_offset: extend(&base.in_offset, [0.0; 5]),
        in_scale: extend(
            &base.in_scale,
            [1.0 / 30.0, 1.0 / 20.0, 1.0 / 15.0, 1.0 / 20.0, 1.0 / 20.0],
        ),
        params,
        in_min: extend(&base.in_min, [-30.0, -20.0, -15.0, -20.0, -20.0]),
        in_max: extend(&base.in_max, [30.0, 20.0, 15.0, 20.0, 20.0]),
        ..base
    }
}

/// `n` parameters in [-2, 2) from a linear congruential generator started at `state`.
fn seeded_params(mut state: u64, n: usize) -> heapless::Vec<f32, { hvs_shared::blob::MAX_PARAMS }> {
    let mut params = heapless::Vec::new();
    for _ in 0..n {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        let r = ((state >> 40) as f32 / (1u64 << 24) as f32) * 2.0 - 1.0;
        params.push(r * 2.0).unwrap();
    }
    params
}

/// The bytes of `blob` as written into a weight slot (no trailing erased bytes).
pub fn blob_bytes(blob: &ModelBlob) -> Vec<u8> {
    let mut buf = vec![0u8; hvs_shared::blob::MAX_BLOB_LEN];
    let n = blob.encode(&mut buf).expect("a valid blob encodes");
    buf.truncate(n);
    buf
}
