//! The facts `RESULTS.md` states, as small pure functions of the presets, protocol or results.

use super::{DepthCurve, PhiRow};
use crate::fmt::join;
use crate::study::reported;
use hvs_shared::sim::camera::Rig;

/// Phi_L or Phi_R of one case over the depths: mean, truth (px), max deviation, SD (% of mean).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PhiStats {
    pub mean: f64,
    pub truth: f64,
    pub max_dev_pct: f64,
    pub sd_pct: f64,
}

impl PhiStats {
    /// The mean's deviation from the true value (%, signed).
    pub fn bias_pct(&self) -> f64 {
        (self.mean / self.truth - 1.0) * 100.0
    }
}

/// [`PhiStats`] of `case`'s Phi_L (`left`) or Phi_R rows (NaN fields when it has none).
pub fn phi_stats(rows: &[PhiRow], case: u8, left: bool) -> PhiStats {
    let pick = |r: &PhiRow| if left { (r.phi_l, r.true_l) } else { (r.phi_r, r.true_r) };
    let v: Vec<(f64, f64)> = rows.iter().filter(|r| r.case == case).map(pick).collect();
    let n = v.len() as f64;
    let mean = v.iter().map(|p| p.0).sum::<f64>() / n;
    let truth = v.first().map_or(f64::NAN, |p| p.1);
    let max_dev_pct = v.iter().map(|p| (p.0 - mean).abs() / mean * 100.0).fold(0.0, f64::max);
    let var = v.iter().map(|p| (p.0 - mean) * (p.0 - mean)).sum::<f64>() / n;
    PhiStats { mean, truth, max_dev_pct, sd_pct: libm::sqrt(var) / mean * 100.0 }
}

/// How far apart two means are, in % of the first.
pub fn apart_pct(a: f64, b: f64) -> f64 {
    (a - b).abs() / a * 100.0
}

/// Neighbouring `depths` (cm) at which the point `xy` has the same rounded pixels in `rig`.
pub fn identical_pixel_depths(rig: &Rig, xy: [f64; 2], depths: &[f64]) -> Vec<(f64, f64)> {
    let px = |z: f64| rig.project_rounded(&[xy[0], xy[1], z]).ok();
    let same = |w: &&[f64]| px(w[0]).is_some() && px(w[0]) == px(w[1]);
    depths.windows(2).filter(same).map(|w| (w[0], w[1])).collect()
}

/// The mean disparity `u_l - u_r` (px, rounded) of the board about `centre_x` at depth `z`.
pub fn board_disparity_px(rig: &Rig, centre_x: f64, z: f64) -> Option<f64> {
    let points = super::board_about(centre_x, z);
    let d = points.iter().map(|p| rig.project_rounded(p).ok().map(|px| px[0] - px[2]));
    Some(d.sum::<Option<f64>>()? / points.len() as f64)
}

/// The depth (cm) of a curve's worst per-depth e_ma (the first, on ties; NaN when empty).
pub fn worst_depth(c: &DepthCurve) -> f64 {
    let k = (0..c.pct.len()).fold(0, |w, k| if c.pct[k] > c.pct[w] { k } else { w });
    c.z.get(k).copied().unwrap_or(f64::NAN)
}

/// A depth grid in words: `65-165 cm in steps of 20 cm` (evenly spaced), or the list.
pub fn depth_grid(d: &[f64]) -> String {
    let step = d.get(1).zip(d.first()).map(|(b, a)| b - a);
    let even = step.is_some_and(|s| s > 0.0 && d.windows(2).all(|w| w[1] - w[0] == s));
    match (even, step) {
        (true, Some(s)) => format!("{}-{} cm in steps of {s} cm", d[0], d[d.len() - 1]),
        _ => format!("{} cm", join(d.iter(), ", ")),
    }
}

/// Signed positions as the text gives them: `-1.75, +1.75`.
pub fn signed_list(v: impl IntoIterator<Item = f64>) -> String {
    join(v.into_iter().map(|x| if x > 0.0 { format!("+{x}") } else { format!("{x}") }), ", ")
}

/// Whether the range `lo`..`hi` (%) is the thesis' for `case` within 10 % (0.1 at the low end).
pub fn matches_thesis_traditional(case: u8, lo: f64, hi: f64) -> bool {
    let th = usize::from(case).checked_sub(1).and_then(|k| reported::TRADITIONAL_PCT.get(k));
    th.is_some_and(|th| {
        (lo - th[0]).abs() <= 0.1 * th[0].max(1.0) && (hi - th[1]).abs() <= 0.1 * th[1]
    })
}

/// The index of the smallest value (the first, on ties; 0 when empty).
pub fn argmin(v: &[f64]) -> usize {
    (0..v.len()).fold(0, |b, k| if v[k] < v[b] { k } else { b })
}
