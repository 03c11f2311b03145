//! What follows the aggregation: winner takes all with uniqueness and sub-pixel refinement,
//! the left-right check, the speckle filter and the confidence of each kept pixel.

use super::{DenseMap, Geo};
use rayon::prelude::*;

/// One pixel's winner.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Best {
    /// Sub-pixel disparity `u_l - u_r` (px).
    pub disparity: f32,
    /// The smallest aggregated cost.
    pub s1: i32,
    /// The smallest more than one disparity away (`i32::MAX` when there is none).
    pub s2: i32,
    /// Disagreement of the left-right check (px).
    pub lr: f32,
}

/// The sub-pixel offset of a minimum `b` between its neighbours `a` (one disparity less) and
/// `c` (one more), in `-0.5..=0.5`: the equiangular (symmetric V) fit, which suits the
/// L1-like census costs better than a parabola (less pull towards whole pixels).
pub(crate) fn subpixel(a: i32, b: i32, c: i32) -> f32 {
    let rise = a.max(c) - b;
    if rise <= 0 {
        return 0.0;
    }
    ((a - c) as f32 / (2 * rise) as f32).clamp(-0.5, 0.5)
}

/// The winners of row `y` of `geo`'s reference image (`None`: refused) from its aggregated
/// sums `sums` (`w * d`).
pub(crate) fn winners_row(geo: &Geo, y: usize, sums: &[i16], uniqueness: f32) -> Vec<Option<Best>> {
    let d = geo.d;
    super::fast(
        #[inline(always)]
        || (0..geo.w).map(|x| winner(geo, x, y, &sums[x * d..(x + 1) * d], uniqueness)).collect(),
    )
}

/// The smallest of `s` (`i16::MAX` when empty).
#[inline(always)]
fn min_of(s: &[i16]) -> i16 {
    s.iter().fold(i16::MAX, |m, &v| m.min(v))
}

/// The winner of pixel `(x, y)` of `geo`'s reference image from its sums `s` (`d` long).
#[inline(always)]
fn winner(geo: &Geo, x: usize, y: usize, s: &[i16], uniqueness: f32) -> Option<Best> {
    let line = geo.line(x, y)?;
    let (lo, hi) = geo.valid_range(x, line)?;
    let run = &s[lo..hi + 1];
    // The first smallest sum.
    let m = min_of(run);
    let k1 = lo + run.iter().position(|&v| v == m)?;
    let s1 = i32::from(m);
    // The minimum at an end of the range (or of the image): the match is not inside the
    // range.
    if k1 == lo || k1 == hi {
        return None;
    }
    let below = min_of(&s[lo..k1 - 1]);
    let above = min_of(&s[k1 + 2..hi + 1]);
    let s2 = if k1 - 1 > lo || k1 + 2 <= hi { i32::from(below.min(above)) } else { i32::MAX };
    if s1 >= s2 || s1 as f32 > (1.0 - uniqueness) * s2 as f32 {
        return None;
    }
    let offset = subpixel(i32::from(s[k1 - 1]), s1, i32::from(s[k1 + 1]));
    Some(Best { disparity: (geo.d_min as f32) + k1 as f32 + offset, s1, s2, lr: 0.0 })
}

/// For a rectified pair: the right image's whole disparities of row `y` read off the left
/// volume's row `sums` (`w * d`; right pixel `(x, y)` at disparity index `k` is left pixel
/// `(x + d_min + k, y)`).
pub(crate) fn right_from_left_row(geo: &Geo, sums: &[i16]) -> Vec<Option<f32>> {
    let (w, d) = (geo.w, geo.d);
    (0..w)
        .map(|xr| {
            // The disparity indices whose left pixel lies inside the image.
            let base = xr as i64 + i64::from(geo.d_min);
            let lo = (-base).max(0);
            let hi = (w as i64 - 1 - base).min(d as i64 - 1);
            if lo > hi {
                return None;
            }
            let (lo, hi) = (lo as usize, hi as usize);
            let at = |k: usize| sums[(base + k as i64) as usize * d + k];
            // The first smallest.
            let (mut s1, mut k1) = (at(lo), lo);
            for k in lo + 1..=hi {
                let v = at(k);
                if v < s1 {
                    (s1, k1) = (v, k);
                }
            }
            // Sub-pixel by the same fit as the left winners where both neighbours exist.
            let offset = if k1 > lo && k1 < hi {
                subpixel(i32::from(at(k1 - 1)), i32::from(s1), i32::from(at(k1 + 1)))
            } else {
                0.0
            };
            Some((geo.d_min as f32) + k1 as f32 + offset)
        })
        .collect()
}

/// Drops every left winner whose right pixel's disparity (`right`, indexed by right pixel)
/// differs by more than `tol` px or is missing; records the disagreement of the others.
pub(crate) fn left_right_check(
    geo: &Geo,
    best: &mut [Option<Best>],
    right: &[Option<f32>],
    tol: f32,
) {
    let w = geo.w;
    best.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
        for (x, slot) in row.iter_mut().enumerate() {
            let Some(b) = slot else { continue };
            let keep = geo.line(x, y).and_then(|(alpha, beta)| {
                let ur = x as f64 - f64::from(b.disparity);
                let vr = alpha + beta * ur;
                let (u, v) = (ur.round(), vr.round());
                if u < 0.0 || v < 0.0 || u >= w as f64 || v >= geo.h as f64 {
                    return None;
                }
                let dr = right[v as usize * w + u as usize]?;
                let diff = (b.disparity - dr).abs();
                (diff <= tol).then_some(diff)
            });
            match keep {
                Some(diff) => b.lr = diff,
                None => *slot = None,
            }
        }
    });
}

/// Drops the 4-connected regions (neighbours within `range` px of disparity) of fewer than
/// `size` pixels.
pub(crate) fn speckle_filter(
    w: usize,
    h: usize,
    best: &mut [Option<Best>],
    size: usize,
    range: f32,
) {
    if size == 0 {
        return;
    }
    let mut label = vec![u32::MAX; w * h];
    let mut stack = Vec::new();
    let mut members = Vec::new();
    let mut next = 0u32;
    for start in 0..w * h {
        if best[start].is_none() || label[start] != u32::MAX {
            continue;
        }
        label[start] = next;
        stack.push(start);
        members.clear();
        while let Some(p) = stack.pop() {
            members.push(p);
            let dp = best[p].map_or(0.0, |b| b.disparity);
            let (x, y) = (p % w, p / w);
            let mut visit = |q: usize| {
                if label[q] == u32::MAX {
                    if let Some(b) = best[q] {
                        if (b.disparity - dp).abs() <= range {
                            label[q] = next;
                            stack.push(q);
                        }
                    }
                }
            };
            if x > 0 {
                visit(p - 1);
            }
            if x + 1 < w {
                visit(p + 1);
            }
            if y > 0 {
                visit(p - w);
            }
            if y + 1 < h {
                visit(p + w);
            }
        }
        if members.len() < size {
            for &p in &members {
                best[p] = None;
            }
        }
        next += 1;
    }
}

/// Bilinear grey level of `img` (`w x h`, rows first) at `(x, y)`, `None` outside.
#[inline]
fn bilinear(img: &[u8], w: usize, h: usize, x: f64, y: f64) -> Option<f64> {
    if !(x >= 0.0 && y >= 0.0 && x <= (w - 1) as f64 && y <= (h - 1) as f64) {
        return None;
    }
    let (x0, y0) = (x as usize, y as usize);
    let (x1, y1) = ((x0 + 1).min(w - 1), (y0 + 1).min(h - 1));
    let (fx, fy) = (x - x0 as f64, y - y0 as f64);
    let at = |x: usize, y: usize| f64::from(img[y * w + x]);
    Some(
        (at(x0, y0) * (1.0 - fx) + at(x1, y0) * fx) * (1.0 - fy)
            + (at(x0, y1) * (1.0 - fx) + at(x1, y1) * fx) * fy,
    )
}

/// Half size of the window of [`refine`] (7 x 7).
const REFINE_HALF: i64 = 3;
/// Side of the window of [`refine`].
const REFINE_SIDE: usize = 2 * REFINE_HALF as usize + 1;

/// The bilinear samples of `img` at `(x + i, y + j)` for `i, j` in `-REFINE_HALF..=REFINE_HALF`
/// into `out` (row by row), or `false` if one lies outside the image (as [`bilinear`] says).
/// Inside, the samples share their fractional offsets: one patch of whole pixels, its rows
/// interpolated along x, then along y (the same products as [`bilinear`]'s).
#[cfg(test)]
fn window_samples(img: &[u8], w: usize, h: usize, x: f64, y: f64, out: &mut [f64]) -> bool {
    scaled_window_samples(img, (w, h), (x, y), [1.0, 1.0], out)
}

/// [`window_samples`] with the samples `step` apart (`(x + i sx, y + j sy)`): the right
/// image's window of a left one when the right camera's scale differs. Unit steps take the
/// shared-offset path; others are sampled one by one.
#[inline(always)]
fn scaled_window_samples(
    img: &[u8],
    (w, h): (usize, usize),
    (x, y): (f64, f64),
    step: [f64; 2],
    out: &mut [f64],
) -> bool {
    const N: usize = REFINE_SIDE;
    let half = REFINE_HALF as f64;
    if step != [1.0, 1.0] {
        for (k, v) in out.iter_mut().enumerate() {
            let (i, j) = ((k % N) as f64 - half, (k / N) as f64 - half);
            match bilinear(img, w, h, x + i * step[0], y + j * step[1]) {
                Some(s) => *v = s,
                None => return false,
            }
        }
        return true;
    }
    let (bx, by) = (x - half, y - half);
    if bx >= 0.0 && by >= 0.0 && x + half < (w - 1) as f64 && y + half < (h - 1) as f64 {
        let (x0, y0) = (bx as usize, by as usize);
        let (fx, fy) = (bx - x0 as f64, by - y0 as f64);
        let mut rows = [[0.0f64; N]; N + 1];
        for (r, row) in rows.iter_mut().enumerate() {
            let line = &img[(y0 + r) * w + x0..(y0 + r) * w + x0 + N + 1];
            for (i, v) in row.iter_mut().enumerate() {
                *v = f64::from(line[i]) * (1.0 - fx) + f64::from(line[i + 1]) * fx;
            }
        }
        for (j, o) in out.chunks_exact_mut(N).enumerate() {
            for (i, v) in o.iter_mut().enumerate() {
                *v = rows[j][i] * (1.0 - fy) + rows[j + 1][i] * fy;
            }
        }
        return true;
    }
    // Near the border: sample by sample.
    for (k, v) in out.iter_mut().enumerate() {
        let (i, j) = ((k % N) as f64 - half, (k / N) as f64 - half);
        match bilinear(img, w, h, x + i, y + j) {
            Some(s) => *v = s,
            None => return false,
        }
    }
    true
}

/// Sub-pixel refinement of every kept winner on the grey levels: two Gauss-Newton steps of a
/// 7 x 7 window's zero-mean, gain-matched difference along the epipolar line (a 1-D
/// Lucas-Kanade), which removes most of the pull of the cost fit towards whole pixels. A step
/// that would move the match by more than half a pixel, or leave the image, is not taken.
pub(crate) fn refine(
    geo: &Geo,
    left: &[u8],
    right: &[u8],
    scale: [f64; 2],
    best: &mut [Option<Best>],
) {
    let w = geo.w;
    best.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
        super::fast(
            #[inline(always)]
            || {
                for (x, slot) in row.iter_mut().enumerate() {
                    if let Some(b) = slot {
                        if let Some(u) = refined(geo, (left, right), scale, (x, y), b.disparity) {
                            b.disparity = (x as f64 - u) as f32;
                        }
                    }
                }
            },
        )
    });
}

/// The refined right `u` of left pixel `(x, y)` at `disparity` ([`refine`]), `None` where
/// the step is not taken. The window sums are gathered in one sweep each (six independent
/// running sums, not a chain of means then deviations): `sum (r - mean r)^2 = sum r^2 - mean
/// r sum r` and the like, the same quantities to rounding.
#[inline(always)]
fn refined(
    geo: &Geo,
    (left, right): (&[u8], &[u8]),
    scale: [f64; 2],
    (x, y): (usize, usize),
    disparity: f32,
) -> Option<f64> {
    const N: usize = REFINE_SIDE * REFINE_SIDE;
    let (w, h) = (geo.w, geo.h);
    let (alpha, beta) = geo.line(x, y)?;
    let (xi, yi) = (x as i64, y as i64);
    if xi < REFINE_HALF
        || yi < REFINE_HALF
        || xi + REFINE_HALF >= w as i64
        || yi + REFINE_HALF >= h as i64
    {
        return None;
    }
    let mut lw = [0.0f64; N];
    let half = REFINE_HALF as usize;
    for (j, out) in lw.chunks_exact_mut(REFINE_SIDE).enumerate() {
        let r = (y + j - half) * w + x - half;
        for (o, &p) in out.iter_mut().zip(&left[r..r + REFINE_SIDE]) {
            *o = f64::from(p);
        }
    }
    let n = N as f64;
    let (mut sl, mut sll) = (0.0, 0.0);
    for &l in &lw {
        sl += l;
        sll += l * l;
    }
    let lmean = sl / n;
    let lvar = sll - sl * lmean;
    if lvar < 1e-6 {
        return None;
    }
    for l in lw.iter_mut() {
        *l -= lmean;
    }
    let u0 = x as f64 - f64::from(disparity);
    let mut u = u0;
    for _ in 0..2 {
        let v = alpha + beta * u;
        // Right window and its derivative along the line (1, beta).
        let mut rw = [0.0f64; N];
        let (mut before, mut after) = (rw, rw);
        let at = |x: f64, y: f64, out: &mut [f64]| {
            scaled_window_samples(right, (w, h), (x, y), scale, out)
        };
        if !(at(u, v, &mut rw)
            && at(u - 0.5, v - 0.5 * beta, &mut before)
            && at(u + 0.5, v + 0.5 * beta, &mut after))
        {
            return None;
        }
        let (mut sr, mut srr, mut sg, mut sgg, mut sgl, mut sgr) = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
        for k in 0..N {
            let (r, g, l) = (rw[k], after[k] - before[k], lw[k]);
            sr += r;
            srr += r * r;
            sg += g;
            sgg += g * g;
            sgl += g * l;
            sgr += g * r;
        }
        let rmean = sr / n;
        let rvar = srr - sr * rmean;
        if rvar < 1e-6 {
            return None;
        }
        let gain = (lvar / rvar).sqrt();
        // With g' = gain (g - mean g) and e = l' - gain (r - mean r) (l' zero-mean):
        // sum g' e = gain (sum g l' - gain (sum g r - sum g mean r)), sum g'^2 = gain^2 (sum g^2 -
        // sum g mean g).
        let num = gain * (sgl - gain * (sgr - sg * rmean));
        let den = gain * gain * (sgg - sg * (sg / n));
        if den <= 1e-9 {
            return None;
        }
        u += (num / den).clamp(-0.5, 0.5);
    }
    ((u - u0).abs() <= 0.5).then_some(u)
}

/// The confidence of a kept pixel in `0..1`: its uniqueness margin `(s2 - s1) / s2` over
/// 0.2 (capped at 1), times `1 - lr / (2 tol)` (the left-right disagreement `lr` against the
/// check's tolerance `tol`).
pub fn confidence(s1: i32, s2: i32, lr: f32, tol: f32) -> f32 {
    let margin =
        if s2 == i32::MAX || s2 <= 0 { 1.0 } else { ((s2 - s1) as f32 / s2 as f32).max(0.0) };
    let agree = if tol > 0.0 { 1.0 - 0.5 * (lr / tol).min(1.0) } else { 1.0 };
    ((margin / 0.2).min(1.0) * agree).clamp(0.0, 1.0)
}

/// The winners as right-image pixels.
pub(crate) fn to_map(geo: &Geo, best: &[Option<Best>], tol: f32) -> DenseMap {
    let n = geo.w * geo.h;
    let (mut ur, mut vr, mut conf) =
        (vec![f32::INFINITY; n], vec![f32::INFINITY; n], vec![0.0f32; n]);
    for (p, b) in best.iter().enumerate() {
        let Some(b) = b else { continue };
        let (x, y) = (p % geo.w, p / geo.w);
        let Some((alpha, beta)) = geo.line(x, y) else {
            continue;
        };
        let u = x as f64 - f64::from(b.disparity);
        ur[p] = u as f32;
        vr[p] = (alpha + beta * u) as f32;
        conf[p] = confidence(b.s1, b.s2, b.lr, tol);
    }
    DenseMap { width: geo.w as u32, height: geo.h as u32, ur, vr, conf }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The window's samples are `bilinear`'s, to a few ulps inside (the shared fractional
    /// offset is rounded once, not per sample) and exactly at the border, where a sample
    /// outside fails the window.
    #[test]
    fn window_samples_are_bilinears() {
        let (w, h) = (23usize, 17usize);
        let img: Vec<u8> = (0..w * h).map(|k| ((k * 37 + k / 7) % 251) as u8).collect();
        let mut out = [0.0f64; REFINE_SIDE * REFINE_SIDE];
        let half = REFINE_HALF as f64;
        let mut inside = 0;
        for y10 in 0..(h * 10) {
            for x10 in 0..(w * 10) {
                let (x, y) = (x10 as f64 * 0.1 - 0.35, y10 as f64 * 0.1 - 0.35);
                let ok = window_samples(&img, w, h, x, y, &mut out);
                let want: Vec<Option<f64>> = (0..REFINE_SIDE * REFINE_SIDE)
                    .map(|k| {
                        let (i, j) =
                            ((k % REFINE_SIDE) as f64 - half, (k / REFINE_SIDE) as f64 - half);
                        bilinear(&img, w, h, x + i, y + j)
                    })
                    .collect();
                assert_eq!(ok, want.iter().all(Option::is_some), "({x}, {y})");
                if ok {
                    inside += 1;
                    for (got, want) in out.iter().zip(&want) {
                        let want = want.unwrap();
                        assert!((got - want).abs() <= 1e-9, "({x}, {y}): {got} vs {want}");
                    }
                }
            }
        }
        assert!(inside > 10_000, "{inside}");
    }

    /// A right camera with 0.8 times the left's scale: the refinement with that scale finds
    /// the true match within 0.05 px from a start 0.3 px off; comparing unscaled windows it
    /// does worse.
    #[test]
    fn a_scaled_right_image_is_refined_at_its_scale() {
        let (w, h, sc, (a, b)) = (80usize, 60usize, 0.8f64, (-10.0, -5.0));
        let texture = |x: f64, y: f64| {
            128.0
                + 40.0 * (0.9 * x + 0.3 * y).sin()
                + 30.0 * (0.5 * y - 0.7 * x).cos()
                + 20.0 * (1.3 * x).sin() * (1.1 * y).cos()
        };
        let left: Vec<u8> =
            (0..w * h).map(|k| texture((k % w) as f64, (k / w) as f64).round() as u8).collect();
        // Left (x, y) is seen at right (sc (x - a), sc (y - b)).
        let right: Vec<u8> = (0..w * h)
            .map(|k| texture((k % w) as f64 / sc + a, (k / w) as f64 / sc + b).round() as u8)
            .collect();
        // The line of (x, y): v = sc y - sc b.
        let m = [[0.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, sc, -sc * b]];
        let geo = Geo { m, sign: -1, d_min: 0, d: 40, w, h };
        let err = |scale: [f64; 2]| {
            let (mut worst, mut n) = (0.0f64, 0);
            for y in 20..40 {
                for x in 30..60 {
                    let true_u = sc * (x as f64 - a);
                    let start = x as f64 - true_u + 0.3;
                    let u = refined(&geo, (&left, &right), scale, (x, y), start as f32);
                    let Some(u) = u else { continue };
                    worst = worst.max((u - true_u).abs());
                    n += 1;
                }
            }
            assert!(n > 500, "{n} refined");
            worst
        };
        let (scaled, unscaled) = (err([sc, sc]), err([1.0, 1.0]));
        assert!(scaled < 0.05, "scaled windows: worst {scaled} px");
        assert!(unscaled > scaled, "unscaled {unscaled} px, scaled {scaled} px");
    }

    fn best(d: f32) -> Option<Best> {
        Some(Best { disparity: d, s1: 1, s2: 10, lr: 0.0 })
    }

    #[test]
    fn equiangular_subpixel_finds_the_v_tip() {
        // A V with slope 10 and its tip at +0.3: a = 10 * 1.3, b = 10 * 0.3, c = 10 * 0.7.
        assert!((subpixel(13, 3, 7) - 0.3).abs() < 1e-6);
        assert!((subpixel(7, 3, 13) + 0.3).abs() < 1e-6);
        assert_eq!(subpixel(5, 5, 5), 0.0);
        assert_eq!(subpixel(4, 0, 4), 0.0);
    }

    #[test]
    fn small_regions_go_and_large_ones_stay() {
        // 10 x 3: a region of 25 at d = 5 and a speck of 3 at d = 9 in its middle row.
        let (w, h) = (10, 3);
        let mut b: Vec<Option<Best>> = (0..w * h).map(|_| best(5.0)).collect();
        for x in 3..6 {
            b[w + x] = best(9.0);
        }
        b[0] = None;
        b[1] = best(5.8);
        speckle_filter(w, h, &mut b, 4, 1.0);
        assert_eq!(b.iter().filter(|x| x.is_some()).count(), 26);
        assert!((3..6).all(|x| b[w + x].is_none()));
        assert!(b[1].is_some());
        speckle_filter(w, h, &mut b, 27, 1.0);
        assert!(b.iter().all(|x| x.is_none()));
    }

    #[test]
    fn confidence_grows_with_the_margin_and_falls_with_the_lr_disagreement() {
        assert_eq!(confidence(10, 10, 0.0, 1.0), 0.0);
        assert!((confidence(90, 100, 0.0, 1.0) - 0.5).abs() < 1e-6);
        assert_eq!(confidence(50, 100, 0.0, 1.0), 1.0);
        assert_eq!(confidence(50, 100, 1.0, 1.0), 0.5);
        assert_eq!(confidence(50, i32::MAX, 0.0, 0.0), 1.0);
    }
}
