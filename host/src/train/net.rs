//! The f64 training-side view of the MLP of `hvs_shared::runtime::mlp`: same parameter layout, same
//! shape (sigmoid hidden layer, linear or sigmoid outputs), in normalised units.
//!
//! A [`Problem`] holds the normalised inputs and targets and, per output value, the weight of
//! its residual. The least-squares algorithms (LM, Adam) minimise
//! `1/2 sum_nk (c_nk (y_nk - t_nk))^2`; back-propagation uses its own eq. 2.1-5.

// Index loops mirror the equations (several arrays indexed by the same unit numbers).
#![allow(clippy::needless_range_loop)]

use super::exp_lanes::{exp_lanes, LANES};
use hvs_shared::runtime::mlp::Activation;

/// Sizes of an `ni-nh-no` net and the index of every parameter in the shared layout: for each
/// hidden unit `j`, `w1[j][0..ni]` then `b1[j]`; then for each output `k`, `w2[k][0..nh]` then
/// `b2[k]`; then, with a linear skip term, `s[k][0..ni]` for each output `k`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Shape {
    pub ni: usize,
    pub nh: usize,
    pub no: usize,
    /// Linear skip term: output `k` also gets `sum_i s[k][i] x[i]`.
    pub skip: bool,
}

impl Shape {
    /// An `ni-nh-no` net, with the linear skip term if `skip`.
    pub(crate) const fn new(ni: usize, nh: usize, no: usize, skip: bool) -> Self {
        Shape { ni, nh, no, skip }
    }
    /// Number of parameters.
    pub(crate) fn n_params(&self) -> usize {
        hvs_shared::runtime::mlp::param_count(self.ni, self.nh, self.no)
            + if self.skip { self.ni * self.no } else { 0 }
    }
    /// Index of the skip weight `s[k][i]`.
    #[inline(always)]
    pub(crate) fn sk(&self, k: usize, i: usize) -> usize {
        hvs_shared::runtime::mlp::param_count(self.ni, self.nh, self.no) + k * self.ni + i
    }
    /// Length of the output layer's input vector `h~`: the hidden units, the bias, then (with a
    /// skip term) the inputs.
    #[inline(always)]
    pub(crate) fn ne(&self) -> usize {
        self.nh + 1 + if self.skip { self.ni } else { 0 }
    }
    /// Index of output `k`'s weight on entry `e` of `h~` (see [`Shape::ne`]).
    #[inline(always)]
    pub(crate) fn w2e(&self, k: usize, e: usize) -> usize {
        if e <= self.nh {
            self.w2(k, e)
        } else {
            self.sk(k, e - self.nh - 1)
        }
    }
    /// Index of `w1[j][i]` (`i == ni` is the bias `b1[j]`).
    #[inline(always)]
    pub(crate) fn w1(&self, j: usize, i: usize) -> usize {
        j * (self.ni + 1) + i
    }
    /// Index of `w2[k][j]` (`j == nh` is the bias `b2[k]`).
    #[inline(always)]
    pub(crate) fn w2(&self, k: usize, j: usize) -> usize {
        self.nh * (self.ni + 1) + k * (self.nh + 1) + j
    }
}

/// A training problem in normalised units.
#[derive(Debug, Clone)]
pub(crate) struct Problem {
    pub shape: Shape,
    /// Output activation.
    pub output: Activation,
    /// Number of samples.
    pub n: usize,
    /// `n * ni` normalised inputs, row-major.
    pub x: Vec<f64>,
    /// `n * no` normalised targets, row-major.
    pub t: Vec<f64>,
    /// `n * no` residual weights.
    pub c: Vec<f64>,
}

/// The logistic sigmoid in f64 (training only; inference uses the f32 one of `hvs_shared`).
#[inline(always)]
pub(crate) fn sigmoid(a: f64) -> f64 {
    1.0 / (1.0 + libm::exp(-a))
}

/// Forward pass of one sample: hidden activations into `h`, outputs into `y`.
#[inline]
pub(crate) fn forward(
    s: &Shape,
    output: Activation,
    p: &[f64],
    x: &[f64],
    h: &mut [f64],
    y: &mut [f64],
) {
    for (j, hj) in h.iter_mut().enumerate().take(s.nh) {
        let row = &p[s.w1(j, 0)..s.w1(j, 0) + s.ni + 1];
        let mut a = row[s.ni];
        for (w, xi) in row[..s.ni].iter().zip(x) {
            a += w * xi;
        }
        *hj = sigmoid(a);
    }
    for (k, yk) in y.iter_mut().enumerate().take(s.no) {
        let row = &p[s.w2(k, 0)..s.w2(k, 0) + s.nh + 1];
        let mut a = row[s.nh];
        for (w, hj) in row[..s.nh].iter().zip(h.iter()) {
            a += w * hj;
        }
        if s.skip {
            for (i, xi) in x.iter().enumerate().take(s.ni) {
                a += p[s.sk(k, i)] * xi;
            }
        }
        *yk = match output {
            Activation::Linear => a,
            Activation::Sigmoid => sigmoid(a),
        };
    }
}

crate::simd::x86_dispatch! {
    /// [`Problem::accumulate`] of `prob` (`at`: the parameters, their forward pass and the
    /// packed inputs): tiles 16 columns wide with AVX-512F, 8 with AVX, 4 otherwise.
    fn accumulate_on(
        prob: &Problem,
        at: (&[f64], &Activations, &[f64]),
        range: std::ops::Range<usize>,
        part: &mut Part,
    ) -> f64 {
        avx512 accumulate_avx512: prob.accumulate_in::<16>(at, range, part),
        avx accumulate_avx: prob.accumulate_in::<8>(at, range, part),
        portable: prob.accumulate_in::<4>(at, range, part),
    }
}

crate::simd::x86_dispatch! {
    /// [`Problem::forward_range`] of `prob`.
    fn forward_range_on(prob: &Problem, p: &[f64], first: usize, h: &mut [f64], y: &mut [f64]) -> f64 {
        avx512 forward_range_avx512: prob.forward_range_in(p, first, h, y),
        avx forward_range_avx: prob.forward_range_in(p, first, h, y),
        portable: prob.forward_range_in(p, first, h, y),
    }
}

/// [`forward`] of [`LANES`] samples (`x`: `LANES * ni` values, `h` and `y` likewise), the
/// same bits: each sample's sums in the same order, the sigmoid's `exp` by [`exp_lanes`].
#[inline(always)]
fn forward_lanes(
    s: &Shape,
    output: Activation,
    p: &[f64],
    (x, h, y): (&[f64], &mut [f64], &mut [f64]),
) {
    let sigmoid_lanes = |a: [f64; LANES]| -> [f64; LANES] {
        let e = exp_lanes(&a.map(|v| -v));
        e.map(|e| 1.0 / (1.0 + e))
    };
    // The hidden units' lanes on the stack for every net a model holds (a buffer from the
    // heap, 5 % slower in `hvs train`, only for the larger nets of tests).
    const STACK: usize = hvs_shared::runtime::blob::MAX_HIDDEN;
    let mut stack = [[0.0; LANES]; STACK];
    let mut heap = Vec::new();
    let hl: &mut [[f64; LANES]] = if s.nh <= STACK {
        &mut stack[..s.nh]
    } else {
        heap.resize(s.nh, [0.0; LANES]);
        &mut heap
    };
    for (j, hj) in hl.iter_mut().enumerate() {
        let row = &p[s.w1(j, 0)..s.w1(j, 0) + s.ni + 1];
        let mut a = [row[s.ni]; LANES];
        for (i, w) in row[..s.ni].iter().enumerate() {
            for l in 0..LANES {
                a[l] += w * x[l * s.ni + i];
            }
        }
        *hj = sigmoid_lanes(a);
        for l in 0..LANES {
            h[l * s.nh + j] = hj[l];
        }
    }
    for k in 0..s.no {
        let row = &p[s.w2(k, 0)..s.w2(k, 0) + s.nh + 1];
        let mut a = [row[s.nh]; LANES];
        for (w, hj) in row[..s.nh].iter().zip(hl.iter()) {
            for l in 0..LANES {
                a[l] += w * hj[l];
            }
        }
        if s.skip {
            for i in 0..s.ni {
                let w = p[s.sk(k, i)];
                for l in 0..LANES {
                    a[l] += w * x[l * s.ni + i];
                }
            }
        }
        let a = match output {
            Activation::Linear => a,
            Activation::Sigmoid => sigmoid_lanes(a),
        };
        for l in 0..LANES {
            y[l * s.no + k] = a[l];
        }
    }
}

/// Hidden activations (`n x nh`) and outputs (`n x no`) of every sample at one parameter
/// vector, row-major.
#[derive(Debug, Clone)]
pub(crate) struct Activations {
    h: Vec<f64>,
    y: Vec<f64>,
}

/// Sets of at least this many samples have their normal equations summed in two fixed
/// halves side by side (rayon), then added: the split depends on the sample count alone, so
/// the result does not depend on the number of threads. Smaller sets (the restarts of a
/// 4-input training, 72-300 points) are summed in one pass, as before.
pub(crate) const SPLIT_MIN_SAMPLES: usize = 1024;

/// Scratch of [`Problem::normal_equations`] for one problem, allocated once per fit.
#[derive(Debug, Clone)]
pub(crate) struct NormalWorkspace {
    /// Row `n` (`nx_p` values, zeros after `nx`): the packed upper triangle of `x~ x~^T`
    /// (constant over a fit).
    xpk: Vec<f64>,
    /// One accumulator per part of the samples (two for [`SPLIT_MIN_SAMPLES`] or more).
    parts: Vec<Part>,
}

/// Samples whose per-sample vectors [`Problem::accumulate`] buffers before it adds them into
/// the sums, tile by tile ([`add_products_in`]).
const CHUNK: usize = 32;

/// `n` rounded up to a whole number of [`add_products_in`]' tiles (4).
const fn pad4(n: usize) -> usize {
    n.div_ceil(4) * 4
}

/// The sizes of [`Problem::normal_equations`]' sums for one shape, each padded to whole tiles
/// (the padding holds zeros in the inputs and is never read from the sums).
#[derive(Debug, Clone, Copy)]
struct Dims {
    /// `x~` (`ni + 1`) and `h~` ([`Shape::ne`]).
    ni1: usize,
    ne: usize,
    /// Packed `U_n` (`nh (nh + 1) / 2`), padded.
    nu: usize,
    /// Packed `x~ x~^T` (`ni1 (ni1 + 1) / 2`), padded.
    nx_p: usize,
    /// `g_k^2 u_k` stacked (`no nh`), padded.
    na: usize,
    /// `x~ (x) h~` (`ni1 ne`), padded.
    nb_p: usize,
    /// `h~` padded: a row of an output's square second-layer block.
    ne_p: usize,
}

impl Dims {
    fn new(s: &Shape) -> Self {
        let (ni1, ne) = (s.ni + 1, s.ne());
        let nx = ni1 * (ni1 + 1) / 2;
        Dims {
            ni1,
            ne,
            nu: pad4(s.nh * (s.nh + 1) / 2),
            nx_p: pad4(nx),
            na: pad4(s.no * s.nh),
            nb_p: pad4(ni1 * ne),
            ne_p: pad4(ne),
        }
    }
}

/// The sums of [`Problem::normal_equations`] over one range of samples, with its scratch.
#[derive(Debug, Clone)]
struct Part {
    /// `nu x nx`, row-major (rows padded): the packed first-layer block `sum_n U_n (x) X_n`.
    m: Vec<f64>,
    /// `(no nh) x (ni1 ne)`, row-major (padded): the cross blocks.
    cross: Vec<f64>,
    /// `sum_n g_k^2 h~ h~^T` per output, `ne_p x ne_p` row-major; only the tiles on and above
    /// the diagonal are summed (the others hold whatever they hold).
    w2w2: Vec<f64>,
    /// `J^T r` of the range.
    jtr: Vec<f64>,
    /// Per sample of a chunk (`CHUNK` rows each): packed `U_n` (`nu`), ...
    ub: Vec<f64>,
    /// ... `g_k^2 u_k` stacked (`no nh`), ...
    ab: Vec<f64>,
    /// ... `x~ (x) h~` (`ni1 ne`), ...
    bb: Vec<f64>,
    /// ... `g_k^2 h~` per output (`no ne`), ...
    gb: Vec<f64>,
    /// ... and `h~` (`ne`).
    hb: Vec<f64>,
    y: Vec<f64>,
    gu: Vec<f64>,
    rb: Vec<f64>,
}

impl Part {
    fn new(s: &Shape) -> Self {
        let d = Dims::new(s);
        Part {
            m: vec![0.0; d.nu * d.nx_p],
            cross: vec![0.0; d.na * d.nb_p],
            w2w2: vec![0.0; s.no * d.ne_p * d.ne_p],
            jtr: vec![0.0; s.n_params()],
            ub: vec![0.0; CHUNK * d.nu],
            ab: vec![0.0; CHUNK * d.na],
            bb: vec![0.0; CHUNK * d.nb_p],
            gb: vec![0.0; CHUNK * s.no * d.ne_p],
            hb: vec![0.0; CHUNK * d.ne_p],
            y: vec![0.0; s.no],
            gu: vec![0.0; s.nh],
            rb: vec![0.0; s.nh],
        }
    }

    /// Adds `other`'s sums to this part's.
    fn add(&mut self, other: &Part) {
        for (a, b) in [
            (&mut self.m, &other.m),
            (&mut self.cross, &other.cross),
            (&mut self.w2w2, &other.w2w2),
            (&mut self.jtr, &other.jtr),
        ] {
            axpy(a, 1.0, b);
        }
    }
}

impl NormalWorkspace {
    /// Scratch for `prob`.
    pub(crate) fn new(prob: &Problem) -> Self {
        let s = &prob.shape;
        let (d, n) = (Dims::new(s), prob.n);
        let mut xpk = Vec::with_capacity(n * d.nx_p);
        for r in 0..n {
            let x = &prob.x[r * s.ni..(r + 1) * s.ni];
            let xt = |i: usize| if i < s.ni { x[i] } else { 1.0 };
            for i in 0..d.ni1 {
                for i2 in i..d.ni1 {
                    xpk.push(xt(i) * xt(i2));
                }
            }
            xpk.resize((r + 1) * d.nx_p, 0.0);
        }
        let parts = if n >= SPLIT_MIN_SAMPLES { 2 } else { 1 };
        NormalWorkspace { xpk, parts: vec![Part::new(s); parts] }
    }
}

/// `dst += a * src`, element by element.
#[inline(always)]
fn axpy(dst: &mut [f64], a: f64, src: &[f64]) {
    for (d, v) in dst.iter_mut().zip(src) {
        *d += a * v;
    }
}

/// `dst[r * ldd + c] += sum_t u[t * ldu + r] * x[t * ldx + c]` for `r < rows`, `c < cols` and
/// `t` in `0..len`: each element adds its products in the order of `t`, so the result has
/// the bits of adding one sample after the other ([`axpy`] per sample). `rows` and `cols`
/// are whole tiles: the elements are summed in register tiles of 4 x `W` while they fit, then
/// 4 x 8 and 4 x 4 (SIMD pairs of f64 on the x86-64 baseline, `W` = 4; quadruples and `W` =
/// 8 in [`Problem::accumulate`]'s AVX build, eights and `W` = 16 in its AVX-512 build; plain
/// multiplies and adds, no fused multiply-add, so every machine gives the same bits).
#[inline(always)]
fn add_products_in<const W: usize>(
    dst: &mut [f64],
    (rows, cols, ldd): (usize, usize, usize),
    (u, ldu): (&[f64], usize),
    (x, ldx): (&[f64], usize),
    len: usize,
) {
    debug_assert!(rows % 4 == 0 && cols % 4 == 0, "padded to whole tiles");
    if len == 0 {
        return;
    }
    for r0 in (0..rows).step_by(4) {
        let mut c0 = 0;
        while c0 < cols {
            let d = &mut dst[r0 * ldd + c0..];
            let (u, x) = ((&u[r0..], ldu), (&x[c0..], ldx));
            if W >= 16 && cols - c0 >= 16 {
                tile::<16>(d, ldd, u, x, len);
                c0 += 16;
            } else if W >= 8 && cols - c0 >= 8 {
                tile::<8>(d, ldd, u, x, len);
                c0 += 8;
            } else {
                tile::<4>(d, ldd, u, x, len);
                c0 += 4;
            }
        }
    }
}

/// One 4 x `C` tile of [`add_products_in`] (`dst`, `u` and `x` start at the tile's corner).
#[inline(always)]
fn tile<const C: usize>(
    dst: &mut [f64],
    ldd: usize,
    (u, ldu): (&[f64], usize),
    (x, ldx): (&[f64], usize),
    len: usize,
) {
    const R: usize = 4;
    let mut acc = [[0.0f64; C]; R];
    for (r, a) in acc.iter_mut().enumerate() {
        a.copy_from_slice(&dst[r * ldd..r * ldd + C]);
    }
    for t in 0..len {
        let ur = &u[t * ldu..t * ldu + R];
        let xr = &x[t * ldx..t * ldx + C];
        for r in 0..R {
            for c in 0..C {
                acc[r][c] += ur[r] * xr[c];
            }
        }
    }
    for (r, a) in acc.iter().enumerate() {
        dst[r * ldd..r * ldd + C].copy_from_slice(a);
    }
}

impl Problem {
    /// Number of residuals.
    pub(crate) fn n_res(&self) -> usize {
        self.n * self.shape.no
    }

    /// Residual `row` (`n * no + k`) for the output value `yk`, `c (y - t)`, and its derivative
    /// with respect to the pre-activation of output `k`.
    #[inline(always)]
    fn residual(&self, row: usize, yk: f64) -> (f64, f64) {
        let c = self.c[row];
        let slope = match self.output {
            Activation::Linear => c,
            Activation::Sigmoid => c * yk * (1.0 - yk),
        };
        (c * (yk - self.t[row]), slope)
    }

    /// Weighted residuals `c (y - t)` into `r` (length `n * no`); returns half their squared sum.
    pub(crate) fn residuals(&self, p: &[f64], r: &mut [f64]) -> f64 {
        let s = &self.shape;
        let mut h = vec![0.0; s.nh];
        let mut y = vec![0.0; s.no];
        let mut cost = 0.0;
        for n in 0..self.n {
            forward(s, self.output, p, &self.x[n * s.ni..(n + 1) * s.ni], &mut h, &mut y);
            for k in 0..s.no {
                let idx = n * s.no + k;
                let v = self.c[idx] * (y[k] - self.t[idx]);
                r[idx] = v;
                cost += v * v;
            }
        }
        0.5 * cost
    }

    /// Zeroed storage for the forward pass of every sample.
    pub(crate) fn activations(&self) -> Activations {
        Activations { h: vec![0.0; self.n * self.shape.nh], y: vec![0.0; self.n * self.shape.no] }
    }

    /// Forward pass of every sample at `p` into `act`; returns the cost `1/2 sum r^2`.
    /// Like the normal equations, a set of [`SPLIT_MIN_SAMPLES`] or more is run in two fixed
    /// halves side by side and their sums added.
    pub(crate) fn evaluate(&self, p: &[f64], act: &mut Activations) -> f64 {
        let s = &self.shape;
        if self.n < SPLIT_MIN_SAMPLES {
            return 0.5 * self.forward_range(p, 0, &mut act.h, &mut act.y);
        }
        let mid = self.n / 2;
        let (h0, h1) = act.h.split_at_mut(mid * s.nh);
        let (y0, y1) = act.y.split_at_mut(mid * s.no);
        let (c0, c1) =
            rayon::join(|| self.forward_range(p, 0, h0, y0), || self.forward_range(p, mid, h1, y1));
        0.5 * (c0 + c1)
    }

    /// The forward pass of the samples from `first` on into `h` and `y` (as many as they
    /// hold); returns their sum of squared residuals.
    ///
    /// [`LANES`] samples at a time ([`forward_lanes`]), the rest one by one. Compiled for AVX
    /// and AVX-512F too, picked at run time (the same bits).
    fn forward_range(&self, p: &[f64], first: usize, h: &mut [f64], y: &mut [f64]) -> f64 {
        forward_range_on(self, p, first, h, y)
    }

    #[inline(always)]
    fn forward_range_in(&self, p: &[f64], first: usize, h: &mut [f64], y: &mut [f64]) -> f64 {
        let s = &self.shape;
        let count = y.len() / s.no;
        let whole = count - count % LANES;
        for b in (0..whole).step_by(LANES) {
            let n = first + b;
            let block = (
                &self.x[n * s.ni..(n + LANES) * s.ni],
                &mut h[b * s.nh..(b + LANES) * s.nh],
                &mut y[b * s.no..(b + LANES) * s.no],
            );
            forward_lanes(s, self.output, p, block);
        }
        let mut cost = 0.0;
        for (i, (h, y)) in h.chunks_exact_mut(s.nh).zip(y.chunks_exact_mut(s.no)).enumerate() {
            let n = first + i;
            if i >= whole {
                forward(s, self.output, p, &self.x[n * s.ni..(n + 1) * s.ni], h, y);
            }
            for k in 0..s.no {
                let idx = n * s.no + k;
                let v = self.c[idx] * (y[k] - self.t[idx]);
                cost += v * v;
            }
        }
        cost
    }

    /// Half the weighted squared error at `p`.
    pub(crate) fn cost(&self, p: &[f64]) -> f64 {
        let mut r = vec![0.0; self.n_res()];
        self.residuals(p, &mut r)
    }

    #[cfg(test)]
    /// Residuals into `r` and their Jacobian into `jac`, column-major `n_res x n_params`
    /// (`jac[q * n_res + row]` is `d r_row / d p_q`, row `n * no + k`). Returns the cost.
    /// `jac` must be zero wherever an output does not depend on a parameter (the entries for
    /// the other outputs' `w2`); this function only writes the structurally non-zero entries,
    /// so callers zero it once.
    pub(crate) fn jacobian(&self, p: &[f64], r: &mut [f64], jac: &mut [f64]) -> f64 {
        let s = &self.shape;
        let nr = self.n_res();
        let mut h = vec![0.0; s.nh];
        let mut dh = vec![0.0; s.nh];
        let mut y = vec![0.0; s.no];
        let mut cost = 0.0;
        for n in 0..self.n {
            let x = &self.x[n * s.ni..(n + 1) * s.ni];
            forward(s, self.output, p, x, &mut h, &mut y);
            for j in 0..s.nh {
                dh[j] = h[j] * (1.0 - h[j]);
            }
            for k in 0..s.no {
                let row = n * s.no + k;
                let (v, g) = self.residual(row, y[k]);
                r[row] = v;
                cost += v * v;
                for j in 0..s.nh {
                    jac[s.w2(k, j) * nr + row] = g * h[j];
                }
                jac[s.w2(k, s.nh) * nr + row] = g;
                if s.skip {
                    for (i, xi) in x.iter().enumerate() {
                        jac[s.sk(k, i) * nr + row] = g * xi;
                    }
                }
                for j in 0..s.nh {
                    let gj = g * p[s.w2(k, j)] * dh[j];
                    for (i, xi) in x.iter().enumerate() {
                        jac[s.w1(j, i) * nr + row] = gj * xi;
                    }
                    jac[s.w1(j, s.ni) * nr + row] = gj;
                }
            }
        }
        0.5 * cost
    }

    /// The Gauss-Newton normal equations without forming the Jacobian: `jtj = J^T J` (full,
    /// row-major `np x np`) and `jtr = J^T r`; returns the cost `1/2 sum r^2`. `act` must hold
    /// the forward pass at `p` ([`Problem::evaluate`]), `ws` come from
    /// [`NormalWorkspace::new`] on this problem.
    ///
    /// The Jacobian row of output `k` of sample `n` is `(g_k u_k) (x) x~` on the first layer
    /// (`u_kj = w2_kj h_j (1 - h_j)`, `x~ = (x, 1)`, `g_k = d r / d a2_k`) and `g_k h~` on
    /// output `k`'s second-layer weights (`h~ = (h, 1)`); other outputs' weights get zeros.
    /// So, summing over samples:
    /// - first-layer block: `sum_n U_n (x) X_n` with `U = sum_k g_k^2 u_k u_k^T`,
    ///   `X = x~ x~^T`, accumulated over their packed upper triangles;
    /// - cross block of output `k`: `sum_n (g_k^2 u_k) (x~ (x) h~)^T`;
    /// - second-layer block of output `k`: `sum_n g_k^2 h~ h~^T`.
    ///
    /// This is about a third of the work of `J^T J` on the explicit Jacobian. Every sum runs
    /// in a fixed order (sample by sample) in plain f64 multiplies and adds, so the result is
    /// the same on every machine: the AVX build of the tiled sums ([`add_products_in`]) gives the
    /// bits of the portable one.
    pub(crate) fn normal_equations(
        &self,
        p: &[f64],
        act: &Activations,
        jtj: &mut [f64],
        jtr: &mut [f64],
        ws: &mut NormalWorkspace,
    ) -> f64 {
        let s = &self.shape;
        let (ni1, ne, np) = (s.ni + 1, s.ne(), s.n_params());
        let xpk = &ws.xpk;
        let cost = match ws.parts.as_mut_slice() {
            [one] => self.accumulate(p, act, xpk, 0..self.n, one),
            [first, second] => {
                let mid = self.n / 2;
                let (c0, c1) = rayon::join(
                    || self.accumulate(p, act, xpk, 0..mid, first),
                    || self.accumulate(p, act, xpk, mid..self.n, second),
                );
                first.add(second);
                c0 + c1
            }
            _ => unreachable!("a workspace has one or two parts"),
        };
        let Part { m, cross, w2w2, jtr: sums, .. } = &ws.parts[0];
        jtr.copy_from_slice(sums);
        let d = Dims::new(s);
        let (nx, ne_p) = (d.nx_p, d.ne_p);

        // Expand into the full matrix.
        let pack = |a: usize, b: usize, dim: usize| {
            let (a, b) = if a <= b { (a, b) } else { (b, a) };
            a * dim - a * (a + 1) / 2 + b
        };
        for j in 0..s.nh {
            for j2 in 0..s.nh {
                let u = pack(j, j2, s.nh);
                for i in 0..ni1 {
                    for i2 in 0..ni1 {
                        jtj[s.w1(j, i) * np + s.w1(j2, i2)] = m[u * nx + pack(i, i2, ni1)];
                    }
                }
            }
        }
        for k in 0..s.no {
            for k2 in 0..s.no {
                for j2 in 0..ne {
                    for j3 in 0..ne {
                        jtj[s.w2e(k, j2) * np + s.w2e(k2, j3)] = if k2 == k {
                            w2w2[(k * ne_p + j2.min(j3)) * ne_p + j2.max(j3)]
                        } else {
                            0.0
                        };
                    }
                }
            }
            for j in 0..s.nh {
                for i in 0..ni1 {
                    for j2 in 0..ne {
                        let v = cross[(k * s.nh + j) * d.nb_p + i * ne + j2];
                        let e = s.w2e(k, j2);
                        jtj[s.w1(j, i) * np + e] = v;
                        jtj[e * np + s.w1(j, i)] = v;
                    }
                }
            }
        }
        0.5 * cost
    }

    /// The sums of [`Problem::normal_equations`] over the samples `range` into `part` (its
    /// blocks and `J^T r`, zeroed first); returns the sum of squared residuals there. A chunk
    /// of samples at a time: their per-sample vectors first, then the blocks' sums over them
    /// ([`add_products_in`], each element in sample order). Compiled for AVX too, picked at run
    /// time: plain multiplies and adds in the same order, so the same bits.
    fn accumulate(
        &self,
        p: &[f64],
        act: &Activations,
        xpk: &[f64],
        range: std::ops::Range<usize>,
        part: &mut Part,
    ) -> f64 {
        accumulate_on(self, (p, act, xpk), range, part)
    }

    /// The body of [`Problem::accumulate`], its tiles `W` columns wide ([`add_products_in`]).
    #[inline(always)]
    fn accumulate_in<const W: usize>(
        &self,
        (p, act, xpk): (&[f64], &Activations, &[f64]),
        range: std::ops::Range<usize>,
        part: &mut Part,
    ) -> f64 {
        let s = &self.shape;
        let d = Dims::new(s);
        let (ni1, ne, nu, na, nb, ne_p) = (d.ni1, d.ne, d.nu, d.na, d.nb_p, d.ne_p);
        let nge = s.no * ne_p;
        let Part { m, cross, w2w2, jtr, ub, ab, bb, gb, hb, y, gu, rb } = part;
        m.iter_mut().for_each(|v| *v = 0.0);
        cross.iter_mut().for_each(|v| *v = 0.0);
        w2w2.iter_mut().for_each(|v| *v = 0.0);
        jtr.iter_mut().for_each(|v| *v = 0.0);
        let mut cost = 0.0;
        let mut n0 = range.start;
        while n0 < range.end {
            let len = (range.end - n0).min(CHUNK);
            for t in 0..len {
                let n = n0 + t;
                let x = &self.x[n * s.ni..(n + 1) * s.ni];
                let ht = &mut hb[t * ne_p..t * ne_p + ne];
                ht[..s.nh].copy_from_slice(&act.h[n * s.nh..(n + 1) * s.nh]);
                ht[s.nh] = 1.0;
                if s.skip {
                    ht[s.nh + 1..].copy_from_slice(x);
                }
                let ht = &hb[t * ne_p..t * ne_p + ne];
                y.copy_from_slice(&act.y[n * s.no..(n + 1) * s.no]);
                // x~ (x) h~.
                let b = &mut bb[t * nb..t * nb + ni1 * ne];
                for (i, row) in b.chunks_exact_mut(ne).enumerate() {
                    let xi = if i < s.ni { x[i] } else { 1.0 };
                    for (v, h) in row.iter_mut().zip(ht) {
                        *v = xi * h;
                    }
                }
                // The padding after each row stays zero.
                let upk = &mut ub[t * nu..t * nu + s.nh * (s.nh + 1) / 2];
                let a = &mut ab[t * na..(t + 1) * na];
                let g2h = &mut gb[t * nge..(t + 1) * nge];
                upk.iter_mut().for_each(|v| *v = 0.0);
                rb.iter_mut().for_each(|v| *v = 0.0);
                for k in 0..s.no {
                    let row = n * s.no + k;
                    let (rk, g) = self.residual(row, y[k]);
                    cost += rk * rk;
                    let base = s.w2(k, 0);
                    for j in 0..s.nh {
                        gu[j] = g * p[base + j] * ht[j] * (1.0 - ht[j]);
                        a[k * s.nh + j] = g * gu[j];
                        rb[j] += rk * gu[j];
                    }
                    // upk[(j, j2)] += gu[j] gu[j2] for j2 >= j, a row at a time.
                    let mut q = 0;
                    for j in 0..s.nh {
                        let w = s.nh - j;
                        axpy(&mut upk[q..q + w], gu[j], &gu[j..]);
                        q += w;
                    }
                    // Second layer (and skip weights) of output k: g h~. Its weights are
                    // w2(k, 0..=nh) then the skip weights sk(k, 0..ni) (`Shape::w2e`).
                    let (rg, gg) = (rk * g, g * g);
                    let (bias_end, skip0) = (base + s.nh + 1, s.sk(k, 0));
                    axpy(&mut jtr[base..bias_end], rg, &ht[..=s.nh]);
                    if s.skip {
                        axpy(&mut jtr[skip0..skip0 + s.ni], rg, &ht[s.nh + 1..]);
                    }
                    for (v, h) in g2h[k * ne_p..k * ne_p + ne].iter_mut().zip(ht) {
                        *v = gg * h;
                    }
                }
                // First-layer gradient: sum_k r_k g_k u_kj x~_i.
                for j in 0..s.nh {
                    let w = s.w1(j, 0);
                    axpy(&mut jtr[w..w + s.ni], rb[j], x);
                    jtr[w + s.ni] += rb[j];
                }
            }
            // The chunk's rank-one updates: the packed first-layer block, the cross blocks,
            // and each output's second-layer block, the tiles on and above its diagonal.
            let nx_p = d.nx_p;
            add_products_in::<W>(m, (nu, nx_p, nx_p), (ub, nu), (&xpk[n0 * nx_p..], nx_p), len);
            add_products_in::<W>(cross, (na, nb, nb), (ab, na), (bb, nb), len);
            for k in 0..s.no {
                for r0 in (0..ne_p).step_by(4) {
                    add_products_in::<W>(
                        &mut w2w2[(k * ne_p + r0) * ne_p + r0..],
                        (4, ne_p - r0, ne_p),
                        (&gb[k * ne_p + r0..], nge),
                        (&hb[r0..], ne_p),
                        len,
                    );
                }
            }
            n0 += len;
        }
        cost
    }

    /// Gradient of the cost into `grad` by back-propagation; returns the cost.
    pub(crate) fn gradient(&self, p: &[f64], grad: &mut [f64]) -> f64 {
        let s = &self.shape;
        let mut h = vec![0.0; s.nh];
        let mut y = vec![0.0; s.no];
        let mut dhid = vec![0.0; s.nh];
        grad.iter_mut().for_each(|g| *g = 0.0);
        let mut cost = 0.0;
        for n in 0..self.n {
            let x = &self.x[n * s.ni..(n + 1) * s.ni];
            forward(s, self.output, p, x, &mut h, &mut y);
            dhid.iter_mut().for_each(|d| *d = 0.0);
            for k in 0..s.no {
                let row = n * s.no + k;
                let (v, dv) = self.residual(row, y[k]);
                cost += v * v;
                let g = v * dv;
                for j in 0..s.nh {
                    grad[s.w2(k, j)] += g * h[j];
                    dhid[j] += g * p[s.w2(k, j)];
                }
                grad[s.w2(k, s.nh)] += g;
                if s.skip {
                    for (i, xi) in x.iter().enumerate() {
                        grad[s.sk(k, i)] += g * xi;
                    }
                }
            }
            for j in 0..s.nh {
                let gj = dhid[j] * h[j] * (1.0 - h[j]);
                for (i, xi) in x.iter().enumerate() {
                    grad[s.w1(j, i)] += gj * xi;
                }
                grad[s.w1(j, s.ni)] += gj;
            }
        }
        0.5 * cost
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::train::rng::SplitMix64;

    /// A random problem of the given shape with smooth targets.
    pub(crate) fn random_problem(shape: Shape, output: Activation, n: usize, seed: u64) -> Problem {
        let mut g = SplitMix64::new(seed);
        let x: Vec<f64> = (0..n * shape.ni).map(|_| g.uniform(-1.0, 1.0)).collect();
        let mut t = Vec::new();
        for row in x.chunks(shape.ni) {
            for k in 0..shape.no {
                let v: f64 = row.iter().enumerate().map(|(i, v)| v * (i + k + 1) as f64).sum();
                t.push(match output {
                    Activation::Linear => (0.7 * v).sin(),
                    Activation::Sigmoid => 0.5 + 0.4 * (0.7 * v).sin(),
                });
            }
        }
        let c = (0..n * shape.no).map(|_| g.uniform(0.5, 2.0)).collect();
        Problem { shape, output, n, x, t, c }
    }

    /// [`random_problem`] with a linear output, random parameters from `seeds[1]` and their cost.
    pub(crate) fn random_start(
        shape: Shape,
        n: usize,
        seeds: [u64; 2],
    ) -> (Problem, Vec<f64>, f64) {
        let prob = random_problem(shape, Activation::Linear, n, seeds[0]);
        let p = random_params(&shape, seeds[1]);
        let cost = prob.cost(&p);
        (prob, p, cost)
    }

    pub(crate) fn random_params(shape: &Shape, seed: u64) -> Vec<f64> {
        let mut g = SplitMix64::new(seed);
        (0..shape.n_params()).map(|_| g.uniform(-1.5, 1.5)).collect()
    }

    /// A random problem of `n` patterns (seed `seeds[0]`), random parameters (seed `seeds[1]`)
    /// and, at those parameters, the residuals, the explicit Jacobian and the cost.
    #[allow(clippy::type_complexity)]
    fn explicit_jacobian(
        shape: Shape,
        act: Activation,
        n: usize,
        seeds: [u64; 2],
    ) -> (Problem, Vec<f64>, Vec<f64>, Vec<f64>, f64) {
        let prob = random_problem(shape, act, n, seeds[0]);
        let p = random_params(&shape, seeds[1]);
        let (nr, np) = (prob.n_res(), shape.n_params());
        let mut r = vec![0.0; nr];
        let mut jac = vec![0.0; nr * np];
        let cost = prob.jacobian(&p, &mut r, &mut jac);
        (prob, p, r, jac, cost)
    }

    #[test]
    fn layout_matches_shared_mlp() {
        // A 2-2-1 net built through hvs_shared from the same flat parameters gives the same
        // outputs as this module's forward pass (to f32 precision).
        let shape = Shape::new(2, 2, 1, false);
        let p = [0.3, -0.7, 0.1, 1.2, 0.4, -0.5, 0.8, -1.1, 0.25];
        let pf: Vec<f32> = p.iter().map(|v| *v as f32).collect();
        for act in [Activation::Linear, Activation::Sigmoid] {
            let m = hvs_shared::runtime::mlp::Mlp::<2, 2, 1>::from_params(
                &pf,
                act,
                [0.0; 2],
                [1.0; 2],
                [0.0],
                [1.0],
            )
            .unwrap();
            let x = [0.6, -0.2];
            let (mut h, mut y) = ([0.0; 2], [0.0; 1]);
            forward(&shape, act, &p, &x, &mut h, &mut y);
            let yf = m.infer(&[0.6, -0.2]).unwrap()[0] as f64;
            assert!((y[0] - yf).abs() < 1e-6, "{act:?}: {} vs {yf}", y[0]);
            // And by hand for the linear case.
            if act == Activation::Linear {
                let h0 = sigmoid(0.1 + 0.3 * 0.6 - 0.7 * -0.2);
                let h1 = sigmoid(-0.5 + 1.2 * 0.6 + 0.4 * -0.2);
                assert!((y[0] - (0.25 + 0.8 * h0 - 1.1 * h1)).abs() < 1e-15);
            }
        }
    }

    /// Nets of both output activations, with and without the skip term, for the structured
    /// normal equations.
    const NORMAL_EQUATION_NETS: [(Shape, Activation); 5] = [
        (Shape::new(4, 5, 3, false), Activation::Linear),
        (Shape::new(9, 3, 1, false), Activation::Sigmoid),
        (Shape::new(2, 1, 2, false), Activation::Linear),
        (Shape::new(4, 5, 3, true), Activation::Linear),
        (Shape::new(9, 2, 1, true), Activation::Sigmoid),
    ];

    /// Nets for the finite-difference checks of the Jacobian and the gradient.
    const FINITE_DIFFERENCE_NETS: [(Shape, Activation); 3] = [
        (Shape::new(4, 5, 3, false), Activation::Linear),
        (Shape::new(3, 4, 1, false), Activation::Sigmoid),
        (Shape::new(4, 3, 3, true), Activation::Linear),
    ];

    #[test]
    fn structured_normal_equations_equal_the_explicit_ones() {
        // A small set (one pass) and one summed in two halves side by side.
        for ((shape, act), n) in NORMAL_EQUATION_NETS
            .into_iter()
            .flat_map(|net| [(net, 13), (net, SPLIT_MIN_SAMPLES + 7)])
        {
            let (prob, p, r, jac, cost) = explicit_jacobian(shape, act, n, [4, 8]);
            let (nr, np) = (prob.n_res(), shape.n_params());
            let mut jtj = vec![f64::NAN; np * np];
            let mut jtr = vec![f64::NAN; np];
            let mut ws = NormalWorkspace::new(&prob);
            assert_eq!(ws.parts.len(), if n < SPLIT_MIN_SAMPLES { 1 } else { 2 });
            let mut act = prob.activations();
            assert!((cost - prob.evaluate(&p, &mut act)).abs() <= 1e-12 * cost);
            // Twice, to check that the workspace is reset between calls.
            for _ in 0..2 {
                let c2 = prob.normal_equations(&p, &act, &mut jtj, &mut jtr, &mut ws);
                assert!((cost - c2).abs() <= 1e-12 * cost);
                for a in 0..np {
                    let want: f64 = (0..nr).map(|row| jac[a * nr + row] * r[row]).sum();
                    assert!((jtr[a] - want).abs() <= 1e-12 * (1.0 + want.abs()));
                    for b in 0..np {
                        let want: f64 =
                            (0..nr).map(|row| jac[a * nr + row] * jac[b * nr + row]).sum();
                        let got = jtj[a * np + b];
                        assert!(
                            (got - want).abs() <= 1e-12 * (1.0 + want.abs()),
                            "{shape:?} JtJ[{a}][{b}] = {got}, explicit {want}"
                        );
                    }
                }
            }
        }
    }

    /// The tiled sums, 4 x 16 tiles, 4 x 8 and 4 x 4, give the bits of adding the samples one after
    /// the other, over chunks that do not fill a tile of 8.
    #[test]
    fn tiled_products_have_the_bits_of_one_sample_at_a_time() {
        let mut g = SplitMix64::new(5);
        for (rows, cols, len) in [(4, 4, 1), (8, 12, 7), (16, 56, 32), (12, 20, 3), (8, 28, 5)] {
            let (ldu, ldx) = (rows + 3, cols + 1);
            let u: Vec<f64> = (0..len * ldu).map(|_| g.uniform(-2.0, 2.0)).collect();
            let x: Vec<f64> = (0..len * ldx).map(|_| g.uniform(-2.0, 2.0)).collect();
            let start: Vec<f64> = (0..rows * cols).map(|_| g.uniform(-1.0, 1.0)).collect();
            let mut want = start.clone();
            for t in 0..len {
                for r in 0..rows {
                    axpy(
                        &mut want[r * cols..(r + 1) * cols],
                        u[t * ldu + r],
                        &x[t * ldx..t * ldx + cols],
                    );
                }
            }
            let (mut wider, mut wide, mut portable) = (start.clone(), start.clone(), start);
            add_products_in::<16>(&mut wider, (rows, cols, cols), (&u, ldu), (&x, ldx), len);
            add_products_in::<8>(&mut wide, (rows, cols, cols), (&u, ldu), (&x, ldx), len);
            add_products_in::<4>(&mut portable, (rows, cols, cols), (&u, ldu), (&x, ldx), len);
            let bits = |v: &[f64]| v.iter().map(|f| f.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&wider), bits(&want), "{rows}x{cols}, {len} samples");
            assert_eq!(bits(&wide), bits(&want), "{rows}x{cols}, {len} samples");
            assert_eq!(bits(&portable), bits(&want), "{rows}x{cols}, {len} samples");
        }
    }

    /// The normal equations' sums as this CPU runs them (AVX-512 or AVX where it has them) have the bits
    /// of the portable build, on chunks full and not (a 9-16-3 skip net, 75 samples).
    #[test]
    fn the_avx_sums_have_the_portable_bits() {
        let prob = random_problem(Shape::new(9, 16, 3, true), Activation::Linear, 75, 3);
        let mut g = SplitMix64::new(8);
        let p: Vec<f64> = (0..prob.shape.n_params()).map(|_| g.uniform(-0.5, 0.5)).collect();
        let mut act = prob.activations();
        prob.evaluate(&p, &mut act);
        let ws = NormalWorkspace::new(&prob);
        let (mut a, mut b) = (ws.parts[0].clone(), ws.parts[0].clone());
        let ca = prob.accumulate(&p, &act, &ws.xpk, 0..prob.n, &mut a);
        let cb = prob.accumulate_in::<4>((&p, &act, &ws.xpk), 0..prob.n, &mut b);
        let bits = |v: &[f64]| v.iter().map(|f| f.to_bits()).collect::<Vec<_>>();
        assert_eq!(ca.to_bits(), cb.to_bits());
        for (x, y) in [(&a.m, &b.m), (&a.cross, &b.cross), (&a.jtr, &b.jtr)] {
            assert_eq!(bits(x), bits(y));
        }
        // Each compiled build this CPU runs, not only the one dispatched to.
        #[cfg(target_arch = "x86_64")]
        for name in crate::simd::builds_here() {
            let mut c = ws.parts[0].clone();
            let at = (p.as_slice(), &act, ws.xpk.as_slice());
            // SAFETY: `builds_here` lists only what this CPU has.
            let cc = unsafe {
                if name == "avx" {
                    accumulate_avx(&prob, at, 0..prob.n, &mut c)
                } else {
                    accumulate_avx512(&prob, at, 0..prob.n, &mut c)
                }
            };
            assert_eq!(cc.to_bits(), cb.to_bits(), "{name}");
            for (x, y) in [(&c.m, &b.m), (&c.cross, &b.cross), (&c.jtr, &b.jtr)] {
                assert_eq!(bits(x), bits(y), "{name}");
            }
        }
    }

    /// The forward passes eight samples at a time (as this CPU runs them, and the portable
    /// build) have the bits of one sample at a time through `forward`, its `libm::exp`
    /// included: sigmoid and linear outputs, with and without skip weights, sets that are and
    /// are not whole blocks, large enough to run in two halves. Parameters up to +-8 reach the
    /// sigmoid's saturation.
    #[test]
    fn the_forward_lanes_have_the_bits_of_one_sample_at_a_time() {
        for (shape, output, n) in [
            (Shape::new(4, 5, 3, true), Activation::Linear, 13),
            (Shape::new(9, 16, 3, true), Activation::Linear, SPLIT_MIN_SAMPLES + 21),
            (Shape::new(4, 40, 3, false), Activation::Sigmoid, 64),
            (Shape::new(2, 1, 1, false), Activation::Sigmoid, 7),
        ] {
            let prob = random_problem(shape, output, n, 4);
            for (seed, scale) in [(1, 1.0), (2, 8.0)] {
                let mut g = SplitMix64::new(seed);
                let p: Vec<f64> =
                    (0..shape.n_params()).map(|_| scale * g.uniform(-1.0, 1.0)).collect();
                let mut act = prob.activations();
                let cost = prob.evaluate(&p, &mut act);
                let mut portable = prob.activations();
                prob.forward_range_in(&p, 0, &mut portable.h, &mut portable.y);
                let (mut h, mut y) = (vec![0.0; shape.nh], vec![0.0; shape.no]);
                let mut sse = 0.0;
                for i in 0..n {
                    forward(
                        &shape,
                        output,
                        &p,
                        &prob.x[i * shape.ni..(i + 1) * shape.ni],
                        &mut h,
                        &mut y,
                    );
                    for (a, b) in act.h[i * shape.nh..(i + 1) * shape.nh].iter().zip(&h) {
                        assert_eq!(a.to_bits(), b.to_bits(), "{shape:?} sample {i} hidden");
                    }
                    for (a, b) in act.y[i * shape.no..(i + 1) * shape.no].iter().zip(&y) {
                        assert_eq!(a.to_bits(), b.to_bits(), "{shape:?} sample {i} output");
                    }
                    for k in 0..shape.no {
                        let v = prob.c[i * shape.no + k] * (y[k] - prob.t[i * shape.no + k]);
                        sse += v * v;
                    }
                }
                assert_eq!(portable.h, act.h);
                assert_eq!(portable.y, act.y);
                // Each compiled build this CPU runs.
                #[cfg(target_arch = "x86_64")]
                for name in crate::simd::builds_here() {
                    let mut b = prob.activations();
                    // SAFETY: `builds_here` lists only what this CPU has.
                    unsafe {
                        if name == "avx" {
                            forward_range_avx(&prob, &p, 0, &mut b.h, &mut b.y);
                        } else {
                            forward_range_avx512(&prob, &p, 0, &mut b.h, &mut b.y);
                        }
                    }
                    assert_eq!((&b.h, &b.y), (&portable.h, &portable.y), "{name}");
                }
                if n < SPLIT_MIN_SAMPLES {
                    assert_eq!(cost.to_bits(), (0.5 * sse).to_bits(), "{shape:?}");
                }
            }
        }
    }

    #[test]
    fn jacobian_and_gradient_match_finite_differences() {
        for (shape, act) in FINITE_DIFFERENCE_NETS {
            let (prob, p, r, jac, cost) = explicit_jacobian(shape, act, 9, [11, 5]);
            let (nr, np) = (prob.n_res(), shape.n_params());
            assert!((cost - prob.cost(&p)).abs() < 1e-12);
            let mut grad = vec![0.0; np];
            let cost_g = prob.gradient(&p, &mut grad);
            assert!((cost - cost_g).abs() < 1e-12);
            let eps = 1e-6;
            let (mut rp, mut rm) = (vec![0.0; nr], vec![0.0; nr]);
            for q in 0..np {
                let mut pp = p.clone();
                pp[q] += eps;
                let cp = prob.residuals(&pp, &mut rp);
                pp[q] -= 2.0 * eps;
                let cm = prob.residuals(&pp, &mut rm);
                for row in 0..nr {
                    let fd = (rp[row] - rm[row]) / (2.0 * eps);
                    let an = jac[q * nr + row];
                    assert!(
                        (fd - an).abs() < 1e-7 * (1.0 + fd.abs()),
                        "{act:?} d r{row} / d p{q}: analytic {an}, numeric {fd}"
                    );
                }
                let fd = (cp - cm) / (2.0 * eps);
                assert!(
                    (fd - grad[q]).abs() < 1e-6 * (1.0 + fd.abs()),
                    "{act:?} dE/dp{q}: analytic {}, numeric {fd}",
                    grad[q]
                );
                // J^T r is the gradient too.
                let jtr: f64 = (0..nr).map(|row| jac[q * nr + row] * r[row]).sum();
                assert!((jtr - grad[q]).abs() < 1e-10 * (1.0 + jtr.abs()));
            }
        }
    }
}
