//! The thesis' HVS camera model (eqs. 3.1-3 to 3.1-9).
//!
//! The stereo reference frame sits at the middle of the baseline, X to the right, Y along the
//! image v axis, Z forward. The left camera is at `(-d, 0, 0)` rotated by
//! `Omega(alpha_L, +beta0, +phi0)`, the right one at `(+d, 0, 0)` rotated by
//! `Omega(alpha_R, -beta0, -phi0)`. A point projects as `p_cam = Omega (p_s - t_cam)`,
//! `u = round(Phi_u X_cam / Z_cam) + u0`, `v = round(Phi_v Y_cam / Z_cam) + v0`, rounding half
//! away from zero. Lengths are centimetres, angles radians, `Phi = k f` in pixels.
//! Everything here is `f64`: the camera model is the simulator's ground truth.

use crate::runtime::gaze::HALF_BASELINE_CM;
use serde::{Deserialize, Serialize};

/// A 3-D point or vector.
pub type Vec3 = [f64; 3];
/// A 3x3 matrix, rows first.
pub type Mat3 = [[f64; 3]; 3];

/// Why a point has no image.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum CameraError {
    /// The point is at or behind the left camera's image plane (Z_cam <= 0).
    BehindLeft,
    /// The point is at or behind the right camera's image plane (Z_cam <= 0).
    BehindRight,
    /// A coordinate or rig parameter is NaN or infinite.
    NonFinite,
}

impl core::fmt::Display for CameraError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            CameraError::BehindLeft => "point is at or behind the left camera",
            CameraError::BehindRight => "point is at or behind the right camera",
            CameraError::NonFinite => "non-finite coordinate",
        })
    }
}

/// The Euler rotation `Omega(pan, tilt, roll)` of eq. 3.1-3, exactly as printed.
pub fn omega(alpha: f64, beta: f64, phi: f64) -> Mat3 {
    let (sa, ca) = (libm::sin(alpha), libm::cos(alpha));
    let (sb, cb) = (libm::sin(beta), libm::cos(beta));
    let (sp, cp) = (libm::sin(phi), libm::cos(phi));
    [
        [ca * cp, sa * sb * cp - cb * sp, sa * cb * cp + sb * sp],
        [ca * sp, sa * sb * sp + cb * cp, sa * cb * sp - sb * cp],
        [-sa, ca * sb, ca * cb],
    ]
}

/// `m * v`.
pub fn mat_vec(m: &Mat3, v: &Vec3) -> Vec3 {
    [
        m[0][0] * v[0] + m[0][1] * v[1] + m[0][2] * v[2],
        m[1][0] * v[0] + m[1][1] * v[1] + m[1][2] * v[2],
        m[2][0] * v[0] + m[2][1] * v[1] + m[2][2] * v[2],
    ]
}

/// `m^T * v` (the inverse rotation).
pub fn mat_t_vec(m: &Mat3, v: &Vec3) -> Vec3 {
    [
        m[0][0] * v[0] + m[1][0] * v[1] + m[2][0] * v[2],
        m[0][1] * v[0] + m[1][1] * v[1] + m[2][1] * v[2],
        m[0][2] * v[0] + m[1][2] * v[1] + m[2][2] * v[2],
    ]
}

/// One pinhole camera: pose in the stereo frame and intrinsics.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Camera {
    /// Camera centre in the stereo frame (cm).
    pub center: Vec3,
    /// World-to-camera rotation `Omega`.
    pub rotation: Mat3,
    /// `Phi_u = k_u f` (px).
    pub phi_u: f64,
    /// `Phi_v = k_v f` (px).
    pub phi_v: f64,
    /// Principal point u (px).
    pub u0: f64,
    /// Principal point v (px).
    pub v0: f64,
}

impl Camera {
    /// The point in this camera's frame, eq. 3.1-4 / 3.1-7.
    pub fn to_camera(&self, p: &Vec3) -> Vec3 {
        let rel = [p[0] - self.center[0], p[1] - self.center[1], p[2] - self.center[2]];
        mat_vec(&self.rotation, &rel)
    }

    /// Unrounded image coordinates `(u, v)`, or `None` when the point is at or behind the camera.
    pub fn project(&self, p: &Vec3) -> Option<[f64; 2]> {
        let c = self.to_camera(p);
        if c[2].is_nan() || c[2] <= 0.0 {
            return None;
        }
        Some([self.phi_u * c[0] / c[2] + self.u0, self.phi_v * c[1] / c[2] + self.v0])
    }

    /// Rounded image coordinates per eq. 3.1-6: `round(Phi X/Z) + u0`.
    pub fn project_rounded(&self, p: &Vec3) -> Option<[f64; 2]> {
        let c = self.to_camera(p);
        if c[2].is_nan() || c[2] <= 0.0 {
            return None;
        }
        Some([
            libm::round(self.phi_u * c[0] / c[2]) + self.u0,
            libm::round(self.phi_v * c[1] / c[2]) + self.v0,
        ])
    }

    /// The viewing ray of pixel `(u, v)`: origin (camera centre) and unit direction in the
    /// stereo frame.
    pub fn ray(&self, u: f64, v: f64) -> (Vec3, Vec3) {
        let d_cam = [(u - self.u0) / self.phi_u, (v - self.v0) / self.phi_v, 1.0];
        let d = mat_t_vec(&self.rotation, &d_cam);
        let n = libm::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
        (self.center, [d[0] / n, d[1] / n, d[2] / n])
    }
}

/// A stereo rig described as in `cases.json`: the thesis' parameters of the two cameras.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Rig {
    /// Half baseline `d` (cm).
    pub half_baseline: f64,
    /// `Phi_u` of the left camera (px).
    pub phi_u_left: f64,
    /// `Phi_u` of the right camera (px).
    pub phi_u_right: f64,
    /// `Phi_v` of the left camera (px).
    pub phi_v_left: f64,
    /// `Phi_v` of the right camera (px).
    pub phi_v_right: f64,
    /// Pan of the left camera `alpha_L` (rad).
    pub alpha_left: f64,
    /// Pan of the right camera `alpha_R` (rad).
    pub alpha_right: f64,
    /// Half tilt between the cameras `beta0` (rad): left `+beta0`, right `-beta0`.
    pub beta0: f64,
    /// Half roll between the cameras `phi0` (rad): left `+phi0`, right `-phi0`.
    pub phi0: f64,
    /// Principal point u (px), both cameras.
    pub u0: f64,
    /// Principal point v (px), both cameras.
    pub v0: f64,
    /// Image width (px).
    pub width: u32,
    /// Image height (px).
    pub height: u32,
}

/// Projections of one point in both cameras: `[u_l, v_l, u_r, v_r]`.
pub type StereoPixels = [f64; 4];

impl Rig {
    /// The thesis' parallel rig with equal focal lengths (case I shape).
    pub fn parallel(phi: f64) -> Rig {
        Rig {
            half_baseline: HALF_BASELINE_CM,
            phi_u_left: phi,
            phi_u_right: phi,
            phi_v_left: phi,
            phi_v_right: phi,
            alpha_left: 0.0,
            alpha_right: 0.0,
            beta0: 0.0,
            phi0: 0.0,
            u0: 320.0,
            v0: 240.0,
            width: 640,
            height: 480,
        }
    }

    /// The left camera at `(-d, 0, 0)`, `Omega(alpha_L, +beta0, +phi0)`.
    pub fn left(&self) -> Camera {
        Camera {
            center: [-self.half_baseline, 0.0, 0.0],
            rotation: omega(self.alpha_left, self.beta0, self.phi0),
            phi_u: self.phi_u_left,
            phi_v: self.phi_v_left,
            u0: self.u0,
            v0: self.v0,
        }
    }

    /// The right camera at `(+d, 0, 0)`, `Omega(alpha_R, -beta0, -phi0)`.
    pub fn right(&self) -> Camera {
        Camera {
            center: [self.half_baseline, 0.0, 0.0],
            rotation: omega(self.alpha_right, -self.beta0, -self.phi0),
            phi_u: self.phi_u_right,
            phi_v: self.phi_v_right,
            u0: self.u0,
            v0: self.v0,
        }
    }

    fn check(p: &Vec3) -> Result<(), CameraError> {
        if p.iter().all(|c| c.is_finite()) {
            Ok(())
        } else {
            Err(CameraError::NonFinite)
        }
    }

    /// Unrounded `[u_l, v_l, u_r, v_r]` of a point in the stereo frame.
    pub fn project(&self, p: &Vec3) -> Result<StereoPixels, CameraError> {
        Self::check(p)?;
        let l = self.left().project(p).ok_or(CameraError::BehindLeft)?;
        let r = self.right().project(p).ok_or(CameraError::BehindRight)?;
        finite4([l[0], l[1], r[0], r[1]])
    }

    /// Rounded `[u_l, v_l, u_r, v_r]` (eqs. 3.1-6 and 3.1-9), what a real camera reports.
    pub fn project_rounded(&self, p: &Vec3) -> Result<StereoPixels, CameraError> {
        Self::check(p)?;
        let l = self.left().project_rounded(p).ok_or(CameraError::BehindLeft)?;
        let r = self.right().project_rounded(p).ok_or(CameraError::BehindRight)?;
        finite4([l[0], l[1], r[0], r[1]])
    }

    /// Rounded `[u_l, v_l, u_r, v_r]` of a camera that sees the pixel coordinates disturbed by
    /// `noise` (px, added before the rounding): `u = round(Phi_u X/Z + n_u) + u0`. With zero
    /// noise this is exactly [`Rig::project_rounded`].
    pub fn project_rounded_noisy(
        &self,
        p: &Vec3,
        noise: &[f64; 4],
    ) -> Result<StereoPixels, CameraError> {
        Self::check(p)?;
        if !noise.iter().all(|n| n.is_finite()) {
            return Err(CameraError::NonFinite);
        }
        let mut out = [0.0; 4];
        for (k, (cam, behind)) in
            [(self.left(), CameraError::BehindLeft), (self.right(), CameraError::BehindRight)]
                .iter()
                .enumerate()
        {
            let c = cam.to_camera(p);
            if c[2].is_nan() || c[2] <= 0.0 {
                return Err(*behind);
            }
            out[2 * k] = libm::round(cam.phi_u * c[0] / c[2] + noise[2 * k]) + cam.u0;
            out[2 * k + 1] = libm::round(cam.phi_v * c[1] / c[2] + noise[2 * k + 1]) + cam.v0;
        }
        finite4(out)
    }

    /// Whether both projections of `px` fall inside the image.
    pub fn in_image(&self, px: &StereoPixels) -> bool {
        let (w, h) = (self.width as f64, self.height as f64);
        px[0] >= 0.0
            && px[0] < w
            && px[2] >= 0.0
            && px[2] < w
            && px[1] >= 0.0
            && px[1] < h
            && px[3] >= 0.0
            && px[3] < h
    }
}

pub(crate) fn finite4(px: StereoPixels) -> Result<StereoPixels, CameraError> {
    if px.iter().all(|c| c.is_finite()) {
        Ok(px)
    } else {
        Err(CameraError::NonFinite)
    }
}

/// Radial lens distortion `1 + k1 r^2 + k2 r^4`, `r` in units of the image half-width.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Distortion {
    /// `k1` (negative: barrel).
    pub k1: f64,
    /// `k2`.
    pub k2: f64,
}

impl Distortion {
    /// A perfect pinhole lens.
    pub const NONE: Distortion = Distortion { k1: 0.0, k2: 0.0 };

    /// True when both coefficients are zero (then projections are exactly the pinhole's).
    pub fn is_none(&self) -> bool {
        self.k1 == 0.0 && self.k2 == 0.0
    }

    /// Whether both coefficients are finite.
    pub fn is_finite(&self) -> bool {
        self.k1.is_finite() && self.k2.is_finite()
    }

    /// The radial factor `1 + k1 s + k2 s^2` at `s = r^2`.
    pub fn factor(&self, r2: f64) -> f64 {
        1.0 + self.k1 * r2 + self.k2 * r2 * r2
    }

    /// Distorted pixel offset (from the principal point) of the ideal offset `o`.
    pub fn apply(&self, o: [f64; 2], half_width: f64) -> [f64; 2] {
        if self.is_none() {
            return o;
        }
        let r2 = (o[0] * o[0] + o[1] * o[1]) / (half_width * half_width);
        let f = self.factor(r2);
        [o[0] * f, o[1] * f]
    }

    /// The ideal offset that the lens shows at offset `d` (Newton on the radius), or `None`
    /// where the distortion folds over (`d` lies beyond the largest radius the lens shows) or
    /// the iteration does not settle.
    pub fn undo(&self, d: [f64; 2], half_width: f64) -> Option<[f64; 2]> {
        if self.is_none() {
            return Some(d);
        }
        let rd = libm::sqrt(d[0] * d[0] + d[1] * d[1]) / half_width;
        if rd == 0.0 {
            return Some(d);
        }
        // Solve g(r) = r (1 + k1 r^2 + k2 r^4) - rd = 0 from r = rd.
        let mut r = rd;
        for _ in 0..50 {
            let r2 = r * r;
            let g = r * self.factor(r2) - rd;
            let dg = 1.0 + 3.0 * self.k1 * r2 + 5.0 * self.k2 * r2 * r2;
            if dg.is_nan() || dg <= 0.0 {
                return None;
            }
            let step = g / dg;
            r -= step;
            if r.is_nan() || r <= 0.0 {
                return None;
            }
            if libm::fabs(step) <= 1e-15 * r {
                let s = r / rd;
                return Some([d[0] * s, d[1] * s]);
            }
        }
        None
    }
}

/// A pinhole camera behind a radially distorting lens.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LensCamera {
    /// Pose and intrinsics.
    pub camera: Camera,
    /// The lens.
    pub distortion: Distortion,
    /// Half the image width (px): the distortion's unit radius.
    pub half_width: f64,
}

impl LensCamera {
    /// A camera without lens distortion.
    pub fn pinhole(camera: Camera, half_width: f64) -> LensCamera {
        LensCamera { camera, distortion: Distortion::NONE, half_width }
    }

    /// Pixel offset from the principal point the lens shows for camera-frame point `c`, or
    /// `None` at or behind the image plane.
    fn offset(&self, c: &Vec3) -> Option<[f64; 2]> {
        if c[2].is_nan() || c[2] <= 0.0 {
            return None;
        }
        let o = [self.camera.phi_u * c[0] / c[2], self.camera.phi_v * c[1] / c[2]];
        Some(self.distortion.apply(o, self.half_width))
    }

    /// Unrounded image coordinates (lens included), or `None` at or behind the camera.
    pub fn project(&self, p: &Vec3) -> Option<[f64; 2]> {
        let o = self.offset(&self.camera.to_camera(p))?;
        Some([o[0] + self.camera.u0, o[1] + self.camera.v0])
    }

    /// What the camera reports: `round(offset + noise) + u0` (and `v`). With no distortion and
    /// no noise this is exactly [`Camera::project_rounded`].
    pub fn project_rounded_noisy(&self, p: &Vec3, noise: [f64; 2]) -> Option<[f64; 2]> {
        let o = self.offset(&self.camera.to_camera(p))?;
        if noise == [0.0, 0.0] {
            return Some([libm::round(o[0]) + self.camera.u0, libm::round(o[1]) + self.camera.v0]);
        }
        Some([
            libm::round(o[0] + noise[0]) + self.camera.u0,
            libm::round(o[1] + noise[1]) + self.camera.v0,
        ])
    }

    /// The viewing ray of an observed pixel (lens undone): origin and unit direction, or `None`
    /// where the lens cannot be undone.
    pub fn ray(&self, u: f64, v: f64) -> Option<(Vec3, Vec3)> {
        let o = self.distortion.undo([u - self.camera.u0, v - self.camera.v0], self.half_width)?;
        Some(self.camera.ray(o[0] + self.camera.u0, o[1] + self.camera.v0))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn omega_is_identity_at_zero_and_orthonormal() {
        let m = omega(0.0, 0.0, 0.0);
        assert_eq!(m, [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]);
        let m = omega(0.3, -0.2, 0.1);
        for i in 0..3 {
            for j in 0..3 {
                let dot: f64 = (0..3).map(|k| m[i][k] * m[j][k]).sum();
                let want = if i == j { 1.0 } else { 0.0 };
                assert!((dot - want).abs() < 1e-12, "row {i}.{j} = {dot}");
            }
        }
    }

    #[test]
    fn omega_matches_printed_entries() {
        // Hand-worked: alpha = 90 deg, beta = phi = 0 -> w13 = sin(a) = 1, w31 = -1.
        let m = omega(core::f64::consts::FRAC_PI_2, 0.0, 0.0);
        assert!((m[0][2] - 1.0).abs() < 1e-15);
        assert!((m[2][0] + 1.0).abs() < 1e-15);
        // phi = 90 deg: w21 = cos(a) sin(phi) = 1, w12 = -cos(b) sin(phi) = -1.
        let m = omega(0.0, 0.0, core::f64::consts::FRAC_PI_2);
        assert!((m[1][0] - 1.0).abs() < 1e-15);
        assert!((m[0][1] + 1.0).abs() < 1e-15);
    }

    #[test]
    fn parallel_projection_by_hand() {
        // Point (0, 0, 100) with d = 5.25, Phi = 300: u_l = 300*5.25/100 + 320 = 335.75.
        let rig = Rig::parallel(300.0);
        let px = rig.project(&[0.0, 0.0, 100.0]).unwrap();
        assert!((px[0] - 335.75).abs() < 1e-12);
        assert!((px[2] - 304.25).abs() < 1e-12);
        assert_eq!(px[1], 240.0);
        let r = rig.project_rounded(&[0.0, 0.0, 100.0]).unwrap();
        assert_eq!(r, [336.0, 240.0, 304.0, 240.0]);
    }

    #[test]
    fn rounding_is_half_away_from_zero() {
        // Phi * X / Z = 300 * 5.25 / 105 = 15 exactly -> 335; choose X so it is 2.5: X+d = 2.5*Z/Phi.
        let rig = Rig::parallel(100.0);
        // left: 100*(x+5.25)/z = 2.5 with z = 100 -> x = -2.75; right: 100*(x-5.25)/100 = -8.0
        let r = rig.project_rounded(&[-2.75, -2.5, 100.0]).unwrap();
        assert_eq!(r[0], 323.0);
        assert_eq!(r[1], 237.0); // -2.5 rounds to -3
    }

    #[test]
    fn points_behind_are_errors() {
        let rig = Rig::parallel(300.0);
        assert_eq!(rig.project(&[0.0, 0.0, 0.0]), Err(CameraError::BehindLeft));
        assert_eq!(rig.project(&[0.0, 0.0, -5.0]), Err(CameraError::BehindLeft));
        assert_eq!(rig.project(&[f64::NAN, 0.0, 50.0]), Err(CameraError::NonFinite));
        assert_eq!(rig.project_rounded(&[0.0, f64::INFINITY, 50.0]), Err(CameraError::NonFinite));
        // Right camera panned so the point is behind only it.
        let mut rig = Rig::parallel(300.0);
        rig.alpha_right = -1.6;
        assert_eq!(rig.project(&[0.0, 0.0, 10.0]), Err(CameraError::BehindRight));
    }

    #[test]
    fn ray_passes_through_the_point() {
        let mut rig = Rig::parallel(285.0);
        rig.alpha_left = -0.03;
        rig.beta0 = 0.01;
        rig.phi0 = 0.02;
        let p = [3.0, -2.0, 90.0];
        let px = rig.project(&p).unwrap();
        let (o, d) = rig.left().ray(px[0], px[1]);
        let t = (p[2] - o[2]) / d[2];
        for k in 0..3 {
            assert!((o[k] + t * d[k] - p[k]).abs() < 1e-9);
        }
    }
}
