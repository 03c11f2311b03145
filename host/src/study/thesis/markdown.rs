//! `RESULTS.md`: the prose is `host/templates/results.md` (the sentences that depend on the
//! results: `results_phrases.md`); this module computes every value it names and fills it in.

use super::facts::*;
use super::{e_ma_hn, hidden_counts, mean_e_ma_hn, AlgoRow, DepthCurve, FewerDepths, Thesis};
use super::{FEWER_DEPTHS, GENERAL_CASE, PHI_DEPTHS};
use crate::fmt::{join, mean, pct, pct_value, roman, span, stages};
use crate::sim::sets::training_volume;
use crate::study::engine::number_word;
use crate::study::reported;
use crate::study::template::fill;
use crate::train::{Algo, TrainConfig};
use anyhow::{anyhow, Result};
use hvs_shared::runtime::blob::OutputKind;
use hvs_shared::runtime::traditional::Calibration;
use hvs_shared::sim::camera::Rig;
use hvs_shared::sim::presets::{
    self, LABELS, TEST_DEPTHS, TEST_POINTS_XY, TRAIN_BOARD_X, TRAIN_BOARD_Y, TRAIN_DEPTHS,
};

/// The prose of `RESULTS.md`.
pub const TEMPLATE: &str = include_str!("../../../templates/results.md");
/// The sentences of `RESULTS.md` that depend on the results, one `name: text` a line.
const PHRASES: &str = include_str!("../../../templates/results_phrases.md");

/// The posture study's page in the thesis' directory (`hvs experiment posture`'s default).
pub const POSTURE_REPORT: &str = "posture/POSTURE.md";

/// Points of one training board.
const N_BOARD: usize = TRAIN_BOARD_X.len() * TRAIN_BOARD_Y.len();

/// Page values, `(placeholder, text)`.
type Values = Vec<(&'static str, String)>;

/// Phrase `name` of [`PHRASES`], its placeholders filled from those of `values` it names.
fn phrase(name: &str, values: &[(&str, String)]) -> Result<String> {
    let text = PHRASES
        .lines()
        .find_map(|l| l.strip_prefix(name)?.strip_prefix(": "))
        .ok_or_else(|| anyhow!("results_phrases.md has no phrase {name}"))?;
    let used: Vec<_> =
        values.iter().filter(|(k, _)| text.contains(&format!("{{{k}}}"))).cloned().collect();
    fill(&format!("results_phrases.md: {name}"), text, &used)
}

/// The thesis' bound on the net's worst depth as it prints it: `4 %`.
fn bound() -> String {
    format!("{} %", reported::NET_BOUND_PCT)
}

fn row<S: ToString>(cells: impl IntoIterator<Item = S>) -> String {
    format!("| {} |", join(cells.into_iter().map(|c| c.to_string()), " | "))
}

/// The proposed net's shape, `4-5-3`: the default `hvs train` net.
fn net_shape() -> String {
    let tc = TrainConfig::default();
    format!("4-{}-{}", tc.hidden, tc.outputs.len())
}

/// The page's placeholder values for a run of `total_s` s; `posture`: link the posture report.
pub fn results_values(t: &Thesis, total_s: f64, posture: bool) -> Result<Values> {
    let cfg = &t.config;
    let case1 = presets::CASE_1;
    let quick = if cfg.quick { " --quick" } else { "" };
    let link = [("posture_report", POSTURE_REPORT.to_string())];
    let mut v: Values = vec![
        ("command", format!("hvs experiment thesis --seed {}{quick}", cfg.seed)),
        ("total_s", format!("{total_s:.1}")),
        ("threads", t.threads.to_string()),
        ("board_points", N_BOARD.to_string()),
        ("board_x", join(TRAIN_BOARD_X, ", ")),
        ("board_y", join(TRAIN_BOARD_Y, ", ")),
        ("board_x_count", number_word(TRAIN_BOARD_X.len())),
        ("train_grid", depth_grid(&TRAIN_DEPTHS)),
        ("train_points", (N_BOARD * TRAIN_DEPTHS.len()).to_string()),
        ("test_xy_count", number_word(TEST_POINTS_XY.len())),
        ("test_x", signed_list(TEST_POINTS_XY.iter().map(|p| p[0]))),
        ("test_grid", depth_grid(&TEST_DEPTHS)),
        ("test_points", (TEST_POINTS_XY.len() * TEST_DEPTHS.len()).to_string()),
        ("phi_grid", depth_grid(&PHI_DEPTHS)),
        ("net_shape", net_shape()),
        ("restarts", cfg.restarts().to_string()),
        ("width", case1.width.to_string()),
        ("height", case1.height.to_string()),
        ("preset_phi", format!("{:.0}", case1.phi_u_left)),
        ("thesis_phi", format!("{:.0}", reported::PHI_L_MEAN)),
        ("stage_times", stages(&t.stage_s)),
        ("bound", bound()),
        ("builtin_phi", Calibration::BUILT_IN.phi.to_string()),
        ("posture_link", if posture { phrase("posture_link", &link)? + "\n\n" } else { "".into() }),
    ];
    for section in [phi_values, traditional_values, net_case4_values, sweep_values] {
        v.extend(section(t)?);
    }
    for section in [proposed_values, fewer_values, algo_values, noise_values] {
        v.extend(section(t)?);
    }
    Ok(v)
}

fn phi_values(t: &Thesis) -> Result<Values> {
    let which = [(1u8, "Phi_L"), (1, "Phi_R"), (2, "Phi_L"), (2, "Phi_R")];
    let [l1, r1, l2, r2] = which.map(|(case, w)| phi_stats(&t.phi, case, w == "Phi_L"));
    let table = which.iter().zip([l1, r1, l2, r2]).map(|(&(case, w), s)| {
        let (mean, truth, bias, dev, sd) = (s.mean, s.truth, s.bias_pct(), s.max_dev_pct, s.sd_pct);
        let fixed = format!("{mean:.3} | {truth:.3} | {bias:+.3} % | {dev:.3} % | {sd:.3} %");
        row([roman(case), w, fixed.as_str()])
    });
    // The far boards of the Phi experiment: the last two depths.
    let far = &PHI_DEPTHS[PHI_DEPTHS.len() - 2..];
    let d = presets::CASE_1.half_baseline;
    let disp = |rig: &Rig, centre: f64| {
        mean(&far.iter().filter_map(|&z| board_disparity_px(rig, centre, z)).collect::<Vec<_>>())
    };
    let far_disp = disp(&presets::CASE_1, d);
    let ratio = disp(&presets::CASE_2, -d) / far_disp;
    Ok(vec![
        ("th_phi_l", reported::PHI_L_MEAN.to_string()),
        ("th_phi_var", reported::PHI_L_VARIATION_PCT.to_string()),
        ("th_phi_lr", reported::PHI_LR_PCT.to_string()),
        ("case1_phi_l", format!("{:.3}", l1.mean)),
        ("case1_phi_l_dev", format!("{:.3}", l1.max_dev_pct)),
        ("case1_phi_l_sd", format!("{:.3}", l1.sd_pct)),
        ("case1_phi_l_dev2", format!("{:.2}", l1.max_dev_pct)),
        ("case1_phi_l_sd2", format!("{:.2}", l1.sd_pct)),
        ("case1_lr_apart", format!("{:.3}", apart_pct(l1.mean, r1.mean))),
        ("case1_bias", format!("{:.2}", l1.bias_pct().abs().max(r1.bias_pct().abs()))),
        ("case2_phi_l", format!("{:.1}", l2.truth)),
        ("case2_phi_r", format!("{:.1}", r2.truth)),
        ("case2_phi_r_dev", format!("{:.2}", r2.max_dev_pct)),
        ("phi_rows", join(table, "\n")),
        ("far_depths", join(far, "-")),
        ("far_disparity", format!("{far_disp:.0}")),
        ("half_px_pct", format!("{:.1}", 50.0 / far_disp)),
        ("case2_disparity_ratio", format!("{ratio:.1}")),
    ])
}

fn traditional_values(t: &Thesis) -> Result<Values> {
    let (mut glance, mut table, mut within) = (Vec::new(), Vec::new(), Vec::new());
    for c in &t.traditional {
        let k = usize::from(c.case - 1);
        let th = reported::traditional_range(c.case).unwrap_or_default();
        let ours = format!("{} .. {}", pct(c.traditional.best()), pct(c.traditional.worst()));
        let case = roman(c.case);
        let fig = format!("4.{} traditional, case {case}", 8 + k);
        glance.push(row([fig, th.clone(), ours.clone()]));
        let rig = LABELS[k].split(": ").nth(1).unwrap_or("");
        table.push(row([format!("{case} ({rig})"), th, ours, pct(c.optimal.worst())]));
        if matches_thesis_traditional(c.case, c.traditional.best(), c.traditional.worst()) {
            within.push(case);
        }
    }
    let (k, n) = (within.len(), t.traditional.len());
    let count = if k == n { "all four".to_string() } else { format!("{k} of {n}") };
    let floor = t.traditional.iter().map(|c| c.optimal.worst()).fold(0.0, f64::max);
    Ok(vec![
        ("glance_traditional_rows", join(glance, "\n")),
        ("traditional_rows", join(table, "\n")),
        ("trad_within", if within.is_empty() { "none".to_string() } else { within.join(", ") }),
        ("trad_within_count", count),
        ("trad_floor_worst", pct(floor)),
    ])
}

fn net_case4_values(t: &Thesis) -> Result<Values> {
    let p = &t.proposed[usize::from(GENERAL_CASE - 1)];
    let rig = presets::case(GENERAL_CASE).unwrap_or(presets::CASE_4);
    let table = (p.net.z.iter().enumerate())
        .map(|(k, z)| row([z.to_string(), pct(p.net.pct[k]), pct(p.optimal.pct[k])]));
    let wz = worst_depth(&p.optimal);
    // Test points with the same pixels at two neighbouring depths, one of them the floor's worst.
    let at = |xy| identical_pixel_depths(&rig, xy, &TEST_DEPTHS);
    let twins: Vec<String> = ((1..).zip(TEST_POINTS_XY))
        .flat_map(|(k, xy)| at(xy).into_iter().map(move |d| (k, d)))
        .filter(|(_, (a, b))| *a == wz || *b == wz)
        .map(|(k, (a, b))| format!("P{k} has identical pixels at {a} and {b} cm"))
        .collect();
    let twins_values = [("case", roman(GENERAL_CASE).into()), ("twins", twins.join(", and "))];
    let twins_sentence =
        phrase(if twins.is_empty() { "twins_none" } else { "twins_some" }, &twins_values)?;
    let note = twins.join("; ").replace(" has identical pixels at", "'s identical pixels at");
    let twins_note = if twins.is_empty() { note } else { format!(" ({note})") };
    let above = p.net.pct.iter().zip(&p.optimal.pct).map(|(a, b)| a - b).fold(0.0, f64::max);
    let [th_lo, th_hi] = reported::NET_CASE4_PCT;
    // Fig. 4.13: the sweep's nets with the proposed shape.
    let ten: Vec<_> =
        t.sweep.iter().filter(|r| r.hidden == 5 && r.outputs == OutputKind::Xyz).collect();
    let (wlo, whi) = span(ten.iter().map(|r| r.test_worst_pct));
    let (mlo, mhi) = span(ten.iter().map(|r| r.test_mean_pct));
    let below = ten.iter().filter(|r| r.test_worst_pct < reported::NET_BOUND_PCT).count();
    Ok(vec![
        ("net_case4_rows", join(table, "\n")),
        ("th_net_case4", format!("{th_lo} .. {th_hi} %")),
        ("th_net_case4_worst", th_hi.to_string()),
        ("net_case4_best", pct(p.net.best())),
        ("net_case4_worst", pct(p.net.worst())),
        ("net_case4_train", pct(p.train_pct)),
        ("floor_case4_best", pct(p.optimal.best())),
        ("floor_case4_worst", pct(p.optimal.worst())),
        ("floor_case4_worst_z", wz.to_string()),
        ("net_case4_above", pct_value(above)),
        ("floor_case4_twins_note", twins_note),
        ("twins_sentence", twins_sentence),
        ("ten_worst_lo", pct(wlo)),
        ("ten_worst_hi", pct(whi)),
        ("ten_mean_lo", pct(mlo)),
        ("ten_mean_hi", pct(mhi)),
        ("ten_count", ten.len().to_string()),
        ("ten_below_bound", below.to_string()),
    ])
}

fn sweep_values(t: &Thesis) -> Result<Values> {
    let hs = hidden_counts(&t.sweep);
    let [z1, x3] = [OutputKind::Z, OutputKind::Xyz].map(|o| e_ma_hn(&t.sweep, o));
    let [zm, xm] = [OutputKind::Z, OutputKind::Xyz].map(|o| mean_e_ma_hn(&t.sweep, o));
    let table = (hs.iter().enumerate())
        .map(|(k, h)| row([h.to_string(), pct(z1[k]), pct(x3[k]), pct(zm[k]), pct(xm[k])]));
    let wins = |one: &[f64], three: &[f64]| one.iter().zip(three).filter(|(a, b)| b < a).count();
    let verdict = match (mean(&x3) < mean(&z1), mean(&xm) < mean(&zm)) {
        (true, true) => "hn_both",
        (true, false) => "hn_worst_only",
        (false, true) => "hn_mean_only",
        (false, false) => "hn_neither",
    };
    let best = |e: &[f64]| hs.get(argmin(e)).copied().unwrap_or(0).to_string();
    Ok(vec![
        ("nets", t.config.nets().to_string()),
        ("hidden_rows", join(table, "\n")),
        ("hidden_counts", join(&hs, ", ")),
        ("hn_one", pct(mean(&z1))),
        ("hn_three", pct(mean(&x3))),
        ("hn_mean_one", pct(mean(&zm))),
        ("hn_mean_three", pct(mean(&xm))),
        ("hn_wins", wins(&z1, &x3).to_string()),
        ("hn_mean_wins", wins(&zm, &xm).to_string()),
        ("hn_n", hs.len().to_string()),
        ("best_h", best(&x3)),
        ("best_h_mean", best(&xm)),
        ("hn_verdict", phrase(verdict, &[])?),
    ])
}

fn proposed_values(t: &Thesis) -> Result<Values> {
    let limit = reported::NET_BOUND_PCT;
    let table = t.proposed.iter().map(|p| {
        let errors = [p.train_pct, p.net.mean, p.net.worst(), p.optimal.worst()].map(pct);
        row([roman(p.case).to_string()].into_iter().chain(errors).chain([format!("< {}", bound())]))
    });
    let over: Vec<&str> =
        t.proposed.iter().filter(|p| p.net.worst() >= limit).map(|p| roman(p.case)).collect();
    let near: Vec<String> = (t.proposed.iter().filter(|p| p.optimal.worst() >= 0.9 * limit))
        .map(|p| format!("{} ({})", roman(p.case), pct(p.optimal.worst())))
        .collect();
    let n = t.proposed.len();
    let values = [
        ("bound", bound()),
        ("kept", (n - over.len()).to_string()),
        ("cases", n.to_string()),
        ("over", over.join(", ")),
        ("test_points", (TEST_POINTS_XY.len() * TEST_DEPTHS.len()).to_string()),
        ("near", near.join(", ")),
    ];
    let bound_sentence = phrase(if over.is_empty() { "bound_all" } else { "bound_some" }, &values)?;
    let floor_sentence =
        phrase(if near.is_empty() { "floor_clear" } else { "floor_near" }, &values)?;
    let ratios = (t.noise.iter().filter(|r| r.sigma == 0.0))
        .map(|r| format!("{:.2}", r.network_pct / r.optimal_pct));
    let glance = t.proposed.iter().map(|p| format!("{} {}", roman(p.case), pct(p.net.worst())));
    Ok(vec![
        ("proposed_rows", join(table, "\n")),
        ("proposed_worst", join(glance, ", ")),
        ("proposed_bound_sentence", bound_sentence),
        ("proposed_floor_sentence", floor_sentence),
        ("proposed_mean_max", pct(t.proposed.iter().map(|p| p.net.mean).fold(0.0, f64::max))),
        ("volume_points", t.config.volume_points().to_string()),
        ("volume_ratios", join(ratios, ", ")),
    ])
}

fn fewer_values(t: &Thesis) -> Result<Values> {
    let p4 = &t.proposed[usize::from(GENERAL_CASE - 1)];
    let both = |c: &DepthCurve| format!("{} / {}", pct(c.mean), pct(c.worst()));
    let fewer_row = |f: &FewerDepths| {
        let th = reported::fewer_depths(f.depths.len());
        row([join(&f.depths, ", "), f.points.to_string(), th, both(&f.net), both(&f.bp)])
    };
    let mut table: Vec<String> = t.fewer.iter().map(fewer_row).collect();
    let bp4 = algo_row(t, GENERAL_CASE, Algo::Bp).map_or("-".to_string(), |r| {
        format!("{} / {}", pct(r.test_mean_pct), pct(r.test_worst_pct))
    });
    let (first, last) = (TRAIN_DEPTHS[0], TRAIN_DEPTHS[TRAIN_DEPTHS.len() - 1]);
    let (step, count) = (TRAIN_DEPTHS[1] - first, number_word(TRAIN_DEPTHS.len()));
    let all = format!("{first}-{last} step {step} (all {count})");
    let points = (N_BOARD * TRAIN_DEPTHS.len()).to_string();
    table.push(row([all, points, format!("< {}", bound()), both(&p4.net), bp4]));
    let (two, four) = (&t.fewer[0], &t.fewer[FEWER_DEPTHS.len() - 1]);
    let th = reported::TWO_DEPTHS_MEAN_PCT;
    let values = [
        ("th", th.to_string()),
        ("lm", pct(two.net.mean)),
        ("bp", pct(two.bp.mean)),
        ("net_shape", net_shape()),
        ("from", two.depths[0].to_string()),
        ("to", two.depths[two.depths.len() - 1].to_string()),
    ];
    let why = match (two.net.mean < th / 2.0, two.bp.mean < th / 2.0) {
        (true, true) => "fewer_both",
        (true, false) => "fewer_lm",
        _ => "fewer_neither",
    };
    let means =
        t.fewer.iter().map(|f| format!("{} depths: mean {}", f.depths.len(), pct(f.net.mean)));
    Ok(vec![
        ("fewer_rows", join(table, "\n")),
        ("fewer_two_mean", pct(two.net.mean)),
        ("fewer_four_mean", pct(four.net.mean)),
        ("fewer_why", phrase(why, &values)?),
        ("th_two_depths", reported::fewer_depths(2)),
        ("th_four_depths", reported::fewer_depths(4)),
        ("fewer_means", join(means, "; ")),
    ])
}

fn algo_row(t: &Thesis, case: u8, algo: Algo) -> Option<&AlgoRow> {
    t.algos.iter().find(|r| r.case == case && r.algo == algo)
}

fn algo_values(t: &Thesis) -> Result<Values> {
    let bp = t.config.bp();
    let three = |r: &AlgoRow| [r.train_pct, r.test_mean_pct, r.test_worst_pct].map(pct).join(" / ");
    let table = (1..=4u8).filter_map(|case| {
        let (b, l) = (algo_row(t, case, Algo::Bp)?, algo_row(t, case, Algo::Lm)?);
        let floor = pct(t.proposed[usize::from(case - 1)].optimal.worst());
        let times = [format!("{:.2} s", b.wall_s), format!("{:.3} s", l.wall_s)];
        Some(row([roman(case).to_string(), three(b), three(l), floor].into_iter().chain(times)))
    });
    let [(bt, be), (lt, le)] = [Algo::Bp, Algo::Lm].map(|a| {
        let rs = t.algos.iter().filter(|r| r.algo == a);
        (rs.clone().map(|r| r.wall_s).sum::<f64>(), rs.map(|r| r.test_worst_pct).sum::<f64>() / 4.0)
    });
    let verdict = match ((be - le).abs() < 0.25 * le, be > le) {
        (true, _) => "algo_close",
        (_, true) => "algo_lm",
        _ => "algo_bp",
    };
    Ok(vec![
        ("bp_rate", bp.learning_rate.to_string()),
        ("bp_e_max", bp.e_max.to_string()),
        ("bp_cycles", bp.max_cycles.to_string()),
        ("algo_rows", join(table, "\n")),
        ("lm_worst_mean", pct(le)),
        ("bp_worst_mean", pct(be)),
        ("floor_worst_mean", pct(t.proposed.iter().map(|p| p.optimal.worst()).sum::<f64>() / 4.0)),
        ("lm_time", format!("{lt:.3}")),
        ("bp_time", format!("{bt:.2}")),
        ("speedup", format!("{:.0}", bt / lt.max(1e-9))),
        ("algo_verdict", phrase(verdict, &[])?),
    ])
}

fn noise_values(t: &Thesis) -> Result<Values> {
    let levels = t.config.noise_levels();
    let shown = [levels[0], levels[levels.len() / 2], levels[levels.len() - 1]];
    let table = t.noise.iter().filter(|r| shown.contains(&r.sigma)).map(|r| {
        let [trad, net, floor] = [r.traditional_pct, r.network_pct, r.optimal_pct].map(pct);
        let (sigma, missing) = (format!("{:.1}", r.sigma), r.traditional_missing_pct);
        let (missing, ratio) = (format!("{missing:.1} %"), r.network_pct / r.optimal_pct);
        row([roman(r.case).to_string(), sigma, trad, missing, net, floor, format!("{ratio:.2}")])
    });
    let (lo, hi) = span(t.noise.iter().map(|r| r.network_pct / r.optimal_pct));
    let top = levels[levels.len() - 1];
    let case1 = t.noise.iter().filter(|r| r.case == 1);
    let floor = |s: f64| case1.clone().find(|r| r.sigma == s).map_or(f64::NAN, |r| r.optimal_pct);
    let grow = floor(top) / floor(0.0);
    let trad = (1..=4u8).map(|case| {
        let (a, b) = span(t.noise.iter().filter(|r| r.case == case).map(|r| r.traditional_pct));
        format!("{} {}-{}", roman(case), pct_value(a), pct(b))
    });
    let (lo_v, hi_v) = training_volume();
    let range = |k: usize| format!("{}..{}", lo_v[k], hi_v[k]);
    let volume_box = format!("X {}, Y {}, Z {} cm", range(0), range(1), range(2));
    Ok(vec![
        ("noise_repeats", t.config.noise_repeats().to_string()),
        ("volume_box", volume_box),
        ("noise_rows", join(table, "\n")),
        ("noise_ratio_lo", format!("{lo:.2}")),
        ("noise_ratio_hi", format!("{hi:.2}")),
        ("noise_floor_growth", format!("{grow:.1}")),
        ("noise_top", top.to_string()),
        ("noise_traditional", join(trad, ", ")),
    ])
}
