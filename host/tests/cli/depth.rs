//! `hvs depth` through the binary: a model trained on a synthetic rectified pinhole pair
//! (f = 200 px, baseline 10 cm, 160 x 120 images, depths 100-300 cm), images of a textured
//! wall at 250 cm with a box at 150 cm in front of it; the outputs' formats, their depths, and
//! bad input (another size, no matcher geometry, a posture model, blank images, an output
//! onto an input).

use crate::common::{fails, hvs, locate_args, ok, s, stderr_with_code};
use hvs_shared::runtime::blob::{self, MAX_BLOB_LEN};
use hvs_shared::test_support::splitmix64;
use hvs_vision::pfm::read_pfm;
use image::GrayImage;
use std::path::{Path, PathBuf};

/// The dense matcher's synthetic pairs (`vision/tests/dense_common`), for its texture.
#[path = "../../../vision/tests/dense_common/mod.rs"]
mod dense_common;

const W: u32 = 160;
const H: u32 = 120;
const FOCAL: f64 = 200.0;
const BASE: f64 = 10.0;
const C: [f64; 2] = [80.0, 60.0];
const Z_WALL: f64 = 250.0;
const Z_BOX: f64 = 150.0;

/// Training points of the rectified pair: `u_l,v_l,u_r,v_r,x,y,z`.
fn training_csv(path: &Path) {
    let mut st = 5u64;
    let mut uni = || (splitmix64(&mut st) >> 11) as f64 / (1u64 << 53) as f64;
    let mut out = String::from("u_l,v_l,u_r,v_r,x,y,z\n");
    let mut n = 0;
    while n < 300 {
        let z = 100.0 + 200.0 * uni();
        let (ul, vl) = (160.0 * uni(), 120.0 * uni());
        let x = (ul - C[0]) * z / FOCAL;
        let y = (vl - C[1]) * z / FOCAL;
        let ur = ul - FOCAL * BASE / z;
        if ur < 0.0 {
            continue;
        }
        out.push_str(&format!("{ul},{vl},{ur},{vl},{x},{y},{z}\n"));
        n += 1;
    }
    std::fs::write(path, out).unwrap();
}

/// A smooth seeded texture (the dense matcher's test texture), read bilinearly.
fn texture(seed: u64) -> impl Fn(f64, f64) -> f64 {
    let t = dense_common::Texture::new(W as usize + 64, H as usize, seed);
    move |x: f64, y: f64| f64::from(t.at(x + 32.0, y))
}

/// Is left pixel `(x, y)` on the box?
fn on_box(x: f64, y: f64) -> bool {
    (60.0..100.0).contains(&x) && (40.0..80.0).contains(&y)
}

/// The wall and the box, both textured (the texture is fixed to the scene: left `x`).
fn pair(dir: &Path) -> (std::path::PathBuf, std::path::PathBuf) {
    let t = texture(9);
    let (dw, db) = (FOCAL * BASE / Z_WALL, FOCAL * BASE / Z_BOX);
    let left =
        GrayImage::from_fn(W, H, |x, y| image::Luma([t(f64::from(x), f64::from(y)).round() as u8]));
    let right = GrayImage::from_fn(W, H, |u, v| {
        let (u, v) = (f64::from(u), f64::from(v));
        let x = if on_box(u + db, v) { u + db } else { u + dw };
        image::Luma([t(x, v).round() as u8])
    });
    let (l, r) = (dir.join("l.png"), dir.join("r.png"));
    left.save(&l).unwrap();
    right.save(&r).unwrap();
    (l, r)
}

fn median(mut v: Vec<f32>) -> f32 {
    v.sort_by(f32::total_cmp);
    v[v.len() / 2]
}

/// A model trained in `d` on [`training_csv`] (one restart, then `extra`) and the [`pair`].
fn model_and_pair(d: &Path, extra: &[&str]) -> (PathBuf, PathBuf, PathBuf) {
    let (data, model) = (d.join("train.csv"), d.join("m.hvsw"));
    training_csv(&data);
    let base = ["train", "--data", s(&data), "-o", s(&model), "--restarts", "1"];
    ok(&[&base[..], extra].concat());
    let (l, r) = pair(d);
    (model, l, r)
}

#[test]
fn depth_of_a_wall_and_a_box_and_its_files() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (model, l, r) = model_and_pair(d, &[]);
    let out = |n: &str| d.join(n);
    let (depth, matches, xyz, colour, ply) =
        (out("d.pfm"), out("m.pfm"), out("xyz.pfm"), out("d.png"), out("c.ply"));
    let args = locate_args(
        &["depth"],
        &model,
        &l,
        &r,
        &[
            "-o",
            s(&depth),
            "--matches",
            s(&matches),
            "--xyz",
            s(&xyz),
            "--colour",
            s(&colour),
            "--ply",
            s(&ply),
        ],
    );
    let err = stderr_with_code(args, 0);
    assert!(err.contains("pixels") && err.contains("0 warning(s)"), "{err}");
    let bytes = std::fs::read(&depth).unwrap();
    assert!(bytes.starts_with(b"Pf\n160 120\n-1\n"), "{:?}", &bytes[..16]);
    let z = read_pfm(&bytes, "d.pfm").unwrap();
    assert_eq!((z.width, z.height, z.channels), (W, H, 1));
    let (mut wall, mut boxed) = (Vec::new(), Vec::new());
    for y in 0..H {
        for x in 20..W - 4 {
            let v = z.data[(y * W + x) as usize];
            let (xf, yf) = (f64::from(x), f64::from(y));
            if !v.is_finite() {
                continue;
            }
            if on_box(xf, yf) && on_box(xf - 3.0, yf - 3.0) && on_box(xf + 3.0, yf + 3.0) {
                boxed.push(v);
            } else if !on_box(xf - 20.0, yf)
                && !on_box(xf + 10.0, yf)
                && !on_box(xf, yf + 5.0)
                && !on_box(xf, yf - 5.0)
            {
                wall.push(v);
            }
        }
    }
    let returned = z.data.iter().filter(|v| v.is_finite()).count();
    assert!(returned as f64 > 0.85 * f64::from(W * H), "{returned} returned");
    let (mw, mb) = (median(wall.clone()), median(boxed.clone()));
    eprintln!("median depth: wall {mw} cm ({} px), box {mb} cm ({} px)", wall.len(), boxed.len());
    assert!((f64::from(mw) - Z_WALL).abs() < 0.01 * Z_WALL, "wall {mw}");
    assert!((f64::from(mb) - Z_BOX).abs() < 0.01 * Z_BOX, "box {mb}");
    // Matches: u_r, v_r, confidence; +inf, +inf, 0 exactly where the depth is +inf.
    let m = read_pfm(&std::fs::read(&matches).unwrap(), "m.pfm").unwrap();
    assert_eq!(m.channels, 3);
    for (k, zk) in z.data.iter().enumerate() {
        let (ur, vr, c) = (m.data[3 * k], m.data[3 * k + 1], m.data[3 * k + 2]);
        if zk.is_finite() {
            assert!(
                ur.is_finite() && (vr - (k as u32 / W) as f32).abs() < 0.5 && c > 0.0 && c <= 1.0
            );
        } else {
            assert_eq!((ur, vr, c), (f32::INFINITY, f32::INFINITY, 0.0));
        }
    }
    let p = read_pfm(&std::fs::read(&xyz).unwrap(), "xyz.pfm").unwrap();
    assert!(z.data.iter().zip(p.data.chunks_exact(3)).all(|(a, b)| a.to_bits() == b[2].to_bits()));
    let png = image::open(&colour).unwrap();
    assert_eq!(png.width(), W);
    assert!(png.height() > H);
    let cloud = std::fs::read(&ply).unwrap();
    let head = format!("element vertex {returned}\n");
    assert!(cloud.windows(head.len()).any(|w| w == head.as_bytes()));
    let end = cloud.windows(11).position(|w| w == b"end_header\n").unwrap() + 11;
    assert_eq!(cloud.len() - end, 15 * returned);

    // `--thorough` (the right image aggregated on its own for the left-right check, the first
    // nearer match past a gap dropped): the matches `hvs locate` answers from, to the printed
    // digit, at the whole pixels where they differ from the default's (beside the box's
    // edges) and at two others.
    let (td, thorough) = (out("dt.pfm"), out("mt.pfm"));
    let args = ["-o", s(&td), "--matches", s(&thorough), "--thorough"];
    let err = stderr_with_code(locate_args(&["depth"], &model, &l, &r, &args), 0);
    assert!(err.contains("0 warning(s)"), "{err}");
    let t = read_pfm(&std::fs::read(&thorough).unwrap(), "mt.pfm").unwrap();
    let t_returned = t.data.chunks_exact(3).filter(|p| p[0].is_finite()).count();
    assert!(t_returned as f64 > 0.85 * f64::from(W * H), "{t_returned} returned");
    let differ: Vec<usize> =
        (0..(W * H) as usize).filter(|&k| t.data[3 * k] != m.data[3 * k]).collect();
    assert!(!differ.is_empty(), "--thorough gave the default's matches");
    let step = (differ.len() / 4).max(1);
    let mut at: Vec<usize> = differ.iter().step_by(step).take(4).copied().collect();
    at.extend([(20 * W + 30) as usize, (60 * W + 80) as usize]);
    for k in at {
        let (x, y) = (k as u32 % W, k as u32 / W);
        let said = ok(&locate_args(&["locate"], &model, &l, &r, &["--at", &format!("{x},{y}")]));
        if t.data[3 * k].is_finite() {
            let want = format!("u_r={} ", t.data[3 * k]);
            assert!(said.contains(&want), "({x}, {y}): {said} against {want}");
        } else {
            assert!(said.contains("no trustworthy match"), "({x}, {y}): {said}");
        }
    }

    // Blank images: every pixel +inf, exit 0, a warning.
    let blank = d.join("blank.png");
    GrayImage::from_pixel(W, H, image::Luma([200])).save(&blank).unwrap();
    let bd = d.join("blank.pfm");
    let err = stderr_with_code(locate_args(&["depth"], &model, &blank, &blank, &["-o", s(&bd)]), 0);
    assert!(
        err.contains("warning: the left image is blank") && err.contains("2 warning(s)"),
        "{err}"
    );
    let bz = read_pfm(&std::fs::read(&bd).unwrap(), "blank.pfm").unwrap();
    assert!(bz.data.iter().all(|v| *v == f32::INFINITY));

    // A colour image named as another format than the PNG it would hold: bad usage.
    // So is `hvs locate --overlay`'s.
    let (jpg, out) = (d.join("c.jpg"), d.join("c.pfm"));
    let err = stderr_with_code(
        locate_args(&["depth"], &model, &l, &r, &["-o", s(&out), "--colour", s(&jpg)]),
        2,
    );
    assert!(err.contains("writes PNG images only") && !jpg.exists() && !out.exists(), "{err}");
    let err = stderr_with_code(
        locate_args(&["locate"], &model, &l, &r, &["--at", "100,80", "--overlay", s(&jpg)]),
        2,
    );
    assert!(err.contains("--overlay") && err.contains("writes PNG images only"), "{err}");
    // Another size than the other image, than the model's.
    let small = d.join("small.png");
    GrayImage::from_pixel(100, 80, image::Luma([9])).save(&small).unwrap();
    let no = d.join("no.pfm");
    fails(&locate_args(&["depth"], &model, &l, &small, &["-o", s(&no)]), "differ in size");
    let mut b = blob::decode(&std::fs::read(&model).unwrap()).unwrap();
    b.set_image_size(Some((320, 240)));
    let mut buf = [0u8; MAX_BLOB_LEN];
    let n = b.encode(&mut buf).unwrap();
    let sized = d.join("sized.hvsw");
    std::fs::write(&sized, &buf[..n]).unwrap();
    let e = fails(
        &locate_args(&["depth"], &sized, &l, &r, &["-o", s(&no)]),
        "trained on 320x240 px images",
    );
    assert!(e.contains("l.png with ") && e.contains("sized.hvsw"), "{e}");
    // hvs locate says the same, also for a pixel of the model's images outside these.
    for at in ["200,150", "20,15"] {
        let e =
            fails(&locate_args(&["locate"], &sized, &l, &r, &["--at", at]), "trained on 320x240");
        assert!(e.contains("l.png with ") && e.contains("sized.hvsw"), "{e}");
    }
    // No matcher geometry; a posture model.
    for (k, (m, want)) in [
        (hvs_shared::test_support::sample_model(1, 3), "no matcher geometry"),
        (hvs_shared::test_support::sample_posture_model(1, 3), "posture-aware"),
    ]
    .into_iter()
    .enumerate()
    {
        let n = m.encode(&mut buf).unwrap();
        let p = d.join(format!("bare{k}.hvsw"));
        std::fs::write(&p, &buf[..n]).unwrap();
        fails(&locate_args(&["depth"], &p, &l, &r, &["-o", s(&no)]), want);
    }
    // An output onto an input.
    fails(&locate_args(&["depth"], &model, &l, &r, &["-o", s(&l)]), "--left");
    assert!(!no.exists());
    let _ = ok(&["depth", "--help"]);
}

/// A Z-only model (`hvs train --outputs z`): depth and `hvs locate` from its Z, X and Y NaN in
/// the XYZ file, and a point cloud refused (nothing written).
#[test]
fn a_z_only_model_gives_depth_and_refuses_a_point_cloud() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (model, l, r) = model_and_pair(d, &["--outputs", "z"]);
    let (depth, xyz, ply) = (d.join("d.pfm"), d.join("xyz.pfm"), d.join("c.ply"));
    let args = ["-o", s(&depth), "--xyz", s(&xyz)];
    let err = stderr_with_code(locate_args(&["depth"], &model, &l, &r, &args), 0);
    assert!(err.contains("0 warning(s)"), "{err}");
    let z = read_pfm(&std::fs::read(&depth).unwrap(), "d.pfm").unwrap();
    let p = z.data.iter().position(|v| v.is_finite()).expect("some depth");
    assert!((100.0..300.0).contains(&z.data[p]), "{}", z.data[p]);
    let xyz = read_pfm(&std::fs::read(&xyz).unwrap(), "xyz.pfm").unwrap();
    assert!(xyz.data[3 * p].is_nan() && xyz.data[3 * p + 1].is_nan());
    assert_eq!(xyz.data[3 * p + 2], z.data[p]);
    let o = locate_args(&["depth"], &model, &l, &r, &["-o", s(&depth), "--ply", s(&ply)]);
    fails(&o, "Z-only model");
    assert!(!ply.exists());
    // `hvs locate` at the same pixel (`read_pfm` gives the rows top to bottom).
    let (x, y) = (p as u32 % z.width, p as u32 / z.width);
    let at = format!("{x},{y}");
    let out = ok(&locate_args(&["locate"], &model, &l, &r, &["--at", &at]));
    assert!(out.contains(" z=") && !out.contains("x="), "{out}");
}

/// Nothing to match gives no depth, whatever the geometry: through a verged model (the thesis'
/// case IV cameras, 640 x 480 images), where the aggregation alone once returned depth for 71 %
/// of a blank pair (candidates outside the right image cost more, which made some disparities
/// "unique"); with one image blank, nearly blank (grey noise of one level) or saturated.
#[test]
fn blank_and_saturated_images_give_no_depth_through_a_verged_model() {
    let (w, h) = (640, 480);
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (data, model) = (d.join("c4.csv"), d.join("c4.hvsw"));
    std::fs::write(&data, ok(&["simulate", "--case", "4", "--set", "train"])).unwrap();
    ok(&["train", "--data", s(&data), "-o", s(&model), "--restarts", "1"]);
    let mut st = 11u64;
    let mut image = |name: &str, level: &mut dyn FnMut(u64) -> u8| {
        let img = GrayImage::from_fn(w, h, |_, _| image::Luma([level(splitmix64(&mut st))]));
        let path = d.join(name);
        img.save(&path).unwrap();
        path
    };
    let textured = image("t.png", &mut |r| (r >> 56) as u8);
    let blank = image("b.png", &mut |_| 120);
    let nearly = image("n.png", &mut |r| 120 + (r & 1) as u8);
    // 95 % white, the rest random.
    let saturated = image("s.png", &mut |r| if r % 20 == 0 { (r >> 56) as u8 } else { 255 });
    let out = d.join("o.pfm");
    for (left, right, warnings) in [
        (&blank, &blank, 2),
        (&textured, &blank, 1),
        (&nearly, &textured, 1),
        (&saturated, &saturated, 2),
        (&textured, &saturated, 1),
        // One textured image twice: nothing to match, said as a warning.
        (&textured, &textured, 1),
    ] {
        let err =
            stderr_with_code(locate_args(&["depth"], &model, left, right, &["-o", s(&out)]), 0);
        assert!(err.contains(&format!("{warnings} warning(s)")), "{err}");
        assert!(err.contains(&format!("0 of {} pixels", w * h)), "{err}");
        let z = read_pfm(&std::fs::read(&out).unwrap(), "o.pfm").unwrap();
        assert_eq!(z.data.len(), (w * h) as usize);
        assert!(z.data.iter().all(|v| *v == f32::INFINITY));
    }
    // `hvs locate` says why it found nothing.
    let out = hvs()
        .args(locate_args(&["locate"], &model, &textured, &blank, &["--at", "320,240"]))
        .assert()
        .success()
        .get_output()
        .clone();
    let (said, err) = (String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
    assert!(said.contains("no_match"), "{said}");
    assert!(err.contains("warning: the right image is blank"), "{err}");
}

/// Case IV's verged cameras (the right focal length 0.8 times the left) at half size, 320 x
/// 240, through `hvs train` and `hvs depth`: a model trained on exact points spread over the
/// whole image at 70-320 cm, and a rendered scene of slanted planes and a sphere before a wall
/// at 300 cm (`hvs_vision::scene`, per-pixel truth). Nearly every pixel both cameras see gets
/// a match within a pixel of the truth, out to the image's edges, where the disparities lie
/// tens of pixels outside those of the middle (a search clipped to the training disparities
/// of a middle band, as before 2026-12-07, returned about two thirds at full size).
#[test]
fn a_verged_pair_is_matched_out_to_its_edges() {
    use hvs_shared::runtime::gaze::Joints;
    use hvs_shared::sim::posture::HeadRig;
    use hvs_vision::render::RenderOptions;
    use hvs_vision::scene::{render_scene, SceneFile};
    const SCENE: &str = r#"{ "rig": {"case": 4}, "camera_fps": 30,
      "background": {"z_cm": 300, "texture_seed": 21},
      "objects": [
        {"shape": "plane", "side_cm": [90, 70], "pitch_deg": 60, "centre_cm": [-10, 30, 170], "texture_seed": 22},
        {"shape": "plane", "side_cm": [50, 40], "yaw_deg": -45, "centre_cm": [45, -10, 130], "texture_seed": 23},
        {"shape": "sphere", "radius_cm": 10, "centre_cm": [-25, -15, 95], "texture_seed": 24}
      ] }"#;
    let mut rig = hvs_shared::sim::presets::case(4).unwrap();
    let k = 0.5;
    (rig.width, rig.height) = (rig.width / 2, rig.height / 2);
    (rig.u0, rig.v0) = (rig.u0 * k, rig.v0 * k);
    rig.phi_u_left *= k;
    rig.phi_u_right *= k;
    rig.phi_v_left *= k;
    rig.phi_v_right *= k;
    let (w, h) = (rig.width, rig.height);
    let scene = SceneFile::parse(SCENE).unwrap().scene().unwrap();
    let head = HeadRig::new(rig);
    let r =
        render_scene(&head, &Joints::HOME, &scene.at(0.0), &RenderOptions::default(), 3).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (left, right) = (d.join("l.png"), d.join("r.png"));
    r.left.save(&left).unwrap();
    r.right.save(&right).unwrap();
    // Exact training points on a grid of directions at six depths, where both cameras see
    // them: from the left image's edges to its edges.
    let mut csv = String::from("u_l,v_l,u_r,v_r,x,y,z\n");
    let inside = |q: [f64; 2]| {
        (0.0..f64::from(w) - 1.0).contains(&q[0]) && (0.0..f64::from(h) - 1.0).contains(&q[1])
    };
    let mut u_l_span = [f64::INFINITY, f64::NEG_INFINITY];
    for z in [70.0, 100.0, 140.0, 190.0, 250.0, 320.0] {
        for i in 0..=12 {
            for j in 0..=9 {
                let p = [(-1.2 + 0.2 * f64::from(i)) * z, (-0.9 + 0.2 * f64::from(j)) * z, z];
                let (Some(l), Some(q)) = (r.cameras[0].project(&p), r.cameras[1].project(&p))
                else {
                    continue;
                };
                if inside(l) && inside(q) {
                    u_l_span = [u_l_span[0].min(l[0]), u_l_span[1].max(l[0])];
                    csv.push_str(&format!(
                        "{},{},{},{},{},{},{}\n",
                        l[0], l[1], q[0], q[1], p[0], p[1], p[2]
                    ));
                }
            }
        }
    }
    assert!(u_l_span[0] < 30.0 && u_l_span[1] > f64::from(w) - 30.0, "{u_l_span:?}");
    let (data, model) = (d.join("t.csv"), d.join("m.hvsw"));
    std::fs::write(&data, csv).unwrap();
    ok(&["train", "--data", s(&data), "-o", s(&model), "--restarts", "3"]);
    let (depth, matches) = (d.join("d.pfm"), d.join("m.pfm"));
    let args = locate_args(
        &["depth"],
        &model,
        &left,
        &right,
        &["-o", s(&depth), "--matches", s(&matches)],
    );
    let err = stderr_with_code(args, 0);
    let m = read_pfm(&std::fs::read(&matches).unwrap(), "m.pfm").unwrap();
    let z = read_pfm(&std::fs::read(&depth).unwrap(), "d.pfm").unwrap();
    let (mut seen, mut returned, mut within, mut edge_seen, mut edge_returned) = (0, 0, 0, 0, 0);
    let mut errs = Vec::new();
    let border = 4;
    for y in border..h - border {
        for x in border..w - border {
            let Some(t) = r.true_match(x, y) else { continue };
            let p = (y * w + x) as usize;
            // The outer sixth of the image on either side.
            let edge = x < w / 6 || x >= w - w / 6;
            seen += 1;
            edge_seen += usize::from(edge);
            let (ur, vr) = (f64::from(m.data[3 * p]), f64::from(m.data[3 * p + 1]));
            if !ur.is_finite() {
                continue;
            }
            returned += 1;
            edge_returned += usize::from(edge);
            within += usize::from((ur - t[0]).hypot(vr - t[1]) <= 1.0);
            let z_true = r.truth_left.z(x, y).unwrap();
            errs.push((z.data[p] - z_true).abs() / z_true * 100.0);
        }
    }
    let pct = |a: usize, b: usize| 100.0 * a as f64 / b as f64;
    let median_err = median(errs);
    eprintln!(
        "{}case IV at 320x240: {seen} pixels seen by both cameras, {:.2} % returned ({:.2} % of \
         the outer sixths'), {:.2} % of them within 1 px, median depth error {median_err:.3} %",
        err.lines().last().map(|l| format!("{l}\n")).unwrap_or_default(),
        pct(returned, seen),
        pct(edge_returned, edge_seen),
        pct(within, returned)
    );
    assert!(pct(returned, seen) >= 95.0, "returned {}", pct(returned, seen));
    assert!(pct(edge_returned, edge_seen) >= 90.0, "edges {}", pct(edge_returned, edge_seen));
    assert!(pct(within, returned) >= 98.0, "within 1 px {}", pct(within, returned));
    // The model's part: a 4-5-3 net over the whole image, at half the resolution.
    assert!(median_err < 1.5, "median depth error {median_err} %");
}

/// `hvs render --scene`: one pair of a scene file and its truth in `hvs depth`'s formats (the
/// left image's depth, and the true match of each left pixel the right camera sees), the same
/// bytes for the same seed; bad usage refused, nothing written.
#[test]
fn render_writes_a_scene_pair_and_its_truth() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let scene = d.join("s.json");
    std::fs::write(
        &scene,
        r#"{ "rig": {"case": 1}, "camera_fps": 30, "background": {"z_cm": 250, "texture_seed": 1},
          "objects": [{"shape": "sphere", "radius_cm": 15, "centre_cm": [0, 0, 120], "texture_seed": 2},
                      {"shape": "plane", "side_cm": [60, 40], "pitch_deg": 50, "centre_cm": [-70, 50, 180]},
                      {"shape": "box", "size_cm": [10, 10, 10], "centre_cm": [0, 0, -40]}] }"#,
    )
    .unwrap();
    let (a, b) = (d.join("a"), d.join("b"));
    for out in [&a, &b] {
        let run = hvs()
            .args(["render", "--scene", s(&scene), "-o", s(out), "--seed", "4"])
            .assert()
            .success();
        // The box behind the head is named; the two objects in view are not.
        let err = String::from_utf8_lossy(&run.get_output().stderr).into_owned();
        assert!(err.contains("objects[2] is in neither image"), "{err}");
        assert!(!err.contains("objects[0]") && !err.contains("objects[1]"), "{err}");
    }
    let file = |dir: &Path, n: &str| std::fs::read(dir.join(n)).unwrap();
    for n in ["left.png", "right.png", "depth.pfm", "matches.pfm"] {
        assert_eq!(file(&a, n), file(&b, n), "{n}: same seed, same bytes");
    }
    let z = read_pfm(&file(&a, "depth.pfm"), "depth.pfm").unwrap();
    let m = read_pfm(&file(&a, "matches.pfm"), "matches.pfm").unwrap();
    assert_eq!((z.width, z.height, z.channels, m.channels), (640, 480, 1, 3));
    // The left camera (at X = -5.25 cm, looking along Z) sees the sphere's front at its
    // principal point, a corner the wall.
    let at = |x: u32, y: u32| z.data[(y * 640 + x) as usize];
    let front = 120.0 - (15.0f32 * 15.0 - 5.25 * 5.25).sqrt();
    assert!((at(320, 240) - front).abs() < 0.01, "{} against {front}", at(320, 240));
    assert!((at(5, 5) - 250.0).abs() < 1e-3, "{}", at(5, 5));
    // The plane, pitched: its depth changes down the image.
    let mut seen = 0;
    for (k, t) in m.data.chunks_exact(3).enumerate() {
        if t[2] == 1.0 {
            seen += 1;
            // Case I's cameras are parallel (the right focal length 0.17 % shorter): the match
            // lies on the same row within 0.41 px, to the left.
            let (x, y) = ((k % 640) as f32, (k / 640) as f32);
            assert!((t[1] - y).abs() < 0.42 && t[0] < x, "pixel {k}: {t:?}");
        } else {
            assert!(t[0] == f32::INFINITY && t[1] == f32::INFINITY && t[2] == 0.0, "{t:?}");
        }
    }
    assert!(seen > 250_000 && seen < 640 * 480, "seen {seen}");
    // Bad usage: nothing written.
    let c = d.join("c");
    for (args, want) in [
        (vec!["--scene", s(&scene), "--case", "1"], "cannot be used with"),
        (vec!["--case", "1", "--time", "1"], "--time goes with --scene"),
        (vec!["--scene", s(&scene), "--time", "inf"], "--time must be finite"),
    ] {
        let out = hvs().arg("render").args(&args).args(["-o", s(&c)]).assert().failure();
        let err = String::from_utf8_lossy(&out.get_output().stderr).into_owned();
        assert!(err.contains(want), "{args:?}: {err}");
        assert!(!c.exists(), "{args:?} wrote {}", c.display());
    }
    // The scene file where a written file would go: refused, kept.
    let inside = a.join("depth.pfm");
    std::fs::copy(&scene, &inside).unwrap();
    let out = hvs().args(["render", "--scene", s(&inside), "-o", s(&a)]).assert().failure();
    let err = String::from_utf8_lossy(&out.get_output().stderr).into_owned();
    assert!(err.contains("is also the --scene input"), "{err}");
    assert_eq!(std::fs::read(&inside).unwrap(), std::fs::read(&scene).unwrap());
    std::fs::write(&scene, r#"{ "rig": {"case": 1}, "camera_fps": 30, "background": {"z_cm": 250}, "objects": [{"shape": "plane", "centre_cm": [0, 0, 100]}] }"#).unwrap();
    let out = hvs().args(["render", "--scene", s(&scene), "-o", s(&c)]).assert().failure();
    let err = String::from_utf8_lossy(&out.get_output().stderr).into_owned();
    assert!(err.contains("objects[0].side_cm: a plane needs it"), "{err}");
    assert!(!c.exists());
}
