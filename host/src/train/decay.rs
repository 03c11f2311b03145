//! How noisy the training pixels are, read off the data: the weight decay of the
//! inverse-depth family follows it.
//!
//! Each camera's pixels are fitted with a 3x4 projection matrix (normalised DLT,
//! `hvs_vision::geometry::fit_dlt`) from the training targets and a cubic in the image
//! coordinates for the lens (the two fitted in turn); the mean squared residual per pixel
//! coordinate over its degrees of freedom estimates the pixel noise variance (rounding:
//! about 1/12 px^2; 0.05 px Gaussian noise: 0.0025 px^2; exact pixels: about 0), and the
//! plain DLT residual over it says how far a lens bends the image beyond the noise
//! ([`PixelNoise::lens_excess`]: the net's hold shrinks by it, `super::lm_options`). Without the lens
//! cubic a barrel lens read as pixel noise and the decay held the net from learning it
//! (9x6 board, 0.01 px noise, k1 = -0.1: 1.70x the floor; with it 1.05x; the regime table
//! on the tuning seeds did not move). The decay is
//! [`DECAY_PER_PX2`] times it, within [[`MIN_DECAY`], [`super::WEIGHT_DECAY`]]: the
//! thesis family's fixed decay suits rounded pixels, and better pixels deserve a closer fit.

use crate::data::dataset::Dataset;
use hvs_vision::geometry::fit_dlt;
use nalgebra::Vector4;

/// Decay per px^2 of estimated pixel noise variance: rounding (1/12 px^2) gets the thesis'
/// [`super::WEIGHT_DECAY`].
pub(crate) const DECAY_PER_PX2: f64 = 12.0 * super::WEIGHT_DECAY;
/// Smallest decay (exact pixels).
pub(crate) const MIN_DECAY: f64 = 1e-9;

/// The pixel noise of a stereo set with ground truth, read off its residuals.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct PixelNoise {
    /// Noise variance (px^2 per pixel coordinate) with the lens terms taken out.
    pub var: f64,
    /// How far the pixels depart from two pinhole cameras beyond their noise: the plain DLT
    /// residual variance over [`PixelNoise::var`] (1 for pinhole cameras, large when a lens
    /// bends the image by more than the pixel noise).
    pub lens_excess: f64,
}

/// [`PixelNoise`] of a stereo set, or `None` if the set has no four pixel columns or too few
/// points for a fit.
pub(crate) fn pixel_noise(data: &Dataset) -> Option<PixelNoise> {
    residual_vars(data).map(|(var, plain)| PixelNoise {
        var,
        lens_excess: (plain / var.max(f64::MIN_POSITIVE)).max(1.0),
    })
}

/// Rounds of the DLT / lens-cubic alternation in [`residual_vars`].
const LENS_ROUNDS: usize = 6;

/// (noise variance with the lens terms taken out, plain DLT residual variance), px^2 per
/// coordinate, each over its degrees of freedom.
fn residual_vars(data: &Dataset) -> Option<(f64, f64)> {
    if data.n_inputs != 4 || data.len() < 12 || !data.has_targets() {
        return None;
    }
    let n = data.len();
    let mut sum = 0.0;
    let mut plain_sum = 0.0;
    let mut dof = 0usize;
    for cam in 0..2 {
        let px: Vec<[f64; 2]> =
            (0..n).map(|r| [data.row(r)[2 * cam], data.row(r)[2 * cam + 1]]).collect();
        // The DLT and the lens cubic, fitted in turn: the DLT to the pixels less the cubic,
        // the cubic to what the DLT leaves ([`LENS_ROUNDS`] rounds).
        let mut corrected = px.clone();
        let mut first_plain = None;
        let mut last = None;
        for _ in 0..LENS_ROUNDS {
            let m = fit_dlt(&data.targets, &corrected).ok()?;
            let mut proj = Vec::with_capacity(n);
            for p in &data.targets {
                let h = m * Vector4::new(p[0], p[1], p[2], 1.0);
                if h[2] == 0.0 {
                    return None;
                }
                proj.push([h[0] / h[2], h[1] / h[2]]);
            }
            first_plain.get_or_insert_with(|| {
                proj.iter()
                    .zip(&px)
                    .map(|(q, x)| (q[0] - x[0]).powi(2) + (q[1] - x[1]).powi(2))
                    .sum::<f64>()
            });
            let (s, used, corr) = smooth_residual(&proj, &px)?;
            for ((c, x), d) in corrected.iter_mut().zip(&px).zip(&corr) {
                *c = [x[0] - d[0], x[1] - d[1]];
            }
            last = Some((s, used));
        }
        let (s, used) = last?;
        sum += s;
        plain_sum += first_plain?;
        dof += used;
    }
    // Degrees of freedom: 2 cameras x 2 coordinates x n residuals, less the DLT's 11 per
    // camera and the lens terms fitted per coordinate.
    let free = (4 * n).checked_sub(22 + dof).filter(|f| *f > 0)?;
    let v = sum / free as f64;
    let plain = plain_sum / (4 * n - 22) as f64;
    (v.is_finite() && plain.is_finite()).then_some((v, plain))
}

/// Sum of squared residuals of `px` about `proj` (a camera's DLT projections) after a
/// least-squares cubic in the projected coordinates is taken out of each coordinate's
/// residual: a lens' radial distortion (`1 + k1 r^2 + ...`, cubic in the image coordinates
/// to first order) is a smooth map the net has to learn, not pixel noise. Returns the sum
/// and the number of fitted terms (both coordinates). Sets with fewer than 3 x the terms
/// keep the plain residual (no terms).
fn smooth_residual(proj: &[[f64; 2]], px: &[[f64; 2]]) -> Option<(f64, usize, Vec<[f64; 2]>)> {
    const TERMS: usize = 10;
    let n = proj.len();
    let plain = || -> f64 {
        proj.iter().zip(px).map(|(q, x)| (q[0] - x[0]).powi(2) + (q[1] - x[1]).powi(2)).sum()
    };
    if n < 3 * TERMS {
        return Some((plain(), 0, vec![[0.0; 2]; n]));
    }
    // Coordinates centred and scaled to unit spread, for a well-conditioned fit.
    let mean: [f64; 2] =
        core::array::from_fn(|k| proj.iter().map(|q| q[k]).sum::<f64>() / n as f64);
    let spread: [f64; 2] = core::array::from_fn(|k| {
        let v = proj.iter().map(|q| (q[k] - mean[k]).powi(2)).sum::<f64>() / n as f64;
        v.sqrt().max(1e-12)
    });
    let a = nalgebra::DMatrix::from_fn(n, TERMS, |r, c| {
        let x = (proj[r][0] - mean[0]) / spread[0];
        let y = (proj[r][1] - mean[1]) / spread[1];
        const POWERS: [(i32, i32); TERMS] =
            [(0, 0), (1, 0), (0, 1), (2, 0), (1, 1), (0, 2), (3, 0), (2, 1), (1, 2), (0, 3)];
        let (i, j) = POWERS[c];
        x.powi(i) * y.powi(j)
    });
    let svd = a.clone().svd(true, true);
    let mut sum = 0.0;
    let mut corr = vec![[0.0; 2]; n];
    for k in 0..2 {
        let b = nalgebra::DVector::from_fn(n, |r, _| px[r][k] - proj[r][k]);
        let coef = svd.solve(&b, 1e-10).ok()?;
        let fit = &a * coef;
        for (c, f) in corr.iter_mut().zip(fit.iter()) {
            c[k] = *f;
        }
        sum += (&b - &fit).norm_squared();
    }
    sum.is_finite().then_some((sum, 2 * TERMS, corr))
}

/// The LM weight decay of the inverse-depth family for a set with this [`pixel_noise`]
/// (`None`: the thesis' decay).
pub(crate) fn decay(noise: Option<&PixelNoise>) -> f64 {
    match noise {
        Some(n) => (DECAY_PER_PX2 * n.var).clamp(MIN_DECAY, super::WEIGHT_DECAY),
        None => super::WEIGHT_DECAY,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::board::{Pixels, TrainingBoard};
    use crate::sim::posture::simulate;
    use crate::sim::sets::{SetKind, SimOptions};
    use hvs_shared::runtime::blob::InputKind;
    use hvs_shared::runtime::gaze::Joints;
    use hvs_shared::sim::camera::Distortion;
    use hvs_shared::sim::posture::HeadRig;
    use hvs_shared::sim::presets;

    /// The 9x6 board at 6 cm through case IV with 0.01 px Gaussian noise, unrounded, through
    /// lenses with radial distortion `k1`.
    fn board_set(k1: f64) -> Dataset {
        let head =
            HeadRig::new(presets::case(4).unwrap()).with_distortion(Distortion { k1, k2: 0.0 });
        let opt = SimOptions {
            board: TrainingBoard::parse("9x6:6").unwrap(),
            pixels: Pixels::Exact,
            noise_px: 0.01,
            seed: 5,
            ..SimOptions::default()
        };
        let mut d = Dataset::new(InputKind::Stereo);
        for s in simulate(&head, SetKind::Train, &[Joints::HOME], &opt).unwrap() {
            d.push(&s.px, Some(s.xyz));
        }
        d
    }

    #[test]
    fn the_noise_estimate_sees_through_a_lens_and_the_excess_sees_the_lens() {
        for k1 in [0.0, -0.1] {
            let d = board_set(k1);
            let PixelNoise { var: v, lens_excess: e } = pixel_noise(&d).unwrap();
            // The true variance is 1e-4 px^2 with or without the lens.
            assert!((0.5e-4..2e-4).contains(&v), "k1 {k1}: noise variance {v}");
            if k1 == 0.0 {
                assert!(e < 1.5, "pinhole: excess {e}");
            } else {
                assert!(e > 10.0, "barrel: excess {e}");
            }
        }
    }
}
