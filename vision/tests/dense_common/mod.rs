//! Synthetic stereo pairs with exact per-pixel truth for the dense matcher's tests and bench:
//! a seeded random texture seen through planes of known disparity (a background plane,
//! optionally slanted, and a fronto-parallel box in front of it), rendered by inverse
//! mapping, with an optional vertical epipolar offset `v_r = v_l - tilt * u_r - shift` (an
//! unrectified pair whose epipolar lines are not the image rows).
#![allow(dead_code, clippy::too_many_arguments)]

use hvs_shared::test_support::splitmix64;
use hvs_vision::geometry::Fundamental;
use image::GrayImage;

/// A smooth random texture: white noise blurred by two 3 x 3 box passes, read bilinearly.
pub struct Texture {
    w: usize,
    h: usize,
    g: Vec<f32>,
}

impl Texture {
    pub fn new(w: usize, h: usize, seed: u64) -> Texture {
        let mut s = seed;
        let mut g: Vec<f32> = (0..w * h).map(|_| (splitmix64(&mut s) >> 56) as f32).collect();
        for _ in 0..2 {
            let src = g.clone();
            for y in 0..h {
                for x in 0..w {
                    let mut acc = 0.0;
                    for dy in -1i64..=1 {
                        for dx in -1i64..=1 {
                            let xx = (x as i64 + dx).clamp(0, w as i64 - 1) as usize;
                            let yy = (y as i64 + dy).clamp(0, h as i64 - 1) as usize;
                            acc += src[yy * w + xx];
                        }
                    }
                    g[y * w + x] = acc / 9.0;
                }
            }
        }
        // Stretch the contrast back to about 0..255.
        let mean = g.iter().sum::<f32>() / g.len() as f32;
        for v in &mut g {
            *v = (128.0 + 3.0 * (*v - mean)).clamp(0.0, 255.0);
        }
        Texture { w, h, g }
    }

    pub fn at(&self, x: f64, y: f64) -> f32 {
        let x = x.clamp(0.0, (self.w - 1) as f64);
        let y = y.clamp(0.0, (self.h - 1) as f64);
        let (x0, y0) = (x.floor() as usize, y.floor() as usize);
        let (x1, y1) = ((x0 + 1).min(self.w - 1), (y0 + 1).min(self.h - 1));
        let (fx, fy) = ((x - x0 as f64) as f32, (y - y0 as f64) as f32);
        let g = |x: usize, y: usize| self.g[y * self.w + x];
        let top = g(x0, y0) * (1.0 - fx) + g(x1, y0) * fx;
        let bot = g(x0, y1) * (1.0 - fx) + g(x1, y1) * fx;
        top * (1.0 - fy) + bot * fy
    }
}

/// A plane: disparity `a + b x` (left `x`) inside the left-image box `x0..x1, y0..y1`.
#[derive(Clone, Copy)]
pub struct Plane {
    pub a: f64,
    pub b: f64,
    pub x0: f64,
    pub x1: f64,
    pub y0: f64,
    pub y1: f64,
}

/// A pair and its truth.
pub struct Pair {
    pub left: GrayImage,
    pub right: GrayImage,
    pub f: Fundamental,
    /// Per left pixel: the true `u_r, v_r` when the point is seen by the right camera too.
    pub truth: Vec<Option<[f64; 2]>>,
    pub d_range: [i32; 2],
}

/// The nearest plane (largest disparity) at left pixel `(x, y)`.
fn nearest(planes: &[Plane], x: f64, y: f64) -> Option<(usize, f64)> {
    planes
        .iter()
        .enumerate()
        .filter(|(_, p)| x >= p.x0 && x < p.x1 && y >= p.y0 && y < p.y1)
        .map(|(k, p)| (k, p.a + p.b * x))
        .max_by(|a, b| a.1.total_cmp(&b.1))
}

/// Renders `planes` (the first must cover the whole image) at `w x h`, texture `seed`, with
/// the vertical epipolar offset `v_r = v_l - tilt u_r - shift`.
pub fn render(w: u32, h: u32, planes: &[Plane], seed: u64, tilt: f64, shift: f64) -> Pair {
    let tex = Texture::new(w as usize + 200, h as usize + 100, seed);
    let left = GrayImage::from_fn(w, h, |x, y| {
        image::Luma([tex.at(f64::from(x) + 100.0, f64::from(y) + 50.0).round() as u8])
    });
    // Right pixel (u, v) sees left row vl = v + tilt u + shift; on plane p the left x with
    // x - (a + b x) = u is (u + a) / (1 - b); the nearest plane that holds it wins.
    let right = GrayImage::from_fn(w, h, |u, v| {
        let (u, v) = (f64::from(u), f64::from(v));
        let vl = v + tilt * u + shift;
        let mut best: Option<(f64, f64)> = None;
        for p in planes {
            let x = (u + p.a) / (1.0 - p.b);
            if x >= p.x0 && x < p.x1 && vl >= p.y0 && vl < p.y1 {
                let d = p.a + p.b * x;
                if best.is_none_or(|(bd, _)| d > bd) {
                    best = Some((d, x));
                }
            }
        }
        let x = best.map_or(u, |(_, x)| x);
        image::Luma([tex.at(x + 100.0, vl + 50.0).round() as u8])
    });
    let mut truth = Vec::with_capacity((w * h) as usize);
    for y in 0..h {
        for x in 0..w {
            let (x, y) = (f64::from(x), f64::from(y));
            let Some((k, d)) = nearest(planes, x, y) else {
                truth.push(None);
                continue;
            };
            let ur = x - d;
            let vr = y - tilt * ur - shift;
            // Seen by the right camera: inside it, and no nearer plane in front there.
            let inside =
                ur >= 0.0 && ur <= f64::from(w) - 1.0 && vr >= 0.0 && vr <= f64::from(h) - 1.0;
            let hidden = planes.iter().enumerate().any(|(j, p)| {
                if j == k {
                    return false;
                }
                let xj = (ur + p.a) / (1.0 - p.b);
                xj >= p.x0 && xj < p.x1 && y >= p.y0 && y < p.y1 && p.a + p.b * xj > d + 1e-9
            });
            truth.push((inside && !hidden).then_some([ur, vr]));
        }
    }
    // r^T F l = 0 with v_l - v_r - tilt u_r - shift = 0.
    let f = Fundamental { m: [[0.0, 0.0, -tilt], [0.0, 0.0, -1.0], [0.0, 1.0, -shift]] };
    let dmax = planes
        .iter()
        .flat_map(|p| [p.a + p.b * p.x0, p.a + p.b * p.x1.min(f64::from(w))])
        .fold(f64::MIN, f64::max);
    let dmin = planes
        .iter()
        .flat_map(|p| [p.a + p.b * p.x0.max(0.0), p.a + p.b * p.x1.min(f64::from(w))])
        .fold(f64::MAX, f64::min);
    Pair { left, right, f, truth, d_range: [(dmin.floor() as i32) - 3, (dmax.ceil() as i32) + 3] }
}

/// The standard test scene at `w x h`: a background slanted from disparity `bg` to
/// `bg + slant` across the image and a box at disparity `fg` in its middle.
pub fn scene(
    w: u32,
    h: u32,
    bg: f64,
    slant: f64,
    fg: f64,
    seed: u64,
    tilt: f64,
    shift: f64,
) -> Pair {
    let (wf, hf) = (f64::from(w), f64::from(h));
    let planes = [
        Plane { a: bg, b: slant / wf, x0: -1e9, x1: 1e9, y0: -1e9, y1: 1e9 },
        Plane { a: fg, b: 0.0, x0: 0.35 * wf, x1: 0.65 * wf, y0: 0.3 * hf, y1: 0.7 * hf },
    ];
    render(w, h, &planes, seed, tilt, shift)
}

/// Scores of a dense map against a pair's truth.
#[derive(Debug)]
pub struct Score {
    /// Left pixels seen by both cameras.
    pub seen: usize,
    /// Of those, returned.
    pub returned: usize,
    /// Of the returned, within 1 px (distance of the right pixel).
    pub within_1: usize,
    /// Of the returned, more than 2 px off.
    pub off_2: usize,
    /// Returned where the truth says not seen.
    pub returned_unseen: usize,
}

impl Score {
    pub fn returned_pct(&self) -> f64 {
        100.0 * self.returned as f64 / self.seen.max(1) as f64
    }
    pub fn within_1_pct(&self) -> f64 {
        100.0 * self.within_1 as f64 / self.returned.max(1) as f64
    }
    pub fn off_2_pct(&self) -> f64 {
        100.0 * self.off_2 as f64 / self.returned.max(1) as f64
    }
}

pub fn score(pair: &Pair, m: &hvs_vision::dense::DenseMap, border: u32) -> Score {
    let (w, h) = (m.width, m.height);
    let mut s = Score { seen: 0, returned: 0, within_1: 0, off_2: 0, returned_unseen: 0 };
    for y in border..h - border {
        for x in border..w - border {
            let p = (y * w + x) as usize;
            let got = m.ur[p].is_finite().then(|| [f64::from(m.ur[p]), f64::from(m.vr[p])]);
            match (pair.truth[p], got) {
                (Some(t), g) => {
                    s.seen += 1;
                    if let Some(g) = g {
                        s.returned += 1;
                        let e = ((t[0] - g[0]).powi(2) + (t[1] - g[1]).powi(2)).sqrt();
                        if e <= 1.0 {
                            s.within_1 += 1;
                        }
                        if e > 2.0 {
                            s.off_2 += 1;
                        }
                    }
                }
                (None, Some(_)) => s.returned_unseen += 1,
                (None, None) => {}
            }
        }
    }
    s
}
