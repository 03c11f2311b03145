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
    let px = img.as_raw();
    // The image padded by its border pixels, so the inner loop needs no clamping.
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
    let mut out = vec![0u64; w * h];
    out.par_chunks_mut(w.max(1)).enumerate().for_each(|(y, row)| {
        super::fast(
            #[inline(always)]
            || census_row(&pad, pw, y, row),
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
