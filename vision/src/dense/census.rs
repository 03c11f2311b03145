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

/// [`census`] of a window scaled by `scale` (`[su, sv]`): the neighbour `(i, j)` of pixel
/// `(x, y)` is the bilinear sample at `(x + i su, y + j sv)` (the border replicated), compared
/// with the pixel itself. The right image's census words when the right camera sees at
/// `scale` times the left one's scale: each word then covers the same patch of the scene as
/// the left word it is compared with, as if the right image were resampled by `1 / scale`
/// about each pixel (the matches stay in the right image's own pixels). Fixed point (8 bits
/// of each weight), so that whole offsets give [`census`]'s words.
pub fn census_scaled(img: &GrayImage, scale: [f64; 2]) -> Vec<u64> {
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
    let xs: Vec<(i64, u32)> = (-HALF_W..=HALF_W).map(|i| split(f64::from(i) * scale[0])).collect();
    let ys: Vec<(i64, u32)> = (-HALF_H..=HALF_H).map(|j| split(f64::from(j) * scale[1])).collect();
    // Padding that holds every offset and the next pixel of its bilinear sample.
    let px_pad = xs.iter().map(|&(o, _)| o.unsigned_abs() as usize + 1).max().unwrap_or(1);
    let py_pad = ys.iter().map(|&(o, _)| o.unsigned_abs() as usize + 1).max().unwrap_or(1);
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
                for (j, &(oy, fy)) in ys.iter().enumerate() {
                    for (i, &(ox, fx)) in xs.iter().enumerate() {
                        if j == HALF_H as usize && i == HALF_W as usize {
                            continue;
                        }
                        let (r0, r1) = (at(oy), at(oy + 1));
                        let s0 = r0.wrapping_add_signed(ox as isize);
                        let s1 = r1.wrapping_add_signed(ox as isize);
                        let (a, b) = (&pad[s0..s0 + w + 1], &pad[s1..s1 + w + 1]);
                        let (gx, gy) = (256 - fx, 256 - fy);
                        for (k, s) in sample.iter_mut().enumerate() {
                            let top = a[k] * gx + a[k + 1] * fx;
                            let bottom = b[k] * gx + b[k + 1] * fx;
                            *s = top * gy + bottom * fy;
                        }
                        for ((word, &n), &c) in row.iter_mut().zip(&sample).zip(&centre) {
                            *word = (*word << 1) | u64::from(n < c);
                        }
                    }
                }
            },
        )
    });
    out
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
        assert_eq!(census_scaled(&img, [1.0, 1.0]), census(&img));
        // Twice as large: every scene pixel twice (nearest), sampled at even pixels.
        let big = GrayImage::from_fn(80, 60, |x, y| *img.get_pixel(x / 2, y / 2));
        let (c, cb) = (census(&img), census_scaled(&big, [2.0, 2.0]));
        for y in 3..27 {
            for x in 4..36 {
                assert_eq!(cb[2 * y * 80 + 2 * x], c[y * 40 + x], "({x}, {y})");
            }
        }
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
