//! Dense matching on the real Middlebury 2014 Motorcycle pair (scikit-image's copy, 741 x 500,
//! rectified), scored as the issue does: every pixel with ground truth whose match lies
//! inside the right image. Not run by default (the data are not in the repository):
//!
//! ```text
//! pip download --no-deps --only-binary=:all: scikit-image==0.26.0 -d /tmp/skim
//! cd /tmp/skim && unzip -o *.whl 'skimage/data/motorcycle*'
//! # motorcycle_left.png, motorcycle_right.png and disp_741x500.f32 (the raw little-endian
//! # f32 payload of arr_0.npy inside motorcycle_disp.npz, after its header) in one folder:
//! HVS_MOTORCYCLE_DIR=/tmp/motorcycle cargo test --release -p hvs-vision --test dense_real -- --ignored --nocapture
//! ```
//!
//! The disparity range is 1..=66 px, the range a model trained on the pair's training points
//! (`host/tests/fixtures/motorcycle/train.csv`) searches; no truth is used by the matcher.

use hvs_vision::dense::{dense_match, DenseParams};
use hvs_vision::geometry::Fundamental;

const W: usize = 741;
const H: usize = 500;

/// Pixels with a truth inside the right image; returned %, > 2 px % and > 1 px % of the
/// returned.
fn rates(m: &hvs_vision::dense::DenseMap, truth: &[f32]) -> (usize, f64, f64, f64) {
    let (mut n, mut ret, mut off1, mut off2) = (0usize, 0usize, 0usize, 0usize);
    for y in 0..H {
        for x in 0..W {
            let d = truth[y * W + x];
            if !d.is_finite() || (x as f32 - d) < 0.0 {
                continue;
            }
            n += 1;
            let ur = m.ur[y * W + x];
            if !ur.is_finite() {
                continue;
            }
            ret += 1;
            let e = (ur - (x as f32 - d)).abs();
            off1 += usize::from(e > 1.0);
            off2 += usize::from(e > 2.0);
        }
    }
    let pct = |a: usize, b: usize| 100.0 * a as f64 / b as f64;
    (n, pct(ret, n), pct(off2, ret), pct(off1, ret))
}

/// `hvs locate`'s two figures over every pixel with truth (its match inside the right image
/// or not, as `host/tests/fixtures/motorcycle/make.py` draws the CLI test's pixels), were it to
/// refuse matches of a confidence below `min_conf`: the share of all within 1 px, and the
/// share of the returned 2 px or more off (the issue's goals: at least 85 % and at most 2 %).
fn locate_rates(m: &hvs_vision::dense::DenseMap, truth: &[f32], min_conf: f32) -> (f64, f64) {
    let (mut n, mut ret, mut within, mut off) = (0usize, 0usize, 0usize, 0usize);
    for (i, &d) in truth.iter().enumerate() {
        if !d.is_finite() {
            continue;
        }
        n += 1;
        let ur = m.ur[i];
        if !ur.is_finite() || m.conf[i] < min_conf {
            continue;
        }
        ret += 1;
        let e = (ur - ((i % W) as f32 - d)).abs();
        within += usize::from(e <= 1.0);
        off += usize::from(e >= 2.0);
    }
    (100.0 * within as f64 / n as f64, 100.0 * off as f64 / ret.max(1) as f64)
}

#[test]
#[ignore = "needs HVS_MOTORCYCLE_DIR (see the file's doc)"]
fn motorcycle_goals() {
    let dir = std::env::var("HVS_MOTORCYCLE_DIR").expect("set HVS_MOTORCYCLE_DIR");
    let dir = std::path::Path::new(&dir);
    let t0 = std::time::Instant::now();
    let left = hvs_vision::image_file::read_grey(&dir.join("motorcycle_left.png")).unwrap();
    let right = hvs_vision::image_file::read_grey(&dir.join("motorcycle_right.png")).unwrap();
    let raw = std::fs::read(dir.join("disp_741x500.f32")).unwrap();
    assert_eq!(raw.len(), W * H * 4);
    let truth: Vec<f32> =
        raw.chunks_exact(4).map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect();
    let f = Fundamental { m: [[0.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]] };
    if std::env::var("HVS_DENSE_SWEEP").is_ok() {
        let base = DenseParams::default();
        let mut sets = vec![base];
        for (p1, g, lr) in [
            (12u16, 16.0f32, 1.0f32),
            (12, 16.0, 1.5),
            (12, 8.0, 1.5),
            (12, 8.0, 2.0),
            (16, 8.0, 1.5),
            (10, 12.0, 1.5),
        ] {
            sets.push(DenseParams { p1, p2_gamma: g, lr_tolerance_px: lr, ..base });
        }
        for p in sets {
            let m = dense_match(&left, &right, &f, [1, 66], &p).unwrap();
            let r = rates(&m, &truth);
            eprintln!(
                "SWEEP {p:?}: returned {:.2} %, > 2 px {:.2} %, > 1 px {:.2} %",
                r.1, r.2, r.3
            );
        }
    }
    let params = DenseParams::default();
    let t1 = std::time::Instant::now();
    let m = dense_match(&left, &right, &f, [1, 66], &params).unwrap();
    let t2 = std::time::Instant::now();
    let (n, returned, off2, off1) = rates(&m, &truth);
    eprintln!(
        "Motorcycle: {n} pixels with truth inside the right image; returned {:.2} %, of them > 2 px {:.2} %, > 1 px {:.2} %; decode {:.0} ms, match {:.0} ms",
        returned,
        off2,
        off1,
        (t1 - t0).as_secs_f64() * 1e3,
        (t2 - t1).as_secs_f64() * 1e3
    );
    // What a confidence threshold would trade in `hvs locate` (it refuses none today).
    for c in [0.0, 0.5, 0.7, 0.8, 0.9] {
        let (within, off) = locate_rates(&m, &truth, c);
        eprintln!(
            "locate, refusing confidence below {c}: {within:.2} % of all within 1 px, {off:.2} % of the returned 2 px or more off"
        );
    }
    let (within, off) = locate_rates(&m, &truth, 0.0);
    assert!(within > 80.0 && off < 4.0, "locate figures {within} {off}");
    assert!(returned >= 92.0, "returned");
    assert!(off2 <= 3.0, "> 2 px");
    assert!(off1 <= 5.0, "> 1 px");
    // `hvs locate`'s settings (`hvs depth --thorough`): fewer wrong matches, nearly as many.
    let t = dense_match(&left, &right, &f, [1, 66], &DenseParams::thorough()).unwrap();
    let (_, t_returned, t_off2, t_off1) = rates(&t, &truth);
    let (t_within, t_off) = locate_rates(&t, &truth, 0.0);
    eprintln!(
        "thorough: returned {t_returned:.2} %, of them > 2 px {t_off2:.2} %, > 1 px {t_off1:.2} %; \
         locate {t_within:.2} % of all within 1 px, {t_off:.2} % of the returned 2 px or more off"
    );
    assert!(t_returned >= returned - 0.5 && t_off2 < off2 && t_off1 < off1, "thorough");
}
