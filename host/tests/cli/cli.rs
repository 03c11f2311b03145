//! The `hvs` binary driven from outside, as a user would: the thesis protocol end to end,
//! bit-exact prediction, every bad-input class, determinism, and the demo.

use crate::common::{fails, hvs, ok, ok_line, s};

use hvs_shared::runtime::blob::{self, ModelBlob};
use serde_json::Value;
use std::path::{Path, PathBuf};
use tempfile::TempDir;

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/tests/fixtures").join(name)
}

/// Simulates case `n`'s train and test sets and trains the default net (with `restarts`)
/// into `dir`; returns (train csv, test csv, model).
/// `hvs simulate --case n --set set` into `dir/name`.
fn simulated(dir: &Path, n: u8, set: &str, name: &str) -> PathBuf {
    let p = dir.join(name);
    ok(&["simulate", "--case", &n.to_string(), "--set", set, "-o", s(&p)]);
    p
}

fn train_case(dir: &Path, n: u8, restarts: usize) -> (PathBuf, PathBuf, PathBuf) {
    let tr = simulated(dir, n, "train", &format!("case{n}_train.csv"));
    let te = simulated(dir, n, "test", &format!("case{n}_test.csv"));
    let m = dir.join(format!("case{n}.hvsw"));
    let r = restarts.to_string();
    let out = ok(&["train", "--data", s(&tr), "-o", s(&m), "--restarts", &r]);
    assert!(out.contains("training e_ma"), "{out}");
    (tr, te, m)
}

/// `hvs simulate --set volume` of case `n` with `args` (`--points 300 ...`) into `dir/name`.
fn volume(dir: &Path, n: u8, args: &str, name: &str) -> PathBuf {
    let p = dir.join(name);
    ok_line(&format!("simulate --case {n} --set volume {args} -o {}", s(&p)));
    p
}

fn eval_json(model: &Path, data: &Path) -> Value {
    let out = ok(&["eval", "--model", s(model), "--data", s(data), "--json"]);
    serde_json::from_str(&out).expect("eval --json prints JSON")
}

fn method<'a>(report: &'a Value, name: &str) -> &'a Value {
    report["evaluation"]["methods"]
        .as_array()
        .expect("methods")
        .iter()
        .find(|m| m["name"] == name)
        .unwrap_or_else(|| panic!("no method {name} in {report}"))
}

fn rows(text: &str) -> Vec<Vec<String>> {
    text.lines()
        .map(|l| l.trim_end_matches('\r'))
        .filter(|l| !l.is_empty())
        .map(|l| l.split(',').map(str::to_string).collect())
        .collect()
}

#[test]
fn simulate_reproduces_the_reference_data_files() {
    let dir = TempDir::new().unwrap();
    for n in 1..=4u8 {
        for set in ["train", "test"] {
            let want = std::fs::read_to_string(fixture(&format!("case{n}_{set}.csv"))).unwrap();
            let case = n.to_string();
            let stdout = ok(&["simulate", "--case", &case, "--set", set]);
            assert_eq!(rows(&stdout), rows(&want), "case {n} {set}");
            // The same rig from cases.json, and written to a file.
            let out = dir.path().join("x.csv");
            let cases = fixture("cases.json");
            ok(&["simulate", "--rig", s(&cases), "--case", &case, "--set", set, "-o", s(&out)]);
            assert_eq!(rows(&std::fs::read_to_string(&out).unwrap()), rows(&want));
        }
    }
}

#[test]
fn simulate_volume_and_noise_are_seeded() {
    let run = |seed: &str, noise: &str| {
        ok(&[
            "simulate",
            "--case",
            "3",
            "--set",
            "volume",
            "--points",
            "200",
            "--seed",
            seed,
            "--noise-px",
            noise,
        ])
    };
    let a = run("5", "0");
    assert_eq!(rows(&a).len(), 201);
    // No rig, or --points with a board set: bad usage (exit 2, as `hvs render`'s).
    for (args, want) in [
        (&["simulate", "--set", "train"][..], "choose a rig"),
        (&["simulate", "--case", "1", "--set", "train", "--points", "9"][..], "--set volume only"),
    ] {
        let e = crate::common::stderr_with_code(args, 2);
        assert!(e.starts_with("error: ") && e.contains(want) && e.lines().count() == 1, "{e}");
    }
    assert_eq!(a, run("5", "0"));
    assert_ne!(a, run("6", "0"));
    let noisy = run("5", "0.7");
    assert_eq!(noisy, run("5", "0.7"));
    assert_ne!(noisy, a);
    // A flat rig file equal to case 3 gives the same points.
    let dir = TempDir::new().unwrap();
    let rig = dir.path().join("rig.json");
    std::fs::write(
        &rig,
        r#"{"phi_u_left": 285.836, "phi_u_right": 285.3500788, "alpha_left": -0.0299,
            "alpha_right": 0.0299, "beta0": 0.008726646259971648, "phi0": 0.008726646259971648}"#,
    )
    .unwrap();
    let b = ok_line(&format!("simulate --rig {} --set volume --points 200 --seed 5", s(&rig)));
    assert_eq!(a, b);
}

/// Trains the default net on case `n`'s boards and evaluates it on the test points; returns
/// the worst per-depth e_ma of the network and of the traditional method (refit Phi).
fn thesis_protocol(dir: &Path, n: u8) -> (f64, Option<f64>) {
    let (_, test, model) = train_case(dir, n, 10);
    let r = eval_json(&model, &test);
    assert_eq!(r["evaluation"]["depths"].as_array().unwrap().len(), 11);
    let net = method(&r, "network")["worst_depth_pct"].as_f64().unwrap();
    let trad = method(&r, "traditional")["worst_depth_pct"].as_f64();
    (net, trad)
}

#[test]
fn network_meets_the_thesis_bound_on_cases_one_and_two() {
    let dir = TempDir::new().unwrap();
    for n in [1, 2] {
        let (worst, _) = thesis_protocol(dir.path(), n);
        assert!(worst < 4.0, "case {n}: worst per-depth e_ma {worst} %");
    }
}

/// The deflected rigs (cases III, IV): the thesis' "< 4 %" is out of reach on these rounded
/// pixels for any method, because optimal triangulation with the *true* rig on the same pixels
/// is itself at 3.86 % (III, 125 cm: both test points' disparity rounds from about 6.9 to 6 px,
/// and one pixel of disparity is 4.2 % of depth there) and 4.00 % (IV, 135 cm). This test pins
/// both facts: the floor is where we say it is, and the default net's worst depth stays within
/// 1.5 percentage points of it (measured: 5.30 % vs 3.86 % and 4.35 % vs 4.00 %); and the net
/// beats the traditional method there by far (about 5 % against 750 %, 4 % against 1000 %).
#[test]
fn network_is_near_the_rounding_floor_and_beats_the_traditional_method_on_the_deflected_rigs() {
    let dir = TempDir::new().unwrap();
    for n in [3u8, 4] {
        let (_, test, model) = train_case(dir.path(), n, 10);
        let out =
            ok_line(&format!("eval --model {} --data {} --case {n} --json", s(&model), s(&test)));
        let r: Value = serde_json::from_str(&out).expect("eval --json prints JSON");
        let net = method(&r, "network")["worst_depth_pct"].as_f64().unwrap();
        let floor = method(&r, "optimal")["worst_depth_pct"].as_f64().unwrap();
        assert!(floor > 3.8, "case {n}: floor {floor} %");
        assert!(net < floor + 1.5, "case {n}: net {net} %, floor {floor} %");
        assert!(net < 6.0, "case {n}: {net}");
        let trad = method(&r, "traditional")["worst_depth_pct"].as_f64();
        assert!(trad.is_none_or(|t| t > 100.0), "case {n}: {trad:?}");
    }
}

#[test]
fn predict_gives_the_bits_of_the_shared_inference() {
    let dir = TempDir::new().unwrap();
    let (_, _, model) = train_case(dir.path(), 4, 2);
    let pts = volume(dir.path(), 4, "--points 3000 --noise-px 0.8", "vol.csv");
    let out = dir.path().join("pred.csv");
    ok_line(&format!("predict --model {} --points {} -o {}", s(&model), s(&pts), s(&out)));
    let blob: ModelBlob = blob::decode(&std::fs::read(&model).unwrap()).unwrap();
    let input = rows(&std::fs::read_to_string(&pts).unwrap());
    let pred = rows(&std::fs::read_to_string(&out).unwrap());
    assert_eq!(pred[0], ["u_l", "v_l", "u_r", "v_r", "x", "y", "z"]);
    assert_eq!(pred.len(), input.len());
    for (i, (a, p)) in input.iter().zip(&pred).enumerate().skip(1) {
        let x: Vec<f32> = a[..4].iter().map(|v| v.parse().unwrap()).collect();
        let echoed: Vec<f32> = p[..4].iter().map(|v| v.parse().unwrap()).collect();
        assert_eq!(echoed, x, "row {i}");
        let mut want = [0.0f32; 3];
        blob.infer(&x, &mut want).unwrap();
        let got: Vec<u32> = p[4..].iter().map(|v| v.parse::<f32>().unwrap().to_bits()).collect();
        assert_eq!(got, want.map(f32::to_bits), "row {i}");
    }
    // stdout gives the same bytes as the file.
    let stdout = ok(&["predict", "--model", s(&model), "--points", s(&pts)]);
    assert_eq!(stdout, std::fs::read_to_string(&out).unwrap());
}

#[test]
fn z_only_models_leave_x_and_y_empty() {
    let dir = TempDir::new().unwrap();
    let tr = simulated(dir.path(), 2, "train", "t.csv");
    let m = dir.path().join("z.hvsw");
    ok_line(&format!("train --data {} -o {} --outputs z --restarts 2", s(&tr), s(&m)));
    let out = ok(&["predict", "--model", s(&m), "--points", s(&tr)]);
    let r = rows(&out);
    assert_eq!(r.len(), 73);
    for row in &r[1..] {
        assert_eq!((row[4].as_str(), row[5].as_str()), ("", ""));
        assert!(row[6].parse::<f32>().unwrap() > 50.0);
    }
    assert!(ok(&["info", s(&m)]).contains("4-5-1"));
}

#[test]
fn the_same_seed_gives_the_same_model_bytes() {
    let dir = TempDir::new().unwrap();
    let tr = simulated(dir.path(), 3, "train", "t.csv");
    let train = |seed: &str, name: &str| {
        let m = dir.path().join(name);
        ok(&["train", "--data", s(&tr), "-o", s(&m), "--seed", seed, "--restarts", "4"]);
        std::fs::read(m).unwrap()
    };
    let a = train("11", "a.hvsw");
    assert_eq!(a, train("11", "b.hvsw"));
    assert_ne!(a, train("12", "c.hvsw"));
}

#[test]
fn train_stores_the_thesis_calibration_as_fallback() {
    let dir = TempDir::new().unwrap();
    let (tr, _, m) = train_case(dir.path(), 1, 2);
    let blob = blob::decode(&std::fs::read(&m).unwrap()).unwrap();
    assert_eq!(blob.generation, 1);
    assert_eq!(
        blob.fallback,
        Some(hvs_shared::runtime::traditional::Calibration::BUILT_IN),
        "Phi of case I's 65 cm board, as cases.json"
    );
    let info = ok(&["info", s(&m)]);
    for want in ["crc:         ok", "generation:  1", "4-5-3", "Phi = 284.7619", "input box"] {
        assert!(info.contains(want), "{want} in {info}");
    }
    // Random volume points hold no symmetric board: no fallback, and eval says so.
    let vol = dir.path().join("v.csv");
    let mv = dir.path().join("v.hvsw");
    ok_line(&format!("simulate --case 1 --set volume --points 100 -o {}", s(&vol)));
    let out = ok(&["train", "--data", s(&vol), "-o", s(&mv), "--restarts", "2"]);
    assert!(out.contains("fallback: none"), "{out}");
    let out = ok(&["eval", "--model", s(&mv), "--data", s(&tr)]);
    assert!(out.contains("traditional: none"), "{out}");
}

#[test]
fn eval_reports_the_optimal_floor_with_a_true_rig() {
    let dir = TempDir::new().unwrap();
    let (_, _, m) = train_case(dir.path(), 2, 2);
    let vol = volume(dir.path(), 2, "--points 300", "v.csv");
    let out = ok_line(&format!("eval --model {} --data {} --json --case 2", s(&m), s(&vol)));
    let r: Value = serde_json::from_str(&out).unwrap();
    assert_eq!(r["evaluation"]["exact_depths"], false);
    let floor = method(&r, "optimal")["mean"]["e_ma_pct"].as_f64().unwrap();
    // Rounded pixels alone cost about 1 % of depth over 65..165 cm on these rigs.
    assert!(floor > 0.3 && floor < 3.0, "{floor}");
    let text = ok(&["eval", "--model", s(&m), "--data", s(&vol), "--case", "2"]);
    assert!(text.contains("optimal e_ma") && text.contains("worst depth"), "{text}");
}

/// Every bad-input class: a clear one-line error naming file, line and column where there is
/// one, exit code 1, and no output file left behind.
#[test]
fn bad_inputs_are_clear_errors_and_leave_no_output() {
    let dir = TempDir::new().unwrap();
    let d = dir.path();
    let (good, _, model) = train_case(d, 1, 1);
    let h = "u_l,v_l,u_r,v_r,x,y,z\n";
    let row = "330,231,284,231,-3.0000,-2.0000,65.0000\n";
    let cases: Vec<(&str, String, String)> = vec![
        (
            "missing_column.csv",
            format!("u_l,v_l,u_r,x,y,z\n{row}"),
            "missing_column.csv:1: missing column \"v_r\"".into(),
        ),
        (
            "not_a_number.csv",
            format!("{h}{row}{row}330,231,284,abc,-3,-2,65\n"),
            "not_a_number.csv:4: column \"v_r\": \"abc\" is not a number".into(),
        ),
        (
            "nan.csv",
            format!("{h}{row}330,NaN,284,231,-3,-2,65\n"),
            "nan.csv:3: column \"v_l\": \"NaN\" is not a finite number".into(),
        ),
        (
            "inf.csv",
            format!("{h}330,231,inf,231,-3,-2,65\n"),
            "inf.csv:2: column \"u_r\": \"inf\" is not a finite number".into(),
        ),
        (
            "ragged.csv",
            format!("{h}{row}330,231,284,231,-3\n"),
            "ragged.csv:3: row has 5 fields, the header has 7".into(),
        ),
        ("empty.csv", String::new(), "empty.csv: empty file".into()),
        ("header_only.csv", h.to_string(), "header_only.csv: no data rows after the header".into()),
    ];
    for (name, text, want) in &cases {
        let p = d.join(name);
        std::fs::write(&p, text).unwrap();
        let out = d.join("out.csv");
        let mout = d.join("out.hvsw");
        fails(&["predict", "--model", s(&model), "--points", s(&p), "-o", s(&out)], want);
        fails(&["eval", "--model", s(&model), "--data", s(&p)], want);
        fails(&["train", "--data", s(&p), "-o", s(&mout)], want);
        assert!(!out.exists() && !mout.exists(), "{name}: output written");
    }
    // Ground truth is required by eval and train only.
    let no_truth = d.join("no_truth.csv");
    std::fs::write(&no_truth, "u_l,v_l,u_r,v_r\n330,231,284,231\n").unwrap();
    ok(&["predict", "--model", s(&model), "--points", s(&no_truth)]);
    fails(
        &["eval", "--model", s(&model), "--data", s(&no_truth)],
        "no_truth.csv:1: missing column \"x\"",
    );
    // A depth at or behind the head is not ground truth; predict does not read z.
    let behind = d.join("behind.csv");
    std::fs::write(&behind, format!("{h}{row}330,231,284,231,0,0,-65\n")).unwrap();
    let want = "behind.csv:3: column \"z\": -65 cm is not a depth in front of the head";
    fails(&["eval", "--model", s(&model), "--data", s(&behind)], want);
    let behind_model = d.join("behind.hvsw");
    fails(&["train", "--data", s(&behind), "-o", s(&behind_model)], want);
    assert!(!behind_model.exists());
    ok(&["predict", "--model", s(&model), "--points", s(&behind)]);

    // A missing file.
    let missing = d.join("nope.csv");
    let out = d.join("out.csv");
    fails(
        &["predict", "--model", s(&model), "--points", s(&missing), "-o", s(&out)],
        "nope.csv: cannot open",
    );
    fails(&["train", "--data", s(&missing), "-o", s(&out)], "nope.csv: cannot open");
    fails(&["info", s(&missing)], "nope.csv: cannot read");
    assert!(!out.exists());

    // Bad model files: not a model, damaged (one flipped byte), truncated.
    let bytes = std::fs::read(&model).unwrap();
    let bad: Vec<(&str, Vec<u8>, &str)> = vec![
        ("text.hvsw", b"u_l,v_l\n1,2\n".to_vec(), "magic check failed"),
        (
            "flipped.hvsw",
            {
                let mut b = bytes.clone();
                b[40] ^= 0x10;
                b
            },
            "CRC check failed",
        ),
        ("short.hvsw", bytes[..bytes.len() - 3].to_vec(), "length check failed"),
    ];
    for (name, b, want) in &bad {
        let p = d.join(name);
        std::fs::write(&p, b).unwrap();
        let msg = fails(&["info", s(&p)], want);
        assert!(msg.contains(name), "{msg}");
        fails(&["predict", "--model", s(&p), "--points", s(&good), "-o", s(&out)], want);
        fails(&["eval", "--model", s(&p), "--data", s(&good)], want);
        assert!(!out.exists());
    }

    // An unwritable output leaves nothing either.
    let nodir = d.join("no/such/dir/out.csv");
    fails(
        &["simulate", "--case", "1", "--set", "test", "-o", s(&nodir)],
        "no/such/dir/out.csv: the directory",
    );
    // Bad rig files name the field.
    let rig = d.join("rig.json");
    std::fs::write(&rig, r#"{"phi_u_left": 285.8, "phi_u_right": "x"}"#).unwrap();
    fails(
        &["simulate", "--rig", s(&rig), "--set", "test"],
        "rig.json: field \"phi_u_right\": expected a number",
    );
}

#[test]
fn every_command_has_help() {
    for c in ["simulate", "train", "predict", "eval", "info", "demo"] {
        let out = ok(&[c, "--help"]);
        assert!(out.contains("Usage: hvs"), "{c}: {out}");
    }
    hvs().assert().code(2);
    hvs().args(["simulate", "--set", "nope", "--case", "1"]).assert().code(2);
}

#[test]
fn demo_writes_models_data_and_report() {
    let dir = TempDir::new().unwrap();
    let out = dir.path().join("demo");
    // One restart per net keeps this test quick in debug builds (10 restarts: ~100 s there,
    // ~2 s in release); the accuracy of the default is tested above.
    let stdout = ok(&["demo", "-o", s(&out), "--restarts", "1"]);
    for case in ["I ", "II ", "III ", "IV "] {
        assert!(stdout.lines().any(|l| l.starts_with(case)), "{case}: {stdout}");
    }
    for n in 1..=4 {
        for f in ["train.csv", "test.csv", "volume_train.csv", "volume_test.csv"] {
            assert!(out.join(format!("case{n}_{f}")).is_file());
        }
        for m in ["", "_volume"] {
            let m = out.join(format!("case{n}{m}.hvsw"));
            assert!(blob::decode(&std::fs::read(&m).unwrap()).is_ok());
        }
        // The demo's data are the simulator's.
        let want = std::fs::read_to_string(fixture(&format!("case{n}_test.csv"))).unwrap();
        let got = std::fs::read_to_string(out.join(format!("case{n}_test.csv"))).unwrap();
        assert_eq!(rows(&got), rows(&want));
    }
    let report = std::fs::read_to_string(out.join("REPORT.md")).unwrap();
    assert!(report.contains("| case |") && report.contains("## Case IV"), "{report}");
}

#[test]
fn demo_images_renders_detects_trains_and_reports() {
    let dir = TempDir::new().unwrap();
    let out = dir.path().join("demo");
    let stdout = ok(&["demo", "--images", "-o", s(&out), "--restarts", "1"]);
    let report = std::fs::read_to_string(out.join("IMAGES.md")).unwrap();
    for case in ["I", "II", "III", "IV"] {
        let row = stdout.lines().find(|l| l.starts_with(&format!("{case} "))).expect(case);
        // Every corner of the 9x6 board found at the six training and eleven test depths, and
        // the model within 1.5 times the floor even with one restart.
        let cells: Vec<&str> = row.split_whitespace().collect();
        assert_eq!(cells[1..3], ["324/324", "594/594"], "{row}");
        let ratio: f64 = cells.last().unwrap().trim_end_matches('x').parse().unwrap();
        assert!((0.9..1.5).contains(&ratio), "{row}");
        assert!(report.contains(&format!("## Case {case}:")), "{report}");
        let n = ["I", "II", "III", "IV"].iter().position(|c| *c == case).unwrap() + 1;
        let model = out.join(format!("case{n}_images/model.hvsw"));
        assert!(blob::decode(&std::fs::read(&model).unwrap()).is_ok());
    }
    assert!(report.contains(&stdout.lines().next().unwrap().to_string()), "{report}");
}

#[test]
fn bad_settings_are_refused_before_anything_is_written() {
    let dir = TempDir::new().unwrap();
    let tr = simulated(dir.path(), 1, "train", "t.csv");
    let m = dir.path().join("m.hvsw");
    let base = ["train", "--data", s(&tr), "-o", s(&m)];
    let run = |extra: &[&str], want: &str| {
        let args: Vec<&str> = base.iter().chain(extra).copied().collect();
        fails(&args, want);
        assert!(!m.exists());
    };
    run(&["--hidden", "0"], "--hidden must be 1..=32");
    run(&["--hidden", "33"], "--hidden must be 1..=32");
    let e = crate::common::stderr_with_code(
        base.iter().chain(&["--restarts", "0"]).copied().collect::<Vec<_>>(),
        2,
    );
    assert!(e.contains("--restarts must be from 1 to 65535, got 0"), "{e}");
    assert!(!m.exists());
    run(&["--threshold=-1"], "--threshold must be a positive percentage");
    run(&["--learning-rate", "0"], "--learning-rate must be a positive number");
    run(&["--threshold", "0.001"], "no restart enrolled");
    fails(
        &["simulate", "--case", "1", "--set", "volume", "--noise-px=-2"],
        "--noise-px must be a finite number >= 0",
    );
    fails(&["simulate", "--case", "7", "--set", "test"], "--case must be 1-4");
}

/// Values the arguments alone show to be wrong are bad usage (exit 2), named, before any
/// work: nothing rendered, no server started, no set read.
#[test]
fn out_of_range_values_are_bad_usage_before_any_work() {
    let dir = TempDir::new().unwrap();
    let out = dir.path().join("out");
    let none = dir.path().join("none");
    let (model, l, r) = (none.join("m.hvsw"), none.join("l.png"), none.join("r.png"));
    let view = ["view", "--model", s(&model), "--left", s(&l), "--right", s(&r)];
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (vec!["render", "--case", "1", "--depths", "0", "-o", s(&out)], "--depths"),
        (vec!["render", "--case", "1", "--depths", "65,-1", "-o", s(&out)], "--depths"),
        (vec!["render", "--case", "1", "--square-cm", "0", "-o", s(&out)], "--square-cm"),
        // Finite but absurd (QA): a board at 10 km, squares of 1e-9 cm.
        (vec!["render", "--case", "1", "--depths", "1e9", "-o", s(&out)], "at most 100000"),
        (vec!["render", "--case", "1", "--square-cm", "1e-9", "-o", s(&out)], "1e-9 cm is outside"),
        (vec!["render", "--case", "1", "--joints", "360,0,0,0,0", "-o", s(&out)], "--joints"),
        ([&view[..], &["--restarts", "0"]].concat(), "--restarts must be from 1 to 65535, got 0"),
        (
            [&view[..], &["--restarts", "1000000000", "--listen", "127.0.0.1:0"]].concat(),
            "--restarts must be from 1 to 65535, got 1000000000",
        ),
        (
            vec!["train", "--data", s(&l), "-o", s(&out), "--restarts", "1000000000"],
            "--restarts must be from 1 to 65535",
        ),
    ];
    for (args, want) in cases {
        let e = crate::common::stderr_with_code(&args, 2);
        assert!(e.starts_with("error: ") && e.contains(want), "{args:?}: {e}");
        assert!(!out.exists(), "{args:?} wrote {}", out.display());
    }
}

/// The README's `--algo bp` and `--threshold` lines: back-propagation without `--arch` trains
/// the thesis' net (the one family it can), and a threshold is judged against the training
/// e_ma `hvs train` reports (the default family's restarts are fitted to synthetic points
/// after they are judged, so their own errors lie above it).
#[test]
fn bp_without_an_arch_and_a_threshold_at_the_reported_error_train() {
    let dir = TempDir::new().unwrap();
    let tr = simulated(dir.path(), 4, "train", "t.csv");
    let bp = dir.path().join("bp.hvsw");
    let out = ok(&["train", "--data", s(&tr), "-o", s(&bp), "--algo", "bp", "--max-cycles", "200"]);
    assert!(out.contains("wrote"), "{out}");
    let b = blob::decode(&std::fs::read(&bp).unwrap()).unwrap();
    assert_eq!(b.family, hvs_shared::runtime::blob::Family::THESIS);
    fails(
        &["train", "--data", s(&tr), "-o", s(&bp), "--algo", "bp", "--arch", "inverse-depth-skip"],
        "back-propagation trains the thesis' sigmoid-output net",
    );
    let m = dir.path().join("m.hvsw");
    let out = ok(&["train", "--data", s(&tr), "-o", s(&m), "--restarts", "3"]);
    let reported: f64 = out
        .split("training e_ma ")
        .nth(1)
        .and_then(|t| t.split_whitespace().next())
        .and_then(|t| t.parse().ok())
        .unwrap_or_else(|| panic!("{out}"));
    let want = std::fs::read(&m).unwrap();
    let t = format!("{}", reported + 0.0001);
    ok(&["train", "--data", s(&tr), "-o", s(&m), "--restarts", "3", "--threshold", &t]);
    assert_eq!(std::fs::read(&m).unwrap(), want);
    let t = format!("{}", reported - 0.0001);
    std::fs::remove_file(&m).unwrap();
    fails(
        &["train", "--data", s(&tr), "-o", s(&m), "--restarts", "3", "--threshold", &t],
        &format!("{reported:.4} %, above the threshold"),
    );
    assert!(!m.exists());
}
