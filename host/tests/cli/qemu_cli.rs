//! The user's path through the emulated head, command by command: `hvs simulate` -> `hvs train`
//! -> `hvs predict` on the host, and `hvs emulate` + `hvs head ... estimate` against the
//! firmware in QEMU; the two CSVs must agree bit for bit, and `hvs head info` must name the
//! trained model.
//!
//! Needs `qemu-system-arm` and the QEMU firmware build
//! (`cargo build --profile firmware -p hvs-firmware --target thumbv7em-none-eabihf --features qemu`);
//! `#[ignore]`d in a plain `cargo test`, run by `.ci/run` with
//! `cargo test -p hvs-host --test cli qemu_cli -- --ignored`. When run, a missing QEMU or ELF is a
//! failure with the command that fixes it, never a skip.

use crate::common::{detect_args, locate_args, ok as run, render_case1, s, train_restarts};
use hvs_host::device::qemu::{find_firmware, free_port, FIRMWARE_BUILD};
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};
use tempfile::TempDir;

fn hvs() -> Command {
    Command::new(env!("CARGO_BIN_EXE_hvs"))
}

/// `hvs emulate`, killed when dropped.
struct Emulate(Child);

impl Drop for Emulate {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// Fails, naming the command that builds it, unless the QEMU firmware ELF is there.
fn assert_firmware_built() {
    let fw = find_firmware(None);
    assert!(fw.exists(), "no firmware ELF at {}: build it with `{FIRMWARE_BUILD}`", fw.display());
}

/// Starts `hvs emulate --model model` on a free port (servo log in `d`): the guard and the
/// `--connect` address.
fn emulate(model: &Path, d: &Path) -> (Emulate, String) {
    emulate_for(model, d, 120)
}

/// [`emulate`], QEMU stopped after `secs` seconds.
fn emulate_for(model: &Path, d: &Path, secs: u32) -> (Emulate, String) {
    let port = free_port().expect("a free port");
    let listen = format!("127.0.0.1:{port}");
    let log = d.join(format!("servo-{port}.log"));
    let emu = Emulate(
        hvs()
            .args(["emulate", "--model", s(model), "--listen", &listen])
            .args(["--servo-log", s(&log), "--timeout", &secs.to_string()])
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .expect("hvs emulate starts"),
    );
    (emu, format!("tcp:{listen}"))
}

/// The stdout of `hvs head --connect connect ARGS`, retried until it succeeds: QEMU opens the
/// port shortly after it starts (20 s at most).
fn once_it_answers(connect: &str, args: &[&str]) -> String {
    let deadline = Instant::now() + Duration::from_secs(20);
    loop {
        let out =
            hvs().args(["head", "--connect", connect]).args(args).output().expect("hvs head runs");
        if out.status.success() {
            break String::from_utf8(out.stdout).expect("utf-8 stdout");
        }
        assert!(
            Instant::now() < deadline,
            "the emulated head never answered: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        std::thread::sleep(Duration::from_millis(200));
    }
}

/// The CSV rows of `text`, the first `cols` fields of each.
fn fields(text: &str, cols: usize) -> Vec<Vec<String>> {
    text.lines()
        .filter(|l| !l.is_empty())
        .map(|l| l.split(',').take(cols).map(str::to_string).collect())
        .collect()
}

#[test]
#[ignore = "needs qemu-system-arm and the firmware ELF; run by .ci/run"]
fn head_estimate_in_qemu_equals_predict_bit_for_bit() {
    head_agrees_with_predict(false);
}

/// The default family on a posture-aware (9-input) net: the head feeds its own joint angles
/// (the home posture, all zero, after boot), the host reads them from the CSV's joint columns.
#[test]
#[ignore = "needs qemu-system-arm and the firmware ELF; run by .ci/run"]
fn head_estimate_of_a_posture_aware_default_net_equals_predict_bit_for_bit() {
    head_agrees_with_predict(true);
}

/// `hvs train` (default family) then `hvs predict` on the host and `hvs head estimate` in QEMU
/// on 300 noisy volume points; with `joints`, trained on a posture set (9 inputs) and asked at
/// the home posture.
fn head_agrees_with_predict(joints: bool) {
    assert_firmware_built();
    let dir = TempDir::new().unwrap();
    let d = dir.path();
    let (train, pts, model) = (d.join("train.csv"), d.join("pts.csv"), d.join("m.hvsw"));
    if joints {
        run(&[
            "simulate",
            "--case",
            "4",
            "--set",
            "train",
            "--postures",
            "random",
            "--posture-count",
            "6",
            "--seed",
            "5",
            "-o",
            s(&train),
        ]);
    } else {
        run(&["simulate", "--case", "4", "--set", "train", "-o", s(&train)]);
    }
    run(&[
        "simulate",
        "--case",
        "4",
        "--set",
        "volume",
        "--points",
        "300",
        "--noise-px",
        "0.4",
        "--seed",
        "11",
        "-o",
        s(&pts),
    ]);
    if joints {
        // The home posture's joint columns after the pixels and truth.
        let text = std::fs::read_to_string(&pts).unwrap();
        let mut out = String::new();
        for (i, l) in text.lines().enumerate() {
            out.push_str(l);
            out.push_str(if i == 0 {
                ",neck_pan,neck_tilt,eye_tilt,left_eye_pan,right_eye_pan\n"
            } else {
                ",0,0,0,0,0\n"
            });
        }
        std::fs::write(&pts, out).unwrap();
    }
    // The default family (and, posture-aware, its default cyclopean frame).
    run(&["train", "--data", s(&train), "-o", s(&model), "--seed", "3"]);
    let shown = run(&["info", s(&model)]);
    assert!(shown.contains("inverse-depth-skip"), "{shown}");
    let frame = if joints { "cyclopean" } else { "head" };
    assert!(shown.contains(&format!("frame:       {frame} ")), "{shown}");
    let predicted = run(&["predict", "--model", s(&model), "--points", s(&pts)]);

    let (_emu, connect) = emulate(&model, d);
    let info = once_it_answers(&connect, &["info"]);
    assert!(info.contains("slot A"), "{info}");
    assert!(info.contains("seed 3"), "{info}");
    let peak: u32 = info
        .lines()
        .find_map(|l| l.strip_prefix("stack peak: ")?.strip_suffix(" B")?.parse().ok())
        .unwrap_or_else(|| panic!("no `stack peak: N B` line: {info}"));
    // Boot has run, so some of the painted stack is used; the budget is 16 KiB for static RAM
    // (about 3 KiB) and stack together (`firmware/measure.sh` checks the sum).
    assert!((256..=12 * 1024).contains(&peak), "stack peak {peak} B");

    let estimated = run(&["head", "--connect", &connect, "estimate", "--points", s(&pts)]);
    // A posture-aware model's prediction repeats the joint columns before x, y, z.
    let host: Vec<Vec<String>> = fields(&predicted, 12)
        .into_iter()
        .map(|r| {
            let n = r.len();
            let mut v = r[..4].to_vec();
            v.extend_from_slice(&r[n - 3..]);
            v
        })
        .collect();
    let head = fields(&estimated, 7);
    assert_eq!(head[0], ["u_l", "v_l", "u_r", "v_r", "x", "y", "z"]);
    assert_eq!(host.len(), 301);
    assert_eq!(head.len(), host.len());
    for (i, (h, e)) in host.iter().zip(&head).enumerate() {
        let bits = |r: &[String]| -> Vec<u32> {
            r.iter().map(|v| v.parse::<f32>().expect("a number").to_bits()).collect()
        };
        if i == 0 {
            continue;
        }
        assert_eq!(bits(e), bits(h), "row {i}: head {e:?}, host {h:?}");
    }
}

/// The loop from images to servo setpoints: a model trained on rendered board photos, a left
/// pixel located in the right image (`hvs head look --model --left --right --at`), the head's
/// estimate and fixation in QEMU; the head's X, Y, Z equal `hvs locate`'s bit for bit.
#[test]
#[ignore = "needs qemu-system-arm and the firmware ELF; run by .ci/run"]
fn head_looks_at_a_point_found_in_the_images() {
    assert_firmware_built();
    let dir = TempDir::new().unwrap();
    let d = dir.path();
    let (shots, test, model) = (d.join("shots"), d.join("test"), d.join("m.hvsw"));
    render_case1(&shots, "4", &[]);
    let points = d.join("points.csv");
    run(&detect_args(&shots.join("board.json"), &shots.join("captures.csv"), &points));
    train_restarts(&points, &model, "2");
    render_case1(&test, "5", &["--depths", "110", "--centre", "2,1"]);
    // A board corner of the test pair: textured, unique along its epipolar line.
    let truth = std::fs::read_to_string(test.join("truth.csv")).unwrap();
    let row: Vec<&str> = truth.lines().nth(20).unwrap().split(',').collect();
    let at = format!("{},{}", row[6], row[7]);
    let (l, r) = (test.join("left01.png"), test.join("right01.png"));
    // The same question to the host (`hvs locate`) and to the head (`hvs head look`).
    let question = |verb| locate_args(&[verb], &model, &l, &r, &["--at", &at]);
    let located = run(&question("locate"));
    let xyz = |text: &str| -> Vec<String> {
        ["x=", "y=", "z="]
            .iter()
            .map(|k| {
                let i = text.find(k).unwrap_or_else(|| panic!("no {k} in {text}")) + 2;
                text[i..].split_whitespace().next().unwrap().to_string()
            })
            .collect()
    };
    let want = xyz(&located);
    let (_emu, connect) = emulate(&model, d);
    let looked = once_it_answers(&connect, &question("look"));
    assert!(looked.contains("(Network, in_range=true)"), "{looked}");
    assert!(looked.contains("joints deg: neck_pan="), "{looked}");
    let got = xyz(&looked);
    assert_eq!(got, want, "head {looked} vs locate {located}");
    // The point is about where the board was.
    let z: f32 = got[2].parse().unwrap();
    assert!((z - 110.0).abs() < 2.0, "z = {z}");
    // Another model (another seed) than the one the head runs: refused, nothing asked.
    let other = d.join("other.hvsw");
    run(&["train", "--data", s(&points), "-o", s(&other), "--restarts", "1", "--seed", "9"]);
    let out = hvs()
        .args(["head", "--connect", &connect])
        .args(locate_args(&["look"], &other, &l, &r, &["--at", &at]))
        .output()
        .unwrap();
    let e = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{e}");
    assert!(e.contains("is not the model the head runs"), "{e}");
}

/// `hvs track --head qemu`: the loop moves the head firmware in QEMU with posture commands
/// (protocol 3) on the head's own clock; the log is the same format as `--head emulate`'s,
/// every joint within the limits, the head turns to the object and holds it about where the
/// emulated head does. A firmware that is not there is named.
#[test]
#[ignore = "needs qemu-system-arm and the firmware ELF; run by .ci/run"]
fn track_moves_the_head_in_qemu_with_posture_commands() {
    let (dir, m, scene) = track_setup();
    let (q, e) = (dir.p("qemu.csv"), dir.p("emulate.csv"));
    let args = |log: &str, head: &str| {
        [
            "track",
            "--model",
            &m,
            "--scene",
            &scene,
            "--seconds",
            "1.5",
            "--log",
            log,
            "--head",
            head,
        ]
        .map(String::from)
        .to_vec()
    };
    let out = hvs().args(args(&q, "qemu")).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    run(&args(&e, "emulate").iter().map(String::as_str).collect::<Vec<_>>());
    let (tq, te) = (std::fs::read_to_string(&q).unwrap(), std::fs::read_to_string(&e).unwrap());
    let (rq, re) = (track_log_rows(&tq), track_log_rows(&te));
    assert_eq!(rq.len(), re.len(), "one row per frame, as many frames");
    let num = |r: &[&str], i: usize| r[i].parse::<f64>().unwrap();
    let mut t_prev = -1.0;
    for r in &rq {
        let t = num(r, 0);
        assert!(t >= t_prev, "the head's clock runs forward: {t} after {t_prev}");
        t_prev = t;
    }
    assert!(t_prev >= 1.4, "the head's clock reached the run's end: {t_prev}");
    // The head turned towards the object: after 0.5 s of the head's clock, the tracked frames'
    // median error is under half the first one's.
    for (what, rows) in [("qemu", &rq), ("emulate", &re)] {
        let r0 = rows
            .iter()
            .find(|r| !r[15].is_empty())
            .unwrap_or_else(|| panic!("{what}: no frame on the object: {rows:?}"));
        let first = num(r0, 15).max(num(r0, 16));
        let mut late: Vec<f64> = rows
            .iter()
            .filter(|r| r[2] == "tracking" && num(r, 0) >= 0.5 && !r[15].is_empty())
            .map(|r| num(r, 15).max(num(r, 16)))
            .collect();
        late.sort_by(f64::total_cmp);
        assert!(late.len() * 3 >= rows.len(), "{what}: {} tracked frames after 0.5 s", late.len());
        let median = late[late.len() / 2];
        assert!(median < first / 2.0, "{what}: median error {median} px, first frame {first} px");
        assert!(rows.iter().any(|r| (10..15).any(|i| num(r, i) != 0.0)), "{what}: the head turned");
    }
    // A firmware that is not there.
    let mut bad = args(&q, "qemu");
    bad.extend(["--firmware".into(), dir.p("none.elf")]);
    let out = hvs().args(&bad).output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(err.contains("none.elf") && err.lines().count() == 1, "{err}");
}

/// `hvs view --scene --head qemu`: the page's live head is the firmware in QEMU; "look at the
/// nearest object" turns it (joints within the limits), "home" brings it back.
#[test]
#[ignore = "needs qemu-system-arm and the firmware ELF; run by .ci/run"]
fn view_runs_the_head_in_qemu() {
    use crate::view::{head_until, joints_at_home, look, start};
    assert_firmware_built();
    let dir = crate::common::Scratch::new();
    let m = crate::common::small_model(&dir);
    let scene = crate::common::small_scene(&dir, "");
    let sv = start(&["--model", &m, "--scene", &scene, "--head", "qemu"]);
    let session = crate::view::json(&sv.addr, "GET", "/api/session", None, 200);
    assert!(session["pairs"][0]["name"].as_str().unwrap().starts_with("head firmware in QEMU"));
    let first = head_until(&sv.addr, "frames", |h| h["frames"].as_u64().unwrap() > 2);
    assert!(joints_at_home(&first) && first["status"] == "idle", "{first}");
    look(&sv.addr, r#"{"target":"nearest"}"#, 200);
    let h = head_until(&sv.addr, "the head to turn", |h| !joints_at_home(h));
    let limits = hvs_shared::runtime::gaze::GazeConfig::DEFAULT.limits;
    let names = ["neck_pan", "neck_tilt", "eye_tilt", "left_eye_pan", "right_eye_pan"];
    let j =
        hvs_shared::runtime::gaze::Joints(names.map(|n| h["joints"][n].as_f64().unwrap() as f32));
    assert!(limits.contains(&j), "{h}");
    look(&sv.addr, r#"{"target":"home"}"#, 200);
    head_until(&sv.addr, "the head at home", |h| joints_at_home(h) && h["moving"] == false);
}

/// `hvs track --port tcp:...`: the loop drives a head controller on a link (here `hvs emulate`'s
/// QEMU, as a real head on a serial port) with virtual cameras: the head turns to the object,
/// every joint within the limits.
#[test]
#[ignore = "needs qemu-system-arm and the firmware ELF; run by .ci/run"]
fn track_drives_a_head_on_a_port() {
    let (dir, m, scene) = track_setup();
    let d = TempDir::new().unwrap();
    let (_emu, connect) = emulate(Path::new(&m), d.path());
    once_it_answers(&connect, &["info"]);
    // By hand first: a posture beyond the neck tilt's limit is clamped; the state follows.
    let posture = run(&["head", "--connect", &connect, "posture", "10,-200,nan,2,-2"]);
    assert!(posture.contains("goal deg: neck_pan=10.08 neck_tilt=-34.92"), "{posture}");
    assert!(posture.contains("moving=true"), "{posture}");
    std::thread::sleep(Duration::from_millis(1500));
    let state = run(&["head", "--connect", &connect, "state"]);
    assert!(state.contains("joints deg: neck_pan=10.08 neck_tilt=-34.92"), "{state}");
    assert!(state.contains("moving=false"), "{state}");
    let log = dir.p("port.csv");
    run(&[
        "track",
        "--model",
        &m,
        "--scene",
        &scene,
        "--seconds",
        "1",
        "--log",
        &log,
        "--port",
        &connect,
    ]);
    let text = std::fs::read_to_string(&log).unwrap();
    let rows = track_log_rows(&text);
    assert_eq!(rows.len(), 30, "{text}");
    let turned = |r: &Vec<&str>| r[10..15].iter().any(|a| a.parse::<f64>().unwrap() != 0.0);
    assert!(rows.iter().any(turned), "the head turned:\n{text}");
    drop(_emu);
    // A head that goes away mid-run (QEMU stopped after 4 s): one clear line, exit 1, and
    // the log keeps the frames before.
    let (_short, connect) = emulate_for(Path::new(&m), d.path(), 4);
    once_it_answers(&connect, &["ping"]);
    let args = ["track", "--model", &m, "--scene", &scene, "--seconds", "30", "--log", &log];
    let out = hvs().args(args).args(["--port", &connect]).output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(err.contains("the run stopped") && err.lines().count() == 1, "{err}");
    let text = std::fs::read_to_string(&log).unwrap();
    let n = text.lines().count() - 1;
    assert!(n > 0 && n < 900 && err.contains(&format!("the {n} frames before")), "{n}: {err}");
}

/// What the `hvs track` tests on QEMU start from: the firmware built, a scratch directory,
/// a posture-aware model of the small rig (32 postures) and its big still scene. With the
/// 4-input model, trained at home only, a turned head's estimates fell outside its box: a
/// loop on a loaded machine could turn the eyes where the model refused every point and stay
/// lost (2 runs in 13 of this test, 0 tracked frames after 0.5 s).
fn track_setup() -> (crate::common::Scratch, String, String) {
    assert_firmware_built();
    let dir = crate::common::Scratch::new();
    let (rig, data, m) = (dir.p("rig.json"), dir.p("posture.csv"), dir.p("posture.hvsw"));
    std::fs::write(&rig, crate::common::SMALL_RIG).unwrap();
    // The 9 x 6 board: the loop takes depths only from pixels inside a model's training box,
    // and the thesis' 4 x 3 board covers the middle of the view only.
    run(&["simulate", "--rig", &rig, "--set", "train", "--board", "9x6:6", "--postures", "grid"]
        .into_iter()
        .chain(["--posture-levels", "2,2,2,2,2", "--seed", "1", "-o", &data])
        .collect::<Vec<_>>());
    run(&["train", "--data", &data, "-o", &m, "--hidden", "12", "--restarts", "1"]);
    let scene = big_still_scene(&dir);
    (dir, m, scene)
}

/// The rows of an `hvs track` log (its header checked), every row's joints within the
/// limits.
fn track_log_rows(text: &str) -> Vec<Vec<&str>> {
    use hvs_shared::runtime::gaze::{GazeConfig, Joints};
    let rows = crate::common::csv_rows(text, hvs_host::track::LOG_HEADER);
    let limits = GazeConfig::DEFAULT.limits;
    for r in &rows {
        let j = Joints(std::array::from_fn(|i| r[10 + i].parse::<f64>().unwrap() as f32));
        assert!(limits.contains(&j), "{r:?}");
    }
    rows
}

/// The small rig's scene with its sphere still, larger (20 cm) and off the axis: the nearest
/// object the small model's loop can hold.
fn big_still_scene(dir: &crate::common::Scratch) -> String {
    let scene = crate::common::small_scene(dir, "").replace("scene.json", "still.json");
    let still = std::fs::read_to_string(dir.p("scene.json"))
        .unwrap()
        .replace("[5, 0, 0]", "[0, 0, 0]")
        .replace(
            r#""radius_cm": 8, "centre_cm": [10, -5, 90]"#,
            r#""radius_cm": 20, "centre_cm": [15, -5, 90]"#,
        );
    assert!(still.contains("[0, 0, 0]") && still.contains(r#""radius_cm": 20"#));
    std::fs::write(&scene, still).unwrap();
    scene
}
