//! `hvs_host::study::accuracy`: the facts of the page, its seeds and levels, the commands it
//! prints, and the real pair's calibration.

use hvs_host::sim::board::TrainingBoard;
use hvs_host::study::accuracy::real_pair::{cameras, floor_depths, sets};
use hvs_host::study::accuracy::{
    floor_span, protocol_rows, regime_rows, set_seed, simulate_command, worst_over_cases,
    AccuracyConfig, RegimeRow, Scores, BIG_BOARD, HELD_OUT_SEED_BASE, REGIMES,
};
use hvs_host::study::engine::Quiet;
use hvs_shared::runtime::blob::Family;

fn quick() -> AccuracyConfig {
    AccuracyConfig {
        default_family: Family::INVERSE_DEPTH_SKIP,
        seed_base: HELD_OUT_SEED_BASE,
        quick: true,
    }
}

fn row(board: TrainingBoard, regime: usize, case: u8, s: [f64; 4]) -> RegimeRow {
    RegimeRow { board, regime: REGIMES[regime], case, scores: Scores(s) }
}

#[test]
fn worst_over_cases_is_the_largest_ratio_or_the_largest_exact_error() {
    let rows = [
        row(TrainingBoard::Thesis, 0, 1, [1.0, 1.1, 1.5, 1.2]),
        row(TrainingBoard::Thesis, 0, 2, [0.5, 0.6, 0.55, 0.7]),
        row(BIG_BOARD, 0, 1, [1.0, 9.0, 9.0, 9.0]),
        row(TrainingBoard::Thesis, 2, 1, [0.0, 1e-9, 0.3, 0.001]),
        row(TrainingBoard::Thesis, 2, 3, [0.0, 2e-9, 0.2, 0.002]),
    ];
    let (w, case) = worst_over_cases(&rows, &TrainingBoard::Thesis, "int", 3).unwrap();
    assert_eq!(case, 2);
    assert!((w - 1.4).abs() < 1e-12);
    assert_eq!(worst_over_cases(&rows, &TrainingBoard::Thesis, "int", 2), Some((1.5, 1)));
    assert_eq!(worst_over_cases(&rows, &TrainingBoard::Thesis, "exact", 2), Some((0.3, 1)));
    assert_eq!(worst_over_cases(&rows, &TrainingBoard::Thesis, "exact", 3), Some((0.002, 3)));
    assert!(worst_over_cases(&rows, &BIG_BOARD, "sub", 1).is_none());
    assert_eq!(floor_span(&rows, &TrainingBoard::Thesis, "int"), (0.5, 1.0));
}

#[test]
fn seeds_are_distinct_and_levels_span_the_issue() {
    let seeds = crate::grid([3, 2, 11, 4, 2]).map(|[part, b, level, case, set]| {
        set_seed(HELD_OUT_SEED_BASE, part, b as usize, level as usize, case as u8 + 1, set + 1)
    });
    assert!(crate::distinct(seeds));
    let full = AccuracyConfig { quick: false, ..quick() };
    let n = full.noise_levels();
    assert_eq!((n.len(), n[0], n[10]), (11, 0.0, 0.5));
    let k = full.k1_levels();
    assert_eq!((k.len(), k[0], k[10]), (11, 0.0, -0.2));
    assert_eq!((n[1], n[3], k[3], k[6]), (0.05, 0.15, -0.06, -0.12));
    assert_eq!((quick().noise_levels(), quick().k1_levels()), (vec![0.0, 0.5], vec![0.0, -0.2]));
    assert!(k[0].is_sign_positive(), "k1 = 0 prints as 0, not -0");
    assert_eq!(full.cases(), vec![1, 2, 3, 4]);
    assert_eq!(full.default_net().family, Family::INVERSE_DEPTH_SKIP);
    assert_eq!(full.thesis_net().family, Family::THESIS);
    assert_eq!(full.default_net().restarts, 10);
}

#[test]
fn the_floor_is_zero_on_exact_pixels_and_the_dlt_is_exact_there() {
    let cfg = quick();
    let rows = regime_rows(&cfg, &Quiet).unwrap();
    for r in rows.iter().filter(|r| r.board == TrainingBoard::Thesis) {
        let s = r.scores;
        let [floor, dlt, thesis, default] = s.0;
        assert!(s.0.iter().all(|v| v.is_finite()), "{r:?}");
        if r.regime.exact() {
            // Pinhole cameras without noise: both projective methods are exact, the thesis
            // net is not.
            assert!(floor < 1e-9 && dlt < 1e-9, "{s:?}");
            assert!(thesis > 10.0 * default.max(1e-4), "{s:?}");
        } else {
            // Rounding, noise or a lens: a real floor, and nothing far below it.
            assert!(floor > 1e-2, "{r:?}");
            for v in [dlt, thesis, default] {
                assert!(v > 0.8 * floor, "{r:?}");
            }
        }
    }
    let p = protocol_rows(&cfg).unwrap();
    assert_eq!(p.len(), 1);
    assert!(p[0].scores.0.iter().all(|v| v.is_finite() && *v > 0.0), "{p:?}");
}

#[test]
fn simulate_command_names_every_flag_of_the_regime() {
    let c = simulate_command(4, &BIG_BOARD, &REGIMES[1], "volume", 17);
    assert_eq!(
        c,
        "hvs simulate --case 4 --set volume --board 9x6:6 --pixels exact --noise-px 0.05 --points N --seed 17"
    );
    let c = simulate_command(1, &TrainingBoard::Thesis, &REGIMES[3], "train", 3);
    assert_eq!(c, "hvs simulate --case 1 --set train --distortion -0.1");
}

#[test]
fn the_true_cameras_reproject_the_motorcycle_fixture_within_its_rounding() {
    let (train_set, test) = sets().unwrap();
    assert_eq!((train_set.len(), test.len()), (1000, 2000));
    let p = cameras();
    for d in [&train_set, &test] {
        for n in 0..d.len() {
            let (r, t) = (d.row(n), d.targets[n]);
            for (c, m) in p.iter().enumerate() {
                let h = m * nalgebra::Vector4::new(t[0], t[1], t[2], 1.0);
                let (u, v) = (h[0] / h[2], h[1] / h[2]);
                assert!((u - r[2 * c]).abs() < 2e-3, "row {n} camera {c}: u {u} vs {}", r[2 * c]);
                assert!((v - r[2 * c + 1]).abs() < 2e-3, "row {n} camera {c}: v {v}");
            }
        }
    }
    let z = floor_depths(&test);
    let worst = (0..test.len())
        .map(|n| (z[n] - test.targets[n][2]).abs() / test.targets[n][2])
        .fold(0.0, f64::max);
    assert!(worst < 1e-5, "{worst}");
}
