//! Training: fits the f32 MLP of `hvs_shared::runtime::mlp` to a [`Dataset`] and returns the
//! [`ModelBlob`] the head runs.
//!
//! - Scaling comes from the data and is stored in the blob: each input is centred on the
//!   middle of its training range; the four pixel inputs share one scale (the widest pixel
//!   range maps onto `[-1, 1]`, so a pixel of rounding weighs the same on every input and the
//!   weight decay does not favour the narrow-range `v` inputs), joint angles get their own.
//!   Outputs map `[-1, 1]` (linear outputs) or the thesis' sigmoid band `[0.1, 0.9]`
//!   (back-propagation) onto their training range. The training box (`in_min`, `in_max`) is
//!   the inputs' range.
//! - Training runs in f64 in normalised units. The f32-rounded scaling is used for that, so
//!   the trained f64 net and the exported f32 one differ only by parameter rounding and
//!   arithmetic precision.
//! - Every restart is exported to f32 and judged by its training e_ma in percent
//!   (`mean(|Z - Z^| / Z) * 100`, `hvs_shared::sim::metrics`) computed with `ModelBlob::infer`,
//!   i.e. exactly what the head computes. Restarts above the threshold are not enrolled (as
//!   in the thesis); the best enrolled one (lowest e_ma, then lowest index) is returned. With
//!   synthetic points (below) the threshold judges the returned model instead: the best
//!   restart after its fit to all of them, the e_ma `hvs train` reports.
//! - Quantised pixels (`synthetic`): on a stereo set of integer pixels that a pinhole camera
//!   per side explains within rounding, the inverse-depth-skip family is fitted to synthetic
//!   points of the two cameras fitted to the data (3x4 matrices, residuals bounded rather than
//!   averaged), with one rounding step of uniform pixel noise; the restarts are still judged
//!   on the measured points.
//! - Restarts run in parallel on the rayon pool. Restart `i` draws its initial weights from
//!   a generator seeded by `(seed, i)` alone and no restart reads another's state, so the
//!   model bytes for a given seed do not depend on the number of threads.
//!
//! Algorithms ([`Algo`]):
//! - [`Algo::Lm`] (default): Levenberg-Marquardt (`lm`) on the residuals
//!   `(Y^ - Y) / Z` in cm, i.e. relative to the true depth of each point, for every output
//!   (the figure of merit is the relative depth error, so a centimetre at 65 cm counts 2.5
//!   times one at 165 cm), plus a weight decay [`WEIGHT_DECAY`]` / 2 * |p|^2`. Without the
//!   decay the 72-point board nets fit the pixel rounding of the six training depths and
//!   interpolate badly between them (worst per-depth test e_ma 6-12 % on cases I and III);
//!   with it the restarts agree with each other and generalise. Linear output layer.
//! - [`Algo::Adam`]: Adam (`adam`) on the same cost, full batch. Linear output layer.
//! - [`Algo::Bp`]: the thesis' 8-step per-pattern back-propagation (`bp`): sigmoid output
//!   layer, targets scaled into `[0.1, 0.9]`, unweighted eq. 2.1-5, learning rate, `E_max`
//!   and a learning-cycle cap.

mod adam;
mod bp;
mod chol;
mod decay;
pub mod describe;
mod exp_lanes;
pub mod fallback;
mod lm;
pub mod matcher;
pub mod model;
mod net;
mod rng;
mod synthetic;
pub mod update;

use crate::data::dataset::Dataset;
use anyhow::{bail, Result};
use hvs_shared::runtime::blob::{
    Algorithm, Family, InputKind, ModelBlob, OutputFrame, OutputKind, Skip, Topology, TrainingMeta,
    MAX_HIDDEN, MAX_INPUTS,
};
use hvs_shared::runtime::mlp::{Activation, OutputMap};
use hvs_shared::sim::metrics::EmaAcc;
use net::{Problem, Shape};
use rayon::prelude::*;
use rng::SplitMix64;
use std::time::{Duration, Instant};

pub use bp::BpParams;

/// Weight decay `alpha` of the LM and Adam cost `1/2 sum ((Y^ - Y) / Z)^2 + alpha/2 |p|^2`
/// (parameters in normalised units). Its weight relative to the data term falls as the
/// training set grows, so large sets are barely regularised.
pub const WEIGHT_DECAY: f64 = 1e-4;

/// LM settings of `train`: stop after 4 consecutive accepted steps that each improve the cost
/// by less than 1e-4 (relative), at most 200 steps. Tighter tolerances cost time and do not
/// change the test errors on the thesis' cases.
const LM_OPTIONS: lm::LmOptions = lm::LmOptions {
    max_iter: 200,
    rel_tol: 1e-4,
    patience: 4,
    weight_decay: WEIGHT_DECAY,
    tail: (0, 0.0),
};

/// Weight decay of the sigmoid net of a family with a linear skip term, per unit of the
/// noise-adaptive decay (`decay::decay`); the skip weights get the plain noise-adaptive decay.
/// The affine part carries the map, so the net only has to model what it misses (vergence,
/// distortion) and is held close to zero unless the pixels are precise: on the dev seeds
/// (`accuracy_regimes`, base 0) 10 overfits rounded thesis boards (1.18x the floor), 300
/// underfits the 9x6 board (1.34x), 30 is near the affine fit's ratio on both (1.12x, 1.02x)
/// and keeps exact pixels below 0.01 %. Not applied when the net learns the synthetic points
/// of quantised pixels (`synthetic`): 2,000 points do not overfit.
pub const SKIP_NET_DECAY_FACTOR: f64 = 30.0;

/// The sigmoid net's weight decay on a posture-aware set with sub-pixel pixels (corners
/// detected in images, `hvs collect` then `hvs board detect`): a hundredth of the
/// [`SKIP_NET_DECAY_FACTOR`] hold, which suits rounded pixels and kept such a net at 1.43x
/// the floor (simulated case III grid set of the 9x6 board with 0.015 px noise, seeds 11 and
/// 12: 9-16-3 at 0.096 % against a floor of 0.067 %; a hundredth of it with the longer fit of
/// [`PRECISE_POSTURE_LM`]: 0.072 %, 1.07x; no decay at all: 1.12x, its worst depth band
/// 1.5x).
pub const PRECISE_POSTURE_NET_DECAY: f64 = 0.01 * SKIP_NET_DECAY_FACTOR * WEIGHT_DECAY;

/// The sigmoid net's weight decay on such sets in the cyclopean frame (the default posture
/// frame): none. There the map bends little with the eye pans and the net is not held at all
/// (simulated stand-in of [`PRECISE_POSTURE_NET_DECAY`], seeds 11 and 12, 104,976 rows:
/// 9-16-3 1.007x the floor against 1.008x with that hold, worst posture band 1.015x and
/// 1.014x; 9-32-3 1.001x against 1.005x, worst band 1.004x and 1.011x; on the collected
/// case III set of the README, 9-32-3 1.03x against 1.07x, worst band 1.06x against 1.19x).
pub const PRECISE_CYCLOPEAN_NET_DECAY: f64 = 0.0;

/// LM's stopping rule on those sets: up to 600 steps, a relative tolerance of 1e-7 (with the
/// 200 steps and 1e-4 of the other sets the weaker hold alone reached 1.24x).
pub const PRECISE_POSTURE_LM: (usize, f64) = (600, 1e-7);

/// Whether `data` is a posture-aware set with ground truth whose pixels are not all whole
/// (detected corners rather than the simulator's rounded pixels).
fn subpixel_posture(data: &Dataset) -> bool {
    data.n_inputs == 9 && data.has_targets() && !synthetic::whole_pixels(data)
}

/// The smallest factor the lens excess can bring [`SKIP_NET_DECAY_FACTOR`] down to.
pub const MIN_SKIP_NET_DECAY_FACTOR: f64 = 0.01;

/// LM settings of a family on `data`, for a net with `n_skip` skip weights: the thesis
/// family's are fixed ([`LM_OPTIONS`]); the inverse-depth families' weight decay follows the
/// pixel noise of the data (`decay`; the thesis' [`WEIGHT_DECAY`] where it cannot be
/// estimated, as on posture-aware sets), times [`SKIP_NET_DECAY_FACTOR`] on the sigmoid net
/// when there is a skip term; sub-pixel posture-aware sets get [`PRECISE_POSTURE_NET_DECAY`]
/// ([`PRECISE_CYCLOPEAN_NET_DECAY`] in the cyclopean frame) and [`PRECISE_POSTURE_LM`].
fn lm_options(f: Family, frame: OutputFrame, data: &Dataset, n_skip: usize) -> lm::LmOptions {
    if f == Family::THESIS {
        return LM_OPTIONS;
    }
    let pixel_noise = decay::pixel_noise(data);
    let decay = decay::decay(pixel_noise.as_ref());
    // A lens that bends the image beyond the pixel noise is what the net is for: its hold
    // shrinks by that excess (`decay::PixelNoise::lens_excess`, 1 for pinhole cameras).
    // Posture-aware (9-input) sets have no pixel-noise estimate: the net is held with the
    // thesis' decay times the factor. In the eye platform's frame the map barely depends on
    // the neck and the eye tilt, so 324 postures of one board are nearly 324 copies of it and
    // an unheld net fits their pixel rounding (posture study, case III, seed 3: 1.23x the
    // floor over the working range; held, 1.01x; seeds 1-7 in `docs/posture-study.md`).
    // Sub-pixel posture sets are held far less (not at all in the cyclopean frame) and fitted
    // longer ([`PRECISE_POSTURE_NET_DECAY`], [`PRECISE_CYCLOPEAN_NET_DECAY`]).
    if n_skip > 0 && pixel_noise.is_none() && subpixel_posture(data) {
        let (max_iter, rel_tol) = PRECISE_POSTURE_LM;
        return lm::LmOptions {
            weight_decay: match frame {
                OutputFrame::Cyclopean => PRECISE_CYCLOPEAN_NET_DECAY,
                _ => PRECISE_POSTURE_NET_DECAY,
            },
            tail: (n_skip, decay),
            max_iter,
            rel_tol,
            ..LM_OPTIONS
        };
    }
    let net = match pixel_noise {
        Some(n) if n_skip > 0 => {
            (SKIP_NET_DECAY_FACTOR / n.lens_excess).max(MIN_SKIP_NET_DECAY_FACTOR) * decay
        }
        None if n_skip > 0 => SKIP_NET_DECAY_FACTOR * decay,
        _ => decay,
    };
    lm::LmOptions { weight_decay: net, tail: (n_skip, decay), ..LM_OPTIONS }
}

/// Training algorithm.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Algo {
    /// Levenberg-Marquardt on the relative depth error (fast and accurate; the default).
    #[default]
    Lm,
    /// The thesis' per-pattern back-propagation (eqs. 2.1-3 to 2.1-8).
    Bp,
    /// Adam, full batch, on the same loss as LM.
    Adam,
}

impl Algo {
    fn algorithm(self) -> Algorithm {
        match self {
            Algo::Lm => Algorithm::Lm,
            Algo::Bp => Algorithm::Bp,
            Algo::Adam => Algorithm::Adam,
        }
    }
    fn output_activation(self) -> Activation {
        match self {
            Algo::Lm | Algo::Adam => Activation::Linear,
            Algo::Bp => Activation::Sigmoid,
        }
    }
}

/// Everything `train` needs besides the data.
#[derive(Debug, Clone, PartialEq)]
pub struct TrainConfig {
    /// Hidden units (1..=32).
    pub hidden: usize,
    /// `X, Y, Z` or `Z` only.
    pub outputs: OutputKind,
    /// Algorithm.
    pub algo: Algo,
    /// Restarts from seeded random weights (1..=65535).
    pub restarts: usize,
    /// Restarts whose training e_ma (percent) exceeds this are not enrolled; with synthetic
    /// points, no model is returned when the best restart's, after its fit to all of them,
    /// exceeds it.
    pub threshold_pct: Option<f64>,
    /// Seed of the whole run.
    pub seed: u64,
    /// Parameters of [`Algo::Bp`].
    pub bp: BpParams,
    /// Draw a progress bar on stderr.
    pub progress: bool,
    /// Model family: what the outputs are ([`Family::THESIS`]: X, Y, Z;
    /// [`Family::INVERSE_DEPTH`]: X/Z, Y/Z, 1/Z).
    pub family: Family,
    /// The frame the net learns its points in ([`OutputFrame::Cyclopean`],
    /// [`OutputFrame::EyePlatform`]: posture-aware sets only; the targets are turned into it,
    /// the model turns its points back).
    pub frame: OutputFrame,
}

impl Default for TrainConfig {
    /// The thesis' 4-5-3 net, Levenberg-Marquardt, 10 restarts, no threshold, seed 0.
    fn default() -> Self {
        TrainConfig {
            hidden: 5,
            outputs: OutputKind::Xyz,
            algo: Algo::Lm,
            restarts: 10,
            threshold_pct: None,
            seed: 0,
            bp: BpParams::default(),
            progress: false,
            family: Family::THESIS,
            frame: OutputFrame::Head,
        }
    }
}

/// How one restart ended.
#[derive(Debug, Clone, PartialEq)]
pub struct RestartReport {
    /// Restart index (0-based).
    pub index: usize,
    /// Training e_ma in percent of the exported f32 model (infinite if it is unusable).
    pub train_error_pct: f64,
    /// Whether it passed the threshold.
    pub enrolled: bool,
    /// LM steps, BP learning cycles or Adam epochs.
    pub iterations: usize,
}

/// The result of [`train`].
#[derive(Debug, Clone)]
pub struct TrainOutcome {
    /// The best enrolled model, `generation` 0 and no fallback calibration (the caller adds
    /// those).
    pub blob: ModelBlob,
    /// Its training e_ma in percent (also in `blob.meta`, as f32).
    pub train_error_pct: f64,
    /// Every restart, in index order.
    pub restarts: Vec<RestartReport>,
    /// Wall time of the whole run.
    pub elapsed: Duration,
    /// Quantised pixels: how many synthetic points of the cameras fitted to them the net
    /// learned from instead of the measured points (`None`: the measured points).
    pub synthetic_points: Option<usize>,
    /// Whether those synthetic points came from cameras with fitted radial lenses (sub-pixel
    /// pixels, `synthetic::lens_distilled`) rather than from pinhole cameras fitted to
    /// integer pixels.
    pub synthetic_lenses: bool,
}

/// Affine maps between physical and normalised units, already rounded to f32 as stored.
#[derive(Debug, Clone)]
struct Scaling {
    in_offset: Vec<f32>,
    in_scale: Vec<f32>,
    out_offset: Vec<f32>,
    out_scale: Vec<f32>,
    in_min: Vec<f32>,
    in_max: Vec<f32>,
}

fn range(values: impl Iterator<Item = f64>) -> (f64, f64) {
    values.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| (lo.min(v), hi.max(v)))
}

/// Smallest range treated as a varying column; below it the column is held constant.
const MIN_SPAN: f64 = 1e-6;

/// What output column `col` of `[x, y, z]` is trained on under `map`.
fn target_value(map: OutputMap, col: usize, t: &[f64; 3]) -> f64 {
    match map {
        OutputMap::Direct => t[col],
        OutputMap::InverseDepth if col == 2 => 1.0 / t[2],
        OutputMap::InverseDepth => t[col] / t[2],
    }
}

/// Weight of the residual of output column `col` (in normalised units, output scale `scale`)
/// so that it is the error in cm relative to the true depth `t[2]`, to first order: `X, Y, Z`
/// directly; `X/Z, Y/Z` as they are (`dX / Z = d(X/Z)`), `1/Z` times `Z` (`dZ / Z = Z d(1/Z)`).
fn residual_weight(map: OutputMap, col: usize, scale: f64, t: &[f64; 3]) -> f64 {
    match map {
        OutputMap::Direct => scale / t[2],
        OutputMap::InverseDepth if col == 2 => scale * t[2],
        OutputMap::InverseDepth => scale,
    }
}

fn scaling(data: &Dataset, out_cols: &[usize], act: Activation, map: OutputMap) -> Scaling {
    let ni = data.n_inputs;
    let mut s = Scaling {
        in_offset: Vec::new(),
        in_scale: Vec::new(),
        out_offset: Vec::new(),
        out_scale: Vec::new(),
        in_min: Vec::new(),
        in_max: Vec::new(),
    };
    let ranges: Vec<(f64, f64)> =
        (0..ni).map(|i| range((0..data.len()).map(|n| data.row(n)[i]))).collect();
    let pixel_span = ranges.iter().take(4).map(|(lo, hi)| hi - lo).fold(0.0, f64::max);
    for (i, &(lo, hi)) in ranges.iter().enumerate() {
        s.in_min.push(lo as f32);
        s.in_max.push(hi as f32);
        s.in_offset.push((0.5 * (lo + hi)) as f32);
        let span = if i < 4 { pixel_span } else { hi - lo };
        s.in_scale.push(if span > MIN_SPAN { 2.0 / span } else { 1.0 } as f32);
    }
    for &k in out_cols {
        let (lo, hi) = range(data.targets.iter().map(|t| target_value(map, k, t)));
        let span = hi - lo;
        let (off, scale) = match act {
            // y = a * scale + offset maps a in [-1, 1] onto [lo, hi].
            Activation::Linear if span > MIN_SPAN => (0.5 * (lo + hi), 0.5 * span),
            Activation::Linear => (lo, 1.0),
            // sigmoid in [0.1, 0.9] onto [lo, hi].
            Activation::Sigmoid if span > MIN_SPAN => (lo - 0.125 * span, span / 0.8),
            Activation::Sigmoid => (lo - 0.5, 1.0),
        };
        s.out_offset.push(off as f32);
        s.out_scale.push(scale as f32);
    }
    s
}

/// Columns of `[x, y, z]` the outputs are, and the index of Z among the outputs.
fn output_columns(kind: OutputKind) -> (&'static [usize], usize) {
    match kind {
        OutputKind::Xyz => (&[0, 1, 2], 2),
        OutputKind::Z => (&[2], 0),
    }
}

fn problem(data: &Dataset, cfg: &TrainConfig, sc: &Scaling) -> Problem {
    let act = cfg.algo.output_activation();
    let (cols, _) = output_columns(cfg.outputs);
    let shape = Shape::new(data.n_inputs, cfg.hidden, cols.len(), cfg.family.skip == Skip::Linear);
    let n = data.len();
    let mut x = Vec::with_capacity(n * shape.ni);
    for row in 0..n {
        for (i, v) in data.row(row).iter().enumerate() {
            x.push((v - sc.in_offset[i] as f64) * sc.in_scale[i] as f64);
        }
    }
    let mut t = Vec::with_capacity(n * shape.no);
    let mut c = Vec::with_capacity(n * shape.no);
    for target in &data.targets {
        for (k, &col) in cols.iter().enumerate() {
            let (off, scale) = (sc.out_offset[k] as f64, sc.out_scale[k] as f64);
            let map = cfg.family.output_map;
            t.push((target_value(map, col, target) - off) / scale);
            // Residual in cm relative to the true depth; back-propagation keeps the thesis'
            // unweighted error (eq. 2.1-5).
            c.push(match cfg.algo {
                Algo::Lm | Algo::Adam => residual_weight(map, col, scale, target),
                Algo::Bp => 1.0,
            });
        }
    }
    Problem { shape, output: act, n, x, t, c }
}

/// Uniform random initial weights: first layer in `[-1, 1]` (inputs are in `[-1, 1]`, so
/// every hidden unit starts in its sigmoid's working range), second layer in `[-0.5, 0.5]`.
fn initial_params(shape: &Shape, rng: &mut SplitMix64) -> Vec<f64> {
    let mut p = vec![0.0; shape.n_params()];
    for j in 0..shape.nh {
        for i in 0..=shape.ni {
            p[shape.w1(j, i)] = rng.uniform(-1.0, 1.0);
        }
    }
    for k in 0..shape.no {
        for j in 0..=shape.nh {
            p[shape.w2(k, j)] = rng.uniform(-0.5, 0.5);
        }
    }
    p
}

/// The blob of f64 parameters `p`, or `None` if they do not make a valid f32 model.
fn export(
    p: &[f64],
    data: &Dataset,
    cfg: &TrainConfig,
    sc: &Scaling,
    train_error_pct: f64,
) -> Option<ModelBlob> {
    let hv = |v: &[f32]| heapless::Vec::from_slice(v).ok();
    let params: Vec<f32> = p.iter().map(|v| *v as f32).collect();
    let blob = ModelBlob {
        generation: 0,
        topology: Topology {
            inputs: data.input_kind()?,
            hidden: u8::try_from(cfg.hidden).ok()?,
            outputs: cfg.outputs,
            output_activation: cfg.algo.output_activation(),
        },
        in_offset: hv(&sc.in_offset)?,
        in_scale: hv(&sc.in_scale)?,
        out_offset: heapless::Vec::from_slice(&sc.out_offset).ok()?,
        out_scale: heapless::Vec::from_slice(&sc.out_scale).ok()?,
        params: heapless::Vec::from_slice(&params).ok()?,
        in_min: hv(&sc.in_min)?,
        in_max: hv(&sc.in_max)?,
        meta: TrainingMeta {
            seed: cfg.seed,
            train_hash: data.hash(),
            train_points: u32::try_from(data.len()).ok()?,
            train_error_pct: train_error_pct as f32,
            algorithm: cfg.algo.algorithm(),
            restarts: u16::try_from(cfg.restarts).ok()?,
        },
        fallback: None,
        family: cfg.family,
        matcher: None,
        frame: cfg.frame,
        image_size: None,
        parent: None,
    };
    blob.validate().ok()?;
    Some(blob)
}

/// e_ma in percent of the blob's depth estimates on `data`, through `ModelBlob::infer` in
/// f32 (a refused inference counts as an infinite error).
pub fn blob_error_pct(blob: &ModelBlob, data: &Dataset) -> f64 {
    let (_, zi) = output_columns(blob.topology.outputs);
    let mut acc = EmaAcc::default();
    let mut x = vec![0.0f32; data.n_inputs];
    let mut out = vec![0.0f32; blob.n_outputs()];
    for (n, t) in data.targets.iter().enumerate() {
        for (xi, v) in x.iter_mut().zip(data.row(n)) {
            *xi = *v as f32;
        }
        let z_hat = match blob.infer(&x, &mut out) {
            Ok(()) => out[zi] as f64,
            Err(_) => f64::INFINITY,
        };
        acc.add(t[2], z_hat);
    }
    acc.e_ma_pct()
}

fn check(data: &Dataset, cfg: &TrainConfig) -> Result<()> {
    if data.is_empty() {
        bail!("the training set is empty");
    }
    if !data.has_targets() {
        bail!(
            "the training set has no ground truth for every row ({} targets for {} rows): \
             training needs x,y,z",
            data.targets.len(),
            data.len()
        );
    }
    if data.input_kind().is_none() || data.n_inputs > MAX_INPUTS {
        bail!(
            "the training set has {} inputs per row; a model takes 4 (pixels) or 9 (pixels and joint angles)",
            data.n_inputs
        );
    }
    if cfg.hidden == 0 || cfg.hidden > MAX_HIDDEN.min(hvs_shared::runtime::mlp::FLAT_MAX_HIDDEN) {
        bail!(
            "hidden units must be 1..={}, got {}",
            MAX_HIDDEN.min(hvs_shared::runtime::mlp::FLAT_MAX_HIDDEN),
            cfg.hidden
        );
    }
    if cfg.restarts == 0 || cfg.restarts > MAX_RESTARTS {
        bail!("restarts must be 1..={MAX_RESTARTS}, got {}", cfg.restarts);
    }
    if cfg.frame != OutputFrame::Head
        && (data.input_kind() != Some(InputKind::StereoJoints) || cfg.outputs != OutputKind::Xyz)
    {
        bail!(
            "the {} frame is for posture-aware sets (pixels and joint angles) with X, Y, Z outputs",
            cfg.frame.name()
        );
    }
    if let Some(t) = cfg.threshold_pct {
        if !(t.is_finite() && t > 0.0) {
            bail!("the threshold must be a positive percentage, got {}", crate::fmt::given(t));
        }
    }
    if cfg.algo == Algo::Bp {
        cfg.bp.check()?;
        if cfg.family.skip != Skip::None {
            bail!(
                "back-propagation trains the thesis' sigmoid-output net; the {} family needs lm or adam",
                cfg.family.name()
            );
        }
    }
    for (n, v) in data.inputs.iter().enumerate() {
        if !v.is_finite() {
            bail!(
                "input {} of row {} is not a finite number",
                n % data.n_inputs + 1,
                n / data.n_inputs + 1
            );
        }
    }
    for (n, t) in data.targets.iter().enumerate() {
        if !t.iter().all(|v| v.is_finite()) {
            bail!("the ground truth of row {} is not finite", n + 1);
        }
        if t[2] <= 0.0 {
            bail!("row {}: depth z = {} cm; the depth of a visible point is positive", n + 1, t[2]);
        }
    }
    Ok(())
}

/// The model family `hvs train`, `hvs demo` and the studies' default nets train when none is
/// chosen: inverse-depth outputs over a linear skip term; a posture-aware net of it gives its
/// points in the eye platform's frame ([`default_frame`]).
pub const DEFAULT_FAMILY: Family = Family::INVERSE_DEPTH_SKIP;

/// The family trained by `algo` when none is chosen: [`DEFAULT_FAMILY`], or the thesis' net
/// for back-propagation, which trains nets without a skip term only.
pub const fn default_family_for(algo: Algo) -> Family {
    match algo {
        Algo::Bp => Family::THESIS,
        Algo::Lm | Algo::Adam => DEFAULT_FAMILY,
    }
}

/// The algorithm a blob records, as `hvs train --algo` spells it.
pub fn algo_name(a: hvs_shared::runtime::blob::Algorithm) -> &'static str {
    use hvs_shared::runtime::blob::Algorithm;
    match a {
        Algorithm::Lm => "lm",
        Algorithm::Bp => "bp",
        Algorithm::Adam => "adam",
        Algorithm::Other => "other",
    }
}

/// The frame `hvs train` (and the posture study) gives a net of `family` on inputs `kind`:
/// the cyclopean one for a posture-aware set outside the thesis family (which is kept
/// exactly: head-frame X, Y, Z), the head frame otherwise. Posture study, case III, seed 1,
/// 9-16-3 inverse-depth-skip: 1.02x the floor overall and 1.11x in the extreme postures in
/// the head frame, 1.00x and 1.03x in the eye platform's frame, 1.00x and 1.01x in the
/// cyclopean frame (`docs/posture-study.md`). On a set collected by the head itself (the
/// board fixed, the head moving, so the board anywhere in the images) the cyclopean frame
/// matters more: 9-16-3 at 2.1x the floor in the platform frame, 1.2x in the cyclopean one
/// (README, `hvs collect`).
pub fn default_frame(family: Family, kind: InputKind) -> OutputFrame {
    if kind == InputKind::StereoJoints && family != Family::THESIS {
        OutputFrame::Cyclopean
    } else {
        OutputFrame::Head
    }
}

/// The most restarts a training takes: the model records their number in 16 bits.
pub const MAX_RESTARTS: usize = u16::MAX as usize;

/// Hidden units and restarts of `hvs train` when not given: 9-32-3 with one restart for a
/// posture-aware set of detected (sub-pixel) corners in a family with a skip term;
/// [`WIDE_FIELD_HIDDEN`] hidden units and 10 restarts for a stereo set in such a family whose
/// left pixels cover most of its images (`image_size`, the set's `image_width,image_height`;
/// [`wide_field`]); the thesis' 5 hidden units and 10 restarts otherwise. On the collected
/// case III set of the README (79,434 rows; the cyclopean frame): 9-32-3, one restart, 1.03x
/// the floor in 133 s; 9-16-3 1.21x in 46 s; 9-5-3 with 10 restarts 3.9x in 130 s. Ten
/// restarts of 9-32-3 would take ten times as long; one reached the floor on the simulated
/// stand-in too (1.001x).
pub fn default_size(
    family: Family,
    data: &Dataset,
    image_size: Option<(u16, u16)>,
) -> (usize, usize) {
    let skip = family.skip_len(data.n_inputs, 3) > 0;
    let restarts = TrainConfig::default().restarts;
    if skip && subpixel_posture(data) {
        (PRECISE_POSTURE_HIDDEN, 1)
    } else if skip && wide_field(data, image_size) {
        (WIDE_FIELD_HIDDEN, restarts)
    } else {
        (TrainConfig::default().hidden, restarts)
    }
}

/// Hidden units of a stereo net on a set whose pixels cover most of the image
/// ([`default_size`]): boards spread over the whole view, for depth over the whole image.
/// The thesis' 5 fit the middle of the image, not all of it: through case IV's verged
/// cameras, 4,536 corners of boards over the whole image at 70-320 cm
/// (`scripts/depth_verged.py`), the net alone on the true matches of two rendered scenes
/// gives a median depth error of 0.40 % with 5 hidden units, 0.08 % with 12, and `hvs depth`
/// 0.57 % against 0.46 % (8 units: 0.47-0.48 %; chosen on those two scenes).
pub const WIDE_FIELD_HIDDEN: usize = 12;

/// Share of the image's width and of its height the left pixels of a set must span to be
/// [`wide_field`].
pub const WIDE_FIELD_SPAN: f64 = 0.6;

/// Whether `data` is a stereo set with targets whose left pixels span at least
/// [`WIDE_FIELD_SPAN`] of the width and of the height of its images (`image_size`; `false`
/// without it). Boards in the middle of the view (the thesis' 72 points, a 9x6 board at
/// 65-165 cm: about a third of the width) are not.
pub fn wide_field(data: &Dataset, image_size: Option<(u16, u16)>) -> bool {
    let Some((w, h)) = image_size else { return false };
    if data.n_inputs != 4 || !data.has_targets() || data.is_empty() {
        return false;
    }
    let span = |k: usize| {
        let (lo, hi) = (0..data.len())
            .map(|i| data.row(i)[k])
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| (a.min(v), b.max(v)));
        hi - lo
    };
    span(0) >= WIDE_FIELD_SPAN * f64::from(w) && span(1) >= WIDE_FIELD_SPAN * f64::from(h)
}

impl TrainConfig {
    /// `hvs train`'s configuration for `data` (from images of `image_size`, when the set
    /// says) in `family` when nothing else is asked: the family's output frame for the set's
    /// inputs ([`default_frame`]; the head frame for a set without inputs' kind), its size
    /// ([`default_size`]), the rest [`TrainConfig::default`]. `hvs train` and `hvs view`'s
    /// retrain start from it.
    pub fn for_set(family: Family, data: &Dataset, image_size: Option<(u16, u16)>) -> Self {
        let (hidden, restarts) = default_size(family, data, image_size);
        let frame = data.input_kind().map_or(OutputFrame::Head, |k| default_frame(family, k));
        TrainConfig { family, frame, hidden, restarts, ..TrainConfig::default() }
    }
}

/// Hidden units of a posture-aware net on detected corners when `hvs train` is not told
/// ([`default_size`]); the largest a blob holds.
pub const PRECISE_POSTURE_HIDDEN: usize = hvs_shared::runtime::blob::MAX_HIDDEN;

/// `data` with its targets turned into `frame` (`None` for the head frame: `data` as it is).
/// The turn is the f64 twin of the model's f32 one (`OutputFrame::apply`), from the joint
/// inputs of each row.
fn in_output_frame(data: &Dataset, frame: OutputFrame) -> Option<Dataset> {
    if frame == OutputFrame::Head {
        return None;
    }
    let mut out = data.clone();
    for (n, t) in out.targets.iter_mut().enumerate() {
        let j = data.row(n);
        *t = match frame {
            OutputFrame::Cyclopean => {
                hvs_shared::sim::posture::base_to_cyclopean([j[4], j[5], j[6], j[7], j[8]], t)
            }
            _ => hvs_shared::sim::posture::base_to_platform([j[4], j[5], j[6]], t),
        };
    }
    Some(out)
}

/// Trains a model on `data` as `cfg` says. Errors name the problem: empty data, missing
/// ground truth, bad settings, or no restart under the threshold.
pub fn train(data: &Dataset, cfg: &TrainConfig) -> Result<TrainOutcome> {
    let start = Instant::now();
    check(data, cfg)?;
    // The net learns the targets in its output frame; the restarts are judged (and the error
    // reported) on `data` itself, through the model's own turn back into the head frame.
    let in_frame = in_output_frame(data, cfg.frame);
    let data_for_net = in_frame.as_ref().unwrap_or(data);
    let act = cfg.algo.output_activation();
    let (cols, _) = output_columns(cfg.outputs);
    let sc = scaling(data_for_net, cols, act, cfg.family.output_map);
    // Quantised pixels: the skip family learns from the fitted cameras (`synthetic`); the
    // scaling, the restart choice and the reported error stay those of the measured points.
    // Precise pixels through lenses (`synthetic::lens_distilled`) likewise learn from the
    // cameras and lenses fitted to them.
    let distilled = (cfg.family == Family::INVERSE_DEPTH_SKIP && cfg.algo != Algo::Bp)
        .then(|| synthetic::distilled(data, cfg.seed))
        .flatten();
    // The restarts learn the first `selection` synthetic points; the best one is then fitted
    // to all of them (below).
    let selection = distilled.as_ref().map(|d| synthetic::prefix(&d.set, d.selection));
    let fit_data = selection.as_ref().unwrap_or(data_for_net);
    let prob = problem(fit_data, cfg, &sc);
    let mut lm_opts = lm_options(
        cfg.family,
        cfg.frame,
        fit_data,
        cfg.family.skip_len(prob.shape.ni, prob.shape.no),
    );
    if distilled.is_some() {
        // 2,000 synthetic points do not overfit: the net gets the plain decay (tuning seeds:
        // worst volume ratio 1.034 vs 1.041 with the factor, protocol 1.06 vs 1.10-1.12).
        lm_opts.weight_decay = lm_opts.tail.1;
    }

    let bar = cfg.progress.then(|| {
        let b = indicatif::ProgressBar::new(cfg.restarts as u64);
        b.set_style(
            indicatif::ProgressStyle::with_template(
                "training {bar:30} {pos}/{len} restarts [{elapsed_precise}]",
            )
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
        );
        b
    });

    let runs: Vec<(RestartReport, Option<ModelBlob>, Vec<f64>)> = (0..cfg.restarts)
        .into_par_iter()
        .map(|index| {
            let mut rng = SplitMix64::for_restart(cfg.seed, index);
            let mut p = initial_params(&prob.shape, &mut rng);
            let iterations = match cfg.algo {
                Algo::Lm => lm::fit(&prob, &mut p, &lm_opts).iterations,
                Algo::Adam => adam::fit(&prob, &mut p, &adam::AdamOptions::default()).epochs,
                Algo::Bp => bp::fit(&prob, &mut p, &cfg.bp).cycles,
            };
            let mut blob = export(&p, data, cfg, &sc, 0.0);
            let err = blob.as_ref().map_or(f64::INFINITY, |b| blob_error_pct(b, data));
            if let Some(b) = blob.as_mut() {
                b.meta.train_error_pct = err as f32;
            }
            // With synthetic points the threshold judges the model the user gets, the best
            // restart fitted to all of them (below), not the restarts' own errors.
            let enrolled = blob.is_some()
                && err.is_finite()
                && (distilled.is_some() || cfg.threshold_pct.is_none_or(|t| err <= t));
            if let Some(b) = &bar {
                b.inc(1);
            }
            let report = RestartReport { index, train_error_pct: err, enrolled, iterations };
            (report, blob.filter(|_| enrolled), p)
        })
        .collect();
    if let Some(b) = &bar {
        b.finish_and_clear();
    }

    // Quantised pixels: the best restart, fitted to every synthetic point; kept when it
    // exports and its training e_ma on the measured points is finite.
    let polish = |all: &synthetic::Distilled, p: &[f64]| -> Option<(f64, ModelBlob)> {
        let opts = lm::LmOptions { max_iter: all.polish_iter, ..lm_opts };
        let mut p = p.to_vec();
        lm::fit(&problem(&all.set, cfg, &sc), &mut p, &opts);
        let mut b = export(&p, data, cfg, &sc, 0.0)?;
        let err = blob_error_pct(&b, data);
        err.is_finite().then(|| {
            b.meta.train_error_pct = err as f32;
            (err, b)
        })
    };
    // The first of the lowest training e_ma among the enrolled restarts.
    let best = runs
        .iter()
        .filter_map(|(rep, blob, p)| Some((rep.train_error_pct, blob.as_ref()?, p)))
        .min_by(|a, b| a.0.total_cmp(&b.0))
        .map(|(e, b, p)| {
            distilled.as_ref().and_then(|all| polish(all, p)).unwrap_or_else(|| (e, b.clone()))
        });
    let restarts: Vec<RestartReport> = runs.into_iter().map(|(r, _, _)| r).collect();
    if let (Some(t), Some((e, _)), Some(all)) = (cfg.threshold_pct, &best, &distilled) {
        if *e > t {
            bail!(
                "no restart enrolled: the best of {} restarts, fitted to all {} synthetic points, has a training e_ma of {e:.4} %, above the threshold {t} %",
                cfg.restarts,
                all.set.len()
            );
        }
    }
    let Some((train_error_pct, blob)) = best else {
        let best_err = restarts.iter().map(|r| r.train_error_pct).fold(f64::INFINITY, f64::min);
        match cfg.threshold_pct {
            Some(t) => bail!(
                "no restart enrolled: the best of {} restarts has a training e_ma of {best_err:.4} %, above the threshold {t} %",
                cfg.restarts
            ),
            None => bail!(
                "no restart enrolled: none of {} restarts produced a usable model (non-finite weights)",
                cfg.restarts
            ),
        }
    };
    Ok(TrainOutcome {
        blob,
        train_error_pct,
        restarts,
        elapsed: start.elapsed(),
        synthetic_points: distilled.as_ref().map(|d| d.set.len()),
        synthetic_lenses: distilled.as_ref().is_some_and(|d| d.lenses),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use hvs_shared::runtime::blob::InputKind;
    use hvs_shared::sim::{presets, triangulate};

    fn set(rig: &hvs_shared::sim::camera::Rig, points: &[[f64; 3]]) -> Dataset {
        let mut d = Dataset::new(InputKind::Stereo);
        for p in points {
            d.push(&rig.project_rounded(p).unwrap(), Some(*p));
        }
        d
    }

    /// The thesis protocol of case `n`: the 72 board points and the 22 test points.
    fn protocol(n: u8) -> (Dataset, Dataset) {
        let rig = presets::case(n).unwrap();
        let train: Vec<[f64; 3]> =
            presets::TRAIN_DEPTHS.iter().flat_map(|z| presets::board_points(*z)).collect();
        let mut test = Vec::new();
        for z in presets::TEST_DEPTHS {
            for [x, y] in presets::TEST_POINTS_XY {
                test.push([x, y, z]);
            }
        }
        (set(&rig, &train), set(&rig, &test))
    }

    /// Case `n`'s training set (see [`protocol`]) and the default configuration with
    /// `restarts` restarts from `seed`.
    fn protocol_with(n: u8, restarts: usize, seed: u64) -> (Dataset, TrainConfig) {
        let cfg = TrainConfig { restarts, seed, ..TrainConfig::default() };
        (protocol(n).0, cfg)
    }

    /// Worst per-depth e_ma (percent) over the test depths, of the depths `estimate` gives.
    fn worst_per_depth(test: &Dataset, estimate: impl Fn(&[f64]) -> f64) -> f64 {
        let mut worst: f64 = 0.0;
        for z in presets::TEST_DEPTHS {
            let mut acc = EmaAcc::default();
            for r in 0..test.len() {
                if test.targets[r][2] == z {
                    acc.add(z, estimate(test.row(r)));
                }
            }
            assert_eq!(acc.count(), 2);
            worst = worst.max(acc.e_ma_pct());
        }
        worst
    }

    fn net_z(blob: &ModelBlob, x: &[f64]) -> f64 {
        let xf: Vec<f32> = x.iter().map(|v| *v as f32).collect();
        let mut out = vec![0.0f32; blob.n_outputs()];
        blob.infer(&xf, &mut out).unwrap();
        out[blob.n_outputs() - 1] as f64
    }

    fn encode(blob: &ModelBlob) -> Vec<u8> {
        let mut buf = [0u8; hvs_shared::runtime::blob::MAX_BLOB_LEN];
        let n = blob.encode(&mut buf).unwrap();
        buf[..n].to_vec()
    }

    #[test]
    fn thesis_protocol_every_case() {
        // Cases I and II: below the thesis' 4 % worst per-depth test e_ma. Cases III and IV:
        // their test points round so that even the optimal triangulation with the true rig has
        // a worst depth of 3.9 % and 4.0 %; the net must stay within 1.5 times that.
        for n in 1..=4u8 {
            let (train_set, test_set) = protocol(n);
            let out = train(&train_set, &TrainConfig::default()).unwrap();
            let net = worst_per_depth(&test_set, |x| net_z(&out.blob, x));
            let rig = presets::case(n).unwrap();
            let floor = worst_per_depth(&test_set, |x| {
                triangulate::optimal_rig(&rig, &x.try_into().unwrap()).unwrap()[2]
            });
            if n <= 2 {
                assert!(net < 4.0, "case {n}: worst per-depth {net} %");
            }
            assert!(
                net < 1.5 * floor.max(1.0),
                "case {n}: worst per-depth {net} % vs optimal triangulation {floor} %"
            );
            assert!(out.train_error_pct < 2.0, "case {n}: {}", out.train_error_pct);
        }
    }

    #[test]
    fn skip_family_stores_skip_weights_and_stays_near_the_floor_on_the_protocol() {
        // Rounded pixels, the thesis protocol (two test points per depth): the worst test depth
        // of every case against optimal triangulation with the true rig. Measured (seed 7):
        // 1.06, 0.99, 1.05, 1.01 times the floor for cases I-IV with the projective fit of
        // quantised pixels (`synthetic`; 1.51, 1.20, 1.14, 1.08 without it; the goal is
        // for 1.25; the thesis family gives 1.39, 1.00, 1.39, 1.09).
        let cfg =
            TrainConfig { family: Family::INVERSE_DEPTH_SKIP, seed: 7, ..TrainConfig::default() };
        for n in 1..=4u8 {
            let (train_set, test_set) = protocol(n);
            let out = train(&train_set, &cfg).unwrap();
            let b = &out.blob;
            assert_eq!(b.family, Family::INVERSE_DEPTH_SKIP);
            assert_eq!(b.params.len(), 43 + 12);
            assert!(b.flat().skip.iter().any(|s| *s != 0.0));
            let net = worst_per_depth(&test_set, |x| net_z(b, x));
            let rig = presets::case(n).unwrap();
            let floor = worst_per_depth(&test_set, |x| {
                triangulate::optimal_rig(&rig, &x.try_into().unwrap()).unwrap()[2]
            });
            assert!(
                net <= 1.1 * floor,
                "case {n}: worst per-depth {net} % vs optimal triangulation {floor} %"
            );
            if n == 4 {
                assert_eq!(
                    hvs_shared::runtime::blob::decode(&encode(b)).unwrap(),
                    *b,
                    "blob round trip"
                );
            }
        }
        // Back-propagation has no skip term.
        let bp = TrainConfig { algo: Algo::Bp, ..cfg };
        assert!(train(&protocol(1).0, &bp).unwrap_err().to_string().contains("inverse-depth-skip"));
    }

    #[test]
    fn precise_pixels_through_lenses_learn_from_the_fitted_lenses() {
        // The 9x6 board at 6 cm through case IV and k1 = -0.1 lenses, 0.01 px Gaussian noise
        // (the rendered barrel images' corner error), against optimal triangulation with the
        // true rig and lenses on 500 volume points.
        use crate::sim::board::{Pixels, TrainingBoard};
        use crate::sim::sets::{SetKind, SimOptions};
        use hvs_shared::sim::camera::Distortion;
        let lens = Distortion { k1: -0.1, k2: 0.0 };
        let rig = presets::case(4).unwrap();
        let set = |lens: Distortion, noise_px: f64, kind: SetKind, seed: u64| {
            let opt = SimOptions {
                board: TrainingBoard::parse("9x6:6").unwrap(),
                pixels: Pixels::Exact,
                noise_px,
                points: 500,
                seed,
            };
            let head = hvs_shared::sim::posture::HeadRig::new(rig).with_distortion(lens);
            let home = [hvs_shared::runtime::gaze::Joints::HOME];
            let mut d = Dataset::new(InputKind::Stereo);
            for s in crate::sim::posture::simulate(&head, kind, &home, &opt).unwrap() {
                d.push(&s.px, Some(s.xyz));
            }
            d
        };
        let sim = |kind, seed| set(lens, 0.01, kind, seed);
        let (train_set, test) = (sim(SetKind::Train, 11), sim(SetKind::Volume, 12));
        let cfg =
            TrainConfig { family: Family::INVERSE_DEPTH_SKIP, seed: 7, ..TrainConfig::default() };
        let out = train(&train_set, &cfg).unwrap();
        assert_eq!(out.synthetic_points, Some(synthetic::SYNTHETIC_POINTS));
        assert!(out.synthetic_lenses);
        let ema = |z: &[f64]| {
            let mut acc = EmaAcc::default();
            for (t, z) in test.targets.iter().zip(z) {
                acc.add(t[2], *z);
            }
            acc.e_ma_pct()
        };
        let net = ema(&crate::evaluate::model_depths(&out.blob, &test).unwrap());
        let floor = ema(&crate::evaluate::optimal_depths_lens(&rig, lens, &test));
        // Measured: 1.010 (0.0481 % / 0.0476 %).
        assert!(net <= 1.03 * floor, "net {net} % vs floor {floor} %");
        // Pinhole pixels of a sub-pixel set take the same path (no lens fitted: k = 0 fits).
        let out = train(&set(Distortion::NONE, 0.05, SetKind::Train, 13), &cfg).unwrap();
        assert_eq!(out.synthetic_points, Some(synthetic::SYNTHETIC_POINTS));
    }

    #[test]
    fn blob_holds_scaling_box_metadata_and_the_reported_error() {
        let (train_set, cfg) = protocol_with(2, 3, 42);
        let out = train(&train_set, &cfg).unwrap();
        let b = &out.blob;
        assert_eq!(b.generation, 0);
        assert!(b.fallback.is_none());
        assert_eq!(b.topology.hidden, 5);
        assert_eq!(b.topology.outputs, OutputKind::Xyz);
        assert_eq!(b.topology.output_activation, Activation::Linear);
        assert_eq!(b.params.len(), 43);
        for i in 0..4 {
            let (lo, hi) = range((0..train_set.len()).map(|n| train_set.row(n)[i]));
            assert_eq!(b.in_min[i], lo as f32);
            assert_eq!(b.in_max[i], hi as f32);
            assert_eq!(b.in_offset[i], (0.5 * (lo + hi)) as f32);
        }
        // One scale for the four pixel inputs; the outputs span the targets.
        assert!(b.in_scale.iter().all(|s| *s == b.in_scale[0]));
        assert_eq!(b.out_offset[2], 115.0);
        assert_eq!(b.out_scale[2], 50.0);
        assert_eq!(b.meta.seed, 42);
        assert_eq!(b.meta.train_hash, train_set.hash());
        assert_eq!(b.meta.train_points, 72);
        assert_eq!(b.meta.restarts, 3);
        assert_eq!(b.meta.algorithm, Algorithm::Lm);
        // The reported error is the f32 blob's, and the best of the restarts.
        assert_eq!(out.train_error_pct, blob_error_pct(b, &train_set));
        assert_eq!(b.meta.train_error_pct, out.train_error_pct as f32);
        assert_eq!(out.restarts.len(), 3);
        for (i, r) in out.restarts.iter().enumerate() {
            assert_eq!(r.index, i);
            assert!(r.enrolled);
            assert!(r.iterations > 0);
            assert!(out.train_error_pct <= r.train_error_pct);
        }
        assert!(out.restarts.iter().any(|r| r.train_error_pct == out.train_error_pct));
        // And it round-trips through the blob format.
        assert_eq!(hvs_shared::runtime::blob::decode(&encode(b)).unwrap(), *b, "blob round trip");
    }

    #[test]
    fn same_seed_same_bytes_whatever_the_thread_count() {
        let (train_set, cfg) = protocol_with(4, 4, 7);
        let run = |threads: usize, cfg: &TrainConfig| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            let out = pool.install(|| train(&train_set, cfg)).unwrap();
            (encode(&out.blob), out.restarts)
        };
        let (one, r1) = run(1, &cfg);
        let (two, r2) = run(2, &cfg);
        let (three, _) = run(3, &cfg);
        assert_eq!(one, two);
        assert_eq!(one, three);
        assert_eq!(r1, r2);
        let (other, _) = run(2, &TrainConfig { seed: 8, ..cfg });
        assert_ne!(one, other, "another seed gives another model");
    }

    #[test]
    fn threshold_decides_enrolment() {
        let (train_set, cfg) = protocol_with(1, 4, 3);
        let all = train(&train_set, &cfg).unwrap();
        let mut errs: Vec<f64> = all.restarts.iter().map(|r| r.train_error_pct).collect();
        errs.sort_by(f64::total_cmp);
        // A threshold between the best and the rest enrols exactly the best.
        if errs[0] < errs[1] {
            let t = 0.5 * (errs[0] + errs[1]);
            let one =
                train(&train_set, &TrainConfig { threshold_pct: Some(t), ..cfg.clone() }).unwrap();
            assert_eq!(one.restarts.iter().filter(|r| r.enrolled).count(), 1);
            assert_eq!(encode(&one.blob), encode(&all.blob));
            for r in &one.restarts {
                assert_eq!(r.enrolled, r.train_error_pct <= t);
            }
        }
        // Below the best: nothing enrolled, and the error says which threshold.
        let t = errs[0] * 0.5;
        let err = train(&train_set, &TrainConfig { threshold_pct: Some(t), ..cfg })
            .unwrap_err()
            .to_string();
        assert!(err.contains("no restart enrolled"), "{err}");
        assert!(err.contains(&format!("threshold {t} %")), "{err}");
    }

    /// With synthetic points (the default family on integer pixels) the threshold judges the
    /// model returned, whose training e_ma is the one reported: at or above it the same bytes
    /// as without a threshold, below it an error naming that e_ma.
    #[test]
    fn the_threshold_judges_the_polished_model() {
        let cfg = TrainConfig { family: Family::INVERSE_DEPTH_SKIP, ..protocol_with(4, 3, 0).1 };
        let train_set = protocol(4).0;
        let all = train(&train_set, &cfg).unwrap();
        assert!(all.synthetic_points.is_some());
        let worst = all.restarts.iter().map(|r| r.train_error_pct).fold(0.0, f64::max);
        // The restarts' own errors lie above the polished model's (so the old rule refused
        // a threshold the reported e_ma met).
        assert!(worst > all.train_error_pct, "{worst} vs {}", all.train_error_pct);
        let t = all.train_error_pct * 1.0001;
        let kept =
            train(&train_set, &TrainConfig { threshold_pct: Some(t), ..cfg.clone() }).unwrap();
        assert_eq!(encode(&kept.blob), encode(&all.blob));
        assert!(kept.restarts.iter().all(|r| r.enrolled));
        let t = all.train_error_pct * 0.999;
        let err = train(&train_set, &TrainConfig { threshold_pct: Some(t), ..cfg })
            .unwrap_err()
            .to_string();
        assert!(
            err.contains(&format!("{:.4} %, above the threshold {t} %", all.train_error_pct)),
            "{err}"
        );
    }

    #[test]
    fn bad_input_is_a_clear_error() {
        let cfg = TrainConfig { restarts: 1, ..TrainConfig::default() };
        let msg = |d: &Dataset, c: &TrainConfig| train(d, c).unwrap_err().to_string();
        assert!(msg(&Dataset::new(InputKind::Stereo), &cfg).contains("empty"));
        let mut no_truth = Dataset::new(InputKind::Stereo);
        no_truth.push(&[320.0, 240.0, 300.0, 240.0], None);
        assert!(msg(&no_truth, &cfg).contains("ground truth"));
        let (mut d, _) = protocol(1);
        d.targets[5][2] = 0.0;
        assert!(msg(&d, &cfg).contains("row 6"));
        let (d, _) = protocol(1);
        for bad in [
            TrainConfig { hidden: 0, ..cfg.clone() },
            TrainConfig { hidden: 33, ..cfg.clone() },
            TrainConfig { restarts: 0, ..cfg.clone() },
            TrainConfig { threshold_pct: Some(-1.0), ..cfg.clone() },
            TrainConfig {
                algo: Algo::Bp,
                bp: BpParams { learning_rate: f64::NAN, ..BpParams::default() },
                ..cfg.clone()
            },
        ] {
            assert!(train(&d, &bad).is_err(), "{bad:?}");
        }
        let mut odd =
            Dataset { n_inputs: 3, inputs: vec![1.0, 2.0, 3.0], targets: vec![[0.0, 0.0, 100.0]] };
        assert!(msg(&odd, &cfg).contains("3 inputs"));
        odd.n_inputs = 4;
        odd.inputs = vec![1.0, f64::NAN, 3.0, 4.0];
        assert!(msg(&odd, &cfg).contains("row 1"));
    }

    #[test]
    fn z_only_joint_inputs_and_constant_columns() {
        // Nine inputs (pixels and five joint angles, some constant) and a Z-only output.
        let (board, _) = protocol(3);
        let mut d = Dataset::new(InputKind::StereoJoints);
        for r in 0..board.len() {
            let mut x = board.row(r).to_vec();
            x.extend_from_slice(&[0.0, 0.0, 0.0, (r % 3) as f64, -((r % 3) as f64)]);
            d.push(&x, Some(board.targets[r]));
        }
        let cfg = TrainConfig {
            outputs: OutputKind::Z,
            hidden: 4,
            restarts: 2,
            ..TrainConfig::default()
        };
        let out = train(&d, &cfg).unwrap();
        assert_eq!(out.blob.topology.inputs, InputKind::StereoJoints);
        assert_eq!(out.blob.n_outputs(), 1);
        assert_eq!(out.blob.params.len(), 4 * 10 + 5);
        assert_eq!(out.blob.in_scale[5], 1.0, "constant input keeps scale 1");
        assert!(out.train_error_pct < 3.0, "{}", out.train_error_pct);
    }

    #[test]
    fn only_sub_pixel_posture_sets_are_held_less_and_fitted_longer() {
        // The thesis' board at three postures: rounded pixels, then the same points nudged
        // by a hundredth of a pixel (as detected corners are).
        let (board, _) = protocol(3);
        let posture_set = |nudge: f64| {
            let mut d = Dataset::new(InputKind::StereoJoints);
            for r in 0..board.len() {
                let mut x = board.row(r).to_vec();
                x[0] += nudge;
                x.extend_from_slice(&[(r % 3) as f64, 0.0, 0.0, 1.0, -1.0]);
                d.push(&x, Some(board.targets[r]));
            }
            d
        };
        let f = Family::INVERSE_DEPTH_SKIP;
        let rounded = lm_options(f, OutputFrame::EyePlatform, &posture_set(0.0), 12);
        assert_eq!(rounded.weight_decay, SKIP_NET_DECAY_FACTOR * WEIGHT_DECAY);
        assert_eq!((rounded.max_iter, rounded.rel_tol), (LM_OPTIONS.max_iter, LM_OPTIONS.rel_tol));
        let precise = lm_options(f, OutputFrame::EyePlatform, &posture_set(0.01), 12);
        assert_eq!(precise.weight_decay, PRECISE_POSTURE_NET_DECAY);
        let cyclopean = lm_options(f, OutputFrame::Cyclopean, &posture_set(0.01), 12);
        assert_eq!(cyclopean.weight_decay, PRECISE_CYCLOPEAN_NET_DECAY);
        assert_eq!(
            (cyclopean.max_iter, cyclopean.tail),
            (PRECISE_POSTURE_LM.0, (12, WEIGHT_DECAY))
        );
        // Rounded posture sets keep their hold in either frame.
        let rounded_cyc = lm_options(f, OutputFrame::Cyclopean, &posture_set(0.0), 12);
        assert_eq!(rounded_cyc.weight_decay, rounded.weight_decay);
        // And only they get the larger net with one restart when `hvs train` is not told.
        let size = Some((640, 480));
        assert_eq!(default_size(f, &posture_set(0.01), size), (PRECISE_POSTURE_HIDDEN, 1));
        assert_eq!(default_size(f, &posture_set(0.0), size), (5, 10));
        assert_eq!(default_size(Family::THESIS, &posture_set(0.01), size), (5, 10));
        assert_eq!(default_size(f, &board, size), (5, 10));
        // A stereo set whose pixels cover most of the image gets the wider net, in a family
        // with a skip term and when the set says its image size.
        let mut wide = Dataset::new(InputKind::Stereo);
        for i in 0..21 {
            let (u, v) = (10.0 + 30.0 * f64::from(i), 20.0 + 21.0 * f64::from(i));
            wide.push(&[u, v, u - 20.0, v], Some([0.0, 0.0, 100.0]));
        }
        assert_eq!(default_size(f, &wide, size), (WIDE_FIELD_HIDDEN, 10));
        assert_eq!(default_size(f, &wide, None), (5, 10));
        assert_eq!(default_size(Family::THESIS, &wide, size), (5, 10));
        // 610 x 420 px of a 1280 x 960 image: not most of it.
        assert_eq!(default_size(f, &wide, Some((1280, 960))), (5, 10));
        assert_eq!((precise.max_iter, precise.rel_tol), PRECISE_POSTURE_LM);
        assert_eq!(precise.tail, (12, WEIGHT_DECAY));
        // A stereo set is no posture set (it keeps its noise-read decay); without a skip term
        // nothing changes.
        assert!(!subpixel_posture(&board));
        assert_eq!(
            lm_options(f, OutputFrame::Cyclopean, &posture_set(0.01), 0).max_iter,
            LM_OPTIONS.max_iter
        );
    }

    #[test]
    fn bp_and_adam_through_train() {
        let (train_set, _) = protocol(2);
        let bp = train(
            &train_set,
            &TrainConfig {
                algo: Algo::Bp,
                restarts: 2,
                bp: BpParams { max_cycles: 300, ..BpParams::default() },
                ..TrainConfig::default()
            },
        )
        .unwrap();
        assert_eq!(bp.blob.topology.output_activation, Activation::Sigmoid);
        assert_eq!(bp.blob.meta.algorithm, Algorithm::Bp);
        assert!(bp.restarts.iter().all(|r| r.iterations == 300));
        // Sigmoid band [0.1, 0.9] is the target range: Z from 65 to 165 cm.
        let (o, s) = (bp.blob.out_offset[2] as f64, bp.blob.out_scale[2] as f64);
        assert!((o + 0.1 * s - 65.0).abs() < 1e-4 && (o + 0.9 * s - 165.0).abs() < 1e-4);
        assert!(bp.train_error_pct < 15.0, "{}", bp.train_error_pct);

        let adam = train(
            &train_set,
            &TrainConfig { algo: Algo::Adam, restarts: 2, ..TrainConfig::default() },
        )
        .unwrap();
        assert_eq!(adam.blob.topology.output_activation, Activation::Linear);
        assert_eq!(adam.blob.meta.algorithm, Algorithm::Adam);
        assert!(adam.train_error_pct < 3.0, "{}", adam.train_error_pct);
    }
}
