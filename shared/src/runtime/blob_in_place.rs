//! [`crate::runtime::blob::decode`] into an existing [`ModelBlob`], for the head's boot: the same
//! checks in the same order (header, length, CRC, postcard payload with nothing left over,
//! [`ModelBlob::validate`]), the same [`BlobError`] for every input, but the payload is
//! deserialized field by field into `out` (serde's `deserialize_in_place`) instead of being
//! built on the stack and moved out through several frames. On the Cortex-M4F this takes
//! boot's stack from about 33 KB to a few KB (`firmware/measure.sh` reports the measured peak).
//!
//! A test checks that [`decode_into`] and [`crate::runtime::blob::decode`] agree on valid blobs and on
//! every way a blob can be broken; a change to the blob format that one of them misses fails it.

use crate::runtime::blob::{
    self, BlobError, ModelBlob, Topology, TrainingMeta, CRC_LEN, HEADER_LEN,
};
use crate::runtime::blob::{Algorithm, InputKind, OutputKind};
use crate::runtime::mlp::Activation;
use heapless::Vec;
use serde::Deserialize;

/// Decodes and validates the blob at the start of `bytes` into `out` (trailing bytes are
/// ignored). `Ok` leaves exactly what [`blob::decode`] returns in `out`; on `Err`, `out` holds
/// some partly decoded blob that must not be used.
pub fn decode_into(bytes: &[u8], out: &mut ModelBlob) -> Result<(), BlobError> {
    let total = blob::framed_len(bytes)?;
    if bytes.len() < total {
        return Err(BlobError::Truncated);
    }
    let body = total - CRC_LEN;
    let stored = u32::from_le_bytes([
        bytes[body],
        bytes[body + 1],
        bytes[body + 2],
        bytes[body + 3],
    ]);
    if blob::crc32(&bytes[..body]) != stored {
        return Err(BlobError::BadCrc);
    }
    let mut de = postcard::Deserializer::from_bytes(&bytes[HEADER_LEN..body]);
    ModelBlob::deserialize_in_place(&mut de, out).map_err(|_| BlobError::Malformed)?;
    let rest = de.finalize().map_err(|_| BlobError::Malformed)?;
    if !rest.is_empty() {
        return Err(BlobError::Malformed);
    }
    out.validate()
}

/// A blob with no parameters (it does not validate): a place to [`decode_into`].
pub fn placeholder() -> ModelBlob {
    ModelBlob {
        generation: 0,
        topology: Topology {
            inputs: InputKind::Stereo,
            hidden: 0,
            outputs: OutputKind::Xyz,
            output_activation: Activation::Linear,
        },
        in_offset: Vec::new(),
        in_scale: Vec::new(),
        out_offset: Vec::new(),
        out_scale: Vec::new(),
        params: Vec::new(),
        in_min: Vec::new(),
        in_max: Vec::new(),
        meta: TrainingMeta {
            seed: 0,
            train_hash: 0,
            train_points: 0,
            train_error_pct: 0.0,
            algorithm: Algorithm::Other,
            restarts: 0,
        },
        fallback: None,
    }
}

#[cfg(test)]
mod tests {
    extern crate std;

    use super::*;
    use crate::runtime::blob::{decode, MAX_BLOB_LEN};
    use crate::runtime::mlp::param_count;
    use crate::runtime::traditional::Calibration;
    use std::vec::Vec as StdVec;

    fn sample(hidden: u8, inputs: InputKind, seed: u64, fallback: bool) -> ModelBlob {
        let n_in = inputs.len();
        let mut b = placeholder();
        b.generation = seed as u32 + 1;
        b.topology = Topology {
            inputs,
            hidden,
            outputs: OutputKind::Xyz,
            output_activation: if seed % 2 == 0 {
                Activation::Linear
            } else {
                Activation::Sigmoid
            },
        };
        for k in 0..param_count(n_in, hidden as usize, 3) {
            let r = ((k as u64 * 2_654_435_761 + seed) % 2000) as f32 / 1000.0 - 1.0;
            b.params.push(r).unwrap();
        }
        for i in 0..n_in {
            b.in_offset.push(300.0 + i as f32).unwrap();
            b.in_scale.push(0.02 + i as f32 * 0.001).unwrap();
            b.in_min.push(-1.0 - i as f32).unwrap();
            b.in_max.push(600.0 + i as f32).unwrap();
        }
        for k in 0..3 {
            b.out_offset.push(k as f32 * 50.0).unwrap();
            b.out_scale.push(3.0 + k as f32).unwrap();
        }
        b.meta = TrainingMeta {
            seed,
            train_hash: seed.wrapping_mul(0x9e37_79b9_7f4a_7c15),
            train_points: 72,
            train_error_pct: 1.5,
            algorithm: Algorithm::Lm,
            restarts: 3,
        };
        b.fallback = fallback.then_some(Calibration::BUILT_IN);
        b
    }

    fn encode(b: &ModelBlob) -> StdVec<u8> {
        let mut buf = std::vec![0u8; MAX_BLOB_LEN];
        let n = b.encode(&mut buf).unwrap();
        buf.truncate(n);
        buf
    }

    /// Re-frames `payload` with a correct header and CRC (so the payload itself is judged).
    fn frame(payload: &[u8]) -> StdVec<u8> {
        let mut v = StdVec::from(&b"HVSW"[..]);
        v.extend_from_slice(&blob::VERSION.to_le_bytes());
        v.extend_from_slice(&(payload.len() as u32).to_le_bytes());
        v.extend_from_slice(payload);
        let crc = blob::crc32(&v);
        v.extend_from_slice(&crc.to_le_bytes());
        v
    }

    fn agree(bytes: &[u8]) {
        // A dirty place: what a previous slot left there.
        let mut place = sample(7, InputKind::StereoJoints, 99, true);
        let got = decode_into(bytes, &mut place);
        match decode(bytes) {
            Ok(want) => {
                assert_eq!(got, Ok(()));
                assert_eq!(place, want);
            }
            Err(e) => assert_eq!(got, Err(e)),
        }
    }

    #[test]
    fn agrees_with_decode_on_valid_and_broken_blobs() {
        let blobs = [
            sample(5, InputKind::Stereo, 1, true),
            sample(16, InputKind::StereoJoints, 2, false),
            sample(1, InputKind::Stereo, 3, false),
            sample(32, InputKind::StereoJoints, 4, true),
        ];
        let mut cases = 0;
        for b in &blobs {
            let bytes = encode(b);
            agree(&bytes);
            let mut padded = bytes.clone();
            padded.resize(MAX_BLOB_LEN, 0xff);
            agree(&padded);
            // Every truncation and a bit flip in every byte (header, payload, CRC).
            for n in 0..bytes.len() {
                agree(&bytes[..n]);
                let mut flipped = bytes.clone();
                flipped[n] ^= 1 << (n % 8);
                agree(&flipped);
                cases += 2;
            }
            // Payloads with a valid CRC that are not a valid blob: cut short, one byte too
            // many, a length prefix changed.
            let payload = &bytes[HEADER_LEN..bytes.len() - CRC_LEN];
            for n in [1, 7, payload.len() / 2, payload.len() - 1] {
                agree(&frame(&payload[..n]));
            }
            let mut long = StdVec::from(payload);
            long.push(0);
            agree(&frame(&long));
            for k in 0..payload.len() {
                let mut p = StdVec::from(payload);
                p[k] = p[k].wrapping_add(1);
                agree(&frame(&p));
                cases += 1;
            }
        }
        assert!(cases > 1000, "{cases}");
        // Decoding into a fresh placeholder works as well.
        let mut place = placeholder();
        assert_eq!(decode_into(&encode(&blobs[1]), &mut place), Ok(()));
        assert_eq!(place, blobs[1]);
        assert_eq!(place.validate(), Ok(()));
        assert_eq!(placeholder().validate(), Err(BlobError::TopologyMismatch));
    }
}
