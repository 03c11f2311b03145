//! The search along an epipolar line: one window shape's candidates, the peak tests
//! (decisions 4-6), the left-right check and the retries with shifted or grown windows.

use super::window::{template, Plane, Win};
use super::zncc::{zncc_at, zncc_scaled, Probe};
use super::{Match, MatchParams, MatchStatus, Matcher, Query};

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
        Search { score: f64::NAN, u: f64::NAN, v: f64::NAN, status, peaks: Vec::new() }
    }
}

/// One search along an epipolar line: the template of `shape` at `at` in one image (the
/// left one searching `Forward`), scored at whole `u` in `u_range` along `line` in the other;
/// `only`: just around these `u`; `check_unique`: whether the uniqueness step applies.
#[derive(Clone, Copy)]
struct LineQuery<'a> {
    side: Side,
    at: [f64; 2],
    shape: Win,
    line: [f64; 3],
    u_range: [f64; 2],
    only: Option<&'a [i64]>,
    check_unique: bool,
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
    pub(super) fn find_with(&self, q: &Query, buf: &mut Vec<f32>) -> Match {
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
        let retry = matches!(first.status, MatchStatus::NoCandidate | MatchStatus::LrCheckFailed);
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
        let forward = LineQuery {
            side: Side::Forward,
            at: [q.ul, q.vl],
            shape,
            line,
            u_range: [q.ul - q.d_max - slack, q.ul - q.d_min + slack],
            only,
            check_unique: true,
        };
        let Some(s) = self.search_from(&forward, buf) else {
            return Match::fail(MatchStatus::Outside);
        };
        *peaks = s.peaks;
        let out = Match { ur: s.u, vr: s.v, score: s.score, status: s.status };
        if s.status != MatchStatus::Ok {
            return out;
        }
        // Left-right check: the right window at the match, searched back in the left image.
        let back_line = self.f.line_in_left([s.u, s.v]);
        let back_only: Option<Vec<i64>> =
            only.map(|o| o.iter().map(|&c| (q.ul + (c as f64 - s.u)).round() as i64).collect());
        let back = LineQuery {
            side: Side::Back,
            at: [s.u, s.v],
            shape,
            line: back_line,
            u_range: [s.u + q.d_min - slack, s.u + q.d_max + slack],
            only: back_only.as_deref(),
            check_unique: false,
        };
        let b = self.search_from(&back, buf);
        let back_ok = b.is_some_and(|b| {
            // `dist` is NaN when the back search found nothing: that fails too.
            let dist = ((b.u - q.ul).powi(2) + (b.v - q.vl).powi(2)).sqrt();
            b.status == MatchStatus::Ok && dist <= self.params.lr_tolerance_px
        });
        if !back_ok {
            return Match { status: MatchStatus::LrCheckFailed, ..out };
        }
        out
    }

    /// The search `q` ([`LineQuery`]); `buf` holds the template. `None` when the window,
    /// clipped to both images, is too small (the point is too close to a border).
    fn search_from(&self, q: &LineQuery, buf: &mut Vec<f32>) -> Option<Search> {
        let LineQuery { side, at: [u, v], shape, line, u_range: [u_lo, u_hi], only, check_unique } =
            *q;
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
        let win = shape.clip([src.w, src.h], [u, u], [v, v], s_src).clip(
            [dst.w, dst.h],
            [k_lo as f64, k_hi as f64],
            [va.min(vb), va.max(vb)],
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
        let ctx = LineSearch {
            img: dst,
            probe: Probe { t: buf, win, scale: s_dst },
            v_at: &v_at,
            params: &self.params,
        };
        let s = ctx.scan(k_lo, k_hi, only, check_unique);
        // A peak found only thanks to the slack must still be near the interval.
        Some(s)
    }
}

/// What one search along a line compares: the template `t` ([`template`]: coefficients
/// then weights) of window `win`, scaled by `scale` in the searched image `img`, along the
/// line `v_at` (`v` for each `u`), under `params`.
struct LineSearch<'a> {
    img: &'a Plane,
    probe: Probe<'a>,
    v_at: &'a dyn Fn(f64) -> f64,
    params: &'a MatchParams,
}

impl LineSearch<'_> {
    /// Scores the whole `u` from `k_lo - 1` to `k_hi + 1` along the line and applies the
    /// decisions 4-6 of the module documentation to the peak in `k_lo..=k_hi` (`only`: score
    /// only around these `u`; `check_unique`: whether step 5 applies).
    fn scan(&self, k_lo: i64, k_hi: i64, only: Option<&[i64]>, check_unique: bool) -> Search {
        let LineSearch { img, probe, v_at, params: p } = *self;
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
            if let Some(zn) = zncc_at(img, probe, u, v_at(u as f64)) {
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
                zncc_scaled(img, probe, u, v_at(u)).map_or(c, |z| z.max(c))
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
                let right_ok =
                    scores[idx + 1].partial_cmp(&z) != Some(core::cmp::Ordering::Greater);
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
        let off = if den < 0.0 { (0.5 * (sl - sr) / den).clamp(-0.5, 0.5) } else { 0.0 };
        out.u = u_best + off;
        out.v = v_at(out.u);
        out
    }
}
