//! Golden blobs of earlier format versions: files written by `hvs train` of format version 1
//! (a 4-5-3 net on the case I boards, `--seed 7`, and a posture-aware 9-8-3 net) and of version
//! 2 (the same two in the inverse-depth-skip family) still decode, with their family and the
//! head output frame, and predict the exact f32 bits `hvs predict` printed for them then
//! (`*_predict.csv`, written by that version's code on volume points). `golden/README.md` has
//! the commands.

use hvs_shared::runtime::blob::{self, Family, OutputFrame, OutputKind};
use std::path::PathBuf;

fn golden(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("tests/golden")
        .join(name)
}

fn check(
    model: &str,
    predictions: &str,
    version: u16,
    n_inputs: usize,
    hidden: u8,
    family: Family,
) {
    let bytes = std::fs::read(golden(model)).unwrap();
    assert_eq!(&bytes[0..4], b"HVSW");
    assert_eq!(
        u16::from_le_bytes([bytes[4], bytes[5]]),
        version,
        "a v{version} file"
    );
    let b = blob::decode(&bytes).unwrap();
    assert_eq!(b.family, family);
    assert_eq!(b.frame, OutputFrame::Head);
    assert_eq!(b.n_inputs(), n_inputs);
    assert_eq!(b.topology.hidden, hidden);
    assert_eq!(b.topology.outputs, OutputKind::Xyz);
    let text = std::fs::read_to_string(golden(predictions)).unwrap();
    let mut rows = 0;
    for line in text.lines().skip(1).filter(|l| !l.trim().is_empty()) {
        let v: Vec<f32> = line.split(',').map(|s| s.parse().unwrap()).collect();
        assert_eq!(v.len(), n_inputs + 3, "{line}");
        let mut out = [0.0f32; 3];
        b.infer(&v[..n_inputs], &mut out).unwrap();
        assert_eq!(
            out.map(f32::to_bits).to_vec(),
            v[n_inputs..]
                .iter()
                .map(|x| x.to_bits())
                .collect::<Vec<_>>(),
            "{model}: {line}"
        );
        rows += 1;
    }
    assert_eq!(rows, 20);
}

#[test]
fn v1_stereo_4_5_3_decodes_and_predicts_the_recorded_bits() {
    check(
        "v1_4_5_3.hvsw",
        "v1_4_5_3_predict.csv",
        1,
        4,
        5,
        Family::THESIS,
    );
}

#[test]
fn v1_posture_9_8_3_decodes_and_predicts_the_recorded_bits() {
    check(
        "v1_9_8_3.hvsw",
        "v1_9_8_3_predict.csv",
        1,
        9,
        8,
        Family::THESIS,
    );
}

#[test]
fn v2_stereo_4_5_3_decodes_and_predicts_the_recorded_bits() {
    check(
        "v2_4_5_3.hvsw",
        "v2_4_5_3_predict.csv",
        2,
        4,
        5,
        Family::INVERSE_DEPTH_SKIP,
    );
}

#[test]
fn v2_posture_9_8_3_decodes_and_predicts_the_recorded_bits() {
    check(
        "v2_9_8_3.hvsw",
        "v2_9_8_3_predict.csv",
        2,
        9,
        8,
        Family::INVERSE_DEPTH_SKIP,
    );
}
