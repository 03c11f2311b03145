//! Lane-wise (several points at once) form of `hvs_shared::runtime::mlp::Mlp::infer`, bit-identical
//! to it, written so that LLVM auto-vectorises it: no `unsafe`, no target features, plain
//! f32 arithmetic (Rust never contracts to FMA) in exactly the order of the scalar code.
//!
//! The sigmoid is `hvs_shared::runtime::mlp::sigmoid` computed lane by lane with its own
//! pieces: its `exp` branches between `exp_fast` (a straight range-reduced polynomial) and
//! `exp_outside` (saturation) on `|x| < EXP_FAST_BELOW`; here every lane computes `exp_fast` on
//! its input (0 where it is out of range) and selects, so the lanes stay branch-free and LLVM
//! vectorises them. (`libm::expf`, the exp of earlier versions, needed a branch-free copy of its
//! own here.) Tested bit for bit against the scalar sigmoid on a dense sweep of f32 inputs, and
//! exhaustively with `cargo test --release -p hvs-host --lib infer::lanes -- --ignored`.
//!
//! A block of [`LANES`] points whose inputs or outputs are not all finite is rerun point by
//! point through `Mlp::infer`, so errors (and the outputs written before them) are those of
//! the scalar path.

// Index loops keep the summation order explicit: it is part of the bit-exactness contract.
#![allow(clippy::needless_range_loop)]

#[cfg(test)]
use hvs_shared::runtime::mlp::sigmoid;
use hvs_shared::runtime::mlp::{exp_fast, exp_outside, Activation, Mlp, MlpError, EXP_FAST_BELOW};

/// Points evaluated together.
pub(crate) const LANES: usize = 16;

type V = [f32; LANES];

/// `hvs_shared::runtime::mlp::sigmoid` on every lane: `1 / (1 + exp(-a))`, `exp`'s branch
/// as a select.
#[inline(always)]
pub(crate) fn sigmoid_lanes(a: &V) -> V {
    let mut out = [0.0f32; LANES];
    for l in 0..LANES {
        let x = -a[l];
        let fast = f32::from_bits(x.to_bits() & 0x7fff_ffff) < EXP_FAST_BELOW;
        let e_fast = exp_fast(if fast { x } else { 0.0 });
        let e = if fast { e_fast } else { exp_outside(x) };
        out[l] = 1.0 / (1.0 + e);
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

/// The linear skip weights `s[k][i]` of a family with a skip term: output `k`'s sum goes on
/// from the net's with `s[k][i] * xn[i]` in input order (as `infer_flat` adds them).
pub(crate) type Skip<const I: usize, const O: usize> = [[f32; I]; O];

/// [`LANES`] points (`x`: `LANES * I` values, `out`: `LANES * O`) through `m` (and its
/// `skip` term, if any). Returns `false`, writing nothing, if an input or an output is not
/// finite: the caller reruns the block point by point.
#[inline(always)]
fn block<const I: usize, const H: usize, const O: usize>(
    m: &Mlp<I, H, O>,
    skip: Option<&Skip<I, O>>,
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
        let mut a = neuron_lanes(m.b2[k], &m.w2[k], &h);
        if let Some(s) = skip {
            for i in 0..I {
                for l in 0..LANES {
                    a[l] += s[k][i] * xn[i][l];
                }
            }
        }
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
#[cfg(test)]
pub(crate) fn run<const I: usize, const H: usize, const O: usize>(
    m: &Mlp<I, H, O>,
    x: &[f32],
    out: &mut [f32],
) -> Result<(), (usize, MlpError)> {
    run_with(m, None, x, out, |xa| m.infer(xa))
}

/// [`run`] for the net `m` with an optional `skip` term, bit-identical to `scalar` (the same
/// net point by point: `Mlp::infer`, or `infer_flat` for a net with a skip term) row by row,
/// which also runs the blocks with a non-finite input or output and the last partial block;
/// stops at the first failing row, as that loop does.
pub(crate) fn run_with<const I: usize, const H: usize, const O: usize>(
    m: &Mlp<I, H, O>,
    skip: Option<&Skip<I, O>>,
    x: &[f32],
    out: &mut [f32],
    scalar: impl Fn(&[f32; I]) -> Result<[f32; O], MlpError>,
) -> Result<(), (usize, MlpError)> {
    let rows = (x.len() / I).min(out.len() / O);
    let mut r = 0;
    while r < rows {
        let n = (rows - r).min(LANES);
        let (xb, ob) = (&x[r * I..(r + n) * I], &mut out[r * O..(r + n) * O]);
        if n < LANES || !block(m, skip, xb, ob) {
            for (q, (xi, oi)) in xb.chunks_exact(I).zip(ob.chunks_exact_mut(O)).enumerate() {
                let xa: &[f32; I] = xi.try_into().map_err(|_| (r + q, MlpError::Shape))?;
                let yv = scalar(xa).map_err(|e| (r + q, e))?;
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

    /// Compares [`sigmoid_lanes`] with the scalar sigmoid on `bits`, [`LANES`] consecutive
    /// patterns per call.
    fn check_sigmoid(bits: impl Iterator<Item = u32>) -> usize {
        let mut n = 0;
        let mut buf = [0.0f32; LANES];
        let mut fill = 0;
        let flush = |buf: &[f32; LANES], fill: usize| {
            let got = sigmoid_lanes(buf);
            for l in 0..fill {
                let want = sigmoid(buf[l]);
                assert_eq!(
                    got[l].to_bits(),
                    want.to_bits(),
                    "sigmoid({:e} = {:#010x}): lanes {:e}, scalar {:e}",
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

    /// Every 2039th bit pattern (both signs, all exponents), plus +-8192 patterns around the
    /// exp's clamps, its overflow and underflow, and +-128 around every point where its `k`
    /// changes (`x = (n + 1/2) ln 2`).
    #[test]
    fn sigmoid_lanes_matches_the_scalar_sigmoid_on_a_dense_sweep() {
        let stride = (0..=u32::MAX).step_by(2039);
        let thresholds = [EXP_FAST_BELOW, 88.38, 87.33, 87.68, 17.33, 1e-30]
            .map(f32::to_bits)
            .into_iter()
            .chain([0, 0x7f80_0000, 0x7fff_ffff - 8192]);
        let near = thresholds.flat_map(|t| {
            [0u32, 0x8000_0000].into_iter().flat_map(move |s| {
                (t.saturating_sub(8192)..=t.saturating_add(8192).min(0x7fff_ffff))
                    .map(move |b| b | s)
            })
        });
        let k_steps = (0..=130).flat_map(|n| {
            let t = ((n as f32 + 0.5) * core::f32::consts::LN_2).to_bits();
            [0u32, 0x8000_0000]
                .into_iter()
                .flat_map(move |s| (t - 128..=t + 128).map(move |b| b | s))
        });
        let n = check_sigmoid(stride.chain(near).chain(k_steps));
        assert!(n > 2_100_000, "{n}");
    }

    /// All 2^32 patterns (seconds in release on two cores):
    /// `cargo test --release -p hvs-host --lib infer::lanes -- --ignored`
    #[test]
    #[ignore]
    fn sigmoid_lanes_matches_the_scalar_sigmoid_exhaustively() {
        use rayon::prelude::*;
        let n: usize = (0..=u16::MAX as u32)
            .into_par_iter()
            .map(|hi| check_sigmoid((0..=u16::MAX as u32).map(move |lo| hi << 16 | lo)))
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
    /// range of `exp`, some are tiny); `special` also draws huge, zero and non-finite ones.
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
        let inputs = if I == 4 { InputKind::Stereo } else { InputKind::StereoJoints };
        let outputs = if O == 3 { OutputKind::Xyz } else { OutputKind::Z };
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

    /// The default family (inverse depth with a linear skip term) and the posture frames run
    /// through the lanes too: against `ModelBlob::infer` row by row, the same bits, the same
    /// first failing row and error, the same rows written before it.
    fn check_skip<const I: usize, const H: usize, const O: usize>(
        rng: &mut rand::rngs::ChaCha8Rng,
    ) -> usize {
        let mut compared = 0;
        use hvs_shared::runtime::blob::{Family, OutputFrame};
        let inputs = if I == 4 { InputKind::Stereo } else { InputKind::StereoJoints };
        let outputs = if O == 3 { OutputKind::Xyz } else { OutputKind::Z };
        let frames: &[OutputFrame] = if I == 9 && O == 3 {
            &[OutputFrame::Head, OutputFrame::EyePlatform, OutputFrame::Cyclopean]
        } else {
            &[OutputFrame::Head]
        };
        for model in 0..6 {
            let mut b = random_blob(rng, H as u8, outputs, inputs, model >= 4);
            let skip: Vec<f32> = (0..I * O).map(|_| rng.random_range(-0.5f32..0.5)).collect();
            b.params.extend_from_slice(&skip).unwrap();
            b.family = if model % 2 == 0 { Family::INVERSE_DEPTH_SKIP } else { Family::THESIS };
            if model % 2 == 1 {
                b.family.skip = Family::INVERSE_DEPTH_SKIP.skip;
            }
            b.frame = frames[model % frames.len()];
            let p = Predictor::new(&b);
            assert!(p.is_fixed(), "{I}-{H}-{O} {:?}", b.family);
            for set in 0..3 {
                let rows = LANES * rng.random_range(0..20) + rng.random_range(0..LANES);
                let x: Vec<f32> = (0..rows * I)
                    .map(|_| {
                        let v = rng.random_range(-50.0f32..700.0);
                        if set > 0 && rng.random_range(0..(20 * set * set)) == 0 {
                            wild(rng, v)
                        } else {
                            v
                        }
                    })
                    .collect();
                let mut want = vec![f32::from_bits(0x7fc0_dead); rows * O];
                let mut want_err = None;
                for r in 0..rows {
                    if let Err(error) =
                        b.infer(&x[r * I..(r + 1) * I], &mut want[r * O..(r + 1) * O])
                    {
                        want_err = Some(PointError { index: r, error });
                        break;
                    }
                }
                let done = want_err.map_or(rows, |e| e.index);
                compared += done;
                let bits = |v: &[f32]| v.iter().map(|y| y.to_bits()).collect::<Vec<_>>();
                let mut got = vec![f32::from_bits(0x7fc0_dead); rows * O];
                assert_eq!(p.run_serial(&x, &mut got).err(), want_err);
                assert_eq!(bits(&got[..done * O]), bits(&want[..done * O]));
                match p.predict(&x) {
                    Ok(y) => {
                        assert_eq!(want_err, None);
                        assert_eq!(bits(&y), bits(&want));
                    }
                    Err(e) => assert_eq!(Some(e), want_err),
                }
            }
        }
        compared
    }

    #[test]
    fn skip_families_and_posture_frames_give_the_bits_and_errors_of_blob_infer() {
        let mut rng = rand::rngs::ChaCha8Rng::seed_from_u64(0x5c1b);
        let rng = &mut rng;
        let compared = check_skip::<4, 1, 3>(rng)
            + check_skip::<4, 5, 3>(rng)
            + check_skip::<4, 10, 3>(rng)
            + check_skip::<4, 5, 1>(rng)
            + check_skip::<9, 3, 3>(rng)
            + check_skip::<9, 7, 3>(rng)
            + check_skip::<9, 10, 3>(rng)
            + check_skip::<9, 5, 1>(rng);
        // Not vacuous: most rows have an estimate, whole blocks of them through the lanes.
        assert!(compared > 4000, "{compared}");
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
        let x: Vec<f32> = (0..4 * 5 * LANES).map(|k| 250.0 + (k / 4 * 2) as f32).collect();
        let e = Predictor::new(&b).predict(&x).unwrap_err();
        assert_eq!(e.error, MlpError::NonFiniteOutput);
        assert!(e.index > LANES && e.index % LANES != 0, "{e:?}");
        check_batch::<4, 5, 1>(&b, &x);
    }
}
