//! Shared by the `match_*` tests: rendered boards with exact truth, and rate bookkeeping.
#![allow(dead_code)]

use hvs_shared::sim::presets;
use hvs_vision::geometry::pinhole_fundamental;
use hvs_vision::matching::{Match, MatchParams, MatchStatus, Matcher, Query};
use hvs_vision::render::{opencv_board, render_rig, RenderOptions};
use rand::{RngExt, SeedableRng};
use std::collections::BTreeMap;

/// Counts of one evaluation.
#[derive(Debug, Default, Clone)]
pub struct Rates {
    /// Points asked.
    pub asked: usize,
    /// Per status.
    pub status: BTreeMap<&'static str, usize>,
    /// Errors (px) of the `ok` answers.
    pub errors: Vec<f64>,
}

impl Rates {
    pub fn add(&mut self, m: &Match, truth: [f64; 2]) {
        self.asked += 1;
        *self.status.entry(m.status.name()).or_default() += 1;
        if m.status == MatchStatus::Ok {
            self.errors.push(((m.ur - truth[0]).powi(2) + (m.vr - truth[1]).powi(2)).sqrt());
        }
    }
    pub fn merge(&mut self, o: &Rates) {
        self.asked += o.asked;
        for (k, v) in &o.status {
            *self.status.entry(k).or_default() += v;
        }
        self.errors.extend_from_slice(&o.errors);
    }
    /// Fraction of asked points returned `ok`.
    pub fn returned(&self) -> f64 {
        self.errors.len() as f64 / self.asked.max(1) as f64
    }
    /// Fraction of returned points within `tol` px.
    pub fn within(&self, tol: f64) -> f64 {
        self.errors.iter().filter(|&&e| e <= tol).count() as f64 / self.errors.len().max(1) as f64
    }
    /// Fraction of returned points with error >= `tol` px.
    pub fn at_least(&self, tol: f64) -> f64 {
        self.errors.iter().filter(|&&e| e >= tol).count() as f64 / self.errors.len().max(1) as f64
    }
    pub fn summary(&self) -> String {
        format!(
            "asked {} returned {:.1} % | of returned: <=0.5 px {:.2} %, <=1 px {:.2} %, >=2 px {:.2} % | {:?}",
            self.asked,
            100.0 * self.returned(),
            100.0 * self.within(0.5),
            100.0 * self.within(1.0),
            100.0 * self.at_least(2.0),
            self.status
        )
    }
}

/// The disparity interval the tests give a point of true disparity `d`: `d +- 10 %`, at least
/// `+- 1 px` (the model's per-point interval is of this kind).
pub fn interval(d: f64) -> (f64, f64) {
    let h = (0.1 * d.abs()).max(1.0);
    (d - h, d + h)
}

/// How a test point's disparity interval is made from its true disparity.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Interval {
    /// [`interval`]: `d +- 10 %` (at least 1 px), what a model's per-point prediction gives.
    Narrow,
    /// One fixed interval for every point (px): a search without a model.
    Fixed(f64, f64),
}

/// Rendered boards of case `case` at the six training depths, each board at a random centre
/// (`x` in +-10 cm, `y` in +-6 cm), default render options, all random draws from `seed`.
/// Returns (corners, random board points) rates. `extra` random board points per pair.
pub fn eval_case(case: u8, seed: u64, extra: usize, params: MatchParams) -> (Rates, Rates) {
    eval_case_with(case, seed, extra, params, Interval::Narrow)
}

/// [`eval_case`] with a choice of interval.
pub fn eval_case_with(
    case: u8,
    seed: u64,
    extra: usize,
    params: MatchParams,
    iv: Interval,
) -> (Rates, Rates) {
    let interval = |d: f64| match iv {
        Interval::Narrow => interval(d),
        Interval::Fixed(a, b) => (a, b),
    };
    let rig = presets::case(case).unwrap();
    let board = opencv_board();
    let opt = RenderOptions::default();
    let f = pinhole_fundamental(&rig.left(), &rig.right());
    let mut rng = rand::rngs::ChaCha8Rng::seed_from_u64(seed ^ (u64::from(case) << 32));
    let (mut corners, mut random) = (Rates::default(), Rates::default());
    for &z in &presets::TRAIN_DEPTHS {
        let cx = -10.0 + 20.0 * rng.random::<f64>();
        let cy = -6.0 + 12.0 * rng.random::<f64>();
        let r = render_rig(&rig, &board, [cx, cy, z], &opt, rng.random()).unwrap();
        let m = Matcher::new(&r.left, &r.right, &f, params).unwrap();
        for c in &r.corners {
            let d = c.px[0] - c.px[2];
            let (d_min, d_max) = interval(d);
            let q = Query { ul: c.px[0], vl: c.px[1], d_min, d_max };
            corners.add(&m.find(&q), [c.px[2], c.px[3]]);
        }
        // Random points on the squares (not the border).
        let hx = 0.5 * f64::from(board.cols + 1) * board.square_cm;
        let hy = 0.5 * f64::from(board.rows + 1) * board.square_cm;
        let mut k = 0;
        while k < extra {
            let p = [
                cx + hx * (2.0 * rng.random::<f64>() - 1.0),
                cy + hy * (2.0 * rng.random::<f64>() - 1.0),
                z,
            ];
            let px = rig.project(&p).unwrap();
            if !rig.in_image(&px) {
                continue;
            }
            k += 1;
            let (d_min, d_max) = interval(px[0] - px[2]);
            let q = Query { ul: px[0], vl: px[1], d_min, d_max };
            random.add(&m.find(&q), [px[2], px[3]]);
        }
    }
    (corners, random)
}
