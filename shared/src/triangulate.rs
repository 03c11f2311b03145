//! Depth from matched pixels without a network.
//!
//! - [`traditional_depth`]: eq. 3.1-17, `Z = Phi 2d / u_sd`, for parallel cameras with equal
//!   focal lengths; [`traditional_xyz`] adds X and Y the same way (this is the firmware's
//!   fallback when no valid model is on flash).
//! - [`general_depth`]: eq. 3.1-16, `Z = (Phi_L X_L - Phi_R X_R) / u_sd`.
//! - [`phi_estimate`]: eq. 4.1-3, `Phi = mean(u_sd Z / 2d)` over board points at a known depth.
//! - [`optimal`]: the point that best explains the pixels given the *true* rig (least squares
//!   reprojection error, Gauss-Newton from the rays' midpoint): the accuracy floor that no
//!   calibration-free method can beat on rounded pixels.

use crate::camera::{Rig, Vec3};
use serde::{Deserialize, Serialize};

/// Why a triangulation has no answer.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum TriError {
    /// Disparity `u_l - u_r` is zero or negative: the point would be at infinity or behind.
    NonPositiveDisparity,
    /// An input or a calibration value is NaN or infinite, or a calibration value is not positive.
    NonFinite,
    /// No samples were given.
    Empty,
    /// The rays are parallel or the solver diverged.
    Degenerate,
}

impl core::fmt::Display for TriError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            TriError::NonPositiveDisparity => "zero or negative disparity",
            TriError::NonFinite => "non-finite input or invalid calibration",
            TriError::Empty => "no samples",
            TriError::Degenerate => "degenerate geometry",
        })
    }
}

/// The traditional method's calibration: one `Phi = k_u f` for both cameras and the half
/// baseline, plus the principal point. Stored in the weights blob as the fallback.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Calibration {
    /// `Phi = k_u f` (px).
    pub phi: f32,
    /// Half baseline `d` (cm).
    pub half_baseline: f32,
    /// Principal point u (px).
    pub u0: f32,
    /// Principal point v (px).
    pub v0: f32,
}

impl Calibration {
    /// Phi of case I estimated by eq. 4.1-3 at Z = 65 cm (`cases.json`), the thesis' HVS with
    /// its 640x480 images: the firmware's built-in calibration when no valid model is on flash.
    pub const BUILT_IN: Calibration = Calibration {
        phi: 284.761_9,
        half_baseline: 5.25,
        u0: 320.0,
        v0: 240.0,
    };

    /// Whether every value is finite and `phi`, `half_baseline` are positive.
    pub fn is_valid(&self) -> bool {
        self.phi.is_finite()
            && self.phi > 0.0
            && self.half_baseline.is_finite()
            && self.half_baseline > 0.0
            && self.u0.is_finite()
            && self.v0.is_finite()
    }
}

/// Eq. 3.1-17: `Z = Phi * 2d / (u_l - u_r)`.
pub fn traditional_depth(
    phi: f64,
    half_baseline: f64,
    u_l: f64,
    u_r: f64,
) -> Result<f64, TriError> {
    if !(phi.is_finite() && half_baseline.is_finite() && u_l.is_finite() && u_r.is_finite()) {
        return Err(TriError::NonFinite);
    }
    let u_sd = u_l - u_r;
    if u_sd <= 0.0 {
        return Err(TriError::NonPositiveDisparity);
    }
    Ok(phi * 2.0 * half_baseline / u_sd)
}

/// Eq. 3.1-17 evaluated as printed, whatever the sign of the disparity: a negative disparity
/// gives a negative depth. This is how the thesis plots the traditional method's error
/// (Figs. 4.8-4.11); the head's fallback ([`traditional_xyz`]) refuses such pixels instead.
pub fn traditional_depth_signed(
    phi: f64,
    half_baseline: f64,
    u_l: f64,
    u_r: f64,
) -> Result<f64, TriError> {
    if !(phi.is_finite() && half_baseline.is_finite() && u_l.is_finite() && u_r.is_finite()) {
        return Err(TriError::NonFinite);
    }
    let u_sd = u_l - u_r;
    if u_sd == 0.0 {
        return Err(TriError::NonPositiveDisparity);
    }
    Ok(phi * 2.0 * half_baseline / u_sd)
}

/// Eq. 3.1-16: `Z = (Phi_L X_L - Phi_R X_R) / u_sd`, with `X_L`, `X_R` the point's X in the
/// left and right camera frames.
pub fn general_depth(
    phi_l: f64,
    phi_r: f64,
    x_l: f64,
    x_r: f64,
    u_sd: f64,
) -> Result<f64, TriError> {
    if ![phi_l, phi_r, x_l, x_r, u_sd].iter().all(|v| v.is_finite()) {
        return Err(TriError::NonFinite);
    }
    if u_sd <= 0.0 {
        return Err(TriError::NonPositiveDisparity);
    }
    Ok((phi_l * x_l - phi_r * x_r) / u_sd)
}

/// Eq. 4.1-3: `Phi = (1/n) sum (u_sd)_i Z / 2d` over `(u_l, u_r)` pixel pairs of board points
/// at the known depth `z` (the board symmetric about the centre line).
pub fn phi_estimate(pairs: &[(f64, f64)], z: f64, half_baseline: f64) -> Result<f64, TriError> {
    if pairs.is_empty() {
        return Err(TriError::Empty);
    }
    if !(z.is_finite() && half_baseline.is_finite() && half_baseline > 0.0) {
        return Err(TriError::NonFinite);
    }
    let mut sum = 0.0;
    for &(u_l, u_r) in pairs {
        if !(u_l.is_finite() && u_r.is_finite()) {
            return Err(TriError::NonFinite);
        }
        sum += (u_l - u_r) * z / (2.0 * half_baseline);
    }
    let phi = sum / pairs.len() as f64;
    if phi <= 0.0 {
        return Err(TriError::NonPositiveDisparity);
    }
    Ok(phi)
}

/// The traditional method in f32 for all three coordinates (the firmware's fallback):
/// `Z` by eq. 3.1-17, then `X = Z ((u_l-u0) + (u_r-u0)) / 2 Phi` and
/// `Y = Z ((v_l-v0) + (v_r-v0)) / 2 Phi` (the same similar triangles, averaged over both eyes).
pub fn traditional_xyz(cal: &Calibration, px: &[f32; 4]) -> Result<[f32; 3], TriError> {
    if !cal.is_valid() || !px.iter().all(|v| v.is_finite()) {
        return Err(TriError::NonFinite);
    }
    let u_sd = px[0] - px[2];
    if u_sd <= 0.0 {
        return Err(TriError::NonPositiveDisparity);
    }
    let z = cal.phi * 2.0 * cal.half_baseline / u_sd;
    let x = z * ((px[0] - cal.u0) + (px[2] - cal.u0)) / (2.0 * cal.phi);
    let y = z * ((px[1] - cal.v0) + (px[3] - cal.v0)) / (2.0 * cal.phi);
    let out = [x, y, z];
    if out.iter().all(|v| v.is_finite()) {
        Ok(out)
    } else {
        Err(TriError::NonFinite)
    }
}

/// Midpoint of the shortest segment between the two viewing rays of the pixels.
pub fn midpoint(rig: &Rig, px: &[f64; 4]) -> Result<Vec3, TriError> {
    if !px.iter().all(|v| v.is_finite()) {
        return Err(TriError::NonFinite);
    }
    let (o1, d1) = rig.left().ray(px[0], px[1]);
    let (o2, d2) = rig.right().ray(px[2], px[3]);
    let w = [o1[0] - o2[0], o1[1] - o2[1], o1[2] - o2[2]];
    let dot = |a: &Vec3, b: &Vec3| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let (a, b, c) = (dot(&d1, &d1), dot(&d1, &d2), dot(&d2, &d2));
    let (d, e) = (dot(&d1, &w), dot(&d2, &w));
    let den = a * c - b * b;
    if den.is_nan() || den.abs() <= 1e-15 {
        return Err(TriError::Degenerate);
    }
    let s = (b * e - c * d) / den;
    let t = (a * e - b * d) / den;
    let p1 = [o1[0] + s * d1[0], o1[1] + s * d1[1], o1[2] + s * d1[2]];
    let p2 = [o2[0] + t * d2[0], o2[1] + t * d2[1], o2[2] + t * d2[2]];
    Ok([
        (p1[0] + p2[0]) / 2.0,
        (p1[1] + p2[1]) / 2.0,
        (p1[2] + p2[2]) / 2.0,
    ])
}

/// Optimal triangulation with the true rig: the point minimising the squared reprojection
/// error of the four pixel coordinates (Gauss-Newton from [`midpoint`]).
pub fn optimal(rig: &Rig, px: &[f64; 4]) -> Result<Vec3, TriError> {
    let mut p = midpoint(rig, px)?;
    let cams = [rig.left(), rig.right()];
    for _ in 0..20 {
        // Normal equations J^T J dp = -J^T r, 4 residuals, 3 unknowns.
        let mut jtj = [[0.0f64; 3]; 3];
        let mut jtr = [0.0f64; 3];
        for (k, cam) in cams.iter().enumerate() {
            let c = cam.to_camera(&p);
            if c[2].is_nan() || c[2] <= 1e-9 {
                return Err(TriError::Degenerate);
            }
            let r = &cam.rotation;
            let iz = 1.0 / c[2];
            let res = [
                cam.phi_u * c[0] * iz + cam.u0 - px[2 * k],
                cam.phi_v * c[1] * iz + cam.v0 - px[2 * k + 1],
            ];
            for (row, (phi, ci)) in [(cam.phi_u, 0usize), (cam.phi_v, 1usize)]
                .iter()
                .enumerate()
            {
                let mut j = [0.0; 3];
                for (m, jm) in j.iter_mut().enumerate() {
                    *jm = phi * (r[*ci][m] * c[2] - c[*ci] * r[2][m]) * iz * iz;
                }
                for a in 0..3 {
                    jtr[a] += j[a] * res[row];
                    for b in 0..3 {
                        jtj[a][b] += j[a] * j[b];
                    }
                }
            }
        }
        let dp = solve3(&jtj, &[-jtr[0], -jtr[1], -jtr[2]]).ok_or(TriError::Degenerate)?;
        p = [p[0] + dp[0], p[1] + dp[1], p[2] + dp[2]];
        if dp.iter().map(|v| v * v).sum::<f64>() < 1e-24 {
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
pub(crate) fn solve3(a: &[[f64; 3]; 3], b: &[f64; 3]) -> Option<[f64; 3]> {
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn traditional_by_hand() {
        // Phi = 300, 2d = 10.5, disparity 31.5 -> Z = 100.
        assert_eq!(traditional_depth(300.0, 5.25, 335.75, 304.25), Ok(100.0));
        assert_eq!(
            traditional_depth(300.0, 5.25, 300.0, 300.0),
            Err(TriError::NonPositiveDisparity)
        );
        assert_eq!(
            traditional_depth(300.0, 5.25, 299.0, 300.0),
            Err(TriError::NonPositiveDisparity)
        );
        assert_eq!(
            traditional_depth(f64::NAN, 5.25, 310.0, 300.0),
            Err(TriError::NonFinite)
        );
    }

    #[test]
    fn signed_traditional_keeps_negative_disparities() {
        assert_eq!(
            traditional_depth_signed(300.0, 5.25, 335.75, 304.25),
            Ok(100.0)
        );
        assert_eq!(
            traditional_depth_signed(300.0, 5.25, 304.25, 335.75),
            Ok(-100.0)
        );
        assert_eq!(
            traditional_depth_signed(300.0, 5.25, 300.0, 300.0),
            Err(TriError::NonPositiveDisparity)
        );
        assert_eq!(
            traditional_depth_signed(300.0, f64::INFINITY, 310.0, 300.0),
            Err(TriError::NonFinite)
        );
    }

    #[test]
    fn general_reduces_to_traditional_when_phis_equal() {
        // X_L - X_R = 2d.
        let z = general_depth(300.0, 300.0, 7.25, -3.25, 31.5).unwrap();
        assert!((z - 100.0).abs() < 1e-12);
        assert_eq!(
            general_depth(300.0, 300.0, 7.25, -3.25, 0.0),
            Err(TriError::NonPositiveDisparity)
        );
    }

    #[test]
    fn phi_estimate_by_hand() {
        // Disparities 30 and 32 at Z = 105, 2d = 10.5 -> Phi = mean(300, 320) = 310.
        let phi = phi_estimate(&[(330.0, 300.0), (352.0, 320.0)], 105.0, 5.25).unwrap();
        assert!((phi - 310.0).abs() < 1e-12);
        assert_eq!(phi_estimate(&[], 105.0, 5.25), Err(TriError::Empty));
    }

    #[test]
    fn traditional_xyz_inverts_parallel_projection() {
        let rig = Rig::parallel(300.0);
        let p = [4.0, -3.0, 80.0];
        let px = rig.project(&p).unwrap();
        let cal = Calibration {
            phi: 300.0,
            half_baseline: 5.25,
            u0: 320.0,
            v0: 240.0,
        };
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
        assert_eq!(
            traditional_xyz(&bad, &[330.0, 240.0, 310.0, 240.0]),
            Err(TriError::NonFinite)
        );
    }

    #[test]
    fn optimal_recovers_point_on_a_deflected_rig() {
        let mut rig = Rig::parallel(285.8);
        rig.phi_u_right = 228.7;
        rig.phi_v_right = 228.7;
        rig.alpha_left = -0.0455;
        rig.alpha_right = 0.0455;
        rig.beta0 = 0.0087;
        rig.phi0 = 0.0087;
        let p = [-2.0, 1.5, 140.0];
        let px = rig.project(&p).unwrap();
        let q = optimal(&rig, &px).unwrap();
        for k in 0..3 {
            assert!((q[k] - p[k]).abs() < 1e-6, "{q:?}");
        }
    }

    proptest::proptest! {
        #[test]
        fn project_then_triangulate_round_trips_on_case_one(
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
            for n in 1..=4 {
                let rig = crate::presets::case(n).unwrap();
                let px = rig.project(&[x, y, z]).unwrap();
                let p = optimal(&rig, &px).unwrap();
                proptest::prop_assert!((p[2] - z).abs() < 1e-6 * z, "case {} {:?}", n, p);
            }
        }
    }
}
