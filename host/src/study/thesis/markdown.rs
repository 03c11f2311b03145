//! `RESULTS.md`: the prose is `host/templates/results.md`; this module computes every value
//! it names (through [`super::facts`] and [`crate::fmt`]) and fills it in.

use super::facts::{
    apart_pct, argmin, board_disparity_px, depth_grid, identical_pixel_depths,
    matches_thesis_traditional, phi_stats, signed_list, worst_depth,
};
use super::{
    e_ma_hn, hidden_counts, mean_e_ma_hn, AlgoRow, Thesis, FEWER_DEPTHS, GENERAL_CASE, PHI_DEPTHS,
};
use crate::fmt::{files_line, join, mean, pct, pct_value, roman, span, stages};
use crate::sim::sets::training_volume;
use crate::study::engine::number_word;
use crate::study::reported;
use crate::train::{Algo, TrainConfig};
use hvs_shared::runtime::blob::OutputKind;
use hvs_shared::runtime::traditional::Calibration;
use hvs_shared::sim::presets::{
    self, LABELS, TEST_DEPTHS, TEST_POINTS_XY, TRAIN_BOARD_X, TRAIN_BOARD_Y, TRAIN_DEPTHS,
};

/// The prose of `RESULTS.md`.
pub const TEMPLATE: &str = include_str!("../../../templates/results.md");

/// Where `hvs experiment posture` writes its report, relative to the thesis' directory (its
/// default output is `docs/results/posture`); `RESULTS.md` links it when it is there.
pub const POSTURE_REPORT: &str = "posture/POSTURE.md";

/// The paragraph of `RESULTS.md` that points to the posture study.
pub fn posture_link() -> String {
    format!(
        "**Depth while the eyes move**: the thesis' 4-5-3 net at verged and turned \
         head postures, a posture-aware net per posture band against the floor at the same \
         posture, the hidden neurons it needs, and lens distortion, in \
         [{POSTURE_REPORT}]({POSTURE_REPORT}) (`hvs experiment posture`)."
    )
}

/// The thesis' bound on the net's worst depth as it prints it: `4 %`.
fn bound() -> String {
    format!("{} %", reported::NET_BOUND_PCT)
}

/// Table rows, one a line.
fn rows(v: impl IntoIterator<Item = String>) -> String {
    join(v, "\n")
}

/// The values of `RESULTS.md`'s placeholders for a run that took `total_s` seconds;
/// `posture`: link the posture report.
pub fn results_values(t: &Thesis, total_s: f64, posture: bool) -> Vec<(&'static str, String)> {
    let cfg = &t.config;
    let case1 = presets::CASE_1;
    let n_board = TRAIN_BOARD_X.len() * TRAIN_BOARD_Y.len();
    let mut v: Vec<(&str, String)> = vec![
        (
            "command",
            format!(
                "hvs experiment thesis --seed {}{}",
                cfg.seed,
                if cfg.quick { " --quick" } else { "" }
            ),
        ),
        ("total_s", format!("{total_s:.1}")),
        ("threads", t.threads.to_string()),
        ("board_points", n_board.to_string()),
        ("board_x", join(TRAIN_BOARD_X, ", ")),
        ("board_y", join(TRAIN_BOARD_Y, ", ")),
        ("board_x_count", number_word(TRAIN_BOARD_X.len())),
        ("train_grid", depth_grid(&TRAIN_DEPTHS)),
        ("train_points", (n_board * TRAIN_DEPTHS.len()).to_string()),
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
        ("posture_link", if posture { format!("{}\n\n", posture_link()) } else { String::new() }),
    ];
    for (key, stem) in [
        ("files_phi", "fig4_03_04_phi"),
        ("files_traditional", "fig4_08_11_traditional"),
        ("files_net_case4", "fig4_12_net_case4"),
        ("files_ten_nets", "fig4_13_ten_nets"),
        ("files_hidden", "fig4_14_15_hidden"),
        ("files_proposed", "fig4_16_19_proposed"),
        ("files_fewer", "fig4_20_22_fewer_depths"),
        ("files_bp_vs_lm", "bp_vs_lm"),
        ("files_noise", "noise"),
    ] {
        v.push((key, files_line(stem)));
    }
    phi_values(&mut v, t);
    traditional_values(&mut v, t);
    net_case4_values(&mut v, t);
    sweep_values(&mut v, t);
    proposed_values(&mut v, t);
    fewer_values(&mut v, t);
    algo_values(&mut v, t);
    noise_values(&mut v, t);
    v
}

/// The proposed net's shape, `4-5-3`: the default `hvs train` net.
fn net_shape() -> String {
    let tc = TrainConfig::default();
    format!("4-{}-{}", tc.hidden, tc.outputs.len())
}

fn phi_values(v: &mut Vec<(&str, String)>, t: &Thesis) {
    let l1 = phi_stats(&t.phi, 1, true);
    let r1 = phi_stats(&t.phi, 1, false);
    let l2 = phi_stats(&t.phi, 2, true);
    let r2 = phi_stats(&t.phi, 2, false);
    let mut table = Vec::new();
    for (case, left, s) in [(1u8, true, l1), (1, false, r1), (2, true, l2), (2, false, r2)] {
        table.push(format!(
            "| {} | {} | {:.3} | {:.3} | {:+.3} % | {:.3} % | {:.3} % |",
            roman(case),
            if left { "Phi_L" } else { "Phi_R" },
            s.mean,
            s.truth,
            s.bias_pct(),
            s.max_dev_pct,
            s.sd_pct
        ));
    }
    // The far boards of the Phi experiment: the last two depths.
    let far = &PHI_DEPTHS[PHI_DEPTHS.len() - 2..];
    let d = presets::CASE_1.half_baseline;
    let disp = |rig: &hvs_shared::sim::camera::Rig, centre: f64| {
        mean(&far.iter().filter_map(|&z| board_disparity_px(rig, centre, z)).collect::<Vec<_>>())
    };
    let far_disp = disp(&presets::CASE_1, d);
    let ratio = disp(&presets::CASE_2, -d) / far_disp;
    v.extend([
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
        ("phi_rows", rows(table)),
        ("far_depths", join(far, "-")),
        ("far_disparity", format!("{far_disp:.0}")),
        ("half_px_pct", format!("{:.1}", 50.0 / far_disp)),
        ("case2_disparity_ratio", format!("{ratio:.1}")),
    ]);
}

fn traditional_values(v: &mut Vec<(&str, String)>, t: &Thesis) {
    let mut glance = Vec::new();
    let mut table = Vec::new();
    for c in &t.traditional {
        let k = usize::from(c.case - 1);
        let th = reported::traditional_range(c.case).unwrap_or_default();
        let (lo, hi) = (pct(c.traditional.best()), pct(c.traditional.worst()));
        glance.push(format!(
            "| 4.{} traditional, case {} | {th} | {lo} .. {hi} |",
            8 + k,
            roman(c.case)
        ));
        table.push(format!(
            "| {} ({}) | {th} | {lo} .. {hi} | {} |",
            roman(c.case),
            LABELS[k].split(": ").nth(1).unwrap_or(""),
            pct(c.optimal.worst())
        ));
    }
    let within: Vec<&str> = t
        .traditional
        .iter()
        .filter(|c| matches_thesis_traditional(c.case, c.traditional.best(), c.traditional.worst()))
        .map(|c| roman(c.case))
        .collect();
    v.extend([
        ("glance_traditional_rows", rows(glance)),
        ("traditional_rows", rows(table)),
        ("trad_within", if within.is_empty() { "none".to_string() } else { within.join(", ") }),
        (
            "trad_within_count",
            if within.len() == t.traditional.len() {
                "all four".to_string()
            } else {
                format!("{} of {}", within.len(), t.traditional.len())
            },
        ),
        (
            "trad_floor_worst",
            pct(t.traditional.iter().map(|c| c.optimal.worst()).fold(0.0, f64::max)),
        ),
    ]);
}

fn net_case4_values(v: &mut Vec<(&str, String)>, t: &Thesis) {
    let p = &t.proposed[usize::from(GENERAL_CASE - 1)];
    let rig = presets::case(GENERAL_CASE).unwrap_or(presets::CASE_4);
    let table = p
        .net
        .z
        .iter()
        .enumerate()
        .map(|(k, z)| format!("| {z} | {} | {} |", pct(p.net.pct[k]), pct(p.optimal.pct[k])));
    let (wz, _) = worst_depth(&p.optimal);
    // Test points that have the same pixels at two neighbouring depths, one of them the
    // floor's worst.
    let twins: Vec<String> = TEST_POINTS_XY
        .iter()
        .enumerate()
        .flat_map(|(k, xy)| {
            identical_pixel_depths(&rig, *xy, &TEST_DEPTHS)
                .into_iter()
                .filter(|(a, b)| *a == wz || *b == wz)
                .map(move |(a, b)| format!("P{} has identical pixels at {a} and {b} cm", k + 1))
        })
        .collect();
    let twins_sentence = if twins.is_empty() {
        "no test point has the same pixels at two depths there, so this is the rounding of \
         nearby depths."
            .to_string()
    } else {
        format!(
            "in this simulation of case {}, {}, so any method gives it one depth there and \
             errs by several percent at one of the two.",
            roman(GENERAL_CASE),
            twins.join(", and ")
        )
    };
    let above = p.net.pct.iter().zip(&p.optimal.pct).map(|(a, b)| a - b).fold(0.0, f64::max);
    let [th_lo, th_hi] = reported::NET_CASE4_PCT;
    v.extend([
        ("net_case4_rows", rows(table)),
        ("th_net_case4", format!("{th_lo} .. {th_hi} %")),
        ("th_net_case4_worst", th_hi.to_string()),
        ("net_case4_best", pct(p.net.best())),
        ("net_case4_worst", pct(p.net.worst())),
        ("net_case4_train", pct(p.train_pct)),
        ("floor_case4_best", pct(p.optimal.best())),
        ("floor_case4_worst", pct(p.optimal.worst())),
        ("floor_case4_worst_z", wz.to_string()),
        ("net_case4_above", pct_value(above)),
        (
            "floor_case4_twins_note",
            if twins.is_empty() {
                String::new()
            } else {
                format!(
                    " ({})",
                    twins.join("; ").replace(" has identical pixels at", "'s identical pixels at")
                )
            },
        ),
        ("twins_sentence", twins_sentence),
    ]);
    // Fig. 4.13: the sweep's nets with the proposed shape.
    let ten: Vec<_> =
        t.sweep.iter().filter(|r| r.hidden == 5 && r.outputs == OutputKind::Xyz).collect();
    let (wlo, whi) = span(ten.iter().map(|r| r.test_worst_pct));
    let (mlo, mhi) = span(ten.iter().map(|r| r.test_mean_pct));
    v.extend([
        ("ten_worst_lo", pct(wlo)),
        ("ten_worst_hi", pct(whi)),
        ("ten_mean_lo", pct(mlo)),
        ("ten_mean_hi", pct(mhi)),
        ("ten_count", ten.len().to_string()),
        (
            "ten_below_bound",
            ten.iter().filter(|r| r.test_worst_pct < reported::NET_BOUND_PCT).count().to_string(),
        ),
    ]);
}

fn sweep_values(v: &mut Vec<(&str, String)>, t: &Thesis) {
    let hs = hidden_counts(&t.sweep);
    let z1 = e_ma_hn(&t.sweep, OutputKind::Z);
    let x3 = e_ma_hn(&t.sweep, OutputKind::Xyz);
    let zm = mean_e_ma_hn(&t.sweep, OutputKind::Z);
    let xm = mean_e_ma_hn(&t.sweep, OutputKind::Xyz);
    let table = hs.iter().enumerate().map(|(k, h)| {
        format!("| {h} | {} | {} | {} | {} |", pct(z1[k]), pct(x3[k]), pct(zm[k]), pct(xm[k]))
    });
    let wins = |one: &[f64], three: &[f64]| one.iter().zip(three).filter(|(a, b)| b < a).count();
    let verdict = match (mean(&x3) < mean(&z1), mean(&xm) < mean(&zm)) {
        (true, true) => {
            "on average three outputs beat one by both measures, as in the thesis, though by \
             much less and not at every count."
        }
        (true, false) => {
            "on average three outputs beat one by the thesis' measure, but not by the mean \
             e_ma."
        }
        (false, true) => {
            "on average three outputs beat one by the mean e_ma, but not by the thesis' \
             measure."
        }
        (false, false) => "unlike the thesis, three outputs do not beat one on average here.",
    };
    let best = |e: &[f64]| hs.get(argmin(e)).copied().unwrap_or(0).to_string();
    v.extend([
        ("nets", t.config.nets().to_string()),
        ("hidden_rows", rows(table)),
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
        ("hn_verdict", verdict.to_string()),
    ]);
}

fn proposed_values(v: &mut Vec<(&str, String)>, t: &Thesis) {
    let limit = reported::NET_BOUND_PCT;
    let table = t.proposed.iter().map(|p| {
        format!(
            "| {} | {} | {} | {} | {} | < {} |",
            roman(p.case),
            pct(p.train_pct),
            pct(p.net.mean),
            pct(p.net.worst()),
            pct(p.optimal.worst()),
            bound()
        )
    });
    let over: Vec<&str> =
        t.proposed.iter().filter(|p| p.net.worst() >= limit).map(|p| roman(p.case)).collect();
    let near: Vec<String> = t
        .proposed
        .iter()
        .filter(|p| p.optimal.worst() >= 0.9 * limit)
        .map(|p| format!("{} ({})", roman(p.case), pct(p.optimal.worst())))
        .collect();
    let n = t.proposed.len();
    let b = bound();
    let bound_sentence = if over.is_empty() {
        format!("as in the thesis, the worst depth stays below {b} in every case.")
    } else {
        format!(
            "the thesis' \"well below {} even in the worst case\" holds here in {} of {n} \
             cases; **difference:** not in case(s) {}.",
            bound(),
            n - over.len(),
            over.join(", ")
        )
    };
    let floor_sentence = if near.is_empty() {
        format!("Optimal triangulation with the true rig stays well below {b} everywhere.")
    } else {
        format!(
            "On these {} rounded test points even optimal triangulation with the true rig \
             comes within 10 % of the {} bound at its worst depth in case(s) {}, so no \
             calibration-free method can be expected to stay clearly below it there; the \
             thesis' real pixels evidently were not this coarse at its test points.",
            TEST_POINTS_XY.len() * TEST_DEPTHS.len(),
            bound(),
            near.join(", ")
        )
    };
    let ratios = t
        .noise
        .iter()
        .filter(|r| r.sigma == 0.0)
        .map(|r| format!("{:.2}", r.network_pct / r.optimal_pct));
    let glance = t.proposed.iter().map(|p| format!("{} {}", roman(p.case), pct(p.net.worst())));
    v.extend([
        ("proposed_rows", rows(table)),
        ("proposed_worst", join(glance, ", ")),
        ("proposed_bound_sentence", bound_sentence),
        ("proposed_floor_sentence", floor_sentence),
        ("proposed_mean_max", pct(t.proposed.iter().map(|p| p.net.mean).fold(0.0, f64::max))),
        ("volume_points", t.config.volume_points().to_string()),
        ("volume_ratios", join(ratios, ", ")),
    ]);
}

fn fewer_values(v: &mut Vec<(&str, String)>, t: &Thesis) {
    let p4 = &t.proposed[usize::from(GENERAL_CASE - 1)];
    let mut table: Vec<String> = t
        .fewer
        .iter()
        .map(|f| {
            format!(
                "| {} | {} | {} | {} / {} | {} / {} |",
                join(&f.depths, ", "),
                f.points,
                reported::fewer_depths(f.depths.len()),
                pct(f.net.mean),
                pct(f.net.worst()),
                pct(f.bp.mean),
                pct(f.bp.worst())
            )
        })
        .collect();
    let bp4 = algo_row(t, GENERAL_CASE, Algo::Bp).map_or("-".to_string(), |r| {
        format!("{} / {}", pct(r.test_mean_pct), pct(r.test_worst_pct))
    });
    let step = TRAIN_DEPTHS[1] - TRAIN_DEPTHS[0];
    table.push(format!(
        "| {}-{} step {step} (all {}) | {} | < {} | {} / {} | {bp4} |",
        TRAIN_DEPTHS[0],
        TRAIN_DEPTHS[TRAIN_DEPTHS.len() - 1],
        number_word(TRAIN_DEPTHS.len()),
        TRAIN_BOARD_X.len() * TRAIN_BOARD_Y.len() * TRAIN_DEPTHS.len(),
        bound(),
        pct(p4.net.mean),
        pct(p4.net.worst())
    ));
    let two = &t.fewer[0];
    let four = &t.fewer[FEWER_DEPTHS.len() - 1];
    let th = reported::TWO_DEPTHS_MEAN_PCT;
    let why = if two.net.mean < th / 2.0 && two.bp.mean < th / 2.0 {
        format!(
            "**difference:** two depths cost far less here than the thesis' {th} % with either \
             algorithm ({} LM, {} BP): on noise-free simulated pixels the depth is a smooth \
             function of the pixels that a {} net interpolates between {} and {} cm. The \
             thesis does not say what its two-depth net got wrong; since our own \
             back-propagation does not fail that way, the cause is more likely in its \
             hand-picked pixels or its training run than in the method.",
            pct(two.net.mean),
            pct(two.bp.mean),
            net_shape(),
            two.depths[0],
            two.depths[two.depths.len() - 1],
        )
    } else if two.net.mean < th / 2.0 {
        format!(
            "**difference:** with LM two depths cost far less than the thesis' {th} % ({}), \
             while back-propagation gets {}, nearer the thesis: the algorithm, not only the \
             data, decides how well a net fitted at two depths interpolates between them.",
            pct(two.net.mean),
            pct(two.bp.mean)
        )
    } else {
        format!("two depths are as insufficient here as in the thesis ({th} %).")
    };
    v.extend([
        ("fewer_rows", rows(table)),
        ("fewer_two_mean", pct(two.net.mean)),
        ("fewer_four_mean", pct(four.net.mean)),
        ("fewer_why", why),
        ("th_two_depths", reported::fewer_depths(2)),
        ("th_four_depths", reported::fewer_depths(4)),
        (
            "fewer_means",
            join(
                t.fewer
                    .iter()
                    .map(|f| format!("{} depths: mean {}", f.depths.len(), pct(f.net.mean))),
                "; ",
            ),
        ),
    ]);
}

fn algo_row(t: &Thesis, case: u8, algo: Algo) -> Option<&AlgoRow> {
    t.algos.iter().find(|r| r.case == case && r.algo == algo)
}

fn algo_values(v: &mut Vec<(&str, String)>, t: &Thesis) {
    let bp = t.config.bp();
    let mut table = Vec::new();
    for case in 1..=4u8 {
        if let (Some(b), Some(l)) = (algo_row(t, case, Algo::Bp), algo_row(t, case, Algo::Lm)) {
            table.push(format!(
                "| {} | {} / {} / {} | {} / {} / {} | {} | {:.2} s | {:.3} s |",
                roman(case),
                pct(b.train_pct),
                pct(b.test_mean_pct),
                pct(b.test_worst_pct),
                pct(l.train_pct),
                pct(l.test_mean_pct),
                pct(l.test_worst_pct),
                pct(t.proposed[usize::from(case - 1)].optimal.worst()),
                b.wall_s,
                l.wall_s
            ));
        }
    }
    let sum = |a: Algo, f: &dyn Fn(&AlgoRow) -> f64| -> f64 {
        t.algos.iter().filter(|r| r.algo == a).map(f).sum::<f64>()
    };
    let (bt, lt) = (sum(Algo::Bp, &|r| r.wall_s), sum(Algo::Lm, &|r| r.wall_s));
    let (be, le) =
        (sum(Algo::Bp, &|r| r.test_worst_pct) / 4.0, sum(Algo::Lm, &|r| r.test_worst_pct) / 4.0);
    let verdict = if (be - le).abs() < 0.25 * le {
        "The thesis' algorithm is not what limits its accuracy: given enough learning \
         cycles it reaches errors close to LM's on these noise-free pixels; what it costs \
         is time (thousands of learning cycles of one update per pattern, against at \
         most 200 LM steps)."
    } else if be > le {
        "LM is both more accurate and much faster here."
    } else {
        "BP is more accurate here, LM much faster."
    };
    v.extend([
        ("bp_rate", bp.learning_rate.to_string()),
        ("bp_e_max", bp.e_max.to_string()),
        ("bp_cycles", bp.max_cycles.to_string()),
        ("algo_rows", rows(table)),
        ("lm_worst_mean", pct(le)),
        ("bp_worst_mean", pct(be)),
        ("floor_worst_mean", pct(t.proposed.iter().map(|p| p.optimal.worst()).sum::<f64>() / 4.0)),
        ("lm_time", format!("{lt:.3}")),
        ("bp_time", format!("{bt:.2}")),
        ("speedup", format!("{:.0}", bt / lt.max(1e-9))),
        ("algo_verdict", verdict.to_string()),
    ]);
}

fn noise_values(v: &mut Vec<(&str, String)>, t: &Thesis) {
    let levels = t.config.noise_levels();
    let shown = [levels[0], levels[levels.len() / 2], levels[levels.len() - 1]];
    let table = t.noise.iter().filter(|r| shown.contains(&r.sigma)).map(|r| {
        format!(
            "| {} | {:.1} | {} | {:.1} % | {} | {} | {:.2} |",
            roman(r.case),
            r.sigma,
            pct(r.traditional_pct),
            r.traditional_missing_pct,
            pct(r.network_pct),
            pct(r.optimal_pct),
            r.network_pct / r.optimal_pct
        )
    });
    let (lo, hi) = span(t.noise.iter().map(|r| r.network_pct / r.optimal_pct));
    let top = levels[levels.len() - 1];
    let at = |case: u8, sigma: f64| t.noise.iter().find(|r| r.case == case && r.sigma == sigma);
    let grow = match (at(1, 0.0), at(1, top)) {
        (Some(a), Some(b)) => b.optimal_pct / a.optimal_pct,
        _ => f64::NAN,
    };
    let trad = (1..=4u8).map(|case| {
        let (a, b) = span(t.noise.iter().filter(|r| r.case == case).map(|r| r.traditional_pct));
        format!("{} {}-{}", roman(case), pct_value(a), pct(b))
    });
    let (vlo, vhi) = training_volume();
    let volume_box =
        format!("X {}..{}, Y {}..{}, Z {}..{} cm", vlo[0], vhi[0], vlo[1], vhi[1], vlo[2], vhi[2]);
    v.extend([
        ("noise_repeats", t.config.noise_repeats().to_string()),
        ("volume_box", volume_box),
        ("noise_rows", rows(table)),
        ("noise_ratio_lo", format!("{lo:.2}")),
        ("noise_ratio_hi", format!("{hi:.2}")),
        ("noise_floor_growth", format!("{grow:.1}")),
        ("noise_top", top.to_string()),
        ("noise_traditional", join(trad, ", ")),
    ]);
}
