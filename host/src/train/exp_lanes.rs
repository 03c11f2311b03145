//! `libm::exp` (f64) on [`LANES`] values at once, bit for bit, for the training's forward
//! passes (the sigmoid of every hidden unit of every sample; `libm::exp` one call at a time
//! was an eighth of `hvs train`'s time).
//!
//! libm's `exp` (FreeBSD's `e_exp.c`) reduces `x = k ln2 + r` with `r = hi - lo`, evaluates a
//! degree-5 polynomial and scales by `2^k` (`scalbn`). Its branches pick `k` (0 below
//! `|x| = ln2 / 2`, +-1 below `1.5 ln2`, else `x / ln2` rounded half away from zero); here
//! they are selects, the same operations in the same order on every lane, so LLVM
//! vectorises them. For `|x|` in `(2^-28, 672)` the scaling by `2^k` (`|k| < 970`) is an exact
//! product, as `scalbn`'s is; lanes outside that range (zero, tiny, huge, infinite, NaN) are
//! recomputed by `libm::exp` itself. Tested bit for bit against `libm::exp`.

// Index loops keep the lane structure explicit.
#![allow(clippy::needless_range_loop)]

/// Values computed together.
pub(crate) const LANES: usize = 8;

// libm's constants, by their bits.
const LN2HI: f64 = f64::from_bits(0x3fe6_2e42_fee0_0000);
const LN2LO: f64 = f64::from_bits(0x3dea_39ef_3579_3c76);
const INVLN2: f64 = f64::from_bits(0x3ff7_1547_652b_82fe);
const P1: f64 = f64::from_bits(0x3fc5_5555_5555_553e);
const P2: f64 = f64::from_bits(0xbf66_c16c_16be_bd93);
const P3: f64 = f64::from_bits(0x3f11_566a_af25_de2c);
const P4: f64 = f64::from_bits(0xbebb_bd41_c5d2_6bf1);
const P5: f64 = f64::from_bits(0x3e66_3769_72be_a4d0);

/// High words of `|x|` between which the lanes compute `exp` themselves: `2^-28` (libm
/// returns `1 + x` below it) and 672 (`2^k` stays a normal number, the product exact).
const INSIDE_ABOVE: u32 = 0x3e30_0000;
const INSIDE_BELOW: u32 = 0x4085_0000;

/// `libm::exp` of every lane, the same bits.
#[inline(always)]
pub(crate) fn exp_lanes(x: &[f64; LANES]) -> [f64; LANES] {
    let mut out = [0.0; LANES];
    let mut inside = [false; LANES];
    for l in 0..LANES {
        let bits = x[l].to_bits();
        let hx = ((bits >> 32) as u32) & 0x7fff_ffff;
        let neg = bits >> 63 != 0;
        inside[l] = hx > INSIDE_ABOVE && hx < INSIDE_BELOW;
        let v = if inside[l] { x[l] } else { 1.0 };
        // libm: k = (INVLN2 x + (+-0.5)) as i32 at |x| >= 1.5 ln2, 1 - 2 sign above
        // 0.5 ln2, else 0 (and then hi = x, lo = 0: what the same formulas give with k = 0).
        let rounded = (INVLN2 * v + if neg { -0.5 } else { 0.5 }).trunc();
        let k = if hx >= 0x3ff0_a2b2 {
            rounded
        } else if hx > 0x3fd6_2e42 {
            if neg {
                -1.0
            } else {
                1.0
            }
        } else {
            0.0
        };
        let hi = v - k * LN2HI;
        let lo = k * LN2LO;
        let r = hi - lo;
        let xx = r * r;
        let c = r - xx * (P1 + xx * (P2 + xx * (P3 + xx * (P4 + xx * P5))));
        let y = 1.0 + (r * c / (2.0 - c) - lo + hi);
        out[l] = y * f64::from_bits(((k as i64 + 1023) as u64) << 52);
    }
    for l in 0..LANES {
        if !inside[l] {
            out[l] = libm::exp(x[l]);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::train::rng::SplitMix64;

    fn check(x: [f64; LANES]) {
        let got = exp_lanes(&x);
        for l in 0..LANES {
            assert_eq!(got[l].to_bits(), libm::exp(x[l]).to_bits(), "exp({:e})", x[l]);
        }
    }

    #[test]
    fn the_bits_of_libm_exp() {
        let mut rng = SplitMix64::new(21);
        // Every range of the branches, both signs: magnitudes from 1e-12 to 800.
        for _ in 0..200_000 {
            let x: [f64; LANES] = core::array::from_fn(|_| {
                let m = 10f64.powf(rng.uniform(-12.0, 2.9));
                if rng.next_f64() < 0.5 {
                    -m
                } else {
                    m
                }
            });
            check(x);
        }
        // The pre-activations a net sees: +-40.
        for _ in 0..200_000 {
            check(core::array::from_fn(|_| rng.uniform(-40.0, 40.0)));
        }
        // Branch edges, special values and the ends of the lanes' own range.
        let mut edges = vec![0.0, -0.0, f64::NAN, f64::INFINITY, f64::NEG_INFINITY, 1e-300];
        for hx in [0x3e30_0000u32, 0x3fd6_2e42, 0x3ff0_a2b2, 0x4085_0000, 0x4086_232b] {
            let base = (hx as u64) << 32;
            for d in [0u64, 1, 0xffff_ffff, 0x1_0000_0000, 0x1_0000_0001] {
                for b in [base.wrapping_sub(d), base + d] {
                    edges.push(f64::from_bits(b));
                    edges.push(-f64::from_bits(b));
                }
            }
        }
        edges.extend([709.78, 709.79, -745.1, -745.2, -708.4, 0.5 * std::f64::consts::LN_2]);
        for chunk in edges.chunks(LANES) {
            let mut x = [0.25; LANES];
            x[..chunk.len()].copy_from_slice(chunk);
            check(x);
        }
    }
}
