//! The files of `hvs experiment accuracy`: `DIR/ACCURACY.md` (prose from
//! `host/templates/accuracy.md`, every number filled in from [`super::Accuracy`]) and, in
//! `DIR/accuracy/`, one CSV per part ([`STEMS`]), the two plots (noise, lens; SVG and PNG) and
//! `timing.csv` (the only file whose bytes vary between runs, with the times in the page).

use super::{
    floor_span, simulate_command, worst_over_cases, Accuracy, AccuracyConfig, RegimeRow, Scores,
    SweepRow, BIG_BOARD, BOARDS, HELD_OUT_SEED_BASE, LENS_SWEEP_PIXELS, METHODS, REGIMES,
    SWEEP_CASE,
};
use crate::fmt::{files_line, join, num, pct, roman, stages, times};
use crate::sim::board::{Board, Pixels};
use crate::study::engine::{table_markdown, Files, Progress, Study};
use crate::study::plot::{Figure, Legend, Panel, Series, Style, FLOOR_COLOR};
use anyhow::Result;
use std::fmt::Write as _;

/// The CSV stems in `DIR/accuracy/` (`noise` and `lens` also as `.svg`, `.png`).
pub const STEMS: [&str; 6] = ["regimes", "protocol", "noise", "lens", "images", "real_pair"];
/// The sub-directory of the CSVs and plots.
pub const SUBDIR: &str = "accuracy";

/// The command that reproduces a run into `dir`.
pub fn command(cfg: &AccuracyConfig, dir: &str) -> String {
    let mut c = "hvs experiment accuracy".to_string();
    if dir != "docs" {
        c.push_str(&format!(" -o {dir}"));
    }
    if cfg.seed_base != HELD_OUT_SEED_BASE {
        c.push_str(&format!(" --seed-base {}", cfg.seed_base));
    }
    if cfg.quick {
        c.push_str(" --quick");
    }
    c
}

/// The estimators' column titles, the default named by its family.
fn method_titles(cfg: &AccuracyConfig) -> [String; 4] {
    [
        "floor".into(),
        "DLT".into(),
        "thesis 4-5-3".into(),
        format!("default ({} 4-5-3)", cfg.default_family.name()),
    ]
}

fn scores_header() -> String {
    let e = METHODS.map(|m| format!("{m}_pct"));
    let r = METHODS[1..].iter().map(|m| format!("{m}_ratio"));
    join(e.into_iter().chain(r), ",")
}

fn scores_csv(s: &Scores) -> String {
    join(s.0.iter().chain(s.ratios().iter()).map(|v| num(*v)), ",")
}

fn pixels_name(p: Pixels) -> &'static str {
    match p {
        Pixels::Rounded => "rounded",
        Pixels::Exact => "exact",
    }
}

/// The CSV texts, in [`STEMS`] order.
pub fn csv_tables(a: &Accuracy) -> Vec<(&'static str, String)> {
    let mut regimes = format!("board,regime,pixels,noise_px,k1,case,{}\n", scores_header());
    for r in &a.regimes {
        let g = &r.regime;
        let _ = writeln!(
            regimes,
            "{},{},{},{},{},{},{}",
            r.board.name(),
            g.name,
            pixels_name(g.pixels),
            g.noise_px,
            g.k1,
            r.case,
            scores_csv(&r.scores)
        );
    }
    let mut protocol = format!("case,{}\n", scores_header().replace("_pct", "_worst_pct"));
    for p in &a.protocol {
        let _ = writeln!(protocol, "{},{}", p.case, scores_csv(&p.worst));
    }
    let sweep = |rows: &[SweepRow], x: &str| {
        let mut s = format!("board,{x},{}\n", scores_header());
        for r in rows {
            let _ = writeln!(s, "{},{},{}", r.board.name(), num(r.x), scores_csv(&r.scores));
        }
        s
    };
    let mut images = format!(
        "regime,blur_px,noise_grey,k1,train_found,train_rendered,test_found,test_rendered,corner_error_px,{}\n",
        scores_header()
    );
    for r in &a.images {
        let g = &r.regime;
        let _ = writeln!(
            images,
            "{},{},{},{},{},{},{},{},{},{}",
            g.name,
            g.blur_px,
            g.noise_grey,
            g.k1,
            r.train_corners[0],
            r.train_corners[1],
            r.test_corners[0],
            r.test_corners[1],
            num(r.corner_error_px),
            scores_csv(&r.scores)
        );
    }
    let mut real_pair =
        format!("set,train_points,test_points,z_min_cm,z_max_cm,{}\n", scores_header());
    if let Some(r) = &a.real_pair {
        let _ = writeln!(
            real_pair,
            "motorcycle,{},{},{},{},{}",
            r.train_points,
            r.test_points,
            num(r.z_range[0]),
            num(r.z_range[1]),
            scores_csv(&r.scores)
        );
    }
    vec![
        ("regimes", regimes),
        ("protocol", protocol),
        ("noise", sweep(&a.noise, "noise_px")),
        ("lens", sweep(&a.lens, "k1")),
        ("images", images),
        ("real_pair", real_pair),
    ]
}

const METHOD_COLORS: [usize; 3] = [1, 2, 0];

/// Below this floor (%) a ratio to it is not drawn: exact pixels, where the floor is zero up
/// to rounding of the arithmetic.
const RATIO_MIN_FLOOR: f64 = 1e-6;

/// A sweep figure: per board (columns), the four estimators' e_ma against the swept value
/// (top row) and the three methods' ratios to the floor (bottom row, where the floor is not
/// zero).
fn sweep_figure(a: &Accuracy, rows: &[SweepRow], title: String, x_label: &str) -> Figure {
    let names = method_titles(&a.config);
    let per_board: Vec<(&Board, Vec<&SweepRow>)> =
        BOARDS.iter().map(|b| (b, rows.iter().filter(|r| r.board == *b).collect())).collect();
    let methods = |rows: &[&SweepRow], y: &dyn Fn(&SweepRow, usize) -> f64| -> Vec<Series> {
        let x: Vec<f64> = rows.iter().map(|r| r.x).collect();
        (1..4)
            .map(|m| {
                let y: Vec<f64> = rows.iter().map(|r| y(r, m)).collect();
                Series::new(names[m].clone(), &x, &y, Style::LinePoints, METHOD_COLORS[m - 1])
            })
            .collect()
    };
    let panel = |board: &Board, y_label: &str, series: Vec<Series>| Panel {
        title: format!("{} board ({} points)", board_words(board), 6 * board.len()),
        x_label: x_label.into(),
        y_label: y_label.into(),
        log_y: false,
        series,
        legend: Legend::UpperLeft,
        integer_x: false,
    };
    let mut panels: Vec<Panel> = per_board
        .iter()
        .map(|(board, rows)| {
            let mut series = methods(rows, &|r, m| r.scores.0[m]);
            let x: Vec<f64> = rows.iter().map(|r| r.x).collect();
            let floor: Vec<f64> = rows.iter().map(|r| r.scores.floor()).collect();
            series.push(Series::new(
                "optimal triangulation, true rig and lenses (floor)",
                &x,
                &floor,
                Style::Dashed,
                FLOOR_COLOR,
            ));
            panel(board, "depth e_ma (% of true depth)", series)
        })
        .collect();
    for (board, rows) in &per_board {
        let rows: Vec<&SweepRow> =
            rows.iter().copied().filter(|r| r.scores.floor() > RATIO_MIN_FLOOR).collect();
        let mut series = methods(&rows, &|r, m| r.scores.ratios()[m - 1]);
        let x: Vec<f64> = rows.iter().map(|r| r.x).collect();
        series.push(Series::new(
            "the floor (ratio 1)",
            &x,
            &vec![1.0; x.len()],
            Style::Dashed,
            FLOOR_COLOR,
        ));
        panels.push(panel(board, "e_ma / the floor's e_ma", series));
    }
    Figure { title, panels, cols: 2 }
}

fn board_words(b: &Board) -> String {
    match b {
        Board::Thesis => "thesis 4x3 at 2 cm".into(),
        Board::Grid { nx, ny, pitch } => format!("{nx}x{ny} at {pitch} cm"),
    }
}

/// Writes the CSVs, plots, `timing.csv` (in `dir/accuracy/`) and `ACCURACY.md` (in `dir`,
/// which must exist); `total_s` is the run's wall time. Returns the files written, relative
/// to `dir`.
pub fn write(files: &mut Files, a: &Accuracy, total_s: f64) -> Result<()> {
    let mut sub = files.sub(SUBDIR)?;
    for (stem, text) in csv_tables(a) {
        sub.bytes(&format!("{stem}.csv"), text.as_bytes())?;
    }
    let figures = [
        (
            "noise",
            sweep_figure(
                a,
                &a.noise,
                format!(
                    "Depth error vs. Gaussian pixel noise on unrounded pixels, case {}, {} random test points",
                    roman(SWEEP_CASE),
                    a.config.test_points()
                ),
                "pixel noise sigma (px), no rounding",
            ),
        ),
        (
            "lens",
            sweep_figure(
                a,
                &a.lens,
                format!(
                    "Depth error vs. radial lens distortion, {} px noise, unrounded, case {}, {} random test points",
                    LENS_SWEEP_PIXELS.noise_px,
                    roman(SWEEP_CASE),
                    a.config.test_points()
                ),
                "k1 of both lenses (radius in image half-widths)",
            ),
        ),
    ];
    for (stem, fig) in &figures {
        sub.figure(stem, fig)?;
    }
    let mut timing = String::from("stage,wall_s\n");
    for (name, s) in a.stage_s.iter().chain([("total", total_s)].iter()) {
        let _ = writeln!(timing, "{name},{s:.3}");
    }
    sub.bytes("timing.csv", timing.as_bytes())?;
    files.absorb(sub);
    let values = accuracy_values(a, total_s, &files.dir().display().to_string());
    files.page("ACCURACY.md", "accuracy.md", TEMPLATE, &values)
}

impl Study for AccuracyConfig {
    type Results = Accuracy;
    fn page(&self) -> &'static str {
        "ACCURACY.md"
    }
    fn what(&self) -> String {
        format!("{} parts: CSV; 2 plots: SVG, PNG; timing.csv; ACCURACY.md", STEMS.len())
    }
    fn compute(&self, progress: &dyn Progress) -> Result<(usize, Accuracy)> {
        super::run(self, progress).map(|r| (r.threads, r))
    }
    fn write(&self, files: &mut Files, a: &Accuracy, total_s: f64) -> Result<()> {
        write(files, a, total_s)
    }
}

/// A table cell for method `m` of the worst over cases: `1.08 x (II)`, or the e_ma in an
/// exact regime.
fn worst_cell(rows: &[RegimeRow], board: &Board, regime: &str, m: usize) -> String {
    match worst_over_cases(rows, board, regime, m) {
        Some(w) if regime == "exact" => format!("{} ({})", small_pct(w.value), roman(w.case)),
        Some(w) => format!("{} ({})", times(w.value), roman(w.case)),
        None => "-".into(),
    }
}

/// A percentage that may be tiny (exact pixels): [`pct`] from 0.001 %, else two significant
/// digits in exponent form.
pub fn small_pct(v: f64) -> String {
    if v.is_finite() && v.abs() < 1e-3 {
        if v == 0.0 {
            "0 %".into()
        } else {
            format!("{v:.1e} %")
        }
    } else {
        pct(v)
    }
}

/// The summary table: per board and regime, the floor's range and each method's worst.
pub fn summary_table(a: &Accuracy) -> String {
    let t = method_titles(&a.config);
    let head = [
        "board",
        "regime",
        "floor e_ma (range over cases)",
        t[1].as_str(),
        t[2].as_str(),
        t[3].as_str(),
    ];
    let mut rows = Vec::new();
    for board in &BOARDS {
        for r in &REGIMES {
            let (lo, hi) = floor_span(&a.regimes, board, r.name);
            if lo > hi {
                continue;
            }
            let mut row = vec![
                board.name(),
                r.name.to_string(),
                format!("{} to {}", small_pct(lo), small_pct(hi)),
            ];
            row.extend((1..4).map(|m| worst_cell(&a.regimes, board, r.name, m)));
            rows.push(row);
        }
    }
    table_markdown(&head, &[], &rows)
}

fn score_cells(s: &Scores, exact: bool) -> Vec<String> {
    let r = s.ratios();
    let mut out = vec![small_pct(s.floor())];
    for m in 1..4 {
        out.push(if exact {
            small_pct(s.0[m])
        } else {
            format!("{} ({})", small_pct(s.0[m]), times(r[m - 1]))
        });
    }
    out
}

/// A table of the four estimators: `lead` columns, then floor and the three methods, one
/// row per `(lead cells, scores, exact)`.
fn method_table<'a>(
    a: &Accuracy,
    lead: &[&str],
    rows: impl Iterator<Item = (Vec<String>, &'a Scores, bool)>,
) -> String {
    let t = method_titles(&a.config);
    let head: Vec<&str> = lead.iter().copied().chain(["floor", &t[1], &t[2], &t[3]]).collect();
    let rows: Vec<Vec<String>> = rows
        .map(|(mut cells, scores, exact)| {
            cells.extend(score_cells(scores, exact));
            cells
        })
        .collect();
    table_markdown(&head, &[], &rows)
}

/// Every case: e_ma (ratio to the floor).
pub fn case_table(a: &Accuracy) -> String {
    method_table(
        a,
        &["board", "regime", "case"],
        a.regimes.iter().map(|r| {
            let lead = vec![r.board.name(), r.regime.name.into(), roman(r.case).into()];
            (lead, &r.scores, r.regime.exact())
        }),
    )
}

fn protocol_table(a: &Accuracy) -> String {
    method_table(
        a,
        &["case"],
        a.protocol.iter().map(|p| (vec![roman(p.case).to_string()], &p.worst, false)),
    )
}

fn images_table(a: &Accuracy) -> String {
    method_table(
        a,
        &[
            "images",
            "blur (px)",
            "noise (grey levels)",
            "k1",
            "training corners",
            "test corners",
            "corner error (px)",
        ],
        a.images.iter().map(|r| {
            let g = &r.regime;
            let lead = vec![
                g.name.to_string(),
                g.blur_px.to_string(),
                g.noise_grey.to_string(),
                g.k1.to_string(),
                format!("{}/{}", r.train_corners[0], r.train_corners[1]),
                format!("{}/{}", r.test_corners[0], r.test_corners[1]),
                format!("{:.3}", r.corner_error_px),
            ];
            (lead, &r.scores, false)
        }),
    )
}

fn real_pair_table(a: &Accuracy) -> String {
    method_table(
        a,
        &["pair", "training points", "test points", "depths (cm)"],
        a.real_pair.iter().map(|r| {
            let lead = vec![
                "Motorcycle (Middlebury 2014, 741 x 500)".to_string(),
                r.train_points.to_string(),
                r.test_points.to_string(),
                format!("{:.0}-{:.0}", r.z_range[0], r.z_range[1]),
            ];
            (lead, &r.scores, true)
        }),
    )
}

/// The worst ratio over cases of method `m` in the protocol, with its case.
fn protocol_worst(a: &Accuracy, m: usize) -> (f64, u8) {
    a.protocol
        .iter()
        .map(|p| (p.worst.0[m] / p.worst.floor(), p.case))
        .fold((f64::NEG_INFINITY, 0), |w, x| if x.0 > w.0 { x } else { w })
}

/// One sentence per board of a sweep: the four at the largest value, and at the smallest.
fn sweep_sentence(rows: &[SweepRow], what: &str) -> String {
    let mut out = Vec::new();
    for board in &BOARDS {
        let rows: Vec<&SweepRow> = rows.iter().filter(|r| r.board == *board).collect();
        let (Some(first), Some(last)) = (rows.first(), rows.last()) else {
            continue;
        };
        let r = last.scores.ratios();
        out.push(format!(
            "{} board: at {what} = {} the floor is {}, DLT {} ({}), the thesis net {} ({}), the default {} ({}); at {what} = {} the floor is {} and the default {} (thesis net {}).",
            board_words(board),
            last.x,
            small_pct(last.scores.floor()),
            small_pct(last.scores.0[1]),
            times(r[0]),
            small_pct(last.scores.0[2]),
            times(r[1]),
            small_pct(last.scores.0[3]),
            times(r[2]),
            first.x,
            small_pct(first.scores.floor()),
            small_pct(first.scores.0[3]),
            small_pct(first.scores.0[2]),
        ));
    }
    out.join(" ")
}

fn commands(a: &Accuracy) -> String {
    let mut s = String::new();
    let c = SWEEP_CASE;
    for (board, r) in
        [(Board::Thesis, &REGIMES[0]), (BIG_BOARD, &REGIMES[1]), (BIG_BOARD, &REGIMES[3])]
    {
        let b = BOARDS.iter().position(|x| *x == board).unwrap_or(0);
        let k = REGIMES.iter().position(|x| x.name == r.name).unwrap_or(0);
        let train_seed = super::set_seed(a.config.seed_base, 0, b, k, c, 1);
        let test_seed = super::set_seed(a.config.seed_base, 0, b, k, c, 2);
        let lens = if r.k1 != 0.0 { format!(" --distortion {}", r.k1) } else { String::new() };
        let _ = writeln!(
            s,
            "# {} board, {} (case {}):\n{} -o train.csv\n{} -o test.csv\nhvs train --data train.csv -o model.hvsw --seed {}\nhvs eval --model model.hvsw --data test.csv --case {c}{lens}\n",
            board.name(),
            r.name,
            roman(c),
            simulate_command(c, &board, r, "train", train_seed),
            simulate_command(c, &board, r, "volume", test_seed).replace(" N ", &format!(" {} ", a.config.test_points())),
            super::TRAIN_SEED,
        );
    }
    s
}

/// The prose of `ACCURACY.md`.
const TEMPLATE: &str = include_str!("../../../templates/accuracy.md");

fn accuracy_values(a: &Accuracy, total_s: f64, dir: &str) -> Vec<(&'static str, String)> {
    let cfg = &a.config;
    let t = method_titles(cfg);
    let (pd, pdc) = protocol_worst(a, 3);
    let (pt, ptc) = protocol_worst(a, 2);
    let (pl, plc) = protocol_worst(a, 1);
    let files = |stem: &str| files_line(&format!("{SUBDIR}/{stem}"));
    vec![
        ("command", command(cfg, dir)),
        ("total_s", format!("{total_s:.1}")),
        ("threads", a.threads.to_string()),
        ("stage_times", stages(&a.stage_s)),
        ("seed_base", cfg.seed_base.to_string()),
        ("train_seed", super::TRAIN_SEED.to_string()),
        ("held_out", if cfg.seed_base == HELD_OUT_SEED_BASE { "the held-out base".into() } else { "not the held-out base (1000000)".to_string() }),
        ("default_family", cfg.default_family.name().to_string()),
        ("default_title", t[3].clone()),
        ("restarts", cfg.restarts().to_string()),
        ("test_points", cfg.test_points().to_string()),
        ("cases", join(cfg.cases().iter().map(|c| roman(*c)), ", ")),
        ("big_board", BIG_BOARD.name()),
        ("big_points", (6 * BIG_BOARD.len()).to_string()),
        ("summary_table", summary_table(a)),
        ("case_table", case_table(a)),
        ("protocol_table", protocol_table(a)),
        (
            "protocol_sentence",
            format!(
                "Worst over cases of (worst-depth e_ma / the floor's worst-depth e_ma): the default {} (case {}), the thesis net {} (case {}), DLT {} (case {}).",
                times(pd),
                roman(pdc),
                times(pt),
                roman(ptc),
                times(pl),
                roman(plc)
            ),
        ),
        ("sweep_case", roman(SWEEP_CASE).to_string()),
        ("files_regimes", format!("[CSV]({SUBDIR}/regimes.csv)")),
        ("files_protocol", format!("[CSV]({SUBDIR}/protocol.csv)")),
        ("files_images", format!("[CSV]({SUBDIR}/images.csv)")),
        ("files_noise", files("noise")),
        ("files_lens", files("lens")),
        ("noise_levels", join(cfg.noise_levels().iter().map(|v| format!("{v}")), ", ")),
        ("lens_noise", LENS_SWEEP_PIXELS.noise_px.to_string()),
        ("k1_levels", join(cfg.k1_levels().iter().map(|v| format!("{v}")), ", ")),
        ("noise_sentence", sweep_sentence(&a.noise, "sigma")),
        ("lens_sentence", sweep_sentence(&a.lens, "k1")),
        ("images_table", images_table(a)),
        ("files_real_pair", format!("[CSV]({SUBDIR}/real_pair.csv)")),
        ("real_pair_table", real_pair_table(a)),
        ("commands", commands(a)),
    ]
}
