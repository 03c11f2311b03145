//! The disparity interval a trained model allows for a left pixel, and the right window's
//! scale for two pinhole cameras.

use hvs_shared::sim::camera::Camera;

/// Steps of the disparity scan of [`model_disparity_interval`] (px).
pub const MODEL_SCAN_STEP_PX: f64 = 0.25;

/// Share of the training depth span allowed beyond either end by
/// [`model_disparity_interval`].
pub const MODEL_Z_MARGIN: f64 = 0.05;

/// The disparity interval a trained model allows for left pixel `(ul, vl)`: the candidate
/// right points on the epipolar line `line` (`a u + b v + c = 0` in the right image, e.g.
/// [`Fundamental::line_in_right`](crate::geometry::Fundamental::line_in_right)) at every disparity `d = ul - u_r` of `d_range` (the
/// training set's whole disparity range, px), [`MODEL_SCAN_STEP_PX`] apart, are fed to
/// `predict` (`[u_l, v_l, u_r, v_r]` to `[X, Y, Z]` cm, `None` when the model has no answer);
/// those whose `Z` lies inside the training depths `z_range` (cm), widened by
/// [`MODEL_Z_MARGIN`] of its span on each side, are kept. Returns the smallest and largest
/// kept disparity, each widened by one scan step and clipped to `d_range`, or `None` when
/// none is kept, an input is not finite or out of order, or the line is steeper than
/// 45 degrees (no `v` per `u`). The model is a closure so that this crate need not know the
/// model's format: the CLI passes `|x| blob.infer(&x)`.
pub fn model_disparity_interval(
    predict: impl Fn([f32; 4]) -> Option<[f32; 3]>,
    ul: f64,
    vl: f64,
    line: [f64; 3],
    z_range: [f64; 2],
    d_range: [f64; 2],
) -> Option<(f64, f64)> {
    let [a, b, c] = line;
    let finite = [ul, vl, a, b, c, z_range[0], z_range[1], d_range[0], d_range[1]]
        .iter()
        .all(|x| x.is_finite());
    if !finite || z_range[0] > z_range[1] || d_range[0] > d_range[1] || b.abs() < a.abs() {
        return None;
    }
    // At most 100 000 model calls per point.
    let n = ((d_range[1] - d_range[0]) / MODEL_SCAN_STEP_PX).ceil();
    if n > 100_000.0 {
        return None;
    }
    let n = n as usize;
    let margin = MODEL_Z_MARGIN * (z_range[1] - z_range[0]);
    let (z_lo, z_hi) = (z_range[0] - margin, z_range[1] + margin);
    let mut kept: Option<(f64, f64)> = None;
    for k in 0..=n {
        let d = (d_range[0] + k as f64 * MODEL_SCAN_STEP_PX).min(d_range[1]);
        let Some(z) = model_z_at(&predict, ul, vl, line, d) else { continue };
        if z >= z_lo && z <= z_hi {
            kept = Some(match kept {
                None => (d, d),
                Some((lo, hi)) => (lo.min(d), hi.max(d)),
            });
        }
    }
    kept.map(|(lo, hi)| {
        ((lo - MODEL_SCAN_STEP_PX).max(d_range[0]), (hi + MODEL_SCAN_STEP_PX).min(d_range[1]))
    })
}

/// The right pixel `[u_r, v_r]` that left column `ul` matches at disparity `d` (`ul - u_r`)
/// on the right line `line` (`a u + b v + c = 0`, `b` not zero): how the model's disparity
/// scans walk an epipolar line.
#[inline]
pub fn line_point(ul: f64, [a, b, c]: [f64; 3], d: f64) -> [f64; 2] {
    let ur = ul - d;
    [ur, -(a * ur + c) / b]
}

/// The model's `Z` of left pixel `(ul, vl)` matched at disparity `d` on the right line
/// `line` ([`line_point`]), `None` where the model has no answer.
#[inline]
fn model_z_at(
    predict: impl Fn([f32; 4]) -> Option<[f32; 3]>,
    ul: f64,
    vl: f64,
    line: [f64; 3],
    d: f64,
) -> Option<f64> {
    let [ur, vr] = line_point(ul, line, d);
    predict([ul as f32, vl as f32, ur as f32, vr as f32]).map(|p| f64::from(p[2]))
}

/// [`model_disparity_interval`] for a left pixel of an image pair `right_width` px wide: the
/// scan over `d_range` (the training set's disparities) first; when it keeps nothing, or
/// what it keeps reaches an end of `d_range` where the model still gives a depth inside the
/// training depths proper (not only their margin), a scan of every disparity whose right
/// point lies inside the right image (`u_r` from -0.5 to `right_width - 0.5`) as well, asking
/// the model only where `trusted` says it may answer (the inputs inside its training box: far
/// outside it a net's answers are extrapolation, and may put the training depths anywhere).
/// The training pixels of a board often cover the middle of the image only; toward the edges
/// of a verged pair, or of two cameras of unequal focal lengths, the same depths lie at
/// disparities tens of pixels outside those of the middle, which a search clipped to them
/// would never reach, and which a model trained on boards spread over the whole image knows.
/// Where the training disparities bracket the training depths (a rectified pair), the answer
/// is [`model_disparity_interval`]'s.
#[allow(clippy::too_many_arguments)]
pub fn model_disparity_interval_in_image(
    predict: impl Fn([f32; 4]) -> Option<[f32; 3]>,
    trusted: impl Fn([f32; 4]) -> bool,
    ul: f64,
    vl: f64,
    line: [f64; 3],
    z_range: [f64; 2],
    d_range: [f64; 2],
    right_width: u32,
) -> Option<(f64, f64)> {
    let first = model_disparity_interval(&predict, ul, vl, line, z_range, d_range);
    // Whether the model puts disparity `d` inside the training depths.
    let deep_inside = |d: f64| {
        model_z_at(&predict, ul, vl, line, d)
            .is_some_and(|z| (z_range[0]..=z_range[1]).contains(&z))
    };
    let clipped = match first {
        None => true,
        Some((lo, hi)) => {
            (lo <= d_range[0] && deep_inside(d_range[0]))
                || (hi >= d_range[1] && deep_inside(d_range[1]))
        }
    };
    if !clipped {
        return first;
    }
    let whole = [ul - f64::from(right_width) + 0.5, ul + 0.5];
    let asked = |x: [f32; 4]| if trusted(x) { predict(x) } else { None };
    match (first, model_disparity_interval(asked, ul, vl, line, z_range, whole)) {
        (Some((a, b)), Some((c, d))) => Some((a.min(c), b.max(d))),
        (first, wider) => wider.or(first),
    }
}

/// The right window's scale for two pinhole cameras: `[phi_u_right / phi_u_left,
/// phi_v_right / phi_v_left]` (for [`MatchParams::right_scale`](super::MatchParams::right_scale); exact for a fronto-parallel
/// patch with parallel axes, close enough with the thesis' small deflections).
pub fn pinhole_right_scale(left: &Camera, right: &Camera) -> [f64; 2] {
    [right.phi_u / left.phi_u, right.phi_v / left.phi_v]
}
