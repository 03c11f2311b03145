//! The weighted zero-mean normalised cross-correlation of a template with a window.

use super::window::{bilinear, Plane, Win};

/// The running sums of a weighted ZNCC, in f32: template times window, and the weighted
/// window's sum and sum of squares.
#[derive(Clone, Copy, Default)]
struct Sums {
    st: f32,
    s1: f32,
    s2: f32,
}

impl Sums {
    /// Adds the window value `val` under template coefficient `coef` and weight `wt`.
    #[inline(always)]
    fn add(&mut self, coef: f32, wt: f32, val: f32) {
        self.st += coef * val;
        let wv = wt * val;
        self.s1 += wv;
        self.s2 += wv * val;
    }

    /// The ZNCC in `[-1, 1]`; 0 for a flat window.
    fn score(self) -> f64 {
        let var = f64::from(self.s2) - f64::from(self.s1) * f64::from(self.s1);
        if var <= 1e-4 {
            return 0.0;
        }
        (f64::from(self.st) / var.sqrt()).clamp(-1.0, 1.0)
    }
}

/// A template ([`template`]: coefficients then weights) with its window, and the scale of
/// the other image's window against it (right/left focal lengths).
#[derive(Debug, Clone, Copy)]
pub(super) struct Probe<'a> {
    pub t: &'a [f32],
    pub win: Win,
    pub scale: [f64; 2],
}

/// Weighted ZNCC of the probe's template with the window of `img` around whole column `u`
/// and sub-pixel row `v` (linear in `v`), or `None` when the window leaves the image.
pub(super) fn zncc_at(img: &Plane, probe: Probe, u: i64, v: f64) -> Option<f64> {
    let Probe { t, win, scale } = probe;
    if !v.is_finite() {
        return None;
    }
    if scale != [1.0, 1.0] {
        return zncc_scaled(img, probe, u as f64, v);
    }
    let y0 = v.floor();
    let fy = (v - y0) as f32;
    let y0i = y0 as i64;
    let (xa, xb) = (u + win.x0, u + win.x1);
    let (ya, yb) = (y0i + win.y0, y0i + win.y1 + i64::from(fy > 0.0));
    if xa < 0 || xb >= img.w as i64 || ya < 0 || yb >= img.h as i64 {
        return None;
    }
    let (ww, wh) = (win.width(), win.height());
    let n = win.len();
    let (coef, wts) = t.split_at(n);
    let (xs, ys) = (xa as usize, ya as usize);
    let wu = img.w;
    let mut sums = Sums::default();
    for dy in 0..wh {
        let row = (ys + dy) * wu + xs;
        let a = &img.px[row..row + ww];
        let tr = &coef[dy * ww..(dy + 1) * ww];
        let wr = &wts[dy * ww..(dy + 1) * ww];
        if fy > 0.0 {
            let b = &img.px[row + wu..row + wu + ww];
            for k in 0..ww {
                sums.add(tr[k], wr[k], a[k] + fy * (b[k] - a[k]));
            }
        } else {
            for k in 0..ww {
                sums.add(tr[k], wr[k], a[k]);
            }
        }
    }
    Some(sums.score())
}

/// [`zncc_at`] with window offset `(dx, dy)` at `(u + scale[0] dx, v + scale[1] dy)`,
/// bilinear.
pub(super) fn zncc_scaled(img: &Plane, probe: Probe, u: f64, v: f64) -> Option<f64> {
    let Probe { t, win, scale } = probe;
    let n = win.len();
    let (coef, wts) = t.split_at(n);
    let ww = win.width();
    let mut sums = Sums::default();
    for dy in 0..win.height() {
        let y = v + scale[1] * (win.y0 + dy as i64) as f64;
        for dx in 0..ww {
            let x = u + scale[0] * (win.x0 + dx as i64) as f64;
            let val = bilinear(img, x, y)?;
            let k = dy * ww + dx;
            sums.add(coef[k], wts[k], val);
        }
    }
    Some(sums.score())
}
