//! `hvs experiment thesis` on the reduced run (`--quick`): the shape and invariants of every
//! experiment, the files written, and determinism (the library run and the CLI run with the
//! same seed write the same CSV bytes).

use crate::common::{plot_svg, read, same_csv, spawn_quick_experiment, wait_ok, written_by};

use assert_cmd::Command;
use hvs_host::study::engine::Quiet;
use hvs_host::study::thesis::{
    e_ma_hn, hidden_counts, report, run, Config, Thesis, FEWER_DEPTHS, PHI_DEPTHS,
};
use hvs_host::train::Algo;
use hvs_shared::runtime::blob::OutputKind;
use hvs_shared::sim::presets::TEST_DEPTHS;

fn check_invariants(t: &Thesis) {
    let cfg = t.config;
    assert!(cfg.quick);

    // Figs. 4.3, 4.4: two parallel cases x 7 depths. From rounded pixels eq. 4.1-3 recovers
    // each camera's Phi within 1 % on average over the depths (0.2 % here) and within 1.5 % at
    // every depth (one pixel of disparity at 95 cm moves it by 1.3 %).
    assert_eq!(t.phi.len(), 2 * PHI_DEPTHS.len());
    for case in [1u8, 2] {
        let rows: Vec<_> = t.phi.iter().filter(|r| r.case == case).collect();
        let n = rows.len() as f64;
        let mean_l = rows.iter().map(|r| r.phi_l).sum::<f64>() / n;
        let mean_r = rows.iter().map(|r| r.phi_r).sum::<f64>() / n;
        assert!((mean_l / rows[0].true_l - 1.0).abs() < 0.01, "case {case}: {mean_l}");
        assert!((mean_r / rows[0].true_r - 1.0).abs() < 0.01, "case {case}: {mean_r}");
        for r in &rows {
            for (est, truth) in [(r.phi_l, r.true_l), (r.phi_r, r.true_r)] {
                assert!(
                    (est / truth - 1.0).abs() < 0.015,
                    "case {case} Z {}: {est} vs {truth}",
                    r.z
                );
            }
        }
    }
    // Case II's two estimates separate its two focal lengths (285.8 and 406.9 px).
    assert!(t.phi.iter().filter(|r| r.case == 2).all(|r| r.phi_r > 1.3 * r.phi_l));

    // Figs. 4.8-4.11: 11 depths per case; the thesis' restriction of eq. 3.1-17.
    assert_eq!(t.traditional.len(), 4);
    for c in &t.traditional {
        assert_eq!(c.traditional.z, TEST_DEPTHS.to_vec());
        assert_eq!(c.optimal.z, TEST_DEPTHS.to_vec());
        assert!(c.optimal.worst() < 4.5, "case {}: floor {}", c.case, c.optimal.worst());
    }
    let tr = |n: usize| &t.traditional[n - 1].traditional;
    assert!(tr(1).worst() < 2.0, "case I: {}", tr(1).worst());
    assert!(tr(2).best() > 10.0 && tr(2).worst() < 25.0, "case II: {:?}", tr(2).pct);
    assert!(tr(3).worst() > 100.0, "case III: {}", tr(3).worst());
    assert!(tr(4).best() > 100.0, "case IV: {}", tr(4).best());

    // Figs. 4.12, 4.16-4.19: the proposed net near the floor, far below the traditional
    // method where that fails.
    assert_eq!(t.proposed.len(), 4);
    for p in &t.proposed {
        assert_eq!(p.net.z, TEST_DEPTHS.to_vec());
        assert!(
            p.net.worst() < 1.5 * p.optimal.worst().max(1.0),
            "case {}: net {} vs floor {}",
            p.case,
            p.net.worst(),
            p.optimal.worst()
        );
        assert!(p.net.mean < 2.5, "case {}: mean {}", p.case, p.net.mean);
        assert!(p.train_pct.is_finite() && p.train_pct < 2.0);
    }

    // Figs. 4.13-4.15: every (outputs, hidden, net) once.
    assert_eq!(hidden_counts(&t.sweep), cfg.hidden().to_vec());
    assert_eq!(t.sweep.len(), 2 * cfg.hidden().len() * cfg.nets());
    let five = t.sweep.iter().filter(|r| r.hidden == 5 && r.outputs == OutputKind::Xyz).count();
    assert_eq!(five, cfg.nets());
    for r in &t.sweep {
        assert!(r.train_pct.is_finite() && r.test_worst_pct >= r.test_mean_pct);
    }
    // The thesis' measure: three outputs beat one on average over the neuron counts (the
    // margin is small here: 4.31 % vs 4.33 % on the quick run, 4.29 % vs 4.34 % on the full).
    let avg = |v: Vec<f64>| v.iter().sum::<f64>() / v.len() as f64;
    let (one, three) =
        (avg(e_ma_hn(&t.sweep, OutputKind::Z)), avg(e_ma_hn(&t.sweep, OutputKind::Xyz)));
    assert!(three < one, "three outputs {three} % vs one {one} %");
    // More hidden neurons fit the training boards better.
    for o in [OutputKind::Z, OutputKind::Xyz] {
        let train = |h: usize| {
            avg(t
                .sweep
                .iter()
                .filter(|r| r.outputs == o && r.hidden == h)
                .map(|r| r.train_pct)
                .collect())
        };
        let h = cfg.hidden();
        assert!(train(h[0]) > train(h[h.len() - 1]), "{o:?}");
    }

    // Figs. 4.20-4.22: fewer depths, fewer points, larger errors.
    assert_eq!(t.fewer.len(), FEWER_DEPTHS.len());
    for (f, d) in t.fewer.iter().zip(FEWER_DEPTHS) {
        assert_eq!(f.depths, d.to_vec());
        assert_eq!(f.points, 12 * d.len());
        assert_eq!(f.net.z, TEST_DEPTHS.to_vec());
        assert_eq!(f.bp.z, TEST_DEPTHS.to_vec());
    }
    assert!(t.fewer[0].net.mean > t.fewer[1].net.mean);
    assert!(t.fewer[1].net.mean > t.fewer[2].net.mean);
    assert!(t.fewer[0].net.mean > 2.0 * t.proposed[3].net.mean);

    // BP vs. LM: both algorithms on every case; LM stays near the floor.
    assert_eq!(t.algos.len(), 8);
    for case in 1..=4u8 {
        for algo in [Algo::Lm, Algo::Bp] {
            let r = t.algos.iter().find(|r| r.case == case && r.algo == algo).unwrap();
            assert!(r.train_pct.is_finite() && r.wall_s > 0.0);
        }
    }

    // Noise: the floor grows with sigma, the net follows it.
    let levels = cfg.noise_levels();
    assert_eq!(t.noise.len(), 4 * levels.len());
    for case in 1..=4u8 {
        let rows: Vec<_> = t.noise.iter().filter(|r| r.case == case).collect();
        for w in rows.windows(2) {
            assert!(w[0].sigma < w[1].sigma);
            assert!(w[0].optimal_pct < w[1].optimal_pct, "case {case}");
        }
        assert!(rows[rows.len() - 1].network_pct > rows[0].network_pct);
        for r in &rows {
            assert!(
                r.network_pct < 1.6 * r.optimal_pct,
                "case {case} sigma {}: net {} floor {}",
                r.sigma,
                r.network_pct,
                r.optimal_pct
            );
        }
    }
    let c1 = t.noise.iter().find(|r| r.case == 1 && r.sigma == 0.0).unwrap();
    assert!(c1.traditional_pct < 1.3 * c1.optimal_pct);
    let c4 = t.noise.iter().find(|r| r.case == 4 && r.sigma == 0.0).unwrap();
    assert!(c4.traditional_pct > 100.0);
}

#[test]
fn quick_run_invariants_files_and_determinism() {
    let cfg = Config { seed: 0, quick: true };
    // The command (same seed, another directory, one worker thread) runs while the library
    // run below does (all threads): equal CSVs also show the thread count does not matter.
    let cli = spawn_quick_experiment("thesis", &["--seed", "0"]);
    let out = cli.out.clone();

    let t = run(&cfg, &Quiet).unwrap();
    check_invariants(&t);
    let (lib_dir, written) = written_by(&t);
    assert_eq!(written.len(), 3 * report::STEMS.len() + 2);

    let (stdout, _) = wait_ok(cli.child);
    assert!(stdout.contains("RESULTS.md"), "{stdout}");

    for stem in report::STEMS {
        let csv = format!("{stem}.csv");
        let text = same_csv(lib_dir.path(), &out, stem);
        let mut lines = text.lines();
        let cols = lines.next().unwrap().split(',').count();
        let mut rows = 0;
        for l in lines {
            assert_eq!(l.split(',').count(), cols, "{csv}: {l}");
            rows += 1;
        }
        assert!(rows > 0, "{csv} has no rows");
        let svg = plot_svg(&out, stem);
        // Labelled axes with units.
        assert!(
            svg.contains("(cm)") || svg.contains("(%") || svg.contains("(% of"),
            "{stem}.svg has no unit in its labels"
        );
    }
    assert!(out.join("bp_vs_lm_timing.csv").is_file());

    // RESULTS.md links only files that exist, and names the thesis' numbers.
    let md = String::from_utf8(read(&out.join("RESULTS.md"))).unwrap();
    let mut links = 0;
    for part in md.split("](").skip(1) {
        let target = &part[..part.find(')').unwrap()];
        assert!(out.join(target).is_file(), "RESULTS.md links missing {target}");
        links += 1;
    }
    assert!(links >= 3 * report::STEMS.len(), "{links} links");
    for thesis_value in ["2653.9037", "2.4771", "53.0081", "142.918"] {
        assert!(md.contains(thesis_value), "RESULTS.md lacks {thesis_value}");
    }
    assert!(md.contains("--quick"));
}

/// Both studies: an output path that is a file is a one-line error naming it.
#[test]
fn an_unusable_output_directory_is_a_clear_error() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("not_a_dir");
    std::fs::write(&file, b"x").unwrap();
    for study in ["thesis", "posture"] {
        let assert = Command::cargo_bin("hvs")
            .unwrap()
            .args(["experiment", study, "--quick", "-o"])
            .arg(&file)
            .assert()
            .failure()
            .code(1);
        let err = String::from_utf8_lossy(&assert.get_output().stderr).into_owned();
        assert!(err.contains("not_a_dir") && err.contains("cannot create"), "{study}: {err}");
    }
}
