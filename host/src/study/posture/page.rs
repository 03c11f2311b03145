//! The files of `hvs experiment posture` ([`crate::study::posture`]): a CSV and a plot (SVG
//! and PNG) per part ([`STEMS`]), `timing.csv`, and `POSTURE.md` from
//! `host/templates/posture.md`.

use super::{
    csv_tables, BandRow, DistortionRow, Errors, FixedRow, HiddenRow, Posture, StudyConfig,
    GOAL_RATIO, TERMS, WIDE_BOARD_U, WIDE_BOARD_V,
};
use crate::fmt::{join, pct, roman, span, stages, times};
use crate::study::engine::{number_word, Files, Report};
use crate::study::plot::{Figure, Legend, Panel, Series, Style, FLOOR_COLOR};
use anyhow::Result;
use hvs_shared::runtime::blob::{Family, OutputFrame};
use hvs_shared::sim::posture::PostureRange;
use std::fmt::Write as _;

/// The stems of the files the study writes (each as `.csv`, `.svg`, `.png`), besides
/// `timing.csv` and `POSTURE.md`.
pub const STEMS: [&str; 4] = ["fixed", "bands", "hidden", "distortion"];

impl Report for Posture {
    const PAGE: &'static str = "POSTURE.md";
    /// The CSVs ([`csv_tables`]), one plot per part (SVG and PNG) and `POSTURE.md`.
    fn write(&self, files: &mut Files, total_s: f64) -> Result<()> {
        let r = self;
        for (name, header, rows) in csv_tables(r) {
            files.csv(name, &header, &rows)?;
        }
        let figures = [fixed_figure(r), bands_figure(r), hidden_figure(r), distortion_figure(r)];
        for (stem, fig) in STEMS.iter().zip(&figures) {
            files.figure(stem, fig)?;
        }
        files.page(Self::PAGE, "host/templates/posture.md", TEMPLATE, &values(r, total_s))
    }
}

// ---------------------------------------------------------------------------------------
// Figures

const EMA_LABEL: &str = "depth e_ma (% of true depth)";
const RATIO_LABEL: &str = "net e_ma / floor e_ma";
const GOAL_COLOR: usize = 1;
/// The gaze terms of the turning panels: index, legend, colour.
const TURNS: [(usize, &str, usize); 4] =
    [(3, "version (eyes turned)", 0), (0, "neck pan", 2), (2, "eye tilt", 3), (1, "neck tilt", 4)];
/// Colours of [`TERMS`] in the band plot.
const TERM_COLORS: [usize; 5] = [0, 2, 3, 4, 6];
const NET_COLORS: [usize; 3] = [0, 2, 4];

/// A series of `(x, y)` points.
fn line(
    name: impl Into<String>,
    xy: impl IntoIterator<Item = (f64, f64)>,
    style: Style,
    color: usize,
) -> Series {
    Series { name: name.into(), points: xy.into_iter().collect(), style, color }
}

fn goal_name() -> String {
    format!("goal: {GOAL_RATIO:.2} x the floor")
}

/// The rows of (a) that move only gaze term `k` (home included, at 0), as `(angle, row)`; a
/// term is at zero within a fraction of the drives' 0.18 degree step.
fn single_term(rows: &[FixedRow], k: usize) -> Vec<(f64, &FixedRow)> {
    rows.iter()
        .filter_map(|r| {
            let g = PostureRange::gaze_terms(&r.joints);
            let others_zero = (0..5).filter(|&i| i != k).all(|i| g[i].abs() < 0.05);
            others_zero.then_some((f64::from(g[k]), r))
        })
        .collect()
}

fn fixed_figure(r: &Posture) -> Figure {
    let verg = single_term(&r.fixed, 4);
    let at = |f: fn(&FixedRow) -> f64| verg.iter().map(move |&(a, row)| (a, f(row)));
    let floor_name = "optimal triangulation at the posture (floor): depth e_ma";
    let vergence = vec![
        line("4-5-3 net: depth e_ma", at(|f| f.net.z_pct), Style::LinePoints, 0),
        line("4-5-3 net: 3-D error", at(|f| f.net.d3_pct), Style::Points, 3),
        line(floor_name, at(|f| f.floor.z_pct), Style::Dashed, FLOOR_COLOR),
    ];
    let vergence_y = "error (% of true depth or distance)";
    let vergence = Panel::new(
        "vergence (neck, tilt and version at 0)",
        "vergence (deg)",
        vergence_y,
        vergence,
    );
    let turned: Vec<&FixedRow> =
        r.fixed.iter().filter(|f| PostureRange::gaze_terms(&f.joints)[4].abs() < 0.05).collect();
    let angles =
        TURNS.iter().flat_map(|&(k, _, _)| single_term(&r.fixed, k).into_iter().map(|v| v.0));
    let xmax = span(angles).1.max(1.0);
    let turn_panel = |title: &str, y_label: &str, value: fn(&Errors) -> f64| {
        let mut series: Vec<Series> = TURNS
            .iter()
            .map(|&(k, name, color)| {
                let rows = single_term(&r.fixed, k);
                line(
                    name,
                    rows.iter().map(|v| (v.0.abs(), value(&v.1.net))),
                    Style::LinePoints,
                    color,
                )
            })
            .collect();
        let (flo, fhi) = span(turned.iter().map(|f| value(&f.floor)));
        let name = format!("floor at these postures ({flo:.2}-{fhi:.2} %), mean");
        series.push(Series::level(name, [0.0, xmax], (flo + fhi) / 2.0, FLOOR_COLOR));
        Panel::new(title, "angle of the one moved term (deg)", y_label, series)
    };
    let (case, points) = (roman(r.config.case), r.config.fixed_points);
    let title = format!(
        "The thesis' 4-5-3 net, trained at the home posture, at other postures (case {case}, \
         {points} random points each)"
    );
    let d3 = "3-D error (% of distance)";
    let panels = vec![
        Panel { log_y: true, ..vergence },
        turn_panel("turning: depth error of the net", EMA_LABEL, |e| e.z_pct),
        turn_panel("turning: 3-D error of the net (head frame)", d3, |e| e.d3_pct),
    ];
    Figure { title, panels, cols: 3 }
}

fn bands_figure(r: &Posture) -> Figure {
    let (bands, c) = (&r.aware.bands, &r.config);
    let mut ratios: Vec<Series> = TERMS
        .iter()
        .zip(TERM_COLORS)
        .map(|(&term, color)| {
            let b = bands.iter().filter(|b| b.term == term);
            let xy = (1..).zip(b).map(|(k, b)| (f64::from(k), b.ratio()));
            line(term, xy, Style::LinePoints, color)
        })
        .collect();
    ratios.push(Series::level(goal_name(), [1.0, 3.0], GOAL_RATIO, GOAL_COLOR));
    ratios.push(Series::level("the floor (1.00)", [1.0, 3.0], 1.0, FLOOR_COLOR));
    let at = |f: fn(&BandRow) -> f64| (1..).zip(bands).map(move |(k, b)| (f64::from(k), f(b)));
    let floor_name = "optimal triangulation at the same postures (floor)";
    let errors = vec![
        line("posture-aware net", at(|b| b.net.z_pct), Style::Points, 0),
        line(floor_name, at(|b| b.floor.z_pct), Style::Dashed, FLOOR_COLOR),
        line(goal_name(), at(|b| b.floor.z_pct * GOAL_RATIO), Style::Dashed, GOAL_COLOR),
    ];
    let (mut order, mut k) = (Vec::new(), 1);
    for group in bands.chunk_by(|a, b| a.term == b.term) {
        let (n, term) = (group.len(), group[0].term);
        let last = if n == 1 { String::new() } else { format!("-{}", k + n - 1) };
        order.push(format!("{k}{last} {term}"));
        k += n;
    }
    let h = r.aware.sweep.iter().find(|h| h.hidden == c.hidden);
    let train = h.map_or(String::new(), |h| format!(" (training e_ma {:.2} %)", h.train_pct));
    let ratio_title = format!(
        "net / floor depth e_ma per band: thirds of each term's range ({} random points at {} \
         random postures)",
        c.test_points, c.test_postures
    );
    let ratio_x = "band: 1 = third nearest home, 3 = outer third";
    let errors_title = format!(
        "depth e_ma per band, and on {} points at extreme postures{train}",
        c.extreme_points
    );
    let errors_x = format!("band: {}", order.join(", "));
    let bands = |p: Panel| Panel { integer_x: true, ..p };
    Figure {
        title: format!("The posture-aware 9-{}-3 net per posture band vs. the floor", c.hidden),
        panels: vec![
            bands(Panel::new(ratio_title, ratio_x, RATIO_LABEL, ratios)),
            bands(Panel::new(errors_title, errors_x, EMA_LABEL, errors)),
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
    let lattice: Vec<&HiddenRow> =
        r.aware.sweep.iter().filter(|h| h.postures == "lattice").collect();
    let at = |rows: &[&HiddenRow], f: fn(&HiddenRow) -> f64| -> Vec<(f64, f64)> {
        rows.iter().map(|h| (h.hidden as f64, f(h))).collect()
    };
    let ends = [
        rows.first().map_or(0.0, |h| h.hidden as f64),
        rows.last().map_or(1.0, |h| h.hidden as f64),
    ];
    let floor = rows.first().map_or(f64::NAN, |h| h.floor.z_pct);
    let lattice_name = "trained on the regular lattice of postures instead";
    let errors = vec![
        line("test, random postures", at(&rows, |h| h.test.z_pct), Style::LinePoints, 0),
        line("training set", at(&rows, |h| h.train_pct), Style::LinePoints, 2),
        line(lattice_name, at(&lattice, |h| h.test.z_pct), Style::Points, 4),
        Series::level("floor on the test points", ends, floor, FLOOR_COLOR),
        Series::level(goal_name(), ends, floor * GOAL_RATIO, GOAL_COLOR),
    ];
    let ratios = vec![
        line(
            "all random postures",
            at(&rows, |h| h.test.z_pct / h.floor.z_pct),
            Style::LinePoints,
            0,
        ),
        line("worst posture band", at(&rows, |h| h.worst_band_ratio), Style::LinePoints, 3),
        line(lattice_name, at(&lattice, |h| h.worst_band_ratio), Style::Points, 4),
        Series::level(goal_name(), ends, GOAL_RATIO, GOAL_COLOR),
    ];
    let x = "hidden neurons of the 9-H-3 net";
    let upper_right = |p: Panel| Panel { legend: Legend::UpperRight, integer_x: true, ..p };
    Figure {
        title: format!(
            "Hidden neurons of the posture-aware net (training: {} rows at {} postures; test: {} \
             random points)",
            r.aware.train_rows, r.aware.train_postures, r.config.test_points
        ),
        panels: vec![
            upper_right(Panel::new("depth e_ma vs. hidden neurons", x, EMA_LABEL, errors)),
            upper_right(Panel::new("net / floor vs. hidden neurons", x, RATIO_LABEL, ratios)),
        ],
        cols: 2,
    }
}

fn distortion_figure(r: &Posture) -> Figure {
    let d = &r.distortion;
    let at = |f: &dyn Fn(&DistortionRow) -> f64| -> Vec<(f64, f64)> {
        d.iter().map(|d| (d.k1, f(d))).collect()
    };
    let mut series = Vec::new();
    for (i, (h, _)) in d.first().map_or(&[][..], |d| &d.nets[..]).iter().enumerate() {
        let xy = at(&|row| row.nets.get(i).map_or(f64::NAN, |n| n.1.z_pct));
        series.push(line(format!("network 4-{h}-3"), xy, Style::LinePoints, NET_COLORS[i % 3]));
    }
    let floor_name = "optimal triangulation, true cameras and lenses (floor)";
    series.push(line("DLT fit + linear triangulation", at(&|d| d.dlt.z_pct), Style::LinePoints, 1));
    series.push(line(floor_name, at(&|d| d.floor.z_pct), Style::Dashed, FLOOR_COLOR));
    let shift_name = "largest |distorted - ideal| pixel coordinate";
    let shift_title = "largest pixel displacement by the lens on the test points";
    let shift = vec![line(shift_name, at(&|d| d.max_shift_px), Style::LinePoints, 3)];
    let x = "k1 (radius in image half-widths)";
    let upper_right = |p: Panel| Panel { legend: Legend::UpperRight, ..p };
    Figure {
        title: format!(
            "Radial lens distortion at the home posture: wide board, {} random test points at \
             65-165 cm",
            r.config.test_points
        ),
        panels: vec![
            upper_right(Panel::new("depth e_ma vs. k1", x, EMA_LABEL, series)),
            upper_right(Panel::new(shift_title, x, "displacement (px)", shift)),
        ],
        cols: 2,
    }
}

// ---------------------------------------------------------------------------------------
// POSTURE.md

const TEMPLATE: &str = include_str!("../../../templates/posture.md");

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
fn smallest_within_goal(r: &Posture) -> Option<&HiddenRow> {
    grid_sweep(r).into_iter().find(|h| h.worst_band_ratio <= GOAL_RATIO)
}

/// The family of the posture-aware nets in words.
fn family_words(f: Family, frame: OutputFrame) -> String {
    use hvs_shared::runtime::blob::Skip;
    use hvs_shared::runtime::mlp::OutputMap;
    let outputs = match f.output_map {
        OutputMap::Direct => "X, Y, Z",
        OutputMap::InverseDepth => "X/Z, Y/Z, 1/Z",
    };
    let skip = match f.skip {
        Skip::None => "",
        Skip::Linear => ", each the sigmoid net's plus an affine skip term of the nine inputs",
    };
    let frame = match frame {
        OutputFrame::Head => "",
        OutputFrame::EyePlatform => {
            ", in the eye platform's frame (the head frame turned by the neck pan, neck tilt and \
             eye tilt inputs), turned back into the head frame by the model"
        }
        OutputFrame::Cyclopean => {
            ", in the cyclopean frame (the head frame turned by the neck pan, neck tilt and eye \
             tilt inputs and by the version, the mean of the eye pans), turned back into the head \
             frame by the model"
        }
    };
    format!("`{}` (outputs {outputs}{skip}{frame})", f.name())
}

/// `yes` if `c`, else `no`.
fn pick(c: bool, yes: &str, no: &str) -> String {
    (if c { yes } else { no }).to_string()
}

/// Why the floor grows with barrel distortion.
const BARREL: &str = ": barrel distortion compresses the image edges, so a rounded pixel there \
                      covers more of the scene";

/// Rows of a markdown table (its head is in the template).
fn md_rows<T>(items: &[T], row: impl Fn(&T) -> Vec<String>) -> String {
    join(items.iter().map(|x| format!("| {} |\n", row(x).join(" | "))), "")
}

/// `lo-hi` of `v` as percentages.
fn pct_span(v: impl Iterator<Item = f64>) -> String {
    let (lo, hi) = span(v);
    format!("{}-{}", pct(lo), pct(hi))
}

fn settings(r: &Posture) -> String {
    let c = &r.config;
    let sweep = join(grid_sweep(r).iter().map(|h| h.hidden), ", ");
    let (hidden, postures, points) = (c.hidden, r.aware.train_postures, c.test_points);
    if c.quick {
        return format!(
            "**Reduced run (`--quick`, for tests):** {postures} training postures ({:?} cells per \
             gaze term), a 9-{hidden}-3 net, hidden neurons {sweep}, {points} test points; the \
             numbers show the shape of the study, not its accuracy. Run `hvs experiment posture` \
             for the study's settings.",
            c.train_levels
        );
    }
    let lattice = format!(" and the 9-{hidden}-3 net trained on the regular lattice of postures");
    let lattice = if c.lattice { lattice.as_str() } else { "" };
    let (seed, family, test_postures) = (c.seed, c.family.name(), c.test_postures);
    format!(
        "Settings: those of the tables in docs/posture-study.md (the study's defaults with the \
         example's `--sweep`): seed {seed}, a 9-{hidden}-3 net of family `{family}` trained at \
         {postures} postures, {points} test points at {test_postures} random postures, hidden \
         neurons {sweep}{lattice}."
    )
}

fn hidden_sentence(r: &Posture) -> String {
    let rows = grid_sweep(r);
    let Some(best) = rows.iter().min_by(|a, b| a.test.z_pct.total_cmp(&b.test.z_pct)) else {
        return "The run has no hidden-neuron sweep.".to_string();
    };
    let (low, at) = (pct(best.test.z_pct), best.hidden);
    let mut s = match smallest_within_goal(r) {
        Some(h) => {
            let fewer = rows.iter().filter(|x| x.hidden < h.hidden);
            let fewer =
                join(fewer.map(|x| format!("{}: {}", x.hidden, times(x.worst_band_ratio))), ", ");
            let more: Vec<&&HiddenRow> = rows.iter().filter(|x| x.hidden > h.hidden).collect();
            let counts = join(more.iter().map(|x| x.hidden), ", ");
            let (first, last) = (pct(rows[0].train_pct), pct(rows[rows.len() - 1].train_pct));
            let more = if more.is_empty() {
                String::new()
            } else if more.iter().any(|x| x.test.z_pct < 0.98 * h.test.z_pct) {
                format!("; more ({counts}) still lower the test error a little")
            } else {
                format!(
                    "; more ({counts}) do not do better on this training set: the training error \
                     keeps falling ({first} to {last}) while the test error does not (lowest, \
                     {low}, at {at} hidden neurons)"
                )
            };
            let fewer_text = format!("; fewer miss it in the worst band ({fewer})");
            let fewer = pick(!fewer.is_empty(), &fewer_text, "");
            let (n, p, bytes, worst) =
                (h.hidden, h.params, h.params * 4, times(h.worst_band_ratio));
            format!(
                "{n} hidden neurons ({p} parameters, {bytes} bytes of weights) is the smallest \
                 count within the goal in every band (worst band {worst} the floor){fewer}{more}."
            )
        }
        None => format!(
            "No count of the sweep is within the goal in every band (best worst band: {} \
             the floor); the lowest test error is {low} at {at} hidden neurons.",
            times(rows.iter().map(|h| h.worst_band_ratio).fold(f64::INFINITY, f64::min)),
        ),
    };
    for l in r.aware.sweep.iter().filter(|h| h.postures == "lattice") {
        let Some(g) = rows.iter().find(|g| g.hidden == l.hidden) else { continue };
        let verdict = if l.worst_band_ratio > g.worst_band_ratio * 1.02 {
            "on this seed the stratified grid, which covers every joint value, is the better \
             training set, at no extra cost"
        } else if g.worst_band_ratio > l.worst_band_ratio * 1.02 {
            "on this seed the lattice is the better training set"
        } else {
            "about the same"
        };
        let (lx, lw) = (times(l.test.z_pct / l.floor.z_pct), times(l.worst_band_ratio));
        let (gx, gw) = (times(g.test.z_pct / g.floor.z_pct), times(g.worst_band_ratio));
        let _ = write!(
            s,
            "\n\nTrained on the regular lattice of postures ({:?} values per term) instead of one \
             random posture per cell, the 9-{}-3 net is {lx} the floor overall and {lw} in its \
             worst band, against {gx} and {gw}: {verdict}.",
            r.config.train_levels, l.hidden
        );
    }
    s
}

fn values(r: &Posture, total_s: f64) -> Vec<(&'static str, String)> {
    let c = &r.config;
    let nan = Errors { z_pct: f64::NAN, d3_pct: f64::NAN, ..Errors::default() };
    let home = r.fixed.iter().find(|f| f.label == "home").map_or((nan, nan), |f| (f.net, f.floor));
    let verged = single_term(&r.fixed, 4).into_iter().filter(|v| v.0 > 0.0);
    let verged = verged.max_by(|a, b| a.0.total_cmp(&b.0));
    let (verged_deg, verged) =
        verged.map_or((f64::NAN, (nan, nan)), |(v, f)| (v, (f.net, f.floor)));
    let moved = TURNS.iter().flat_map(|&(k, _, _)| single_term(&r.fixed, k));
    let turned: Vec<&FixedRow> = moved.filter(|v| v.0 != 0.0).map(|v| v.1).collect();
    let bands = &r.aware.bands;
    let all = bands.first().map_or((nan, nan), |b| (b.net, b.floor));
    let worst = bands.iter().max_by(|a, b| a.ratio().total_cmp(&b.ratio()));
    let worst_x = worst.map_or(f64::NAN, BandRow::ratio);
    let (ratio_lo, ratio_hi) = span(bands.iter().map(BandRow::ratio));
    let met = worst_x <= GOAL_RATIO;
    let (d0, d1) = (r.distortion.first(), r.distortion.last());
    let lens =
        |d: Option<&DistortionRow>| d.map_or((f64::NAN, nan, nan), |d| (d.k1, d.dlt, d.floor));
    let ((k1_0, dlt_0, floor_0), (k1_1, dlt_1, floor_1)) = (lens(d0), lens(d1));
    let best_net =
        d1.map_or(f64::NAN, |d| d.nets.iter().map(|n| n.1.z_pct).fold(f64::INFINITY, f64::min));
    let [nets0, nets1] = [d0, d1].map(|d| d.map_or(&[][..], |d| &d.nets[..]));
    let lens_nets = nets0.iter().zip(nets1);
    let lens_nets =
        lens_nets.map(|((h, a), (_, b))| format!("4-{h}-3 {} to {}", pct(a.z_pct), pct(b.z_pct)));
    let params = r.aware.blob.params.len();
    let smallest = smallest_within_goal(r)
        .map_or("none of the sweep".into(), |h| format!("{} ({} parameters)", h.hidden, h.params));
    let breaks = verged.0.z_pct > 10.0 * verged.1.z_pct;
    let dlt_grows = dlt_1.z_pct > 1.5 * dlt_0.z_pct;
    let range = TERMS.iter().zip(PostureRange::WORKING.intervals()).map(|(n, [lo, hi])| {
        let span = if lo == -hi { format!("+-{hi}") } else { format!("{lo}-{hi}") };
        format!("{n} {span}")
    });
    vec![
        ("command", command(c)),
        ("total_s", format!("{total_s:.1}")),
        ("threads", r.threads.to_string()),
        ("case", roman(c.case).to_string()),
        ("settings", settings(r)),
        ("stage_times", stages(&r.stage_s)),
        ("verged_deg", format!("{verged_deg:.1}")),
        ("verged_z", pct(verged.0.z_pct)),
        ("verged_x", format!("{:.0}", verged.0.z_pct / verged.1.z_pct)),
        ("verged_floor", pct(verged.1.z_pct)),
        ("hidden", c.hidden.to_string()),
        ("goal_pct", format!("{:.0}", (GOAL_RATIO - 1.0) * 100.0)),
        ("all_net", pct(all.0.z_pct)),
        ("all_floor", pct(all.1.z_pct)),
        ("all_x", times(all.0.z_pct / all.1.z_pct)),
        ("worst_term", worst.map_or("-", |w| w.term).to_string()),
        ("worst_band", worst.map_or("-".to_string(), |w| w.band.clone())),
        ("worst_x", times(worst_x)),
        ("goal_verdict", pick(met, "met", "missed")),
        ("smallest", smallest),
        ("k1_last", format!("{k1_1:.1}")),
        ("dlt_last", pct(dlt_1.z_pct)),
        ("best_net_last", pct(best_net)),
        ("floor_last", pct(floor_1.z_pct)),
        ("fixed_points", c.fixed_points.to_string()),
        ("fixed_verdict", pick(breaks, "is what breaks", "degrades")),
        ("home_z", pct(home.0.z_pct)),
        ("home_x", format!("{:.1}", home.0.z_pct / home.1.z_pct)),
        ("turned_z", pct_span(turned.iter().map(|f| f.net.z_pct))),
        ("turned_3d", pct_span(turned.iter().map(|f| f.net.d3_pct))),
        ("fixed_floor", pct_span(r.fixed.iter().map(|f| f.floor.z_pct))),
        ("train_postures", r.aware.train_postures.to_string()),
        ("working_range", join(range, ", ")),
        ("train_levels", format!("{:?}", c.train_levels)),
        ("train_rows", r.aware.train_rows.to_string()),
        ("test_points", c.test_points.to_string()),
        ("test_postures", c.test_postures.to_string()),
        ("extreme_points", c.extreme_points.to_string()),
        ("ratio_lo", format!("{ratio_lo:.2}")),
        ("ratio_hi", format!("{ratio_hi:.2}")),
        ("goal_side", pick(met, "inside", "against")),
        ("goal_ratio", format!("{GOAL_RATIO:.2}")),
        ("band_floor", pct_span(bands.iter().map(|b| b.floor.z_pct))),
        ("seed", c.seed.to_string()),
        ("restarts", format!("{} restart{}", c.restarts, if c.restarts == 1 { "" } else { "s" })),
        ("hidden_sentence", hidden_sentence(r)),
        ("train_depths", number_word(hvs_shared::sim::presets::TRAIN_DEPTHS.len())),
        ("dlt_verdict", pick(dlt_grows, "degrades steadily", "changes little")),
        ("dlt_first", pct(dlt_0.z_pct)),
        ("k1_first", format!("{k1_0:.1}")),
        ("dlt_first_x", times(dlt_0.z_pct / floor_0.z_pct)),
        ("dlt_last_x", times(dlt_1.z_pct / floor_1.z_pct)),
        ("lens_nets", join(lens_nets, ", ")),
        ("best_net_x", times(best_net / floor_1.z_pct)),
        ("floor_first", pct(floor_0.z_pct)),
        ("floor_why", pick(floor_1.z_pct > 1.05 * floor_0.z_pct, BARREL, "")),
        ("case_number", c.case.to_string()),
        ("family", family_words(c.family, c.frame)),
        ("restarts_count", c.restarts.to_string()),
        ("params", params.to_string()),
        ("weight_bytes", (params * 4).to_string()),
        (
            "fixed_rows",
            md_rows(&r.fixed, |f| {
                let (n, fl) = (&f.net, &f.floor);
                let ratio = format!("{:.1}", n.z_pct / fl.z_pct);
                vec![f.label.clone(), pct(n.z_pct), pct(n.d3_pct), pct(fl.z_pct), ratio]
            }),
        ),
        (
            "bands_rows",
            md_rows(bands, |b| {
                let (net, floor) = (&b.net, &b.floor);
                let head = vec![b.term.to_string(), b.band.clone(), net.points.to_string()];
                let ratio = format!("{:.2}", b.ratio());
                let errors =
                    [pct(net.z_pct), pct(floor.z_pct), ratio, pct(net.d3_pct), pct(floor.d3_pct)];
                [head, errors.to_vec()].concat()
            }),
        ),
        (
            "sweep_rows",
            md_rows(&r.aware.sweep, |h| {
                let head = vec![h.postures.to_string(), h.hidden.to_string(), h.params.to_string()];
                let ratios =
                    [h.test.z_pct / h.floor.z_pct, h.worst_band_ratio].map(|x| format!("{x:.2}"));
                let (train, test, time) =
                    (pct(h.train_pct), pct(h.test.z_pct), format!("{:.0} s", h.seconds));
                [head, vec![train, test], ratios.to_vec(), vec![time]].concat()
            }),
        ),
        ("board_width_pct", format!("{:.0}", WIDE_BOARD_U * 100.0)),
        ("board_height_pct", format!("{:.0}", WIDE_BOARD_V * 100.0 * 320.0 / 240.0)),
        ("lens_heads", join(nets0.iter().map(|(h, _)| format!("net 4-{h}-3 | ")), "")),
        ("lens_aligns", "---:|".repeat(nets0.len())),
        (
            "distortion_rows",
            md_rows(&r.distortion, |d| {
                let head = vec![format!("{:.1}", d.k1), format!("{:.1} px", d.max_shift_px)];
                let nets = d.nets.iter().map(|(_, e)| pct(e.z_pct)).collect();
                [head, nets, vec![pct(d.dlt.z_pct), pct(d.floor.z_pct)]].concat()
            }),
        ),
        (
            "part_times",
            join(
                ["a", "b", "c"].iter().zip(r.seconds).map(|(p, s)| format!("({p}) {s:.1} s")),
                ", ",
            ),
        ),
    ]
}
