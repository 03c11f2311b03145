//! A capture set's board photos into a training set (`hvs board detect`): detection of every
//! pair in parallel, the checks of the pairs taken at one posture together, and `POINTS.csv`.

use super::files::read_grey;
use crate::data::captures::{Capture, CaptureSet};
use crate::data::dataset::{Dataset, JOINT_COLUMNS};
use anyhow::Result;
use hvs_shared::runtime::blob::InputKind;
use hvs_vision::board::Board;
use hvs_vision::detect::{self, SetCheck, StereoCorners};
use image::GrayImage;
use rayon::prelude::*;
use std::path::Path;

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

impl Detection {
    /// The pairs whose board was found in both images.
    pub fn usable(&self) -> usize {
        self.outcomes.iter().filter(|o| matches!(o, PairOutcome::Found(_))).count()
    }

    /// What the fundamental-matrix check found, for people (`hvs board detect`'s report,
    /// `hvs view`'s capture set): none without two usable pairs at one posture, else the
    /// Sampson rms of the one matrix over all pairs, or its range over one matrix per posture.
    pub fn fundamental_check(&self) -> String {
        let usable = self.usable();
        let checked: usize = self.groups.iter().map(|g| g.pairs).sum();
        match self.groups.as_slice() {
            [] => "no two pairs at one posture: no fundamental-matrix check".into(),
            [g] if g.pairs == usable => {
                format!("one fundamental matrix over all: Sampson rms {:.3} px", g.rms_sampson)
            }
            gs => format!(
                "one fundamental matrix per posture over {} postures ({checked} pairs): Sampson rms {:.3}-{:.3} px",
                gs.len(),
                gs.iter().map(|g| g.rms_sampson).fold(f64::INFINITY, f64::min),
                gs.iter().map(|g| g.rms_sampson).fold(0.0, f64::max),
            ),
        }
    }
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
    let joints =
        set.extra_columns.iter().take_while(|c| JOINT_COLUMNS.contains(&c.as_str())).count();
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
    let postures = posture_groups(set);
    // Disparities that cannot be right (the same image twice; a pair or the whole set swapped,
    // mirrored or turned): one fundamental matrix fits those too, so they are looked at first.
    let usable: Vec<Vec<usize>> = postures
        .iter()
        .map(|m| {
            m.iter().copied().filter(|&k| matches!(outcomes[k], PairOutcome::Found(_))).collect()
        })
        .collect();
    let faults = {
        let groups: Vec<(Vec<&StereoCorners>, Vec<Option<f64>>)> = usable
            .iter()
            .map(|g| {
                let pairs = g
                    .iter()
                    .filter_map(|&k| match &outcomes[k] {
                        PairOutcome::Found(p) => Some(&**p),
                        PairOutcome::Skipped(_) => None,
                    })
                    .collect();
                (pairs, g.iter().map(|&k| set.captures[k].z).collect())
            })
            .collect();
        detect::set_faults(&groups)
    };
    for (g, faults) in usable.iter().zip(faults) {
        for (&k, fault) in g.iter().zip(faults) {
            if let Some(why) = fault {
                outcomes[k] = PairOutcome::Skipped(why.to_string());
            }
        }
    }
    let mut groups = Vec::new();
    for members in postures {
        if let Some(fit) = check_group(&members, &mut outcomes, &mut epipolar) {
            groups.push(fit);
        }
    }
    let det = Detection { outcomes, epipolar, groups, image_size };
    Ok((det, images))
}

/// The epipolar checks of one posture group (capture indices `members`), after the disparity
/// checks: skips the pairs labelled unlike the others and fills their epipolar residuals; the
/// group's fit if it has two usable pairs.
fn check_group(
    members: &[usize],
    outcomes: &mut [PairOutcome],
    epipolar: &mut [Option<[f64; 2]>],
) -> Option<GroupFit> {
    let found = |outcomes: &[PairOutcome]| -> Vec<usize> {
        members.iter().copied().filter(|&k| matches!(outcomes[k], PairOutcome::Found(_))).collect()
    };
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
    Some(GroupFit { pairs: usable.len(), rms_sampson: c.fit.rms_sampson })
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
    let size =
        det.image_size.and_then(|(w, h)| Some((u16::try_from(w).ok()?, u16::try_from(h).ok()?)));
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
                        xyz: cap.z.map(|z| board.corner_position([cap.xy[0], cap.xy[1], z], i, j)),
                    }
                })
            })
        })
}

/// The training set of detected corners, each `(detected [u_l, v_l, u_r, v_r], true position,
/// exact pixels)` of a rendered board, and the mean |detected - exact| per image coordinate
/// (px): rendered boards into a dataset (`hvs demo --images`, `hvs experiment accuracy`).
pub fn detected_set(
    corners: impl IntoIterator<Item = ([f64; 4], [f64; 3], [f64; 4])>,
) -> (Dataset, f64) {
    let mut data = Dataset::new(InputKind::Stereo);
    let mut err = 0.0;
    for (px, xyz, exact) in corners {
        data.push(&px, Some(xyz));
        err += (0..4).map(|c| (px[c] - exact[c]).abs()).sum::<f64>();
    }
    let n = data.len();
    (data, err / (4 * n) as f64)
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
