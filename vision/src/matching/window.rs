//! Windows: the images as `f32` planes, window shapes and their clipping at the borders,
//! support weights, bilinear samples and the weighted template of a window.

use image::GrayImage;

/// A grey image as `f32`, row-major.
pub(super) struct Plane {
    pub(super) w: usize,
    pub(super) h: usize,
    pub(super) px: Vec<f32>,
}

impl Plane {
    pub(super) fn new(img: &GrayImage) -> Plane {
        Plane {
            w: img.width() as usize,
            h: img.height() as usize,
            px: img.as_raw().iter().map(|&p| f32::from(p)).collect(),
        }
    }
}

/// A rectangular window around a point: columns `x0..=x1` and rows `y0..=y1` relative to
/// it (the point itself always inside: `x0 <= 0 <= x1`, `y0 <= 0 <= y1`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) struct Win {
    pub(super) x0: i64,
    pub(super) x1: i64,
    pub(super) y0: i64,
    pub(super) y1: i64,
}

impl Win {
    /// The square window of half size `r`, moved by `(sx, sy)` px (the point stays inside).
    pub(super) fn shifted(r: i64, sx: i64, sy: i64) -> Win {
        Win { x0: -r + sx, x1: r + sx, y0: -r + sy, y1: r + sy }
    }
    pub(super) fn width(&self) -> usize {
        (self.x1 - self.x0 + 1) as usize
    }
    pub(super) fn height(&self) -> usize {
        (self.y1 - self.y0 + 1) as usize
    }
    pub(super) fn len(&self) -> usize {
        self.width() * self.height()
    }
    /// Whether the point is inside and both sides are at least `min_side` px.
    pub(super) fn usable(&self, min_side: i64) -> bool {
        self.x0 <= 0
            && self.x1 >= 0
            && self.y0 <= 0
            && self.y1 >= 0
            && self.x1 - self.x0 + 1 >= min_side
            && self.y1 - self.y0 + 1 >= min_side
    }
    /// The part of the window that fits, with its interpolation support, in a `w x h` image
    /// around every centre with `u` in `[u_lo, u_hi]` and `v` in `[v_lo, v_hi]` when window
    /// offset `(dx, dy)` lands at `(u + scale[0] dx, v + scale[1] dy)` (centres clamped to
    /// the image first: candidates off the image are dropped, not the window).
    pub(super) fn clip(
        &self,
        [w, h]: [usize; 2],
        [u_lo, u_hi]: [f64; 2],
        [v_lo, v_hi]: [f64; 2],
        scale: [f64; 2],
    ) -> Win {
        let (wm, hm) = ((w - 1) as f64, (h - 1) as f64);
        let (u_lo, u_hi) = (u_lo.clamp(0.0, wm), u_hi.clamp(0.0, wm));
        let (v_lo, v_hi) = (v_lo.clamp(0.0, hm), v_hi.clamp(0.0, hm));
        // A tiny tolerance so that exact multiples are not lost to rounding.
        let lo = |c: f64, s: f64| (-c / s - 1e-9).ceil() as i64;
        let hi = |c: f64, m: f64, s: f64| ((m - c) / s + 1e-9).floor() as i64;
        Win {
            x0: self.x0.max(lo(u_lo, scale[0])),
            x1: self.x1.min(hi(u_hi, wm, scale[0])),
            y0: self.y0.max(lo(v_lo, scale[1])),
            y1: self.y1.min(hi(v_hi, hm, scale[1])),
        }
    }
}

/// Entries per grey level of the support-weight table.
const WEIGHT_STEPS_PER_GREY: f64 = 4.0;

/// The support weights `floor + (1 - floor) exp(-|dI| / gamma)` for `|dI|` = 0, 1/4, ...,
/// 255 grey levels (empty when `gamma` is 0: every pixel counts the same).
pub(super) fn weight_lut(gamma: f64, floor: f64) -> Vec<f32> {
    if gamma <= 0.0 {
        return Vec::new();
    }
    let n = (255.0 * WEIGHT_STEPS_PER_GREY) as usize + 1;
    (0..n)
        .map(|k| {
            let d = k as f64 / WEIGHT_STEPS_PER_GREY;
            (floor + (1.0 - floor) * (-d / gamma).exp()) as f32
        })
        .collect()
}

/// Bilinear grey level of `img` at `(x, y)`, `None` off the image (support included).
pub(super) fn bilinear(img: &Plane, x: f64, y: f64) -> Option<f32> {
    let (xf, yf) = (x.floor(), y.floor());
    if !(xf >= 0.0 && yf >= 0.0 && x <= (img.w - 1) as f64 && y <= (img.h - 1) as f64) {
        return None;
    }
    let (xi, yi) = (xf as usize, yf as usize);
    let (fx, fy) = ((x - xf) as f32, (y - yf) as f32);
    let x2 = if fx > 0.0 { xi + 1 } else { xi };
    let y2 = if fy > 0.0 { yi + 1 } else { yi };
    let p = |xx: usize, yy: usize| img.px[yy * img.w + xx];
    let a = p(xi, yi) + fx * (p(x2, yi) - p(xi, yi));
    let b = p(xi, y2) + fx * (p(x2, y2) - p(xi, y2));
    Some(a + fy * (b - a))
}

/// Fills `t` (`2 n` long for the `n` pixels of `win`) with the weighted template of `img`'s
/// window `win` around sub-pixel `(u, v)` (bilinear): `t[..n]` the coefficients
/// `a_i = w_i (I_i - m) / s`, `t[n..]` the weights `w_i` (summing to 1), with `m` and `s^2`
/// the weighted mean and variance, so that `sum a_i J_i` over a candidate window `J` is the
/// weighted covariance over `s`. Weights: [`MatchParams::support_gamma`]. Returns the
/// window's (unweighted) standard deviation, or `None` when the window (with its
/// interpolation support) leaves the image.
pub(super) fn template(
    img: &Plane,
    u: f64,
    v: f64,
    win: Win,
    scale: [f64; 2],
    lut: &[f32],
    t: &mut [f32],
) -> Option<f64> {
    let n = win.len();
    if scale != [1.0, 1.0] {
        let ww = win.width();
        for dy in 0..win.height() {
            let y = v + scale[1] * (win.y0 + dy as i64) as f64;
            for dx in 0..ww {
                let x = u + scale[0] * (win.x0 + dx as i64) as f64;
                t[dy * ww + dx] = bilinear(img, x, y)?;
            }
        }
        return Some(weigh(win, lut, t));
    }
    let (x0, y0) = (u.floor(), v.floor());
    let (fx, fy) = (u - x0, v - y0);
    let (xa, xb) = (x0 as i64 + win.x0, x0 as i64 + win.x1 + i64::from(fx > 0.0));
    let (ya, yb) = (y0 as i64 + win.y0, y0 as i64 + win.y1 + i64::from(fy > 0.0));
    if !(x0.is_finite()
        && y0.is_finite()
        && xa >= 0
        && ya >= 0
        && xb < img.w as i64
        && yb < img.h as i64)
    {
        return None;
    }
    let (fx, fy) = (fx as f32, fy as f32);
    let (xs, ys) = (xa as usize, ya as usize);
    let (ww, wh) = (win.width(), win.height());
    let (vals, _) = t.split_at_mut(n);
    let w = img.w;
    for dy in 0..wh {
        let row = (ys + dy) * w;
        let row2 = if fy > 0.0 { row + w } else { row };
        for dx in 0..ww {
            let x = xs + dx;
            let x2 = if fx > 0.0 { x + 1 } else { x };
            let a = img.px[row + x] + fx * (img.px[row + x2] - img.px[row + x]);
            let b = img.px[row2 + x] + fx * (img.px[row2 + x2] - img.px[row2 + x]);
            vals[dy * ww + dx] = a + fy * (b - a);
        }
    }
    Some(weigh(win, lut, t))
}

/// Turns the grey levels in `t[..n]` into the template of [`template`] (coefficients, then
/// weights in `t[n..]`) and returns their unweighted standard deviation.
fn weigh(win: Win, lut: &[f32], t: &mut [f32]) -> f64 {
    let n = win.len();
    let ww = win.width();
    let (vals, wts) = t.split_at_mut(n);
    let mean = vals.iter().map(|&x| f64::from(x)).sum::<f64>() / n as f64;
    let ss: f64 = vals.iter().map(|&x| (f64::from(x) - mean).powi(2)).sum();
    let std = (ss / n as f64).sqrt();
    // Weights.
    let centre = f64::from(vals[(-win.y0) as usize * ww + (-win.x0) as usize]);
    let mut wsum = 0.0f64;
    for (wt, &x) in wts.iter_mut().zip(vals.iter()) {
        let wv = if lut.is_empty() {
            1.0
        } else {
            let k = ((f64::from(x) - centre).abs() * WEIGHT_STEPS_PER_GREY).round() as usize;
            f64::from(lut[k.min(lut.len() - 1)])
        };
        *wt = wv as f32;
        wsum += wv;
    }
    let mut wmean = 0.0f64;
    for (wt, &x) in wts.iter_mut().zip(vals.iter()) {
        *wt = (f64::from(*wt) / wsum) as f32;
        wmean += f64::from(*wt) * f64::from(x);
    }
    let mut wvar = 0.0f64;
    for (&wt, x) in wts.iter().zip(vals.iter_mut()) {
        let dev = f64::from(*x) - wmean;
        wvar += f64::from(wt) * dev * dev;
        *x = (f64::from(wt) * dev) as f32;
    }
    if wvar > 0.0 {
        let k = (1.0 / wvar.sqrt()) as f32;
        vals.iter_mut().for_each(|x| *x *= k);
    }
    std
}
