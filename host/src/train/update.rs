//! Learning stroke by stroke: a trained stereo model updated with a new set of points,
//! without forgetting what the new set does not cover.
//!
//! A new capture (one board at one depth is enough) says little about the rest of the volume,
//! so the net is not fitted to it alone. The update reads the old rig out of the old model and
//! asks the new points only what changed in each camera:
//!
//! 1. Samples of the old model's view of its training volume: left pixels uniform in its
//!    training box, a disparity uniform in its training range, the right pixel on the
//!    epipolar line of the blob's fundamental matrix; the old net's point for each, kept when
//!    it lies in the box of the old training targets ([`SAMPLES`] of them).
//! 2. A 3x4 camera per side fitted to those samples (normalised DLT): the old rig as the old
//!    model sees it.
//! 3. Per camera, the image-to-image homography from the old camera's pixels of the new
//!    points to their measured pixels. A camera that turned on its mount (a knock) moves every
//!    pixel by exactly such a homography, whatever the depth, so one plane of points measures
//!    it. It is used only when it explains the new pixels significantly better than the old
//!    camera does (an F test, [`F_CRITICAL`]): where the old model still fits the new points
//!    the camera is held as it was.
//! 4. The net, from the old weights and the old scaling, learns the samples with their
//!    pixels moved by those homographies and their targets the old model's own points (where
//!    nothing moved, exactly what it gave before) ([`UPDATE_MAX_ITER`] LM steps at most). The new points reach the net only through the
//!    cameras' homographies: learned directly, 54 noisy points of one depth pull the net
//!    away from the rest of the volume (ten updates of an unchanged rig, case III: up to
//!    1.07x the error before the first; through the cameras: 1.00x).
//!
//! A camera that also moved along its mount (a translation) moves the pixels by a homography
//! only at the new points' depth: the update is then exact there and approximate elsewhere.
//! Family, topology, inputs, output frame and scaling are the old model's. Posture-aware
//! (9-input) and Z-only models, and models without stereo geometry, are refused: the update
//! needs the old model's rig.

use super::net::Problem;
use super::rng::SplitMix64;
use super::{lm, problem, Algo, Scaling, TrainConfig};
use crate::data::dataset::Dataset;
use anyhow::{bail, Result};
use hvs_shared::runtime::blob::{InputKind, ModelBlob, OutputKind};
use hvs_shared::runtime::mlp::Activation;
use hvs_vision::geometry::{fit_dlt, fit_homography, Homography};
use nalgebra::{Matrix3x4, Vector4};
use std::time::{Duration, Instant};

/// Samples of the old model's volume the update learns.
pub const SAMPLES: usize = 1000;
/// Most draws made to find [`SAMPLES`] samples inside the old training box.
const MAX_DRAWS: usize = 50 * SAMPLES;
/// Fewest new points an update takes (a homography per camera needs four; the F test needs
/// residual degrees of freedom).
pub const MIN_POINTS: usize = 8;
/// A camera's homography is used when `((SS_old - SS_fit) / 8) / (SS_fit / (2n - 8))`
/// exceeds this (`SS`: sums of squared pixel residuals of the `n` new points, before and
/// after the fit). Unchanged rigs, 0.05 px noise (case III, 44 captures of one board): 0.6-7;
/// the left camera panned by 0.5 degrees: above 10^4.
pub const F_CRITICAL: f64 = 20.0;
/// Most LM steps of the update (it starts from the old weights). The knocked camera of the
/// CLI test and the README: 12 and 30 steps give the same volume error to 3 digits, in half
/// the time.
pub const UPDATE_MAX_ITER: usize = 12;
/// Largest RMS (px) of the new points about an old camera that the update holds, and about
/// a moved camera's homography: above it about the old camera, with no homography that the F
/// test takes or one that leaves more than this, the points fit neither the old camera nor a
/// moved one, so a row is wrong or the rig changed in a way one set of points cannot measure,
/// and the update is refused. Rounded pixels of an unchanged rig: 0.3-0.5 px; the README's
/// knocked camera's homography: 0.07 px. One row at z = 0.001 cm (a QA pass, 2026-12-08): F
/// in the thousands, the homography 44 px rms, and the update had been written.
pub const HELD_MAX_RMS_PX: f64 = 2.0;
/// An update whose e_ma on the new points is above this many times the old model's (plus
/// [`WORSE_SLACK_PCT`]) is refused: it learned points that its cameras do not explain.
pub const WORSE_FACTOR: f64 = 1.5;
/// See [`WORSE_FACTOR`] (percentage points).
pub const WORSE_SLACK_PCT: f64 = 0.1;
/// Mixed into the seed for the samples' stream.
const STREAM: u64 = 0x7570_6461_7465_7374;

/// What one camera's check found.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CameraCheck {
    /// RMS (px) of the old camera's pixels of the new points against the measured ones.
    pub old_rms_px: f64,
    /// RMS (px) after the homography fit.
    pub fit_rms_px: f64,
    /// The F statistic of the fit.
    pub f: f64,
    /// Whether the camera moved (the homography is used).
    pub moved: bool,
    /// Largest move (px) of the homography over the samples' pixels of this camera (0 when
    /// not moved).
    pub max_move_px: f64,
}

/// The result of [`update`].
#[derive(Debug, Clone)]
pub struct UpdateOutcome {
    /// The updated model: the old one with new weights, input box and training metadata
    /// (generation, parent, fallback and matcher are the caller's).
    pub blob: ModelBlob,
    /// e_ma (%) of the old model on the new points.
    pub old_error_pct: f64,
    /// e_ma (%) of the updated model on the new points.
    pub new_error_pct: f64,
    /// Left and right camera.
    pub cameras: [CameraCheck; 2],
    /// The set the net learned: the samples of the old volume through the moved cameras.
    pub learned: Dataset,
    /// LM steps taken.
    pub iterations: usize,
    /// Wall time.
    pub elapsed: Duration,
}

/// Updates `old` with the points of `new` (ground truth required); `seed` draws the samples.
/// Errors name what does not match or cannot be done, and the rows by `at(row)` (the
/// caller's `file:line`). Refused too: points that cannot show whether a camera moved (on one
/// line, or one point repeated), points that fit neither an old camera nor a moved one
/// ([`HELD_MAX_RMS_PX`]), and an update that fits its own points worse than the old model
/// ([`WORSE_FACTOR`]); each names the row farthest from the cameras.
pub fn update(
    old: &ModelBlob,
    new: &Dataset,
    seed: u64,
    at: &dyn Fn(usize) -> String,
) -> Result<UpdateOutcome> {
    let start = Instant::now();
    check(old, new, at)?;
    let Some(matcher) = old.matcher else {
        bail!(
            "the old model has no matcher geometry to sample its volume from: {}",
            super::matcher::NO_MATCHER_WHY
        );
    };
    let samples = sample_volume(old, &matcher, seed)?;
    let cams = [0, 1].map(|c| fit_camera(&samples, c));
    let [Some(cam_l), Some(cam_r)] = cams else {
        bail!("the old model's view of its volume is not explained by two pinhole cameras");
    };
    let (hl, check_l) = camera_move(&cam_l, new, &samples, 0, at)?;
    let (hr, check_r) = camera_move(&cam_r, new, &samples, 1, at)?;
    let farthest = || farthest_row([(&cam_l, hl.as_ref()), (&cam_r, hr.as_ref())], new, at);
    for (k, (side, c)) in ["left", "right"].iter().zip([&check_l, &check_r]).enumerate() {
        if c.old_rms_px <= HELD_MAX_RMS_PX {
            continue;
        }
        if !c.moved {
            bail!(
                "the new points fit neither the old {side} camera ({:.2} px rms) nor a moved one (the best homography {:.2} px rms, F = {:.1}, under {F_CRITICAL}); {}: check its pixels and x,y,z",
                c.old_rms_px,
                c.fit_rms_px,
                c.f,
                farthest()
            );
        }
        if c.fit_rms_px > HELD_MAX_RMS_PX {
            // The row farthest from this camera as it was: the homography, fitted to the
            // wrong rows too, spreads their miss over the others.
            let h = [hl.as_ref(), hr.as_ref()];
            let as_was = |s: usize| if s == k { None } else { h[s] };
            let farthest = farthest_row([(&cam_l, as_was(0)), (&cam_r, as_was(1))], new, at);
            bail!(
                "the new points fit neither the old {side} camera ({:.2} px rms) nor a moved one: the best homography, though far better (F = {:.1}), leaves {:.2} px rms, over {HELD_MAX_RMS_PX} px (a camera turned on its mount moves every pixel by a homography); {}: check its pixels and x,y,z",
                c.old_rms_px,
                c.f,
                c.fit_rms_px,
                farthest
            );
        }
    }

    // The samples through the moved cameras, then the new points.
    let mut learned = Dataset::new(InputKind::Stereo);
    for n in 0..samples.len() {
        let x = samples.row(n);
        let l = apply(hl.as_ref(), [x[0], x[1]]);
        let r = apply(hr.as_ref(), [x[2], x[3]]);
        if let (Some(l), Some(r)) = (l, r) {
            learned.push(&[l[0], l[1], r[0], r[1]], Some(samples.targets[n]));
        }
    }

    let cfg = config(old, seed);
    let sc = scaling(old, &learned);
    let prob: Problem = problem(&learned, &cfg, &sc);
    let n_skip = cfg.family.skip_len(prob.shape.ni, prob.shape.no);
    let base = super::lm_options(cfg.family, cfg.frame, &learned, n_skip);
    let opts = lm::LmOptions { max_iter: UPDATE_MAX_ITER, weight_decay: base.tail.1, ..base };
    let mut p: Vec<f64> = old.params.iter().map(|v| *v as f64).collect();
    let iterations = lm::fit(&prob, &mut p, &opts).iterations;
    let Some(mut blob) = super::export(&p, new, &cfg, &sc, 0.0) else {
        bail!("the update gave weights that do not make a valid model");
    };
    let new_error_pct = super::blob_error_pct(&blob, new);
    let old_error_pct = super::blob_error_pct(old, new);
    if new_error_pct.is_nan() || new_error_pct > WORSE_FACTOR * old_error_pct + WORSE_SLACK_PCT {
        bail!(
            "the update would fit the new points worse than the old model (e_ma {old_error_pct:.4} % before, {new_error_pct:.4} % after): the cameras it measured do not explain them; {}: check its pixels and x,y,z",
            farthest()
        );
    }
    blob.meta.train_error_pct = new_error_pct as f32;
    blob.generation = old.generation;
    blob.fallback = old.fallback;
    blob.matcher = old.matcher;
    Ok(UpdateOutcome {
        blob,
        old_error_pct,
        new_error_pct,
        cameras: [check_l, check_r],
        learned,
        iterations,
        elapsed: start.elapsed(),
    })
}

fn check(old: &ModelBlob, new: &Dataset, at: &dyn Fn(usize) -> String) -> Result<()> {
    let kind = |k: InputKind| match k {
        InputKind::Stereo => "4 inputs (pixels)",
        InputKind::StereoJoints => "9 inputs (pixels and joint angles)",
    };
    match new.input_kind() {
        Some(k) if k == old.topology.inputs => {}
        Some(k) => bail!(
            "the new set has {} but the old model takes {}",
            kind(k),
            kind(old.topology.inputs)
        ),
        None => bail!("the new set has {} inputs per row; a model takes 4 or 9", new.n_inputs),
    }
    if old.topology.inputs != InputKind::Stereo {
        bail!("updating a posture-aware (9-input) model is not supported: train it again");
    }
    if old.topology.outputs != OutputKind::Xyz {
        bail!("updating a Z-only model is not supported (the update needs X, Y, Z outputs)");
    }
    if old.generation == u32::MAX {
        bail!(
            "the old model is at the last generation a blob can hold ({}): train it again",
            u32::MAX
        );
    }
    if !new.has_targets() {
        bail!("the new set has no ground truth for every row: an update needs x,y,z");
    }
    if new.len() < MIN_POINTS {
        bail!(
            "the new set has {}; an update needs at least {MIN_POINTS}",
            crate::fmt::count(new.len(), "row")
        );
    }
    for (n, t) in new.targets.iter().enumerate() {
        if !(t.iter().all(|v| v.is_finite()) && t[2] > 0.0) {
            bail!("{}: the ground truth must be finite with z > 0", at(n));
        }
    }
    if let Some(n) = (0..new.len()).find(|n| !new.row(*n).iter().all(|v| v.is_finite())) {
        bail!("{}: the pixels must be finite numbers", at(n));
    }
    Ok(())
}

/// The training configuration that reproduces `old`'s net.
fn config(old: &ModelBlob, seed: u64) -> TrainConfig {
    TrainConfig {
        hidden: old.topology.hidden as usize,
        outputs: old.topology.outputs,
        algo: match old.topology.output_activation {
            Activation::Linear => Algo::Lm,
            Activation::Sigmoid => Algo::Bp,
        },
        restarts: 1,
        threshold_pct: None,
        seed,
        family: old.family,
        frame: old.frame,
        ..TrainConfig::default()
    }
}

/// `old`'s scaling, with the input box of `learned`.
fn scaling(old: &ModelBlob, learned: &Dataset) -> Scaling {
    let (mut in_min, mut in_max) = (Vec::new(), Vec::new());
    for i in 0..learned.n_inputs {
        let (lo, hi) = super::range((0..learned.len()).map(|n| learned.row(n)[i]));
        in_min.push(lo as f32);
        in_max.push(hi as f32);
    }
    Scaling {
        in_offset: old.in_offset.to_vec(),
        in_scale: old.in_scale.to_vec(),
        out_offset: old.out_offset.to_vec(),
        out_scale: old.out_scale.to_vec(),
        in_min,
        in_max,
    }
}

/// The old model's view of its training volume ([`SAMPLES`] rows: pixels and the old
/// model's point).
fn sample_volume(
    old: &ModelBlob,
    m: &hvs_shared::runtime::blob::MatcherGeometry,
    seed: u64,
) -> Result<Dataset> {
    let mut rng = SplitMix64::new(seed ^ STREAM);
    let f = m.fundamental.map(|r| r.map(|v| v as f64));
    let lo: Vec<f64> = old.in_min.iter().map(|v| *v as f64).collect();
    let hi: Vec<f64> = old.in_max.iter().map(|v| *v as f64).collect();
    let mut out = Dataset::new(InputKind::Stereo);
    let mut y = vec![0.0f32; old.n_outputs()];
    let (d0, d1) = (m.disparity[0] as f64, m.disparity[1] as f64);
    for _ in 0..MAX_DRAWS {
        if out.len() == SAMPLES {
            break;
        }
        let (ul, vl) = (rng.uniform(lo[0], hi[0]), rng.uniform(lo[1], hi[1]));
        let ur = ul - rng.uniform(d0, d1);
        // The epipolar line a u_r + b v_r + c = 0 of the left pixel.
        let l = [0, 1, 2].map(|k| f[k][0] * ul + f[k][1] * vl + f[k][2]);
        if l[1].abs() < 1e-12 {
            continue;
        }
        let vr = -(l[0] * ur + l[2]) / l[1];
        if !(lo[2]..=hi[2]).contains(&ur) || !(lo[3]..=hi[3]).contains(&vr) {
            continue;
        }
        let x = [ul as f32, vl as f32, ur as f32, vr as f32];
        if old.infer(&x, &mut y).is_err() {
            continue;
        }
        let t = [y[0] as f64, y[1] as f64, y[2] as f64];
        let inside = (0..3).all(|k| (m.out_min[k] as f64..=m.out_max[k] as f64).contains(&t[k]));
        if inside {
            out.push(&[ul, vl, ur, vr], Some(t));
        }
    }
    if out.len() < SAMPLES / 2 {
        bail!(
            "only {} of {MAX_DRAWS} draws of the old model's volume fell inside its training box",
            out.len()
        );
    }
    Ok(out)
}

/// Camera `c` (0 left, 1 right) fitted to the samples.
fn fit_camera(samples: &Dataset, c: usize) -> Option<Matrix3x4<f64>> {
    let px: Vec<[f64; 2]> =
        (0..samples.len()).map(|n| [samples.row(n)[2 * c], samples.row(n)[2 * c + 1]]).collect();
    fit_dlt(&samples.targets, &px).ok()
}

fn project(m: &Matrix3x4<f64>, p: &[f64; 3]) -> Option<[f64; 2]> {
    let q = m * Vector4::new(p[0], p[1], p[2], 1.0);
    let out = [q[0] / q[2], q[1] / q[2]];
    (q[2].abs() > 1e-300 && out.iter().all(|v| v.is_finite())).then_some(out)
}

fn apply(h: Option<&Homography>, p: [f64; 2]) -> Option<[f64; 2]> {
    match h {
        Some(h) => h.apply(p),
        None => Some(p),
    }
}

/// Whether camera `c` moved, measured on the new points: the homography from the old
/// camera's pixels to the new ones when significant (see [`F_CRITICAL`]).
fn camera_move(
    cam: &Matrix3x4<f64>,
    new: &Dataset,
    samples: &Dataset,
    c: usize,
    at: &dyn Fn(usize) -> String,
) -> Result<(Option<Homography>, CameraCheck)> {
    let side = ["left", "right"][c];
    let mut pairs = Vec::with_capacity(new.len());
    for (n, t) in new.targets.iter().enumerate() {
        let Some(p) = project(cam, t) else {
            bail!("{}: the point is behind the old model's {side} camera", at(n));
        };
        pairs.push((p, [new.row(n)[2 * c], new.row(n)[2 * c + 1]]));
    }
    let n = pairs.len() as f64;
    let ss_old: f64 =
        pairs.iter().map(|(p, d)| (p[0] - d[0]).powi(2) + (p[1] - d[1]).powi(2)).sum();
    let (h, ss_fit) = match fit_homography(&pairs) {
        Ok(fit) => (Some(fit.h), fit.rms * fit.rms * n),
        // Points on one line (or one point again and again) cannot measure a homography, so
        // they cannot say whether the camera moved: an update from them would only claim to.
        Err(e) => bail!(
            "the new points cannot show whether the {side} camera moved ({e}): give points spread over a plane, such as a board's corners (at least {MIN_POINTS}, not all on one line)"
        ),
    };
    let dof = 2.0 * n - 8.0;
    let f = ((ss_old - ss_fit) / 8.0) / (ss_fit / dof).max(1e-300);
    let moved = h.is_some() && f > F_CRITICAL;
    let h = h.filter(|_| moved);
    let max_move_px = match &h {
        Some(h) => (0..samples.len())
            .filter_map(|r| {
                let x = [samples.row(r)[2 * c], samples.row(r)[2 * c + 1]];
                let y = h.apply(x)?;
                Some(((y[0] - x[0]).powi(2) + (y[1] - x[1]).powi(2)).sqrt())
            })
            .fold(0.0, f64::max),
        None => 0.0,
    };
    Ok((
        h,
        CameraCheck {
            old_rms_px: (ss_old / n).sqrt(),
            fit_rms_px: (ss_fit / n).sqrt(),
            f,
            moved,
            max_move_px,
        },
    ))
}

/// Where the new point farthest from its pixels lies: `file:line` by `at`, the camera, and how
/// far (px) its measured pixel is from the camera's (`cams`: each old camera and, when it
/// moved, its homography).
fn farthest_row(
    cams: [(&Matrix3x4<f64>, Option<&Homography>); 2],
    new: &Dataset,
    at: &dyn Fn(usize) -> String,
) -> String {
    let mut worst: Option<(f64, usize, usize)> = None;
    for (n, t) in new.targets.iter().enumerate() {
        let x = new.row(n);
        for (c, (cam, h)) in cams.iter().enumerate() {
            let off = project(cam, t)
                .and_then(|p| apply(*h, p))
                .map_or(f64::INFINITY, |p| (p[0] - x[2 * c]).hypot(p[1] - x[2 * c + 1]));
            if worst.is_none_or(|(w, _, _)| off > w) {
                worst = Some((off, n, c));
            }
        }
    }
    match worst {
        Some((off, n, c)) => format!(
            "the farthest, {}, has its {} pixel {off:.1} px from where the cameras put its x,y,z",
            at(n),
            ["left", "right"][c]
        ),
        None => "no rows".to_string(),
    }
}

/// The blob an update writes (`hvs train --from`): `up`'s net as the next generation of
/// `old`, whose parent is `old` (`old_crc`: the CRC stored in its file); the old images' size
/// (else `new_image_size`, that of the new points' images); the matcher geometry refitted to
/// the samples the update learned (else the old one); and the traditional method's
/// calibration refitted to the new points (`new`, with `half_baseline`, `u0`, `v0`) when a
/// camera moved or `refit_fallback` (those values given on the command line), else the old one.
pub fn next_generation(
    old: &ModelBlob,
    old_crc: u32,
    up: &UpdateOutcome,
    new: &Dataset,
    new_image_size: Option<(u16, u16)>,
    (half_baseline, u0, v0): (f64, f64, f64),
    refit_fallback: bool,
) -> ModelBlob {
    let mut blob = up.blob.clone();
    blob.generation = old.generation.saturating_add(1); // `check` refused u32::MAX
    blob.set_parent(Some(hvs_shared::runtime::blob::Parent {
        crc: old_crc,
        generation: old.generation,
    }));
    blob.set_image_size(old.image_size().or(new_image_size));
    blob.matcher = super::matcher::matcher_geometry(&up.learned).or(old.matcher);
    if refit_fallback || up.cameras.iter().any(|c| c.moved) {
        blob.fallback = super::fallback::fit(new, half_baseline, u0, v0)
            .map(|f| f.calibration)
            .or(old.fallback);
    }
    blob
}
