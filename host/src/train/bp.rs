//! The thesis' back-propagation (chapter 2.2, Steps 1-8), reproduced as printed.
//!
//! - Step 1: patterns are presented one at a time, in data order; `E_max` and the learning
//!   rate `eta` are parameters ([`BpParams`]).
//! - Step 2: random initial weights *and biases* (the caller's seeded initialisation).
//! - Step 3: forward pass, sigmoid hidden and sigmoid output units (eqs. 2.1-3, 2.1-4), so
//!   targets are scaled into `[0.1, 0.9]` by the caller.
//! - Step 4: the pattern's error `E = 1/2 sum_n (d_n - y_n)^2` (eq. 2.1-5).
//! - Steps 5-6: `delta_n = (d_n - y_n) f'(net_n)`, `Delta w_mn = eta delta_n h_m`,
//!   `Delta v_km = eta (sum_n delta_n w_mn) f'(net_m) x_k` (eqs. 2.1-6, 2.1-7), both computed
//!   from the same forward pass and then applied (eq. 2.1-8). Biases are weights on a
//!   constant input 1.
//! - Step 7: one pass over the whole set is a learning cycle.
//! - Step 8: stop when the cycle's error `E` is below `E_max`, or after `max_cycles` cycles
//!   (the thesis gives no cap; without one a too-small `E_max` never ends). The thesis does not
//!   say how the per-pattern errors of a cycle combine into `E`; here `E` is their mean (each
//!   taken in Step 4, before that pattern's update), so `E_max` does not depend on the size of
//!   the training set.

// Index loops mirror the equations (several arrays indexed by the same unit numbers).
#![allow(clippy::needless_range_loop)]

use super::net::{forward, Problem};
use anyhow::{bail, Result};

/// The thesis' BP settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BpParams {
    /// Learning rate `eta` (the thesis: between 0.1 and 1.0).
    pub learning_rate: f64,
    /// Stop when a cycle's mean pattern error (eq. 2.1-5) falls below this.
    pub e_max: f64,
    /// Most learning cycles.
    pub max_cycles: usize,
}

impl Default for BpParams {
    /// `eta = 0.5` (mid-range of the thesis' 0.1-1.0); at most 20 000 cycles; `E_max = 1e-4`,
    /// below what the pixel rounding of the thesis' board sets allows (about 3e-4 with X, Y
    /// and Z outputs), so there the cycle cap ends training: stopping at a higher `E_max`
    /// leaves the nets less well fitted (worse test errors).
    fn default() -> Self {
        BpParams { learning_rate: 0.5, e_max: 1e-4, max_cycles: 20_000 }
    }
}

impl BpParams {
    /// Rejects settings the algorithm cannot run with.
    pub fn check(&self) -> Result<()> {
        if !(self.learning_rate.is_finite() && self.learning_rate > 0.0) {
            bail!(
                "the BP learning rate must be positive, got {}",
                crate::fmt::given(self.learning_rate)
            );
        }
        if !(self.e_max.is_finite() && self.e_max >= 0.0) {
            bail!(
                "the BP E_max must be a non-negative number, got {}",
                crate::fmt::given(self.e_max)
            );
        }
        if self.max_cycles == 0 {
            bail!("the BP learning-cycle cap must be at least 1");
        }
        Ok(())
    }
}

/// What a BP run did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct BpResult {
    /// Learning cycles run.
    pub cycles: usize,
    /// Error `E` (mean pattern error) of the last cycle.
    pub error: f64,
}

/// Presents one pattern (Steps 3-6) and updates `p`; returns the pattern's error (eq. 2.1-5)
/// before the update. `h`, `y`, `dy` are scratch of the hidden and output sizes.
pub(crate) fn step(
    prob: &Problem,
    p: &mut [f64],
    eta: f64,
    n: usize,
    scratch: &mut (Vec<f64>, Vec<f64>, Vec<f64>),
) -> f64 {
    let s = prob.shape;
    let (h, y, dy) = scratch;
    let x = &prob.x[n * s.ni..(n + 1) * s.ni];
    let d = &prob.t[n * s.no..(n + 1) * s.no];
    forward(&s, prob.output, p, x, h, y);
    let mut e = 0.0;
    for k in 0..s.no {
        let err = d[k] - y[k];
        e += 0.5 * err * err;
        dy[k] = err * y[k] * (1.0 - y[k]); // delta_mn of eq. 2.1-6 (f' of the sigmoid)
    }
    // Hidden deltas with the weights before this pattern's update (eq. 2.1-7).
    for j in 0..s.nh {
        let mut back = 0.0;
        for k in 0..s.no {
            back += dy[k] * p[s.w2(k, j)];
        }
        let dh = back * h[j] * (1.0 - h[j]);
        for (i, xi) in x.iter().enumerate() {
            p[s.w1(j, i)] += eta * dh * xi;
        }
        p[s.w1(j, s.ni)] += eta * dh;
    }
    for k in 0..s.no {
        for j in 0..s.nh {
            p[s.w2(k, j)] += eta * dy[k] * h[j];
        }
        p[s.w2(k, s.nh)] += eta * dy[k];
    }
    e
}

/// Runs learning cycles from `p` (updated in place) until Step 8 stops it.
pub(crate) fn fit(prob: &Problem, p: &mut [f64], params: &BpParams) -> BpResult {
    let s = prob.shape;
    let mut scratch = (vec![0.0; s.nh], vec![0.0; s.no], vec![0.0; s.no]);
    let mut result = BpResult { cycles: 0, error: f64::INFINITY };
    while result.cycles < params.max_cycles {
        let mut e = 0.0;
        for n in 0..prob.n {
            e += step(prob, p, params.learning_rate, n, &mut scratch);
        }
        result.cycles += 1;
        result.error = e / prob.n as f64;
        if !result.error.is_finite() || result.error < params.e_max {
            break;
        }
    }
    result
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::train::net::tests::{random_params, random_problem};
    use crate::train::net::Shape;
    use hvs_shared::runtime::mlp::Activation;

    fn sig(a: f64) -> f64 {
        1.0 / (1.0 + (-a).exp())
    }

    #[test]
    fn one_update_matches_the_hand_computation() {
        // 1 input, 1 hidden unit, 2 sigmoid outputs; layout [v, b1, w_1, b2_1, w_2, b2_2].
        let (v, b1, w1, c1, w2, c2) = (0.4, -0.2, 0.7, 0.1, -0.5, 0.3);
        let (x, d1, d2, eta) = (0.8, 0.9, 0.2, 0.5);
        let prob = Problem {
            shape: Shape::new(1, 1, 2, false),
            output: Activation::Sigmoid,
            n: 1,
            x: vec![x],
            t: vec![d1, d2],
            c: vec![1.0, 1.0],
        };
        let mut p = vec![v, b1, w1, c1, w2, c2];
        let mut scratch = (vec![0.0; 1], vec![0.0; 2], vec![0.0; 2]);
        let e = step(&prob, &mut p, eta, 0, &mut scratch);

        // By hand: h = f(0.4 * 0.8 - 0.2) = f(0.12), y_n = f(w_n h + b_n).
        let h = sig(0.12);
        let y1 = sig(0.7 * h + 0.1);
        let y2 = sig(-0.5 * h + 0.3);
        assert!((e - 0.5 * ((0.9 - y1).powi(2) + (0.2 - y2).powi(2))).abs() < 1e-15);
        let dl1 = (0.9 - y1) * y1 * (1.0 - y1);
        let dl2 = (0.2 - y2) * y2 * (1.0 - y2);
        let dh = (dl1 * 0.7 + dl2 * -0.5) * h * (1.0 - h);
        let want = [
            0.4 + 0.5 * dh * 0.8,
            -0.2 + 0.5 * dh,
            0.7 + 0.5 * dl1 * h,
            0.1 + 0.5 * dl1,
            -0.5 + 0.5 * dl2 * h,
            0.3 + 0.5 * dl2,
        ];
        for (q, (got, want)) in p.iter().zip(want).enumerate() {
            assert!((got - want).abs() < 1e-15, "p{q}: {got} vs {want}");
        }
        // The same numbers evaluated independently (Python, double precision) from the
        // printed equations.
        let reference = [
            0.408_538_119_063_289,
            -0.189_327_351_170_889,
            0.717_831_988_622_485,
            0.133_647_543_759_075,
            -0.520_447_269_492_414,
            0.261_417_629_319_701,
        ];
        for (q, (got, want)) in p.iter().zip(reference).enumerate() {
            assert!((got - want).abs() < 1e-14, "p{q}: {got} vs {want}");
        }
    }

    /// A random sigmoid-output problem of `n` patterns (seed `seeds[0]`) with every residual
    /// weight 1 (eq. 2.1-5 has none), and random parameters (seed `seeds[1]`).
    fn unit_weight_problem(shape: Shape, n: usize, seeds: [u64; 2]) -> (Problem, Vec<f64>) {
        let mut prob = random_problem(shape, Activation::Sigmoid, n, seeds[0]);
        prob.c.iter_mut().for_each(|c| *c = 1.0);
        (prob, random_params(&shape, seeds[1]))
    }

    #[test]
    fn is_steepest_descent_on_the_pattern_error() {
        // One pattern's update is exactly -eta * grad of its eq. 2.1-5 (both layers' deltas
        // come from the same forward pass), checked against the least-squares gradient.
        let (prob, p0) = unit_weight_problem(Shape::new(3, 4, 2, false), 1, [21, 2]);
        let mut grad = vec![0.0; p0.len()];
        prob.gradient(&p0, &mut grad);
        let mut p = p0.clone();
        let eta = 0.25;
        let mut scratch = (vec![0.0; 4], vec![0.0; 2], vec![0.0; 2]);
        step(&prob, &mut p, eta, 0, &mut scratch);
        for q in 0..p.len() {
            assert!(((p[q] - p0[q]) + eta * grad[q]).abs() < 1e-14);
        }
    }

    #[test]
    fn stops_at_e_max_or_the_cycle_cap_and_lowers_the_error() {
        let (prob, p0) = unit_weight_problem(Shape::new(2, 3, 1, false), 20, [5, 6]);
        let start = prob.cost(&p0);
        let run = |e_max: f64| {
            let mut p = p0.clone();
            let params = BpParams { learning_rate: 0.5, e_max, max_cycles: 300 };
            (fit(&prob, &mut p, &params), p)
        };
        let (capped, p) = run(0.0);
        assert_eq!(capped.cycles, 300);
        assert!(prob.cost(&p) < 0.5 * start);
        let (easy, _) = run(capped.error * 2.0);
        assert!(easy.cycles < 300 && easy.error < capped.error * 2.0);
    }

    #[test]
    fn rejects_bad_settings() {
        for bad in [
            BpParams { learning_rate: 0.0, ..BpParams::default() },
            BpParams { e_max: f64::NAN, ..BpParams::default() },
            BpParams { max_cycles: 0, ..BpParams::default() },
        ] {
            assert!(bad.check().is_err());
        }
        assert!(BpParams::default().check().is_ok());
    }
}
