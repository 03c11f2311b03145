//! Images on the host, around `hvs-vision`: board photos of a capture set into a training set
//! (`hvs board detect`), and image files in and out. The detection, rendering and matching
//! themselves live in the `hvs-vision` crate; this module reads and writes the files and
//! turns the crate's results into the project's CSV rows.

use crate::data::captures::{Capture, CaptureSet};
use crate::data::dataset::JOINT_COLUMNS;
use crate::data::output::write_bytes;
use anyhow::{anyhow, bail, Context, Result};
use hvs_shared::runtime::blob::ModelBlob;
use hvs_shared::runtime::gaze::Joints;
use hvs_vision::board::Board;
use hvs_vision::detect::{self, SetCheck, StereoCorners};
use hvs_vision::geometry::Fundamental;
use hvs_vision::matching::{model_disparity_interval, MatchParams, MatchStatus, Matcher, Query};
use hvs_vision::render;
use image::{GrayImage, Rgb, RgbImage};
use rayon::prelude::*;
use std::fmt::Write as _;
use std::io::Cursor;
use std::path::Path;

/// Reads an image file (PNG or JPEG, any colour type) as grey levels, through
/// [`hvs_vision::image_file`]: other formats and images over
/// [`hvs_vision::image_file::MAX_PIXELS`] are refused before decoding; errors name the file.
pub fn read_grey(path: &Path) -> Result<GrayImage> {
    hvs_vision::image_file::read_grey(path).map_err(|e| anyhow!("{e}"))
}

/// PNG bytes of an image (written with the one atomic writer by the caller).
pub fn png_bytes<P, C>(img: &image::ImageBuffer<P, C>) -> Result<Vec<u8>>
where
    P: image::PixelWithColorType,
    [P::Subpixel]: image::EncodableLayout,
    C: std::ops::Deref<Target = [P::Subpixel]>,
{
    let mut out = Cursor::new(Vec::new());
    img.write_to(&mut out, image::ImageFormat::Png)
        .map_err(|e| anyhow!("cannot encode a PNG: {e}"))?;
    Ok(out.into_inner())
}

/// The `captures.csv` of a rendered set, one row per pair: `left,right,z,x,y` (the board
/// centre, cm) and, with `joints`, the [`JOINT_COLUMNS`] of the posture it was rendered at.
pub fn captures_csv(set: &render::CaptureSet, joints: Option<&Joints>) -> String {
    let mut s = String::from("left,right,z,x,y");
    if joints.is_some() {
        s.push(',');
        s.push_str(&JOINT_COLUMNS.join(","));
    }
    s.push('\n');
    for c in &set.captures {
        let [x, y, z] = c.centre;
        let _ = write!(s, "{},{},{z},{x},{y}", c.left_name, c.right_name);
        for v in joints.map_or(&[][..], |j| &j.0[..]) {
            let _ = write!(s, ",{v}");
        }
        s.push('\n');
    }
    s
}

/// Writes a rendered capture set into `dir` (created if missing), each file atomically: the
/// PNG pairs, `captures.csv` ([`captures_csv`]), `truth.csv` and `board.json`, which is
/// what `hvs board detect` reads.
pub fn write_capture_set(
    dir: &Path,
    set: &render::CaptureSet,
    joints: Option<&Joints>,
) -> Result<()> {
    std::fs::create_dir_all(dir)
        .with_context(|| format!("{}: cannot create the folder", dir.display()))?;
    for c in &set.captures {
        write_bytes(&dir.join(&c.left_name), &png_bytes(&c.render.left)?)?;
        write_bytes(&dir.join(&c.right_name), &png_bytes(&c.render.right)?)?;
    }
    for (name, text) in [
        ("captures.csv", captures_csv(set, joints)),
        ("truth.csv", set.truth_csv()),
        ("board.json", set.board_json()),
    ] {
        write_bytes(&dir.join(name), text.as_bytes())?;
    }
    Ok(())
}

/// One pair's outcome.
#[derive(Debug, Clone)]
pub enum PairOutcome {
    /// Detected, labelled and consistent.
    Found(Box<StereoCorners>),
    /// Skipped, with the reason.
    Skipped(String),
}

/// The detection over a capture set.
#[derive(Debug, Clone)]
pub struct Detection {
    /// Per capture, in order.
    pub outcomes: Vec<PairOutcome>,
    /// Per capture: the median and largest distance (px) of its right corners from the
    /// epipolar lines of its group's fundamental matrix; `None` for a skipped pair or one whose
    /// group has fewer than two usable pairs.
    pub epipolar: Vec<Option<[f64; 2]>>,
    /// One fundamental matrix per group of pairs taken at one posture (the whole set when it
    /// has no joint columns) with at least two usable pairs.
    pub groups: Vec<GroupFit>,
    /// The size (width, height) of the images of every usable pair (a pair of another size
    /// than the first usable one is skipped: a model is for one image size).
    pub image_size: Option<(u32, u32)>,
}

/// The fundamental matrix of one group of pairs seen at one posture.
#[derive(Debug, Clone)]
pub struct GroupFit {
    /// Usable pairs in the group.
    pub pairs: usize,
    /// The fit's Sampson rms (px).
    pub rms_sampson: f64,
}

/// A pair whose corners lie this far (median, px) from the epipolar lines of the fundamental
/// matrix fitted to all *other* pairs is labelled differently from them (a shifted row or a
/// flip moves corners by whole squares) and is skipped.
pub const MAX_HELD_OUT_EPIPOLAR_PX: f64 = 2.0;

/// Detects `board` in every pair of `set` (in parallel; `progress` is called after each
/// pair), then checks the pairs taken at one posture together: disparities of the wrong sign
/// for their depth, and one fundamental matrix over the group's usable pairs, skipping a pair
/// whose labels disagree with the others ([`MAX_HELD_OUT_EPIPOLAR_PX`]). A set without joint
/// columns is one posture; with them, the pairs of equal joint values form a group (the
/// epipolar geometry changes with the eyes' pans).
pub fn detect_set(
    board: &Board,
    set: &CaptureSet,
    progress: &(dyn Fn() + Sync),
) -> Result<Detection> {
    Ok(detect_all(board, set, progress, false)?.0)
}

/// A pair's two images (left, right) as [`detect_set_with_images`] read them; `None` where
/// one could not be read.
pub type PairImages = Option<[GrayImage; 2]>;

/// [`detect_set`], also returning every pair's images as read, so that a caller drawing on
/// them (`hvs board detect --overlays`) does not decode the files again.
pub fn detect_set_with_images(
    board: &Board,
    set: &CaptureSet,
    progress: &(dyn Fn() + Sync),
) -> Result<(Detection, Vec<PairImages>)> {
    detect_all(board, set, progress, true)
}

/// The posture groups of `set`: capture indices with equal joint fields, in order of first
/// appearance (one group when the set has no joint columns).
fn posture_groups(set: &CaptureSet) -> Vec<Vec<usize>> {
    let joints = set
        .extra_columns
        .iter()
        .take_while(|c| JOINT_COLUMNS.contains(&c.as_str()))
        .count();
    if joints == 0 {
        return vec![(0..set.captures.len()).collect()];
    }
    let mut groups: Vec<Vec<usize>> = Vec::new();
    let mut index: std::collections::HashMap<Vec<u64>, usize> = Default::default();
    for (k, c) in set.captures.iter().enumerate() {
        // The fields were checked as numbers when the set was read; equal values, one group.
        let key: Vec<u64> = c.extra[..joints]
            .iter()
            .map(|f| f.parse::<f64>().map_or(u64::MAX, |v| (v + 0.0).to_bits()))
            .collect();
        let g = *index.entry(key).or_insert_with(|| {
            groups.push(Vec::new());
            groups.len() - 1
        });
        groups[g].push(k);
    }
    groups
}

/// [`detect_set`], keeping the images if `keep` (else the second vector is empty).
fn detect_all(
    board: &Board,
    set: &CaptureSet,
    progress: &(dyn Fn() + Sync),
    keep: bool,
) -> Result<(Detection, Vec<PairImages>)> {
    // Each pair's images are dropped as soon as it is detected unless kept: a posture set
    // holds thousands of pairs.
    let detected: Vec<_> = set
        .captures
        .par_iter()
        .map(|c| {
            let (outcome, pair) = detect_capture(board, c);
            progress();
            let size = pair.as_ref().map(|[l, _]| l.dimensions());
            (outcome, size, if keep { pair } else { None })
        })
        .collect();
    let mut images = Vec::new();
    let mut outcomes: Vec<PairOutcome> = Vec::with_capacity(set.captures.len());
    let mut image_size = None;
    for (mut outcome, size, pair) in detected {
        if let (PairOutcome::Found(_), Some(size)) = (&outcome, size) {
            match image_size {
                None => image_size = Some(size),
                Some(first) if first != size => {
                    outcome = PairOutcome::Skipped(format!(
                        "its images are {}x{} px, the set's first usable pair's {}x{}: a model is for one image size",
                        size.0, size.1, first.0, first.1
                    ));
                }
                Some(_) => {}
            }
        }
        if keep {
            images.push(pair);
        }
        outcomes.push(outcome);
    }
    let mut epipolar = vec![None; outcomes.len()];
    let mut groups = Vec::new();
    for members in posture_groups(set) {
        if let Some(fit) = check_group(set, &members, &mut outcomes, &mut epipolar) {
            groups.push(fit);
        }
    }
    let det = Detection {
        outcomes,
        epipolar,
        groups,
        image_size,
    };
    Ok((det, images))
}

/// The checks of one posture group (capture indices `members`): skips the pairs that fail
/// and fills their epipolar residuals; the group's fit if it has two usable pairs.
fn check_group(
    set: &CaptureSet,
    members: &[usize],
    outcomes: &mut [PairOutcome],
    epipolar: &mut [Option<[f64; 2]>],
) -> Option<GroupFit> {
    let found = |outcomes: &[PairOutcome]| -> Vec<usize> {
        members
            .iter()
            .copied()
            .filter(|&k| matches!(outcomes[k], PairOutcome::Found(_)))
            .collect()
    };
    // Disparities that cannot be right (the same image twice; a pair swapped, mirrored or
    // turned): one fundamental matrix fits those too, so they are looked at first.
    let usable = found(outcomes);
    let (mut disparity, mut same, mut depth) = (Vec::new(), Vec::new(), Vec::new());
    for &k in &usable {
        if let PairOutcome::Found(p) = &outcomes[k] {
            disparity.push(p.median_disparity());
            same.push(p.same_in_both());
            depth.push(set.captures[k].z);
        }
    }
    for (&k, fault) in usable
        .iter()
        .zip(detect::disparity_faults(&disparity, &same, &depth))
    {
        if let Some(why) = fault {
            outcomes[k] = PairOutcome::Skipped(why);
        }
    }
    let fit = |outcomes: &[PairOutcome]| -> Option<(Vec<usize>, SetCheck)> {
        let usable = found(outcomes);
        let pairs: Vec<StereoCorners> = usable
            .iter()
            .filter_map(|&k| match &outcomes[k] {
                PairOutcome::Found(p) => Some((**p).clone()),
                PairOutcome::Skipped(_) => None,
            })
            .collect();
        if pairs.len() < 2 {
            return None;
        }
        detect::check_set(&pairs).ok().map(|c| (usable, c))
    };
    let mut check = fit(outcomes);
    // A pair labelled unlike the others is dropped, and the rest refitted (once).
    if let Some((usable, c)) = &check {
        let mut dropped = false;
        for (slot, &k) in usable.iter().enumerate() {
            if let Some(Some(m)) = c.pair_held_out_median_px.get(slot) {
                if *m > MAX_HELD_OUT_EPIPOLAR_PX {
                    outcomes[k] = PairOutcome::Skipped(format!(
                        "its corners lie {m:.2} px (median) from the epipolar lines of the other pairs: labelled unlike them (shifted or flipped grid)"
                    ));
                    dropped = true;
                }
            }
        }
        if dropped {
            check = fit(outcomes);
        }
    }
    let (usable, c) = check?;
    for (slot, &k) in usable.iter().enumerate() {
        epipolar[k] = Some([c.pair_median_px[slot], c.pair_max_px[slot]]);
    }
    Some(GroupFit {
        pairs: usable.len(),
        rms_sampson: c.fit.rms_sampson,
    })
}

fn detect_capture(board: &Board, c: &Capture) -> (PairOutcome, PairImages) {
    let load = |p: &Path| read_grey(p).map_err(|e| format!("{e:#}"));
    let (l, r) = match (load(&c.left), load(&c.right)) {
        (Ok(l), Ok(r)) => (l, r),
        (Err(e), _) | (_, Err(e)) => return (PairOutcome::Skipped(e), None),
    };
    // The labels must follow the board convention in both images (POINTS.csv's i, j and the
    // corner positions depend on it).
    let upright = |p: detect::StereoCorners| -> Result<detect::StereoCorners, detect::DetectError> {
        detect::check_upright(&p.left)
            .map_err(|e| detect::DetectError::InImage(detect::Side::Left, Box::new(e)))?;
        detect::check_upright(&p.right)
            .map_err(|e| detect::DetectError::InImage(detect::Side::Right, Box::new(e)))?;
        Ok(p)
    };
    let outcome = match detect::detect_pair(&l, &r, board).and_then(upright) {
        Ok(p) => PairOutcome::Found(Box::new(p)),
        Err(e) => PairOutcome::Skipped(e.to_string()),
    };
    (outcome, Some([l, r]))
}

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
        Some(if n_out == 1 {
            [f32::NAN, f32::NAN, out[0]]
        } else {
            out
        })
    }
}

/// Refuses a left and a right image of different sizes (every command that matches a pair).
pub fn check_same_size(left: &GrayImage, right: &GrayImage) -> Result<()> {
    if left.dimensions() != right.dimensions() {
        bail!(
            "the images differ in size: left {}x{}, right {}x{}",
            left.width(),
            left.height(),
            right.width(),
            right.height()
        );
    }
    Ok(())
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

/// `POINTS.csv`: one row per corner found in both images, `capture,i,j,u_l,v_l,u_r,v_r`, then
/// `x,y,z` when the captures give `z`, then the passed-through columns, then `image_width,image_height`
/// (the images' size, [`Detection::image_size`]). `capture` is the
/// 1-based number of the pair in `CAPTURES.csv`. Pixels in shortest round-trip form.
pub fn points_csv(board: &Board, set: &CaptureSet, det: &Detection) -> String {
    let mut s = crate::data::captures::DETECTED_COLUMNS.join(",");
    if set.has_z {
        s.push_str(",x,y,z");
    }
    for c in &set.extra_columns {
        s.push(',');
        s.push_str(&csv_field(c));
    }
    // The images' size, for `hvs train` to record in the model (at most 65535 px a side: the
    // pixel limit of every image input keeps them far below).
    let size = det
        .image_size
        .and_then(|(w, h)| Some((u16::try_from(w).ok()?, u16::try_from(h).ok()?)));
    if size.is_some() {
        s.push(',');
        s.push_str(&crate::data::csv::IMAGE_SIZE_COLUMNS.join(","));
    }
    s.push('\n');
    for c in found_corners(board, set, det) {
        let (i, j, px) = (c.i, c.j, c.px);
        s.push_str(&format!(
            "{},{i},{j},{},{},{},{}",
            c.capture + 1,
            shortest(px[0]),
            shortest(px[1]),
            shortest(px[2]),
            shortest(px[3])
        ));
        if let Some(q) = c.xyz {
            s.push_str(&format!(",{},{},{}", q[0], q[1], q[2]));
        }
        for e in &set.captures[c.capture].extra {
            s.push(',');
            s.push_str(&csv_field(e));
        }
        if let Some((w, h)) = size {
            s.push_str(&format!(",{w},{h}"));
        }
        s.push('\n');
    }
    s
}

/// One board corner found in both images of a pair.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FoundCorner {
    /// Index of the pair in the capture set (0-based).
    pub capture: usize,
    /// Column of the corner on the board.
    pub i: u32,
    /// Row of the corner on the board.
    pub j: u32,
    /// `[u_l, v_l, u_r, v_r]` (px).
    pub px: [f64; 4],
    /// Its position (cm) when the capture gives the board depth.
    pub xyz: Option<[f64; 3]>,
}

/// Every corner of every detected pair, pair by pair in capture order, each pair row by row
/// (`j`, then `i`): the rows of [`points_csv`] and of a training set from images.
pub fn found_corners<'a>(
    board: &'a Board,
    set: &'a CaptureSet,
    det: &'a Detection,
) -> impl Iterator<Item = FoundCorner> + 'a {
    set.captures
        .iter()
        .zip(&det.outcomes)
        .enumerate()
        .filter_map(|(k, (cap, out))| match out {
            PairOutcome::Found(p) => Some((k, cap, p)),
            PairOutcome::Skipped(_) => None,
        })
        .flat_map(move |(capture, cap, p)| {
            (0..board.rows).flat_map(move |j| {
                (0..board.cols).map(move |i| {
                    let (l, r) = (p.left.at(i, j), p.right.at(i, j));
                    FoundCorner {
                        capture,
                        i,
                        j,
                        px: [l[0], l[1], r[0], r[1]],
                        xyz: cap
                            .z
                            .map(|z| board.corner_position([cap.xy[0], cap.xy[1], z], i, j)),
                    }
                })
            })
        })
}

/// The shortest decimal that reads back as `v`: as an `f32` when `v` is one (the detector's
/// corners are), else as the `f64`.
fn shortest(v: f64) -> String {
    let f = v as f32;
    if f64::from(f) == v {
        f.to_string()
    } else {
        v.to_string()
    }
}

fn csv_field(s: &str) -> String {
    if s.contains([',', '"', '\n', '\r']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_string()
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
            if x[0].is_finite() {
                x[0].to_string()
            } else {
                String::new()
            },
            if x[1].is_finite() {
                x[1].to_string()
            } else {
                String::new()
            },
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

/// Finds each left pixel of `points` in the right image along its epipolar line, inside the
/// disparities the model maps into its training depths at that pixel, and gives the model's
/// X, Y, Z of every trustworthy match. Everything comes from the model
/// ([`MatcherGeometry`](hvs_shared::runtime::blob::MatcherGeometry): learned at training time from the training pixels); the images must
/// have the same size.
pub fn locate(
    blob: &ModelBlob,
    left: &GrayImage,
    right: &GrayImage,
    points: &[[f64; 2]],
) -> Result<Vec<Located>> {
    let g = blob.matcher.ok_or_else(|| {
        anyhow!(
            "the model has no matcher geometry: its training set could not give one (fewer \
             than 8 rows, joint columns, or no fundamental matrix fits its pixels, e.g. all \
             on one board plane), or it was written before blob format v2: retrain it with \
             `hvs train` on board points seen at one head posture, at two or more depths"
        )
    })?;
    check_same_size(left, right)?;
    check_image_size(blob, left.dimensions())?;
    let f = Fundamental {
        m: g.fundamental.map(|r| r.map(f64::from)),
    };
    let params = MatchParams {
        right_scale: g.right_scale.map(f64::from),
        ..MatchParams::default()
    };
    let matcher = Matcher::new(left, right, &f, params).map_err(|e| anyhow!("{e}"))?;
    let span = f64::from(g.disparity[1] - g.disparity[0]);
    let d_range = [
        f64::from(g.disparity[0]) - DISPARITY_SLACK * span,
        f64::from(g.disparity[1]) + DISPARITY_SLACK * span,
    ];
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
            let m = matcher.find(&Query {
                ul,
                vl,
                d_min,
                d_max,
            });
            if m.status != MatchStatus::Ok {
                return Located {
                    score: m.score,
                    ..none(m.status.name())
                };
            }
            match predict([ul as f32, vl as f32, m.ur as f32, m.vr as f32]) {
                Some(xyz) => Located {
                    left: [ul, vl],
                    right: Some([m.ur, m.vr]),
                    xyz: Some(xyz),
                    score: m.score,
                    status: "ok",
                },
                None => Located {
                    score: m.score,
                    ..none("no_estimate")
                },
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

/// Reads a left and a right image of the same size as grey levels.
pub fn read_pair(left: &Path, right: &Path) -> Result<(GrayImage, GrayImage)> {
    let (l, r) = (read_grey(left)?, read_grey(right)?);
    if l.dimensions() != r.dimensions() {
        bail!(
            "{} and {}: the images differ in size ({}x{} and {}x{})",
            left.display(),
            right.display(),
            l.width(),
            l.height(),
            r.width(),
            r.height()
        );
    }
    Ok((l, r))
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

#[cfg(test)]
mod tests {
    use super::*;
    use hvs_shared::sim::presets;

    /// Two clean pairs of the OpenCV board at (1, -2, 65 | 85) cm through case I at home.
    fn two_pairs() -> render::CaptureSet {
        render::render_capture_set(
            &hvs_shared::sim::posture::HeadRig::new(presets::CASE_1),
            &Joints::HOME,
            &render::opencv_board(),
            [1.0, -2.0],
            &[65.0, 85.0],
            &render::RenderOptions::clean(),
            0,
        )
        .unwrap()
    }

    #[test]
    fn capture_set_files_are_what_board_detect_reads() {
        let set = two_pairs();
        assert_eq!(
            captures_csv(&set, None),
            "left,right,z,x,y\nleft01.png,right01.png,65,1,-2\nleft02.png,right02.png,85,1,-2\n"
        );
        let j = Joints([1.5, -2.0, 0.0, 3.0, -3.0]);
        let with = captures_csv(&set, Some(&j));
        assert_eq!(
            with.lines().next(),
            Some("left,right,z,x,y,neck_pan,neck_tilt,eye_tilt,left_eye_pan,right_eye_pan")
        );
        assert_eq!(
            with.lines().nth(1),
            Some("left01.png,right01.png,65,1,-2,1.5,-2,0,3,-3")
        );

        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("shots");
        write_capture_set(&out, &set, None).unwrap();
        let read = crate::data::captures::read(&out.join("captures.csv")).unwrap();
        assert_eq!(read.captures.len(), 2);
        assert_eq!(
            (read.captures[1].z, read.captures[1].xy),
            (Some(85.0), [1.0, -2.0])
        );
        assert_eq!(
            read_grey(&read.captures[0].left).unwrap(),
            set.captures[0].render.left
        );
        let board = std::fs::read_to_string(out.join("board.json")).unwrap();
        assert_eq!(Board::from_json(&board).unwrap(), set.board);
        assert_eq!(
            std::fs::read_to_string(out.join("truth.csv")).unwrap(),
            set.truth_csv()
        );
        // Writing names the file that failed.
        let blocked = dir.path().join("file");
        std::fs::write(&blocked, "").unwrap();
        let err = write_capture_set(&blocked, &set, None).unwrap_err();
        let err = format!("{err:#}");
        assert!(err.contains(&blocked.display().to_string()), "{err}");
    }
}
