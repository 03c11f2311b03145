//! `hvs image` and `hvs flash` driven from outside: image addresses, dry run, missing probe.

use crate::common::{hvs, ok, s};
use hvs_shared::runtime::blob::{self, ModelBlob, OutputKind, MAX_BLOB_LEN};
use hvs_shared::runtime::layout::{SLOT_A_ADDR, SLOT_B_ADDR};
use hvs_shared::test_support::SampleSpec;
use std::path::{Path, PathBuf};

fn model(generation: u32) -> ModelBlob {
    SampleSpec::THESIS.generation(generation).build()
}

/// Writes `b` encoded to `dir/name`; returns the path.
fn write_blob(dir: &Path, name: &str, b: &ModelBlob) -> PathBuf {
    let mut buf = [0u8; MAX_BLOB_LEN];
    let n = b.encode(&mut buf).unwrap();
    let p = dir.join(name);
    std::fs::write(&p, &buf[..n]).unwrap();
    p
}

fn write_model(dir: &Path, generation: u32) -> PathBuf {
    write_blob(dir, "m.hvsw", &model(generation))
}

/// Runs `hvs args`, asserts that it fails; returns stderr.
fn refused(args: &[&str]) -> String {
    let o = hvs().args(args).output().unwrap();
    assert!(!o.status.success(), "{args:?} succeeded");
    String::from_utf8_lossy(&o.stderr).into_owned()
}

#[test]
fn bin_image_is_the_blob_with_the_requested_generation() {
    let dir = tempfile::tempdir().unwrap();
    let m = write_model(dir.path(), 1);
    let out = dir.path().join("a.bin");
    let stdout = ok(&[
        "image",
        "--model",
        s(&m),
        "--slot",
        "b",
        "--generation",
        "9",
        "--format",
        "bin",
        "-o",
        s(&out),
    ]);
    assert!(stdout.contains(&format!("{SLOT_B_ADDR:#010x}")), "{stdout}");
    let b = blob::decode(&std::fs::read(&out).unwrap()).unwrap();
    assert_eq!(b.generation, 9);
    assert_eq!(b.params, model(1).params);
}

#[test]
fn hex_image_sits_at_the_slot_address() {
    let dir = tempfile::tempdir().unwrap();
    let m = write_model(dir.path(), 3);
    for (slot, addr) in [("a", SLOT_A_ADDR), ("b", SLOT_B_ADDR)] {
        let out = dir.path().join(format!("{slot}.hex"));
        ok(&["image", "--model", s(&m), "--slot", slot, "--format", "hex", "-o", s(&out)]);
        let text = std::fs::read_to_string(&out).unwrap();
        let mut base = 0u32;
        let mut first = None;
        let mut bytes = Vec::new();
        for r in ihex::Reader::new(&text) {
            match r.unwrap() {
                ihex::Record::ExtendedLinearAddress(h) => base = (h as u32) << 16,
                ihex::Record::Data { offset, value } => {
                    first.get_or_insert(base + offset as u32);
                    bytes.extend(value);
                }
                _ => {}
            }
        }
        assert_eq!(first, Some(addr));
        assert_eq!(blob::decode(&bytes).unwrap().generation, 3);
    }
}

/// The exact length of `model(generation)` encoded.
fn encoded_len(generation: u32) -> usize {
    let mut buf = [0u8; MAX_BLOB_LEN];
    model(generation).encode(&mut buf).unwrap()
}

fn dry_run(m: &Path, slot: &str) -> String {
    ok(&["flash", "--model", s(m), "--dry-run", "--slot", slot])
}

#[test]
fn dry_run_prints_the_plan_without_a_probe() {
    let dir = tempfile::tempdir().unwrap();
    // Generation 200 in the file (a 2-byte varint): the blob written is re-encoded with the
    // generation the plan chooses, one byte shorter below 128.
    let m = write_model(dir.path(), 200);
    let file_len = std::fs::metadata(&m).unwrap().len() as usize;
    let (n1, n2) = (encoded_len(1), encoded_len(128));
    assert_eq!((file_len, n2), (n1 + 1, n1 + 1));

    let s = dry_run(&m, "b");
    assert!(s.contains("no probe touched"), "{s}");
    assert!(s.contains("chip: STM32F405RGTx"), "{s}");
    assert!(s.contains(&format!("({file_len} bytes, CRC ok, 4-5-3")), "{s}");
    assert!(s.contains("slot: B at 0x080e0000 (sector 11)\n"), "{s}");
    assert!(
        s.contains(&format!(
            "write generation G+1 if the head runs a model (generation G), {n1} bytes if G+1 <= 127; generation 1, {n1} bytes if it runs none"
        )),
        "{s}"
    );
    assert!(s.contains("refused if slot B holds the only model the head runs"), "{s}");
    assert!(!s.contains("slot A at"), "{s}");

    let s = dry_run(&m, "auto");
    for want in [
        format!("if A runs (generation G): write slot B at 0x080e0000 (sector 11), generation G+1, {n1} bytes if G+1 <= 127"),
        format!("if B runs (generation G): write slot A at 0x080c0000 (sector 10), generation G+1, {n1} bytes if G+1 <= 127"),
        format!("if neither runs a model: write slot A at 0x080c0000 (sector 10), generation 1, {n1} bytes"),
        "generation rule: 1 + the highest generation among the slots the head can run (G), read through the probe; 1 if it runs none.".to_string(),
        format!("size by generation written: {n1} bytes for 1..=127, {n2} bytes for 128..=16383, "),
    ] {
        assert!(s.contains(&want), "missing {want:?} in\n{s}");
    }
}

#[test]
fn a_model_the_head_would_not_run_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let z = SampleSpec::THESIS.outputs(OutputKind::Z).build();
    let p = write_blob(dir.path(), "z.hvsw", &z);
    let out = dir.path().join("z.bin");
    for args in [
        vec!["flash", "--model", p.to_str().unwrap(), "--dry-run"],
        vec!["flash", "--model", p.to_str().unwrap()],
        vec![
            "image",
            "--model",
            p.to_str().unwrap(),
            "--slot",
            "a",
            "--format",
            "bin",
            "-o",
            out.to_str().unwrap(),
        ],
    ] {
        let o = hvs().args(&args).output().unwrap();
        assert_eq!(o.status.code(), Some(1), "{args:?}");
        let e = String::from_utf8_lossy(&o.stderr);
        assert!(e.contains("z.hvsw: the head would not run this 4-5-1 model"), "{e}");
        assert_eq!(e.trim().lines().count(), 1, "{e}");
        assert!(o.stdout.is_empty(), "{args:?}");
    }
    assert!(!out.exists());
}

#[test]
fn flash_errors_are_one_clear_line() {
    let dir = tempfile::tempdir().unwrap();
    let m = write_model(dir.path(), 1);
    // No probe is attached on a build machine.
    let e = refused(&["flash", "--model", s(&m)]);
    assert!(e.contains("no debug probe"), "{e}");
    assert!(!e.contains("panicked"), "{e}");
    assert_eq!(e.trim().lines().count(), 1, "{e}");
    // Unknown chip, bad probe selector, damaged model.
    let e = refused(&["flash", "--model", s(&m), "--chip", "NOPE123", "--dry-run"]);
    assert!(e.contains("--chip NOPE123"), "{e}");
    refused(&["flash", "--model", s(&m), "--probe", "zz"]);
    let mut bytes = std::fs::read(&m).unwrap();
    bytes[20] ^= 0xFF;
    let bad = dir.path().join("bad.hvsw");
    std::fs::write(&bad, &bytes).unwrap();
    let e = refused(&["flash", "--model", s(&bad), "--dry-run"]);
    assert!(e.contains("bad.hvsw") && e.contains("CRC"), "{e}");
}
