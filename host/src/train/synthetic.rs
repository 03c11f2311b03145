//! Quantised pixels: a projective fit of each camera, distilled into the net's training set.
//!
//! Integer pixels carry rounding noise, uniform in `[-0.5, 0.5]` px: not Gaussian, and not
//! independent of the board's regular grid. A least-squares fit (the net's, or a
//! gold-standard 3x4 camera fit) averages it and stays 1.04-1.09x the floor on the thesis'
//! 72 rounded board points; a fit that bounds the residuals instead (here: each camera's 3x4
//! projection matrix minimising `sum |r|^p` over the reprojection residuals, `p` =
//! [`LP_EXPONENT`], towards the minimax fit that is the natural estimate under uniform noise)
//! lands much closer to the true cameras (`docs/model-families.md`, tuning seeds:
//! 0.99-1.01x on the volume, worst protocol depth 0.97-1.05x).
//!
//! The net cannot be fitted by such a cost directly (its errors are in the outputs, the
//! rounding is in the inputs), so the fitted cameras make its training set:
//! [`SYNTHETIC_POINTS`] points drawn uniformly in the box of the training targets, projected
//! through both fitted matrices, each pixel coordinate moved by uniform noise of one
//! rounding step (what the pixels the net will see carry). The restarts learn the first
//! [`SELECTION_POINTS`] of them and the best one is fitted to all of them ([`prefix`]). The net then learns the depth of
//! noisy pixels of the fitted geometry, the same head-side family and bits as before.
//!
//! It applies only when every pixel of a stereo set is an integer and a pinhole camera
//! explains every training pixel within [`MAX_RESIDUAL_PX`] (rounding bounds the residuals of
//! the true camera by 0.5 px): a lens with visible distortion, or sub-pixel corners, keep
//! the plain fit on the measured points.

use super::rng::SplitMix64;
use crate::data::dataset::Dataset;
use hvs_shared::runtime::blob::InputKind;
use hvs_vision::geometry::fit_dlt;
use nalgebra::{DMatrix, DVector, Matrix3x4, SMatrix, SVector, Vector4};

/// Exponent of the residual cost of the camera fit (reached through 2, 4, 8, 16). On the
/// tuning seeds 8 is 1.11x on the protocol's worst depth of case I, 16 1.05x; 64 is no better
/// on the volume and worse on case II's protocol.
pub(crate) const LP_EXPONENT: u32 = 16;
/// Largest reprojection residual (px, any coordinate, either camera) for which the pinhole
/// fit is trusted: rounding alone gives at most 0.5 px with the true cameras.
pub(crate) const MAX_RESIDUAL_PX: f64 = 0.6;
/// Synthetic training points drawn from the fitted cameras.
pub(crate) const SYNTHETIC_POINTS: usize = 2000;
/// The first this many synthetic points are what the restarts train on; only the best
/// restart (by the training e_ma on the measured points) is then fitted to all
/// [`SYNTHETIC_POINTS`]. Tuning seeds (cases I-IV, 3 x 2,000 volume points, protocol):
/// 10 restarts on 100 points, then the best polished on 2,000 ([`POLISH_MAX_ITER`]), ties
/// the 10 restarts on all 2,000 (volume 0.986 / 1.020 / 0.986 / 1.016 vs 0.986 / 1.020 /
/// 0.979 / 1.017 times the floor) in a fifth of the time (whole `hvs train` 0.35-0.42 s ->
/// 0.06-0.08 s); 500 points for every restart, and no polish, was 0.995-1.025.
pub(crate) const SELECTION_POINTS: usize = 100;
/// Most LM iterations of that last fit (it starts from the best restart). Tuning seeds: 15
/// and 30 match the uncapped fit within 0.007 on every case's volume ratio; the uncapped
/// fit took up to 71 iterations (80 ms on case II).
pub(crate) const POLISH_MAX_ITER: usize = 30;
/// Mixed into the training seed for the synthetic points' stream.
const STREAM: u64 = 0x7072_6f6a_6563_7476;

/// Whether `data` is a stereo set with ground truth whose four pixel columns are all integers.
pub(crate) fn quantised(data: &Dataset) -> bool {
    data.n_inputs == 4 && data.len() >= 12 && data.has_targets() && whole_pixels(data)
}

/// Whether every row's pixel columns (its first four inputs) are finite integers.
pub(crate) fn whole_pixels(data: &Dataset) -> bool {
    data.n_inputs >= 4
        && data
            .inputs
            .chunks_exact(data.n_inputs)
            .all(|row| row[..4].iter().all(|v| v.is_finite() && v.fract() == 0.0))
}

/// Projection of `p` through `m` (signed so that the training points lie in front), `None`
/// at or behind the camera plane.
pub(crate) fn project(m: &Matrix3x4<f64>, p: &[f64; 3]) -> Option<[f64; 2]> {
    let h = m * Vector4::new(p[0], p[1], p[2], 1.0);
    (h[2] > 1e-300).then(|| [h[0] / h[2], h[1] / h[2]])
}

/// `|x|^p` for the even integer exponents of the fit (2, 4, 8, 16 and the weights' 0, 2, 6,
/// 14): repeated squaring, the multiplies in the order of `powi` (the runtime's
/// `__powidf2`), so the same bits; inlined, it unrolls where `p` is a constant, where `powi`
/// with a variable exponent is a call.
#[inline(always)]
fn abs_pow(x: f64, p: u32) -> f64 {
    let mut a = x.abs();
    let mut n = p;
    let mut mul = 1.0;
    loop {
        if n & 1 != 0 {
            mul *= a;
        }
        n >>= 1;
        if n == 0 {
            return mul;
        }
        a *= a;
    }
}

#[inline(always)]
fn lp_cost(m: &Matrix3x4<f64>, pts: &[[f64; 3]], px: &[[f64; 2]], p: u32) -> f64 {
    let mut s = 0.0;
    for (q, x) in pts.iter().zip(px) {
        match project(m, q) {
            Some(y) => s += abs_pow(y[0] - x[0], p) + abs_pow(y[1] - x[1], p),
            None => return f64::INFINITY,
        }
    }
    if s.is_finite() {
        s
    } else {
        f64::INFINITY
    }
}

crate::simd::x86_dispatch! {
    /// Minimises `sum |r|^p` of the reprojection residuals of `m` (unit Frobenius norm) by damped
    /// iteratively reweighted Gauss-Newton steps; `p` = 2 is the gold-standard fit. The normal
    /// equations (12 x 12) are accumulated point by point, without the 2n x 12 Jacobian.
    /// Compiled for AVX and AVX-512F too (plain multiplies and adds: the same bits).
    fn refine(m: &mut Matrix3x4<f64>, pts: &[[f64; 3]], px: &[[f64; 2]], p: u32) {
        avx512 refine_avx512: refine_exponents(m, pts, px, p),
        avx refine_avx: refine_exponents(m, pts, px, p),
        portable: refine_exponents(m, pts, px, p),
    }
}

#[inline(always)]
fn refine_exponents(m: &mut Matrix3x4<f64>, pts: &[[f64; 3]], px: &[[f64; 2]], p: u32) {
    // One copy per exponent the fit uses, each with its powers unrolled.
    match p {
        2 => refine_with(m, pts, px, 2),
        4 => refine_with(m, pts, px, 4),
        8 => refine_with(m, pts, px, 8),
        16 => refine_with(m, pts, px, 16),
        _ => refine_with(m, pts, px, p),
    }
}

#[inline(always)]
fn refine_with(m: &mut Matrix3x4<f64>, pts: &[[f64; 3]], px: &[[f64; 2]], p: u32) {
    *m /= m.norm();
    let mut cost = lp_cost(m, pts, px, p);
    let mut lambda = 1e-3;
    for _ in 0..300 {
        // Every row of the Jacobian is a multiple of a = x~ / w: u's row is (a, 0, -u a),
        // v's (0, a, -v a). So J^T W J is made of five weighted sums of a a^T: the blocks
        // (0,0) sum w_u a a^T, (1,1) sum w_v a a^T, (0,2) -sum w_u u a a^T, (1,2)
        // -sum w_v v a a^T, (2,2) sum (w_u u^2 + w_v v^2) a a^T.
        let mut blocks = [[0.0f64; 16]; 5];
        let mut g = SVector::<f64, 12>::zeros();
        for (q, x) in pts.iter().zip(px) {
            let h = *m * Vector4::new(q[0], q[1], q[2], 1.0);
            let w = h[2];
            let a = [q[0] / w, q[1] / w, q[2] / w, 1.0 / w];
            let uv = [h[0] / w, h[1] / w];
            let r = [uv[0] - x[0], uv[1] - x[1]];
            let wt = r.map(|r| abs_pow(r.abs().max(1e-6), p - 2));
            let coef = [
                wt[0],
                wt[1],
                -wt[0] * uv[0],
                -wt[1] * uv[1],
                wt[0] * uv[0] * uv[0] + wt[1] * uv[1] * uv[1],
            ];
            for (blk, c) in blocks.iter_mut().zip(coef) {
                for i in 0..4 {
                    let ca = c * a[i];
                    for j in 0..4 {
                        blk[4 * i + j] += ca * a[j];
                    }
                }
            }
            let gl = -wt[0] * r[0] * uv[0] - wt[1] * r[1] * uv[1];
            for i in 0..4 {
                g[i] += wt[0] * r[0] * a[i];
                g[4 + i] += wt[1] * r[1] * a[i];
                g[8 + i] += gl * a[i];
            }
        }
        let mut jtj = SMatrix::<f64, 12, 12>::zeros();
        for i in 0..4 {
            for j in 0..4 {
                let k = 4 * i + j;
                jtj[(i, j)] = blocks[0][k];
                jtj[(4 + i, 4 + j)] = blocks[1][k];
                jtj[(i, 8 + j)] = blocks[2][k];
                jtj[(8 + j, i)] = blocks[2][k];
                jtj[(4 + i, 8 + j)] = blocks[3][k];
                jtj[(8 + j, 4 + i)] = blocks[3][k];
                jtj[(8 + i, 8 + j)] = blocks[4][k];
            }
        }
        let step = damped_step(&mut lambda, &mut cost, 30, 1e-12, |lambda| {
            let mut a = jtj;
            for q in 0..12 {
                a[(q, q)] += lambda * (jtj[(q, q)] + 1e-12);
            }
            let dp = a.lu().solve(&(-g))?;
            let mut t = *m;
            for q in 0..12 {
                t[(q / 4, q % 4)] += dp[q];
            }
            t /= t.norm();
            Some((t, lp_cost(&t, pts, px, p)))
        });
        match step {
            Some((t, improved)) => {
                *m = t;
                if !improved {
                    break;
                }
            }
            None => break,
        }
    }
}

/// One damped (Levenberg-Marquardt) step: for a damping growing tenfold from `lambda`, at
/// most `tries` times, `propose(lambda)` gives a candidate and its cost (`None`: no solution
/// at this damping); the first that lowers `cost` is returned, `cost` and `lambda` (x 0.3,
/// at least 1e-12) updated, with whether it lowered the cost by more than `rel_tol` of it.
#[inline(always)]
fn damped_step<T>(
    lambda: &mut f64,
    cost: &mut f64,
    tries: usize,
    rel_tol: f64,
    mut propose: impl FnMut(f64) -> Option<(T, f64)>,
) -> Option<(T, bool)> {
    for _ in 0..tries {
        if let Some((t, c)) = propose(*lambda) {
            if c < *cost {
                let improved = *cost - c > rel_tol * *cost;
                *cost = c;
                *lambda = (*lambda * 0.3).max(1e-12);
                return Some((t, improved));
            }
        }
        *lambda *= 10.0;
    }
    None
}

/// The normalised DLT of one camera, signed so that the training points lie in front of it.
fn dlt_in_front(pts: &[[f64; 3]], px: &[[f64; 2]]) -> Option<Matrix3x4<f64>> {
    let m = fit_dlt(pts, px).ok()?;
    let front = pts.iter().map(|q| (m * Vector4::new(q[0], q[1], q[2], 1.0))[2]).sum::<f64>();
    Some(if front < 0.0 { -m } else { m })
}

/// The 3x4 projection matrix of one camera from the training targets and its pixels: the
/// normalised DLT, then the `sum |r|^p` fit for p = 2, 4, 8, .. [`LP_EXPONENT`].
pub(crate) fn fit_camera(pts: &[[f64; 3]], px: &[[f64; 2]]) -> Option<Matrix3x4<f64>> {
    let mut m = dlt_in_front(pts, px)?;
    let mut p = 2;
    refine(&mut m, pts, px, p);
    while p < LP_EXPONENT {
        p = (2 * p).min(LP_EXPONENT);
        refine(&mut m, pts, px, p);
    }
    m.iter().all(|v| v.is_finite()).then_some(m)
}

/// Largest reprojection residual (px) of `m` over a camera's training pixels.
pub(crate) fn max_residual(m: &Matrix3x4<f64>, pts: &[[f64; 3]], px: &[[f64; 2]]) -> f64 {
    pts.iter()
        .zip(px)
        .map(|(q, x)| match project(m, q) {
            Some(y) => (y[0] - x[0]).abs().max((y[1] - x[1]).abs()),
            None => f64::INFINITY,
        })
        .fold(0.0, f64::max)
}

/// Both cameras fitted to a quantised stereo set, if a pinhole camera explains each one
/// within [`MAX_RESIDUAL_PX`].
pub(crate) fn fit_cameras(data: &Dataset) -> Option<[Matrix3x4<f64>; 2]> {
    if !quantised(data) {
        return None;
    }
    // The two cameras are independent fits: one on each core.
    let fit = |cam: usize| -> Option<Matrix3x4<f64>> {
        let px: Vec<[f64; 2]> =
            (0..data.len()).map(|r| [data.row(r)[2 * cam], data.row(r)[2 * cam + 1]]).collect();
        let m = fit_camera(&data.targets, &px)?;
        (max_residual(&m, &data.targets, &px) <= MAX_RESIDUAL_PX).then_some(m)
    };
    let (l, r) = rayon::join(|| fit(0), || fit(1));
    Some([l?, r?])
}

/// The training set the net learns from on quantised pixels ([`fit_cameras`]):
/// [`SYNTHETIC_POINTS`] points uniform in the targets' box through the fitted cameras, each
/// pixel coordinate plus uniform noise in `[-0.5, 0.5)`, drawn from `seed`. `None` when the
/// data are not quantised, a pinhole fit does not explain them, or the box is degenerate.
pub(crate) fn distilled_set(data: &Dataset, seed: u64) -> Option<Dataset> {
    let cams = fit_cameras(data)?;
    let (lo, hi) = target_box(data)?;
    draw_set(
        (lo, hi),
        seed ^ STREAM,
        |p| Some((project(&cams[0], p)?, project(&cams[1], p)?)),
        |rng| rng.uniform(-0.5, 0.5),
    )
}

/// [`SYNTHETIC_POINTS`] points uniform in the box `(lo, hi)`, through `cams` (left and right
/// images of a point, `None` when it is not seen), each pixel coordinate plus a `noise` draw;
/// from the stream `seed`. `None` when fewer than half of them are seen.
fn draw_set(
    (lo, hi): ([f64; 3], [f64; 3]),
    seed: u64,
    cams: impl Fn(&[f64; 3]) -> Option<([f64; 2], [f64; 2])>,
    mut noise: impl FnMut(&mut SplitMix64) -> f64,
) -> Option<Dataset> {
    let mut rng = SplitMix64::new(seed);
    let mut out = Dataset::new(InputKind::Stereo);
    for _ in 0..SYNTHETIC_POINTS {
        let p: [f64; 3] = core::array::from_fn(|k| rng.uniform(lo[k], hi[k]));
        let Some((l, r)) = cams(&p) else {
            continue;
        };
        let mut px = [l[0], l[1], r[0], r[1]];
        for v in &mut px {
            *v += noise(&mut rng);
        }
        if px.iter().all(|v| v.is_finite()) {
            out.push(&px, Some(p));
        }
    }
    (out.len() >= SYNTHETIC_POINTS / 2).then_some(out)
}

/// A pinhole camera (3x4 matrix) seen through a radial lens about its principal point:
/// offset `o` from the principal point `c` of the matrix's projection moves to
/// `o (1 + k1 r^2 + k2 r^4)`, `r = |o| / scale` (what `hvs_shared::sim::camera::LensCamera`
/// does with a pinhole `K [R | t]`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct LensFit {
    pub m: Matrix3x4<f64>,
    pub k: [f64; 2],
    /// Unit radius (px) of `r`.
    pub scale: f64,
}

/// Principal point of a 3x4 projection matrix `K [R | t]`: `(m1 . m3, m2 . m3) / |m3|^2` of
/// the rows of its left 3x3 block.
fn principal_point(m: &Matrix3x4<f64>) -> Option<[f64; 2]> {
    let row = |i: usize| nalgebra::Vector3::new(m[(i, 0)], m[(i, 1)], m[(i, 2)]);
    let m3 = row(2);
    let n = m3.norm_squared();
    (n > 0.0).then(|| [row(0).dot(&m3) / n, row(1).dot(&m3) / n])
}

impl LensFit {
    /// Image of `p`, `None` behind the camera.
    pub fn project(&self, p: &[f64; 3]) -> Option<[f64; 2]> {
        let y = project(&self.m, p)?;
        let c = principal_point(&self.m)?;
        let o = [y[0] - c[0], y[1] - c[1]];
        let r2 = (o[0] * o[0] + o[1] * o[1]) / (self.scale * self.scale);
        let f = 1.0 + self.k[0] * r2 + self.k[1] * r2 * r2;
        Some([c[0] + o[0] * f, c[1] + o[1] * f])
    }

    fn params(&self) -> [f64; 14] {
        let mut q = [0.0; 14];
        for (i, v) in q.iter_mut().take(12).enumerate() {
            *v = self.m[(i / 4, i % 4)];
        }
        q[12] = self.k[0];
        q[13] = self.k[1];
        q
    }

    /// The fit with parameters `q` as they are (the matrix not renormalised).
    fn with_raw_params(&self, q: &[f64; 14]) -> LensFit {
        let mut m = self.m;
        for (i, v) in q.iter().take(12).enumerate() {
            m[(i / 4, i % 4)] = *v;
        }
        LensFit { m, k: [q[12], q[13]], scale: self.scale }
    }

    /// The fit with parameters `q`, the matrix scaled to unit Frobenius norm.
    fn with_params(&self, q: &[f64; 14]) -> LensFit {
        let f = self.with_raw_params(q);
        LensFit { m: f.m / f.m.norm(), ..f }
    }

    /// Sum of squared reprojection residuals (infinite when a point is behind the camera).
    pub fn cost(&self, pts: &[[f64; 3]], px: &[[f64; 2]]) -> f64 {
        let mut s = 0.0;
        for (q, x) in pts.iter().zip(px) {
            match self.project(q) {
                Some(y) => s += (y[0] - x[0]).powi(2) + (y[1] - x[1]).powi(2),
                None => return f64::INFINITY,
            }
        }
        if s.is_finite() {
            s
        } else {
            f64::INFINITY
        }
    }
}

/// Parameters of a [`LensFit`] (3x4 up to scale: 11, and `k1`, `k2`).
pub(crate) const LENS_FIT_DOF: usize = 13;

/// One camera's [`LensFit`] to its training pixels by least squares (Levenberg-Marquardt,
/// forward-difference Jacobian), from the normalised DLT and no lens.
pub(crate) fn fit_lens_camera(pts: &[[f64; 3]], px: &[[f64; 2]]) -> Option<LensFit> {
    let mut m = dlt_in_front(pts, px)?;
    m /= m.norm();
    // Unit radius: half the pixels' widest spread about the principal point.
    let c = principal_point(&m)?;
    let scale = px
        .iter()
        .map(|x| (x[0] - c[0]).abs().max((x[1] - c[1]).abs()))
        .fold(0.0, f64::max)
        .max(1.0);
    let mut fit = LensFit { m, k: [0.0; 2], scale };
    let n = pts.len();
    let resid = |f: &LensFit| -> Option<DVector<f64>> {
        let mut r = DVector::zeros(2 * n);
        for (i, (q, x)) in pts.iter().zip(px).enumerate() {
            let y = f.project(q)?;
            r[2 * i] = y[0] - x[0];
            r[2 * i + 1] = y[1] - x[1];
        }
        Some(r)
    };
    let mut r = resid(&fit)?;
    let mut cost = r.norm_squared();
    let mut lambda = 1e-3;
    for _ in 0..100 {
        let q = fit.params();
        let mut j = DMatrix::<f64>::zeros(2 * n, 14);
        for c in 0..14 {
            let h = 1e-7 * q[c].abs().max(1e-3);
            let mut qh = q;
            qh[c] += h;
            // Without the renormalisation: the derivative along the parameter itself.
            let rh = resid(&fit.with_raw_params(&qh))?;
            j.set_column(c, &((rh - &r) / h));
        }
        let jtj = j.transpose() * &j;
        let grad = j.transpose() * &r;
        let step = damped_step(&mut lambda, &mut cost, 20, 1e-10, |lambda| {
            let mut a = jtj.clone();
            for d in 0..14 {
                a[(d, d)] += lambda * (jtj[(d, d)] + 1e-12);
            }
            let dp = a.lu().solve(&(-&grad))?;
            let mut qt = q;
            for (v, d) in qt.iter_mut().zip(dp.iter()) {
                *v += d;
            }
            let t = fit.with_params(&qt);
            let rt = resid(&t)?;
            let ct = rt.norm_squared();
            Some(((t, rt), ct))
        });
        match step {
            Some(((t, rt), improved)) => {
                fit = t;
                r = rt;
                if !improved {
                    break;
                }
            }
            None => break,
        }
    }
    (fit.params().iter().all(|v| v.is_finite()) && cost.is_finite()).then_some(fit)
}

/// Precise pixels through a distorting lens: both cameras' [`LensFit`]s and the residual
/// variance (px^2 per coordinate, over the degrees of freedom) of the two fits.
pub(crate) fn fit_lens_cameras(data: &Dataset) -> Option<([LensFit; 2], f64)> {
    if data.n_inputs != 4 || data.len() < 3 * LENS_FIT_DOF || !data.has_targets() {
        return None;
    }
    let fit = |cam: usize| -> Option<(LensFit, f64)> {
        let px: Vec<[f64; 2]> =
            (0..data.len()).map(|r| [data.row(r)[2 * cam], data.row(r)[2 * cam + 1]]).collect();
        let f = fit_lens_camera(&data.targets, &px)?;
        let c = f.cost(&data.targets, &px);
        Some((f, c))
    };
    let (l, r) = rayon::join(|| fit(0), || fit(1));
    let ((l, cl), (r, cr)) = (l?, r?);
    let free = (4 * data.len()).checked_sub(2 * LENS_FIT_DOF)?;
    Some(([l, r], (cl + cr) / free as f64))
}

/// The synthetic training set of precise pixels through lenses: [`SYNTHETIC_POINTS`] points
/// uniform in the targets' box through the two [`LensFit`]s, each pixel coordinate plus
/// Gaussian noise of variance `var`, drawn from `seed`.
pub(crate) fn lens_distilled_set(
    data: &Dataset,
    cams: &[LensFit; 2],
    var: f64,
    seed: u64,
) -> Option<Dataset> {
    let (mut lo, mut hi) = target_box(data)?;
    for k in 0..2 {
        let w = hi[k] - lo[k];
        lo[k] -= LENS_MARGIN * w;
        hi[k] += LENS_MARGIN * w;
    }
    let sigma = var.max(0.0).sqrt();
    draw_set(
        (lo, hi),
        seed ^ LENS_STREAM,
        |p| Some((cams[0].project(p)?, cams[1].project(p)?)),
        |rng| sigma * gaussian(rng),
    )
}

/// A synthetic training set and how it is learned: the restarts on its first `selection`
/// points, the best of them then on all of them for at most `polish_iter` LM iterations.
#[derive(Debug, Clone)]
pub(crate) struct Distilled {
    pub set: Dataset,
    pub selection: usize,
    pub polish_iter: usize,
    /// Drawn through fitted lenses ([`lens_distilled`]), not pinhole cameras.
    pub lenses: bool,
}

/// How much wider (each side, as a fraction of the targets' extent) the lens-distilled points'
/// box is than the training targets' in X and Y: a lens bends the image most at its edges,
/// where the board's outer corners are and uniform points inside their box are few (tuning
/// seeds, rendered barrel images: margin 0 was worse than the measured points, 0.1 and 0.2
/// better; 0.2 the best on the rendered mild and barrel sets).
pub(crate) const LENS_MARGIN: f64 = 0.2;
/// Synthetic points the restarts learn on lens-distilled sets (a lens needs more than the
/// [`SELECTION_POINTS`] of a pinhole: 100 was worse than the measured points).
pub(crate) const LENS_SELECTION_POINTS: usize = 300;
/// Most LM iterations of the polish on lens-distilled sets (200 changed nothing).
pub(crate) const LENS_POLISH_MAX_ITER: usize = 100;
/// The lens fit is trusted when its residual variance is at most this times the pixel
/// noise variance that `decay` reads off the data (a smooth cubic per coordinate): a
/// radial lens about the principal point then explains the image as well as the cubic.
pub(crate) const LENS_MAX_VAR_RATIO: f64 = 2.0;
/// Fewest training points for a lens fit to be distilled. The thesis' 4x3 board at 2 cm (72
/// points, a small patch of the image where a lens barely bends it) was worse with it on the
/// tuning seeds (0.05 px noise, k1 0 to -0.2, case IV, bases 0 and 2,000,000: 1.02x, 1.05x
/// -> 1.01-1.05x, 1.06x the floor); the 9x6 board's 324 points better in most sub-pixel sets.
pub(crate) const LENS_MIN_POINTS: usize = 200;

/// Sub-pixel (not quantised) stereo pixels: the net's training set from the two fitted
/// [`LensFit`]s ([`lens_distilled_set`], noise of the fits' residual variance), when the
/// fits explain the pixels ([`LENS_MAX_VAR_RATIO`]). `None` for quantised sets (they have
/// [`distilled_set`]), sets of fewer than [`LENS_MIN_POINTS`], or pixels the fit does not
/// explain.
pub(crate) fn lens_distilled(data: &Dataset, seed: u64) -> Option<Distilled> {
    if quantised(data) || data.len() < LENS_MIN_POINTS {
        return None;
    }
    let noise = super::decay::pixel_noise(data)?;
    let (cams, var) = fit_lens_cameras(data)?;
    if var.is_nan() || var > LENS_MAX_VAR_RATIO * noise.var {
        return None;
    }
    Some(Distilled {
        set: lens_distilled_set(data, &cams, var, seed)?,
        selection: LENS_SELECTION_POINTS,
        polish_iter: LENS_POLISH_MAX_ITER,
        lenses: true,
    })
}

/// The synthetic training set of `data`, if one applies: quantised pixels through the
/// pinhole cameras fitted to them ([`distilled_set`]), otherwise precise pixels through the
/// fitted lenses ([`lens_distilled`]).
pub(crate) fn distilled(data: &Dataset, seed: u64) -> Option<Distilled> {
    match distilled_set(data, seed) {
        Some(set) => Some(Distilled {
            set,
            selection: SELECTION_POINTS,
            polish_iter: POLISH_MAX_ITER,
            lenses: false,
        }),
        None => lens_distilled(data, seed),
    }
}

/// A standard normal draw (Box-Muller).
fn gaussian(rng: &mut SplitMix64) -> f64 {
    let u = rng.next_f64().max(f64::MIN_POSITIVE);
    let v = rng.next_f64();
    (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
}

/// Mixed into the training seed for the lens-distilled points' stream.
const LENS_STREAM: u64 = 0x6c65_6e73_6469_7374;

/// The box of the training targets, `None` when it is degenerate.
fn target_box(data: &Dataset) -> Option<([f64; 3], [f64; 3])> {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for t in &data.targets {
        for k in 0..3 {
            lo[k] = lo[k].min(t[k]);
            hi[k] = hi[k].max(t[k]);
        }
    }
    (0..3).all(|k| hi[k] > lo[k]).then_some((lo, hi))
}

/// The first `n` rows of `data` (all of them when it has fewer).
pub(crate) fn prefix(data: &Dataset, n: usize) -> Dataset {
    let mut out = Dataset::new(InputKind::Stereo);
    for r in 0..data.len().min(n) {
        out.push(data.row(r), data.targets.get(r).copied());
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use hvs_shared::runtime::gaze::Joints;
    use hvs_shared::sim::camera::Distortion;
    use hvs_shared::sim::posture::HeadRig;
    use hvs_shared::sim::presets;

    fn thesis_points() -> Vec<[f64; 3]> {
        presets::TRAIN_DEPTHS.iter().flat_map(|z| presets::board_points(*z)).collect()
    }

    fn set(head: &HeadRig, pts: &[[f64; 3]], round: bool) -> Dataset {
        let mut d = Dataset::new(InputKind::Stereo);
        for p in pts {
            let px = if round {
                head.project_rounded(&Joints::HOME, p).unwrap()
            } else {
                head.project(&Joints::HOME, p).unwrap()
            };
            d.push(&px, Some(*p));
        }
        d
    }

    #[test]
    fn abs_pow_has_the_bits_of_powi() {
        // Residuals from tiny to large, both signs; every exponent up to 20.
        let mut rng = SplitMix64::new(11);
        for _ in 0..2000 {
            let x = (rng.uniform(-1.0, 1.0)) * 10f64.powi((rng.uniform(-8.0, 3.0)) as i32);
            for p in 0..=20u32 {
                let want = x.abs().powi(p as i32);
                assert_eq!(abs_pow(x, p).to_bits(), want.to_bits(), "{x}^{p}");
                // The copies unrolled for the fit's constants.
                let got = match p {
                    2 => abs_pow(x, 2),
                    6 => abs_pow(x, 6),
                    14 => abs_pow(x, 14),
                    16 => abs_pow(x, 16),
                    _ => continue,
                };
                assert_eq!(got.to_bits(), want.to_bits(), "{x}^{p} unrolled");
            }
        }
    }

    /// The camera fit's compiled builds this CPU runs have the portable build's bits (case IV's
    /// rounded board, each exponent the fit uses).
    #[test]
    fn the_camera_fits_builds_have_the_portable_bits() {
        let head = HeadRig::new(presets::CASE_4);
        let pts = thesis_points();
        let d = set(&head, &pts, true);
        let px: Vec<[f64; 2]> = (0..d.len()).map(|r| [d.row(r)[0], d.row(r)[1]]).collect();
        let start = dlt_in_front(&pts, &px).unwrap();
        for p in [2, 4, 8, 16] {
            let mut want = start;
            refine_exponents(&mut want, &pts, &px, p);
            let mut got = start;
            refine(&mut got, &pts, &px, p);
            assert_eq!(got.map(f64::to_bits), want.map(f64::to_bits), "dispatched, p {p}");
            #[cfg(target_arch = "x86_64")]
            for name in crate::simd::builds_here() {
                let mut got = start;
                // SAFETY: `builds_here` lists only what this CPU has.
                unsafe {
                    if name == "avx" {
                        refine_avx(&mut got, &pts, &px, p);
                    } else {
                        refine_avx512(&mut got, &pts, &px, p);
                    }
                }
                assert_eq!(got.map(f64::to_bits), want.map(f64::to_bits), "{name}, p {p}");
            }
        }
    }

    #[test]
    fn only_integer_stereo_sets_are_quantised() {
        let head = HeadRig::new(presets::CASE_4);
        assert!(quantised(&set(&head, &thesis_points(), true)));
        assert!(!quantised(&set(&head, &thesis_points(), false)));
        assert!(!quantised(&set(&head, &thesis_points()[..11], true)));
        assert!(distilled_set(&set(&head, &thesis_points(), false), 7).is_none());
    }

    #[test]
    fn exact_pixels_give_the_true_cameras_and_rounding_stays_within_half_a_pixel() {
        let head = HeadRig::new(presets::CASE_4);
        let pts = thesis_points();
        for (round, bound) in [(false, 1e-6), (true, 0.55)] {
            let d = set(&head, &pts, round);
            for cam in 0..2 {
                let px: Vec<[f64; 2]> =
                    (0..d.len()).map(|r| [d.row(r)[2 * cam], d.row(r)[2 * cam + 1]]).collect();
                let m = fit_camera(&pts, &px).unwrap();
                let worst = max_residual(&m, &pts, &px);
                assert!(worst <= bound, "round {round} camera {cam}: {worst} px");
                // A point off the board projects where the true camera puts it (rounded
                // pixels: within a quarter of the rounding step).
                let q = [2.5, -1.5, 100.0];
                let truth = head.project(&Joints::HOME, &q).unwrap();
                let y = project(&m, &q).unwrap();
                let tol = if round { 0.25 } else { 1e-6 };
                for c in 0..2 {
                    assert!((y[c] - truth[2 * cam + c]).abs() < tol, "{y:?} vs {truth:?}");
                }
            }
        }
    }

    #[test]
    fn distilled_set_is_seeded_and_inside_the_targets_box() {
        let d = set(&HeadRig::new(presets::CASE_1), &thesis_points(), true);
        let a = distilled_set(&d, 7).unwrap();
        assert_eq!(a.len(), SYNTHETIC_POINTS);
        assert_eq!(a.inputs, distilled_set(&d, 7).unwrap().inputs);
        assert_ne!(a.inputs, distilled_set(&d, 8).unwrap().inputs);
        for t in &a.targets {
            assert!(t[0].abs() <= 3.0 && t[1].abs() <= 2.0 && (65.0..=165.0).contains(&t[2]));
        }
        // The synthetic pixels are not integers: they carry one rounding step of noise.
        assert!(!quantised(&a));
    }

    /// The 9x6 board at 6 cm at the training depths.
    fn wide_board() -> Vec<[f64; 3]> {
        let mut pts = Vec::new();
        for z in presets::TRAIN_DEPTHS {
            for j in 0..6 {
                for i in 0..9 {
                    pts.push([(i as f64 - 4.0) * 6.0, (j as f64 - 2.5) * 6.0, z]);
                }
            }
        }
        pts
    }

    #[test]
    fn a_lens_fit_recovers_the_lens_of_precise_pixels() {
        let lens = Distortion { k1: -0.1, k2: 0.0 };
        let head = HeadRig::new(presets::CASE_4).with_distortion(lens);
        let pts = wide_board();
        let d = set(&head, &pts, false);
        let (cams, var) = fit_lens_cameras(&d).unwrap();
        assert!(var < 1e-12, "exact pixels: residual variance {var}");
        // Off the board and beyond its box: where the true cameras and lenses put it.
        for q in [[27.0, -17.0, 70.0], [-5.0, 8.0, 120.0], [30.0, 20.0, 160.0]] {
            let truth = head.project(&Joints::HOME, &q).unwrap();
            for (cam, f) in cams.iter().enumerate() {
                let y = f.project(&q).unwrap();
                for c in 0..2 {
                    let e = (y[c] - truth[2 * cam + c]).abs();
                    assert!(e < 1e-4, "{q:?} camera {cam}: {e} px");
                }
            }
        }
        // The barrel lens is in k1 (both cameras), not left as residual.
        assert!(cams.iter().all(|f| f.k[0] < -1e-3), "{:?}", cams.map(|f| f.k));
        // The distilled set: synthetic points beyond the targets' box, noise of the fit's.
        let dist = lens_distilled(&d, 7).unwrap();
        assert_eq!(dist.set.len(), SYNTHETIC_POINTS);
        assert_eq!(dist.selection, LENS_SELECTION_POINTS);
        assert!(dist.set.targets.iter().any(|t| t[0] > 24.0));
        assert!(dist.set.targets.iter().all(|t| t[0].abs() <= 24.0 * (1.0 + 2.0 * LENS_MARGIN)));
        assert_eq!(dist.set.inputs, lens_distilled(&d, 7).unwrap().set.inputs);
        assert_ne!(dist.set.inputs, lens_distilled(&d, 8).unwrap().set.inputs);
        // Quantised pixels are not for it (they have `distilled_set`), nor the thesis' small
        // board.
        assert!(lens_distilled(&set(&head, &pts, true), 7).is_none());
        assert!(lens_distilled(&set(&head, &thesis_points(), false), 7).is_none());
    }

    #[test]
    fn a_distorting_lens_on_a_wide_board_is_not_explained_by_a_pinhole() {
        let head = HeadRig::new(presets::CASE_1).with_distortion(Distortion { k1: -0.1, k2: 0.0 });
        let mut pts = Vec::new();
        for z in presets::TRAIN_DEPTHS {
            for j in 0..6 {
                for i in 0..9 {
                    pts.push([(i as f64 - 4.0) * 6.0, (j as f64 - 2.5) * 6.0, z]);
                }
            }
        }
        let d = set(&head, &pts, true);
        assert!(quantised(&d));
        assert!(fit_cameras(&d).is_none());
        let plain = set(&HeadRig::new(presets::CASE_1), &pts, true);
        assert!(fit_cameras(&plain).is_some());
    }
}
