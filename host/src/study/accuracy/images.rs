//! The `images` part of the accuracy study: the pixels are not simulated but detected.
//! Stereo images of the 9x6 chessboard at 6 cm (`hvs_vision::render::opencv_board`, the
//! board of `hvs demo --images`) are rendered through thesis case IV at the training depths
//! (centred on the axis) and at the thesis' test depths (3 cm right, 2 cm up, as the demo's
//! test boards, so no test corner is a training corner), their corners detected
//! (`hvs_vision::detect::detect_pair`, sub-pixel), and the four estimators fitted on the
//! detected training corners and scored on the detected test corners. Three image regimes:
//! mild (the renderer's default blur and sensor noise), heavy (more of both), barrel (mild,
//! through lenses with k1 = -0.1; the floor triangulates through the true lenses).
//!
//! Everything happens in memory; the same seeds give the same images, corners and numbers.

use super::{case_rig, estimate, mean_scores, set_seed, AccuracyConfig, Scores, SWEEP_CASE};
use crate::data::dataset::Dataset;
use crate::study::engine::Progress;
use anyhow::{anyhow, bail, Context, Result};
use hvs_shared::runtime::blob::InputKind;
use hvs_shared::runtime::gaze::Joints;
use hvs_shared::sim::camera::{Distortion, Vec3};
use hvs_shared::sim::posture::HeadRig;
use hvs_shared::sim::presets;
use hvs_vision::detect::detect_pair;
use hvs_vision::render::{opencv_board, render_pair, RenderOptions};
use rayon::prelude::*;

/// Where the test boards' centre is (cm), as `hvs demo --images`.
pub const TEST_CENTRE: [f64; 2] = [3.0, -2.0];

/// How the images of a regime are made.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImageRegime {
    /// Short name.
    pub name: &'static str,
    /// Gaussian blur (px).
    pub blur_px: f64,
    /// Sensor noise (grey levels).
    pub noise_grey: f64,
    /// Radial distortion k1 of both lenses.
    pub k1: f64,
}

/// Mild (the renderer's defaults), heavy, and mild through barrel lenses.
pub fn image_regimes() -> [ImageRegime; 3] {
    let d = RenderOptions::default();
    [
        ImageRegime { name: "mild", blur_px: d.blur_sigma_px, noise_grey: d.noise_sigma, k1: 0.0 },
        ImageRegime { name: "heavy", blur_px: 2.0, noise_grey: 8.0, k1: 0.0 },
        ImageRegime {
            name: "barrel",
            blur_px: d.blur_sigma_px,
            noise_grey: d.noise_sigma,
            k1: -0.1,
        },
    ]
}

/// What one image regime gave.
#[derive(Debug, Clone, PartialEq)]
pub struct ImageRow {
    /// The regime.
    pub regime: ImageRegime,
    /// Training corners detected, of those rendered.
    pub train_corners: [usize; 2],
    /// Test corners detected, of those rendered.
    pub test_corners: [usize; 2],
    /// Mean |detected - exact| per image coordinate over the detected training corners (px).
    pub corner_error_px: f64,
    /// Mean e_ma on the detected test corners.
    pub scores: Scores,
}

/// One detected corner: its detected pixels, true position and exact pixels.
type Found = ([f64; 4], Vec3, [f64; 4]);

/// Detected corners of boards at `depths` centred at `xy`, with their true positions, and
/// the number of corners rendered, and the sum of |detected - exact| over every coordinate.
fn detect_boards(
    head: &HeadRig,
    regime: &ImageRegime,
    xy: [f64; 2],
    depths: &[f64],
    seed: impl Fn(usize) -> u64 + Sync,
) -> Result<(Dataset, usize, f64)> {
    let board = opencv_board();
    let opt = RenderOptions {
        blur_sigma_px: regime.blur_px,
        noise_sigma: regime.noise_grey,
        ..RenderOptions::default()
    };
    let found: Vec<Option<Vec<Found>>> = depths
        .par_iter()
        .enumerate()
        .map(|(k, &z)| {
            let r = render_pair(head, &Joints::HOME, &board, [xy[0], xy[1], z], &opt, seed(k))
                .map_err(|e| anyhow!("{e}"))
                .with_context(|| format!("rendering the board at Z = {z} cm"))?;
            let Ok(p) = detect_pair(&r.left, &r.right, &board) else {
                return Ok(None);
            };
            let mut out = Vec::new();
            for c in &r.corners {
                let (l, rt) = (p.left.at(c.i, c.j), p.right.at(c.i, c.j));
                out.push(([l[0], l[1], rt[0], rt[1]], c.xyz, c.px));
            }
            Ok(Some(out))
        })
        .collect::<Result<_>>()?;
    let mut data = Dataset::new(InputKind::Stereo);
    let mut err = 0.0;
    for pts in found.iter().flatten() {
        for (px, xyz, truth) in pts {
            data.push(px, Some(*xyz));
            err += (0..4).map(|c| (px[c] - truth[c]).abs()).sum::<f64>();
        }
    }
    Ok((data, depths.len() * board.corner_count(), err))
}

/// Training and test depths (cm): the thesis' (65 and 165 cm only when quick).
fn depths(cfg: &AccuracyConfig) -> (Vec<f64>, Vec<f64>) {
    if cfg.quick {
        (vec![65.0, 165.0], vec![65.0, 165.0])
    } else {
        (presets::TRAIN_DEPTHS.to_vec(), presets::TEST_DEPTHS.to_vec())
    }
}

/// The image part: every regime of [`image_regimes`] (the first only when quick).
pub fn image_rows(cfg: &AccuracyConfig, progress: &dyn Progress) -> Result<Vec<ImageRow>> {
    let regimes = image_regimes();
    let regimes = if cfg.quick { &regimes[..1] } else { &regimes[..] };
    progress.start("images", regimes.len() as u64);
    let rig = case_rig(SWEEP_CASE)?;
    let rows = regimes
        .iter()
        .enumerate()
        .map(|(k, regime)| {
            let s = image_sets(cfg, k, regime)?;
            let ev = estimate(cfg, &rig, s.lens, &s.train, &s.test)
                .with_context(|| format!("images {}", regime.name))?;
            progress.inc();
            Ok(ImageRow {
                regime: *regime,
                train_corners: [s.train.len(), s.train_rendered],
                test_corners: [s.test.len(), s.test_rendered],
                corner_error_px: s.corner_error_px,
                scores: mean_scores(&ev),
            })
        })
        .collect::<Result<Vec<_>>>()?;
    progress.finish();
    Ok(rows)
}

/// The detected corners of one image regime: what the estimators are fitted on and scored on.
#[derive(Debug, Clone)]
pub struct ImageSets {
    /// Both lenses.
    pub lens: Distortion,
    /// Detected training corners with their true positions.
    pub train: Dataset,
    /// Detected test corners with their true positions.
    pub test: Dataset,
    /// Training corners rendered.
    pub train_rendered: usize,
    /// Test corners rendered.
    pub test_rendered: usize,
    /// Mean |detected - exact| per image coordinate over the detected training corners (px).
    pub corner_error_px: f64,
}

/// Renders and detects the training and test boards of regime `regime`, the `k`-th of
/// [`image_regimes`] (its seeds derive from `cfg.seed_base` and `k`), through case IV.
pub fn image_sets(cfg: &AccuracyConfig, k: usize, regime: &ImageRegime) -> Result<ImageSets> {
    let rig = case_rig(SWEEP_CASE)?;
    let (train_z, test_z) = depths(cfg);
    let lens = Distortion { k1: regime.k1, k2: 0.0 };
    let head = HeadRig::new(rig).with_distortion(lens);
    let seed = |set: u64| move |d: usize| set_seed(cfg.seed_base, 3, k, d, SWEEP_CASE, set);
    let (train, train_n, err) = detect_boards(&head, regime, [0.0, 0.0], &train_z, seed(1))?;
    let (test, test_n, _) = detect_boards(&head, regime, TEST_CENTRE, &test_z, seed(2))?;
    if train.len() < 2 * opencv_board().corner_count() || test.is_empty() {
        bail!(
            "images {}: too few boards detected ({} training and {} test corners)",
            regime.name,
            train.len(),
            test.len()
        );
    }
    Ok(ImageSets {
        lens,
        corner_error_px: err / (4 * train.len()) as f64,
        train,
        test,
        train_rendered: train_n,
        test_rendered: test_n,
    })
}
