//! Cholesky factorisation and solve of Levenberg-Marquardt's damped normal equations, with the
//! bits of `nalgebra::linalg::Cholesky` (0.34: `new`, then `solve_mut`) and several times its
//! speed on the nets' 40-300 parameters.
//!
//! nalgebra factors column by column, subtracting from column `j` the columns `k < j` one at a
//! time as `y = (-l_jk) x + y`, then divides the column by the root of its diagonal; it solves
//! `L y = b` forward with the same updates and `L^T x = y` backward with its dot product of
//! eight interleaved sums. Here every element sees the same operations in the same order (each
//! element of column `j` still takes the columns `k = 0..j` in turn), but a block of rows is
//! kept in registers over all `k` (where nalgebra loads and stores the column for every `k`,
//! and goes one element at a time through the rows past its last whole vector), and the whole
//! is compiled for AVX and AVX-512F too, picked at run time: plain multiplies and adds (no
//! fused multiply-add), so the same bits on every CPU. The unit tests compare every build the
//! CPU runs with nalgebra bit for bit.

// Index loops mirror nalgebra's (row i, column j of a column-major matrix).
#![allow(clippy::needless_range_loop)]

/// Elements [`factor`] may read (never write) past the end of the matrix: blocks of rows
/// are loaded whole, and their rows below the matrix are discarded.
pub(crate) const SLACK: usize = 32;

crate::simd::x86_dispatch! {
    /// Factors the symmetric positive definite `n x n` matrix in the first `n * n` elements of
    /// `a` (column-major; only its lower triangle, diagonal included, is read; `a` has
    /// [`SLACK`] more elements) into `L L^T` in place: `L` in the lower triangle, the strict
    /// upper triangle left as it was. `false` (and `a` half-factored) where a pivot is zero,
    /// negative or NaN, as nalgebra's `Cholesky::new` returns `None`. Blocks of 32 rows with
    /// AVX-512F, 16 with AVX, 8 otherwise.
    pub(crate) fn factor(a: &mut [f64], n: usize) -> bool {
        avx512 factor_avx512: factor_in::<SLACK>(a, n),
        avx factor_avx: factor_in::<16>(a, n),
        portable: factor_in::<8>(a, n),
    }
}

/// The body of [`factor`], `W` rows at a time (`W` at most [`SLACK`]): each block of a column
/// stays in registers while the columns before it are subtracted, four or more registers of
/// independent sums, so the adds' latency is hidden.
#[inline(always)]
fn factor_in<const W: usize>(a: &mut [f64], n: usize) -> bool {
    assert!(a.len() >= n * n + SLACK, "a {n} x {n} matrix and its slack");
    for j in 0..n {
        let mut i = j;
        while i < n {
            // Rows i..i + W of column j; those at n and beyond lie in the next column or the
            // slack and are dropped.
            let mut y = [0.0; W];
            y.copy_from_slice(&a[j * n + i..j * n + i + W]);
            for k in 0..j {
                let f = -a[k * n + j];
                let x = &a[k * n + i..k * n + i + W];
                for r in 0..W {
                    y[r] += f * x[r];
                }
            }
            let keep = W.min(n - i);
            a[j * n + i..j * n + i + keep].copy_from_slice(&y[..keep]);
            i += W;
        }
        let d = a[j * n + j];
        // nalgebra: a zero pivot fails, then `try_sqrt` (`d >= 0`), so a negative or NaN one.
        if d.is_nan() || d <= 0.0 {
            return false;
        }
        let s = d.sqrt();
        a[j * n + j] = s;
        for v in &mut a[j * n + j + 1..(j + 1) * n] {
            *v /= s;
        }
    }
    true
}

crate::simd::x86_dispatch! {
    /// Solves `L L^T x = b` in place, `l` the factor [`factor`] left in an `n x n`
    /// column-major matrix (its lower triangle).
    pub(crate) fn solve(l: &[f64], n: usize, b: &mut [f64]) {
        avx512 solve_avx512: solve_in(l, n, b),
        avx solve_avx: solve_in(l, n, b),
        portable: solve_in(l, n, b),
    }
}

/// The body of [`solve`]: nalgebra's `solve_lower_triangular_unchecked_mut`, then
/// `ad_solve_lower_triangular_unchecked_mut` with its dot product.
#[inline(always)]
fn solve_in(l: &[f64], n: usize, b: &mut [f64]) {
    assert_eq!(l.len(), n * n, "a {n} x {n} factor");
    assert_eq!(b.len(), n, "a right-hand side of {n}");
    for i in 0..n {
        let coeff = b[i] / l[i * n + i];
        b[i] = coeff;
        let col = &l[i * n + i + 1..(i + 1) * n];
        for (y, x) in b[i + 1..].iter_mut().zip(col) {
            *y += -coeff * x;
        }
    }
    for i in (0..n).rev() {
        let dot = dot8(&l[i * n + i + 1..(i + 1) * n], &b[i + 1..]);
        b[i] = (b[i] - dot) / l[i * n + i];
    }
}

/// nalgebra's dot product (`Matrix::dotx` for a dynamic column): eight sums over every eighth
/// element while eight or more remain, folded as `((((0 + (s0 + s4)) + (s1 + s5)) + ..`, then
/// the rest added one by one.
#[inline(always)]
fn dot8(x: &[f64], y: &[f64]) -> f64 {
    let len = x.len();
    let mut acc = [0.0f64; 8];
    let mut i = 0;
    while len - i >= 8 {
        for k in 0..8 {
            acc[k] += x[i + k] * y[i + k];
        }
        i += 8;
    }
    let mut res = 0.0;
    res += acc[0] + acc[4];
    res += acc[1] + acc[5];
    res += acc[2] + acc[6];
    res += acc[3] + acc[7];
    for k in i..len {
        res += x[k] * y[k];
    }
    res
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::train::rng::SplitMix64;
    use nalgebra::{linalg::Cholesky, DMatrix, DVector};

    /// A random symmetric matrix `B B^T + shift I` (positive definite for a positive shift;
    /// a negative one can make it indefinite).
    fn matrix(n: usize, shift: f64, rng: &mut SplitMix64) -> DMatrix<f64> {
        let b = DMatrix::<f64>::from_fn(n, n + 2, |_, _| rng.uniform(-1.0, 1.0));
        let mut a = &b * b.transpose();
        for q in 0..n {
            a[(q, q)] += shift;
        }
        a
    }

    /// The matrix's elements, then [`SLACK`] NaNs (never to reach the result).
    fn with_slack(a: &DMatrix<f64>) -> Vec<f64> {
        let mut m = a.as_slice().to_vec();
        m.extend([f64::NAN; SLACK]);
        m
    }

    /// Every build this CPU can run: (name, factor, solve).
    #[allow(clippy::type_complexity)]
    fn builds() -> Vec<(&'static str, fn(&mut [f64], usize) -> bool, fn(&[f64], usize, &mut [f64]))>
    {
        let mut v: Vec<(
            &'static str,
            fn(&mut [f64], usize) -> bool,
            fn(&[f64], usize, &mut [f64]),
        )> = vec![("portable", factor_in::<8>, solve_in), ("dispatched", factor, solve)];
        #[cfg(target_arch = "x86_64")]
        for name in crate::simd::builds_here() {
            // SAFETY: `builds_here` lists only what this CPU has.
            v.push(if name == "avx" {
                ("avx", |a, n| unsafe { factor_avx(a, n) }, |l, n, b| unsafe { solve_avx(l, n, b) })
            } else {
                (
                    "avx512",
                    |a, n| unsafe { factor_avx512(a, n) },
                    |l, n, b| unsafe { solve_avx512(l, n, b) },
                )
            });
        }
        v
    }

    #[test]
    fn the_bits_of_nalgebras_factor_and_solve() {
        let mut rng = SplitMix64::new(5);
        for n in (1..=40).chain([55, 63, 64, 65, 120, 301]) {
            for shift in [1e-9, 1e-3, 1.0] {
                let a = matrix(n, shift, &mut rng);
                let rhs = DVector::<f64>::from_fn(n, |_, _| rng.uniform(-1.0, 1.0));
                let chol = Cholesky::new(a.clone()).expect("positive definite");
                let mut want = rhs.clone();
                chol.solve_mut(&mut want);
                let l = chol.unpack_dirty();
                for (name, f, s) in builds() {
                    let mut m = with_slack(&a);
                    assert!(f(&mut m, n), "{name} n {n}");
                    for c in 0..n {
                        for r in c..n {
                            assert_eq!(
                                m[c * n + r].to_bits(),
                                l[(r, c)].to_bits(),
                                "{name}: L[{r}, {c}] of {n} x {n}"
                            );
                        }
                    }
                    let mut x = rhs.as_slice().to_vec();
                    s(&m[..n * n], n, &mut x);
                    for q in 0..n {
                        assert_eq!(x[q].to_bits(), want[q].to_bits(), "{name}: x[{q}] of {n}");
                    }
                }
            }
        }
    }

    #[test]
    fn refuses_what_nalgebra_refuses() {
        let mut rng = SplitMix64::new(9);
        let mut refused = 0;
        for n in [3, 9, 17, 55] {
            for shift in [-0.5, -0.05, -2.0] {
                let a = matrix(n, shift, &mut rng);
                let want = Cholesky::new(a.clone()).is_some();
                refused += usize::from(!want);
                for (name, f, _) in builds() {
                    let mut m = with_slack(&a);
                    assert_eq!(f(&mut m, n), want, "{name} n {n} shift {shift}");
                }
            }
        }
        assert!(refused >= 4, "the shifts make indefinite matrices ({refused})");
        // A zero pivot and a NaN.
        for bad in [0.0, f64::NAN] {
            let mut a = matrix(4, 1.0, &mut rng);
            a[(0, 0)] = bad;
            assert!(Cholesky::new(a.clone()).is_none());
            for (name, f, _) in builds() {
                assert!(!f(&mut with_slack(&a), 4), "{name}: pivot {bad}");
            }
        }
    }
}
