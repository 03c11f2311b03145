//! Triangulation with the *true* cameras: the accuracy floor.
//!
//! - [`midpoint`]: the middle of the shortest segment between the two viewing rays.
//! - [`optimal`]: the point that best explains the four pixel coordinates through the true
//!   cameras and lenses (least squares reprojection error, damped Gauss-Newton from the
//!   midpoint): the floor that no calibration-free method can beat on the same pixels.
//! - [`optimal_rig`] / [`midpoint_rig`]: the same for a thesis [`Rig`] at home (pinhole lenses).
//!
//! One solver serves the thesis rig, every head posture and every lens. Everything is `f64`
//! through `libm` (ground truth, not what the head computes).

use crate::runtime::traditional::TriError;
use crate::sim::camera::{LensCamera, Rig, StereoPixels, Vec3};

/// The two cameras of a thesis rig at home, as pinhole [`LensCamera`]s.
pub fn rig_cameras(rig: &Rig) -> [LensCamera; 2] {
    let half_width = f64::from(rig.width) / 2.0;
    [LensCamera::pinhole(rig.left(), half_width), LensCamera::pinhole(rig.right(), half_width)]
}

/// [`midpoint`] with the cameras of a thesis rig.
pub fn midpoint_rig(rig: &Rig, px: &StereoPixels) -> Result<Vec3, TriError> {
    midpoint(&rig_cameras(rig), px)
}

/// [`optimal`] with the cameras of a thesis rig: the floor of the thesis' experiments.
pub fn optimal_rig(rig: &Rig, px: &StereoPixels) -> Result<Vec3, TriError> {
    optimal(&rig_cameras(rig), px)
}

/// Midpoint of the shortest segment between the viewing rays of the pixels (lenses undone).
pub fn midpoint(cams: &[LensCamera; 2], px: &StereoPixels) -> Result<Vec3, TriError> {
    if !px.iter().all(|v| v.is_finite()) {
        return Err(TriError::NonFinite);
    }
    let (o1, d1) = cams[0].ray(px[0], px[1]).ok_or(TriError::Degenerate)?;
    let (o2, d2) = cams[1].ray(px[2], px[3]).ok_or(TriError::Degenerate)?;
    let w = sub(o1, o2);
    let (a, b, c) = (dot(d1, d1), dot(d1, d2), dot(d2, d2));
    let (d, e) = (dot(d1, w), dot(d2, w));
    let den = a * c - b * b;
    if den.is_nan() || den.abs() <= 1e-15 {
        return Err(TriError::Degenerate);
    }
    let s = (b * e - c * d) / den;
    let t = (a * e - b * d) / den;
    Ok([
        0.5 * (o1[0] + s * d1[0] + o2[0] + t * d2[0]),
        0.5 * (o1[1] + s * d1[1] + o2[1] + t * d2[1]),
        0.5 * (o1[2] + s * d1[2] + o2[2] + t * d2[2]),
    ])
}

/// Squared reprojection error of `p` and, if `jac` is given, the normal equations
/// `J^T J`, `J^T r` of the four residuals (lens included).
fn reprojection(
    cams: &[LensCamera; 2],
    px: &StereoPixels,
    p: &Vec3,
    mut jac: Option<(&mut [[f64; 3]; 3], &mut [f64; 3])>,
) -> Option<f64> {
    let mut sse = 0.0;
    for (k, lc) in cams.iter().enumerate() {
        let cam = &lc.camera;
        let c = cam.to_camera(p);
        if c[2].is_nan() || c[2] <= 1e-9 {
            return None;
        }
        let iz = 1.0 / c[2];
        let o = [cam.phi_u * c[0] * iz, cam.phi_v * c[1] * iz];
        // d o / d p (2x3).
        let r = &cam.rotation;
        let mut jo = [[0.0; 3]; 2];
        for (row, (phi, ci)) in [(cam.phi_u, 0usize), (cam.phi_v, 1usize)].into_iter().enumerate() {
            for m in 0..3 {
                jo[row][m] = phi * (r[ci][m] * c[2] - c[ci] * r[2][m]) * iz * iz;
            }
        }
        let hw2 = lc.half_width * lc.half_width;
        let s = (o[0] * o[0] + o[1] * o[1]) / hw2;
        let f = lc.distortion.factor(s);
        let df = lc.distortion.k1 + 2.0 * lc.distortion.k2 * s;
        let d = [o[0] * f, o[1] * f];
        let res = [d[0] + cam.u0 - px[2 * k], d[1] + cam.v0 - px[2 * k + 1]];
        sse += res[0] * res[0] + res[1] * res[1];
        if let Some((jtj, jtr)) = jac.as_mut() {
            // d d / d o = f I + (2 f' / hw^2) o o^T.
            let g = 2.0 * df / hw2;
            let dd =
                [[f + g * o[0] * o[0], g * o[0] * o[1]], [g * o[1] * o[0], f + g * o[1] * o[1]]];
            for row in 0..2 {
                let mut j = [0.0; 3];
                for (m, jm) in j.iter_mut().enumerate() {
                    *jm = dd[row][0] * jo[0][m] + dd[row][1] * jo[1][m];
                }
                for a in 0..3 {
                    jtr[a] += j[a] * res[row];
                    for b in 0..3 {
                        jtj[a][b] += j[a] * j[b];
                    }
                }
            }
        }
    }
    sse.is_finite().then_some(sse)
}

/// Optimal triangulation over two arbitrary cameras: the point minimising the squared
/// reprojection error of the four observed pixel coordinates through the true cameras and
/// lenses (damped Gauss-Newton from [`midpoint`]). With pinhole lenses and a thesis rig at
/// home this is the floor of the thesis' experiments ([`optimal_rig`]).
pub fn optimal(cams: &[LensCamera; 2], px: &StereoPixels) -> Result<Vec3, TriError> {
    let mut p = midpoint(cams, px)?;
    let mut cost = reprojection(cams, px, &p, None).ok_or(TriError::Degenerate)?;
    let mut lambda = 0.0;
    for _ in 0..100 {
        let mut jtj = [[0.0f64; 3]; 3];
        let mut jtr = [0.0f64; 3];
        reprojection(cams, px, &p, Some((&mut jtj, &mut jtr))).ok_or(TriError::Degenerate)?;
        let mut accepted = false;
        let mut dp = [0.0; 3];
        for _ in 0..30 {
            let mut a = jtj;
            for (q, row) in a.iter_mut().enumerate() {
                row[q] += lambda * jtj[q][q];
            }
            dp = solve3(&a, &[-jtr[0], -jtr[1], -jtr[2]]).ok_or(TriError::Degenerate)?;
            let trial = [p[0] + dp[0], p[1] + dp[1], p[2] + dp[2]];
            match reprojection(cams, px, &trial, None) {
                Some(c) if c <= cost => {
                    p = trial;
                    cost = c;
                    lambda *= 0.1;
                    accepted = true;
                    break;
                }
                _ => lambda = if lambda == 0.0 { 1e-6 } else { lambda * 10.0 },
            }
        }
        if !accepted || dp.iter().map(|v| v * v).sum::<f64>() < 1e-24 {
            break;
        }
    }
    if p.iter().all(|v| v.is_finite()) {
        Ok(p)
    } else {
        Err(TriError::Degenerate)
    }
}

/// Solves a 3x3 system by Cramer's rule (`None` when it is singular or not finite).
pub fn solve3(a: &[[f64; 3]; 3], b: &[f64; 3]) -> Option<[f64; 3]> {
    let det = |m: &[[f64; 3]; 3]| {
        m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
            - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
    };
    let d = det(a);
    if !d.is_finite() || d.abs() <= 1e-300 {
        return None;
    }
    let mut out = [0.0; 3];
    for (k, o) in out.iter_mut().enumerate() {
        let mut m = *a;
        for r in 0..3 {
            m[r][k] = b[r];
        }
        *o = det(&m) / d;
    }
    Some(out)
}

fn sub(a: Vec3, b: Vec3) -> Vec3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn dot(a: Vec3, b: Vec3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::runtime::traditional::{traditional_depth, traditional_xyz, Calibration};
    use crate::sim::presets;

    #[test]
    fn optimal_recovers_point_on_a_deflected_rig() {
        // Case IV: distinct focal lengths, verged, tilted and rolled.
        let rig = presets::CASE_4;
        let p = [-2.0, 1.5, 140.0];
        let px = rig.project(&p).unwrap();
        let q = optimal_rig(&rig, &px).unwrap();
        for k in 0..3 {
            assert!((q[k] - p[k]).abs() < 1e-6, "{q:?}");
        }
    }

    proptest::proptest! {
        #[test]
        fn project_then_triangulate_round_trips(
            x in -30.0f64..30.0, y in -20.0f64..20.0, z in 40.0f64..250.0,
        ) {
            for n in 1..=4 {
                let rig = presets::case(n).unwrap();
                let px = rig.project(&[x, y, z]).unwrap();
                let p = optimal_rig(&rig, &px).unwrap();
                proptest::prop_assert!((p[2] - z).abs() < 1e-6 * z, "case {} {:?}", n, p);
                let m = midpoint_rig(&rig, &px).unwrap();
                proptest::prop_assert!((m[2] - z).abs() < 1e-6 * z, "case {} {:?}", n, m);
            }
        }
    }

    #[test]
    fn traditional_xyz_inverts_parallel_projection() {
        let rig = Rig::parallel(300.0);
        let p = [4.0, -3.0, 80.0];
        let px = rig.project(&p).unwrap();
        let cal = Calibration { phi: 300.0, half_baseline: 5.25, u0: 320.0, v0: 240.0 };
        let q = traditional_xyz(&cal, &px.map(|v| v as f32)).unwrap();
        for k in 0..3 {
            assert!((q[k] as f64 - p[k]).abs() < 1e-3, "{q:?}");
        }
        assert_eq!(
            traditional_xyz(&cal, &[300.0, 240.0, 310.0, 240.0]),
            Err(TriError::NonPositiveDisparity)
        );
        assert_eq!(
            traditional_xyz(&cal, &[f32::NAN, 240.0, 310.0, 240.0]),
            Err(TriError::NonFinite)
        );
        let bad = Calibration { phi: 0.0, ..cal };
        assert_eq!(traditional_xyz(&bad, &[330.0, 240.0, 310.0, 240.0]), Err(TriError::NonFinite));
    }

    proptest::proptest! {
        #[test]
        fn traditional_round_trips_on_case_one(
            x in -30.0f64..30.0, y in -20.0f64..20.0, z in 40.0f64..250.0,
        ) {
            // Case I shape, unrounded: eq. 3.1-17 is exact when both Phi are equal.
            let rig = Rig::parallel(285.836);
            let px = rig.project(&[x, y, z]).unwrap();
            let zt = traditional_depth(285.836, 5.25, px[0], px[2]).unwrap();
            proptest::prop_assert!((zt - z).abs() < 1e-9 * z);
            let cal = Calibration { phi: 285.836, half_baseline: 5.25, u0: 320.0, v0: 240.0 };
            let q = traditional_xyz(&cal, &px.map(|v| v as f32)).unwrap();
            proptest::prop_assert!((q[2] as f64 - z).abs() < 1e-4 * z);
            proptest::prop_assert!((q[0] as f64 - x).abs() < 1e-3 + 1e-4 * z);
        }
    }
}
