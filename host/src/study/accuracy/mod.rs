//! `hvs experiment accuracy`: the depth accuracy of four estimators ([`METHODS`]) on the same
//! test pixels in every pixel regime: the floor (optimal triangulation with the true rig and
//! lenses), a DLT fit, the thesis 4-5-3 net and the default of `hvs train`. [`run`] computes,
//! [`report`] writes. Every set is an `hvs simulate` command's ([`simulate_command`]),
//! seeded by [`set_seed`]; the same config gives the same CSV bytes on any thread count.

pub mod images;
pub mod real_pair;
pub mod report;

use crate::data::dataset::Dataset;
use crate::evaluate::{evaluate, model_depths, optimal_depths_lens, Evaluation, Method};
use crate::sim::board::{Pixels, TrainingBoard};
use crate::sim::sets::{SetKind, SimOptions};
use crate::study::engine::{par_stage, timed, Progress, Quiet, Reduced};
use crate::train::{train, TrainConfig};
use anyhow::{anyhow, Context, Result};
use hvs_shared::runtime::{blob::Family, blob::InputKind, gaze::Joints};
use hvs_shared::sim::{camera::Distortion, camera::Rig, posture::HeadRig, presets};
use hvs_vision::geometry::{fit_dlt, triangulate_dlt};
use nalgebra::Matrix3x4;

/// The held-out seed base of the page: the families were tuned on base 0.
pub const HELD_OUT_SEED_BASE: u64 = 1_000_000;

/// How the pixels of a regime are made: rounded or exact, Gaussian noise (px) before any
/// rounding, radial distortion k1 of both lenses (0: none).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Regime {
    pub name: &'static str,
    pub pixels: Pixels,
    pub noise_px: f64,
    pub k1: f64,
}

impl Regime {
    /// Whether the floor is zero (exact pixels, no noise): errors compared as e_ma, not ratios.
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

/// The pixels of the lens sweep: the `sub` regime's, so that no rounding hides the lens.
pub const LENS_SWEEP_PIXELS: Regime = REGIMES[1];
/// The bigger board: 9 x 6 inner corners at 6 cm (the board `hvs demo --images` renders).
pub const BIG_BOARD: TrainingBoard = TrainingBoard::Grid { nx: 9, ny: 6, pitch: 6.0 };
/// The two training boards.
pub const BOARDS: [TrainingBoard; 2] = [TrainingBoard::Thesis, BIG_BOARD];
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

impl Reduced for AccuracyConfig {
    fn quick(&self) -> bool {
        self.quick
    }
}

impl AccuracyConfig {
    /// The cases of the regime table (I-IV; IV when quick).
    pub fn cases(&self) -> Vec<u8> {
        self.pick(vec![1, 2, 3, 4], vec![SWEEP_CASE])
    }
    /// Random test points per volume set (500; 60 when quick).
    pub fn test_points(&self) -> usize {
        self.pick(500, 60)
    }
    /// Restarts of both nets (the trainer's default, 10; 2 when quick).
    pub fn restarts(&self) -> usize {
        self.pick(TrainConfig::default().restarts, 2)
    }
    /// Pixel noise levels of the noise sweep (px): 0 to 0.5 by 0.05 (0 and 0.5 when quick).
    pub fn noise_levels(&self) -> Vec<f64> {
        // In hundredths, so that each level is the double nearest its decimal.
        self.steps().map(|k| (5 * k) as f64 / 100.0).collect()
    }
    /// k1 of the lens sweep: 0 to -0.2 by -0.02 (0 and -0.2 when quick).
    pub fn k1_levels(&self) -> Vec<f64> {
        self.steps().map(|k| -((2 * k) as f64) / 100.0 + 0.0).collect()
    }
    /// The sweeps' steps out of 10 (0 and 10 when quick).
    fn steps(&self) -> impl Iterator<Item = usize> {
        (0..=10).step_by(self.pick(1, 10))
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
    /// Mean e_ma of the four.
    pub fn mean(ev: &Evaluation) -> Scores {
        Scores(core::array::from_fn(|k| ev.methods[k].mean.e_ma_pct))
    }
    /// Worst per-depth e_ma of the four.
    pub fn worst(ev: &Evaluation) -> Scores {
        Scores(core::array::from_fn(|k| ev.methods[k].worst_depth_pct))
    }
    /// The floor's e_ma.
    pub fn floor(&self) -> f64 {
        self.0[0]
    }
    /// Ratios to the floor of DLT, thesis and default (infinite where the floor is zero).
    pub fn ratios(&self) -> [f64; 3] {
        core::array::from_fn(|k| self.0[k + 1] / self.floor())
    }
}

/// One cell of the regime table: mean e_ma over the volume test points; or one case of the
/// thesis' protocol (thesis board, `int` pixels, tested on P1 and P2 at the 11 test depths):
/// worst per-depth e_ma, as the thesis.
#[derive(Debug, Clone, PartialEq)]
pub struct RegimeRow {
    pub board: TrainingBoard,
    pub regime: Regime,
    pub case: u8,
    pub scores: Scores,
}

/// One point of a sweep (case IV): the swept value `x` (noise px or k1), mean e_ma over the
/// volume test points.
#[derive(Debug, Clone, PartialEq)]
pub struct SweepRow {
    pub board: TrainingBoard,
    pub x: f64,
    pub scores: Scores,
}

/// Everything [`run`] computed, one field per part (`real_pair` `None` when not run), the wall
/// time per stage (s, not in the CSVs) and the worker threads.
#[derive(Debug, Clone)]
pub struct Accuracy {
    pub config: AccuracyConfig,
    pub regimes: Vec<RegimeRow>,
    pub protocol: Vec<RegimeRow>,
    pub noise: Vec<SweepRow>,
    pub lens: Vec<SweepRow>,
    pub images: Vec<images::ImageRow>,
    pub real_pair: Option<real_pair::RealPairRow>,
    pub stage_s: Vec<(&'static str, f64)>,
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
        crate::sim::sets::simulate(rig, kind, opt)?.iter().for_each(|s| d.push(&s.px, Some(s.xyz)));
    } else {
        let head = HeadRig::new(*rig).with_distortion(lens);
        let sim = crate::sim::posture::simulate(&head, kind, &[Joints::HOME], opt)?;
        sim.iter().for_each(|s| d.push(&s.px, Some(s.xyz)));
    }
    Ok(d)
}

/// The `hvs simulate` command that writes the same set.
pub fn simulate_command(
    case: u8,
    board: &TrainingBoard,
    r: &Regime,
    kind: &str,
    seed: u64,
) -> String {
    let flags = [
        (*board != TrainingBoard::Thesis, format!(" --board {}", board.name())),
        (r.pixels == Pixels::Exact, " --pixels exact".into()),
        (r.noise_px > 0.0, format!(" --noise-px {}", r.noise_px)),
        (r.k1 != 0.0, format!(" --distortion {}", r.k1)),
        (kind == "volume", format!(" --points N --seed {seed}")),
        (kind != "volume" && r.noise_px > 0.0, format!(" --seed {seed}")),
    ];
    let on = flags.into_iter().filter_map(|(on, flag)| on.then_some(flag));
    on.fold(format!("hvs simulate --case {case} --set {kind}"), |c, flag| c + &flag)
}

/// Depths of `test` by linear triangulation through the two 3x4 cameras `p` (NaN where it
/// fails).
pub fn triangulated_depths(p: &[Matrix3x4<f64>; 2], test: &Dataset) -> Vec<f64> {
    (0..test.len())
        .map(|n| {
            let r = test.row(n);
            triangulate_dlt(p, &[r[0], r[1], r[2], r[3]]).map_or(f64::NAN, |x| x[2])
        })
        .collect()
}

/// DLT depths: one 3x4 matrix per camera fitted to `train`, linear triangulation of `test`
/// (NaN where it fails).
pub fn dlt_depths(train: &Dataset, test: &Dataset) -> Result<Vec<f64>> {
    let split = |k: usize| -> Vec<[f64; 2]> {
        (0..train.len()).map(|n| [train.row(n)[k], train.row(n)[k + 1]]).collect()
    };
    let p = [fit_dlt(&train.targets, &split(0))?, fit_dlt(&train.targets, &split(2))?];
    Ok(triangulated_depths(&p, test))
}

/// The four estimators on `test` after fitting on `train`, the floor's depths given: the
/// evaluation, methods in [`METHODS`] order.
pub fn estimate(
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

/// Training and test set (`test`: a volume set, or the thesis' test points) of one cell, and
/// the four estimators' evaluation on it.
fn cell(
    cfg: &AccuracyConfig,
    (part, b, level): (u64, usize, usize),
    board: TrainingBoard,
    r: &Regime,
    (case, test): (u8, SetKind),
) -> Result<Evaluation> {
    let (rig, lens) = (case_rig(case)?, Distortion { k1: r.k1, k2: 0.0 });
    let opt = |set: u64| SimOptions {
        points: cfg.test_points(),
        noise_px: r.noise_px,
        seed: set_seed(cfg.seed_base, part, b, level, case, set),
        board,
        pixels: r.pixels,
    };
    let tr = simulate_set(&rig, lens, SetKind::Train, &opt(1))?;
    let te = simulate_set(&rig, lens, test, &opt(2))?;
    estimate(cfg, optimal_depths_lens(&rig, lens, &te), &tr, &te)
        .with_context(|| format!("board {}, regime {}, case {case}", board.name(), r.name))
}

/// The regime table: every board, regime and case (board outer, then regime, then case).
pub fn regime_rows(cfg: &AccuracyConfig, progress: &dyn Progress) -> Result<Vec<RegimeRow>> {
    let mut jobs = Vec::new();
    for (b, board) in BOARDS.iter().enumerate() {
        for (k, regime) in REGIMES.iter().enumerate() {
            jobs.extend(cfg.cases().into_iter().map(|case| (b, *board, k, *regime, case)));
        }
    }
    par_stage(progress, "regimes", &jobs, |&(b, board, k, regime, case)| {
        let ev = cell(cfg, (0, b, k), board, &regime, (case, SetKind::Volume))?;
        Ok(RegimeRow { board, regime, case, scores: Scores::mean(&ev) })
    })
}

/// The thesis protocol: trained on the `int` cell's training set of the thesis board, tested
/// on P1, P2 at the 11 test depths.
pub fn protocol_rows(cfg: &AccuracyConfig) -> Result<Vec<RegimeRow>> {
    par_stage(&Quiet, "protocol", &cfg.cases(), |&case| {
        let (board, regime) = (TrainingBoard::Thesis, REGIMES[0]);
        let ev = cell(cfg, (0, 0, 0), board, &regime, (case, SetKind::Test))?;
        Ok(RegimeRow { board, regime, case, scores: Scores::worst(&ev) })
    })
}

/// A sweep on case IV, both boards (board outer), regime `regime(x)` at each level `x`; every
/// level on the same seeds (common random numbers: the curve shows the swept value, not the
/// draws).
fn sweep_rows(
    cfg: &AccuracyConfig,
    (name, part): (&str, u64),
    levels: Vec<f64>,
    regime: impl Fn(f64) -> Regime + Sync,
    progress: &dyn Progress,
) -> Result<Vec<SweepRow>> {
    let jobs: Vec<_> = (0..2).flat_map(|b| levels.iter().map(move |&x| (b, x))).collect();
    par_stage(progress, name, &jobs, |&(b, x)| {
        let ev = cell(cfg, (part, b, 0), BOARDS[b], &regime(x), (SWEEP_CASE, SetKind::Volume))?;
        Ok(SweepRow { board: BOARDS[b], x, scores: Scores::mean(&ev) })
    })
}

/// Runs every part.
pub fn run(cfg: &AccuracyConfig, progress: &dyn Progress) -> Result<Accuracy> {
    let s = &mut Vec::new();
    let regimes = timed(s, "regimes", || regime_rows(cfg, progress))?;
    let protocol = timed(s, "protocol", || protocol_rows(cfg))?;
    let noise = timed(s, "noise", || {
        let r = |x| Regime { name: "noise", pixels: Pixels::Exact, noise_px: x, k1: 0.0 };
        sweep_rows(cfg, ("noise sweep", 1), cfg.noise_levels(), r, progress)
    })?;
    let lens = timed(s, "lens", || {
        let r = |x| Regime { name: "lens", k1: x, ..LENS_SWEEP_PIXELS };
        sweep_rows(cfg, ("lens sweep", 2), cfg.k1_levels(), r, progress)
    })?;
    let images = timed(s, "images", || images::image_rows(cfg, progress))?;
    let real_pair = Some(timed(s, "real_pair", || real_pair::real_pair_row(cfg))?);
    Ok(Accuracy {
        config: *cfg,
        regimes,
        protocol,
        noise,
        lens,
        images,
        real_pair,
        stage_s: std::mem::take(s),
        threads: rayon::current_num_threads(),
    })
}

/// Worst over the cases of `board` and `regime` of method `m` (1 DLT, 2 thesis, 3 default):
/// `(ratio to the floor, or in an exact regime e_ma (%), case)`; `None` without a row.
pub fn worst_over_cases(
    rows: &[RegimeRow],
    board: &TrainingBoard,
    regime: &str,
    m: usize,
) -> Option<(f64, u8)> {
    rows.iter()
        .filter(|r| r.board == *board && r.regime.name == regime)
        .map(|r| (r.scores.0[m] / if r.regime.exact() { 1.0 } else { r.scores.floor() }, r.case))
        .max_by(|a, b| a.0.total_cmp(&b.0))
}

/// The range `(min, max)` of the floor's e_ma over the cases of `board` and `regime`.
pub fn floor_span(rows: &[RegimeRow], board: &TrainingBoard, regime: &str) -> (f64, f64) {
    let rows = rows.iter().filter(|r| r.board == *board && r.regime.name == regime);
    crate::fmt::span(rows.map(|r| r.scores.floor()))
}
