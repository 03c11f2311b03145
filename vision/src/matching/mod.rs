//! One point of the left image found in the right one: zero-mean normalised cross-correlation
//! (ZNCC) along the epipolar line, inside a disparity interval.
//!
//! # What is searched
//!
//! For a left pixel `(u_l, v_l)` (sub-pixel allowed; pixel-centre convention of
//! [`crate::render`]: integer coordinates at pixel centres) and a disparity interval
//! `[d_min, d_max]` with `d = u_l - u_r`, the candidates are the right-image points on the
//! epipolar line `F (u_l, v_l, 1)^T` ([`Fundamental::line_in_right`]) at every whole `u_r` in
//! `[u_l - d_max - s, u_l - d_min + s]` (`s` = [`MatchParams::interval_slack_px`]), one pixel
//! apart, plus one more on each side (for the peak test and the sub-pixel fit only).
//!
//! The left window (`(2r + 1)^2` pixels, bilinear at the sub-pixel point) is compared with
//! each candidate's window (vertically interpolated at the line's `v`) by a **weighted**
//! ZNCC: each window pixel counts `f + (1 - f) exp(-|I - I_centre| / gamma)`
//! ([`MatchParams::support_gamma`], [`MatchParams::support_floor`]; adaptive support weights
//! of the left window, used for the candidate too), so a window across a depth edge is ruled
//! by the pixels that look like the point. The template's weighted mean and norm are
//! computed once per point, each candidate's weighted sum and sum of squares in the same
//! pass as the cross term.
//!
//! Near a border the window is **clipped** to the part that fits in the left image at the
//! point and in the right image at every candidate of the interval (rectangular, the point
//! still inside, each side at least `r + 1` px).
//!
//! # Decisions, in order (the first that applies is the [`MatchStatus`])
//!
//! 1. Non-finite point or interval: [`MatchStatus::NanInput`].
//! 2. The point is off the left image, its clipped window is too small, or no candidate
//!    window lies inside the right image: [`MatchStatus::Outside`].
//! 3. The left window's standard deviation is below [`MatchParams::min_std`] grey levels:
//!    [`MatchStatus::NoTexture`] (nothing to correlate).
//! 4. The best score inside the interval is below [`MatchParams::min_score`], is not a local
//!    maximum (the peak lies beyond the interval), or the line is steeper than 45 degrees:
//!    [`MatchStatus::NoCandidate`].
//! 5. Another local maximum at least [`MatchParams::min_peak_separation_px`] away scores
//!    within [`MatchParams::uniqueness_margin`] of the best: [`MatchStatus::Ambiguous`].
//! 6. The best integer position is refined by a parabola through its score and its two
//!    neighbours' (offset clamped to half a pixel); `v_r` follows the line.
//! 7. Left-right check: the right window at the refined match is searched back along the
//!    left epipolar line ([`Fundamental::line_in_left`], `F^T`) over the same disparity
//!    interval; if that search fails or lands more than [`MatchParams::lr_tolerance_px`] from
//!    `(u_l, v_l)`: [`MatchStatus::LrCheckFailed`].
//! 8. Otherwise [`MatchStatus::Ok`].
//!
//! When the centred window ends in 4 (no acceptable peak) or 7 (left-right check) and
//! [`MatchParams::shifted_windows`] is on, four windows moved left, right, up and down by
//! `shift_fraction * r` px (the point near their edge, so one of them may lie on the point's
//! surface only) go through 2-8 in full; the best-scoring one that passes is returned if
//! another window's best candidate lies within `lr_tolerance_px` of it
//! ([`MatchParams::shifted_must_agree`]); otherwise the centred window's status stands.
//! Textureless and outside points are never retried. An **ambiguous** point (step 5) is
//! retried with the window grown to `2r`, `4r`, ... up to [`MatchParams::max_half_window`]
//! until one is not ambiguous; its answer is returned if it passes every check and scores at
//! least [`MatchParams::grown_min_score`] (a large window that reaches the end of a repeating
//! pattern, such as a board's border, tells the repeats apart); otherwise the point stays
//! ambiguous.
//!
//! In step 5 peaks are compared by their ZNCC at the sub-pixel top of their parabola
//! (sampled there), and a score still rising at an end of the interval counts as a peak
//! just beyond it: a repeat that falls on the pixel grid must not beat the true peak that
//! falls between two pixels.
//!
//! With cameras of different focal lengths set [`MatchParams::right_scale`] (e.g.
//! [`pinhole_right_scale`]): the right window then covers the same patch of the scene.
//!
//! # Parameters (how the defaults were chosen)
//!
//! See [`MatchParams::default`]: chosen on rendered boards with development seeds (never the
//! test seeds) and on the Motorcycle pair's development seeds.

mod interval;
mod params;
mod search;
mod window;
mod zncc;

pub use interval::{
    line_point, model_disparity_interval, model_disparity_interval_in_image, pinhole_right_scale,
    MODEL_SCAN_STEP_PX, MODEL_Z_MARGIN,
};
pub use params::{MatchError, MatchParams};

use crate::geometry::Fundamental;
use crate::invalid::InvalidField;
use image::GrayImage;
use std::fmt;
use window::{weight_lut, Plane};

/// What became of one point.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum MatchStatus {
    /// A unique, left-right consistent match.
    Ok,
    /// The left window or every candidate window leaves its image.
    Outside,
    /// The left window is too flat to correlate.
    NoTexture,
    /// Two peaks score too alike.
    Ambiguous,
    /// Searching back from the right match does not return to the left point.
    LrCheckFailed,
    /// No acceptable peak inside the interval.
    NoCandidate,
    /// The point or the interval is not finite.
    NanInput,
}

impl MatchStatus {
    /// The status' snake_case name (`ok`, `outside`, `no_texture`, `ambiguous`,
    /// `lr_check_failed`, `no_candidate`, `nan_input`).
    pub fn name(&self) -> &'static str {
        match self {
            MatchStatus::Ok => "ok",
            MatchStatus::Outside => "outside",
            MatchStatus::NoTexture => "no_texture",
            MatchStatus::Ambiguous => "ambiguous",
            MatchStatus::LrCheckFailed => "lr_check_failed",
            MatchStatus::NoCandidate => "no_candidate",
            MatchStatus::NanInput => "nan_input",
        }
    }
}

impl fmt::Display for MatchStatus {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// The answer for one point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Match {
    /// Right-image `u` (px). With a status other than `Ok` it is the best candidate found
    /// (for diagnostics; `NaN` when there was none): use it only when `status` is `Ok`.
    pub ur: f64,
    /// Right-image `v` (px), on the epipolar line (same caveat as `ur`).
    pub vr: f64,
    /// ZNCC at the best whole-pixel candidate, in `[-1, 1]` (`NaN` when there was none).
    pub score: f64,
    /// What happened.
    pub status: MatchStatus,
}

impl Match {
    fn fail(status: MatchStatus) -> Match {
        Match { ur: f64::NAN, vr: f64::NAN, score: f64::NAN, status }
    }

    /// Whether the match is usable (`status == Ok`).
    pub fn is_ok(&self) -> bool {
        self.status == MatchStatus::Ok
    }
}

/// One point to match: the left pixel and its disparity interval `d = u_l - u_r` (px).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Query {
    /// Left `u` (px).
    pub ul: f64,
    /// Left `v` (px).
    pub vl: f64,
    /// Smallest disparity searched (px).
    pub d_min: f64,
    /// Largest disparity searched (px).
    pub d_max: f64,
}

/// A stereo pair prepared for matching: both images as `f32`, the fundamental matrix and
/// the parameters.
pub struct Matcher {
    left: Plane,
    right: Plane,
    /// Support weights by grey-level difference ([`weight_lut`]).
    weights: Vec<f32>,
    f: Fundamental,
    /// The parameters in use.
    pub params: MatchParams,
}

impl Matcher {
    /// Prepares `left` and `right` (same size) with `f` (`r^T F l = 0`) and `params`.
    pub fn new(
        left: &GrayImage,
        right: &GrayImage,
        f: &Fundamental,
        params: MatchParams,
    ) -> Result<Matcher, MatchError> {
        params.validate()?;
        crate::invalid::same_size(left, right)?;
        if left.width() == 0 || left.height() == 0 {
            return Err(InvalidField::new("left", "image is empty"));
        }
        if !f.m.iter().flatten().all(|x| x.is_finite()) || f.m.iter().flatten().all(|&x| x == 0.0) {
            return Err(InvalidField::new("fundamental", "must be finite and not all zero"));
        }
        Ok(Matcher {
            left: Plane::new(left),
            right: Plane::new(right),
            weights: weight_lut(params.support_gamma, params.support_floor),
            f: *f,
            params,
        })
    }

    /// Matches one left point (see the module documentation for the decisions).
    pub fn find(&self, q: &Query) -> Match {
        let mut buf = Vec::new();
        self.find_with(q, &mut buf)
    }

    /// Matches every query in order, on the calling thread.
    pub fn find_all(&self, queries: &[Query]) -> Vec<Match> {
        let mut buf = Vec::new();
        queries.iter().map(|q| self.find_with(q, &mut buf)).collect()
    }
}

/// Matches `queries` in `left`/`right` with `f` and `params` (one [`Matcher`], one thread).
pub fn match_points(
    left: &GrayImage,
    right: &GrayImage,
    f: &Fundamental,
    queries: &[Query],
    params: MatchParams,
) -> Result<Vec<Match>, MatchError> {
    Ok(Matcher::new(left, right, f, params)?.find_all(queries))
}

#[cfg(test)]
mod tests {
    use super::window::{template, weight_lut, Plane, Win};
    use super::zncc::{zncc_at, Probe};
    use super::*;

    #[test]
    fn model_interval_keeps_the_disparities_of_the_training_depths() {
        // A rectified toy model: Z = 1000 / d.
        let model = |x: [f32; 4]| {
            let d = x[0] - x[2];
            (d > 0.0).then(|| [0.0, 0.0, 1000.0 / d])
        };
        let row = [0.0, -1.0, 50.0];
        let (lo, hi) =
            model_disparity_interval(model, 300.0, 50.0, row, [50.0, 100.0], [0.0, 80.0]).unwrap();
        // Z in 47.5..102.5 cm: d in 9.76..21.05 px, plus one step.
        assert!((lo - 9.5).abs() < 0.26 && (hi - 21.25).abs() < 0.26, "{lo} {hi}");
        // Nothing inside: None; bad input: None.
        assert!(
            model_disparity_interval(model, 300.0, 50.0, row, [500.0, 600.0], [0.0, 1.0]).is_none()
        );
        assert!(model_disparity_interval(model, f64::NAN, 50.0, row, [50.0, 100.0], [0.0, 80.0])
            .is_none());
        assert!(model_disparity_interval(
            model,
            300.0,
            50.0,
            [1.0, 0.0, -5.0],
            [50.0, 100.0],
            [0.0, 80.0]
        )
        .is_none());
        assert!(model_disparity_interval(|_| None, 300.0, 50.0, row, [50.0, 100.0], [0.0, 80.0])
            .is_none());
    }

    #[test]
    fn bad_params_name_the_field() {
        // The defaults with one field set bad.
        let refused = |spoil: fn(&mut MatchParams), field: &str| {
            let mut p = MatchParams::default();
            spoil(&mut p);
            crate::invalid::assert_refused(p.validate(), field);
        };
        refused(|p| p.half_window = 0, "params.half_window");
        refused(|p| p.min_score = f64::NAN, "params.min_score");
    }

    #[test]
    fn template_is_zero_mean_unit_norm() {
        let img = GrayImage::from_fn(40, 30, |x, y| image::Luma([((x * 7 + y * 13) % 97) as u8]));
        let p = Plane::new(&img);
        let mut t = vec![0.0f32; 98];
        let w = Win::shifted(3, 0, 0);
        for gamma in [0.0, 10.0] {
            let std =
                template(&p, 20.3, 14.6, w, [1.0, 1.0], &weight_lut(gamma, 0.2), &mut t).unwrap();
            assert!(std > 1.0);
            let (a, wt) = t.split_at(49);
            let s: f32 = a.iter().sum();
            let ws: f32 = wt.iter().sum();
            let ss: f32 = a.iter().zip(wt).map(|(x, w)| x * x / w).sum();
            assert!(s.abs() < 1e-4 && (ws - 1.0).abs() < 1e-4 && (ss - 1.0).abs() < 1e-3);
            // The same window correlates with itself at 1, and not with its neighbour.
            template(&p, 20.0, 14.0, w, [1.0, 1.0], &weight_lut(gamma, 0.2), &mut t).unwrap();
            let z = zncc_at(&p, Probe { t: &t, win: w, scale: [1.0, 1.0] }, 20, 14.0).unwrap();
            assert!((z - 1.0).abs() < 1e-4, "{z}");
            let z = zncc_at(&p, Probe { t: &t, win: w, scale: [1.0, 1.0] }, 21, 14.0).unwrap();
            assert!(z < 0.999, "{z}");
        }
        assert!(template(&p, 2.5, 14.0, w, [1.0, 1.0], &[], &mut t).is_none());
        assert!(template(&p, 3.0, 3.0, w, [1.0, 1.0], &[], &mut t).is_some());
        assert!(template(&p, 36.0, 26.0, w, [1.0, 1.0], &[], &mut t).is_some());
        assert!(template(&p, 36.5, 26.0, w, [1.0, 1.0], &[], &mut t).is_none());
        // Clipped at the border: the part that fits.
        let c = w.clip([40, 30], [1.5, 1.5], [28.0, 28.0], [1.0, 1.0]);
        assert_eq!(c, Win { x0: -1, x1: 3, y0: -3, y1: 1 });
        assert!(template(&p, 1.5, 28.0, c, [1.0, 1.0], &[], &mut t[..2 * c.len()]).is_some());
    }
}
