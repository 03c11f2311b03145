//! `hvs demo`: the thesis' experiment end to end, with no arguments: simulate the four
//! camera cases, train the default net on each, evaluate it next to the traditional method,
//! print the comparison with the thesis' own numbers and write models, data and a report.

use crate::cli::train::{train_model, Plan};
use crate::data::csv::{write_atomically, write_output};
use crate::data::dataset::Dataset;
use crate::data::model;
use crate::evaluate::{
    evaluate, model_depths, optimal_depths, text_table, traditional_depths, Evaluation, Method,
};
use crate::fmt::{pct, roman};
use crate::sim::sets::{simulate, write_csv, Sample, SetKind, SimOptions};
use crate::study::reported::{self, NET_BOUND_PCT};
use crate::train::TrainConfig;
use anyhow::{anyhow, Context, Result};
use hvs_shared::runtime::blob::InputKind;
use hvs_shared::runtime::traditional::Calibration;
use hvs_shared::sim::presets::{self, LABELS};
use rayon::prelude::*;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Random points of the training volume used for the accuracy-floor comparison.
pub const VOLUME_POINTS: usize = 500;
/// Random points of the training volume a second net is trained on.
pub const VOLUME_TRAIN_POINTS: usize = 1000;

/// Arguments of `hvs demo`.
#[derive(Debug, clap::Args)]
#[command(
    about = "The thesis' experiment end to end: 4 camera cases, traditional vs. network",
    long_about = "The thesis' experiment end to end, no arguments needed. For each of the four \
    camera cases: simulate the training boards (72 points), the test points (22) and 500 random \
    points of the training volume; train the default 4-5-3 net; compare its depth error with \
    the traditional method (eq. 3.1-17 with the Phi calibrated on case I as in the thesis, and \
    with Phi refitted on the case's own boards) and with optimal triangulation using the true \
    rig; train a second net on 1000 random points of the training volume and compare it with \
    that floor on 500 others. Prints the table next to the thesis' numbers and writes the data \
    (caseN_{train,test,volume_train,volume_test}.csv), the models (caseN.hvsw, \
    caseN_volume.hvsw) and REPORT.md into the output directory."
)]
pub struct Args {
    /// Output directory (created if missing).
    #[arg(short = 'o', long, value_name = "DIR", default_value = "hvs-demo")]
    output: PathBuf,
    /// Seed of the training restarts and of the random volume points.
    #[arg(long, value_name = "S", default_value_t = 0, allow_negative_numbers = true, value_parser = crate::cli::whole_u64)]
    seed: u64,
    /// Restarts per net (the default net's 10; fewer for a quick run).
    #[arg(long, value_name = "R", default_value_t = TrainConfig::default().restarts, allow_negative_numbers = true, value_parser = crate::cli::whole_usize)]
    restarts: usize,
    /// Instead, the image front end end to end: render stereo photos of a 9x6 board, detect
    /// the corners, train the default model on them, predict on other rendered boards and
    /// compare with the floor on the same detected corners (writes caseN_images/ and IMAGES.md).
    #[arg(long)]
    images: bool,
}

/// Results of one case.
#[derive(Debug, Clone)]
pub struct CaseResult {
    /// Case number 1-4.
    pub case: u8,
    /// Test set: network, traditional (thesis Phi), optimal (true rig), then traditional
    /// (refit Phi) when the model has a fallback.
    pub test: Evaluation,
    /// Volume test set: volume-trained network, board-trained network, optimal (true rig).
    pub volume: Evaluation,
    /// Training e_ma of the board-trained model (%).
    pub train_pct: f64,
    /// Training e_ma of the volume-trained model (%).
    pub volume_train_pct: f64,
    /// Refitted Phi, if any.
    pub refit_phi: Option<f64>,
    /// Training wall time of the board-trained and the volume-trained model (s).
    pub train_s: [f64; 2],
}

/// Seed of case `n`'s random volume training set.
pub fn volume_train_seed(seed: u64, n: u8) -> u64 {
    seed.wrapping_mul(10_000).wrapping_add(1000 + n as u64)
}

/// Seed of case `n`'s random volume test set.
pub fn volume_test_seed(seed: u64, n: u8) -> u64 {
    seed.wrapping_mul(10_000).wrapping_add(2000 + n as u64)
}

fn dataset(samples: &[Sample]) -> Dataset {
    let mut d = Dataset::new(InputKind::Stereo);
    for s in samples {
        d.push(&s.px, Some(s.xyz));
    }
    d
}

fn write_set(dir: &Path, name: &str, samples: &[Sample]) -> Result<()> {
    let p = dir.join(name);
    write_atomically(&p, |w| {
        write_csv(w, samples).with_context(|| format!("{}: cannot write", p.display()))
    })
}

/// Runs one case, writing its files into `dir`.
pub fn run_case(n: u8, dir: &Path, seed: u64, restarts: usize) -> Result<CaseResult> {
    let rig = presets::case(n).ok_or_else(|| anyhow!("no case {n}"))?;
    let sim = |kind, points, seed| {
        simulate(
            &rig,
            kind,
            &SimOptions {
                points,
                noise_px: 0.0,
                seed,
                ..SimOptions::default()
            },
        )
    };
    let train = sim(SetKind::Train, 0, 0)?;
    let test = sim(SetKind::Test, 0, 0)?;
    let vtrain = sim(
        SetKind::Volume,
        VOLUME_TRAIN_POINTS,
        volume_train_seed(seed, n),
    )?;
    let vtest = sim(SetKind::Volume, VOLUME_POINTS, volume_test_seed(seed, n))?;
    write_set(dir, &format!("case{n}_train.csv"), &train)?;
    write_set(dir, &format!("case{n}_test.csv"), &test)?;
    write_set(dir, &format!("case{n}_volume_train.csv"), &vtrain)?;
    write_set(dir, &format!("case{n}_volume_test.csv"), &vtest)?;
    let (train, test) = (dataset(&train), dataset(&test));
    let (vtrain, vtest) = (dataset(&vtrain), dataset(&vtest));

    let mut plan = Plan::default();
    plan.config.seed = seed;
    plan.config.progress = false;
    plan.config.restarts = restarts;
    let t = train_model(&train, &plan).with_context(|| format!("case {n}: training failed"))?;
    model::save(&dir.join(format!("case{n}.hvsw")), &t.blob)?;
    let tv = train_model(&vtrain, &plan)
        .with_context(|| format!("case {n}: training on the volume set failed"))?;
    model::save(&dir.join(format!("case{n}_volume.hvsw")), &tv.blob)?;

    let net = |b: &hvs_shared::runtime::blob::ModelBlob, d: &Dataset| {
        model_depths(b, d).map_err(|e| anyhow!("case {n}: the model failed: {e:?}"))
    };
    let mut test_methods = vec![
        Method {
            name: "network".into(),
            z: net(&t.blob, &test)?,
        },
        Method {
            name: "trad. (thesis Phi)".into(),
            z: traditional_depths(&Calibration::BUILT_IN, &test),
        },
        Method {
            name: "optimal (true rig)".into(),
            z: optimal_depths(&rig, &test),
        },
    ];
    if let Some(c) = &t.blob.fallback {
        test_methods.push(Method {
            name: "trad. (refit Phi)".into(),
            z: traditional_depths(c, &test),
        });
    }
    let vol_methods = [
        Method {
            name: "net (volume-trained)".into(),
            z: net(&tv.blob, &vtest)?,
        },
        Method {
            name: "net (board-trained)".into(),
            z: net(&t.blob, &vtest)?,
        },
        Method {
            name: "optimal (true rig)".into(),
            z: optimal_depths(&rig, &vtest),
        },
    ];
    Ok(CaseResult {
        case: n,
        test: evaluate(&test, &test_methods),
        volume: evaluate(&vtest, &vol_methods),
        train_pct: t.outcome.train_error_pct,
        volume_train_pct: tv.outcome.train_error_pct,
        refit_phi: t.fallback.map(|f| f.phi),
        train_s: [
            t.outcome.elapsed.as_secs_f64(),
            tv.outcome.elapsed.as_secs_f64(),
        ],
    })
}

/// The comparison table, one row per case, as cells.
fn table(results: &[CaseResult]) -> (Vec<&'static str>, Vec<Vec<String>>) {
    let head = vec![
        "case",
        "traditional, thesis Phi: depths",
        "thesis' trad.",
        "trad., refit Phi: worst",
        "network: worst (mean)",
        "optimal, true rig: worst",
        "thesis' net",
        "volume: net / floor",
    ];
    let rows = results
        .iter()
        .map(|r| {
            let m = &r.test.methods;
            let net_ok = m[0].worst_depth_pct < NET_BOUND_PCT;
            let (vn, vf) = (
                r.volume.methods[0].mean.e_ma_pct,
                r.volume.methods[2].mean.e_ma_pct,
            );
            vec![
                roman(r.case).to_string(),
                format!(
                    "{} .. {}",
                    pct(m[1].best_depth_pct),
                    pct(m[1].worst_depth_pct)
                ),
                reported::traditional_range(r.case).unwrap_or_default(),
                m.get(3)
                    .map_or("no fallback".into(), |s| pct(s.worst_depth_pct)),
                format!(
                    "{} ({}){}",
                    pct(m[0].worst_depth_pct),
                    pct(m[0].mean.e_ma_pct),
                    if net_ok {
                        String::new()
                    } else {
                        format!(" > {NET_BOUND_PCT} %")
                    }
                ),
                pct(m[2].worst_depth_pct),
                format!("< {NET_BOUND_PCT} %"),
                format!(
                    "{} / {} ({:+.1} %)",
                    pct(vn),
                    pct(vf),
                    (vn / vf - 1.0) * 100.0
                ),
            ]
        })
        .collect();
    (head, rows)
}

fn text(head: &[&str], rows: &[Vec<String>]) -> String {
    let mut w: Vec<usize> = head.iter().map(|h| h.len()).collect();
    for r in rows {
        for (k, c) in r.iter().enumerate() {
            w[k] = w[k].max(c.chars().count());
        }
    }
    let mut s = String::new();
    let line = |s: &mut String, cells: Vec<&str>| {
        let parts: Vec<String> = cells
            .iter()
            .zip(&w)
            .map(|(c, w)| format!("{c:<w$}"))
            .collect();
        let _ = writeln!(s, "{}", parts.join("  ").trim_end());
    };
    line(&mut s, head.to_vec());
    line(
        &mut s,
        w.iter()
            .map(|n| "-".repeat(*n))
            .collect::<Vec<_>>()
            .iter()
            .map(|x| x.as_str())
            .collect(),
    );
    for r in rows {
        line(&mut s, r.iter().map(|c| c.as_str()).collect());
    }
    s
}

fn markdown(head: &[&str], rows: &[Vec<String>]) -> String {
    let mut s = format!("| {} |\n|{}\n", head.join(" | "), "---|".repeat(head.len()));
    for r in rows {
        let _ = writeln!(s, "| {} |", r.join(" | "));
    }
    s
}

fn report(results: &[CaseResult], tbl: &str, total_s: f64, seed: u64, restarts: usize) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "# hvs demo report\n");
    let _ = writeln!(
        s,
        "The thesis' four camera cases, simulated with the thesis camera model (`hvs-shared`), \
         training seed {seed}, {total_s:.2} s in all. For each case the default net (4-5-3, \
         Levenberg-Marquardt, {restarts} seeded restarts) was trained on the 72 training-board points \
         and tested on P1, P2 at the 11 test depths (65..165 cm), as in the thesis; a second \
         default net was trained on {VOLUME_TRAIN_POINTS} random points of the training volume \
         and tested on {VOLUME_POINTS} other ones.\n"
    );
    let _ = writeln!(s, "{tbl}");
    let _ = writeln!(
        s,
        "- *traditional, thesis Phi*: eq. 3.1-17 with Phi = {} px, calibrated by eq. 4.1-3 on \
         case I's board at 65 cm, as the thesis calibrates its HVS once; the smallest and \
         largest per-depth e_ma on the test points, to compare with the thesis' range \
         (Figs. 4.8-4.11). Negative disparities are evaluated as printed, as in the thesis' \
         figures.\n\
         - *trad., refit Phi*: the same formula with Phi refitted on the case's own training \
         boards (the fallback stored in `caseN.hvsw`): a better Phi does not rescue the formula \
         when the cameras differ.\n\
         - *network*: worst per-depth e_ma of the exported f32 model (what the head computes), \
         mean over all test points in brackets; the thesis' bound is the worst depth below {NET_BOUND_PCT} %.\n\
         - *optimal, true rig*: least-reprojection-error triangulation with the exact rig on \
         the same rounded pixels: what the pixel rounding alone costs on these 22 points. \
         Where it is close to {NET_BOUND_PCT} %, no calibration-free method can be expected to stay below \
         the thesis' bound on simulated pixels.\n\
         - *volume*: mean e_ma of the volume-trained net on the {VOLUME_POINTS} test points of \
         the training volume (X -3..3, Y -2..2, Z 65..165 cm), next to optimal triangulation \
         with the true rig on the same pixels (the floor), and how far above the floor it is.\n",
        Calibration::BUILT_IN.phi
    );
    for r in results {
        let k = (r.case - 1) as usize;
        let _ = writeln!(s, "## Case {}\n\n{}.\n", roman(r.case), &LABELS[k]);
        let _ = writeln!(
            s,
            "Board-trained net: training e_ma {:.4} %, {:.3} s; volume-trained net: training \
             e_ma {:.4} %, {:.3} s; refitted Phi {}.\n",
            r.train_pct,
            r.train_s[0],
            r.volume_train_pct,
            r.train_s[1],
            r.refit_phi.map_or("none".into(), |p| format!("{p:.4} px"))
        );
        let _ = writeln!(s, "Test points:\n\n```text\n{}```\n", text_table(&r.test));
        let _ = writeln!(
            s,
            "Volume test points (depth bins):\n\n```text\n{}```\n",
            text_table(&r.volume)
        );
    }
    let (vtr, vte) = (volume_train_seed(seed, 1), volume_test_seed(seed, 1));
    let _ = writeln!(
        s,
        "## Files and how to redo each step\n\n\
         `caseN_train.csv`, `caseN_test.csv`, `caseN_volume_train.csv`, \
         `caseN_volume_test.csv` (u_l,v_l,u_r,v_r,x,y,z); `caseN.hvsw` (board-trained, with \
         the refit fallback) and `caseN_volume.hvsw` (volume-trained, no fallback: random points \
         hold no symmetric board). For case 1:\n\n```sh\n\
         hvs simulate --case 1 --set train -o case1_train.csv\n\
         hvs simulate --case 1 --set test -o case1_test.csv\n\
         hvs simulate --case 1 --set volume --points {VOLUME_TRAIN_POINTS} --seed {vtr} -o case1_volume_train.csv\n\
         hvs simulate --case 1 --set volume --points {VOLUME_POINTS} --seed {vte} -o case1_volume_test.csv\n\
         hvs train --data case1_train.csv --seed {seed} --restarts {restarts} -o case1.hvsw\n\
         hvs train --data case1_volume_train.csv --seed {seed} --restarts {restarts} -o case1_volume.hvsw\n\
         hvs eval --model case1.hvsw --data case1_test.csv --case 1\n\
         hvs eval --model case1_volume.hvsw --data case1_volume_test.csv --case 1\n```"
    );
    s
}

/// Runs `hvs demo`.
pub fn run(a: Args) -> Result<()> {
    let start = Instant::now();
    if a.restarts == 0 {
        anyhow::bail!("--restarts must be at least 1");
    }
    std::fs::create_dir_all(&a.output)
        .with_context(|| format!("{}: cannot create the directory", a.output.display()))?;
    if a.images {
        return super::demo_images::run(&a.output, a.seed, a.restarts);
    }
    // Cases run in parallel; each is deterministic on its own, so the output does not
    // depend on the scheduling.
    let results = (1..=4u8)
        .into_par_iter()
        .map(|n| run_case(n, &a.output, a.seed, a.restarts))
        .collect::<Result<Vec<_>>>()?;
    let total = start.elapsed().as_secs_f64();
    let (head, rows) = table(&results);
    let md = markdown(&head, &rows);
    write_atomically(&a.output.join("REPORT.md"), |w| {
        w.write_all(report(&results, &md, total, a.seed, a.restarts).as_bytes())
            .context("cannot write REPORT.md")
    })?;
    let mut out = String::new();
    let _ = writeln!(
        out,
        "The thesis' four camera cases: default 4-5-3 net vs. the traditional method\n\
         (eq. 3.1-17); e_ma in % of the true depth on the test points P1, P2 at 65..165 cm.\n"
    );
    // Two tables of at most 100 columns (REPORT.md keeps the one wide table): the
    // traditional method, then the net, the floor and the volume.
    for (k, cols) in [&[0usize, 1, 2, 3][..], &[0, 4, 5, 6, 7][..]]
        .iter()
        .enumerate()
    {
        let h: Vec<&str> = cols.iter().filter_map(|&c| head.get(c).copied()).collect();
        let r: Vec<Vec<String>> = rows
            .iter()
            .map(|row| cols.iter().filter_map(|&c| row.get(c).cloned()).collect())
            .collect();
        if k > 0 {
            out.push('\n');
        }
        out.push_str(&text(&h, &r));
    }
    let _ = writeln!(
        out,
        "\nwrote models, data and REPORT.md to {} in {total:.2} s",
        a.output.display()
    );
    write_output(None, |w| Ok(w.write_all(out.as_bytes())?))
}
