//! `hvs render` and `hvs board detect`: rendered stereo photos into a training set, through the
//! built binary, and every kind of bad input named and skipped or refused.

use crate::common::{
    csv_rows, detect_args, hvs, locate_args, ok, s, stderr_with_code, train_restarts,
};
use std::collections::HashMap;
use std::path::Path;

fn render(dir: &Path, extra: &[&str]) {
    let mut args = vec!["render", "--case", "1", "-o", s(dir)];
    args.extend_from_slice(extra);
    hvs().args(&args).assert().success();
}

/// `(capture, i, j) -> [u_l, v_l, u_r, v_r]` of a points or truth CSV with those columns
/// (truth.csv names captures by their left image `leftNN.png`).
fn corners(path: &Path) -> HashMap<(String, u32, u32), [f64; 4]> {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let h: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |n: &str| h.iter().position(|c| *c == n).unwrap();
    let (cap, i, j) = if h.contains(&"capture") {
        (col("capture"), col("i"), col("j"))
    } else {
        (col("left"), col("i"), col("j"))
    };
    let px = ["u_l", "v_l", "u_r", "v_r"].map(col);
    lines
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            let key = f[cap]
                .trim_start_matches("left")
                .trim_end_matches(".png")
                .trim_start_matches('0')
                .to_string();
            (
                (key, f[i].parse().unwrap(), f[j].parse().unwrap()),
                px.map(|k| f[k].parse::<f64>().unwrap()),
            )
        })
        .collect()
}

#[test]
fn rendered_boards_become_a_training_set_with_sub_pixel_corners() {
    let dir = tempfile::tempdir().unwrap();
    let shots = dir.path().join("shots");
    render(&shots, &["--depths", "65,115,165", "--seed", "2"]);
    for f in ["left01.png", "right03.png", "captures.csv", "truth.csv", "board.json"] {
        assert!(shots.join(f).is_file(), "{f}");
    }
    let caps = std::fs::read_to_string(shots.join("captures.csv")).unwrap();
    assert_eq!(caps.lines().next(), Some("left,right,z,x,y"));
    assert_eq!(caps.lines().count(), 4);
    // Same seed, same bytes; another seed, other noise.
    let again = dir.path().join("again");
    render(&again, &["--depths", "65,115,165", "--seed", "2"]);
    let other = dir.path().join("other");
    render(&other, &["--depths", "65,115,165", "--seed", "3"]);
    let img = |d: &Path| std::fs::read(d.join("left02.png")).unwrap();
    assert_eq!(img(&shots), img(&again));
    assert_ne!(img(&shots), img(&other));

    let points = dir.path().join("points.csv");
    let ov = dir.path().join("ov");
    let (board, caps) = (shots.join("board.json"), shots.join("captures.csv"));
    let mut args = detect_args(&board, &caps, &points);
    args.extend(["--overlays", s(&ov)]);
    let summary = stderr_with_code(&args, 0);
    assert!(summary.contains("54/54 corners"), "{summary}");
    assert!(summary.contains("3 of 3 pairs, 162 corners"), "{summary}");
    let text = std::fs::read_to_string(&points).unwrap();
    assert_eq!(
        text.lines().next(),
        Some("capture,i,j,u_l,v_l,u_r,v_r,x,y,z,image_width,image_height")
    );
    assert_eq!(text.lines().count(), 1 + 3 * 54);
    // Board coordinates of the convention: (0, 0) top-left, 6 cm squares, centred on the axis.
    let row1: Vec<&str> = text.lines().nth(1).unwrap().split(',').collect();
    assert_eq!(&row1[..3], ["1", "0", "0"]);
    assert_eq!(&row1[7..], ["-24", "-15", "65", "640", "480"]);
    // Every detected corner is within 0.1 px of the exact one, under the same label.
    let got = corners(&points);
    let truth = corners(&shots.join("truth.csv"));
    assert_eq!(got.len(), 162);
    let mut worst = 0.0f64;
    for (k, p) in &got {
        let t = truth.get(k).unwrap_or_else(|| panic!("{k:?} not in the truth"));
        for c in 0..4 {
            worst = worst.max((p[c] - t[c]).abs());
        }
    }
    assert!(worst < 0.1, "worst corner error {worst} px");
    for f in ["01-left-left01.overlay.png", "03-right-right03.overlay.png"] {
        assert!(ov.join(f).is_file(), "{f}");
    }
    // hvs train takes it as it is.
    let model = dir.path().join("m.hvsw");
    train_restarts(&points, &model, "2");
    let info = ok(&["info", s(&model)]);
    assert!(info.contains("matcher"), "{info}");
    assert!(info.contains("640x480"), "the images' size is recorded: {info}");
    // ... and a pair of another size is refused by locate, naming both sizes.
    let half = dir.path().join("half.png");
    image::imageops::resize(
        &image::open(shots.join("left01.png")).unwrap().to_luma8(),
        320,
        240,
        image::imageops::FilterType::Triangle,
    )
    .save(&half)
    .unwrap();
    let e =
        stderr_with_code(locate_args(&["locate"], &model, &half, &half, &["--at", "160,120"]), 1);
    assert!(e.contains("320x240") && e.contains("640x480"), "{e}");
}

/// Runs `board detect` expecting exit 1; returns stderr.
fn detect_fails(board: &Path, captures: &Path, out: &Path) -> String {
    let e = stderr_with_code(detect_args(board, captures, out), 1);
    assert!(!e.contains("panicked"), "{e}");
    assert!(!out.exists(), "nothing is written on failure");
    e
}

#[test]
fn bad_images_and_boards_are_named_skipped_or_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    render(&d.join("r"), &["--depths", "85", "--seed", "1"]);
    let copy = |from: &str, to: &str| std::fs::copy(d.join("r").join(from), d.join(to)).unwrap();
    copy("left01.png", "l.png");
    copy("right01.png", "r.png");
    copy("board.json", "board.json");
    // A truncated PNG, a blank picture, an image of another size.
    let png = std::fs::read(d.join("l.png")).unwrap();
    std::fs::write(d.join("cut.png"), &png[..png.len() / 2]).unwrap();
    image::GrayImage::from_pixel(640, 480, image::Luma([128u8])).save(d.join("blank.png")).unwrap();
    image::GrayImage::from_pixel(320, 240, image::Luma([128u8])).save(d.join("small.png")).unwrap();
    let board = d.join("board.json");
    let out = d.join("points.csv");
    let cases = [
        ("missing.png,r.png", "missing.png"),
        ("cut.png,r.png", "cut.png"),
        ("blank.png,r.png", "left"),
        ("l.png,small.png", "size"),
    ];
    for (row, want) in cases {
        let caps = d.join("caps.csv");
        std::fs::write(&caps, format!("left,right,z\n{row},85\n")).unwrap();
        let e = detect_fails(&board, &caps, &out);
        assert!(e.contains("caps.csv:2"), "{row}: {e}");
        assert!(e.contains(want), "{row}: {e}");
        assert!(e.contains("no usable stereo pair"), "{row}: {e}");
    }
    // A wrong inner_corners: the board is not found as described.
    let wrong = d.join("wrong.json");
    std::fs::write(
        &wrong,
        r#"{"pattern": "chessboard", "inner_corners": [7, 4], "square_cm": 6.0}"#,
    )
    .unwrap();
    let caps = d.join("caps.csv");
    std::fs::write(&caps, "left,right,z\nl.png,r.png,85\n").unwrap();
    let e = detect_fails(&wrong, &caps, &out);
    assert!(e.contains("caps.csv:2") && e.contains("skipped"), "{e}");
    // A bad board file names itself.
    let bad = d.join("bad.json");
    std::fs::write(&bad, r#"{"pattern": "chessboard", "inner_corners": [9]}"#).unwrap();
    let e = detect_fails(&bad, &caps, &out);
    assert!(e.contains("bad.json"), "{e}");
    // One good pair and one bad one: the good one is written, the bad one named.
    std::fs::write(&caps, "left,right,z\nl.png,r.png,85\nmissing.png,r.png,95\n").unwrap();
    let e = stderr_with_code(detect_args(&board, &caps, &out), 0);
    assert!(e.contains("caps.csv:3") && e.contains("missing.png"), "{e}");
    assert_eq!(std::fs::read_to_string(&out).unwrap().lines().count(), 1 + 54);
}

#[test]
fn locate_finds_board_corners_in_a_new_pair_and_names_what_it_refuses() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let shots = d.join("shots");
    render(&shots, &["--seed", "6"]);
    let points = d.join("points.csv");
    ok(&detect_args(&shots.join("board.json"), &shots.join("captures.csv"), &points));
    let model = d.join("m.hvsw");
    train_restarts(&points, &model, "2");
    let test = d.join("test");
    render(&test, &["--seed", "7", "--depths", "95", "--centre", "-3,2"]);
    // The test pair's true corners, plus a point outside the image.
    let truth = std::fs::read_to_string(test.join("truth.csv")).unwrap();
    let mut px = String::from("u_l,v_l,tag,true_u_r,true_v_r\n");
    for l in truth.lines().skip(1) {
        let f: Vec<&str> = l.split(',').collect();
        px.push_str(&format!("{},{},c{}_{},{},{}\n", f[6], f[7], f[1], f[2], f[8], f[9]));
    }
    px.push_str("-50,10,off,0,0\n");
    let pix = d.join("px.csv");
    std::fs::write(&pix, px).unwrap();
    let (l, r) = (test.join("left01.png"), test.join("right01.png"));
    let out = d.join("out.csv");
    let overlay = d.join("ov.png");
    ok(&locate_args(
        &["locate"],
        &model,
        &l,
        &r,
        &["--points", s(&pix), "-o", s(&out), "--overlay", s(&overlay)],
    ));
    assert!(overlay.is_file());
    let text = std::fs::read_to_string(&out).unwrap();
    let rows = csv_rows(&text, "u_l,v_l,u_r,v_r,x,y,z,score,status,tag,true_u_r,true_v_r");
    assert_eq!(rows.len(), 54 + 1);
    let (mut okc, mut good) = (0, 0);
    for f in &rows[..54] {
        if f[8] == "ok" {
            okc += 1;
            let e = (f[2].parse::<f64>().unwrap() - f[10].parse::<f64>().unwrap())
                .hypot(f[3].parse::<f64>().unwrap() - f[11].parse::<f64>().unwrap());
            // Dense matches interpolated between pixels: every returned corner within 1 px
            // (the depth within 2 %), nearly all within half a pixel.
            assert!(e < 1.0, "{f:?}");
            good += usize::from(e < 0.5);
            let z: f64 = f[6].parse().unwrap();
            assert!((z - 95.0).abs() < 1.9, "{f:?}");
        } else {
            assert!(f[2..7].iter().all(|v| v.is_empty()), "{f:?}");
            assert!(["no_match", "out_of_depth_range"].contains(&f[8]), "{f:?}");
        }
    }
    assert!(okc >= 40, "{okc} of 54 returned");
    assert!(good * 10 >= okc * 9, "{good} of {okc} returned corners within 0.5 px");
    assert_eq!(rows[54][8], "outside");
    // `hvs locate --points` of the pixels file as it now is.
    let locate_points = || {
        crate::common::hvs()
            .args(locate_args(&["locate"], &model, &l, &r, &["--points", s(&pix)]))
            .output()
            .unwrap()
    };
    // NaN is refused as infinities are (one rule with every CSV input), naming the line.
    for bad in ["NaN", "inf"] {
        std::fs::write(&pix, format!("u_l,v_l\n300,200\n{bad},10\n")).unwrap();
        let o = locate_points();
        assert_eq!(o.status.code(), Some(1));
        let e = String::from_utf8_lossy(&o.stderr).into_owned();
        assert!(e.contains(":3: column \"u_l\"") && e.contains("is not a finite number"), "{e}");
    }
    // Columns the output writes itself are replaced, and the user is told.
    std::fs::write(&pix, "u_l,v_l,z,tag\n300,200,95,a\n").unwrap();
    let o = locate_points();
    assert_eq!(o.status.code(), Some(0));
    let e = String::from_utf8_lossy(&o.stderr).into_owned();
    assert!(e.contains("px.csv: its columns z are replaced by the located values"), "{e}");
    let text = String::from_utf8_lossy(&o.stdout).into_owned();
    assert!(text.starts_with("u_l,v_l,u_r,v_r,x,y,z,score,status,tag\n"), "{text}");
    // One point, printed.
    let one = ok(&locate_args(&["locate"], &model, &l, &r, &["--at", "300,200"]));
    assert!(one.contains("z=") || one.contains("no trustworthy match"), "{one}");
    // A point outside the image asked for alone is bad usage (exit 2, as `hvs track
    // --target`'s), naming the image's size.
    let (w, h) = image::image_dimensions(&l).unwrap();
    // `hvs head look --at` the same, before any matching and before the head is asked.
    let look = ["head", "--connect", "tcp:127.0.0.1:9", "look"];
    for verb in [&["locate"][..], &look[..]] {
        for at in [format!("{w},10"), "-0.6,3".to_string(), "9999,1".to_string()] {
            let args = locate_args(verb, &model, &l, &r, &["--at", &at]);
            let e = crate::common::stderr_with_code(&args, 2);
            assert!(e.contains(&format!("outside the {w}x{h} left image")), "{verb:?}: {e}");
            assert!(e.contains("left01.png") && e.lines().count() == 1, "{e}");
        }
    }
    // Images of different sizes; a model without the matcher's geometry (a v1 blob).
    image::GrayImage::from_pixel(320, 240, image::Luma([90u8])).save(d.join("small.png")).unwrap();
    let e = crate::common::fails(
        &locate_args(&["locate"], &model, &l, &d.join("small.png"), &["--at", "1,1"]),
        "differ in size",
    );
    assert!(e.contains("small.png"), "{e}");
    let v1 = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/tests/golden/v1_4_5_3.hvsw");
    crate::common::fails(
        &locate_args(&["locate"], &v1, &l, &r, &["--at", "1,1"]),
        "retrain it with `hvs train`",
    );
}
