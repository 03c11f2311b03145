//! The files of `hvs experiment posture` ([`crate::study::posture`]): a CSV and a plot (SVG
//! and PNG) per part and `POSTURE.md` from `host/templates/posture.md`.
//!
//! | stem | part |
//! |---|---|
//! | `fixed` | the thesis' 4-5-3 net, trained at home, at verged and turned postures, vs. the floor |
//! | `bands` | the posture-aware 9-H-3 net per posture band vs. the floor |
//! | `hidden` | the hidden-neuron count the posture-aware net needs |
//! | `distortion` | lens distortion `k1` 0 to -0.5: the networks, a DLT fit, the floor |
//!
//! Wall times go to `timing.csv` and `POSTURE.md` only.

use super::{
    csv_tables, family_words, run, BandRow, DistortionRow, Errors, FixedRow, HiddenRow, Posture,
    StudyConfig, GOAL_RATIO, WIDE_BOARD_U, WIDE_BOARD_V,
};
use crate::fmt::{files_line, join, pct, roman, span, stages, times};
use crate::study::engine::{number_word, table_markdown, Align, Files, Progress, Study};
use crate::study::plot::{Figure, Legend, Panel, Series, Style, FLOOR_COLOR};
use anyhow::Result;
use hvs_shared::sim::posture::PostureRange;
use std::fmt::Write as _;

/// The stems of the files [`write()`] produces (each as `.csv`, `.svg`, `.png`), besides
/// `timing.csv` and `POSTURE.md`.
pub const STEMS: [&str; 4] = ["fixed", "bands", "hidden", "distortion"];

// ---------------------------------------------------------------------------------------
// Files

/// Writes the CSVs (the study's own tables, [`csv_tables`]), one plot per part (SVG and PNG)
/// and `POSTURE.md`; `total_s` is the run's wall time.
pub fn write(files: &mut Files, r: &Posture, total_s: f64) -> Result<()> {
    for (name, text) in csv_tables(r) {
        files.bytes(name, text.as_bytes())?;
    }
    files.figure("fixed", &fixed_figure(r))?;
    files.figure("bands", &bands_figure(r))?;
    files.figure("hidden", &hidden_figure(r))?;
    files.figure("distortion", &distortion_figure(r))?;
    let values = posture_values(r, total_s);
    files.page("POSTURE.md", "host/templates/posture.md", TEMPLATE, &values)
}

impl Study for StudyConfig {
    type Results = Posture;
    fn page(&self) -> &'static str {
        "POSTURE.md"
    }
    fn what(&self) -> String {
        format!("{} parts: CSV, SVG, PNG; timing.csv, POSTURE.md", STEMS.len())
    }
    fn compute(&self, progress: &dyn Progress) -> Result<(usize, Posture)> {
        run(self, progress).map(|r| (r.threads, r))
    }
    fn write(&self, files: &mut Files, r: &Posture, total_s: f64) -> Result<()> {
        write(files, r, total_s)
    }
}

const EMA_LABEL: &str = "depth e_ma (% of true depth)";
const GOAL_COLOR: usize = 1;

/// A term is "at zero" within a fraction of the drives' 0.18 degree step.
fn zero(v: f32) -> bool {
    v.abs() < 0.05
}

/// The rows of (a) that move only gaze term `k` (home included, at 0), as `(angle, row)`.
fn single_term(rows: &[FixedRow], k: usize) -> Vec<(f64, &FixedRow)> {
    rows.iter()
        .filter_map(|r| {
            let g = PostureRange::gaze_terms(&r.joints);
            let others_zero = (0..5).filter(|&i| i != k).all(|i| zero(g[i]));
            others_zero.then_some((f64::from(g[k]), r))
        })
        .collect()
}

const TURNS: [(usize, &str, usize); 4] =
    [(3, "version (eyes turned)", 0), (0, "neck pan", 2), (2, "eye tilt", 3), (1, "neck tilt", 4)];

fn fixed_figure(r: &Posture) -> Figure {
    let verg = single_term(&r.fixed, 4);
    let x: Vec<f64> = verg.iter().map(|v| v.0).collect();
    let y = |f: &dyn Fn(&FixedRow) -> f64| -> Vec<f64> { verg.iter().map(|v| f(v.1)).collect() };
    let vergence = Panel {
        title: "vergence (neck, tilt and version at 0)".into(),
        x_label: "vergence (deg)".into(),
        y_label: "error (% of true depth or distance)".into(),
        log_y: true,
        series: vec![
            Series::new("4-5-3 net: depth e_ma", &x, &y(&|f| f.net.z_pct), Style::LinePoints, 0),
            Series::new("4-5-3 net: 3-D error", &x, &y(&|f| f.net.d3_pct), Style::Points, 3),
            Series::new(
                "optimal triangulation at the posture (floor): depth e_ma",
                &x,
                &y(&|f| f.floor.z_pct),
                Style::Dashed,
                FLOOR_COLOR,
            ),
        ],
        legend: Legend::UpperLeft,
        integer_x: false,
    };
    let turned: Vec<&FixedRow> = r
        .fixed
        .iter()
        .filter(|f| {
            let g = PostureRange::gaze_terms(&f.joints);
            zero(g[4])
        })
        .collect();
    let xmax =
        span(TURNS.iter().flat_map(|&(k, _, _)| single_term(&r.fixed, k).into_iter().map(|v| v.0)))
            .1
            .max(1.0);
    let turn_panel = |title: &str, y_label: &str, value: fn(&Errors) -> f64| {
        let mut series: Vec<Series> = TURNS
            .iter()
            .map(|&(k, name, color)| {
                let rows = single_term(&r.fixed, k);
                let x: Vec<f64> = rows.iter().map(|v| v.0.abs()).collect();
                let y: Vec<f64> = rows.iter().map(|v| value(&v.1.net)).collect();
                Series::new(name, &x, &y, Style::LinePoints, color)
            })
            .collect();
        let (flo, fhi) = span(turned.iter().map(|f| value(&f.floor)));
        series.push(Series::new(
            format!("floor at these postures ({flo:.2}-{fhi:.2} %), mean"),
            &[0.0, xmax],
            &[(flo + fhi) / 2.0, (flo + fhi) / 2.0],
            Style::Dashed,
            FLOOR_COLOR,
        ));
        Panel {
            title: title.into(),
            x_label: "angle of the one moved term (deg)".into(),
            y_label: y_label.into(),
            log_y: false,
            series,
            legend: Legend::UpperLeft,
            integer_x: false,
        }
    };
    Figure {
        title: format!(
            "The thesis' 4-5-3 net, trained at the home posture, at other postures (case {}, {} random points each)",
            roman(r.config.case),
            r.config.fixed_points
        ),
        panels: vec![
            vergence,
            turn_panel(
                "turning: depth error of the net",
                EMA_LABEL,
                |e| e.z_pct,
            ),
            turn_panel(
                "turning: 3-D error of the net (head frame)",
                "3-D error (% of distance)",
                |e| e.d3_pct,
            ),
        ],
        cols: 3,
    }
}

/// The five gaze terms of the bands, in the study's order, with their colours.
const TERMS: [(&str, usize); 5] =
    [("neck pan", 0), ("neck tilt", 2), ("eye tilt", 3), ("version", 4), ("vergence", 6)];

fn bands_figure(r: &Posture) -> Figure {
    let bands = &r.aware.bands;
    let mut ratio_series: Vec<Series> = TERMS
        .iter()
        .map(|&(term, color)| {
            let b: Vec<&BandRow> = bands.iter().filter(|b| b.term == term).collect();
            let x: Vec<f64> = (1..=b.len()).map(|k| k as f64).collect();
            let y: Vec<f64> = b.iter().map(|b| b.ratio()).collect();
            Series::new(term, &x, &y, Style::LinePoints, color)
        })
        .collect();
    ratio_series.push(Series::new(
        format!("goal: {GOAL_RATIO:.2} x the floor"),
        &[1.0, 3.0],
        &[GOAL_RATIO, GOAL_RATIO],
        Style::Dashed,
        GOAL_COLOR,
    ));
    ratio_series.push(Series::new(
        "the floor (1.00)",
        &[1.0, 3.0],
        &[1.0, 1.0],
        Style::Dashed,
        FLOOR_COLOR,
    ));
    let x: Vec<f64> = (1..=bands.len()).map(|k| k as f64).collect();
    let net: Vec<f64> = bands.iter().map(|b| b.net.z_pct).collect();
    let floor: Vec<f64> = bands.iter().map(|b| b.floor.z_pct).collect();
    let goal: Vec<f64> = floor.iter().map(|f| f * GOAL_RATIO).collect();
    let mut order = Vec::new();
    let mut last = "";
    for (k, b) in (1..).zip(bands) {
        if b.term != last {
            let n = bands.iter().filter(|c| c.term == b.term).count();
            order.push(if n == 1 {
                format!("{k} {}", b.term)
            } else {
                format!("{k}-{} {}", k + n - 1, b.term)
            });
            last = b.term;
        }
    }
    let h = r.aware.sweep.iter().find(|h| h.hidden == r.config.hidden);
    Figure {
        title: format!(
            "The posture-aware 9-{}-3 net per posture band vs. the floor",
            r.config.hidden
        ),
        panels: vec![
            Panel {
                title: format!(
                    "net / floor depth e_ma per band: thirds of each term's range ({} random points at {} random postures)",
                    r.config.test_points, r.config.test_postures
                ),
                x_label: "band: 1 = third nearest home, 3 = outer third".into(),
                y_label: "net e_ma / floor e_ma".into(),
                log_y: false,
                series: ratio_series,
                legend: Legend::UpperLeft,
                integer_x: true,
            },
            Panel {
                title: format!(
                    "depth e_ma per band, and on {} points at extreme postures{}",
                    r.config.extreme_points,
                    h.map_or(String::new(), |h| format!(" (training e_ma {:.2} %)", h.train_pct))
                ),
                x_label: format!("band: {}", order.join(", ")),
                y_label: EMA_LABEL.into(),
                log_y: false,
                series: vec![
                    Series::new("posture-aware net", &x, &net, Style::Points, 0),
                    Series::new(
                        "optimal triangulation at the same postures (floor)",
                        &x,
                        &floor,
                        Style::Dashed,
                        FLOOR_COLOR,
                    ),
                    Series::new(
                        format!("goal: {GOAL_RATIO:.2} x the floor"),
                        &x,
                        &goal,
                        Style::Dashed,
                        GOAL_COLOR,
                    ),
                ],
                legend: Legend::UpperLeft,
                integer_x: true,
            },
        ],
        // One panel a row: the band key under the second needs the width.
        cols: 1,
    }
}

fn grid_sweep(r: &Posture) -> Vec<&HiddenRow> {
    r.aware.sweep.iter().filter(|h| h.postures == "grid").collect()
}

fn hidden_figure(r: &Posture) -> Figure {
    let rows = grid_sweep(r);
    let x: Vec<f64> = rows.iter().map(|h| h.hidden as f64).collect();
    let y = |f: fn(&HiddenRow) -> f64| -> Vec<f64> { rows.iter().map(|h| f(h)).collect() };
    let ends = [x.first().copied().unwrap_or(0.0), x.last().copied().unwrap_or(1.0)];
    let floor = rows.first().map_or(f64::NAN, |h| h.floor.z_pct);
    let lattice: Vec<&HiddenRow> =
        r.aware.sweep.iter().filter(|h| h.postures == "lattice").collect();
    let lx: Vec<f64> = lattice.iter().map(|h| h.hidden as f64).collect();
    let lattice_series = |f: fn(&HiddenRow) -> f64| {
        Series::new(
            "trained on the regular lattice of postures instead",
            &lx,
            &lattice.iter().map(|h| f(h)).collect::<Vec<_>>(),
            Style::Points,
            4,
        )
    };
    Figure {
        title: format!(
            "Hidden neurons of the posture-aware net (training: {} rows at {} postures; test: {} random points)",
            r.aware.train_rows, r.aware.train_postures, r.config.test_points
        ),
        panels: vec![
            Panel {
                title: "depth e_ma vs. hidden neurons".into(),
                x_label: "hidden neurons of the 9-H-3 net".into(),
                y_label: EMA_LABEL.into(),
                log_y: false,
                series: vec![
                    Series::new(
                        "test, random postures",
                        &x,
                        &y(|h| h.test.z_pct),
                        Style::LinePoints,
                        0,
                    ),
                    Series::new(
                        "training set",
                        &x,
                        &y(|h| h.train_pct),
                        Style::LinePoints,
                        2,
                    ),
                    lattice_series(|h| h.test.z_pct),
                    Series::new(
                        "floor on the test points",
                        &ends,
                        &[floor, floor],
                        Style::Dashed,
                        FLOOR_COLOR,
                    ),
                    Series::new(
                        format!("goal: {GOAL_RATIO:.2} x the floor"),
                        &ends,
                        &[floor * GOAL_RATIO, floor * GOAL_RATIO],
                        Style::Dashed,
                        GOAL_COLOR,
                    ),
                ],
                legend: Legend::UpperRight,
                integer_x: true,
            },
            Panel {
                title: "net / floor vs. hidden neurons".into(),
                x_label: "hidden neurons of the 9-H-3 net".into(),
                y_label: "net e_ma / floor e_ma".into(),
                log_y: false,
                series: vec![
                    Series::new(
                        "all random postures",
                        &x,
                        &y(|h| h.test.z_pct / h.floor.z_pct),
                        Style::LinePoints,
                        0,
                    ),
                    Series::new(
                        "worst posture band",
                        &x,
                        &y(|h| h.worst_band_ratio),
                        Style::LinePoints,
                        3,
                    ),
                    lattice_series(|h| h.worst_band_ratio),
                    Series::new(
                        format!("goal: {GOAL_RATIO:.2} x the floor"),
                        &ends,
                        &[GOAL_RATIO, GOAL_RATIO],
                        Style::Dashed,
                        GOAL_COLOR,
                    ),
                ],
                legend: Legend::UpperRight,
                integer_x: true,
            },
        ],
        cols: 2,
    }
}

const NET_COLORS: [usize; 3] = [0, 2, 4];

fn distortion_figure(r: &Posture) -> Figure {
    let d = &r.distortion;
    let x: Vec<f64> = d.iter().map(|d| d.k1).collect();
    let mut series = Vec::new();
    if let Some(first) = d.first() {
        for (i, (h, _)) in first.nets.iter().enumerate() {
            let y: Vec<f64> =
                d.iter().map(|row| row.nets.get(i).map_or(f64::NAN, |n| n.1.z_pct)).collect();
            series.push(Series::new(
                format!("network 4-{h}-3"),
                &x,
                &y,
                Style::LinePoints,
                NET_COLORS[i % NET_COLORS.len()],
            ));
        }
    }
    series.push(Series::new(
        "DLT fit + linear triangulation",
        &x,
        &d.iter().map(|d| d.dlt.z_pct).collect::<Vec<_>>(),
        Style::LinePoints,
        1,
    ));
    series.push(Series::new(
        "optimal triangulation, true cameras and lenses (floor)",
        &x,
        &d.iter().map(|d| d.floor.z_pct).collect::<Vec<_>>(),
        Style::Dashed,
        FLOOR_COLOR,
    ));
    Figure {
        title: format!(
            "Radial lens distortion at the home posture: wide board, {} random test points at 65-165 cm",
            r.config.test_points
        ),
        panels: vec![
            Panel {
                title: "depth e_ma vs. k1".into(),
                x_label: "k1 (radius in image half-widths)".into(),
                y_label: EMA_LABEL.into(),
                log_y: false,
                series,
                legend: Legend::UpperRight,
                integer_x: false,
            },
            Panel {
                title: "largest pixel displacement by the lens on the test points".into(),
                x_label: "k1 (radius in image half-widths)".into(),
                y_label: "displacement (px)".into(),
                log_y: false,
                series: vec![Series::new(
                    "largest |distorted - ideal| pixel coordinate",
                    &x,
                    &d.iter().map(|d| d.max_shift_px).collect::<Vec<_>>(),
                    Style::LinePoints,
                    3,
                )],
                legend: Legend::UpperRight,
                integer_x: false,
            },
        ],
        cols: 2,
    }
}

// ---------------------------------------------------------------------------------------
// POSTURE.md

/// The command that reproduces a run of `hvs experiment posture`'s settings
/// ([`StudyConfig::experiment`]); other settings come from the example.
pub fn command(cfg: &StudyConfig) -> String {
    if *cfg != StudyConfig::experiment(cfg.seed, cfg.quick) {
        return "cargo run --release -p hvs-host --example posture_study -- (custom settings)"
            .into();
    }
    format!("hvs experiment posture --seed {}{}", cfg.seed, if cfg.quick { " --quick" } else { "" })
}

/// The smallest hidden count whose worst band is within the goal (grid postures).
pub fn smallest_within_goal(r: &Posture) -> Option<&HiddenRow> {
    grid_sweep(r).into_iter().find(|h| h.worst_band_ratio <= GOAL_RATIO)
}

const TEMPLATE: &str = include_str!("../../../templates/posture.md");

/// The working range of the gaze terms in words: `neck pan +-30, ..., vergence 0-10`.
pub fn working_range_words(range: &PostureRange) -> String {
    const NAMES: [&str; 5] = ["neck pan", "neck tilt", "eye tilt", "version", "vergence"];
    join(
        NAMES.iter().zip(range.intervals()).map(|(n, [lo, hi])| {
            if lo == -hi {
                format!("{n} +-{hi}")
            } else {
                format!("{n} {lo}-{hi}")
            }
        }),
        ", ",
    )
}

/// The goal as a share of the floor: `20 %` above it at most.
fn goal_pct() -> String {
    format!("{:.0} %", (GOAL_RATIO - 1.0) * 100.0)
}

fn posture_values(r: &Posture, total_s: f64) -> Vec<(&'static str, String)> {
    let c = &r.config;
    let cmd = command(c);
    let sweep: Vec<String> = grid_sweep(r).iter().map(|h| h.hidden.to_string()).collect();
    let settings = if c.quick {
        format!(
            "**Reduced run (`--quick`, for tests):** {} training postures ({:?} cells per \
             gaze term), a 9-{}-3 net, hidden neurons {}, {} test points; the numbers show the \
             shape of the study, not its accuracy. Run `hvs experiment posture` for the \
             study's settings.",
            r.aware.train_postures,
            c.train_levels,
            c.hidden,
            sweep.join(", "),
            c.test_points
        )
    } else {
        format!(
            "Settings: those of the tables in docs/posture-study.md (the study's defaults \
             with the example's `--sweep`): seed {}, a 9-{}-3 net of family `{}` trained at {} \
             postures, {} test points at {} random postures, hidden neurons {}{}.",
            c.seed,
            c.hidden,
            c.family.name(),
            r.aware.train_postures,
            c.test_points,
            c.test_postures,
            sweep.join(", "),
            if c.lattice {
                format!(" and the 9-{}-3 net trained on the regular lattice of postures", c.hidden)
            } else {
                String::new()
            }
        )
    };
    vec![
        ("command", cmd.clone()),
        ("total_s", format!("{total_s:.1}")),
        ("threads", r.threads.to_string()),
        ("case", roman(c.case).to_string()),
        ("settings", settings),
        ("stage_times", stages(&r.stage_s)),
        ("glance_rows", at_a_glance(r)),
        ("files_fixed", files_line("fixed")),
        ("files_bands", files_line("bands")),
        ("files_hidden", files_line("hidden")),
        ("files_distortion", files_line("distortion")),
        ("fixed_points", c.fixed_points.to_string()),
        ("fixed_sentence", fixed_sentence(r)),
        ("hidden", c.hidden.to_string()),
        ("train_postures", r.aware.train_postures.to_string()),
        ("working_range", working_range_words(&PostureRange::WORKING)),
        ("train_levels", format!("{:?}", c.train_levels)),
        ("train_rows", r.aware.train_rows.to_string()),
        ("test_points", c.test_points.to_string()),
        ("test_postures", c.test_postures.to_string()),
        ("extreme_points", c.extreme_points.to_string()),
        ("bands_sentence", bands_sentence(r)),
        ("seed", c.seed.to_string()),
        ("restarts", format!("{} restart{}", c.restarts, if c.restarts == 1 { "" } else { "s" })),
        ("hidden_sentence", hidden_sentence(r)),
        ("train_depths", number_word(hvs_shared::sim::presets::TRAIN_DEPTHS.len())),
        ("distortion_sentence", distortion_sentence(r)),
        ("case_number", c.case.to_string()),
        ("family", family_words(c.family, c.frame)),
        ("restarts_count", c.restarts.to_string()),
        ("params", r.aware.blob.params.len().to_string()),
        ("weight_bytes", (r.aware.blob.params.len() * 4).to_string()),
        (
            "worst_band",
            format!("{:.2}", r.aware.bands.iter().map(BandRow::ratio).fold(0.0, f64::max)),
        ),
        ("goal_ratio", format!("{GOAL_RATIO:.2}")),
        ("board_width_pct", format!("{:.0}", WIDE_BOARD_U * 100.0)),
        ("board_height_pct", format!("{:.0}", WIDE_BOARD_V * 100.0 * 320.0 / 240.0)),
        ("fixed_table", fixed_table(r)),
        ("bands_table", bands_table(r)),
        ("sweep_table", sweep_table(r)),
        ("distortion_table", distortion_table(r)),
        ("seconds_a", format!("{:.1}", r.seconds[0])),
        ("seconds_b", format!("{:.1}", r.seconds[1])),
        ("seconds_c", format!("{:.1}", r.seconds[2])),
    ]
}

/// Table (a): the home-trained net at each posture.
fn fixed_table(r: &Posture) -> String {
    let rows: Vec<Vec<String>> = r
        .fixed
        .iter()
        .map(|f| {
            vec![
                f.label.clone(),
                pct(f.net.z_pct),
                pct(f.net.d3_pct),
                pct(f.floor.z_pct),
                format!("{:.1}", f.net.z_pct / f.floor.z_pct),
            ]
        })
        .collect();
    let head = ["posture", "net depth e_ma", "net 3-D", "floor depth e_ma", "net / floor"];
    table_markdown(&head, &right_after(1, head.len()), &rows)
}

/// Columns left-aligned up to `left`, right-aligned after.
fn right_after(left: usize, n: usize) -> Vec<Align> {
    (0..n).map(|k| if k < left { Align::Left } else { Align::Right }).collect()
}

/// Table (b): the posture-aware net per band.
fn bands_table(r: &Posture) -> String {
    let rows: Vec<Vec<String>> = r
        .aware
        .bands
        .iter()
        .map(|b| {
            vec![
                b.term.to_string(),
                b.band.clone(),
                b.net.points.to_string(),
                pct(b.net.z_pct),
                pct(b.floor.z_pct),
                format!("{:.2}", b.ratio()),
                pct(b.net.d3_pct),
                pct(b.floor.d3_pct),
            ]
        })
        .collect();
    let head = [
        "term",
        "band (deg)",
        "points",
        "net depth e_ma",
        "floor depth e_ma",
        "net / floor",
        "net 3-D",
        "floor 3-D",
    ];
    table_markdown(&head, &right_after(2, head.len()), &rows)
}

/// Table (b), second: the hidden-neuron sweep.
fn sweep_table(r: &Posture) -> String {
    let rows: Vec<Vec<String>> = r
        .aware
        .sweep
        .iter()
        .map(|h| {
            vec![
                h.postures.to_string(),
                h.hidden.to_string(),
                h.params.to_string(),
                pct(h.train_pct),
                pct(h.test.z_pct),
                format!("{:.2}", h.test.z_pct / h.floor.z_pct),
                format!("{:.2}", h.worst_band_ratio),
                format!("{:.0} s", h.seconds),
            ]
        })
        .collect();
    let head = [
        "training postures",
        "hidden",
        "parameters",
        "train e_ma",
        "test e_ma",
        "net / floor",
        "worst band / floor",
        "training time",
    ];
    table_markdown(&head, &right_after(1, head.len()), &rows)
}

/// Table (c): every estimator per lens.
fn distortion_table(r: &Posture) -> String {
    let nets: Vec<String> = r
        .distortion
        .first()
        .map_or(Vec::new(), |d| d.nets.iter().map(|(h, _)| format!("net 4-{h}-3")).collect());
    let mut head = vec!["k1", "largest shift"];
    head.extend(nets.iter().map(String::as_str));
    head.extend(["DLT", "floor"]);
    let rows: Vec<Vec<String>> = r
        .distortion
        .iter()
        .map(|d| {
            let mut row = vec![format!("{:.1}", d.k1), format!("{:.1} px", d.max_shift_px)];
            row.extend(d.nets.iter().map(|(_, e)| pct(e.z_pct)));
            row.extend([pct(d.dlt.z_pct), pct(d.floor.z_pct)]);
            row
        })
        .collect();
    table_markdown(&head, &right_after(0, head.len()), &rows)
}

fn verged_worst(r: &Posture) -> Option<(f64, &FixedRow)> {
    single_term(&r.fixed, 4).into_iter().filter(|v| v.0 > 0.0).max_by(|a, b| a.0.total_cmp(&b.0))
}

fn worst_band(r: &Posture) -> Option<&BandRow> {
    r.aware.bands.iter().max_by(|a, b| a.ratio().total_cmp(&b.ratio()))
}

fn at_a_glance(r: &Posture) -> String {
    let mut rows = Vec::new();
    if let Some((v, row)) = verged_worst(r) {
        rows.push(format!(
            "| thesis 4-5-3 net (trained at home), vergence {v:.1} deg | none: how wrong it gets | {} ({:.0} x the floor, {}) |",
            pct(row.net.z_pct),
            row.net.z_pct / row.floor.z_pct,
            pct(row.floor.z_pct)
        ));
    }
    if let Some(all) = r.aware.bands.first() {
        rows.push(format!(
            "| posture-aware 9-{}-3, random postures of the working range | within {} of the floor | {} vs. {} ({}) |",
            r.config.hidden,
            goal_pct(),
            pct(all.net.z_pct),
            pct(all.floor.z_pct),
            times(all.ratio())
        ));
    }
    if let Some(w) = worst_band(r) {
        rows.push(format!(
            "| same, worst posture band ({}: {}) | at most {} | {} ({}) |",
            w.term,
            w.band,
            times(GOAL_RATIO),
            times(w.ratio()),
            if w.ratio() <= GOAL_RATIO { "met" } else { "missed" }
        ));
    }
    rows.push(format!(
        "| smallest hidden count within the goal in every band | | {} |",
        smallest_within_goal(r).map_or("none of the sweep".to_string(), |h| format!(
            "{} ({} parameters)",
            h.hidden, h.params
        ))
    ));
    if let Some(d1) = r.distortion.last() {
        rows.push(format!(
            "| lens k1 = {:.1}: DLT / best net / floor | none: an honest curve | {} / {} / {} |",
            d1.k1,
            pct(d1.dlt.z_pct),
            pct(best_net(d1)),
            pct(d1.floor.z_pct)
        ));
    }
    join(rows, "\n")
}

fn best_net(d: &DistortionRow) -> f64 {
    d.nets.iter().map(|n| n.1.z_pct).fold(f64::INFINITY, f64::min)
}

fn fixed_sentence(r: &Posture) -> String {
    let home = r.fixed.iter().find(|f| f.label == "home");
    let turned: Vec<&FixedRow> = TURNS
        .iter()
        .flat_map(|&(k, _, _)| single_term(&r.fixed, k))
        .filter(|v| v.0 != 0.0)
        .map(|v| v.1)
        .collect();
    let (zlo, zhi) = span(turned.iter().map(|f| f.net.z_pct));
    let (dlo, dhi) = span(turned.iter().map(|f| f.net.d3_pct));
    let (flo, fhi) = span(r.fixed.iter().map(|f| f.floor.z_pct));
    let turned_z = format!("{}-{}", pct(zlo), pct(zhi));
    let turned_3d = format!("{}-{}", pct(dlo), pct(dhi));
    let floor = format!("{}-{}", pct(flo), pct(fhi));
    match (home, verged_worst(r)) {
        (Some(h), Some((v, row))) if row.net.z_pct > 10.0 * row.floor.z_pct => format!(
            "Vergence is what breaks the home-trained net: {} at home ({:.1} x the floor) but \
             {} at {v:.1} degrees of vergence ({:.0} x the floor), because vergence changes \
             the disparity of every point, which the net reads as depth; turning the eyes or \
             the neck keeps the disparity, so its depth error grows only to {turned_z}, but it \
             answers in the turned cameras' frame, not the head's, so its 3-D error is \
             {turned_3d}, while the floor stays at {floor} at every posture.",
            pct(h.net.z_pct),
            h.net.z_pct / h.floor.z_pct,
            pct(row.net.z_pct),
            row.net.z_pct / row.floor.z_pct,
        ),
        (_, Some((v, row))) => format!(
            "At {v:.1} degrees of vergence the home-trained net's depth error is {} ({:.1} x \
             the floor), at the turned postures {turned_z} (3-D error {turned_3d}); the floor \
             stays at {floor}.",
            pct(row.net.z_pct),
            row.net.z_pct / row.floor.z_pct,
        ),
        _ => "The run has no verged posture.".to_string(),
    }
}

fn bands_sentence(r: &Posture) -> String {
    let bands = &r.aware.bands;
    let (lo, hi) = span(bands.iter().map(BandRow::ratio));
    let (flo, fhi) = span(bands.iter().map(|b| b.floor.z_pct));
    let Some(w) = worst_band(r) else {
        return "The run has no posture bands.".to_string();
    };
    let met = hi <= GOAL_RATIO;
    format!(
        "{} in every band the net's depth e_ma is {lo:.2}-{hi:.2} times the floor's (worst: \
         {}, {}, {}), {} the goal of {GOAL_RATIO:.2}; the floor itself hardly moves with \
         the posture ({}-{}), because pixel rounding, not the posture, limits it.",
        if met { "The goal is met:" } else { "The goal is missed:" },
        w.term,
        w.band,
        times(w.ratio()),
        if met { "inside" } else { "against" },
        pct(flo),
        pct(fhi)
    )
}

fn hidden_sentence(r: &Posture) -> String {
    let rows = grid_sweep(r);
    let Some(best) = rows.iter().min_by(|a, b| a.test.z_pct.total_cmp(&b.test.z_pct)) else {
        return "The run has no hidden-neuron sweep.".to_string();
    };
    let (first, last) = (rows[0], rows[rows.len() - 1]);
    let mut sentence = match smallest_within_goal(r) {
        Some(h) => {
            let smaller: Vec<String> = rows
                .iter()
                .filter(|x| x.hidden < h.hidden)
                .map(|x| format!("{}: {}", x.hidden, times(x.worst_band_ratio)))
                .collect();
            let larger: Vec<&&HiddenRow> = rows.iter().filter(|x| x.hidden > h.hidden).collect();
            let mut t = format!(
                "{} hidden neurons ({} parameters, {} bytes of weights) is the smallest count \
                 within the goal in every band (worst band {} the floor)",
                h.hidden,
                h.params,
                h.params * 4,
                times(h.worst_band_ratio)
            );
            if !smaller.is_empty() {
                let _ = write!(t, "; fewer miss it in the worst band ({})", smaller.join(", "));
            }
            if !larger.is_empty() {
                let better = larger.iter().any(|x| x.test.z_pct < 0.98 * h.test.z_pct);
                let _ = write!(
                    t,
                    "; more ({}) {}",
                    join(larger.iter().map(|x| x.hidden), ", "),
                    if better {
                        "still lower the test error a little".to_string()
                    } else {
                        format!(
                            "do not do better on this training set: the training error keeps \
                             falling ({} to {}) while the test error does not (lowest, {}, at \
                             {} hidden neurons)",
                            pct(first.train_pct),
                            pct(last.train_pct),
                            pct(best.test.z_pct),
                            best.hidden
                        )
                    }
                );
            }
            t.push('.');
            t
        }
        None => format!(
            "No count of the sweep is within the goal in every band (best worst band: {} \
             the floor); the lowest test error is {} at {} hidden neurons.",
            times(rows.iter().map(|h| h.worst_band_ratio).fold(f64::INFINITY, f64::min)),
            pct(best.test.z_pct),
            best.hidden
        ),
    };
    for l in r.aware.sweep.iter().filter(|h| h.postures == "lattice") {
        if let Some(g) = rows.iter().find(|g| g.hidden == l.hidden) {
            let _ = write!(
                sentence,
                "\n\nTrained on the regular lattice of postures ({:?} values per term) instead \
                 of one random posture per cell, the 9-{}-3 net is {} the floor overall and \
                 {} in its worst band, against {} and {}: {}.",
                r.config.train_levels,
                l.hidden,
                times(l.test.z_pct / l.floor.z_pct),
                times(l.worst_band_ratio),
                times(g.test.z_pct / g.floor.z_pct),
                times(g.worst_band_ratio),
                if l.worst_band_ratio > g.worst_band_ratio * 1.02 {
                    "on this seed the stratified grid, which covers every joint value, is \
                     the better training set, at no extra cost"
                } else if g.worst_band_ratio > l.worst_band_ratio * 1.02 {
                    "on this seed the lattice is the better training set"
                } else {
                    "about the same"
                }
            );
        }
    }
    sentence
}

fn distortion_sentence(r: &Posture) -> String {
    let (Some(d0), Some(d1)) = (r.distortion.first(), r.distortion.last()) else {
        return "The run has no lens study.".to_string();
    };
    let nets: Vec<String> = d0
        .nets
        .iter()
        .zip(&d1.nets)
        .map(|((h, a), (_, b))| format!("4-{h}-3 {} to {}", pct(a.z_pct), pct(b.z_pct)))
        .collect();
    let dlt_grows = d1.dlt.z_pct > 1.5 * d0.dlt.z_pct;
    format!(
        "{} from {} at k1 = {:.1} ({} the floor) to {} at k1 = {:.1} ({}); the nets learn the lens \
         ({}, {} the floor at the strongest lens); the floor itself goes from {} to {}{}.",
        if dlt_grows {
            "The DLT, a linear camera model, degrades steadily as the lens bends the image:"
        } else {
            "The DLT changes little with the lens here:"
        },
        pct(d0.dlt.z_pct),
        d0.k1,
        times(d0.dlt.z_pct / d0.floor.z_pct),
        pct(d1.dlt.z_pct),
        d1.k1,
        times(d1.dlt.z_pct / d1.floor.z_pct),
        nets.join(", "),
        times(best_net(d1) / d1.floor.z_pct),
        pct(d0.floor.z_pct),
        pct(d1.floor.z_pct),
        if d1.floor.z_pct > 1.05 * d0.floor.z_pct {
            ": barrel distortion compresses the image edges, so a rounded pixel there covers \
             more of the scene"
        } else {
            ""
        }
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quick_and_full_settings() {
        let full = StudyConfig::experiment(super::super::DEFAULT_SEED, false);
        let d = StudyConfig::default();
        // The settings of docs/posture-study.md's tables: the defaults and the example's
        // `--sweep`.
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
}
