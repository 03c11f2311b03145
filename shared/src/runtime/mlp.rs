//! Fixed-size f32 MLP inference: one sigmoid hidden layer, linear or sigmoid outputs.
//!
//! The scaling is part of the model: callers pass pixels (and, for posture-aware models,
//! joint angles) and get centimetres. Inputs are normalised as `(x - in_offset) * in_scale`,
//! outputs de-normalised as `y * out_scale + out_offset`. Every sum starts from the bias and
//! adds the products in index order, in plain f32 (no fused multiply-add), with `libm::expf`,
//! so [`Mlp::infer`] and the runtime-sized [`infer_flat`] give the same bits on the host and on
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

/// The logistic sigmoid in f32, eq. 2.1-2.
#[inline(always)]
pub fn sigmoid(a: f32) -> f32 {
    1.0 / (1.0 + libm::expf(-a))
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
    for (v, (x, (off, scale))) in xn
        .iter_mut()
        .zip(x.iter().zip(m.in_offset.iter().zip(m.in_scale)))
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
    forward(m, x, &mut xn[..ni], &mut hid[..h], out, sigmoid, dot)
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

/// The 4-5-3 test nets of this module and of `activation`: case I's pixel scaling, outputs
/// around the working volume.
#[cfg(test)]
pub(crate) mod fixture {
    use super::{Activation, FlatMlp};
    use proptest::prelude::*;
    extern crate alloc;
    use alloc::vec::Vec;

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
        assert_eq!(
            m.infer(&[0.0, f32::INFINITY]),
            Err(MlpError::NonFiniteInput)
        );
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
