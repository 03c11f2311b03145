//! The census transform (Zabih & Woodfill 1994): each pixel's 9 x 7 neighbourhood as 62 bits
//! (neighbour darker than the centre), compared by Hamming distance. Robust to gain and offset
//! differences between the two cameras.

use image::GrayImage;
use rayon::prelude::*;

/// Half width of the census window (9 columns).
pub const HALF_W: i32 = 4;
/// Half height of the census window (7 rows).
pub const HALF_H: i32 = 3;
/// The largest Hamming distance of two census words (the window less its centre).
pub const MAX_COST: u8 = ((2 * HALF_W + 1) * (2 * HALF_H + 1) - 1) as u8;

/// The census word of every pixel, rows first. Pixels beyond the border are the border's
/// (replicated), so every pixel has a word.
pub fn census(img: &GrayImage) -> Vec<u64> {
    let (w, h) = (img.width() as usize, img.height() as usize);
    let px = img.as_raw();
    let mut out = vec![0u64; w * h];
    out.par_chunks_mut(w.max(1))
        .enumerate()
        .for_each(|(y, row)| {
            let rows: Vec<&[u8]> = (-HALF_H..=HALF_H)
                .map(|dy| {
                    let yy = (y as i32 + dy).clamp(0, h as i32 - 1) as usize;
                    &px[yy * w..(yy + 1) * w]
                })
                .collect();
            let centre = rows[HALF_H as usize];
            for (x, word) in row.iter_mut().enumerate() {
                let c = centre[x];
                let mut bits = 0u64;
                for (j, r) in rows.iter().enumerate() {
                    for dx in -HALF_W..=HALF_W {
                        if j == HALF_H as usize && dx == 0 {
                            continue;
                        }
                        let xx = (x as i32 + dx).clamp(0, w as i32 - 1) as usize;
                        bits = (bits << 1) | u64::from(r[xx] < c);
                    }
                }
                *word = bits;
            }
        });
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn census_bits_say_which_neighbours_are_darker() {
        // A centre brighter than everything: all 62 bits set; a flat image: none.
        let mut img = GrayImage::from_pixel(11, 9, image::Luma([100]));
        img.put_pixel(5, 4, image::Luma([200]));
        let c = census(&img);
        assert_eq!(MAX_COST, 62);
        assert_eq!(c[4 * 11 + 5].count_ones(), 62);
        assert_eq!(c[0], 0);
        // Its right neighbour sees only equal or brighter pixels: no bit.
        assert_eq!(c[4 * 11 + 6], 0);
        // One darker neighbour, two to its right: one bit, at that neighbour's place (row 3
        // of 7, column 6 of 9: bit 62 - 1 - (3 * 9 + 6 - 1)).
        img.put_pixel(8, 4, image::Luma([0]));
        let c = census(&img);
        assert_eq!(c[4 * 11 + 6], 1 << (62 - 1 - (3 * 9 + 6 - 1)));
    }
}
