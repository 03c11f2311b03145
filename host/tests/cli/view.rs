//! `hvs view` over HTTP: the page and its assets, a click answered with `hvs locate --at`'s
//! own line, the model panel with `hvs info`'s text, a capture set retrained on the ticked
//! pairs, bad requests refused with a 4xx while the server stays up, the token off loopback,
//! Ctrl-C. `browser_*` (ignored) drive Debian's chromium through chromedriver; `load_*`
//! (ignored) measure click latency and 20 polling clients.

use crate::common::{hvs, ok, s};
use serde_json::{json, Value};
use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::OnceLock;
use std::time::{Duration, Instant};

/// A rendered capture set (case 1, three depths), its points, a model trained on them and
/// one test pair with its true corners.
struct Fixture {
    _dir: tempfile::TempDir,
    shots: PathBuf,
    model: PathBuf,
    left: PathBuf,
    right: PathBuf,
    /// Left pixels of true board corners of the test pair, rounded.
    corners: Vec<[i64; 2]>,
}

fn fixture() -> &'static Fixture {
    static F: OnceLock<Fixture> = OnceLock::new();
    F.get_or_init(|| {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let shots = d.join("shots");
        crate::common::render_case1(&shots, "6", &["--depths", "65,115,165"]);
        let points = d.join("points.csv");
        ok(&crate::common::detect_args(
            &shots.join("board.json"),
            &shots.join("captures.csv"),
            &points,
        ));
        let model = d.join("m.hvsw");
        crate::common::train_restarts(&points, &model, "2");
        let test = d.join("test");
        crate::common::render_case1(&test, "7", &["--depths", "95", "--centre", "-3,2"]);
        let truth = std::fs::read_to_string(test.join("truth.csv")).unwrap();
        let corners = truth
            .lines()
            .skip(1)
            .map(|l| {
                let f: Vec<&str> = l.split(',').collect();
                [
                    f[6].parse::<f64>().unwrap().round() as i64,
                    f[7].parse::<f64>().unwrap().round() as i64,
                ]
            })
            .collect();
        Fixture {
            shots,
            model,
            left: test.join("left01.png"),
            right: test.join("right01.png"),
            corners,
            _dir: dir,
        }
    })
}

/// A running `hvs view`, killed when dropped.
pub struct Server {
    child: Child,
    /// `127.0.0.1:PORT`.
    pub addr: String,
    /// The printed URL.
    pub url: String,
}

impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// Starts `hvs view` with `args` (and `--listen 127.0.0.1:0` unless given) and waits for its
/// address line.
pub fn start(args: &[&str]) -> Server {
    let mut all: Vec<&str> = vec!["view"];
    all.extend_from_slice(args);
    if !args.contains(&"--listen") {
        all.extend(["--listen", "127.0.0.1:0"]);
    }
    let mut child = Command::new(assert_cmd::cargo::cargo_bin("hvs"))
        .args(&all)
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .expect("hvs view starts");
    let mut line = String::new();
    BufReader::new(child.stdout.take().unwrap()).read_line(&mut line).unwrap();
    let url = line
        .trim()
        .strip_prefix("hvs view: serving ")
        .unwrap_or_else(|| panic!("unexpected first line {line:?}"))
        .to_string();
    let port = url
        .strip_prefix("http://")
        .and_then(|r| r.split('/').next())
        .and_then(|h| h.rsplit(':').next())
        .unwrap()
        .to_string();
    Server { child, addr: format!("127.0.0.1:{port}"), url }
}

/// A view of the fixture's test pair.
pub fn start_pair() -> Server {
    start_pair_with(&[])
}

/// A view of the live virtual head in the small rig's scene (its model trained first), with
/// the options `rest`; the folder holding the model and the scene comes back with it.
pub fn start_live(rest: &[&str]) -> (crate::common::Scratch, Server) {
    let dir = crate::common::Scratch::new();
    let (m, scene) = (crate::common::small_model(&dir), crate::common::small_scene(&dir, ""));
    let mut args = vec!["--model", m.as_str(), "--scene", scene.as_str()];
    args.extend_from_slice(rest);
    let sv = start(&args);
    (dir, sv)
}

/// A view of the fixture's capture set, retraining with one restart.
pub fn start_captures() -> Server {
    let f = fixture();
    let (b, c) = (f.shots.join("board.json"), f.shots.join("captures.csv"));
    start(&["--model", s(&f.model), "--board", s(&b), "--captures", s(&c), "--restarts", "1"])
}

/// A view of the fixture's test pair with the options `rest`.
pub fn start_pair_with(rest: &[&str]) -> Server {
    let f = fixture();
    let mut args = vec!["--model", s(&f.model), "--left", s(&f.left), "--right", s(&f.right)];
    args.extend_from_slice(rest);
    start(&args)
}

/// One HTTP/1.1 request (`Connection: close`): the status and the body.
pub fn http(addr: &str, method: &str, path: &str, body: Option<&[u8]>) -> (u16, Vec<u8>) {
    let (status, _, body) = http_with_head(addr, method, path, body);
    (status, body)
}

/// A frame: the status, the `x-frame-seq` header and the PNG bytes.
fn get_frame(addr: &str, path: &str) -> (u16, Option<u64>, Vec<u8>) {
    let (status, head, body) = http_with_head(addr, "GET", path, None);
    let seq = head.lines().find_map(|l| {
        let (k, v) = l.split_once(':')?;
        k.eq_ignore_ascii_case("x-frame-seq").then(|| v.trim().parse().unwrap())
    });
    (status, seq, body)
}

/// [`http`], with the response's head (status line and headers) as text.
fn http_with_head(
    addr: &str,
    method: &str,
    path: &str,
    body: Option<&[u8]>,
) -> (u16, String, Vec<u8>) {
    let mut c = TcpStream::connect(addr).unwrap();
    c.set_read_timeout(Some(Duration::from_secs(60))).unwrap();
    let mut req = format!("{method} {path} HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n");
    if let Some(b) = body {
        req.push_str(&format!("Content-Type: application/json\r\nContent-Length: {}\r\n", b.len()));
    }
    req.push_str("\r\n");
    c.write_all(req.as_bytes()).unwrap();
    if let Some(b) = body {
        // The server may answer (413) and close before reading all of a large body.
        let _ = c.write_all(b);
    }
    raw_response(c)
}

fn raw_response(mut c: TcpStream) -> (u16, String, Vec<u8>) {
    let mut all = Vec::new();
    let _ = c.read_to_end(&mut all);
    let end = all
        .windows(4)
        .position(|w| w == b"\r\n\r\n")
        .unwrap_or_else(|| panic!("no response head in {:?}", String::from_utf8_lossy(&all)));
    let head = String::from_utf8_lossy(&all[..end]).to_string();
    let status = head
        .split_whitespace()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or_else(|| panic!("bad status line in {head:?}"));
    let body = all[end + 4..].to_vec();
    if head.to_ascii_lowercase().contains("transfer-encoding: chunked") {
        return (status, head, unchunk(&body));
    }
    (status, head, body)
}

fn unchunk(mut b: &[u8]) -> Vec<u8> {
    let mut out = Vec::new();
    loop {
        let nl = b.windows(2).position(|w| w == b"\r\n").unwrap();
        let n = usize::from_str_radix(std::str::from_utf8(&b[..nl]).unwrap().trim(), 16).unwrap();
        if n == 0 {
            return out;
        }
        out.extend_from_slice(&b[nl + 2..nl + 2 + n]);
        b = &b[nl + 4 + n..];
    }
}

/// A JSON answer with `want` status.
pub fn json(addr: &str, method: &str, path: &str, body: Option<&str>, want: u16) -> Value {
    let (st, b) = http(addr, method, path, body.map(str::as_bytes));
    let text = String::from_utf8_lossy(&b).to_string();
    assert_eq!(st, want, "{method} {path} {body:?}: {text}");
    serde_json::from_str(&text).unwrap_or_else(|e| panic!("{method} {path}: {e}: {text}"))
}

/// What `hvs locate --at u,v` prints for the fixture's pair.
fn locate_at(u: i64, v: i64) -> String {
    let f = fixture();
    let at = format!("{u},{v}");
    ok(&crate::common::locate_args(&["locate"], &f.model, &f.left, &f.right, &["--at", &at]))
        .trim()
        .to_string()
}

#[test]
fn view_answers_a_click_with_the_numbers_of_locate_at() {
    let f = fixture();
    let sv = start_pair();
    let (st, page) = http(&sv.addr, "GET", "/", None);
    assert_eq!(st, 200);
    let page = String::from_utf8(page).unwrap();
    assert!(page.contains("<title>hvs view</title>") && page.contains("app.js"), "{page}");
    for asset in ["/app.js", "/style.css"] {
        let (st, b) = http(&sv.addr, "GET", asset, None);
        assert_eq!(st, 200, "{asset}");
        assert!(b.len() > 500, "{asset}");
    }
    // The model panel is `hvs info`'s text.
    let session = json(&sv.addr, "GET", "/api/session", None, 200);
    assert_eq!(session["model"]["info"].as_str().unwrap(), ok(&["info", s(&f.model)]));
    assert_eq!(session["pairs"].as_array().unwrap().len(), 1);
    assert_eq!(session["live"], false);
    assert!(session["locate_refused"].is_null());
    // Frames are the images, as PNG.
    for side in ["left", "right"] {
        let (st, png) = http(&sv.addr, "GET", &format!("/api/frame/0/{side}"), None);
        assert_eq!(st, 200);
        let img = image::load_from_memory(&png).unwrap().to_luma8();
        let file = image::open(if side == "left" { &f.left } else { &f.right }).unwrap().to_luma8();
        assert_eq!(img, file, "{side}");
    }
    // Clicks on board corners and on a flat corner of the image: the same line as `hvs
    // locate --at`, and the fields are its numbers.
    let mut oks = 0;
    let picks: Vec<[i64; 2]> = f.corners.iter().step_by(7).copied().chain([[3, 3]]).collect();
    for [u, v] in picks {
        let r = json(
            &sv.addr,
            "POST",
            "/api/locate",
            Some(&format!(r#"{{"pair":0,"u":{u},"v":{v}}}"#)),
            200,
        );
        let line = locate_at(u, v);
        assert_eq!(r["line"].as_str().unwrap(), line, "at {u},{v}");
        assert_eq!((r["u"].as_f64(), r["v"].as_f64()), (Some(u as f64), Some(v as f64)));
        if r["status"] == "ok" {
            oks += 1;
            let want = format!(
                "u_r={} v_r={} x={} y={} z={} cm (score {})",
                r["u_r"].as_str().unwrap(),
                r["v_r"].as_str().unwrap(),
                r["x"].as_str().unwrap(),
                r["y"].as_str().unwrap(),
                r["z"].as_str().unwrap(),
                r["score"].as_str().unwrap()
            );
            assert_eq!(want, line);
            let z: f64 = r["z"].as_str().unwrap().parse().unwrap();
            assert!((z - 95.0).abs() < 1.0, "{r}");
        } else {
            assert!(r["z"].is_null(), "{r}");
            assert_eq!(line, format!("no trustworthy match: {}", r["status"].as_str().unwrap()));
        }
    }
    assert!(oks >= 4, "{oks} board corners located");
}

/// The depth overlay is `hvs depth --thorough --colour` of the pair (the matches a click is
/// answered from, as `hvs locate` answers), pixel for pixel, with its counts;
/// a pair that does not exist is refused.
#[test]
fn view_shows_the_depth_of_the_pair_as_hvs_depth_colours_it() {
    let f = fixture();
    let sv = start_pair();
    let d = json(&sv.addr, "GET", "/api/depth/0", None, 200);
    let (w, h) = image::image_dimensions(&f.left).unwrap();
    assert_eq!(d["pixels"].as_u64(), Some(u64::from(w * h)), "{d}");
    // The board is the textured part of the rendered pair: a few percent of the pixels.
    let returned = d["returned"].as_u64().unwrap();
    assert!(returned > 5000, "{d}");
    let (st, png) = http(&sv.addr, "GET", "/api/depth/0/image", None);
    assert_eq!(st, 200);
    let shown = image::load_from_memory(&png).unwrap().to_rgb8();
    let dir = tempfile::tempdir().unwrap();
    let (pfm, colour) = (dir.path().join("d.pfm"), dir.path().join("d.png"));
    let ply = dir.path().join("d.ply");
    let out = crate::common::hvs()
        .args(crate::common::locate_args(
            &["depth"],
            &f.model,
            &f.left,
            &f.right,
            &["-o", s(&pfm), "--colour", s(&colour), "--ply", s(&ply), "--thorough"],
        ))
        .output()
        .unwrap();
    let said = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{said}");
    assert!(said.contains(&format!("{returned} of {} pixels", w * h)), "{said}");
    // The page's line is the command's.
    let summary = d["summary"].as_str().unwrap();
    assert!(said.starts_with(&format!("{summary}; ")), "{summary} / {said}");
    assert_eq!(shown, image::open(&colour).unwrap().to_rgb8());
    // The 3-D view's cloud: the bytes of `hvs depth --thorough --ply`.
    let (st, cloud) = http(&sv.addr, "GET", "/api/depth/0/cloud.ply", None);
    assert_eq!(st, 200);
    assert!(
        cloud == std::fs::read(&ply).unwrap(),
        "the cloud differs from hvs depth --thorough --ply"
    );
    // Asked again: the same map, kept.
    assert_eq!(json(&sv.addr, "GET", "/api/depth/0", None, 200)["returned"], returned);
    // No such pair: not found, as its frames.
    for path in ["/api/depth/1", "/api/depth/1/image", "/api/depth/1/cloud.ply"] {
        assert_eq!(http(&sv.addr, "GET", path, None).0, 404, "{path}");
    }
    assert_eq!(http(&sv.addr, "GET", "/api/depth/x", None).0, 400);
}

/// Polls `GET /api/head` until `done` holds (60 s at most); the last state.
pub fn head_until(addr: &str, what: &str, done: impl Fn(&Value) -> bool) -> Value {
    let t0 = Instant::now();
    loop {
        let h = json(addr, "GET", "/api/head", None, 200);
        if done(&h) {
            return h;
        }
        assert!(t0.elapsed() < Duration::from_secs(60), "waited 60 s for {what}: {h}");
        std::thread::sleep(Duration::from_millis(100));
    }
}

/// `POST /api/look` with `body`, answered with `want`.
pub fn look(addr: &str, body: &str, want: u16) -> Value {
    json(addr, "POST", "/api/look", Some(body), want)
}

pub fn joints_at_home(h: &Value) -> bool {
    h["joints"].as_object().unwrap().values().all(|v| v.as_f64() == Some(0.0))
}

/// `hvs view --scene`: the virtual head runs live (frames keep coming, the state is served),
/// looks at the nearest object when asked (the joints leave home) and goes home again; bad
/// look requests are refused and a still source has no head.
#[test]
fn view_runs_the_virtual_head_live_and_looks_where_asked() {
    let (_dir, sv) = start_live(&["--seed", "3"]);
    let session = json(&sv.addr, "GET", "/api/session", None, 200);
    assert_eq!((&session["live"], &session["head"]), (&json!(true), &json!(true)));
    let first = json(&sv.addr, "GET", "/api/head", None, 200);
    assert_eq!(first["status"], "idle", "{first}");
    assert!(joints_at_home(&first), "{first}");
    // Frames keep coming: the head's frame count and the frames' sequence numbers grow.
    let n0 = first["frames"].as_u64().unwrap();
    head_until(&sv.addr, "more frames", |h| h["frames"].as_u64().unwrap() > n0 + 2);
    let (st, png) = http(&sv.addr, "GET", "/api/frame/0/left", None);
    assert_eq!(st, 200);
    let img = image::load_from_memory(&png).unwrap();
    assert_eq!((img.width(), img.height()), (160, 120));
    // `after=S` waits for a frame newer than S; `seq=S` gives the other image of pair S.
    let (st, s0, _) = get_frame(&sv.addr, "/api/frame/0/left");
    let s0 = s0.expect("a live frame has a number");
    assert!(st == 200 && s0 > 0);
    let (st, s1, left) = get_frame(&sv.addr, &format!("/api/frame/0/left?after={s0}&n=7"));
    let s1 = s1.unwrap();
    assert!(st == 200 && s1 > s0, "{s0} -> {s1}");
    let (st, s2, right) = get_frame(&sv.addr, &format!("/api/frame/0/right?seq={s1}"));
    assert_eq!((st, s2), (200, Some(s1)));
    assert_ne!(left, right, "the left and the right image of the pair");
    // A frame the head no longer keeps (0: none has that number) or has not taken yet is
    // not another frame's image: 404, naming it and the frames kept.
    for gone in [0, 999_999] {
        let (st, seq, body) = get_frame(&sv.addr, &format!("/api/frame/0/right?seq={gone}"));
        let text = String::from_utf8_lossy(&body).into_owned();
        assert_eq!((st, seq), (404, None), "seq={gone}: {text}");
        let v: Value = serde_json::from_str(&text).expect("a JSON error");
        let e = v["error"].as_str().unwrap();
        assert!(e.contains(&format!("frame {gone} ")) && e.contains("keeps frames"), "{e}");
    }
    for q in ["after=-1", "after=x", "seq=1.5", "after="] {
        let (st, _, body) = get_frame(&sv.addr, &format!("/api/frame/0/left?{q}"));
        assert_eq!(st, 400, "{q}: {}", String::from_utf8_lossy(&body));
        assert!(String::from_utf8_lossy(&body).contains("not a frame number"), "{q}");
    }
    // Look at the nearest object: the loop runs and the joints leave home.
    look(&sv.addr, r#"{"target":"nearest"}"#, 200);
    let h = head_until(&sv.addr, "the head to turn", |h| !joints_at_home(h));
    assert_eq!(h["goal"]["target"], "nearest", "{h}");
    assert!(["tracking", "image_only", "lost"].contains(&h["status"].as_str().unwrap()), "{h}");
    // Home again.
    look(&sv.addr, r#"{"target":"home"}"#, 200);
    head_until(&sv.addr, "the head at home", |h| {
        joints_at_home(h) && h["moving"] == false && h["status"] == "idle"
    });
    look(&sv.addr, r#"{"target":"pixel","u":100,"v":50}"#, 200);
    for (body, want) in [
        (r#"{"target":"pixel","u":1000,"v":5}"#, 400),
        (r#"{"target":"pixel","u":5}"#, 422),
        (r#"{"target":"fly"}"#, 422),
        (r#"{"target":"home","x":1}"#, 422),
    ] {
        let (st, b) = http(&sv.addr, "POST", "/api/look", Some(body.as_bytes()));
        assert_eq!(st, want, "{body}");
        let v: serde_json::Value = serde_json::from_slice(&b).expect("a JSON error");
        assert!(v["error"].is_string(), "{v}");
    }
    drop(sv);
    // A still pair has no head.
    let sv = start_pair();
    json(&sv.addr, "GET", "/api/head", None, 404);
    look(&sv.addr, r#"{"target":"home"}"#, 400);
}

/// Every request in `bad` gets its 4xx; the server answers normally after each.
#[test]
fn view_refuses_bad_requests_and_stays_up() {
    let sv = start_pair();
    let big = format!(r#"{{"pair":0,"u":1,"v":1,"pad":"{}"}}"#, "x".repeat(200_000));
    // Bodies of `POST /api/locate`: malformed JSON (400), wrong fields (422), bad values (400).
    let locates: [(&str, u16); 9] = [
        ("{not json", 400),
        (r#"{"pair":0,"u":"a","v":1}"#, 422),
        (r#"{"pair":0,"u":1}"#, 422),
        (r#"{"pair":0,"u":1,"v":2,"w":3}"#, 422),
        (r#"{"pair":-1,"u":1,"v":2}"#, 422),
        (r#"{"pair":0,"u":1e999,"v":2}"#, 400),
        (r#"{"pair":0,"u":-5,"v":2}"#, 400),
        (r#"{"pair":0,"u":100000,"v":2}"#, 400),
        (r#"{"pair":3,"u":1,"v":2}"#, 404),
    ];
    let mut bad: Vec<(&str, &str, Option<&str>, u16)> =
        locates.iter().map(|&(body, code)| ("POST", "/api/locate", Some(body), code)).collect();
    bad.extend([
        ("POST", "/api/locate", Some(big.as_str()), 413),
        ("GET", "/api/locate", None, 405),
        ("POST", "/api/retrain", Some(r#"{"use":[true]}"#), 400),
        ("POST", "/api/retrain", Some("{}"), 400),
        ("GET", "/api/depth/3", None, 404),
        ("GET", "/api/captures", None, 404),
        ("GET", "/api/frame/1/left", None, 404),
        ("GET", "/api/frame/0/top", None, 404),
        ("GET", "/api/frame/x/left", None, 400),
        ("GET", "/api/frame/0/..%2f..%2fCargo.toml", None, 404),
        ("GET", "/../../Cargo.toml", None, 404),
        ("GET", "/etc/passwd", None, 404),
        ("GET", "/app.js/../../Cargo.toml", None, 404),
    ]);
    for (method, path, body, want) in bad {
        let (st, b) = http(&sv.addr, method, path, body.map(str::as_bytes));
        let text = String::from_utf8_lossy(&b);
        assert_eq!(st, want, "{method} {path}: {}", &text[..text.len().min(300)]);
        assert!(!text.contains("[package]") && !text.contains("root:"), "{path}");
        // A refused body, however it is wrong, is a one-line JSON error like the rest.
        if method == "POST" {
            let v: serde_json::Value = serde_json::from_slice(&b)
                .unwrap_or_else(|e| panic!("{path} {body:?}: not JSON ({e}): {text}"));
            let e = v["error"].as_str().unwrap_or_else(|| panic!("{text}"));
            assert!(!e.is_empty() && !e.contains('\n'), "{e}");
        }
        json(&sv.addr, "GET", "/api/session", None, 200);
    }
    // An unknown pair is not found wherever it is named; a still pair is no capture set,
    // whatever the retrain's body.
    for (method, path, body) in [
        ("POST", "/api/locate", Some(r#"{"pair":3,"u":1,"v":2}"#)),
        ("GET", "/api/depth/3", None),
        ("GET", "/api/frame/3/left", None),
    ] {
        let e = json(&sv.addr, method, path, body, 404);
        assert!(e["error"].as_str().is_some_and(|m| m.contains("pair 3: no such pair")), "{e}");
    }
    for body in ["{}", r#"{"use":[true]}"#, "[]"] {
        let e = json(&sv.addr, "POST", "/api/retrain", Some(body), 400);
        assert!(e["error"].as_str().is_some_and(|m| m.starts_with("not a capture set")), "{e}");
    }
    // Not HTTP at all.
    let mut c = TcpStream::connect(&sv.addr).unwrap();
    c.write_all(b"\x00\x01garbage\r\n\r\n").unwrap();
    let (st, _, _) = raw_response(c);
    assert_eq!(st, 400);
    // A body sent without a JSON content type.
    let mut c = TcpStream::connect(&sv.addr).unwrap();
    c.write_all(
        b"POST /api/locate HTTP/1.1\r\nHost: x\r\nConnection: close\r\nContent-Length: 2\r\n\r\n{}",
    )
    .unwrap();
    assert_eq!(raw_response(c).0, 415);
    // A malformed path parameter and a method the path does not serve: JSON errors too.
    let e = json(&sv.addr, "GET", "/api/frame/-1/left", None, 400);
    assert!(e["error"].as_str().is_some_and(|m| m.contains("-1")), "{e}");
    json(&sv.addr, "GET", "/api/locate", None, 405);
    json(&sv.addr, "GET", "/api/session", None, 200);
}

#[test]
fn view_needs_the_token_off_loopback() {
    let sv = start_pair_with(&["--listen", "0.0.0.0:0"]);
    let token = sv.url.split("?token=").nth(1).expect("a token in the URL").to_string();
    assert_eq!(token.len(), 32);
    assert!(token.bytes().all(|b| b.is_ascii_hexdigit()), "{token}");
    for path in ["/", "/app.js", "/api/session", "/api/frame/0/left"] {
        assert_eq!(http(&sv.addr, "GET", path, None).0, 403, "{path} without a token");
        let wrong = format!("{path}?token={}", "0".repeat(32));
        assert_eq!(http(&sv.addr, "GET", &wrong, None).0, 403, "{path} with a wrong token");
        let right = format!("{path}?token={token}");
        assert_eq!(http(&sv.addr, "GET", &right, None).0, 200, "{path} with the token");
    }
    // The page asks for its stylesheet and script with the token (a browser does not pass the
    // page's query on to them).
    let page = http(&sv.addr, "GET", &format!("/?token={token}"), None).1;
    let page = String::from_utf8_lossy(&page);
    for asset in ["style.css", "app.js"] {
        assert!(page.contains(&format!("{asset}?token={token}\"")), "{asset} in:\n{page}");
    }
    let body = r#"{"pair":0,"u":3,"v":3}"#;
    assert_eq!(http(&sv.addr, "POST", "/api/locate", Some(body.as_bytes())).0, 403);
    json(&sv.addr, "POST", &format!("/api/locate?token={token}"), Some(body), 200);
    // Another start, another token; loopback needs none.
    let again = start_pair_with(&["--listen", "0.0.0.0:0"]);
    assert!(!again.url.contains(&token));
    let local = start_pair();
    assert!(!local.url.contains("token"), "{}", local.url);
}

#[test]
fn view_retrains_a_capture_set_on_the_ticked_pairs() {
    let sv = start_captures();
    let retrain =
        |ticks: &str, want: u16| json(&sv.addr, "POST", "/api/retrain", Some(ticks), want);
    let session = json(&sv.addr, "GET", "/api/session", None, 200);
    assert_eq!(session["captures"], true);
    let c = json(&sv.addr, "GET", "/api/captures", None, 200);
    let pairs = c["pairs"].as_array().unwrap();
    assert_eq!(pairs.len(), 3);
    for p in pairs {
        assert_eq!(p["found"], true, "{p}");
        assert_eq!(p["corners"], 54);
        let h = p["homography_rms_px"].as_array().unwrap();
        assert!(h.iter().all(|v| v.as_f64().unwrap() < 0.5), "{p}");
        assert!(p["epipolar"]["median_px"].as_f64().unwrap() < 0.5, "{p}");
    }
    assert!(c["sampson_rms_px"].as_f64().unwrap() < 0.5);
    // The check in words, as `hvs board detect` says it.
    let f = c["fundamental"].as_str().unwrap();
    assert!(f.starts_with("one fundamental matrix over all: Sampson rms 0."), "{f}");
    // The corners drawn on a pair.
    let (st, png) = http(&sv.addr, "GET", "/api/frame/1/left-corners", None);
    assert_eq!(st, 200);
    let drawn = image::load_from_memory(&png).unwrap().to_rgb8();
    assert!(drawn.pixels().any(|p| p[0] != p[1] || p[1] != p[2]), "colour marks drawn");
    let all = retrain(r#"{"use":[true,true,true]}"#, 200);
    assert_eq!((all["pairs"].as_u64(), all["points"].as_u64()), (Some(3), Some(162)));
    let two = retrain(r#"{"use":[true,false,true]}"#, 200);
    assert_eq!((two["pairs"].as_u64(), two["points"].as_u64()), (Some(2), Some(108)));
    let (s3, s2) = (all["summary"].as_str().unwrap(), two["summary"].as_str().unwrap());
    assert!(s3.contains("on 162 points") && s2.contains("on 108 points"), "{s3}\n{s2}");
    assert_ne!(all["train_error_pct"], two["train_error_pct"]);
    // The same ticks, the same summary numbers (seeded).
    let again = retrain(r#"{"use":[true,false,true]}"#, 200);
    assert_eq!(again["train_error_pct"], two["train_error_pct"]);
    retrain(r#"{"use":[true]}"#, 400);
    retrain(r#"{"use":[false,false,false]}"#, 422);
    // Clicks work on a capture pair too.
    let r = json(&sv.addr, "POST", "/api/locate", Some(r#"{"pair":2,"u":3,"v":3}"#), 200);
    assert!(r["line"].as_str().is_some());
}

#[test]
fn view_names_bad_inputs_and_stops_on_ctrl_c() {
    let f = fixture();
    let view = |rest: &[&'static str]| -> Vec<String> {
        let mut v = vec!["view".to_string(), "--model".into(), s(&f.model).into()];
        v.extend(rest.iter().map(|a| a.to_string()));
        v
    };
    let (l, r) = (s(&f.left).to_string(), s(&f.right).to_string());
    let missing = s(&f.shots.join("nope.png")).to_string();
    let with = |mut v: Vec<String>, more: &[&str]| -> Vec<String> {
        v.extend(more.iter().map(|a| a.to_string()));
        v
    };
    let err = crate::common::stderr_with_code(
        with(view(&[]), &["--left", &missing, "--right", &r, "--listen", "127.0.0.1:0"]),
        1,
    );
    assert!(err.starts_with("error: ") && err.contains("nope.png"), "{err}");
    let err = crate::common::stderr_with_code(
        with(view(&[]), &["--left", &l, "--right", &r, "--listen", "here"]),
        2,
    );
    assert!(err.contains("--listen"), "{err}");
    hvs().args(view(&[])).assert().code(2);
    // A scene with a still pair is bad usage; a bad scene file is named.
    let scene = f.shots.join("scene.json");
    std::fs::write(&scene, r#"{"rig": {"case": 1}, "camera_fps": 30, "objects": [], "wall": 1}"#)
        .unwrap();
    let sc = with(view(&[]), &["--scene", s(&scene)]);
    crate::common::stderr_with_code(with(sc.clone(), &["--left", &l, "--right", &r]), 2);
    let err = crate::common::stderr_with_code(with(sc.clone(), &["--head", "qemu"]), 1);
    assert!(err.contains("scene.json") && err.contains("wall"), "{err}");
    let err = crate::common::stderr_with_code(sc, 1);
    assert!(err.contains("scene.json") && err.contains("wall"), "{err}");
    // A scene whose cameras make images of another size than the model's: refused at the
    // start (every click and depth would be), naming both.
    let dir = crate::common::Scratch::new();
    let small = crate::common::small_scene(&dir, "");
    let err = crate::common::stderr_with_code(with(view(&[]), &["--scene", &small]), 1);
    assert!(err.contains("scene.json with") && err.contains("the images are 160x120"), "{err}");
    // The QEMU head with a firmware that is not there: named, before QEMU is started.
    let good = dir.p("case1.json");
    std::fs::write(&good, r#"{"rig": {"case": 1}, "camera_fps": 30, "background": {"z_cm": 300, "texture_seed": 1}, "objects": []}"#).unwrap();
    let none = dir.p("none.elf");
    let qemu = with(view(&[]), &["--scene", &good, "--head", "qemu", "--firmware", &none]);
    let err = crate::common::stderr_with_code(qemu, 1);
    assert!(err.contains("none.elf"), "{err}");
    // Real cameras: a bad spec or size is bad usage; a port needs cameras; a build without
    // the v4l feature says how to get one, a build with it names the missing device.
    let cams = |more: &[&str]| with(view(&["--listen", "127.0.0.1:0"]), more);
    let err = crate::common::stderr_with_code(cams(&["--cameras", "v4l:3,3"]), 2);
    assert!(err.contains("the same device (/dev/video3)"), "{err}");
    let size = ["--cameras", "v4l:/nonexistent/l,/nonexistent/r", "--camera-size", "640"];
    let err = crate::common::stderr_with_code(cams(&size), 2);
    assert!(err.contains("--camera-size"), "{err}");
    // A head's port with the cameras: the cameras (not there) or the port (not there) named.
    let head = ["--cameras", "v4l:/nonexistent/l,/nonexistent/r", "--port", "/dev/hvs-no-port"];
    let err = crate::common::stderr_with_code(cams(&head), 1);
    assert!(
        err.contains("built without V4L2 cameras")
            || err.contains("/nonexistent/l")
            || err.contains("/dev/hvs-no-port"),
        "{err}"
    );
    crate::common::stderr_with_code(cams(&["--port", "/dev/hvs-no-port"]), 2);
    crate::common::stderr_with_code(cams(&["--cameras", "v4l:0,2", "--left", &l]), 2);
    let err = crate::common::stderr_with_code(cams(&size[..2]), 1);
    assert!(err.contains("built without V4L2 cameras") || err.contains("/nonexistent/l"), "{err}");
    // SIGINT stops it at once, even with a client connected.
    let mut sv = start_pair();
    let _idle = TcpStream::connect(&sv.addr).unwrap();
    let t0 = Instant::now();
    unsafe { libc::kill(sv.child.id() as i32, libc::SIGINT) };
    loop {
        if let Some(st) = sv.child.try_wait().unwrap() {
            assert!(st.success(), "{st:?}");
            break;
        }
        assert!(t0.elapsed() < Duration::from_secs(3), "still running after SIGINT");
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// Measurement, not a check of speed: click-to-answer latency over HTTP and 20 clients
/// polling frames (`HVS_VIEW_LOAD_SECS`, default 60 s), with the server's memory.
/// `cargo test --release -p hvs-host --test cli load_view -- --ignored --nocapture`
#[test]
#[ignore]
fn load_view_click_latency_and_20_polling_clients() {
    let f = fixture();
    let sv = start_pair();
    let mut ms = Vec::new();
    for (k, [u, v]) in f.corners.iter().cycle().take(100).enumerate() {
        let body = format!(r#"{{"pair":0,"u":{},"v":{}}}"#, u + (k as i64 % 3), v);
        let t0 = Instant::now();
        json(&sv.addr, "POST", "/api/locate", Some(&body), 200);
        ms.push(t0.elapsed().as_secs_f64() * 1e3);
    }
    ms.sort_by(f64::total_cmp);
    println!(
        "click to answer over HTTP (100 clicks): median {:.2} ms, 95th percentile {:.2} ms, max {:.2} ms",
        ms[50], ms[95], ms[99]
    );
    poll_load(&sv, "");
}

/// 20 clients polling both frames (and `/api/head` when `head`) of `sv` for
/// `HVS_VIEW_LOAD_SECS` (60) s: their pair rates and the server's memory, printed.
fn poll_load(sv: &Server, what: &str) {
    let secs: u64 =
        std::env::var("HVS_VIEW_LOAD_SECS").ok().and_then(|v| v.parse().ok()).unwrap_or(60);
    let rss = || {
        let st = std::fs::read_to_string(format!("/proc/{}/status", sv.child.id())).unwrap();
        st.lines().find_map(|l| l.strip_prefix("VmRSS:")).map(|v| v.trim().to_string()).unwrap()
    };
    println!("server memory before: {}", rss());
    let head = !what.is_empty();
    let head_frames = || json(&sv.addr, "GET", "/api/head", None, 200)["frames"].as_u64().unwrap();
    let f0 = if head { head_frames() } else { 0 };
    let end = Instant::now() + Duration::from_secs(secs);
    let clients: Vec<_> = (0..20)
        .map(|_| {
            let addr = sv.addr.clone();
            std::thread::spawn(move || {
                let mut frames = 0u64;
                while Instant::now() < end {
                    for side in ["left", "right"] {
                        let (st, b) = http(&addr, "GET", &format!("/api/frame/0/{side}"), None);
                        assert!(st == 200 && b.len() > 1000);
                    }
                    if head {
                        assert_eq!(http(&addr, "GET", "/api/head", None).0, 200);
                    }
                    frames += 1;
                }
                frames
            })
        })
        .collect();
    let mut mid = String::new();
    std::thread::sleep(Duration::from_secs(secs / 2));
    mid.push_str(&rss());
    let frames: Vec<u64> = clients.into_iter().map(|c| c.join().unwrap()).collect();
    let rates: Vec<f64> = frames.iter().map(|&n| n as f64 / secs as f64).collect();
    let min = rates.iter().copied().fold(f64::INFINITY, f64::min);
    let mean = rates.iter().sum::<f64>() / rates.len() as f64;
    println!(
        "20 clients polling both frames{} for {secs} s: {:.1} to {:.1} pairs/s per client (mean {mean:.1}); memory at half time {mid}, at the end {}",
        if head { " and the head" } else { "" },
        min,
        rates.iter().copied().fold(0.0, f64::max),
        rss()
    );
    if head {
        println!(
            "{what}: the head grabbed {:.1} frames/s meanwhile",
            (head_frames() - f0) as f64 / secs as f64
        );
    }
}

/// The same load on the live virtual head (the small rig's scene) while it follows the
/// nearest object: `cargo test --release -p hvs-host --test cli load_live -- --ignored
/// --nocapture`.
#[test]
#[ignore]
fn load_live_view_20_polling_clients() {
    let (_dir, sv) = start_live(&[]);
    look(&sv.addr, r#"{"target":"nearest"}"#, 200);
    poll_load(&sv, "the live head following the nearest object");
}

/// Where the browser test leaves its screenshots.
fn screenshot_dir() -> PathBuf {
    let d = Path::new(env!("CARGO_MANIFEST_DIR")).join("../target/view-screenshots");
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// A chromedriver started on a free port, killed when dropped.
struct Driver {
    child: Child,
    url: String,
    _profile: tempfile::TempDir,
}

impl Drop for Driver {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

fn chromedriver() -> Driver {
    let port = std::net::TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port();
    let child = Command::new("/usr/bin/chromedriver")
        .arg(format!("--port={port}"))
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("/usr/bin/chromedriver (apt-get install chromium chromium-driver)");
    let t0 = Instant::now();
    while TcpStream::connect(("127.0.0.1", port)).is_err() {
        assert!(t0.elapsed() < Duration::from_secs(20), "chromedriver does not listen");
        std::thread::sleep(Duration::from_millis(50));
    }
    Driver {
        child,
        url: format!("http://127.0.0.1:{port}"),
        _profile: tempfile::tempdir().unwrap(),
    }
}

async fn browser(d: &Driver) -> fantoccini::Client {
    let profile = format!("--user-data-dir={}", d._profile.path().display());
    let args = [
        "--headless",
        "--no-sandbox",
        "--disable-gpu",
        "--disable-quic",
        "--no-first-run",
        "--disable-background-networking",
        "--disable-component-update",
        "--disable-sync",
        "--window-size=1400,1000",
        profile.as_str(),
    ];
    let mut caps = serde_json::Map::new();
    caps.insert(
        "goog:chromeOptions".into(),
        serde_json::json!({"binary": "/usr/bin/chromium", "args": args}),
    );
    fantoccini::ClientBuilder::new(hyper_util::client::legacy::connect::HttpConnector::new())
        .capabilities(caps)
        .connect(&d.url)
        .await
        .expect("a chromium session")
}

/// Polls `js` (an expression) until it is truthy; returns its value.
async fn wait_js(c: &fantoccini::Client, js: &str) -> Value {
    let t0 = Instant::now();
    loop {
        let v = c.execute(&format!("return {js};"), vec![]).await.unwrap();
        if !(v.is_null() || v == false || v == "" || v == 0) {
            return v;
        }
        if t0.elapsed() > Duration::from_secs(60) {
            let page = c
                .execute("return document.body.innerText;", vec![])
                .await
                .map(|v| v.as_str().unwrap_or_default().chars().take(3000).collect())
                .unwrap_or_else(|e| format!("(no page text: {e})"));
            panic!("waited 60 s for {js}; the page said:\n{page}");
        }
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
}

async fn text(c: &fantoccini::Client, id: &str) -> String {
    c.find(fantoccini::Locator::Id(id)).await.unwrap().text().await.unwrap()
}

async fn shot(c: &fantoccini::Client, name: &str) {
    let png = c.screenshot().await.unwrap();
    let p = screenshot_dir().join(name);
    std::fs::write(&p, png).unwrap();
    eprintln!("screenshot: {}", p.display());
}

/// Clicks the element with id `id`.
async fn click_id(c: &fantoccini::Client, id: &str) {
    c.find(fantoccini::Locator::Id(id)).await.unwrap().click().await.unwrap();
}

/// Clicks the left image at pixel `(u, v)` (shown at its natural size) with the mouse.
async fn click_left(c: &fantoccini::Client, u: i64, v: i64) {
    use fantoccini::actions::{InputSource, MouseActions, PointerAction, MOUSE_BUTTON_LEFT};
    let img = c.find(fantoccini::Locator::Id("left")).await.unwrap();
    let size = c
        .execute(
            "const i = document.getElementById('left'); return [i.naturalWidth, i.naturalHeight, i.clientWidth, i.clientHeight];",
            vec![],
        )
        .await
        .unwrap();
    let n: Vec<f64> = size.as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect();
    assert_eq!((n[0], n[1]), (n[2], n[3]), "the left image is shown at its natural size");
    let mouse = MouseActions::new("mouse".into())
        .then(PointerAction::MoveToElement {
            element: img,
            duration: None,
            x: (u as f64 + 0.5 - n[0] / 2.0).round(),
            y: (v as f64 + 0.5 - n[1] / 2.0).round(),
        })
        .then(PointerAction::Down { button: MOUSE_BUTTON_LEFT })
        .then(PointerAction::Up { button: MOUSE_BUTTON_LEFT });
    c.perform_actions(mouse).await.unwrap();
}

/// The real browser: frames shown, a click answered with `hvs locate --at`'s numbers, and a
/// capture set's summary changed by unticking a pair. Screenshots in target/view-screenshots/.
#[test]
#[ignore]
fn browser_click_and_retrain_in_chromium() {
    let f = fixture();
    let driver = chromedriver();
    let rt = tokio::runtime::Runtime::new().unwrap();
    rt.block_on(async {
        let c = browser(&driver).await;
        // A still pair: frames, then clicks on three board corners.
        let sv = start_pair();
        c.goto(&sv.url).await.unwrap();
        wait_js(&c, "document.getElementById('frames-status').dataset.loaded").await;
        wait_js(&c, "document.getElementById('left').naturalWidth > 0 && document.getElementById('right').naturalWidth > 0").await;
        assert!(text(&c, "model-info").await.contains("topology:"));
        let mut oks = 0;
        for (k, &[u, v]) in f.corners.iter().step_by(11).take(3).enumerate() {
            click_left(&c, u, v).await;
            wait_js(&c, &format!("Number(document.getElementById('point').dataset.answered || 0) >= {}", k + 1)).await;
            // The pixel the page asked for (WebDriver moves the mouse by whole CSS pixels
            // from the element's centre): within a pixel of the one aimed at.
            let at = text(&c, "at").await;
            let (pu, pv) = at.split_once(',').unwrap();
            let (pu, pv): (i64, i64) = (pu.parse().unwrap(), pv.parse().unwrap());
            assert!((pu - u).abs() <= 1 && (pv - v).abs() <= 1, "aimed at {u},{v}, the page asked for {at}");
            let line = locate_at(pu, pv);
            assert_eq!(text(&c, "line").await, line);
            let status = text(&c, "status").await;
            if status == "ok" {
                oks += 1;
                let shown = format!(
                    "u_r={} v_r={} x={} y={} z={} cm (score {})",
                    text(&c, "u_r").await,
                    text(&c, "v_r").await,
                    text(&c, "x").await,
                    text(&c, "y").await,
                    text(&c, "z").await,
                    text(&c, "score").await
                );
                assert_eq!(shown, line, "X, Y, Z read off the page");
            }
            eprintln!("clicked {at}: {line}; {}", text(&c, "ms").await);
        }
        assert!(oks >= 2, "{oks} of 3 corners located");
        shot(&c, "pair-click.png").await;
        // The depth overlay: every pixel matched, the map shown with its counts.
        click_id(&c, "show-depth").await;
        wait_js(&c, "document.getElementById('depth').dataset.loaded").await;
        let status = text(&c, "depth-status").await;
        // `Depth::summary`, the line `hvs depth` prints, then the depth box and the time.
        assert!(status.contains(" pixels (") && status.contains("%) with a depth"), "{status}");
        eprintln!("depth: {status}");
        shot(&c, "pair-depth.png").await;
        // The 3-D view: the cloud of every pixel with a depth, drawn; a drag turns it.
        click_id(&c, "show-cloud").await;
        let points = wait_js(&c, "document.getElementById('cloud').dataset.points").await;
        let returned = status.split(' ').next().unwrap();
        assert_eq!(points.as_str().unwrap(), returned, "the cloud holds the depth's points");
        let drawn = wait_js(&c, "Number(document.getElementById('cloud').dataset.drawn)").await;
        assert!(drawn.as_f64().unwrap() > 1000.0, "{drawn} points drawn");
        {
            use fantoccini::actions::{InputSource, MouseActions, PointerAction, MOUSE_BUTTON_LEFT};
            let canvas = c.find(fantoccini::Locator::Id("cloud")).await.unwrap();
            let before = c.execute("return document.getElementById('cloud').toDataURL();", vec![]).await.unwrap();
            let drag = MouseActions::new("mouse".into())
                .then(PointerAction::MoveToElement { element: canvas, duration: None, x: 0.0, y: 0.0 })
                .then(PointerAction::Down { button: MOUSE_BUTTON_LEFT })
                .then(PointerAction::MoveBy { duration: None, x: 60.0, y: 20.0 })
                .then(PointerAction::Up { button: MOUSE_BUTTON_LEFT });
            c.perform_actions(drag).await.unwrap();
            let after = c.execute("return document.getElementById('cloud').toDataURL();", vec![]).await.unwrap();
            assert_ne!(before, after, "a drag turns the cloud");
        }
        c.execute("document.getElementById('cloud').scrollIntoView({block: 'end'});", vec![])
            .await
            .unwrap();
        shot(&c, "pair-cloud.png").await;
        drop(sv);
        // A capture set: untick a pair, retrain, the summary changes.
        let sv = start_captures();
        c.goto(&sv.url).await.unwrap();
        wait_js(&c, "document.querySelectorAll('input.use').length === 3").await;
        wait_js(&c, "document.getElementById('frames-status').dataset.loaded").await;
        click_id(&c, "retrain").await;
        wait_js(&c, "document.getElementById('summary').dataset.runs === '1'").await;
        let first = text(&c, "summary").await;
        assert!(first.starts_with("3 pairs, 162 points"), "{first}");
        c.find(fantoccini::Locator::Css("input.use[data-k='1']"))
            .await
            .unwrap()
            .click()
            .await
            .unwrap();
        click_id(&c, "retrain").await;
        wait_js(&c, "document.getElementById('summary').dataset.runs === '2'").await;
        let second = text(&c, "summary").await;
        assert!(second.starts_with("2 pairs, 108 points"), "{second}");
        assert_ne!(first, second);
        assert_eq!(text(&c, "summary-before").await, first);
        click_id(&c, "show-corners").await;
        wait_js(&c, "document.getElementById('left').src.includes('left-corners') && document.getElementById('left').complete").await;
        shot(&c, "captures-retrain.png").await;
        c.execute("document.getElementById('summary').scrollIntoView({block: 'end'});", vec![])
            .await
            .unwrap();
        shot(&c, "captures-table.png").await;
        drop(sv);
        // The virtual head, live: frames keep coming, a click on a still sphere (20 cm
        // radius, at 90 cm straight ahead: most of the small rig's view) and "look" turn the
        // head.
        let dir = crate::common::Scratch::new();
        let m = crate::common::small_model(&dir);
        let scene = crate::common::small_scene(&dir, "")
            .replace("scene.json", "still.json");
        let still = std::fs::read_to_string(dir.p("scene.json"))
            .unwrap()
            .replace("[5, 0, 0]", "[0, 0, 0]")
            .replace(r#""radius_cm": 8, "centre_cm": [10, -5, 90]"#, r#""radius_cm": 20, "centre_cm": [0, 0, 90]"#);
        assert!(still.contains(r#""radius_cm": 20"#), "{still}");
        std::fs::write(&scene, still).unwrap();
        let sv = start(&["--model", &m, "--scene", &scene]);
        c.goto(&sv.url).await.unwrap();
        wait_js(&c, "document.getElementById('frames-status').textContent.startsWith('live')").await;
        wait_js(&c, "Number(document.getElementById('head').dataset.updates || 0) >= 3").await;
        assert_eq!(
            wait_js(&c, "document.getElementById('head').dataset.status").await,
            "idle"
        );
        click_left(&c, 90, 64).await;
        // As a person would: read the answer, then press "look". Pressed while the answer
        // was arriving, the button moved under the pointer when the answer's lines reflowed
        // the page, and the press landed beside it (seen once in CI, debug build, 101 ms).
        wait_js(&c, "document.getElementById('point').dataset.answered === '1'").await;
        click_id(&c, "look").await;
        wait_js(&c, "document.getElementById('head').dataset.asked === '1'").await;
        wait_js(&c, "document.getElementById('head').dataset.moved === 'yes'").await;
        let goal = text(&c, "head-goal").await;
        // The pixel the page took from the mouse (the pointer lands within a pixel of it).
        assert_eq!(goal, format!("the object under {}", text(&c, "at").await));
        eprintln!(
            "live: {} | {} | {}",
            text(&c, "frames-status").await,
            text(&c, "head-loop").await,
            text(&c, "head-joints").await
        );
        shot(&c, "live-look.png").await;
        c.close().await.unwrap();
    });
}

/// The frame rate of the live page in chromium on the README's scene (case III, 640 x 480, a
/// 5 cm sphere on a textured wall) with the README's small posture-aware model: frames shown
/// per second by the page (distinct pairs), idle and while the head follows the nearest
/// object, and the head's own rate. A measurement, not a pass/fail on speed:
/// `cargo test --release -p hvs-host --test cli fps_live_page -- --ignored --nocapture`.
#[test]
#[ignore]
fn fps_live_page_in_chromium() {
    let dir = crate::common::Scratch::new();
    let (train, m, scene) = (dir.p("train.csv"), dir.p("small.hvsw"), dir.p("static.json"));
    ok(&["simulate", "--case", "3", "--set", "train", "--board", "9x6:6", "--postures", "grid"]
        .into_iter()
        .chain(["--posture-levels", "2,2,2,2,2", "--seed", "1", "-o", &train])
        .collect::<Vec<_>>());
    ok(&["train", "--data", &train, "-o", &m, "--hidden", "12", "--restarts", "1"]);
    std::fs::write(
        &scene,
        r#"{ "rig": {"case": 3}, "camera_fps": 30,
  "background": {"z_cm": 300, "texture_seed": 1},
  "objects": [ {"shape": "sphere", "radius_cm": 5, "centre_cm": [20, -8, 100],
                "velocity_cm_s": [0, 0, 0], "texture_seed": 2} ] }"#,
    )
    .unwrap();
    let sv = start(&["--model", &m, "--scene", &scene]);
    let driver = chromedriver();
    let rt = tokio::runtime::Runtime::new().unwrap();
    rt.block_on(async {
        let c = browser(&driver).await;
        c.goto(&sv.url).await.unwrap();
        wait_js(&c, "document.getElementById('frames-status').textContent.startsWith('live')").await;
        let secs = 8;
        let mut rates = vec![];
        for (what, look_at) in [("idle", None), ("following the nearest object", Some("nearest"))] {
            if let Some(t) = look_at {
                look(&sv.addr, &format!(r#"{{"target":"{t}"}}"#), 200);
            }
            tokio::time::sleep(Duration::from_secs(2)).await;
            let seq = |v: Value| v.as_str().unwrap().parse::<u64>().unwrap();
            // Distinct pairs the page has put on screen.
            let shown = "document.getElementById('frames-status').dataset.shown";
            let (f0, h0) = (seq(wait_js(&c, shown).await), head_frames(&sv.addr));
            let t0 = Instant::now();
            tokio::time::sleep(Duration::from_secs(secs)).await;
            let (f1, h1) = (seq(wait_js(&c, shown).await), head_frames(&sv.addr));
            let el = t0.elapsed().as_secs_f64();
            let page = text(&c, "frames-status").await;
            let h = json(&sv.addr, "GET", "/api/head", None, 200);
            eprintln!(
                "{what}: the page showed {} new pairs in {el:.1} s ({:.1} frames/s; it says {page:?}); the head grabbed {:.1} frames/s; status {}",
                f1 - f0,
                (f1 - f0) as f64 / el,
                (h1 - h0) as f64 / el,
                h["status"]
            );
            assert!(f1 > f0 && h1 > h0, "frames keep coming");
            rates.push(h["status"].as_str().unwrap().to_string());
        }
        assert_eq!(rates, ["idle", "tracking"]);
        shot(&c, "live-fps.png").await;
        c.close().await.unwrap();
    });
}

/// The live head's frame count.
fn head_frames(addr: &str) -> u64 {
    json(addr, "GET", "/api/head", None, 200)["frames"].as_u64().unwrap()
}
