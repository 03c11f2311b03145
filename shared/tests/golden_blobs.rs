//! Golden blobs of earlier format versions: files written by `hvs train` of format version 1
//! (a 4-5-3 net on the case I boards, `--seed 7`, and a posture-aware 9-8-3 net) and of version
//! 2 (the same two in the inverse-depth-skip family) and of version 3 (the same two again, the
//! posture-aware one in the eye platform's frame) still decode, with their family and output
//! frame, and predict the exact f32 bits `hvs predict` printed for them then
//! (`*_predict.csv`, written by that version's code on volume points). `golden/README.md` has
//! the commands. Version 4's files (the same two, no images, no parent) and a sample blob with
//! both version-4 fields set pin the current encoding.

use hvs_shared::runtime::blob::{self, Family, ModelBlob, OutputFrame, OutputKind, Parent};
use std::path::PathBuf;

fn golden(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/golden").join(name)
}

/// Checks `v{version}_{n_inputs}_{hidden}_3.hvsw` (its header, shape, family and frame) and
/// that it predicts the bits recorded in `v{version}_{n_inputs}_{hidden}_3_predict.csv`.
fn check(
    version: u16,
    n_inputs: usize,
    hidden: u8,
    family: Family,
    frame: OutputFrame,
) -> ModelBlob {
    let model = format!("v{version}_{n_inputs}_{hidden}_3.hvsw");
    let predictions = format!("v{version}_{n_inputs}_{hidden}_3_predict.csv");
    let bytes = std::fs::read(golden(&model)).unwrap();
    assert_eq!(&bytes[0..4], b"HVSW");
    assert_eq!(u16::from_le_bytes([bytes[4], bytes[5]]), version, "a v{version} file");
    let b = blob::decode(&bytes).unwrap();
    assert_eq!(b.family, family);
    assert_eq!(b.frame, frame);
    assert_eq!(b.n_inputs(), n_inputs);
    assert_eq!(b.topology.hidden, hidden);
    assert_eq!(b.topology.outputs, OutputKind::Xyz);
    let text = std::fs::read_to_string(golden(&predictions)).unwrap();
    let mut rows = 0;
    for line in text.lines().skip(1).filter(|l| !l.trim().is_empty()) {
        let v: Vec<f32> = line.split(',').map(|s| s.parse().unwrap()).collect();
        assert_eq!(v.len(), n_inputs + 3, "{line}");
        let mut out = [0.0f32; 3];
        b.infer(&v[..n_inputs], &mut out).unwrap();
        assert_eq!(
            out.map(f32::to_bits).to_vec(),
            v[n_inputs..].iter().map(|x| x.to_bits()).collect::<Vec<_>>(),
            "{model}: {line}"
        );
        rows += 1;
    }
    assert_eq!(rows, 20);
    b
}

/// Every committed format version, a stereo 4-5-3 net and a posture-aware 9-8-3 one each:
/// `(version, inputs, hidden, family, frame)`.
const GOLDEN: [(u16, usize, u8, Family, OutputFrame); 8] = [
    (1, 4, 5, Family::THESIS, OutputFrame::Head),
    (1, 9, 8, Family::THESIS, OutputFrame::Head),
    (2, 4, 5, Family::INVERSE_DEPTH_SKIP, OutputFrame::Head),
    (2, 9, 8, Family::INVERSE_DEPTH_SKIP, OutputFrame::Head),
    (3, 4, 5, Family::INVERSE_DEPTH_SKIP, OutputFrame::Head),
    (3, 9, 8, Family::INVERSE_DEPTH_SKIP, OutputFrame::EyePlatform),
    (4, 4, 5, Family::INVERSE_DEPTH_SKIP, OutputFrame::Head),
    (4, 9, 8, Family::INVERSE_DEPTH_SKIP, OutputFrame::EyePlatform),
];

#[test]
fn every_version_decodes_and_predicts_the_recorded_bits() {
    for (version, inputs, hidden, family, frame) in GOLDEN {
        let b = check(version, inputs, hidden, family, frame);
        // Only v4 can hold them; these files have neither.
        assert_eq!((b.image_size(), b.parent()), (None, None));
    }
}

/// The model of `v4_image_size_parent.hvsw`: `v4_4_5_3.hvsw` at generation 7 with 640x480
/// training images, updated from generation 6 of a blob with CRC 0x89ab_cdef.
fn with_image_size_and_parent() -> ModelBlob {
    let mut b = blob::decode(&std::fs::read(golden("v4_4_5_3.hvsw")).unwrap()).unwrap();
    b.generation = 7;
    b.set_image_size(Some((640, 480)));
    b.set_parent(Some(Parent { crc: 0x89ab_cdef, generation: 6 }));
    b
}

#[test]
fn v4_image_size_and_parent_have_the_recorded_bytes() {
    let golden = std::fs::read(golden("v4_image_size_parent.hvsw")).unwrap();
    let b = blob::decode(&golden).unwrap();
    assert_eq!(b, with_image_size_and_parent());
    assert_eq!(b.image_size(), Some((640, 480)));
    assert_eq!(b.parent(), Some((0x89ab_cdef, 6)));
    let mut buf = [0u8; blob::MAX_BLOB_LEN];
    let n = b.encode(&mut buf).unwrap();
    assert_eq!(&buf[..n], &golden[..], "the encoding changed");
    // The two fields are the payload's last bytes: Some, 640, 480, Some, CRC, 6 (varints).
    let payload_end = n - blob::CRC_LEN;
    assert_eq!(
        &golden[payload_end - 12..payload_end],
        &[0x01, 0x80, 0x05, 0xE0, 0x03, 0x01, 0xEF, 0x9B, 0xAF, 0xCD, 0x08, 0x06]
    );
}
