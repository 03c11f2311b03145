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
        image::open(&p)
            .unwrap_or_else(|e| panic!("{}: {e}", p.display()))
            .to_luma8()
    };
    let p = dir.join("disp_741x500.f32");
    let raw = std::fs::read(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
    assert_eq!(
        raw.len(),
        W * H * 4,
        "{}: expected {W}x{H} f32",
        p.display()
    );
    let disp = raw
        .chunks_exact(4)
        .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
        .collect();
    (
        img("motorcycle_left.png"),
        img("motorcycle_right.png"),
        disp,
    )
}

/// A rectified pair: the epipolar line of `(u, v)` is the row `v`.
fn rectified() -> Fundamental {
    Fundamental {
        m: [[0.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]],
    }
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
        let q = Query {
            ul: u as f64,
            vl: v as f64,
            d_min,
            d_max,
        };
        rates.add(&m.find(&q), [u as f64 - d, v as f64]);
    }
    rates
}

#[test]
#[ignore = "needs HVS_MOTORCYCLE_DIR (real data not in the repository)"]
fn motorcycle_rates() {
    for seed in [1u64, 2] {
        let narrow = eval(seed, 1000, false, MatchParams::default());
        eprintln!("seed {seed} d+-10 %: {}", narrow.summary());
        let wide = eval(seed, 1000, true, MatchParams::default());
        eprintln!("seed {seed} 5..65 px: {}", wide.summary());
    }
    // Held out (not used to choose the parameters): seed 7.
    let r = eval(7, 1000, false, MatchParams::default());
    let asked = r.asked as f64;
    let good = r.errors.iter().filter(|&&e| e <= 1.0).count() as f64 / asked;
    let bad = r.errors.iter().filter(|&&e| e >= 2.0).count() as f64 / asked;
    eprintln!(
        "seed 7 d+-10 %: {} | of asked: within 1 px {:.1} %, returned >= 2 px {:.1} %",
        r.summary(),
        100.0 * good,
        100.0 * bad
    );
    assert!(r.within(1.0) >= 0.90, "{}", r.summary());
    assert!(bad <= 0.03, "{}", r.summary());
}

#[test]
#[ignore = "development sweep on the Motorcycle pair (seeds 1, 2; needs HVS_MOTORCYCLE_DIR)"]
fn motorcycle_sweep() {
    for half_window in [5u32, 7, 9] {
        for min_std in [1.0, 2.0, 4.0] {
            for min_score in [0.3, 0.5, 0.7] {
                let p = MatchParams {
                    half_window,
                    min_std,
                    min_score,
                    ..MatchParams::default()
                };
                let mut all = Rates::default();
                for seed in [1u64, 2] {
                    all.merge(&eval(seed, 1000, false, p));
                }
                let asked = all.asked as f64;
                let good = all.errors.iter().filter(|&&e| e <= 1.0).count() as f64 / asked;
                let bad = all.errors.iter().filter(|&&e| e >= 2.0).count() as f64 / asked;
                eprintln!(
                    "r {half_window} min_std {min_std} min_score {min_score}: within 1 px {:.1} % of asked, >= 2 px {:.1} % of asked | {}",
                    100.0 * good,
                    100.0 * bad,
                    all.summary()
                );
            }
        }
    }
}
