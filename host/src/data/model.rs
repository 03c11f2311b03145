//! Model files on disk: the `hvs_shared::runtime::blob` format read with a precise account of what is
//! wrong with a damaged file, and written atomically.

use crate::data::output::write_bytes;
use anyhow::{anyhow, Context, Result};
use hvs_shared::runtime::blob::{
    self, BlobError, InputKind, ModelBlob, OutputKind, CRC_LEN, MAX_BLOB_LEN,
};
use std::path::Path;

/// A blob file as found on disk.
#[derive(Debug, Clone)]
pub struct ModelFile {
    /// The decoded model.
    pub blob: ModelBlob,
    /// Bytes in the file.
    pub file_len: usize,
    /// Bytes of the blob (header, payload, CRC); the rest of the file is ignored.
    pub blob_len: usize,
    /// The CRC-32 stored in (and matching) the blob.
    pub crc: u32,
    /// The file's blob format version (1 to `blob::VERSION`).
    pub version: u16,
}

/// Reads and fully checks a model file. The error says which check failed.
pub fn load(path: &Path) -> Result<ModelFile> {
    let bytes = std::fs::read(path).with_context(|| format!("{}: cannot read", path.display()))?;
    check(&bytes).map_err(|e| anyhow!("{}: {e}", path.display()))
}

/// Checks model bytes; the error says which check failed.
pub fn check(bytes: &[u8]) -> Result<ModelFile, String> {
    match blob::decode(bytes) {
        Ok(b) => {
            let blob_len = blob::framed_len(bytes).map_err(|e| e.to_string())?;
            let crc = stored_crc(bytes, blob_len).unwrap_or(0);
            Ok(ModelFile {
                blob: b,
                file_len: bytes.len(),
                blob_len,
                crc,
                version: u16::from_le_bytes([bytes[4], bytes[5]]),
            })
        }
        Err(e) => Err(explain(bytes, e)),
    }
}

fn stored_crc(bytes: &[u8], total: usize) -> Option<u32> {
    let c = bytes.get(total - CRC_LEN..total)?;
    Some(u32::from_le_bytes([c[0], c[1], c[2], c[3]]))
}

/// A one-line account of a decode failure, with the numbers that show it.
fn explain(bytes: &[u8], e: BlobError) -> String {
    let check = match e {
        BlobError::BadMagic => "magic check failed",
        BlobError::UnsupportedVersion(_) => "version check failed",
        BlobError::Truncated => "length check failed",
        BlobError::TooLarge => "length check failed",
        BlobError::BadCrc => "CRC check failed",
        BlobError::Malformed => "payload check failed",
        BlobError::TopologyMismatch => "topology check failed",
        BlobError::BadParameter => "parameter check failed",
        BlobError::BufferTooSmall => "size check failed",
    };
    let detail = match e {
        BlobError::BadMagic => {
            let hex = |b: &[u8]| b.iter().map(|x| format!("{x:02x}")).collect::<Vec<_>>().join(" ");
            format!(
                ": first bytes {} (hex), expected {} (\"HVSW\")",
                hex(&bytes[..bytes.len().min(4)]),
                hex(&blob::MAGIC)
            )
        }
        BlobError::Truncated => match blob::framed_len(bytes) {
            Ok(n) => format!(": the header announces {n} bytes, the file has {}", bytes.len()),
            Err(_) => format!(": only {} bytes", bytes.len()),
        },
        BlobError::BadCrc => match blob::framed_len(bytes) {
            Ok(n) => format!(
                ": stored {:#010x}, computed {:#010x} over {} bytes",
                stored_crc(bytes, n).unwrap_or(0),
                blob::crc32(&bytes[..n - CRC_LEN]),
                n - CRC_LEN
            ),
            Err(_) => String::new(),
        },
        _ => String::new(),
    };
    format!("not a valid model: {check}: {e}{detail}")
}

/// Encodes and writes a model atomically; returns the number of bytes written.
pub fn save(path: &Path, blob: &ModelBlob) -> Result<usize> {
    let mut buf = vec![0u8; MAX_BLOB_LEN];
    let n = blob
        .encode(&mut buf)
        .map_err(|e| anyhow!("{}: cannot encode the model: {e}", path.display()))?;
    write_bytes(path, &buf[..n])?;
    Ok(n)
}

/// `4-5-3`-style shape of a model.
pub fn shape(b: &ModelBlob) -> String {
    format!("{}-{}-{}", b.n_inputs(), b.topology.hidden, b.n_outputs())
}

/// Names of a model's input columns.
pub fn input_names(kind: InputKind) -> Vec<&'static str> {
    let mut v = crate::data::dataset::PIXEL_COLUMNS.to_vec();
    if kind == InputKind::StereoJoints {
        v.extend(crate::data::dataset::JOINT_COLUMNS);
    }
    v
}

/// Names of a model's outputs.
pub fn output_names(kind: OutputKind) -> &'static [&'static str] {
    match kind {
        OutputKind::Xyz => &["x", "y", "z"],
        OutputKind::Z => &["z"],
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::infer::tests::blob as sample;

    #[test]
    fn round_trip_and_each_damage_named() {
        let b = sample(5, OutputKind::Xyz, InputKind::Stereo);
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("m.hvsw");
        let n = save(&p, &b).unwrap();
        let f = load(&p).unwrap();
        assert_eq!(f.blob, b);
        assert_eq!((f.file_len, f.blob_len), (n, n));
        let good = std::fs::read(&p).unwrap();
        let mut bad = good.clone();
        bad[20] ^= 1;
        let e = check(&bad).unwrap_err();
        assert!(e.starts_with("not a valid model: CRC check failed"), "{e}");
        assert!(e.contains("stored 0x"), "{e}");
        let e = check(&good[..good.len() - 1]).unwrap_err();
        assert!(e.contains("length check failed"), "{e}");
        let e = check(b"hello world, not a model").unwrap_err();
        assert!(e.contains("magic check failed"), "{e}");
        let e = check(b"").unwrap_err();
        assert!(e.contains("length check failed"), "{e}");
        let mut v = good.clone();
        v[4] = 9;
        assert!(check(&v).unwrap_err().contains("version check failed"));
    }
}
