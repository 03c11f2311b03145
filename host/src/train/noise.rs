//! How noisy the training pixels are, read off the data: the weight decay of the
//! inverse-depth family follows it.
//!
//! Each camera's pixels are fitted with a 3x4 projection matrix (normalised DLT,
//! `posture_study::fit_dlt`) from the training targets; the mean squared reprojection
//! residual per pixel coordinate estimates the pixel noise variance (rounding: about
//! 1/12 px^2; 0.05 px Gaussian noise: 0.0025 px^2; exact pixels: about 0). The decay is
//! [`DECAY_PER_PX2`] times it, within [[`MIN_DECAY`], [`super::WEIGHT_DECAY`]]: the
//! thesis family's fixed decay suits rounded pixels, and better pixels deserve a closer fit.

use crate::data::dataset::Dataset;
use crate::study::posture::fit_dlt;
use nalgebra::Vector4;

/// Decay per px^2 of estimated pixel noise variance: rounding (1/12 px^2) gets the thesis'
/// [`super::WEIGHT_DECAY`].
pub(crate) const DECAY_PER_PX2: f64 = 12.0 * super::WEIGHT_DECAY;
/// Smallest decay (exact pixels).
pub(crate) const MIN_DECAY: f64 = 1e-9;

/// Mean squared reprojection residual (px^2) of the per-camera DLT fits of a stereo set, or
/// `None` if the set has no four pixel columns or too few points for a fit.
pub(crate) fn pixel_noise_var(data: &Dataset) -> Option<f64> {
    if data.n_inputs != 4 || data.len() < 12 || !data.has_targets() {
        return None;
    }
    let mut sum = 0.0;
    for cam in 0..2 {
        let px: Vec<[f64; 2]> = (0..data.len())
            .map(|r| [data.row(r)[2 * cam], data.row(r)[2 * cam + 1]])
            .collect();
        let m = fit_dlt(&data.targets, &px).ok()?;
        for (p, x) in data.targets.iter().zip(&px) {
            let h = m * Vector4::new(p[0], p[1], p[2], 1.0);
            if h[2] == 0.0 {
                return None;
            }
            sum += (h[0] / h[2] - x[0]).powi(2) + (h[1] / h[2] - x[1]).powi(2);
        }
    }
    let v = sum / (4 * data.len()) as f64;
    v.is_finite().then_some(v)
}

/// The LM weight decay of the inverse-depth family on `data`.
pub(crate) fn decay(data: &Dataset) -> f64 {
    match pixel_noise_var(data) {
        Some(v) => (DECAY_PER_PX2 * v).clamp(MIN_DECAY, super::WEIGHT_DECAY),
        None => super::WEIGHT_DECAY,
    }
}
