//! The image commands keep the CLI's contract (README "Using the CLI"): an output that is an
//! input is refused before any work, outputs never collide or get lost, nothing is written
//! when a command fails, results that cannot be right are refused with the reason, every
//! image input is bounded in size and time, bad usage exits 2. Through the built binary.

use crate::common::{detect_args, hvs, locate_args, s, stderr_with_code};
use std::path::{Path, PathBuf};

/// A rendered capture set of four pairs at 65-125 cm in `dir/shots`.
fn shots(dir: &Path) -> PathBuf {
    let shots = dir.join("shots");
    hvs()
        .args(["render", "--case", "1", "--depths", "65,85,105,125", "-o", s(&shots)])
        .assert()
        .success();
    shots
}

/// `hvs board detect` with the set's board and `captures`, writing `out`, plus `extra`.
/// [`shots`] and their corners detected into `points.csv`: `(shots, points)`.
fn detected_shots(dir: &Path) -> (PathBuf, PathBuf) {
    let (shots, points) = (shots(dir), dir.join("points.csv"));
    let o = detect(&shots, "captures.csv", &points, &[]);
    assert!(o.status.success(), "{}", err(&o));
    (shots, points)
}

fn detect(shots: &Path, captures: &str, out: &Path, extra: &[&str]) -> std::process::Output {
    let (b, c) = (shots.join("board.json"), shots.join(captures));
    let mut args = detect_args(&b, &c, out);
    args.extend_from_slice(extra);
    hvs().args(&args).output().unwrap()
}

fn err(o: &std::process::Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// The one error line of a failed run (exit `code`), no panic.
fn one_error(o: &std::process::Output, code: i32) -> String {
    assert_eq!(o.status.code(), Some(code), "{}", err(o));
    let e = err(o);
    let last = e.lines().last().unwrap_or_default().to_string();
    assert!(last.starts_with("error: "), "{e}");
    assert!(!e.contains("panicked"), "{e}");
    last
}

/// A captures file `name` in `shots` with `rows` (after the header `left,right,z`).
fn captures(shots: &Path, name: &str, rows: &[&str]) {
    let mut t = String::from("left,right,z\n");
    for r in rows {
        t.push_str(r);
        t.push('\n');
    }
    std::fs::write(shots.join(name), t).unwrap();
}

#[test]
fn board_detect_never_overwrites_an_input() {
    let dir = tempfile::tempdir().unwrap();
    let shots = shots(dir.path());
    std::fs::create_dir(shots.join("sub")).unwrap();
    for out in ["captures.csv", "board.json", "left03.png", "sub/../right02.png"] {
        let path = shots.join(out);
        let before = std::fs::read(&path).unwrap();
        let o = detect(&shots, "captures.csv", &path, &[]);
        let e = one_error(&o, 1);
        assert!(e.contains("input (it would be overwritten)"), "{out}: {e}");
        assert_eq!(std::fs::read(&path).unwrap(), before, "{out} changed");
    }
    // An input image named like an overlay of another image stays as it was.
    std::fs::copy(shots.join("right01.png"), shots.join("left01.overlay.png")).unwrap();
    captures(
        &shots,
        "named.csv",
        &["left01.png,left01.overlay.png,65", "left02.png,right02.png,85"],
    );
    let before = std::fs::read(shots.join("left01.overlay.png")).unwrap();
    let o = detect(&shots, "named.csv", &dir.path().join("p.csv"), &["--overlays", s(&shots)]);
    assert!(o.status.success(), "{}", err(&o));
    assert_eq!(std::fs::read(shots.join("left01.overlay.png")).unwrap(), before);
}

#[test]
fn overlays_of_images_with_one_stem_are_all_written() {
    let dir = tempfile::tempdir().unwrap();
    let shots = shots(dir.path());
    for (sub, k) in [("a", "01"), ("b", "02")] {
        std::fs::create_dir(shots.join(sub)).unwrap();
        std::fs::copy(shots.join(format!("left{k}.png")), shots.join(sub).join("img.png")).unwrap();
        std::fs::copy(shots.join(format!("right{k}.png")), shots.join(sub).join("r.png")).unwrap();
    }
    captures(&shots, "stems.csv", &["a/img.png,a/r.png,65", "b/img.png,b/r.png,85"]);
    let ov = dir.path().join("ov");
    let o = detect(&shots, "stems.csv", &dir.path().join("p.csv"), &["--overlays", s(&ov)]);
    assert!(o.status.success(), "{}", err(&o));
    let mut names: Vec<String> = std::fs::read_dir(&ov)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    assert_eq!(
        names,
        [
            "01-left-img.overlay.png",
            "01-right-r.overlay.png",
            "02-left-img.overlay.png",
            "02-right-r.overlay.png"
        ]
    );
}

#[test]
fn a_failing_run_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let shots = shots(dir.path());
    let points = dir.path().join("points.csv");
    std::fs::write(&points, "old").unwrap();
    let file = dir.path().join("file");
    std::fs::write(&file, "").unwrap();
    for bad in [s(&file), "/dev/null", "/nonexistent/dir/ov"] {
        let o = detect(&shots, "captures.csv", &points, &["--overlays", bad]);
        let e = one_error(&o, 1);
        assert!(e.contains("--overlays"), "{e}");
        assert!(!e.contains("File exists"), "{e}");
        assert_eq!(std::fs::read_to_string(&points).unwrap(), "old", "{bad}");
    }
    // hvs render into an existing file: refused up front, saying what is wrong.
    let o = hvs().args(["render", "--case", "1", "-o", s(&file)]).output().unwrap();
    let e = one_error(&o, 1);
    assert!(e.contains("is not a directory") && !e.contains("File exists"), "{e}");
}

#[test]
fn pairs_that_cannot_be_right_are_refused_with_the_reason() {
    let dir = tempfile::tempdir().unwrap();
    let shots = shots(dir.path());
    let out = dir.path().join("p.csv");
    let good = [
        "left01.png,right01.png,65",
        "left02.png,right02.png,85",
        "left03.png,right03.png,105",
        "left04.png,right04.png,125",
    ];
    // Left and right swapped in one pair; one image given twice in another.
    let mut rows = good.to_vec();
    rows[2] = "right03.png,left03.png,105";
    rows[1] = "left02.png,left02.png,85";
    // Two boards in view: each image of pair 4 beside a copy of itself.
    for side in ["left", "right"] {
        let one = image::open(shots.join(format!("{side}04.png"))).unwrap();
        let (w, h) = (one.width(), one.height());
        let mut two = image::DynamicImage::new(2 * w, h, one.color());
        image::GenericImage::copy_from(&mut two, &one, 0, 0).unwrap();
        image::GenericImage::copy_from(&mut two, &one, w, 0).unwrap();
        two.save(shots.join(format!("two-{side}04.png"))).unwrap();
    }
    rows.push("two-left04.png,two-right04.png,125");
    // Both images of pair 4 mirrored, and both turned 180 degrees.
    for side in ["left", "right"] {
        let one = image::open(shots.join(format!("{side}04.png"))).unwrap();
        one.fliph().save(shots.join(format!("mirror-{side}04.png"))).unwrap();
        one.rotate180().save(shots.join(format!("turned-{side}04.png"))).unwrap();
    }
    captures(&shots, "bad.csv", &rows);
    let o = detect(&shots, "bad.csv", &out, &[]);
    assert!(o.status.success(), "{}", err(&o));
    let e = err(&o);
    assert!(e.contains("bad.csv:4 (right03.png, left03.png): skipped: its disparity is -"), "{e}");
    assert!(
        e.contains(
            "bad.csv:3 (left02.png, left02.png): skipped: every corner is at the same pixel"
        ),
        "{e}"
    );
    assert!(
        e.contains("bad.csv:6 (two-left04.png, two-right04.png): skipped:")
            && e.contains("several boards in view"),
        "{e}"
    );

    let text = std::fs::read_to_string(&out).unwrap();
    assert_eq!(text.lines().count(), 1 + 2 * 54);
    // Among good pairs, one with both images mirrored and one with both turned 180 degrees.
    let mut rows = good.to_vec();
    rows.push("mirror-left04.png,mirror-right04.png,125");
    rows.push("turned-left04.png,turned-right04.png,125");
    captures(&shots, "flipped.csv", &rows);
    let o = detect(&shots, "flipped.csv", &out, &[]);
    assert!(o.status.success(), "{}", err(&o));
    let e = err(&o);
    for (line, pair) in [(6, "mirror"), (7, "turned")] {
        let at = format!("flipped.csv:{line} ({pair}-left04.png, {pair}-right04.png): skipped: ");
        assert!(e.contains(&at), "{pair}: {e}");
    }
    let text = std::fs::read_to_string(&out).unwrap();
    assert_eq!(text.lines().count(), 1 + 4 * 54, "{e}");
    // Every pair swapped: nothing usable.
    let all: Vec<String> = good
        .iter()
        .map(|r| {
            let f: Vec<&str> = r.split(',').collect();
            format!("{},{},{}", f[1], f[0], f[2])
        })
        .collect();
    let all: Vec<&str> = all.iter().map(String::as_str).collect();
    captures(&shots, "swapped.csv", &all);
    let o = detect(&shots, "swapped.csv", &out, &[]);
    one_error(&o, 1);
    assert!(err(&o).contains("left and right swapped"), "{}", err(&o));
    // A 9x6 board described as [6, 9]: refused, naming the fix.
    let b69 = dir.path().join("b69.json");
    std::fs::write(&b69, r#"{"pattern": "chessboard", "inner_corners": [6, 9], "square_cm": 6.0}"#)
        .unwrap();
    let c = shots.join("captures.csv");
    let o = hvs().args(detect_args(&b69, &c, &out)).output().unwrap();
    one_error(&o, 1);
    assert!(err(&o).contains(r#"describe it as "inner_corners": [9, 6]"#), "{}", err(&o));
    // A captures column named like one POINTS.csv writes.
    for col in ["u_l", "capture"] {
        let text = std::fs::read_to_string(&c).unwrap();
        let mut lines = text.lines();
        let mut t = format!("{},{col}\n", lines.next().unwrap());
        for l in lines {
            t.push_str(&format!("{l},1\n"));
        }
        std::fs::write(shots.join("dup.csv"), t).unwrap();
        let o = detect(&shots, "dup.csv", &out, &[]);
        let e = one_error(&o, 1);
        assert!(
            e.contains(&format!("\"{col}\": hvs board detect writes a column of that name")),
            "{e}"
        );
    }
}

/// An 8-bit grey PNG header claiming `w x h` pixels, without the image data.
fn png_bomb(w: u32, h: u32) -> Vec<u8> {
    let crc = |data: &[u8]| crc::Crc::<u32>::new(&crc::CRC_32_ISO_HDLC).checksum(data);
    let mut out = b"\x89PNG\r\n\x1a\n".to_vec();
    let mut chunk = |data: Vec<u8>| {
        out.extend_from_slice(&((data.len() - 4) as u32).to_be_bytes());
        out.extend_from_slice(&data);
        out.extend_from_slice(&crc(&data).to_be_bytes());
    };
    let mut ihdr = b"IHDR".to_vec();
    ihdr.extend_from_slice(&w.to_be_bytes());
    ihdr.extend_from_slice(&h.to_be_bytes());
    ihdr.extend_from_slice(&[8, 0, 0, 0, 0]);
    chunk(ihdr);
    chunk(b"IDAT\x78\x01".to_vec());
    out
}

#[test]
fn huge_images_and_corner_textures_are_refused_quickly() {
    let dir = tempfile::tempdir().unwrap();
    let shots = shots(dir.path());
    std::fs::write(shots.join("bomb.png"), png_bomb(20_000, 20_000)).unwrap();
    // A 3000 x 3000 checker of 20 px squares: 22,000 corners.
    let tex = image::GrayImage::from_fn(3000, 3000, |x, y| {
        image::Luma([if (x / 20 + y / 20) % 2 == 0 { 0 } else { 255 }])
    });
    tex.save(shots.join("tex.png")).unwrap();
    captures(
        &shots,
        "big.csv",
        &["bomb.png,bomb.png,65", "tex.png,tex.png,85", "left03.png,right03.png,105"],
    );
    let o = detect(&shots, "big.csv", &dir.path().join("p.csv"), &[]);
    assert!(o.status.success(), "{}", err(&o));
    let e = err(&o);
    assert!(e.contains("20000x20000 is 400000000 pixels, more than the 16000000"), "{e}");
    assert!(e.contains("corner candidates, more than the 8000"), "{e}");
}

#[cfg(unix)]
#[test]
fn contracts_links_formats_and_exit_codes() {
    let dir = tempfile::tempdir().unwrap();
    let shots = shots(dir.path());
    // A dangling link given as -o stays a link; the file it names is written.
    let link = dir.path().join("link.csv");
    std::os::unix::fs::symlink("points.csv", &link).unwrap();
    let o = detect(&shots, "captures.csv", &link, &[]);
    assert!(o.status.success(), "{}", err(&o));
    assert!(std::fs::symlink_metadata(&link).unwrap().file_type().is_symlink());
    assert!(std::fs::read_to_string(dir.path().join("points.csv"))
        .unwrap()
        .starts_with("capture,i,j"));
    // Formats other than PNG and JPEG are refused by their bytes, naming the format.
    std::fs::write(shots.join("x.bmp"), b"BM\x3a\0\0\0\0\0\0\0\x36\0\0\0\x28\0\0\0").unwrap();
    captures(&shots, "bmp.csv", &["x.bmp,x.bmp,65", "left02.png,right02.png,85"]);
    let o = detect(&shots, "bmp.csv", &dir.path().join("p.csv"), &[]);
    assert!(
        err(&o).contains("x.bmp: a BMP file; hvs reads PNG and JPEG images only"),
        "{}",
        err(&o)
    );
    // Bad usage exits 2 with the flag's name and plain ranges.
    let e = stderr_with_code(
        ["render", "--case", "1", "--blur", "99", "-o", s(&dir.path().join("r"))],
        2,
    );
    assert!(e.contains("--blur: must be a number from 0 to 10, got 99"), "{e}");
    assert!(!e.contains("..=") && !e.contains("blur_sigma_px"), "{e}");
    let e = stderr_with_code(
        ["render", "--case", "1", "--inner-corners", "9", "-o", s(&dir.path().join("r"))],
        2,
    );
    assert!(e.contains("--inner-corners"), "{e}");
}

#[test]
fn locate_checks_its_outputs_usage_and_image_sizes() {
    let dir = tempfile::tempdir().unwrap();
    let (shots, points) = detected_shots(dir.path());
    let model = dir.path().join("m.hvsw");
    crate::common::train_restarts(&points, &model, "1");
    let (l, r) = (shots.join("left02.png"), shots.join("right02.png"));
    let locate = |rest: &[&str]| {
        let mut v = locate_args(&["locate"], &model, &l, &r, &[]);
        v.extend_from_slice(rest);
        hvs().args(&v).output().unwrap()
    };
    // -o and --overlay on one file (also through sub/../): refused before any work.
    std::fs::create_dir(dir.path().join("sub")).unwrap();
    let px = dir.path().join("px.csv");
    std::fs::write(&px, "u_l,v_l\n320,240\n").unwrap();
    let x = dir.path().join("x.out");
    let via = dir.path().join("sub/../x.out");
    let o = locate(&["--points", s(&px), "-o", s(&x), "--overlay", s(&via)]);
    assert!(one_error(&o, 1).contains("are the same file"), "{}", err(&o));
    assert!(!x.exists());
    // --at prints its point: -o with it is bad usage, as are malformed or infinite values.
    for bad in [vec!["--at", "320,240", "-o", s(&x)], vec!["--at", "320"], vec!["--at", "inf,240"]]
    {
        let o = locate(&bad);
        assert_eq!(o.status.code(), Some(2), "{bad:?}: {}", err(&o));
        assert!(!x.exists());
    }
    // Images over the pixel limit are refused from their header.
    let bomb = dir.path().join("bomb.png");
    std::fs::write(&bomb, png_bomb(20_000, 20_000)).unwrap();
    let o = hvs()
        .args(locate_args(&["locate"], &model, &bomb, &bomb, &["--at", "320,240"]))
        .output()
        .unwrap();
    assert!(one_error(&o, 1).contains("more than the 16000000"), "{}", err(&o));
}

#[test]
fn a_z_only_model_locates_and_predicts_without_false_alarms() {
    let dir = tempfile::tempdir().unwrap();
    let (shots, points) = detected_shots(dir.path());
    let model = dir.path().join("z.hvsw");
    crate::common::ok(&[
        "train",
        "--data",
        s(&points),
        "-o",
        s(&model),
        "--outputs",
        "z",
        "--restarts",
        "1",
    ]);
    // `hvs predict` on its own training points: no "damaged" or out-of-range warning.
    let o = hvs().args(["predict", "--model", s(&model), "--points", s(&points)]).output().unwrap();
    assert!(o.status.success(), "{}", err(&o));
    assert!(!err(&o).contains("warning"), "{}", err(&o));
    // `hvs locate` at an inner corner of the 85 cm pair (its neighbours are squares, not the
    // board's border): a match and its depth, no X or Y.
    let text = std::fs::read_to_string(&points).unwrap();
    let header: Vec<&str> = text.lines().next().unwrap().split(',').collect();
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let row: Vec<&str> = text
        .lines()
        .skip(1)
        .map(|l| l.split(',').collect::<Vec<_>>())
        .find(|r| {
            r[col("z")].parse::<f64>().unwrap() == 85.0 && r[col("i")] == "4" && r[col("j")] == "2"
        })
        .unwrap();
    let at = format!("{},{}", row[col("u_l")], row[col("v_l")]);
    let (l, r) = (shots.join("left02.png"), shots.join("right02.png"));
    let o = hvs().args(locate_args(&["locate"], &model, &l, &r, &["--at", &at])).output().unwrap();
    assert!(o.status.success(), "{}", err(&o));
    let out = String::from_utf8_lossy(&o.stdout).into_owned();
    assert!(!out.contains("x=") && out.contains(" z="), "{out}");
    let z: f64 = out.split(" z=").nth(1).unwrap().split(' ').next().unwrap().parse().unwrap();
    assert!((z - 85.0).abs() < 1.0, "{out}");
}
