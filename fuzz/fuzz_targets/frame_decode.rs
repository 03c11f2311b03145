//! Any bytes into the protocol's receive path: the COBS/postcard decoders and the
//! `FrameAccumulator`.
//!
//! - `decode_request` / `decode_response` on the raw bytes return, never panic; whatever
//!   decodes re-encodes into one `MAX_FRAME_LEN` frame that decodes to the same bytes again.
//! - The bytes as a stream through accumulators of two sizes (`MAX_FRAME_LEN`, as the firmware,
//!   and 8 bytes, so overlong frames are common) give exactly the frames of a reference
//!   splitter: split at every `0x00`, skip empty pieces, an overlong piece is one `Oversize`;
//!   `pending()` is the unfinished piece (0 once it overflowed).
#![no_main]

use hvs_shared::protocol::{
    self, FrameAccumulator, ProtocolError, Request, Response, MAX_FRAME_LEN,
};
use libfuzzer_sys::fuzz_target;

fn round_trip<T, F>(bytes: &[u8], encode: F)
where
    F: Fn(&T, &mut [u8]) -> Result<usize, ProtocolError>,
    T: for<'a> serde::Deserialize<'a>,
{
    let mut copy = bytes.to_vec();
    let Ok(msg) = protocol::decode::<T>(&mut copy) else {
        return;
    };
    let mut a = [0u8; MAX_FRAME_LEN];
    let n = encode(&msg, &mut a).expect("a decoded message fits one frame");
    let mut b = a;
    let again: T = protocol::decode(&mut b[..n]).expect("a re-encoded message decodes");
    let mut c = [0u8; MAX_FRAME_LEN];
    let m = encode(&again, &mut c).expect("fits");
    assert_eq!(&a[..n], &c[..m], "encode(decode(encode(x))) differs");
}

fn reference<const N: usize>(bytes: &[u8]) -> (Vec<Result<Vec<u8>, ProtocolError>>, usize) {
    let mut out = Vec::new();
    let mut pieces = bytes.split(|&b| b == 0).peekable();
    let mut pending = 0;
    while let Some(p) = pieces.next() {
        if pieces.peek().is_none() {
            // No 0x00 after the last piece: still being received.
            pending = if p.len() > N { 0 } else { p.len() };
        } else if p.len() > N {
            out.push(Err(ProtocolError::Oversize));
        } else if !p.is_empty() {
            out.push(Ok(p.to_vec()));
        }
    }
    (out, pending)
}

fn accumulate<const N: usize>(bytes: &[u8]) {
    let mut acc = FrameAccumulator::<N>::new();
    let mut got = Vec::new();
    for &b in bytes {
        if let Some(r) = acc.push(b) {
            let r = r.map(|f| f.to_vec());
            if let Ok(f) = &r {
                assert!(!f.is_empty() && f.len() <= N && !f.contains(&0));
            }
            got.push(r);
        }
    }
    let (want, pending) = reference::<N>(bytes);
    assert_eq!(got, want);
    assert_eq!(acc.pending(), pending);
}

fuzz_target!(|data: &[u8]| {
    round_trip::<Request, _>(data, |m, buf| {
        protocol::encode_request(m, buf).map(|f| f.len())
    });
    round_trip::<Response, _>(data, |m, buf| {
        protocol::encode_response(m, buf).map(|f| f.len())
    });
    accumulate::<MAX_FRAME_LEN>(data);
    accumulate::<8>(data);
});
