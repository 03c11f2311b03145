//! `hvs_host::study::thesis`: the derived seeds, the per-hidden-count means and the facts
//! `RESULTS.md` states.

use hvs_host::study::thesis::facts::*;
use hvs_host::study::thesis::{derive_seed, e_ma_hn, hidden_counts, mean_e_ma_hn};
use hvs_host::study::thesis::{DepthCurve, NetRow, PhiRow};
use hvs_shared::runtime::blob::OutputKind;
use hvs_shared::runtime::gaze::HALF_BASELINE_CM;
use hvs_shared::runtime::traditional::phi_estimate;
use hvs_shared::sim::camera::Rig;
use hvs_shared::sim::presets::{self, CASE_1, CASE_2, CASE_4, TEST_DEPTHS, TEST_POINTS_XY};

fn row(case: u8, phi_l: f64, phi_r: f64) -> PhiRow {
    PhiRow { case, z: 50.0, phi_l, phi_r, true_l: 100.0, true_r: 200.0 }
}

#[test]
fn phi_statistics() {
    let rows = [row(1, 99.0, 1.0), row(1, 101.0, 1.0), row(2, 0.0, 202.0)];
    let s = phi_stats(&rows, 1, true);
    assert_eq!((s.mean, s.truth, s.max_dev_pct, s.sd_pct), (100.0, 100.0, 1.0, 1.0));
    assert_eq!(s.bias_pct(), 0.0);
    let r = phi_stats(&rows, 2, false);
    assert_eq!((r.mean, r.truth, r.max_dev_pct), (202.0, 200.0, 0.0));
    assert!((r.bias_pct() - 1.0).abs() < 1e-12);
    assert!(phi_stats(&rows, 3, true).mean.is_nan());
    assert_eq!(apart_pct(200.0, 199.0), 0.5);
}

#[test]
fn case_iv_p1_has_identical_pixels_at_two_test_depths() {
    let twins = identical_pixel_depths(&CASE_4, TEST_POINTS_XY[0], &TEST_DEPTHS);
    assert_eq!(twins, vec![(135.0, 145.0)]);
    // Case I sees P1 differently at every test depth.
    assert!(identical_pixel_depths(&CASE_1, TEST_POINTS_XY[0], &TEST_DEPTHS).is_empty());
    // On the axis 20 m away, one centimetre moves no pixel (u_l = 320 + 0.75 px).
    assert_eq!(
        identical_pixel_depths(&CASE_1, [0.0, 0.0], &[2000.0, 2001.0, 1000.0]),
        vec![(2000.0, 2001.0)]
    );
}

#[test]
fn disparities_of_the_phi_boards() {
    let d = CASE_1.half_baseline;
    // Parallel rig: u_l - u_r = Phi 2d / Z up to rounding.
    for z in [45.0, 105.0] {
        let got = board_disparity_px(&CASE_1, d, z).unwrap();
        let want = CASE_1.phi_u_left * 2.0 * d / z;
        assert!((got - want).abs() <= 1.0, "{z}: {got} vs {want}");
    }
    let r = board_disparity_px(&CASE_2, -d, 100.0).unwrap()
        / board_disparity_px(&CASE_1, d, 100.0).unwrap();
    assert!((r - 1.4).abs() < 0.05, "{r}");
    assert_eq!(board_disparity_px(&CASE_1, 0.0, -10.0), None);
}

#[test]
fn worst_depth_and_argmin() {
    let c = DepthCurve { z: vec![65.0, 75.0, 85.0], pct: vec![1.0, 3.0, 3.0], mean: 2.0 };
    assert_eq!(worst_depth(&c), 75.0);
    assert_eq!(argmin(&[3.0, 1.0, 1.0, 2.0]), 1);
    assert_eq!(argmin(&[]), 0);
}

#[test]
fn grids_and_lists_in_words() {
    assert_eq!(depth_grid(&presets::TRAIN_DEPTHS), "65-165 cm in steps of 20 cm");
    assert_eq!(depth_grid(&TEST_DEPTHS), "65-165 cm in steps of 10 cm");
    assert_eq!(depth_grid(&[65.0, 95.0, 165.0]), "65, 95, 165 cm");
    assert_eq!(depth_grid(&[]), " cm");
    assert_eq!(signed_list([-1.75, 1.75, 0.0]), "-1.75, +1.75, 0");
}

#[test]
fn traditional_ranges_within_ten_percent() {
    assert!(matches_thesis_traditional(1, 0.0, 1.806));
    assert!(matches_thesis_traditional(4, 158.7, 2600.0));
    assert!(!matches_thesis_traditional(4, 158.7, 2000.0));
    assert!(!matches_thesis_traditional(2, 13.0, 18.9));
    assert!(!matches_thesis_traditional(5, 0.0, 0.0));
}

#[test]
fn derived_seeds_differ_per_item_and_per_run() {
    let seeds = crate::grid([3, 3, 10, 10]).map(|[s, tag, a, b]| derive_seed(s, tag + 1, a, b));
    assert!(crate::distinct(seeds));
    assert_eq!(derive_seed(5, 1, 2, 3), derive_seed(5, 1, 2, 3));
}

#[test]
fn per_hidden_means_follow_the_rows() {
    let row = |outputs, hidden, worst, mean| NetRow {
        outputs,
        hidden,
        index: 0,
        seed: 0,
        train_pct: 1.0,
        test_mean_pct: mean,
        test_worst_pct: worst,
    };
    let rows = [
        row(OutputKind::Z, 3, 4.0, 1.0),
        row(OutputKind::Z, 3, 6.0, 2.0),
        row(OutputKind::Z, 1, 8.0, 3.0),
        row(OutputKind::Xyz, 1, 2.0, 1.0),
        row(OutputKind::Xyz, 3, 3.0, 1.5),
    ];
    assert_eq!(hidden_counts(&rows), vec![1, 3]);
    assert_eq!(e_ma_hn(&rows, OutputKind::Z), vec![8.0, 5.0]);
    assert_eq!(mean_e_ma_hn(&rows, OutputKind::Z), vec![3.0, 1.5]);
    assert_eq!(e_ma_hn(&rows, OutputKind::Xyz), vec![2.0, 3.0]);
}

#[test]
fn phi_points_are_symmetric_about_each_camera() {
    // The Phi experiment's board about the left camera's axis (X -3, -1, 1, 3 cm around it).
    let b = presets::board_points(95.0).map(|[x, y, z]| [HALF_BASELINE_CM + x, y, z]);
    let sum_xr: f64 = b.iter().map(|p| p[0] - HALF_BASELINE_CM).sum();
    assert_eq!(sum_xr, 0.0);
    assert!(b.iter().all(|p| p[2] == 95.0));
    // On an ideal parallel rig without rounding, eq. 4.1-3 is exact.
    let rig = Rig::parallel(300.0);
    let pairs: Vec<_> = b.iter().map(|p| rig.project(p).map(|px| (px[0], px[2]))).collect();
    let pairs: Vec<(f64, f64)> = pairs.into_iter().map(Result::unwrap).collect();
    let phi = phi_estimate(&pairs, 95.0, HALF_BASELINE_CM).unwrap();
    assert!((phi - 300.0).abs() < 1e-9, "{phi}");
}
