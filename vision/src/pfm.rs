//! Depth files: PFM images (Middlebury's float format) in and out, binary PLY point clouds
//! with grey levels, and a colour-mapped depth image with a legend in cm.
//!
//! - **PFM**: a text header `Pf` (one channel) or `PF` (three), `W H`, then a scale whose
//!   sign is the byte order (`-1`: little-endian, what is written), each on its own line, then
//!   `f32` rows from the **bottom** row up, channels interleaved. Unknown values are `+inf`.
//! - **PLY**: `binary_little_endian 1.0`, one `vertex` element with `float x, y, z` and
//!   `uchar red, green, blue` (the grey level three times), which MeshLab, CloudCompare and
//!   Open3D read.

use image::{Rgb, RgbImage};

/// A float image of one or three channels, rows top to bottom, channels interleaved.
#[derive(Debug, Clone, PartialEq)]
pub struct FloatImage {
    /// Width (px).
    pub width: u32,
    /// Height (px).
    pub height: u32,
    /// 1 or 3.
    pub channels: u8,
    /// `width * height * channels` values.
    pub data: Vec<f32>,
}

/// PFM bytes of `img` (little-endian, bottom row first). Panics only if `data` has the wrong
/// length or `channels` is not 1 or 3 (a programming error).
pub fn pfm_bytes(img: &FloatImage) -> Vec<u8> {
    let (w, h, c) = (img.width as usize, img.height as usize, usize::from(img.channels));
    assert!(c == 1 || c == 3, "PFM has 1 or 3 channels, not {c}");
    assert_eq!(img.data.len(), w * h * c, "PFM data length");
    let tag = if c == 1 { "Pf" } else { "PF" };
    let mut out = format!("{tag}\n{w} {h}\n-1\n").into_bytes();
    out.reserve(w * h * c * 4);
    for row in img.data.chunks_exact(w * c).rev() {
        for v in row {
            out.extend_from_slice(&v.to_le_bytes());
        }
    }
    out
}

/// Reads PFM bytes (either byte order); `shown` names the file in the error.
pub fn read_pfm(bytes: &[u8], shown: &str) -> Result<FloatImage, String> {
    // Three whitespace-separated header fields after the tag, the last followed by one
    // whitespace byte.
    let mut pos = 0;
    let field = |pos: &mut usize| -> Result<String, String> {
        while *pos < bytes.len() && bytes[*pos].is_ascii_whitespace() {
            *pos += 1;
        }
        let start = *pos;
        while *pos < bytes.len() && !bytes[*pos].is_ascii_whitespace() && *pos - start < 32 {
            *pos += 1;
        }
        if start == *pos || *pos >= bytes.len() {
            return Err(format!("{shown}: not a PFM file (its header ends early)"));
        }
        Ok(String::from_utf8_lossy(&bytes[start..*pos]).into_owned())
    };
    let channels = match field(&mut pos)?.as_str() {
        "Pf" => 1u8,
        "PF" => 3,
        t => return Err(format!("{shown}: not a PFM file (starts with {t:?}, not Pf or PF)")),
    };
    let num = |t: String, what: &str| -> Result<u32, String> {
        t.parse::<u32>()
            .ok()
            .filter(|&v| v > 0 && v <= 1 << 16)
            .ok_or_else(|| format!("{shown}: PFM {what} {t:?} is not a size from 1 to 65536"))
    };
    let w = num(field(&mut pos)?, "width")?;
    let h = num(field(&mut pos)?, "height")?;
    let scale_text = field(&mut pos)?;
    let scale: f32 = scale_text
        .parse()
        .ok()
        .filter(|s: &f32| s.is_finite() && *s != 0.0)
        .ok_or_else(|| format!("{shown}: PFM scale {scale_text:?} is not a non-zero number"))?;
    pos += 1;
    let n = w as usize * h as usize * usize::from(channels);
    let body = &bytes[pos.min(bytes.len())..];
    if body.len() != n * 4 {
        return Err(format!(
            "{shown}: PFM {w}x{h} with {channels} channel(s) needs {} data bytes, the file has {}",
            n * 4,
            body.len()
        ));
    }
    let little = scale < 0.0;
    let mut data = Vec::with_capacity(n);
    let row = w as usize * usize::from(channels) * 4;
    for r in body.chunks_exact(row).rev() {
        for b in r.chunks_exact(4) {
            let b = [b[0], b[1], b[2], b[3]];
            data.push(if little { f32::from_le_bytes(b) } else { f32::from_be_bytes(b) });
        }
    }
    Ok(FloatImage { width: w, height: h, channels, data })
}

/// Binary little-endian PLY bytes of `points` (`[x, y, z]`) with their grey levels.
pub fn ply_bytes(points: &[[f32; 3]], grey: &[u8]) -> Vec<u8> {
    assert_eq!(points.len(), grey.len(), "one grey level per point");
    let mut out = format!(
        "ply\nformat binary_little_endian 1.0\ncomment hvs depth: X Y Z in cm, X right, Y down, Z forward (flip Y to view it upright)\nelement vertex {}\n\
         property float x\nproperty float y\nproperty float z\n\
         property uchar red\nproperty uchar green\nproperty uchar blue\nend_header\n",
        points.len()
    )
    .into_bytes();
    out.reserve(points.len() * 15);
    for (p, &g) in points.iter().zip(grey) {
        for v in p {
            out.extend_from_slice(&v.to_le_bytes());
        }
        out.extend_from_slice(&[g, g, g]);
    }
    out
}

/// The colour of `t` in `0..1` (near to far): a perceptual blue-green-yellow-red ramp
/// (anchors of the "turbo" map), linear in between. It starts at turbo's bright blue, not at
/// its near-black violet, so that the nearest depths are not mistaken for black, which
/// [`colour_depth`] keeps for no depth.
pub fn ramp(t: f32) -> Rgb<u8> {
    const STOPS: [[f32; 3]; 6] = [
        [70.0, 134.0, 251.0],
        [27.0, 229.0, 181.0],
        [164.0, 252.0, 60.0],
        [251.0, 185.0, 56.0],
        [228.0, 70.0, 10.0],
        [122.0, 4.0, 3.0],
    ];
    let t = if t.is_finite() { t.clamp(0.0, 1.0) } else { 0.0 };
    let s = t * (STOPS.len() - 1) as f32;
    let i = (s.floor() as usize).min(STOPS.len() - 2);
    let f = s - i as f32;
    let c: [u8; 3] =
        core::array::from_fn(|k| (STOPS[i][k] + f * (STOPS[i + 1][k] - STOPS[i][k])).round() as u8);
    Rgb(c)
}

/// Height (px) of the legend below the depth image of [`colour_depth`].
pub const LEGEND_PX: u32 = 28;

/// A colour-mapped depth image (`z` rows first, cm; not finite: black), near `z_range[0]`
/// blue to far `z_range[1]` red, with a legend bar below it labelled in cm at both ends and
/// in the middle.
pub fn colour_depth(width: u32, height: u32, z: &[f32], z_range: [f32; 2]) -> RgbImage {
    use crate::overlay::draw_text;
    let (lo, hi) = (z_range[0], z_range[1].max(z_range[0] + 1e-3));
    let mut img = RgbImage::new(width, height + LEGEND_PX);
    for (p, &v) in z.iter().enumerate().take(width as usize * height as usize) {
        let (x, y) = (p as u32 % width, p as u32 / width);
        if v.is_finite() {
            img.put_pixel(x, y, ramp((v - lo) / (hi - lo)));
        }
    }
    for x in 0..width {
        let c = ramp(x as f32 / (width.max(2) - 1) as f32);
        for y in height + 2..height + 10 {
            img.put_pixel(x, y, c);
        }
    }
    let white = Rgb([255, 255, 255]);
    let label = |v: f32| format!("{} cm", v.round() as i64);
    let ty = i64::from(height) + 13;
    draw_text(&mut img, 1, ty, &label(lo), 2, white);
    let mid = label((lo + hi) / 2.0);
    draw_text(&mut img, i64::from(width / 2) - 4 * mid.len() as i64, ty, &mid, 2, white);
    let hi_t = label(hi);
    draw_text(&mut img, i64::from(width) - 8 * hi_t.len() as i64 - 1, ty, &hi_t, 2, white);
    img
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pfm_golden_bytes_and_round_trip() {
        // 2 x 2, one channel: top row 1, 2; bottom row 3, +inf. Stored bottom row first.
        let img = FloatImage {
            width: 2,
            height: 2,
            channels: 1,
            data: vec![1.0, 2.0, 3.0, f32::INFINITY],
        };
        let b = pfm_bytes(&img);
        let mut want = b"Pf\n2 2\n-1\n".to_vec();
        for v in [3.0f32, f32::INFINITY, 1.0, 2.0] {
            want.extend_from_slice(&v.to_le_bytes());
        }
        assert_eq!(b, want);
        assert_eq!(&b[10..14], &[0, 0, 0x40, 0x40]);
        assert_eq!(&b[14..18], &[0, 0, 0x80, 0x7f]);
        assert_eq!(read_pfm(&b, "x.pfm").unwrap(), img);
        // Three channels, one pixel per row.
        let rgb = FloatImage {
            width: 1,
            height: 2,
            channels: 3,
            data: vec![1.0, 2.0, 0.5, f32::INFINITY, f32::INFINITY, 0.0],
        };
        let b = pfm_bytes(&rgb);
        assert!(b.starts_with(b"PF\n1 2\n-1\n"));
        assert_eq!(&b[10..14], &f32::INFINITY.to_le_bytes());
        assert_eq!(read_pfm(&b, "x.pfm").unwrap(), rgb);
        // Big-endian (positive scale) as other writers make it.
        let mut be = b"Pf\n1 1\n1.0\n".to_vec();
        be.extend_from_slice(&2.5f32.to_be_bytes());
        assert_eq!(read_pfm(&be, "b.pfm").unwrap().data, vec![2.5]);
        // Damaged files: one line naming the file.
        for (bytes, says) in [
            (&b"P6\n1 1\n255\n"[..], "not Pf or PF"),
            (&b"Pf\n1 1\n-1\n\0\0"[..], "needs 4 data bytes, the file has 2"),
            (&b"Pf\n0 1\n-1\n"[..], "width"),
            (&b"Pf\n1 1\nzz\n\0\0\0\0"[..], "scale"),
            (&b"Pf\n1"[..], "ends early"),
        ] {
            let e = read_pfm(bytes, "bad.pfm").unwrap_err();
            assert!(e.starts_with("bad.pfm: ") && e.contains(says) && !e.contains('\n'), "{e}");
        }
    }

    #[test]
    fn ply_golden_bytes() {
        let b = ply_bytes(&[[1.0, -2.0, 300.0]], &[7]);
        let header = "ply\nformat binary_little_endian 1.0\ncomment hvs depth: X Y Z in cm, X right, Y down, Z forward (flip Y to view it upright)\n\
                      element vertex 1\nproperty float x\nproperty float y\nproperty float z\n\
                      property uchar red\nproperty uchar green\nproperty uchar blue\nend_header\n";
        assert_eq!(&b[..header.len()], header.as_bytes());
        let body = &b[header.len()..];
        assert_eq!(body.len(), 15);
        assert_eq!(&body[..4], &[0, 0, 0x80, 0x3f]);
        assert_eq!(&body[4..8], &(-2.0f32).to_le_bytes());
        assert_eq!(&body[8..12], &300.0f32.to_le_bytes());
        assert_eq!(&body[12..], &[7, 7, 7]);
    }

    #[test]
    fn colour_depth_maps_near_to_blue_far_to_red_unknown_to_black() {
        let z = [100.0, 300.0, f32::INFINITY, 200.0];
        let img = colour_depth(4, 1, &z, [100.0, 300.0]);
        assert_eq!(img.dimensions(), (4, 1 + LEGEND_PX));
        assert_eq!(*img.get_pixel(0, 0), ramp(0.0));
        assert_eq!(*img.get_pixel(1, 0), ramp(1.0));
        assert_eq!(*img.get_pixel(2, 0), Rgb([0, 0, 0]));
        assert_eq!(*img.get_pixel(3, 0), ramp(0.5));
        let (near, far) = (ramp(0.0), ramp(1.0));
        assert!(near[2] > near[0] && far[0] > far[2]);
        // No depth is the only black: every colour of the ramp is far from it.
        for k in 0..=100 {
            let c = ramp(k as f32 / 100.0);
            assert!(c.0.iter().map(|&v| u32::from(v)).sum::<u32>() >= 120, "{k}: {c:?}");
        }
        // The legend bar runs from near to far.
        assert_eq!(*img.get_pixel(0, 5), ramp(0.0));
        assert_eq!(*img.get_pixel(3, 5), ramp(1.0));
        // Labelled in cm: "100 cm" at the left end, six glyphs on a black box.
        let wide = colour_depth(200, 1, &[100.0; 200], [100.0, 300.0]);
        let lit = |x0: u32, x1: u32| {
            (x0..x1).any(|x| (14..24).any(|y| *wide.get_pixel(x, y) == Rgb([255, 255, 255])))
        };
        // "100" then a space, "c" and "m" (8 px a glyph at scale 2, from x = 1).
        assert!(lit(1, 25) && !lit(25, 33) && lit(33, 41) && lit(41, 49), "no unit drawn");
    }
}
