//! The `images` part: stereo images of the 9x6 board at 6 cm rendered through case IV at the
//! training depths (on the axis) and the thesis' test depths ([`TEST_CENTRE`], as `hvs demo
//! --images`), corners detected in memory; the four estimators fitted and scored on them.

use super::{case_rig, estimate, set_seed, AccuracyConfig, Scores, SWEEP_CASE};
use crate::data::dataset::Dataset;
use crate::evaluate::optimal_depths_lens;
use crate::study::engine::{par_stage, Progress, Reduced};
use crate::vision::detected_set;
use anyhow::{anyhow, bail, Context, Result};
use hvs_shared::runtime::gaze::Joints;
use hvs_shared::sim::{camera::Distortion, posture::HeadRig, presets};
use hvs_vision::detect::detect_pair;
use hvs_vision::render::{opencv_board, render_pair, RenderOptions};
use rayon::prelude::*;

/// How the images of a regime are made: Gaussian blur (px), sensor noise (grey levels),
/// radial distortion k1 of both lenses.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImageRegime {
    pub name: &'static str,
    pub blur_px: f64,
    pub noise_grey: f64,
    pub k1: f64,
}

/// Mild (the renderer's defaults), heavy, and mild through barrel lenses.
pub fn image_regimes() -> [ImageRegime; 3] {
    let d = RenderOptions::default();
    let mild =
        ImageRegime { name: "mild", blur_px: d.blur_sigma_px, noise_grey: d.noise_sigma, k1: 0.0 };
    [
        mild,
        ImageRegime { name: "heavy", blur_px: 2.0, noise_grey: 8.0, k1: 0.0 },
        ImageRegime { name: "barrel", k1: -0.1, ..mild },
    ]
}

/// Where the test boards' centre is (cm): off the training boards' axis, so that no test
/// corner is a training corner.
pub const TEST_CENTRE: [f64; 2] = [3.0, -2.0];

/// What detection found in the rendered boards of one run (this part's, or `hvs demo
/// --images`'s).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Detected {
    /// Training corners detected, of those rendered.
    pub train_corners: [usize; 2],
    /// Test corners detected, of those rendered.
    pub test_corners: [usize; 2],
    /// Mean |detected - exact| per image coordinate of the detected training corners (px).
    pub corner_error_px: f64,
}

/// What one image regime gave: its detection and the scores on the detected test corners.
#[derive(Debug, Clone, PartialEq)]
pub struct ImageRow {
    pub regime: ImageRegime,
    pub detected: Detected,
    pub scores: Scores,
}

/// The detected corners of boards at `depths` centred at `xy` with their true positions, the
/// number of corners rendered, and the mean corner error (px).
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
    let found: Vec<Vec<_>> = depths
        .par_iter()
        .enumerate()
        .map(|(k, &z)| {
            let r = render_pair(head, &Joints::HOME, &board, [xy[0], xy[1], z], &opt, seed(k))
                .map_err(|e| anyhow!("{e}"))
                .with_context(|| format!("rendering the board at Z = {z} cm"))?;
            let Ok(p) = detect_pair(&r.left, &r.right, &board) else { return Ok(Vec::new()) };
            let (l, rt) = (&p.left, &p.right);
            let px = |i, j| [l.at(i, j)[0], l.at(i, j)[1], rt.at(i, j)[0], rt.at(i, j)[1]];
            Ok(r.corners.iter().map(|c| (px(c.i, c.j), c.xyz, c.px)).collect())
        })
        .collect::<Result<_>>()?;
    let (data, err) = detected_set(found.into_iter().flatten());
    Ok((data, depths.len() * board.corner_count(), err))
}

/// The image part: every regime of [`image_regimes`] (the first only when quick), the `k`-th
/// with seeds from `cfg.seed_base` and `k`; training and test depths the thesis' (65 and 165
/// cm only when quick).
pub fn image_rows(cfg: &AccuracyConfig, progress: &dyn Progress) -> Result<Vec<ImageRow>> {
    let regimes = image_regimes();
    let regimes: Vec<_> = regimes.iter().take(cfg.pick(3, 1)).enumerate().collect();
    let quick = &[65.0, 165.0][..];
    let (train_z, test_z) =
        cfg.pick((&presets::TRAIN_DEPTHS[..], &presets::TEST_DEPTHS[..]), (quick, quick));
    let rig = case_rig(SWEEP_CASE)?;
    par_stage(progress, "images", &regimes, |&(k, regime)| {
        let lens = Distortion { k1: regime.k1, k2: 0.0 };
        let head = HeadRig::new(rig).with_distortion(lens);
        let seed = |set: u64| move |d: usize| set_seed(cfg.seed_base, 3, k, d, SWEEP_CASE, set);
        let (train, train_n, corner_error_px) =
            detect_boards(&head, regime, [0.0, 0.0], train_z, seed(1))?;
        let (test, test_n, _) = detect_boards(&head, regime, TEST_CENTRE, test_z, seed(2))?;
        if train.len() < 2 * opencv_board().corner_count() || test.is_empty() {
            let (name, n, m) = (regime.name, train.len(), test.len());
            bail!("images {name}: too few boards detected ({n} training and {m} test corners)");
        }
        let ev = estimate(cfg, optimal_depths_lens(&rig, lens, &test), &train, &test)
            .with_context(|| format!("images {}", regime.name))?;
        let (train_corners, test_corners) = ([train.len(), train_n], [test.len(), test_n]);
        let detected = Detected { train_corners, test_corners, corner_error_px };
        Ok(ImageRow { regime: *regime, detected, scores: Scores::mean(&ev) })
    })
}
