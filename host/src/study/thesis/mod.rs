//! `hvs experiment thesis`: the thesis' chapter 4 on the four preset rigs, plus three
//! experiments it did not run; [`run`] computes, the `Report` impl of [`Thesis`] writes the files.
//! Every random step takes a seed derived from [`Config::seed`] and results are collected in a
//! fixed order, so the same seed gives the same CSV bytes; only the wall times vary.

pub mod facts;
pub mod markdown;
pub mod report;

use crate::data::dataset::Dataset;
use crate::evaluate::{evaluate, model_depths, optimal_depths, traditional_depths, Method};
use crate::fmt::mean;
use crate::sim::sets::{dataset, simulate, Sample, SetKind, SimOptions};
use crate::study::engine::{par_stage, timed, Progress, Reduced};
use crate::train::{fallback, train, Algo, BpParams, TrainConfig};
use anyhow::{anyhow, Context, Result};
use hvs_shared::runtime::blob::OutputKind;
use hvs_shared::runtime::gaze::HALF_BASELINE_CM;
use hvs_shared::runtime::traditional::{phi_estimate, Calibration};
use hvs_shared::sim::camera::Rig;
use hvs_shared::sim::metrics::EmaAcc;
use hvs_shared::sim::presets;
use std::collections::BTreeSet;
use std::time::Instant;

/// Depths of the Phi experiment (Figs. 4.3, 4.4), cm.
pub const PHI_DEPTHS: [f64; 7] = [45.0, 55.0, 65.0, 75.0, 85.0, 95.0, 105.0];
/// The reduced training-depth sets of Figs. 4.20-4.22 (cm).
pub const FEWER_DEPTHS: [&[f64]; 3] =
    [&[65.0, 165.0], &[65.0, 115.0, 165.0], &[65.0, 95.0, 135.0, 165.0]];
/// The case the thesis treats as the general one (section 4.2.2): IV.
pub const GENERAL_CASE: u8 = 4;

/// What to run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Config {
    /// Seed of every random step.
    pub seed: u64,
    /// Reduced run: fewer restarts, nets, noise levels and test points (for tests).
    pub quick: bool,
}

impl Reduced for Config {
    fn quick(&self) -> bool {
        self.quick
    }
}

impl Config {
    /// Restarts of the proposed net (the trainer's default, 10; 2 when quick).
    pub fn restarts(&self) -> usize {
        self.pick(TrainConfig::default().restarts, 2)
    }
    /// Nets per hidden-neuron count and output kind (the thesis' ten; 2 when quick).
    pub fn nets(&self) -> usize {
        self.pick(10, 2)
    }
    /// Hidden-neuron counts of the sweep: 1-10 as in the thesis (1, 3, 5, 8 when quick).
    pub fn hidden(&self) -> &'static [usize] {
        self.pick(&[1, 2, 3, 4, 5, 6, 7, 8, 9, 10], &[1, 3, 5, 8])
    }
    /// Pixel-noise levels (px): 0 to 1 in steps of 0.1 (0, 0.5, 1 when quick).
    pub fn noise_levels(&self) -> Vec<f64> {
        let steps = self.pick(10, 2);
        (0..=steps).map(|k| k as f64 / steps as f64).collect()
    }
    /// Independent noise draws averaged per level (3; 1 when quick).
    pub fn noise_repeats(&self) -> usize {
        self.pick(3, 1)
    }
    /// Random test points of the training volume in the noise experiment.
    pub fn volume_points(&self) -> usize {
        self.pick(500, 100)
    }
    /// Back-propagation settings: the trainer's defaults (300 cycles when quick).
    pub fn bp(&self) -> BpParams {
        let full = BpParams::default();
        BpParams { max_cycles: self.pick(full.max_cycles, 300), ..full }
    }
    /// The proposed net's training configuration.
    pub fn proposed(&self) -> TrainConfig {
        let restarts = self.restarts();
        TrainConfig { seed: self.seed, restarts, progress: false, ..TrainConfig::default() }
    }
}

/// Seed of item `(tag, a, b)` of a run with seed `seed` (SplitMix64 finaliser of a mix).
pub fn derive_seed(seed: u64, tag: u64, a: u64, b: u64) -> u64 {
    let mut z = seed
        ^ tag.wrapping_mul(0x9E37_79B9_7F4A_7C15)
        ^ a.wrapping_mul(0xD1B5_4A32_D192_ED03)
        ^ b.wrapping_mul(0x8CB9_2BA7_2F3D_8DD7);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

const TAG_NET: u64 = 1;
const TAG_NOISE_TRAIN: u64 = 2;
const TAG_NOISE_TEST: u64 = 3;
/// The stages that run in parallel, named as the stage times name them.
const SWEEP: &str = "Figs. 4.13-4.15";
const NOISE: &str = "pixel noise";

/// e_ma (%) of an estimator per test depth `z` (cm) and over all test points (`mean`).
#[derive(Debug, Clone, PartialEq)]
pub struct DepthCurve {
    pub z: Vec<f64>,
    pub pct: Vec<f64>,
    pub mean: f64,
}

impl DepthCurve {
    /// Largest per-depth e_ma (%).
    pub fn worst(&self) -> f64 {
        self.pct.iter().copied().fold(f64::NEG_INFINITY, f64::max)
    }
    /// Smallest per-depth e_ma (%).
    pub fn best(&self) -> f64 {
        self.pct.iter().copied().fold(f64::INFINITY, f64::min)
    }
}

fn curve(test: &Dataset, z_hat: Vec<f64>) -> DepthCurve {
    let ev = evaluate(test, &[Method { name: String::new(), z: z_hat }]);
    DepthCurve {
        z: ev.depths.iter().map(|d| d.z_min).collect(),
        pct: ev.depths.iter().map(|d| d.methods[0].e_ma_pct).collect(),
        mean: ev.methods[0].mean.e_ma_pct,
    }
}

/// A trained net's training e_ma (%), curve on the test set and training wall time (s).
type Trained = (f64, DepthCurve, f64);

/// The net trained on `set` by `tc` (`what` names it in errors), tested on `test`.
fn net(set: &Dataset, test: &Dataset, tc: &TrainConfig, what: String) -> Result<Trained> {
    let t = Instant::now();
    let out = train(set, tc).context(what)?;
    let wall_s = t.elapsed().as_secs_f64();
    let z = model_depths(&out.blob, test)
        .map_err(|e| anyhow!("the model cannot run on the set: {e:?}"))?;
    Ok((out.train_error_pct, curve(test, z), wall_s))
}

fn rig(case: u8) -> Result<Rig> {
    presets::case(case).ok_or_else(|| anyhow!("no case {case}"))
}

fn pixels(r: &Rig, p: [f64; 3]) -> Result<[f64; 4]> {
    r.project_rounded(&p).map_err(|e| anyhow!("point {p:?} has no image: {e:?}"))
}

/// The thesis protocol of a case: training boards (72 points) and test points (22).
pub fn protocol(case: u8) -> Result<(Dataset, Dataset)> {
    let r = rig(case)?;
    let set = |kind| simulate(&r, kind, &SimOptions::default()).map(|s| dataset(&s));
    Ok((set(SetKind::Train)?, set(SetKind::Test)?))
}

/// One depth (cm) of the Phi experiment in case 1 or 2: Phi_L, Phi_R and the true values (px).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PhiRow {
    pub case: u8,
    pub z: f64,
    pub phi_l: f64,
    pub phi_r: f64,
    pub true_l: f64,
    pub true_r: f64,
}

/// The 12 board points (X -3, -1, 1, 3 and Y -2, 0, 2 cm around `centre_x`) at depth `z`.
fn board_about(centre_x: f64, z: f64) -> [[f64; 3]; 12] {
    presets::board_points(z).map(|[x, y, z]| [centre_x + x, y, z])
}

/// Figs. 4.3, 4.4: Phi_L, Phi_R of cases I, II by eq. 4.1-3 from rounded pixels (the points
/// symmetric about the other camera's axis cancel the `X_R (Phi_L - Phi_R)` terms).
pub fn phi() -> Result<Vec<PhiRow>> {
    let mut rows = Vec::new();
    for case in [1u8, 2] {
        let r = rig(case)?;
        let d = r.half_baseline;
        for z in PHI_DEPTHS {
            let est = |centre: f64| -> Result<f64> {
                let px = board_about(centre, z).map(|p| pixels(&r, p).map(|px| (px[0], px[2])));
                let pairs = px.into_iter().collect::<Result<Vec<_>>>()?;
                phi_estimate(&pairs, z, d).map_err(|e| anyhow!("case {case}, Z = {z} cm: {e}"))
            };
            let (phi_l, phi_r, true_l, true_r) = (est(d)?, est(-d)?, r.phi_u_left, r.phi_u_right);
            rows.push(PhiRow { case, z, phi_l, phi_r, true_l, true_r });
        }
    }
    Ok(rows)
}

/// One case's test set: eq. 3.1-17 with [`Calibration::BUILT_IN`], and the floor.
#[derive(Debug, Clone, PartialEq)]
pub struct TraditionalCase {
    pub case: u8,
    pub traditional: DepthCurve,
    pub optimal: DepthCurve,
}

/// Figs. 4.8-4.11: eq. 3.1-17 with the thesis' one Phi (case I, 65 cm) on each case's test set.
pub fn traditional() -> Result<Vec<TraditionalCase>> {
    (1..=4u8)
        .map(|case| {
            let (_, test) = protocol(case)?;
            let traditional = curve(&test, traditional_depths(&Calibration::BUILT_IN, &test));
            let optimal = curve(&test, optimal_depths(&rig(case)?, &test));
            Ok(TraditionalCase { case, traditional, optimal })
        })
        .collect()
}

/// The proposed net on one case: training e_ma (%), the net and the floor on the test set.
#[derive(Debug, Clone, PartialEq)]
pub struct ProposedCase {
    pub case: u8,
    pub train_pct: f64,
    pub net: DepthCurve,
    pub optimal: DepthCurve,
}

/// Figs. 4.12 (case IV) and 4.16-4.19: the default `hvs train` net on each case's protocol.
pub fn proposed(cfg: &Config, progress: &dyn Progress) -> Result<Vec<ProposedCase>> {
    (1..=4u8)
        .map(|case| {
            let (train_set, test) = protocol(case)?;
            let (train_pct, net, _) =
                net(&train_set, &test, &cfg.proposed(), format!("case {case}"))?;
            progress.inc();
            let optimal = curve(&test, optimal_depths(&rig(case)?, &test));
            Ok(ProposedCase { case, train_pct, net, optimal })
        })
        .collect()
}

/// One net of the case IV sweep: shape, 0-based number, seed, training/mean/worst-depth e_ma (%).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NetRow {
    pub outputs: OutputKind,
    pub hidden: usize,
    pub index: usize,
    pub seed: u64,
    pub train_pct: f64,
    pub test_mean_pct: f64,
    pub test_worst_pct: f64,
}

/// Figs. 4.13-4.15: [`Config::nets`] nets per hidden count and output kind, one start each.
pub fn hidden_sweep(cfg: &Config, progress: &dyn Progress) -> Result<Vec<NetRow>> {
    let (train_set, test) = protocol(GENERAL_CASE)?;
    let mut jobs = Vec::new();
    for outputs in [OutputKind::Z, OutputKind::Xyz] {
        for &hidden in cfg.hidden() {
            jobs.extend((0..cfg.nets()).map(|index| (outputs, hidden, index)));
        }
    }
    par_stage(progress, SWEEP, &jobs, |&(outputs, hidden, index)| {
        let seed = derive_seed(cfg.seed, TAG_NET, hidden as u64, index as u64);
        let tc = TrainConfig { hidden, outputs, restarts: 1, seed, ..cfg.proposed() };
        let what = format!("{hidden} hidden, {outputs:?}, net {index}");
        let (train_pct, c, _) = net(&train_set, &test, &tc, what)?;
        let (test_mean_pct, test_worst_pct) = (c.mean, c.worst());
        Ok(NetRow { outputs, hidden, index, seed, train_pct, test_mean_pct, test_worst_pct })
    })
}

/// The hidden-neuron counts present in `rows`, ascending.
pub fn hidden_counts(rows: &[NetRow]) -> Vec<usize> {
    rows.iter().map(|r| r.hidden).collect::<BTreeSet<_>>().into_iter().collect()
}

/// The thesis' `e_ma_Hn`: the nets' mean worst per-depth e_ma per count of [`hidden_counts`].
pub fn e_ma_hn(rows: &[NetRow], outputs: OutputKind) -> Vec<f64> {
    per_hidden(rows, outputs, |r| r.test_worst_pct)
}

/// Mean of the nets' e_ma over all test points for each count of [`hidden_counts`].
pub fn mean_e_ma_hn(rows: &[NetRow], outputs: OutputKind) -> Vec<f64> {
    per_hidden(rows, outputs, |r| r.test_mean_pct)
}

fn per_hidden(rows: &[NetRow], outputs: OutputKind, f: impl Fn(&NetRow) -> f64) -> Vec<f64> {
    let of = |h| rows.iter().filter(move |r| r.outputs == outputs && r.hidden == h).map(&f);
    hidden_counts(rows).into_iter().map(|h| mean(&of(h).collect::<Vec<_>>())).collect()
}

/// The proposed net by LM and by back-propagation trained at `depths` (cm) of case IV.
#[derive(Debug, Clone, PartialEq)]
pub struct FewerDepths {
    pub depths: Vec<f64>,
    pub points: usize,
    pub net: DepthCurve,
    pub bp: DepthCurve,
}

/// Figs. 4.20-4.22: the proposed net (LM and BP) on case IV's boards at [`FEWER_DEPTHS`] only.
pub fn fewer_depths(cfg: &Config, progress: &dyn Progress) -> Result<Vec<FewerDepths>> {
    let r = rig(GENERAL_CASE)?;
    let (_, test) = protocol(GENERAL_CASE)?;
    let tc = cfg.proposed();
    let bp_tc = TrainConfig { algo: Algo::Bp, bp: cfg.bp(), ..tc.clone() };
    FEWER_DEPTHS
        .iter()
        .map(|depths| {
            let boards = depths.iter().flat_map(|&z| presets::board_points(z));
            let samples = boards.map(|p| Ok(Sample { px: pixels(&r, p)?, xyz: p }));
            let set = dataset(&samples.collect::<Result<Vec<_>>>()?);
            let (_, net_curve, _) = net(&set, &test, &tc, format!("training depths {depths:?}"))?;
            progress.inc();
            let (_, bp, _) =
                net(&set, &test, &bp_tc, format!("training depths {depths:?}, back-propagation"))?;
            progress.inc();
            Ok(FewerDepths { depths: depths.to_vec(), points: set.len(), net: net_curve, bp })
        })
        .collect()
}

/// One algorithm on one case: training, mean and worst per-depth test e_ma (%), wall time (s).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AlgoRow {
    pub case: u8,
    pub algo: Algo,
    pub train_pct: f64,
    pub test_mean_pct: f64,
    pub test_worst_pct: f64,
    pub wall_s: f64,
}

/// BP vs. LM per case, same net and seed; run one after the other so their wall times compare.
pub fn bp_vs_lm(cfg: &Config, progress: &dyn Progress) -> Result<Vec<AlgoRow>> {
    let mut rows = Vec::new();
    for case in 1..=4u8 {
        let (train_set, test) = protocol(case)?;
        for algo in [Algo::Lm, Algo::Bp] {
            let tc = TrainConfig { algo, bp: cfg.bp(), ..cfg.proposed() };
            let (train_pct, c, wall_s) =
                net(&train_set, &test, &tc, format!("case {case}, {algo:?}"))?;
            progress.inc();
            let (test_mean_pct, test_worst_pct) = (c.mean, c.worst());
            rows.push(AlgoRow { case, algo, train_pct, test_mean_pct, test_worst_pct, wall_s });
        }
    }
    Ok(rows)
}

/// One noise sigma (px) of a case, e_ma means over `repeats` draws (%): traditional (refitted
/// Phi; `traditional_missing_pct` of the points get none), the net and the floor.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NoiseRow {
    pub case: u8,
    pub sigma: f64,
    pub repeats: usize,
    pub traditional_pct: f64,
    pub traditional_missing_pct: f64,
    pub network_pct: f64,
    pub optimal_pct: f64,
}

/// e_ma vs. pixel noise on the boards and [`Config::volume_points`] random test points.
pub fn noise(cfg: &Config, progress: &dyn Progress) -> Result<Vec<NoiseRow>> {
    let levels = cfg.noise_levels();
    let jobs: Vec<(u8, usize, f64)> = (1..=4u8)
        .flat_map(|case| levels.iter().enumerate().map(move |(k, &s)| (case, k, s)))
        .collect();
    let (tc, repeats) = (cfg.proposed(), cfg.noise_repeats());
    par_stage(progress, NOISE, &jobs, |&(case, k, sigma)| {
        let r = rig(case)?;
        let mut sums = [0.0; 3];
        let (mut missing, mut points) = (0usize, 0usize);
        for rep in 0..repeats {
            let item = (case as u64) << 32 | (k as u64) << 16 | rep as u64;
            let sim = |kind, points, tag| {
                let seed = derive_seed(cfg.seed, tag, item, 0);
                let opt = SimOptions { points, noise_px: sigma, seed, ..SimOptions::default() };
                simulate(&r, kind, &opt).map(|s| dataset(&s))
            };
            let boards = sim(SetKind::Train, 0, TAG_NOISE_TRAIN)?;
            let test = sim(SetKind::Volume, cfg.volume_points(), TAG_NOISE_TEST)?;
            let (_, c, _) = net(&boards, &test, &tc, format!("case {case}, noise {sigma} px"))?;
            let fit = fallback::fit(&boards, HALF_BASELINE_CM, r.u0, r.v0);
            let nan = vec![f64::NAN; test.len()];
            let trad = fit.map_or(nan, |f| traditional_depths(&f.calibration, &test));
            // The traditional method over the points it answers for (the others are
            // counted): one zero disparity would make its mean infinite.
            let mut acc = EmaAcc::default();
            for (zh, t) in trad.iter().zip(&test.targets).filter(|(zh, _)| zh.is_finite()) {
                acc.add(t[2], *zh);
            }
            missing += trad.iter().filter(|zh| !zh.is_finite()).count();
            points += test.len();
            let floor = curve(&test, optimal_depths(&r, &test)).mean;
            sums = [sums[0] + acc.e_ma_pct(), sums[1] + c.mean, sums[2] + floor];
        }
        let [traditional_pct, network_pct, optimal_pct] = sums.map(|s| s / repeats as f64);
        let traditional_missing_pct = missing as f64 / points as f64 * 100.0;
        Ok(NoiseRow {
            case,
            sigma,
            repeats,
            traditional_pct,
            traditional_missing_pct,
            network_pct,
            optimal_pct,
        })
    })
}

/// Everything [`run`] measured, per experiment, with the stage times and threads used.
#[derive(Debug, Clone)]
pub struct Thesis {
    pub config: Config,
    pub phi: Vec<PhiRow>,
    pub traditional: Vec<TraditionalCase>,
    pub proposed: Vec<ProposedCase>,
    pub sweep: Vec<NetRow>,
    pub fewer: Vec<FewerDepths>,
    pub algos: Vec<AlgoRow>,
    pub noise: Vec<NoiseRow>,
    /// Wall time of each stage (s), in run order; not deterministic.
    pub stage_s: Vec<(&'static str, f64)>,
    pub threads: usize,
}

/// Runs every experiment.
pub fn run(cfg: &Config, progress: &dyn Progress) -> Result<Thesis> {
    let mut s = Vec::new();
    let (phi, traditional) = stage(progress, &mut s, "Figs. 4.3-4.11", 2, || {
        Ok((phi().inspect(|_| progress.inc())?, traditional().inspect(|_| progress.inc())?))
    })?;
    let proposed = stage(progress, &mut s, "Figs. 4.12, 4.16-4.19", 4, || proposed(cfg, progress))?;
    let sweep = timed(&mut s, SWEEP, || hidden_sweep(cfg, progress))?;
    let units = 2 * FEWER_DEPTHS.len();
    let fewer = stage(progress, &mut s, "Figs. 4.20-4.22", units, || fewer_depths(cfg, progress))?;
    let algos = stage(progress, &mut s, "BP vs. LM", 8, || bp_vs_lm(cfg, progress))?;
    let noise = timed(&mut s, NOISE, || noise(cfg, progress))?;
    let (config, threads, stage_s) = (*cfg, rayon::current_num_threads(), s);
    Ok(Thesis { config, phi, traditional, proposed, sweep, fewer, algos, noise, stage_s, threads })
}

/// [`timed`] `f` as the stage `name` of `units` steps of `progress`.
fn stage<T>(
    progress: &dyn Progress,
    stage_s: &mut Vec<(&'static str, f64)>,
    name: &'static str,
    units: usize,
    f: impl FnOnce() -> Result<T>,
) -> Result<T> {
    progress.start(name, units as u64);
    let out = timed(stage_s, name, f);
    progress.finish();
    out
}
