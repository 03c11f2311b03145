//! The checks of the fuzz targets in `fuzz/`, as plain functions: the targets only call
//! these, and `tests/tests/fuzz_regressions.rs` replays every input kept in
//! `tests/fuzz-regressions/<target>/` (crashes found by the fuzzer, minimised) and the seed
//! corpus through the same functions in a normal `cargo test`. Each panics on a failure.

use crate::sim::SimHead;
use hvs_host::data::csv::{self as csv_io, Inputs};
use hvs_host::data::dataset::{JOINT_COLUMNS, PIXEL_COLUMNS, TARGET_COLUMNS};
use hvs_shared::runtime::blob::{self, HEADER_LEN, MAGIC, MAX_BLOB_LEN, VERSION};
use hvs_shared::runtime::gaze::Joints;
use hvs_shared::runtime::protocol::{
    self, FrameAccumulator, ProtocolError, Request, RequestBody, Response, StereoPoint,
    MAX_FRAME_LEN,
};
use std::path::Path;
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
    assert!(n <= framed, "re-encoding grew the blob from {framed} to {n} bytes");
    let again = blob::decode(&buf[..n]).expect("a re-encoded blob decodes");
    assert_eq!(format!("{again:?}"), format!("{b:?}"), "re-encoding changed the model");
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
    round_trip::<Request, _>(data, |m, buf| protocol::encode_request(m, buf).map(|f| f.len()));
    round_trip::<Response, _>(data, |m, buf| protocol::encode_response(m, buf).map(|f| f.len()));
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
            let p = StereoPoint { u_l: f(1), v_l: f(5), u_r: f(9), v_r: f(13) };
            let body = match r[0] % 7 {
                0 => RequestBody::Look(p),
                1 => RequestBody::Estimate(p),
                2 => RequestBody::Home,
                3 => RequestBody::Info,
                4 => RequestBody::Posture(Joints([p.u_l, p.v_l, p.u_r, p.v_r, f(1) - f(13)])),
                5 => RequestBody::State,
                _ => RequestBody::Ping,
            };
            let id = k as u32 + 1;
            let got = head.request(&Request { id, body })?;
            if got.last().map(|r| r.id) != Some(id) {
                return Err(crate::sim::Violation(format!("request {id} unanswered: {got:?}")));
            }
            head.tick(ticks)?;
        }
    }
    head.settle(1000)?;
    head.still_answers(u32::MAX)
}

/// `csv_read`: any bytes as a CSV point file, read by the host's reader
/// (`hvs_host::data::csv::read_set_from`) in four modes (pixels; pixels with targets; pixels,
/// joints and targets; auto-detected joints). It must return, never panic. An error names the
/// file first (`fuzz.csv`), and a line number in it lies within the input. A table it returns
/// has at least one row, the promised columns (4 or 9 inputs; targets iff asked), only finite
/// numbers, one line number per row, increasing, on non-blank lines of the input (lines end at
/// `\n`, `\r\n` or a lone `\r`, as in the csv crate); written back as plain CSV and read again
/// it gives the same numbers, bit for bit.
pub fn csv_read(data: &[u8]) {
    let name = Path::new("fuzz.csv");
    let text_lines = lines_of(data);
    let n_lines = text_lines.len() as u64;
    for (inputs, targets) in [
        (Inputs::Stereo, false),
        (Inputs::Stereo, true),
        (Inputs::StereoJoints, true),
        (Inputs::Auto, false),
    ] {
        let t = match csv_io::read_set_from(name, data, inputs, targets) {
            Ok(t) => t,
            Err(e) => {
                let msg = format!("{e:#}");
                let rest = msg
                    .strip_prefix("fuzz.csv")
                    .unwrap_or_else(|| panic!("error does not name the file: {msg}"));
                if let Some(after) = rest.strip_prefix(':') {
                    let digits: String = after.chars().take_while(char::is_ascii_digit).collect();
                    if let Ok(line) = digits.parse::<u64>() {
                        assert!(
                            (1..=n_lines).contains(&line),
                            "line {line} of {n_lines} in: {msg}"
                        );
                    }
                }
                continue;
            }
        };
        let d = &t.data;
        assert!(!d.is_empty(), "{inputs:?}: a table without rows");
        let n = d.len();
        match inputs {
            Inputs::Stereo => assert_eq!(d.n_inputs, 4),
            Inputs::StereoJoints => assert_eq!(d.n_inputs, 9),
            Inputs::Auto => assert!(d.n_inputs == 4 || d.n_inputs == 9),
        }
        assert_eq!(d.inputs.len(), n * d.n_inputs);
        assert_eq!(d.has_targets(), targets);
        assert!(targets || d.targets.is_empty());
        assert!(d.inputs.iter().all(|v| v.is_finite()));
        assert!(d.targets.iter().flatten().all(|v| v.is_finite()));
        assert_eq!(t.lines.len(), n);
        for (i, w) in t.lines.windows(2).enumerate() {
            assert!(w[0] < w[1], "rows {i} and {} on lines {} and {}", i + 1, w[0], w[1]);
        }
        for &l in &t.lines {
            assert!((2..=n_lines).contains(&l), "row on line {l} of {n_lines}");
            let text = text_lines[(l - 1) as usize];
            assert!(text.iter().any(|b| !b.is_ascii_whitespace()), "row on blank line {l}");
            assert!(t.at(0).starts_with("fuzz.csv:"));
        }
        // Round trip through plain CSV.
        let mut cols: Vec<&str> = PIXEL_COLUMNS.to_vec();
        if d.n_inputs == 9 {
            cols.extend(JOINT_COLUMNS);
        }
        if targets {
            cols.extend(TARGET_COLUMNS);
        }
        let mut out = cols.join(",");
        out.push('\n');
        for i in 0..n {
            let mut row: Vec<String> = d.row(i).iter().map(|v| format!("{v:?}")).collect();
            if targets {
                row.extend(d.targets[i].iter().map(|v| format!("{v:?}")));
            }
            out.push_str(&row.join(","));
            out.push('\n');
        }
        let again = csv_io::read_set_from(name, out.as_bytes(), inputs, targets)
            .unwrap_or_else(|e| panic!("{inputs:?}: own output unreadable: {e:#}\n{out}"));
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&again.data.inputs), bits(&d.inputs), "{inputs:?}");
        assert_eq!(bits(&again.data.targets.concat()), bits(&d.targets.concat()), "{inputs:?}");
    }
}

/// The lines of `data` as a text editor shows them: a line ends at `\n`, `\r\n` or a lone
/// `\r` (the csv crate accepts all three as record terminators).
fn lines_of(data: &[u8]) -> Vec<&[u8]> {
    let mut out = Vec::new();
    let mut start = 0;
    let mut i = 0;
    while i < data.len() {
        match data[i] {
            b'\n' => {
                out.push(&data[start..i]);
                start = i + 1;
            }
            b'\r' => {
                out.push(&data[start..i]);
                if data.get(i + 1) == Some(&b'\n') {
                    i += 1;
                }
                start = i + 1;
            }
            _ => {}
        }
        i += 1;
    }
    out.push(&data[start..]);
    out
}

fn frame(req: &Request) -> Vec<u8> {
    let mut buf = [0u8; MAX_FRAME_LEN];
    protocol::encode_request(req, &mut buf).expect("requests fit a frame").to_vec()
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

    let p = StereoPoint { u_l: 340.0, v_l: 236.0, u_r: 300.0, v_r: 236.0 };
    let bodies = [
        ("ping", RequestBody::Ping),
        ("info", RequestBody::Info),
        ("estimate", RequestBody::Estimate(p)),
        ("look", RequestBody::Look(p)),
        ("home", RequestBody::Home),
        ("bench", RequestBody::Bench { point: p, count: 10 }),
        ("posture", RequestBody::Posture(Joints([10.0, -200.0, f32::NAN, 3.0, -3.0]))),
        ("state", RequestBody::State),
    ];
    let mut stream = Vec::new();
    for (k, (name, body)) in bodies.iter().enumerate() {
        let f = frame(&Request { id: k as u32 + 1, body: *body });
        stream.extend_from_slice(&f);
        out.push(("frame_decode", name, f));
    }
    out.push(("frame_decode", "stream", stream));

    // head_stream: mode (bits 0-1 slots, bit 2 structured), ticks per frame, then the input.
    let looks: Vec<u8> = [
        RequestBody::Look(p),
        RequestBody::Look(StereoPoint { u_l: 250.0, u_r: 220.0, ..p }),
        RequestBody::Home,
        RequestBody::Estimate(p),
    ]
    .iter()
    .enumerate()
    .flat_map(|(k, body)| frame(&Request { id: k as u32 + 1, body: *body }))
    .collect();
    for (name, mode) in [("fallback_raw", 0u8), ("network_a_raw", 1), ("network_b_raw", 2)] {
        let mut v = vec![mode, 20];
        v.extend_from_slice(&looks);
        out.push(("head_stream", name, v));
    }
    let mut structured = vec![5u8, 30];
    for (kind, q) in [(0u8, p), (0, StereoPoint { u_l: 200.0, ..p }), (2, p), (1, p)] {
        structured.push(kind);
        for c in q.to_array() {
            structured.extend_from_slice(&c.to_le_bytes());
        }
    }
    out.push(("head_stream", "network_structured", structured));

    // csv_read: a pixel set with targets, a posture-aware set, and one with quirks the reader
    // accepts (CRLF, spaces, blank lines, extra and reordered columns).
    out.push((
        "csv_read",
        "pixels_targets",
        b"u_l,v_l,u_r,v_r,x,y,z\n343.5,240,297.25,240,0,0,110\n330,231.5,310,249,-3.5,2,65\n"
            .to_vec(),
    ));
    out.push((
        "csv_read",
        "joints",
        b"u_l,v_l,u_r,v_r,neck_pan,neck_tilt,eye_tilt,left_eye_pan,right_eye_pan,x,y,z\n\
          340,236,300,236,1.5,-2,0,3.25,4,1,2,100\n"
            .to_vec(),
    ));
    out.push((
        "csv_read",
        "quirks",
        b"z , note, v_r,u_r ,v_l,u_l,y,x\r\n\r\n 110,a,240,297,240,343,0,0\r\n\n120,\"b,c\",241,296,241,344,1,1\r\n"
            .to_vec(),
    ));

    // rig_json: cases.json (case 1: first byte 3), a flat rig, and one with a duplicate key.
    let mut cases = vec![3u8];
    cases.extend_from_slice(include_bytes!("../../shared/tests/fixtures/cases.json"));
    out.push(("rig_json", "cases_json_case1", cases));
    let flat = br#"{"phi_u_left": 285.8, "phi_u_right": 228.7, "alpha_left": -0.0455,
        "alpha_right": 0.0455, "beta0": 0.0087, "phi0": 0.0087, "width": 1280, "u0": 600.5}"#;
    let mut v = vec![0u8];
    v.extend_from_slice(flat);
    out.push(("rig_json", "flat", v.clone()));
    let mut dup = v;
    dup.extend_from_slice(b"\n");
    let at = dup.len() - 2;
    dup.splice(at..at, b", \"u0\": 1".iter().copied());
    out.push(("rig_json", "duplicate_key", dup));
    out.extend(image_seeds());
    out
}

/// `rig_json`: the first byte picks `--case` (even: none; odd: case `(b >> 1) % 8`), the rest
/// is the rig file's text. `hvs_host::data::rig::parse` must return, never panic; an error is
/// one non-empty line; an accepted rig has finite, positive focal lengths and half baseline,
/// small angles, a 1..65535 pixel image and a finite principal point, and written back as a
/// flat rig object (every field, shortest round-trip numbers) it parses to the same rig.
pub fn rig_json(data: &[u8]) {
    let Some((mode, rest)) = data.split_first() else {
        return;
    };
    let Ok(text) = std::str::from_utf8(rest) else {
        return;
    };
    let case = (mode & 1 == 1).then_some((mode >> 1) % 8);
    let rig = match hvs_host::data::rig::parse(text, case) {
        Ok(r) => r,
        Err(e) => {
            let msg = format!("{e:#}");
            assert!(!msg.is_empty(), "an empty error");
            return;
        }
    };
    for (name, v) in [
        ("phi_u_left", rig.phi_u_left),
        ("phi_u_right", rig.phi_u_right),
        ("phi_v_left", rig.phi_v_left),
        ("phi_v_right", rig.phi_v_right),
        ("half_baseline", rig.half_baseline),
    ] {
        assert!(v.is_finite() && v > 0.0, "{name} = {v}");
    }
    for (name, v) in [
        ("alpha_left", rig.alpha_left),
        ("alpha_right", rig.alpha_right),
        ("beta0", rig.beta0),
        ("phi0", rig.phi0),
    ] {
        assert!(v.abs() < core::f64::consts::FRAC_PI_2, "{name} = {v}");
    }
    assert!(rig.u0.is_finite() && rig.v0.is_finite(), "{rig:?}");
    assert!((1..=65_535).contains(&rig.width) && (1..=65_535).contains(&rig.height));
    let flat = format!(
        "{{\"phi_u_left\": {:?}, \"phi_u_right\": {:?}, \"phi_v_left\": {:?}, \"phi_v_right\": {:?}, \
         \"alpha_left\": {:?}, \"alpha_right\": {:?}, \"beta0\": {:?}, \"phi0\": {:?}, \"u0\": {:?}, \
         \"v0\": {:?}, \"width\": {}, \"height\": {}, \"half_baseline_cm\": {:?}}}",
        rig.phi_u_left,
        rig.phi_u_right,
        rig.phi_v_left,
        rig.phi_v_right,
        rig.alpha_left,
        rig.alpha_right,
        rig.beta0,
        rig.phi0,
        rig.u0,
        rig.v0,
        rig.width,
        rig.height,
        rig.half_baseline
    );
    let again = hvs_host::data::rig::parse(&flat, None)
        .unwrap_or_else(|e| panic!("the accepted rig written back is refused: {e:#}: {flat}"));
    assert_eq!(again, rig, "{flat}");
}

/// Splits `data` into `N` parts: each but the last is prefixed by its length (`u32`, little
/// endian, cut to what is left); the last part is the rest.
fn parts<const N: usize>(data: &[u8]) -> [&[u8]; N] {
    let mut out = [&data[..0]; N];
    let mut rest = data;
    for p in out.iter_mut().take(N - 1) {
        let (len, tail) = match rest {
            [a, b, c, d, tail @ ..] => (u32::from_le_bytes([*a, *b, *c, *d]) as usize, tail),
            _ => (0, &rest[rest.len()..]),
        };
        let len = len.min(tail.len());
        *p = &tail[..len];
        rest = &tail[len..];
    }
    out[N - 1] = rest;
    out
}

/// `N` parts joined as [`parts`] splits them.
fn joined(parts: &[&[u8]]) -> Vec<u8> {
    let mut out = Vec::new();
    for (k, p) in parts.iter().enumerate() {
        if k + 1 < parts.len() {
            out.extend_from_slice(&(p.len() as u32).to_le_bytes());
        }
        out.extend_from_slice(p);
    }
    out
}

/// An error message must be one line and never Rust debug output of a panic.
fn one_line(msg: &str) {
    assert!(!msg.contains('\n'), "a multi-line error: {msg}");
    assert!(!msg.contains("panicked"), "{msg}");
}

/// `capture_set`: the path of `hvs board detect`. The input is four parts (`parts`): a
/// board JSON, a captures CSV and two image files, written as `board.json`, `captures.csv`,
/// `l.png` and `r.png` in a fresh folder. Reading the board and the captures, detecting every
/// pair (images read through `hvs_vision::image_file`: PNG or JPEG, at most 16 Mpx) and
/// writing `POINTS.csv` must return, never panic; an error is one line; the points file has
/// the header `capture,i,j,u_l,v_l,u_r,v_r` and one row per corner of every found pair, each
/// with the header's field count.
pub fn capture_set(data: &[u8]) {
    capture_set_found(data);
}

/// [`capture_set`], returning how many pairs were found (0 where the input stopped earlier):
/// the seeds' test checks that their boards are found, so that the fuzzer starts from inputs
/// that go all the way through.
pub fn capture_set_found(data: &[u8]) -> usize {
    let [board, captures, left, right] = parts::<4>(data);
    let dir = tempfile::tempdir().expect("a temporary folder");
    for (name, bytes) in
        [("board.json", board), ("captures.csv", captures), ("l.png", left), ("r.png", right)]
    {
        std::fs::write(dir.path().join(name), bytes).expect("written");
    }
    let board = match hvs_vision::board::Board::from_path(&dir.path().join("board.json")) {
        Ok(b) => b,
        Err(e) => {
            one_line(&e.to_string());
            return 0;
        }
    };
    let set = match hvs_host::data::captures::read(&dir.path().join("captures.csv")) {
        Ok(s) => s,
        Err(e) => {
            one_line(&format!("{e:#}"));
            return 0;
        }
    };
    // Images named in the CSV may be anything: only the folder's own files are read.
    if set
        .captures
        .iter()
        .any(|c| !c.left.starts_with(dir.path()) || !c.right.starts_with(dir.path()))
    {
        return 0;
    }
    let det = match hvs_host::vision::detect_set(&board, &set, &|| {}) {
        Ok(d) => d,
        Err(e) => {
            one_line(&format!("{e:#}"));
            return 0;
        }
    };
    assert_eq!(det.outcomes.len(), set.captures.len());
    for o in &det.outcomes {
        if let hvs_host::vision::PairOutcome::Skipped(why) = o {
            one_line(why);
        }
    }
    let text = hvs_host::vision::points_csv(&board, &set, &det);
    let mut lines = text.lines();
    let header = lines.next().expect("a header");
    assert!(header.starts_with("capture,i,j,u_l,v_l,u_r,v_r"), "{header}");
    let fields = csv_fields(header);
    let found = det
        .outcomes
        .iter()
        .filter(|o| matches!(o, hvs_host::vision::PairOutcome::Found(_)))
        .count();
    let rows: Vec<&str> = lines.collect();
    assert_eq!(rows.len(), found * board.corner_count());
    for r in rows {
        assert_eq!(csv_fields(r), fields, "{r}");
    }
    found
}

/// Fields of one CSV line (quoted fields may hold commas).
fn csv_fields(line: &str) -> usize {
    let mut rdr = ::csv::ReaderBuilder::new().has_headers(false).from_reader(line.as_bytes());
    rdr.records().next().map_or(0, |r| r.map_or(0, |r| r.len()))
}

/// `locate`: the path of `hvs locate`. The input is four parts (`parts`): a model file, two
/// image files and a pixels CSV. Loading the model, reading both images, reading the pixels
/// and locating them must return, never panic; errors are one line; every point gets one
/// result with a known status, an `ok` one with a right pixel inside the right image and a
/// finite X, Y, Z, the others without.
pub fn locate(data: &[u8]) {
    let [model, left, right, points] = parts::<4>(data);
    let dir = tempfile::tempdir().expect("a temporary folder");
    let path = |n: &str| dir.path().join(n);
    for (name, bytes) in [("m.hvsw", model), ("l.png", left), ("r.png", right), ("p.csv", points)] {
        std::fs::write(path(name), bytes).expect("written");
    }
    let pixels = match hvs_host::data::pixels::read_pixels(&path("p.csv")) {
        Ok(p) => p,
        Err(e) => return one_line(&format!("{e:#}")),
    };
    let m = match hvs_host::data::model::load(&path("m.hvsw")) {
        Ok(m) => m,
        Err(e) => return one_line(&format!("{e:#}")),
    };
    let (l, r) = match (
        hvs_host::vision::read_grey(&path("l.png")),
        hvs_host::vision::read_grey(&path("r.png")),
    ) {
        (Ok(l), Ok(r)) => (l, r),
        (Err(e), _) | (_, Err(e)) => return one_line(&format!("{e:#}")),
    };
    if m.blob.n_inputs() != 4 || l.dimensions() != r.dimensions() {
        return;
    }
    let (found, warnings) = match hvs_host::depth::locate(&m.blob, &l, &r, &pixels.points) {
        Ok(f) => f,
        Err(e) => return one_line(&format!("{e:#}")),
    };
    assert_eq!(found.len(), pixels.points.len());
    assert!(warnings.iter().all(|w| !w.is_empty() && !w.contains('\n')), "{warnings:?}");
    let known = hvs_host::vision::STATUSES;
    let (w, h) = (f64::from(r.width()), f64::from(r.height()));
    for f in &found {
        assert!(known.contains(&f.status), "{}", f.status);
        if f.status == "ok" {
            let rp = f.right.expect("an ok match has a right pixel");
            assert!(rp[0] > -1.0 && rp[0] < w && rp[1] > -1.0 && rp[1] < h, "{rp:?}");
            assert!(f.xyz.expect("an estimate").iter().all(|v| v.is_finite()));
        } else {
            assert!(f.xyz.is_none(), "{f:?}");
        }
    }
}

/// The seeds of `capture_set` and `locate`: two rendered pairs of case I at a quarter of its
/// size (160 x 120, a 5x4 board, so that the fuzzer's runs stay short) with their board and captures; a sample model with a
/// matcher geometry of parallel cameras, a pair and two pixels.
pub fn image_seeds() -> Vec<Seed> {
    use hvs_shared::sim::posture::HeadRig;
    use hvs_vision::render;
    let board = render::Board::new(5, 4, 6.0).expect("a board");
    // Case I at a quarter of its size (160 x 120): a run detects two small images.
    let c = hvs_shared::sim::presets::CASE_1;
    let rig = hvs_shared::sim::camera::Rig {
        phi_u_left: c.phi_u_left / 4.0,
        phi_u_right: c.phi_u_right / 4.0,
        phi_v_left: c.phi_v_left / 4.0,
        phi_v_right: c.phi_v_right / 4.0,
        u0: c.u0 / 4.0,
        v0: c.v0 / 4.0,
        width: c.width / 4,
        height: c.height / 4,
        ..c
    };
    let set = render::render_capture_set(
        &HeadRig::new(rig),
        &hvs_shared::runtime::gaze::Joints::HOME,
        &board,
        [0.0, 0.0],
        &[40.0, 50.0],
        &render::RenderOptions::default(),
        7,
    )
    .expect("rendered");
    let png = |img: &image::GrayImage| hvs_host::vision::png_bytes(img).expect("a PNG");
    let (l0, r0) = (png(&set.captures[0].render.left), png(&set.captures[0].render.right));
    let board_json = set.board_json();
    let mut out: Vec<Seed> = vec![(
        "capture_set",
        "one_pair",
        joined(&[board_json.as_bytes(), b"left,right,z\nl.png,r.png,40\n", &l0, &r0]),
    )];
    out.push((
        "capture_set",
        "same_image_twice",
        joined(&[
            board_json.as_bytes(),
            b"left,right,z,x,y,note\nl.png,r.png,40,1,-2,a\nl.png,l.png,50,0,0,b\n",
            &l0,
            &r0,
        ]),
    ));
    let mut blob = crate::sample_model(3, 42);
    blob.matcher = Some(hvs_shared::runtime::blob::MatcherGeometry {
        fundamental: [[0.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]],
        out_min: [-30.0, -20.0, 65.0],
        out_max: [30.0, 20.0, 165.0],
        disparity: [10.0, 60.0],
        right_scale: [1.0, 1.0],
    });
    let model = crate::blob_bytes(&blob);
    out.push((
        "locate",
        "two_points",
        joined(&[&model, &l0, &r0, b"u_l,v_l,note\n320,240,a\nnan,3,b\n"]),
    ));
    out
}
