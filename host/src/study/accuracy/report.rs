//! The files of `hvs experiment accuracy`: `DIR/ACCURACY.md` (from `host/templates/accuracy.md`)
//! and, in `DIR/accuracy/`, one CSV per part ([`STEMS`]), two plots (SVG, PNG), `timing.csv`.

use super::{
    floor_span, set_seed, simulate_command, worst_over_cases, Accuracy, AccuracyConfig, Scores,
    SweepRow, BIG_BOARD, BOARDS, HELD_OUT_SEED_BASE, LENS_SWEEP_PIXELS, METHODS, REGIMES,
    SWEEP_CASE, TRAIN_SEED,
};
use crate::fmt::{join, num, pct, roman, stages, times};
use crate::sim::board::{Pixels, TrainingBoard};
use crate::study::engine::{table_markdown, Files, Report};
use crate::study::plot::{Figure, Panel, Series, Style, FLOOR_COLOR};
use anyhow::Result;
use std::fmt::Write as _;

/// The CSV stems in `DIR/accuracy/` (`noise` and `lens` also as `.svg`, `.png`).
pub const STEMS: [&str; 6] = ["regimes", "protocol", "noise", "lens", "images", "real_pair"];
/// The sub-directory of the CSVs and plots.
pub const SUBDIR: &str = "accuracy";
/// The prose of `ACCURACY.md`.
const TEMPLATE: &str = include_str!("../../../templates/accuracy.md");
/// The palette entries of DLT, thesis and default in the plots.
const METHOD_COLORS: [usize; 3] = [1, 2, 0];
/// Below this floor (%) a ratio to it is not drawn: exact pixels, where the floor is zero up
/// to rounding of the arithmetic.
const RATIO_MIN_FLOOR: f64 = 1e-6;
/// The lead columns of `images.csv`.
const IMAGES_CSV_LEAD: &str =
    "regime,blur_px,noise_grey,k1,train_found,train_rendered,test_found,test_rendered,corner_error_px";
/// The lead columns of the images table.
const IMAGES_HEAD: &str =
    "images,blur (px),noise (grey levels),k1,training corners,test corners,corner error (px)";

/// The lead columns of the real pair's table.
const REAL_PAIR_HEAD: &str = "pair,training points,test points,depths (cm)";

/// The cells of a table row, each value by its `Display`.
macro_rules! cells {
    ($($v:expr),* $(,)?) => { vec![$($v.to_string()),*] };
}

/// The command that reproduces a run into `dir`.
pub fn command(cfg: &AccuracyConfig, dir: &str) -> String {
    let flags = [
        (dir != "docs", format!(" -o {dir}")),
        (cfg.seed_base != HELD_OUT_SEED_BASE, format!(" --seed-base {}", cfg.seed_base)),
        (cfg.quick, " --quick".into()),
    ];
    let on = flags.into_iter().filter_map(|(on, flag)| on.then_some(flag));
    on.fold("hvs experiment accuracy".to_string(), |c, flag| c + &flag)
}

/// The estimators' column titles, the default named by its family.
fn method_titles(cfg: &AccuracyConfig) -> [String; 4] {
    let default = format!("default ({} 4-5-3)", cfg.default_family.name());
    ["floor".into(), "DLT".into(), "thesis 4-5-3".into(), default]
}

/// A CSV: the `lead` columns, then each estimator's e_ma (named `{method}{pct}`) and the
/// ratios to the floor; one line per `(lead cells, scores)`.
fn csv<'a>(lead: &str, pct: &str, rows: impl Iterator<Item = (Vec<String>, &'a Scores)>) -> String {
    let ratios = METHODS[1..].iter().map(|m| format!("{m}_ratio"));
    let head = METHODS.iter().map(|m| format!("{m}{pct}")).chain(ratios);
    let mut s = format!("{lead},{}\n", join(head, ","));
    for (mut cells, sc) in rows {
        cells.extend(sc.0.iter().chain(&sc.ratios()).map(|v| num(*v)));
        let _ = writeln!(s, "{}", cells.join(","));
    }
    s
}

/// The CSV texts, in [`STEMS`] order.
pub fn csv_tables(a: &Accuracy) -> Vec<(&'static str, String)> {
    let sweep = |rows: &[SweepRow], x: &str| {
        let rows = rows.iter().map(|r| (cells![r.board.name(), num(r.x)], &r.scores));
        csv(&format!("board,{x}"), "_pct", rows)
    };
    let regimes = a.regimes.iter().map(|r| {
        let g = &r.regime;
        let pixels = if g.pixels == Pixels::Exact { "exact" } else { "rounded" };
        (cells![r.board.name(), g.name, pixels, g.noise_px, g.k1, r.case], &r.scores)
    });
    let images = a.images.iter().map(|r| {
        let (g, d) = (&r.regime, &r.detected);
        let ([tf, tn], [sf, sn]) = (d.train_corners, d.test_corners);
        (
            cells![g.name, g.blur_px, g.noise_grey, g.k1, tf, tn, sf, sn, num(d.corner_error_px)],
            &r.scores,
        )
    });
    let real_pair = a.real_pair.iter().map(|r| {
        let [lo, hi] = r.z_range.map(num);
        (cells!["motorcycle", r.train_points, r.test_points, lo, hi], &r.scores)
    });
    let protocol = a.protocol.iter().map(|p| (cells![p.case], &p.scores));
    vec![
        ("regimes", csv("board,regime,pixels,noise_px,k1,case", "_pct", regimes)),
        ("protocol", csv("case", "_worst_pct", protocol)),
        ("noise", sweep(&a.noise, "noise_px")),
        ("lens", sweep(&a.lens, "k1")),
        ("images", csv(IMAGES_CSV_LEAD, "_pct", images)),
        ("real_pair", csv("set,train_points,test_points,z_min_cm,z_max_cm", "_pct", real_pair)),
    ]
}

fn board_words(b: &TrainingBoard) -> String {
    match b {
        TrainingBoard::Thesis => "thesis 4x3 at 2 cm".into(),
        TrainingBoard::Grid { nx, ny, pitch } => format!("{nx}x{ny} at {pitch} cm"),
    }
}

/// A sweep figure: per board (columns), the four estimators' e_ma against the swept value
/// (top row) and the three methods' ratios to the floor (bottom row, where the floor is not
/// zero).
fn sweep_figure(a: &Accuracy, all: &[SweepRow], title: String, x_label: &str) -> Figure {
    let names = method_titles(&a.config);
    let mut panels = Vec::new();
    let optimal = "optimal triangulation, true rig and lenses (floor)";
    for (ratio, y_label, floor) in [
        (false, "depth e_ma (% of true depth)", optimal),
        (true, "e_ma / the floor's e_ma", "the floor (ratio 1)"),
    ] {
        for board in &BOARDS {
            let shown = |r: &&SweepRow| !ratio || r.scores.floor() > RATIO_MIN_FLOOR;
            let rows: Vec<&SweepRow> =
                all.iter().filter(|r| r.board == *board && shown(r)).collect();
            let x: Vec<f64> = rows.iter().map(|r| r.x).collect();
            let series = [1, 2, 3, 0].map(|m| {
                if ratio && m == 0 {
                    // The floor is 1 wherever a ratio exists: a level line over the sweep,
                    // drawn even where a single level has a ratio (the quick sweeps).
                    return Series::level(floor, sweep_ends(all, *board), 1.0, FLOOR_COLOR);
                }
                let unit = |r: &SweepRow| if ratio { r.scores.floor() } else { 1.0 };
                let y: Vec<f64> = rows.iter().map(|r| r.scores.0[m] / unit(r)).collect();
                let (name, style, color) = if m == 0 {
                    (floor, Style::Dashed, FLOOR_COLOR)
                } else {
                    (names[m].as_str(), Style::LinePoints, METHOD_COLORS[m - 1])
                };
                Series::new(name, &x, &y, style, color)
            });
            let title = format!("{} board ({} points)", board_words(board), 6 * board.len());
            panels.push(Panel::new(title, x_label, y_label, series.to_vec()));
        }
    }
    Figure { title, panels, cols: 2 }
}

/// The first and last level of `board`'s sweep.
fn sweep_ends(rows: &[SweepRow], board: TrainingBoard) -> [f64; 2] {
    let x = rows.iter().filter(|r| r.board == board).map(|r| r.x);
    [x.clone().fold(f64::INFINITY, f64::min), x.fold(f64::NEG_INFINITY, f64::max)]
}

impl Report for Accuracy {
    const PAGE: &'static str = "ACCURACY.md";
    /// The CSVs, plots and `timing.csv` in `accuracy/`, then `ACCURACY.md`.
    fn write(&self, files: &mut Files, total_s: f64) -> Result<()> {
        let a = self;
        let mut sub = files.sub(SUBDIR)?;
        for (stem, text) in csv_tables(a) {
            sub.bytes(&format!("{stem}.csv"), text.as_bytes())?;
        }
        let (case, n, lens_px) =
            (roman(SWEEP_CASE), a.config.test_points(), LENS_SWEEP_PIXELS.noise_px);
        let noise = format!("Depth error vs. Gaussian pixel noise on unrounded pixels, case {case}, {n} random test points");
        let lens = format!("Depth error vs. radial lens distortion, {lens_px} px noise, unrounded, case {case}, {n} random test points");
        let noise_x = "pixel noise sigma (px), no rounding";
        let lens_x = "k1 of both lenses (radius in image half-widths)";
        sub.figure("noise", &sweep_figure(a, &a.noise, noise, noise_x))?;
        sub.figure("lens", &sweep_figure(a, &a.lens, lens, lens_x))?;
        let stages = [&a.stage_s[..], &[("total", total_s)]].concat();
        sub.rows("timing.csv", "stage,wall_s", &stages, |(n, s)| cells![n, format!("{s:.3}")])?;
        files.absorb(sub);
        let values = accuracy_values(a, total_s, &files.dir().display().to_string());
        files.page(Self::PAGE, "accuracy.md", TEMPLATE, &values)
    }
}

/// A percentage that may be tiny (exact pixels): [`pct`] from 0.001 %, else two significant
/// digits in exponent form.
pub fn small_pct(v: f64) -> String {
    if v == 0.0 {
        "0 %".into()
    } else if v.is_finite() && v.abs() < 1e-3 {
        format!("{v:.1e} %")
    } else {
        pct(v)
    }
}

/// The summary table: per board and regime, the floor's range over the cases and each
/// method's worst ratio (`1.08 x (II)`; in an exact regime, its worst e_ma).
pub fn summary_table(a: &Accuracy) -> String {
    let t = method_titles(&a.config);
    let head = ["board", "regime", "floor e_ma (range over cases)", t[1].as_str(), &t[2], &t[3]];
    let mut rows = Vec::new();
    for board in &BOARDS {
        for r in &REGIMES {
            let (lo, hi) = floor_span(&a.regimes, board, r.name);
            if lo > hi {
                continue;
            }
            let worst = (1..4).map(|m| match worst_over_cases(&a.regimes, board, r.name, m) {
                Some((w, c)) if r.name == "exact" => format!("{} ({})", small_pct(w), roman(c)),
                Some((w, c)) => format!("{} ({})", times(w), roman(c)),
                None => "-".into(),
            });
            let span = format!("{} to {}", small_pct(lo), small_pct(hi));
            rows.push([board.name(), r.name.to_string(), span].into_iter().chain(worst).collect());
        }
    }
    table_markdown(&head, &[], &rows)
}

/// A table of the four estimators: the `lead` columns (comma-separated), then floor and the
/// three methods (e_ma, and unless `exact` the ratio to the floor), one row per `(lead cells,
/// scores, exact)`.
fn method_table<'a>(
    a: &Accuracy,
    lead: &str,
    rows: impl Iterator<Item = (Vec<String>, &'a Scores, bool)>,
) -> String {
    let t = method_titles(&a.config);
    let head: Vec<&str> = lead.split(',').chain(["floor", &t[1], &t[2], &t[3]]).collect();
    let rows: Vec<Vec<String>> = rows
        .map(|(mut cells, s, exact)| {
            cells.push(small_pct(s.floor()));
            cells.extend((1..4).map(|m| {
                if exact {
                    small_pct(s.0[m])
                } else {
                    format!("{} ({})", small_pct(s.0[m]), times(s.ratios()[m - 1]))
                }
            }));
            cells
        })
        .collect();
    table_markdown(&head, &[], &rows)
}

/// Every case: e_ma (ratio to the floor).
pub fn case_table(a: &Accuracy) -> String {
    let rows = a.regimes.iter().map(|r| {
        (cells![r.board.name(), r.regime.name, roman(r.case)], &r.scores, r.regime.exact())
    });
    method_table(a, "board,regime,case", rows)
}

/// One sentence per board of a sweep: the four at the largest value, and at the smallest.
fn sweep_sentence(rows: &[SweepRow], what: &str) -> String {
    let mut out = Vec::new();
    for board in &BOARDS {
        let rows: Vec<&SweepRow> = rows.iter().filter(|r| r.board == *board).collect();
        let (Some(first), Some(last)) = (rows.first(), rows.last()) else { continue };
        let ([f, d, t, n], [dr, tr, nr]) =
            (last.scores.0.map(small_pct), last.scores.ratios().map(times));
        let [f0, t0, n0] = [0, 2, 3].map(|m| small_pct(first.scores.0[m]));
        let (b, x, x0) = (board_words(board), last.x, first.x);
        out.push(format!("{b} board: at {what} = {x} the floor is {f}, DLT {d} ({dr}), the thesis net {t} ({tr}), the default {n} ({nr}); at {what} = {x0} the floor is {f0} and the default {n0} (thesis net {t0})."));
    }
    out.join(" ")
}

/// The commands of three cells of case IV: simulate, train, evaluate.
fn commands(a: &Accuracy) -> String {
    let (mut s, c, case) = (String::new(), SWEEP_CASE, roman(SWEEP_CASE));
    for (b, k) in [(0, 0), (1, 1), (1, 3)] {
        let (board, r) = (BOARDS[b], &REGIMES[k]);
        let (name, regime) = (board.name(), r.name);
        let seed = |set| set_seed(a.config.seed_base, 0, b, k, c, set);
        let train = simulate_command(c, &board, r, "train", seed(1));
        let points = format!(" {} ", a.config.test_points());
        let test = simulate_command(c, &board, r, "volume", seed(2)).replace(" N ", &points);
        let lens = if r.k1 != 0.0 { format!(" --distortion {}", r.k1) } else { String::new() };
        let _ = writeln!(s, "# {name} board, {regime} (case {case}):\n{train} -o train.csv\n{test} -o test.csv\nhvs train --data train.csv -o model.hvsw --seed {TRAIN_SEED}\nhvs eval --model model.hvsw --data test.csv --case {c}{lens}\n");
    }
    s
}

/// Every placeholder of the template.
fn accuracy_values(a: &Accuracy, total_s: f64, dir: &str) -> Vec<(&'static str, String)> {
    let cfg = &a.config;
    let list = |v: Vec<f64>| join(v, ", ");
    let images = a.images.iter().map(|r| {
        let g = &r.regime;
        let [t, u] =
            [r.detected.train_corners, r.detected.test_corners].map(|[f, n]| format!("{f}/{n}"));
        let err = format!("{:.3}", r.detected.corner_error_px);
        (cells![g.name, g.blur_px, g.noise_grey, g.k1, t, u, err], &r.scores, false)
    });
    let real_pair = a.real_pair.iter().map(|r| {
        let pair = "Motorcycle (Middlebury 2014, 741 x 500)";
        let depths = format!("{:.0}-{:.0}", r.z_range[0], r.z_range[1]);
        (cells![pair, r.train_points, r.test_points, depths], &r.scores, true)
    });
    let held_out = match cfg.seed_base {
        HELD_OUT_SEED_BASE => "the held-out base".into(),
        _ => format!("not the held-out base ({HELD_OUT_SEED_BASE})"),
    };
    let protocol = a.protocol.iter().map(|p| (cells![roman(p.case)], &p.scores, false));
    let mut values = vec![
        ("command", command(cfg, dir)),
        ("total_s", format!("{total_s:.1}")),
        ("threads", a.threads.to_string()),
        ("stage_times", stages(&a.stage_s)),
        ("seed_base", cfg.seed_base.to_string()),
        ("train_seed", TRAIN_SEED.to_string()),
        ("held_out", held_out),
        ("default_family", cfg.default_family.name().to_string()),
        ("default_title", method_titles(cfg)[3].clone()),
        ("restarts", cfg.restarts().to_string()),
        ("test_points", cfg.test_points().to_string()),
        ("cases", join(cfg.cases().iter().map(|c| roman(*c)), ", ")),
        ("big_board", BIG_BOARD.name()),
        ("big_points", (6 * BIG_BOARD.len()).to_string()),
        ("summary_table", summary_table(a)),
        ("case_table", case_table(a)),
        ("protocol_table", method_table(a, "case", protocol)),
        ("sweep_case", roman(SWEEP_CASE).to_string()),
        ("noise_levels", list(cfg.noise_levels())),
        ("lens_noise", LENS_SWEEP_PIXELS.noise_px.to_string()),
        ("k1_levels", list(cfg.k1_levels())),
        ("noise_sentence", sweep_sentence(&a.noise, "sigma")),
        ("lens_sentence", sweep_sentence(&a.lens, "k1")),
        ("images_table", method_table(a, IMAGES_HEAD, images)),
        ("real_pair_table", method_table(a, REAL_PAIR_HEAD, real_pair)),
        ("commands", commands(a)),
    ];
    // The protocol's worst ratio over cases per method, with its case.
    for (m, name) in [(3, "protocol_default"), (2, "protocol_thesis"), (1, "protocol_dlt")] {
        let worst = worst_over_cases(&a.protocol, &TrainingBoard::Thesis, REGIMES[0].name, m);
        let (w, case) = worst.unwrap_or((f64::NEG_INFINITY, 0));
        values.push((name, format!("{} (case {})", times(w), roman(case))));
    }
    values
}
