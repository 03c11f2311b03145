//! Joint space and fixation kinematics of the five-axis head (thesis §3.1, Fig. 3.1).
//!
//! # Frames
//!
//! The **base frame** is the thesis' stereo reference frame `O_s` at the home posture (all
//! joints 0), fixed to the robot's body: origin at the centre of the baseline, `X` to the
//! right, `Y` **down** (the image `v` axis grows downwards and the camera model has
//! `v = round(k_v f Y / Z) + v_0`), `Z` forward. Lengths are in cm, angles in degrees.
//!
//! # Kinematic chain
//!
//! 1. **Neck pan** about the base's vertical (`Y`) axis through the neck centre
//!    [`HeadGeometry::neck_centre_cm`] (default: the origin).
//! 2. **Neck tilt** about the panned horizontal axis through the same point. The neck moves
//!    the whole head: both eye centres and the eye mechanism.
//! 3. **Eye tilt** (conjugate): one platform carrying both eyes, tilting about the baseline
//!    (the head's `X` axis through both eye centres).
//! 4. **Left / right eye pan** about each eye's own vertical axis (tilted with the platform)
//!    through its centre. The eye centres sit at `(-d, 0, 0)` and `(+d, 0, 0)` in the head,
//!    `d` = [`HALF_BASELINE_CM`].
//!
//! With the neck at 0, the camera rotation is exactly the thesis' `Ω(α, β, 0)` of eq. 3.1-3
//! (tilt outer, pan inner), `p_cam = Ω (p_s - d_{L,R})` (eqs. 3.1-4, 3.1-7), the same
//! convention as the simulator's camera model (`sim::camera`: `omega`, `Camera::rotation`): an [`EyePose`] converts
//! to a `camera::Camera` by widening to `f64`.
//!
//! # Sign convention (the thesis' `Ω`)
//!
//! A **positive pan** (neck or eye) turns the optic axis towards `-X` (the head's left); a
//! **positive tilt** (neck or eye) turns it towards `+Y` (down). The optic axis of an eye
//! with pan `α` and tilt `β` (neck at 0) points along `(-sin α, cos α sin β, cos α cos β)`.
//! Fixating a point straight ahead at distance `Z` therefore gives the left eye
//! `-atan(d/Z)` and the right eye `+atan(d/Z)`: vergence = right pan - left pan > 0.
//!
//! # Fixation
//!
//! [`fixate`] gives the neck a share ([`GazeConfig::neck_share`]) of the target's azimuth and
//! elevation seen from the neck centre; the eyes then fixate exactly from the resulting head
//! posture (conjugate tilt into the plane of baseline and target, each eye pan onto the
//! target: vergence). If an eye would pass its limit the excess is handed to the neck, then
//! everything is clamped to the [`JointLimits`].
//!
//! # Arithmetic
//!
//! Everything is `f32`. `atan2f` comes from `libm`; the square root is [`sqrt`], a bit-by-bit
//! integer square root, correctly rounded like `libm::sqrtf` (the same bits) in a sixth of the
//! flash (libm's takes a 256 B table for its speed, which a look does not need); sine and cosine are a small
//! pure-`f32` kernel here ([`sin_cos`]), because `libm`'s `sinf`/`cosf` evaluate in `f64`
//! (soft-float on the Cortex-M4F) with a large-argument reduction, about 6 KiB of the
//! firmware's 24 KiB flash budget, while joint angles never leave ±π. Host and MCU still
//! compute the same bits (IEEE `f32` operations only, no fused multiply-add).
use core::ops::{Index, IndexMut};

use libm::{atan2f, ceilf, floorf, roundf};
use serde::{Deserialize, Serialize};

/// Positioning resolution of the MCDC 3006 S drives in the thesis' head, degrees.
pub const STEP_DEG: f32 = 0.18;

/// Extra angle handed from a saturated eye axis to the neck, degrees.
const HANDOVER_MARGIN_DEG: f32 = 0.5;
const RAD_TO_DEG: f32 = 180.0 / core::f32::consts::PI;
const DEG_TO_RAD: f32 = core::f32::consts::PI / 180.0;

/// Half the baseline `d` of the head (cm): each eye's centre is `d` from the baseline's middle
/// (10.5 cm between the cameras). The one definition: the simulator's rigs use it too.
pub const HALF_BASELINE_CM: f64 = 5.25;

/// The five axes of the head, in the order of [`Joints`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Axis {
    /// Neck pan, about the vertical axis.
    NeckPan = 0,
    /// Neck tilt, about the (panned) horizontal axis.
    NeckTilt = 1,
    /// Conjugate tilt of both eyes.
    EyeTilt = 2,
    /// Pan of the left eye.
    LeftEyePan = 3,
    /// Pan of the right eye.
    RightEyePan = 4,
}

impl Axis {
    /// All axes, in [`Joints`] order.
    pub const ALL: [Axis; 5] =
        [Axis::NeckPan, Axis::NeckTilt, Axis::EyeTilt, Axis::LeftEyePan, Axis::RightEyePan];

    /// Index of this axis in [`Joints`] and every per-axis array.
    pub const fn index(self) -> usize {
        self as usize
    }

    /// True for the two neck axes (the slow ones).
    pub const fn is_neck(self) -> bool {
        matches!(self, Axis::NeckPan | Axis::NeckTilt)
    }
}

/// Joint angles in degrees, indexed by [`Axis`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Joints(pub [f32; 5]);

impl Joints {
    /// The home posture: every joint at 0.
    pub const HOME: Joints = Joints([0.0; 5]);
}

impl Index<Axis> for Joints {
    type Output = f32;
    fn index(&self, axis: Axis) -> &f32 {
        &self.0[axis.index()]
    }
}

impl IndexMut<Axis> for Joints {
    fn index_mut(&mut self, axis: Axis) -> &mut f32 {
        &mut self.0[axis.index()]
    }
}

/// Travel and speed limits of one axis.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AxisLimits {
    /// Lowest angle, degrees (at most 0: home must be reachable).
    pub min_deg: f32,
    /// Highest angle, degrees (at least 0).
    pub max_deg: f32,
    /// Largest speed, degrees per second.
    pub max_vel_deg_s: f32,
}

/// Why a [`JointLimits`] was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LimitsError {
    /// `min_deg <= 0 <= max_deg` does not hold, or a bound is not finite.
    Range(Axis),
    /// The speed limit is not finite and positive, or is below one [`STEP_DEG`] per control
    /// tick (the axis could never move).
    Velocity(Axis),
}

/// Limits of all five axes, indexed by [`Axis`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct JointLimits(pub [AxisLimits; 5]);

const fn lim(min_deg: f32, max_deg: f32, max_vel_deg_s: f32) -> AxisLimits {
    AxisLimits { min_deg, max_deg, max_vel_deg_s }
}

impl JointLimits {
    /// Defaults for a humanoid head of the thesis' kind (the thesis gives no numbers):
    /// neck pan ±60° at 180°/s, neck tilt ±35° at 180°/s, eye tilt ±30° and eye pans ±35°
    /// at 400°/s (human saccades peak at 400-700°/s).
    pub const DEFAULT: JointLimits = JointLimits([
        lim(-60.0, 60.0, 180.0),
        lim(-35.0, 35.0, 180.0),
        lim(-30.0, 30.0, 400.0),
        lim(-35.0, 35.0, 400.0),
        lim(-35.0, 35.0, 400.0),
    ]);

    /// Limits of one axis.
    pub fn axis(&self, axis: Axis) -> &AxisLimits {
        &self.0[axis.index()]
    }

    /// Checks every axis for a control loop at `control_hz`: finite bounds with
    /// `min <= 0 <= max`, a finite positive speed of at least one step per tick.
    pub fn validate(&self, control_hz: u32) -> Result<(), LimitsError> {
        for axis in Axis::ALL {
            let l = self.axis(axis);
            let range_ok = l.min_deg.is_finite()
                && l.max_deg.is_finite()
                && l.min_deg <= 0.0
                && l.max_deg >= 0.0;
            if !range_ok {
                return Err(LimitsError::Range(axis));
            }
            if !(l.max_vel_deg_s.is_finite() && l.max_vel_deg_s > 0.0)
                || max_steps_per_tick(l.max_vel_deg_s, control_hz) < 1
            {
                return Err(LimitsError::Velocity(axis));
            }
        }
        Ok(())
    }

    /// `deg` clamped into the axis' range. NaN goes to home (0 clamped into the range), so
    /// the result is always finite and within the limits.
    pub fn clamp_axis(&self, axis: Axis, deg: f32) -> f32 {
        let l = self.axis(axis);
        let x = if deg.is_nan() { 0.0 } else { deg };
        // Written out (not f32::clamp) so inverted limits cannot panic.
        if x > l.max_deg {
            l.max_deg
        } else if x < l.min_deg {
            l.min_deg
        } else {
            x
        }
    }

    /// Every joint clamped, as [`JointLimits::clamp_axis`].
    pub fn clamp(&self, joints: &Joints) -> Joints {
        let mut out = *joints;
        for axis in Axis::ALL {
            out[axis] = self.clamp_axis(axis, joints[axis]);
        }
        out
    }

    /// True when every joint is finite and within its range.
    pub fn contains(&self, joints: &Joints) -> bool {
        Axis::ALL.iter().all(|&a| {
            let l = self.axis(a);
            joints[a] >= l.min_deg && joints[a] <= l.max_deg
        })
    }

    /// The range of whole [`STEP_DEG`] steps `(lo, hi)` whose angles
    /// ([`from_steps`]) lie within the axis' range; `lo <= 0 <= hi` for valid limits.
    pub fn step_range(&self, axis: Axis) -> (i32, i32) {
        let l = self.axis(axis);
        let mut lo = ceilf(l.min_deg / STEP_DEG) as i32;
        let mut hi = floorf(l.max_deg / STEP_DEG) as i32;
        // f32 rounding of the division can put the bound one step outside: step back in.
        while lo < 0 && from_steps(lo) < l.min_deg {
            lo += 1;
        }
        while hi > 0 && from_steps(hi) > l.max_deg {
            hi -= 1;
        }
        (lo.min(0), hi.max(0))
    }
}

impl Default for JointLimits {
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// Largest whole number of [`STEP_DEG`] steps an axis with speed limit `max_vel_deg_s` may
/// move in one tick of a `control_hz` loop (0 for bad input): `floor(v / hz / 0.18)`, where
/// a quotient within 1e-4 below an integer counts as that integer (f32 cannot hold 0.18, so
/// 180°/s at 100 Hz is 10 steps, not 9).
pub fn max_steps_per_tick(max_vel_deg_s: f32, control_hz: u32) -> i32 {
    if control_hz == 0 || !max_vel_deg_s.is_finite() || max_vel_deg_s <= 0.0 {
        return 0;
    }
    floorf(max_vel_deg_s / control_hz as f32 / STEP_DEG + 1e-4) as i32
}

/// Whole [`STEP_DEG`] steps nearest to `deg` (ties away from zero); NaN gives 0 and
/// out-of-range values saturate.
pub fn to_steps(deg: f32) -> i32 {
    // `as` saturates and maps NaN to 0.
    roundf(deg / STEP_DEG) as i32
}

/// The angle of `steps` whole [`STEP_DEG`] steps, degrees.
pub fn from_steps(steps: i32) -> f32 {
    steps as f32 * STEP_DEG
}

/// `deg` rounded to the nearest multiple of [`STEP_DEG`] (NaN gives 0).
pub fn quantize(deg: f32) -> f32 {
    from_steps(to_steps(deg))
}

/// Fixed dimensions of the head.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HeadGeometry {
    /// `d`: each eye centre sits at `(∓d, 0, 0)` in the head, cm.
    pub half_baseline_cm: f32,
    /// Where the neck pan and tilt axes cross, in the base frame, cm (e.g. `[0, 6, -4]` for
    /// a neck 6 cm below and 4 cm behind the baseline).
    pub neck_centre_cm: [f32; 3],
}

impl HeadGeometry {
    /// Thesis baseline, neck axes through the baseline centre.
    pub const DEFAULT: HeadGeometry =
        HeadGeometry { half_baseline_cm: HALF_BASELINE_CM as f32, neck_centre_cm: [0.0; 3] };
}

impl Default for HeadGeometry {
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// Everything [`fixate`] needs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GazeConfig {
    /// Dimensions of the head.
    pub geometry: HeadGeometry,
    /// Share of the target's azimuth and elevation taken by the neck, 0 (eyes only) to 1
    /// (neck points the head at the target); values outside are clamped, NaN counts as 0.
    pub neck_share: f32,
    /// Targets nearer than this to the base origin are refused, cm.
    pub min_distance_cm: f32,
    /// Targets with a coordinate beyond this are pulled in along their direction until the
    /// largest coordinate is this, cm (vergence is then below 0.001°; keeps the arithmetic
    /// far from overflow).
    pub max_distance_cm: f32,
    /// Joint limits; every output of [`fixate`] lies within them.
    pub limits: JointLimits,
}

impl GazeConfig {
    /// Half-and-half neck/eye split, 10 cm to 1 km, default geometry and limits.
    pub const DEFAULT: GazeConfig = GazeConfig {
        geometry: HeadGeometry::DEFAULT,
        neck_share: 0.5,
        min_distance_cm: 10.0,
        max_distance_cm: 100_000.0,
        limits: JointLimits::DEFAULT,
    };
}

impl Default for GazeConfig {
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// Why a target was refused by [`fixate`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GazeError {
    /// A coordinate is NaN or infinite.
    NonFinite,
    /// `Z <= 0`: the target is not in front of the baseline.
    BehindHead,
    /// Nearer than [`GazeConfig::min_distance_cm`].
    TooClose,
}

/// Result of [`fixate`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Fixation {
    /// Joint targets, within the limits.
    pub joints: Joints,
    /// True when some joint had to be clamped: the optic axes then miss the target.
    pub clamped: bool,
}

/// One of the two eyes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Eye {
    /// Centre at `(-d, 0, 0)` in the head.
    Left,
    /// Centre at `(+d, 0, 0)` in the head.
    Right,
}

/// A half-line in the base frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray {
    /// Start point, cm.
    pub origin: [f32; 3],
    /// Unit direction.
    pub dir: [f32; 3],
}

impl Ray {
    /// Distance from `p` to the half-line (to the origin if `p` lies behind it), cm.
    pub fn distance_to(&self, p: [f32; 3]) -> f32 {
        let w = sub(p, self.origin);
        let along = dot(w, self.dir);
        if along <= 0.0 {
            return norm(w);
        }
        norm(sub(w, scale(self.dir, along)))
    }
}

/// Pose of one camera in the base frame, thesis style.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EyePose {
    /// Eye (camera) centre in the base frame, cm.
    pub centre: [f32; 3],
    /// `Ω`: maps base-frame offsets to camera coordinates, `p_cam = Ω (p - centre)`
    /// (thesis eqs. 3.1-4, 3.1-7). Row `i` is camera axis `i` in the base frame.
    pub rot: [[f32; 3]; 3],
}

impl EyePose {
    /// The optic axis (camera `+Z`) as a ray in the base frame.
    pub fn optic_axis(&self) -> Ray {
        Ray { origin: self.centre, dir: self.rot[2] }
    }

    /// A base-frame point in camera coordinates, cm.
    pub fn to_camera(&self, p: [f32; 3]) -> [f32; 3] {
        mat_vec(&self.rot, sub(p, self.centre))
    }
}

/// Forward kinematics: the pose of `eye` at posture `joints` (degrees, used as given).
pub fn eye_pose(geometry: &HeadGeometry, joints: &Joints, eye: Eye) -> EyePose {
    let neck = neck_rotation(joints[Axis::NeckPan], joints[Axis::NeckTilt]);
    let (pan, x) = match eye {
        Eye::Left => (joints[Axis::LeftEyePan], -geometry.half_baseline_cm),
        Eye::Right => (joints[Axis::RightEyePan], geometry.half_baseline_cm),
    };
    // Active rotation of the camera in the head: tilt platform (outer), then pan (inner).
    let in_head =
        mat_mul(&rot_tilt(joints[Axis::EyeTilt] * DEG_TO_RAD), &rot_pan(pan * DEG_TO_RAD));
    let in_base = mat_mul(&neck, &in_head);
    let c = geometry.neck_centre_cm;
    let centre = add(c, mat_vec(&neck, sub([x, 0.0, 0.0], c)));
    EyePose { centre, rot: transpose(&in_base) }
}

/// Fixation kinematics: joint targets that point both optic axes at `target_cm` (base
/// frame, cm). See the module documentation for the chain and signs. The result is always
/// finite and within `cfg.limits`.
pub fn fixate(cfg: &GazeConfig, target_cm: [f32; 3]) -> Result<Fixation, GazeError> {
    if !target_cm.iter().all(|v| v.is_finite()) {
        return Err(GazeError::NonFinite);
    }
    if target_cm[2] <= 0.0 {
        return Err(GazeError::BehindHead);
    }
    // Pull far targets in first (keeps every later product far from overflow).
    let largest = target_cm.iter().fold(0.0f32, |m, v| m.max(v.abs()));
    let p = if largest > cfg.max_distance_cm {
        scale(target_cm, cfg.max_distance_cm / largest)
    } else {
        target_cm
    };
    // Written so that a NaN minimum refuses everything.
    let far_enough = norm(p) >= cfg.min_distance_cm;
    if !far_enough {
        return Err(GazeError::TooClose);
    }
    let limits = &cfg.limits;
    let share = if cfg.neck_share > 0.0 { cfg.neck_share.min(1.0) } else { 0.0 };

    // Neck: a share of the azimuth/elevation seen from the neck centre (pan outer).
    let rel = sub(p, cfg.geometry.neck_centre_cm);
    let azimuth = atan2f(-rel[0], rel[2]) * RAD_TO_DEG;
    let elevation = atan2f(rel[1], norm([rel[0], 0.0, rel[2]])) * RAD_TO_DEG;
    let mut neck_pan = limits.clamp_axis(Axis::NeckPan, share * azimuth);
    let mut neck_tilt = limits.clamp_axis(Axis::NeckTilt, share * elevation);

    let mut eyes = eye_angles(&cfg.geometry, neck_pan, neck_tilt, p);
    // Hand eye excess beyond the limits to the neck (a positive neck angle moves the gaze
    // the same way as a positive eye angle); two passes settle it.
    for _ in 0..2 {
        let excess = |axis: Axis, v: f32| v - limits.clamp_axis(axis, v);
        let tilt_excess = excess(Axis::EyeTilt, eyes[0]);
        let left = excess(Axis::LeftEyePan, eyes[1]);
        let right = excess(Axis::RightEyePan, eyes[2]);
        // Opposite-signed excess is vergence the neck cannot take.
        let pan_excess = if left * right < 0.0 {
            0.0
        } else if left.abs() > right.abs() {
            left
        } else {
            right
        };
        // A small margin so the re-solved eyes land inside, not on, the limit.
        let (pan_excess, tilt_excess) = (with_margin(pan_excess), with_margin(tilt_excess));
        let new_pan = limits.clamp_axis(Axis::NeckPan, neck_pan + pan_excess);
        let new_tilt = limits.clamp_axis(Axis::NeckTilt, neck_tilt + tilt_excess);
        if new_pan == neck_pan && new_tilt == neck_tilt {
            break;
        }
        neck_pan = new_pan;
        neck_tilt = new_tilt;
        eyes = eye_angles(&cfg.geometry, neck_pan, neck_tilt, p);
    }

    let raw = Joints([neck_pan, neck_tilt, eyes[0], eyes[1], eyes[2]]);
    let joints = limits.clamp(&raw);
    Ok(Fixation { joints, clamped: joints != raw })
}

/// `e` pushed [`HANDOVER_MARGIN_DEG`] further from 0 (0 stays 0).
fn with_margin(e: f32) -> f32 {
    if e > 0.0 {
        e + HANDOVER_MARGIN_DEG
    } else if e < 0.0 {
        e - HANDOVER_MARGIN_DEG
    } else {
        0.0
    }
}

/// Exact eye tilt and left/right pans (degrees) fixating `p` (base frame) for a given neck.
fn eye_angles(geometry: &HeadGeometry, neck_pan: f32, neck_tilt: f32, p: [f32; 3]) -> [f32; 3] {
    let neck = neck_rotation(neck_pan, neck_tilt);
    let c = geometry.neck_centre_cm;
    // Target in the head frame: q = R^T (p - c) + c.
    let q = add(mat_t_vec(&neck, sub(p, c)), c);
    let d = geometry.half_baseline_cm;
    // The tilt platform puts the baseline and the target in one plane; r is the target's
    // forward distance within it.
    let tilt = atan2f(q[1], q[2]);
    let r = norm([0.0, q[1], q[2]]);
    let left = atan2f(-(q[0] + d), r);
    let right = atan2f(d - q[0], r);
    [tilt * RAD_TO_DEG, left * RAD_TO_DEG, right * RAD_TO_DEG]
}

/// A point `p` of the eye platform's frame in the base frame, at neck pan, neck tilt and eye
/// tilt `angles_deg` (degrees): `Pan(neck pan) Tilt(neck tilt) Tilt(eye tilt) p`, the part of
/// the chain that turns both cameras together. The platform frame turns about the baseline's
/// centre whatever the neck centre; it is where a posture-aware model of
/// [`crate::runtime::blob::OutputFrame::EyePlatform`] gives its points. The two tilts share
/// their axis, so they are applied as one tilt by their sum: two plane rotations, in `f32`.
pub fn platform_to_base(angles_deg: [f32; 3], p: [f32; 3]) -> [f32; 3] {
    let (st, ct) = sin_cos((angles_deg[1] + angles_deg[2]) * DEG_TO_RAD);
    let (sp, cp) = sin_cos(angles_deg[0] * DEG_TO_RAD);
    // Tilt (about X), then pan (about Y), as `rot_tilt` and `rot_pan`.
    let y = ct * p[1] + st * p[2];
    let z = ct * p[2] - st * p[1];
    [cp * p[0] - sp * z, y, sp * p[0] + cp * z]
}

/// A base-frame point `p` in the eye platform's frame: the inverse of [`platform_to_base`].
pub fn base_to_platform(angles_deg: [f32; 3], p: [f32; 3]) -> [f32; 3] {
    let (st, ct) = sin_cos((angles_deg[1] + angles_deg[2]) * DEG_TO_RAD);
    let (sp, cp) = sin_cos(angles_deg[0] * DEG_TO_RAD);
    let x = cp * p[0] + sp * p[2];
    let z = cp * p[2] - sp * p[0];
    [x, ct * p[1] - st * z, ct * z + st * p[1]]
}

/// A point `p` of the cyclopean frame in the base frame, at the five joints `joints_deg`
/// (neck pan, neck tilt, eye tilt, left and right eye pan; degrees): the eye platform's frame
/// turned by the version, the mean of the two eye pans, about its vertical axis through the
/// baseline's centre (`Pan(version) p`), then [`platform_to_base`]. Its `Z` axis is where the
/// eyes look on average, so in it each eye is turned from straight ahead by half the vergence
/// only; it is where a posture-aware model of
/// [`crate::runtime::blob::OutputFrame::Cyclopean`] gives its points. In `f32`, the same bits
/// on host and head.
pub fn cyclopean_to_base(joints_deg: [f32; 5], p: [f32; 3]) -> [f32; 3] {
    posture_to_base(
        [joints_deg[0], joints_deg[1], joints_deg[2]],
        version_deg(joints_deg[3], joints_deg[4]),
        p,
    )
}

/// A base-frame point `p` in the cyclopean frame: the inverse of [`cyclopean_to_base`].
pub fn base_to_cyclopean(joints_deg: [f32; 5], p: [f32; 3]) -> [f32; 3] {
    base_to_posture(
        [joints_deg[0], joints_deg[1], joints_deg[2]],
        version_deg(joints_deg[3], joints_deg[4]),
        p,
    )
}

/// A point `p` of the eye platform's frame turned by `version_deg` about its vertical axis,
/// in the base frame: `Pan(version) p`, then [`platform_to_base`] at neck pan, neck tilt and
/// eye tilt `angles_deg`. A version of 0 is the eye platform's frame itself, bit for bit (one
/// code path for both posture frames keeps the head's image small).
pub fn posture_to_base(angles_deg: [f32; 3], version_deg: f32, p: [f32; 3]) -> [f32; 3] {
    let q = if version_deg == 0.0 {
        p
    } else {
        let (sv, cv) = sin_cos(version_deg * DEG_TO_RAD);
        [cv * p[0] - sv * p[2], p[1], sv * p[0] + cv * p[2]]
    };
    platform_to_base(angles_deg, q)
}

/// A base-frame point `p` in the frame of [`posture_to_base`]: its inverse.
pub fn base_to_posture(angles_deg: [f32; 3], version_deg: f32, p: [f32; 3]) -> [f32; 3] {
    let q = base_to_platform(angles_deg, p);
    if version_deg == 0.0 {
        return q;
    }
    let (sv, cv) = sin_cos(version_deg * DEG_TO_RAD);
    [cv * q[0] + sv * q[2], q[1], cv * q[2] - sv * q[0]]
}

/// The version (degrees): the mean of the left and right eye pans.
pub fn version_deg(left_pan_deg: f32, right_pan_deg: f32) -> f32 {
    0.5 * (left_pan_deg + right_pan_deg)
}

/// Active rotation of the head in the base frame: pan (outer) then tilt (inner).
fn neck_rotation(pan_deg: f32, tilt_deg: f32) -> [[f32; 3]; 3] {
    mat_mul(&rot_pan(pan_deg * DEG_TO_RAD), &rot_tilt(tilt_deg * DEG_TO_RAD))
}

/// Active pan: turns `+Z` towards `-X` for a positive angle (rotation about `-Y`).
fn rot_pan(a: f32) -> [[f32; 3]; 3] {
    let (s, c) = sin_cos(a);
    [[c, 0.0, -s], [0.0, 1.0, 0.0], [s, 0.0, c]]
}

/// Active tilt: turns `+Z` towards `+Y` (down) for a positive angle (rotation about `-X`).
fn rot_tilt(b: f32) -> [[f32; 3]; 3] {
    let (s, c) = sin_cos(b);
    [[1.0, 0.0, 0.0], [0.0, c, s], [0.0, -s, c]]
}

fn mat_mul(a: &[[f32; 3]; 3], b: &[[f32; 3]; 3]) -> [[f32; 3]; 3] {
    let mut m = [[0.0; 3]; 3];
    for (i, row) in m.iter_mut().enumerate() {
        for (j, v) in row.iter_mut().enumerate() {
            *v = a[i][0] * b[0][j] + a[i][1] * b[1][j] + a[i][2] * b[2][j];
        }
    }
    m
}

fn transpose(a: &[[f32; 3]; 3]) -> [[f32; 3]; 3] {
    [[a[0][0], a[1][0], a[2][0]], [a[0][1], a[1][1], a[2][1]], [a[0][2], a[1][2], a[2][2]]]
}

fn mat_vec(a: &[[f32; 3]; 3], v: [f32; 3]) -> [f32; 3] {
    [dot(a[0], v), dot(a[1], v), dot(a[2], v)]
}

fn mat_t_vec(a: &[[f32; 3]; 3], v: [f32; 3]) -> [f32; 3] {
    mat_vec(&transpose(a), v)
}

fn dot(a: [f32; 3], b: [f32; 3]) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn add(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

fn sub(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn scale(a: [f32; 3], k: f32) -> [f32; 3] {
    [a[0] * k, a[1] * k, a[2] * k]
}

/// Euclidean length (no overflow guard: callers bound their inputs).
fn norm(a: [f32; 3]) -> f32 {
    sqrt(dot(a, a))
}

/// The square root of `x`, correctly rounded to nearest as IEEE 754 requires: the same bits as
/// `libm::sqrtf` for every `x` (NaN payloads aside; a negative `x` gives NaN, `-0` gives `-0`,
/// `+inf` gives `+inf`). fdlibm's bit-by-bit method (`e_sqrtf.c`): the 24-bit root of the
/// mantissa is built one bit per step from the integer remainder, then rounded from whether a
/// remainder is left. About 25 steps of a few integer instructions, and small: libm's fast
/// version needs a 256 B table, which a look (a few roots) does not need.
pub fn sqrt(x: f32) -> f32 {
    let bits = x.to_bits();
    if bits & 0x7f80_0000 == 0x7f80_0000 {
        // NaN stays NaN, +inf stays +inf, -inf gives NaN.
        return x * x + x;
    }
    if bits & 0x7fff_ffff == 0 {
        return x; // +-0
    }
    if bits >> 31 != 0 {
        return f32::NAN;
    }
    let mut ix = bits as i32;
    let mut m = ix >> 23;
    if m == 0 {
        // Subnormal: normalise.
        let mut i = 0;
        while ix & 0x0080_0000 == 0 {
            ix <<= 1;
            i += 1;
        }
        m -= i - 1;
    }
    m -= 127;
    ix = (ix & 0x007f_ffff) | 0x0080_0000;
    if m & 1 == 1 {
        ix += ix;
    }
    m >>= 1;
    ix += ix;
    let (mut q, mut s, mut r) = (0i32, 0i32, 0x0100_0000i32);
    while r != 0 {
        let t = s + r;
        if t <= ix {
            s = t + r;
            ix -= t;
            q += r;
        }
        ix += ix;
        r >>= 1;
    }
    if ix != 0 {
        q += q & 1; // round to nearest (a root is never exactly halfway)
    }
    f32::from_bits((((q >> 1) + 0x3f00_0000) + (m << 23)) as u32)
}

/// `(sin x, cos x)` for `x` in radians, within 2 ulp of the true values for `|x| <= 2π`
/// (accurate well beyond; NaN for non-finite `x`). Reduction to `|r| <= π/4` with a
/// three-part `π/2` (Cody-Waite, Cephes constants), then the minimax polynomials of musl's
/// `__sindf`/`__cosdf`, evaluated in `f32`.
pub fn sin_cos(x: f32) -> (f32, f32) {
    const FRAC_2_PI: f32 = core::f32::consts::FRAC_2_PI;
    const PIO2_1: f32 = 1.5703125;
    const PIO2_2: f32 = 4.837_513e-4;
    const PIO2_3: f32 = 7.549_79e-8;
    const S1: f32 = -0.166_666_67;
    const S2: f32 = 0.008_333_329;
    const S3: f32 = -0.000_198_393_35;
    const S4: f32 = 2.718_311_5e-6;
    const C0: f32 = -0.5;
    const C1: f32 = 0.041_666_623;
    const C2: f32 = -0.001_388_676_4;
    const C3: f32 = 2.439_045e-5;
    let k = roundf(x * FRAC_2_PI);
    let r = ((x - k * PIO2_1) - k * PIO2_2) - k * PIO2_3;
    let z = r * r;
    let s = r + r * z * (S1 + z * (S2 + z * (S3 + z * S4)));
    let c = 1.0 + z * (C0 + z * (C1 + z * (C2 + z * C3)));
    match (k as i32) & 3 {
        0 => (s, c),
        1 => (c, -s),
        2 => (-s, -c),
        _ => (-c, s),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    extern crate std;
    use libm::{cosf, sinf};
    use proptest::prelude::*;

    /// `sqrt` against libm's on every 257th f32 pattern (both signs, subnormals, infinities,
    /// NaNs) and around 1, 2 and 4: the same bits, or NaN for NaN.
    #[test]
    fn sqrt_gives_libms_bits() {
        let bits = crate::runtime::mlp::fixture::f32_sweep(257, &[1.0, 2.0, 4.0]).chain(0..4096);
        check_sqrt(bits);
    }

    /// Every f32: `cargo test --release -p hvs-shared --lib sqrt_on_every -- --ignored`.
    #[test]
    #[ignore]
    fn sqrt_on_every_f32_gives_libms_bits() {
        let parts: std::vec::Vec<_> = (0..4u32)
            .map(|t| std::thread::spawn(move || check_sqrt(t << 30..=(t << 30) | 0x3fff_ffff)))
            .collect();
        for p in parts {
            p.join().unwrap();
        }
    }

    fn check_sqrt(bits: impl Iterator<Item = u32>) {
        for b in bits {
            let x = f32::from_bits(b);
            let (got, want) = (sqrt(x), libm::sqrtf(x));
            assert!(
                got.to_bits() == want.to_bits() || (got.is_nan() && want.is_nan()),
                "sqrt({x:e}) = {got:e} ({:#x}), libm {want:e} ({:#x})",
                got.to_bits(),
                want.to_bits()
            );
        }
    }

    /// `got` is the rotation `r` of `p` and `back` turns it back, to f32 rounding.
    fn assert_turn(r: &[[f32; 3]; 3], p: [f32; 3], got: [f32; 3], back: [f32; 3]) {
        let want = mat_vec(r, p);
        for i in 0..3 {
            assert!((got[i] - want[i]).abs() < 1e-4, "{p:?}: {got:?} {want:?}");
            assert!((back[i] - p[i]).abs() < 1e-4, "{p:?}: {back:?}");
        }
    }

    #[test]
    fn platform_frame_is_the_chain_of_neck_pan_neck_tilt_eye_tilt() {
        for (k, angles) in
            [[0.0f32, 0.0, 0.0], [30.0, -20.0, 15.0], [-12.6, 7.2, -9.0], [-30.0, 20.0, -15.0]]
                .into_iter()
                .enumerate()
        {
            let p = [12.0 - k as f32, -7.0 + 2.0 * k as f32, 80.0 + 20.0 * k as f32];
            // The chain as matrices: Pan(neck pan) Tilt(neck tilt) Tilt(eye tilt).
            let r =
                mat_mul(&neck_rotation(angles[0], angles[1]), &rot_tilt(angles[2] * DEG_TO_RAD));
            let got = platform_to_base(angles, p);
            let back = base_to_platform(angles, got);
            assert_turn(&r, p, got, back);
            if angles == [0.0; 3] {
                // Home: the identity, bit for bit.
                assert_eq!(got, p);
                assert_eq!(back, p);
            }
        }
    }

    #[test]
    fn cyclopean_frame_is_the_platform_turned_by_the_version() {
        for (k, j) in [
            [0.0f32, 0.0, 0.0, 0.0, 0.0],
            [30.0, -20.0, 15.0, 12.0, 4.0],
            [-12.6, 7.2, -9.0, -20.0, -10.0],
            [0.0, 0.0, 0.0, 5.0, -5.0],
        ]
        .into_iter()
        .enumerate()
        {
            let p = [12.0 - k as f32, -7.0 + 2.0 * k as f32, 80.0 + 20.0 * k as f32];
            // The chain as matrices: the platform's rotation, then Pan(version).
            let platform = mat_mul(&neck_rotation(j[0], j[1]), &rot_tilt(j[2] * DEG_TO_RAD));
            let r = mat_mul(&platform, &rot_pan(0.5 * (j[3] + j[4]) * DEG_TO_RAD));
            let got = cyclopean_to_base(j, p);
            assert_turn(&r, p, got, base_to_cyclopean(j, got));
            if version_deg(j[3], j[4]) == 0.0 {
                // No version: the eye platform's frame, bit for bit.
                assert_eq!(got, platform_to_base([j[0], j[1], j[2]], p));
            }
        }
        // A positive version (both eyes panned towards -X) puts the frame's Z axis there.
        let z = cyclopean_to_base([0.0, 0.0, 0.0, 10.0, 10.0], [0.0, 0.0, 1.0]);
        assert!(z[0] < -0.17 && z[2] > 0.98, "{z:?}");
    }

    #[test]
    fn sin_cos_matches_libm() {
        let mut worst = 0.0f32;
        for i in -200_000..=200_000 {
            let x = i as f32 * (2.0 * core::f32::consts::PI / 200_000.0);
            let (s, c) = sin_cos(x);
            worst = worst.max((s - sinf(x)).abs()).max((c - cosf(x)).abs());
        }
        assert!(worst <= 1.2e-7, "worst {worst}");
        std::eprintln!("sin_cos worst {worst:e}");
        assert_eq!(sin_cos(0.0), (0.0, 1.0));
        let (s, c) = sin_cos(core::f32::consts::FRAC_PI_2);
        assert!((s - 1.0).abs() < 6e-8 && c.abs() < 1e-7);
        let (s, c) = sin_cos(-core::f32::consts::PI);
        assert!(s.abs() < 1e-7 && (c + 1.0).abs() < 6e-8);
        assert!(sin_cos(f32::NAN).0.is_nan());
    }

    fn close(a: f32, b: f32, tol: f32) -> bool {
        (a - b).abs() <= tol
    }

    /// Largest distance of the two optic axes from `p`.
    fn miss(geometry: &HeadGeometry, j: &Joints, p: [f32; 3]) -> f32 {
        let l = eye_pose(geometry, j, Eye::Left).optic_axis().distance_to(p);
        let r = eye_pose(geometry, j, Eye::Right).optic_axis().distance_to(p);
        l.max(r)
    }

    #[test]
    fn straight_ahead_at_one_metre_verges_symmetrically() {
        let f = fixate(&GazeConfig::DEFAULT, [0.0, 0.0, 100.0]).unwrap();
        let a = libm::atan(5.25f64 / 100.0).to_degrees() as f32; // 3.0050...
        assert!(!f.clamped);
        assert_eq!(f.joints[Axis::NeckPan], 0.0);
        assert_eq!(f.joints[Axis::NeckTilt], 0.0);
        assert_eq!(f.joints[Axis::EyeTilt], 0.0);
        assert!(close(f.joints[Axis::LeftEyePan], -a, 1e-5), "{f:?}");
        assert!(close(f.joints[Axis::RightEyePan], a, 1e-5), "{f:?}");
        assert!(close(a, 3.005269, 1e-5));
    }

    #[test]
    fn neck_takes_its_share_of_azimuth_and_elevation() {
        // Target 30° to the right and level: neck pans -15° (right is negative).
        let t = [100.0 * libm::sinf(30.0 * DEG_TO_RAD), 0.0, 100.0 * libm::cosf(30.0 * DEG_TO_RAD)];
        let f = fixate(&GazeConfig::DEFAULT, t).unwrap();
        assert!(close(f.joints[Axis::NeckPan], -15.0, 1e-4), "{f:?}");
        assert_eq!(f.joints[Axis::NeckTilt], 0.0);
        // Target 20° below straight ahead: neck tilts +10° (down is positive).
        let t = [0.0, 200.0 * libm::sinf(20.0 * DEG_TO_RAD), 200.0 * libm::cosf(20.0 * DEG_TO_RAD)];
        let f = fixate(&GazeConfig::DEFAULT, t).unwrap();
        assert!(close(f.joints[Axis::NeckTilt], 10.0, 1e-4), "{f:?}");
        assert!(close(f.joints[Axis::EyeTilt], 10.0, 1e-3), "{f:?}");
        assert_eq!(f.joints[Axis::NeckPan], 0.0);
        // Eyes only.
        let cfg = GazeConfig { neck_share: 0.0, ..GazeConfig::DEFAULT };
        let f = fixate(&cfg, t).unwrap();
        assert_eq!(f.joints[Axis::NeckTilt], 0.0);
        assert!(close(f.joints[Axis::EyeTilt], 20.0, 1e-4), "{f:?}");
    }

    #[test]
    fn pose_at_neck_home_is_the_thesis_omega() {
        // Eq. 3.1-3 with roll 0, written out term by term.
        let (a, b) = (12.0f32 * DEG_TO_RAD, -7.0f32 * DEG_TO_RAD);
        let (sa, ca, sb, cb) = (sinf(a), cosf(a), sinf(b), cosf(b));
        let omega = [[ca, sa * sb, sa * cb], [0.0, cb, -sb], [-sa, ca * sb, ca * cb]];
        let j = Joints([0.0, 0.0, -7.0, 12.0, 0.0]);
        let pose = eye_pose(&HeadGeometry::DEFAULT, &j, Eye::Left);
        assert_eq!(pose.centre, [-5.25, 0.0, 0.0]);
        for (got, want) in pose.rot.iter().flatten().zip(omega.iter().flatten()) {
            assert!(close(*got, *want, 1e-6), "{:?} vs {omega:?}", pose.rot);
        }
        // Eq. 3.1-4 for a point: X_L = (X_s + d) ω11 + Y_s ω12 + Z_s ω13.
        let p = [10.0, -4.0, 80.0];
        let cam = pose.to_camera(p);
        let xl = (p[0] + 5.25) * omega[0][0] + p[1] * omega[0][1] + p[2] * omega[0][2];
        assert!(close(cam[0], xl, 1e-4));
    }

    #[test]
    fn neck_moves_the_eyes() {
        // Neck panned +90° (left): the head's +X turns to base +Z, so the right eye sits at
        // (0, 0, +d) and looks along -X.
        let j = Joints([90.0, 0.0, 0.0, 0.0, 0.0]);
        let pose = eye_pose(&HeadGeometry::DEFAULT, &j, Eye::Right);
        let ray = pose.optic_axis();
        assert!(close(ray.origin[0], 0.0, 1e-5) && close(ray.origin[2], 5.25, 1e-5));
        assert!(close(ray.dir[0], -1.0, 1e-6) && close(ray.dir[2], 0.0, 1e-6));
        // Neck tilted +90° (down) about a centre 10 cm behind: eyes move down and back.
        let g = HeadGeometry { neck_centre_cm: [0.0, 0.0, -10.0], ..HeadGeometry::DEFAULT };
        let j = Joints([0.0, 90.0, 0.0, 0.0, 0.0]);
        let pose = eye_pose(&g, &j, Eye::Left);
        assert!(close(pose.centre[1], 10.0, 1e-5) && close(pose.centre[2], -10.0, 1e-5));
        assert!(close(pose.optic_axis().dir[1], 1.0, 1e-6));
    }

    #[test]
    fn bad_targets_are_refused() {
        let cfg = GazeConfig::DEFAULT;
        for t in
            [[f32::NAN, 0.0, 100.0], [0.0, f32::INFINITY, 100.0], [0.0, 0.0, f32::NEG_INFINITY]]
        {
            assert_eq!(fixate(&cfg, t), Err(GazeError::NonFinite));
        }
        assert_eq!(fixate(&cfg, [0.0, 0.0, 0.0]), Err(GazeError::BehindHead));
        assert_eq!(fixate(&cfg, [50.0, 0.0, -1.0]), Err(GazeError::BehindHead));
        assert_eq!(fixate(&cfg, [0.0, 3.0, 9.0]), Err(GazeError::TooClose));
        assert!(fixate(&cfg, [0.0, 0.0, 10.0]).is_ok());
    }

    #[test]
    fn far_lateral_target_is_reached_by_giving_the_excess_to_the_neck() {
        // 80° to the left: half (40°) would leave 40° for the eyes, beyond their 35°.
        let a = 80.0 * DEG_TO_RAD;
        let t = [-300.0 * sinf(a), 0.0, 300.0 * cosf(a)];
        let f = fixate(&GazeConfig::DEFAULT, t).unwrap();
        assert!(!f.clamped, "{f:?}");
        assert!(f.joints[Axis::NeckPan] > 40.0, "{f:?}");
        assert!(miss(&HeadGeometry::DEFAULT, &f.joints, t) < 1e-3);
        // 80° down is out of reach (35° neck + 30° eyes): clamped, within limits.
        let t = [0.0, 300.0 * sinf(a), 300.0 * cosf(a)];
        let f = fixate(&GazeConfig::DEFAULT, t).unwrap();
        assert!(f.clamped);
        assert_eq!(f.joints[Axis::NeckTilt], 35.0);
        assert_eq!(f.joints[Axis::EyeTilt], 30.0);
    }

    #[test]
    fn far_targets_are_pulled_in_not_refused() {
        let f = fixate(&GazeConfig::DEFAULT, [f32::MAX, f32::MAX, f32::MAX]).unwrap();
        assert!(GazeConfig::DEFAULT.limits.contains(&f.joints));
        let f = fixate(&GazeConfig::DEFAULT, [0.0, 0.0, 1e30]).unwrap();
        assert!(f.joints.0.iter().all(|v| v.abs() < 1e-2), "{f:?}");
    }

    #[test]
    fn quantisation_is_in_steps_of_0_18_degrees() {
        assert_eq!(STEP_DEG, 0.18);
        assert_eq!(to_steps(0.0), 0);
        assert_eq!(to_steps(0.08), 0);
        assert_eq!(to_steps(0.1), 1);
        assert_eq!(to_steps(0.36), 2);
        assert_eq!(to_steps(-0.28), -2);
        assert_eq!(to_steps(90.0), 500);
        assert_eq!(to_steps(f32::NAN), 0);
        assert_eq!(to_steps(f32::INFINITY), i32::MAX);
        assert_eq!(quantize(1.0), 0.18 * 6.0);
        assert_eq!(quantize(-1.0), -0.18 * 6.0);
        assert!(close(quantize(10.0) - quantize(9.9), 0.18, 1e-6));
        assert_eq!(quantize(f32::NAN), 0.0);
    }

    #[test]
    fn step_ranges_stay_inside_the_limits() {
        let l = JointLimits::DEFAULT;
        assert_eq!(l.step_range(Axis::NeckPan), (-333, 333));
        assert_eq!(l.step_range(Axis::EyeTilt), (-166, 166));
        // 36° = 200 steps exactly in reals: whatever f32 does, the bound is inside.
        let mut l2 = l;
        l2.0[0] = lim(-36.0, 36.0, 100.0);
        let (lo, hi) = l2.step_range(Axis::NeckPan);
        assert!(from_steps(lo) >= -36.0 && from_steps(hi) <= 36.0);
        assert!(hi >= 199 && lo <= -199);
    }

    #[test]
    fn limits_validation() {
        let l = JointLimits::DEFAULT;
        assert_eq!(l.validate(100), Ok(()));
        let mut bad = l;
        bad.0[2] = lim(5.0, 30.0, 100.0);
        assert_eq!(bad.validate(100), Err(LimitsError::Range(Axis::EyeTilt)));
        bad.0[2] = lim(-5.0, f32::NAN, 100.0);
        assert_eq!(bad.validate(100), Err(LimitsError::Range(Axis::EyeTilt)));
        let mut bad = l;
        bad.0[4] = lim(-5.0, 5.0, 17.0); // under 0.18° per 10 ms tick
        assert_eq!(bad.validate(100), Err(LimitsError::Velocity(Axis::RightEyePan)));
        assert_eq!(bad.validate(50), Ok(()));
        assert_eq!(l.validate(0), Err(LimitsError::Velocity(Axis::NeckPan)));
        assert_eq!(max_steps_per_tick(180.0, 100), 10);
        assert_eq!(max_steps_per_tick(400.0, 100), 22);
    }

    #[test]
    fn clamp_maps_nan_home_and_inf_to_the_bounds() {
        let l = JointLimits::DEFAULT;
        let j = l.clamp(&Joints([f32::NAN, f32::INFINITY, f32::NEG_INFINITY, 1e9, -3.0]));
        assert_eq!(j, Joints([0.0, 35.0, -30.0, 35.0, -3.0]));
        assert!(l.contains(&j));
        assert!(!l.contains(&Joints([f32::NAN, 0.0, 0.0, 0.0, 0.0])));
    }

    const SPECIAL: [f32; 10] = [
        f32::NAN,
        f32::INFINITY,
        f32::NEG_INFINITY,
        0.0,
        -0.0,
        f32::MAX,
        f32::MIN,
        f32::MIN_POSITIVE,
        1e-30,
        -1e30,
    ];

    fn any_coord() -> impl Strategy<Value = f32> {
        prop_oneof![
            4 => -500.0f32..500.0,
            1 => any::<f32>(),
            1 => prop::sample::select(&SPECIAL[..]),
        ]
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(4000))]

        #[test]
        fn any_target_gives_an_error_or_joints_within_limits(
            x in any_coord(), y in any_coord(), z in any_coord(), share in any::<f32>()
        ) {
            let cfg = GazeConfig { neck_share: share, ..GazeConfig::DEFAULT };
            match fixate(&cfg, [x, y, z]) {
                Ok(f) => {
                    prop_assert!(cfg.limits.contains(&f.joints), "{:?}", f);
                    prop_assert!(z > 0.0);
                }
                Err(GazeError::NonFinite) => {
                    prop_assert!(!(x.is_finite() && y.is_finite() && z.is_finite()))
                }
                Err(GazeError::BehindHead) => prop_assert!(z <= 0.0),
                Err(GazeError::TooClose) => prop_assert!(norm([x, y, z]) < 10.0),
            }
        }

        #[test]
        fn reachable_targets_are_fixated_by_both_eyes(
            az in -75.0f32..75.0, el in -50.0f32..50.0, dist in 25.0f32..2000.0,
            share in 0.0f32..1.0,
            cy in -10.0f32..10.0, cz in -10.0f32..0.0,
        ) {
            let geometry = HeadGeometry { half_baseline_cm: 5.25, neck_centre_cm: [0.0, cy, cz] };
            let cfg = GazeConfig { geometry, neck_share: share, ..GazeConfig::DEFAULT };
            let (a, e) = (az * DEG_TO_RAD, el * DEG_TO_RAD);
            let t = [-dist * sinf(a) * cosf(e), dist * sinf(e), dist * cosf(a) * cosf(e)];
            let f = fixate(&cfg, t).unwrap();
            prop_assert!(cfg.limits.contains(&f.joints));
            if !f.clamped {
                let m = miss(&geometry, &f.joints, t);
                prop_assert!(m < 2e-6 * dist + 1e-4, "miss {} cm for {:?}", m, f);
            }
            // Within ±(neck + eye limits)/2 nothing needs clamping.
            if az.abs() < 45.0 && el.abs() < 30.0 && dist > 50.0 {
                prop_assert!(!f.clamped, "{:?}", f);
            }
        }
    }
}
