//! Levenberg-Marquardt for the weighted least-squares problem of [`Problem`], with weight
//! decay.
//!
//! The cost is `F(p) = 1/2 sum r^2 + 1/2 sum alpha_q p_q^2` (`alpha_q` is the weight decay,
//! another one for the tail of skip weights, [`LmOptions::tail`]). Each iteration solves
//! `(J^T J + alpha I + lambda D) delta = -(J^T r + alpha p)` by Cholesky ([`chol`]: the bits
//! of `nalgebra`'s, faster), with `D` the diagonal of `J^T J + alpha I` (Marquardt's scaling,
//! floored so that no direction is free), and updates `lambda` by Nielsen's rule from the
//! ratio of actual to predicted reduction. The normal equations come from the analytic Jacobian without forming it
//! ([`Problem::normal_equations`], reusing the forward pass of the accepted trial step);
//! every buffer is allocated once per fit. It stops when `F` has improved by less than
//! [`LmOptions::rel_tol`] (relative) on [`LmOptions::patience`] consecutive accepted steps,
//! when `lambda` explodes (no descent direction left), or after [`LmOptions::max_iter`] trial
//! steps.

// Index loops mirror the equations (several arrays indexed by the same unit numbers).
#![allow(clippy::needless_range_loop)]

use super::chol;
use super::net::{NormalWorkspace, Problem};

/// Cost and stopping rules.
#[derive(Debug, Clone, Copy)]
pub(crate) struct LmOptions {
    /// Most trial steps (accepted or not).
    pub max_iter: usize,
    /// An accepted step that lowers the cost by less than this fraction counts as stalled.
    pub rel_tol: f64,
    /// Stop after this many consecutive stalled steps.
    pub patience: usize,
    /// Weight decay `alpha` (0: plain least squares).
    pub weight_decay: f64,
    /// The last `tail.0` parameters (a net's linear skip weights) decay with `tail.1` instead.
    pub tail: (usize, f64),
}

impl Default for LmOptions {
    /// Plain least squares, run to a relative stall of 1e-6 (tests use this; `train` sets
    /// its own options).
    fn default() -> Self {
        LmOptions { max_iter: 300, rel_tol: 1e-6, patience: 4, weight_decay: 0.0, tail: (0, 0.0) }
    }
}

/// What a fit did.
#[derive(Debug, Clone, Copy)]
pub(crate) struct LmResult {
    /// Trial steps taken.
    pub iterations: usize,
    /// Final cost `F`.
    #[cfg_attr(not(test), allow(dead_code))]
    pub cost: f64,
}

fn sum_sq(v: &[f64]) -> f64 {
    v.iter().map(|x| x * x).sum()
}

/// Minimises the problem's regularised cost from `p` (updated in place).
pub(crate) fn fit(prob: &Problem, p: &mut [f64], opts: &LmOptions) -> LmResult {
    let np = p.len();
    let decay: Vec<f64> = (0..np)
        .map(|q| if q + opts.tail.0 >= np { opts.tail.1 } else { opts.weight_decay })
        .collect();
    let alpha_max = decay.iter().copied().fold(0.0, f64::max);
    let mut ws = NormalWorkspace::new(prob);
    let mut jtj = vec![0.0; np * np];
    let mut jtr = vec![0.0; np];
    let mut g = vec![0.0; np];
    let mut a = vec![0.0; np * np + chol::SLACK];
    let mut delta = vec![0.0; np];
    let mut diag = vec![0.0; np];
    let mut trial = vec![0.0; np];
    let mut act = prob.activations();
    let mut act_trial = prob.activations();
    // Without a tail the decay is one number: the regulariser is summed as alpha * sum(p^2),
    // in that order, so nets without skip weights train to the same bits as before the tail.
    let alpha = opts.weight_decay;
    let uniform = opts.tail.0 == 0;
    let objective = |sse_half: f64, q: &[f64]| {
        if uniform {
            sse_half + 0.5 * alpha * sum_sq(q)
        } else {
            sse_half + 0.5 * q.iter().zip(&decay).map(|(v, a)| a * v * v).sum::<f64>()
        }
    };

    prob.evaluate(p, &mut act);
    let mut f = objective(prob.normal_equations(p, &act, &mut jtj, &mut jtr, &mut ws), p);
    if !f.is_finite() {
        return LmResult { iterations: 0, cost: f };
    }
    let mut lambda = 1e-3;
    let mut nu = 2.0;
    let mut stalled = 0;
    let mut fresh = true; // gradient and scaling need recomputing at `p`
    let mut iterations = 0;
    while iterations < opts.max_iter {
        if fresh {
            for q in 0..np {
                g[q] = jtr[q] + decay[q] * p[q];
            }
            let dmax = (0..np).map(|q| jtj[q * np + q]).fold(0.0, f64::max) + alpha_max;
            for (q, d) in diag.iter_mut().enumerate() {
                *d = (jtj[q * np + q] + decay[q]).max(1e-9 * dmax).max(1e-300);
            }
            fresh = false;
        }
        iterations += 1;
        // The damped matrix, column-major (the factor reads its lower triangle).
        for q in 0..np {
            for s in 0..np {
                a[s * np + q] = jtj[q * np + s];
            }
            a[q * np + q] += decay[q] + lambda * diag[q];
        }
        if !chol::factor(&mut a, np) {
            lambda *= nu;
            nu *= 2.0;
            if lambda > 1e16 {
                break;
            }
            continue;
        }
        for q in 0..np {
            delta[q] = -g[q];
        }
        chol::solve(&a[..np * np], np, &mut delta);

        // Predicted reduction of the quadratic model: 1/2 delta^T (lambda D delta - g).
        let mut pred = 0.0;
        for q in 0..np {
            pred += delta[q] * (lambda * diag[q] * delta[q] - g[q]);
        }
        pred *= 0.5;
        for q in 0..np {
            trial[q] = p[q] + delta[q];
        }
        let f_new = objective(prob.evaluate(&trial, &mut act_trial), &trial);
        let rho = if pred > 0.0 { (f - f_new) / pred } else { -1.0 };
        if f_new.is_finite() && rho > 0.0 {
            let improvement = (f - f_new) / f.max(f64::MIN_POSITIVE);
            p.copy_from_slice(&trial);
            stalled = if improvement < opts.rel_tol { stalled + 1 } else { 0 };
            if stalled >= opts.patience || iterations >= opts.max_iter {
                // The last step: the normal equations at `p` would not be used.
                f = f_new;
                break;
            }
            std::mem::swap(&mut act, &mut act_trial);
            f = objective(prob.normal_equations(p, &act, &mut jtj, &mut jtr, &mut ws), p);
            fresh = true;
            lambda *= f64::max(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0).powi(3));
            lambda = lambda.max(1e-12);
            nu = 2.0;
        } else {
            lambda *= nu;
            nu *= 2.0;
            if lambda > 1e16 {
                break;
            }
        }
    }
    LmResult { iterations, cost: f }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::train::net::tests::{random_params, random_problem};
    use crate::train::net::Shape;
    use hvs_shared::runtime::mlp::Activation;

    #[test]
    fn reduces_the_cost_and_fits_a_realisable_problem() {
        let shape = Shape::new(2, 3, 1, false);
        // Targets produced by a 2-3-1 net: the global minimum is zero.
        let mut prob = random_problem(shape, Activation::Linear, 40, 3);
        let truth = random_params(&shape, 99);
        let mut r = vec![0.0; prob.n_res()];
        prob.t.iter_mut().for_each(|t| *t = 0.0);
        prob.c.iter_mut().for_each(|c| *c = 1.0);
        prob.residuals(&truth, &mut r);
        prob.t.copy_from_slice(&r);
        assert!(prob.cost(&truth) < 1e-28);

        // From a random start: a large reduction (the landscape has slow valleys, so not
        // necessarily zero within the iteration cap).
        let mut p = random_params(&shape, 4);
        let start = prob.cost(&p);
        let res = fit(&prob, &mut p, &LmOptions::default());
        assert!(res.cost < 1e-5 * start, "{} vs start {start}", res.cost);
        assert!(
            (res.cost - prob.cost(&p)).abs() <= 1e-15 * (1.0 + res.cost),
            "reported cost is the cost of the returned parameters"
        );
        // From near the truth: all the way down to rounding level.
        let d = random_params(&shape, 50);
        let mut p: Vec<f64> = truth.iter().zip(&d).map(|(t, d)| t + 0.1 * d).collect();
        let res = fit(&prob, &mut p, &LmOptions::default());
        assert!(res.cost < 1e-24, "{} after {}", res.cost, res.iterations);
    }

    #[test]
    fn never_increases_the_cost_and_respects_the_iteration_cap() {
        let shape = Shape::new(3, 4, 2, false);
        let prob = random_problem(shape, Activation::Linear, 25, 8);
        for seed in 0..5 {
            let mut p = random_params(&shape, seed);
            let start = prob.cost(&p);
            let opts = LmOptions { max_iter: 7, ..LmOptions::default() };
            let res = fit(&prob, &mut p, &opts);
            assert!(res.iterations <= 7);
            assert!(res.cost <= start);
        }
    }

    #[test]
    fn weight_decay_converges_to_a_stationary_point_of_the_regularised_cost() {
        let shape = Shape::new(3, 3, 2, false);
        let prob = random_problem(shape, Activation::Linear, 30, 12);
        let alpha = 1e-2;
        let mut p = random_params(&shape, 3);
        let f0 = prob.cost(&p) + 0.5 * alpha * sum_sq(&p);
        let opts = LmOptions {
            max_iter: 2000,
            rel_tol: 1e-14,
            patience: 8,
            weight_decay: alpha,
            tail: (0, 0.0),
        };
        let res = fit(&prob, &mut p, &opts);
        let f = prob.cost(&p) + 0.5 * alpha * sum_sq(&p);
        assert!((res.cost - f).abs() <= 1e-12 * f);
        assert!(f < f0);
        let mut grad = vec![0.0; p.len()];
        prob.gradient(&p, &mut grad);
        let norm: f64 =
            grad.iter().zip(&p).map(|(g, q)| (g + alpha * q).powi(2)).sum::<f64>().sqrt();
        assert!(norm < 1e-7, "gradient norm {norm} at the end");
        // The decay shrinks the weights compared with plain least squares from the same start.
        let mut q = random_params(&shape, 3);
        fit(&prob, &mut q, &LmOptions { weight_decay: 0.0, ..opts });
        assert!(sum_sq(&p) < sum_sq(&q));
    }
}
