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

use crate::geometry::Fundamental;
use crate::invalid::{in_range, InvalidField};
use hvs_shared::sim::camera::Camera;
use image::GrayImage;
use std::fmt;

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
        Match {
            ur: f64::NAN,
            vr: f64::NAN,
            score: f64::NAN,
            status,
        }
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

/// Knobs of the matcher.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MatchParams {
    /// Half window `r`: windows are `(2r + 1) x (2r + 1)` pixels (1..=30).
    pub half_window: u32,
    /// Smallest score of a grown window's answer (a large window fits a plane, such as a
    /// board, well; across the depth changes of a real scene it scores lower and is then
    /// not trusted).
    pub grown_min_score: f64,
    /// How much larger the scene looks in the right image than in the left, along `u` and
    /// `v` (the right window's pixel offsets are the left one's times this, sampled
    /// bilinearly): the ratio of the focal lengths, e.g. [`pinhole_right_scale`]; `[1, 1]`
    /// for cameras alike (0.25..=4).
    pub right_scale: [f64; 2],
    /// Largest half window tried when the `half_window` one is ambiguous: the window doubles
    /// (`2r`, `4r`, ... up to this) until it is unique or fails otherwise (`half_window` or
    /// less: never grow). At most 60.
    pub max_half_window: u32,
    /// Smallest standard deviation of the left window (grey levels) worth correlating.
    pub min_std: f64,
    /// Smallest acceptable best ZNCC.
    pub min_score: f64,
    /// A second peak within this much ZNCC of the best makes the point ambiguous.
    pub uniqueness_margin: f64,
    /// Peaks at least this far apart (px along `u`) count as distinct.
    pub min_peak_separation_px: f64,
    /// Largest distance (px) of the left-right check's answer from the left point.
    pub lr_tolerance_px: f64,
    /// Widest disparity interval accepted (px; wider queries are an error).
    pub max_interval_px: f64,
    /// The peak may lie this far (px) beyond either end of the disparity interval.
    pub interval_slack_px: f64,
    /// When the centred window finds no acceptable peak or fails the left-right check, try
    /// four windows moved left, right, up and down by `shift_fraction * half_window` px.
    pub shifted_windows: bool,
    /// How far the shifted windows move, as a fraction of `half_window` (0..=1).
    pub shift_fraction: f64,
    /// A shifted window's answer counts only if another window's best candidate (the
    /// centred one's or another shifted one's, acceptable or not) lies within
    /// `lr_tolerance_px` of it.
    pub shifted_must_agree: bool,
    /// Adaptive support weights: a window pixel counts `exp(-|I - I_centre| / gamma)` (grey
    /// levels; `0` = every pixel counts the same), so a window across a depth edge is ruled
    /// by the pixels that look like the point, on its own surface.
    pub support_gamma: f64,
    /// The smallest support weight (0..=1): every pixel keeps at least this share, so a
    /// point whose own grey level is rare in its window (a chessboard's saddle) still
    /// correlates its whole window.
    pub support_floor: f64,
}

impl Default for MatchParams {
    /// `r = 5` (11 x 11 windows: on the development Motorcycle pair 77 % of points came back
    /// within 1 px against 73 % with 15 x 15 and 69 % with 19 x 19, and it still spans a full
    /// period of the 10 px squares at 165 cm), `min_std = 1` grey level (only truly flat
    /// windows are refused as such), `min_score = 0.5`, `uniqueness_margin = 0.05`, peaks
    /// 2 px apart are distinct, left-right tolerance 1 px, intervals up to 256 px, no
    /// interval slack (1 px of slack admitted more wrong peaks than it found right ones with
    /// intervals that hold the truth), shifted windows on (moved by a whole `r`, and they
    /// must agree), support weights `gamma = 10` grey levels with a floor of 0.2 (without a
    /// floor a chessboard saddle, whose own grey is rare in its window, lost its accuracy).
    /// Ambiguous points grow their window up to `r = 40`, trusted from a score of 0.9 (0.8
    /// and 0.95 differed by 0.1 % of points on the real pair). On the Motorcycle development
    /// seeds 1-4 (4000 points, interval true disparity +- 10 %) this took the points
    /// returned within 1 px from 77.5 % (the previous defaults) to 83.4 % with 1.3 %
    /// returned 2 px or more off. Chosen on development seeds
    /// only (rendered boards seeds 1-4, Motorcycle point seeds 1-4; tests use other seeds).
    fn default() -> Self {
        MatchParams {
            half_window: 5,
            max_half_window: 40,
            right_scale: [1.0, 1.0],
            grown_min_score: 0.9,
            min_std: 1.0,
            min_score: 0.5,
            uniqueness_margin: 0.05,
            min_peak_separation_px: 2.0,
            lr_tolerance_px: 1.0,
            max_interval_px: 256.0,
            interval_slack_px: 0.0,
            shifted_windows: true,
            shift_fraction: 1.0,
            shifted_must_agree: true,
            support_gamma: 10.0,
            support_floor: 0.2,
        }
    }
}

/// Why a matcher could not be built or a batch not run: a parameter or input is out of
/// range, and the error names it.
pub type MatchError = InvalidField;

impl MatchParams {
    /// Checks the parameters (field names in the error).
    pub fn validate(&self) -> Result<(), MatchError> {
        in_range("params.half_window", self.half_window, 1, 30)?;
        if self.max_half_window > 60 {
            return Err(InvalidField::new(
                "params.max_half_window",
                format!("must be at most 60, got {}", self.max_half_window),
            ));
        }
        let checks: [(&'static str, f64, f64, f64); 13] = [
            ("params.grown_min_score", self.grown_min_score, -1.0, 1.0),
            ("params.right_scale[0]", self.right_scale[0], 0.25, 4.0),
            ("params.right_scale[1]", self.right_scale[1], 0.25, 4.0),
            ("params.support_floor", self.support_floor, 0.0, 1.0),
            ("params.support_gamma", self.support_gamma, 0.0, 1000.0),
            (
                "params.interval_slack_px",
                self.interval_slack_px,
                0.0,
                100.0,
            ),
            ("params.shift_fraction", self.shift_fraction, 0.0, 1.0),
            ("params.min_std", self.min_std, 0.0, 255.0),
            ("params.min_score", self.min_score, -1.0, 1.0),
            ("params.uniqueness_margin", self.uniqueness_margin, 0.0, 2.0),
            (
                "params.min_peak_separation_px",
                self.min_peak_separation_px,
                1.0,
                1000.0,
            ),
            ("params.lr_tolerance_px", self.lr_tolerance_px, 0.0, 1000.0),
            (
                "params.max_interval_px",
                self.max_interval_px,
                0.0,
                100_000.0,
            ),
        ];
        for (field, v, lo, hi) in checks {
            if !(v.is_finite() && v >= lo && v <= hi) {
                return Err(InvalidField::new(
                    field,
                    format!("must be in {lo}..={hi}, got {v}"),
                ));
            }
        }
        Ok(())
    }
}

/// A grey image as `f32`, row-major.
struct Plane {
    w: usize,
    h: usize,
    px: Vec<f32>,
}

impl Plane {
    fn new(img: &GrayImage) -> Plane {
        Plane {
            w: img.width() as usize,
            h: img.height() as usize,
            px: img.as_raw().iter().map(|&p| f32::from(p)).collect(),
        }
    }
}

/// A rectangular window around a point: columns `x0..=x1` and rows `y0..=y1` relative to
/// it (the point itself always inside: `x0 <= 0 <= x1`, `y0 <= 0 <= y1`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Win {
    x0: i64,
    x1: i64,
    y0: i64,
    y1: i64,
}

impl Win {
    /// The square window of half size `r`, moved by `(sx, sy)` px (the point stays inside).
    fn shifted(r: i64, sx: i64, sy: i64) -> Win {
        Win {
            x0: -r + sx,
            x1: r + sx,
            y0: -r + sy,
            y1: r + sy,
        }
    }
    fn width(&self) -> usize {
        (self.x1 - self.x0 + 1) as usize
    }
    fn height(&self) -> usize {
        (self.y1 - self.y0 + 1) as usize
    }
    fn len(&self) -> usize {
        self.width() * self.height()
    }
    /// Whether the point is inside and both sides are at least `min_side` px.
    fn usable(&self, min_side: i64) -> bool {
        self.x0 <= 0
            && self.x1 >= 0
            && self.y0 <= 0
            && self.y1 >= 0
            && self.x1 - self.x0 + 1 >= min_side
            && self.y1 - self.y0 + 1 >= min_side
    }
    /// The part of the window that fits, with its interpolation support, in a `w x h` image
    /// around every centre with `u` in `[u_lo, u_hi]` and `v` in `[v_lo, v_hi]` when window
    /// offset `(dx, dy)` lands at `(u + scale[0] dx, v + scale[1] dy)` (centres clamped to
    /// the image first: candidates off the image are dropped, not the window).
    #[allow(clippy::too_many_arguments)]
    fn clip(
        &self,
        w: usize,
        h: usize,
        u_lo: f64,
        u_hi: f64,
        v_lo: f64,
        v_hi: f64,
        scale: [f64; 2],
    ) -> Win {
        let (wm, hm) = ((w - 1) as f64, (h - 1) as f64);
        let (u_lo, u_hi) = (u_lo.clamp(0.0, wm), u_hi.clamp(0.0, wm));
        let (v_lo, v_hi) = (v_lo.clamp(0.0, hm), v_hi.clamp(0.0, hm));
        // A tiny tolerance so that exact multiples are not lost to rounding.
        let lo = |c: f64, s: f64| (-c / s - 1e-9).ceil() as i64;
        let hi = |c: f64, m: f64, s: f64| ((m - c) / s + 1e-9).floor() as i64;
        Win {
            x0: self.x0.max(lo(u_lo, scale[0])),
            x1: self.x1.min(hi(u_hi, wm, scale[0])),
            y0: self.y0.max(lo(v_lo, scale[1])),
            y1: self.y1.min(hi(v_hi, hm, scale[1])),
        }
    }
}

/// Entries per grey level of the support-weight table.
const WEIGHT_STEPS_PER_GREY: f64 = 4.0;

/// The support weights `floor + (1 - floor) exp(-|dI| / gamma)` for `|dI|` = 0, 1/4, ...,
/// 255 grey levels (empty when `gamma` is 0: every pixel counts the same).
fn weight_lut(gamma: f64, floor: f64) -> Vec<f32> {
    if gamma <= 0.0 {
        return Vec::new();
    }
    let n = (255.0 * WEIGHT_STEPS_PER_GREY) as usize + 1;
    (0..n)
        .map(|k| {
            let d = k as f64 / WEIGHT_STEPS_PER_GREY;
            (floor + (1.0 - floor) * (-d / gamma).exp()) as f32
        })
        .collect()
}

/// Bilinear grey level of `img` at `(x, y)`, `None` off the image (support included).
fn bilinear(img: &Plane, x: f64, y: f64) -> Option<f32> {
    let (xf, yf) = (x.floor(), y.floor());
    if !(xf >= 0.0 && yf >= 0.0 && x <= (img.w - 1) as f64 && y <= (img.h - 1) as f64) {
        return None;
    }
    let (xi, yi) = (xf as usize, yf as usize);
    let (fx, fy) = ((x - xf) as f32, (y - yf) as f32);
    let x2 = if fx > 0.0 { xi + 1 } else { xi };
    let y2 = if fy > 0.0 { yi + 1 } else { yi };
    let p = |xx: usize, yy: usize| img.px[yy * img.w + xx];
    let a = p(xi, yi) + fx * (p(x2, yi) - p(xi, yi));
    let b = p(xi, y2) + fx * (p(x2, y2) - p(xi, y2));
    Some(a + fy * (b - a))
}

/// The outcome of one search along a line.
struct Search {
    /// Its score.
    score: f64,
    /// Refined `u` of the peak.
    u: f64,
    /// `v` on the line at `u`.
    v: f64,
    status: MatchStatus,
    /// When ambiguous: the whole-pixel `u` of the best peak and of its rivals.
    peaks: Vec<i64>,
}

impl Search {
    fn none(status: MatchStatus) -> Search {
        Search {
            score: f64::NAN,
            u: f64::NAN,
            v: f64::NAN,
            status,
            peaks: Vec::new(),
        }
    }
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

/// Which image a search runs in.
#[derive(Clone, Copy)]
enum Side {
    /// Left point, candidates in the right image (`u_r = u_l - d`).
    Forward,
    /// Right point, candidates in the left image (`u_l = u_r + d`): the left-right check.
    Back,
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
        if left.dimensions() != right.dimensions() {
            return Err(InvalidField::new(
                "right",
                format!(
                    "image is {:?}, the left one {:?}: both must be the same size",
                    right.dimensions(),
                    left.dimensions()
                ),
            ));
        }
        if left.width() == 0 || left.height() == 0 {
            return Err(InvalidField::new("left", "image is empty"));
        }
        if !f.m.iter().flatten().all(|x| x.is_finite()) || f.m.iter().flatten().all(|&x| x == 0.0) {
            return Err(InvalidField::new(
                "fundamental",
                "must be finite and not all zero",
            ));
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
        queries
            .iter()
            .map(|q| self.find_with(q, &mut buf))
            .collect()
    }

    fn find_with(&self, q: &Query, buf: &mut Vec<f32>) -> Match {
        if ![q.ul, q.vl, q.d_min, q.d_max].iter().all(|x| x.is_finite()) {
            return Match::fail(MatchStatus::NanInput);
        }
        if q.d_min > q.d_max || q.d_max - q.d_min > self.params.max_interval_px {
            return Match::fail(MatchStatus::NoCandidate);
        }
        let (w, h) = (self.left.w as f64, self.left.h as f64);
        if !(q.ul >= 0.0 && q.ul <= w - 1.0 && q.vl >= 0.0 && q.vl <= h - 1.0) {
            return Match::fail(MatchStatus::Outside);
        }
        let r = i64::from(self.params.half_window);
        let mut peaks = Vec::new();
        let first = self.find_window(q, Win::shifted(r, 0, 0), None, &mut peaks, buf);
        if first.status == MatchStatus::Ambiguous {
            // A repeating pattern: a larger window may reach what does not repeat (the edge
            // of the pattern); it must pass every check on its own. Only the rivals are
            // compared (and mirrored in the left-right check): a few candidates, not the
            // whole interval.
            let rivals = std::mem::take(&mut peaks);
            let mut big = 2 * r;
            while big <= i64::from(self.params.max_half_window) {
                let m =
                    self.find_window(q, Win::shifted(big, 0, 0), Some(&rivals), &mut peaks, buf);
                if m.status != MatchStatus::Ambiguous {
                    if m.status == MatchStatus::Ok && m.score >= self.params.grown_min_score {
                        return m;
                    }
                    break;
                }
                big *= 2;
            }
            return first;
        }
        let retry = matches!(
            first.status,
            MatchStatus::NoCandidate | MatchStatus::LrCheckFailed
        );
        if first.status == MatchStatus::Ok || !retry || !self.params.shifted_windows {
            return first;
        }
        // Near a depth edge the centred window straddles two surfaces: a window beside the
        // point, on one surface only, may still match (its own checks apply in full).
        let step = (r as f64 * self.params.shift_fraction).round() as i64;
        let mut tried = [first; 5];
        for (k, (sx, sy)) in [(-1, 0), (1, 0), (0, -1), (0, 1)].into_iter().enumerate() {
            let w = Win::shifted(r, sx * step, sy * step);
            tried[k + 1] = self.find_window(q, w, None, &mut peaks, buf);
        }
        // The best-scoring acceptable shifted window, if another window's best candidate
        // (acceptable or not) lies within `lr_tolerance_px` of it when agreement is asked.
        let mut best: Option<Match> = None;
        for (k, m) in tried.iter().enumerate().skip(1) {
            if m.status != MatchStatus::Ok || best.is_some_and(|b| b.score >= m.score) {
                continue;
            }
            let agrees = !self.params.shifted_must_agree
                || tried
                    .iter()
                    .enumerate()
                    .any(|(j, o)| j != k && (o.ur - m.ur).abs() <= self.params.lr_tolerance_px);
            if agrees {
                best = Some(*m);
            }
        }
        best.unwrap_or(first)
    }

    /// One window shape's search from the left point and its left-right check.
    /// `only`: search only around these whole-pixel `u_r` (and, in the left-right check,
    /// around the left points they mirror); `peaks` receives the rivals when ambiguous.
    fn find_window(
        &self,
        q: &Query,
        shape: Win,
        only: Option<&[i64]>,
        peaks: &mut Vec<i64>,
        buf: &mut Vec<f32>,
    ) -> Match {
        let slack = self.params.interval_slack_px;
        let line = self.f.line_in_right([q.ul, q.vl]);
        let Some(s) = self.search_from(
            Side::Forward,
            q.ul,
            q.vl,
            shape,
            line,
            q.ul - q.d_max - slack,
            q.ul - q.d_min + slack,
            only,
            true,
            buf,
        ) else {
            return Match::fail(MatchStatus::Outside);
        };
        *peaks = s.peaks;
        let out = Match {
            ur: s.u,
            vr: s.v,
            score: s.score,
            status: s.status,
        };
        if s.status != MatchStatus::Ok {
            return out;
        }
        // Left-right check: the right window at the match, searched back in the left image.
        let back_line = self.f.line_in_left([s.u, s.v]);
        let back_only: Option<Vec<i64>> = only.map(|o| {
            o.iter()
                .map(|&c| (q.ul + (c as f64 - s.u)).round() as i64)
                .collect()
        });
        let b = self.search_from(
            Side::Back,
            s.u,
            s.v,
            shape,
            back_line,
            s.u + q.d_min - slack,
            s.u + q.d_max + slack,
            back_only.as_deref(),
            false,
            buf,
        );
        let back_ok = b.is_some_and(|b| {
            // `dist` is NaN when the back search found nothing: that fails too.
            let dist = ((b.u - q.ul).powi(2) + (b.v - q.vl).powi(2)).sqrt();
            b.status == MatchStatus::Ok && dist <= self.params.lr_tolerance_px
        });
        if !back_ok {
            return Match {
                status: MatchStatus::LrCheckFailed,
                ..out
            };
        }
        out
    }

    /// The template of `shape` at `(u, v)` in one image, searched along `line` in the other
    /// at whole `u` in `[u_lo, u_hi]`. `None` when the window, clipped to both images, is too
    /// small (the point is too close to a border).
    #[allow(clippy::too_many_arguments)]
    fn search_from(
        &self,
        side: Side,
        u: f64,
        v: f64,
        shape: Win,
        line: [f64; 3],
        u_lo: f64,
        u_hi: f64,
        only: Option<&[i64]>,
        check_unique: bool,
        buf: &mut Vec<f32>,
    ) -> Option<Search> {
        let (src, dst) = match side {
            Side::Forward => (&self.left, &self.right),
            Side::Back => (&self.right, &self.left),
        };
        // The right window is the left one scaled by `right_scale` (both searches).
        let one = [1.0, 1.0];
        let (s_src, s_dst) = match side {
            Side::Forward => (one, self.params.right_scale),
            Side::Back => (self.params.right_scale, one),
        };
        let [a, b, c] = line;
        if !(a.is_finite() && b.is_finite() && c.is_finite()) || b.abs() < a.abs() {
            return Some(Search::none(MatchStatus::NoCandidate));
        }
        let v_at = |u: f64| -(a * u + c) / b;
        let (mut k_lo, mut k_hi) = (u_lo.ceil() as i64, u_hi.floor() as i64);
        if let Some(o) = only {
            // Only around the listed candidates (the rivals of an ambiguous search).
            let (lo, hi) = (o.iter().min(), o.iter().max());
            let (Some(&lo), Some(&hi)) = (lo, hi) else {
                return Some(Search::none(MatchStatus::NoCandidate));
            };
            (k_lo, k_hi) = (lo, hi);
        }
        if k_lo > k_hi {
            // The interval holds no whole pixel: take the nearest one.
            k_lo = (0.5 * (u_lo + u_hi)).round() as i64;
            k_hi = k_lo;
        }
        // Keep the candidate count sane for absurd coordinates.
        if k_hi - k_lo > 100_000 {
            return Some(Search::none(MatchStatus::NoCandidate));
        }
        let (ka, kb) = ((k_lo - 1) as f64, (k_hi + 1) as f64);
        let (va, vb) = (v_at(ka), v_at(kb));
        // Clip the window to the source image at the point and to the destination image
        // over the candidates of the interval proper.
        let win = shape.clip(src.w, src.h, u, u, v, v, s_src).clip(
            dst.w,
            dst.h,
            k_lo as f64,
            k_hi as f64,
            va.min(vb),
            va.max(vb),
            s_dst,
        );
        if !win.usable(i64::from(self.params.half_window) + 1) {
            return None;
        }
        buf.clear();
        buf.resize(2 * win.len(), 0.0);
        let std = template(src, u, v, win, s_src, &self.weights, buf)?;
        if std < self.params.min_std {
            return Some(Search::none(match side {
                Side::Forward => MatchStatus::NoTexture,
                Side::Back => MatchStatus::LrCheckFailed,
            }));
        }
        let s = search_range(
            dst,
            buf,
            win,
            s_dst,
            k_lo,
            k_hi,
            only,
            &v_at,
            &self.params,
            check_unique,
        );
        // A peak found only thanks to the slack must still be near the interval.
        Some(s)
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

/// Fills `t` (`2 n` long for the `n` pixels of `win`) with the weighted template of `img`'s
/// window `win` around sub-pixel `(u, v)` (bilinear): `t[..n]` the coefficients
/// `a_i = w_i (I_i - m) / s`, `t[n..]` the weights `w_i` (summing to 1), with `m` and `s^2`
/// the weighted mean and variance, so that `sum a_i J_i` over a candidate window `J` is the
/// weighted covariance over `s`. Weights: [`MatchParams::support_gamma`]. Returns the
/// window's (unweighted) standard deviation, or `None` when the window (with its
/// interpolation support) leaves the image.
#[allow(clippy::too_many_arguments)]
fn template(
    img: &Plane,
    u: f64,
    v: f64,
    win: Win,
    scale: [f64; 2],
    lut: &[f32],
    t: &mut [f32],
) -> Option<f64> {
    let n = win.len();
    if scale != [1.0, 1.0] {
        let ww = win.width();
        for dy in 0..win.height() {
            let y = v + scale[1] * (win.y0 + dy as i64) as f64;
            for dx in 0..ww {
                let x = u + scale[0] * (win.x0 + dx as i64) as f64;
                t[dy * ww + dx] = bilinear(img, x, y)?;
            }
        }
        return Some(weigh(win, lut, t));
    }
    let (x0, y0) = (u.floor(), v.floor());
    let (fx, fy) = (u - x0, v - y0);
    let (xa, xb) = (x0 as i64 + win.x0, x0 as i64 + win.x1 + i64::from(fx > 0.0));
    let (ya, yb) = (y0 as i64 + win.y0, y0 as i64 + win.y1 + i64::from(fy > 0.0));
    if !(x0.is_finite()
        && y0.is_finite()
        && xa >= 0
        && ya >= 0
        && xb < img.w as i64
        && yb < img.h as i64)
    {
        return None;
    }
    let (fx, fy) = (fx as f32, fy as f32);
    let (xs, ys) = (xa as usize, ya as usize);
    let (ww, wh) = (win.width(), win.height());
    let (vals, _) = t.split_at_mut(n);
    let w = img.w;
    for dy in 0..wh {
        let row = (ys + dy) * w;
        let row2 = if fy > 0.0 { row + w } else { row };
        for dx in 0..ww {
            let x = xs + dx;
            let x2 = if fx > 0.0 { x + 1 } else { x };
            let a = img.px[row + x] + fx * (img.px[row + x2] - img.px[row + x]);
            let b = img.px[row2 + x] + fx * (img.px[row2 + x2] - img.px[row2 + x]);
            vals[dy * ww + dx] = a + fy * (b - a);
        }
    }
    Some(weigh(win, lut, t))
}

/// Turns the grey levels in `t[..n]` into the template of [`template`] (coefficients, then
/// weights in `t[n..]`) and returns their unweighted standard deviation.
fn weigh(win: Win, lut: &[f32], t: &mut [f32]) -> f64 {
    let n = win.len();
    let ww = win.width();
    let (vals, wts) = t.split_at_mut(n);
    let mean = vals.iter().map(|&x| f64::from(x)).sum::<f64>() / n as f64;
    let ss: f64 = vals.iter().map(|&x| (f64::from(x) - mean).powi(2)).sum();
    let std = (ss / n as f64).sqrt();
    // Weights.
    let centre = f64::from(vals[(-win.y0) as usize * ww + (-win.x0) as usize]);
    let mut wsum = 0.0f64;
    for (wt, &x) in wts.iter_mut().zip(vals.iter()) {
        let wv = if lut.is_empty() {
            1.0
        } else {
            let k = ((f64::from(x) - centre).abs() * WEIGHT_STEPS_PER_GREY).round() as usize;
            f64::from(lut[k.min(lut.len() - 1)])
        };
        *wt = wv as f32;
        wsum += wv;
    }
    let mut wmean = 0.0f64;
    for (wt, &x) in wts.iter_mut().zip(vals.iter()) {
        *wt = (f64::from(*wt) / wsum) as f32;
        wmean += f64::from(*wt) * f64::from(x);
    }
    let mut wvar = 0.0f64;
    for (&wt, x) in wts.iter().zip(vals.iter_mut()) {
        let dev = f64::from(*x) - wmean;
        wvar += f64::from(wt) * dev * dev;
        *x = (f64::from(wt) * dev) as f32;
    }
    if wvar > 0.0 {
        let k = (1.0 / wvar.sqrt()) as f32;
        vals.iter_mut().for_each(|x| *x *= k);
    }
    std
}

/// The running sums of a weighted ZNCC, in f32: template times window, and the weighted
/// window's sum and sum of squares.
#[derive(Clone, Copy, Default)]
struct Sums {
    st: f32,
    s1: f32,
    s2: f32,
}

impl Sums {
    /// Adds the window value `val` under template coefficient `coef` and weight `wt`.
    #[inline(always)]
    fn add(&mut self, coef: f32, wt: f32, val: f32) {
        self.st += coef * val;
        let wv = wt * val;
        self.s1 += wv;
        self.s2 += wv * val;
    }

    /// The ZNCC in `[-1, 1]`; 0 for a flat window.
    fn score(self) -> f64 {
        let var = f64::from(self.s2) - f64::from(self.s1) * f64::from(self.s1);
        if var <= 1e-4 {
            return 0.0;
        }
        (f64::from(self.st) / var.sqrt()).clamp(-1.0, 1.0)
    }
}

/// Weighted ZNCC of the template `t` ([`template`]: coefficients then weights, window `win`)
/// with the window of `img` around whole column `u` and sub-pixel row `v` (linear in `v`),
/// or `None` when the window leaves the image.
fn zncc_at(img: &Plane, t: &[f32], win: Win, scale: [f64; 2], u: i64, v: f64) -> Option<f64> {
    if !v.is_finite() {
        return None;
    }
    if scale != [1.0, 1.0] {
        return zncc_scaled(img, t, win, scale, u as f64, v);
    }
    let y0 = v.floor();
    let fy = (v - y0) as f32;
    let y0i = y0 as i64;
    let (xa, xb) = (u + win.x0, u + win.x1);
    let (ya, yb) = (y0i + win.y0, y0i + win.y1 + i64::from(fy > 0.0));
    if xa < 0 || xb >= img.w as i64 || ya < 0 || yb >= img.h as i64 {
        return None;
    }
    let (ww, wh) = (win.width(), win.height());
    let n = win.len();
    let (coef, wts) = t.split_at(n);
    let (xs, ys) = (xa as usize, ya as usize);
    let wu = img.w;
    let mut sums = Sums::default();
    for dy in 0..wh {
        let row = (ys + dy) * wu + xs;
        let a = &img.px[row..row + ww];
        let tr = &coef[dy * ww..(dy + 1) * ww];
        let wr = &wts[dy * ww..(dy + 1) * ww];
        if fy > 0.0 {
            let b = &img.px[row + wu..row + wu + ww];
            for k in 0..ww {
                sums.add(tr[k], wr[k], a[k] + fy * (b[k] - a[k]));
            }
        } else {
            for k in 0..ww {
                sums.add(tr[k], wr[k], a[k]);
            }
        }
    }
    Some(sums.score())
}

/// [`zncc_at`] with window offset `(dx, dy)` at `(u + scale[0] dx, v + scale[1] dy)`,
/// bilinear.
fn zncc_scaled(img: &Plane, t: &[f32], win: Win, scale: [f64; 2], u: f64, v: f64) -> Option<f64> {
    let n = win.len();
    let (coef, wts) = t.split_at(n);
    let ww = win.width();
    let mut sums = Sums::default();
    for dy in 0..win.height() {
        let y = v + scale[1] * (win.y0 + dy as i64) as f64;
        for dx in 0..ww {
            let x = u + scale[0] * (win.x0 + dx as i64) as f64;
            let val = bilinear(img, x, y)?;
            let k = dy * ww + dx;
            sums.add(coef[k], wts[k], val);
        }
    }
    Some(sums.score())
}

/// Scores the whole `u` from `k_lo - 1` to `k_hi + 1` along the line `v_at` and applies the
/// decisions 4-6 of the module documentation to the peak in `k_lo..=k_hi`
/// (`check_unique`: whether step 5 applies).
#[allow(clippy::too_many_arguments)]
fn search_range(
    img: &Plane,
    t: &[f32],
    win: Win,
    scale: [f64; 2],
    k_lo: i64,
    k_hi: i64,
    only: Option<&[i64]>,
    v_at: &dyn Fn(f64) -> f64,
    p: &MatchParams,
    check_unique: bool,
) -> Search {
    // Scores at k_lo - 1 ..= k_hi + 1 (index 0 is the extra one on the left).
    let len = (k_hi - k_lo + 3) as usize;
    let mut s = [f64::NAN; 64];
    let mut heap;
    let scores: &mut [f64] = if len <= s.len() {
        &mut s[..len]
    } else {
        heap = vec![f64::NAN; len];
        &mut heap
    };
    let mut any = false;
    for (idx, sc) in scores.iter_mut().enumerate() {
        let u = k_lo - 1 + idx as i64;
        if only.is_some_and(|o| !o.iter().any(|&c| (c - u).abs() <= 1)) {
            continue;
        }
        if let Some(zn) = zncc_at(img, t, win, scale, u, v_at(u as f64)) {
            *sc = zn;
            if idx >= 1 && idx + 1 < len {
                any = true;
            }
        }
    }
    if !any {
        return Search::none(MatchStatus::Outside);
    }
    // Best in the interval proper (indices 1..len-1).
    let mut best = 1;
    for idx in 1..len - 1 {
        if scores[idx] > scores[best] || scores[best].is_nan() {
            best = idx;
        }
    }
    let sb = scores[best];
    let u_best = (k_lo - 1 + best as i64) as f64;
    let (sl, sr) = (scores[best - 1], scores[best + 1]);
    let mut out = Search {
        score: sb,
        u: u_best,
        v: v_at(u_best),
        status: MatchStatus::Ok,
        peaks: Vec::new(),
    };
    // A peak needs both neighbours, no higher than it.
    // NaN compares false: a missing neighbour (window off the image) is no peak.
    let is_peak = sb >= p.min_score && sl <= sb && sr <= sb;
    if !is_peak {
        out.status = MatchStatus::NoCandidate;
        return out;
    }
    if check_unique {
        // Peaks are compared by their score at the parabola's sub-pixel top (sampled there,
        // bilinear), not by the whole-pixel sample: a sharp peak half a pixel off the grid
        // samples low and would lose to a repeat that happens to fall on the grid.
        let refined = |idx: usize| -> f64 {
            let (l, c, r) = (scores[idx - 1], scores[idx], scores[idx + 1]);
            let den = l - 2.0 * c + r;
            let off = if den < 0.0 && l.is_finite() && r.is_finite() {
                (0.5 * (l - r) / den).clamp(-0.5, 0.5)
            } else if r > c {
                0.5
            } else if l > c {
                -0.5
            } else {
                0.0
            };
            if off == 0.0 {
                return c;
            }
            let u = (k_lo - 1 + idx as i64) as f64 + off;
            zncc_scaled(img, t, win, scale, u, v_at(u)).map_or(c, |z| z.max(c))
        };
        let sb_top = refined(best);
        let sep = p.min_peak_separation_px;
        for idx in 1..len - 1 {
            if idx == best || ((idx as f64) - (best as f64)).abs() < sep {
                continue;
            }
            let z = scores[idx];
            // Not worth a closer look: far below the best even at its top.
            if !z.is_finite() || z < sb - p.uniqueness_margin - 0.15 {
                continue;
            }
            // A neighbour off the image (NaN) does not stop a peak here.
            let left_ok = scores[idx - 1].partial_cmp(&z) != Some(core::cmp::Ordering::Greater);
            let right_ok = scores[idx + 1].partial_cmp(&z) != Some(core::cmp::Ordering::Greater);
            // At an end of the interval, scores still rising outwards: a peak just beyond
            // the end competes too (the interval's ends are not sharp).
            let outer = if idx == 1 {
                scores[0]
            } else if idx == len - 2 {
                scores[len - 1]
            } else {
                f64::NAN
            };
            let rising_out = outer > z;
            if !(rising_out || left_ok && right_ok) {
                continue;
            }
            let mut z_top = refined(idx);
            if rising_out {
                z_top = z_top.max(outer);
            }
            if z_top > sb_top - p.uniqueness_margin {
                out.status = MatchStatus::Ambiguous;
                out.peaks.push(k_lo - 1 + idx as i64);
            }
        }
        if out.status == MatchStatus::Ambiguous {
            out.peaks.push(k_lo - 1 + best as i64);
            return out;
        }
    }
    // Parabola through the three scores.
    let den = sl - 2.0 * sb + sr;
    let off = if den < 0.0 {
        (0.5 * (sl - sr) / den).clamp(-0.5, 0.5)
    } else {
        0.0
    };
    out.u = u_best + off;
    out.v = v_at(out.u);
    out
}

/// Steps of the disparity scan of [`model_disparity_interval`] (px).
pub const MODEL_SCAN_STEP_PX: f64 = 0.25;

/// Share of the training depth span allowed beyond either end by
/// [`model_disparity_interval`].
pub const MODEL_Z_MARGIN: f64 = 0.05;

/// The disparity interval a trained model allows for left pixel `(ul, vl)`: the candidate
/// right points on the epipolar line `line` (`a u + b v + c = 0` in the right image, e.g.
/// [`Fundamental::line_in_right`]) at every disparity `d = ul - u_r` of `d_range` (the
/// training set's whole disparity range, px), [`MODEL_SCAN_STEP_PX`] apart, are fed to
/// `predict` (`[u_l, v_l, u_r, v_r]` to `[X, Y, Z]` cm, `None` when the model has no answer);
/// those whose `Z` lies inside the training depths `z_range` (cm), widened by
/// [`MODEL_Z_MARGIN`] of its span on each side, are kept. Returns the smallest and largest
/// kept disparity, each widened by one scan step and clipped to `d_range`, or `None` when
/// none is kept, an input is not finite or out of order, or the line is steeper than
/// 45 degrees (no `v` per `u`). The model is a closure so that this crate need not know the
/// model's format: the CLI passes `|x| blob.infer(&x)`.
pub fn model_disparity_interval(
    predict: impl Fn([f32; 4]) -> Option<[f32; 3]>,
    ul: f64,
    vl: f64,
    line: [f64; 3],
    z_range: [f64; 2],
    d_range: [f64; 2],
) -> Option<(f64, f64)> {
    let [a, b, c] = line;
    let finite = [
        ul, vl, a, b, c, z_range[0], z_range[1], d_range[0], d_range[1],
    ]
    .iter()
    .all(|x| x.is_finite());
    if !finite || z_range[0] > z_range[1] || d_range[0] > d_range[1] || b.abs() < a.abs() {
        return None;
    }
    // At most 100 000 model calls per point.
    let n = ((d_range[1] - d_range[0]) / MODEL_SCAN_STEP_PX).ceil();
    if n > 100_000.0 {
        return None;
    }
    let n = n as usize;
    let margin = MODEL_Z_MARGIN * (z_range[1] - z_range[0]);
    let (z_lo, z_hi) = (z_range[0] - margin, z_range[1] + margin);
    let mut kept: Option<(f64, f64)> = None;
    for k in 0..=n {
        let d = (d_range[0] + k as f64 * MODEL_SCAN_STEP_PX).min(d_range[1]);
        let ur = ul - d;
        let vr = -(a * ur + c) / b;
        let Some(xyz) = predict([ul as f32, vl as f32, ur as f32, vr as f32]) else {
            continue;
        };
        let z = f64::from(xyz[2]);
        if z >= z_lo && z <= z_hi {
            kept = Some(match kept {
                None => (d, d),
                Some((lo, hi)) => (lo.min(d), hi.max(d)),
            });
        }
    }
    kept.map(|(lo, hi)| {
        (
            (lo - MODEL_SCAN_STEP_PX).max(d_range[0]),
            (hi + MODEL_SCAN_STEP_PX).min(d_range[1]),
        )
    })
}

/// The right window's scale for two pinhole cameras: `[phi_u_right / phi_u_left,
/// phi_v_right / phi_v_left]` (for [`MatchParams::right_scale`]; exact for a fronto-parallel
/// patch with parallel axes, close enough with the thesis' small deflections).
pub fn pinhole_right_scale(left: &Camera, right: &Camera) -> [f64; 2] {
    [right.phi_u / left.phi_u, right.phi_v / left.phi_v]
}

/// The fundamental matrix of two pinhole cameras (no lens): `r~^T F l~ = 0`, unit Frobenius
/// norm. For a thesis rig at home: `pinhole_fundamental(&rig.left(), &rig.right())`.
pub fn pinhole_fundamental(left: &Camera, right: &Camera) -> Fundamental {
    // Right-camera coordinates of a left ray point: R (x - c_r) with x = c_l + R_l^T y.
    let rl = left.rotation;
    let rr = right.rotation;
    // R = R_r R_l^T, t = R_r (c_l - c_r).
    let mut rot = [[0.0; 3]; 3];
    for (i, row) in rot.iter_mut().enumerate() {
        for (j, x) in row.iter_mut().enumerate() {
            *x = (0..3).map(|k| rr[i][k] * rl[j][k]).sum();
        }
    }
    let dc = [
        left.center[0] - right.center[0],
        left.center[1] - right.center[1],
        left.center[2] - right.center[2],
    ];
    let t: [f64; 3] = core::array::from_fn(|i| (0..3).map(|k| rr[i][k] * dc[k]).sum());
    let tx = [[0.0, -t[2], t[1]], [t[2], 0.0, -t[0]], [-t[1], t[0], 0.0]];
    let mut e = [[0.0; 3]; 3];
    for (i, row) in e.iter_mut().enumerate() {
        for (j, x) in row.iter_mut().enumerate() {
            *x = (0..3).map(|k| tx[i][k] * rot[k][j]).sum();
        }
    }
    // K^-1 = [[1/fu, 0, -u0/fu], [0, 1/fv, -v0/fv], [0, 0, 1]].
    let kinv = |c: &Camera| {
        [
            [1.0 / c.phi_u, 0.0, -c.u0 / c.phi_u],
            [0.0, 1.0 / c.phi_v, -c.v0 / c.phi_v],
            [0.0, 0.0, 1.0],
        ]
    };
    let (kl, kr) = (kinv(left), kinv(right));
    // F = Kr^-T E Kl^-1.
    let mut tmp = [[0.0; 3]; 3];
    for (i, row) in tmp.iter_mut().enumerate() {
        for (j, x) in row.iter_mut().enumerate() {
            *x = (0..3).map(|k| e[i][k] * kl[k][j]).sum();
        }
    }
    let mut f = [[0.0; 3]; 3];
    for (i, row) in f.iter_mut().enumerate() {
        for (j, x) in row.iter_mut().enumerate() {
            *x = (0..3).map(|k| kr[k][i] * tmp[k][j]).sum();
        }
    }
    let norm = f.iter().flatten().map(|x| x * x).sum::<f64>().sqrt();
    if norm > 0.0 {
        f.iter_mut().flatten().for_each(|x| *x /= norm);
    }
    Fundamental { m: f }
}

#[cfg(test)]
mod tests {
    use super::*;
    use hvs_shared::sim::presets;

    #[test]
    fn pinhole_fundamental_holds_for_projected_points() {
        for n in 1..=4 {
            let rig = presets::case(n).unwrap();
            let f = pinhole_fundamental(&rig.left(), &rig.right());
            for p in [[-20.0, -10.0, 65.0], [15.0, 12.0, 165.0], [0.0, 0.0, 100.0]] {
                let px = rig.project(&p).unwrap();
                let d = f.distance_in_right([px[0], px[1]], [px[2], px[3]]);
                assert!(d < 1e-9, "case {n}: {d}");
            }
        }
    }

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
        assert!(
            (lo - 9.5).abs() < 0.26 && (hi - 21.25).abs() < 0.26,
            "{lo} {hi}"
        );
        // Nothing inside: None; bad input: None.
        assert!(
            model_disparity_interval(model, 300.0, 50.0, row, [500.0, 600.0], [0.0, 1.0]).is_none()
        );
        assert!(
            model_disparity_interval(model, f64::NAN, 50.0, row, [50.0, 100.0], [0.0, 80.0])
                .is_none()
        );
        assert!(model_disparity_interval(
            model,
            300.0,
            50.0,
            [1.0, 0.0, -5.0],
            [50.0, 100.0],
            [0.0, 80.0]
        )
        .is_none());
        assert!(
            model_disparity_interval(|_| None, 300.0, 50.0, row, [50.0, 100.0], [0.0, 80.0])
                .is_none()
        );
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
            let std = template(
                &p,
                20.3,
                14.6,
                w,
                [1.0, 1.0],
                &weight_lut(gamma, 0.2),
                &mut t,
            )
            .unwrap();
            assert!(std > 1.0);
            let (a, wt) = t.split_at(49);
            let s: f32 = a.iter().sum();
            let ws: f32 = wt.iter().sum();
            let ss: f32 = a.iter().zip(wt).map(|(x, w)| x * x / w).sum();
            assert!(s.abs() < 1e-4 && (ws - 1.0).abs() < 1e-4 && (ss - 1.0).abs() < 1e-3);
            // The same window correlates with itself at 1, and not with its neighbour.
            template(
                &p,
                20.0,
                14.0,
                w,
                [1.0, 1.0],
                &weight_lut(gamma, 0.2),
                &mut t,
            )
            .unwrap();
            let z = zncc_at(&p, &t, w, [1.0, 1.0], 20, 14.0).unwrap();
            assert!((z - 1.0).abs() < 1e-4, "{z}");
            let z = zncc_at(&p, &t, w, [1.0, 1.0], 21, 14.0).unwrap();
            assert!(z < 0.999, "{z}");
        }
        assert!(template(&p, 2.5, 14.0, w, [1.0, 1.0], &[], &mut t).is_none());
        assert!(template(&p, 3.0, 3.0, w, [1.0, 1.0], &[], &mut t).is_some());
        assert!(template(&p, 36.0, 26.0, w, [1.0, 1.0], &[], &mut t).is_some());
        assert!(template(&p, 36.5, 26.0, w, [1.0, 1.0], &[], &mut t).is_none());
        // Clipped at the border: the part that fits.
        let c = w.clip(40, 30, 1.5, 1.5, 28.0, 28.0, [1.0, 1.0]);
        assert_eq!(
            c,
            Win {
                x0: -1,
                x1: 3,
                y0: -3,
                y1: 1
            }
        );
        assert!(template(&p, 1.5, 28.0, c, [1.0, 1.0], &[], &mut t[..2 * c.len()]).is_some());
    }
}
