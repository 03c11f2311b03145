//! Beyond the thesis: depth that stays right while the eyes move. The study behind the
//! experiments report's posture section, as functions that return rows:
//!
//! - [`fixed_posture_study`]: the thesis' 4-5-3 net, trained at the home posture on the board
//!   protocol, evaluated at verged and turned postures (how wrong it gets), next to the
//!   optimal-triangulation floor at the same posture;
//! - [`posture_aware_study`]: a 9-input net (pixels and the five joint angles) trained on the
//!   board protocol repeated over a stratified grid of postures of
//!   [`PostureRange::WORKING`], evaluated on random postures of the working range, per posture
//!   band, against the floor; optionally a sweep of the hidden-neuron count and the same net
//!   trained on the regular lattice of postures;
//! - [`distortion_study`]: radial lens distortion `k1` from 0 to -0.5 (units of the image
//!   half-width) on a board that fills much of the image: the network, a DLT fit (3x4
//!   projection matrices fitted per camera from the training points, then linear
//!   triangulation) and the floor (optimal triangulation with the true, distorting cameras).
//!
//! Errors are the thesis' e_ma in percent of the true depth (`mean |Z - Z^| / Z`, Z in the
//! head frame) and, because a turned head sees points off to the side, the 3-D error in percent
//! of the distance (`mean |p - p^| / |p|`). [`run`] runs the three parts; [`csv_tables`] turns
//! the rows into CSV tables and [`page`] writes the files and `POSTURE.md`. Every random step takes the study's seed; the same
//! [`StudyConfig`] gives the same numbers.

pub mod page;

use crate::data::dataset::Dataset;
use crate::fmt::join;
use crate::sim::posture::{self, PostureOptions, PostureSample, Sampling};
use crate::sim::sets::{SetKind, SimOptions};
use crate::study::engine::Progress;
use crate::train::{default_frame, train, TrainConfig};
use anyhow::{anyhow, bail, Context, Result};
use hvs_shared::runtime::blob::{Family, InputKind, ModelBlob, OutputFrame};
use hvs_shared::runtime::gaze::Joints;
use hvs_shared::sim::camera::Distortion;
use hvs_shared::sim::camera::{Rig, Vec3};
use hvs_shared::sim::metrics::EmaAcc;
use hvs_shared::sim::posture::{joints_from_gaze, HeadRig, PostureRange};
use hvs_shared::sim::presets;
use hvs_vision::geometry::{fit_dlt, triangulate_dlt};
use rand::{RngExt, SeedableRng};
use rayon::prelude::*;
use std::fmt::Write as _;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;
use std::time::Instant;

/// Seed of the default run: the one of `docs/posture-study.md`'s tables.
pub const DEFAULT_SEED: u64 = 1;
/// The posture study's goal: the posture-aware net within 20 % of the floor in every band.
pub const GOAL_RATIO: f64 = 1.2;
/// Hidden-neuron counts of the full run's sweep (the chosen size, 16, among them): those of
/// the example's `--sweep`, which produced `docs/posture-study.md`'s tables.
pub const HIDDEN_SWEEP: [usize; 6] = [5, 8, 12, 16, 24, 32];
/// Hidden neurons of the posture-aware net of the full run.
pub const HIDDEN: usize = 16;
/// Hidden-neuron counts of the quick run's sweep.
pub const HIDDEN_SWEEP_QUICK: [usize; 2] = [3, 6];
/// Hidden neurons of the quick run's posture-aware net.
pub const HIDDEN_QUICK: usize = 6;

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
    /// Model family of the posture-aware nets (part (b) and its sweep): `hvs train`'s
    /// default for posture-aware sets
    /// ([`crate::train::DEFAULT_FAMILY`]) unless
    /// set. Part (a) always trains the thesis family (it studies the thesis' fixed-posture
    /// net), and so does part (c) (the thesis' net next to a wider one, a DLT fit and the
    /// floor).
    pub family: Family,
    /// Frame of the posture-aware nets' points: `hvs train`'s default for the family
    /// ([`default_frame`]) unless set.
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
    /// The settings of `hvs experiment posture`: the defaults with the sweep
    /// [`HIDDEN_SWEEP`] and the lattice-trained net (the settings of
    /// `docs/posture-study.md`'s tables); when `quick`, a 2x1x1x2x2 grid of training
    /// postures (8 postures, 576 rows), 9-6-3 nets, 3 and 6 hidden neurons, 300 test points,
    /// two lenses (k1 0 and -0.5) and a 4-4-3 lens net.
    pub fn experiment(seed: u64, quick: bool) -> StudyConfig {
        let full = StudyConfig {
            seed,
            hidden: HIDDEN,
            sweep: HIDDEN_SWEEP.to_vec(),
            lattice: true,
            ..StudyConfig::default()
        };
        if !quick {
            return full;
        }
        StudyConfig {
            train_levels: [2, 1, 1, 2, 2],
            hidden: HIDDEN_QUICK,
            sweep: HIDDEN_SWEEP_QUICK.to_vec(),
            distortion_hidden: vec![4],
            quick: true,
            ..full.reduced()
        }
    }
    /// This configuration at test size: one restart, 100 test postures, 300 test points,
    /// 100 extreme and 60 fixed-posture points, two lenses (k1 0 and -0.5).
    pub fn reduced(self) -> StudyConfig {
        StudyConfig {
            restarts: 1,
            test_postures: 100,
            test_points: 300,
            extreme_points: 100,
            fixed_points: 60,
            k1: vec![0.0, -0.5],
            ..self
        }
    }
    /// The rig of the configured case.
    pub fn rig(&self) -> Result<Rig> {
        match presets::case(self.case) {
            Some(r) => Ok(r),
            None => bail!("case must be 1-4, got {}", self.case),
        }
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
    let q = hvs_shared::runtime::gaze::quantize;
    let mut v = vec![("home".to_string(), Joints::HOME)];
    for (verg, dist) in [(2.5f32, 240), (5.0, 120), (10.0, 60)] {
        v.push((
            format!("vergence {verg} deg (fixating {dist} cm)"),
            Joints(joints_from_gaze(0.0, 0.0, 0.0, 0.0, verg).0.map(q)),
        ));
    }
    for version in [5.0f32, 10.0, 15.0] {
        v.push((
            format!("version {version} deg (eyes turned left)"),
            Joints(joints_from_gaze(0.0, 0.0, 0.0, version, 0.0).0.map(q)),
        ));
    }
    for pan in [10.0f32, 30.0] {
        v.push((
            format!("neck pan {pan} deg"),
            Joints(joints_from_gaze(pan, 0.0, 0.0, 0.0, 0.0).0.map(q)),
        ));
    }
    v.push((
        "eye tilt 10 deg".to_string(),
        Joints(joints_from_gaze(0.0, 0.0, 10.0, 0.0, 0.0).0.map(q)),
    ));
    v.push((
        "neck tilt 15 deg".to_string(),
        Joints(joints_from_gaze(0.0, 15.0, 0.0, 0.0, 0.0).0.map(q)),
    ));
    v.push((
        "verged 5 deg, version 10, neck pan 20".to_string(),
        Joints(joints_from_gaze(20.0, 0.0, 0.0, 10.0, 5.0).0.map(q)),
    ));
    v
}

/// The thesis' 4-5-3 net trained at home (board protocol, `hvs train` defaults), evaluated on
/// random points of the training volume placed in front of the head at each of
/// [`fixed_postures`] (the net gets the pixels only), with the floor at the same posture.
pub fn fixed_posture_study(cfg: &StudyConfig) -> Result<(ModelBlob, Vec<FixedRow>)> {
    let rig = cfg.rig()?;
    let head = HeadRig::new(rig);
    let train_set =
        posture::simulate(&head, SetKind::Train, &[Joints::HOME], &SimOptions::default())?;
    let mut data = Dataset::new(InputKind::Stereo);
    for s in &train_set {
        data.push(&s.px, Some(s.xyz));
    }
    let out = train(
        &data,
        &TrainConfig { seed: cfg.seed, family: Family::THESIS, ..TrainConfig::default() },
    )
    .context("training the home-posture 4-5-3 net")?;
    let mut rows = Vec::new();
    for (k, (label, j)) in fixed_postures().into_iter().enumerate() {
        let samples = posture::simulate(
            &head,
            SetKind::Volume,
            &[j],
            &SimOptions {
                points: cfg.fixed_points,
                noise_px: 0.0,
                seed: cfg.seed.wrapping_add(100 + k as u64),
                ..SimOptions::default()
            },
        )?;
        let (mut net, mut floor) = (Acc::default(), Acc::default());
        for s in &samples {
            net.add(&s.xyz, net_xyz(&out.blob, &s.px));
            floor.add(&s.xyz, head.optimal(&s.joints, &s.px).ok());
        }
        rows.push(FixedRow { label, joints: j, net: net.errors(), floor: floor.errors() });
    }
    Ok((out.blob, rows))
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

/// One hidden count of the sweep.
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
    /// The chosen net.
    pub blob: ModelBlob,
    /// Rows of its training set.
    pub train_rows: usize,
    /// Training postures.
    pub train_postures: usize,
    /// Per-band results of the chosen net.
    pub bands: Vec<BandRow>,
    /// The chosen net and the sweep, one row per training.
    pub sweep: Vec<HiddenRow>,
}

/// The gaze terms a band can be on, with their labels and band edges (thirds of the working
/// range, by magnitude; vergence by value).
fn band_defs(range: &PostureRange) -> Vec<(&'static str, usize, [f32; 4], bool)> {
    let names = ["neck pan", "neck tilt", "eye tilt", "version", "vergence"];
    let iv = range.intervals();
    (0..5)
        .map(|k| {
            let [lo, hi] = iv[k];
            let by_magnitude = k < 4;
            let (a, b) = if by_magnitude { (0.0, lo.abs().max(hi.abs())) } else { (lo, hi) };
            let e = [a, a + (b - a) / 3.0, a + 2.0 * (b - a) / 3.0, b];
            (names[k], k, e, by_magnitude)
        })
        .collect()
}

/// The test sets of the posture-aware study: random postures of the working range, and
/// extreme postures (the four angles in the outer third of their magnitude, vergence in the
/// upper third of its range).
fn test_sets(
    cfg: &StudyConfig,
    head: &HeadRig,
) -> Result<(Vec<PostureSample>, Vec<PostureSample>)> {
    let range = PostureRange::WORKING;
    let random = posture::postures(
        &PostureOptions {
            sampling: Sampling::Random,
            count: cfg.test_postures,
            ..PostureOptions::default()
        },
        cfg.seed.wrapping_add(11),
    )?;
    let test = posture::simulate(
        head,
        SetKind::Volume,
        &random,
        &SimOptions {
            points: cfg.test_points,
            noise_px: 0.0,
            seed: cfg.seed.wrapping_add(12),
            ..SimOptions::default()
        },
    )?;
    let mut rng = rand::rngs::ChaCha8Rng::seed_from_u64(cfg.seed.wrapping_add(13));
    let extreme: Vec<Joints> = (0..cfg.extreme_points.max(1))
        .map(|_| {
            range.at(core::array::from_fn(|k| {
                let u: f64 = rng.random();
                if k == 4 {
                    // Vergence: the upper third (the nearest fixations).
                    return 1.0 - u / 3.0;
                }
                // The outer third of the magnitude: the outer sixth at either end.
                let outer = u / 6.0;
                if rng.random::<bool>() {
                    1.0 - outer
                } else {
                    outer
                }
            }))
        })
        .collect();
    let extreme_set = posture::simulate(
        head,
        SetKind::Volume,
        &extreme,
        &SimOptions {
            points: cfg.extreme_points,
            noise_px: 0.0,
            seed: cfg.seed.wrapping_add(14),
            ..SimOptions::default()
        },
    )?;
    Ok((test, extreme_set))
}

/// Per-band errors of `blob` on `test` (and the whole `extreme` set), with the floor.
pub fn bands(
    blob: &ModelBlob,
    head: &HeadRig,
    test: &[PostureSample],
    extreme: &[PostureSample],
) -> Vec<BandRow> {
    let eval = |set: &[&PostureSample]| -> (Errors, Errors) {
        let (mut n, mut f) = (Acc::default(), Acc::default());
        for s in set {
            n.add(&s.xyz, net_xyz(blob, &s.inputs()));
            f.add(&s.xyz, head.optimal(&s.joints, &s.px).ok());
        }
        (n.errors(), f.errors())
    };
    let mut rows = Vec::new();
    let all: Vec<&PostureSample> = test.iter().collect();
    let (net, floor) = eval(&all);
    rows.push(BandRow {
        term: "all",
        band: "random postures of the working range".to_string(),
        net,
        floor,
    });
    for (name, k, e, by_magnitude) in band_defs(&PostureRange::WORKING) {
        for b in 0..3 {
            let inside: Vec<&PostureSample> = test
                .iter()
                .filter(|s| {
                    let v = PostureRange::gaze_terms(&s.joints)[k];
                    let v = if by_magnitude { v.abs() } else { v };
                    // The last band takes the quantisation overshoot at the top.
                    v >= e[b] - if b == 0 { 1.0 } else { 0.0 } && (v < e[b + 1] || b == 2)
                })
                .collect();
            if inside.is_empty() {
                continue;
            }
            let (net, floor) = eval(&inside);
            let side = if by_magnitude { " (either side)" } else { "" };
            rows.push(BandRow {
                term: name,
                band: format!("{:.1} to {:.1}{side}", e[b], e[b + 1]),
                net,
                floor,
            });
        }
    }
    let ext: Vec<&PostureSample> = extreme.iter().collect();
    if !ext.is_empty() {
        let (net, floor) = eval(&ext);
        rows.push(BandRow {
            term: "extreme",
            band: "all four angles in their outer third, vergence 6.7-10".to_string(),
            net,
            floor,
        });
    }
    rows
}

/// Trains the posture-aware net (and the sweep) and evaluates it per band.
pub fn posture_aware_study(cfg: &StudyConfig) -> Result<PostureAware> {
    let rig = cfg.rig()?;
    let head = HeadRig::new(rig);
    let (test, extreme) = test_sets(cfg, &head)?;
    let set_for = |sampling: Sampling| -> Result<(Dataset, usize)> {
        let js = posture::postures(
            &PostureOptions { sampling, levels: cfg.train_levels, ..PostureOptions::default() },
            cfg.seed,
        )?;
        let s = posture::simulate(&head, SetKind::Train, &js, &SimOptions::default())?;
        Ok((posture::dataset(&s), js.len()))
    };
    let (grid, n_postures) = set_for(Sampling::Grid)?;
    let run =
        |data: &Dataset, hidden: usize, postures: &'static str| -> Result<(ModelBlob, HiddenRow)> {
            let t0 = Instant::now();
            let out = train(
                data,
                &TrainConfig {
                    hidden,
                    restarts: cfg.restarts,
                    seed: cfg.seed,
                    family: cfg.family,
                    frame: cfg.frame,
                    ..TrainConfig::default()
                },
            )
            .with_context(|| format!("training the 9-{hidden}-3 net"))?;
            let seconds = t0.elapsed().as_secs_f64();
            let rows = bands(&out.blob, &head, &test, &extreme);
            let worst = rows.iter().map(BandRow::ratio).fold(0.0f64, |a, b| {
                if b.is_nan() {
                    f64::INFINITY
                } else {
                    a.max(b)
                }
            });
            let row = HiddenRow {
                hidden,
                postures,
                params: out.blob.params.len(),
                train_pct: out.train_error_pct,
                test: rows[0].net,
                floor: rows[0].floor,
                worst_band_ratio: worst,
                seconds,
            };
            Ok((out.blob, row))
        };
    let (blob, chosen) = run(&grid, cfg.hidden, "grid")?;
    let band_rows = bands(&blob, &head, &test, &extreme);
    let mut sweep = vec![chosen];
    for &h in &cfg.sweep {
        if h != cfg.hidden {
            sweep.push(run(&grid, h, "grid")?.1);
        }
    }
    if cfg.lattice {
        let (lattice, _) = set_for(Sampling::Lattice)?;
        sweep.push(run(&lattice, cfg.hidden, "lattice")?.1);
    }
    sweep.sort_by(|a, b| (a.postures, a.hidden).cmp(&(b.postures, b.hidden)));
    Ok(PostureAware {
        blob,
        train_rows: grid.len(),
        train_postures: n_postures,
        bands: band_rows,
        sweep,
    })
}

/// The wide board of [`distortion_study`]: a grid of points whose ideal cyclopean images span
/// `+-0.55` of the image half-width horizontally and `+-0.40` vertically (55 % of the width,
/// 53 % of the height of a 640x480 image) at each depth; per camera the farthest image point
/// is then about 0.74 half-widths from the centre, inside the radius (0.816) where a lens with
/// `k1 = -0.5` folds over.
pub const WIDE_BOARD_U: f64 = 0.55;
/// Vertical half-extent of the wide board, image half-widths.
pub const WIDE_BOARD_V: f64 = 0.40;

/// Points of the wide board at depth `z` (cm): `nu x nv` points evenly spread over the
/// board's extent, sized for the rig's larger focal length (so that neither camera sees more).
pub fn wide_board(rig: &Rig, z: f64, nu: usize, nv: usize) -> Vec<Vec3> {
    let hw = f64::from(rig.width) / 2.0;
    let phi = wide_board_phi(rig);
    let mut out = Vec::new();
    for i in 0..nv {
        for k in 0..nu {
            let a = |n: usize, j: usize| -1.0 + 2.0 * j as f64 / (n - 1).max(1) as f64;
            let u = a(nu, k) * WIDE_BOARD_U * hw;
            let v = a(nv, i) * WIDE_BOARD_V * hw;
            out.push([u * z / phi, v * z / phi, z]);
        }
    }
    out
}

fn wide_board_phi(rig: &Rig) -> f64 {
    rig.phi_u_left.max(rig.phi_u_right).max(rig.phi_v_left).max(rig.phi_v_right)
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

/// The lens study at the home posture: for each `k1`, the nets (4-H-3, trained on the wide
/// board at the six training depths, 9x7 points each) and the DLT fit (from the same
/// training points) against the floor, on random points of the wide board's frustum at
/// 65-165 cm.
pub fn distortion_study(cfg: &StudyConfig) -> Result<Vec<DistortionRow>> {
    let rig = cfg.rig()?;
    let mut train_pts = Vec::new();
    for z in presets::TRAIN_DEPTHS {
        train_pts.extend(wide_board(&rig, z, 9, 7));
    }
    let hw = f64::from(rig.width) / 2.0;
    let phi = wide_board_phi(&rig);
    let mut rng = rand::rngs::ChaCha8Rng::seed_from_u64(cfg.seed.wrapping_add(21));
    let test_pts: Vec<Vec3> = (0..cfg.test_points)
        .map(|_| {
            let (a, b, c): (f64, f64, f64) = (rng.random(), rng.random(), rng.random());
            let z = 65.0 + 100.0 * c;
            let u = (2.0 * a - 1.0) * WIDE_BOARD_U * hw;
            let v = (2.0 * b - 1.0) * WIDE_BOARD_V * hw;
            [u * z / phi, v * z / phi, z]
        })
        .collect();
    let mut rows = Vec::new();
    for &k1 in &cfg.k1 {
        let lens = Distortion { k1, k2: 0.0 };
        let head = HeadRig::new(rig).with_distortion(lens);
        let plain = HeadRig::new(rig);
        let j = Joints::HOME;
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
            let out = train(
                &data,
                &TrainConfig {
                    hidden: h,
                    seed: cfg.seed,
                    family: Family::THESIS,
                    ..TrainConfig::default()
                },
            )
            .with_context(|| format!("training the 4-{h}-3 net at k1 = {k1}"))?;
            nets.push((h, out.blob));
        }
        let mut net_acc = vec![Acc::default(); nets.len()];
        let (mut d, mut f) = (Acc::default(), Acc::default());
        let mut shift: f64 = 0.0;
        for p in &test_pts {
            let Some(px) = project(p) else { continue };
            if let Ok(ideal) = plain.project_rounded(&j, p) {
                for k in 0..4 {
                    shift = shift.max((ideal[k] - px[k]).abs());
                }
            }
            for (acc, (_, blob)) in net_acc.iter_mut().zip(&nets) {
                acc.add(p, net_xyz(blob, &px));
            }
            d.add(p, triangulate_dlt(&dlt, &px));
            f.add(p, head.optimal(&j, &px).ok());
        }
        rows.push(DistortionRow {
            k1,
            nets: nets.iter().zip(&net_acc).map(|((h, _), a)| (*h, a.errors())).collect(),
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
    /// (b) the posture-aware net.
    pub aware: PostureAware,
    /// (c) lens distortion.
    pub distortion: Vec<DistortionRow>,
    /// Wall time of each part (s): part (a); the sum of the posture-aware trainings' wall
    /// times, which overlap; the lens study's.
    pub seconds: [f64; 3],
    /// Wall time of each stage (s), in run order; not deterministic.
    pub stage_s: Vec<(&'static str, f64)>,
    /// Worker threads used.
    pub threads: usize,
}

enum Job {
    Aware(usize),
    Lens,
}

impl Job {
    /// Rough relative cost, for the order of the queue (a training's time grows about
    /// linearly with the hidden count at this size; the lens study costs about as much as an
    /// 8-neuron net; the chosen count also trains the lattice net).
    fn cost(&self, study: &StudyConfig) -> usize {
        match self {
            Job::Aware(h) if *h == study.hidden && study.lattice => 2 * h,
            Job::Aware(h) => *h,
            Job::Lens => 8,
        }
    }
}

enum Done {
    Aware(usize, Box<PostureAware>, f64),
    Lens(Vec<DistortionRow>, f64),
}

/// Runs the study: part (a) first, then the posture-aware nets of the sweep and the lens
/// study side by side on the rayon pool (longest first), each one call of
/// [`posture_aware_study`] with one hidden count and no sweep (the chosen count with the
/// lattice-trained net) or of [`distortion_study`]. Every training takes the study's seed,
/// so the numbers do not depend on the thread count; only the wall times do.
pub fn run(study: &StudyConfig, progress: &dyn Progress) -> Result<Posture> {
    let mut stage_s = Vec::new();

    progress.start("fixed-posture 4-5-3 net", 1);
    let t = Instant::now();
    let (_, fixed) = fixed_posture_study(study)?;
    let fixed_s = t.elapsed().as_secs_f64();
    progress.inc();
    progress.finish();
    stage_s.push(("fixed-posture net", fixed_s));

    // Longest first.
    let mut hidden: Vec<usize> = study.sweep.clone();
    if !hidden.contains(&study.hidden) {
        hidden.push(study.hidden);
    }
    hidden.sort_unstable();
    hidden.dedup();
    let mut jobs: Vec<Job> = hidden.iter().map(|&h| Job::Aware(h)).collect();
    jobs.push(Job::Lens);
    jobs.sort_by_key(|j| std::cmp::Reverse(j.cost(study)));

    progress.start("posture-aware nets, lens", jobs.len() as u64);
    let t = Instant::now();
    let next = AtomicUsize::new(0);
    let results: Mutex<Vec<Option<Result<Done>>>> =
        Mutex::new((0..jobs.len()).map(|_| None).collect());
    let threads = rayon::current_num_threads().min(jobs.len()).max(1);
    (0..threads).into_par_iter().for_each(|_| loop {
        let k = next.fetch_add(1, Ordering::SeqCst);
        let Some(job) = jobs.get(k) else { break };
        let t0 = Instant::now();
        let done = match job {
            Job::Aware(h) => posture_aware_study(&StudyConfig {
                hidden: *h,
                sweep: Vec::new(),
                lattice: study.lattice && *h == study.hidden,
                ..study.clone()
            })
            .map(|a| Done::Aware(*h, Box::new(a), t0.elapsed().as_secs_f64()))
            .with_context(|| format!("the posture-aware 9-{h}-3 net")),
            Job::Lens => distortion_study(study)
                .map(|d| Done::Lens(d, t0.elapsed().as_secs_f64()))
                .context("the lens study"),
        };
        progress.inc();
        if done.is_err() {
            // No point in the rest: the first error is the run's.
            next.store(jobs.len(), Ordering::SeqCst);
        }
        if let Ok(mut r) = results.lock() {
            r[k] = Some(done);
        }
    });
    progress.finish();
    stage_s.push(("posture-aware nets and lens", t.elapsed().as_secs_f64()));

    let mut results =
        results.into_inner().map_err(|_| anyhow!("a worker of the posture study panicked"))?;
    if let Some(k) = results.iter().position(|r| matches!(r, Some(Err(_)))) {
        if let Some(Some(Err(e))) = results.get_mut(k).map(Option::take) {
            return Err(e);
        }
    }
    let mut chosen: Option<PostureAware> = None;
    let mut sweep: Vec<HiddenRow> = Vec::new();
    let mut distortion = Vec::new();
    let (mut aware_s, mut lens_s) = (0.0, 0.0);
    for r in results {
        match r.ok_or_else(|| anyhow!("a job of the posture study did not run"))?? {
            Done::Aware(h, a, s) => {
                aware_s += s;
                sweep.extend(a.sweep.iter().cloned());
                if h == study.hidden {
                    chosen = Some(*a);
                }
            }
            Done::Lens(d, s) => {
                distortion = d;
                lens_s = s;
            }
        }
    }
    let mut aware = chosen.ok_or_else(|| anyhow!("no posture-aware net of the chosen size"))?;
    // As the library orders its sweep.
    sweep.sort_by(|a, b| (a.postures, a.hidden).cmp(&(b.postures, b.hidden)));
    aware.sweep = sweep;
    Ok(Posture {
        config: study.clone(),
        fixed,
        aware,
        distortion,
        seconds: [fixed_s, aware_s, lens_s],
        stage_s,
        threads,
    })
}

/// The family of the posture-aware nets in words, for the report.
pub fn family_words(f: Family, frame: OutputFrame) -> String {
    use hvs_shared::runtime::blob::Skip;
    use hvs_shared::runtime::mlp::OutputMap;
    let outputs = match f.output_map {
        OutputMap::Direct => "X, Y, Z",
        OutputMap::InverseDepth => "X/Z, Y/Z, 1/Z",
    };
    let skip = match f.skip {
        Skip::None => "",
        Skip::Linear => ", each the sigmoid net's plus an affine skip term of the nine inputs",
    };
    let frame = match frame {
        OutputFrame::Head => "",
        OutputFrame::EyePlatform => {
            ", in the eye platform's frame (the head frame turned by the neck pan, neck tilt and \
             eye tilt inputs), turned back into the head frame by the model"
        }
    };
    format!("`{}` (outputs {outputs}{skip}{frame})", f.name())
}

/// Appends one CSV line: the fields as they display, comma-separated.
fn csv_row(out: &mut String, fields: &[&dyn std::fmt::Display]) {
    let _ = writeln!(out, "{}", join(fields, ","));
}

/// The report's tables as CSV files: `fixed.csv`, `bands.csv`, `hidden.csv`,
/// `distortion.csv`, and the wall times in `timing.csv` (so that the four tables depend on the
/// configuration only: same seed, same bytes). The caller writes them atomically.
pub fn csv_tables(r: &Posture) -> Vec<(&'static str, String)> {
    let e =
        |x: &Errors| format!("{},{},{},{},{}", x.points, x.z_pct, x.d3_pct, x.max_z_pct, x.failed);
    let eh = |p: &str| format!("{p}_points,{p}_z_pct,{p}_d3_pct,{p}_max_z_pct,{p}_failed");
    let mut fixed = format!(
        "posture,{},{},{}\n",
        crate::data::dataset::JOINT_COLUMNS.join(","),
        eh("net"),
        eh("floor")
    );
    for row in &r.fixed {
        let label = format!("\"{}\"", row.label);
        let j = join(row.joints.0, ",");
        csv_row(&mut fixed, &[&label, &j, &e(&row.net), &e(&row.floor)]);
    }
    let mut bands = format!("term,band,{},{}\n", eh("net"), eh("floor"));
    for b in &r.aware.bands {
        let band = format!("\"{}\"", b.band);
        csv_row(&mut bands, &[&b.term, &band, &e(&b.net), &e(&b.floor)]);
    }
    let mut hidden = format!(
        "postures,hidden,params,train_pct,{},{},worst_band_ratio\n",
        eh("test"),
        eh("floor")
    );
    let mut timing = "what,postures,hidden,seconds\n".to_string();
    for (k, part) in ["(a) fixed posture", "(b) posture-aware", "(c) lens"].iter().enumerate() {
        let _ = writeln!(timing, "{part},,,{}", r.seconds[k]);
    }
    for h in &r.aware.sweep {
        csv_row(
            &mut hidden,
            &[
                &h.postures,
                &h.hidden,
                &h.params,
                &h.train_pct,
                &e(&h.test),
                &e(&h.floor),
                &h.worst_band_ratio,
            ],
        );
        let _ = writeln!(timing, "training,{},{},{}", h.postures, h.hidden, h.seconds);
    }
    let mut dist = "k1,max_shift_px,method,points,z_pct,d3_pct,max_z_pct,failed\n".to_string();
    for d in &r.distortion {
        for (h, x) in &d.nets {
            let _ = writeln!(dist, "{},{},net_4_{h}_3,{}", d.k1, d.max_shift_px, e(x));
        }
        let _ = writeln!(dist, "{},{},dlt,{}", d.k1, d.max_shift_px, e(&d.dlt));
        let _ = writeln!(dist, "{},{},floor,{}", d.k1, d.max_shift_px, e(&d.floor));
    }
    vec![
        ("fixed.csv", fixed),
        ("bands.csv", bands),
        ("hidden.csv", hidden),
        ("distortion.csv", dist),
        ("timing.csv", timing),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wide_board_stays_inside_the_image_and_the_lens_fold() {
        for n in 1..=4 {
            let rig = presets::case(n).unwrap();
            let head = HeadRig::new(rig).with_distortion(Distortion { k1: -0.5, k2: 0.0 });
            let [l, r] = head.cameras(&Joints::HOME);
            for z in [65.0, 165.0] {
                let b = wide_board(&rig, z, 9, 7);
                assert_eq!(b.len(), 63);
                for p in &b {
                    let px = head.project(&Joints::HOME, p).unwrap();
                    assert!(rig.in_image(&px), "case {n} {p:?}: {px:?}");
                    for (c, cam) in [(0, &l), (2, &r)] {
                        let o = [px[c] - 320.0, px[c + 1] - 240.0];
                        assert!(cam.distortion.undo(o, 320.0).is_some(), "case {n} {p:?}");
                    }
                }
            }
        }
    }

    fn small() -> StudyConfig {
        StudyConfig {
            train_levels: [2, 2, 2, 2, 2],
            hidden: 8,
            distortion_hidden: vec![5],
            ..StudyConfig::default().reduced()
        }
    }

    /// The posture-aware nets are trained in the configured family and frame (by default
    /// `hvs train`'s for a posture-aware set); part (a) stays the thesis' net whatever it is.
    #[test]
    fn posture_aware_nets_use_the_configured_family() {
        assert_eq!(StudyConfig::default().family, crate::train::DEFAULT_FAMILY);
        assert_eq!(StudyConfig::default().frame, OutputFrame::EyePlatform);
        let cfg = StudyConfig {
            train_levels: [1, 1, 1, 1, 2],
            hidden: 3,
            test_postures: 10,
            test_points: 30,
            extreme_points: 10,
            fixed_points: 10,
            family: Family::INVERSE_DEPTH_SKIP,
            ..StudyConfig::default().reduced()
        };
        let aware = posture_aware_study(&cfg).unwrap();
        assert_eq!(aware.blob.family, Family::INVERSE_DEPTH_SKIP);
        assert_eq!(aware.blob.frame, OutputFrame::EyePlatform);
        // 9-3-3: 13 * 3 + 3 net weights and 3 x 9 skip weights.
        assert_eq!(aware.blob.params.len(), 13 * 3 + 3 + 27);
        assert_eq!(aware.sweep[0].params, aware.blob.params.len());
        let (fixed, _) = fixed_posture_study(&cfg).unwrap();
        assert_eq!(fixed.family, Family::THESIS);
    }

    /// (a) and (c) at a small size: what they show must hold even there.
    #[test]
    fn fixed_posture_and_lens_parts_show_the_effects() {
        let cfg = small();
        let (_, fixed) = fixed_posture_study(&cfg).unwrap();
        // Home: the thesis net is near the floor; verged 10 degrees it is off by over 50 %.
        assert_eq!(fixed[0].label, "home");
        assert!(fixed[0].net.z_pct < 2.5, "{:?}", fixed[0]);
        let verged = fixed.iter().find(|f| f.label.starts_with("vergence 10")).unwrap();
        assert!(verged.net.z_pct > 50.0, "{verged:?}");
        assert!(verged.floor.z_pct < 2.0, "{verged:?}");
        // Without distortion the DLT is the floor up to rounding; at k1 = -0.5 the linear
        // model is clearly worse, the floor barely moves.
        let d = distortion_study(&cfg).unwrap();
        let (d0, d5) = (&d[0], &d[1]);
        assert_eq!(d0.max_shift_px, 0.0);
        assert!(d5.max_shift_px > 20.0, "{d5:?}");
        assert!(d0.dlt.z_pct < 1.1 * d0.floor.z_pct, "{d0:?}");
        assert!(d5.dlt.z_pct > 2.0 * d0.dlt.z_pct, "{d5:?}");
        assert!(d5.floor.z_pct < 1.5 * d0.floor.z_pct, "{d5:?}");
        assert_eq!((d0.floor.failed, d5.floor.failed, d5.dlt.failed), (0, 0, 0));
        // Writers: every table has a header and one line per row.
        let r = Posture {
            config: cfg.clone(),
            fixed,
            aware: PostureAware {
                blob: hvs_tests_blob(),
                train_rows: 0,
                train_postures: 0,
                bands: Vec::new(),
                sweep: Vec::new(),
            },
            distortion: d,
            seconds: [0.0; 3],
            stage_s: Vec::new(),
            threads: 1,
        };
        let tables = csv_tables(&r);
        assert_eq!(tables[0].1.lines().count(), 1 + r.fixed.len());
        assert_eq!(tables[3].1.lines().count(), 1 + 2 * 3);
        assert_eq!(tables[4].0, "timing.csv");
        assert_eq!(tables[4].1.lines().count(), 1 + 3);
    }

    /// Any 9-input blob (a barely trained one) for the writers and the band bookkeeping.
    fn hvs_tests_blob() -> ModelBlob {
        let head = HeadRig::new(presets::CASE_3);
        let js = [Joints::HOME, Joints([10.0, 5.0, -5.0, 3.0, 8.0])];
        let s = posture::simulate(&head, SetKind::Train, &js, &SimOptions::default()).unwrap();
        let cfg = TrainConfig { hidden: 3, restarts: 1, ..TrainConfig::default() };
        train(&posture::dataset(&s), &cfg).unwrap().blob
    }

    #[test]
    fn bands_partition_the_test_set_and_the_floor_is_posture_independent() {
        let cfg = small();
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
        let rows = bands(&hvs_tests_blob(), &head, &test, &extreme);
        assert_eq!(rows[0].term, "all");
        assert_eq!(rows.last().unwrap().term, "extreme");
        for term in ["neck pan", "neck tilt", "eye tilt", "version", "vergence"] {
            let b: Vec<&BandRow> = rows.iter().filter(|b| b.term == term).collect();
            assert_eq!(b.len(), 3, "{term}");
            assert_eq!(b.iter().map(|b| b.net.points).sum::<usize>(), 300, "{term}");
            // The floor is about the same in every band: rounding, not posture, limits it.
            for x in &b {
                assert!(x.floor.z_pct > 0.9 && x.floor.z_pct < 1.8, "{x:?}");
                assert_eq!(x.floor.failed, 0);
            }
        }
    }
}
