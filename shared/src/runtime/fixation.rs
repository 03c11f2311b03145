//! The closed loop's step: from the target's pixels in both images and the current joint
//! positions to the joint targets that keep the target in the middle of both eyes.
//!
//! One [`step`] per camera frame, pure and allocation-free (the firmware and every simulated
//! head call the same function):
//!
//! 1. **Estimate** X, Y, Z of the target with the head's estimator
//!    ([`Estimator::estimate`], posture-aware nets get the five joints as extra inputs).
//! 2. **Kinematics**: [`gaze::fixate`] of the estimate (neck/eye split, limits).
//! 3. **Image correction**: with the case's camera errors the nominal kinematics miss; what
//!    the images show corrects it. The angle by which each eye misses the target at the
//!    current posture (`atan((u - u0) / phi)` per eye for the pans, the mean over both eyes of
//!    `atan((v - v0) / phi)` for the conjugate tilt) added to the current joints is where the
//!    eyes should be; its difference with the kinematic fixation of the same frame is the
//!    kinematics' miss. The state keeps a low-pass filtered miss (the integral part, gain
//!    [`LoopConfig::gain`], never more than [`LoopConfig::max_correction_deg`]) and adds it to
//!    the fixation; the proportional part is the fresh fixation itself.
//! 4. **Lead**: a moving target is aimed at where it will be: the state keeps the estimate's
//!    change per frame, low-pass filtered (gain [`LoopConfig::velocity_gain`]), and the
//!    kinematics fixate the estimate plus [`LoopConfig::lead_frames`] frames of it (the image
//!    correction still compares the fixation of the estimate itself with what the images show).
//! 5. The result is quantised to the drives' 0.18 degree steps and clamped to the limits:
//!    whatever the input (NaN, infinities, huge pixels), the command is within the limits.
//!
//! Without a target (lost), the head holds the last command, and after
//! [`LoopConfig::home_after_frames`] lost frames in a row it turns home (straight ahead, the
//! eyes parallel: the widest view) to look again; without an estimate (the estimator refused
//! the pixels) it servos on the image alone (current joints + the miss).

use crate::runtime::gaze::{self, Axis, GazeConfig, Joints};
use crate::runtime::head::Estimator;
use crate::runtime::protocol::StereoPoint;

/// Settings of the loop.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LoopConfig {
    /// Fixation settings (neck/eye split, limits).
    pub gaze: GazeConfig,
    /// Image centre `(u0, v0)` (px): where the target should be seen.
    pub centre_px: [f32; 2],
    /// Focal lengths `[phi_u_left, phi_v_left, phi_u_right, phi_v_right]` (px), nominal.
    pub focal_px: [f32; 4],
    /// Share of the newly measured kinematic miss taken into the correction each frame
    /// (0 = no image correction, the kinematics alone; 1 = the last frame's miss).
    pub gain: f32,
    /// Largest correction of any eye axis (degrees).
    pub max_correction_deg: f32,
    /// Frames of the target's motion the fixation leads it by (0: aim where it is seen).
    pub lead_frames: f32,
    /// Share of the newest change of the estimate taken into its filtered velocity per frame.
    pub velocity_gain: f32,
    /// Lost frames in a row after which the head turns home to look for a target again (0:
    /// it holds the last command however long the target stays lost).
    pub home_after_frames: u32,
}

impl LoopConfig {
    /// Default gaze settings, the thesis' 640 x 480 cameras (`phi` 285.8 px), gain 0.5, at
    /// most 10 degrees of correction, home after 60 lost frames (2 s at 30 frames/s).
    pub const DEFAULT: LoopConfig = LoopConfig {
        gaze: GazeConfig::DEFAULT,
        centre_px: [320.0, 240.0],
        focal_px: [285.836; 4],
        gain: 0.5,
        max_correction_deg: 10.0,
        lead_frames: 0.0,
        velocity_gain: 0.3,
        home_after_frames: 60,
    };
}

/// What the loop remembers between frames.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LoopState {
    /// The filtered kinematic miss: `[eye tilt, left eye pan, right eye pan]` (degrees).
    pub correction_deg: [f32; 3],
    /// The last command (held when the target is lost).
    pub last: Joints,
    /// The last frame's estimate (cm, head frame), `None` when it had none.
    pub last_estimate: Option<[f32; 3]>,
    /// The estimate's filtered change per frame (cm).
    pub velocity: [f32; 3],
    /// Frames in a row without a target.
    pub lost_frames: u32,
}

/// One frame's input.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Observation {
    /// The target's pixels `(u_l, v_l, u_r, v_r)`, `None` when not found in this frame:
    /// what the image correction brings to the image centres.
    pub target: Option<StereoPoint>,
    /// Where the target is estimated, when not at `target`: the pixels of one point of its
    /// visible surface (an object's centre seen in each image, `target`, is not a point of
    /// its surface: a sphere's centre lies a radius behind the surface the eyes see).
    pub surface: Option<StereoPoint>,
    /// Where the joints are (degrees) when the frame was taken.
    pub joints: Joints,
}

/// How the frame went.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LoopStatus {
    /// Estimated, fixated and corrected.
    Tracking,
    /// The estimator refused the pixels: the image correction alone moved the eyes.
    ImageOnly,
    /// No target in this frame: the last command is held (home after
    /// [`LoopConfig::home_after_frames`] such frames in a row).
    Lost,
}

/// One frame's output.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Command {
    /// Joint targets (degrees): on the step grid, within the limits.
    pub joints: Joints,
    /// The estimate (cm, head frame), `None` without one.
    pub estimate: Option<[f32; 3]>,
    /// How the frame went.
    pub status: LoopStatus,
}

/// The eye axes the image corrects, in the order of [`LoopState::correction_deg`].
const EYE_AXES: [Axis; 3] = [Axis::EyeTilt, Axis::LeftEyePan, Axis::RightEyePan];

const RAD_TO_DEG: f32 = 180.0 / core::f32::consts::PI;

/// Largest filtered velocity kept (cm per frame): anything faster is a wrong estimate.
const MAX_VELOCITY_CM: f32 = 50.0;
/// Largest change of the estimate between frames taken as the target's motion (cm): 3 m/s
/// at 30 frames/s. A larger one resets the motion.
const MAX_JUMP_CM: f32 = 10.0;
/// Slowest sideways motion (cm per frame, filtered) the fixation leads: below it the
/// estimate's frame-to-frame noise, not motion (20 cm/s at 30 frames/s is 0.67).
const MIN_LEAD_VELOCITY_CM: f32 = 0.25;
/// Largest lead (frames).
pub const MAX_LEAD_FRAMES: f32 = 30.0;

/// The angles (degrees) by which the eyes miss the target at pixels `p`:
/// `[tilt, left pan, right pan]` to add to the joints. `None` if not finite.
fn image_miss(cfg: &LoopConfig, p: &StereoPoint) -> Option<[f32; 3]> {
    let [u0, v0] = cfg.centre_px;
    let [fu_l, fv_l, fu_r, fv_r] = cfg.focal_px;
    let ang = |e: f32, f: f32| libm::atanf(e / f) * RAD_TO_DEG;
    // A positive tilt turns the optic axis down (+v); a positive pan to the left (-u).
    let tilt = 0.5 * (ang(p.v_l - v0, fv_l) + ang(p.v_r - v0, fv_r));
    let m = [tilt, -ang(p.u_l - u0, fu_l), -ang(p.u_r - u0, fu_r)];
    m.iter().all(|x| x.is_finite()).then_some(m)
}

/// `x` clamped to `+-bound` (NaN gives 0; written out so that a NaN bound gives 0).
fn clamp_abs(x: f32, bound: f32) -> f32 {
    if bound.is_nan() || bound < 0.0 || x.is_nan() {
        0.0
    } else if x > bound {
        bound
    } else if x < -bound {
        -bound
    } else {
        x
    }
}

/// Joints on the step grid within the limits (NaN goes home).
fn safe(cfg: &GazeConfig, j: &Joints) -> Joints {
    let limits = &cfg.limits;
    Joints(Axis::ALL.map(|axis| {
        let (lo, hi) = limits.step_range(axis);
        gaze::from_steps(gaze::to_steps(limits.clamp_axis(axis, j[axis])).clamp(lo, hi))
    }))
}

/// One frame of the loop (see the module documentation).
pub fn step(
    cfg: &LoopConfig,
    estimator: &Estimator,
    state: &LoopState,
    obs: &Observation,
) -> (LoopState, Command) {
    let mut next = *state;
    // A state from elsewhere may hold anything: keep the correction bounded and finite.
    for c in next.correction_deg.iter_mut() {
        *c = clamp_abs(*c, cfg.max_correction_deg);
    }
    next.last = safe(&cfg.gaze, &next.last);
    for v in next.velocity.iter_mut() {
        *v = clamp_abs(*v, MAX_VELOCITY_CM);
    }
    let Some(p) = obs.target else {
        (next.last_estimate, next.velocity) = (None, [0.0; 3]);
        next.lost_frames = next.lost_frames.saturating_add(1);
        if cfg.home_after_frames > 0 && next.lost_frames >= cfg.home_after_frames {
            next.last = safe(&cfg.gaze, &Joints::HOME);
        }
        return (next, Command { joints: next.last, estimate: None, status: LoopStatus::Lost });
    };
    next.lost_frames = 0;
    let now = safe(&cfg.gaze, &obs.joints);
    let miss = image_miss(cfg, &p);
    let estimate = estimator
        .estimate(&obs.surface.unwrap_or(p), &now)
        .ok()
        .map(|e| [e.x, e.y, e.z])
        .filter(|e| e.iter().all(|x| x.is_finite()));
    let fix = estimate.and_then(|e| gaze::fixate(&cfg.gaze, e).ok());
    // The lead: the fixation of where the target will be `lead_frames` on.
    let (lead, vg) =
        (clamp_abs(cfg.lead_frames, MAX_LEAD_FRAMES), clamp_abs(cfg.velocity_gain, 1.0));
    match (estimate, next.last_estimate.filter(|l| l.iter().all(|x| x.is_finite()))) {
        // A jump is another target (the scan took a nearer one) or a wrong estimate, not
        // motion: the motion starts again from rest.
        (Some(e), Some(l)) if (0..3).any(|k| libm::fabsf(e[k] - l[k]) > MAX_JUMP_CM) => {
            next.velocity = [0.0; 3];
        }
        (Some(e), Some(l)) => {
            for k in 0..3 {
                let v = next.velocity[k] + vg * ((e[k] - l[k]) - next.velocity[k]);
                next.velocity[k] = clamp_abs(v, MAX_VELOCITY_CM);
            }
        }
        _ => next.velocity = [0.0; 3],
    }
    next.last_estimate = estimate;
    let aim = match (estimate, fix) {
        (Some(e), Some(f))
            if lead > 0.0
                && libm::hypotf(next.velocity[0], next.velocity[1]) >= MIN_LEAD_VELOCITY_CM =>
        {
            let ahead: [f32; 3] = core::array::from_fn(|k| e[k] + lead * next.velocity[k]);
            Some(gaze::fixate(&cfg.gaze, ahead).unwrap_or(f))
        }
        _ => fix,
    };
    let gain = if cfg.gain > 0.0 { cfg.gain.min(1.0) } else { 0.0 };
    let (target, status) = match (fix, miss) {
        (Some(f), miss) => {
            if let Some(m) = miss {
                // The kinematics' miss at this frame: where the eyes should be minus where
                // the kinematics would put them.
                for (k, axis) in EYE_AXES.iter().enumerate() {
                    let seen = now[*axis] + m[k] - f.joints[*axis];
                    if seen.is_finite() {
                        let c = next.correction_deg[k] + gain * (seen - next.correction_deg[k]);
                        next.correction_deg[k] = clamp_abs(c, cfg.max_correction_deg);
                    }
                }
            }
            let mut j = aim.unwrap_or(f).joints;
            for (k, axis) in EYE_AXES.iter().enumerate() {
                j[*axis] += next.correction_deg[k];
            }
            (j, LoopStatus::Tracking)
        }
        (None, Some(m)) => {
            let mut j = now;
            for (k, axis) in EYE_AXES.iter().enumerate() {
                j[*axis] += gain * m[k];
            }
            (j, LoopStatus::ImageOnly)
        }
        (None, None) => (next.last, LoopStatus::Lost),
    };
    next.last = safe(&cfg.gaze, &target);
    (
        next,
        Command {
            joints: next.last,
            estimate: if status == LoopStatus::Tracking { estimate } else { None },
            status,
        },
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::runtime::head::tests::any_f32;
    use crate::runtime::traditional::Calibration;
    use proptest::prelude::*;

    fn fallback() -> Estimator {
        Estimator::Fallback(Calibration::BUILT_IN)
    }

    fn point(p: [f32; 4]) -> StereoPoint {
        StereoPoint { u_l: p[0], v_l: p[1], u_r: p[2], v_r: p[3] }
    }

    #[test]
    fn a_consistent_view_needs_no_correction_and_lost_holds() {
        // 20 px of disparity: about 150 cm straight ahead. At home the fallback's estimate
        // and the images agree, so the kinematics need no correction.
        let cfg = LoopConfig::DEFAULT;
        let obs = Observation {
            target: Some(point([330.0, 240.0, 310.0, 240.0])),
            joints: Joints::HOME,
            surface: None,
        };
        let (s, c) = step(&cfg, &fallback(), &LoopState::default(), &obs);
        assert_eq!(c.status, LoopStatus::Tracking);
        let z = c.estimate.unwrap()[2];
        assert!((140.0..160.0).contains(&z), "z {z}");
        assert!(s.correction_deg.iter().all(|c| c.abs() < 0.05), "{:?}", s.correction_deg);
        // Converging eyes: left turns right (negative pan), right turns left.
        assert!(c.joints[Axis::LeftEyePan] < -1.0 && c.joints[Axis::RightEyePan] > 1.0);
        assert!(cfg.gaze.limits.contains(&c.joints));
        let lost = Observation { target: None, joints: Joints::HOME, surface: None };
        let (_, c2) = step(&cfg, &fallback(), &s, &lost);
        assert_eq!(c2.status, LoopStatus::Lost);
        assert_eq!(c2.joints, c.joints);
    }

    #[test]
    fn a_long_lost_target_sends_the_head_home_and_a_found_one_resets_the_count() {
        let cfg = LoopConfig { home_after_frames: 5, ..LoopConfig::DEFAULT };
        let seen = Observation {
            target: Some(point([330.0, 240.0, 310.0, 240.0])),
            joints: Joints::HOME,
            surface: None,
        };
        let lost = Observation { target: None, joints: Joints::HOME, surface: None };
        let (mut s, c) = step(&cfg, &fallback(), &LoopState::default(), &seen);
        assert_ne!(c.joints, Joints::HOME, "the eyes converge on the target");
        for k in 1..5 {
            let c;
            (s, c) = step(&cfg, &fallback(), &s, &lost);
            assert_eq!((c.status, s.lost_frames), (LoopStatus::Lost, k));
            assert_ne!(c.joints, Joints::HOME, "held for {k} lost frames");
        }
        let c;
        (s, c) = step(&cfg, &fallback(), &s, &lost);
        assert_eq!((c.status, c.joints), (LoopStatus::Lost, Joints::HOME), "home at the 5th");
        assert_eq!(s.last, Joints::HOME);
        // Found again: the count starts over, the target is fixated.
        let (s2, c2) = step(&cfg, &fallback(), &s, &seen);
        assert_eq!((c2.status, s2.lost_frames), (LoopStatus::Tracking, 0));
        assert_ne!(c2.joints, Joints::HOME);
        // 0: held however long.
        let hold = LoopConfig { home_after_frames: 0, ..cfg };
        let mut s3 = LoopState { lost_frames: u32::MAX - 1, ..s2 };
        for _ in 0..3 {
            let c3;
            (s3, c3) = step(&hold, &fallback(), &s3, &lost);
            assert_eq!(c3.joints, c2.joints);
        }
        assert_eq!(s3.lost_frames, u32::MAX, "the count saturates");
    }

    /// Given surface pixels, the estimate is made there (a nearer point here: 2 px more
    /// disparity), and the image correction still centres the target's pixels.
    #[test]
    fn the_estimate_is_made_at_the_surface_pixels() {
        let cfg = LoopConfig { gain: 1.0, ..LoopConfig::DEFAULT };
        let (target, surface) =
            (point([330.0, 240.0, 310.0, 240.0]), point([330.0, 240.0, 308.0, 240.0]));
        let run = |surface| {
            let obs = Observation { target: Some(target), surface, joints: Joints::HOME };
            step(&cfg, &fallback(), &LoopState::default(), &obs).1
        };
        let (centre, front) = (run(None), run(Some(surface)));
        let at = |p: &StereoPoint| {
            let e = fallback().estimate(p, &Joints::HOME).unwrap();
            [e.x, e.y, e.z]
        };
        assert_eq!(centre.estimate, Some(at(&target)));
        assert_eq!(front.estimate, Some(at(&surface)));
        assert!(front.estimate.unwrap()[2] < centre.estimate.unwrap()[2]);
        assert_eq!(front.status, LoopStatus::Tracking);
    }

    #[test]
    fn a_target_to_the_right_and_below_turns_the_eyes_there() {
        let cfg = LoopConfig { gain: 1.0, ..LoopConfig::DEFAULT };
        // From home, a target right of and below the centre in both images.
        let obs = Observation {
            target: Some(point([360.0, 270.0, 350.0, 270.0])),
            joints: Joints::HOME,
            surface: None,
        };
        let (_, c) = step(&cfg, &fallback(), &LoopState::default(), &obs);
        let j = c.joints;
        assert!(j[Axis::LeftEyePan] < 0.0 && j[Axis::RightEyePan] < 0.0, "{j:?}");
        assert!(j[Axis::EyeTilt] + j[Axis::NeckTilt] > 0.0, "{j:?}");
    }

    #[test]
    fn the_correction_learns_a_constant_miss() {
        // The eyes are panned 1 degree to the left of where the (posture-blind) estimate
        // says they are: the image shows the target where it would be at home. The
        // kinematics miss by 1 degree on both pans; the correction learns it.
        let cfg = LoopConfig::DEFAULT;
        let mut s = LoopState::default();
        let obs = Observation {
            target: Some(point([330.0, 240.0, 310.0, 240.0])),
            surface: None,
            joints: Joints([0.0, 0.0, 0.0, 0.9, 0.9]),
        };
        for _ in 0..20 {
            s = step(&cfg, &fallback(), &s, &obs).0;
        }
        for k in [1, 2] {
            assert!((s.correction_deg[k] - 0.9).abs() < 0.01, "{:?}", s.correction_deg);
        }
        assert!(s.correction_deg[0].abs() < 1e-3);
        let (_, c) = step(&cfg, &fallback(), &s, &obs);
        // The command is the kinematics plus the learnt miss (on the step grid).
        let (_, plain) =
            step(&LoopConfig { gain: 0.0, ..cfg }, &fallback(), &LoopState::default(), &obs);
        let d = c.joints[Axis::LeftEyePan] - plain.joints[Axis::LeftEyePan];
        assert!((d - 0.9).abs() < 0.1, "{d}");
    }

    /// A target moving sideways at a steady pace: with a lead the command turns ahead of the
    /// fixation of where it is seen, by about the lead's worth of motion; without one (the
    /// default) it is that fixation; losing the target forgets the motion.
    #[test]
    fn a_moving_target_is_led() {
        let est = fallback();
        // The target moves right in both images by 2 px a frame (about 1 cm at 150 cm).
        let seen = |k: usize| {
            let du = 2.0 * k as f32;
            Observation {
                target: Some(point([330.0 + du, 240.0, 310.0 + du, 240.0])),
                surface: None,
                joints: Joints::HOME,
            }
        };
        let run = |cfg: &LoopConfig| {
            let mut s = LoopState::default();
            let mut c = None;
            for k in 0..30 {
                let (n, cmd) = step(cfg, &est, &s, &seen(k));
                (s, c) = (n, Some(cmd));
            }
            (s, c.unwrap())
        };
        let plain = LoopConfig { gain: 0.0, ..LoopConfig::DEFAULT };
        let (s0, c0) = run(&plain);
        let (s4, c4) = run(&LoopConfig { lead_frames: 4.0, ..plain });
        // The velocity is learnt either way (about 1 cm a frame in X), used only with a lead.
        assert!(
            (0.6..1.6).contains(&s0.velocity[0]) && s4.velocity == s0.velocity,
            "{:?}",
            s0.velocity
        );
        let ahead = c0.joints[Axis::NeckPan] - c4.joints[Axis::NeckPan]
            + c0.joints[Axis::LeftEyePan]
            - c4.joints[Axis::LeftEyePan];
        // Moving right (+X) turns the gaze to negative pans: the lead turns further.
        assert!(ahead > 0.5, "lead turned {ahead} degrees further");
        let last_fix = gaze::fixate(&plain.gaze, c0.estimate.unwrap()).unwrap();
        assert_eq!(c0.joints, safe(&plain.gaze, &last_fix.joints));
        let lost = Observation { target: None, joints: Joints::HOME, surface: None };
        let (s, _) = step(&plain, &est, &s4, &lost);
        assert_eq!((s.velocity, s.last_estimate), ([0.0; 3], None));
        // Another target (a nearer one, far to the left): a jump, not motion, and no lead.
        let other = Observation {
            target: Some(point([200.0, 240.0, 150.0, 240.0])),
            joints: Joints::HOME,
            surface: None,
        };
        let (s, c) = step(&LoopConfig { lead_frames: 4.0, ..plain }, &est, &s4, &other);
        assert_eq!(s.velocity, [0.0; 3]);
        let fix = gaze::fixate(&plain.gaze, c.estimate.unwrap()).unwrap();
        assert_eq!(c.joints, safe(&plain.gaze, &fix.joints));
    }

    proptest! {
        #[test]
        fn never_outside_limits(
            px in proptest::array::uniform4(any_f32()),
            joints in proptest::array::uniform5(any_f32()),
            corr in proptest::array::uniform3(any_f32()),
            last in proptest::array::uniform5(any_f32()),
            gain in any_f32(),
            seen in any::<bool>(),
            (lead, velocity_gain) in (any_f32(), any_f32()),
            (est, vel) in (proptest::array::uniform3(any_f32()), proptest::array::uniform3(any_f32())),
            (lost_frames, home_after_frames) in (any::<u32>(), 0u32..100),
        ) {
            let cfg = LoopConfig { gain, lead_frames: lead, velocity_gain, home_after_frames, ..LoopConfig::DEFAULT };
            let state = LoopState {
                correction_deg: corr,
                last: Joints(last),
                last_estimate: Some(est),
                velocity: vel,
                lost_frames: lost_frames % 100,
            };
            let obs = Observation {
                target: seen.then(|| point(px)),
                // Any surface pixels too (swapped: another point).
                surface: seen.then(|| point([px[2], px[3], px[0], px[1]])),
                joints: Joints(joints),
            };
            let (s, c) = step(&cfg, &fallback(), &state, &obs);
            prop_assert!(cfg.gaze.limits.contains(&c.joints), "{:?}", c.joints);
            for a in Axis::ALL {
                let steps = c.joints[a] / gaze::STEP_DEG;
                prop_assert!((steps - libm::roundf(steps)).abs() < 1e-3);
            }
            prop_assert!(s.correction_deg.iter().all(|x| x.is_finite() && x.abs() <= cfg.max_correction_deg));
            prop_assert!(s.velocity.iter().all(|v| v.is_finite() && v.abs() <= MAX_VELOCITY_CM));
            // And again from the returned state.
            let (_, c2) = step(&cfg, &fallback(), &s, &obs);
            prop_assert!(cfg.gaze.limits.contains(&c2.joints));
        }
    }
}
