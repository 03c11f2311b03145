//! The census transform (Zabih & Woodfill 1994): each pixel's 7 x 5 neighbourhood as 34 bits
//! (neighbour darker than the centre), compared by Hamming distance. Robust to gain and offset
//! differences between the two cameras.
//!
//! The window: 7 x 5 against 9 x 7 (its penalties and checks swept) and 5 x 3, 7 x 3, 5 x 5,
//! 7 x 7, 9 x 5, 11 x 5 (one setting each) on the Motorcycle pair, then 7 x 5 swept: a smaller
//! window fattens foreground edges less (most errors of 9 x 7 lay along depth edges), and
//! 7 x 5 returned the most pixels at the same error shares (the README's `hvs depth` section).

use image::GrayImage;
use rayon::prelude::*;

/// Half width of the census window (7 columns).
pub const HALF_W: i32 = 3;
/// Half height of the census window (5 rows).
pub const HALF_H: i32 = 2;
/// The largest Hamming distance of two census words (the window less its centre).
pub const MAX_COST: u8 = ((2 * HALF_W + 1) * (2 * HALF_H + 1) - 1) as u8;

/// The census word of every pixel, rows first. Pixels beyond the border are the border's
/// (replicated), so every pixel has a word.
pub fn census(img: &GrayImage) -> Vec<u64> {
    let (w, h) = (img.width() as usize, img.height() as usize);
    let (pad, pw) = padded(img);
    let mut out = vec![0u64; w * h];
    out.par_chunks_mut(w.max(1)).enumerate().for_each(|(y, row)| {
        super::fast(
            #[inline(always)]
            || census_row(&pad, pw, y, row),
        )
    });
    out
}

/// Steps of the per-column scales of [`census_scaled`] (1/128: at most 0.012 px off at the
/// 7-px window's ends).
pub const SCALE_STEPS: f64 = 128.0;

/// [`census`] of a window scaled by `scale + slope (u - (w - 1) / 2)` (`[su, sv]` per
/// column `u` of the `w`-px wide image): the neighbour `(i, j)` of pixel `(x, y)` is the
/// bilinear sample at `(x + i su, y + j sv)` (the border replicated), compared with the
/// pixel itself. The right image's census words when the right camera sees at `scale` times
/// the left one's scale (`slope` zero), or at a scale that changes across the image (a
/// verged pair of unequal focal lengths: `slope` per px of the right image's column): each
/// word then covers the same patch of the scene as the left word it is compared with, as if
/// the right image were resampled by `1 / scale` about each pixel (the matches stay in the
/// right image's own pixels). A non-zero `slope` quantises each column's scale to steps of
/// `1 / `[`SCALE_STEPS`] (each run of columns of one step with its own offsets, so the cost
/// stays one pass), clipped to 0.25..4. Fixed point (8 bits of each weight), so that whole
/// offsets give [`census`]'s words.
pub fn census_scaled(img: &GrayImage, scale: [f64; 2], slope: [f64; 2]) -> Vec<u64> {
    let (w, h) = (img.width() as usize, img.height() as usize);
    // Each neighbour's whole offset (floor) and fraction (of 256), per axis.
    let split = |t: f64| {
        let f = t.floor();
        let frac = ((t - f) * 256.0).round() as i64;
        // A fraction that rounds to 256 is the next whole pixel.
        if frac == 256 {
            (f as i64 + 1, 0u32)
        } else {
            (f as i64, frac as u32)
        }
    };
    // Each run of columns `x0..x1` of one scale with its offsets along u and v.
    let runs: Vec<Run> = scale_runs(w, scale, slope)
        .into_iter()
        .map(|(x0, x1, s)| Run {
            x0,
            x1,
            xs: (-HALF_W..=HALF_W).map(|i| split(f64::from(i) * s[0])).collect(),
            ys: (-HALF_H..=HALF_H).map(|j| split(f64::from(j) * s[1])).collect(),
        })
        .collect();
    // Padding that holds every offset and the next pixel of its bilinear sample.
    let reach = |o: &[(i64, u32)]| o.iter().map(|&(o, _)| o.unsigned_abs() as usize + 1).max();
    let px_pad = runs.iter().filter_map(|r| reach(&r.xs)).max().unwrap_or(1);
    let py_pad = runs.iter().filter_map(|r| reach(&r.ys)).max().unwrap_or(1);
    let pw = w + 2 * px_pad;
    let src = img.as_raw();
    let mut pad = vec![0u32; pw * (h + 2 * py_pad)];
    for (py, row) in pad.chunks_exact_mut(pw).enumerate() {
        let y = py.saturating_sub(py_pad).min(h - 1);
        let line = &src[y * w..(y + 1) * w];
        for (o, x) in row.iter_mut().zip((0..pw).map(|x| x.saturating_sub(px_pad).min(w - 1))) {
            *o = u32::from(line[x]);
        }
    }
    let mut out = vec![0u64; w * h];
    out.par_chunks_mut(w.max(1)).enumerate().for_each(|(y, row)| {
        super::fast(
            #[inline(always)]
            || {
                let at = |dy: i64| (y + py_pad).wrapping_add_signed(dy as isize) * pw + px_pad;
                let centre: Vec<u32> = pad[at(0)..at(0) + w].iter().map(|&c| c << 16).collect();
                row.fill(0);
                let mut sample = vec![0u32; w];
                for run in &runs {
                    let (x0, n) = (run.x0, run.x1 - run.x0);
                    let (words, centre) = (&mut row[x0..run.x1], &centre[x0..run.x1]);
                    let sample = &mut sample[..n];
                    for (j, &(oy, fy)) in run.ys.iter().enumerate() {
                        for (i, &(ox, fx)) in run.xs.iter().enumerate() {
                            if j == HALF_H as usize && i == HALF_W as usize {
                                continue;
                            }
                            let (r0, r1) = (at(oy) + x0, at(oy + 1) + x0);
                            let s0 = r0.wrapping_add_signed(ox as isize);
                            let s1 = r1.wrapping_add_signed(ox as isize);
                            let (a, b) = (&pad[s0..s0 + n + 1], &pad[s1..s1 + n + 1]);
                            let (gx, gy) = (256 - fx, 256 - fy);
                            for (k, s) in sample.iter_mut().enumerate() {
                                let top = a[k] * gx + a[k + 1] * fx;
                                let bottom = b[k] * gx + b[k + 1] * fx;
                                *s = top * gy + bottom * fy;
                            }
                            for ((word, &v), &c) in words.iter_mut().zip(&*sample).zip(centre) {
                                *word = (*word << 1) | u64::from(v < c);
                            }
                        }
                    }
                }
            },
        )
    });
    out
}

/// One run of columns of [`census_scaled`]: columns `x0..x1`, each neighbour's whole offset
/// and fraction along u (`xs`) and v (`ys`).
struct Run {
    x0: usize,
    x1: usize,
    xs: Vec<(i64, u32)>,
    ys: Vec<(i64, u32)>,
}

/// The runs of columns of one scale of [`census_scaled`] (`x0..x1` and the scale): the whole
/// image at `scale` when `slope` is zero, else each column's scale quantised to steps of
/// `1 / `[`SCALE_STEPS`] and clipped to 0.25..4.
fn scale_runs(w: usize, scale: [f64; 2], slope: [f64; 2]) -> Vec<(usize, usize, [f64; 2])> {
    if slope == [0.0, 0.0] {
        return vec![(0, w, scale)];
    }
    let c = (w as f64 - 1.0) / 2.0;
    let at = |x: usize| {
        [0, 1].map(|k| {
            let s = scale[k] + slope[k] * (x as f64 - c);
            (s * SCALE_STEPS).round().clamp(0.25 * SCALE_STEPS, 4.0 * SCALE_STEPS) / SCALE_STEPS
        })
    };
    let mut runs: Vec<(usize, usize, [f64; 2])> = Vec::new();
    for x in 0..w {
        let s = at(x);
        match runs.last_mut() {
            Some(last) if last.2 == s => last.1 = x + 1,
            _ => runs.push((x, x + 1, s)),
        }
    }
    runs
}

/// `img` padded by its border pixels (the window's half width and height on each side), so
/// that the inner loops need no clamping, and the padded width.
fn padded(img: &GrayImage) -> (Vec<u8>, usize) {
    let (w, h) = (img.width() as usize, img.height() as usize);
    let px = img.as_raw();
    let (hw, hh) = (HALF_W as usize, HALF_H as usize);
    let pw = w + 2 * hw;
    let mut pad = vec![0u8; pw * (h + 2 * hh)];
    for (py, row) in pad.chunks_exact_mut(pw).enumerate() {
        let y = py.saturating_sub(hh).min(h - 1);
        let src = &px[y * w..(y + 1) * w];
        for (px_out, x) in row.iter_mut().zip((0..pw).map(|x| x.saturating_sub(hw).min(w - 1))) {
            *px_out = src[x];
        }
    }
    (pad, pw)
}

/// Whether each pixel's census window (7 x 5, the border replicated as [`census`] does) is one
/// grey level, rows first: such a window carries nothing to match (a blank patch, or one
/// clipped to black or white), whatever the aggregation carries into it from its neighbours.
pub fn flat_windows(img: &GrayImage) -> Vec<bool> {
    let (w, h) = (img.width() as usize, img.height() as usize);
    let (pad, pw) = padded(img);
    let (hw, hh) = (HALF_W as usize, HALF_H as usize);
    let mut out = vec![false; w * h];
    out.par_chunks_mut(w.max(1)).enumerate().for_each(|(y, row)| {
        super::fast(
            #[inline(always)]
            || {
                // Whether any neighbour differs from the centre, a byte per pixel.
                let mut differs = vec![0u8; w];
                let centre = &pad[(y + hh) * pw + hw..(y + hh) * pw + hw + w];
                for j in 0..2 * hh + 1 {
                    let r = &pad[(y + j) * pw..(y + j + 1) * pw];
                    for i in 0..2 * hw + 1 {
                        for ((d, &n), &c) in differs.iter_mut().zip(&r[i..i + w]).zip(centre) {
                            *d |= u8::from(n != c);
                        }
                    }
                }
                for (flat, &d) in row.iter_mut().zip(&differs) {
                    *flat = d == 0;
                }
            },
        )
    });
    out
}

/// The census words of row `y` (`row`, `w` long) from the padded image `pad` (`pw` wide).
#[inline(always)]
fn census_row(pad: &[u8], pw: usize, y: usize, row: &mut [u64]) {
    let (hw, hh) = (HALF_W as usize, HALF_H as usize);
    let w = row.len();
    let centre = &pad[(y + hh) * pw + hw..(y + hh) * pw + hw + w];
    row.fill(0);
    for j in 0..2 * hh + 1 {
        let r = &pad[(y + j) * pw..(y + j + 1) * pw];
        for i in 0..2 * hw + 1 {
            if j == hh && i == hw {
                continue;
            }
            let shifted = &r[i..i + w];
            for ((a, &n), &c) in row.iter_mut().zip(shifted).zip(centre) {
                *a = (*a << 1) | u64::from(n < c);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_window_of_one_grey_level_is_flat() {
        // Grey 100 everywhere but one pixel at (10, 6): the windows that hold it are not flat
        // (7 columns x 5 rows around it, cut by nothing here), all others are.
        let mut img = GrayImage::from_pixel(21, 13, image::Luma([100]));
        img.put_pixel(10, 6, image::Luma([101]));
        let flat = flat_windows(&img);
        for y in 0..13usize {
            for x in 0..21usize {
                let holds = x.abs_diff(10) <= 3 && y.abs_diff(6) <= 2;
                assert_eq!(flat[y * 21 + x], !holds, "({x}, {y})");
            }
        }
        // At the border the window is cut (the border replicated adds no new level).
        let mut edge = GrayImage::from_pixel(9, 7, image::Luma([0]));
        edge.put_pixel(0, 0, image::Luma([255]));
        let flat = flat_windows(&edge);
        assert!(!flat[0] && !flat[3] && flat[4] && !flat[2 * 9] && flat[3 * 9]);
    }

    /// Unit steps give the plain census; a scaled window on an image scaled by the same
    /// factor gives the plain census of the unscaled image (at whole-pixel samples).
    #[test]
    fn a_scaled_census_sees_the_scaled_window() {
        let mut seed = 5u64;
        let img = GrayImage::from_fn(40, 30, |_, _| {
            image::Luma([(hvs_shared::test_support::splitmix64(&mut seed) >> 56) as u8])
        });
        assert_eq!(census_scaled(&img, [1.0, 1.0], [0.0, 0.0]), census(&img));
        // Twice as large: every scene pixel twice (nearest), sampled at even pixels.
        let big = GrayImage::from_fn(80, 60, |x, y| *img.get_pixel(x / 2, y / 2));
        let (c, cb) = (census(&img), census_scaled(&big, [2.0, 2.0], [0.0, 0.0]));
        for y in 3..27 {
            for x in 4..36 {
                assert_eq!(cb[2 * y * 80 + 2 * x], c[y * 40 + x], "({x}, {y})");
            }
        }
    }

    /// A per-column scale gives each column the words of the whole image at that column's
    /// quantised scale.
    #[test]
    fn a_per_column_census_is_each_columns_scaled_census() {
        let mut seed = 7u64;
        let img = GrayImage::from_fn(90, 20, |_, _| {
            image::Luma([(hvs_shared::test_support::splitmix64(&mut seed) >> 56) as u8])
        });
        let (scale, slope) = ([0.8, 0.85], [0.004, 0.002]);
        let runs = scale_runs(90, scale, slope);
        assert!(runs.len() > 10 && runs[0].0 == 0 && runs.last().unwrap().1 == 90);
        let c = census_scaled(&img, scale, slope);
        for (x0, x1, s) in runs {
            // Quantised: whole steps of 1/128, within half a step of the line.
            let want = [0, 1].map(|k| scale[k] + slope[k] * (x0 as f64 - 44.5));
            for k in 0..2 {
                assert_eq!((s[k] * SCALE_STEPS).fract(), 0.0);
                assert!((s[k] - want[k]).abs() <= 0.5 / SCALE_STEPS + 1e-12);
            }
            let whole = census_scaled(&img, s, [0.0, 0.0]);
            for y in 0..20 {
                assert_eq!(c[y * 90 + x0..y * 90 + x1], whole[y * 90 + x0..y * 90 + x1]);
            }
        }
    }

    /// An image stretched along u by a factor that grows across it (0.7 at its left edge to
    /// 1.0 at its right, a line in its column): the per-column census sees (nearly) the
    /// unstretched scene's census words, the global scale only in the middle.
    #[test]
    fn a_per_column_census_follows_a_stretch_across_the_image() {
        // A smooth texture of the scene's coordinates (periods of 5 to 13 px).
        let scene = |x: f64, y: f64| {
            120.0
                + 40.0 * (x / 1.3 + 0.7 * y).sin()
                + 35.0 * (x / 2.1 - y / 1.7 + 1.0).sin()
                + 30.0 * (0.4 * x + y / 1.1 + 2.0).cos()
        };
        let (w, h) = (240usize, 24usize);
        let c = (w as f64 - 1.0) / 2.0;
        let (a, b) = (0.85, 0.3 / (w as f64 - 1.0));
        // The scene column of image column x: its local scale dx / dx_scene is a + b (x - c).
        let phi = |x: f64| (a + b * (x - c)).ln() / b;
        let img = GrayImage::from_fn(w as u32, h as u32, |x, y| {
            image::Luma([scene(phi(f64::from(x)), f64::from(y)).round().clamp(0.0, 255.0) as u8])
        });
        // The scene's own words at every pixel's scene point.
        let truth = |x: usize, y: usize| {
            let (xs, ys) = (phi(x as f64), y as f64);
            let centre = scene(xs, ys);
            let mut word = 0u64;
            for j in -HALF_H..=HALF_H {
                for i in -HALF_W..=HALF_W {
                    if (i, j) != (0, 0) {
                        let n = scene(xs + f64::from(i), ys + f64::from(j));
                        word = (word << 1) | u64::from(n < centre);
                    }
                }
            }
            word
        };
        let wrong_bits = |words: &[u64], cols: std::ops::Range<usize>| {
            let mut sum = 0u32;
            let mut n = 0u32;
            for y in 3..h - 3 {
                for x in cols.clone() {
                    sum += (words[y * w + x] ^ truth(x, y)).count_ones();
                    n += 1;
                }
            }
            f64::from(sum) / f64::from(n)
        };
        let per_column = census_scaled(&img, [a, 1.0], [b, 0.0]);
        let global = census_scaled(&img, [a, 1.0], [0.0, 0.0]);
        let (edges, middle) = ([5..40, 200..235], 100..140);
        for cols in edges {
            let (p, g) = (wrong_bits(&per_column, cols.clone()), wrong_bits(&global, cols));
            assert!(p < 2.0 && p < 0.6 * g, "per column {p:.2} bits, global {g:.2}");
        }
        let (p, g) = (wrong_bits(&per_column, middle.clone()), wrong_bits(&global, middle));
        assert!(p < 2.0 && (p - g).abs() < 0.5, "per column {p:.2} bits, global {g:.2}");
    }

    #[test]
    fn census_bits_say_which_neighbours_are_darker() {
        // A centre brighter than everything: all 34 bits set; a flat image: none.
        let mut img = GrayImage::from_pixel(11, 9, image::Luma([100]));
        img.put_pixel(5, 4, image::Luma([200]));
        let c = census(&img);
        assert_eq!(MAX_COST, 34);
        assert_eq!(c[4 * 11 + 5].count_ones(), 34);
        assert_eq!(c[0], 0);
        // Its right neighbour sees only equal or brighter pixels: no bit.
        assert_eq!(c[4 * 11 + 6], 0);
        // One darker neighbour, two to its right: one bit, at that neighbour's place (row 2
        // of 5, column 5 of 7: bit 34 - 1 - (2 * 7 + 5 - 1)).
        img.put_pixel(8, 4, image::Luma([0]));
        let c = census(&img);
        assert_eq!(c[4 * 11 + 6], 1 << (34 - 1 - (2 * 7 + 5 - 1)));
    }
}
