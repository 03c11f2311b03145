//! `hvs experiment posture` on the reduced run (`--quick`): the shape and invariants of each
//! part, the files written, and determinism (the library run and the CLI run on one thread
//! with the same seed write the same CSV bytes).

use crate::common::{plot_svg, read, same_csv, spawn_quick_experiment, wait_ok, written_by};

use hvs_host::data::dataset::JOINT_COLUMNS;
use hvs_host::study::engine::Quiet;
use hvs_host::study::posture::page::STEMS;
use hvs_host::study::posture::{
    fixed_postures, run as posture_run, Posture, StudyConfig, HIDDEN_SWEEP_QUICK,
};

fn check_invariants(r: &Posture) {
    let c = &r.config;
    assert!(c.quick);

    // (a) Every posture of the study once, home first. At home the thesis net is at the
    // floor; verged 10 degrees it is off by over 100 % (tens of times the floor); turning
    // keeps the depth but not the direction, so the 3-D error outgrows the depth error.
    let postures = fixed_postures();
    assert_eq!(r.fixed.len(), postures.len());
    for (row, (label, j)) in r.fixed.iter().zip(&postures) {
        assert_eq!((&row.label, row.joints), (label, *j));
        assert_eq!(row.net.points, c.fixed_points);
        assert_eq!(row.floor.failed, 0, "{row:?}");
        assert!(row.floor.z_pct < 2.0, "{row:?}");
    }
    let home = &r.fixed[0];
    assert_eq!(home.label, "home");
    assert!(home.net.z_pct < 1.5 * home.floor.z_pct, "{home:?}");
    let verged = r.fixed.iter().find(|f| f.label.starts_with("vergence 10")).unwrap();
    assert!(verged.net.z_pct > 100.0, "{verged:?}");
    assert!(verged.net.z_pct > 20.0 * verged.floor.z_pct, "{verged:?}");
    let pan = r.fixed.iter().find(|f| f.label == "neck pan 30 deg").unwrap();
    assert!(pan.net.d3_pct > 2.0 * pan.net.z_pct, "{pan:?}");
    assert!(pan.net.d3_pct > 10.0 * pan.floor.d3_pct, "{pan:?}");

    // (b) The bands: all, three per gaze term (a partition of the test points), extreme.
    let bands = &r.aware.bands;
    assert_eq!(bands.len(), 1 + 5 * 3 + 1);
    assert_eq!(bands[0].term, "all");
    assert_eq!(bands[0].net.points, c.test_points);
    assert_eq!(bands[16].term, "extreme");
    assert_eq!(bands[16].net.points, c.extreme_points);
    for term in ["neck pan", "neck tilt", "eye tilt", "version", "vergence"] {
        let b: Vec<_> = bands.iter().filter(|b| b.term == term).collect();
        assert_eq!(b.len(), 3, "{term}");
        assert_eq!(b.iter().map(|b| b.net.points).sum::<usize>(), c.test_points, "{term}");
    }
    for b in bands {
        // Rounding, not posture, limits the floor: about the same in every band.
        assert!(b.floor.z_pct > 0.9 && b.floor.z_pct < 1.9, "{b:?}");
        assert_eq!((b.floor.failed, b.net.failed), (0, 0), "{b:?}");
        assert!(b.ratio() > 1.0, "{b:?}");
    }
    // Even from 8 training postures and 6 hidden neurons (the full run: 1.04 x) the
    // posture-aware net stays within a few times the floor over the working range, and at the
    // nearest fixations (vergence 6.7-10) it is far better than the thesis net verged 10 deg.
    assert!(bands[0].ratio() < 6.0, "{:?}", bands[0]);
    let near = bands.iter().rfind(|b| b.term == "vergence").unwrap();
    assert!(near.net.z_pct < verged.net.z_pct / 10.0, "{near:?}");

    // (c) The sweep: the quick counts on the grid, the chosen one on the lattice too.
    let sweep = &r.aware.sweep;
    let grid: Vec<usize> =
        sweep.iter().filter(|h| h.postures == "grid").map(|h| h.hidden).collect();
    assert_eq!(grid, HIDDEN_SWEEP_QUICK.to_vec());
    let lattice: Vec<usize> =
        sweep.iter().filter(|h| h.postures == "lattice").map(|h| h.hidden).collect();
    assert_eq!(lattice, vec![c.hidden]);
    for h in sweep {
        // 9-H-3: 9H + H weights and biases into the hidden layer, 3H + 3 out, and the
        // family's skip weights (3 x 9 for the default family).
        assert_eq!(h.params, 13 * h.hidden + 3 + c.family.skip_len(9, 3), "{h:?}");
        assert!(h.train_pct.is_finite() && h.test.z_pct.is_finite(), "{h:?}");
        assert!(h.worst_band_ratio >= h.test.z_pct / h.floor.z_pct, "{h:?}");
        assert_eq!(h.floor, bands[0].floor);
    }
    let chosen = sweep.iter().find(|h| h.postures == "grid" && h.hidden == c.hidden).unwrap();
    assert_eq!(chosen.test, bands[0].net);
    // More hidden neurons fit the training set better.
    assert!(sweep[0].train_pct > chosen.train_pct, "{sweep:?}");

    // (d) Lens: no shift without distortion; at k1 = -0.5 the linear DLT is clearly worse,
    // the floor barely moves, the net stays near it.
    let d = &r.distortion;
    assert_eq!(d.iter().map(|d| d.k1).collect::<Vec<_>>(), c.k1);
    let (d0, d5) = (&d[0], &d[d.len() - 1]);
    assert_eq!((d0.k1, d5.k1), (0.0, -0.5));
    assert_eq!(d0.max_shift_px, 0.0);
    assert!(d5.max_shift_px > 20.0, "{d5:?}");
    assert!(d0.dlt.z_pct < 1.1 * d0.floor.z_pct, "{d0:?}");
    assert!(d5.dlt.z_pct > 2.0 * d0.dlt.z_pct, "{d5:?}");
    assert!(d5.floor.z_pct < 1.5 * d0.floor.z_pct, "{d5:?}");
    assert!(d5.nets[0].1.z_pct < d5.dlt.z_pct, "{d5:?}");
    assert_eq!((d5.floor.failed, d5.dlt.failed), (0, 0));
}

/// The rows of a CSV (header first), parsed with the quotes the labels need.
fn csv_rows(text: &str) -> Vec<Vec<String>> {
    let mut rdr = csv::ReaderBuilder::new().has_headers(false).from_reader(text.as_bytes());
    rdr.records().map(|r| r.unwrap().iter().map(str::to_string).collect()).collect()
}

#[test]
fn quick_run_invariants_files_and_determinism() {
    let cfg = StudyConfig::experiment(1, true);
    // The command (same seed, one worker thread) runs while the library run does.
    let cli = spawn_quick_experiment("posture", &["--seed", "1"]);
    let out = cli.out.clone();

    let run = posture_run(&cfg, &Quiet).unwrap();
    check_invariants(&run);
    let (lib_dir, written) = written_by(&run);
    assert_eq!(written.len(), 3 * STEMS.len() + 2);

    let (stdout, stderr) = wait_ok(cli.child);
    assert!(stdout.contains("POSTURE.md"), "{stdout}");
    // Not a terminal: no progress bars.
    assert!(stderr.is_empty(), "{stderr:?}");

    let r = &run;
    let headers = [
        ("fixed", format!("posture,{},net_points", JOINT_COLUMNS.join(",")), r.fixed.len()),
        ("bands", "term,band,net_points,net_z_pct".to_string(), r.aware.bands.len()),
        ("hidden", "postures,hidden,params,train_pct,test_points".to_string(), r.aware.sweep.len()),
        (
            "distortion",
            "k1,max_shift_px,method,points,z_pct".to_string(),
            r.distortion.len() * (r.distortion[0].nets.len() + 2),
        ),
    ];
    for (stem, header, rows) in &headers {
        let csv = format!("{stem}.csv");
        let text = same_csv(lib_dir.path(), &out, stem);
        assert!(text.starts_with(header.as_str()), "{csv}: {text}");
        let parsed = csv_rows(&text);
        assert_eq!(parsed.len(), 1 + rows, "{csv}");
        for row in &parsed {
            assert_eq!(row.len(), parsed[0].len(), "{csv}: {row:?}");
        }
        let svg = plot_svg(&out, stem);
        assert!(
            svg.contains("(%") || svg.contains("(deg)"),
            "{stem}.svg has no unit in its labels"
        );
    }
    assert_eq!(STEMS.to_vec(), headers.map(|h| h.0).to_vec());
    // Wall times live in timing.csv only.
    let timing = String::from_utf8(read(&out.join("timing.csv"))).unwrap();
    assert!(timing.starts_with("what,postures,hidden,seconds\n"));
    assert_eq!(timing.lines().count(), 1 + 3 + r.aware.sweep.len());

    // POSTURE.md links only files that exist (docs/posture-study.md is two levels up, outside
    // the output directory), states the goal and the command.
    let md = String::from_utf8(read(&out.join("POSTURE.md"))).unwrap();
    let mut links = 0;
    for part in md.split("](").skip(1) {
        let target = &part[..part.find(')').unwrap()];
        if target.starts_with("../") {
            continue;
        }
        assert!(out.join(target).is_file(), "POSTURE.md links missing {target}");
        links += 1;
    }
    assert!(links >= 4 * STEMS.len(), "{links} links");
    for want in
        ["hvs experiment posture --seed 1 --quick", "at most 1.20 x", "## Tables", "#### (a)"]
    {
        assert!(md.contains(want), "POSTURE.md lacks {want}");
    }
}
