//! Files of `hvs experiment thesis`: one CSV and one plot (SVG and PNG) per experiment, and
//! `RESULTS.md`, which shows the plots with the thesis' reported values beside ours.
//!
//! Every file is written atomically. CSVs hold numbers with 6 decimals (`inf` where a method
//! has no estimate), so equal results give equal bytes; the only file with wall times is
//! `bp_vs_lm_timing.csv` (and the run time stated in `RESULTS.md`).

use super::markdown::{results_values, POSTURE_REPORT, TEMPLATE};
use super::Config;
use super::{e_ma_hn, hidden_counts, mean_e_ma_hn, DepthCurve, Thesis, GENERAL_CASE, PHI_DEPTHS};
use crate::fmt::{join, num, roman};
use crate::study::engine::{Files, Progress, Study};
use crate::study::plot::{Figure, Legend, Panel, Series, Style, FLOOR_COLOR};
use crate::study::reported::NET_BOUND_PCT;
use crate::train::Algo;
use anyhow::Result;
use hvs_shared::runtime::blob::OutputKind;
use hvs_shared::sim::presets::TEST_DEPTHS;

fn algo_name(a: Algo) -> &'static str {
    match a {
        Algo::Lm => "lm",
        Algo::Bp => "bp",
        Algo::Adam => "adam",
    }
}

fn outputs_name(o: OutputKind) -> &'static str {
    match o {
        OutputKind::Xyz => "xyz",
        OutputKind::Z => "z",
    }
}

const Z_LABEL: &str = "true depth Z (cm)";
const EMA_LABEL: &str = "e_ma (% of true depth)";

fn floor_series(c: &DepthCurve) -> Series {
    Series::new("optimal triangulation, true rig (floor)", &c.z, &c.pct, Style::Dashed, FLOOR_COLOR)
}

/// The stems of the files [`write()`] produces (each as `.csv`, `.svg`, `.png`), besides
/// `bp_vs_lm_timing.csv` and `RESULTS.md`.
pub const STEMS: [&str; 9] = [
    "fig4_03_04_phi",
    "fig4_08_11_traditional",
    "fig4_12_net_case4",
    "fig4_13_ten_nets",
    "fig4_14_15_hidden",
    "fig4_16_19_proposed",
    "fig4_20_22_fewer_depths",
    "bp_vs_lm",
    "noise",
];

/// Writes every CSV, plot and `RESULTS.md`; `total_s` is the run's wall time.
pub fn write(o: &mut Files, t: &Thesis, total_s: f64) -> Result<()> {
    phi_files(o, t)?;
    traditional_files(o, t)?;
    net_case4_files(o, t)?;
    sweep_files(o, t)?;
    proposed_files(o, t)?;
    fewer_files(o, t)?;
    algo_files(o, t)?;
    noise_files(o, t)?;
    let posture = o.dir().join(POSTURE_REPORT).is_file();
    let values = results_values(t, total_s, posture);
    o.page("RESULTS.md", "host/templates/results.md", TEMPLATE, &values)
}

impl Study for Config {
    type Results = Thesis;
    fn page(&self) -> &'static str {
        "RESULTS.md"
    }
    fn what(&self) -> String {
        format!("{} experiments: CSV, SVG, PNG; RESULTS.md", STEMS.len())
    }
    fn compute(&self, progress: &dyn Progress) -> Result<(usize, Thesis)> {
        super::run(self, progress).map(|t| (t.threads, t))
    }
    fn write(&self, files: &mut Files, t: &Thesis, total_s: f64) -> Result<()> {
        write(files, t, total_s)
    }
}

fn phi_files(o: &mut Files, t: &Thesis) -> Result<()> {
    o.rows(
        "fig4_03_04_phi.csv",
        "case,z_cm,phi_l_px,phi_r_px,true_phi_l_px,true_phi_r_px",
        &t.phi,
        |r| {
            vec![
                r.case.to_string(),
                num(r.z),
                num(r.phi_l),
                num(r.phi_r),
                num(r.true_l),
                num(r.true_r),
            ]
        },
    )?;
    let case1: Vec<_> = t.phi.iter().filter(|r| r.case == 1).collect();
    let z: Vec<f64> = case1.iter().map(|r| r.z).collect();
    let panel = |which: &str, est: Vec<f64>, truth: f64, color: usize| Panel {
        title: format!(
            "Fig. 4.{}: {which} by eq. 4.1-3, case I",
            if which == "Phi_L" { 3 } else { 4 }
        ),
        x_label: "board depth Z (cm)".into(),
        y_label: format!("{which} = k_u f (px)"),
        log_y: false,
        series: vec![
            Series::new(
                format!("{which}, 12 symmetric points, rounded pixels"),
                &z,
                &est,
                Style::LinePoints,
                color,
            ),
            Series::new(
                format!("true {which} of the rig"),
                &[PHI_DEPTHS[0], PHI_DEPTHS[PHI_DEPTHS.len() - 1]],
                &[truth, truth],
                Style::Dashed,
                FLOOR_COLOR,
            ),
        ],
        legend: Legend::LowerRight,
        integer_x: false,
    };
    let fig = Figure {
        title: "Phi estimated at Z = 45-105 cm (thesis Figs. 4.3, 4.4)".into(),
        panels: vec![
            panel("Phi_L", case1.iter().map(|r| r.phi_l).collect(), case1[0].true_l, 0),
            panel("Phi_R", case1.iter().map(|r| r.phi_r).collect(), case1[0].true_r, 1),
        ],
        cols: 2,
    };
    o.figure("fig4_03_04_phi", &fig)
}

/// One method against the floor in each case: the CSV `case,z_cm,<column>,optimal_pct` and
/// a figure with one panel per case (`Fig. 4.<first_fig + k>`), the method as `method`
/// (label, colour) beside the floor and the `extra` series.
struct PerCase<'a> {
    stem: &'a str,
    column: &'a str,
    title: &'a str,
    first_fig: usize,
    method: (&'a str, usize),
    log_y: bool,
    extra: Vec<Series>,
}

fn per_case_files(
    o: &mut Files,
    spec: PerCase,
    cases: &[(u8, &DepthCurve, &DepthCurve)],
) -> Result<()> {
    let mut rows = Vec::new();
    for (case, curve, floor) in cases {
        for (k, z) in curve.z.iter().enumerate() {
            rows.push(vec![case.to_string(), num(*z), num(curve.pct[k]), num(floor.pct[k])]);
        }
    }
    o.csv(&format!("{}.csv", spec.stem), &format!("case,z_cm,{},optimal_pct", spec.column), &rows)?;
    let panels = cases
        .iter()
        .map(|(case, curve, floor)| {
            let mut series = vec![
                Series::new(spec.method.0, &curve.z, &curve.pct, Style::LinePoints, spec.method.1),
                floor_series(floor),
            ];
            series.extend(spec.extra.iter().cloned());
            Panel {
                title: format!(
                    "Fig. 4.{}: case {}",
                    spec.first_fig + usize::from(case - 1),
                    roman(*case)
                ),
                x_label: Z_LABEL.into(),
                y_label: EMA_LABEL.into(),
                log_y: spec.log_y,
                series,
                legend: Legend::UpperLeft,
                integer_x: false,
            }
        })
        .collect();
    o.figure(spec.stem, &Figure { title: spec.title.into(), panels, cols: 2 })
}

fn traditional_files(o: &mut Files, t: &Thesis) -> Result<()> {
    let cases: Vec<_> =
        t.traditional.iter().map(|c| (c.case, &c.traditional, &c.optimal)).collect();
    per_case_files(
        o,
        PerCase {
            stem: "fig4_08_11_traditional",
            column: "traditional_pct",
            title: "Traditional method vs. depth, cases I-IV (thesis Figs. 4.8-4.11)",
            first_fig: 8,
            method: ("traditional, eq. 3.1-17, one Phi", 1),
            log_y: true,
            extra: Vec::new(),
        },
        &cases,
    )
}

fn net_case4_files(o: &mut Files, t: &Thesis) -> Result<()> {
    let p = &t.proposed[(GENERAL_CASE - 1) as usize];
    let rows: Vec<Vec<String>> = p
        .net
        .z
        .iter()
        .enumerate()
        .map(|(k, z)| vec![num(*z), num(p.net.pct[k]), num(p.optimal.pct[k])])
        .collect();
    o.csv("fig4_12_net_case4.csv", "z_cm,network_pct,optimal_pct", &rows)?;
    o.figure(
        "fig4_12_net_case4",
        &Figure::single(
            "Per-depth e_ma of the 4-5-3 net, case IV (thesis Fig. 4.12)",
            Panel {
                title: format!(
                    "proposed net ({} restarts, LM), trained on 72 board points",
                    t.config.restarts()
                ),
                x_label: Z_LABEL.into(),
                y_label: EMA_LABEL.into(),
                log_y: false,
                series: vec![
                    Series::new("4-5-3 net", &p.net.z, &p.net.pct, Style::LinePoints, 0),
                    floor_series(&p.optimal),
                ],
                legend: Legend::UpperLeft,
                integer_x: false,
            },
        ),
    )?;
    // Fig. 4.13: the sweep's nets with 5 hidden neurons and three outputs.
    let ten: Vec<_> =
        t.sweep.iter().filter(|r| r.hidden == 5 && r.outputs == OutputKind::Xyz).collect();
    let rows: Vec<Vec<String>> = ten
        .iter()
        .map(|r| {
            vec![
                (r.index + 1).to_string(),
                r.seed.to_string(),
                num(r.train_pct),
                num(r.test_mean_pct),
                num(r.test_worst_pct),
            ]
        })
        .collect();
    o.csv("fig4_13_ten_nets.csv", "net,seed,train_pct,test_mean_pct,test_worst_depth_pct", &rows)?;
    let x: Vec<f64> = ten.iter().map(|r| (r.index + 1) as f64).collect();
    let floor = p.optimal.worst();
    o.figure(
        "fig4_13_ten_nets",
        &Figure::single(
            "Ten 4-5-3 nets, case IV (thesis Fig. 4.13)",
            Panel {
                title: "each net: one training from one seeded random start".into(),
                x_label: "net number".into(),
                y_label: EMA_LABEL.into(),
                log_y: false,
                series: vec![
                    Series::new(
                        "worst per-depth test e_ma (the net's error)",
                        &x,
                        &ten.iter().map(|r| r.test_worst_pct).collect::<Vec<_>>(),
                        Style::Points,
                        0,
                    ),
                    Series::new(
                        "mean test e_ma",
                        &x,
                        &ten.iter().map(|r| r.test_mean_pct).collect::<Vec<_>>(),
                        Style::Points,
                        2,
                    ),
                    Series::new(
                        "training e_ma",
                        &x,
                        &ten.iter().map(|r| r.train_pct).collect::<Vec<_>>(),
                        Style::Points,
                        3,
                    ),
                    Series::new(
                        "floor: worst per-depth e_ma of optimal triangulation",
                        &[0.5, x.len() as f64 + 0.5],
                        &[floor, floor],
                        Style::Dashed,
                        FLOOR_COLOR,
                    ),
                    Series::new(
                        "floor: mean e_ma of optimal triangulation",
                        &[0.5, x.len() as f64 + 0.5],
                        &[p.optimal.mean, p.optimal.mean],
                        Style::Dashed,
                        6,
                    ),
                ],
                legend: Legend::UpperLeft,
                integer_x: true,
            },
        ),
    )
}

fn sweep_files(o: &mut Files, t: &Thesis) -> Result<()> {
    o.rows(
        "fig4_14_15_hidden.csv",
        "outputs,hidden,net,seed,train_pct,test_mean_pct,test_worst_depth_pct",
        &t.sweep,
        |r| {
            vec![
                outputs_name(r.outputs).to_string(),
                r.hidden.to_string(),
                (r.index + 1).to_string(),
                r.seed.to_string(),
                num(r.train_pct),
                num(r.test_mean_pct),
                num(r.test_worst_pct),
            ]
        },
    )?;
    let h: Vec<f64> = hidden_counts(&t.sweep).iter().map(|&h| h as f64).collect();
    let floor = t.proposed[(GENERAL_CASE - 1) as usize].optimal.worst();
    let floor_line = Series::new(
        "floor: worst per-depth e_ma of optimal triangulation",
        &[1.0, 10.0],
        &[floor, floor],
        Style::Dashed,
        FLOOR_COLOR,
    );
    let floor_mean = t.proposed[(GENERAL_CASE - 1) as usize].optimal.mean;
    let floor_mean_line = Series::new(
        "floor: mean e_ma of optimal triangulation",
        &[1.0, 10.0],
        &[floor_mean, floor_mean],
        Style::Dashed,
        FLOOR_COLOR,
    );
    let n = t.config.nets();
    o.figure(
        "fig4_14_15_hidden",
        &Figure {
            title: format!(
                "e_ma vs. hidden neurons, one output (Z) vs. three (X, Y, Z), case IV, {n} nets each (thesis Figs. 4.14, 4.15)"
            ),
            panels: vec![
                Panel {
                    title: "e_ma_Hn: mean over the nets of their worst per-depth e_ma".into(),
                    x_label: "hidden neurons H_n".into(),
                    y_label: EMA_LABEL.into(),
                    log_y: false,
                    series: vec![
                        Series::new(
                            "one output (Z), Fig. 4.14",
                            &h,
                            &e_ma_hn(&t.sweep, OutputKind::Z),
                            Style::LinePoints,
                            1,
                        ),
                        Series::new(
                            "three outputs (X, Y, Z), Fig. 4.15",
                            &h,
                            &e_ma_hn(&t.sweep, OutputKind::Xyz),
                            Style::LinePoints,
                            0,
                        ),
                        floor_line,
                    ],
                    legend: Legend::UpperRight,
                    integer_x: true,
                },
                Panel {
                    title: "mean over the nets of their mean test e_ma (all 22 points)".into(),
                    x_label: "hidden neurons H_n".into(),
                    y_label: EMA_LABEL.into(),
                    log_y: false,
                    series: vec![
                        Series::new(
                            "one output (Z)",
                            &h,
                            &mean_e_ma_hn(&t.sweep, OutputKind::Z),
                            Style::LinePoints,
                            1,
                        ),
                        Series::new(
                            "three outputs (X, Y, Z)",
                            &h,
                            &mean_e_ma_hn(&t.sweep, OutputKind::Xyz),
                            Style::LinePoints,
                            0,
                        ),
                        floor_mean_line,
                    ],
                    legend: Legend::UpperRight,
                    integer_x: true,
                },
            ],
            cols: 2,
        },
    )
}

fn proposed_files(o: &mut Files, t: &Thesis) -> Result<()> {
    let cases: Vec<_> = t.proposed.iter().map(|c| (c.case, &c.net, &c.optimal)).collect();
    let depths = [TEST_DEPTHS[0], TEST_DEPTHS[TEST_DEPTHS.len() - 1]];
    per_case_files(
        o,
        PerCase {
            stem: "fig4_16_19_proposed",
            column: "network_pct",
            title: "The proposed net in cases I-IV (thesis Figs. 4.16-4.19)",
            first_fig: 16,
            method: ("proposed 4-5-3 net", 0),
            log_y: false,
            extra: vec![Series::new(
                format!("thesis' bound, {NET_BOUND_PCT} %"),
                &depths,
                &[NET_BOUND_PCT, NET_BOUND_PCT],
                Style::Dashed,
                1,
            )],
        },
        &cases,
    )
}

fn fewer_files(o: &mut Files, t: &Thesis) -> Result<()> {
    let full = &t.proposed[(GENERAL_CASE - 1) as usize];
    let mut rows = Vec::new();
    for f in &t.fewer {
        for (k, z) in f.net.z.iter().enumerate() {
            rows.push(vec![
                join(&f.depths, " "),
                f.points.to_string(),
                num(*z),
                num(f.net.pct[k]),
                num(f.bp.pct[k]),
            ]);
        }
    }
    o.csv(
        "fig4_20_22_fewer_depths.csv",
        "training_depths_cm,training_points,z_cm,network_lm_pct,network_bp_pct",
        &rows,
    )?;
    let panel = |bp: bool| {
        let mut series: Vec<Series> = t
            .fewer
            .iter()
            .enumerate()
            .map(|(k, f)| {
                let c = if bp { &f.bp } else { &f.net };
                Series::new(
                    format!("trained at {} cm (Fig. 4.{})", join(&f.depths, ", "), 20 + k),
                    &c.z,
                    &c.pct,
                    Style::LinePoints,
                    [1, 3, 2][k % 3],
                )
            })
            .collect();
        series.push(Series::new(
            "proposed net, all 6 depths (Fig. 4.19)",
            &full.net.z,
            &full.net.pct,
            Style::LinePoints,
            0,
        ));
        series.push(floor_series(&full.optimal));
        Panel {
            title: if bp {
                "4-5-3 net trained by the thesis' back-propagation".into()
            } else {
                "proposed net (Levenberg-Marquardt)".into()
            },
            x_label: Z_LABEL.into(),
            y_label: EMA_LABEL.into(),
            log_y: true,
            series,
            legend: Legend::UpperRight,
            integer_x: false,
        }
    };
    o.figure(
        "fig4_20_22_fewer_depths",
        &Figure {
            title: "Training on fewer depths (12 board points each), case IV, tested at 65-165 cm (thesis Figs. 4.20-4.22)".into(),
            panels: vec![panel(false), panel(true)],
            cols: 2,
        },
    )
}

fn algo_files(o: &mut Files, t: &Thesis) -> Result<()> {
    o.rows(
        "bp_vs_lm.csv",
        "case,algorithm,train_pct,test_mean_pct,test_worst_depth_pct",
        &t.algos,
        |r| {
            vec![
                r.case.to_string(),
                algo_name(r.algo).to_string(),
                num(r.train_pct),
                num(r.test_mean_pct),
                num(r.test_worst_pct),
            ]
        },
    )?;
    o.rows("bp_vs_lm_timing.csv", "case,algorithm,wall_s", &t.algos, |r| {
        vec![r.case.to_string(), algo_name(r.algo).to_string(), format!("{:.4}", r.wall_s)]
    })?;
    let pick = |a: Algo, f: &dyn Fn(&super::AlgoRow) -> f64| -> (Vec<f64>, Vec<f64>) {
        t.algos.iter().filter(|r| r.algo == a).map(|r| (r.case as f64, f(r))).unzip()
    };
    let (cx, lm_err) = pick(Algo::Lm, &|r| r.test_worst_pct);
    let (_, bp_err) = pick(Algo::Bp, &|r| r.test_worst_pct);
    let (_, lm_t) = pick(Algo::Lm, &|r| r.wall_s);
    let (_, bp_t) = pick(Algo::Bp, &|r| r.wall_s);
    let floors: Vec<f64> = t.proposed.iter().map(|p| p.optimal.worst()).collect();
    let r = t.config.restarts();
    let cycles = t.config.bp().max_cycles;
    o.figure(
        "bp_vs_lm",
        &Figure {
            title: format!(
                "Back-propagation (thesis) vs. Levenberg-Marquardt, 4-5-3 net, {r} restarts each"
            ),
            panels: vec![
                Panel {
                    title: "worst per-depth test e_ma (P1, P2 at 65-165 cm)".into(),
                    x_label: "case (1 = I ... 4 = IV)".into(),
                    y_label: EMA_LABEL.into(),
                    log_y: true,
                    series: vec![
                        Series::new(
                            format!("BP, up to {cycles} cycles"),
                            &cx,
                            &bp_err,
                            Style::LinePoints,
                            1,
                        ),
                        Series::new("LM (default)", &cx, &lm_err, Style::LinePoints, 0),
                        Series::new(
                            "optimal triangulation, true rig (floor)",
                            &cx,
                            &floors,
                            Style::Dashed,
                            FLOOR_COLOR,
                        ),
                    ],
                    legend: Legend::UpperLeft,
                    integer_x: true,
                },
                Panel {
                    title: format!("training wall time, {} threads", t.threads),
                    x_label: "case (1 = I ... 4 = IV)".into(),
                    y_label: "wall time (s)".into(),
                    log_y: true,
                    series: vec![
                        Series::new("BP", &cx, &bp_t, Style::LinePoints, 1),
                        Series::new("LM", &cx, &lm_t, Style::LinePoints, 0),
                    ],
                    legend: Legend::LowerRight,
                    integer_x: true,
                },
            ],
            cols: 2,
        },
    )
}

fn noise_files(o: &mut Files, t: &Thesis) -> Result<()> {
    o.rows(
        "noise.csv",
        "case,sigma_px,repeats,traditional_pct,traditional_no_estimate_pct,network_pct,optimal_pct",
        &t.noise,
        |r| {
            vec![
                r.case.to_string(),
                num(r.sigma),
                r.repeats.to_string(),
                num(r.traditional_pct),
                num(r.traditional_missing_pct),
                num(r.network_pct),
                num(r.optimal_pct),
            ]
        },
    )?;
    let panels = (1..=4u8)
        .map(|case| {
            let rs: Vec<_> = t.noise.iter().filter(|r| r.case == case).collect();
            let s: Vec<f64> = rs.iter().map(|r| r.sigma).collect();
            let col = |f: &dyn Fn(&super::NoiseRow) -> f64| -> Vec<f64> {
                rs.iter().map(|r| f(r)).collect()
            };
            Panel {
                title: format!("case {}", roman(case)),
                x_label: "pixel noise sigma (px)".into(),
                y_label: "mean e_ma (% of true depth)".into(),
                log_y: true,
                series: vec![
                    Series::new(
                        "traditional (points with an estimate), Phi refitted",
                        &s,
                        &col(&|r| r.traditional_pct),
                        Style::LinePoints,
                        1,
                    ),
                    Series::new("proposed net", &s, &col(&|r| r.network_pct), Style::LinePoints, 0),
                    Series::new(
                        "optimal triangulation, true rig (floor)",
                        &s,
                        &col(&|r| r.optimal_pct),
                        Style::Dashed,
                        FLOOR_COLOR,
                    ),
                ],
                legend: Legend::UpperLeft,
                integer_x: false,
            }
        })
        .collect();
    o.figure(
        "noise",
        &Figure {
            title: format!(
                "e_ma vs. Gaussian pixel noise before rounding ({} random test points of the training volume)",
                t.config.volume_points()
            ),
            panels,
            cols: 2,
        },
    )
}
