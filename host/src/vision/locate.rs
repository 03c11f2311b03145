//! `hvs locate`: left pixels found in the right image along their epipolar lines, inside the
//! disparities the model maps into its training depths, and the model's X, Y, Z of each
//! match; the overlay of what was found.

use super::files::{check_same_size, read_pair};
use anyhow::{anyhow, bail, Result};
use hvs_shared::runtime::blob::{MatcherGeometry, ModelBlob};
use hvs_vision::geometry::Fundamental;
use hvs_vision::matching::{model_disparity_interval, MatchParams, MatchStatus, Matcher, Query};
use image::{GrayImage, Rgb, RgbImage};
use rayon::prelude::*;
use std::path::Path;

/// The model's X, Y, Z (cm) of a stereo pixel pair, `None` where it gives no finite estimate;
/// a Z-only model (`hvs train --outputs z`) gives Z, and X, Y as NaN.
pub fn model_xyz(blob: &ModelBlob) -> impl Fn([f32; 4]) -> Option<[f32; 3]> + Sync + '_ {
    let n_out = blob.n_outputs().min(3);
    move |x: [f32; 4]| {
        let mut out = [0.0f32; 3];
        blob.infer(&x, &mut out[..n_out]).ok()?;
        if !out[..n_out].iter().all(|v| v.is_finite()) {
            return None;
        }
        Some(if n_out == 1 { [f32::NAN, f32::NAN, out[0]] } else { out })
    }
}

/// Refuses images of another size than the model's training images (when the model records
/// it: `hvs train` on `hvs board detect`'s points): its geometry and depths are for that size.
pub fn check_image_size(blob: &ModelBlob, (w, h): (u32, u32)) -> Result<()> {
    match blob.image_size() {
        Some((mw, mh)) if (u32::from(mw), u32::from(mh)) != (w, h) => bail!(
            "the images are {w}x{h} px, the model was trained on {mw}x{mh} px images: its \
             matcher geometry and depths hold for that size only (resize the images, or train \
             on points found in images of this size)"
        ),
        _ => Ok(()),
    }
}

/// One point located in the right image and triangulated by the model.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Located {
    /// The left pixel asked for.
    pub left: [f64; 2],
    /// The match in the right image, when trustworthy.
    pub right: Option<[f64; 2]>,
    /// The model's X, Y, Z (cm) of the matched pair (X and Y NaN for a Z-only model).
    pub xyz: Option<[f32; 3]>,
    /// Zero-mean normalised cross-correlation of the match (NaN when none was scored).
    pub score: f64,
    /// `ok`, or why there is no trustworthy match (`outside`, `no_texture`, `ambiguous`,
    /// `lr_check_failed`, `no_candidate`, `out_of_depth_range`, `nan_input`, `no_estimate`).
    pub status: &'static str,
}

impl Located {
    /// The numbers `hvs locate --at` prints for a trustworthy match, as it prints them:
    /// `[u_r, v_r, x, y, z, score]` (the right pixel as an `f32`, X, Y, Z in shortest
    /// round-trip form, the score with 3 decimals); `None` without one.
    pub fn texts(&self) -> Option<[String; 6]> {
        let (rp, x) = (self.right?, self.xyz?);
        Some([
            (rp[0] as f32).to_string(),
            (rp[1] as f32).to_string(),
            // A Z-only model gives no X, Y: empty, as in `hvs locate`'s CSV.
            if x[0].is_finite() { x[0].to_string() } else { String::new() },
            if x[1].is_finite() { x[1].to_string() } else { String::new() },
            x[2].to_string(),
            format!("{:.3}", self.score),
        ])
    }

    /// The line `hvs locate --at` prints for this point (and `hvs view` shows): the match,
    /// X, Y, Z and the score ([`Located::texts`]), or why there is none.
    pub fn line(&self) -> String {
        match self.texts() {
            Some([ur, vr, x, _, z, score]) if x.is_empty() => {
                format!("u_r={ur} v_r={vr} z={z} cm (score {score})")
            }
            Some([ur, vr, x, y, z, score]) => {
                format!("u_r={ur} v_r={vr} x={x} y={y} z={z} cm (score {score})")
            }
            None => format!("no trustworthy match: {}", self.status),
        }
    }
}

/// The training set's disparities widened by this share of their span on each side, as the
/// search range the model's depth range is looked for in.
pub const DISPARITY_SLACK: f64 = 0.1;

/// The model's matcher geometry, or the error every image command gives without it.
pub fn matcher_geometry(blob: &ModelBlob) -> Result<MatcherGeometry> {
    blob.matcher.ok_or_else(|| {
        anyhow!(
            "the model has no matcher geometry: its training set could not give one (fewer \
             than 8 rows, joint columns, or no fundamental matrix fits its pixels, e.g. all \
             on one board plane), or it was written before blob format v2: retrain it with \
             `hvs train` on board points seen at one head posture, at two or more depths"
        )
    })
}

/// The training set's disparities (`u_l - u_r`, px) widened by [`DISPARITY_SLACK`] of their
/// span on each side.
pub fn training_disparities(g: &MatcherGeometry) -> [f64; 2] {
    let span = f64::from(g.disparity[1] - g.disparity[0]);
    [
        f64::from(g.disparity[0]) - DISPARITY_SLACK * span,
        f64::from(g.disparity[1]) + DISPARITY_SLACK * span,
    ]
}

/// Finds each left pixel of `points` in the right image along its epipolar line, inside the
/// disparities the model maps into its training depths at that pixel, and gives the model's
/// X, Y, Z of every trustworthy match. Everything comes from the model
/// ([`MatcherGeometry`]: learned at training time from the training pixels); the images must
/// have the same size.
pub fn locate(
    blob: &ModelBlob,
    left: &GrayImage,
    right: &GrayImage,
    points: &[[f64; 2]],
) -> Result<Vec<Located>> {
    let g = matcher_geometry(blob)?;
    check_same_size(left, right)?;
    check_image_size(blob, left.dimensions())?;
    let f = Fundamental { m: g.fundamental.map(|r| r.map(f64::from)) };
    let params =
        MatchParams { right_scale: g.right_scale.map(f64::from), ..MatchParams::default() };
    let matcher = Matcher::new(left, right, &f, params).map_err(|e| anyhow!("{e}"))?;
    let d_range = training_disparities(&g);
    let z_range = [f64::from(g.out_min[2]), f64::from(g.out_max[2])];
    let predict = model_xyz(blob);
    Ok(points
        .par_iter()
        .map(|&[ul, vl]| {
            let none = |status| Located {
                left: [ul, vl],
                right: None,
                xyz: None,
                score: f64::NAN,
                status,
            };
            if !(ul.is_finite() && vl.is_finite()) {
                return none("nan_input");
            }
            let (w, h) = (f64::from(left.width()), f64::from(left.height()));
            if !(ul > -0.5 && vl > -0.5 && ul < w - 0.5 && vl < h - 0.5) {
                return none("outside");
            }
            let line = f.line_in_right([ul, vl]);
            let Some((d_min, d_max)) =
                model_disparity_interval(&predict, ul, vl, line, z_range, d_range)
            else {
                return none("out_of_depth_range");
            };
            let m = matcher.find(&Query { ul, vl, d_min, d_max });
            if m.status != MatchStatus::Ok {
                return Located { score: m.score, ..none(m.status.name()) };
            }
            match predict([ul as f32, vl as f32, m.ur as f32, m.vr as f32]) {
                Some(xyz) => Located {
                    left: [ul, vl],
                    right: Some([m.ur, m.vr]),
                    xyz: Some(xyz),
                    score: m.score,
                    status: "ok",
                },
                None => Located { score: m.score, ..none("no_estimate") },
            }
        })
        .collect())
}

/// Loads a model that can locate from an image pair alone (4 inputs: u_l, v_l, u_r, v_r).
pub fn load_stereo_model(model_path: &Path) -> Result<crate::data::model::ModelFile> {
    let m = crate::data::model::load(model_path)?;
    if m.blob.n_inputs() != 4 {
        bail!(
            "{}: a posture-aware model (9 inputs) cannot locate from images alone: its epipolar geometry moves with the eyes",
            model_path.display()
        );
    }
    Ok(m)
}

/// [`locate`] with a model read from `model_path`: its errors name the file.
pub fn locate_with(
    model_path: &Path,
    blob: &ModelBlob,
    left: &GrayImage,
    right: &GrayImage,
    points: &[[f64; 2]],
) -> Result<Vec<Located>> {
    locate(blob, left, right, points).map_err(|e| anyhow!("{}: {e:#}", model_path.display()))
}

/// Loads the model and both images, then locates `points` (`hvs locate`).
pub fn locate_files(
    model_path: &Path,
    left: &Path,
    right: &Path,
    points: &[[f64; 2]],
) -> Result<(Vec<Located>, image::GrayImage, image::GrayImage)> {
    let m = load_stereo_model(model_path)?;
    let (l, r) = read_pair(left, right)?;
    let found = locate_with(model_path, &m.blob, &l, &r, points)?;
    Ok((found, l, r))
}

/// The two images side by side, each located point drawn in both (a cross, a line between
/// them, its row number) in green, refused ones as a red cross in the left image only.
pub fn locate_overlay(left: &GrayImage, right: &GrayImage, found: &[Located]) -> RgbImage {
    use hvs_vision::overlay::{draw_cross, draw_line, draw_text};
    let (w, h) = left.dimensions();
    let mut img = RgbImage::new(2 * w, h.max(right.height()));
    for (x, y, p) in left.enumerate_pixels() {
        img.put_pixel(x, y, Rgb([p[0]; 3]));
    }
    for (x, y, p) in right.enumerate_pixels() {
        img.put_pixel(x + w, y, Rgb([p[0]; 3]));
    }
    let (ok, bad) = (Rgb([40, 220, 60]), Rgb([230, 40, 40]));
    for (k, l) in found.iter().enumerate() {
        if !(l.left[0].is_finite() && l.left[1].is_finite()) {
            continue;
        }
        match l.right {
            Some(r) => {
                let r = [r[0] + f64::from(w), r[1]];
                draw_cross(&mut img, l.left, 4.0, ok);
                draw_cross(&mut img, r, 4.0, ok);
                draw_line(&mut img, l.left, r, Rgb([40, 140, 220]));
                let label = (k + 1).to_string();
                for p in [l.left, r] {
                    draw_text(&mut img, p[0] as i64 + 5, p[1] as i64 - 12, &label, 2, ok);
                }
            }
            None => draw_cross(&mut img, l.left, 4.0, bad),
        }
    }
    img
}
