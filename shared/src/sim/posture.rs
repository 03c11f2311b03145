//! The simulator's head postures and lenses: the thesis rig mounted on the five-axis head.
//!
//! # Frames and chain
//!
//! The **head frame** is the thesis' stereo frame at the home posture, fixed to the body (the
//! base frame of [`crate::runtime::gaze`]): origin at the middle of the baseline, `X` right, `Y` down,
//! `Z` forward, cm. A [`HeadRig`] places the two cameras of a thesis [`Rig`] on the head's
//! mechanism, with the kinematic chain of [`crate::runtime::gaze`] in `f64`:
//!
//! 1. neck pan, then neck tilt, about the neck centre [`HeadRig::neck_centre_cm`]: the whole
//!    head moves, both eye centres with it;
//! 2. the conjugate eye tilt about the baseline (through both eye centres);
//! 3. each eye's pan about its own vertical axis through its centre.
//!
//! The eye centres are the camera centres, at `(-d, 0, 0)` and `(+d, 0, 0)` of the moved head.
//! The case's fixed errors ride on top, in the eye: the left camera is rotated by
//! `Omega(alpha_L, +beta0, +phi0)` and the right one by `Omega(alpha_R, -beta0, -phi0)` with
//! respect to its eye, so a point maps to camera coordinates as
//! `p_cam = Omega_case A^T (p - c)` with `A = Pan(neck) Tilt(neck) Tilt(eye) Pan(eye pan)` the
//! eye's active rotation in the head frame and `c` its centre. At the home posture `A = I` and
//! `c = (-+d, 0, 0)`: exactly the thesis rig ([`Rig::left`], [`Rig::right`]), bit for bit.
//! Signs are those of [`crate::runtime::gaze`]: a positive pan turns the optic axis towards `-X`, a
//! positive tilt towards `+Y` (down).
//!
//! # Lenses
//!
//! [`Distortion`] is a radial (Brown) distortion of each camera, in pixel offsets from the
//! principal point normalised by the image half-width `w/2`: with `n = (u - u0, v - v0) / (w/2)`
//! of the ideal pinhole image and `r^2 = |n|^2`, the lens shows `u0 + (u - u0)(1 + k1 r^2 +
//! k2 r^4)` (and the same for `v`), which the camera then rounds to whole pixels. `k1 < 0` is
//! barrel distortion; at `k1 = -0.5` a point at the image's left or right edge appears half
//! way in.
//!
//! # Floor
//!
//! [`optimal`] is the least-reprojection-error point of two arbitrary [`LensCamera`]s (the
//! true cameras, lenses included): the accuracy floor at any posture.
//!
//! Everything is `f64` (this is ground truth, not what the head computes) through `libm`.

use crate::runtime::gaze::{Axis, Joints};
use crate::runtime::traditional::TriError;
use crate::sim::camera::{finite4, mat_vec, CameraError, Mat3, Rig, StereoPixels, Vec3};
use crate::sim::camera::{Distortion, LensCamera};
use crate::sim::triangulate::optimal;
use serde::{Deserialize, Serialize};

const DEG: f64 = core::f64::consts::PI / 180.0;

/// The active rotation of the eye `pan_deg` belongs to, in the head frame:
/// `Pan(neck) Tilt(neck) Tilt(eye) Pan(eye)`.
fn eye_in_head(j: &Joints, pan_deg: f32) -> Mat3 {
    let neck = neck_rotation(j);
    mat_mul(
        &neck,
        &mat_mul(&rot_tilt(f64::from(j[Axis::EyeTilt]) * DEG), &rot_pan(f64::from(pan_deg) * DEG)),
    )
}

/// The eye platform's active rotation in the head frame at neck pan, neck tilt and eye tilt
/// `angles_deg`: `Pan(neck) Tilt(neck) Tilt(eye)`, the `f64` twin of
/// [`crate::runtime::gaze::platform_to_base`].
pub fn platform_rotation(angles_deg: [f64; 3]) -> Mat3 {
    mat_mul(
        &mat_mul(&rot_pan(angles_deg[0] * DEG), &rot_tilt(angles_deg[1] * DEG)),
        &rot_tilt(angles_deg[2] * DEG),
    )
}

/// A head-frame point in the eye platform's frame: `R^T p`, `R` = [`platform_rotation`]
/// (what a posture-aware net of `OutputFrame::EyePlatform` learns).
pub fn base_to_platform(angles_deg: [f64; 3], p: &Vec3) -> Vec3 {
    let r = platform_rotation(angles_deg);
    core::array::from_fn(|k| r[0][k] * p[0] + r[1][k] * p[1] + r[2][k] * p[2])
}

/// A head-frame point in the cyclopean frame at the five joints `joints_deg` (degrees): the
/// eye platform's frame ([`base_to_platform`]) turned by the version, the mean of the eye
/// pans, about its vertical axis (`Pan(version)^T`); the `f64` twin of
/// [`crate::runtime::gaze::base_to_cyclopean`] (what a posture-aware net of
/// `OutputFrame::Cyclopean` learns). Its axes are those of [`gaze_frame`] (the simulator's
/// boards are placed in that frame); the model's frame keeps its origin at the baseline's
/// centre whatever the neck centre, as the eye platform's frame does.
pub fn base_to_cyclopean(joints_deg: [f64; 5], p: &Vec3) -> Vec3 {
    let q = base_to_platform([joints_deg[0], joints_deg[1], joints_deg[2]], p);
    let r = rot_pan(0.5 * (joints_deg[3] + joints_deg[4]) * DEG);
    core::array::from_fn(|k| r[0][k] * q[0] + r[1][k] * q[1] + r[2][k] * q[2])
}

/// The neck's active rotation `Pan(neck pan) Tilt(neck tilt)` of the head in the head frame.
pub fn neck_rotation(j: &Joints) -> Mat3 {
    mat_mul(
        &rot_pan(f64::from(j[Axis::NeckPan]) * DEG),
        &rot_tilt(f64::from(j[Axis::NeckTilt]) * DEG),
    )
}

/// Where a head point at `home` (cm) is after the neck rotated the head by `neck` about
/// `neck_centre`: `c + (N - I)(c - n)`, written so that `N = I` leaves `c` untouched bit for bit.
fn moved_centre(neck: &Mat3, neck_centre: Vec3, home: Vec3) -> Vec3 {
    let rel = sub(home, neck_centre);
    let moved = mat_vec(neck, &rel);
    [home[0] + (moved[0] - rel[0]), home[1] + (moved[1] - rel[1]), home[2] + (moved[2] - rel[2])]
}

/// The thesis rig on the five-axis head, with a lens on each camera.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HeadRig {
    /// The cameras' intrinsics, baseline and fixed deflections (a thesis case).
    pub rig: Rig,
    /// Where the neck pan and tilt axes cross, in the head frame (cm).
    pub neck_centre_cm: Vec3,
    /// Lens of the left and right camera.
    pub distortion: [Distortion; 2],
}

impl HeadRig {
    /// `rig` with the neck axes through the baseline centre (as [`crate::runtime::gaze::HeadGeometry::DEFAULT`])
    /// and pinhole lenses.
    pub fn new(rig: Rig) -> HeadRig {
        HeadRig { rig, neck_centre_cm: [0.0; 3], distortion: [Distortion::NONE; 2] }
    }

    /// The same head with the same lens `(k1, k2)` on both cameras.
    pub fn with_distortion(self, d: Distortion) -> HeadRig {
        HeadRig { distortion: [d; 2], ..self }
    }

    /// The left and right cameras at posture `joints` (degrees), in the head frame.
    pub fn cameras(&self, joints: &Joints) -> [LensCamera; 2] {
        let neck = neck_rotation(joints);
        let half_width = f64::from(self.rig.width) / 2.0;
        let mut out = [self.rig.left(), self.rig.right()];
        for (cam, pan) in out.iter_mut().zip([joints[Axis::LeftEyePan], joints[Axis::RightEyePan]])
        {
            let a = eye_in_head(joints, pan);
            // p_cam = Omega_case A^T (p - c).
            cam.rotation = mat_mul_bt(&cam.rotation, &a);
            cam.center = moved_centre(&neck, self.neck_centre_cm, cam.center);
        }
        [
            LensCamera { camera: out[0], distortion: self.distortion[0], half_width },
            LensCamera { camera: out[1], distortion: self.distortion[1], half_width },
        ]
    }

    /// Unrounded `[u_l, v_l, u_r, v_r]` of head-frame point `p` at `joints`.
    pub fn project(&self, joints: &Joints, p: &Vec3) -> Result<StereoPixels, CameraError> {
        check(p)?;
        let [l, r] = self.cameras(joints);
        let a = l.project(p).ok_or(CameraError::BehindLeft)?;
        let b = r.project(p).ok_or(CameraError::BehindRight)?;
        finite4([a[0], a[1], b[0], b[1]])
    }

    /// Rounded `[u_l, v_l, u_r, v_r]` at `joints`, with pixel `noise` added before rounding
    /// (zero noise: what a perfect camera reports; at [`Joints::HOME`] without lenses exactly
    /// [`Rig::project_rounded`]).
    pub fn project_rounded_noisy(
        &self,
        joints: &Joints,
        p: &Vec3,
        noise: &[f64; 4],
    ) -> Result<StereoPixels, CameraError> {
        check(p)?;
        if !noise.iter().all(|n| n.is_finite()) {
            return Err(CameraError::NonFinite);
        }
        let [l, r] = self.cameras(joints);
        let a = l.project_rounded_noisy(p, [noise[0], noise[1]]).ok_or(CameraError::BehindLeft)?;
        let b = r.project_rounded_noisy(p, [noise[2], noise[3]]).ok_or(CameraError::BehindRight)?;
        finite4([a[0], a[1], b[0], b[1]])
    }

    /// Rounded `[u_l, v_l, u_r, v_r]` at `joints`, no noise.
    pub fn project_rounded(&self, joints: &Joints, p: &Vec3) -> Result<StereoPixels, CameraError> {
        self.project_rounded_noisy(joints, p, &[0.0; 4])
    }

    /// The floor at `joints`: [`optimal`] with this head's true cameras.
    pub fn optimal(&self, joints: &Joints, px: &StereoPixels) -> Result<Vec3, TriError> {
        optimal(&self.cameras(joints), px)
    }
}

/// The joint angles of a posture given as neck pan and tilt, conjugate eye tilt, version (the
/// mean eye pan) and vergence (right pan minus left pan; positive when the eyes converge), all
/// in degrees.
pub fn joints_from_gaze(
    neck_pan: f32,
    neck_tilt: f32,
    eye_tilt: f32,
    version: f32,
    vergence: f32,
) -> Joints {
    Joints([neck_pan, neck_tilt, eye_tilt, version - 0.5 * vergence, version + 0.5 * vergence])
}

/// A box of postures in gaze terms (degrees): neck pan and tilt, conjugate eye tilt, version
/// and vergence (see [`joints_from_gaze`]). Postures drawn from it are quantised to the
/// drives' [`crate::runtime::gaze::STEP_DEG`] grid, the only angles the head's setpoints take.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PostureRange {
    /// Neck pan `[min, max]`.
    pub neck_pan: [f32; 2],
    /// Neck tilt `[min, max]`.
    pub neck_tilt: [f32; 2],
    /// Conjugate eye tilt `[min, max]`.
    pub eye_tilt: [f32; 2],
    /// Version (mean eye pan) `[min, max]`.
    pub version: [f32; 2],
    /// Vergence (right minus left eye pan) `[min, max]`.
    pub vergence: [f32; 2],
}

impl PostureRange {
    /// The working range of the posture-aware model: neck pan +-30, neck tilt +-20, eye tilt
    /// +-15, version +-15 and vergence 0-10 degrees (fixation from 60 cm to infinity with the
    /// thesis' 10.5 cm baseline), gaze up to 45 degrees sideways and 35 up or down. Inside
    /// [`crate::runtime::gaze::JointLimits::DEFAULT`].
    pub const WORKING: PostureRange = PostureRange {
        neck_pan: [-30.0, 30.0],
        neck_tilt: [-20.0, 20.0],
        eye_tilt: [-15.0, 15.0],
        version: [-15.0, 15.0],
        vergence: [0.0, 10.0],
    };

    /// Only the home posture.
    pub const HOME: PostureRange = PostureRange {
        neck_pan: [0.0; 2],
        neck_tilt: [0.0; 2],
        eye_tilt: [0.0; 2],
        version: [0.0; 2],
        vergence: [0.0; 2],
    };

    /// The five `[min, max]` intervals in the order neck pan, neck tilt, eye tilt, version,
    /// vergence.
    pub fn intervals(&self) -> [[f32; 2]; 5] {
        [self.neck_pan, self.neck_tilt, self.eye_tilt, self.version, self.vergence]
    }

    /// Whether every interval is finite with `min <= max`.
    pub fn is_valid(&self) -> bool {
        self.intervals().iter().all(|[lo, hi]| lo.is_finite() && hi.is_finite() && lo <= hi)
    }

    /// The posture at fractions `t` (each in `[0, 1]`, clamped) of the five intervals,
    /// quantised to whole drive steps.
    pub fn at(&self, t: [f64; 5]) -> Joints {
        let iv = self.intervals();
        let g: [f32; 5] = core::array::from_fn(|k| {
            let f = if t[k].is_nan() { 0.0 } else { t[k].clamp(0.0, 1.0) };
            let [lo, hi] = iv[k];
            (f64::from(lo) + (f64::from(hi) - f64::from(lo)) * f) as f32
        });
        let j = joints_from_gaze(g[0], g[1], g[2], g[3], g[4]);
        Joints(j.0.map(crate::runtime::gaze::quantize))
    }

    /// Grid posture number `index` of a grid with `levels[k]` evenly spaced values on
    /// interval `k` (1 level: the interval's middle), the last interval varying fastest;
    /// `None` past the last one ([`grid_len`]).
    pub fn grid(&self, levels: [u8; 5], index: usize) -> Option<Joints> {
        if index >= grid_len(levels) {
            return None;
        }
        let mut rest = index;
        let mut t = [0.0; 5];
        for k in (0..5).rev() {
            let n = usize::from(levels[k]);
            let i = rest % n;
            rest /= n;
            t[k] = if n == 1 { 0.5 } else { i as f64 / (n - 1) as f64 };
        }
        Some(self.at(t))
    }

    /// The gaze terms `[neck pan, neck tilt, eye tilt, version, vergence]` of `j`.
    pub fn gaze_terms(j: &Joints) -> [f32; 5] {
        let (l, r) = (j[Axis::LeftEyePan], j[Axis::RightEyePan]);
        [j[Axis::NeckPan], j[Axis::NeckTilt], j[Axis::EyeTilt], 0.5 * (l + r), r - l]
    }

    /// Whether `j`'s gaze terms lie in the box (with `slack` degrees to spare for the step
    /// quantisation).
    pub fn contains(&self, j: &Joints, slack: f32) -> bool {
        let g = Self::gaze_terms(j);
        self.intervals().iter().zip(g).all(|([lo, hi], v)| v >= lo - slack && v <= hi + slack)
    }
}

/// Number of postures of a grid with these levels (0 if any is 0).
pub fn grid_len(levels: [u8; 5]) -> usize {
    levels.iter().map(|&n| usize::from(n)).product()
}

/// The cyclopean gaze frame of a posture: origin half way between the eye centres (of a head
/// with its neck centre at `neck_centre_cm` and half baseline `half_baseline`), axes turned by
/// `Pan(neck) Tilt(neck) Tilt(eye) Pan(version)`. Boards placed in this frame sit in front of
/// wherever the head looks; at [`Joints::HOME`] it is the head frame itself (identity, origin
/// 0). Returns `(origin, rotation)`; a gaze-frame point `q` is `origin + rotation q` in the head
/// frame ([`to_head`]).
pub fn gaze_frame(joints: &Joints, neck_centre_cm: Vec3, half_baseline: f64) -> (Vec3, Mat3) {
    let version = 0.5 * (joints[Axis::LeftEyePan] + joints[Axis::RightEyePan]);
    let rot = eye_in_head(joints, version);
    let neck = neck_rotation(joints);
    let l = moved_centre(&neck, neck_centre_cm, [-half_baseline, 0.0, 0.0]);
    let r = moved_centre(&neck, neck_centre_cm, [half_baseline, 0.0, 0.0]);
    ([0.5 * (l[0] + r[0]), 0.5 * (l[1] + r[1]), 0.5 * (l[2] + r[2])], rot)
}

/// `origin + rotation q`: a point of a frame returned by [`gaze_frame`] in the head frame.
pub fn to_head(frame: &(Vec3, Mat3), q: &Vec3) -> Vec3 {
    let m = mat_vec(&frame.1, q);
    [frame.0[0] + m[0], frame.0[1] + m[1], frame.0[2] + m[2]]
}

fn check(p: &Vec3) -> Result<(), CameraError> {
    if p.iter().all(|c| c.is_finite()) {
        Ok(())
    } else {
        Err(CameraError::NonFinite)
    }
}

/// Active pan: turns `+Z` towards `-X` for a positive angle.
fn rot_pan(a: f64) -> Mat3 {
    let (s, c) = (libm::sin(a), libm::cos(a));
    [[c, 0.0, -s], [0.0, 1.0, 0.0], [s, 0.0, c]]
}

/// Active tilt: turns `+Z` towards `+Y` (down) for a positive angle.
fn rot_tilt(b: f64) -> Mat3 {
    let (s, c) = (libm::sin(b), libm::cos(b));
    [[1.0, 0.0, 0.0], [0.0, c, s], [0.0, -s, c]]
}

fn mat_mul(a: &Mat3, b: &Mat3) -> Mat3 {
    let mut m = [[0.0; 3]; 3];
    for (i, row) in m.iter_mut().enumerate() {
        for (j, v) in row.iter_mut().enumerate() {
            *v = a[i][0] * b[0][j] + a[i][1] * b[1][j] + a[i][2] * b[2][j];
        }
    }
    m
}

/// `a b^T`.
fn mat_mul_bt(a: &Mat3, b: &Mat3) -> Mat3 {
    let mut m = [[0.0; 3]; 3];
    for (i, row) in m.iter_mut().enumerate() {
        for (j, v) in row.iter_mut().enumerate() {
            *v = a[i][0] * b[j][0] + a[i][1] * b[j][1] + a[i][2] * b[j][2];
        }
    }
    m
}

fn sub(a: Vec3, b: Vec3) -> Vec3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use crate::runtime::gaze::{self, Eye, HeadGeometry};
    use crate::sim::camera::omega;
    use crate::sim::presets;
    use proptest::prelude::*;
    use std::vec::Vec;

    fn close(a: f64, b: f64, tol: f64) -> bool {
        (a - b).abs() <= tol
    }

    #[test]
    fn the_frames_f64_turns_are_the_inverses_of_the_heads_f32_ones() {
        let p = [17.0, -9.0, 120.0];
        for j in [[0.0f32; 5], [30.0, -20.0, 15.0, 12.0, 4.0], [-12.6, 7.2, -9.0, -20.0, -10.0]] {
            let jd = j.map(f64::from);
            let c = base_to_cyclopean(jd, &p);
            let back = gaze::cyclopean_to_base(j, c.map(|v| v as f32));
            // The axes of the simulator's gaze frame.
            let (_, r) = gaze_frame(&Joints(j), [0.0; 3], 5.25);
            let want: Vec3 =
                core::array::from_fn(|k| r[0][k] * p[0] + r[1][k] * p[1] + r[2][k] * p[2]);
            assert!((0..3).all(|k| close(c[k], want[k], 1e-9)), "{j:?}: {c:?} {want:?}");
            let q = base_to_platform([jd[0], jd[1], jd[2]], &p);
            let back_q = gaze::platform_to_base([j[0], j[1], j[2]], q.map(|v| v as f32));
            for k in 0..3 {
                assert!(close(f64::from(back[k]), p[k], 1e-4), "{j:?}: {back:?}");
                assert!(close(f64::from(back_q[k]), p[k], 1e-4), "{j:?}: {back_q:?}");
            }
        }
    }

    fn mat_close(a: &Mat3, b: &Mat3, tol: f64) -> bool {
        (0..3).all(|i| (0..3).all(|j| close(a[i][j], b[i][j], tol)))
    }

    fn joints(j: [f32; 5]) -> Joints {
        Joints(j)
    }

    #[test]
    fn home_posture_is_the_thesis_rig_bit_for_bit() {
        for n in 1..=4 {
            let rig = presets::case(n).unwrap();
            let head = HeadRig::new(rig);
            let [l, r] = head.cameras(&Joints::HOME);
            assert_eq!(l.camera, rig.left(), "case {n}");
            assert_eq!(r.camera, rig.right(), "case {n}");
            // Also with the neck centre away from the baseline.
            let head = HeadRig { neck_centre_cm: [0.3, 6.1, -4.7], ..head };
            for z in [65.0, 97.3, 165.0] {
                for p in presets::board_points(z) {
                    assert_eq!(
                        head.project_rounded(&Joints::HOME, &p),
                        rig.project_rounded(&p),
                        "case {n} {p:?}"
                    );
                    assert_eq!(head.project(&Joints::HOME, &p), rig.project(&p));
                }
            }
        }
    }

    #[test]
    fn pure_eye_pan_moves_only_that_cameras_rotation() {
        let ten = 10.0f64.to_radians();
        for n in [1, 3, 4] {
            let rig = presets::case(n).unwrap();
            let head = HeadRig { neck_centre_cm: [0.0, 6.0, -4.0], ..HeadRig::new(rig) };
            let [l, r] = head.cameras(&joints([0.0, 0.0, 0.0, 10.0, 0.0]));
            assert_eq!(r.camera, rig.right());
            assert_eq!(l.camera.center, rig.left().center);
            // p_cam = Omega_case Pan(10)^T p = Omega_case Omega(10 deg, 0, 0) p.
            let want = mat_mul(&omega(rig.alpha_left, rig.beta0, rig.phi0), &omega(ten, 0.0, 0.0));
            assert!(mat_close(&l.camera.rotation, &want, 1e-15), "case {n}");
        }
        // Parallel rig: the optic axis turns 10 degrees towards -X.
        let head = HeadRig::new(Rig::parallel(300.0));
        let [l, _] = head.cameras(&joints([0.0, 0.0, 0.0, 10.0, 0.0]));
        let axis = l.camera.rotation[2];
        assert!(close(axis[0], -ten.sin(), 1e-15) && close(axis[2], ten.cos(), 1e-15));
        assert_eq!(axis[1], 0.0);
    }

    #[test]
    fn neck_pan_rotates_both_centres_about_the_neck_axis() {
        // Neck centre 6 cm below and 4 cm behind the baseline centre; neck pan 30 degrees.
        let head =
            HeadRig { neck_centre_cm: [0.0, 6.0, -4.0], ..HeadRig::new(Rig::parallel(300.0)) };
        let [l, r] = head.cameras(&joints([30.0, 0.0, 0.0, 0.0, 0.0]));
        // By hand: c' = n + Pan(30) (c - n), Pan = [[cos, 0, -sin], [0, 1, 0], [sin, 0, cos]].
        // Left: c - n = (-5.25, -6, 4) -> (-5.25 cos30 - 4 sin30, -6, -5.25 sin30 + 4 cos30).
        let want_l = [-6.546_633_369_868_303, 0.0, -3.160_898_384_862_245_6];
        let want_r = [2.546_633_369_868_303, 0.0, 2.089_101_615_137_754_6];
        for k in 0..3 {
            assert!(close(l.camera.center[k], want_l[k], 1e-12), "{:?}", l.camera);
            assert!(close(r.camera.center[k], want_r[k], 1e-12), "{:?}", r.camera);
        }
        // Both cameras turned by the same 30 degrees.
        let want = omega(30.0f64.to_radians(), 0.0, 0.0);
        assert!(mat_close(&l.camera.rotation, &want, 1e-15));
        assert!(mat_close(&r.camera.rotation, &want, 1e-15));
    }

    #[test]
    fn eye_tilt_turns_both_cameras_about_the_baseline() {
        let head = HeadRig::new(Rig::parallel(300.0));
        let [l, r] = head.cameras(&joints([0.0, 0.0, 10.0, 0.0, 0.0]));
        let want = omega(0.0, 10.0f64.to_radians(), 0.0);
        assert_eq!(l.camera.center, [-5.25, 0.0, 0.0]);
        assert_eq!(r.camera.center, [5.25, 0.0, 0.0]);
        assert!(mat_close(&l.camera.rotation, &want, 1e-15));
        assert!(mat_close(&r.camera.rotation, &want, 1e-15));
        // The optic axis points 10 degrees down (+Y): a point on it images at the principal point.
        let b = 10.0f64.to_radians();
        let p = [-5.25, 100.0 * b.sin(), 100.0 * b.cos()];
        let px = head.project(&joints([0.0, 0.0, 10.0, 0.0, 0.0]), &p).unwrap();
        assert!(close(px[0], 320.0, 1e-9) && close(px[1], 240.0, 1e-9), "{px:?}");
    }

    #[test]
    fn neck_moves_the_head_rigidly() {
        // A point fixed to the head images the same at every neck posture.
        let head = HeadRig { neck_centre_cm: [0.5, 6.0, -4.0], ..HeadRig::new(presets::CASE_4) };
        let eyes = [2.0, -3.0, 4.5];
        let home = joints([0.0, 0.0, eyes[0], eyes[1], eyes[2]]);
        let q = [2.0, -1.0, 90.0];
        let at_home = head.project(&home, &q).unwrap();
        for (pan, tilt) in [(25.0f32, 0.0f32), (0.0, -15.0), (-40.0, 20.0)] {
            let j = joints([pan, tilt, eyes[0], eyes[1], eyes[2]]);
            let n = neck_rotation(&j);
            let p = to_head(&(head.neck_centre_cm, n), &sub(q, head.neck_centre_cm));
            let px = head.project(&j, &p).unwrap();
            for k in 0..4 {
                assert!(close(px[k], at_home[k], 1e-9), "{pan} {tilt}: {px:?} vs {at_home:?}");
            }
        }
    }

    proptest! {
        #[test]
        fn agrees_with_the_head_controllers_f32_kinematics(
            j in proptest::array::uniform5(-40.0f32..40.0),
            nc in proptest::array::uniform3(-8.0f32..8.0),
        ) {
            let j = Joints(j);
            let geometry = HeadGeometry { half_baseline_cm: 5.25, neck_centre_cm: nc };
            let head = HeadRig {
                neck_centre_cm: nc.map(f64::from),
                ..HeadRig::new(Rig::parallel(300.0))
            };
            let cams = head.cameras(&j);
            for (cam, eye) in cams.iter().zip([Eye::Left, Eye::Right]) {
                let pose = gaze::eye_pose(&geometry, &j, eye);
                for a in 0..3 {
                    prop_assert!(close(cam.camera.center[a], f64::from(pose.centre[a]), 2e-5));
                    for b in 0..3 {
                        prop_assert!(close(cam.camera.rotation[a][b], f64::from(pose.rot[a][b]), 2e-6));
                    }
                }
            }
        }

        #[test]
        fn optimal_recovers_exact_points_at_any_posture_and_lens(
            j in proptest::array::uniform5(-20.0f32..20.0),
            q in (-15.0f64..15.0, -10.0f64..10.0, 50.0f64..200.0),
            k1 in -0.4f64..0.1,
            n in 1u8..=4,
        ) {
            let j = Joints(j);
            let head = HeadRig {
                neck_centre_cm: [0.0, 6.0, -4.0],
                ..HeadRig::new(presets::case(n).unwrap())
            }
            .with_distortion(Distortion { k1, k2: 0.0 });
            let p = to_head(&gaze_frame(&j, head.neck_centre_cm, 5.25), &[q.0, q.1, q.2]);
            let px = head.project(&j, &p).unwrap();
            // Stay inside the region where the lens does not fold over.
            let [l, r] = head.cameras(&j);
            for (c, cam) in [(0, l), (2, r)] {
                let o = [px[c] - 320.0, px[c + 1] - 240.0];
                prop_assume!(cam.distortion.undo(o, 320.0).is_some());
                prop_assume!(o[0].abs() < 320.0 && o[1].abs() < 240.0);
            }
            let got = head.optimal(&j, &px).unwrap();
            for k in 0..3 {
                prop_assert!(close(got[k], p[k], 1e-6 * p[2].abs().max(1.0)), "{:?} vs {:?}", got, p);
            }
        }
    }

    #[test]
    fn optimal_equals_the_rig_floor_at_home() {
        for n in 1..=4 {
            let rig = presets::case(n).unwrap();
            let head = HeadRig::new(rig);
            let cams = head.cameras(&Joints::HOME);
            for z in presets::TEST_DEPTHS {
                for [x, y] in presets::TEST_POINTS_XY {
                    let px = rig.project_rounded(&[x, y, z]).unwrap();
                    let a = crate::sim::triangulate::optimal_rig(&rig, &px).unwrap();
                    let b = optimal(&cams, &px).unwrap();
                    for k in 0..3 {
                        assert!(close(a[k], b[k], 1e-9 * z), "case {n}: {a:?} {b:?}");
                    }
                }
            }
        }
    }

    #[test]
    fn distortion_by_hand() {
        // Ideal offset 160 px = half of the half-width: r = 0.5, r^2 = 0.25.
        let d = Distortion { k1: -0.2, k2: 0.0 };
        assert_eq!(d.apply([160.0, 0.0], 320.0), [152.0, 0.0]); // 1 - 0.2 * 0.25 = 0.95
        let d2 = Distortion { k1: -0.2, k2: 0.1 };
        let a = d2.apply([0.0, -160.0], 320.0); // 0.95 + 0.1 * 0.0625 = 0.95625
        assert!(close(a[1], -153.0, 1e-12) && a[0] == 0.0, "{a:?}");
        // Through a camera: a point whose ideal image is 160 px right of the principal point.
        let head = HeadRig::new(Rig::parallel(300.0)).with_distortion(d);
        let p = [74.75, 0.0, 150.0]; // left camera: X_cam = 80, 300 * 80 / 150 = 160
        let px = head.project_rounded(&Joints::HOME, &p).unwrap();
        assert_eq!((px[0], px[1]), (472.0, 240.0));
        // Undo inverts apply inside the region where the lens does not fold.
        for o in [[100.0, 50.0], [-200.0, 120.0], [0.0, -230.0], [250.0, 0.0]] {
            let shown = d2.apply(o, 320.0);
            let back = d2.undo(shown, 320.0).unwrap();
            assert!(close(back[0], o[0], 1e-9) && close(back[1], o[1], 1e-9));
        }
        // k1 = -0.5 folds over at r^2 = 2/3: nothing beyond r_d = 0.544 is shown.
        let strong = Distortion { k1: -0.5, k2: 0.0 };
        assert!(strong.undo([0.55 * 320.0, 0.0], 320.0).is_none());
        assert!(strong.undo([0.5 * 320.0, 0.0], 320.0).is_some());
        // No distortion: exactly the pinhole camera.
        let rig = presets::CASE_3;
        let plain = HeadRig::new(rig).with_distortion(Distortion::NONE);
        let p = [2.5, -1.5, 77.0];
        assert_eq!(plain.project_rounded(&Joints::HOME, &p), rig.project_rounded(&p));
    }

    #[test]
    fn noise_is_added_before_rounding() {
        let head = HeadRig::new(Rig::parallel(300.0));
        let p = [0.0, 0.0, 100.0]; // left: 300 * 5.25 / 100 = 15.75
        let j = Joints::HOME;
        assert_eq!(head.project_rounded_noisy(&j, &p, &[0.3, 0.0, 0.0, 0.0]).unwrap()[0], 336.0);
        assert_eq!(head.project_rounded_noisy(&j, &p, &[-0.3, 0.0, 0.0, 0.0]).unwrap()[0], 335.0);
        assert_eq!(
            head.project_rounded_noisy(&j, &p, &[f64::NAN, 0.0, 0.0, 0.0]),
            Err(CameraError::NonFinite)
        );
        assert_eq!(head.project(&j, &[0.0, 0.0, -1.0]), Err(CameraError::BehindLeft));
    }

    #[test]
    fn gaze_frame_is_the_head_frame_at_home_and_follows_the_eyes() {
        let f = gaze_frame(&Joints::HOME, [0.0, 6.0, -4.0], 5.25);
        assert_eq!(f.0, [0.0; 3]);
        for p in presets::board_points(85.0) {
            assert_eq!(to_head(&f, &p), p);
        }
        // Verged on a point D = 80 cm straight ahead of the (turned, tilted) gaze frame:
        // both cameras see it at their principal points.
        let d = 80.0f64;
        let verg = (2.0 * (5.25 / d).atan()).to_degrees() as f32;
        let head =
            HeadRig { neck_centre_cm: [0.0, 6.0, -4.0], ..HeadRig::new(Rig::parallel(300.0)) };
        let j = joints_from_gaze(20.0, -10.0, 5.0, 0.0, verg);
        assert!(close(
            f64::from(j[Axis::RightEyePan] - j[Axis::LeftEyePan]),
            f64::from(verg),
            1e-6
        ));
        let p = to_head(&gaze_frame(&j, head.neck_centre_cm, 5.25), &[0.0, 0.0, d]);
        let px = head.project(&j, &p).unwrap();
        for (k, want) in [320.0, 240.0, 320.0, 240.0].into_iter().enumerate() {
            assert!(close(px[k], want, 1e-4), "{px:?}");
        }
    }

    #[test]
    fn posture_grid_and_box() {
        let w = PostureRange::WORKING;
        assert!(w.is_valid());
        let levels = [3, 3, 3, 3, 4];
        assert_eq!(grid_len(levels), 324);
        let all: Vec<Joints> = (0..324).map(|i| w.grid(levels, i).unwrap()).collect();
        assert_eq!(w.grid(levels, 324), None);
        // First: every interval at its low end; last: every one at its high end.
        let q = crate::runtime::gaze::quantize;
        assert_eq!(all[0], Joints([q(-30.0), q(-20.0), q(-15.0), q(-15.0), q(-15.0)]));
        assert_eq!(all[323], Joints([q(30.0), q(20.0), q(15.0), q(10.0), q(20.0)]));
        assert_eq!(all[0].0.map(|v| (v / 0.18).round()), [-167.0, -111.0, -83.0, -83.0, -83.0]);
        // Vergence varies fastest, on its 4 levels 0, 3.33, 6.67, 10 (quantised).
        let verg: Vec<f32> = all[..4].iter().map(|j| PostureRange::gaze_terms(j)[4]).collect();
        for (v, want) in verg.iter().zip([0.0f32, 3.33, 6.67, 10.0]) {
            assert!((v - want).abs() <= 0.18, "{verg:?}");
        }
        // Every grid posture: whole steps, inside the box and the joint limits, all distinct.
        for j in &all {
            for v in j.0 {
                assert!((v / 0.18 - libm::roundf(v / 0.18)).abs() < 1e-3, "{j:?}");
            }
            assert!(w.contains(j, 0.18), "{j:?}");
            assert!(crate::runtime::gaze::JointLimits::DEFAULT.contains(j));
        }
        for a in 0..all.len() {
            for b in a + 1..all.len() {
                assert_ne!(all[a], all[b]);
            }
        }
        // One level sits in the middle; the home range gives home.
        assert_eq!(w.grid([1; 5], 0), Some(Joints([0.0, 0.0, 0.0, q(-2.5), q(2.5)])));
        assert_eq!(PostureRange::HOME.at([0.3; 5]), Joints::HOME);
        assert!(!PostureRange { vergence: [2.0, 1.0], ..w }.is_valid());
        assert!(!w.contains(&Joints([40.0, 0.0, 0.0, 0.0, 0.0]), 0.18));
    }
}
