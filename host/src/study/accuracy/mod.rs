//! `hvs experiment accuracy`: the depth accuracy of the learned models against the floor in
//! every pixel regime. [`run`] computes; [`report::write`] writes the CSVs, two
//! plots (SVG and PNG) and `ACCURACY.md`.
//!
//! | part | what | function |
//! |---|---|---|
//! | `regimes` | per board, pixel regime and case: floor, DLT, thesis 4-5-3, the default of `hvs train` | [`regime_rows`] |
//! | `protocol` | the thesis' protocol (P1, P2 at the 11 test depths): worst-depth e_ma | [`protocol_rows`] |
//! | `noise` | e_ma vs. Gaussian pixel noise 0 to 0.5 px on unrounded pixels (case IV) | [`sweep_rows`] |
//! | `lens` | e_ma vs. radial distortion k1 0 to -0.2 on the `sub` regime's pixels (case IV) | [`sweep_rows`] |
//! | `images` | corners detected in rendered images of the 9x6 board, then the same four | [`images::image_rows`] |
//! | `real_pair` | a real stereo pair with ground truth (Middlebury's Motorcycle), 1000 training points | [`real_pair::real_pair_row`] |
//!
//! The four estimators, on the same test pixels:
//! - the **floor**: optimal triangulation with the true rig and lenses
//!   ([`crate::evaluate::optimal_depths_lens`]), what no calibration-free method can beat on
//!   average;
//! - **DLT**: a 3x4 projection matrix per camera fitted to the training points (normalised
//!   DLT, [`hvs_vision::geometry::fit_dlt`]), then linear triangulation;
//! - the **thesis** net: 4-5-3, X, Y, Z outputs, `TrainConfig::default()`;
//! - the **default** of `hvs train`: the family the caller passes
//!   ([`AccuracyConfig::default_family`]; the CLI passes
//!   [`crate::train::DEFAULT_FAMILY`]), otherwise `hvs train`'s settings (4-5-3, LM,
//!   10 restarts, seed [`TRAIN_SEED`]).
//!
//! Sets are made by the functions behind `hvs simulate` ([`crate::sim::sets::simulate`], and
//! [`crate::sim::posture::simulate`] at the home posture when there is a lens), so every set
//! is one `hvs simulate` command away ([`simulate_command`]). Seeds: every set draws from
//! `seed_base + ...` ([`set_seed`]); the page's run uses [`HELD_OUT_SEED_BASE`], the held-out
//! base of `examples/accuracy_regimes.rs --eval`: no setting of the families was chosen on
//! these draws. The nets train with seed [`TRAIN_SEED`] (`hvs train --seed 7`). Results are collected in a fixed
//! order and the trainer's result does not depend on the thread count: the same config gives
//! the same CSV bytes; wall times go to `timing.csv` and the page only.

pub mod images;
pub mod real_pair;
pub mod report;

use crate::data::dataset::Dataset;
use crate::evaluate::{evaluate, model_depths, optimal_depths_lens, Evaluation, Method};
use crate::sim::board::{Board, Pixels};
use crate::sim::sets::{SetKind, SimOptions};
use crate::study::engine::Progress;
use crate::train::{train, TrainConfig};
use anyhow::{anyhow, Context, Result};
use hvs_shared::runtime::blob::{Family, InputKind};
use hvs_shared::runtime::gaze::Joints;
use hvs_shared::sim::camera::{Distortion, Rig};
use hvs_shared::sim::posture::HeadRig;
use hvs_shared::sim::presets;
use hvs_vision::geometry::{fit_dlt, triangulate_dlt};
use rayon::prelude::*;
use std::time::Instant;

/// The held-out seed base of the page (as `examples/accuracy_regimes.rs --eval`): the
/// families' settings were tuned on base 0.
pub const HELD_OUT_SEED_BASE: u64 = 1_000_000;

/// How the pixels of a regime are made.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Regime {
    /// Short name (`int`, `sub`, `exact`, `barrel`).
    pub name: &'static str,
    /// Rounded or exact.
    pub pixels: Pixels,
    /// Gaussian pixel noise (px), before any rounding.
    pub noise_px: f64,
    /// Radial distortion k1 of both lenses (0: none).
    pub k1: f64,
}

impl Regime {
    /// The lens of the regime.
    pub fn lens(&self) -> Distortion {
        Distortion { k1: self.k1, k2: 0.0 }
    }
    /// Whether the floor is zero (exact pixels, no noise): then errors are compared as e_ma,
    /// not as ratios.
    pub fn exact(&self) -> bool {
        self.pixels == Pixels::Exact && self.noise_px == 0.0
    }
}

/// The four pixel regimes: rounded pixels (the thesis), sub-pixel noise of 0.05 px
/// without rounding, exact pixels, rounded pixels through barrel lenses (k1 = -0.1).
pub const REGIMES: [Regime; 4] = [
    Regime { name: "int", pixels: Pixels::Rounded, noise_px: 0.0, k1: 0.0 },
    Regime { name: "sub", pixels: Pixels::Exact, noise_px: 0.05, k1: 0.0 },
    Regime { name: "exact", pixels: Pixels::Exact, noise_px: 0.0, k1: 0.0 },
    Regime { name: "barrel", pixels: Pixels::Rounded, noise_px: 0.0, k1: -0.1 },
];

/// The pixels of the lens sweep: the `sub` regime's (0.05 px noise, unrounded), so that what
/// the lens costs is not hidden under the rounding (on rounded pixels the thesis board's
/// images move by less than a pixel even at k1 = -0.2).
pub const LENS_SWEEP_PIXELS: Regime = REGIMES[1];

/// The bigger board: 9 x 6 inner corners at 6 cm (the OpenCV board `hvs demo --images`
/// renders), 324 training points.
pub const BIG_BOARD: Board = Board::Grid { nx: 9, ny: 6, pitch: 6.0 };
/// The two training boards.
pub const BOARDS: [Board; 2] = [Board::Thesis, BIG_BOARD];
/// The case of the sweeps and the images: IV, the thesis' general case.
pub const SWEEP_CASE: u8 = 4;

/// The training seed of both nets, as `hvs train --seed 7` sets it.
pub const TRAIN_SEED: u64 = 7;

/// The four estimators, in column order.
pub const METHODS: [&str; 4] = ["floor", "dlt", "thesis", "default"];

/// What to run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AccuracyConfig {
    /// The family of the default net (the CLI passes [`crate::train::DEFAULT_FAMILY`]).
    pub default_family: Family,
    /// Base of every set's seed ([`HELD_OUT_SEED_BASE`] for the page).
    pub seed_base: u64,
    /// Reduced run (for tests): case IV only, 2 restarts, 60 test points, 2 sweep levels,
    /// one image regime with 2 training and 2 test boards.
    pub quick: bool,
}

impl AccuracyConfig {
    /// The cases of the regime table (I-IV; IV when quick).
    pub fn cases(&self) -> Vec<u8> {
        if self.quick {
            vec![SWEEP_CASE]
        } else {
            vec![1, 2, 3, 4]
        }
    }
    /// Random test points per volume set (500; 60 when quick).
    pub fn test_points(&self) -> usize {
        if self.quick {
            60
        } else {
            500
        }
    }
    /// Restarts of both nets (the trainer's default, 10; 2 when quick).
    pub fn restarts(&self) -> usize {
        if self.quick {
            2
        } else {
            TrainConfig::default().restarts
        }
    }
    /// Pixel noise levels of the noise sweep (px): 0 to 0.5 in steps of 0.05 (0 and 0.5
    /// when quick).
    pub fn noise_levels(&self) -> Vec<f64> {
        let n = if self.quick { 1 } else { 10 };
        // In hundredths, so that each level is the double nearest its decimal (0.15, not
        // 0.15000000000000002).
        (0..=n).map(|k| (50 * k / n) as f64 / 100.0).collect()
    }
    /// k1 of the lens sweep: 0 to -0.2 in steps of -0.02 (0 and -0.2 when quick).
    pub fn k1_levels(&self) -> Vec<f64> {
        let n = if self.quick { 1 } else { 10 };
        (0..=n).map(|k| -((20 * k / n) as f64) / 100.0 + 0.0).collect()
    }
    /// The thesis net's training configuration.
    pub fn thesis_net(&self) -> TrainConfig {
        TrainConfig {
            restarts: self.restarts(),
            progress: false,
            family: Family::THESIS,
            seed: TRAIN_SEED,
            ..TrainConfig::default()
        }
    }
    /// The default net's training configuration.
    pub fn default_net(&self) -> TrainConfig {
        TrainConfig { family: self.default_family, ..self.thesis_net() }
    }
}

/// e_ma (%) of the four estimators, in [`METHODS`] order.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Scores(pub [f64; 4]);

impl Scores {
    /// The floor's e_ma.
    pub fn floor(&self) -> f64 {
        self.0[0]
    }
    /// Ratios to the floor of DLT, thesis and default (infinite where the floor is zero).
    pub fn ratios(&self) -> [f64; 3] {
        core::array::from_fn(|k| self.0[k + 1] / self.floor())
    }
}

/// One row of the regime table.
#[derive(Debug, Clone, PartialEq)]
pub struct RegimeRow {
    /// The training board.
    pub board: Board,
    /// The pixel regime.
    pub regime: Regime,
    /// The thesis case.
    pub case: u8,
    /// Mean e_ma over the volume test points.
    pub scores: Scores,
}

/// One row of the thesis-protocol table: worst per-depth e_ma over P1, P2 at the 11 test
/// depths (the thesis' convention), thesis board, rounded pixels.
#[derive(Debug, Clone, PartialEq)]
pub struct ProtocolRow {
    /// The thesis case.
    pub case: u8,
    /// Worst per-depth e_ma.
    pub worst: Scores,
}

/// One point of a sweep (case IV).
#[derive(Debug, Clone, PartialEq)]
pub struct SweepRow {
    /// The training board.
    pub board: Board,
    /// The swept value (noise px or k1).
    pub x: f64,
    /// Mean e_ma over the volume test points.
    pub scores: Scores,
}

/// Everything [`run`] computed.
#[derive(Debug, Clone)]
pub struct Accuracy {
    /// What ran.
    pub config: AccuracyConfig,
    /// Per board, regime, case.
    pub regimes: Vec<RegimeRow>,
    /// The thesis protocol per case.
    pub protocol: Vec<ProtocolRow>,
    /// e_ma vs. pixel noise.
    pub noise: Vec<SweepRow>,
    /// e_ma vs. k1.
    pub lens: Vec<SweepRow>,
    /// Rendered images of the 9x6 board.
    pub images: Vec<images::ImageRow>,
    /// The real stereo pair (`None` when not run).
    pub real_pair: Option<real_pair::RealPairRow>,
    /// Wall time per stage (s), not part of the CSVs.
    pub stage_s: Vec<(&'static str, f64)>,
    /// Worker threads.
    pub threads: usize,
}

/// The seed of one set: `base + 100_000 part + 10_000 board + 100 level + 10 case + set`
/// (`set` 1 training, 2 test); distinct for every set of a run.
pub fn set_seed(base: u64, part: u64, board: usize, level: usize, case: u8, set: u64) -> u64 {
    base.wrapping_add(
        100_000 * part + 10_000 * board as u64 + 100 * level as u64 + 10 * u64::from(case) + set,
    )
}

/// The rig of a case.
pub fn case_rig(case: u8) -> Result<Rig> {
    presets::case(case).ok_or_else(|| anyhow!("no thesis case {case}"))
}

/// Simulates a set as `hvs simulate` does: through [`crate::sim::sets::simulate`], or, with a
/// lens, [`crate::sim::posture::simulate`] at the home posture.
pub fn simulate_set(
    rig: &Rig,
    lens: Distortion,
    kind: SetKind,
    opt: &SimOptions,
) -> Result<Dataset> {
    let mut d = Dataset::new(InputKind::Stereo);
    if lens.is_none() {
        for s in crate::sim::sets::simulate(rig, kind, opt)? {
            d.push(&s.px, Some(s.xyz));
        }
    } else {
        let head = HeadRig::new(*rig).with_distortion(lens);
        for s in crate::sim::posture::simulate(&head, kind, &[Joints::HOME], opt)? {
            d.push(&s.px, Some(s.xyz));
        }
    }
    Ok(d)
}

/// The `hvs simulate` command that writes the same set.
pub fn simulate_command(case: u8, board: &Board, r: &Regime, kind: &str, seed: u64) -> String {
    let mut c = format!("hvs simulate --case {case} --set {kind}");
    if *board != Board::Thesis {
        c.push_str(&format!(" --board {}", board.name()));
    }
    if r.pixels == Pixels::Exact {
        c.push_str(" --pixels exact");
    }
    if r.noise_px > 0.0 {
        c.push_str(&format!(" --noise-px {}", r.noise_px));
    }
    if r.k1 != 0.0 {
        c.push_str(&format!(" --distortion {}", r.k1));
    }
    if kind == "volume" {
        c.push_str(&format!(" --points N --seed {seed}"));
    } else if r.noise_px > 0.0 {
        c.push_str(&format!(" --seed {seed}"));
    }
    c
}

/// DLT depths: one 3x4 matrix per camera fitted to `train`, linear triangulation of `test`
/// (NaN where it fails).
pub fn dlt_depths(train: &Dataset, test: &Dataset) -> Result<Vec<f64>> {
    let split = |k: usize| -> Vec<[f64; 2]> {
        (0..train.len()).map(|n| [train.row(n)[k], train.row(n)[k + 1]]).collect()
    };
    let p = [fit_dlt(&train.targets, &split(0))?, fit_dlt(&train.targets, &split(2))?];
    Ok((0..test.len())
        .map(|n| {
            let r = test.row(n);
            triangulate_dlt(&p, &[r[0], r[1], r[2], r[3]]).map_or(f64::NAN, |x| x[2])
        })
        .collect())
}

/// The four estimators on `test` after fitting on `train`: the evaluation, methods in
/// [`METHODS`] order.
pub fn estimate(
    cfg: &AccuracyConfig,
    rig: &Rig,
    lens: Distortion,
    train_set: &Dataset,
    test: &Dataset,
) -> Result<Evaluation> {
    estimate_with_floor(cfg, optimal_depths_lens(rig, lens, test), train_set, test)
}

/// [`estimate`] with the floor's depths of `test` given (a real pair's true cameras).
pub fn estimate_with_floor(
    cfg: &AccuracyConfig,
    floor: Vec<f64>,
    train_set: &Dataset,
    test: &Dataset,
) -> Result<Evaluation> {
    let net = |c: TrainConfig| -> Result<Vec<f64>> {
        let out = train(train_set, &c)?;
        model_depths(&out.blob, test).map_err(|e| anyhow!("{e:?}"))
    };
    let z = [floor, dlt_depths(train_set, test)?, net(cfg.thesis_net())?, net(cfg.default_net())?];
    let methods: Vec<Method> =
        METHODS.iter().zip(z).map(|(name, z)| Method { name: name.to_string(), z }).collect();
    Ok(evaluate(test, &methods))
}

/// Mean e_ma of the four.
pub fn mean_scores(ev: &Evaluation) -> Scores {
    Scores(core::array::from_fn(|k| ev.methods[k].mean.e_ma_pct))
}

/// Worst per-depth e_ma of the four.
pub fn worst_scores(ev: &Evaluation) -> Scores {
    Scores(core::array::from_fn(|k| ev.methods[k].worst_depth_pct))
}

/// Training and volume test set of one cell.
fn cell(
    cfg: &AccuracyConfig,
    part: u64,
    (b, board): (usize, &Board),
    level: usize,
    r: &Regime,
    case: u8,
) -> Result<Scores> {
    let rig = case_rig(case)?;
    let opt = |set: u64| SimOptions {
        points: cfg.test_points(),
        noise_px: r.noise_px,
        seed: set_seed(cfg.seed_base, part, b, level, case, set),
        board: *board,
        pixels: r.pixels,
    };
    let tr = simulate_set(&rig, r.lens(), SetKind::Train, &opt(1))?;
    let te = simulate_set(&rig, r.lens(), SetKind::Volume, &opt(2))?;
    let ev = estimate(cfg, &rig, r.lens(), &tr, &te)
        .with_context(|| format!("board {}, regime {}, case {case}", board.name(), r.name))?;
    Ok(mean_scores(&ev))
}

/// The regime table: every board, regime and case (board outer, then regime, then case).
pub fn regime_rows(cfg: &AccuracyConfig, progress: &dyn Progress) -> Result<Vec<RegimeRow>> {
    let mut jobs = Vec::new();
    for (b, board) in BOARDS.iter().enumerate() {
        for (k, r) in REGIMES.iter().enumerate() {
            for case in cfg.cases() {
                jobs.push((b, *board, k, *r, case));
            }
        }
    }
    progress.start("regimes", jobs.len() as u64);
    let rows = jobs
        .par_iter()
        .map(|&(b, board, k, regime, case)| {
            let scores = cell(cfg, 0, (b, &board), k, &regime, case)?;
            progress.inc();
            Ok(RegimeRow { board, regime, case, scores })
        })
        .collect::<Result<Vec<_>>>()?;
    progress.finish();
    Ok(rows)
}

/// The thesis protocol: trained on the thesis board with rounded pixels (the `int` cell's
/// training set), tested on P1, P2 at the 11 test depths.
pub fn protocol_rows(cfg: &AccuracyConfig) -> Result<Vec<ProtocolRow>> {
    cfg.cases()
        .par_iter()
        .map(|&case| {
            let rig = case_rig(case)?;
            let r = &REGIMES[0];
            let opt = SimOptions {
                seed: set_seed(cfg.seed_base, 0, 0, 0, case, 1),
                ..SimOptions::default()
            };
            let tr = simulate_set(&rig, r.lens(), SetKind::Train, &opt)?;
            let te = simulate_set(&rig, r.lens(), SetKind::Test, &opt)?;
            let ev = estimate(cfg, &rig, r.lens(), &tr, &te)?;
            Ok(ProtocolRow { case, worst: worst_scores(&ev) })
        })
        .collect()
}

/// Which sweep.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Sweep {
    /// Gaussian pixel noise on exact pixels (no rounding).
    Noise,
    /// Radial distortion k1 on the pixels of [`LENS_SWEEP_PIXELS`].
    Lens,
}

/// A sweep on case IV, both boards (board outer); every level on the same seeds.
pub fn sweep_rows(
    cfg: &AccuracyConfig,
    which: Sweep,
    progress: &dyn Progress,
) -> Result<Vec<SweepRow>> {
    let (levels, part) = match which {
        Sweep::Noise => (cfg.noise_levels(), 1),
        Sweep::Lens => (cfg.k1_levels(), 2),
    };
    let mut jobs = Vec::new();
    for (b, board) in BOARDS.iter().enumerate() {
        for &x in &levels {
            jobs.push((b, *board, x));
        }
    }
    progress.start(
        match which {
            Sweep::Noise => "noise sweep",
            Sweep::Lens => "lens sweep",
        },
        jobs.len() as u64,
    );
    let rows = jobs
        .par_iter()
        .map(|&(b, board, x)| {
            let r = match which {
                Sweep::Noise => {
                    Regime { name: "noise", pixels: Pixels::Exact, noise_px: x, k1: 0.0 }
                }
                Sweep::Lens => Regime { name: "lens", k1: x, ..LENS_SWEEP_PIXELS },
            };
            // One seed for every level (common random numbers): the same points and the
            // same standard-normal draws, so the curve shows the swept value, not the draws.
            let scores = cell(cfg, part, (b, &board), 0, &r, SWEEP_CASE)?;
            progress.inc();
            Ok(SweepRow { board, x, scores })
        })
        .collect::<Result<Vec<_>>>()?;
    progress.finish();
    Ok(rows)
}

/// Runs every part.
pub fn run(cfg: &AccuracyConfig, progress: &dyn Progress) -> Result<Accuracy> {
    let mut stage_s = Vec::new();
    let mut timed =
        |name: &'static str, t: Instant| stage_s.push((name, t.elapsed().as_secs_f64()));
    let t = Instant::now();
    let regimes = regime_rows(cfg, progress)?;
    timed("regimes", t);
    let t = Instant::now();
    let protocol = protocol_rows(cfg)?;
    timed("protocol", t);
    let t = Instant::now();
    let noise = sweep_rows(cfg, Sweep::Noise, progress)?;
    timed("noise", t);
    let t = Instant::now();
    let lens = sweep_rows(cfg, Sweep::Lens, progress)?;
    timed("lens", t);
    let t = Instant::now();
    let images = images::image_rows(cfg, progress)?;
    timed("images", t);
    let t = Instant::now();
    let real_pair = Some(real_pair::real_pair_row(cfg)?);
    timed("real_pair", t);
    Ok(Accuracy {
        config: *cfg,
        regimes,
        protocol,
        noise,
        lens,
        images,
        real_pair,
        stage_s,
        threads: rayon::current_num_threads(),
    })
}

// ---------------------------------------------------------------------------------------
// Facts the page states

/// How a method compares with the floor over cases: the worst ratio (or, when the floor is
/// zero, the worst e_ma) and the case where it is.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Worst {
    /// Worst ratio to the floor, or worst e_ma (%) in an exact regime.
    pub value: f64,
    /// Its case.
    pub case: u8,
}

/// Worst over the cases of `board` and `regime`, for method `m` (1 DLT, 2 thesis, 3
/// default); `None` when there is no row.
pub fn worst_over_cases(
    rows: &[RegimeRow],
    board: &Board,
    regime: &str,
    m: usize,
) -> Option<Worst> {
    rows.iter()
        .filter(|r| r.board == *board && r.regime.name == regime)
        .map(|r| Worst {
            value: if r.regime.exact() { r.scores.0[m] } else { r.scores.0[m] / r.scores.floor() },
            case: r.case,
        })
        .max_by(|a, b| a.value.total_cmp(&b.value))
}

/// The range `(min, max)` of the floor's e_ma over the cases of `board` and `regime`.
pub fn floor_span(rows: &[RegimeRow], board: &Board, regime: &str) -> (f64, f64) {
    crate::fmt::span(
        rows.iter()
            .filter(|r| r.board == *board && r.regime.name == regime)
            .map(|r| r.scores.floor()),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn quick() -> AccuracyConfig {
        AccuracyConfig {
            default_family: Family::INVERSE_DEPTH_SKIP,
            seed_base: HELD_OUT_SEED_BASE,
            quick: true,
        }
    }

    fn row(board: Board, regime: usize, case: u8, s: [f64; 4]) -> RegimeRow {
        RegimeRow { board, regime: REGIMES[regime], case, scores: Scores(s) }
    }

    #[test]
    fn worst_over_cases_is_the_largest_ratio_or_the_largest_exact_error() {
        let rows = [
            row(Board::Thesis, 0, 1, [1.0, 1.1, 1.5, 1.2]),
            row(Board::Thesis, 0, 2, [0.5, 0.6, 0.55, 0.7]),
            row(BIG_BOARD, 0, 1, [1.0, 9.0, 9.0, 9.0]),
            row(Board::Thesis, 2, 1, [0.0, 1e-9, 0.3, 0.001]),
            row(Board::Thesis, 2, 3, [0.0, 2e-9, 0.2, 0.002]),
        ];
        let w = worst_over_cases(&rows, &Board::Thesis, "int", 3).unwrap();
        assert_eq!(w.case, 2);
        assert!((w.value - 1.4).abs() < 1e-12);
        let w = worst_over_cases(&rows, &Board::Thesis, "int", 2).unwrap();
        assert_eq!((w.case, w.value), (1, 1.5));
        let w = worst_over_cases(&rows, &Board::Thesis, "exact", 2).unwrap();
        assert_eq!((w.case, w.value), (1, 0.3));
        let w = worst_over_cases(&rows, &Board::Thesis, "exact", 3).unwrap();
        assert_eq!((w.case, w.value), (3, 0.002));
        assert!(worst_over_cases(&rows, &BIG_BOARD, "sub", 1).is_none());
        assert_eq!(floor_span(&rows, &Board::Thesis, "int"), (0.5, 1.0));
    }

    #[test]
    fn seeds_are_distinct_and_levels_span_the_issue() {
        let mut seen = std::collections::HashSet::new();
        for part in 0..3 {
            for b in 0..2 {
                for level in 0..11 {
                    for case in 1..=4 {
                        for set in 1..=2 {
                            assert!(seen.insert(set_seed(
                                HELD_OUT_SEED_BASE,
                                part,
                                b,
                                level,
                                case,
                                set
                            )));
                        }
                    }
                }
            }
        }
        let full = AccuracyConfig { quick: false, ..quick() };
        let n = full.noise_levels();
        assert_eq!((n.len(), n[0], n[10]), (11, 0.0, 0.5));
        let k = full.k1_levels();
        assert_eq!((k.len(), k[0], k[10]), (11, 0.0, -0.2));
        assert_eq!((n[1], n[3], k[3], k[6]), (0.05, 0.15, -0.06, -0.12));
        assert_eq!(full.cases(), vec![1, 2, 3, 4]);
        assert_eq!(full.default_net().family, Family::INVERSE_DEPTH_SKIP);
        assert_eq!(full.thesis_net().family, Family::THESIS);
        assert_eq!(full.default_net().restarts, 10);
    }

    #[test]
    fn the_floor_is_zero_on_exact_pixels_and_the_dlt_is_exact_there() {
        let cfg = quick();
        for (k, r) in REGIMES.iter().enumerate() {
            let s = cell(&cfg, 0, (0, &Board::Thesis), k, r, SWEEP_CASE).unwrap();
            let [floor, dlt, thesis, default] = s.0;
            assert!(s.0.iter().all(|v| v.is_finite()), "{r:?} {s:?}");
            if r.exact() {
                // Pinhole cameras without noise: both projective methods are exact, the
                // thesis net is not.
                assert!(floor < 1e-9 && dlt < 1e-9, "{s:?}");
                assert!(thesis > 10.0 * default.max(1e-4), "{s:?}");
            } else {
                // Rounding, noise or a lens: a real floor, and nothing far below it.
                assert!(floor > 1e-2, "{r:?} {s:?}");
                for v in [dlt, thesis, default] {
                    assert!(v > 0.8 * floor, "{r:?} {s:?}");
                }
            }
        }
        let p = protocol_rows(&cfg).unwrap();
        assert_eq!(p.len(), 1);
        assert!(p[0].worst.0.iter().all(|v| v.is_finite() && *v > 0.0), "{p:?}");
    }

    #[test]
    fn simulate_command_names_every_flag_of_the_regime() {
        let c = simulate_command(4, &BIG_BOARD, &REGIMES[1], "volume", 17);
        assert_eq!(
            c,
            "hvs simulate --case 4 --set volume --board 9x6:6 --pixels exact --noise-px 0.05 --points N --seed 17"
        );
        let c = simulate_command(1, &Board::Thesis, &REGIMES[3], "train", 3);
        assert_eq!(c, "hvs simulate --case 1 --set train --distortion -0.1");
    }
}
