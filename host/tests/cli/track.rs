//! `hvs track` driven from outside: the log's columns and rows, the same log bytes for the
//! same scene and seed, `--record`, the rate line, and the refusals (bad scene field, bad
//! flags, qemu).

use crate::common::{
    csv_rows, fails, ok, small_model as model, small_scene as scene, stderr_with_code, Scratch,
};
use std::fs;

#[test]
fn track_logs_every_frame_and_repeats_its_bytes() {
    let dir = Scratch::new();
    let (m, sc) = (model(&dir), scene(&dir, ""));
    let (a, b) = (dir.p("a.csv"), dir.p("b.csv"));
    let rec = dir.p("rec");
    let args = |log: &str| {
        vec![
            "track",
            "--model",
            &m,
            "--scene",
            &sc,
            "--seconds",
            "0.2",
            "--log",
            log,
            "--seed",
            "4",
        ]
        .into_iter()
        .map(String::from)
        .collect::<Vec<_>>()
    };
    let mut first = args(&a);
    first.extend(["--record".to_string(), rec.clone()]);
    ok(&first.iter().map(String::as_str).collect::<Vec<_>>());
    // The run's rate on stderr: perception and control, and the render on its own.
    let err = stderr_with_code(args(&b), 0);
    assert!(
        err.contains("perception and control: ") && err.contains("rendering the pair: "),
        "{err}"
    );
    let (ta, tb) = (fs::read_to_string(&a).unwrap(), fs::read_to_string(&b).unwrap());
    assert_eq!(ta, tb, "same scene and seed, same log bytes");
    let rows = csv_rows(&ta, "t_s,frame,status,u_l,v_l,u_r,v_r,x,y,z,neck_pan,neck_tilt,eye_tilt,left_eye_pan,right_eye_pan,err_l_px,err_r_px");
    assert_eq!(rows.len(), 6, "0.2 s at 30 fps");
    for (k, r) in rows.iter().enumerate() {
        assert_eq!(r.len(), 17);
        assert_eq!(r[1], k.to_string());
        assert!(["tracking", "image_only", "lost"].contains(&r[2]), "{r:?}");
        for j in &r[10..15] {
            let j: f64 = j.parse().unwrap();
            assert!(j.abs() <= 60.0);
        }
    }
    // The recording: six pairs and their joint columns.
    let caps = fs::read_to_string(format!("{rec}/CAPTURES.csv")).unwrap();
    assert!(caps
        .starts_with("left,right,z,x,y,neck_pan,neck_tilt,eye_tilt,left_eye_pan,right_eye_pan\n"));
    assert_eq!(caps.lines().count(), 7);
    assert!(fs::metadata(format!("{rec}/left0005.png")).is_ok());
    // A pixel target in the image's corner, where no window fits: never found, and said so.
    let mut corner = args(&dir.p("c.csv"));
    corner.extend(["--target".to_string(), "1,1".to_string()]);
    let err = stderr_with_code(corner, 0);
    assert!(
        err.contains("0 tracking") && err.contains("warning: --target 1,1: no object"),
        "{err}"
    );
    // The small model takes the pixels only: its depths do not follow the eyes, and the run
    // says so.
    assert!(err.contains("the model takes the four pixels only"), "{err}");
}

#[test]
fn track_refuses_bad_input_with_one_clear_line() {
    let dir = Scratch::new();
    let m = dir.p("m.hvsw");
    fs::write(&m, b"not a model").unwrap();
    let bad = scene(&dir, r#", "colour": 3"#);
    let log = dir.p("log.csv");
    let base = |sc: &str, extra: &[&str]| {
        let mut v = vec!["track", "--model", &m, "--scene", sc, "--log", &log];
        if !extra.contains(&"--seconds") {
            v.extend(["--seconds", "0.1"]);
        }
        v.extend_from_slice(extra);
        v.into_iter().map(String::from).collect::<Vec<_>>()
    };
    let run = |v: Vec<String>, want: &str| {
        fails(&v.iter().map(String::as_str).collect::<Vec<_>>(), want);
    };
    // Bad usage: exit code 2, the flag named.
    let usage = |v: Vec<String>, want: &str| {
        let e = stderr_with_code(&v, 2);
        assert!(e.contains(want) && e.lines().count() == 1, "{e}");
    };
    run(base(&bad, &[]), "m.hvsw");
    usage(base(&bad, &["--seconds", "0"]), "--seconds");
    usage(base(&bad, &["--target", "1,x"]), "--target");
    // The value as given, not as an `f32` rounds it (4294967300).
    usage(base(&bad, &["--lead-frames", "4294967296"]), "got 4.294967296e9");
    usage(base(&bad, &["--correction-gain", "1.1"]), "got 1.1");
    // With a valid model the scene's unknown field is named.
    let good = model(&dir);
    let v: Vec<String> =
        vec!["track", "--model", &good, "--scene", &bad, "--seconds", "0.1", "--log", &log]
            .into_iter()
            .map(String::from)
            .collect();
    run(v, "unknown field `colour`");
    let sc = scene(&dir, "");
    let v: Vec<String> = vec![
        "track",
        "--model",
        &good,
        "--scene",
        &sc,
        "--seconds",
        "0.1",
        "--log",
        &log,
        "--target",
        "500,10",
    ]
    .into_iter()
    .map(String::from)
    .collect();
    usage(v, "outside the 160x120 left image");
    // `model` on the good scene for `seconds`.
    let on_scene = |model: &str, seconds: &str| -> Vec<String> {
        ["track", "--model", model, "--scene", &sc, "--seconds", seconds, "--log", &log]
            .map(String::from)
            .to_vec()
    };
    // Less than one frame: nothing would run.
    usage(on_scene(&good, "0.01"), "less than one frame at 30 frames/s");
    // A tiny value is quoted as given, not as 300 digits.
    usage(on_scene(&good, "1e-300"), "--seconds: 1e-300 s is less than one frame");
    // A model trained on points of images of another size than the scene's cameras make: its
    // depths do not hold there (as `hvs depth` and `hvs locate` refuse), and no log is written.
    let text = fs::read_to_string(dir.p("train.csv")).unwrap();
    let mut lines = text.lines();
    let mut sized = format!("{},image_width,image_height\n", lines.next().unwrap());
    for l in lines {
        sized.push_str(&format!("{l},320,240\n"));
    }
    fs::write(dir.p("sized.csv"), sized).unwrap();
    let other = dir.p("other_size.hvsw");
    ok(&["train", "--data", &dir.p("sized.csv"), "-o", &other, "--restarts", "1"]);
    run(
        on_scene(&other, "0.1"),
        "the images are 160x120 px, the model was trained on 320x240 px images",
    );
    assert!(!std::path::Path::new(&log).exists());
    // Heads and cameras: one head; real cameras need a head's port; a port that is not
    // there is named; a build without V4L2 says how to get one.
    let with = |more: &[&str]| {
        let mut v: Vec<String> = ["track", "--model", &good, "--seconds", "0.1", "--log", &log]
            .map(String::from)
            .to_vec();
        v.extend(more.iter().map(|s| s.to_string()));
        v
    };
    let e = stderr_with_code(with(&["--scene", &sc, "--port", "/dev/none", "--head", "qemu"]), 2);
    assert!(e.contains("--port and --head qemu"), "{e}");
    stderr_with_code(with(&["--cameras", "v4l:0,1"]), 2);
    stderr_with_code(with(&["--scene", &sc, "--cameras", "v4l:0,1", "--port", "/dev/x"]), 2);
    run(with(&["--scene", &sc, "--port", "/dev/hvs-no-such-port"]), "/dev/hvs-no-such-port");
    if !cfg!(feature = "v4l") {
        run(with(&["--cameras", "v4l:0,1", "--port", "/dev/x"]), "--features v4l");
    }
    assert!(fs::metadata(&log).is_err(), "no log written on refusal");
}
