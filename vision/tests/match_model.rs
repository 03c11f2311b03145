//! The matcher with the disparity interval a model gives each pixel
//! ([`model_disparity_interval`]), on rendered chessboards at every depth of the training
//! volume. The model here is exact: optimal triangulation through the true rig (what a
//! perfectly trained network would answer), so the interval is the disparities the training
//! depths (65-165 cm) map to at that pixel, scanned over the training set's whole disparity
//! range.

mod match_common;
use hvs_shared::runtime::gaze::Joints;
use hvs_shared::sim::posture::HeadRig;
use hvs_shared::sim::presets;
use hvs_shared::sim::triangulate;
use hvs_vision::geometry::pinhole_fundamental;
use hvs_vision::matching::{
    model_disparity_interval, model_disparity_interval_in_image, pinhole_right_scale, MatchParams,
    Matcher, Query,
};
use hvs_vision::render::{corner_truth, opencv_board, render_rig, Board, RenderOptions};
use match_common::Rates;
use rand::{RngExt, SeedableRng};

/// The disparity range of the training set, every corner of the training boards (centres
/// `TRAIN_BOARD_X x TRAIN_BOARD_Y x TRAIN_DEPTHS`), widened by 10 % of its span each side
/// (the test's boards also stand off the training positions).
fn training_disparity_range(rig: &hvs_shared::sim::camera::Rig, board: &Board) -> [f64; 2] {
    let head = HeadRig::new(*rig);
    let mut r = [f64::INFINITY, f64::NEG_INFINITY];
    for &z in &presets::TRAIN_DEPTHS {
        for &x in &presets::TRAIN_BOARD_X {
            for &y in &presets::TRAIN_BOARD_Y {
                for c in corner_truth(&head, &Joints::HOME, board, [x, y, z]).unwrap() {
                    let d = c.px[0] - c.px[2];
                    r = [r[0].min(d), r[1].max(d)];
                }
            }
        }
    }
    let pad = 0.1 * (r[1] - r[0]);
    [r[0] - pad, r[1] + pad]
}

#[test]
fn corners_with_the_model_interval_at_every_depth() {
    let board = opencv_board();
    let z_range = [65.0, 165.0];
    let mut all = Rates::default();
    let mut widths = Vec::new();
    for case in 1..=4u8 {
        let rig = presets::case(case).unwrap();
        let f = pinhole_fundamental(&rig.left(), &rig.right());
        let d_range = training_disparity_range(&rig, &board);
        let params = MatchParams {
            right_scale: pinhole_right_scale(&rig.left(), &rig.right()),
            ..MatchParams::default()
        };
        let model = |x: [f32; 4]| {
            let px = x.map(f64::from);
            triangulate::optimal_rig(&rig, &px).ok().map(|p| p.map(|c| c as f32))
        };
        let mut rng = rand::rngs::ChaCha8Rng::seed_from_u64(2001 + u64::from(case));
        for z in (65..=165).step_by(10).map(f64::from) {
            let cx = -10.0 + 20.0 * rng.random::<f64>();
            let cy = -6.0 + 12.0 * rng.random::<f64>();
            let r = render_rig(&rig, &board, [cx, cy, z], &RenderOptions::default(), rng.random())
                .unwrap();
            let m = Matcher::new(&r.left, &r.right, &f, params).unwrap();
            let mut at_z = Rates::default();
            for c in r.corners.iter().filter(|c| c.in_image) {
                let line = f.line_in_right([c.px[0], c.px[1]]);
                let (d_min, d_max) =
                    model_disparity_interval(model, c.px[0], c.px[1], line, z_range, d_range)
                        .expect("a corner inside the training depths has an interval");
                let d = c.px[0] - c.px[2];
                assert!(d >= d_min && d <= d_max, "case {case} z {z}: {d} not in {d_min}..{d_max}");
                widths.push(d_max - d_min);
                let q = Query { ul: c.px[0], vl: c.px[1], d_min, d_max };
                let got = m.find(&q);
                at_z.add(&got, [c.px[2], c.px[3]]);
            }
            eprintln!(
                "case {case} z {z} (d range {:.1}..{:.1}): {}",
                d_range[0],
                d_range[1],
                at_z.summary()
            );
            assert!(at_z.returned() >= 0.40, "case {case} z {z}: {}", at_z.summary());
            assert!(at_z.within(0.5) >= 0.99, "case {case} z {z}: {}", at_z.summary());
            all.merge(&at_z);
        }
    }
    widths.sort_by(f64::total_cmp);
    eprintln!(
        "all: {} | interval width median {:.1} px, max {:.1} px",
        all.summary(),
        widths[widths.len() / 2],
        widths[widths.len() - 1]
    );
    assert!(all.returned() >= 0.40, "{}", all.summary());
    assert!(all.within(0.5) >= 0.99, "{}", all.summary());
    assert_eq!(all.at_least(2.0), 0.0, "{}", all.summary());
}

/// Toward the edges of a verged pair, and of two cameras of unequal focal lengths, the
/// training depths lie at disparities far outside those of boards in the middle of the image:
/// `model_disparity_interval_in_image` finds them there (the whole image's interval, as `hvs
/// depth` and `hvs locate` search), where the scan of the training disparities alone misses
/// them. Points at the training depths seen near the image's corners and edges, cases III
/// and IV, the exact model.
#[test]
fn the_interval_reaches_the_image_edges_of_a_verged_pair() {
    let board = opencv_board();
    let z_range = [65.0, 165.0];
    for case in [3u8, 4] {
        let rig = presets::case(case).unwrap();
        let (left, right) = (rig.left(), rig.right());
        let f = pinhole_fundamental(&left, &right);
        let d_range = training_disparity_range(&rig, &board);
        let model = |x: [f32; 4]| {
            let px = x.map(f64::from);
            triangulate::optimal_rig(&rig, &px).ok().map(|p| p.map(|c| c as f32))
        };
        let (mut seen, mut outside_training) = (0, 0);
        for z in [66.0, 100.0, 164.0] {
            for sx in [-1.0, -0.5, 0.0, 0.5, 1.0] {
                for sy in [-1.0, 0.0, 1.0] {
                    // Tangents a little inside the left camera's view (phi about 286 px).
                    let p = [sx * 1.0 * z, sy * 0.75 * z, z];
                    let (Some(l), Some(r)) = (left.project(&p), right.project(&p)) else {
                        continue;
                    };
                    let inside = |q: [f64; 2]| {
                        (0.0..f64::from(rig.width) - 1.0).contains(&q[0])
                            && (0.0..f64::from(rig.height) - 1.0).contains(&q[1])
                    };
                    if !(inside(l) && inside(r)) {
                        continue;
                    }
                    seen += 1;
                    let d = l[0] - r[0];
                    let line = f.line_in_right(l);
                    // The exact model may be asked anywhere.
                    let (lo, hi) = model_disparity_interval_in_image(
                        model,
                        |_| true,
                        l[0],
                        l[1],
                        line,
                        z_range,
                        d_range,
                        rig.width,
                    )
                    .unwrap_or_else(|| panic!("case {case}: no interval at {l:?} ({p:?})"));
                    assert!(d >= lo && d <= hi, "case {case} {p:?}: {d} not in {lo}..{hi}");
                    if d < d_range[0] || d > d_range[1] {
                        outside_training += 1;
                        let clipped =
                            model_disparity_interval(model, l[0], l[1], line, z_range, d_range);
                        assert!(
                            clipped.is_none_or(|(a, b)| d < a || d > b),
                            "case {case}: the training scan holds {d}"
                        );
                    }
                }
            }
        }
        eprintln!("case {case}: {seen} points, {outside_training} outside the training disparities {d_range:?}");
        assert!(seen >= 20, "case {case}: {seen} points");
        assert!(outside_training >= 4, "case {case}: the test would not show the need");
    }
}
