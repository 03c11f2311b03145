//! One point of the left image found in the right one: zero-mean normalised cross-correlation
//! (ZNCC) along the epipolar line, inside a disparity interval.
//!
//! # What is searched
//!
//! For a left pixel `(u_l, v_l)` (sub-pixel allowed; pixel-centre convention of
//! [`crate::render`]: integer coordinates at pixel centres) and a disparity interval
//! `[d_min, d_max]` with `d = u_l - u_r`, the candidates are the right-image points on the
//! epipolar line `F (u_l, v_l, 1)^T` ([`Fundamental::line_in_right`]) at every whole `u_r` in
//! `[u_l - d_max, u_l - d_min]`, one pixel apart, plus one more on each side (for the peak
//! test and the sub-pixel fit only). The left window (`(2r + 1)^2` pixels, bilinear at the
//! sub-pixel point) is compared with each candidate's window (vertically interpolated at the
//! line's `v`) by ZNCC; the template's mean and norm are computed once per point, each
//! candidate's sum and sum of squares in the same pass as the cross term.
//!
//! # Decisions, in order (the first that applies is the [`MatchStatus`])
//!
//! 1. Non-finite point or interval: [`MatchStatus::NanInput`].
//! 2. The left window leaves the left image, or no candidate window lies inside the right
//!    image: [`MatchStatus::Outside`].
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
//! # Parameters (how the defaults were chosen)
//!
//! See [`MatchParams::default`]: chosen on rendered boards with development seeds (never the
//! test seeds) and on the matching notes in the project's shared notes.

use crate::geometry::Fundamental;
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
}

impl Default for MatchParams {
    /// `r = 5` (11 x 11 windows: on the development Motorcycle pair 77 % of points come back
    /// within 1 px against 73 % with 15 x 15 and 69 % with 19 x 19, and it still spans a full
    /// period of the 10 px squares at 165 cm), `min_std = 1` grey level (only truly flat
    /// windows are refused as such: `min_score` and the left-right check refuse windows of
    /// noise; `min_std = 4` cost 16 points of returns on the real pair and gained no
    /// accuracy), `min_score = 0.6` (between 0.5 and 0.7, which differed by 1.5 % returns),
    /// `uniqueness_margin = 0.05`, peaks 2 px apart are distinct, left-right tolerance 1 px,
    /// intervals up to 256 px. Chosen on development seeds only (rendered boards seeds 1-4,
    /// Motorcycle point seeds 1-2; tests use other seeds).
    fn default() -> Self {
        MatchParams {
            half_window: 5,
            min_std: 1.0,
            min_score: 0.6,
            uniqueness_margin: 0.05,
            min_peak_separation_px: 2.0,
            lr_tolerance_px: 1.0,
            max_interval_px: 256.0,
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
        let checks: [(&'static str, f64, f64, f64); 6] = [
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

/// A stereo pair prepared for matching: both images as `f32`, the fundamental matrix and
/// the parameters.
pub struct Matcher {
    left: Plane,
    right: Plane,
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
        let r = self.params.half_window as usize;
        let n = (2 * r + 1) * (2 * r + 1);
        buf.clear();
        buf.resize(n, 0.0);
        match template(&self.left, q.ul, q.vl, r, buf) {
            None => return Match::fail(MatchStatus::Outside),
            Some(std) if std < self.params.min_std => return Match::fail(MatchStatus::NoTexture),
            Some(_) => {}
        }
        let line = self.f.line_in_right([q.ul, q.vl]);
        let s = search(
            &self.right,
            buf,
            r,
            line,
            q.ul - q.d_max,
            q.ul - q.d_min,
            &self.params,
            true,
        );
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
        match template(&self.right, s.u, s.v, r, buf) {
            None => {
                return Match {
                    status: MatchStatus::LrCheckFailed,
                    ..out
                }
            }
            Some(std) if std < self.params.min_std => {
                return Match {
                    status: MatchStatus::LrCheckFailed,
                    ..out
                }
            }
            Some(_) => {}
        }
        let back_line = self.f.line_in_left([s.u, s.v]);
        let b = search(
            &self.left,
            buf,
            r,
            back_line,
            s.u + q.d_min,
            s.u + q.d_max,
            &self.params,
            false,
        );
        let dist = ((b.u - q.ul).powi(2) + (b.v - q.vl).powi(2)).sqrt();
        // `dist` is NaN when the back search found nothing: that fails too.
        let back_ok = dist <= self.params.lr_tolerance_px;
        if b.status != MatchStatus::Ok || !back_ok {
            return Match {
                status: MatchStatus::LrCheckFailed,
                ..out
            };
        }
        out
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

/// Fills `t` with the zero-mean, unit-norm window of `img` centred at sub-pixel `(u, v)`
/// (bilinear) and returns the window's standard deviation (grey levels), or `None` when the
/// window (with its interpolation support) leaves the image.
fn template(img: &Plane, u: f64, v: f64, r: usize, t: &mut [f32]) -> Option<f64> {
    let (x0, y0) = (u.floor(), v.floor());
    let (fx, fy) = (u - x0, v - y0);
    let rf = r as f64;
    // Columns x0 - r ..= x0 + r (+ 1 with a fraction), rows likewise, inside the image.
    let x_last = x0 + rf + if fx > 0.0 { 1.0 } else { 0.0 };
    let y_last = y0 + rf + if fy > 0.0 { 1.0 } else { 0.0 };
    if !(x0 - rf >= 0.0
        && y0 - rf >= 0.0
        && x_last <= (img.w - 1) as f64
        && y_last <= (img.h - 1) as f64)
    {
        return None;
    }
    let (fx, fy) = (fx as f32, fy as f32);
    let (xs, ys) = (x0 as usize - r, y0 as usize - r);
    let side = 2 * r + 1;
    let w = img.w;
    let mut sum = 0.0f64;
    for dy in 0..side {
        let row = (ys + dy) * w;
        let row2 = if fy > 0.0 { row + w } else { row };
        for dx in 0..side {
            let x = xs + dx;
            let x2 = if fx > 0.0 { x + 1 } else { x };
            let a = img.px[row + x] + fx * (img.px[row + x2] - img.px[row + x]);
            let b = img.px[row2 + x] + fx * (img.px[row2 + x2] - img.px[row2 + x]);
            let val = a + fy * (b - a);
            t[dy * side + dx] = val;
            sum += f64::from(val);
        }
    }
    let n = (side * side) as f64;
    let mean = (sum / n) as f32;
    let mut ss = 0.0f64;
    for x in t.iter_mut() {
        *x -= mean;
        ss += f64::from(*x) * f64::from(*x);
    }
    let std = (ss / n).sqrt();
    if ss > 0.0 {
        let k = (1.0 / ss.sqrt()) as f32;
        t.iter_mut().for_each(|x| *x *= k);
    }
    Some(std)
}

/// ZNCC of the normalised template `t` with the window of `img` centred at whole column `u`
/// and sub-pixel row `v` (linear in `v`), or `None` when the window leaves the image.
fn zncc_at(img: &Plane, t: &[f32], r: usize, u: i64, v: f64) -> Option<f64> {
    let y0 = v.floor();
    let fy = (v - y0) as f32;
    let (w, h) = (img.w as i64, img.h as i64);
    let ri = r as i64;
    let y0i = y0 as i64;
    let y_last = if fy > 0.0 { y0i + ri + 1 } else { y0i + ri };
    if !y0.is_finite() || u - ri < 0 || u + ri >= w || y0i - ri < 0 || y_last >= h {
        return None;
    }
    let side = 2 * r + 1;
    let (xs, ys) = ((u - ri) as usize, (y0i - ri) as usize);
    let wu = img.w;
    let (mut st, mut s1, mut s2) = (0.0f32, 0.0f32, 0.0f32);
    for dy in 0..side {
        let row = (ys + dy) * wu + xs;
        let a = &img.px[row..row + side];
        let tr = &t[dy * side..(dy + 1) * side];
        if fy > 0.0 {
            let b = &img.px[row + wu..row + wu + side];
            for k in 0..side {
                let val = a[k] + fy * (b[k] - a[k]);
                st += tr[k] * val;
                s1 += val;
                s2 += val * val;
            }
        } else {
            for k in 0..side {
                let val = a[k];
                st += tr[k] * val;
                s1 += val;
                s2 += val * val;
            }
        }
    }
    let n = (side * side) as f32;
    let var = f64::from(s2) - f64::from(s1) * f64::from(s1) / f64::from(n);
    if var <= 1e-6 {
        return Some(0.0);
    }
    Some((f64::from(st) / var.sqrt()).clamp(-1.0, 1.0))
}

/// Searches `img` along `line` (`a u + b v + c = 0`) at whole `u` from `ceil(u_lo)` to
/// `floor(u_hi)` (plus one each side), with the decisions 4-6 of the module documentation
/// (`check_unique`: whether step 5 applies).
#[allow(clippy::too_many_arguments)]
fn search(
    img: &Plane,
    t: &[f32],
    r: usize,
    line: [f64; 3],
    u_lo: f64,
    u_hi: f64,
    p: &MatchParams,
    check_unique: bool,
) -> Search {
    let none = |status| Search {
        score: f64::NAN,
        u: f64::NAN,
        v: f64::NAN,
        status,
    };
    let [a, b, c] = line;
    if !(a.is_finite() && b.is_finite() && c.is_finite()) || b.abs() < a.abs() {
        return none(MatchStatus::NoCandidate);
    }
    let v_at = |u: f64| -(a * u + c) / b;
    let (k_lo, k_hi) = (u_lo.ceil() as i64, u_hi.floor() as i64);
    if k_lo > k_hi {
        // The interval holds no whole pixel: take the nearest one.
        let k = u_lo.round() as i64;
        return search_range(img, t, r, k, k, &v_at, p, check_unique);
    }
    search_range(img, t, r, k_lo, k_hi, &v_at, p, check_unique)
}

#[allow(clippy::too_many_arguments)]
fn search_range(
    img: &Plane,
    t: &[f32],
    r: usize,
    k_lo: i64,
    k_hi: i64,
    v_at: &dyn Fn(f64) -> f64,
    p: &MatchParams,
    check_unique: bool,
) -> Search {
    let none = |status| Search {
        score: f64::NAN,
        u: f64::NAN,
        v: f64::NAN,
        status,
    };
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
        if let Some(z) = zncc_at(img, t, r, u, v_at(u as f64)) {
            *sc = z;
            if idx >= 1 && idx + 1 < len {
                any = true;
            }
        }
    }
    if !any {
        return none(MatchStatus::Outside);
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
        let mut t = vec![0.0f32; 49];
        let std = template(&p, 20.3, 14.6, 3, &mut t).unwrap();
        assert!(std > 1.0);
        let s: f32 = t.iter().sum();
        let ss: f32 = t.iter().map(|x| x * x).sum();
        assert!(s.abs() < 1e-4 && (ss - 1.0).abs() < 1e-4);
        assert!(template(&p, 2.5, 14.0, 3, &mut t).is_none());
        assert!(template(&p, 3.0, 3.0, 3, &mut t).is_some());
        assert!(template(&p, 36.0, 26.0, 3, &mut t).is_some());
        assert!(template(&p, 36.5, 26.0, 3, &mut t).is_none());
    }
}
