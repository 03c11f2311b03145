//! Drawing what was found, for a user to look at: detected corners and their labels over the
//! image, as an RGB image (write it with [`save_png`]).
//!
//! Each corner gets a small cross (red; green at `(0, 0)`), consecutive corners of a row are
//! joined by a line (a colour per row, so a wrongly ordered grid shows at a glance), and a
//! label in a built-in 3 x 5 pixel digit font: `i,j` at `(0, 0)` and at the start of every row,
//! the index `i` elsewhere along the first row. No fonts or system libraries are involved.

use crate::detect::Corners;
use image::{GrayImage, Rgb, RgbImage};

/// 3 x 5 bitmaps of `0`-`9`, `,`, `c`, `m` and a space (rows top to bottom, bit 2 = left
/// column): numbers, and the unit of a depth legend.
const GLYPHS: [[u8; 5]; 14] = [
    [0b111, 0b101, 0b101, 0b101, 0b111], // 0
    [0b010, 0b110, 0b010, 0b010, 0b111], // 1
    [0b111, 0b001, 0b111, 0b100, 0b111], // 2
    [0b111, 0b001, 0b111, 0b001, 0b111], // 3
    [0b101, 0b101, 0b111, 0b001, 0b001], // 4
    [0b111, 0b100, 0b111, 0b001, 0b111], // 5
    [0b111, 0b100, 0b111, 0b101, 0b111], // 6
    [0b111, 0b001, 0b010, 0b010, 0b010], // 7
    [0b111, 0b101, 0b111, 0b101, 0b111], // 8
    [0b111, 0b101, 0b111, 0b001, 0b111], // 9
    [0b000, 0b000, 0b000, 0b010, 0b100], // ,
    [0b000, 0b011, 0b100, 0b100, 0b011], // c
    [0b000, 0b111, 0b111, 0b101, 0b101], // m
    [0b000, 0b000, 0b000, 0b000, 0b000], // space
];

fn put(img: &mut RgbImage, x: i64, y: i64, c: Rgb<u8>) {
    if x >= 0 && y >= 0 && (x as u64) < img.width() as u64 && (y as u64) < img.height() as u64 {
        img.put_pixel(x as u32, y as u32, c);
    }
}

/// Draw `text` (digits, commas, `c`, `m` and spaces; other characters are skipped) with its top-left pixel at
/// `(x, y)`, each font pixel `scale x scale`, on a black backing box so it reads on any
/// background.
pub fn draw_text(img: &mut RgbImage, x: i64, y: i64, text: &str, scale: u32, c: Rgb<u8>) {
    let s = scale.max(1) as i64;
    let glyphs: Vec<&[u8; 5]> = text
        .chars()
        .filter_map(|ch| match ch {
            '0'..='9' => Some(&GLYPHS[ch as usize - '0' as usize]),
            ',' => Some(&GLYPHS[10]),
            'c' => Some(&GLYPHS[11]),
            'm' => Some(&GLYPHS[12]),
            ' ' => Some(&GLYPHS[13]),
            _ => None,
        })
        .collect();
    let w = glyphs.len() as i64 * 4 * s;
    for yy in y - s..y + 6 * s {
        for xx in x - s..x + w {
            put(img, xx, yy, Rgb([0, 0, 0]));
        }
    }
    for (k, g) in glyphs.iter().enumerate() {
        let ox = x + k as i64 * 4 * s;
        for (row, bits) in g.iter().enumerate() {
            for col in 0..3 {
                if bits & (0b100 >> col) != 0 {
                    for dy in 0..s {
                        for dx in 0..s {
                            put(img, ox + col * s + dx, y + row as i64 * s + dy, c);
                        }
                    }
                }
            }
        }
    }
}

/// Draw a line from `a` to `b` (pixel-centre coordinates).
pub fn draw_line(img: &mut RgbImage, a: [f64; 2], b: [f64; 2], c: Rgb<u8>) {
    let n = ((b[0] - a[0]).abs().max((b[1] - a[1]).abs()).ceil() as i64).clamp(1, 1 << 16);
    for k in 0..=n {
        let t = k as f64 / n as f64;
        let x = a[0] + t * (b[0] - a[0]);
        let y = a[1] + t * (b[1] - a[1]);
        if x.is_finite() && y.is_finite() {
            put(img, x.round() as i64, y.round() as i64, c);
        }
    }
}

/// Draw a cross of half-size `r` px centred at `p`.
pub fn draw_cross(img: &mut RgbImage, p: [f64; 2], r: f64, c: Rgb<u8>) {
    draw_line(img, [p[0] - r, p[1]], [p[0] + r, p[1]], c);
    draw_line(img, [p[0], p[1] - r], [p[0], p[1] + r], c);
}

/// Row colours, cycled.
const ROW_COLOURS: [Rgb<u8>; 6] = [
    Rgb([255, 64, 64]),
    Rgb([255, 160, 0]),
    Rgb([230, 230, 0]),
    Rgb([0, 200, 255]),
    Rgb([80, 120, 255]),
    Rgb([220, 80, 255]),
];

/// The grey image in colour with the corners, row lines and labels drawn over it.
pub fn draw_corners(grey: &GrayImage, corners: &Corners) -> RgbImage {
    let mut img = RgbImage::from_fn(grey.width(), grey.height(), |x, y| {
        let v = grey.get_pixel(x, y).0[0];
        Rgb([v, v, v])
    });
    let b = corners.board;
    let r = (corners.square_px / 5.0).clamp(2.0, 6.0);
    let scale = if corners.square_px >= 30.0 { 2 } else { 1 };
    for j in 0..b.rows {
        let colour = ROW_COLOURS[j as usize % ROW_COLOURS.len()];
        for i in 0..b.cols {
            let p = corners.at(i, j);
            if i + 1 < b.cols {
                draw_line(&mut img, p, corners.at(i + 1, j), colour);
            }
        }
    }
    for j in 0..b.rows {
        for i in 0..b.cols {
            let p = corners.at(i, j);
            let c = if (i, j) == (0, 0) { Rgb([0, 255, 0]) } else { Rgb([255, 0, 0]) };
            draw_cross(&mut img, p, r, c);
            let label = if i == 0 {
                Some(format!("{i},{j}"))
            } else if j == 0 {
                Some(format!("{i}"))
            } else {
                None
            };
            if let Some(t) = label {
                let (x, y) = (p[0].round() as i64 + 3, p[1].round() as i64 + 3);
                draw_text(&mut img, x, y, &t, scale, Rgb([255, 255, 255]));
            }
        }
    }
    img
}

/// Write an RGB image as PNG (the path is named in the error).
pub fn save_png(img: &RgbImage, path: &std::path::Path) -> Result<(), String> {
    img.save_with_format(path, image::ImageFormat::Png)
        .map_err(|e| format!("cannot write {}: {e}", path.display()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::board::Board;
    use crate::detect::label_grid;

    fn corners() -> Corners {
        let board = Board::new(4, 3, 1.0).unwrap();
        let mut l = Vec::new();
        for j in 0..3 {
            for i in 0..4 {
                l.push(((i, j), [20.0 + 20.0 * i as f64, 15.0 + 20.0 * j as f64]));
            }
        }
        label_grid(&l, &[], &board, 120, 80).unwrap()
    }

    #[test]
    fn marks_every_corner_and_the_origin_in_green() {
        let grey = GrayImage::from_pixel(120, 80, image::Luma([128]));
        let img = draw_corners(&grey, &corners());
        // (0, 0) at (20, 15) is green; another corner's centre is red.
        assert_eq!(img.get_pixel(20, 15), &Rgb([0, 255, 0]));
        assert_eq!(img.get_pixel(40, 35), &Rgb([255, 0, 0]));
        // Far from everything the grey background is untouched.
        assert_eq!(img.get_pixel(110, 75), &Rgb([128, 128, 128]));
        // The row-0 label "0,0" was written (white pixels) near (23, 18).
        let white = (18..30)
            .flat_map(|y| (23..40).map(move |x| (x, y)))
            .filter(|&(x, y)| img.get_pixel(x, y) == &Rgb([255, 255, 255]))
            .count();
        assert!(white > 10, "{white}");
    }

    #[test]
    fn text_draws_the_glyphs_and_clips_at_the_border() {
        let mut img = RgbImage::new(10, 10);
        draw_text(&mut img, 1, 1, "1", 1, Rgb([255, 255, 255]));
        // "1": middle column set on every row.
        for row in 0..5 {
            assert_eq!(img.get_pixel(2, 1 + row), &Rgb([255, 255, 255]));
        }
        assert_eq!(img.get_pixel(1, 2), &Rgb([255, 255, 255]));
        assert_eq!(img.get_pixel(1, 3), &Rgb([0, 0, 0]));
        // Drawing off the image does not panic.
        draw_text(&mut img, -50, 8, "0123456789", 3, Rgb([1, 2, 3]));
        draw_line(&mut img, [-1e9, 0.0], [1e9, 5.0], Rgb([9, 9, 9]));
        draw_cross(&mut img, [f64::NAN, 1.0], 3.0, Rgb([9, 9, 9]));
    }

    #[test]
    fn save_png_names_a_bad_path() {
        let e =
            save_png(&RgbImage::new(2, 2), std::path::Path::new("/nonexistent/x.png")).unwrap_err();
        assert!(e.contains("/nonexistent/x.png"), "{e}");
    }
}
