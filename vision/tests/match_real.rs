//! The matcher on a real textured pair with dense ground truth: Middlebury 2014 "Motorcycle"
//! (rectified, 741 x 500, disparities 7-60 px), as scikit-image 0.26.0 ships it (down-sampled
//! by 4). The data is not in the repository; to run:
//!
//! ```text
//! pip download --no-deps --only-binary=:all: scikit-image==0.26.0 -d /tmp/skim
//! cd /tmp/skim && unzip -o *.whl 'skimage/data/motorcycle*'
//! # disparity: the raw little-endian f32 payload of arr_0.npy inside motorcycle_disp.npz
//! HVS_MOTORCYCLE_DIR=/tmp/motorcycle cargo test --release -p hvs-vision --test match_real -- --ignored --nocapture
//! ```
//!
//! `HVS_MOTORCYCLE_DIR` holds `motorcycle_left.png`, `motorcycle_right.png` and
//! `disp_741x500.f32` (row-major, NaN where there is no truth; `u_r = u_l - d`).

mod match_common;
use hvs_vision::geometry::Fundamental;
use hvs_vision::matching::{MatchParams, Matcher, Query};
use match_common::{interval, Rates};
use rand::{RngExt, SeedableRng};

const W: usize = 741;
const H: usize = 500;

fn load() -> (image::GrayImage, image::GrayImage, Vec<f32>) {
    let dir = std::env::var("HVS_MOTORCYCLE_DIR").expect(
        "set HVS_MOTORCYCLE_DIR to the folder with the Motorcycle pair (see the file's doc)",
    );
    let dir = std::path::Path::new(&dir);
    let img = |n: &str| {
        let p = dir.join(n);
        image::open(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display())).to_luma8()
    };
    let p = dir.join("disp_741x500.f32");
    let raw = std::fs::read(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
    assert_eq!(raw.len(), W * H * 4, "{}: expected {W}x{H} f32", p.display());
    let disp = raw.chunks_exact(4).map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect();
    (img("motorcycle_left.png"), img("motorcycle_right.png"), disp)
}

/// A rectified pair: the epipolar line of `(u, v)` is the row `v`.
fn rectified() -> Fundamental {
    Fundamental { m: [[0.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]] }
}

fn eval(seed: u64, n: usize, wide: bool, params: MatchParams) -> Rates {
    let (l, r, disp) = load();
    let m = Matcher::new(&l, &r, &rectified(), params).unwrap();
    let mut rng = rand::rngs::ChaCha8Rng::seed_from_u64(seed);
    let mut rates = Rates::default();
    while rates.asked < n {
        let (u, v) = (rng.random_range(0..W), rng.random_range(0..H));
        let d = f64::from(disp[v * W + u]);
        if !d.is_finite() {
            continue;
        }
        let (d_min, d_max) = if wide { (5.0, 65.0) } else { interval(d) };
        let q = Query { ul: u as f64, vl: v as f64, d_min, d_max };
        rates.add(&m.find(&q), [u as f64 - d, v as f64]);
    }
    rates
}

/// Of the points asked: the fraction returned within 1 px of the truth and the fraction
/// returned with an error of 2 px or more.
fn of_asked(r: &Rates) -> (f64, f64) {
    let asked = r.asked.max(1) as f64;
    let good = r.errors.iter().filter(|&&e| e <= 1.0).count() as f64 / asked;
    let bad = r.errors.iter().filter(|&&e| e >= 2.0).count() as f64 / asked;
    (good, bad)
}

fn line(name: &str, r: &Rates) -> String {
    let (good, bad) = of_asked(r);
    format!(
        "{name}: of asked: within 1 px {:.1} %, returned >= 2 px {:.1} % | {}",
        100.0 * good,
        100.0 * bad,
        r.summary()
    )
}

/// Held-out seeds (never used to choose anything): 7 and 8.
#[test]
#[ignore = "needs HVS_MOTORCYCLE_DIR (real data not in the repository)"]
fn motorcycle_rates() {
    for seed in [7u64, 8] {
        let r = eval(seed, 1000, false, MatchParams::default());
        eprintln!("{}", line(&format!("seed {seed} d+-10 %"), &r));
        let wide = eval(seed, 1000, true, MatchParams::default());
        eprintln!("{}", line(&format!("seed {seed} 5..65 px"), &wide));
        let (good, bad) = of_asked(&r);
        assert!(good >= 0.80, "{}", r.summary());
        assert!(bad <= 0.03, "{}", r.summary());
    }
}

/// Development variants on seeds 1-4 (what the defaults were chosen with).
#[test]
#[ignore = "development sweep on the Motorcycle pair (seeds 1-4; needs HVS_MOTORCYCLE_DIR)"]
fn motorcycle_dev() {
    let d = MatchParams::default();
    let variants: Vec<(&str, MatchParams)> = vec![
        ("default", d),
        ("no shifted windows", MatchParams { shifted_windows: false, ..d }),
        ("no growing", MatchParams { max_half_window: 5, ..d }),
        ("grown 0.8", MatchParams { grown_min_score: 0.8, ..d }),
        ("grown 0.95", MatchParams { grown_min_score: 0.95, ..d }),
        ("margin 0.1", MatchParams { uniqueness_margin: 0.1, ..d }),
        ("lr 0.5", MatchParams { lr_tolerance_px: 0.5, ..d }),
        ("no agree", MatchParams { shifted_must_agree: false, ..d }),
        ("floor 0", MatchParams { support_floor: 0.0, ..d }),
        ("floor 0.1", MatchParams { support_floor: 0.1, ..d }),
        ("floor 0.35", MatchParams { support_floor: 0.35, ..d }),
        ("unweighted", MatchParams { support_gamma: 0.0, ..d }),
        ("no slack", MatchParams { interval_slack_px: 0.0, ..d }),
        ("shift 0.6", MatchParams { shift_fraction: 0.6, ..d }),
        ("min score 0.5", MatchParams { min_score: 0.5, ..d }),
        ("r 4", MatchParams { half_window: 4, ..d }),
        ("r 6", MatchParams { half_window: 6, ..d }),
    ];
    let only = std::env::var("HVS_DEV_VARIANT").ok();
    for (name, p) in variants {
        if only.as_deref().is_some_and(|o| !o.split(',').any(|o| o == name)) {
            continue;
        }
        let mut all = Rates::default();
        let mut wide = Rates::default();
        for seed in 1..=4u64 {
            all.merge(&eval(seed, 1000, false, p));
            wide.merge(&eval(seed, 1000, true, p));
        }
        eprintln!("{}", line(&format!("{name} d+-10 %"), &all));
        eprintln!("{}", line(&format!("{name} 5..65 px"), &wide));
    }
}
