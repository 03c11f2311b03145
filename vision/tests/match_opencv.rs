//! The matcher on OpenCV's 13 real stereo pairs (tests/fixtures/opencv-stereo): the detected
//! chessboard corners are sparse true matches. For each pair the fundamental matrix is fitted
//! on the corners of the 12 other pairs (leave-one-out), each left corner is searched along
//! its epipolar line, and the answer is compared with the detected right corner.
//!
//! Two intervals: the true disparity +- 10 % (at least 1 px; what a model's per-point
//! prediction gives) and, without a model, the whole disparity range of the 12 other pairs
//! (widened by 10 % of its span): on a chessboard that range holds several repeats of the
//! pattern, the worst case.

mod opencv_common;

use hvs_vision::geometry::fit_fundamental;
use hvs_vision::matching::{MatchParams, MatchStatus, Matcher, Query};
use std::collections::BTreeMap;

#[derive(Default)]
struct Tally {
    asked: usize,
    errors: Vec<f64>,
    status: BTreeMap<&'static str, usize>,
}

impl Tally {
    fn of_asked(&self, tol: f64) -> f64 {
        self.errors.iter().filter(|&&e| e <= tol).count() as f64 / self.asked.max(1) as f64
    }
    fn of_returned(&self, tol: f64) -> f64 {
        self.errors.iter().filter(|&&e| e <= tol).count() as f64 / self.errors.len().max(1) as f64
    }
    fn wrong(&self) -> f64 {
        self.errors.iter().filter(|&&e| e >= 2.0).count() as f64 / self.asked.max(1) as f64
    }
    fn summary(&self) -> String {
        format!(
            "asked {}, returned {:.1} %, within 1 px {:.1} % of asked ({:.1} % of returned, within 0.5 px {:.1} %), returned >= 2 px {:.1} % of asked | {:?}",
            self.asked,
            100.0 * self.errors.len() as f64 / self.asked.max(1) as f64,
            100.0 * self.of_asked(1.0),
            100.0 * self.of_returned(1.0),
            100.0 * self.of_returned(0.5),
            100.0 * self.wrong(),
            self.status
        )
    }
}

#[test]
fn corners_of_the_real_pairs_leave_one_out() {
    let pairs = opencv_common::load();
    assert_eq!(pairs.len(), 13);
    let (mut narrow, mut wide) = (Tally::default(), Tally::default());
    // Distance of the true right corner from the leave-one-out epipolar line: the matcher
    // answers on the line, so this much error comes with F.
    let mut epipolar = Vec::new();
    for (k, p) in pairs.iter().enumerate() {
        let others: Vec<_> = pairs
            .iter()
            .enumerate()
            .filter(|(j, _)| *j != k)
            .flat_map(|(_, o)| o.corners.pairs())
            .collect();
        let f = fit_fundamental(&others).unwrap();
        let ds: Vec<f64> = others.iter().map(|(l, r)| l[0] - r[0]).collect();
        let (lo, hi) =
            ds.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &d| (a.min(d), b.max(d)));
        let pad = 0.1 * (hi - lo);
        let m = Matcher::new(&p.left, &p.right, &f, MatchParams::default()).unwrap();
        let (mut n_pair, mut w_pair) = (Tally::default(), Tally::default());
        let mut epi: Vec<f64> =
            p.corners.pairs().iter().map(|(l, r)| f.distance_in_right(*l, *r)).collect();
        epi.sort_by(f64::total_cmp);
        epipolar.extend_from_slice(&epi);
        for (l, r) in p.corners.pairs() {
            let d = l[0] - r[0];
            let h = (0.1 * d.abs()).max(1.0);
            for (t, (d_min, d_max)) in
                [(&mut n_pair, (d - h, d + h)), (&mut w_pair, (lo - pad, hi + pad))]
            {
                let got = m.find(&Query { ul: l[0], vl: l[1], d_min, d_max });
                t.asked += 1;
                *t.status.entry(got.status.name()).or_default() += 1;
                if got.status == MatchStatus::Ok {
                    t.errors.push(((got.ur - r[0]).powi(2) + (got.vr - r[1]).powi(2)).sqrt());
                }
            }
        }
        eprintln!(
            "{} d {:.1}..{:.1} px, epipolar distance median {:.2} max {:.2} px, narrow: {}",
            p.name,
            lo,
            hi,
            epi[epi.len() / 2],
            epi[epi.len() - 1],
            n_pair.summary()
        );
        eprintln!("{} wide: {}", p.name, w_pair.summary());
        for (all, one) in [(&mut narrow, n_pair), (&mut wide, w_pair)] {
            all.asked += one.asked;
            all.errors.extend(one.errors);
            for (s, c) in one.status {
                *all.status.entry(s).or_default() += c;
            }
        }
    }
    eprintln!("all pairs, true d +- 10 %: {}", narrow.summary());
    eprintln!("all pairs, other pairs' disparity range: {}", wide.summary());
    epipolar.sort_by(f64::total_cmp);
    let over1 = epipolar.iter().filter(|&&e| e > 1.0).count() as f64 / epipolar.len() as f64;
    eprintln!(
        "leave-one-out epipolar distance of the true corners: median {:.2} px, {:.1} % over 1 px",
        epipolar[epipolar.len() / 2],
        100.0 * over1
    );
    assert!(narrow.of_asked(1.0) >= 0.88, "{}", narrow.summary());
    assert!(narrow.wrong() <= 0.03, "{}", narrow.summary());
    assert!(wide.of_asked(1.0) >= 0.85, "{}", wide.summary());
    assert!(wide.wrong() <= 0.03, "{}", wide.summary());
}
