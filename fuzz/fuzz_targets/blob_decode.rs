//! Any bytes into the weights-blob decoder: it must return, never panic, and whatever it
//! accepts must re-encode to the same bytes and run inference without panicking.
//!
//! Half the inputs are used raw (headers, lengths, CRC); the other half are wrapped as a
//! payload under a correct header and CRC, so the fuzzer reaches the postcard decoder and the
//! topology checks instead of stopping at the CRC.
#![no_main]

use hvs_shared::blob::{self, HEADER_LEN, MAGIC, MAX_BLOB_LEN, VERSION};
use libfuzzer_sys::fuzz_target;

fn check(bytes: &[u8]) {
    if let Ok(b) = blob::decode(bytes) {
        let mut buf = [0u8; MAX_BLOB_LEN];
        let n = b.encode(&mut buf).expect("a decoded blob re-encodes");
        assert_eq!(&buf[..n], &bytes[..n], "decode/encode is not the identity");
        let x = [320.0f32; 12];
        let mut out = [0.0f32; 3];
        let _ = b.infer(&x[..b.n_inputs()], &mut out[..b.n_outputs()]);
        let _ = b.in_range(&x[..b.n_inputs()]);
    }
}

fuzz_target!(|data: &[u8]| {
    match data.split_first() {
        Some((mode, payload)) if mode & 1 == 1 => {
            let mut v = Vec::with_capacity(payload.len() + 14);
            v.extend_from_slice(&MAGIC);
            v.extend_from_slice(&VERSION.to_le_bytes());
            v.extend_from_slice(&(payload.len() as u32).to_le_bytes());
            v.extend_from_slice(payload);
            let crc = blob::crc32(&v[..HEADER_LEN + payload.len()]);
            v.extend_from_slice(&crc.to_le_bytes());
            check(&v);
        }
        _ => check(data),
    }
});
