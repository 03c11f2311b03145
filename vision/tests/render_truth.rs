//! The renderer against the camera model: truth is `Rig::project` / `HeadRig::project`, the
//! images show the corners where the truth says (pixel-centre convention), the squares have
//! the expected size, and the same seed gives the same bytes.

use hvs_shared::runtime::gaze::Joints;
use hvs_shared::sim::camera::Distortion;
use hvs_shared::sim::camera::Rig;
use hvs_shared::sim::posture::HeadRig;
use hvs_shared::sim::presets;
use hvs_vision::render::{
    corner_truth, opencv_board, render_capture_set, render_pair, render_rig, training_captures,
    Board, CornerTruth, RenderOptions,
};
use image::GrayImage;

fn px(img: &GrayImage, c: i64, r: i64) -> f64 {
    f64::from(img.get_pixel(c as u32, r as u32)[0])
}

/// Darkness in `[0, 1]` of a clean render's pixel.
fn dark(img: &GrayImage, opt: &RenderOptions, c: i64, r: i64) -> f64 {
    let (b, w) = (f64::from(opt.black), f64::from(opt.white));
    (w - px(img, c, r)) / (w - b)
}

/// Position of the one black/white edge crossed by row `r` between columns `c0..=c1` (clean
/// render): the run's summed darkness (or lightness) from the run's left pixel boundary.
fn edge_u(img: &GrayImage, opt: &RenderOptions, r: i64, c0: i64, c1: i64, dark_left: bool) -> f64 {
    edge(c0, c1, dark_left, |c| dark(img, opt, c, r))
}

/// The same down column `c` between rows `r0..=r1`.
fn edge_v(img: &GrayImage, opt: &RenderOptions, c: i64, r0: i64, r1: i64, dark_top: bool) -> f64 {
    edge(r0, r1, dark_top, |r| dark(img, opt, c, r))
}

/// The run `i0..=i1`'s summed darkness (lightness unless `dark_first`) from its first pixel
/// boundary.
fn edge(i0: i64, i1: i64, dark_first: bool, dark_at: impl Fn(i64) -> f64) -> f64 {
    let s: f64 = (i0..=i1)
        .map(|i| {
            let d = dark_at(i);
            if dark_first {
                d
            } else {
                1.0 - d
            }
        })
        .sum();
    i0 as f64 - 0.5 + s
}

/// The corner `(u, v)` measured in a clean image from the grid lines through it: the vertical
/// line's `u` on a row above and a row below (interpolated to `v`), and the horizontal
/// line's `v` on a column left and right. `sq` is the local square size in px.
fn measure_corner(
    img: &GrayImage,
    opt: &RenderOptions,
    c: &CornerTruth,
    u: f64,
    v: f64,
    sq: f64,
) -> [f64; 2] {
    let tl_black = (c.i + c.j) % 2 == 0;
    let off = (0.3 * sq).round().max(2.0) as i64;
    let half = (0.4 * sq).floor().max(2.0) as i64;
    let (uc, vc) = (u.round() as i64, v.round() as i64);
    // Row above: TL square left of the line, TR right. Row below: BL left (opposite colour).
    let (ra, rb) = (vc - off, vc + off);
    let ua = edge_u(img, opt, ra, uc - half, uc + half, tl_black);
    let ub = edge_u(img, opt, rb, uc - half, uc + half, !tl_black);
    let u_est = ua + (v - ra as f64) * (ub - ua) / (rb - ra) as f64;
    let (ca, cb) = (uc - off, uc + off);
    let va = edge_v(img, opt, ca, vc - half, vc + half, tl_black);
    let vb = edge_v(img, opt, cb, vc - half, vc + half, !tl_black);
    let v_est = va + (u - ca as f64) * (vb - va) / (cb - ca) as f64;
    [u_est, v_est]
}

/// Mean and max distance between truth and measured corners, over both images.
fn corner_errors(
    r: &hvs_vision::render::StereoRender,
    opt: &RenderOptions,
    square_px: [f64; 2],
) -> (f64, f64) {
    let (mut sum, mut max, mut n) = (0.0, 0.0f64, 0);
    for c in &r.corners {
        for (k, img) in [&r.left, &r.right].into_iter().enumerate() {
            let (u, v) = (c.px[2 * k], c.px[2 * k + 1]);
            let m = measure_corner(img, opt, c, u, v, square_px[k]);
            let e = ((m[0] - u).powi(2) + (m[1] - v).powi(2)).sqrt();
            sum += e;
            max = max.max(e);
            n += 1;
        }
    }
    (sum / n as f64, max)
}

#[test]
fn truth_is_rig_project_with_the_labelling_convention() {
    let board = opencv_board();
    for n in 1..=4 {
        let rig = presets::case(n).unwrap();
        let centre = [2.0, -1.5, 105.0];
        let t = corner_truth(&HeadRig::new(rig), &Joints::HOME, &board, centre).unwrap();
        assert_eq!(t.len(), 54);
        for (k, c) in t.iter().enumerate() {
            assert_eq!((c.i, c.j), ((k % 9) as u32, (k / 9) as u32));
            let want = [
                centre[0] + (f64::from(c.i) - 4.0) * 6.0,
                centre[1] + (f64::from(c.j) - 2.5) * 6.0,
                centre[2],
            ];
            assert_eq!(c.xyz, want);
            assert_eq!(c.px, rig.project(&want).unwrap(), "case {n} corner {k}");
            assert!(c.in_image);
        }
        // (0, 0) top-left: smallest u and v in both images; i grows with u, j with v.
        assert!(t[1].px[0] > t[0].px[0] && t[1].px[2] > t[0].px[2]);
        assert!(t[9].px[1] > t[0].px[1] && t[9].px[3] > t[0].px[3]);
    }
}

#[test]
fn same_seed_same_bytes_other_seed_other_bytes() {
    let rig = presets::CASE_3;
    let board = opencv_board();
    let opt = RenderOptions::default();
    let a = render_rig(&rig, &board, [0.0, 0.0, 125.0], &opt, 7).unwrap();
    let b = render_rig(&rig, &board, [0.0, 0.0, 125.0], &opt, 7).unwrap();
    let c = render_rig(&rig, &board, [0.0, 0.0, 125.0], &opt, 8).unwrap();
    assert_eq!(a.left.as_raw(), b.left.as_raw());
    assert_eq!(a.right.as_raw(), b.right.as_raw());
    assert_ne!(a.left.as_raw(), c.left.as_raw());
    assert_ne!(a.right.as_raw(), c.right.as_raw());
    // Noise-free renders do not depend on the seed at all.
    let clean = RenderOptions::clean();
    let d = render_rig(&rig, &board, [0.0, 0.0, 125.0], &clean, 1).unwrap();
    let e = render_rig(&rig, &board, [0.0, 0.0, 125.0], &clean, 2).unwrap();
    assert_eq!(d, e);
}

#[test]
fn capture_set_is_the_training_depths_and_deterministic() {
    let rig = presets::CASE_1;
    let board = opencv_board();
    let opt = RenderOptions::default();
    let a = training_captures(&rig, &board, &opt, 3).unwrap();
    let b = training_captures(&rig, &board, &opt, 3).unwrap();
    assert_eq!(a, b);
    let depths: Vec<f64> = a.captures.iter().map(|c| c.centre[2]).collect();
    assert_eq!(depths, presets::TRAIN_DEPTHS.to_vec());
    assert_eq!(a.captures[0].left_name, "left01.png");
    assert_eq!(a.captures[5].right_name, "right06.png");
    // Every pair has its own noise.
    assert_ne!(a.captures[0].render.left.as_raw(), a.captures[1].render.left.as_raw());
    let rows = a.truth_rows();
    assert_eq!(rows.len(), 6 * 54);
    assert!(rows.iter().all(|r| r.corner.in_image));
    assert_eq!(
        a.board_json(),
        "{\"pattern\": \"chessboard\", \"inner_corners\": [9, 6], \"square_cm\": 6}\n"
    );
    let truth = a.truth_csv();
    assert_eq!(truth.lines().count(), 1 + 6 * 54);
    // The truth CSV round-trips the exact pixels.
    let line = truth.lines().nth(1).unwrap();
    let f: Vec<&str> = line.split(',').collect();
    assert_eq!(&f[..3], &["left01.png", "0", "0"]);
    let ul: f64 = f[6].parse().unwrap();
    assert_eq!(ul, rows[0].corner.px[0]);
}

#[test]
fn black_squares_centroid_is_where_the_model_projects_them() {
    // Case I at home: the board is fronto-parallel, so the image is an exact scaling of the
    // board and the darkness centroid of the black squares is the projected mean of their
    // centres. A half-pixel slip of the pixel convention would show as 0.5 px.
    let rig = Rig::parallel(285.836);
    let board = opencv_board();
    let opt = RenderOptions::clean();
    let centre = [3.0, 2.0, 85.0];
    let r = render_rig(&rig, &board, centre, &opt, 0).unwrap();
    let s = board.square_cm;
    let mut want = [[0.0f64; 2]; 2];
    let mut count = 0.0;
    for b in 0..=board.rows {
        for a in 0..=board.cols {
            if (a + b) % 2 != 0 {
                continue;
            }
            let p = [
                centre[0] + (f64::from(a) - f64::from(board.cols) / 2.0) * s,
                centre[1] + (f64::from(b) - f64::from(board.rows) / 2.0) * s,
                centre[2],
            ];
            let q = rig.project(&p).unwrap();
            for k in 0..2 {
                want[k][0] += q[2 * k];
                want[k][1] += q[2 * k + 1];
            }
            count += 1.0;
        }
    }
    // Window: the squares plus half the white border.
    let hx = (f64::from(board.cols) + 1.0) / 2.0 * s + 0.5 * RenderOptions::default().margin_cm;
    let hy = (f64::from(board.rows) + 1.0) / 2.0 * s + 0.5 * RenderOptions::default().margin_cm;
    for (k, img) in [&r.left, &r.right].into_iter().enumerate() {
        let tl = rig.project(&[centre[0] - hx, centre[1] - hy, centre[2]]).unwrap();
        let br = rig.project(&[centre[0] + hx, centre[1] + hy, centre[2]]).unwrap();
        let (mut su, mut sv, mut sd) = (0.0, 0.0, 0.0);
        for row in tl[2 * k + 1].round() as i64..=br[2 * k + 1].round() as i64 {
            for col in tl[2 * k].round() as i64..=br[2 * k].round() as i64 {
                let d = dark(img, &opt, col, row);
                su += d * col as f64;
                sv += d * row as f64;
                sd += d;
            }
        }
        let got = [su / sd, sv / sd];
        let w = [want[k][0] / count, want[k][1] / count];
        assert!(
            (got[0] - w[0]).abs() < 0.01 && (got[1] - w[1]).abs() < 0.01,
            "camera {k}: centroid {got:?}, model {w:?}"
        );
    }
}

#[test]
fn corners_in_the_image_are_where_the_truth_says() {
    for n in [1u8, 3, 4] {
        let rig = presets::case(n).unwrap();
        let opt = RenderOptions::clean();
        let board = opencv_board();
        let r = render_rig(&rig, &board, [-4.0, 3.0, 85.0], &opt, 0).unwrap();
        let sq =
            [rig.phi_u_left * board.square_cm / 85.0, rig.phi_u_right * board.square_cm / 85.0];
        let (mean, max) = corner_errors(&r, &opt, sq);
        eprintln!("case {n}: corner error mean {mean:.4} max {max:.4} px");
        assert!(mean < 0.02 && max < 0.05, "case {n}: mean {mean} max {max}");
    }
}

#[test]
fn distortion_and_posture_render_where_head_rig_projects() {
    let head = HeadRig::new(presets::CASE_3).with_distortion(Distortion { k1: -0.2, k2: 0.05 });
    let joints = Joints([4.0, -3.0, 2.0, -1.5, 1.0]);
    let board = opencv_board();
    let opt = RenderOptions::clean();
    let centre = [-8.0, 6.0, 95.0];
    let r = render_pair(&head, &joints, &board, centre, &opt, 0).unwrap();
    for c in &r.corners {
        assert_eq!(c.px, head.project(&joints, &c.xyz).unwrap());
        assert!(c.in_image);
    }
    let sq = 285.0 * board.square_cm / 95.0 * 0.9;
    let (mean, max) = corner_errors(&r, &opt, [sq, sq]);
    eprintln!("lens + posture: corner error mean {mean:.4} max {max:.4} px");
    assert!(mean < 0.03 && max < 0.08, "mean {mean} max {max}");
    // The lens moved the corners: the pinhole truth would be more than a pixel off.
    let pin = HeadRig::new(presets::CASE_3);
    let shift = r
        .corners
        .iter()
        .map(|c| {
            let p = pin.project(&joints, &c.xyz).unwrap();
            (p[0] - c.px[0]).abs().max((p[1] - c.px[1]).abs())
        })
        .fold(0.0f64, f64::max);
    assert!(shift > 1.0, "distortion shifted corners by only {shift} px");
}

#[test]
fn squares_at_165_cm_are_about_10_px() {
    let rig = presets::CASE_1;
    let board = opencv_board();
    let r = render_rig(&rig, &board, [0.0, 0.0, 165.0], &RenderOptions::default(), 5).unwrap();
    // Row through the middle of the top square row (between corner rows -1 and 0).
    let c0 = &r.corners[0];
    let row = (c0.px[1] - 0.5 * (r.corners[9].px[1] - c0.px[1])).round() as u32;
    let mid = 125.0;
    let mut crossings = Vec::new();
    let mut prev = f64::from(r.left.get_pixel(0, row)[0]) > mid;
    for c in 1..r.left.width() {
        let now = f64::from(r.left.get_pixel(c, row)[0]) > mid;
        if now != prev {
            crossings.push(f64::from(c));
        }
        prev = now;
    }
    // background -> white border -> 10 squares -> white border -> background.
    let inner: Vec<f64> = crossings.windows(2).map(|w| w[1] - w[0]).collect();
    let squares: Vec<f64> = inner.iter().copied().filter(|&d| d > 6.0 && d < 14.0).collect();
    assert!(squares.len() >= 8, "crossings {crossings:?}");
    let mean = squares.iter().sum::<f64>() / squares.len() as f64;
    let want = rig.phi_u_left * board.square_cm / 165.0;
    assert!(
        (mean - want).abs() < 0.5 && (want - 10.4).abs() < 0.1,
        "mean square {mean} px, model {want}"
    );
}

#[test]
fn bad_input_is_an_error_naming_the_field() {
    let rig = presets::CASE_1;
    let opt = RenderOptions::default();
    let e = render_rig(&rig, &Board { cols: 0, ..opencv_board() }, [0.0, 0.0, 100.0], &opt, 0)
        .unwrap_err();
    assert!(e.to_string().starts_with("board.cols"), "{e}");
    let e = render_rig(&rig, &opencv_board(), [0.0, f64::NAN, 100.0], &opt, 0).unwrap_err();
    assert!(e.to_string().starts_with("centre"), "{e}");
    let e = render_rig(&rig, &opencv_board(), [0.0, 0.0, -10.0], &opt, 0).unwrap_err();
    assert!(e.to_string().contains("behind"), "{e}");
    let bad = RenderOptions { supersample: 0, ..opt };
    let e = render_rig(&rig, &opencv_board(), [0.0, 0.0, 100.0], &bad, 0).unwrap_err();
    assert!(e.to_string().starts_with("supersample"), "{e}");
    let e = render_capture_set(
        &HeadRig::new(rig),
        &Joints::HOME,
        &opencv_board(),
        [0.0, 0.0],
        &[100.0, f64::INFINITY],
        &opt,
        0,
    )
    .unwrap_err();
    assert!(e.to_string().starts_with("depths"), "{e}");
}
