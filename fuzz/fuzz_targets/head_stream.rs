//! A whole head fed arbitrary byte streams: the firmware loop of `hvs_tests::sim::SimHead`
//! (`FrameAccumulator` -> `head::read_frame` -> `Head::respond`, control ticks, MCDC and PWM
//! conversion) must never panic, every setpoint and servo command stays within the joint limits
//! and the per-tick step limit, every response fits a frame and echoes its request id, and
//! afterwards the head still answers a `Ping`.
//!
//! Input: byte 0 picks the weight slots (bits 0-1: fallback, network in A, network in B, both)
//! and the input form (bit 2); byte 1 is the number of control ticks run after each frame
//! terminator (0-63). Raw form: the rest is the byte stream. Structured form: the rest is read
//! as 17-byte records `kind, u_l, v_l, u_r, v_r` (four little-endian f32), each sent as a
//! well-formed `Look`/`Estimate`/`Home`/`Info`/`Ping` frame, so any float (NaN, infinities,
//! subnormals, huge) reaches the estimator and the gaze controller.
#![no_main]

use hvs_shared::protocol::{Request, RequestBody, StereoPoint};
use hvs_tests::sim::SimHead;
use libfuzzer_sys::fuzz_target;
use std::sync::OnceLock;

fn model() -> &'static [u8] {
    static M: OnceLock<Vec<u8>> = OnceLock::new();
    M.get_or_init(|| {
        let mut b = hvs_tests::blob_bytes(&hvs_tests::sample_model(3, 42));
        b.resize(hvs_shared::blob::MAX_BLOB_LEN, 0xFF);
        b
    })
}

fn run(data: &[u8]) -> Result<(), hvs_tests::sim::Violation> {
    let Some((&mode, rest)) = data.split_first() else {
        return Ok(());
    };
    let Some((&ticks, rest)) = rest.split_first() else {
        return Ok(());
    };
    let ticks = u32::from(ticks % 64);
    let (a, b): (&[u8], &[u8]) = match mode & 3 {
        0 => (&[], &[]),
        1 => (model(), &[]),
        2 => (&[], model()),
        _ => (model(), model()),
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
            assert_eq!(got.last().map(|r| r.id), Some(id), "request {id} unanswered");
            head.tick(ticks)?;
        }
    }
    head.settle(1000)?;
    head.still_answers(u32::MAX)
}

fuzz_target!(|data: &[u8]| {
    if let Err(v) = run(data) {
        panic!("{v}");
    }
});
