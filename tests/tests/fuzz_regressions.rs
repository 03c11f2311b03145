//! The fuzz targets' checks (`hvs_tests::fuzz`) in the normal test suite: every seed input
//! and every input kept in `tests/fuzz-regressions/<target>/` (crashes the fuzzer found,
//! fixed since) goes through the same function the target runs.

use hvs_host::data::csv::{self as csv_io, Inputs};
use hvs_shared::runtime::blob::{self, CRC_LEN, HEADER_LEN};
use hvs_tests::{fuzz, workspace_root};
use std::path::Path;

fn kept(target: &str) -> Vec<(String, Vec<u8>)> {
    let dir = workspace_root().join("tests").join("fuzz-regressions").join(target);
    let mut out = Vec::new();
    if let Ok(entries) = std::fs::read_dir(&dir) {
        for e in entries {
            let path = e.unwrap().path();
            out.push((path.display().to_string(), std::fs::read(&path).unwrap()));
        }
    }
    out.sort();
    out
}

/// The seeds (name, bytes) of fuzz target `target`.
fn seeds_of(target: &str) -> impl Iterator<Item = (&'static str, Vec<u8>)> + '_ {
    fuzz::seeds()
        .into_iter()
        .filter(move |(t, _, _)| *t == target)
        .map(|(_, name, bytes)| (name, bytes))
}

fn replay(target: &str, check: Check) -> usize {
    let mut n = 0;
    for (name, bytes) in seeds_of(target) {
        eprintln!("{target}: seed {name}");
        check(&bytes);
        n += 1;
    }
    for (name, bytes) in kept(target) {
        eprintln!("{target}: {name}");
        check(&bytes);
        n += 1;
    }
    n
}

/// What a fuzz target runs on one input.
type Check = fn(&[u8]);

/// Every fuzz target, the function it runs, and the least number of inputs (seeds and kept
/// regressions) its replay must find.
const TARGETS: [(&str, Check, usize); 7] = [
    // Two seeds and the overlong-varint crash.
    ("blob_decode", fuzz::blob_decode, 3),
    ("frame_decode", fuzz::frame_decode, 7),
    ("rig_json", fuzz::rig_json, 3),
    ("head_stream", fuzz::head_stream, 4),
    ("csv_read", fuzz::csv_read, 3),
    ("capture_set", fuzz::capture_set, 2),
    ("locate", fuzz::locate, 1),
];

#[test]
fn every_target_replays_its_inputs() {
    for (target, check, least) in TARGETS {
        let n = replay(target, check);
        assert!(n >= least, "{target}: {n} inputs, expected at least {least}");
    }
}

#[test]
fn rig_json_seeds_are_refused_only_for_the_duplicate_key() {
    // The duplicate-key seed is refused, the others are accepted.
    for (name, bytes) in seeds_of("rig_json") {
        let text = std::str::from_utf8(&bytes[1..]).unwrap();
        let case = (bytes[0] & 1 == 1).then_some((bytes[0] >> 1) % 8);
        let r = hvs_host::data::rig::parse(text, case);
        assert_eq!(r.is_err(), name == "duplicate_key", "{name}: {r:?}");
    }
}

#[test]
fn csv_read_seeds_are_accepted() {
    // The seeds are files the reader accepts (so the checks on tables run).
    for (name, bytes) in seeds_of("csv_read") {
        let r = csv_io::read_set_from(Path::new(name), bytes.as_slice(), Inputs::Auto, true);
        let table = r.unwrap_or_else(|e| panic!("seed {name}: {e:#}"));
        assert!(!table.data.is_empty());
    }
}

/// Found by `blob_decode`: postcard accepts an overlong (non-canonical) varint, so one
/// model has more than one valid blob encoding. Harmless (same values; the CRC covers the
/// bytes as stored), but encode(decode(b)) == b does not hold: re-encoding is canonical and
/// shorter, and decodes to the same model.
#[test]
fn overlong_varint_decodes_to_the_same_model() {
    let canonical = hvs_tests::blob_bytes(&hvs_tests::sample_model(7, 42));
    // The payload opens with the generation (varint 7 = 0x07); write it as 0x87 0x00.
    assert_eq!(canonical[HEADER_LEN], 7);
    let payload = &canonical[HEADER_LEN..canonical.len() - CRC_LEN];
    let mut long = Vec::new();
    long.extend_from_slice(&canonical[..6]);
    long.extend_from_slice(&(payload.len() as u32 + 1).to_le_bytes());
    long.extend_from_slice(&[0x87, 0x00]);
    long.extend_from_slice(&payload[1..]);
    let crc = blob::crc32(&long);
    long.extend_from_slice(&crc.to_le_bytes());

    let a = blob::decode(&canonical).unwrap();
    let b = blob::decode(&long).unwrap();
    assert_eq!(a, b);
    assert_eq!(b.generation, 7);
    assert_eq!(hvs_tests::blob_bytes(&b), canonical);
    fuzz::blob_decode(&long);
}

/// The capture-set seeds go all the way through: their boards are found (a seed that stops
/// at detection would start the fuzzer from the refusals only).
#[test]
fn the_capture_set_seeds_find_their_boards() {
    for (name, bytes) in seeds_of("capture_set") {
        assert!(fuzz::capture_set_found(&bytes) >= 1, "{name}");
    }
}
