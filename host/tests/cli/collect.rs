//! `hvs collect` driven from outside: the virtual head visits the postures with the board in
//! place, keeps the pairs that see the whole board (with the joints it reports), writes a
//! capture set `hvs board detect` reads, repeats its bytes for the same seed, and refuses bad
//! input naming the file, line and column.

use crate::common::{csv_rows, fails, ok, stderr_with_code, Scratch};
use std::fs;

const BOARD: &str = r#"{"pattern": "chessboard", "inner_corners": [7, 5], "square_cm": 4.0}"#;

fn inputs(dir: &Scratch, positions: &str) -> (String, String, String) {
    let (b, p, s) = (dir.p("board.json"), dir.p("positions.csv"), dir.p("scene.json"));
    fs::write(&b, BOARD).unwrap();
    fs::write(&p, positions).unwrap();
    fs::write(
        &s,
        r#"{"rig": {"case": 3}, "camera_fps": 30, "background": {"z_cm": 300, "texture_seed": 1}}"#,
    )
    .unwrap();
    (b, p, s)
}

fn collect(b: &str, p: &str, s: &str, out: &str, seed: &str) -> String {
    ok(&[
        "collect",
        "--board",
        b,
        "--positions",
        p,
        "--postures",
        "lattice",
        "--posture-levels",
        "3,1,1,1,1",
        "--scene",
        s,
        "--supersample",
        "2",
        "--seed",
        seed,
        "-o",
        out,
    ])
}

#[test]
fn collect_keeps_the_postures_that_see_the_board_and_board_detect_reads_them() {
    let dir = Scratch::new();
    // Near boards (outlines 36 x 28 cm at 45 and 47 cm): the wide case III cameras see them
    // whole looking ahead, not with the neck turned 30 degrees.
    let (b, p, s) = inputs(&dir, "x,y,z\n0,0,45\n0,-1,47\n");
    let (out, again) = (dir.p("set"), dir.p("again"));
    collect(&b, &p, &s, &out, "3");
    let text = fs::read_to_string(format!("{out}/CAPTURES.csv")).unwrap();
    let rows =
        csv_rows(&text, "left,right,z,x,y,neck_pan,neck_tilt,eye_tilt,left_eye_pan,right_eye_pan");
    // Neck pan -30, 0, +30 at each placement (vergence 5 degrees, the middle of its range).
    assert_eq!(rows.len(), 2, "{text}");
    for (r, z) in rows.iter().zip(["45", "47"]) {
        assert_eq!(r[2], z);
        assert_eq!(&r[5..], ["0", "0", "0", "-2.52", "2.52"], "the joints the head reports");
        for img in &r[..2] {
            assert!(fs::metadata(format!("{out}/{img}")).unwrap().len() > 1000);
        }
    }
    // The same seed gives the same bytes.
    collect(&b, &p, &s, &again, "3");
    for f in ["CAPTURES.csv", "board.json", rows[1][0], rows[1][1]] {
        assert_eq!(
            fs::read(format!("{out}/{f}")).unwrap(),
            fs::read(format!("{again}/{f}")).unwrap(),
            "{f}"
        );
    }
    // board detect turns it into a nine-input training set: every corner of both pairs.
    let points = dir.p("points.csv");
    ok(&[
        "board",
        "detect",
        "--board",
        &format!("{out}/board.json"),
        "--captures",
        &format!("{out}/CAPTURES.csv"),
        "-o",
        &points,
    ]);
    let pts = fs::read_to_string(&points).unwrap();
    let header = pts.lines().next().unwrap();
    assert!(header.contains("neck_pan") && header.contains("right_eye_pan"), "{header}");
    assert_eq!(pts.lines().count(), 1 + 2 * 35, "{header}");
}

#[test]
fn collect_refuses_bad_input_naming_it() {
    let dir = Scratch::new();
    let (b, p, s) = inputs(&dir, "x,y,z\n0,0,70\n0,zero,95\n");
    let out = dir.p("set");
    let base = |extra: &[&str]| {
        let mut v = vec!["collect", "--board", &b, "--positions", &p, "-o", &out];
        v.extend_from_slice(extra);
        v.into_iter().map(String::from).collect::<Vec<_>>()
    };
    let run = |extra: &[&str], want: &str| {
        let args = base(extra);
        fails(&args.iter().map(String::as_str).collect::<Vec<_>>(), want)
    };
    let e = run(&["--postures", "grid", "--scene", &s], "positions.csv:3");
    assert!(e.contains("\"y\""), "{e}");
    let usage = |extra: &[&str], want: &str| {
        let e = stderr_with_code(base(extra), 2);
        assert!(e.contains(want), "{e}");
    };
    usage(&["--postures", "grid"], "--scene");
    // A real head: the same input checks, then the cameras (a build without V4L2 says how
    // to get them; a head port that is not there is named).
    let real = ["--postures", "grid", "--port", "/dev/hvs-no-port", "--cameras", "v4l:0,1"];
    run(&real, "positions.csv:3");
    usage(&["--postures", "grid", "--port", "/dev/hvs-no-port"], "--cameras");
    fs::write(&p, "x,y,z\n0,0,70\n").unwrap();
    let e = run(&real, "");
    assert!(
        e.contains("--features v4l") || e.contains("/dev/video0") || e.contains("/dev/hvs-no-port"),
        "{e}"
    );
    assert!(!std::path::Path::new(&out).join("CAPTURES.csv").exists());
    usage(&["--scene", &s], "--postures");
    usage(&["--postures", "grid", "--posture-levels", "3,3", "--scene", &s], "five counts");
    usage(&["--postures", "random", "--posture-count", "0", "--scene", &s], "--posture-count");
    usage(
        &["--postures", "grid", "--settle-ms", "99999999999", "--scene", &s],
        "--settle-ms 99999999999: the settle time must be 0 to 60 s",
    );
    // A board far out to the side: no posture sees it, and nothing is written.
    fs::write(&p, "x,y,z\n500,0,70\n").unwrap();
    run(
        &["--postures", "lattice", "--posture-levels", "1,1,1,1,1", "--scene", &s],
        "no posture saw the whole board",
    );
    // Not even the folder, which this run would have made.
    assert!(!std::path::Path::new(&out).exists(), "{out} left behind");
}

#[test]
fn collect_refuses_an_input_among_the_files_it_writes() {
    let dir = Scratch::new();
    let (b, p, s) = inputs(&dir, "x,y,z\n0,0,45\n");
    let out = dir.p("set");
    fs::create_dir(&out).unwrap();
    // The scene and the placements named as images the set writes: refused before the run,
    // kept as they were.
    let (scene_in, positions_in) =
        (format!("{out}/left_001_0002.png"), format!("{out}/right_001_0002.png"));
    fs::copy(&s, &scene_in).unwrap();
    fs::copy(&p, &positions_in).unwrap();
    for (flag, file, pp, ss) in
        [("--scene", &scene_in, &p, &scene_in), ("--positions", &positions_in, &positions_in, &s)]
    {
        let before = fs::read(file).unwrap();
        let e = stderr_with_code(
            [
                "collect",
                "--board",
                &b,
                "--positions",
                pp,
                "--postures",
                "lattice",
                "--posture-levels",
                "3,1,1,1,1",
                "--scene",
                ss,
                "--supersample",
                "2",
                "-o",
                &out,
            ],
            2,
        );
        assert!(e.contains(&format!("the set's files would replace the {flag} file")), "{e}");
        assert_eq!(fs::read(file).unwrap(), before, "{flag}");
        assert!(!std::path::Path::new(&out).join("CAPTURES.csv").exists());
    }
}

/// Issue 27's goal through the CLI, as the README's worked example runs it: the case III
/// virtual head collects the 9 x 6 board at the thesis' six depths at grid postures, `hvs
/// board detect` and `hvs train` (its defaults) make a posture-aware model, and on test
/// captures of other placements at random postures (`--seed 4`, held out from every choice of
/// the training settings) it is within 1.10 x of the floor (optimal triangulation with the
/// true cameras at each row's posture, `hvs eval --case 3`) and within 1.15 x in the worst
/// posture band (the posture study's bands). About 6 minutes in release:
/// `cargo test --release -p hvs-host --test cli collected_posture_model -- --ignored --nocapture`.
#[test]
#[ignore = "about 6 minutes in release: the README's hvs collect example end to end"]
fn collected_posture_model_is_near_the_floor() {
    let dir = Scratch::new();
    let board = r#"{"pattern": "chessboard", "inner_corners": [9, 6], "square_cm": 6.0}"#;
    let (b, s) = (dir.p("board.json"), dir.p("scene.json"));
    fs::write(&b, board).unwrap();
    fs::write(
        &s,
        r#"{"rig": {"case": 3}, "camera_fps": 30, "background": {"z_cm": 300, "texture_seed": 1}}"#,
    )
    .unwrap();
    let (train_pos, test_pos) = (dir.p("positions.csv"), dir.p("test_positions.csv"));
    fs::write(&train_pos, "x,y,z\n0,0,65\n0,0,85\n0,0,105\n0,0,125\n0,0,145\n0,0,165\n").unwrap();
    fs::write(&test_pos, "x,y,z\n-6,5,80\n4,-4,100\n-3,2,120\n6,3,140\n-2,-5,160\n").unwrap();
    let set = |positions: &str, postures: &[&str], seed: &str, name: &str| -> String {
        let out = dir.p(name);
        let mut args = vec!["collect", "--board", &b, "--positions", positions];
        args.extend_from_slice(postures);
        args.extend_from_slice(&["--scene", &s, "--seed", seed, "-o", &out]);
        ok(&args);
        let points = dir.p(&format!("{name}.csv"));
        let (bj, caps) = (format!("{out}/board.json"), format!("{out}/CAPTURES.csv"));
        ok(&["board", "detect", "--board", &bj, "--captures", &caps, "-o", &points]);
        points
    };
    let train = set(&train_pos, &["--postures", "grid"], "1", "set");
    let test = set(&test_pos, &["--postures", "random", "--posture-count", "60"], "4", "test");
    let model = dir.p("posture.hvsw");
    ok(&["train", "--data", &train, "-o", &model]);
    let json = ok(&["eval", "--model", &model, "--data", &test, "--case", "3", "--json"]);
    let v: serde_json::Value = serde_json::from_str(&json).unwrap();
    let methods = v["evaluation"]["methods"].as_array().unwrap();
    let mean = |m: &serde_json::Value| m["mean"]["e_ma_pct"].as_f64().unwrap();
    let floor = mean(methods.iter().find(|m| m["name"] == "optimal").expect("an optimal method"));
    let net = mean(methods.iter().find(|m| m["name"] == "network").expect("the model"));
    println!("mean depth e_ma: model {net:.4} %, floor {floor:.4} %, {:.3} x", net / floor);
    assert!(net <= 1.10 * floor, "{net} against the floor's {floor}");
    // Per posture band (the posture study's bands), as `hvs eval` prints them.
    let bands = v["posture_bands"].as_array().expect("posture bands of a posture-aware model");
    assert!(bands.len() > 10, "{json}");
    for band in bands {
        let ratio = band["ratio"].as_f64().unwrap();
        println!("{} {}: {ratio:.3} x", band["term"], band["band"]);
        assert!(ratio <= 1.15, "{band}");
    }
}
