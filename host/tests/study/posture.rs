//! The posture study's parts at a small size: what they show must hold even there.

use hvs_host::sim::posture::{self as sim, Sampling};
use hvs_host::sim::sets::{SetKind, SimOptions};
use hvs_host::study::posture::page::command;
use hvs_host::study::posture::{
    csv_tables, distortion_study, fixed_posture_study, posture_aware_study, wide_board, Posture,
    PostureAware, StudyConfig, DEFAULT_SEED,
};
use hvs_host::train::{train, TrainConfig};
use hvs_shared::runtime::blob::{Family, ModelBlob, OutputFrame};
use hvs_shared::runtime::gaze::Joints;
use hvs_shared::sim::camera::Distortion;
use hvs_shared::sim::posture::HeadRig;
use hvs_shared::sim::presets;

#[test]
fn wide_board_stays_inside_the_image_and_the_lens_fold() {
    for n in 1..=4 {
        let rig = presets::case(n).unwrap();
        let head = HeadRig::new(rig).with_distortion(Distortion { k1: -0.5, k2: 0.0 });
        let [l, r] = head.cameras(&Joints::HOME);
        for z in [65.0, 165.0] {
            let b = wide_board(&rig, z, 9, 7);
            assert_eq!(b.len(), 63);
            for p in &b {
                let px = head.project(&Joints::HOME, p).unwrap();
                assert!(rig.in_image(&px), "case {n} {p:?}: {px:?}");
                for (c, cam) in [(0, &l), (2, &r)] {
                    let o = [px[c] - 320.0, px[c + 1] - 240.0];
                    assert!(cam.distortion.undo(o, 320.0).is_some(), "case {n} {p:?}");
                }
            }
        }
    }
}

/// The quick run's sizes, without its sweep, with a 2-level training grid and a 4-5-3 lens
/// net.
fn small() -> StudyConfig {
    StudyConfig {
        train_levels: [2, 2, 2, 2, 2],
        hidden: 8,
        sweep: Vec::new(),
        lattice: false,
        distortion_hidden: vec![5],
        quick: false,
        ..StudyConfig::experiment(DEFAULT_SEED, true)
    }
}

/// The posture-aware nets are trained in the configured family and frame (by default
/// `hvs train`'s for a posture-aware set); part (a) stays the thesis' net whatever it is.
#[test]
fn posture_aware_nets_use_the_configured_family() {
    assert_eq!(StudyConfig::default().family, hvs_host::train::DEFAULT_FAMILY);
    assert_eq!(StudyConfig::default().frame, OutputFrame::Cyclopean);
    let cfg = StudyConfig {
        train_levels: [1, 1, 1, 1, 2],
        test_postures: 10,
        test_points: 30,
        extreme_points: 10,
        fixed_points: 10,
        family: Family::INVERSE_DEPTH_SKIP,
        ..small()
    };
    let aware = posture_aware_study(&cfg, 3, Sampling::Grid).unwrap();
    assert_eq!(aware.blob.family, Family::INVERSE_DEPTH_SKIP);
    assert_eq!(aware.blob.frame, OutputFrame::Cyclopean);
    // 9-3-3: 13 * 3 + 3 net weights and 3 x 9 skip weights.
    assert_eq!(aware.blob.params.len(), 13 * 3 + 3 + 27);
    assert_eq!(aware.sweep[0].params, aware.blob.params.len());
    let (fixed, _) = fixed_posture_study(&cfg).unwrap();
    assert_eq!(fixed.family, Family::THESIS);
}

/// Any 9-input blob (a barely trained one) for the writers.
fn any_blob() -> ModelBlob {
    let head = HeadRig::new(presets::CASE_3);
    let js = [Joints::HOME, Joints([10.0, 5.0, -5.0, 3.0, 8.0])];
    let s = sim::simulate(&head, SetKind::Train, &js, &SimOptions::default()).unwrap();
    let cfg = TrainConfig { hidden: 3, restarts: 1, ..TrainConfig::default() };
    train(&sim::dataset(&s), &cfg).unwrap().blob
}

#[test]
fn fixed_posture_and_lens_parts_show_the_effects() {
    let cfg = small();
    let (_, fixed) = fixed_posture_study(&cfg).unwrap();
    // Home: the thesis net is near the floor; verged 10 degrees it is off by over 50 %.
    assert_eq!(fixed[0].label, "home");
    assert!(fixed[0].net.z_pct < 2.5, "{:?}", fixed[0]);
    let verged = fixed.iter().find(|f| f.label.starts_with("vergence 10")).unwrap();
    assert!(verged.net.z_pct > 50.0, "{verged:?}");
    assert!(verged.floor.z_pct < 2.0, "{verged:?}");
    // Without distortion the DLT is the floor up to rounding; at k1 = -0.5 the linear
    // model is clearly worse, the floor barely moves.
    let d = distortion_study(&cfg).unwrap();
    let (d0, d5) = (&d[0], &d[1]);
    assert_eq!(d0.max_shift_px, 0.0);
    assert!(d5.max_shift_px > 20.0, "{d5:?}");
    assert!(d0.dlt.z_pct < 1.1 * d0.floor.z_pct, "{d0:?}");
    assert!(d5.dlt.z_pct > 2.0 * d0.dlt.z_pct, "{d5:?}");
    assert!(d5.floor.z_pct < 1.5 * d0.floor.z_pct, "{d5:?}");
    assert_eq!((d0.floor.failed, d5.floor.failed, d5.dlt.failed), (0, 0, 0));
    // Writers: every table has a header and one line per row.
    let aware = PostureAware {
        blob: any_blob(),
        train_rows: 0,
        train_postures: 0,
        bands: Vec::new(),
        sweep: Vec::new(),
    };
    let r = Posture {
        config: cfg.clone(),
        fixed,
        aware,
        distortion: d,
        seconds: [0.0; 3],
        stage_s: Vec::new(),
        threads: 1,
    };
    let tables = csv_tables(&r);
    assert_eq!(tables[0].2.len(), r.fixed.len());
    assert_eq!(tables[3].2.len(), 2 * 3);
    assert_eq!(tables[4].0, "timing.csv");
    assert_eq!(tables[4].2.len(), 3);
    for (name, header, rows) in &tables {
        let columns = header.split(',').count();
        assert!(rows.iter().all(|r| r.len() == columns), "{name}");
    }
}

#[test]
fn quick_and_full_settings() {
    let full = StudyConfig::experiment(DEFAULT_SEED, false);
    let d = StudyConfig::default();
    // The settings of docs/posture-study.md's tables: the defaults and the example's `--sweep`.
    assert_eq!(
        (full.case, full.seed, full.train_levels, full.hidden),
        (d.case, d.seed, d.train_levels, d.hidden)
    );
    assert_eq!(
        (full.test_postures, full.test_points, full.k1.clone()),
        (d.test_postures, d.test_points, d.k1.clone())
    );
    assert_eq!(full.sweep, vec![5, 8, 12, 16, 24, 32]);
    assert!(full.lattice && full.sweep.contains(&full.hidden) && !full.quick);
    assert_eq!(command(&full), "hvs experiment posture --seed 1");
    let quick = StudyConfig::experiment(4, true);
    assert_eq!(quick.seed, 4);
    assert!(quick.sweep.contains(&quick.hidden) && quick.quick);
    assert_eq!(quick.k1.first(), Some(&0.0));
    assert_eq!(quick.k1.last(), Some(&-0.5));
    assert_eq!(command(&quick), "hvs experiment posture --seed 4 --quick");
    assert!(command(&StudyConfig::default()).contains("--example posture_study"));
}
