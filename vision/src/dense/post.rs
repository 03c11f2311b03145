//! What follows the aggregation: winner takes all with uniqueness and sub-pixel refinement,
//! the left-right check, the speckle filter and the confidence of each kept pixel.

use super::sgm::{chunk_starts, LANES};
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
    // A plain loop: an iterator's closure would not be inlined into the AVX2 body.
    super::fast(
        #[inline(always)]
        || {
            let mut row = Vec::with_capacity(geo.w);
            for x in 0..geo.w {
                row.push(winner(geo, x, y, &sums[x * d..(x + 1) * d], uniqueness));
            }
            row
        },
    )
}

/// The smallest of `s` (`i16::MAX` when empty): chunks of [`LANES`] lanes (the last one
/// overlapping its predecessor), element by element below one chunk.
#[inline(always)]
fn min_of(s: &[i16]) -> i16 {
    let n = s.len();
    if n < LANES {
        return s.iter().fold(i16::MAX, |m, &v| m.min(v));
    }
    let mut m = [i16::MAX; LANES];
    for j0 in chunk_starts(n, LANES) {
        let c: &[i16; LANES] = s[j0..j0 + LANES].try_into().expect("chunk");
        for i in 0..LANES {
            m[i] = m[i].min(c[i]);
        }
    }
    m.iter().fold(i16::MAX, |a, &b| a.min(b))
}

/// The smallest of `s` (not empty, no negative value) and the first index where it lies.
/// Below 65,536 values, in one vector pass: the smallest of the keys `value << 16 | index`
/// (8 `i32` lanes; the last chunk overlaps its predecessor).
#[inline(always)]
fn first_smallest(s: &[i16]) -> (i32, usize) {
    const KEYS: usize = 8;
    let n = s.len();
    if !(KEYS..1 << 16).contains(&n) {
        let m = min_of(s);
        return (i32::from(m), s.iter().position(|&v| v == m).expect("not empty"));
    }
    let mut best = [i32::MAX; KEYS];
    for j0 in chunk_starts(n, KEYS) {
        let c: &[i16; KEYS] = s[j0..j0 + KEYS].try_into().expect("chunk");
        for i in 0..KEYS {
            best[i] = best[i].min(i32::from(c[i]) << 16 | (j0 + i) as i32);
        }
    }
    let key = best.iter().fold(i32::MAX, |a, &b| a.min(b));
    (key >> 16, (key & 0xFFFF) as usize)
}

/// The winner of pixel `(x, y)` of `geo`'s reference image from its sums `s` (`d` long).
#[inline(always)]
fn winner(geo: &Geo, x: usize, y: usize, s: &[i16], uniqueness: f32) -> Option<Best> {
    let line = geo.line(x, y)?;
    let (lo, hi) = geo.valid_range(x, line)?;
    let run = &s[lo..hi + 1];
    let (s1, k1) = first_smallest(run);
    let k1 = lo + k1;
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
/// `(x + d_min + k, y)`), with the same sub-pixel fit as the left winners where both
/// neighbours of the minimum exist.
///
/// The volume's row is read in its own order (left pixel by left pixel, disparities
/// contiguous), each cell offered to the running minimum of its right pixel: right pixel
/// `x_r` sees its disparities in increasing order, so keeping a candidate only when it is
/// strictly smaller keeps the first smallest, as a scan of `x_r`'s own disparities would.
pub(crate) fn right_from_left_row(geo: &Geo, sums: &[i16]) -> Vec<Option<f32>> {
    super::fast(
        #[inline(always)]
        || right_from_left_row_body(geo, sums),
    )
}

#[inline(always)]
fn right_from_left_row_body(geo: &Geo, sums: &[i16]) -> Vec<Option<f32>> {
    let (w, d) = (geo.w, geo.d);
    let d_min = i64::from(geo.d_min);
    // The smallest sum of each right pixel and its disparity index, stored from the last
    // right pixel to the first (slot `w - 1 - x_r`), so that a left pixel's disparities,
    // contiguous in the volume, meet their right pixels' slots contiguous too.
    let mut s1 = vec![i16::MAX; w];
    // Disparity indices as i32: a volume may have more than i16::MAX disparities.
    let mut k1 = vec![0i32; w];
    for x in 0..w {
        // Right pixel x_r = top - k at disparity index k, in slot w - 1 - top + k.
        let top = x as i64 - d_min;
        let k_lo = (top - (w as i64 - 1)).max(0);
        let k_hi = top.min(d as i64 - 1);
        if k_lo > k_hi {
            continue;
        }
        let (k_lo, k_hi) = (k_lo as usize, k_hi as usize);
        // The slot of k_lo (w - 1 - top alone may be negative: a negative d_min).
        let first = (w as i64 - 1 - top + k_lo as i64) as usize;
        let n = k_hi - k_lo + 1;
        let cells = &sums[x * d + k_lo..x * d + k_lo + n];
        let best = &mut s1[first..first + n];
        let at = &mut k1[first..first + n];
        // Chunks of 16 (the last one overlapping its predecessor: offering a cell twice
        // changes nothing), or cell by cell when there are fewer.
        let offer = |j: usize, best: &mut [i16], at: &mut [i32]| {
            let better = cells[j] < best[j];
            best[j] = if better { cells[j] } else { best[j] };
            at[j] = if better { (k_lo + j) as i32 } else { at[j] };
        };
        if n < LANES {
            for j in 0..n {
                offer(j, best, at);
            }
            continue;
        }
        for j0 in chunk_starts(n, LANES) {
            let c: &[i16; LANES] = cells[j0..j0 + LANES].try_into().expect("chunk");
            let b: &mut [i16; LANES] = (&mut best[j0..j0 + LANES]).try_into().expect("chunk");
            let a: &mut [i32; LANES] = (&mut at[j0..j0 + LANES]).try_into().expect("chunk");
            // Every lane stored, selected by a mask (a store only where better would not
            // be vectorised: AVX2 has no masked store of 16-bit lanes).
            let k0 = (k_lo + j0) as i32;
            let (mut nb, mut na) = (*b, *a);
            for i in 0..LANES {
                let better = -i32::from(c[i] < b[i]);
                nb[i] = c[i].min(b[i]);
                na[i] = ((k0 + i as i32) & better) | (a[i] & !better);
            }
            *b = nb;
            *a = na;
        }
    }
    (0..w)
        .map(|xr| {
            // The disparity indices whose left pixel lies inside the image.
            let base = xr as i64 + d_min;
            let lo = (-base).max(0);
            let hi = (w as i64 - 1 - base).min(d as i64 - 1);
            if lo > hi {
                return None;
            }
            let (lo, hi, k) = (lo as usize, hi as usize, k1[w - 1 - xr] as usize);
            let at = |k: usize| i32::from(sums[(base + k as i64) as usize * d + k]);
            let offset = if k > lo && k < hi {
                subpixel(at(k - 1), i32::from(s1[w - 1 - xr]), at(k + 1))
            } else {
                0.0
            };
            Some((geo.d_min as f32) + k as f32 + offset)
        })
        .collect()
}

/// The right image's scale along `u` against the left's at each right column, for the
/// left-right check of a pair whose cameras' scales differ ([`super::DenseParams::right_scale`]
/// and its slope): `scale + slope (u_r - centre)`, clipped to 0.25..4 as the census's.
#[derive(Debug, Clone, Copy)]
pub(crate) struct ColumnScale {
    pub scale: f64,
    pub slope: f64,
    pub centre: f64,
}

impl ColumnScale {
    #[inline(always)]
    fn at(&self, ur: f64) -> f64 {
        (self.scale + self.slope * (ur - self.centre)).clamp(0.25, 4.0)
    }
}

/// Drops every left winner whose right pixel's disparity (`right`, indexed by right pixel)
/// disagrees by more than `tol` px or is missing, and every one whose census window or whose
/// right pixel's is flat ([`super::census::flat_windows`] of each image); records the
/// disagreement of the others. With `scale` (the right image at another scale than the
/// left), the disagreement is the round trip's miss in the pixels of the coarser image
/// ([`right_agreement`]); without, `|d - d_r|`.
pub(crate) fn left_right_check(
    geo: &Geo,
    best: &mut [Option<Best>],
    right: &[Option<f32>],
    (flat_left, flat_right): (&[bool], &[bool]),
    tol: f32,
    scale: Option<ColumnScale>,
) {
    let w = geo.w;
    // Compiled for AVX2 where the CPU has it: `round` is then inlined instead of a libm call
    // (the same values: its rounding is defined, half away from zero).
    best.par_chunks_mut(w).zip(flat_left.par_chunks(w)).enumerate().for_each(
        |(y, (row, flat_row))| {
            super::fast(
                #[inline(always)]
                || {
                    for ((x, slot), &flat) in row.iter_mut().enumerate().zip(flat_row) {
                        let Some(b) = slot else { continue };
                        if flat {
                            *slot = None;
                            continue;
                        }
                        let right = (right, flat_right);
                        match right_agreement(geo, right, x, y, b.disparity, tol, scale) {
                            Some(diff) => b.lr = diff,
                            None => *slot = None,
                        }
                    }
                },
            )
        },
    );
}

/// How far the right image's disparity at the match of left pixel `(x, y)` (disparity `d`)
/// lies from `d`, if it has one within `tol` and the right pixel's window is not flat.
///
/// Where the right image's scale `s` (`du_r / du_l`, [`ColumnScale`] at the match) is not 1,
/// `|d - d_r|` is not the round trip's miss: the match `u_r = x - d` is read at the right
/// pixel `u = round(u_r)`, whose own match `u + d_r` should lie at `x + (u - u_r) / s`, not
/// at `x + (u - u_r)`; and the miss, in left pixels, adds the left match's error in right
/// pixels divided by `s` to the right match's in left pixels. So the miss is
/// `u + d_r - x - (u - u_r) / s` (left pixels), and it is measured in the pixels of the
/// coarser of the two images (times `min(s, 1)`): both matches locate the patch to about
/// a pixel of the image that resolves it less finely, as `tol` does for cameras alike. At
/// `s = 1` both are `|d - d_r|`.
#[inline(always)]
fn right_agreement(
    geo: &Geo,
    (right, flat_right): (&[Option<f32>], &[bool]),
    x: usize,
    y: usize,
    d: f32,
    tol: f32,
    scale: Option<ColumnScale>,
) -> Option<f32> {
    let (alpha, beta) = geo.line(x, y)?;
    let w = geo.w;
    let ur = x as f64 - f64::from(d);
    let vr = alpha + beta * ur;
    let (u, v) = (ur.round(), vr.round());
    if u < 0.0 || v < 0.0 || u >= w as f64 || v >= geo.h as f64 {
        return None;
    }
    let at = v as usize * w + u as usize;
    if flat_right[at] {
        return None;
    }
    let dr = right[at]?;
    let diff = match scale {
        None => (d - dr).abs(),
        Some(scale) => {
            let s = scale.at(ur);
            let miss = u + f64::from(dr) - x as f64 - (u - ur) / s;
            (miss.abs() * s.min(1.0)) as f32
        }
    };
    (diff <= tol).then_some(diff)
}

/// A neighbour's disparity counts as the far side of a depth edge when it is this much (px)
/// smaller than the pixel's ([`edge_switch`], [`past_gaps`]).
const EDGE_STEP: f32 = 1.5;

/// Drops the first match past each run of unmatched pixels along a row when its disparity is
/// more than [`EDGE_STEP`] larger than the match just before the run. With the left image as
/// reference, the strip the right camera does not see lies on the left of a nearer object;
/// the left-right check refuses most of it, and the first match past the refused run is
/// most often the nearer object spread over the strip's last pixel. Decided on the matches
/// as they are (a dropped pixel starts no run of its own).
pub(crate) fn past_gaps(w: usize, best: &mut [Option<Best>]) {
    best.par_chunks_mut(w.max(1)).for_each(|row| {
        let mut drop = Vec::new();
        let mut x = 1;
        while x < row.len() {
            let Some(before) = row[x - 1].filter(|_| row[x].is_none()) else {
                x += 1;
                continue;
            };
            while x < row.len() && row[x].is_none() {
                x += 1;
            }
            if let Some(past) = row.get(x).copied().flatten() {
                if past.disparity > before.disparity + EDGE_STEP {
                    drop.push(x);
                }
            }
        }
        for x in drop {
            row[x] = None;
        }
    });
}
/// How far [`edge_switch`] looks for such a neighbour: columns and rows either side.
const EDGE_REACH: [usize; 2] = [2, 1];
/// Half side of [`edge_switch`]'s windows (5 x 5), and how far they are shifted (+-2 px).
const EDGE_HALF: i64 = 2;

/// Depth edges put back where the grey levels say (rectified pairs of cameras alike): a window
/// across a depth edge matches the nearer surface best, so its disparity spreads a pixel or
/// two onto the farther one ("fattening"; most of the matches 2 px or more off lie there). A
/// pixel with a neighbour ([`EDGE_REACH`]) more than [`EDGE_STEP`] px farther takes the
/// farthest such neighbour's winner when a 5 x 5 window at its disparity, shifted by up to
/// 2 px so that it need not straddle the edge, fits better than one at its own (zero-mean
/// sums of absolute differences, whole pixels). Every pixel is decided on the winners before
/// this step, so the order does not matter. Chosen on six Middlebury scenes that no other
/// setting was chosen on (`scripts/depth_heldout.py`): 7-20 % fewer matches 2 px or more off.
pub(crate) fn edge_switch(geo: &Geo, (left, right): (&[u8], &[u8]), best: &mut [Option<Best>]) {
    let (w, h) = (geo.w, geo.h);
    // The winners' disparities, +inf where none.
    let mut disp = vec![f32::INFINITY; w * h];
    disp.par_chunks_mut(w).zip(best.par_chunks(w)).for_each(|(d, b)| {
        for (d, b) in d.iter_mut().zip(b) {
            if let Some(b) = b {
                *d = b.disparity;
            }
        }
    });
    let (before, disp) = (&*best, &disp[..]);
    let switched: Vec<Vec<(usize, Best)>> = (0..h)
        .into_par_iter()
        .map(|y| {
            super::fast(
                #[inline(always)]
                move || {
                    let y = y;
                    edge_row((before, disp), (left, right), (w, h), y)
                },
            )
        })
        .collect();
    for (p, f) in switched.into_iter().flatten() {
        best[p] = Some(f);
    }
}

/// [`edge_switch`]'s decisions for row `y`: the pixels that take a farther neighbour's
/// winner, and that winner. No closures: this body is compiled for the CPU's vectors.
#[inline(always)]
fn edge_row(
    (before, disp): (&[Option<Best>], &[f32]),
    images: (&[u8], &[u8]),
    (w, h): (usize, usize),
    y: usize,
) -> Vec<(usize, Best)> {
    let [rx, ry] = EDGE_REACH;
    let (y0, y1) = (y.saturating_sub(ry), (y + ry).min(h - 1));
    // The smallest disparity (`disp`: +inf where none) over the neighbouring rows of each
    // pixel's columns x - rx ..= x + rx, through a row padded with +inf.
    let mut padded = vec![f32::INFINITY; w + 2 * rx];
    let mut near = vec![f32::INFINITY; w];
    for yy in y0..=y1 {
        padded[rx..rx + w].copy_from_slice(&disp[yy * w..(yy + 1) * w]);
        for k in 0..=2 * rx {
            for (m, &v) in near.iter_mut().zip(&padded[k..k + w]) {
                *m = m.min(v);
            }
        }
    }
    let mut out = Vec::new();
    for x in 0..w {
        let Some(b) = before[y * w + x] else { continue };
        let step = b.disparity - EDGE_STEP;
        if near[x] >= step {
            continue;
        }
        // The farthest neighbour past the step: the first of the smallest disparity.
        let (x0, x1) = (x.saturating_sub(rx), (x + rx).min(w - 1));
        let mut far: Option<Best> = None;
        let mut far_d = step;
        for yy in y0..=y1 {
            for n in before[yy * w + x0..=yy * w + x1].iter().flatten() {
                if n.disparity < far_d {
                    (far, far_d) = (Some(*n), n.disparity);
                }
            }
        }
        let Some(f) = far else { continue };
        let own = shifted_zsad(images, (w, h), (x, y), b.disparity.round() as i64, 0);
        if shifted_zsad(images, (w, h), (x, y), f.disparity.round() as i64, own) < own {
            out.push((y * w + x, f));
        }
    }
    out
}

/// The best over shifts of up to [`EDGE_HALF`] px of the zero-mean sum of absolute
/// differences (times 25, in integers) between the 5 x 5 left window around `(x, y)` shifted
/// by `(sx, sy)` and the right one `d` px to its left; `u32::MAX` when no shifted window lies
/// inside both images. Stops at the first row of shifts that has one below `below` (a smaller
/// best is then of no interest). The five horizontal shifts of a row of shifts side by side
/// in eight lanes (the compiler's vectors; the same integers either way).
#[inline(always)]
fn shifted_zsad(
    (left, right): (&[u8], &[u8]),
    (w, h): (usize, usize),
    (x, y): (usize, usize),
    d: i64,
    below: u32,
) -> u32 {
    const SIDE: usize = 2 * EDGE_HALF as usize + 1;
    const REGION: usize = 2 * SIDE - 1;
    const N: i32 = (SIDE * SIDE) as i32;
    let reach = 2 * EDGE_HALF;
    let (x, y, w, h) = (x as i64, y as i64, w as i64, h as i64);
    // The region the shifted windows cover, cut to where both images have pixels: rows
    // `j0..j1` and columns `i0..i1` of it.
    let j0 = (reach - y).max(0);
    let j1 = (h - y + reach).min(REGION as i64);
    let i0 = (reach - x).max(reach - x + d).max(0);
    let i1 = (w - x + reach).min(w - x + reach + d).min(REGION as i64);
    if j1 - j0 < SIDE as i64 || i1 - i0 < SIDE as i64 {
        return u32::MAX;
    }
    let (j0, j1, i0, i1) = (j0 as usize, j1 as usize, i0 as usize, i1 as usize);
    // Columns padded to 16, so that each of the window's columns `c` reads the eight lanes
    // `c..c + 8` (lane `k`: the shift by `k` columns).
    let mut diff = [[0i32; 16]; REGION];
    for (j, dr) in diff.iter_mut().enumerate().take(j1).skip(j0) {
        let r = (y + j as i64 - reach) * w + x - reach;
        let (a0, b0) = ((r + i0 as i64) as usize, (r + i0 as i64 - d) as usize);
        let (l, rr) = (&left[a0..a0 + i1 - i0], &right[b0..b0 + i1 - i0]);
        for ((v, &a), &b) in dr[i0..i1].iter_mut().zip(l).zip(rr) {
            *v = i32::from(a) - i32::from(b);
        }
    }
    let mut best = u32::MAX;
    for sy in j0..=j1 - SIDE {
        let rows = &diff[sy..sy + SIDE];
        // Each column's sum over the window's rows, then each lane's over its columns.
        let mut column = [0i32; 16];
        for r in rows {
            for (s, v) in column.iter_mut().zip(r) {
                *s += v;
            }
        }
        let mut sum = [0i32; 8];
        for c in 0..SIDE {
            for (s, v) in sum.iter_mut().zip(&column[c..c + 8]) {
                *s += v;
            }
        }
        let mut cost = [0u32; 8];
        for r in rows {
            for c in 0..SIDE {
                for ((e, v), s) in cost.iter_mut().zip(&r[c..c + 8]).zip(&sum) {
                    *e += (N * v - s).unsigned_abs();
                }
            }
        }
        for &e in &cost[i0..=i1 - SIDE] {
            best = best.min(e);
        }
        if best < below {
            break;
        }
    }
    best
}

/// Rows per strip of [`speckle_filter`]: the strips are labelled in parallel.
const SPECKLE_STRIP_ROWS: usize = 32;

/// Drops the 4-connected regions (neighbours within `range` px of disparity) of fewer than
/// `size` pixels.
///
/// Strips of [`SPECKLE_STRIP_ROWS`] rows are labelled side by side (a flood fill inside each),
/// then the regions that meet across a strip's border are joined (union-find) and their sizes
/// added: the regions, and so the pixels dropped, are those of one flood fill over the whole
/// image, whatever the number of threads (a region is a connected component of the
/// neighbour relation, which does not depend on the order it is explored in).
pub(crate) fn speckle_filter(
    w: usize,
    h: usize,
    best: &mut [Option<Best>],
    size: usize,
    range: f32,
) {
    if size == 0 || w == 0 || h == 0 {
        return;
    }
    // The disparities alone (NaN: no match; a NaN is never within `range`), 4 bytes a pixel
    // instead of the winners' 20: the flood fill reads each pixel up to four times.
    let disp: Vec<f32> = best.par_iter().map(|b| b.map_or(f32::NAN, |b| b.disparity)).collect();
    let mut label = vec![u32::MAX; w * h];
    let strip = SPECKLE_STRIP_ROWS * w;
    // Each strip's regions, labelled 0.. within it, and their sizes.
    let sizes: Vec<Vec<u32>> = label
        .par_chunks_mut(strip)
        .zip(disp.par_chunks(strip))
        .map(|(label, disp)| label_regions(w, disp, label, range))
        .collect();
    let mut first = Vec::with_capacity(sizes.len());
    let mut total = 0u32;
    for s in &sizes {
        first.push(total);
        total += s.len() as u32;
    }
    // Join the regions that touch across each border between two strips.
    let mut parent: Vec<u32> = (0..total).collect();
    for s in 1..sizes.len() {
        let (above, below) = ((s * SPECKLE_STRIP_ROWS - 1) * w, s * SPECKLE_STRIP_ROWS * w);
        for x in 0..w {
            let (p, q) = (above + x, below + x);
            if label[p] != u32::MAX && label[q] != u32::MAX && (disp[q] - disp[p]).abs() <= range {
                union(&mut parent, first[s - 1] + label[p], first[s] + label[q]);
            }
        }
    }
    // Each region's root and the whole region's size.
    for i in 0..parent.len() {
        parent[i] = root(&mut parent, i as u32);
    }
    let mut whole = vec![0u32; parent.len()];
    for (i, &n) in sizes.iter().flatten().enumerate() {
        whole[parent[i] as usize] += n;
    }
    let small = |l: u32| (whole[parent[l as usize] as usize] as usize) < size;
    best.par_chunks_mut(strip).zip(label.par_chunks(strip)).enumerate().for_each(
        |(s, (best, label))| {
            for (b, &l) in best.iter_mut().zip(label) {
                if l != u32::MAX && small(first[s] + l) {
                    *b = None;
                }
            }
        },
    );
}

/// Labels the 4-connected regions of one strip (`w` pixels a row; `disp` NaN where no match)
/// 0, 1, .. in `label` (`u32::MAX` where no match), by a flood fill from each unlabelled pixel
/// in row order; returns each region's size.
fn label_regions(w: usize, disp: &[f32], label: &mut [u32], range: f32) -> Vec<u32> {
    let n = disp.len();
    let mut sizes = Vec::new();
    let mut stack = Vec::new();
    for start in 0..n {
        if disp[start].is_nan() || label[start] != u32::MAX {
            continue;
        }
        let next = sizes.len() as u32;
        label[start] = next;
        stack.push(start);
        let mut count = 0u32;
        while let Some(p) = stack.pop() {
            count += 1;
            let dp = disp[p];
            let x = p % w;
            let mut visit = |q: usize| {
                // A pixel without a match (NaN) fails the comparison.
                if label[q] == u32::MAX && (disp[q] - dp).abs() <= range {
                    label[q] = next;
                    stack.push(q);
                }
            };
            if x > 0 {
                visit(p - 1);
            }
            if x + 1 < w {
                visit(p + 1);
            }
            if p >= w {
                visit(p - w);
            }
            if p + w < n {
                visit(p + w);
            }
        }
        sizes.push(count);
    }
    sizes
}

/// The root of `i` in the union-find forest `parent`, halving the path on the way.
fn root(parent: &mut [u32], mut i: u32) -> u32 {
    while parent[i as usize] != i {
        let up = parent[parent[i as usize] as usize];
        parent[i as usize] = up;
        i = up;
    }
    i
}

/// Joins the trees of `a` and `b` (the larger root under the smaller).
fn union(parent: &mut [u32], a: u32, b: u32) {
    let (ra, rb) = (root(parent, a), root(parent, b));
    if ra != rb {
        let (lo, hi) = (ra.min(rb), ra.max(rb));
        parent[hi as usize] = lo;
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

/// Half size of the window of the warped refinement ([`refined_warped`], 9 x 9): larger than
/// the others', since the warp follows a slanted or differently scaled surface across it, so
/// that a larger window only averages more of the cameras' noise. On the rendered scenes of
/// `vision/tests/dense_scene.rs` (case IV, whose error is at the goal's 0.5 %), the median depth
/// error went 0.455 -> 0.368 % and 0.441 -> 0.354 % from 7 x 7 (0.330 % and 0.317 % at 11 x 11,
/// at half as much time again); a sweep on those two scenes, then checked on others.
const WARP_REFINE_HALF: usize = 4;
/// Side of the window of the warped refinement.
const WARP_REFINE_SIDE: usize = 2 * WARP_REFINE_HALF + 1;
/// Pixels of the window of the warped refinement.
const WARP_REFINE_N: usize = WARP_REFINE_SIDE * WARP_REFINE_SIDE;

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

/// Sub-pixel refinement of every kept winner on the grey levels: Gauss-Newton steps of a
/// 7 x 7 window's (9 x 9 warped: [`WARP_REFINE_HALF`]) zero-mean, gain-matched difference
/// along the epipolar line (a 1-D Lucas-Kanade), which removes most of the pull of the cost fit towards whole pixels. A
/// `rectified` pair at unit `scale`: two steps of the window shifted along its row (bilinear
/// samples sharing one fractional offset) with the left window's derivative
/// ([`refined_rectified`]). Otherwise one step of the window under its
/// [`local_warps`] warp ([`warped_window_samples`]), or two of the window at `scale` where the
/// neighbourhood gives no warp. A step that would move the match by more than half a pixel,
/// or leave the image, is not taken.
pub(crate) fn refine(
    geo: &Geo,
    (left, right): (&[u8], &[u8]),
    scale: [f64; 2],
    rectified: bool,
    best: &mut [Option<Best>],
) {
    let (w, h) = (geo.w, geo.h);
    // A rectified pair of cameras alike: every window's map is (nearly) a shift along its row.
    if rectified && scale == [1.0, 1.0] {
        let planes = Planes::new(left, right);
        #[cfg(target_arch = "x86_64")]
        if let Some(simd) = pulp::x86::V3::try_new() {
            best.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
                let planes = &planes;
                simd.vectorize(
                    #[inline(always)]
                    move || {
                        // `row` moved out: the closure is `FnOnce` only, so the vectorised
                        // body calls it directly. A closure that could be `Fn` is called
                        // through a `call_once` shim, which is not inlined once the body is
                        // large: the body then lost the target features (every intrinsic a
                        // call, 17x slower).
                        let row = row;
                        refine_row_rectified(avx::Rows(simd), geo, planes, y, row)
                    },
                )
            });
            return;
        }
        best.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
            let planes = &planes;
            super::fast(
                #[inline(always)]
                move || {
                    // Moved out: `FnOnce` only (see above).
                    let row = row;
                    refine_row_rectified(Rows8, geo, planes, y, row)
                },
            )
        });
        return;
    }
    // The warps come from the winners before refinement; a band of rows at a time, so that
    // the warps' tables stay small whatever the image's size.
    let ur: Vec<f64> = best
        .iter()
        .enumerate()
        .map(|(p, b)| b.map_or(f64::NAN, |b| (p % w) as f64 - f64::from(b.disparity)))
        .collect();
    let grey: Vec<f32> = right.iter().map(|&p| f32::from(p)).collect();
    for y0 in (0..h).step_by(WARP_BAND) {
        let rows = y0..(y0 + WARP_BAND).min(h);
        let warps = local_warps(&ur, w, h, rows.clone());
        best[rows.start * w..rows.end * w].par_chunks_mut(w).enumerate().for_each(|(dy, row)| {
            let y = y0 + dy;
            super::fast(
                #[inline(always)]
                || {
                    for (x, slot) in row.iter_mut().enumerate() {
                        let Some(b) = slot else { continue };
                        let u = match warps[dy * w + x] {
                            Some(warp) => {
                                let u0 = x as f64 - f64::from(b.disparity);
                                refined_warped(geo, (left, &grey), (x, y), u0, warp)
                            }
                            None => refined(geo, (left, right), scale, (x, y), b.disparity),
                        };
                        if let Some(u) = u {
                            b.disparity = (x as f64 - u) as f32;
                        }
                    }
                },
            )
        });
    }
}

/// Rows of [`refine`]'s bands of warps.
const WARP_BAND: usize = 64;

/// The refined right `u` of left pixel `(x, y)` at `disparity` ([`refine`] with the right
/// window at the cameras' scale, on the pixel's own line; its derivative from the windows half
/// a pixel either side), `None` where a step is not taken.
#[inline(always)]
fn refined(
    geo: &Geo,
    (left, right): (&[u8], &[u8]),
    scale: [f64; 2],
    (x, y): (usize, usize),
    disparity: f32,
) -> Option<f64> {
    let (alpha, beta) = geo.line(x, y)?;
    let (w, h) = (geo.w, geo.h);
    // The derivative along the line (1, beta): the windows half a pixel either side. The
    // closure LK calls is inlined, so that it is compiled for the instruction set [`refine`]
    // runs.
    let at =
        |x: f64, y: f64, out: &mut [f64]| scaled_window_samples(right, (w, h), (x, y), scale, out);
    lucas_kanade::<{ REFINE_HALF as usize }, { REFINE_SIDE * REFINE_SIDE }>(
        geo,
        left,
        (x, y),
        x as f64 - f64::from(disparity),
        2,
        #[inline(always)]
        |u, rw, gw| {
            let v = alpha + beta * u;
            let mut after = [0.0f64; REFINE_SIDE * REFINE_SIDE];
            if !(at(u, v, rw)
                && at(u - 0.5, v - 0.5 * beta, gw)
                && at(u + 0.5, v + 0.5 * beta, &mut after))
            {
                return false;
            }
            for (g, a) in gw.iter_mut().zip(&after) {
                *g = a - *g;
            }
            true
        },
    )
}

/// Lanes of one window row in [`refined_rectified`]: the window's 7 pixels and one of
/// padding, so that a row is one 8-lane vector (one AVX2 register of `f32`).
const ROW: usize = 8;
/// One window row ([`ROW`] lanes).
type Lanes = [f32; ROW];
/// The arithmetic of [`refined_rectified`] on window rows of [`ROW`] lanes (the window's 7
/// pixels and a padding lane held at 0): [`Rows8`] on plain arrays, `avx::Rows` in AVX2
/// registers. Both do the same float operations lane by lane in the same order, and total
/// the lanes in the same order, so they give the same bits (a unit test compares them).
trait RowOps: Copy {
    /// One window row.
    type R: Copy;
    /// A row of zeros.
    fn zero(self) -> Self::R;
    /// The [`ROW`] values of `plane` from `at`.
    fn load(self, plane: &[f32], at: usize) -> Self::R;
    /// `v` in the window's lanes, +0 in the padding lane.
    fn masked(self, v: Self::R) -> Self::R;
    /// `v - s` in every lane.
    fn minus(self, v: Self::R, s: f32) -> Self::R;
    /// `a * wa + b * wb` in every lane.
    fn lerp(self, a: Self::R, wa: f32, b: Self::R, wb: f32) -> Self::R;
    /// `acc + v` (`mul`: `acc + v * u`) in every lane.
    fn add(self, acc: Self::R, v: Self::R) -> Self::R;
    fn add_product(self, acc: Self::R, v: Self::R, u: Self::R) -> Self::R;
    /// The lanes' sum: `((a0 + a4) + (a1 + a5)) + ((a2 + a6) + (a3 + a7))`.
    fn total(self, v: Self::R) -> f32;
}

/// [`RowOps`] on arrays, for the compiler to vectorise.
#[derive(Clone, Copy)]
struct Rows8;

impl RowOps for Rows8 {
    type R = Lanes;
    #[inline(always)]
    fn zero(self) -> Lanes {
        [0.0; ROW]
    }
    #[inline(always)]
    fn load(self, plane: &[f32], at: usize) -> Lanes {
        lanes_at(plane, at)
    }
    /// A select, not a product with a 0/1 mask (the products by 1 fold away lane by lane and
    /// the rest was split into narrower pieces; a product by 0 gives -0 for negative `v`).
    #[inline(always)]
    fn masked(self, v: Lanes) -> Lanes {
        core::array::from_fn(|i| if i < REFINE_SIDE { v[i] } else { 0.0 })
    }
    #[inline(always)]
    fn minus(self, v: Lanes, s: f32) -> Lanes {
        v.map(|x| x - s)
    }
    #[inline(always)]
    fn lerp(self, a: Lanes, wa: f32, b: Lanes, wb: f32) -> Lanes {
        core::array::from_fn(|i| a[i] * wa + b[i] * wb)
    }
    #[inline(always)]
    fn add(self, acc: Lanes, v: Lanes) -> Lanes {
        core::array::from_fn(|i| acc[i] + v[i])
    }
    #[inline(always)]
    fn add_product(self, acc: Lanes, v: Lanes, u: Lanes) -> Lanes {
        core::array::from_fn(|i| acc[i] + v[i] * u[i])
    }
    #[inline(always)]
    fn total(self, a: Lanes) -> f32 {
        ((a[0] + a[4]) + (a[1] + a[5])) + ((a[2] + a[6]) + (a[3] + a[7]))
    }
}

/// The sum over a window's rows: lane by lane over the rows, then [`RowOps::total`].
#[inline(always)]
fn window_sum<O: RowOps>(o: O, rows: &[O::R; REFINE_SIDE]) -> f32 {
    let mut acc = o.zero();
    for r in rows {
        acc = o.add(acc, *r);
    }
    o.total(acc)
}

/// The sum of `a * b` over two windows (lane by lane over the rows, then the total).
#[inline(always)]
fn window_dot<O: RowOps>(o: O, a: &[O::R; REFINE_SIDE], b: &[O::R; REFINE_SIDE]) -> f32 {
    let mut acc = o.zero();
    for (a, b) in a.iter().zip(b) {
        acc = o.add_product(acc, *a, *b);
    }
    o.total(acc)
}

/// The grey levels [`refined_rectified`] reads, as floats: both images and the left one's
/// central difference along its rows (`0.5 (l[i + 1] - l[i - 1])` over the image as one
/// row, so a window row is one plain load of [`ROW`] lanes instead of [`ROW`] conversions
/// from bytes, three of them on the left), each followed by `2 ROW` zeros (what a window
/// row's padding lane, or the bilinear window's pixel past its last, reads past the last
/// pixel). The same floats as converting at each window.
pub(crate) struct Planes {
    left: Vec<f32>,
    grad: Vec<f32>,
    right: Vec<f32>,
}

impl Planes {
    pub(crate) fn new(left: &[u8], right: &[u8]) -> Self {
        let plane = |img: &[u8]| -> Vec<f32> {
            img.iter().map(|&p| f32::from(p)).chain([0.0; 2 * ROW]).collect()
        };
        let left = plane(left);
        let n = left.len();
        let grad = (0..n)
            .map(|i| if i == 0 || i + 1 == n { 0.0 } else { 0.5 * (left[i + 1] - left[i - 1]) })
            .collect();
        Planes { left, grad, right: plane(right) }
    }
}

/// The [`ROW`] values of `plane` from `start`.
#[inline(always)]
fn lanes_at(plane: &[f32], start: usize) -> Lanes {
    plane[start..start + ROW].try_into().expect("inside the padded plane")
}

/// The refined right `u` of left pixel `(x, y)` at `disparity` for a rectified pair of
/// cameras alike ([`refine`]), `None` where a step is not taken: the derivative is the left
/// window's (central differences along its row, computed once), not the right one's at each
/// step (the inverse-compositional form of Lucas-Kanade: one right window per step instead of
/// three; at the match the two derivatives agree up to the gain). In `f32`, a window row per
/// 8-lane vector ([`Lanes`]); the windows are centred on their means before any sum of
/// squares, so that no large sums cancel.
#[inline(always)]
fn refined_rectified<O: RowOps>(
    o: O,
    geo: &Geo,
    planes: &Planes,
    (x, y): (usize, usize),
    disparity: f32,
) -> Option<f64> {
    let [u] = refined_rectified_lanes(o, geo, planes, y, [(x, disparity)]);
    u
}

/// [`refined_rectified`] of `K` pixels of row `y` at once (each `(x, disparity)`), step by
/// step side by side: each pixel's chain of window sums is latency-bound and the chains are
/// independent, so the processor overlaps them. Each pixel gets the same operations in the
/// same order whatever `K` (a unit test compares four pixels with one at a time). A pixel
/// refused on the way is carried along without its windows and answers `None`.
#[inline(always)]
fn refined_rectified_lanes<O: RowOps, const K: usize>(
    o: O,
    geo: &Geo,
    planes: &Planes,
    y: usize,
    px: [(usize, f32); K],
) -> [Option<f64>; K] {
    const N: f32 = (REFINE_SIDE * REFINE_SIDE) as f32;
    let (w, h) = (geo.w, geo.h);
    let half = REFINE_HALF as usize;
    // Plain loops (no closures) here and below: a closure would not be compiled for the
    // instruction set of the vectorised caller.
    let mut alive = [true; K];
    let mut lines = [(0.0f64, 0.0f64); K];
    let mut lw = [[o.zero(); REFINE_SIDE]; K];
    let mut gl = [[o.zero(); REFINE_SIDE]; K];
    for i in 0..K {
        let x = px[i].0;
        // One column more on each side for the central differences.
        match geo.line(x, y) {
            Some(line) if window_inside((w, h), (x, y), REFINE_HALF, 1) => lines[i] = line,
            _ => {
                alive[i] = false;
                continue;
            }
        }
        for j in 0..REFINE_SIDE {
            // The window's pixels x - 3 ..= x + 3 (inside: checked above; the padding lane
            // reads whatever follows).
            let r = (y + j - half) * w + x - half;
            lw[i][j] = o.masked(o.load(&planes.left, r));
            gl[i][j] = o.masked(o.load(&planes.grad, r));
        }
    }
    let mut lmean = [0.0f32; K];
    for i in 0..K {
        lmean[i] = window_sum(o, &lw[i]) / N;
        for row in lw[i].iter_mut() {
            *row = o.masked(o.minus(*row, lmean[i]));
        }
    }
    let (mut lvar, mut den, mut sgl) = ([0.0f32; K], [0.0f32; K], [0.0f32; K]);
    for i in 0..K {
        lvar[i] = window_dot(o, &lw[i], &lw[i]);
        let sg = window_sum(o, &gl[i]);
        den[i] = window_dot(o, &gl[i], &gl[i]) - sg * (sg / N);
        sgl[i] = window_dot(o, &gl[i], &lw[i]);
        // Refusals as written (their converse would differ for NaN).
        let refused = lvar[i] < 1e-6 || den[i] <= 1e-9;
        alive[i] &= !refused;
    }
    let mut u0 = [0.0f64; K];
    for i in 0..K {
        u0[i] = px[i].0 as f64 - f64::from(px[i].1);
    }
    let mut u = u0;
    for _ in 0..2 {
        let mut rw = [[o.zero(); REFINE_SIDE]; K];
        for i in 0..K {
            if alive[i] {
                let v = lines[i].0 + lines[i].1 * u[i];
                match right_window_lanes(o, &planes.right, (w, h), (u[i], v)) {
                    Some(r) => rw[i] = r,
                    None => alive[i] = false,
                }
            }
        }
        let (mut rvar, mut sgr) = ([0.0f32; K], [0.0f32; K]);
        for i in 0..K {
            let rmean = window_sum(o, &rw[i]) / N;
            for row in rw[i].iter_mut() {
                *row = o.masked(o.minus(*row, rmean));
            }
            rvar[i] = window_dot(o, &rw[i], &rw[i]);
            sgr[i] = window_dot(o, &gl[i], &rw[i]);
        }
        for i in 0..K {
            let flat = rvar[i] < 1e-6;
            alive[i] &= !flat;
            if alive[i] {
                let gain = (lvar[i] / rvar[i]).sqrt();
                let num = sgl[i] - gain * sgr[i];
                u[i] += f64::from((num / den[i]).clamp(-0.5, 0.5));
            }
        }
    }
    let mut out = [None; K];
    for i in 0..K {
        if alive[i] && (u[i] - u0[i]).abs() <= 0.5 {
            out[i] = Some(u[i]);
        }
    }
    out
}

/// The rectified refinement of row `y`'s winners, its matched pixels [`BATCH`] at a time
/// ([`refined_rectified_lanes`]), the last few one at a time. Plain loops, no closures:
/// this runs inside the vectorised body.
#[inline(always)]
fn refine_row_rectified<O: RowOps>(
    o: O,
    geo: &Geo,
    planes: &Planes,
    y: usize,
    row: &mut [Option<Best>],
) {
    let mut waiting = [(0usize, 0.0f32); BATCH];
    let mut n = 0;
    for x in 0..row.len() {
        let Some(b) = row[x] else { continue };
        waiting[n] = (x, b.disparity);
        n += 1;
        if n < BATCH {
            continue;
        }
        n = 0;
        let u = refined_rectified_lanes(o, geo, planes, y, waiting);
        for (&(x, _), u) in waiting.iter().zip(u) {
            if let (Some(u), Some(b)) = (u, &mut row[x]) {
                b.disparity = (x as f64 - u) as f32;
            }
        }
    }
    for &(x, d) in &waiting[..n] {
        if let (Some(u), Some(b)) = (refined_rectified(o, geo, planes, (x, y), d), &mut row[x]) {
            b.disparity = (x as f64 - u) as f32;
        }
    }
}

/// Pixels refined side by side by [`refine_row_rectified`] (their latency-bound chains of
/// window sums overlap): on Motorcycle's matches the refinement took 37.2 ms on one core two
/// at a time and 35.7 ms four at a time (stage timers, 2026-12-06).
const BATCH: usize = 4;

/// [`RowOps`] in AVX registers, a window row per register (pulp's safe `V3` intrinsics): the
/// compiler had vectorised [`Rows8`]'s rows as 4-lane pieces and scalars.
#[cfg(target_arch = "x86_64")]
mod avx {
    use super::{RowOps, ROW};
    use core::arch::x86_64::__m256;
    use pulp::x86::V3;

    /// All bits of the window's lanes, none of the padding lane.
    const KEEP: [u32; ROW] =
        [u32::MAX, u32::MAX, u32::MAX, u32::MAX, u32::MAX, u32::MAX, u32::MAX, 0];

    #[derive(Clone, Copy)]
    pub(super) struct Rows(pub V3);

    impl RowOps for Rows {
        type R = __m256;
        #[inline(always)]
        fn zero(self) -> __m256 {
            self.0.avx._mm256_set1_ps(0.0)
        }
        #[inline(always)]
        fn load(self, plane: &[f32], at: usize) -> __m256 {
            pulp::cast(super::lanes_at(plane, at))
        }
        #[inline(always)]
        fn masked(self, v: __m256) -> __m256 {
            self.0.avx._mm256_and_ps(v, pulp::cast(KEEP))
        }
        #[inline(always)]
        fn minus(self, v: __m256, s: f32) -> __m256 {
            self.0.avx._mm256_sub_ps(v, self.0.avx._mm256_set1_ps(s))
        }
        #[inline(always)]
        fn lerp(self, a: __m256, wa: f32, b: __m256, wb: f32) -> __m256 {
            let avx = self.0.avx;
            avx._mm256_add_ps(
                avx._mm256_mul_ps(a, avx._mm256_set1_ps(wa)),
                avx._mm256_mul_ps(b, avx._mm256_set1_ps(wb)),
            )
        }
        #[inline(always)]
        fn add(self, acc: __m256, v: __m256) -> __m256 {
            self.0.avx._mm256_add_ps(acc, v)
        }
        #[inline(always)]
        fn add_product(self, acc: __m256, v: __m256, u: __m256) -> __m256 {
            self.0.avx._mm256_add_ps(acc, self.0.avx._mm256_mul_ps(v, u))
        }
        #[inline(always)]
        fn total(self, v: __m256) -> f32 {
            let simd = self.0;
            let lo = simd.avx._mm256_castps256_ps128(v);
            let hi = simd.avx._mm256_extractf128_ps::<1>(v);
            let s: [f32; 4] = pulp::cast(simd.sse._mm_add_ps(lo, hi));
            (s[0] + s[1]) + (s[2] + s[3])
        }
    }
}

/// The bilinear 7 x 7 window of `img` centred at `(x, y)`, a row per [`Lanes`] (padding lane
/// 0), or `None` unless the whole window lies inside the image. The samples share
/// their fractional offsets: the rows of whole pixels interpolated along x, then along y.
#[inline(always)]
fn right_window_lanes<O: RowOps>(
    o: O,
    img: &[f32],
    (w, h): (usize, usize),
    (x, y): (f64, f64),
) -> Option<[O::R; REFINE_SIDE]> {
    let half = REFINE_HALF as f64;
    let (bx, by) = (x - half, y - half);
    if !(bx >= 0.0 && by >= 0.0 && x + half <= (w - 1) as f64 && y + half <= (h - 1) as f64) {
        return None;
    }
    let (x0, y0) = (bx as usize, by as usize);
    let (fx, fy) = ((bx - x0 as f64) as f32, (by - y0 as f64) as f32);
    let mut rows = [o.zero(); REFINE_SIDE + 1];
    for (r, row) in rows.iter_mut().enumerate() {
        // Pixels x0 ..= x0 + 8 of the row; only the padding lane reads the last one, and a
        // window whose right (bottom) edge lies on the image's takes the pixel (row) past it
        // with weight 0 (the last row stands in for the one past it).
        let a = (y0 + r).min(h - 1) * w + x0;
        *row = o.lerp(o.load(img, a), 1.0 - fx, o.load(img, a + 1), fx);
    }
    let mut out = [o.zero(); REFINE_SIDE];
    for (j, v) in out.iter_mut().enumerate() {
        *v = o.masked(o.lerp(rows[j], 1.0 - fy, rows[j + 1], fy));
    }
    Some(out)
}

/// The refined right `u` of left pixel `(x, y)` from `u0` ([`refine`] with the right window
/// under the pixel's local `warp`, [`local_warps`]), `None` where the step is not taken.
#[inline(always)]
fn refined_warped(
    geo: &Geo,
    (left, right): (&[u8], &[f32]),
    (x, y): (usize, usize),
    u0: f64,
    warp: [f64; 2],
) -> Option<f64> {
    // Inlined, so that it is compiled for the instruction set [`refine`] runs.
    lucas_kanade::<WARP_REFINE_HALF, WARP_REFINE_N>(
        geo,
        left,
        (x, y),
        u0,
        1,
        #[inline(always)]
        |u, rw, gw| warped_window_samples(right, geo, (x, y), u, warp, rw, gw),
    )
}

/// Whether the window of half size `half` of pixel `(x, y)`, widened by `margin` columns on
/// each side, lies inside an image of `w x h`.
#[inline(always)]
fn window_inside((w, h): (usize, usize), (x, y): (usize, usize), half: i64, margin: i64) -> bool {
    let (xi, yi) = (x as i64, y as i64);
    xi >= half + margin && yi >= half && xi + half + margin < w as i64 && yi + half < h as i64
}

/// The window of half size `H` (`N` = `(2 H + 1)^2` pixels) of left pixel `(x, y)` (image
/// `w x h`), less its mean, and its sum of squared deviations; `None` where the window,
/// widened by `margin` columns on each side, leaves the image, or where it is flat.
#[inline(always)]
fn left_window<const H: usize, const N: usize>(
    left: &[u8],
    (w, h): (usize, usize),
    (x, y): (usize, usize),
    margin: i64,
) -> Option<([f64; N], f64)> {
    const { assert!(N == (2 * H + 1) * (2 * H + 1)) };
    let side = 2 * H + 1;
    if !window_inside((w, h), (x, y), H as i64, margin) {
        return None;
    }
    let mut lw = [0.0f64; N];
    for (j, out) in lw.chunks_exact_mut(side).enumerate() {
        let r = (y + j - H) * w + x - H;
        for (o, &p) in out.iter_mut().zip(&left[r..r + side]) {
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
    Some((lw, lvar))
}

/// `steps` Gauss-Newton steps of [`refine`] for left pixel `(x, y)` from right `u0`:
/// `sample(u, window, slope)` fills the right window whose centre is at right `u` and its
/// derivative along the line (`false` outside the image). The window sums are gathered in
/// one sweep each (six independent running sums, not a chain of means then deviations): `sum
/// (r - mean r)^2 = sum r^2 - mean r sum r` and the like, the same quantities to rounding.
#[inline(always)]
fn lucas_kanade<const H: usize, const N: usize>(
    geo: &Geo,
    left: &[u8],
    (x, y): (usize, usize),
    u0: f64,
    steps: usize,
    sample: impl Fn(f64, &mut [f64], &mut [f64]) -> bool,
) -> Option<f64> {
    let (lw, lvar) = left_window::<H, N>(left, (geo.w, geo.h), (x, y), 0)?;
    let n = N as f64;
    let mut u = u0;
    for _ in 0..steps {
        // Right window and its derivative along the line.
        let mut rw = [0.0f64; N];
        let mut gw = [0.0f64; N];
        if !sample(u, &mut rw, &mut gw) {
            return None;
        }
        let (mut sr, mut srr, mut sg, mut sgg, mut sgl, mut sgr) = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
        for k in 0..N {
            let (r, g, l) = (rw[k], gw[k], lw[k]);
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

/// The Catmull-Rom weights of the four samples around an offset `t` in `0..1`.
#[inline(always)]
fn cubic_weights(t: f32) -> [f32; 4] {
    let (t2, t3) = (t * t, t * t * t);
    [
        -0.5 * t3 + t2 - 0.5 * t,
        1.5 * t3 - 2.5 * t2 + 1.0,
        -1.5 * t3 + 2.0 * t2 + 0.5 * t,
        0.5 * t3 - 0.5 * t2,
    ]
}

/// The derivatives of [`cubic_weights`] with respect to `t`.
#[inline(always)]
fn cubic_slopes(t: f32) -> [f32; 4] {
    let t2 = t * t;
    [-1.5 * t2 + 2.0 * t - 0.5, 4.5 * t2 - 5.0 * t, -4.5 * t2 + 4.0 * t + 0.5, 1.5 * t2 - t]
}

/// The right window of left pixel `(x, y)` centred at right `u` under `warp`, into `out`, and
/// its derivative along the epipolar lines into `slope`: the sample of left pixel
/// `(x + i, y + j)` lies at right `u + warp[0] i + warp[1] j`, on that pixel's own epipolar line
/// (bicubic, Catmull-Rom: less pull towards whole pixels than bilinear, which matters once
/// the samples no longer share their fractional offsets); `false` if one lies outside the
/// image (within a pixel of its border) or the line is steeper than 45 degrees.
#[inline(always)]
fn warped_window_samples(
    img: &[f32],
    geo: &Geo,
    (x, y): (usize, usize),
    u: f64,
    warp: [f64; 2],
    out: &mut [f64],
    slope: &mut [f64],
) -> bool {
    const N: usize = WARP_REFINE_N;
    let (m, w, h) = (&geo.m, geo.w, geo.h);
    let half = WARP_REFINE_HALF as f64;
    // Every sample's place and its line's slope first (the line of left pixel (x + i, y + j)
    // is m (x + i, y + j, 1)^T, linear in i and j), then the interpolation weights, then the
    // samples: each loop over the window's pixels without branches, so that the first two run
    // in vector lanes (a window off the image or on a steep line is refused after the first).
    let l0: [f64; 3] = core::array::from_fn(|r| m[r][0] * x as f64 + m[r][1] * y as f64 + m[r][2]);
    let mut base = [0usize; N];
    let (mut tx, mut ty, mut betas) = ([0.0f32; N], [0.0f32; N], [0.0f32; N]);
    let mut inside = true;
    let (u_end, v_end) = ((w - 2) as f64, (h - 2) as f64);
    for k in 0..N {
        let (fi, fj) = ((k % WARP_REFINE_SIDE) as f64 - half, (k / WARP_REFINE_SIDE) as f64 - half);
        let l: [f64; 3] = core::array::from_fn(|r| l0[r] + m[r][0] * fi + m[r][1] * fj);
        inside &= l[1].abs() >= l[0].abs();
        // The line v = alpha + beta u of this left pixel.
        let inv = 1.0 / l[1];
        let beta = -l[0] * inv;
        let us = u + warp[0] * fi + warp[1] * fj;
        let vs = -l[2] * inv + beta * us;
        inside &= us >= 1.0 && vs >= 1.0 && us < u_end && vs < v_end;
        // Saturating casts: a place off the image gives some index, never used.
        let (x0, y0) = (us as usize, vs as usize);
        base[k] = y0.wrapping_sub(1).wrapping_mul(w).wrapping_add(x0).wrapping_sub(1);
        tx[k] = (us - x0 as f64) as f32;
        ty[k] = (vs - y0 as f64) as f32;
        betas[k] = beta as f32;
    }
    if !inside {
        return false;
    }
    let mut wx = [[0.0f32; N]; 4];
    let mut dx = [[0.0f32; N]; 4];
    let mut wy = [[0.0f32; N]; 4];
    let mut dy = [[0.0f32; N]; 4];
    for k in 0..N {
        let (a, b, c, d) =
            (cubic_weights(tx[k]), cubic_slopes(tx[k]), cubic_weights(ty[k]), cubic_slopes(ty[k]));
        for t in 0..4 {
            wx[t][k] = a[t];
            dx[t][k] = b[t];
            wy[t][k] = c[t];
            dy[t][k] = d[t];
        }
    }
    // The 4 x 4 pixels around each place, gathered tap by tap.
    let mut taps = [[[0.0f32; N]; 4]; 4];
    for k in 0..N {
        for (r, row) in taps.iter_mut().enumerate() {
            let at = base[k] + r * w;
            let p: &[f32; 4] = img[at..at + 4].try_into().expect("4 samples");
            for c in 0..4 {
                row[c][k] = p[c];
            }
        }
    }
    let (mut val, mut gx, mut gy) = ([0.0f32; N], [0.0f32; N], [0.0f32; N]);
    for (r, p) in taps.iter().enumerate() {
        for k in 0..N {
            let sv =
                p[0][k] * wx[0][k] + p[1][k] * wx[1][k] + p[2][k] * wx[2][k] + p[3][k] * wx[3][k];
            let sd =
                p[0][k] * dx[0][k] + p[1][k] * dx[1][k] + p[2][k] * dx[2][k] + p[3][k] * dx[3][k];
            val[k] += wy[r][k] * sv;
            gx[k] += wy[r][k] * sd;
            gy[k] += dy[r][k] * sv;
        }
    }
    for k in 0..N {
        out[k] = f64::from(val[k]);
        slope[k] = f64::from(gx[k] + betas[k] * gy[k]);
    }
    true
}

/// Half size of the neighbourhood of [`local_warps`] (9 x 9).
const WARP_HALF: usize = 4;

/// The local map of each left pixel's neighbourhood into the right image from the matches
/// `ur` (right `u` of each left pixel, NaN where none; [`refine`] passes the winners before
/// refinement, whose sub-pixel noise the 81-pixel fit averages), for the pixels of `rows`:
/// `[du_r/dx, du_r/dy]` of the least-squares plane through the matched pixels of its 9 x 9
/// neighbourhood (box sums over summed-area tables of the rows it needs), `None` with fewer
/// than half of them matched or a degenerate fit. A slanted surface, a right camera of
/// another scale or one rolled against the left all show here as a gradient of `u_r` that a
/// window of fixed shape would not follow.
fn local_warps(
    ur: &[f64],
    w: usize,
    h: usize,
    rows: std::ops::Range<usize>,
) -> Vec<Option<[f64; 2]>> {
    // Summed-area tables of 1, x, y, x^2, y^2, xy, u, xu, yu over the matched pixels of the
    // rows the band's neighbourhoods reach (table row t sums image rows lo..lo + t), with x, y
    // relative to the image centre (smaller sums, less cancellation).
    const K: usize = 9;
    let r = WARP_HALF;
    let (lo, hi) = (rows.start.saturating_sub(r), (rows.end + r).min(h));
    let (cx, cy) = (w as f64 / 2.0, h as f64 / 2.0);
    let stride = w + 1;
    let mut sat = vec![[0.0f64; K]; stride * (hi - lo + 1)];
    for y in lo..hi {
        let t = y - lo;
        let mut row = [0.0f64; K];
        for x in 0..w {
            let u = ur[y * w + x];
            if u.is_finite() {
                let (xf, yf) = (x as f64 - cx, y as f64 - cy);
                let v = [1.0, xf, yf, xf * xf, yf * yf, xf * yf, u, xf * u, yf * u];
                for (r, v) in row.iter_mut().zip(v) {
                    *r += v;
                }
            }
            let above = sat[t * stride + x + 1];
            sat[(t + 1) * stride + x + 1] = core::array::from_fn(|k| above[k] + row[k]);
        }
    }
    let need = ((2 * r + 1) * (2 * r + 1) / 2) as f64;
    (rows.start * w..rows.end * w)
        .into_par_iter()
        .map(|p| {
            let (x, y) = (p % w, p / w);
            if !ur[p].is_finite() || x < r || y < r || x + r >= w || y + r >= h {
                return None;
            }
            let (x0, y0, x1, y1) = (x - r, y - r - lo, x + r + 1, y + r + 1 - lo);
            let s: [f64; K] = core::array::from_fn(|k| {
                sat[y1 * stride + x1][k] - sat[y0 * stride + x1][k] - sat[y1 * stride + x0][k]
                    + sat[y0 * stride + x0][k]
            });
            let n = s[0];
            if n < need {
                return None;
            }
            // Centred moments.
            let (mx, my, mu) = (s[1] / n, s[2] / n, s[6] / n);
            let sxx = s[3] - n * mx * mx;
            let syy = s[4] - n * my * my;
            let sxy = s[5] - n * mx * my;
            let sxu = s[7] - n * mx * mu;
            let syu = s[8] - n * my * mu;
            let det = sxx * syy - sxy * sxy;
            if det.is_nan() || det <= 1e-6 * sxx * syy {
                return None;
            }
            let a = (sxu * syy - syu * sxy) / det;
            let b = (syu * sxx - sxu * sxy) / det;
            (a.is_finite() && b.is_finite()).then_some([a, b])
        })
        .collect()
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
    let (w, n) = (geo.w, geo.w * geo.h);
    let (mut ur, mut vr, mut conf) =
        (vec![f32::INFINITY; n], vec![f32::INFINITY; n], vec![0.0f32; n]);
    // Row by row, in parallel (each pixel on its own: the same values either way).
    ur.par_chunks_mut(w.max(1))
        .zip(vr.par_chunks_mut(w.max(1)))
        .zip(conf.par_chunks_mut(w.max(1)))
        .zip(best.par_chunks(w.max(1)))
        .enumerate()
        .for_each(|(y, (((ur, vr), conf), best))| {
            for (x, b) in best.iter().enumerate() {
                let Some(b) = b else { continue };
                let Some((alpha, beta)) = geo.line(x, y) else {
                    continue;
                };
                let u = x as f64 - f64::from(b.disparity);
                ur[x] = u as f32;
                vr[x] = (alpha + beta * u) as f32;
                conf[x] = confidence(b.s1, b.s2, b.lr, tol);
            }
        });
    DenseMap { width: w as u32, height: geo.h as u32, ur, vr, conf }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// [`shifted_zsad`] by its definition: every shift of the 5 x 5 window that lies inside
    /// both images, its zero-mean absolute differences times 25, the least; near the borders
    /// and for disparities that push the right window out.
    #[test]
    fn shifted_zsad_is_its_definition() {
        let (w, h) = (23usize, 17usize);
        let mut st = 9u64;
        let mut img = || -> Vec<u8> {
            (0..w * h)
                .map(|_| (hvs_shared::test_support::splitmix64(&mut st) >> 56) as u8)
                .collect()
        };
        let (l, r) = (img(), img());
        for y in 0..h {
            for x in 0..w {
                for d in [-3i64, 0, 2, 7, 30] {
                    let mut want = u32::MAX;
                    for sy in -2..=2i64 {
                        'shift: for sx in -2..=2i64 {
                            let mut px = Vec::new();
                            for j in -2..=2i64 {
                                for i in -2..=2i64 {
                                    let (u, v) = (x as i64 + sx + i, y as i64 + sy + j);
                                    let inside = |u: i64| u >= 0 && u < w as i64;
                                    if v < 0 || v >= h as i64 || !inside(u) || !inside(u - d) {
                                        continue 'shift;
                                    }
                                    let k = v as usize * w;
                                    px.push(
                                        i64::from(l[k + u as usize])
                                            - i64::from(r[k + (u - d) as usize]),
                                    );
                                }
                            }
                            let sum: i64 = px.iter().sum();
                            let cost: i64 = px.iter().map(|v| (25 * v - sum).abs()).sum();
                            want = want.min(cost as u32);
                        }
                    }
                    let got = shifted_zsad((&l, &r), (w, h), (x, y), d, 0);
                    assert_eq!(got, want, "({x}, {y}) d {d}");
                    // With a bound it stops early, never above the true least once below it.
                    let bounded = shifted_zsad((&l, &r), (w, h), (x, y), d, want.saturating_add(1));
                    assert!(
                        bounded >= want && (bounded < want.saturating_add(1) || want == u32::MAX)
                    );
                }
            }
        }
    }

    /// A foreground square (disparity 12) over a background (4), its winners spread two
    /// pixels onto the background on either side, as a census window across the edge does:
    /// [`edge_switch`] gives the spread pixels right of the square (background both cameras
    /// see) the background's disparity back, and leaves the square's own. Left of it the
    /// background is hidden from the right camera (8 px): nothing fits there, nothing is
    /// claimed.
    #[test]
    fn edge_switch_takes_back_what_the_foreground_spread() {
        let (w, h) = (80usize, 60usize);
        let mut st = 17u64;
        let mut tex = |n: usize| -> Vec<u8> {
            (0..n).map(|_| (hvs_shared::test_support::splitmix64(&mut st) >> 56) as u8).collect()
        };
        let (bg, fg) = (tex(w * h), tex(w * h));
        let on_square = |x: usize, y: usize| (30..50).contains(&x) && (20..40).contains(&y);
        // The scene's texture at left pixel (x, y): the square's fixed to it, the wall's too.
        let left: Vec<u8> =
            (0..w * h).map(|p| if on_square(p % w, p / w) { fg[p] } else { bg[p] }).collect();
        // The right image: the wall shifted by 4, the square by 12 (drawn over the wall).
        let mut right = vec![0u8; w * h];
        for y in 0..h {
            for u in 0..w {
                let xw = u + 4;
                right[y * w + u] = if xw < w { bg[y * w + xw] } else { 0 };
                let xs = u + 12;
                if xs < w && on_square(xs, y) {
                    right[y * w + u] = fg[y * w + xs];
                }
            }
        }
        let truth = |x: usize, y: usize| if on_square(x, y) { 12.0 } else { 4.0 };
        let fat = |x: usize, y: usize| (28..52).contains(&x) && (20..40).contains(&y);
        let winner = |d: f32| Some(Best { disparity: d, s1: 1, s2: 100, lr: 0.0 });
        let mut best: Vec<Option<Best>> = (0..w * h)
            .map(|p| {
                let (x, y) = (p % w, p / w);
                winner(if fat(x, y) { 12.0 } else { truth(x, y) })
            })
            .collect();
        let geo = Geo { m: [[0.0; 3]; 3], sign: -1, d_min: 0, d: 20, w, h };
        edge_switch(&geo, (&left, &right), &mut best);
        let (mut back, mut spread, mut kept) = (0, 0, true);
        for y in 22..38 {
            for x in 20..60 {
                let d = best[y * w + x].unwrap().disparity;
                if fat(x, y) && x >= 50 {
                    spread += 1;
                    back += usize::from(d == 4.0);
                } else if on_square(x, y) && (32..48).contains(&x) {
                    kept &= d == 12.0;
                }
            }
        }
        assert!(kept, "the square's inside lost its disparity");
        assert_eq!((back, spread), (32, 32), "spread pixels taken back, of the spread");
    }

    /// [`refined_rectified`] as first written, in `f64` sample by sample.
    fn refined_rectified_f64(
        geo: &Geo,
        (left, right): (&[u8], &[u8]),
        (x, y): (usize, usize),
        disparity: f32,
    ) -> Option<f64> {
        const N: usize = REFINE_SIDE * REFINE_SIDE;
        let (alpha, beta) = geo.line(x, y)?;
        let (w, h) = (geo.w, geo.h);
        // One column more on each side for the central differences.
        let (lw, lvar) = left_window::<{ REFINE_HALF as usize }, N>(left, (w, h), (x, y), 1)?;
        let half = REFINE_HALF as usize;
        let mut gl = [0.0f64; N];
        for j in 0..REFINE_SIDE {
            let r = (y + j - half) * w + x - half;
            for i in 0..REFINE_SIDE {
                gl[j * REFINE_SIDE + i] =
                    0.5 * (f64::from(left[r + i + 1]) - f64::from(left[r + i - 1]));
            }
        }
        let n = N as f64;
        let (mut sg, mut sgg) = (0.0, 0.0);
        for &g in &gl {
            sg += g;
            sgg += g * g;
        }
        let den = sgg - sg * (sg / n);
        if den <= 1e-9 {
            return None;
        }
        let mut sgl = 0.0;
        for k in 0..N {
            sgl += gl[k] * lw[k];
        }
        let u0 = x as f64 - f64::from(disparity);
        let mut u = u0;
        let mut rw = [0.0f64; N];
        for _ in 0..2 {
            let v = alpha + beta * u;
            if !scaled_window_samples(right, (w, h), (u, v), [1.0, 1.0], &mut rw) {
                return None;
            }
            let (mut sr, mut srr, mut sgr) = (0.0, 0.0, 0.0);
            for k in 0..N {
                sr += rw[k];
                srr += rw[k] * rw[k];
                sgr += gl[k] * rw[k];
            }
            let rmean = sr / n;
            let rvar = srr - sr * rmean;
            if rvar < 1e-6 {
                return None;
            }
            let gain = (lvar / rvar).sqrt();
            let num = sgl - gain * (sgr - sg * rmean);
            u += (num / den).clamp(-0.5, 0.5);
        }
        ((u - u0).abs() <= 0.5).then_some(u)
    }

    /// [`right_from_left_row`] as first written, right pixel by right pixel.
    fn right_from_left_row_reference(geo: &Geo, sums: &[i16]) -> Vec<Option<f32>> {
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

    /// A rectified 61 x 33 pair of random grey levels for the refinement's tests: a flat
    /// patch in the corner (refused), elsewhere a ramp with noise.
    fn refinement_pair(mut seed: u64) -> (Geo, Planes) {
        let (w, h) = (61usize, 33usize);
        let mut grey = |k: usize| -> u8 {
            let r = hvs_shared::test_support::splitmix64(&mut seed);
            if k % w < 12 && k / w < 10 {
                90
            } else {
                ((k % w) as u64 * 3 + (k / w) as u64 * 5 + r % 40) as u8
            }
        };
        let left: Vec<u8> = (0..w * h).map(&mut grey).collect();
        let right: Vec<u8> = (0..w * h).map(&mut grey).collect();
        let m = [[0.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]];
        (Geo { m, sign: -1, d_min: 0, d: 20, w, h }, Planes::new(&left, &right))
    }

    /// Four pixels refined side by side (portable and AVX forms) give the bits of each
    /// refined alone: neighbours and far pixels, every pixel of random grey levels (flat
    /// patches, edges and starts beyond the image refused), each with other starts.
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn the_batched_refinement_has_the_single_bits() {
        let simd = pulp::x86::V3::try_new().expect("the AVX2 build is tested on a CPU with AVX2");
        let (geo, planes) = refinement_pair(0x9a1du64);
        let (w, h) = (geo.w, geo.h);
        let ds = [-0.5f32, 0.0, 0.37, 3.0, 7.25, 12.5, 20.0, 57.0];
        let (mut some, mut none) = (0, 0);
        for y in 0..h {
            for x in 0..w {
                // Neighbours and far pixels, every disparity against others.
                for x2 in [(x + 1) % w, (x + 29) % w] {
                    for i in 0..ds.len() {
                        let px: [(usize, f32); 4] = core::array::from_fn(|k| {
                            let at = [x, x2, (x2 + 1) % w, (x + 5 * k) % w][k];
                            (at, ds[(i + k * (3 + x)) % ds.len()])
                        });
                        let single =
                            px.map(|(x, d)| refined_rectified(Rows8, &geo, &planes, (x, y), d));
                        let batch = refined_rectified_lanes(Rows8, &geo, &planes, y, px);
                        let vector = simd.vectorize(|| {
                            refined_rectified_lanes(avx::Rows(simd), &geo, &planes, y, px)
                        });
                        let bits = |r: [Option<f64>; 4]| r.map(|u| u.map(f64::to_bits));
                        assert_eq!(bits(batch), bits(single), "{px:?}, {y}");
                        assert_eq!(bits(vector), bits(single), "{px:?}, {y}");
                        for r in single {
                            if r.is_some() {
                                some += 1;
                            } else {
                                none += 1;
                            }
                        }
                    }
                }
            }
        }
        // Both outcomes were met, refused pixels among them (borders, the flat patch).
        assert!(some > 1000 && none > 1000, "{some} refined, {none} refused");
    }

    /// The AVX form of the rectified refinement gives the portable form's answers bit for
    /// bit: random grey levels (flat patches too, which both refuse), every pixel, starts
    /// off by up to half a pixel either way, edges of the image included.
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn the_avx_refinement_has_the_portable_bits() {
        let simd = pulp::x86::V3::try_new().expect("the AVX2 build is tested on a CPU with AVX2");
        let (geo, planes) = refinement_pair(0x5eedu64);
        let (w, h) = (geo.w, geo.h);
        let (mut some, mut none) = (0, 0);
        for y in 0..h {
            for x in 0..w {
                for d in [-0.5f32, 0.0, 0.37, 3.0, 7.25, 12.5, 20.0] {
                    let portable = refined_rectified(Rows8, &geo, &planes, (x, y), d);
                    let vector = simd
                        .vectorize(|| refined_rectified(avx::Rows(simd), &geo, &planes, (x, y), d));
                    assert_eq!(
                        portable.map(f64::to_bits),
                        vector.map(f64::to_bits),
                        "({x}, {y}) {d}"
                    );
                    if portable.is_some() {
                        some += 1;
                    } else {
                        none += 1;
                    }
                }
            }
        }
        assert!(some > 5000 && none > 500, "{some} refined, {none} refused");
    }

    /// The rectified refinement in `f32` lanes finds the reference's (`f64`, sample by
    /// sample) match within 1e-4 px, and both find the true shift of a smooth texture from
    /// starts up to 0.45 px off; windows at the border are refused by both.
    #[test]
    fn the_lane_refinement_is_the_reference_one() {
        let (w, h, shift) = (90usize, 40usize, 7.3f64);
        let texture = |x: f64, y: f64| {
            128.0 + 50.0 * (0.7 * x + 0.2 * y).sin() + 35.0 * (0.45 * y - 0.6 * x).cos()
        };
        let left: Vec<u8> =
            (0..w * h).map(|k| texture((k % w) as f64, (k / w) as f64).round() as u8).collect();
        let right: Vec<u8> = (0..w * h)
            .map(|k| texture((k % w) as f64 + shift, (k / w) as f64).round() as u8)
            .collect();
        let m = [[0.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]];
        let geo = Geo { m, sign: -1, d_min: 0, d: 20, w, h };
        let planes = Planes::new(&left, &right);
        let (mut both, mut worst_ref, mut worst_true) = (0, 0.0f64, 0.0f64);
        for y in 0..h {
            for x in 0..w {
                for start in [-0.45, -0.2, 0.0, 0.3, 0.45] {
                    let disparity = (shift + start) as f32;
                    let lanes = refined_rectified(Rows8, &geo, &planes, (x, y), disparity);
                    let reference = refined_rectified_f64(&geo, (&left, &right), (x, y), disparity);
                    let inside = x >= 4 && x + 4 < w && y >= 3 && y + 3 < h && x as f64 > 11.0;
                    if !inside {
                        assert_eq!(lanes.is_some(), reference.is_some(), "({x}, {y})");
                        continue;
                    }
                    let (a, b) = (lanes.expect("inside"), reference.expect("inside"));
                    worst_ref = worst_ref.max((a - b).abs());
                    worst_true = worst_true.max((a - (x as f64 - shift)).abs());
                    both += 1;
                }
            }
        }
        assert!(both > 10_000, "{both}");
        assert!(worst_ref < 1e-4, "lanes against f64: {worst_ref} px");
        assert!(worst_true < 0.05, "against the true shift: {worst_true} px");
    }

    /// The right disparities read in the volume's order are the reference's (right pixel by
    /// right pixel), ties, both ends of the range, a negative `d_min` and more than 32,767
    /// disparities included.
    #[test]
    fn right_disparities_are_the_references() {
        let mut seed = 5u64;
        // The last: more disparities than an i16 counts.
        for (w, d, d_min) in
            [(30usize, 7usize, 0i32), (41, 16, 3), (25, 33, -4), (12, 20, 5), (4, 33_000, -2)]
        {
            for _ in 0..20 {
                // Few distinct values: many ties.
                let sums: Vec<i16> = (0..w * d)
                    .map(|_| (hvs_shared::test_support::splitmix64(&mut seed) % 9) as i16)
                    .collect();
                let m = [[0.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]];
                let geo = Geo { m, sign: -1, d_min, d, w, h: 1 };
                let got = right_from_left_row(&geo, &sums);
                let want = right_from_left_row_reference(&geo, &sums);
                assert_eq!(got, want, "w {w}, d {d}, d_min {d_min}");
            }
        }
    }

    /// `first_smallest` is the smallest value and its first index, ties included, at every
    /// length below, at and above its chunk.
    #[test]
    fn the_first_smallest_is_the_scans() {
        let mut seed = 9u64;
        for n in [1usize, 2, 7, 8, 9, 15, 16, 17, 62, 64, 100] {
            for _ in 0..50 {
                let s: Vec<i16> = (0..n)
                    .map(|_| (hvs_shared::test_support::splitmix64(&mut seed) % 5) as i16 * 300)
                    .collect();
                let m = *s.iter().min().unwrap();
                let want = (i32::from(m), s.iter().position(|&v| v == m).unwrap());
                assert_eq!(first_smallest(&s), want, "{s:?}");
                assert_eq!(min_of(&s), m);
            }
        }
    }

    /// A slanted plane: `local_warps` recovers the gradient of `u_r` exactly inside, refuses
    /// near the border and where too few neighbours are matched.
    #[test]
    fn local_warps_are_the_gradient_of_the_matches() {
        let (w, h) = (40usize, 30usize);
        let mut ur: Vec<f64> =
            (0..w * h).map(|k| 3.0 + 0.83 * (k % w) as f64 - 0.07 * (k / w) as f64).collect();
        let warps = local_warps(&ur, w, h, 0..h);
        for y in 0..h {
            for x in 0..w {
                let inside =
                    x >= WARP_HALF && y >= WARP_HALF && x + WARP_HALF < w && y + WARP_HALF < h;
                match warps[y * w + x] {
                    Some([a, b]) => {
                        assert!(inside, "({x}, {y})");
                        assert!((a - 0.83).abs() < 1e-9 && (b + 0.07).abs() < 1e-9, "{a} {b}");
                    }
                    None => assert!(!inside, "({x}, {y})"),
                }
            }
        }
        // A hole: its neighbours keep a fit while most of their window is matched.
        for y in 5..25 {
            for x in 10..30 {
                ur[y * w + x] = f64::NAN;
            }
        }
        let warps = local_warps(&ur, w, h, 0..h);
        assert!(warps[15 * w + 20].is_none() && warps[15 * w + 31].is_some());
        // A band of rows: the whole image's warps of those rows.
        for rows in [0..7, 7..19, 19..h, 3..4] {
            let band = local_warps(&ur, w, h, rows.clone());
            assert_eq!(band.len(), rows.len() * w);
            for (got, want) in band.iter().zip(&warps[rows.start * w..rows.end * w]) {
                match (got, want) {
                    (Some(g), Some(e)) => {
                        assert!((g[0] - e[0]).abs() < 1e-9 && (g[1] - e[1]).abs() < 1e-9)
                    }
                    (g, e) => assert_eq!(g.is_some(), e.is_some()),
                }
            }
        }
        assert!(warps[15 * w + 33]
            .is_some_and(|[a, b]| (a - 0.83).abs() < 1e-9 && (b + 0.07).abs() < 1e-9));
    }

    /// Catmull-Rom bicubic grey level at `(x, y)`, tap by tap.
    fn bicubic(img: &[u8], w: usize, x: f64, y: f64) -> f64 {
        let (x0, y0) = (x.floor() as usize, y.floor() as usize);
        let (wx, wy) =
            (cubic_weights((x - x0 as f64) as f32), cubic_weights((y - y0 as f64) as f32));
        let mut acc = 0.0;
        for j in 0..4 {
            for i in 0..4 {
                let p = f64::from(img[(y0 + j - 1) * w + x0 + i - 1]);
                acc += f64::from(wy[j]) * f64::from(wx[i]) * p;
            }
        }
        acc
    }

    /// The warped window's samples interpolate the image (whole offsets give the pixels), and
    /// its slope is the derivative along the line (against a central difference).
    #[test]
    fn warped_windows_sample_the_image_and_its_slope() {
        let (w, h) = (40usize, 30usize);
        let img: Vec<u8> = (0..w * h)
            .map(|k| {
                (128.0 + 60.0 * ((k % w) as f64 * 0.4).sin() * ((k / w) as f64 * 0.3).cos()) as u8
            })
            .collect();
        let grey: Vec<f32> = img.iter().map(|&p| f32::from(p)).collect();
        // Lines v = y + 0.1 u - 2 (F's row for the line of (x, y): (0.1, -1, y - 2)).
        let m = [[0.0, 0.0, 0.1], [0.0, 0.0, -1.0], [0.0, 1.0, -2.0]];
        let geo = Geo { m, sign: -1, d_min: 0, d: 10, w, h };
        const N: usize = WARP_REFINE_N;
        let (mut out, mut slope) = ([0.0; N], [0.0; N]);
        // Identity warp, whole u on a line through whole pixels: the pixels themselves.
        let (x, y, u) = (20usize, 12usize, 20.0);
        assert!(warped_window_samples(&grey, &geo, (x, y), u, [1.0, 0.0], &mut out, &mut slope));
        let half = WARP_REFINE_HALF as f64;
        for (k, v) in out.iter().enumerate() {
            let (i, j) = (k % WARP_REFINE_SIDE, k / WARP_REFINE_SIDE);
            let (us, ly) = (u + i as f64 - half, y as f64 + j as f64 - half);
            let vs = ly + 0.1 * us - 2.0;
            let want = bicubic(&img, w, us, vs);
            // f32 arithmetic inside.
            assert!((v - want).abs() < 1e-3, "{k}: {v} vs {want}");
            if vs.fract() == 0.0 {
                assert!((v - f64::from(img[vs as usize * w + us as usize])).abs() < 1e-3);
            }
        }
        // The slope against a central difference along the line, at a warped, fractional place.
        let (u, warp) = (17.3, [0.85, -0.04]);
        assert!(warped_window_samples(&grey, &geo, (x, y), u, warp, &mut out, &mut slope));
        let (mut lo, mut hi, mut s2) = ([0.0; N], [0.0; N], [0.0; N]);
        let e = 1e-2;
        assert!(warped_window_samples(&grey, &geo, (x, y), u - e, warp, &mut lo, &mut s2));
        assert!(warped_window_samples(&grey, &geo, (x, y), u + e, warp, &mut hi, &mut s2));
        for k in 0..N {
            let fd = (hi[k] - lo[k]) / (2.0 * e);
            assert!((slope[k] - fd).abs() < 1e-2 * (1.0 + fd.abs()), "{k}: {} vs {fd}", slope[k]);
        }
        // Near the border: refused.
        assert!(!warped_window_samples(&grey, &geo, (x, y), 2.5, warp, &mut out, &mut slope));
    }

    /// A right camera rolled by 3 degrees against the left, at 0.8 times its scale: one warped
    /// step (with the warp the matches' gradient gives) from 0.2 px off finds the true match
    /// within 0.06 px; two steps of the window at the cameras' scale alone do much worse.
    #[test]
    fn a_rolled_right_image_is_refined_with_its_warp() {
        let (w, h, sc) = (90usize, 70usize, 0.8f64);
        let (c, s) = (3f64.to_radians().cos(), 3f64.to_radians().sin());
        let texture = |x: f64, y: f64| {
            128.0
                + 40.0 * (0.9 * x + 0.3 * y).sin()
                + 30.0 * (0.5 * y - 0.7 * x).cos()
                + 20.0 * (1.3 * x).sin() * (1.1 * y).cos()
        };
        // Left (x, y) at right (ur, vr) = sc R (x - 10, y - 5): the right image samples the
        // texture at the inverse map.
        let to_right = |x: f64, y: f64| {
            let (p, q) = (x - 10.0, y - 5.0);
            (sc * (c * p - s * q), sc * (s * p + c * q))
        };
        let left: Vec<u8> =
            (0..w * h).map(|k| texture((k % w) as f64, (k / w) as f64).round() as u8).collect();
        let right: Vec<u8> = (0..w * h)
            .map(|k| {
                let (ur, vr) = ((k % w) as f64 / sc, (k / w) as f64 / sc);
                let (p, q) = (c * ur + s * vr, -s * ur + c * vr);
                texture(p + 10.0, q + 5.0).round() as u8
            })
            .collect();
        // The line of left (x, y) for a pure shift-rotation-scale: the right points of left
        // (x + t, y) over t, v = vr0 + tan(roll) (u - ur0): F's rows give l = (tan, -1, vr0 -
        // tan ur0) linear in (x, y).
        let t = s / c;
        // vr0 - t ur0 = sc (s p + c q) - t sc (c p - s q) = sc q (c + t s) = sc q / c.
        let m = [[0.0, 0.0, t], [0.0, 0.0, -1.0], [0.0, sc / c, -sc * 5.0 / c]];
        let geo = Geo { m, sign: -1, d_min: 0, d: 40, w, h };
        let grey: Vec<f32> = right.iter().map(|&p| f32::from(p)).collect();
        let warp = [sc * c, -sc * s];
        let (mut worst_warped, mut worst_plain, mut n) = (0.0f64, 0.0f64, 0);
        for y in 25..45 {
            for x in 30..60 {
                let (ur, vr) = to_right(x as f64, y as f64);
                // The line of (x, y) goes through the true match.
                let (alpha, beta) = geo.line(x, y).unwrap();
                assert!((alpha + beta * ur - vr).abs() < 1e-9);
                let start = ur + 0.2;
                let warped = refined_warped(&geo, (&left, &grey), (x, y), start, warp);
                let plain =
                    refined(&geo, (&left, &right), [sc, sc], (x, y), (x as f64 - start) as f32);
                let (Some(a), Some(b)) = (warped, plain) else { continue };
                worst_warped = worst_warped.max((a - ur).abs());
                worst_plain = worst_plain.max((b - ur).abs());
                n += 1;
            }
        }
        assert!(n > 500, "{n} refined");
        assert!(worst_warped < 0.06, "warped: worst {worst_warped} px (plain {worst_plain})");
        assert!(
            worst_plain > 2.0 * worst_warped,
            "plain {worst_plain} px, warped {worst_warped} px"
        );
    }

    fn best(d: f32) -> Option<Best> {
        Some(Best { disparity: d, s1: 1, s2: 10, lr: 0.0 })
    }

    /// [`past_gaps`] drops the first match past a run of unmatched pixels when it is more than
    /// 1.5 px nearer than the match before the run, and nothing else: not a smaller step, not
    /// a run at the row's start, not one measured against an earlier match than the one just
    /// before the run.
    #[test]
    fn the_first_nearer_match_past_a_gap_is_dropped() {
        let n = None;
        let rows: [(Vec<Option<Best>>, Vec<bool>); 5] = [
            (vec![best(5.0), n, n, best(10.0), best(10.0)], vec![true, false, false, false, true]),
            (vec![best(5.0), n, best(6.5), best(9.0)], vec![true, false, true, true]),
            (vec![n, n, best(10.0), best(10.0)], vec![false, false, true, true]),
            (vec![best(9.0), n, best(3.0), n, best(4.6)], vec![true, false, true, false, false]),
            (vec![best(2.0), best(8.0), n, best(9.0), n], vec![true, true, false, true, false]),
        ];
        let w = 5;
        let mut all: Vec<Option<Best>> = Vec::new();
        let mut want = Vec::new();
        for (mut row, keep) in rows {
            row.resize(w, None);
            all.extend(row);
            want.extend(keep.into_iter().chain(std::iter::repeat(false)).take(w));
        }
        past_gaps(w, &mut all);
        let kept: Vec<bool> = all.iter().map(Option::is_some).collect();
        assert_eq!(kept, want);
    }

    #[test]
    fn equiangular_subpixel_finds_the_v_tip() {
        // A V with slope 10 and its tip at +0.3: a = 10 * 1.3, b = 10 * 0.3, c = 10 * 0.7.
        assert!((subpixel(13, 3, 7) - 0.3).abs() < 1e-6);
        assert!((subpixel(7, 3, 13) + 0.3).abs() < 1e-6);
        assert_eq!(subpixel(5, 5, 5), 0.0);
        assert_eq!(subpixel(4, 0, 4), 0.0);
    }

    /// The speckle filter as first written: one flood fill over the whole image.
    fn speckle_reference(w: usize, h: usize, best: &mut [Option<Best>], size: usize, range: f32) {
        let mut label = vec![false; w * h];
        for start in 0..w * h {
            if best[start].is_none() || label[start] {
                continue;
            }
            label[start] = true;
            let (mut stack, mut members) = (vec![start], Vec::new());
            while let Some(p) = stack.pop() {
                members.push(p);
                let dp = best[p].map(|b| b.disparity).unwrap_or(f32::NAN);
                let (x, y) = (p % w, p / w);
                let mut near = Vec::new();
                if x > 0 {
                    near.push(p - 1);
                }
                if x + 1 < w {
                    near.push(p + 1);
                }
                if y > 0 {
                    near.push(p - w);
                }
                if y + 1 < h {
                    near.push(p + w);
                }
                for q in near {
                    if let Some(bq) = best[q] {
                        if !label[q] && (bq.disparity - dp).abs() <= range {
                            label[q] = true;
                            stack.push(q);
                        }
                    }
                }
            }
            if members.len() < size {
                for p in members {
                    best[p] = None;
                }
            }
        }
    }

    /// Regions across strips (tall snakes, combs, plateaus with noise, NaN-free gaps) are
    /// dropped as one flood fill over the whole image drops them, at any image size.
    #[test]
    fn strip_labelling_drops_what_one_flood_fill_drops() {
        let mut rng = 99u64;
        let mut next = move || {
            rng = rng.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (rng >> 33) as u32
        };
        for (w, h) in [(1, 1), (1, 100), (100, 1), (7, 33), (40, 64), (33, 97), (121, 130)] {
            for trial in 0..6 {
                let levels = 1 + trial as u32 * 2;
                let mut b: Vec<Option<Best>> = (0..w * h)
                    .map(|p| {
                        let r = next();
                        if r % 7 == 0 {
                            return None;
                        }
                        // Vertical bands of one level (regions that cross many strips) with
                        // noise, or speckled pixels.
                        let band = ((p % w) / 3) as u32 % levels;
                        let d = if r % 5 == 0 { (r / 7 % 17) as f32 } else { band as f32 * 1.7 };
                        best(d + (r % 100) as f32 / 400.0)
                    })
                    .collect();
                for (size, range) in [(4, 1.0f32), (50, 1.0), (200, 0.5), (1, 1.0)] {
                    let mut want = b.clone();
                    speckle_reference(w, h, &mut want, size, range);
                    let mut got = b.clone();
                    speckle_filter(w, h, &mut got, size, range);
                    let kept =
                        |v: &[Option<Best>]| v.iter().map(Option::is_some).collect::<Vec<_>>();
                    assert_eq!(
                        kept(&got),
                        kept(&want),
                        "{w}x{h} trial {trial} size {size} range {range}"
                    );
                }
                b.reverse();
            }
        }
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

    /// The left-right check of a right image at another scale `s` (`du_r / du_l`): the round
    /// trip's miss, in the coarser image's pixels. Left pixel 40 at disparity 15.3 lands at
    /// `u_r = 24.7`, read at right pixel 25, whose consistent match lies at `40 + 0.3 / s`.
    /// At `s = 0.6` a right match 2 left px past it (1.2 right px) is kept with its miss
    /// (`|d - d_r|` = 2.2 px would drop it), 3 left px (1.8) is dropped; at `s = 1.25` (the
    /// left image the coarser) 2 left px is dropped; the scale is the one at the match's
    /// column (1 at the centre, 0.6 there); without a scale the disagreement is `|d - d_r|`.
    #[test]
    fn the_left_right_check_measures_the_round_trip_at_the_right_scale() {
        let w = 60usize;
        let m = [[0.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]];
        let geo = Geo { m, sign: -1, d_min: 0, d: 40, w, h: 1 };
        let (x, d, ur) = (40usize, 15.3f32, 24.7f64);
        let centre = (w as f64 - 1.0) / 2.0;
        let at = |scale: f64, slope: f64| ColumnScale { scale, slope, centre };
        let slope_to_06 = (0.6 - 1.0) / (ur - centre);
        // (scale, left px past the consistent match, kept with this miss).
        let cases: [(Option<ColumnScale>, f64, Option<f32>); 6] = [
            (Some(at(0.6, 0.0)), 2.0, Some(1.2)),
            (Some(at(0.6, 0.0)), 3.0, None),
            (Some(at(0.6, 0.0)), 0.0, Some(0.0)),
            (Some(at(1.25, 0.0)), 2.0, None),
            (Some(at(1.0, slope_to_06)), 2.0, Some(1.2)),
            (None, 0.2, Some(0.2)),
        ];
        let flat = vec![false; w];
        let check = |scale: Option<ColumnScale>, dr: f32| {
            let mut right = vec![None; w];
            right[25] = Some(dr);
            let mut best = vec![None; w];
            best[x] = Some(Best { disparity: d, s1: 10, s2: 100, lr: 0.0 });
            left_right_check(&geo, &mut best, &right, (&flat, &flat), 1.5, scale);
            best[x].map(|b| b.lr)
        };
        for (scale, past, want) in cases {
            let s = scale.map_or(1.0, |c| c.at(ur));
            let dr = (x as f64 + (25.0 - ur) / s + past - 25.0) as f32;
            match (check(scale, dr), want) {
                (Some(g), Some(e)) => assert!((g - e).abs() < 1e-4, "{scale:?} {past}: {g}"),
                (got, _) => assert_eq!(got, want, "{scale:?} {past}"),
            }
        }
        // Without a scale, exactly |d - d_r| (the bits of cameras alike).
        assert_eq!(check(None, 16.1), Some((d - 16.1f32).abs()));
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
