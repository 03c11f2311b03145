//! Dense matching on synthetic pairs with exact truth (seeded random texture, a slanted
//! background and a box in front of it): rectified, and unrectified with tilted epipolar
//! lines (`v_r = v_l - 0.03 u_r - 2`). Goals as the for rendered scenes: at least
//! 95 % of the pixels seen by both cameras returned, at least 98 % of those within 1 px.

mod dense_common;
use dense_common::{scene, score};
use hvs_vision::dense::{dense_match, DenseParams};

fn check(tilt: f64, shift: f64, seed: u64, params: &DenseParams) -> dense_common::Score {
    let pair = scene(200, 150, 8.0, 6.0, 26.0, seed, tilt, shift);
    let m = dense_match(&pair.left, &pair.right, &pair.f, pair.d_range, params).unwrap();
    let s = score(&pair, &m, 4);
    eprintln!(
        "tilt {tilt}, shift {shift}, thorough {}: returned {:.2} % of {}, within 1 px {:.2} %, > 2 px {:.2} %, returned where unseen {}",
        params.aggregate_right,
        s.returned_pct(),
        s.seen,
        s.within_1_pct(),
        s.off_2_pct(),
        s.returned_unseen
    );
    assert!(s.returned_pct() >= 95.0, "{s:?}");
    assert!(s.within_1_pct() >= 98.0, "{s:?}");
    assert!(s.off_2_pct() <= 1.5, "{s:?}");
    // Every kept pixel has a confidence, every other none.
    for (u, c) in m.ur.iter().zip(&m.conf) {
        assert_eq!(u.is_finite(), *c > 0.0, "{u} {c}");
        assert!((0.0..=1.0).contains(c));
    }
    s
}

#[test]
fn rectified_pair_within_the_goals() {
    check(0.0, 0.0, 11, &DenseParams::default());
}

#[test]
fn unrectified_pair_with_tilted_lines_within_the_goals() {
    check(0.03, 2.0, 12, &DenseParams::default());
}

/// `hvs locate`'s settings (the right image aggregated on its own for the left-right check,
/// the first nearer match past a gap dropped) meet the same goals, and on the rectified pair
/// return fewer pixels the right camera does not see than the default (which reads the right
/// image's disparities off the left image's sums).
#[test]
fn thorough_settings_within_the_goals() {
    let (def, thorough) = (DenseParams::default(), DenseParams::thorough());
    let (a, b) = (check(0.0, 0.0, 11, &def), check(0.0, 0.0, 11, &thorough));
    assert!(b.returned_unseen < a.returned_unseen, "{a:?} {b:?}");
    check(0.03, 2.0, 12, &thorough);
}

#[test]
fn same_input_same_bytes() {
    let pair = scene(120, 90, 5.0, 3.0, 15.0, 3, 0.02, 1.0);
    let p = DenseParams::default();
    let a = dense_match(&pair.left, &pair.right, &pair.f, pair.d_range, &p).unwrap();
    let b = dense_match(&pair.left, &pair.right, &pair.f, pair.d_range, &p).unwrap();
    assert_eq!(a, b);
    assert!(a.matched() > 5000);
}
