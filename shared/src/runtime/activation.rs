//! Candidate fast hidden activation for the head: the logistic sigmoid over `micromath`'s
//! `exp` (a 4-term series on the fraction of `x / ln 2`, the exponent set directly) instead of
//! [`crate::runtime::mlp::exp`] (evaluated, and rejected for its error, before that
//! polynomial replaced `libm::expf`). Host and head run this same code, so a model that
//! selects it gives the same bits on both; it is a *model* property (a net must be trained
//! and evaluated with the function it runs with). Which activation a blob uses is the blob
//! format's business (`crate::runtime::blob`): this module only provides the function and an
//! inference over it.
//!
//! Relative error of [`exp_micromath`] against `libm::expf`: below 3e-3 over -87..88 (tested: 2.4e-3);
//! the sigmoid's absolute error stays below 5e-4.

use micromath::F32Ext;

/// `e^x` by `micromath` (`F32Ext::exp`) on -87..=88; 0 below, infinity above, NaN for NaN
/// (outside that range micromath's exponent arithmetic asserts, so it is never called there).
#[inline]
pub fn exp_micromath(x: f32) -> f32 {
    if x.is_nan() {
        x
    } else if x < -87.0 {
        0.0
    } else if x > 88.0 {
        f32::INFINITY
    } else {
        F32Ext::exp(x)
    }
}

/// The logistic sigmoid `1 / (1 + e^-a)` over [`exp_micromath`].
#[inline]
pub fn sigmoid_micromath(a: f32) -> f32 {
    1.0 / (1.0 + exp_micromath(-a))
}

/// The inference over any sigmoid (here [`sigmoid_micromath`]): [`crate::runtime::mlp::infer_fixed`]'s
/// checks and summation order, so with [`crate::runtime::mlp::sigmoid`] it gives exactly
/// `infer_fixed`'s bits (tested).
pub use crate::runtime::mlp::infer_fixed_with;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::runtime::mlp::{fixture, infer_fixed, sigmoid, MlpError};
    use proptest::prelude::*;

    #[test]
    fn exp_is_close_to_libm_and_saturates() {
        let mut worst = 0.0f32;
        let mut x = -87.0f32;
        while x <= 88.0 {
            let (got, want) = (exp_micromath(x), libm::expf(x));
            worst = worst.max(((got - want) / want).abs());
            x += 0.01;
        }
        assert!(worst < 3e-3, "worst relative error {worst}");
        assert!(worst > 0.0, "not a different function");
        assert_eq!(exp_micromath(0.0), 1.0);
        assert_eq!(exp_micromath(-200.0), 0.0);
        assert_eq!(exp_micromath(200.0), f32::INFINITY);
        assert_eq!(exp_micromath(f32::NEG_INFINITY), 0.0);
        assert_eq!(exp_micromath(f32::INFINITY), f32::INFINITY);
        assert!(exp_micromath(f32::NAN).is_nan());
        for x in [-87.0f32, -86.99, 88.0, 87.99, 88.5, 88.7, 89.0, -87.5, -100.0] {
            let _ = exp_micromath(x); // no assertion inside micromath fires
        }
    }

    #[test]
    fn sigmoid_stays_in_range_and_near_the_exact_one() {
        let mut a = -120.0f32;
        while a <= 120.0 {
            let s = sigmoid_micromath(a);
            assert!((0.0..=1.0).contains(&s), "{a}: {s}");
            assert!((s - sigmoid(a)).abs() < 5e-4, "{a}: {s} vs {}", sigmoid(a));
            a += 0.05;
        }
        assert_eq!(sigmoid_micromath(0.0), 0.5);
        assert_eq!(sigmoid_micromath(f32::INFINITY), 1.0);
        assert_eq!(sigmoid_micromath(f32::NEG_INFINITY), 0.0);
    }

    proptest! {
        #[test]
        fn with_the_standard_sigmoid_it_is_infer_fixed((params, x, output) in fixture::case()) {
            let m = fixture::net(&params, output);
            let os = fixture::OUT_SCALE;
            let want = infer_fixed::<4, 5, 3>(&m, &x).unwrap();
            let got = infer_fixed_with::<4, 5, 3>(&m, &x, sigmoid).unwrap();
            prop_assert_eq!(got.map(f32::to_bits), want.map(f32::to_bits));
            // The micromath one differs, but little (5e-4 per hidden unit, weights below 3).
            let fast = infer_fixed_with::<4, 5, 3>(&m, &x, sigmoid_micromath).unwrap();
            for k in 0..3 {
                prop_assert!((fast[k] - want[k]).abs() <= 0.05 * os[k], "{k}: {} vs {}", fast[k], want[k]);
            }
            prop_assert_eq!(infer_fixed_with::<4, 6, 3>(&m, &x, sigmoid), Err(MlpError::Shape));
        }
    }
}
