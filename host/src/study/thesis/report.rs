//! Files of `hvs experiment thesis`: one CSV (numbers with 6 decimals, so equal results give
//! equal bytes) and one plot (SVG and PNG) per experiment, and `RESULTS.md`.

use super::markdown::{results_values, POSTURE_REPORT, TEMPLATE};
use super::{e_ma_hn, hidden_counts, mean_e_ma_hn, AlgoRow, DepthCurve, FewerDepths};
use super::{NetRow, NoiseRow, Thesis, GENERAL_CASE, PHI_DEPTHS};
use crate::fmt::{join, num, roman};
use crate::study::engine::{Files, Report};
use crate::study::plot::{Figure, Legend, Panel, Series, Style, FLOOR_COLOR};
use crate::study::reported::NET_BOUND_PCT;
use crate::train::Algo;
use anyhow::Result;
use hvs_shared::runtime::blob::OutputKind;
use hvs_shared::sim::presets::TEST_DEPTHS;

/// The file stems, each as `.csv`, `.svg`, `.png` (besides `bp_vs_lm_timing.csv`, `RESULTS.md`).
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

impl Report for Thesis {
    const PAGE: &'static str = "RESULTS.md";
    /// Writes every CSV, plot and `RESULTS.md`; `total_s` is the run's wall time.
    fn write(&self, o: &mut Files, total_s: f64) -> Result<()> {
        phi_files(o, self)?;
        per_case_files(o, self, false)?;
        net_case4_files(o, self)?;
        sweep_files(o, self)?;
        per_case_files(o, self, true)?;
        fewer_files(o, self)?;
        algo_files(o, self)?;
        noise_files(o, self)?;
        let values = results_values(self, total_s, o.dir().join(POSTURE_REPORT).is_file())?;
        o.page(Self::PAGE, "host/templates/results.md", TEMPLATE, &values)
    }
}

const EMA: &str = "e_ma (% of true depth)";
/// A panel's x label, y label, and whether its x axis shows whole numbers only.
type Axes = (&'static str, &'static str, bool);
const DEPTH: Axes = ("true depth Z (cm)", EMA, false);
const CASES: Axes = ("case (1 = I ... 4 = IV)", EMA, true);
const HIDDEN: Axes = ("hidden neurons H_n", EMA, true);

fn panel(title: impl Into<String>, a: Axes, log_y: bool, legend: Legend, s: Vec<Series>) -> Panel {
    Panel { log_y, legend, integer_x: a.2, ..Panel::new(title, a.0, a.1, s) }
}

fn grid(title: impl Into<String>, panels: Vec<Panel>) -> Figure {
    Figure { title: title.into(), panels, cols: 2 }
}

fn line(name: impl Into<String>, x: &[f64], y: &[f64], color: usize) -> Series {
    Series::new(name, x, y, Style::LinePoints, color)
}

fn floor(x: &[f64], y: &[f64]) -> Series {
    Series::new("optimal triangulation, true rig (floor)", x, y, Style::Dashed, FLOOR_COLOR)
}

const WORST_FLOOR: &str = "floor: worst per-depth e_ma of optimal triangulation";
const MEAN_FLOOR: &str = "floor: mean e_ma of optimal triangulation";

/// CSV rows, one per depth of `curves`: the cells `lead`, the depth, each curve's e_ma.
fn depth_rows(lead: &[String], curves: &[&DepthCurve]) -> Vec<Vec<String>> {
    let cells = |k: usize| curves.iter().map(move |c| num(c.pct[k]));
    let row =
        |(k, z): (usize, &f64)| lead.iter().cloned().chain([num(*z)]).chain(cells(k)).collect();
    curves[0].z.iter().enumerate().map(row).collect()
}

fn phi_files(o: &mut Files, t: &Thesis) -> Result<()> {
    let head = "case,z_cm,phi_l_px,phi_r_px,true_phi_l_px,true_phi_r_px";
    o.rows("fig4_03_04_phi.csv", head, &t.phi, |r| {
        let v = [r.z, r.phi_l, r.phi_r, r.true_l, r.true_r].map(num);
        [r.case.to_string()].into_iter().chain(v).collect()
    })?;
    let case1: Vec<_> = t.phi.iter().filter(|r| r.case == 1).collect();
    let z: Vec<f64> = case1.iter().map(|r| r.z).collect();
    let ends = [PHI_DEPTHS[0], PHI_DEPTHS[PHI_DEPTHS.len() - 1]];
    let phi_panel = |fig: usize, which: &str, est: Vec<f64>, truth: f64, color: usize| {
        let est = line(format!("{which}, 12 symmetric points, rounded pixels"), &z, &est, color);
        let truth = Series::level(format!("true {which} of the rig"), ends, truth, FLOOR_COLOR);
        let title = format!("Fig. 4.{fig}: {which} by eq. 4.1-3, case I");
        let axes = ("board depth Z (cm)", "", false);
        let p = panel(title, axes, false, Legend::LowerRight, vec![est, truth]);
        Panel { y_label: format!("{which} = k_u f (px)"), ..p }
    };
    let panels = vec![
        phi_panel(3, "Phi_L", case1.iter().map(|r| r.phi_l).collect(), case1[0].true_l, 0),
        phi_panel(4, "Phi_R", case1.iter().map(|r| r.phi_r).collect(), case1[0].true_r, 1),
    ];
    let title = "Phi estimated at Z = 45-105 cm (thesis Figs. 4.3, 4.4)";
    o.figure("fig4_03_04_phi", &grid(title, panels))
}

/// Figs. 4.8-4.11 (traditional) or, with `net`, 4.16-4.19 (the net): CSV and a panel per case.
fn per_case_files(o: &mut Files, t: &Thesis, net: bool) -> Result<()> {
    let (cases, stem, column, first_fig, method, color, title) = if net {
        let cases: Vec<_> = t.proposed.iter().map(|c| (c.case, &c.net, &c.optimal)).collect();
        let title = "The proposed net in cases I-IV (thesis Figs. 4.16-4.19)";
        (cases, "fig4_16_19_proposed", "network_pct", 16, "proposed 4-5-3 net", 0, title)
    } else {
        let cases = t.traditional.iter().map(|c| (c.case, &c.traditional, &c.optimal)).collect();
        let method = "traditional, eq. 3.1-17, one Phi";
        let title = "Traditional method vs. depth, cases I-IV (thesis Figs. 4.8-4.11)";
        (cases, "fig4_08_11_traditional", "traditional_pct", 8, method, 1, title)
    };
    let rows = cases.iter().flat_map(|(case, c, f)| depth_rows(&[case.to_string()], &[c, f]));
    let head = format!("case,z_cm,{column},optimal_pct");
    o.csv(&format!("{stem}.csv"), &head, &rows.collect::<Vec<_>>())?;
    let ends = [TEST_DEPTHS[0], TEST_DEPTHS[TEST_DEPTHS.len() - 1]];
    let bound = Series::level(format!("thesis' bound, {NET_BOUND_PCT} %"), ends, NET_BOUND_PCT, 1);
    let panels = cases.iter().map(|(case, c, f)| {
        let mut series = vec![line(method, &c.z, &c.pct, color), floor(&f.z, &f.pct)];
        series.extend(net.then(|| bound.clone()));
        let title = format!("Fig. 4.{}: case {}", first_fig + usize::from(case - 1), roman(*case));
        panel(title, DEPTH, !net, Legend::UpperLeft, series)
    });
    o.figure(stem, &grid(title, panels.collect()))
}

fn net_case4_files(o: &mut Files, t: &Thesis) -> Result<()> {
    let p = &t.proposed[usize::from(GENERAL_CASE - 1)];
    let rows = depth_rows(&[], &[&p.net, &p.optimal]);
    o.csv("fig4_12_net_case4.csv", "z_cm,network_pct,optimal_pct", &rows)?;
    let title =
        format!("proposed net ({} restarts, LM), trained on 72 board points", t.config.restarts());
    let series =
        vec![line("4-5-3 net", &p.net.z, &p.net.pct, 0), floor(&p.optimal.z, &p.optimal.pct)];
    let fig = "Per-depth e_ma of the 4-5-3 net, case IV (thesis Fig. 4.12)";
    let panel_12 = panel(title, DEPTH, false, Legend::UpperLeft, series);
    o.figure("fig4_12_net_case4", &Figure::single(fig, panel_12))?;
    // Fig. 4.13: the sweep's nets with 5 hidden neurons and three outputs.
    let ten: Vec<_> =
        t.sweep.iter().filter(|r| r.hidden == 5 && r.outputs == OutputKind::Xyz).collect();
    let head = "net,seed,train_pct,test_mean_pct,test_worst_depth_pct";
    o.rows("fig4_13_ten_nets.csv", head, &ten, |r| {
        let v = [r.train_pct, r.test_mean_pct, r.test_worst_pct].map(num);
        [(r.index + 1).to_string(), r.seed.to_string()].into_iter().chain(v).collect()
    })?;
    let x: Vec<f64> = ten.iter().map(|r| (r.index + 1) as f64).collect();
    let points = |name: &str, f: fn(&NetRow) -> f64, color| {
        Series::new(name, &x, &ten.iter().map(|r| f(r)).collect::<Vec<_>>(), Style::Points, color)
    };
    let ends = [0.5, x.len() as f64 + 0.5];
    let series = vec![
        points("worst per-depth test e_ma (the net's error)", |r| r.test_worst_pct, 0),
        points("mean test e_ma", |r| r.test_mean_pct, 2),
        points("training e_ma", |r| r.train_pct, 3),
        Series::level(WORST_FLOOR, ends, p.optimal.worst(), FLOOR_COLOR),
        Series::level(MEAN_FLOOR, ends, p.optimal.mean, 6),
    ];
    let title = "each net: one training from one seeded random start";
    let panel_13 = panel(title, ("net number", EMA, true), false, Legend::UpperLeft, series);
    let fig = "Ten 4-5-3 nets, case IV (thesis Fig. 4.13)";
    o.figure("fig4_13_ten_nets", &Figure::single(fig, panel_13))
}

fn sweep_files(o: &mut Files, t: &Thesis) -> Result<()> {
    let head = "outputs,hidden,net,seed,train_pct,test_mean_pct,test_worst_depth_pct";
    o.rows("fig4_14_15_hidden.csv", head, &t.sweep, |r| {
        let outputs = if r.outputs == OutputKind::Z { "z" } else { "xyz" };
        let v = [r.train_pct, r.test_mean_pct, r.test_worst_pct].map(num);
        let ids = [outputs.to_string(), r.hidden.to_string(), (r.index + 1).to_string()];
        ids.into_iter().chain([r.seed.to_string()]).chain(v).collect()
    })?;
    let h: Vec<f64> = hidden_counts(&t.sweep).iter().map(|&h| h as f64).collect();
    let opt = &t.proposed[usize::from(GENERAL_CASE - 1)].optimal;
    let of_nets = |title: &str, f: fn(&[NetRow], OutputKind) -> Vec<f64>, figs: [&str; 2], fl| {
        let [z, xyz] = [OutputKind::Z, OutputKind::Xyz].map(|o| f(&t.sweep, o));
        let one = line(format!("one output (Z){}", figs[0]), &h, &z, 1);
        let three = line(format!("three outputs (X, Y, Z){}", figs[1]), &h, &xyz, 0);
        panel(title, HIDDEN, false, Legend::UpperRight, vec![one, three, fl])
    };
    let fl = |name, y| Series::level(name, [1.0, 10.0], y, FLOOR_COLOR);
    let title = "e_ma_Hn: mean over the nets of their worst per-depth e_ma";
    let figs = [", Fig. 4.14", ", Fig. 4.15"];
    let worst = of_nets(title, e_ma_hn, figs, fl(WORST_FLOOR, opt.worst()));
    let title = "mean over the nets of their mean test e_ma (all 22 points)";
    let mean = of_nets(title, mean_e_ma_hn, ["", ""], fl(MEAN_FLOOR, opt.mean));
    let title = format!(
        "e_ma vs. hidden neurons, one output (Z) vs. three (X, Y, Z), case IV, {} nets each (thesis Figs. 4.14, 4.15)",
        t.config.nets()
    );
    o.figure("fig4_14_15_hidden", &grid(title, vec![worst, mean]))
}

fn fewer_files(o: &mut Files, t: &Thesis) -> Result<()> {
    let full = &t.proposed[usize::from(GENERAL_CASE - 1)];
    let lead = |f: &FewerDepths| [join(&f.depths, " "), f.points.to_string()];
    let rows = t.fewer.iter().flat_map(|f| depth_rows(&lead(f), &[&f.net, &f.bp]));
    let head = "training_depths_cm,training_points,z_cm,network_lm_pct,network_bp_pct";
    o.csv("fig4_20_22_fewer_depths.csv", head, &rows.collect::<Vec<_>>())?;
    let fewer_panel = |title: &str, bp: bool| {
        let mut series: Vec<Series> = (t.fewer.iter().enumerate())
            .map(|(k, f)| {
                let c = if bp { &f.bp } else { &f.net };
                let name = format!("trained at {} cm (Fig. 4.{})", join(&f.depths, ", "), 20 + k);
                line(name, &c.z, &c.pct, [1, 3, 2][k % 3])
            })
            .collect();
        series.push(line("proposed net, all 6 depths (Fig. 4.19)", &full.net.z, &full.net.pct, 0));
        series.push(floor(&full.optimal.z, &full.optimal.pct));
        panel(title, DEPTH, true, Legend::UpperRight, series)
    };
    let panels = vec![
        fewer_panel("proposed net (Levenberg-Marquardt)", false),
        fewer_panel("4-5-3 net trained by the thesis' back-propagation", true),
    ];
    let title = "Training on fewer depths (12 board points each), case IV, tested at 65-165 cm (thesis Figs. 4.20-4.22)";
    o.figure("fig4_20_22_fewer_depths", &grid(title, panels))
}

fn algo_files(o: &mut Files, t: &Thesis) -> Result<()> {
    let name = |a: Algo| format!("{a:?}").to_lowercase();
    let head = "case,algorithm,train_pct,test_mean_pct,test_worst_depth_pct";
    o.rows("bp_vs_lm.csv", head, &t.algos, |r| {
        let v = [r.train_pct, r.test_mean_pct, r.test_worst_pct].map(num);
        [r.case.to_string(), name(r.algo)].into_iter().chain(v).collect()
    })?;
    o.rows("bp_vs_lm_timing.csv", "case,algorithm,wall_s", &t.algos, |r| {
        vec![r.case.to_string(), name(r.algo), format!("{:.4}", r.wall_s)]
    })?;
    let pick = |a: Algo, f: fn(&AlgoRow) -> f64| -> (Vec<f64>, Vec<f64>) {
        t.algos.iter().filter(|r| r.algo == a).map(|r| (r.case as f64, f(r))).unzip()
    };
    let (cx, lm_err) = pick(Algo::Lm, |r| r.test_worst_pct);
    let floors: Vec<f64> = t.proposed.iter().map(|p| p.optimal.worst()).collect();
    let cycles = t.config.bp().max_cycles;
    let errors = vec![
        line(format!("BP, up to {cycles} cycles"), &cx, &pick(Algo::Bp, |r| r.test_worst_pct).1, 1),
        line("LM (default)", &cx, &lm_err, 0),
        floor(&cx, &floors),
    ];
    let times = vec![
        line("BP", &cx, &pick(Algo::Bp, |r| r.wall_s).1, 1),
        line("LM", &cx, &pick(Algo::Lm, |r| r.wall_s).1, 0),
    ];
    let title = "worst per-depth test e_ma (P1, P2 at 65-165 cm)";
    let errors = panel(title, CASES, true, Legend::UpperLeft, errors);
    let title = format!("training wall time, {} threads", t.threads);
    let times = panel(title, (CASES.0, "wall time (s)", true), true, Legend::LowerRight, times);
    let r = t.config.restarts();
    let title =
        format!("Back-propagation (thesis) vs. Levenberg-Marquardt, 4-5-3 net, {r} restarts each");
    o.figure("bp_vs_lm", &grid(title, vec![errors, times]))
}

fn noise_files(o: &mut Files, t: &Thesis) -> Result<()> {
    let head =
        "case,sigma_px,repeats,traditional_pct,traditional_no_estimate_pct,network_pct,optimal_pct";
    o.rows("noise.csv", head, &t.noise, |r| {
        let v = [r.traditional_pct, r.traditional_missing_pct, r.network_pct, r.optimal_pct];
        let ids = [r.case.to_string(), num(r.sigma), r.repeats.to_string()];
        ids.into_iter().chain(v.map(num)).collect()
    })?;
    let panels = (1..=4u8).map(|case| {
        let rs: Vec<_> = t.noise.iter().filter(|r| r.case == case).collect();
        let col = |f: fn(&NoiseRow) -> f64| rs.iter().map(|r| f(r)).collect::<Vec<f64>>();
        let (s, trad) = (col(|r| r.sigma), col(|r| r.traditional_pct));
        let series = vec![
            line("traditional (points with an estimate), Phi refitted", &s, &trad, 1),
            line("proposed net", &s, &col(|r| r.network_pct), 0),
            floor(&s, &col(|r| r.optimal_pct)),
        ];
        let axes = ("pixel noise sigma (px)", "mean e_ma (% of true depth)", false);
        panel(format!("case {}", roman(case)), axes, true, Legend::UpperLeft, series)
    });
    let title = format!(
        "e_ma vs. Gaussian pixel noise before rounding ({} random test points of the training volume)",
        t.config.volume_points()
    );
    o.figure("noise", &grid(title, panels.collect()))
}
