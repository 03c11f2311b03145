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
//! Ambiguous, textureless and outside points are never retried.
//!
//! # Parameters (how the defaults were chosen)
//!
//! See [`MatchParams::default`]: chosen on rendered boards with development seeds (never the
//! test seeds) and on the Motorcycle pair's development seeds.

use crate::geometry::Fundamental;
use hvs_shared::camera::Camera;
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
    /// On the Motorcycle development seeds 1-4 (4000 points, interval true disparity
    /// +- 10 %) this took the points returned within 1 px from 77.5 % (the previous
    /// defaults) to 83.4 % with 1.3 % returned 2 px or more off. Chosen on development seeds
    /// only (rendered boards seeds 1-4, Motorcycle point seeds 1-4; tests use other seeds).
    fn default() -> Self {
        MatchParams {
            half_window: 5,
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

/// Why a matcher could not be built or a batch not run.
#[derive(Debug, Clone, PartialEq)]
pub enum MatchError {
    /// A parameter or input is out of range; names it.
    Invalid {
        /// The parameter (e.g. `params.half_window`).
        field: &'static str,
        /// What is wrong with it.
        reason: String,
    },
}

impl fmt::Display for MatchError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            MatchError::Invalid { field, reason } => write!(f, "{field}: {reason}"),
        }
    }
}

impl std::error::Error for MatchError {}

fn invalid(field: &'static str, reason: impl Into<String>) -> MatchError {
    MatchError::Invalid {
        field,
        reason: reason.into(),
    }
}

impl MatchParams {
    /// Checks the parameters (field names in the error).
    pub fn validate(&self) -> Result<(), MatchError> {
        if !(1..=30).contains(&self.half_window) {
            return Err(invalid(
                "params.half_window",
                format!("must be 1..=30, got {}", self.half_window),
            ));
        }
        let checks: [(&'static str, f64, f64, f64); 10] = [
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
                return Err(invalid(field, format!("must be in {lo}..={hi}, got {v}")));
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
    /// around every centre with `u` in `[u_lo, u_hi]` and `v` in `[v_lo, v_hi]` (centres
    /// clamped to the image first: candidates off the image are dropped, not the window).
    #[allow(clippy::too_many_arguments)]
    fn clip(&self, w: usize, h: usize, u_lo: f64, u_hi: f64, v_lo: f64, v_hi: f64) -> Win {
        let (wm, hm) = ((w - 1) as f64, (h - 1) as f64);
        let (u_lo, u_hi) = (u_lo.clamp(0.0, wm), u_hi.clamp(0.0, wm));
        let (v_lo, v_hi) = (v_lo.clamp(0.0, hm), v_hi.clamp(0.0, hm));
        Win {
            x0: self.x0.max(-(u_lo.floor() as i64)),
            x1: self.x1.min((w - 1) as i64 - u_hi.ceil() as i64),
            y0: self.y0.max(-(v_lo.floor() as i64)),
            y1: self.y1.min((h - 1) as i64 - v_hi.ceil() as i64),
        }
    }
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
}

impl Search {
    fn none(status: MatchStatus) -> Search {
        Search {
            score: f64::NAN,
            u: f64::NAN,
            v: f64::NAN,
            status,
        }
    }
}

/// A stereo pair prepared for matching: both images as `f32`, the fundamental matrix and
/// the parameters.
pub struct Matcher {
    left: Plane,
    right: Plane,
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
            return Err(invalid(
                "right",
                format!(
                    "image is {:?}, the left one {:?}: both must be the same size",
                    right.dimensions(),
                    left.dimensions()
                ),
            ));
        }
        if left.width() == 0 || left.height() == 0 {
            return Err(invalid("left", "image is empty"));
        }
        if !f.m.iter().flatten().all(|x| x.is_finite()) || f.m.iter().flatten().all(|&x| x == 0.0) {
            return Err(invalid("fundamental", "must be finite and not all zero"));
        }
        Ok(Matcher {
            left: Plane::new(left),
            right: Plane::new(right),
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
        let first = self.find_window(q, Win::shifted(r, 0, 0), buf);
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
            tried[k + 1] = self.find_window(q, Win::shifted(r, sx * step, sy * step), buf);
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
    fn find_window(&self, q: &Query, shape: Win, buf: &mut Vec<f32>) -> Match {
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
            true,
            buf,
        ) else {
            return Match::fail(MatchStatus::Outside);
        };
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
        let b = self.search_from(
            Side::Back,
            s.u,
            s.v,
            shape,
            back_line,
            s.u + q.d_min - slack,
            s.u + q.d_max + slack,
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
        check_unique: bool,
        buf: &mut Vec<f32>,
    ) -> Option<Search> {
        let (src, dst) = match side {
            Side::Forward => (&self.left, &self.right),
            Side::Back => (&self.right, &self.left),
        };
        let [a, b, c] = line;
        if !(a.is_finite() && b.is_finite() && c.is_finite()) || b.abs() < a.abs() {
            return Some(Search::none(MatchStatus::NoCandidate));
        }
        let v_at = |u: f64| -(a * u + c) / b;
        let (mut k_lo, mut k_hi) = (u_lo.ceil() as i64, u_hi.floor() as i64);
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
        let win = shape.clip(src.w, src.h, u, u, v, v).clip(
            dst.w,
            dst.h,
            k_lo as f64,
            k_hi as f64,
            va.min(vb),
            va.max(vb),
        );
        if !win.usable(i64::from(self.params.half_window) + 1) {
            return None;
        }
        buf.clear();
        buf.resize(2 * win.len(), 0.0);
        let std = template(
            src,
            u,
            v,
            win,
            (self.params.support_gamma, self.params.support_floor),
            buf,
        )?;
        if std < self.params.min_std {
            return Some(Search::none(match side {
                Side::Forward => MatchStatus::NoTexture,
                Side::Back => MatchStatus::LrCheckFailed,
            }));
        }
        let s = search_range(dst, buf, win, k_lo, k_hi, &v_at, &self.params, check_unique);
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
fn template(
    img: &Plane,
    u: f64,
    v: f64,
    win: Win,
    (gamma, floor): (f64, f64),
    t: &mut [f32],
) -> Option<f64> {
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
    let n = win.len();
    let (vals, wts) = t.split_at_mut(n);
    let w = img.w;
    let mut sum = 0.0f64;
    for dy in 0..wh {
        let row = (ys + dy) * w;
        let row2 = if fy > 0.0 { row + w } else { row };
        for dx in 0..ww {
            let x = xs + dx;
            let x2 = if fx > 0.0 { x + 1 } else { x };
            let a = img.px[row + x] + fx * (img.px[row + x2] - img.px[row + x]);
            let b = img.px[row2 + x] + fx * (img.px[row2 + x2] - img.px[row2 + x]);
            let val = a + fy * (b - a);
            vals[dy * ww + dx] = val;
            sum += f64::from(val);
        }
    }
    let mean = sum / n as f64;
    let ss: f64 = vals.iter().map(|&x| (f64::from(x) - mean).powi(2)).sum();
    let std = (ss / n as f64).sqrt();
    // Weights.
    let centre = f64::from(vals[(-win.y0) as usize * ww + (-win.x0) as usize]);
    let mut wsum = 0.0f64;
    for (wt, &x) in wts.iter_mut().zip(vals.iter()) {
        let wv = if gamma > 0.0 {
            floor + (1.0 - floor) * (-(f64::from(x) - centre).abs() / gamma).exp()
        } else {
            1.0
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
    Some(std)
}

/// Weighted ZNCC of the template `t` ([`template`]: coefficients then weights, window `win`)
/// with the window of `img` around whole column `u` and sub-pixel row `v` (linear in `v`),
/// or `None` when the window leaves the image.
fn zncc_at(img: &Plane, t: &[f32], win: Win, u: i64, v: f64) -> Option<f64> {
    if !v.is_finite() {
        return None;
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
    let (mut st, mut s1, mut s2) = (0.0f32, 0.0f32, 0.0f32);
    for dy in 0..wh {
        let row = (ys + dy) * wu + xs;
        let a = &img.px[row..row + ww];
        let tr = &coef[dy * ww..(dy + 1) * ww];
        let wr = &wts[dy * ww..(dy + 1) * ww];
        if fy > 0.0 {
            let b = &img.px[row + wu..row + wu + ww];
            for k in 0..ww {
                let val = a[k] + fy * (b[k] - a[k]);
                st += tr[k] * val;
                let wv = wr[k] * val;
                s1 += wv;
                s2 += wv * val;
            }
        } else {
            for k in 0..ww {
                let val = a[k];
                st += tr[k] * val;
                let wv = wr[k] * val;
                s1 += wv;
                s2 += wv * val;
            }
        }
    }
    let var = f64::from(s2) - f64::from(s1) * f64::from(s1);
    if var <= 1e-4 {
        return Some(0.0);
    }
    Some((f64::from(st) / var.sqrt()).clamp(-1.0, 1.0))
}

/// Scores the whole `u` from `k_lo - 1` to `k_hi + 1` along the line `v_at` and applies the
/// decisions 4-6 of the module documentation to the peak in `k_lo..=k_hi`
/// (`check_unique`: whether step 5 applies).
#[allow(clippy::too_many_arguments)]
fn search_range(
    img: &Plane,
    t: &[f32],
    win: Win,
    k_lo: i64,
    k_hi: i64,
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
        if let Some(z) = zncc_at(img, t, win, u, v_at(u as f64)) {
            *sc = z;
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
    };
    // A peak needs both neighbours, no higher than it.
    // NaN compares false: a missing neighbour (window off the image) is no peak.
    let is_peak = sb >= p.min_score && sl <= sb && sr <= sb;
    if !is_peak {
        out.status = MatchStatus::NoCandidate;
        return out;
    }
    if check_unique {
        let sep = p.min_peak_separation_px;
        for idx in 1..len - 1 {
            if idx == best || ((idx as f64) - (best as f64)).abs() < sep {
                continue;
            }
            let z = scores[idx];
            // A neighbour off the image (NaN) does not stop a peak here.
            let left_ok = scores[idx - 1].partial_cmp(&z) != Some(core::cmp::Ordering::Greater);
            let right_ok = scores[idx + 1].partial_cmp(&z) != Some(core::cmp::Ordering::Greater);
            if z.is_finite() && left_ok && right_ok && z > sb - p.uniqueness_margin {
                out.status = MatchStatus::Ambiguous;
                return out;
            }
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
    use hvs_shared::presets;

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
    fn bad_params_name_the_field() {
        let p = MatchParams {
            half_window: 0,
            ..MatchParams::default()
        };
        assert!(p
            .validate()
            .unwrap_err()
            .to_string()
            .starts_with("params.half_window"));
        let p = MatchParams {
            min_score: f64::NAN,
            ..MatchParams::default()
        };
        assert!(p
            .validate()
            .unwrap_err()
            .to_string()
            .starts_with("params.min_score"));
    }

    #[test]
    fn template_is_zero_mean_unit_norm() {
        let img = GrayImage::from_fn(40, 30, |x, y| image::Luma([((x * 7 + y * 13) % 97) as u8]));
        let p = Plane::new(&img);
        let mut t = vec![0.0f32; 98];
        let w = Win::shifted(3, 0, 0);
        for gamma in [0.0, 10.0] {
            let std = template(&p, 20.3, 14.6, w, (gamma, 0.2), &mut t).unwrap();
            assert!(std > 1.0);
            let (a, wt) = t.split_at(49);
            let s: f32 = a.iter().sum();
            let ws: f32 = wt.iter().sum();
            let ss: f32 = a.iter().zip(wt).map(|(x, w)| x * x / w).sum();
            assert!(s.abs() < 1e-4 && (ws - 1.0).abs() < 1e-4 && (ss - 1.0).abs() < 1e-3);
            // The same window correlates with itself at 1, and not with its neighbour.
            template(&p, 20.0, 14.0, w, (gamma, 0.2), &mut t).unwrap();
            let z = zncc_at(&p, &t, w, 20, 14.0).unwrap();
            assert!((z - 1.0).abs() < 1e-4, "{z}");
            let z = zncc_at(&p, &t, w, 21, 14.0).unwrap();
            assert!(z < 0.999, "{z}");
        }
        assert!(template(&p, 2.5, 14.0, w, (0.0, 0.0), &mut t).is_none());
        assert!(template(&p, 3.0, 3.0, w, (0.0, 0.0), &mut t).is_some());
        assert!(template(&p, 36.0, 26.0, w, (0.0, 0.0), &mut t).is_some());
        assert!(template(&p, 36.5, 26.0, w, (0.0, 0.0), &mut t).is_none());
        // Clipped at the border: the part that fits.
        let c = w.clip(40, 30, 1.5, 1.5, 28.0, 28.0);
        assert_eq!(
            c,
            Win {
                x0: -1,
                x1: 3,
                y0: -3,
                y1: 1
            }
        );
        assert!(template(&p, 1.5, 28.0, c, (0.0, 0.0), &mut t[..2 * c.len()]).is_some());
    }
}
