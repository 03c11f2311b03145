//! The output side of the head: joint setpoints to drive commands.
//!
//! - Faulhaber MCDC 3006 S motion controllers over RS-232 ASCII: `<node>LA<counts>\r`
//!   (load absolute position) then `<node>M\r` (move), one node per axis. Lines are built in
//!   fixed buffers ([`McdcLine`]) with hand-written integer formatting: no `core::fmt`, no
//!   floats printed. [`parse_mcdc`] reads them back (tests, and the host checking the servo
//!   log of an emulated run).
//! - 50 Hz hobby servos: degrees to a 1000-2000 µs pulse ([`PwmConfig`]) and a pulse to a
//!   timer duty value ([`duty_for`]).
//! - [`ServoOutput`]: the trait the firmware implements for both.
//!
//! Every conversion clamps: whatever angle comes in (NaN and infinities included), the
//! counts stay within the joint limits and the pulse within 1000-2000 µs.
use libm::{ceilf, floorf, roundf};

use crate::runtime::gaze::{Axis, JointLimits, Joints, STEP_DEG};

/// Where a setpoint goes: a set of drives for the five axes. The firmware implements it for
/// the MCDC USART writer and for PWM channels; implementations convert with
/// [`McdcConfig::position_commands`] or [`PwmConfig::pulses`], which clamp to the limits.
pub trait ServoOutput {
    /// Transport error (e.g. a USART error).
    type Error;
    /// Commands every axis to `joints` (degrees).
    fn command(&mut self, joints: &Joints) -> Result<(), Self::Error>;
    /// Stops every axis in a safe state (MCDC: [`McdcConfig::halt_commands`]).
    fn halt(&mut self) -> Result<(), Self::Error>;
}

/// Longest MCDC command line: 3 node digits, 2 letters, 11 for an `i32`, `\r`.
pub const MCDC_LINE_MAX: usize = 20;
/// One MCDC command line, `\r` included.
pub type McdcLine = heapless::Vec<u8, MCDC_LINE_MAX>;

/// The MCDC 3006 S commands this crate writes and reads.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum McdcCmd {
    /// `LA<counts>`: load an absolute target position.
    LoadAbsolute(i32),
    /// `M`: start the loaded move.
    Move,
    /// `V<rpm>`: velocity mode; `V0` stops and holds (used for halting).
    Velocity(i32),
    /// `DI`: disable the power stage.
    Disable,
    /// `EN`: enable the power stage.
    Enable,
}

/// One axis' MCDC drive.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct McdcAxis {
    /// Node number (the `<node>` prefix).
    pub node: u8,
    /// Encoder counts per joint degree (negative reverses the direction).
    pub counts_per_deg: f32,
    /// Counts at joint angle 0.
    pub zero_counts: i32,
}

/// MCDC drives of all five axes, indexed by [`Axis`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct McdcConfig(pub [McdcAxis; 5]);

const fn mcdc(node: u8) -> McdcAxis {
    McdcAxis { node, counts_per_deg: 1.0 / STEP_DEG, zero_counts: 0 }
}

impl McdcConfig {
    /// Nodes 1 to 5 in [`Axis`] order, one count per 0.18° step (the thesis' positioning
    /// resolution), zero at 0 counts.
    pub const DEFAULT: McdcConfig = McdcConfig([mcdc(1), mcdc(2), mcdc(3), mcdc(4), mcdc(5)]);

    /// Position counts for `deg` on `axis`: clamped to the limits (NaN counts as 0),
    /// rounded, and kept on counts whose angle lies within the limits.
    pub fn counts(&self, limits: &JointLimits, axis: Axis, deg: f32) -> i32 {
        let a = &self.0[axis.index()];
        let l = limits.axis(axis);
        let k = a.counts_per_deg;
        let (lo, hi) =
            if k >= 0.0 { (l.min_deg * k, l.max_deg * k) } else { (l.max_deg * k, l.min_deg * k) };
        let rel = roundf(limits.clamp_axis(axis, deg) * k);
        // Inclusive bounds on whole counts; NaN (a broken config) gives 0 through `as`.
        let rel = rel.max(ceilf(lo)).min(floorf(hi)) as i32;
        a.zero_counts.saturating_add(rel)
    }

    /// `LA` and `M` for every axis, in [`Axis`] order: 10 lines.
    pub fn position_commands(&self, limits: &JointLimits, joints: &Joints) -> [McdcLine; 10] {
        let mut out: [McdcLine; 10] = Default::default();
        for axis in Axis::ALL {
            let node = self.0[axis.index()].node;
            let counts = self.counts(limits, axis, joints[axis]);
            out[2 * axis.index()] = format_mcdc(node, McdcCmd::LoadAbsolute(counts));
            out[2 * axis.index() + 1] = format_mcdc(node, McdcCmd::Move);
        }
        out
    }

    /// `V0` for every axis: stop and hold (the power stage stays on so the neck does not
    /// drop under gravity).
    pub fn halt_commands(&self) -> [McdcLine; 5] {
        let mut out: [McdcLine; 5] = Default::default();
        for (line, a) in out.iter_mut().zip(self.0.iter()) {
            *line = format_mcdc(a.node, McdcCmd::Velocity(0));
        }
        out
    }
}

impl Default for McdcConfig {
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// Writes the decimal digits of `v` (no sign) into `out`.
fn push_u32(out: &mut McdcLine, mut v: u32) {
    let mut digits = [0u8; 10];
    let mut n = 0;
    loop {
        digits[n] = b'0' + (v % 10) as u8;
        n += 1;
        v /= 10;
        if v == 0 || n == digits.len() {
            break;
        }
    }
    for &d in digits[..n].iter().rev() {
        // Capacity covers the longest line.
        let _ = out.push(d);
    }
}

fn push_i32(out: &mut McdcLine, v: i32) {
    if v < 0 {
        let _ = out.push(b'-');
    }
    push_u32(out, v.unsigned_abs());
}

/// `<node><cmd>\r`, e.g. `3LA1000\r`, `3M\r`.
pub fn format_mcdc(node: u8, cmd: McdcCmd) -> McdcLine {
    let mut out = McdcLine::new();
    push_u32(&mut out, node as u32);
    let (name, arg): (&[u8], Option<i32>) = match cmd {
        McdcCmd::LoadAbsolute(c) => (b"LA", Some(c)),
        McdcCmd::Move => (b"M", None),
        McdcCmd::Velocity(v) => (b"V", Some(v)),
        McdcCmd::Disable => (b"DI", None),
        McdcCmd::Enable => (b"EN", None),
    };
    let _ = out.extend_from_slice(name);
    if let Some(a) = arg {
        push_i32(&mut out, a);
    }
    let _ = out.push(b'\r');
    out
}

/// Why [`parse_mcdc`] refused a line.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum McdcParseError {
    /// No node number, or one above 255.
    Node,
    /// Not one of `LA`, `M`, `V`, `DI`, `EN`.
    Command,
    /// Missing, malformed or out-of-range number, or bytes after the command.
    Argument,
}

/// Reads one command line as [`format_mcdc`] writes it. A trailing `\r` (or `\r\n`, `\n`)
/// is optional; nothing else is tolerated (no spaces, no `+`).
pub fn parse_mcdc(line: &[u8]) -> Result<(u8, McdcCmd), McdcParseError> {
    let line = line.strip_suffix(b"\n").unwrap_or(line);
    let line = line.strip_suffix(b"\r").unwrap_or(line);
    let digits = line.iter().take_while(|b| b.is_ascii_digit()).count();
    if digits == 0 || digits > 3 {
        return Err(McdcParseError::Node);
    }
    let (node, rest) = line.split_at_checked(digits).ok_or(McdcParseError::Node)?;
    let node = node.iter().fold(0u32, |n, &d| n * 10 + (d - b'0') as u32);
    let node = u8::try_from(node).map_err(|_| McdcParseError::Node)?;
    let no_arg = |cmd: McdcCmd, tail: &[u8]| {
        if tail.is_empty() {
            Ok((node, cmd))
        } else {
            Err(McdcParseError::Argument)
        }
    };
    if let Some(arg) = rest.strip_prefix(b"LA") {
        Ok((node, McdcCmd::LoadAbsolute(parse_i32(arg)?)))
    } else if let Some(tail) = rest.strip_prefix(b"DI") {
        no_arg(McdcCmd::Disable, tail)
    } else if let Some(tail) = rest.strip_prefix(b"EN") {
        no_arg(McdcCmd::Enable, tail)
    } else if let Some(tail) = rest.strip_prefix(b"M") {
        no_arg(McdcCmd::Move, tail)
    } else if let Some(arg) = rest.strip_prefix(b"V") {
        Ok((node, McdcCmd::Velocity(parse_i32(arg)?)))
    } else {
        Err(McdcParseError::Command)
    }
}

/// An optional `-` then 1-10 decimal digits, within `i32`.
fn parse_i32(s: &[u8]) -> Result<i32, McdcParseError> {
    let (neg, digits) = match s.strip_prefix(b"-") {
        Some(d) => (true, d),
        None => (false, s),
    };
    if digits.is_empty() || digits.len() > 10 || !digits.iter().all(u8::is_ascii_digit) {
        return Err(McdcParseError::Argument);
    }
    let mag = digits.iter().fold(0i64, |n, &d| n * 10 + (d - b'0') as i64);
    let v = if neg { -mag } else { mag };
    i32::try_from(v).map_err(|_| McdcParseError::Argument)
}

/// Shortest hobby-servo pulse ever produced, µs.
pub const PWM_MIN_US: u16 = 1000;
/// Longest hobby-servo pulse ever produced, µs.
pub const PWM_MAX_US: u16 = 2000;
/// Hobby-servo frame rate, Hz.
pub const PWM_HZ: u32 = 50;
/// Hobby-servo frame period, µs.
pub const PWM_PERIOD_US: u32 = 1_000_000 / PWM_HZ;

/// One axis' hobby servo.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PwmAxis {
    /// Pulse at joint angle 0, µs.
    pub centre_us: u16,
    /// Pulse change per joint degree, µs (negative reverses the direction).
    pub us_per_deg: f32,
}

/// Hobby servos of all five axes, indexed by [`Axis`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PwmConfig(pub [PwmAxis; 5]);

const STD_SERVO: PwmAxis = PwmAxis { centre_us: 1500, us_per_deg: 500.0 / 90.0 };

impl PwmConfig {
    /// A standard servo on every axis: 1500 µs at 0°, 1000-2000 µs for -90° to +90°.
    pub const DEFAULT: PwmConfig = PwmConfig([STD_SERVO; 5]);

    /// Pulse width for `deg` on `axis`, µs: the angle is clamped to the limits (NaN counts
    /// as 0), then the pulse to [`PWM_MIN_US`]-[`PWM_MAX_US`].
    pub fn pulse_us(&self, limits: &JointLimits, axis: Axis, deg: f32) -> u16 {
        let a = &self.0[axis.index()];
        let us = a.centre_us as f32 + a.us_per_deg * limits.clamp_axis(axis, deg);
        // `f32::max` drops a NaN (from a broken config): it becomes PWM_MIN_US.
        roundf(us).max(PWM_MIN_US as f32).min(PWM_MAX_US as f32) as u16
    }

    /// Pulse widths of all axes, µs.
    pub fn pulses(&self, limits: &JointLimits, joints: &Joints) -> [u16; 5] {
        Axis::ALL.map(|axis| self.pulse_us(limits, axis, joints[axis]))
    }
}

impl Default for PwmConfig {
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// Duty value for a `pulse_us` pulse on a timer whose full period `period_us` (normally
/// [`PWM_PERIOD_US`]) corresponds to `max_duty`: `round(pulse · max_duty / period)`. The
/// pulse is first clamped to [`PWM_MIN_US`]-[`PWM_MAX_US`]; the result never exceeds
/// `max_duty`, and a zero period gives 0 (no pulses).
pub fn duty_for(pulse_us: u16, max_duty: u16, period_us: u32) -> u16 {
    if period_us == 0 {
        return 0;
    }
    let pulse = pulse_us.clamp(PWM_MIN_US, PWM_MAX_US) as u64;
    let period = period_us as u64;
    let duty = (pulse * max_duty as u64 + period / 2) / period;
    duty.min(max_duty as u64) as u16
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn s(line: &McdcLine) -> &str {
        core::str::from_utf8(line).unwrap()
    }

    #[test]
    fn exact_mcdc_strings() {
        assert_eq!(s(&format_mcdc(3, McdcCmd::LoadAbsolute(1000))), "3LA1000\r");
        assert_eq!(s(&format_mcdc(3, McdcCmd::Move)), "3M\r");
        assert_eq!(s(&format_mcdc(12, McdcCmd::LoadAbsolute(-250))), "12LA-250\r");
        assert_eq!(s(&format_mcdc(0, McdcCmd::LoadAbsolute(0))), "0LA0\r");
        assert_eq!(s(&format_mcdc(255, McdcCmd::LoadAbsolute(i32::MIN))), "255LA-2147483648\r");
        assert_eq!(s(&format_mcdc(7, McdcCmd::Velocity(0))), "7V0\r");
        assert_eq!(s(&format_mcdc(1, McdcCmd::Disable)), "1DI\r");
        assert_eq!(s(&format_mcdc(1, McdcCmd::Enable)), "1EN\r");
    }

    #[test]
    fn position_commands_for_a_posture() {
        let j = Joints([10.0, -5.0, 0.0, -3.005, 100.0]);
        let lines = McdcConfig::DEFAULT.position_commands(&JointLimits::DEFAULT, &j);
        let text: [&str; 10] = core::array::from_fn(|i| s(&lines[i]));
        // 10/0.18 = 55.6 -> 56; -5/0.18 = -27.8 -> -28; -3.005/0.18 = -16.7 -> -17;
        // 100° clamps to 35° = 194.4 counts -> 194.
        assert_eq!(
            text,
            [
                "1LA56\r", "1M\r", "2LA-28\r", "2M\r", "3LA0\r", "3M\r", "4LA-17\r", "4M\r",
                "5LA194\r", "5M\r"
            ]
        );
        let halt = McdcConfig::DEFAULT.halt_commands();
        assert_eq!(s(&halt[0]), "1V0\r");
        assert_eq!(s(&halt[4]), "5V0\r");
    }

    #[test]
    fn counts_with_gearing_offset_and_reversal() {
        let l = JointLimits::DEFAULT;
        let mut cfg = McdcConfig::DEFAULT;
        cfg.0[0] = McdcAxis { node: 9, counts_per_deg: -100.0, zero_counts: 5000 };
        assert_eq!(cfg.counts(&l, Axis::NeckPan, 1.234), 5000 - 123);
        assert_eq!(cfg.counts(&l, Axis::NeckPan, 500.0), 5000 - 6000);
        assert_eq!(cfg.counts(&l, Axis::NeckPan, -500.0), 5000 + 6000);
        assert_eq!(cfg.counts(&l, Axis::NeckPan, f32::NAN), 5000);
    }

    #[test]
    fn parser_reads_back_and_refuses_junk() {
        assert_eq!(parse_mcdc(b"3LA1000\r"), Ok((3, McdcCmd::LoadAbsolute(1000))));
        assert_eq!(parse_mcdc(b"3LA-7"), Ok((3, McdcCmd::LoadAbsolute(-7))));
        assert_eq!(parse_mcdc(b"12M\r\n"), Ok((12, McdcCmd::Move)));
        assert_eq!(parse_mcdc(b"1V0\n"), Ok((1, McdcCmd::Velocity(0))));
        assert_eq!(parse_mcdc(b"1DI"), Ok((1, McdcCmd::Disable)));
        assert_eq!(parse_mcdc(b"1EN\r"), Ok((1, McdcCmd::Enable)));
        assert_eq!(parse_mcdc(b"2LA2147483647"), Ok((2, McdcCmd::LoadAbsolute(i32::MAX))));
        use McdcParseError::*;
        for (line, err) in [
            (&b""[..], Node),
            (b"\r", Node),
            (b"LA5\r", Node),
            (b"256M", Node),
            (b"1234M", Node),
            (b"3XX", Command),
            (b"3", Command),
            (b"3la5", Command),
            (b"3LA", Argument),
            (b"3LA-", Argument),
            (b"3LA+5", Argument),
            (b"3LA 5", Argument),
            (b"3LA1x", Argument),
            (b"3LA2147483648", Argument),
            (b"3LA99999999999", Argument),
            (b"3M5", Argument),
            (b"3M\r\r", Argument),
            (b"3DIX", Argument),
        ] {
            assert_eq!(parse_mcdc(line), Err(err), "{:?}", core::str::from_utf8(line));
        }
    }

    #[test]
    fn pwm_hand_values() {
        let l = JointLimits::DEFAULT;
        let p = PwmConfig::DEFAULT;
        assert_eq!(p.pulse_us(&l, Axis::NeckPan, 0.0), 1500);
        assert_eq!(p.pulse_us(&l, Axis::NeckPan, 45.0), 1750);
        assert_eq!(p.pulse_us(&l, Axis::NeckPan, -45.0), 1250);
        // Clamped to the 60° limit: 1500 + 333.3.
        assert_eq!(p.pulse_us(&l, Axis::NeckPan, 1e9), 1833);
        assert_eq!(p.pulse_us(&l, Axis::NeckPan, f32::NAN), 1500);
        let wide = PwmConfig([PwmAxis { centre_us: 1900, us_per_deg: 20.0 }; 5]);
        assert_eq!(wide.pulse_us(&l, Axis::EyeTilt, 30.0), 2000);
        assert_eq!(wide.pulse_us(&l, Axis::EyeTilt, -30.0), 1300);
        // 1500 µs of 20 ms on a 16-bit timer: 1500 * 65535 / 20000 = 4915.1.
        assert_eq!(duty_for(1500, 65535, PWM_PERIOD_US), 4915);
        assert_eq!(duty_for(1000, 20000, 20000), 1000);
        assert_eq!(duty_for(3000, 20000, 20000), 2000);
        assert_eq!(duty_for(0, 20000, 20000), 1000);
        assert_eq!(duty_for(1500, 0, 20000), 0);
        assert_eq!(duty_for(1500, 20000, 0), 0);
        assert_eq!(duty_for(1500, 1000, 1000), 1000);
        assert_eq!(PWM_PERIOD_US, 20_000);
    }

    fn any_deg() -> impl Strategy<Value = f32> {
        prop_oneof![
            3 => -100.0f32..100.0,
            1 => any::<f32>(),
            1 => prop::sample::select(&[f32::NAN, f32::INFINITY, f32::NEG_INFINITY][..]),
        ]
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(3000))]

        #[test]
        fn format_then_parse_round_trips(node: u8, v: i32, kind in 0u8..5) {
            let cmd = match kind {
                0 => McdcCmd::LoadAbsolute(v),
                1 => McdcCmd::Move,
                2 => McdcCmd::Velocity(v),
                3 => McdcCmd::Disable,
                _ => McdcCmd::Enable,
            };
            let line = format_mcdc(node, cmd);
            prop_assert_eq!(line.last(), Some(&b'\r'));
            prop_assert_eq!(parse_mcdc(&line), Ok((node, cmd)));
        }

        #[test]
        fn parser_never_panics(bytes in prop::collection::vec(any::<u8>(), 0..24)) {
            let _ = parse_mcdc(&bytes);
        }

        #[test]
        fn counts_stay_within_the_limits(
            deg in any_deg(), axis in 0usize..5,
            k in prop_oneof![1.0f32..5000.0, -5000.0f32..-1.0], zero in -100_000i32..100_000,
        ) {
            let l = JointLimits::DEFAULT;
            let axis = Axis::ALL[axis];
            let mut cfg = McdcConfig::DEFAULT;
            cfg.0[axis.index()].counts_per_deg = k;
            cfg.0[axis.index()].zero_counts = zero;
            let c = cfg.counts(&l, axis, deg);
            let back = (c - zero) as f32 / k;
            let lim = l.axis(axis);
            // The commanded angle is within the limits (to f32 rounding of the division).
            let inside = back >= lim.min_deg - 1e-4 && back <= lim.max_deg + 1e-4;
            prop_assert!(inside, "{} -> {}", deg, back);
            // And it is the nearest count to the clamped angle (one count in when the nearest
            // lies just past a limit).
            let want = l.clamp_axis(axis, deg);
            let tol = if want == lim.min_deg || want == lim.max_deg { 1.0 } else { 0.5 };
            prop_assert!((back - want).abs() <= tol / k.abs() + 1e-4, "{} -> {}", want, back);
            // The printed line carries exactly these counts.
            let line = format_mcdc(cfg.0[axis.index()].node, McdcCmd::LoadAbsolute(c));
            let node = axis.index() as u8 + 1;
            prop_assert_eq!(parse_mcdc(&line), Ok((node, McdcCmd::LoadAbsolute(c))));
        }

        #[test]
        fn pulses_and_duties_stay_in_range(
            deg in any_deg(), axis in 0usize..5,
            centre in 0u16..4000, us_per_deg in any::<f32>(),
            max_duty in 1u16..=u16::MAX, period in 2000u32..100_000,
        ) {
            let l = JointLimits::DEFAULT;
            let axis = Axis::ALL[axis];
            let cfg = PwmConfig([PwmAxis { centre_us: centre, us_per_deg }; 5]);
            let p = cfg.pulse_us(&l, axis, deg);
            prop_assert!((PWM_MIN_US..=PWM_MAX_US).contains(&p));
            let d = duty_for(p, max_duty, period);
            prop_assert!(d <= max_duty);
            // The duty encodes the pulse to within half a timer tick.
            let us = d as f64 * period as f64 / max_duty as f64;
            let half_tick = 0.5 * period as f64 / max_duty as f64;
            prop_assert!((us - p as f64).abs() <= half_tick + 1e-9, "{} vs {}", us, p);
            let d_any = duty_for(centre, max_duty, period);
            let us = d_any as f64 * period as f64 / max_duty as f64;
            let (lo, hi) = (PWM_MIN_US as f64 - half_tick, PWM_MAX_US as f64 + half_tick);
            prop_assert!(us >= lo && us <= hi);
        }
    }
}
