//! The geometry a model carries for the run-time matcher (`hvs locate`), fitted to its
//! training pixels: the fundamental matrix, the training box and disparities, the right
//! image's scale.

use crate::data::dataset::Dataset;
use hvs_shared::runtime::blob::MatcherGeometry;

/// Why a model has no matcher geometry, and what to do: the tail of every message that needs
/// one (the image commands, `hvs train --from`).
pub const NO_MATCHER_WHY: &str = "its training set could not give one (fewer than 8 rows, \
    joint columns, or no fundamental matrix fits its pixels, e.g. all on one board plane or \
    one pixel far off the others), or it was written before blob format v2: retrain it with \
    `hvs train` on board points seen at one head posture, at two or more depths";

/// What the run-time matcher (`hvs locate`) needs, learned from a training set's pixels alone:
/// one fundamental matrix fitted to the training correspondences (normalised 8-point, then
/// Levenberg-Marquardt on the Sampson error) and the box of the training targets (the depth
/// range the matcher searches). `None` for a set that cannot give one: fewer than 8 rows, no
/// targets, joint inputs (the epipolar geometry moves with the eyes), or a degenerate fit.
pub fn matcher_geometry(data: &Dataset) -> Option<MatcherGeometry> {
    if data.n_inputs != 4 || !data.has_targets() || data.len() < 8 {
        return None;
    }
    let pairs: Vec<([f64; 2], [f64; 2])> = (0..data.len())
        .map(|i| {
            let r = data.row(i);
            ([r[0], r[1]], [r[2], r[3]])
        })
        .collect();
    let f = hvs_vision::geometry::fit_fundamental(&pairs).ok()?;
    let mut out_min = [f32::INFINITY; 3];
    let mut out_max = [f32::NEG_INFINITY; 3];
    for t in &data.targets {
        for k in 0..3 {
            out_min[k] = out_min[k].min(t[k] as f32);
            out_max[k] = out_max[k].max(t[k] as f32);
        }
    }
    let mut disparity = [f32::INFINITY, f32::NEG_INFINITY];
    for (l, r) in &pairs {
        let d = (l[0] - r[0]) as f32;
        disparity = [disparity[0].min(d), disparity[1].max(d)];
    }
    let g = MatcherGeometry {
        fundamental: {
            let big = f.m.iter().flatten().fold(0.0f64, |a, v| a.max(v.abs()));
            f.m.map(|r| r.map(|v| (v / big) as f32))
        },
        out_min,
        out_max,
        disparity,
        right_scale: right_scale(data)?,
    };
    g.is_valid().then_some(g)
}

/// How much larger the right image shows a patch than the left one, per axis: the ratio of
/// the two cameras' image scales, read off the training set. Each camera's `u` is fitted as
/// `a X/Z + b / Z + c` (and `v` with `Y/Z`) by least squares over the training points;
/// `[a_right / a_left]` per axis is the scale (1 for equal focal lengths).
fn right_scale(data: &Dataset) -> Option<[f32; 2]> {
    let fit = |col: usize, along: usize| -> Option<f64> {
        let mut ata = nalgebra::Matrix3::<f64>::zeros();
        let mut atb = nalgebra::Vector3::<f64>::zeros();
        for (i, t) in data.targets.iter().enumerate() {
            let a = nalgebra::Vector3::new(t[along] / t[2], 1.0 / t[2], 1.0);
            ata += a * a.transpose();
            atb += a * data.row(i)[col];
        }
        let x = ata.cholesky()?.solve(&atb);
        x[0].is_finite().then_some(x[0])
    };
    let su = fit(2, 0)? / fit(0, 0)?;
    let sv = fit(3, 1)? / fit(1, 1)?;
    let ok = |s: f64| s.is_finite() && (0.25..=4.0).contains(&s);
    (ok(su) && ok(sv)).then_some([su as f32, sv as f32])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::sets::{simulate, SetKind, SimOptions};
    use hvs_shared::sim::presets;

    #[test]
    fn matcher_geometry_is_the_rigs_epipolar_geometry() {
        let rig = presets::CASE_2;
        let opt = SimOptions { points: 300, noise_px: 0.0, seed: 5, ..SimOptions::default() };
        let mut d = Dataset::new(hvs_shared::runtime::blob::InputKind::Stereo);
        for s in simulate(&rig, SetKind::Volume, &opt).unwrap() {
            d.push(&s.px, Some(s.xyz));
        }
        let g = matcher_geometry(&d).unwrap();
        assert!(g.out_min[2] >= 65.0 && g.out_max[2] <= 165.0 && g.out_min[2] < g.out_max[2]);
        // Case II's right camera has the longer focal length: the right image is larger.
        let want = [rig.phi_u_right / rig.phi_u_left, rig.phi_v_right / rig.phi_v_left];
        for (got, want) in g.right_scale.iter().zip(want) {
            let got = f64::from(*got);
            assert!((got / want - 1.0).abs() < 0.01, "{got} vs {want}");
        }
        assert!(g.disparity[0] > 0.0 && g.disparity[0] < g.disparity[1]);
        // Points the fit never saw lie on their epipolar lines (rounded pixels: within ~1 px).
        let f = crate::vision::model_fundamental(&g);
        let test = simulate(&rig, SetKind::Test, &SimOptions::default()).unwrap();
        for s in &test {
            let d = f.distance_in_right([s.px[0], s.px[1]], [s.px[2], s.px[3]]);
            assert!(d < 1.5, "{d} px");
        }
        // No geometry from too few rows or without targets.
        let mut few = Dataset::new(hvs_shared::runtime::blob::InputKind::Stereo);
        for i in 0..7 {
            let r = d.row(i).to_vec();
            few.push(&r, Some(d.targets[i]));
        }
        assert!(matcher_geometry(&few).is_none());
    }
}
