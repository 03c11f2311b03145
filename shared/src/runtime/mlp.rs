//! Fixed-size f32 MLP inference: one sigmoid hidden layer, linear or sigmoid outputs.
//!
//! The scaling is part of the model: callers pass pixels (and, for posture-aware models,
//! joint angles) and get centimetres. Inputs are normalised as `(x - in_offset) * in_scale`,
//! outputs de-normalised as `y * out_scale + out_offset`. Every sum starts from the bias and
//! adds the products in index order, in plain f32 (no fused multiply-add), with the
//! range-reduced polynomial [`exp`] in the sigmoid (`libm::expf` in earlier versions), so
//! [`Mlp::infer`] and the runtime-sized [`infer_flat`] give the same bits on the host and on
//! the Cortex-M4F.
//!
//! Parameter layout (also the blob's): for each hidden unit `j`, `w1[j][0..I]` then `b1[j]`;
//! then for each output `k`, `w2[k][0..H]` then `b2[k]`. A net with a linear skip term
//! ([`FlatMlp::skip`]) adds, for each output `k`, `s[k][0..I]` after all of those: output `k`'s
//! sum is `b2[k] + sum_j w2[k][j] h[j]`, then `+ sum_i s[k][i] xn[i]` over the normalised
//! inputs, in that order, before the output activation. The net then learns a residual over
//! an affine map of the pixels.

// Index loops keep the summation order explicit: it is part of the bit-exactness contract.
#![allow(clippy::needless_range_loop)]

use serde::{Deserialize, Serialize};

/// An activation function.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Activation {
    /// `f(a) = a`.
    Linear,
    /// `f(a) = 1 / (1 + e^-a)` (eq. 2.1-2).
    Sigmoid,
}

impl Activation {
    /// Applies the activation in f32 through `libm`.
    #[inline(always)]
    pub fn apply(self, a: f32) -> f32 {
        match self {
            Activation::Linear => a,
            Activation::Sigmoid => sigmoid(a),
        }
    }
}

/// The logistic sigmoid in f32, eq. 2.1-2: `1 / (1 + e^-a)` over [`exp`].
///
/// Relative error against the exact sigmoid: below 1.5e-7 wherever the exact value is a normal
/// f32 (`a >= -87.33`; 1.48e-7 worst over every f32 in `-87.33..17.5`, beyond which both
/// round to 1), as for `1 / (1 + libm::expf(-a))`, the sigmoid every model used before (1.54e-7
/// worst there): an ulp or so either way; below that the result is 0 or a subnormal, within 2^-126 of the exact
/// value. NaN in, NaN out.
#[inline(always)]
pub fn sigmoid(a: f32) -> f32 {
    // `exp(-a)`'s two halves, the rare one out of the straight path.
    if f32::from_bits(a.to_bits() & 0x7fff_ffff) < EXP_FAST_BELOW {
        1.0 / (1.0 + exp_fast(-a))
    } else {
        sigmoid_outside(a)
    }
}

/// [`sigmoid`] for `|a| >=` [`EXP_FAST_BELOW`] and NaN: `1 / (1 + exp_outside(-a))`, which is
/// 1 for `a > 0`, 0 for `a < 0` and NaN for NaN. Cold, and out of line on the head, so the
/// straight path through [`sigmoid`] has no jump around it.
#[cold]
#[cfg_attr(target_os = "none", inline(never))]
#[cfg_attr(not(target_os = "none"), inline)]
fn sigmoid_outside(a: f32) -> f32 {
    1.0 / (1.0 + exp_outside(-a))
}

/// [`sigmoid`] (the same function, the same bits), inlined on the host and one out-of-line
/// copy on the head, where flash is short: [`infer_flat`] (every net but the 4-5-3 fast path)
/// and [`FixedMlp`]'s output sigmoid call it; [`FixedMlp`]'s hidden layer inlines [`sigmoid`],
/// whose constants then stay in registers across the layer.
#[cfg_attr(target_os = "none", inline(never))]
#[cfg_attr(not(target_os = "none"), inline(always))]
pub fn sigmoid_shared(a: f32) -> f32 {
    sigmoid(a)
}

/// `|x|` from here on (and NaN): [`exp`] is [`exp_outside`]'s saturated value.
pub const EXP_FAST_BELOW: f32 = 88.0;
/// `1 / ln 2`, rounded (libm's `INV_LN2`).
const INV_LN2: f32 = f32::from_bits(0x3fb8_aa3b);
/// `ln 2` in two parts (libm's): `k * LN2_HI` is exact for `|k| <= 128`.
const LN2_HI: f32 = f32::from_bits(0x3f31_7200);
/// `ln 2 - LN2_HI`.
const LN2_LO: f32 = f32::from_bits(0x35bf_be8e);
/// `1.5 * 2^23`: `t + ROUND` rounds `t` (`|t| < 2^22`) to the nearest integer `k` and holds
/// `k` in its low mantissa bits.
const ROUND: f32 = 12_582_912.0;
/// `e^r ~ 1 + r + r^2 (E2 + r (E3 + r (E4 + r (E5 + r E6))))` on `|r| <= ln 2 / 2`: the
/// minimax fit of the relative error with the first two terms fixed (Remez, 3.1e-9 before
/// rounding to f32).
const E2: f32 = f32::from_bits(0x3eff_fffe); // 0.49999994
const E3: f32 = f32::from_bits(0x3e2a_aa49); // 0.16666521
const E4: f32 = f32::from_bits(0x3d2a_ac79); // 0.04166839
const E5: f32 = f32::from_bits(0x3c09_1cea); // 0.00836871
const E6: f32 = f32::from_bits(0x3ab5_1227); // 0.0013814614

/// `e^x` in f32 for [`sigmoid`]: [`exp_fast`] for `|x| <` [`EXP_FAST_BELOW`], [`exp_outside`]
/// otherwise (and for NaN). One compare and a branch around a straight polynomial: on the
/// Cortex-M4F about 25 instructions where `libm::expf` took about 49. Plain f32 multiplies and
/// adds (no fused multiply-add), so the host and the Cortex-M4F give the same bits; the host's
/// lane-wise kernel (`hvs_host::infer::lanes`) computes both halves with selects (tested bit
/// for bit).
///
/// Relative error at most 8.2e-8 for `-87.33 <= x < 88` (a dense sweep of f32 inputs; every f32
/// with the ignored test); 0 for `-88 < x < -87.68` (the exact value is below 2^-126 there, 6e-39 at most) and
/// `x <= -88`; infinity from 88 on (the exact value overflows from 88.73); NaN for NaN.
#[inline(always)]
pub fn exp(x: f32) -> f32 {
    // NaN fails the comparison.
    if f32::from_bits(x.to_bits() & 0x7fff_ffff) < EXP_FAST_BELOW {
        exp_fast(x)
    } else {
        exp_outside(x)
    }
}

/// [`exp`] for `|x| <` [`EXP_FAST_BELOW`] (any other input gives some value, no panic):
/// `x = k ln 2 + r` with `k` the nearest integer to `x / ln 2` (Cody-Waite reduction with
/// libm's two-part `ln 2`), a degree-6 polynomial for `e^r`, then the exact multiply by `2^k`
/// (`k` in `-127..=127`; `2^-127` is taken as 0) built from `k`'s bits.
#[inline(always)]
pub fn exp_fast(x: f32) -> f32 {
    let s = x * INV_LN2 + ROUND;
    let kf = s - ROUND;
    let r = (x - kf * LN2_HI) - kf * LN2_LO;
    let q = (((E6 * r + E5) * r + E4) * r + E3) * r + E2;
    let p = 1.0 + (r + (r * r) * q);
    // s's low mantissa bits hold k; (k + 127) << 23 is 2^k as an f32 (0 for k = -127).
    let scale = f32::from_bits(s.to_bits().wrapping_add(127) << 23);
    p * scale
}

/// [`exp`] for `|x| >=` [`EXP_FAST_BELOW`] and NaN: infinity above, 0 below, NaN for NaN.
#[inline(always)]
pub fn exp_outside(x: f32) -> f32 {
    // x * inf: infinity for x > 0, NaN for NaN.
    if x < 0.0 {
        0.0
    } else {
        x * f32::INFINITY
    }
}

/// How a net's de-normalised outputs become centimetres: the model family's output side.
///
/// Applied after the output scaling, in f32 with IEEE division (the same bits on the host and
/// on the Cortex-M4F's VDIV).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum OutputMap {
    /// The outputs are `X, Y, Z` (or `Z`) in cm: the thesis' net.
    Direct,
    /// The outputs are `X/Z, Y/Z, 1/Z` (1/cm for the last; or `1/Z` alone for a Z-only
    /// model): `X = o0 / o2`, `Y = o1 / o2`, `Z = 1 / o2`. For a pinhole rig these are close to
    /// affine in the pixels (exactly so for parallel cameras), which the sigmoid layer fits far
    /// better than `X, Y, Z` themselves. As with `X, Y, Z` outputs, only a non-finite result
    /// is refused ([`MlpError::NonFiniteOutput`]: `o2 = 0`, or an overflow); a negative `o2`
    /// (far outside the training box) gives a negative depth.
    InverseDepth,
}

impl OutputMap {
    /// Turns the de-normalised outputs `y` (length 3 or 1) into cm in place.
    #[inline]
    pub fn apply(self, y: &mut [f32]) -> Result<(), MlpError> {
        match self {
            OutputMap::Direct => Ok(()),
            OutputMap::InverseDepth => {
                let (n, w) = match y.last() {
                    Some(w) => (y.len(), *w),
                    None => return Err(MlpError::Shape),
                };
                for v in y[..n - 1].iter_mut() {
                    *v /= w;
                }
                y[n - 1] = 1.0 / w;
                if y.iter().all(|v| v.is_finite()) {
                    Ok(())
                } else {
                    Err(MlpError::NonFiniteOutput)
                }
            }
        }
    }
}

/// Why an inference was refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum MlpError {
    /// An input is NaN or infinite.
    NonFiniteInput,
    /// The result is NaN or infinite (a broken model, or an inverse-depth model's `1/Z` is 0).
    NonFiniteOutput,
    /// Slice lengths do not match the topology.
    Shape,
}

impl core::fmt::Display for MlpError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            MlpError::NonFiniteInput => "non-finite input",
            MlpError::NonFiniteOutput => "non-finite output",
            MlpError::Shape => "input or output length does not match the model",
        })
    }
}

/// Number of parameters of an `i-h-o` net.
pub const fn param_count(i: usize, h: usize, o: usize) -> usize {
    h * (i + 1) + o * (h + 1)
}

/// A fixed-size MLP `I -> H (sigmoid) -> O`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Mlp<const I: usize, const H: usize, const O: usize> {
    /// Input-to-hidden weights, `w1[j][i]`.
    pub w1: [[f32; I]; H],
    /// Hidden biases.
    pub b1: [f32; H],
    /// Hidden-to-output weights, `w2[k][j]`.
    pub w2: [[f32; H]; O],
    /// Output biases.
    pub b2: [f32; O],
    /// Output activation.
    pub output: Activation,
    /// Input offsets.
    pub in_offset: [f32; I],
    /// Input scales.
    pub in_scale: [f32; I],
    /// Output offsets.
    pub out_offset: [f32; O],
    /// Output scales.
    pub out_scale: [f32; O],
}

impl<const I: usize, const H: usize, const O: usize> Mlp<I, H, O> {
    /// Builds a model from flat parameters in the documented layout and its scaling.
    pub fn from_params(
        params: &[f32],
        output: Activation,
        in_offset: [f32; I],
        in_scale: [f32; I],
        out_offset: [f32; O],
        out_scale: [f32; O],
    ) -> Result<Self, MlpError> {
        if params.len() != param_count(I, H, O) {
            return Err(MlpError::Shape);
        }
        let mut m = Mlp {
            w1: [[0.0; I]; H],
            b1: [0.0; H],
            w2: [[0.0; H]; O],
            b2: [0.0; O],
            output,
            in_offset,
            in_scale,
            out_offset,
            out_scale,
        };
        let mut it = params.iter().copied();
        for j in 0..H {
            for w in m.w1[j].iter_mut() {
                *w = it.next().unwrap_or(0.0);
            }
            m.b1[j] = it.next().unwrap_or(0.0);
        }
        for k in 0..O {
            for w in m.w2[k].iter_mut() {
                *w = it.next().unwrap_or(0.0);
            }
            m.b2[k] = it.next().unwrap_or(0.0);
        }
        Ok(m)
    }

    /// Pixels (and joint angles) in, centimetres out. Non-finite input is rejected.
    #[inline]
    pub fn infer(&self, x: &[f32; I]) -> Result<[f32; O], MlpError> {
        let mut xn = [0.0f32; I];
        for i in 0..I {
            if !x[i].is_finite() {
                return Err(MlpError::NonFiniteInput);
            }
            xn[i] = (x[i] - self.in_offset[i]) * self.in_scale[i];
        }
        let mut h = [0.0f32; H];
        for j in 0..H {
            let mut a = self.b1[j];
            for i in 0..I {
                a += self.w1[j][i] * xn[i];
            }
            h[j] = sigmoid(a);
        }
        let mut y = [0.0f32; O];
        for k in 0..O {
            let mut a = self.b2[k];
            for j in 0..H {
                a += self.w2[k][j] * h[j];
            }
            let v = self.output.apply(a) * self.out_scale[k] + self.out_offset[k];
            if !v.is_finite() {
                return Err(MlpError::NonFiniteOutput);
            }
            y[k] = v;
        }
        Ok(y)
    }
}

/// Number of linear skip weights of an `i`-input, `o`-output net that has them.
pub const fn skip_count(i: usize, o: usize) -> usize {
    i * o
}

/// How a sum of products is laid out: [`dot`] or [`dot4`] (the same additions in the same
/// order, so the same bits).
type Dot = fn(f32, &[f32], &[f32]) -> f32;

/// `a + sum_i w[i] x[i]` over `min(w.len(), x.len())` products, in index order: every sum of
/// the net (a layer's pre-activation after its bias, the skip term after the net's sum). A
/// counted loop: the compact form, for runtime lengths.
#[inline(always)]
fn dot(mut a: f32, w: &[f32], x: &[f32]) -> f32 {
    for (w, x) in w.iter().zip(x) {
        a += *w * *x;
    }
    a
}

/// [`dot`] written four products a step (then the rest one by one): the same additions in the
/// same order, hence the same bits. With a constant length (the fixed-size path) the compiler
/// lays the products out straight, where a size-optimised build keeps [`dot`]'s counted loop
/// with its index arithmetic (5 instructions more per product on the Cortex-M4F).
#[inline(always)]
fn dot4(mut a: f32, w: &[f32], x: &[f32]) -> f32 {
    let n = w.len().min(x.len());
    let (w, x) = (&w[..n], &x[..n]);
    let mut w4 = w.chunks_exact(4);
    let mut x4 = x.chunks_exact(4);
    for (w, x) in (&mut w4).zip(&mut x4) {
        a += w[0] * x[0];
        a += w[1] * x[1];
        a += w[2] * x[2];
        a += w[3] * x[3];
    }
    dot(a, w4.remainder(), x4.remainder())
}

/// Runtime-sized view of a model, used where the topology is only known from a blob.
#[derive(Debug, Clone, Copy)]
pub struct FlatMlp<'a> {
    /// Hidden units.
    pub hidden: usize,
    /// Flat parameters of the sigmoid net (documented layout, without the skip weights).
    pub params: &'a [f32],
    /// Linear skip weights `s[k][0..I]` for each output `k` (empty: no skip term; otherwise
    /// exactly `inputs * outputs` of them).
    pub skip: &'a [f32],
    /// Output activation.
    pub output: Activation,
    /// Input offsets (length = number of inputs).
    pub in_offset: &'a [f32],
    /// Input scales.
    pub in_scale: &'a [f32],
    /// Output offsets (length = number of outputs).
    pub out_offset: &'a [f32],
    /// Output scales.
    pub out_scale: &'a [f32],
}

/// Largest hidden layer [`infer_flat`] evaluates (scratch space on the stack).
pub const FLAT_MAX_HIDDEN: usize = 32;
/// Largest input vector [`infer_flat`] evaluates.
pub const FLAT_MAX_INPUTS: usize = 16;

/// Whether `m` is an `ni`-`h`-`no` net (with or without a skip term): every length the
/// forward pass relies on.
#[inline(always)]
fn shaped(m: &FlatMlp<'_>, ni: usize, h: usize, no: usize) -> bool {
    m.hidden == h
        && m.params.len() == param_count(ni, h, no)
        && m.in_offset.len() == ni
        && m.in_scale.len() == ni
        && m.out_offset.len() == no
        && m.out_scale.len() == no
        && (m.skip.is_empty() || m.skip.len() == skip_count(ni, no))
}

/// The forward pass of [`infer_flat`] and [`infer_fixed_with`] (one body for both): `x` in,
/// `y` out, for a net [`shaped`] `x.len()`-`hid.len()`-`y.len()`; `xn` (as long as `x`) and
/// `hid` are scratch. Outputs before a non-finite one are written. Inlined, so the fixed-size
/// callers get constant lengths (straight-line sums, no bounds checks).
#[inline(always)]
fn forward(
    m: &FlatMlp<'_>,
    x: &[f32],
    xn: &mut [f32],
    hid: &mut [f32],
    y: &mut [f32],
    sigmoid: impl Fn(f32) -> f32,
    dot: Dot,
) -> Result<(), MlpError> {
    for (v, (x, (off, scale))) in
        xn.iter_mut().zip(x.iter().zip(m.in_offset.iter().zip(m.in_scale)))
    {
        if !x.is_finite() {
            return Err(MlpError::NonFiniteInput);
        }
        *v = (*x - *off) * *scale;
    }
    let (ni, h) = (xn.len(), hid.len());
    let Some((hidden_rows, output_rows)) = m.params.split_at_checked(h * (ni + 1)) else {
        return Err(MlpError::Shape);
    };
    for (row, v) in hidden_rows.chunks_exact(ni + 1).zip(hid.iter_mut()) {
        if let Some((b, w)) = row.split_last() {
            *v = sigmoid(dot(*b, w, xn));
        }
    }
    // Skip rows s[k][0..I]; none when `m.skip` is empty (a zero-input net has none either).
    let mut skip = m.skip.chunks_exact(ni.max(1));
    let outputs = y.iter_mut().zip(m.out_scale.iter().zip(m.out_offset));
    for (row, (v, (scale, off))) in output_rows.chunks_exact(h + 1).zip(outputs) {
        let Some((b, w)) = row.split_last() else {
            return Err(MlpError::Shape);
        };
        let mut a = dot(*b, w, hid);
        if let Some(s) = skip.next() {
            a = dot(a, s, xn);
        }
        let out = match m.output {
            Activation::Linear => a,
            Activation::Sigmoid => sigmoid(a),
        };
        let o = out * *scale + *off;
        if !o.is_finite() {
            return Err(MlpError::NonFiniteOutput);
        }
        *v = o;
    }
    Ok(())
}

/// The same arithmetic as [`Mlp::infer`] over runtime sizes: identical bits for the same model.
pub fn infer_flat(m: &FlatMlp<'_>, x: &[f32], out: &mut [f32]) -> Result<(), MlpError> {
    let (ni, h, no) = (m.in_offset.len(), m.hidden, m.out_offset.len());
    if x.len() != ni
        || out.len() != no
        || ni > FLAT_MAX_INPUTS
        || h > FLAT_MAX_HIDDEN
        || !shaped(m, ni, h, no)
    {
        return Err(MlpError::Shape);
    }
    let mut xn = [0.0f32; FLAT_MAX_INPUTS];
    let mut hid = [0.0f32; FLAT_MAX_HIDDEN];
    forward(m, x, &mut xn[..ni], &mut hid[..h], out, sigmoid_shared, dot)
}

/// [`infer_flat`] for a model known to be `I-H-O` at compile time: the arithmetic of
/// [`Mlp::infer`] (identical bits) read straight from the runtime-sized view, with fixed
/// lengths the compiler lays out straight. Used by the head's fast path for 4-5-3 nets.
#[inline]
pub fn infer_fixed<const I: usize, const H: usize, const O: usize>(
    m: &FlatMlp<'_>,
    x: &[f32; I],
) -> Result<[f32; O], MlpError> {
    infer_fixed_with::<I, H, O>(m, x, sigmoid)
}

/// [`infer_fixed`] with the hidden activation `sigmoid` (and, for a sigmoid output, the same
/// function there): the same checks, the same summation order, so with [`sigmoid`] it gives
/// exactly `infer_fixed`'s bits (it is `infer_fixed`). The head's candidate fast activation
/// (`crate::runtime::activation::sigmoid_micromath`) runs through it.
#[inline]
pub fn infer_fixed_with<const I: usize, const H: usize, const O: usize>(
    m: &FlatMlp<'_>,
    x: &[f32; I],
    sigmoid: impl Fn(f32) -> f32,
) -> Result<[f32; O], MlpError> {
    let mut y = [0.0f32; O];
    infer_fixed_into::<I, H, O>(m, x, &mut y, sigmoid)?;
    Ok(y)
}

/// [`infer_fixed_with`] writing into `y` (the outputs before a non-finite one are written):
/// the head's fast path, which keeps the outputs in place for the family's [`OutputMap`]
/// instead of moving an array through `Result`s.
#[inline]
pub fn infer_fixed_into<const I: usize, const H: usize, const O: usize>(
    m: &FlatMlp<'_>,
    x: &[f32; I],
    y: &mut [f32; O],
    sigmoid: impl Fn(f32) -> f32,
) -> Result<(), MlpError> {
    if !shaped(m, I, H, O) {
        return Err(MlpError::Shape);
    }
    let (mut xn, mut hid) = ([0.0f32; I], [0.0f32; H]);
    forward(m, x, &mut xn, &mut hid, y, sigmoid, dot4)
}

/// Calls `f(0)`, ..., `f(N - 1)` in order, written out for `N <= 4` (`N` is a constant, so
/// the compiler drops the calls past it), a loop beyond: straight-line code at opt-level s,
/// which keeps counted loops.
#[inline(always)]
fn unrolled<const N: usize>(mut f: impl FnMut(usize)) {
    if N > 4 {
        for i in 0..N {
            f(i);
        }
        return;
    }
    if N > 0 {
        f(0);
    }
    if N > 1 {
        f(1);
    }
    if N > 2 {
        f(2);
    }
    if N > 3 {
        f(3);
    }
}

/// Most parameters (sigmoid net and skip weights) a [`FixedMlp`] holds: a 4-5-3 net with a
/// skip term has 55.
pub const FIXED_MAX_PARAMS: usize = 64;

/// A net known to be `I-H-O` at compile time, its parameters copied once out of a
/// [`FlatMlp`] (in the blob's layout): the head's fast path for 4-5-3 nets
/// (`crate::runtime::head::Network` builds it when a slot boots). [`FixedMlp::infer_into`]
/// does [`infer_flat`]'s arithmetic in its order (identical bits, tested) with every length
/// and offset a constant: no shape checks and no slicing at inference.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FixedMlp<const I: usize, const H: usize, const O: usize> {
    /// The sigmoid net's parameters, then the skip weights (if any), as in the blob.
    p: [f32; FIXED_MAX_PARAMS],
    /// Whether the net has a skip term.
    has_skip: bool,
    /// Output activation.
    output: Activation,
    /// Input offsets.
    in_offset: [f32; I],
    /// Input scales.
    in_scale: [f32; I],
    /// Output offsets.
    out_offset: [f32; O],
    /// Output scales.
    out_scale: [f32; O],
}

impl<const I: usize, const H: usize, const O: usize> FixedMlp<I, H, O> {
    /// Where the output rows start in `p`.
    const OUT_ROWS: usize = H * (I + 1);
    /// Where the skip rows start in `p`.
    const SKIP_ROWS: usize = param_count(I, H, O);
    /// Refuses, at compile time, a topology whose parameters do not fit.
    const FITS: () = assert!(param_count(I, H, O) + skip_count(I, O) <= FIXED_MAX_PARAMS);

    /// A net of zeros (outputs `out_offset` = 0), to [`FixedMlp::load`] into.
    pub const ZERO: Self = FixedMlp {
        p: [0.0; FIXED_MAX_PARAMS],
        has_skip: false,
        output: Activation::Linear,
        in_offset: [0.0; I],
        in_scale: [0.0; I],
        out_offset: [0.0; O],
        out_scale: [0.0; O],
    };

    /// The fixed-size copy of `m`, or [`MlpError::Shape`] if `m` is not an `I-H-O` net
    /// (with or without a skip term).
    pub fn from_flat(m: &FlatMlp<'_>) -> Result<Self, MlpError> {
        let mut f = Self::ZERO;
        f.load(m)?;
        Ok(f)
    }

    /// Copies `m` into `self` in place (what [`FixedMlp::from_flat`] returns), or
    /// [`MlpError::Shape`], leaving `self` as it was, if `m` is not an `I-H-O` net.
    pub fn load(&mut self, m: &FlatMlp<'_>) -> Result<(), MlpError> {
        let () = Self::FITS;
        if !shaped(m, I, H, O) {
            return Err(MlpError::Shape);
        }
        // Plain copies, no panics: the lengths were checked just above.
        let copy = |to: &mut [f32], from: &[f32]| {
            for (t, v) in to.iter_mut().zip(from) {
                *t = *v;
            }
        };
        let (net, skip) = self.p.split_at_mut(Self::SKIP_ROWS);
        copy(net, m.params);
        copy(skip, m.skip);
        self.has_skip = !m.skip.is_empty();
        self.output = m.output;
        copy(&mut self.in_offset, m.in_offset);
        copy(&mut self.in_scale, m.in_scale);
        copy(&mut self.out_offset, m.out_offset);
        copy(&mut self.out_scale, m.out_scale);
        Ok(())
    }

    /// [`infer_flat`] of the net it was built from, into `y` (the outputs before a non-finite
    /// one are written): the same checks, sums and order, hence the same bits.
    #[inline]
    pub fn infer_into(&self, x: &[f32; I], y: &mut [f32; O]) -> Result<(), MlpError> {
        let () = Self::FITS;
        let mut xn = [0.0f32; I];
        let mut finite = true;
        unrolled::<I>(|i| {
            finite &= x[i].is_finite();
            xn[i] = (x[i] - self.in_offset[i]) * self.in_scale[i];
        });
        if !finite {
            return Err(MlpError::NonFiniteInput);
        }
        let p = &self.p;
        let h: [f32; H] = core::array::from_fn(|j| {
            let row = j * (I + 1);
            sigmoid(dot4(p[row + I], &p[row..row + I], &xn))
        });
        for k in 0..O {
            let row = Self::OUT_ROWS + k * (H + 1);
            let mut a = dot4(p[row + H], &p[row..row + H], &h);
            if self.has_skip {
                let s = Self::SKIP_ROWS + k * I;
                a = dot4(a, &p[s..s + I], &xn);
            }
            let out = match self.output {
                Activation::Linear => a,
                Activation::Sigmoid => sigmoid_shared(a),
            };
            let o = out * self.out_scale[k] + self.out_offset[k];
            if !o.is_finite() {
                return Err(MlpError::NonFiniteOutput);
            }
            y[k] = o;
        }
        Ok(())
    }
}

/// The 4-5-3 test nets of this module and of `activation`: case I's pixel scaling, outputs
/// around the working volume.
#[cfg(test)]
pub(crate) mod fixture {
    use super::{Activation, FlatMlp};
    use proptest::prelude::*;
    extern crate alloc;
    use alloc::vec::Vec;

    /// Every `step`th f32 bit pattern (both signs, every exponent), then the 8193 patterns
    /// around each value of `around`: the sweeps of the f32 kernels' tests.
    pub(crate) fn f32_sweep(step: usize, around: &[f32]) -> impl Iterator<Item = u32> + '_ {
        (0..=u32::MAX).step_by(step).chain(around.iter().flat_map(|v| {
            let b = v.to_bits();
            b - 4096..=b + 4096
        }))
    }

    /// Input offsets (pixels).
    pub(crate) const IN_OFFSET: [f32; 4] = [320.0, 240.0, 320.0, 240.0];
    /// Input scales.
    pub(crate) const IN_SCALE: [f32; 4] = [1.0 / 320.0, 1.0 / 240.0, 1.0 / 320.0, 1.0 / 240.0];
    /// Output offsets (cm).
    pub(crate) const OUT_OFFSET: [f32; 3] = [0.0, 0.0, 115.0];
    /// Output scales (cm).
    pub(crate) const OUT_SCALE: [f32; 3] = [10.0, 5.0, 50.0];

    /// Parameters of a 4-5-3 net (weights and biases in -3..3).
    pub(crate) fn params() -> impl Strategy<Value = Vec<f32>> {
        proptest::collection::vec(-3.0f32..3.0, super::param_count(4, 5, 3))
    }

    /// Four pixels of a 640 x 480 pair.
    pub(crate) fn pixels() -> impl Strategy<Value = [f32; 4]> {
        proptest::array::uniform4(0.0f32..640.0)
    }

    /// A 4-5-3 net's parameters, four pixels and either output activation.
    pub(crate) fn case() -> impl Strategy<Value = (Vec<f32>, [f32; 4], Activation)> {
        let act = prop_oneof![Just(Activation::Linear), Just(Activation::Sigmoid)];
        (params(), pixels(), act)
    }

    /// A 4-5-3 view of `params` with that scaling and no skip term.
    pub(crate) fn net(params: &[f32], output: Activation) -> FlatMlp<'_> {
        FlatMlp {
            hidden: 5,
            params,
            skip: &[],
            output,
            in_offset: &IN_OFFSET,
            in_scale: &IN_SCALE,
            out_offset: &OUT_OFFSET,
            out_scale: &OUT_SCALE,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use fixture::{IN_OFFSET as io, IN_SCALE as is, OUT_OFFSET as oo, OUT_SCALE as os};
    use proptest::prelude::*;

    fn tiny() -> Mlp<2, 1, 1> {
        // h = sigmoid(0 + 1*x0 - 1*x1); y = 2*h + 1, scaled by 10, offset 5.
        Mlp::from_params(
            &[1.0, -1.0, 0.0, 2.0, 1.0],
            Activation::Linear,
            [0.0, 0.0],
            [1.0, 1.0],
            [5.0],
            [10.0],
        )
        .unwrap()
    }

    #[test]
    fn hand_worked_forward_pass() {
        let m = tiny();
        // x0 = x1 -> h = 0.5 -> y = 2, out = 25.
        assert_eq!(m.infer(&[3.0, 3.0]).unwrap(), [25.0]);
        let y = m.infer(&[1.0, 0.0]).unwrap()[0];
        let h = 1.0 / (1.0 + (-1.0f64).exp());
        assert!((y as f64 - (5.0 + 10.0 * (2.0 * h + 1.0))).abs() < 1e-5);
    }

    #[test]
    fn sigmoid_output_and_scaling() {
        let m: Mlp<1, 1, 1> = Mlp::from_params(
            &[0.0, 0.0, 0.0, 0.0],
            Activation::Sigmoid,
            [100.0],
            [0.5],
            [1.0],
            [4.0],
        )
        .unwrap();
        // a2 = 0 -> sigmoid 0.5 -> 0.5 * 4 + 1 = 3.
        assert_eq!(m.infer(&[7.0]).unwrap(), [3.0]);
    }

    #[test]
    fn rejects_non_finite_and_bad_shapes() {
        let m = tiny();
        assert_eq!(m.infer(&[f32::NAN, 0.0]), Err(MlpError::NonFiniteInput));
        assert_eq!(m.infer(&[0.0, f32::INFINITY]), Err(MlpError::NonFiniteInput));
        assert!(Mlp::<2, 1, 1>::from_params(
            &[0.0; 4],
            Activation::Linear,
            [0.0; 2],
            [1.0; 2],
            [0.0],
            [1.0]
        )
        .is_err());
        let huge: Mlp<1, 1, 1> = Mlp::from_params(
            &[0.0, 0.0, f32::MAX, f32::MAX],
            Activation::Linear,
            [0.0],
            [1.0],
            [0.0],
            [f32::MAX],
        )
        .unwrap();
        assert_eq!(huge.infer(&[0.0]), Err(MlpError::NonFiniteOutput));
    }

    /// The exact sigmoid (f64, `libm::exp`), as f64.
    fn exact_sigmoid(a: f32) -> f64 {
        1.0 / (1.0 + libm::exp(-(a as f64)))
    }

    /// Worst relative errors over the bit patterns `bits`: [`exp`] against the exact `e^x` where
    /// that is a normal f32 and below the saturation (`-87.33 <= x < 88`), [`sigmoid`]
    /// and libm's sigmoid against the exact one where it is normal (`a >= -87.33`).
    /// Returns `(exp, sigmoid, libm sigmoid, patterns)`.
    fn worst_errors(bits: impl Iterator<Item = u32>) -> (f64, f64, f64, u64) {
        let (mut we, mut ws, mut wl, mut n) = (0.0f64, 0.0f64, 0.0f64, 0u64);
        for b in bits {
            let v = f32::from_bits(b);
            if !v.is_finite() {
                continue;
            }
            n += 1;
            if (-87.33..EXP_FAST_BELOW).contains(&v) {
                let want = libm::exp(v as f64);
                we = we.max(((exp(v) as f64 - want) / want).abs());
            }
            if v >= -87.33 {
                let want = exact_sigmoid(v);
                ws = ws.max(((sigmoid(v) as f64 - want) / want).abs());
                let libm_sigmoid = 1.0 / (1.0 + libm::expf(-v));
                wl = wl.max(((libm_sigmoid as f64 - want) / want).abs());
            }
        }
        (we, ws, wl, n)
    }

    /// Every 1021st f32 bit pattern (both signs, every exponent) and 8193 patterns around each
    /// end of the ranges.
    #[test]
    fn exp_and_sigmoid_are_within_their_stated_errors_on_a_dense_sweep() {
        let around = [-87.33, -87.68, EXP_FAST_BELOW, -17.33, 17.33, 1e-30];
        let bits = fixture::f32_sweep(1021, &around);
        let (we, ws, wl, n) = worst_errors(bits);
        assert!(n > 4_000_000, "{n}");
        assert!(we <= 8.2e-8, "exp: worst relative error {we:e}");
        assert!(ws < 1.5e-7, "sigmoid: worst relative error {ws:e}");
        // The sigmoid it replaced is within an ulp too, no better.
        assert!((1e-7..1.6e-7).contains(&wl), "libm's sigmoid: {wl:e}");
    }

    /// Every f32 (a minute or two in release on two cores; the figures of the docs):
    /// `cargo test --release -p hvs-shared --lib runtime::mlp -- --ignored --nocapture`
    #[test]
    #[ignore]
    fn exp_and_sigmoid_are_within_their_stated_errors_on_every_f32() {
        extern crate std;
        let parts: std::vec::Vec<_> = (0..4u32)
            .map(|t| std::thread::spawn(move || worst_errors(t << 30..=(t << 30) | 0x3fff_ffff)))
            .collect();
        let (mut we, mut ws, mut wl, mut n) = (0.0f64, 0.0f64, 0.0f64, 0u64);
        for p in parts {
            let (e, s, l, c) = p.join().unwrap();
            (we, ws, wl, n) = (we.max(e), ws.max(s), wl.max(l), n + c);
        }
        std::println!("exp {we:e}, sigmoid {ws:e}, libm sigmoid {wl:e}, {n} finite f32");
        assert_eq!(n, (1u64 << 32) - 2 * (1 << 23));
        assert!(we <= 8.2e-8 && ws < 1.5e-7 && ws <= wl, "{we:e} {ws:e} {wl:e}");
    }

    /// The sigmoid's two halves are `1 / (1 + exp(-a))` bit for bit, at the split and on
    /// every 1021st pattern (infinities and NaNs included).
    #[test]
    fn sigmoid_is_one_over_one_plus_exp_bit_for_bit() {
        let bits = fixture::f32_sweep(1021, &[EXP_FAST_BELOW, -EXP_FAST_BELOW]).chain([
            0x7f80_0000,
            0xff80_0000,
            0x7fc0_0000,
            0xffc0_0000,
        ]);
        for b in bits {
            let a = f32::from_bits(b);
            let (got, want) = (sigmoid(a), 1.0 / (1.0 + exp(-a)));
            assert!(
                got.to_bits() == want.to_bits() || (got.is_nan() && want.is_nan()),
                "sigmoid({a:e}) = {got:e}, 1 / (1 + exp(-a)) = {want:e}"
            );
            assert_eq!(sigmoid_shared(a).to_bits(), got.to_bits());
        }
    }

    #[test]
    fn exp_and_sigmoid_ends_and_non_finite_inputs() {
        assert_eq!(exp(0.0), 1.0);
        assert_eq!(exp(-0.0), 1.0);
        assert_eq!(exp(f32::NEG_INFINITY), 0.0);
        assert_eq!(exp(-87.7), 0.0);
        assert_eq!(exp(-1e30), 0.0);
        assert_eq!(exp(88.0), f32::INFINITY);
        assert_eq!(exp(-88.0), 0.0);
        assert_eq!(exp(f32::INFINITY), f32::INFINITY);
        assert_eq!(exp(f32::MAX), f32::INFINITY);
        assert!(exp(87.99).is_finite() && exp(87.99) > 1e38);
        assert!(exp(f32::NAN).is_nan());
        assert_eq!(sigmoid(0.0), 0.5);
        assert_eq!(sigmoid(17.4), 1.0);
        assert_eq!(sigmoid(f32::INFINITY), 1.0);
        assert_eq!(sigmoid(f32::NEG_INFINITY), 0.0);
        assert_eq!(sigmoid(-88.0), 0.0);
        assert!(sigmoid(f32::NAN).is_nan());
        // Below the normal range the result is 0 or subnormal, within 2^-126 of the exact one.
        let mut a = -87.33f32;
        while a > -120.0 {
            let (got, want) = (sigmoid(a) as f64, exact_sigmoid(a));
            assert!((got - want).abs() <= f32::MIN_POSITIVE as f64, "{a}: {got:e} vs {want:e}");
            a -= 0.01;
        }
    }

    proptest! {
        #[test]
        fn dot4_is_dot_bit_for_bit(
            w in proptest::collection::vec(-3.0f32..3.0, 0..20),
            x in proptest::collection::vec(-640.0f32..640.0, 0..20),
            a in -10.0f32..10.0,
        ) {
            // Any lengths, equal or not (both stop at the shorter): chunks and remainders.
            prop_assert_eq!(dot4(a, &w, &x).to_bits(), dot(a, &w, &x).to_bits());
            let n = w.len().min(x.len());
            let mut by_hand = a;
            for i in 0..n {
                by_hand += w[i] * x[i];
            }
            prop_assert_eq!(dot(a, &w, &x).to_bits(), by_hand.to_bits());
        }

        #[test]
        fn flat_and_const_give_identical_bits((params, x, act) in fixture::case()) {
            let m: Mlp<4, 5, 3> = Mlp::from_params(&params, act, io, is, oo, os).unwrap();
            let a = m.infer(&x).unwrap();
            let flat = fixture::net(&params, act);
            let mut b = [0.0f32; 3];
            infer_flat(&flat, &x, &mut b).unwrap();
            prop_assert_eq!(a.map(f32::to_bits), b.map(f32::to_bits));
            let c = infer_fixed::<4, 5, 3>(&flat, &x).unwrap();
            prop_assert_eq!(a.map(f32::to_bits), c.map(f32::to_bits));
            prop_assert_eq!(infer_fixed::<4, 6, 3>(&flat, &x), Err(MlpError::Shape));
        }

        #[test]
        fn fixed_mlp_gives_the_bits_and_errors_of_infer_flat(
            params in fixture::params(),
            skip in proptest::collection::vec(-2.0f32..2.0, skip_count(4, 3)),
            x in fixture::pixels(),
            sigmoid_out in any::<bool>(),
            with_skip in any::<bool>(),
            bad in 0usize..6,
        ) {
            let act = if sigmoid_out { Activation::Sigmoid } else { Activation::Linear };
            let plain = fixture::net(&params, act);
            let m = if with_skip { FlatMlp { skip: &skip, ..plain } } else { plain };
            let f = FixedMlp::<4, 5, 3>::from_flat(&m).unwrap();
            // Now and then a non-finite input (bad < 4) or a huge one that overflows an output.
            let mut x = x;
            if bad < 4 {
                x[bad] = [f32::NAN, f32::INFINITY, f32::NEG_INFINITY][bad % 3];
            } else if bad == 4 {
                x[0] = f32::MAX;
            }
            let (mut want, mut got) = ([f32::MIN; 3], [f32::MIN; 3]);
            let e_want = infer_flat(&m, &x, &mut want);
            let e_got = f.infer_into(&x, &mut got);
            prop_assert_eq!(e_got, e_want);
            prop_assert_eq!(got.map(f32::to_bits), want.map(f32::to_bits));
            prop_assert_eq!(FixedMlp::<4, 6, 3>::from_flat(&m), Err(MlpError::Shape));
            let short = FlatMlp { skip: &skip[..11], ..plain };
            prop_assert_eq!(FixedMlp::<4, 5, 3>::from_flat(&short), Err(MlpError::Shape));
        }

        #[test]
        fn skip_term_is_added_in_order_and_flat_and_fixed_agree(
            params in fixture::params(),
            skip in proptest::collection::vec(-2.0f32..2.0, skip_count(4, 3)),
            x in fixture::pixels(),
        ) {
            let plain = fixture::net(&params, Activation::Linear);
            let with = FlatMlp { skip: &skip, ..plain };
            let mut b = [0.0f32; 3];
            infer_flat(&with, &x, &mut b).unwrap();
            let c = infer_fixed::<4, 5, 3>(&with, &x).unwrap();
            prop_assert_eq!(b.map(f32::to_bits), c.map(f32::to_bits));
            // By hand: the net's pre-activation sum, then the skip products in input order.
            let xn: [f32; 4] = core::array::from_fn(|i| (x[i] - io[i]) * is[i]);
            let hid: [f32; 5] = core::array::from_fn(|j| {
                let mut a = params[j * 5 + 4];
                for i in 0..4 { a += params[j * 5 + i] * xn[i]; }
                sigmoid(a)
            });
            for k in 0..3 {
                let row = 25 + k * 6;
                let mut a = params[row + 5];
                for j in 0..5 { a += params[row + j] * hid[j]; }
                for i in 0..4 { a += skip[k * 4 + i] * xn[i]; }
                prop_assert_eq!((a * os[k] + oo[k]).to_bits(), b[k].to_bits());
            }
            // A skip of the wrong length is a shape error.
            let short = FlatMlp { skip: &skip[..11], ..plain };
            prop_assert_eq!(infer_flat(&short, &x, &mut b), Err(MlpError::Shape));
            prop_assert_eq!(infer_fixed::<4, 5, 3>(&short, &x), Err(MlpError::Shape));
        }
    }
}
