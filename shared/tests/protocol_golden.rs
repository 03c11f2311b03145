//! Golden bytes of every protocol message: a round-trip test cannot see a reordered enum or a
//! field added in the middle, these can. Each message's COBS frame (as it goes on the wire) is
//! compared with `tests/golden/protocol.txt` and decoded back from it.
//!
//! A deliberate change to the wire format (with a `PROTOCOL_VERSION` bump) re-blesses the file:
//! `HVS_BLESS=1 cargo test -p hvs-shared --test protocol_golden`, then review the diff.

use hvs_shared::runtime::blob::BlobError;
use hvs_shared::runtime::gaze::Joints;
use hvs_shared::runtime::layout::Slot;
use hvs_shared::runtime::protocol::*;
use hvs_shared::runtime::traditional::Calibration;

const P: StereoPoint = StereoPoint { u_l: 335.25, v_l: 240.5, u_r: 289.0, v_r: -1.5 };

fn estimate(source: Source) -> EstimateData {
    EstimateData { x: -1.75, y: 0.5, z: 65.125, source, in_range: true }
}

fn info(mode: Mode, model: Option<ModelInfo>, a: SlotStatus, b: SlotStatus) -> InfoData {
    InfoData {
        firmware: FirmwareVersion { major: 0, minor: 1, patch: 2 },
        protocol: PROTOCOL_VERSION,
        slot: model.map(|_| Slot::B),
        generation: if model.is_some() { 7 } else { 0 },
        mode,
        slot_a: a,
        slot_b: b,
        model,
        fallback: Calibration::BUILT_IN,
        stack_peak: model.map(|_| 5_260),
    }
}

fn requests() -> Vec<(&'static str, Request)> {
    let r = |id, body| Request { id, body };
    vec![
        ("request ping", r(1, RequestBody::Ping)),
        ("request info", r(2, RequestBody::Info)),
        ("request estimate", r(3, RequestBody::Estimate(P))),
        ("request look", r(300, RequestBody::Look(P))),
        ("request home", r(70_000, RequestBody::Home)),
        ("request bench", r(u32::MAX, RequestBody::Bench { point: P, count: 1000 })),
        ("request posture", r(301, RequestBody::Posture(Joints([12.5, -3.25, 0.0, -0.0, 1e-30])))),
        ("request state", r(302, RequestBody::State)),
    ]
}

fn responses() -> Vec<(&'static str, Response)> {
    let r = |id, body| Response { id, body };
    let model = ModelInfo {
        inputs: 4,
        hidden: 5,
        outputs: 3,
        seed: 11,
        train_hash: 0x0123_4567_89ab_cdef,
        train_points: 72,
        train_error_pct: 0.875,
    };
    vec![
        ("response ready", r(UNSOLICITED_ID, ResponseBody::Ready { protocol: 1 })),
        ("response pong", r(1, ResponseBody::Pong)),
        (
            "response info network",
            r(
                2,
                ResponseBody::Info(info(
                    Mode::Network,
                    Some(model),
                    SlotStatus::Invalid(BlobError::BadCrc),
                    SlotStatus::Valid { generation: 7 },
                )),
            ),
        ),
        (
            "response info fallback",
            r(
                2,
                ResponseBody::Info(info(
                    Mode::Fallback,
                    None,
                    SlotStatus::Empty,
                    SlotStatus::UnsupportedTopology { inputs: 4, hidden: 5, outputs: 1 },
                )),
            ),
        ),
        ("response estimate network", r(3, ResponseBody::Estimate(estimate(Source::Network)))),
        ("response estimate fallback", r(3, ResponseBody::Estimate(estimate(Source::Fallback)))),
        (
            "response look",
            r(
                300,
                ResponseBody::Look(LookData {
                    estimate: estimate(Source::Network),
                    target: Joints([1.08, -0.18, 2.52, -3.6, 3.6]),
                    limited: false,
                }),
            ),
        ),
        ("response home", r(70_000, ResponseBody::Home)),
        (
            "response bench",
            r(
                u32::MAX,
                ResponseBody::Bench(BenchData {
                    count: 1000,
                    ticks: 4_900,
                    overhead_ticks: 12,
                    tick_hz: 168_000_000,
                }),
            ),
        ),
        (
            "response state",
            r(
                302,
                ResponseBody::State(StateData {
                    joints: Joints([1.08, -0.18, 2.52, -3.6, 3.6]),
                    goal: Joints([12.42, -3.24, 0.0, 0.0, 0.0]),
                    ticks: 70_000,
                    moving: true,
                }),
            ),
        ),
    ]
    .into_iter()
    .chain(
        [
            ("response error malformed", ErrorCode::Malformed),
            ("response error oversize", ErrorCode::Oversize),
            ("response error non-finite", ErrorCode::NonFinite),
            ("response error unreachable", ErrorCode::Unreachable),
            ("response error no solution", ErrorCode::NoSolution),
            ("response error unsupported", ErrorCode::Unsupported),
        ]
        .into_iter()
        .map(|(n, c)| (n, r(9, ResponseBody::Error(c)))),
    )
    .chain(
        [
            ("response info slot A bad magic", BlobError::BadMagic),
            ("response info slot A unsupported version", BlobError::UnsupportedVersion(2)),
            ("response info slot A truncated", BlobError::Truncated),
            ("response info slot A too large", BlobError::TooLarge),
            ("response info slot A malformed", BlobError::Malformed),
            ("response info slot A topology mismatch", BlobError::TopologyMismatch),
            ("response info slot A bad parameter", BlobError::BadParameter),
            ("response info slot A buffer too small", BlobError::BufferTooSmall),
        ]
        .into_iter()
        .map(|(n, e)| {
            let i = info(Mode::Fallback, None, SlotStatus::Invalid(e), SlotStatus::Empty);
            (n, r(2, ResponseBody::Info(i)))
        }),
    )
    .collect()
}

fn hex(b: &[u8]) -> String {
    b.iter().map(|x| format!("{x:02x}")).collect()
}

fn unhex(s: &str) -> Vec<u8> {
    (0..s.len()).step_by(2).map(|i| u8::from_str_radix(&s[i..i + 2], 16).unwrap()).collect()
}

fn frames() -> Vec<(String, Vec<u8>)> {
    let mut out = Vec::new();
    let mut buf = [0u8; MAX_FRAME_LEN];
    for (name, req) in requests() {
        out.push((name.to_string(), encode_request(&req, &mut buf).unwrap().to_vec()));
    }
    for (name, resp) in responses() {
        out.push((name.to_string(), encode_response(&resp, &mut buf).unwrap().to_vec()));
    }
    out
}

const GOLDEN: &str = "tests/golden/protocol.txt";

#[test]
fn every_message_has_its_golden_bytes() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join(GOLDEN);
    let now = frames();
    let text: String = now.iter().map(|(n, b)| format!("{n}: {}\n", hex(b))).collect();
    if std::env::var_os("HVS_BLESS").is_some() {
        std::fs::write(&path, &text).unwrap();
    }
    let golden = std::fs::read_to_string(&path).expect("tests/golden/protocol.txt is committed");
    let want: Vec<(&str, &str)> =
        golden.lines().map(|l| l.split_once(": ").expect("name: hex")).collect();
    assert_eq!(want.len(), now.len(), "a message was added or removed");
    for ((name, bytes), (gname, ghex)) in now.iter().zip(&want) {
        assert_eq!(name, gname);
        assert_eq!(&hex(bytes), ghex, "{name}: the wire bytes changed");
    }
}

#[test]
fn golden_bytes_decode_to_the_messages() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join(GOLDEN);
    let golden = std::fs::read_to_string(path).unwrap();
    let mut lines = golden.lines().map(|l| unhex(l.split_once(": ").unwrap().1));
    for (name, req) in requests() {
        let mut f = lines.next().unwrap();
        let body = f.len() - 1; // the frame ends with its 0x00 delimiter
        assert_eq!(decode_request(&mut f[..body]).unwrap(), req, "{name}");
    }
    for (name, resp) in responses() {
        let mut f = lines.next().unwrap();
        let body = f.len() - 1;
        assert_eq!(decode_response(&mut f[..body]).unwrap(), resp, "{name}");
    }
}
