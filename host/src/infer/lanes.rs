//! Lane-wise (several points at once) form of `hvs_shared::runtime::mlp::Mlp::infer`, bit-identical
//! to it, written so that LLVM auto-vectorises it: no `unsafe`, no target features, plain
//! f32 arithmetic (Rust never contracts to FMA) in exactly the order of the scalar code.
//!
//! The time of the scalar path is spent in `libm::expf` (the sigmoid). [`expf_lanes`] is
//! libm 0.2.16's `expf` (FreeBSD `e_expf.c`) with its branches turned into selects over the
//! lanes: for `|x| < 0x1.5d58a0p+6` (~87.34, bit pattern below `0x42aeac50`) every branch
//! of the original computes the same expression with `k = 0`, `k = +-1` or
//! `k = (INV_LN2 * x + HALF[sign]) as i32`, and `scalbnf(y, k)` with `k` in `-126..=126` is
//! the single multiply `y * 2^k`; the tiny branch (`|x| <= 2^-14`) is `1 + x`. Lanes
//! outside that range (large `|x|`, infinities, NaN) are recomputed with scalar
//! `libm::expf`.
//!
//! A block of [`LANES`] points whose inputs or outputs are not all finite is rerun point by
//! point through `Mlp::infer`, so errors (and the outputs written before them) are those of
//! the scalar path.

// Index loops keep the summation order explicit: it is part of the bit-exactness contract.
#![allow(clippy::needless_range_loop)]

use hvs_shared::runtime::mlp::{Activation, Mlp, MlpError};

/// Points evaluated together.
pub(crate) const LANES: usize = 16;

type V = [f32; LANES];

// libm's constants, by bit pattern (its decimal literals round to exactly these).
const LN2_HI: f32 = f32::from_bits(0x3f31_7200); // 6.9314575195e-01
const LN2_LO: f32 = f32::from_bits(0x35bf_be8e); // 1.4286067653e-06
const INV_LN2: f32 = f32::from_bits(0x3fb8_aa3b); // 1.4426950216e+00
const P1: f32 = f32::from_bits(0x3e2a_aa8f); // 1.6666625440e-1 = 0xaaaa8f.0p-26
const P2: f32 = f32::from_bits(0xbb35_5215); // -2.7667332906e-3 = -0xb55215.0p-32

/// `|x|` bit patterns at or above this take the scalar `libm::expf` (|x| >= ~87.34, inf,
/// NaN): libm's own special-case threshold, below which `k` stays in `-126..=126`.
const SLOW_FROM: u32 = 0x42ae_ac50;
/// Above: |x| > 1.5 ln 2, `k` from rounding `x / ln 2`.
const K_ROUND_ABOVE: u32 = 0x3f85_1592;
/// Above: |x| > 0.5 ln 2, `k = +-1`.
const K_ONE_ABOVE: u32 = 0x3eb1_7218;
/// At or below: |x| <= 2^-14, `expf(x) = 1 + x`.
const TINY_UP_TO: u32 = 0x3900_0000;

/// `1.5 * 2^23`: `(t + ROUND) - ROUND` is `t` rounded to the nearest integer for
/// `|t| < 2^22`, and the low bits of `t + ROUND` are that integer.
const ROUND: f32 = 12_582_912.0;
/// `ROUND.to_bits()`.
const ROUND_BITS: u32 = 0x4b40_0000;

/// One lane of the fast path, exact for `|x|` bit patterns below [`SLOW_FROM`] (any
/// value, no panic, for other inputs). LLVM scalarises the saturating `as i32` on baseline
/// x86_64, so `k` is computed in floating point: `trunc(t)` as `t` rounded to the nearest
/// integer, stepped one toward zero where that rounded away from zero (`t` has the sign of
/// `x` wherever `k_round` is used: there `|t| > 2`), and `2^k` from the bits of `k + ROUND`.
/// Both are exact for the `|t| < 128` of the fast range.
#[inline(always)]
fn expf_fast(x: f32) -> f32 {
    let bits = x.to_bits();
    let hx = bits & 0x7fff_ffff;
    let neg = bits >> 31 != 0;
    // libm: k = (INV_LN2 * x + HALF[sign]) as i32, i.e. trunc(t).
    let t = INV_LN2 * x + if neg { -0.5f32 } else { 0.5f32 };
    let rn = (t + ROUND) - ROUND;
    let k_round = if neg {
        if rn < t {
            rn + 1.0
        } else {
            rn
        }
    } else if rn > t {
        rn - 1.0
    } else {
        rn
    };
    // libm: k = 1 - sign - sign.
    let k_one = if neg { -1.0f32 } else { 1.0f32 };
    // `kf` is libm's `k as f32`.
    let kf = if hx > K_ROUND_ABOVE {
        k_round
    } else if hx > K_ONE_ABOVE {
        k_one
    } else {
        0.0
    };
    // With k = 0 these are libm's `hi = x, lo = 0` exactly (x - 0 = x, also for -0).
    let hi = x - kf * LN2_HI;
    let lo = kf * LN2_LO;
    let r = hi - lo;
    let xx = r * r;
    let c = r - xx * (P1 + xx * P2);
    let y = 1. + (r * c / (2. - c) - lo + hi);
    // scalbnf(y, k) for -126 <= k <= 127 is the one multiply y * 2^k (y * 1 = y for k = 0).
    // Wrapping: lanes outside the fast range may have any k; their result is replaced.
    let k = (kf + ROUND).to_bits().wrapping_sub(ROUND_BITS);
    let scale = f32::from_bits(k.wrapping_add(0x7f) << 23);
    let normal = y * scale;
    if hx > TINY_UP_TO {
        normal
    } else {
        1. + x
    }
}

/// `libm::expf` on every lane, bit for bit.
#[inline(always)]
pub(crate) fn expf_lanes(x: &V) -> V {
    let mut out = [0.0f32; LANES];
    let mut slow = false;
    for l in 0..LANES {
        out[l] = expf_fast(x[l]);
        slow |= x[l].to_bits() & 0x7fff_ffff >= SLOW_FROM;
    }
    if slow {
        for l in 0..LANES {
            if x[l].to_bits() & 0x7fff_ffff >= SLOW_FROM {
                out[l] = libm::expf(x[l]);
            }
        }
    }
    out
}

/// `hvs_shared::runtime::mlp::sigmoid` on every lane: `1 / (1 + expf(-a))`.
#[inline(always)]
pub(crate) fn sigmoid_lanes(a: &V) -> V {
    let mut na = [0.0f32; LANES];
    for l in 0..LANES {
        na[l] = -a[l];
    }
    let e = expf_lanes(&na);
    let mut out = [0.0f32; LANES];
    for l in 0..LANES {
        out[l] = 1.0 / (1.0 + e[l]);
    }
    out
}

/// `bias + sum_i w[i] x[i]` on every lane, the terms added in input order (as
/// `Mlp::infer` adds them).
#[inline(always)]
fn neuron_lanes<const N: usize>(bias: f32, w: &[f32; N], x: &[V; N]) -> V {
    let mut a = [bias; LANES];
    for i in 0..N {
        for l in 0..LANES {
            a[l] += w[i] * x[i][l];
        }
    }
    a
}

/// [`LANES`] points (`x`: `LANES * I` values, `out`: `LANES * O`) through `m`. Returns
/// `false`, writing nothing, if an input or an output is not finite: the caller reruns the
/// block through `Mlp::infer`.
#[inline(always)]
fn block<const I: usize, const H: usize, const O: usize>(
    m: &Mlp<I, H, O>,
    x: &[f32],
    out: &mut [f32],
) -> bool {
    let x = &x[..LANES * I];
    let out = &mut out[..LANES * O];
    let mut finite = true;
    for v in x {
        finite &= v.is_finite();
    }
    if !finite {
        return false;
    }
    let mut xn = [[0.0f32; LANES]; I];
    for i in 0..I {
        for l in 0..LANES {
            xn[i][l] = (x[l * I + i] - m.in_offset[i]) * m.in_scale[i];
        }
    }
    let mut h = [[0.0f32; LANES]; H];
    for j in 0..H {
        h[j] = sigmoid_lanes(&neuron_lanes(m.b1[j], &m.w1[j], &xn));
    }
    let mut y = [[0.0f32; LANES]; O];
    for k in 0..O {
        let a = neuron_lanes(m.b2[k], &m.w2[k], &h);
        let f = match m.output {
            Activation::Linear => a,
            Activation::Sigmoid => sigmoid_lanes(&a),
        };
        for l in 0..LANES {
            let v = f[l] * m.out_scale[k] + m.out_offset[k];
            finite &= v.is_finite();
            y[k][l] = v;
        }
    }
    if !finite {
        return false;
    }
    for l in 0..LANES {
        for k in 0..O {
            out[l * O + k] = y[k][l];
        }
    }
    true
}

/// Rows of `x` (`I` values each) through `m` into `out` (`O` each), bit-identical to
/// calling `m.infer` row by row; stops at the first failing row, as that loop does.
pub(crate) fn run<const I: usize, const H: usize, const O: usize>(
    m: &Mlp<I, H, O>,
    x: &[f32],
    out: &mut [f32],
) -> Result<(), (usize, MlpError)> {
    let rows = (x.len() / I).min(out.len() / O);
    let mut r = 0;
    while r < rows {
        let n = (rows - r).min(LANES);
        let (xb, ob) = (&x[r * I..(r + n) * I], &mut out[r * O..(r + n) * O]);
        if n < LANES || !block(m, xb, ob) {
            for (q, (xi, oi)) in xb.chunks_exact(I).zip(ob.chunks_exact_mut(O)).enumerate() {
                let xa: &[f32; I] = xi.try_into().map_err(|_| (r + q, MlpError::Shape))?;
                let yv = m.infer(xa).map_err(|e| (r + q, e))?;
                oi.copy_from_slice(&yv);
            }
        }
        r += n;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::infer::tests::blob;
    use crate::infer::{PointError, Predictor};
    use hvs_shared::runtime::blob::{InputKind, ModelBlob, OutputKind};
    use hvs_shared::runtime::mlp::param_count;
    use rand::{RngExt, SeedableRng};

    /// Compares [`expf_lanes`] with `libm::expf` on `bits`, [`LANES`] consecutive patterns
    /// per call (so fast and scalar lanes mix at the thresholds).
    fn check_expf(bits: impl Iterator<Item = u32>) -> usize {
        let mut n = 0;
        let mut buf = [0.0f32; LANES];
        let mut fill = 0;
        let flush = |buf: &[f32; LANES], fill: usize| {
            let got = expf_lanes(buf);
            for l in 0..fill {
                let want = libm::expf(buf[l]);
                assert_eq!(
                    got[l].to_bits(),
                    want.to_bits(),
                    "expf({:e} = {:#010x}): lanes {:e}, libm {:e}",
                    buf[l],
                    buf[l].to_bits(),
                    got[l],
                    want
                );
            }
        };
        for b in bits {
            buf[fill] = f32::from_bits(b);
            fill += 1;
            n += 1;
            if fill == LANES {
                flush(&buf, fill);
                fill = 0;
            }
        }
        if fill > 0 {
            flush(&buf, fill);
        }
        n
    }

    /// Every 2039th bit pattern (both signs, all exponents), plus +-8192 patterns around
    /// every threshold of libm's `expf` and +-128 around every point where its `k` changes.
    #[test]
    fn expf_lanes_matches_libm_on_a_dense_sweep() {
        let stride = (0..=u32::MAX).step_by(2039);
        let thresholds = [
            0,
            TINY_UP_TO,
            K_ONE_ABOVE,
            K_ROUND_ABOVE,
            SLOW_FROM,
            0x42b1_7218, // overflow
            0x42cf_f1b5, // underflow to 0
            0x7f80_0000, // inf
            0x7fff_ffff,
        ];
        let near = thresholds.into_iter().flat_map(|t| {
            [0u32, 0x8000_0000].into_iter().flat_map(move |s| {
                (t.saturating_sub(8192)..=t.saturating_add(8192).min(0x7fff_ffff))
                    .map(move |b| b | s)
            })
        });
        // k = trunc(x / ln2 +- 1/2) steps at x = +-(n + 1/2) ln 2.
        let k_steps = (0..=130).flat_map(|n| {
            let t = ((n as f32 + 0.5) * core::f32::consts::LN_2).to_bits();
            [0u32, 0x8000_0000]
                .into_iter()
                .flat_map(move |s| (t - 128..=t + 128).map(move |b| b | s))
        });
        let n = check_expf(stride.chain(near).chain(k_steps));
        assert!(n > 2_400_000, "{n}");
    }

    /// All 2^32 patterns (about 30 s in release on two cores):
    /// `cargo test --release -p hvs-host --lib infer::lanes -- --ignored`
    #[test]
    #[ignore]
    fn expf_lanes_matches_libm_exhaustively() {
        use rayon::prelude::*;
        let n: usize = (0..=u16::MAX as u32)
            .into_par_iter()
            .map(|hi| check_expf((0..=u16::MAX as u32).map(move |lo| hi << 16 | lo)))
            .sum();
        assert_eq!(n, 1 << 32);
    }

    /// A value drawn to reach every branch: ordinary, tiny, huge, infinite, NaN.
    fn wild(rng: &mut rand::rngs::ChaCha8Rng, ordinary: f32) -> f32 {
        match rng.random_range(0..40) {
            0 => f32::NAN,
            1 => f32::INFINITY,
            2 => f32::NEG_INFINITY,
            3 => f32::MAX,
            4 => -1e30,
            5 => 0.0,
            6 => -0.0,
            7 => f32::from_bits(rng.random_range(1..0x0080_0000)), // subnormal
            8 => rng.random_range(-1e-5f32..1e-5),
            9 => rng.random_range(-200.0f32..200.0),
            _ => ordinary,
        }
    }

    /// A random `ni-h-no` model: weights of random magnitudes (some sums leave the fast
    /// range of `expf`, some are tiny); `special` also draws huge, zero and non-finite ones.
    fn random_blob(
        rng: &mut rand::rngs::ChaCha8Rng,
        h: u8,
        outputs: OutputKind,
        inputs: InputKind,
        special: bool,
    ) -> ModelBlob {
        let mut b = blob(h, outputs, inputs);
        let (ni, no) = (inputs.len(), outputs.len());
        let n = param_count(ni, h as usize, no);
        let mag = rng.random_range(-3.0f32..1.5);
        let draw = |rng: &mut rand::rngs::ChaCha8Rng| -> f32 {
            let v = rng.random_range(-1.0f32..1.0) * 10f32.powf(mag + rng.random_range(-1.0..1.0));
            if special {
                wild(rng, v)
            } else {
                v
            }
        };
        let params: Vec<f32> = (0..n).map(|_| draw(rng)).collect();
        b.params = heapless::Vec::from_slice(&params).unwrap();
        for k in 0..ni {
            b.in_offset[k] = rng.random_range(0.0f32..640.0);
            b.in_scale[k] = rng.random_range(0.001f32..0.05);
        }
        for k in 0..no {
            b.out_offset[k] = rng.random_range(-200.0f32..200.0);
            b.out_scale[k] = rng.random_range(-100.0f32..100.0);
        }
        if rng.random_range(0..2) == 0 {
            b.topology.output_activation = Activation::Sigmoid;
        }
        b
    }

    /// The batch paths against row-by-row `Mlp::infer` and `ModelBlob::infer`: the same
    /// output bits, the same first failing row and error, the same rows written before it.
    fn check_batch<const I: usize, const H: usize, const O: usize>(b: &ModelBlob, x: &[f32]) {
        let m: Mlp<I, H, O> = b.to_mlp().unwrap();
        let rows = x.len() / I;
        let mut want = vec![f32::from_bits(0x7fc0_dead); rows * O];
        let mut want_err = None;
        for r in 0..rows {
            let xa: &[f32; I] = x[r * I..(r + 1) * I].try_into().unwrap();
            let mut flat = [0.0f32; O];
            let e1 = b.infer(xa, &mut flat);
            let e2 = m.infer(xa);
            assert_eq!(e1.err(), e2.err());
            match e2 {
                Ok(y) => {
                    assert_eq!(y.map(f32::to_bits), flat.map(f32::to_bits));
                    want[r * O..(r + 1) * O].copy_from_slice(&y);
                }
                Err(error) => {
                    want_err = Some(PointError { index: r, error });
                    break;
                }
            }
        }
        let done = want_err.map_or(rows, |e| e.index);
        let bits = |v: &[f32]| v.iter().map(|y| y.to_bits()).collect::<Vec<_>>();

        let mut got = vec![f32::from_bits(0x7fc0_dead); rows * O];
        let e = run(&m, x, &mut got).err();
        assert_eq!(e, want_err.map(|e| (e.index, e.error)));
        assert_eq!(bits(&got[..done * O]), bits(&want[..done * O]));

        let p = Predictor::new(b);
        assert!(p.is_fixed());
        let mut got = vec![f32::from_bits(0x7fc0_dead); rows * O];
        assert_eq!(p.run_serial(x, &mut got).err(), want_err);
        assert_eq!(bits(&got[..done * O]), bits(&want[..done * O]));
        match p.predict(x) {
            Ok(y) => {
                assert_eq!(want_err, None);
                assert_eq!(bits(&y), bits(&want));
            }
            Err(e) => assert_eq!(Some(e), want_err),
        }
    }

    fn check_topology<const I: usize, const H: usize, const O: usize>(
        rng: &mut rand::rngs::ChaCha8Rng,
    ) {
        let inputs = if I == 4 {
            InputKind::Stereo
        } else {
            InputKind::StereoJoints
        };
        let outputs = if O == 3 {
            OutputKind::Xyz
        } else {
            OutputKind::Z
        };
        for model in 0..6 {
            let b = random_blob(rng, H as u8, outputs, inputs, model >= 4);
            for set in 0..3 {
                // Not a multiple of LANES: the tail runs point by point.
                let rows = LANES * rng.random_range(0..20) + rng.random_range(0..LANES);
                let x: Vec<f32> = (0..rows * I)
                    .map(|_| {
                        let v = rng.random_range(-50.0f32..700.0);
                        if set == 0 {
                            v
                        } else if rng.random_range(0..(20 * set * set)) == 0 {
                            wild(rng, v)
                        } else {
                            v
                        }
                    })
                    .collect();
                check_batch::<I, H, O>(&b, &x);
            }
        }
    }

    macro_rules! topologies {
        ($rng:expr; $($I:literal, $O:literal: $($H:literal)*;)*) => {
            $( $( check_topology::<$I, $H, $O>($rng); )* )*
        };
    }

    #[test]
    fn batches_give_the_bits_and_errors_of_mlp_infer() {
        let mut rng = rand::rngs::ChaCha8Rng::seed_from_u64(0x1a9e5);
        topologies!(&mut rng;
            4, 3: 1 2 3 4 5 6 7 8 9 10;
            4, 1: 1 2 3 4 5 6 7 8 9 10;
            9, 3: 1 2 3 4 5 6 7 8 9 10;
            9, 1: 1 2 3 4 5 6 7 8 9 10;
        );
    }

    /// Blocks with one bad lane at every position: the error names that row, the rows
    /// before it are written.
    #[test]
    fn a_bad_lane_anywhere_in_a_block_is_the_reported_row() {
        let b = blob(5, OutputKind::Xyz, InputKind::Stereo);
        for bad in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
            for row in 0..3 * LANES {
                for col in 0..4 {
                    let mut x: Vec<f32> = (0..4 * 3 * LANES).map(|k| 250.0 + k as f32).collect();
                    x[row * 4 + col] = bad;
                    check_batch::<4, 5, 3>(&b, &x);
                }
            }
        }
        // A model whose output overflows from some row in the middle of a block on:
        // a = sigmoid((x0 - 300) * 0.02) - 0.5, v = a * 1e32 + f32::MAX, infinite for
        // a > ~0.1, i.e. x0 > ~320.
        let mut b = blob(5, OutputKind::Z, InputKind::Stereo);
        let mut params = [0.0f32; 31];
        params[0] = 1.0;
        params[25] = 1.0;
        params[30] = -0.5;
        b.params = heapless::Vec::from_slice(&params).unwrap();
        b.out_scale[0] = 1e32;
        b.out_offset[0] = f32::MAX;
        let x: Vec<f32> = (0..4 * 5 * LANES)
            .map(|k| 250.0 + (k / 4 * 2) as f32)
            .collect();
        let e = Predictor::new(&b).predict(&x).unwrap_err();
        assert_eq!(e.error, MlpError::NonFiniteOutput);
        assert!(e.index > LANES && e.index % LANES != 0, "{e:?}");
        check_batch::<4, 5, 1>(&b, &x);
    }
}
