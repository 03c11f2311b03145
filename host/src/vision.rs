//! Images on the host, around `hvs-vision`: board photos of a capture set into a training set
//! (`hvs board detect`), and image files in and out. The detection, rendering and matching
//! themselves live in the `hvs-vision` crate; this module reads and writes the files and
//! turns the crate's results into the project's CSV rows.

use crate::data::captures::{Capture, CaptureSet};
use anyhow::{anyhow, Context, Result};
use hvs_vision::board::Board;
use hvs_vision::detect::{self, SetCheck, StereoCorners};
use image::GrayImage;
use std::io::Cursor;
use std::path::Path;

/// Reads an image file (PNG or JPEG, any colour type) as grey levels; errors name the file.
pub fn read_grey(path: &Path) -> Result<GrayImage> {
    let img = image::ImageReader::open(path)
        .with_context(|| format!("{}: cannot open", path.display()))?
        .with_guessed_format()
        .with_context(|| format!("{}: cannot read", path.display()))?
        .decode()
        .map_err(|e| anyhow!("{}: not a readable image: {e}", path.display()))?;
    Ok(img.to_luma8())
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
    /// One fundamental matrix over all usable pairs (at least two), with per-pair residuals
    /// (indexed like the usable pairs, in capture order).
    pub set: Option<SetCheck>,
}

/// A pair whose corners lie this far (median, px) from the epipolar lines of the fundamental
/// matrix fitted to all *other* pairs is labelled differently from them (a shifted row or a
/// flip moves corners by whole squares) and is skipped.
pub const MAX_HELD_OUT_EPIPOLAR_PX: f64 = 2.0;

/// Detects `board` in every pair of `set` (`progress` is called after each pair), then fits
/// one fundamental matrix over the usable pairs and skips a pair whose labels disagree with
/// the others ([`MAX_HELD_OUT_EPIPOLAR_PX`]).
pub fn detect_set(board: &Board, set: &CaptureSet, progress: &dyn Fn()) -> Result<Detection> {
    let mut outcomes: Vec<PairOutcome> = set
        .captures
        .iter()
        .map(|c| {
            let r = detect_capture(board, c);
            progress();
            r
        })
        .collect();
    let fit = |outcomes: &[PairOutcome]| -> Option<SetCheck> {
        let pairs: Vec<StereoCorners> = outcomes
            .iter()
            .filter_map(|o| match o {
                PairOutcome::Found(p) => Some((**p).clone()),
                PairOutcome::Skipped(_) => None,
            })
            .collect();
        (pairs.len() >= 2)
            .then(|| detect::check_set(&pairs).ok())
            .flatten()
    };
    let mut check = fit(&outcomes);
    // A pair labelled unlike the others is dropped, and the rest refitted (once).
    if let Some(c) = &check {
        let found: Vec<usize> = (0..outcomes.len())
            .filter(|&k| matches!(outcomes[k], PairOutcome::Found(_)))
            .collect();
        let mut dropped = false;
        for (slot, &k) in found.iter().enumerate() {
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
            check = fit(&outcomes);
        }
    }
    Ok(Detection {
        outcomes,
        set: check,
    })
}

fn detect_capture(board: &Board, c: &Capture) -> PairOutcome {
    let load = |p: &Path| read_grey(p).map_err(|e| format!("{e:#}"));
    let (l, r) = match (load(&c.left), load(&c.right)) {
        (Ok(l), Ok(r)) => (l, r),
        (Err(e), _) | (_, Err(e)) => return PairOutcome::Skipped(e),
    };
    match detect::detect_pair(&l, &r, board) {
        Ok(p) => PairOutcome::Found(Box::new(p)),
        Err(e) => PairOutcome::Skipped(e.to_string()),
    }
}

/// `POINTS.csv`: one row per corner found in both images, `capture,i,j,u_l,v_l,u_r,v_r`, then
/// `x,y,z` when the captures give `z`, then the passed-through columns. `capture` is the
/// 1-based number of the pair in `CAPTURES.csv`. Pixels in shortest round-trip form.
pub fn points_csv(board: &Board, set: &CaptureSet, det: &Detection) -> String {
    let mut s = String::from("capture,i,j,u_l,v_l,u_r,v_r");
    if set.has_z {
        s.push_str(",x,y,z");
    }
    for c in &set.extra_columns {
        s.push(',');
        s.push_str(&csv_field(c));
    }
    s.push('\n');
    for (k, (cap, out)) in set.captures.iter().zip(&det.outcomes).enumerate() {
        let PairOutcome::Found(p) = out else { continue };
        for j in 0..board.rows {
            for i in 0..board.cols {
                let (l, r) = (p.left.at(i, j), p.right.at(i, j));
                s.push_str(&format!(
                    "{},{i},{j},{},{},{},{}",
                    k + 1,
                    shortest(l[0]),
                    shortest(l[1]),
                    shortest(r[0]),
                    shortest(r[1])
                ));
                if let Some(z) = cap.z {
                    let q = board.corner_position([cap.xy[0], cap.xy[1], z], i, j);
                    s.push_str(&format!(",{},{},{}", q[0], q[1], q[2]));
                }
                for e in &cap.extra {
                    s.push(',');
                    s.push_str(&csv_field(e));
                }
                s.push('\n');
            }
        }
    }
    s
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
