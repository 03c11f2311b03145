//! Minimum-jerk joint trajectories, sampled at the control rate into safe setpoints.
//!
//! Each axis follows `x(t) = x0 + (x1 - x0)(10s³ - 15s⁴ + 6s⁵)`, `s = t/T` (Flash & Hogan),
//! with the neck slower than the eyes (`T` = 0.7 s and 0.2 s by default, as iCub's gaze
//! controller uses). A move whose peak speed `1.875 |x1 - x0| / T` would exceed 90 % of the
//! axis' speed limit is stretched until it does not.
//!
//! [`GazeController::start`] retargets from the **current setpoint**, carrying the current
//! velocity and acceleration (the quintic with those initial conditions), so a new target
//! mid-motion bends the path instead of stopping it dead.
//!
//! Every setpoint [`GazeController::tick`] returns is, whatever came before:
//! a whole number of 0.18° steps ([`crate::runtime::gaze::STEP_DEG`]), within the joint limits
//! ([`crate::runtime::gaze::JointLimits::step_range`]), and at most
//! [`crate::runtime::gaze::max_steps_per_tick`] steps from the previous setpoint. These hold by
//! construction (integer steps, clamped, then rate-limited) and are property-tested.
use libm::roundf;

use crate::runtime::gaze::{
    from_steps, max_steps_per_tick, Axis, JointLimits, Joints, LimitsError,
};

/// Control rate of the head controller, Hz (one setpoint per tick).
pub const CONTROL_HZ: u32 = 100;
/// Default duration of a neck movement, s.
pub const NECK_TIME_S: f32 = 0.7;
/// Default duration of an eye movement, s.
pub const EYE_TIME_S: f32 = 0.2;
/// Share of the speed limit a planned move may use at its peak (the rest absorbs
/// quantisation and retargeting).
const PLAN_SPEED_SHARE: f32 = 0.9;
/// Peak of the minimum-jerk speed profile, in units of `|x1 - x0| / T`.
const MIN_JERK_PEAK: f32 = 1.875;

/// The minimum-jerk shape `10s³ - 15s⁴ + 6s⁵` for `s` clamped to `[0, 1]` (NaN gives 1).
pub fn min_jerk_shape(s: f32) -> f32 {
    let s = if s >= 0.0 {
        s.min(1.0)
    } else if s < 0.0 {
        0.0
    } else {
        1.0
    };
    s * s * s * (10.0 + s * (-15.0 + 6.0 * s))
}

/// Minimum-jerk position from `x0` (at `t = 0`) to `x1` (at `t >= duration`).
/// A duration that is not positive means already arrived: `x1`.
pub fn min_jerk(x0: f32, x1: f32, t: f32, duration: f32) -> f32 {
    let moving = duration > 0.0;
    if !moving {
        return x1;
    }
    x0 + (x1 - x0) * min_jerk_shape(t / duration)
}

/// Minimum-jerk velocity, `(x1 - x0)/T · 30s²(1 - s)²`; 0 outside `(0, duration)`.
pub fn min_jerk_velocity(x0: f32, x1: f32, t: f32, duration: f32) -> f32 {
    let inside = duration > 0.0 && t > 0.0 && t < duration;
    if !inside {
        return 0.0;
    }
    let s = t / duration;
    let u = s * (1.0 - s);
    (x1 - x0) / duration * 30.0 * u * u
}

/// Settings of a [`GazeController`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ControllerConfig {
    /// Joint limits (range and speed).
    pub limits: JointLimits,
    /// Nominal duration of a neck move, s.
    pub neck_time_s: f32,
    /// Nominal duration of an eye move, s.
    pub eye_time_s: f32,
    /// Ticks per second.
    pub control_hz: u32,
}

impl ControllerConfig {
    /// Default limits, 0.7 s neck, 0.2 s eyes, 100 Hz.
    pub const DEFAULT: ControllerConfig = ControllerConfig {
        limits: JointLimits::DEFAULT,
        neck_time_s: NECK_TIME_S,
        eye_time_s: EYE_TIME_S,
        control_hz: CONTROL_HZ,
    };
}

impl Default for ControllerConfig {
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// Why a [`ControllerConfig`] was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ConfigError {
    /// The joint limits are unusable at this control rate.
    Limits(LimitsError),
    /// A move duration is not finite and positive, or the control rate is 0.
    Timing,
}

/// One axis' reference: a quintic in normalised time `s = t / dur`.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Quintic {
    c: [f32; 6],
    dur: f32,
    goal: f32,
}

impl Quintic {
    const fn rest(at: f32) -> Self {
        Quintic { c: [at, 0.0, 0.0, 0.0, 0.0, 0.0], dur: 0.0, goal: at }
    }

    /// Position, velocity (°/s) and acceleration (°/s²) at `t` seconds after the start.
    fn eval(&self, t: f32) -> (f32, f32, f32) {
        let running = t < self.dur;
        if !running {
            return (self.goal, 0.0, 0.0);
        }
        let s = if t > 0.0 { t / self.dur } else { 0.0 };
        let c = &self.c;
        let x = c[0] + s * (c[1] + s * (c[2] + s * (c[3] + s * (c[4] + s * c[5]))));
        let dx = c[1] + s * (2.0 * c[2] + s * (3.0 * c[3] + s * (4.0 * c[4] + s * 5.0 * c[5])));
        let ddx = 2.0 * c[2] + s * (6.0 * c[3] + s * (12.0 * c[4] + s * 20.0 * c[5]));
        (x, dx / self.dur, ddx / (self.dur * self.dur))
    }

    /// From `x0` with velocity `v0` and acceleration `a0` to rest at `x1` in `dur` seconds.
    fn new(x0: f32, v0: f32, a0: f32, x1: f32, dur: f32) -> Self {
        let h = x1 - x0;
        let v = v0 * dur;
        let a = a0 * dur * dur;
        Quintic {
            c: [
                x0,
                v,
                0.5 * a,
                10.0 * h - 6.0 * v - 1.5 * a,
                -15.0 * h + 8.0 * v + 1.5 * a,
                6.0 * h - 3.0 * v - 0.5 * a,
            ],
            dur,
            goal: x1,
        }
    }
}

/// The head's setpoint generator: call [`GazeController::tick`] once per control tick.
#[derive(Clone, Debug, PartialEq)]
pub struct GazeController {
    limits: JointLimits,
    times: [f32; 5],
    hz: f32,
    /// Steps range `(lo, hi)` and the per-tick step limit of each axis.
    lo: [i32; 5],
    hi: [i32; 5],
    max_step: [i32; 5],
    /// Current setpoint in whole steps.
    steps: [i32; 5],
    refs: [Quintic; 5],
    /// Ticks since the last start.
    ticks: u32,
}

impl GazeController {
    /// A controller resting at home (all joints 0), if `cfg` is usable.
    pub fn new(cfg: &ControllerConfig) -> Result<Self, ConfigError> {
        cfg.limits.validate(cfg.control_hz).map_err(ConfigError::Limits)?;
        let ok = |t: f32| t.is_finite() && t > 0.0;
        if !ok(cfg.neck_time_s) || !ok(cfg.eye_time_s) || cfg.control_hz == 0 {
            return Err(ConfigError::Timing);
        }
        let mut c = GazeController {
            limits: cfg.limits,
            times: [0.0; 5],
            hz: cfg.control_hz as f32,
            lo: [0; 5],
            hi: [0; 5],
            max_step: [0; 5],
            steps: [0; 5],
            refs: [Quintic::rest(0.0); 5],
            ticks: 0,
        };
        for axis in Axis::ALL {
            let i = axis.index();
            let l = cfg.limits.axis(axis);
            (c.lo[i], c.hi[i]) = cfg.limits.step_range(axis);
            c.max_step[i] = max_steps_per_tick(l.max_vel_deg_s, cfg.control_hz);
            c.times[i] = if axis.is_neck() { cfg.neck_time_s } else { cfg.eye_time_s };
        }
        Ok(c)
    }

    /// Moves towards `to` from the current setpoint (and its current velocity and
    /// acceleration). `to` is clamped to the limits; a NaN joint keeps its current goal.
    pub fn start(&mut self, to: &Joints) {
        let t = self.ticks as f32 / self.hz;
        let half = 0.5 * crate::runtime::gaze::STEP_DEG;
        for axis in Axis::ALL {
            let i = axis.index();
            let goal = if to[axis].is_nan() {
                self.refs[i].goal
            } else {
                self.limits.clamp_axis(axis, to[axis])
            };
            let (x, v0, a0) = self.refs[i].eval(t);
            // From where the reference is, within half a step of the setpoint and within the
            // steps' range: restarted from the setpoint itself, a move re-sent before it had
            // gone half a step lost what it had gone, and goals re-sent that often left the
            // head short of them for ever.
            let xs = from_steps(self.steps[i]);
            let lo = if self.steps[i] > self.lo[i] { xs - half } else { xs };
            let hi = if self.steps[i] < self.hi[i] { xs + half } else { xs };
            // Comparisons, not `max`/`min` (their NaN handling costs flash on the head); a
            // NaN reference fails all three and starts from the setpoint.
            let x0 = if x > hi {
                hi
            } else if x < lo {
                lo
            } else if x <= hi {
                x
            } else {
                xs
            };
            let plan_speed = PLAN_SPEED_SHARE * self.limits.axis(axis).max_vel_deg_s;
            let dur = self.times[i].max(MIN_JERK_PEAK * (goal - x0).abs() / plan_speed);
            self.refs[i] = Quintic::new(x0, v0, a0, goal, dur);
        }
        self.ticks = 0;
    }

    /// Moves home (all joints 0).
    pub fn home(&mut self) {
        self.start(&Joints::HOME);
    }

    /// Advances one control tick and returns the new setpoint (degrees): whole steps,
    /// within the limits, within the per-tick rate limit of the previous setpoint.
    pub fn tick(&mut self) -> Joints {
        self.ticks = self.ticks.saturating_add(1);
        let t = self.ticks as f32 / self.hz;
        for i in 0..5 {
            let (x, _, _) = self.refs[i].eval(t);
            let want = if x.is_finite() { self.grid(i, x) } else { self.steps[i] };
            let m = self.max_step[i];
            // max/min rather than `clamp`, which carries a panic path.
            let delta = want.saturating_sub(self.steps[i]).max(-m).min(m);
            self.steps[i] += delta;
        }
        self.setpoint()
    }

    /// The current setpoint, degrees.
    pub fn setpoint(&self) -> Joints {
        Joints(self.steps.map(from_steps))
    }

    /// The current setpoint in whole 0.18° steps.
    pub fn setpoint_steps(&self) -> [i32; 5] {
        self.steps
    }

    /// Where the current move ends, degrees (within the limits, not yet quantised).
    pub fn goal(&self) -> Joints {
        Joints(self.refs.map(|r| r.goal))
    }

    /// Largest change of each axis per tick, in steps.
    pub fn max_steps_per_tick(&self) -> [i32; 5] {
        self.max_step
    }

    /// True until every axis' move has run its duration and the setpoint has reached the
    /// quantised goal.
    pub fn is_moving(&self) -> bool {
        let t = self.ticks as f32 / self.hz;
        (0..5).any(|i| t < self.refs[i].dur || self.steps[i] != self.goal_step(i))
    }

    /// Where the setpoints of the current move settle (degrees): each goal on the step grid,
    /// within the limits.
    pub fn settled_goal(&self) -> Joints {
        Joints(core::array::from_fn(|i| from_steps(self.goal_step(i))))
    }

    /// Axis `i`'s goal in whole steps, within the limits.
    fn goal_step(&self, i: usize) -> i32 {
        self.grid(i, self.refs[i].goal)
    }

    /// `x` degrees of axis `i` to the nearest whole step within the limits (NaN: 0, clamped).
    #[inline(never)]
    fn grid(&self, i: usize, x: f32) -> i32 {
        (roundf(x / crate::runtime::gaze::STEP_DEG) as i32).max(self.lo[i]).min(self.hi[i])
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::runtime::gaze::{quantize, to_steps, AxisLimits, STEP_DEG};
    use proptest::prelude::*;

    fn ctl() -> GazeController {
        GazeController::new(&ControllerConfig::DEFAULT).unwrap()
    }

    #[test]
    fn min_jerk_profile_hand_values() {
        let (x0, x1, t) = (-10.0f32, 30.0f32, 0.7f32);
        assert_eq!(min_jerk(x0, x1, 0.0, t), x0);
        assert_eq!(min_jerk(x0, x1, t, t), x1);
        assert_eq!(min_jerk(x0, x1, 2.0 * t, t), x1);
        assert_eq!(min_jerk(x0, x1, -1.0, t), x0);
        assert!((min_jerk(x0, x1, t / 2.0, t) - 10.0).abs() < 1e-5);
        // s = 0.25: 10/64 - 15/256 + 6/1024 = 0.103515625
        assert!((min_jerk_shape(0.25) - 0.103_515_625).abs() < 1e-7);
        assert!((min_jerk_shape(0.75) - (1.0 - 0.103_515_625)).abs() < 1e-6);
        assert_eq!(min_jerk_velocity(x0, x1, 0.0, t), 0.0);
        assert_eq!(min_jerk_velocity(x0, x1, t, t), 0.0);
        assert!(min_jerk_velocity(x0, x1, 1e-4, t).abs() < 1e-4);
        assert!(min_jerk_velocity(x0, x1, t - 1e-4, t).abs() < 1e-4);
        // Peak at the middle: 1.875 * 40 / 0.7.
        assert!((min_jerk_velocity(x0, x1, t / 2.0, t) - 1.875 * 40.0 / 0.7).abs() < 1e-3);
        assert_eq!(min_jerk(x0, x1, 0.3, 0.0), x1);
        assert_eq!(min_jerk(x0, x1, 0.3, f32::NAN), x1);
    }

    #[test]
    fn velocity_is_the_derivative_of_position() {
        let (x0, x1, t) = (5.0f32, -25.0f32, 0.2f32);
        for k in 1..20 {
            let tt = k as f32 * 0.01;
            let h = 1e-3;
            let fd = (min_jerk(x0, x1, tt + h, t) - min_jerk(x0, x1, tt - h, t)) / (2.0 * h);
            assert!((fd - min_jerk_velocity(x0, x1, tt, t)).abs() < 0.5, "{tt}");
        }
    }

    #[test]
    fn a_move_from_rest_follows_min_jerk_and_neck_is_slower() {
        let mut c = ctl();
        let to = Joints([20.0, -10.0, 8.0, -12.0, 14.0]);
        c.start(&to);
        let mut last = c.setpoint();
        for k in 1..=100 {
            let j = c.tick();
            let t = k as f32 / 100.0;
            for axis in Axis::ALL {
                let dur = if axis.is_neck() { 0.7 } else { 0.2 };
                let ideal = min_jerk(0.0, to[axis], t, dur);
                // Quantisation only: within half a step of the ideal profile.
                assert!((j[axis] - ideal).abs() <= 0.5 * STEP_DEG + 1e-4, "{axis:?} {t}");
                // Monotonic towards the goal.
                assert!((j[axis] - last[axis]) * to[axis] >= 0.0);
            }
            if k == 10 {
                // Eyes at the midpoint after 0.1 s, neck far from it.
                assert_eq!(j[Axis::EyeTilt], quantize(4.0));
                assert!(j[Axis::NeckPan] < 5.0);
            }
            if k == 20 {
                assert_eq!(j[Axis::RightEyePan], quantize(14.0));
                assert!(c.is_moving());
            }
            if k == 35 {
                assert_eq!(j[Axis::NeckPan], quantize(10.0));
            }
            if k == 70 {
                assert_eq!(j, Joints(to.0.map(quantize)));
                assert!(!c.is_moving());
            }
            last = j;
        }
    }

    #[test]
    fn long_moves_are_stretched_to_respect_the_speed_limit() {
        let mut c = ctl();
        // 120° of neck pan at 0.9 * 180°/s peak: T = 1.875 * 120 / 162 = 1.389 s.
        c.start(&Joints([-60.0, 0.0, 0.0, 0.0, 0.0]));
        for _ in 0..200 {
            c.tick();
        }
        c.start(&Joints([60.0, 0.0, 0.0, 0.0, 0.0]));
        let x0 = c.setpoint()[Axis::NeckPan];
        let dur = 1.875 * (60.0 - x0) / 162.0;
        let mut prev = x0;
        let mut max_delta = 0i32;
        for k in 1..=140 {
            let j = c.tick();
            let ideal = min_jerk(x0, 60.0, k as f32 / 100.0, dur);
            assert!((j[Axis::NeckPan] - ideal).abs() <= 0.5 * STEP_DEG + 1e-4, "{k}");
            max_delta = max_delta.max(to_steps(j[Axis::NeckPan] - prev).abs());
            prev = j[Axis::NeckPan];
        }
        assert_eq!(prev, from_steps(333));
        assert!((9..=10).contains(&max_delta), "{max_delta}");
    }

    #[test]
    fn retargeting_keeps_the_velocity() {
        let mut c = ctl();
        c.start(&Joints([0.0, 0.0, 0.0, 30.0, 0.0]));
        let mut prev = 0.0;
        let mut step = 0.0;
        for _ in 0..8 {
            let j = c.tick()[Axis::LeftEyePan];
            step = j - prev;
            prev = j;
        }
        assert!(step > 2.0, "moving fast mid-saccade: {step}");
        // New target further on: the eye keeps going, no stop and restart.
        c.start(&Joints([0.0, 0.0, 0.0, 34.0, 0.0]));
        let j = c.tick()[Axis::LeftEyePan];
        assert!((j - prev - step).abs() <= 3.0 * STEP_DEG, "{} vs {step}", j - prev);
        for _ in 0..100 {
            c.tick();
        }
        assert_eq!(c.setpoint()[Axis::LeftEyePan], quantize(34.0));
        // Retargeting backwards mid-move reverses smoothly and ends at the new goal.
        c.start(&Joints([0.0, 0.0, 0.0, -20.0, 0.0]));
        for _ in 0..5 {
            c.tick();
        }
        c.start(&Joints([0.0, 0.0, 0.0, 10.0, 0.0]));
        for _ in 0..100 {
            c.tick();
        }
        assert_eq!(c.setpoint()[Axis::LeftEyePan], quantize(10.0));
        assert!(!c.is_moving());
    }

    #[test]
    fn goals_re_sent_every_tick_are_reached() {
        // A goal re-sent (or moved a little) before the move has gone half a step: the move
        // goes on from where its reference is, and the head arrives.
        for period in [1u32, 2, 3, 5] {
            for (from, to) in [(28.08f32, 25.02f32), (0.0, 0.9), (-10.0, 12.0), (3.0, 2.82)] {
                let mut c = ctl();
                c.start(&Joints([from, 0.0, 0.0, from, 0.0]));
                for _ in 0..600 {
                    c.tick();
                }
                for t in 0..1500u32 {
                    if t % period == 0 {
                        c.start(&Joints([to, 0.0, 0.0, to, 0.0]));
                    }
                    c.tick();
                }
                let j = c.setpoint();
                for axis in [Axis::NeckPan, Axis::LeftEyePan] {
                    assert_eq!(j[axis], quantize(to), "{period} ticks, {from} -> {to}: {j:?}");
                }
            }
        }
        // A goal moving slowly, re-sent every tick, is followed, then reached where it stops.
        let mut c = ctl();
        for t in 0..1000u32 {
            let goal = (t.min(500) as f32) * 0.5 / 100.0; // 0.5 degrees/s for 5 s
            c.start(&Joints([goal, 0.0, 0.0, 0.0, 0.0]));
            c.tick();
            if t == 300 {
                assert!(c.setpoint()[Axis::NeckPan] > 1.0, "following: {:?}", c.setpoint());
            }
        }
        assert_eq!(c.setpoint()[Axis::NeckPan], quantize(2.5));
        assert!(!c.is_moving() || c.goal()[Axis::NeckPan] == 2.5);
    }

    #[test]
    fn bad_goals_are_clamped_or_ignored() {
        let mut c = ctl();
        c.start(&Joints([f32::NAN, f32::INFINITY, -1e30, 1e9, f32::NEG_INFINITY]));
        assert_eq!(c.goal(), Joints([0.0, 35.0, -30.0, 35.0, -35.0]));
        for _ in 0..500 {
            c.tick();
        }
        let (lo, hi) = (from_steps(-194), from_steps(194));
        assert_eq!(c.setpoint(), Joints([0.0, from_steps(194), from_steps(-166), hi, lo]));
        c.home();
        for _ in 0..500 {
            c.tick();
        }
        assert_eq!(c.setpoint(), Joints::HOME);
        // NaN mid-move keeps that axis' goal.
        c.start(&Joints([20.0, 0.0, 0.0, 0.0, 0.0]));
        for _ in 0..10 {
            c.tick();
        }
        c.start(&Joints([f32::NAN, 5.0, 0.0, 0.0, 0.0]));
        assert_eq!(c.goal()[Axis::NeckPan], 20.0);
        for _ in 0..100 {
            c.tick();
        }
        assert_eq!(c.setpoint()[Axis::NeckPan], quantize(20.0));
    }

    #[test]
    fn config_validation() {
        let mut cfg = ControllerConfig::DEFAULT;
        cfg.eye_time_s = 0.0;
        assert_eq!(GazeController::new(&cfg), Err(ConfigError::Timing));
        cfg.eye_time_s = f32::NAN;
        assert_eq!(GazeController::new(&cfg), Err(ConfigError::Timing));
        let mut cfg = ControllerConfig::DEFAULT;
        cfg.limits.0[1].max_vel_deg_s = 0.0;
        assert_eq!(
            GazeController::new(&cfg),
            Err(ConfigError::Limits(LimitsError::Velocity(Axis::NeckTilt)))
        );
        assert_eq!(ctl().max_steps_per_tick(), [10, 10, 22, 22, 22]);
    }

    #[derive(Clone, Debug)]
    enum Op {
        Start([f32; 5]),
        Home,
        Ticks(u16),
    }

    const SPECIAL: [f32; 5] = [f32::NAN, f32::INFINITY, f32::NEG_INFINITY, 1e30, -1e30];

    fn any_angle() -> impl Strategy<Value = f32> {
        prop_oneof![
            4 => -90.0f32..90.0,
            1 => any::<f32>(),
            1 => prop::sample::select(&SPECIAL[..]),
        ]
    }

    fn any_op() -> impl Strategy<Value = Op> {
        prop_oneof![
            3 => prop::array::uniform5(any_angle()).prop_map(Op::Start),
            1 => Just(Op::Home),
            4 => (0u16..120).prop_map(Op::Ticks),
        ]
    }

    fn any_limits() -> impl Strategy<Value = JointLimits> {
        let axis = (-90.0f32..0.0, 0.0f32..90.0, 20.0f32..1000.0)
            .prop_map(|(a, b, v)| AxisLimits { min_deg: a, max_deg: b, max_vel_deg_s: v });
        prop::array::uniform5(axis).prop_map(JointLimits)
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(600))]

        #[test]
        fn every_setpoint_is_safe_whatever_the_commands(
            limits in any_limits(),
            neck_time_s in 0.01f32..3.0,
            eye_time_s in 0.01f32..1.0,
            ops in prop::collection::vec(any_op(), 1..25),
        ) {
            let cfg = ControllerConfig { limits, neck_time_s, eye_time_s, control_hz: CONTROL_HZ };
            let mut c = GazeController::new(&cfg).unwrap();
            let max = c.max_steps_per_tick();
            let mut prev = c.setpoint_steps();
            for op in ops {
                match op {
                    Op::Start(to) => c.start(&Joints(to)),
                    Op::Home => c.home(),
                    Op::Ticks(n) => for _ in 0..n {
                        let j = c.tick();
                        let steps = c.setpoint_steps();
                        prop_assert!(limits.contains(&j), "{:?} outside {:?}", j, limits);
                        for axis in Axis::ALL {
                            let i = axis.index();
                            prop_assert_eq!(j[axis], from_steps(steps[i]));
                            prop_assert_eq!(to_steps(j[axis]), steps[i]);
                            prop_assert!((steps[i] - prev[i]).abs() <= max[i]);
                            let per_tick = limits.axis(axis).max_vel_deg_s / CONTROL_HZ as f32;
                            prop_assert!((j[axis] - from_steps(prev[i])).abs()
                                <= per_tick * (1.0 + 1e-4) + 1e-5);
                        }
                        prev = steps;
                    },
                }
            }
            // Any goal is eventually reached (or its clamped, quantised version).
            let goal = c.goal();
            for _ in 0..3000 {
                c.tick();
            }
            prop_assert!(!c.is_moving());
            for axis in Axis::ALL {
                let (lo, hi) = limits.step_range(axis);
                let want = to_steps(goal[axis]).clamp(lo, hi);
                prop_assert_eq!(c.setpoint_steps()[axis.index()], want);
            }
        }
    }
}
