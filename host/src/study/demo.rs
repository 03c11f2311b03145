//! `hvs demo`'s results and files: per camera case the default net next to the traditional
//! method and the floor ([`CaseResult`]), the comparison table, `REPORT.md` from
//! `host/templates/demo.md` (a section per case from `demo_case.md`) and the printed summary
//! from `demo.txt`; for `hvs demo --images` ([`ImageCase`]) `IMAGES.md` from
//! `demo_images.md` and the printed table from `demo_images.txt`.

pub mod run;

use crate::evaluate::{text_table, Evaluation};
use crate::fmt::{join, pct, roman};
use crate::sim::sets::training_volume;
use crate::study::accuracy::images::{Detected, TEST_CENTRE};
use crate::study::engine::{table_markdown, table_text, Files};
use crate::study::reported::{self, NET_BOUND_PCT};
use crate::study::template::fill;
use crate::train::TrainConfig;
use anyhow::Result;
use hvs_shared::runtime::traditional::Calibration;
use hvs_shared::sim::presets::{
    LABELS, TEST_DEPTHS, TEST_POINTS_XY, TRAIN_BOARD_X, TRAIN_BOARD_Y, TRAIN_DEPTHS,
};
use hvs_vision::render::{opencv_board, RenderOptions};
use std::path::Path;

/// Random points of the training volume used for the accuracy-floor comparison.
pub const VOLUME_POINTS: usize = 500;
/// Random points of the training volume a second net is trained on.
pub const VOLUME_TRAIN_POINTS: usize = 1000;

const REPORT: &str = include_str!("../../templates/demo.md");
const CASE: &str = include_str!("../../templates/demo_case.md");
const SUMMARY: &str = include_str!("../../templates/demo.txt");
const IMAGES: &str = include_str!("../../templates/demo_images.md");
const IMAGES_CASE: &str = include_str!("../../templates/demo_images_case.md");
const IMAGES_SUMMARY: &str = include_str!("../../templates/demo_images.txt");

/// Seed of case `n`'s random volume training set.
pub fn volume_train_seed(seed: u64, n: u8) -> u64 {
    seed.wrapping_mul(10_000).wrapping_add(1000 + n as u64)
}

/// Seed of case `n`'s random volume test set.
pub fn volume_test_seed(seed: u64, n: u8) -> u64 {
    seed.wrapping_mul(10_000).wrapping_add(2000 + n as u64)
}

/// Seed of case `n`'s rendered training boards (`hvs demo --images`).
pub fn image_train_seed(seed: u64, n: u8) -> u64 {
    seed.wrapping_mul(10_000).wrapping_add(3000 + n as u64)
}

/// Seed of case `n`'s rendered test boards (`hvs demo --images`).
pub fn image_test_seed(seed: u64, n: u8) -> u64 {
    seed.wrapping_mul(10_000).wrapping_add(4000 + n as u64)
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

/// The whole demo.
#[derive(Debug, Clone)]
pub struct Demo {
    /// The cases, in order.
    pub cases: Vec<CaseResult>,
    /// The training configuration of every net.
    pub config: TrainConfig,
    /// Wall time of the run (s).
    pub total_s: f64,
}

impl Demo {
    /// The net's shape, `4-5-3`.
    fn net_shape(&self) -> String {
        format!("4-{}-{}", self.config.hidden, self.config.outputs.len())
    }
}

/// The test depths as a range, `65..165`.
fn test_depths() -> String {
    format!("{}..{}", TEST_DEPTHS[0], TEST_DEPTHS[TEST_DEPTHS.len() - 1])
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
            let (vn, vf) = (r.volume.methods[0].mean.e_ma_pct, r.volume.methods[2].mean.e_ma_pct);
            vec![
                roman(r.case).to_string(),
                format!("{} .. {}", pct(m[1].best_depth_pct), pct(m[1].worst_depth_pct)),
                reported::traditional_range(r.case).unwrap_or_default(),
                m.get(3).map_or("no fallback".into(), |s| pct(s.worst_depth_pct)),
                format!(
                    "{} ({}){}",
                    pct(m[0].worst_depth_pct),
                    pct(m[0].mean.e_ma_pct),
                    if net_ok { String::new() } else { format!(" > {NET_BOUND_PCT} %") }
                ),
                pct(m[2].worst_depth_pct),
                format!("< {NET_BOUND_PCT} %"),
                format!("{} / {} ({:+.1} %)", pct(vn), pct(vf), (vn / vf - 1.0) * 100.0),
            ]
        })
        .collect();
    (head, rows)
}

/// The columns `cols` of a table.
fn columns(head: &[&'static str], rows: &[Vec<String>], cols: &[usize]) -> String {
    let h: Vec<&str> = cols.iter().filter_map(|&c| head.get(c).copied()).collect();
    let r: Vec<Vec<String>> =
        rows.iter().map(|row| cols.iter().filter_map(|&c| row.get(c).cloned()).collect()).collect();
    table_text(&h, &r)
}

fn case_section(r: &CaseResult) -> Result<String> {
    let label = LABELS.get(usize::from(r.case) - 1).copied().unwrap_or("");
    fill(
        "demo_case.md",
        CASE,
        &[
            ("case", roman(r.case).to_string()),
            ("label", label.to_string()),
            ("train_pct", format!("{:.4}", r.train_pct)),
            ("train_s", format!("{:.3}", r.train_s[0])),
            ("volume_train_pct", format!("{:.4}", r.volume_train_pct)),
            ("volume_train_s", format!("{:.3}", r.train_s[1])),
            ("refit_phi", r.refit_phi.map_or("none".into(), |p| format!("{p:.4} px"))),
            ("test_table", text_table(&r.test)),
            ("volume_table", text_table(&r.volume)),
        ],
    )
}

/// Writes `REPORT.md` of a run with `seed` and `restarts`.
pub fn write(files: &mut Files, d: &Demo) -> Result<()> {
    let (head, rows) = table(&d.cases);
    let cases = d.cases.iter().map(case_section).collect::<Result<Vec<_>>>()?;
    let (lo, hi) = training_volume();
    let c = &d.config;
    let values = [
        ("seed", c.seed.to_string()),
        ("total_s", format!("{:.2}", d.total_s)),
        ("net_shape", d.net_shape()),
        ("restarts", c.restarts.to_string()),
        (
            "train_points",
            (TRAIN_BOARD_X.len() * TRAIN_BOARD_Y.len() * TRAIN_DEPTHS.len()).to_string(),
        ),
        ("test_depth_count", TEST_DEPTHS.len().to_string()),
        ("test_depths", test_depths()),
        ("test_points", (TEST_DEPTHS.len() * TEST_POINTS_XY.len()).to_string()),
        ("volume_train_points", VOLUME_TRAIN_POINTS.to_string()),
        ("volume_points", VOLUME_POINTS.to_string()),
        (
            "volume",
            format!("X {}..{}, Y {}..{}, Z {}..{} cm", lo[0], hi[0], lo[1], hi[1], lo[2], hi[2]),
        ),
        ("table", table_markdown(&head, &[], &rows)),
        ("builtin_phi", Calibration::BUILT_IN.phi.to_string()),
        ("bound", NET_BOUND_PCT.to_string()),
        ("cases", join(cases, "")),
        ("volume_train_seed", volume_train_seed(c.seed, 1).to_string()),
        ("volume_test_seed", volume_test_seed(c.seed, 1).to_string()),
    ];
    files.page("REPORT.md", "demo.md", REPORT, &values)
}

/// What `hvs demo` prints: two tables of at most 100 columns (`REPORT.md` keeps the one wide
/// table), the traditional method, then the net, the floor and the volume.
pub fn summary(d: &Demo, output: &Path) -> Result<String> {
    let (head, rows) = table(&d.cases);
    fill(
        "demo.txt",
        SUMMARY,
        &[
            ("net_shape", d.net_shape()),
            ("test_depths", test_depths()),
            ("traditional_table", columns(&head, &rows, &[0, 1, 2, 3])),
            ("network_table", columns(&head, &rows, &[0, 4, 5, 6, 7])),
            ("output", output.display().to_string()),
            ("total_s", format!("{:.2}", d.total_s)),
        ],
    )
}

/// What `hvs demo --images` found for one case.
#[derive(Debug, Clone)]
pub struct ImageCase {
    /// The case.
    pub case: u8,
    /// The corners detected in its training and test images.
    pub detected: Detected,
    /// The test evaluation: the default model, then the floor.
    pub test: Evaluation,
}

/// The image demo's table, one row per case.
fn images_table(cases: &[ImageCase]) -> String {
    let head = ["case", "train corners", "test corners", "corner err", "network", "floor", "ratio"];
    let rows: Vec<Vec<String>> = cases
        .iter()
        .map(|r| {
            let (net, floor) = (r.test.methods[0].mean.e_ma_pct, r.test.methods[1].mean.e_ma_pct);
            let d = &r.detected;
            let [t, u] = [d.train_corners, d.test_corners].map(|[f, n]| format!("{f}/{n}"));
            let err = format!("{:.3} px", d.corner_error_px);
            vec![
                roman(r.case).into(),
                t,
                u,
                err,
                pct(net),
                pct(floor),
                format!("{:.2}x", net / floor),
            ]
        })
        .collect();
    table_text(&head, &rows)
}

/// Writes `IMAGES.md` of `hvs demo --images` and returns what it prints.
pub fn write_images(files: &mut Files, cases: &[ImageCase], output: &Path) -> Result<String> {
    let case = |r: &ImageCase| {
        let d = &r.detected;
        let [t, u] = [d.train_corners, d.test_corners].map(|[f, n]| format!("{f}/{n}"));
        let values = [
            ("label", LABELS.get(usize::from(r.case) - 1).copied().unwrap_or("").to_string()),
            ("train_corners", t),
            ("corner_error_px", format!("{:.3}", d.corner_error_px)),
            ("test_corners", u),
            ("test_table", text_table(&r.test)),
        ];
        fill("demo_images_case.md", IMAGES_CASE, &values)
    };
    let (board, opt) = (opencv_board(), RenderOptions::default());
    let [x, y] = TEST_CENTRE;
    let table = images_table(cases);
    let values = [
        ("board", format!("{}x{}", board.cols, board.rows)),
        ("square_cm", board.square_cm.to_string()),
        ("blur_px", opt.blur_sigma_px.to_string()),
        ("noise_grey", opt.noise_sigma.to_string()),
        ("test_centre", format!("X {x} cm, Y {y} cm")),
        ("table", table.clone()),
        ("cases", join(cases.iter().map(case).collect::<Result<Vec<_>>>()?, "")),
    ];
    files.page("IMAGES.md", "demo_images.md", IMAGES, &values)?;
    let out = [("table", table), ("output", output.display().to_string())];
    fill("demo_images.txt", IMAGES_SUMMARY, &out)
}
