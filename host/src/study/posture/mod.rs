//! Beyond the thesis: depth that stays right while the eyes move. [`run`] measures (a) the
//! thesis' 4-5-3 net, trained at the home posture, at verged and turned postures; (b) a
//! posture-aware 9-H-3 net (pixels and the five joint angles) per posture band of
//! [`PostureRange::WORKING`], with a sweep of H; (c) radial lens distortion for the nets, a
//! DLT fit and the floor. The floor is optimal triangulation with the true cameras at the same
//! posture; errors are e_ma in % of the true depth and the 3-D error in % of the distance.
//! [`csv_tables`] and [`page`] format the rows. The same [`StudyConfig`] gives the same numbers.

pub mod page;

use crate::data::dataset::{Dataset, JOINT_COLUMNS};
use crate::sim::posture::{self, PostureOptions, PostureSample, Sampling};
use crate::sim::sets::{SetKind, SimOptions};
use crate::study::engine::{timed, Progress};
use crate::train::{default_frame, train, TrainConfig};
use anyhow::{anyhow, Context, Result};
use hvs_shared::runtime::blob::{Family, InputKind, ModelBlob, OutputFrame};
use hvs_shared::runtime::gaze::{quantize, Joints};
use hvs_shared::sim::camera::{Distortion, Rig, Vec3};
use hvs_shared::sim::metrics::EmaAcc;
use hvs_shared::sim::posture::{joints_from_gaze, HeadRig, PostureRange};
use hvs_shared::sim::presets;
use hvs_vision::geometry::{fit_dlt, triangulate_dlt};
use rand::{RngExt, SeedableRng};
use rayon::prelude::*;
use std::sync::Mutex;
use std::time::Instant;

/// Seed of the default run: the one of `docs/posture-study.md`'s tables.
pub const DEFAULT_SEED: u64 = 1;
/// The posture study's goal: the posture-aware net within 20 % of the floor in every band.
pub const GOAL_RATIO: f64 = 1.2;
/// Hidden-neuron counts of the full run's sweep (those of the example's `--sweep`).
pub const HIDDEN_SWEEP: [usize; 6] = [5, 8, 12, 16, 24, 32];
/// Hidden-neuron counts of the quick run's sweep.
pub const HIDDEN_SWEEP_QUICK: [usize; 2] = [3, 6];
/// The gaze terms, in the order of [`PostureRange::gaze_terms`].
pub const TERMS: [&str; 5] = ["neck pan", "neck tilt", "eye tilt", "version", "vergence"];

/// Everything the study needs; [`StudyConfig::default`] is what the report shows.
#[derive(Debug, Clone, PartialEq)]
pub struct StudyConfig {
    /// Thesis case 1-4 (the rig on the head).
    pub case: u8,
    /// Seed of every random step (postures, points, restarts).
    pub seed: u64,
    /// Stratified training grid of the posture-aware net.
    pub train_levels: [u8; 5],
    /// Hidden neurons of the posture-aware net.
    pub hidden: usize,
    /// Model family of the posture-aware nets (parts (a) and (c) train the thesis family).
    pub family: Family,
    /// Frame of the posture-aware nets' points.
    pub frame: OutputFrame,
    /// Restarts of the posture-aware trainings.
    pub restarts: usize,
    /// Hidden counts of the sweep (empty: no sweep).
    pub sweep: Vec<usize>,
    /// Also train the chosen net on the regular lattice of postures.
    pub lattice: bool,
    /// Random test postures of the working range.
    pub test_postures: usize,
    /// Test points (each at the next test posture in turn).
    pub test_points: usize,
    /// Test points of the extreme-posture set (every gaze term in its outer third).
    pub extreme_points: usize,
    /// Test points per fixed posture of [`fixed_posture_study`].
    pub fixed_points: usize,
    /// Lens coefficients `k1` of [`distortion_study`].
    pub k1: Vec<f64>,
    /// Hidden neurons of the nets of [`distortion_study`].
    pub distortion_hidden: Vec<usize>,
    /// A reduced run (for tests): the report says its numbers show the study's shape only.
    pub quick: bool,
}

impl Default for StudyConfig {
    fn default() -> Self {
        StudyConfig {
            case: 3,
            seed: 1,
            train_levels: posture::DEFAULT_LEVELS,
            hidden: 16,
            family: crate::train::DEFAULT_FAMILY,
            frame: default_frame(crate::train::DEFAULT_FAMILY, InputKind::StereoJoints),
            restarts: 1,
            sweep: Vec::new(),
            lattice: false,
            test_postures: 1000,
            test_points: 3000,
            extreme_points: 600,
            fixed_points: 300,
            k1: vec![0.0, -0.1, -0.2, -0.3, -0.4, -0.5],
            distortion_hidden: vec![5, 10],
            quick: false,
        }
    }
}

impl StudyConfig {
    /// The settings of `hvs experiment posture`: the defaults with the sweep [`HIDDEN_SWEEP`]
    /// and the lattice-trained net; when `quick`, a 2x1x1x2x2 grid of training postures,
    /// 9-6-3 nets, few test points, two lenses and a 4-4-3 lens net.
    pub fn experiment(seed: u64, quick: bool) -> StudyConfig {
        let full =
            StudyConfig { seed, sweep: HIDDEN_SWEEP.to_vec(), lattice: true, ..Self::default() };
        if !quick {
            return full;
        }
        StudyConfig {
            train_levels: [2, 1, 1, 2, 2],
            hidden: 6,
            sweep: HIDDEN_SWEEP_QUICK.to_vec(),
            test_postures: 100,
            test_points: 300,
            extreme_points: 100,
            fixed_points: 60,
            k1: vec![0.0, -0.5],
            distortion_hidden: vec![4],
            quick: true,
            ..full
        }
    }
    /// The rig of the configured case.
    pub fn rig(&self) -> Result<Rig> {
        presets::case(self.case).ok_or_else(|| anyhow!("case must be 1-4, got {}", self.case))
    }
    /// A 4-input net of the thesis family with `hidden` neurons, trained on `data`.
    fn thesis_net(&self, data: &Dataset, hidden: usize) -> Result<ModelBlob> {
        let tc =
            TrainConfig { hidden, seed: self.seed, family: Family::THESIS, ..Default::default() };
        Ok(train(data, &tc)?.blob)
    }
}

/// Errors of one estimator over a set of points.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Errors {
    /// Points.
    pub points: usize,
    /// e_ma in percent of the true depth.
    pub z_pct: f64,
    /// Mean 3-D error in percent of the distance.
    pub d3_pct: f64,
    /// Largest depth error, percent.
    pub max_z_pct: f64,
    /// Points without an estimate (counted as infinite errors in the means).
    pub failed: usize,
}

impl Errors {
    /// The CSV header of `prefix`'s errors.
    fn header(p: &str) -> String {
        format!("{p}_points,{p}_z_pct,{p}_d3_pct,{p}_max_z_pct,{p}_failed")
    }
    /// The CSV cells.
    fn cells(&self) -> Vec<String> {
        cells(&[&self.points, &self.z_pct, &self.d3_pct, &self.max_z_pct, &self.failed])
    }
}

/// Accumulates [`Errors`].
#[derive(Debug, Clone, Copy, Default)]
struct Acc {
    z: EmaAcc,
    d3: f64,
    failed: usize,
}

impl Acc {
    fn add(&mut self, truth: &Vec3, est: Option<Vec3>) {
        match est {
            Some(e) if e.iter().all(|v| v.is_finite()) => {
                self.z.add(truth[2], e[2]);
                let n = norm(truth);
                self.d3 += norm(&[e[0] - truth[0], e[1] - truth[1], e[2] - truth[2]]) / n;
            }
            _ => {
                self.z.add(truth[2], f64::NAN);
                self.d3 = f64::INFINITY;
                self.failed += 1;
            }
        }
    }
    fn errors(&self) -> Errors {
        let n = self.z.count() as usize;
        Errors {
            points: n,
            z_pct: self.z.e_ma_pct(),
            d3_pct: self.d3 / n as f64 * 100.0,
            max_z_pct: self.z.max_pct(),
            failed: self.failed,
        }
    }
}

fn norm(v: &Vec3) -> f64 {
    (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
}

/// `[X, Y, Z]` of a blob for inputs `x` (f32, as the head computes), `None` if refused.
fn net_xyz(blob: &ModelBlob, x: &[f64]) -> Option<Vec3> {
    let xf: Vec<f32> = x.iter().map(|v| *v as f32).collect();
    let mut out = [0.0f32; 3];
    blob.infer(&xf, &mut out).ok()?;
    Some(out.map(f64::from))
}

/// The errors of `blob` (given the inputs it takes) and of the floor over `set`.
fn eval<'a>(
    blob: &ModelBlob,
    head: &HeadRig,
    set: impl IntoIterator<Item = &'a PostureSample>,
) -> (Errors, Errors) {
    let set: Vec<&PostureSample> = set.into_iter().collect();
    let est = estimates(blob, head, set.iter().copied());
    errors_of(set.iter().copied().zip(&est))
}

/// The net's and the floor's estimate of each sample's point.
type Estimates = (Option<Vec3>, Option<Vec3>);

/// [`Estimates`] of every sample of `set`, in order.
fn estimates<'a>(
    blob: &ModelBlob,
    head: &HeadRig,
    set: impl IntoIterator<Item = &'a PostureSample>,
) -> Vec<Estimates> {
    set.into_iter().map(|s| (net_point(blob, s), floor_point(head, s))).collect()
}

/// The net's estimate of a sample's point (from the inputs it takes).
fn net_point(blob: &ModelBlob, s: &PostureSample) -> Option<Vec3> {
    net_xyz(blob, &s.inputs()[..blob.n_inputs()])
}

/// The floor's estimate of a sample's point: optimal triangulation with the true head at the
/// sample's posture (`None` where it fails).
fn floor_point(head: &HeadRig, s: &PostureSample) -> Option<Vec3> {
    head.optimal(&s.joints, &s.px).ok()
}

/// The floor's estimate of every sample of `test`, in order: what [`bands_with_floor`] takes,
/// for a caller that needs the floor's points for something else as well (`hvs eval`'s table).
pub fn floor_points(head: &HeadRig, test: &[PostureSample]) -> Vec<Option<Vec3>> {
    test.iter().map(|s| floor_point(head, s)).collect()
}

/// The net's and the floor's errors over samples with their estimates, in order.
fn errors_of<'a>(
    set: impl IntoIterator<Item = (&'a PostureSample, &'a Estimates)>,
) -> (Errors, Errors) {
    let (mut net, mut floor) = (Acc::default(), Acc::default());
    for (s, (n, f)) in set {
        net.add(&s.xyz, *n);
        floor.add(&s.xyz, *f);
    }
    (net.errors(), floor.errors())
}

/// Noise-free samples of `points` random points of the training volume, at `joints` in turn.
fn volume(head: &HeadRig, js: &[Joints], points: usize, seed: u64) -> Result<Vec<PostureSample>> {
    let opt = SimOptions { points, noise_px: 0.0, seed, ..SimOptions::default() };
    posture::simulate(head, SetKind::Volume, js, &opt)
}

/// One row of [`fixed_posture_study`].
#[derive(Debug, Clone, PartialEq)]
pub struct FixedRow {
    /// What the posture is.
    pub label: String,
    /// The posture.
    pub joints: Joints,
    /// The home-trained 4-5-3 net at this posture.
    pub net: Errors,
    /// The floor at this posture.
    pub floor: Errors,
}

/// The postures of [`fixed_posture_study`]: home, vergence, version, neck pan, tilts.
pub fn fixed_postures() -> Vec<(String, Joints)> {
    let mut v: Vec<(String, [f32; 5])> = vec![("home".into(), [0.0; 5])];
    for (g, cm) in [(2.5f32, 240), (5.0, 120), (10.0, 60)] {
        v.push((format!("vergence {g} deg (fixating {cm} cm)"), [0.0, 0.0, 0.0, 0.0, g]));
    }
    for g in [5.0f32, 10.0, 15.0] {
        v.push((format!("version {g} deg (eyes turned left)"), [0.0, 0.0, 0.0, g, 0.0]));
    }
    for g in [10.0f32, 30.0] {
        v.push((format!("neck pan {g} deg"), [g, 0.0, 0.0, 0.0, 0.0]));
    }
    v.push(("eye tilt 10 deg".into(), [0.0, 0.0, 10.0, 0.0, 0.0]));
    v.push(("neck tilt 15 deg".into(), [0.0, 15.0, 0.0, 0.0, 0.0]));
    v.push(("verged 5 deg, version 10, neck pan 20".into(), [20.0, 0.0, 0.0, 10.0, 5.0]));
    let joints =
        |[a, b, c, d, e]: [f32; 5]| Joints(joints_from_gaze(a, b, c, d, e).0.map(quantize));
    v.into_iter().map(|(label, g)| (label, joints(g))).collect()
}

/// The thesis' 4-5-3 net trained at home (board protocol), evaluated on random points of the
/// training volume in front of the head at each of [`fixed_postures`], with the floor.
pub fn fixed_posture_study(cfg: &StudyConfig) -> Result<(ModelBlob, Vec<FixedRow>)> {
    let head = HeadRig::new(cfg.rig()?);
    let home = posture::simulate(&head, SetKind::Train, &[Joints::HOME], &SimOptions::default())?;
    let mut data = Dataset::new(InputKind::Stereo);
    for s in &home {
        data.push(&s.px, Some(s.xyz));
    }
    let blob = cfg.thesis_net(&data, 5).context("training the home-posture 4-5-3 net")?;
    let mut rows = Vec::new();
    for (k, (label, joints)) in fixed_postures().into_iter().enumerate() {
        let set =
            volume(&head, &[joints], cfg.fixed_points, cfg.seed.wrapping_add(100 + k as u64))?;
        let (net, floor) = eval(&blob, &head, &set);
        rows.push(FixedRow { label, joints, net, floor });
    }
    Ok((blob, rows))
}

/// One posture band of [`posture_aware_study`].
#[derive(Debug, Clone, PartialEq)]
pub struct BandRow {
    /// Which gaze term the band is on (`all`, `extreme` for the whole sets).
    pub term: &'static str,
    /// The band, e.g. `10.0 to 20.0 (either side)`.
    pub band: String,
    /// The posture-aware net.
    pub net: Errors,
    /// The floor at the same postures and pixels.
    pub floor: Errors,
}

impl BandRow {
    /// Net depth e_ma over the floor's.
    pub fn ratio(&self) -> f64 {
        self.net.z_pct / self.floor.z_pct
    }
}

/// One training of the sweep.
#[derive(Debug, Clone, PartialEq)]
pub struct HiddenRow {
    /// Hidden neurons.
    pub hidden: usize,
    /// Which training postures (`grid` stratified or `lattice`).
    pub postures: &'static str,
    /// Parameters of the net.
    pub params: usize,
    /// Training e_ma, percent.
    pub train_pct: f64,
    /// Test errors on the random postures.
    pub test: Errors,
    /// The floor on the same test points.
    pub floor: Errors,
    /// Worst net/floor depth-error ratio over the bands.
    pub worst_band_ratio: f64,
    /// Training wall time, seconds.
    pub seconds: f64,
}

/// What [`posture_aware_study`] returns.
#[derive(Debug, Clone)]
pub struct PostureAware {
    /// The trained net.
    pub blob: ModelBlob,
    /// Rows of its training set.
    pub train_rows: usize,
    /// Training postures.
    pub train_postures: usize,
    /// Per-band results of the net.
    pub bands: Vec<BandRow>,
    /// One row per training ([`run`]: the sweep, ordered by postures and hidden count).
    pub sweep: Vec<HiddenRow>,
}

/// The test sets: random postures of the working range, and extreme postures (the four
/// angles in the outer third of their magnitude, vergence in the upper third of its range).
fn test_sets(
    cfg: &StudyConfig,
    head: &HeadRig,
) -> Result<(Vec<PostureSample>, Vec<PostureSample>)> {
    let count = cfg.test_postures;
    let opt = PostureOptions { sampling: Sampling::Random, count, ..Default::default() };
    let random = posture::postures(&opt, cfg.seed.wrapping_add(11))?;
    let mut rng = rand::rngs::ChaCha8Rng::seed_from_u64(cfg.seed.wrapping_add(13));
    let extreme: Vec<Joints> = (0..cfg.extreme_points.max(1))
        .map(|_| {
            PostureRange::WORKING.at(core::array::from_fn(|k| {
                let u: f64 = rng.random();
                if k == 4 {
                    return 1.0 - u / 3.0;
                }
                // The outer third of the magnitude: the outer sixth at either end.
                if rng.random::<bool>() {
                    1.0 - u / 6.0
                } else {
                    u / 6.0
                }
            }))
        })
        .collect();
    Ok((
        volume(head, &random, cfg.test_points, cfg.seed.wrapping_add(12))?,
        volume(head, &extreme, cfg.extreme_points, cfg.seed.wrapping_add(14))?,
    ))
}

/// The rows of a posture-aware set with ground truth (pixels, the five joint columns, `x,y,z`)
/// as samples for [`bands`]: e.g. test captures through `hvs board detect` (`hvs eval` prints
/// their bands). Rows of a set without joint columns are at the home posture.
pub fn samples(data: &Dataset) -> Vec<PostureSample> {
    (0..data.len().min(data.targets.len()))
        .map(|i| {
            let r = data.row(i);
            let joints = data.joints(i).unwrap_or(Joints::HOME);
            PostureSample { px: [r[0], r[1], r[2], r[3]], joints, xyz: data.targets[i] }
        })
        .collect()
}

/// Per-band errors of `blob` on `test` (and the whole `extreme` set), with the floor: thirds
/// of each gaze term's working range, by magnitude (vergence by value).
pub fn bands(
    blob: &ModelBlob,
    head: &HeadRig,
    test: &[PostureSample],
    extreme: &[PostureSample],
) -> Vec<BandRow> {
    bands_with_floor(blob, head, test, &floor_points(head, test), extreme)
}

/// [`bands`] with the floor's point of each sample of `test` given ([`floor_points`]).
///
/// # Panics
/// If `floor` is not as long as `test`.
pub fn bands_with_floor(
    blob: &ModelBlob,
    head: &HeadRig,
    test: &[PostureSample],
    floor: &[Option<Vec3>],
    extreme: &[PostureSample],
) -> Vec<BandRow> {
    assert_eq!(floor.len(), test.len(), "a floor point per sample");
    // Each sample's estimates once; a band sums its samples' in the set's order.
    let est: Vec<Estimates> =
        test.iter().zip(floor).map(|(s, f)| (net_point(blob, s), *f)).collect();
    let row = |term, band: &str, set: Vec<usize>| {
        let (net, floor) = errors_of(set.into_iter().map(|i| (&test[i], &est[i])));
        BandRow { term, band: band.to_string(), net, floor }
    };
    let mut rows =
        vec![row("all", "random postures of the working range", (0..test.len()).collect())];
    for (k, [lo, hi]) in PostureRange::WORKING.intervals().into_iter().enumerate() {
        let by_magnitude = k < 4;
        let (a, b) = if by_magnitude { (0.0, lo.abs().max(hi.abs())) } else { (lo, hi) };
        let e = [a, a + (b - a) / 3.0, a + 2.0 * (b - a) / 3.0, b];
        for i in 0..3 {
            let inside: Vec<usize> = (0..test.len())
                .filter(|&j| {
                    let v = PostureRange::gaze_terms(&test[j].joints)[k];
                    let v = if by_magnitude { v.abs() } else { v };
                    // The last band takes the quantisation overshoot at the top.
                    v >= e[i] - if i == 0 { 1.0 } else { 0.0 } && (v < e[i + 1] || i == 2)
                })
                .collect();
            let side = if by_magnitude { " (either side)" } else { "" };
            if !inside.is_empty() {
                rows.push(row(TERMS[k], &format!("{:.1} to {:.1}{side}", e[i], e[i + 1]), inside));
            }
        }
    }
    if !extreme.is_empty() {
        let band = "all four angles in their outer third, vergence 6.7-10";
        let (net, floor) = eval(blob, head, extreme);
        rows.push(BandRow { term: "extreme", band: band.to_string(), net, floor });
    }
    rows
}

/// Trains the posture-aware 9-`hidden`-3 net on the board protocol at the postures of
/// `sampling` (the stratified grid or the lattice) and evaluates it per band.
pub fn posture_aware_study(
    cfg: &StudyConfig,
    hidden: usize,
    sampling: Sampling,
) -> Result<PostureAware> {
    let head = HeadRig::new(cfg.rig()?);
    let (test, extreme) = test_sets(cfg, &head)?;
    let opt = PostureOptions { sampling, levels: cfg.train_levels, ..PostureOptions::default() };
    let joints = posture::postures(&opt, cfg.seed)?;
    let set = posture::simulate(&head, SetKind::Train, &joints, &SimOptions::default())?;
    let data = posture::dataset(&set);
    let t0 = Instant::now();
    let (restarts, seed, family, frame) = (cfg.restarts, cfg.seed, cfg.family, cfg.frame);
    let tc = TrainConfig { hidden, restarts, seed, family, frame, ..TrainConfig::default() };
    let out = train(&data, &tc).with_context(|| format!("training the 9-{hidden}-3 net"))?;
    let seconds = t0.elapsed().as_secs_f64();
    let bands = bands(&out.blob, &head, &test, &extreme);
    let nan_inf = |x: f64| if x.is_nan() { f64::INFINITY } else { x };
    let worst = bands.iter().map(|b| nan_inf(b.ratio())).fold(0.0, f64::max);
    let row = HiddenRow {
        hidden,
        postures: if sampling == Sampling::Lattice { "lattice" } else { "grid" },
        params: out.blob.params.len(),
        train_pct: out.train_error_pct,
        test: bands[0].net,
        floor: bands[0].floor,
        worst_band_ratio: worst,
        seconds,
    };
    let (train_rows, train_postures) = (data.len(), joints.len());
    Ok(PostureAware { blob: out.blob, train_rows, train_postures, bands, sweep: vec![row] })
}

/// Horizontal half-extent of the wide board of [`distortion_study`], image half-widths: its
/// farthest image point is then inside the radius where a lens with `k1 = -0.5` folds over.
pub const WIDE_BOARD_U: f64 = 0.55;
/// Vertical half-extent of the wide board, image half-widths.
pub const WIDE_BOARD_V: f64 = 0.40;

/// A point of the wide board's frustum at depth `z` (cm), `a` and `b` from -1 to 1 across it,
/// sized for the rig's larger focal length (so that neither camera sees more).
fn board_point(rig: &Rig, a: f64, b: f64, z: f64) -> Vec3 {
    let hw = f64::from(rig.width) / 2.0;
    let phi = rig.phi_u_left.max(rig.phi_u_right).max(rig.phi_v_left).max(rig.phi_v_right);
    [a * WIDE_BOARD_U * hw * z / phi, b * WIDE_BOARD_V * hw * z / phi, z]
}

/// Points of the wide board at depth `z` (cm): `nu x nv` points evenly spread over it.
pub fn wide_board(rig: &Rig, z: f64, nu: usize, nv: usize) -> Vec<Vec3> {
    let a = |n: usize, j: usize| -1.0 + 2.0 * j as f64 / (n - 1).max(1) as f64;
    (0..nv).flat_map(|i| (0..nu).map(move |k| board_point(rig, a(nu, k), a(nv, i), z))).collect()
}

/// One lens of [`distortion_study`].
#[derive(Debug, Clone, PartialEq)]
pub struct DistortionRow {
    /// `k1` (image half-widths).
    pub k1: f64,
    /// Nets: (hidden neurons, errors).
    pub nets: Vec<(usize, Errors)>,
    /// The DLT fit with linear triangulation.
    pub dlt: Errors,
    /// The floor (optimal triangulation with the true cameras and lenses).
    pub floor: Errors,
    /// Largest pixel displacement the lens causes on the test points.
    pub max_shift_px: f64,
}

/// The lens study at the home posture: for each `k1`, the 4-H-3 nets and the DLT fit, trained
/// on the wide board (9x7 points) at the six training depths, against the floor, on random
/// points of the board's frustum at 65-165 cm.
pub fn distortion_study(cfg: &StudyConfig) -> Result<Vec<DistortionRow>> {
    let rig = cfg.rig()?;
    let train_pts: Vec<Vec3> =
        presets::TRAIN_DEPTHS.iter().flat_map(|&z| wide_board(&rig, z, 9, 7)).collect();
    let mut rng = rand::rngs::ChaCha8Rng::seed_from_u64(cfg.seed.wrapping_add(21));
    let test_pts: Vec<Vec3> = (0..cfg.test_points)
        .map(|_| {
            let (a, b, c): (f64, f64, f64) = (rng.random(), rng.random(), rng.random());
            board_point(&rig, 2.0 * a - 1.0, 2.0 * b - 1.0, 65.0 + 100.0 * c)
        })
        .collect();
    let (plain, j) = (HeadRig::new(rig), Joints::HOME);
    let mut rows = Vec::new();
    for &k1 in &cfg.k1 {
        let head = plain.with_distortion(Distortion { k1, k2: 0.0 });
        let project = |p: &Vec3| head.project_rounded(&j, p).ok().filter(|px| rig.in_image(px));
        let mut data = Dataset::new(InputKind::Stereo);
        let (mut pts, mut pix_l, mut pix_r) = (Vec::new(), Vec::new(), Vec::new());
        for p in &train_pts {
            if let Some(px) = project(p) {
                data.push(&px, Some(*p));
                pts.push(*p);
                pix_l.push([px[0], px[1]]);
                pix_r.push([px[2], px[3]]);
            }
        }
        let dlt = [fit_dlt(&pts, &pix_l)?, fit_dlt(&pts, &pix_r)?];
        let mut nets = Vec::new();
        for &h in &cfg.distortion_hidden {
            let ctx = || format!("training the 4-{h}-3 net at k1 = {k1}");
            nets.push((h, cfg.thesis_net(&data, h).with_context(ctx)?, Acc::default()));
        }
        let (mut d, mut f, mut shift) = (Acc::default(), Acc::default(), 0.0f64);
        for p in &test_pts {
            let Some(px) = project(p) else { continue };
            if let Ok(ideal) = plain.project_rounded(&j, p) {
                shift = (0..4).fold(shift, |m, k| m.max((ideal[k] - px[k]).abs()));
            }
            for (_, blob, acc) in &mut nets {
                acc.add(p, net_xyz(blob, &px));
            }
            d.add(p, triangulate_dlt(&dlt, &px));
            f.add(p, head.optimal(&j, &px).ok());
        }
        rows.push(DistortionRow {
            k1,
            nets: nets.iter().map(|(h, _, a)| (*h, a.errors())).collect(),
            dlt: d.errors(),
            floor: f.errors(),
            max_shift_px: shift,
        });
    }
    Ok(rows)
}

/// Everything the study measured.
#[derive(Debug, Clone)]
pub struct Posture {
    /// Its configuration.
    pub config: StudyConfig,
    /// (a) the fixed-posture net at other postures.
    pub fixed: Vec<FixedRow>,
    /// (b) the posture-aware net of the chosen size, with the whole sweep.
    pub aware: PostureAware,
    /// (c) lens distortion.
    pub distortion: Vec<DistortionRow>,
    /// Wall time (s) of part (a), of the posture-aware trainings (summed: they overlap) and
    /// of the lens study.
    pub seconds: [f64; 3],
    /// Wall time of each stage (s), in run order; not deterministic.
    pub stage_s: Vec<(&'static str, f64)>,
    /// Worker threads used.
    pub threads: usize,
}

/// Runs the study: part (a), then the posture-aware nets of the sweep (a queue the workers
/// take the largest first from: a training's time grows about linearly with the hidden count)
/// next to the lens study, on the rayon pool. Every training takes the study's seed, so the
/// numbers do not depend on the thread count; only the wall times do.
pub fn run(study: &StudyConfig, progress: &dyn Progress) -> Result<Posture> {
    progress.start("fixed-posture 4-5-3 net", 1);
    let mut stage_s = Vec::new();
    let (_, fixed) = timed(&mut stage_s, "fixed-posture net", || fixed_posture_study(study))?;
    progress.inc();
    progress.finish();

    let mut hidden = study.sweep.clone();
    hidden.push(study.hidden);
    hidden.sort_unstable();
    hidden.dedup();
    let mut jobs: Vec<(usize, Sampling)> = hidden.iter().map(|&h| (h, Sampling::Grid)).collect();
    if study.lattice {
        jobs.push((study.hidden, Sampling::Lattice));
    }
    jobs.sort_by_key(|j| j.0);
    let n = jobs.len() + 1;
    progress.start("posture-aware nets, lens", n as u64);
    let queue = Mutex::new(jobs);
    let worker = |_| -> Result<Vec<PostureAware>> {
        let mut done = Vec::new();
        while let Some((h, s)) = queue.lock().ok().and_then(|mut q| q.pop()) {
            let a = posture_aware_study(study, h, s);
            progress.inc();
            // No point in the rest after an error: the first error is the run's.
            let a = a.inspect_err(|_| drop(queue.lock().map(|mut q| q.clear())));
            done.push(a.with_context(|| format!("the posture-aware 9-{h}-3 net"))?);
        }
        Ok(done)
    };
    let lens = || {
        let t0 = Instant::now();
        let d = distortion_study(study).context("the lens study");
        progress.inc();
        d.map(|d| (d, t0.elapsed().as_secs_f64()))
    };
    let threads = rayon::current_num_threads().min(n);
    let (nets, lens) = timed(&mut stage_s, "posture-aware nets and lens", || {
        let all = || (0..threads).into_par_iter().map(worker).collect::<Result<Vec<_>>>();
        Ok(rayon::join(all, lens))
    })?;
    progress.finish();
    let mut nets: Vec<PostureAware> = nets?.into_iter().flatten().collect();
    let (distortion, lens_s) = lens?;
    let mut sweep: Vec<HiddenRow> = nets.iter().flat_map(|a| a.sweep.clone()).collect();
    sweep.sort_by_key(|h| (h.postures, h.hidden));
    let aware_s = sweep.iter().map(|h| h.seconds).sum();
    let chosen =
        |a: &PostureAware| (a.sweep[0].postures, a.sweep[0].hidden) == ("grid", study.hidden);
    let k = nets.iter().position(chosen).ok_or_else(|| anyhow!("no 9-{}-3 net", study.hidden))?;
    let aware = PostureAware { sweep, ..nets.swap_remove(k) };
    let seconds = [stage_s[0].1, aware_s, lens_s];
    Ok(Posture { config: study.clone(), fixed, aware, distortion, seconds, stage_s, threads })
}

/// A CSV table: file name, header, rows of cells.
pub type CsvTable = (&'static str, String, Vec<Vec<String>>);

/// Cells of a CSV row, each as it displays.
fn cells(v: &[&dyn std::fmt::Display]) -> Vec<String> {
    v.iter().map(|x| x.to_string()).collect()
}

/// The report's tables as CSV: `fixed.csv`, `bands.csv`, `hidden.csv`, `distortion.csv`, and
/// the wall times in `timing.csv` (so that the four tables depend on the configuration only).
pub fn csv_tables(r: &Posture) -> Vec<CsvTable> {
    let (net, floor, test) =
        (Errors::header("net"), Errors::header("floor"), Errors::header("test"));
    let quoted = |s: &str| format!("\"{s}\"");
    let fixed = r.fixed.iter().map(|f| {
        let joints = f.joints.0.map(|j| j.to_string()).to_vec();
        [vec![quoted(&f.label)], joints, f.net.cells(), f.floor.cells()].concat()
    });
    let bands = r.aware.bands.iter().map(|b| {
        [vec![b.term.to_string(), quoted(&b.band)], b.net.cells(), b.floor.cells()].concat()
    });
    let hidden = r.aware.sweep.iter().map(|h| {
        let head = cells(&[&h.postures, &h.hidden, &h.params, &h.train_pct]);
        [head, h.test.cells(), h.floor.cells(), cells(&[&h.worst_band_ratio])].concat()
    });
    let mut dist = Vec::new();
    for d in &r.distortion {
        let nets = d.nets.iter().map(|(h, e)| (format!("net_4_{h}_3"), e));
        for (method, e) in nets.chain([("dlt".into(), &d.dlt), ("floor".into(), &d.floor)]) {
            dist.push([cells(&[&d.k1, &d.max_shift_px, &method]), e.cells()].concat());
        }
    }
    let parts = ["(a) fixed posture", "(b) posture-aware", "(c) lens"];
    let mut timing: Vec<Vec<String>> =
        parts.iter().zip(r.seconds).map(|(p, s)| cells(&[p, &"", &"", &s])).collect();
    timing.extend(
        r.aware.sweep.iter().map(|h| cells(&[&"training", &h.postures, &h.hidden, &h.seconds])),
    );
    let hidden_head = format!("postures,hidden,params,train_pct,{test},{floor},worst_band_ratio");
    let dist_head = "k1,max_shift_px,method,points,z_pct,d3_pct,max_z_pct,failed";
    vec![
        (
            "fixed.csv",
            format!("posture,{},{net},{floor}", JOINT_COLUMNS.join(",")),
            fixed.collect(),
        ),
        ("bands.csv", format!("term,band,{net},{floor}"), bands.collect()),
        ("hidden.csv", hidden_head, hidden.collect()),
        ("distortion.csv", dist_head.into(), dist),
        ("timing.csv", "what,postures,hidden,seconds".into(), timing),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn test_sets_cover_the_working_range_and_its_extremes() {
        let cfg = StudyConfig::experiment(1, true);
        let head = HeadRig::new(cfg.rig().unwrap());
        let (test, extreme) = test_sets(&cfg, &head).unwrap();
        assert_eq!((test.len(), extreme.len()), (300, 100));
        let range = PostureRange::WORKING;
        for s in test.iter().chain(&extreme) {
            assert!(range.contains(&s.joints, 0.18), "{:?}", s.joints);
        }
        // Extreme postures: every term in its outer third.
        for s in &extreme {
            let g = PostureRange::gaze_terms(&s.joints);
            for k in 0..4 {
                let m = range.intervals()[k][1];
                assert!(g[k].abs() >= 2.0 * m / 3.0 - 0.2, "{g:?}");
            }
            assert!(g[4] >= 20.0 / 3.0 - 0.2, "{g:?}");
        }
    }

    /// `hvs eval` takes its optimal column from [`floor_points`] on a posture-aware set: the
    /// same depths, to the bit, as `evaluate::optimal_depths_lens` row by row, lens or not.
    #[test]
    fn floor_points_are_the_optimal_depths_of_each_row() {
        let cfg = StudyConfig::experiment(1, true);
        let rig = cfg.rig().unwrap();
        for lens in [Distortion::NONE, Distortion { k1: -0.05, k2: 0.0 }] {
            let head = HeadRig::new(rig).with_distortion(lens);
            let (test, _) = test_sets(&cfg, &head).unwrap();
            let data = posture::dataset(&test);
            let points = floor_points(&head, &samples(&data));
            let z = crate::evaluate::optimal_depths_lens(&rig, lens, &data);
            assert_eq!(points.len(), z.len());
            assert!(points.iter().all(Option::is_some));
            for (p, z) in points.iter().zip(&z) {
                assert_eq!(p.map(|p| p[2].to_bits()), Some(z.to_bits()));
            }
        }
    }
}
