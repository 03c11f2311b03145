//! The checks of the fuzz targets in `fuzz/`, as plain functions: the targets only call
//! these, and `tests/tests/fuzz_regressions.rs` replays every input kept in
//! `tests/fuzz-regressions/<target>/` (crashes found by the fuzzer, minimised) and the seed
//! corpus through the same functions in a normal `cargo test`. Each panics on a failure.

use crate::sim::SimHead;
use hvs_shared::blob::{self, HEADER_LEN, MAGIC, MAX_BLOB_LEN, VERSION};
use hvs_shared::protocol::{
    self, FrameAccumulator, ProtocolError, Request, RequestBody, Response, StereoPoint,
    MAX_FRAME_LEN,
};
use std::sync::OnceLock;

/// `blob_decode`: any bytes into the weights-blob decoder. It must return, never panic;
/// whatever it accepts re-encodes into a blob (at most as long: postcard also accepts
/// overlong varints, which re-encode shorter) that decodes to the same model and re-encodes
/// to the same bytes, and runs inference without panicking.
///
/// Odd first byte: the rest is wrapped as a payload under a correct header and CRC, so the
/// input reaches the postcard decoder and the topology checks instead of stopping at the CRC.
pub fn blob_decode(data: &[u8]) {
    match data.split_first() {
        Some((mode, payload)) if mode & 1 == 1 => {
            let mut v = Vec::with_capacity(payload.len() + 14);
            v.extend_from_slice(&MAGIC);
            v.extend_from_slice(&VERSION.to_le_bytes());
            v.extend_from_slice(&(payload.len() as u32).to_le_bytes());
            v.extend_from_slice(payload);
            let crc = blob::crc32(&v[..HEADER_LEN + payload.len()]);
            v.extend_from_slice(&crc.to_le_bytes());
            check_blob(&v);
        }
        _ => check_blob(data),
    }
}

fn check_blob(bytes: &[u8]) {
    let Ok(b) = blob::decode(bytes) else {
        return;
    };
    let framed = blob::framed_len(bytes).expect("a decoded blob has a length");
    let mut buf = [0u8; MAX_BLOB_LEN];
    let n = b.encode(&mut buf).expect("a decoded blob re-encodes");
    assert!(
        n <= framed,
        "re-encoding grew the blob from {framed} to {n} bytes"
    );
    let again = blob::decode(&buf[..n]).expect("a re-encoded blob decodes");
    assert_eq!(
        format!("{again:?}"),
        format!("{b:?}"),
        "re-encoding changed the model"
    );
    let mut buf2 = [0u8; MAX_BLOB_LEN];
    let m = again.encode(&mut buf2).expect("re-encodes");
    assert_eq!(&buf[..n], &buf2[..m], "encoding is not a fixed point");
    let x = [320.0f32; 12];
    let mut out = [0.0f32; 3];
    let _ = b.infer(&x[..b.n_inputs()], &mut out[..b.n_outputs()]);
    let _ = b.in_range(&x[..b.n_inputs()]);
}

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

/// The frames and final `pending()` a `FrameAccumulator<N>` must produce: split at every
/// `0x00`, skip empty pieces, an overlong piece is one `Oversize`; the unfinished piece is
/// pending (0 once it overflowed).
fn reference_split<const N: usize>(bytes: &[u8]) -> (Vec<Result<Vec<u8>, ProtocolError>>, usize) {
    let mut out = Vec::new();
    let mut pieces = bytes.split(|&b| b == 0).peekable();
    let mut pending = 0;
    while let Some(p) = pieces.next() {
        if pieces.peek().is_none() {
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
    let (want, pending) = reference_split::<N>(bytes);
    assert_eq!(got, want);
    assert_eq!(acc.pending(), pending);
}

/// `frame_decode`: any bytes into the protocol's receive path.
///
/// - `decode_request` / `decode_response` on the raw bytes return, never panic; whatever
///   decodes re-encodes into one `MAX_FRAME_LEN` frame, and encoding is a fixed point.
/// - The bytes as a stream through accumulators of two sizes (`MAX_FRAME_LEN`, as the
///   firmware, and 8 bytes, so overlong frames are common) give exactly the frames of the
///   reference splitter.
pub fn frame_decode(data: &[u8]) {
    round_trip::<Request, _>(data, |m, buf| {
        protocol::encode_request(m, buf).map(|f| f.len())
    });
    round_trip::<Response, _>(data, |m, buf| {
        protocol::encode_response(m, buf).map(|f| f.len())
    });
    accumulate::<MAX_FRAME_LEN>(data);
    accumulate::<8>(data);
}

fn model_slot() -> &'static [u8] {
    static M: OnceLock<Vec<u8>> = OnceLock::new();
    M.get_or_init(|| {
        let mut b = crate::blob_bytes(&crate::sample_model(3, 42));
        b.resize(MAX_BLOB_LEN, 0xFF);
        b
    })
}

/// `head_stream`: a whole head (`SimHead`: the firmware loop with every tick checked) fed an
/// arbitrary stream. It must never panic; every setpoint and servo command stays within the
/// joint limits and the per-tick step limit, every response fits a frame and echoes its
/// request id, the head comes to rest, and afterwards it still answers a `Ping`.
///
/// Input: byte 0 picks the weight slots (bits 0-1: fallback, network in A, network in B,
/// both) and the form (bit 2); byte 1 is the number of control ticks run after each frame
/// terminator (0-63). Raw form: the rest is the byte stream. Structured form: the rest is
/// read as 17-byte records `kind, u_l, v_l, u_r, v_r` (four little-endian f32), each sent as
/// a well-formed `Look`/`Estimate`/`Home`/`Info`/`Ping` frame, so any float (NaN,
/// infinities, subnormals, huge) reaches the estimator and the gaze controller.
pub fn head_stream(data: &[u8]) {
    if let Err(v) = run_head_stream(data) {
        panic!("{v}");
    }
}

fn run_head_stream(data: &[u8]) -> Result<(), crate::sim::Violation> {
    let Some((&mode, rest)) = data.split_first() else {
        return Ok(());
    };
    let Some((&ticks, rest)) = rest.split_first() else {
        return Ok(());
    };
    let ticks = u32::from(ticks % 64);
    let (a, b): (&[u8], &[u8]) = match mode & 3 {
        0 => (&[], &[]),
        1 => (model_slot(), &[]),
        2 => (&[], model_slot()),
        _ => (model_slot(), model_slot()),
    };
    let mut head = SimHead::boot(a, b);
    if mode & 4 == 0 {
        for chunk in rest.split_inclusive(|&b| b == 0) {
            head.feed(chunk)?;
            head.tick(ticks)?;
        }
    } else {
        for (k, r) in rest.chunks_exact(17).enumerate() {
            let f = |i: usize| f32::from_le_bytes([r[i], r[i + 1], r[i + 2], r[i + 3]]);
            let p = StereoPoint {
                u_l: f(1),
                v_l: f(5),
                u_r: f(9),
                v_r: f(13),
            };
            let body = match r[0] % 5 {
                0 => RequestBody::Look(p),
                1 => RequestBody::Estimate(p),
                2 => RequestBody::Home,
                3 => RequestBody::Info,
                _ => RequestBody::Ping,
            };
            let id = k as u32 + 1;
            let got = head.request(&Request { id, body })?;
            if got.last().map(|r| r.id) != Some(id) {
                return Err(crate::sim::Violation(format!(
                    "request {id} unanswered: {got:?}"
                )));
            }
            head.tick(ticks)?;
        }
    }
    head.settle(1000)?;
    head.still_answers(u32::MAX)
}

fn frame(req: &Request) -> Vec<u8> {
    let mut buf = [0u8; MAX_FRAME_LEN];
    protocol::encode_request(req, &mut buf)
        .expect("requests fit a frame")
        .to_vec()
}

/// One seed input: `(target, name, bytes)`.
pub type Seed = (&'static str, &'static str, Vec<u8>);

/// The seed corpora of the fuzz targets: valid inputs the fuzzer mutates from (written to
/// `fuzz/corpus/` by `cargo run -p hvs-tests --example fuzz_seeds -- fuzz/corpus`).
pub fn seeds() -> Vec<Seed> {
    let mut out: Vec<Seed> = Vec::new();
    let blob = crate::blob_bytes(&crate::sample_model(3, 42));
    // blob_decode: the raw blob (first byte 'H' is even: used raw), and its payload alone
    // (odd first byte: wrapped under a correct header and CRC by the target).
    let mut payload = vec![1u8];
    payload.extend_from_slice(&blob[HEADER_LEN..blob.len() - blob::CRC_LEN]);
    out.push(("blob_decode", "valid_blob", blob));
    out.push(("blob_decode", "valid_payload", payload));

    let p = StereoPoint {
        u_l: 340.0,
        v_l: 236.0,
        u_r: 300.0,
        v_r: 236.0,
    };
    let bodies = [
        ("ping", RequestBody::Ping),
        ("info", RequestBody::Info),
        ("estimate", RequestBody::Estimate(p)),
        ("look", RequestBody::Look(p)),
        ("home", RequestBody::Home),
        (
            "bench",
            RequestBody::Bench {
                point: p,
                count: 10,
            },
        ),
    ];
    let mut stream = Vec::new();
    for (k, (name, body)) in bodies.iter().enumerate() {
        let f = frame(&Request {
            id: k as u32 + 1,
            body: *body,
        });
        stream.extend_from_slice(&f);
        out.push(("frame_decode", name, f));
    }
    out.push(("frame_decode", "stream", stream));

    // head_stream: mode (bits 0-1 slots, bit 2 structured), ticks per frame, then the input.
    let looks: Vec<u8> = [
        RequestBody::Look(p),
        RequestBody::Look(StereoPoint {
            u_l: 250.0,
            u_r: 220.0,
            ..p
        }),
        RequestBody::Home,
        RequestBody::Estimate(p),
    ]
    .iter()
    .enumerate()
    .flat_map(|(k, body)| {
        frame(&Request {
            id: k as u32 + 1,
            body: *body,
        })
    })
    .collect();
    for (name, mode) in [
        ("fallback_raw", 0u8),
        ("network_a_raw", 1),
        ("network_b_raw", 2),
    ] {
        let mut v = vec![mode, 20];
        v.extend_from_slice(&looks);
        out.push(("head_stream", name, v));
    }
    let mut structured = vec![5u8, 30];
    for (kind, q) in [
        (0u8, p),
        (0, StereoPoint { u_l: 200.0, ..p }),
        (2, p),
        (1, p),
    ] {
        structured.push(kind);
        for c in q.to_array() {
            structured.extend_from_slice(&c.to_le_bytes());
        }
    }
    out.push(("head_stream", "network_structured", structured));
    out
}
