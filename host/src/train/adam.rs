//! Adam (Kingma & Ba 2015), full batch, on the same cost as LM: weighted least squares plus
//! weight decay `alpha/2 |p|^2` (added to the gradient, as in LM; not decoupled).
//!
//! Full-batch gradients make the run a pure function of the initial weights (no sampling),
//! so it is deterministic. The step size decays geometrically from
//! [`AdamOptions::lr_start`] to [`AdamOptions::lr_end`] over the epochs; the parameters with
//! the lowest cost seen are returned.

// Index loops mirror the equations (several arrays indexed by the same unit numbers).
#![allow(clippy::needless_range_loop)]

use super::net::Problem;

/// Adam settings.
#[derive(Debug, Clone, Copy)]
pub(crate) struct AdamOptions {
    /// Full-batch epochs.
    pub epochs: usize,
    /// First step size.
    pub lr_start: f64,
    /// Last step size.
    pub lr_end: f64,
    /// First-moment decay.
    pub beta1: f64,
    /// Second-moment decay.
    pub beta2: f64,
    /// Denominator guard.
    pub eps: f64,
    /// Weight decay `alpha`.
    pub weight_decay: f64,
}

impl Default for AdamOptions {
    fn default() -> Self {
        AdamOptions {
            epochs: 4000,
            lr_start: 2e-2,
            lr_end: 1e-4,
            beta1: 0.9,
            beta2: 0.999,
            eps: 1e-12,
            weight_decay: super::WEIGHT_DECAY,
        }
    }
}

/// What a run did.
#[derive(Debug, Clone, Copy)]
pub(crate) struct AdamResult {
    /// Epochs run.
    pub epochs: usize,
    /// Cost (with the decay term) of the returned parameters.
    #[cfg_attr(not(test), allow(dead_code))]
    pub cost: f64,
}

/// Minimises the problem's cost from `p` (replaced by the best parameters seen).
pub(crate) fn fit(prob: &Problem, p: &mut [f64], o: &AdamOptions) -> AdamResult {
    let decay_term = |q: &[f64]| 0.5 * o.weight_decay * q.iter().map(|v| v * v).sum::<f64>();
    let np = p.len();
    let (mut m, mut v, mut g) = (vec![0.0; np], vec![0.0; np], vec![0.0; np]);
    let mut best = p.to_vec();
    let mut best_cost = f64::INFINITY;
    let decay = if o.epochs > 1 {
        libm::pow(o.lr_end / o.lr_start, 1.0 / (o.epochs - 1) as f64)
    } else {
        1.0
    };
    let (mut lr, mut b1t, mut b2t) = (o.lr_start, 1.0, 1.0);
    let mut epochs = 0;
    for _ in 0..o.epochs {
        let cost = prob.gradient(p, &mut g) + decay_term(p);
        if !cost.is_finite() {
            break;
        }
        epochs += 1;
        for (gq, pq) in g.iter_mut().zip(p.iter()) {
            *gq += o.weight_decay * pq;
        }
        if cost < best_cost {
            best_cost = cost;
            best.copy_from_slice(p);
        }
        b1t *= o.beta1;
        b2t *= o.beta2;
        for q in 0..np {
            m[q] = o.beta1 * m[q] + (1.0 - o.beta1) * g[q];
            v[q] = o.beta2 * v[q] + (1.0 - o.beta2) * g[q] * g[q];
            let mh = m[q] / (1.0 - b1t);
            let vh = v[q] / (1.0 - b2t);
            p[q] -= lr * mh / (vh.sqrt() + o.eps);
        }
        lr *= decay;
    }
    let last = prob.cost(p) + decay_term(p);
    if last < best_cost {
        best_cost = last;
        best.copy_from_slice(p);
    }
    p.copy_from_slice(&best);
    AdamResult { epochs, cost: best_cost }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::train::net::tests::random_start;
    use crate::train::net::Shape;

    #[test]
    fn lowers_the_cost() {
        let (prob, mut p, start) = random_start(Shape::new(2, 3, 2, false), 30, [1, 2]);
        let opts = AdamOptions { epochs: 500, weight_decay: 0.0, ..AdamOptions::default() };
        let res = fit(&prob, &mut p, &opts);
        assert_eq!(res.epochs, 500);
        assert_eq!(res.cost, prob.cost(&p));
        assert!(res.cost < 0.2 * start, "{} vs start {start}", res.cost);
    }
}
