//! The simulated head: the firmware's loop step ([`MainLoop`], which `firmware/src/main.rs`
//! runs too) over the same `hvs-shared` pieces, servo setpoints that follow the trajectories on
//! the control clock, and every safety rule checked on every tick. `hvs track`'s virtual head
//! runs on it, and so do the cross-crate robustness tests and fuzz targets (`hvs-tests`).
//!
//! Bytes go through [`FrameAccumulator`] and [`MainLoop::frame`] into [`Head::respond`], as
//! on the head; every response must encode into one [`MAX_FRAME_LEN`] frame. Each control
//! tick is [`MainLoop::tick`]; once armed (first `Look` or `Home`, as the firmware) each setpoint
//! also goes through the MCDC and PWM conversions the firmware sends to the servos. A tick
//! fails the run ([`Violation`]) if a setpoint leaves its joint limits, leaves the 0.18° grid,
//! moves an axis by more than its per-tick step limit, or if an MCDC line or PWM pulse would
//! command anything beyond the limits.

use hvs_shared::runtime::gaze::{self, Axis, GazeConfig, JointLimits, Joints};
use hvs_shared::runtime::head::{self, Boot, Head, MainLoop};
use hvs_shared::runtime::protocol::{
    self, ErrorCode, FirmwareVersion, FrameAccumulator, Request, RequestBody, Response,
    ResponseBody, MAX_FRAME_LEN, UNSOLICITED_ID,
};
use hvs_shared::runtime::servo::{parse_mcdc, McdcCmd, McdcConfig, PwmConfig};
use hvs_shared::runtime::trajectory::{ConfigError, ControllerConfig};

/// Firmware version the simulated head reports.
pub const VERSION: FirmwareVersion = FirmwareVersion { major: 0, minor: 1, patch: 0 };

/// A broken safety rule: what and where.
#[derive(Debug, Clone, PartialEq)]
pub struct Violation(pub String);

impl core::fmt::Display for Violation {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(&self.0)
    }
}

macro_rules! ensure {
    ($cond:expr, $($arg:tt)*) => {
        let ok: bool = $cond;
        if !ok {
            return Err(Violation(format!($($arg)*)));
        }
    };
}

/// The simulated head.
#[derive(Debug, Clone)]
pub struct SimHead {
    /// The head logic (boot result, gaze settings, trajectories).
    pub head: Head,
    acc: FrameAccumulator<MAX_FRAME_LEN>,
    /// The firmware's loop step (its arming rule: the servos are commanded from the first
    /// `Look` or `Home` on).
    pub main_loop: MainLoop,
    last_steps: [i32; 5],
    last_counts: Option<[i32; 5]>,
    /// Ticks run so far.
    pub ticks: u64,
    /// MCDC drive settings the servo lines are made with.
    pub mcdc: McdcConfig,
    /// Hobby-servo settings the pulses are made with.
    pub pwm: PwmConfig,
}

/// The firmware's controller settings: [`ControllerConfig::DEFAULT`] with the gaze limits.
pub fn firmware_control(gaze: &GazeConfig) -> ControllerConfig {
    ControllerConfig { limits: gaze.limits, ..ControllerConfig::DEFAULT }
}

impl SimHead {
    /// Boots from the raw bytes of both slots with the firmware's settings.
    pub fn boot(slot_a: &[u8], slot_b: &[u8]) -> SimHead {
        let gaze = GazeConfig::DEFAULT;
        SimHead::new(head::boot(slot_a, slot_b), gaze, &firmware_control(&gaze))
            .expect("the firmware's settings are valid")
    }

    /// A head with other gaze and controller settings (the servo conversions use
    /// `control.limits`, as the firmware passes its limits to both).
    pub fn new(
        boot: Boot,
        gaze: GazeConfig,
        control: &ControllerConfig,
    ) -> Result<SimHead, ConfigError> {
        let head = Head::new(boot, gaze, control)?;
        let last_steps = head.controller.setpoint_steps();
        Ok(SimHead {
            head,
            acc: FrameAccumulator::new(),
            main_loop: MainLoop::new(),
            last_steps,
            last_counts: None,
            ticks: 0,
            mcdc: McdcConfig::DEFAULT,
            pwm: PwmConfig::DEFAULT,
        })
    }

    fn limits(&self) -> JointLimits {
        self.head.gaze.limits
    }

    /// Feeds `bytes` as they arrive on the protocol USART; returns the responses sent, in
    /// order. Fails if a response does not fit one frame, or carries the wrong id.
    pub fn feed(&mut self, bytes: &[u8]) -> Result<Vec<Response>, Violation> {
        let mut out = Vec::new();
        for &b in bytes {
            let Some(frame) = self.acc.push(b) else {
                continue;
            };
            let head = &mut self.head;
            let mut asked = None;
            let resp = self.main_loop.frame(frame, |req| {
                asked = Some(req.id);
                head.respond(req, VERSION)
            });
            match asked {
                Some(id) => {
                    ensure!(resp.id == id, "request {id} answered with id {}", resp.id);
                }
                None => {
                    ensure!(
                        resp.id == UNSOLICITED_ID
                            && matches!(
                                resp.body,
                                ResponseBody::Error(ErrorCode::Malformed | ErrorCode::Oversize)
                            ),
                        "a bad frame got {resp:?}"
                    );
                }
            }
            let mut buf = [0u8; MAX_FRAME_LEN];
            ensure!(
                protocol::encode_response(&resp, &mut buf).is_ok(),
                "{resp:?} does not fit one {MAX_FRAME_LEN}-byte frame"
            );
            out.push(resp);
        }
        Ok(out)
    }

    /// Sends one request as a well-formed frame; returns the responses (the last one answers
    /// it unless a partial frame was pending, which the frame then completes).
    pub fn request(&mut self, req: &Request) -> Result<Vec<Response>, Violation> {
        let mut buf = [0u8; MAX_FRAME_LEN];
        let frame = protocol::encode_request(req, &mut buf).expect("requests fit a frame");
        let frame = frame.to_vec();
        self.feed(&frame)
    }

    /// Runs `n` control ticks, checking every setpoint and servo command.
    pub fn tick(&mut self, n: u32) -> Result<(), Violation> {
        for _ in 0..n {
            let tick = self.main_loop.tick(&mut self.head);
            self.ticks += 1;
            self.check(&tick.setpoint, tick.command)?;
        }
        Ok(())
    }

    fn check(&mut self, sp: &Joints, commanded: bool) -> Result<(), Violation> {
        let limits = self.limits();
        let t = self.ticks;
        ensure!(limits.contains(sp), "tick {t}: setpoint {sp:?} outside the joint limits");
        let steps = self.head.controller.setpoint_steps();
        let max = self.head.controller.max_steps_per_tick();
        for axis in Axis::ALL {
            let i = axis.index();
            ensure!(
                sp[axis] == gaze::from_steps(steps[i]),
                "tick {t}: {axis:?} at {} is off the 0.18° grid",
                sp[axis]
            );
            let d = (i64::from(steps[i]) - i64::from(self.last_steps[i])).abs();
            ensure!(
                d <= i64::from(max[i]),
                "tick {t}: {axis:?} moved {d} steps (limit {})",
                max[i]
            );
        }
        self.last_steps = steps;
        if !commanded {
            return Ok(());
        }
        // What goes on the MCDC wire: LA then M per axis, counts within the limits, and
        // (one count per step) within the per-tick step limit of the last command.
        let lines = self.mcdc.position_commands(&limits, sp);
        let mut counts = [0i32; 5];
        for axis in Axis::ALL {
            let i = axis.index();
            let drive = &self.mcdc.0[i];
            let la = parse_mcdc(&lines[2 * i]);
            let m = parse_mcdc(&lines[2 * i + 1]);
            let Ok((node, McdcCmd::LoadAbsolute(c))) = la else {
                return Err(Violation(format!("tick {t}: {axis:?}: bad LA line {la:?}")));
            };
            ensure!(
                node == drive.node && m == Ok((drive.node, McdcCmd::Move)),
                "tick {t}: {axis:?}: lines {la:?} {m:?} for node {}",
                drive.node
            );
            let l = limits.axis(axis);
            let deg = f64::from(c - drive.zero_counts) / f64::from(drive.counts_per_deg);
            ensure!(
                deg >= f64::from(l.min_deg) - 1e-3 && deg <= f64::from(l.max_deg) + 1e-3,
                "tick {t}: {axis:?}: {c} counts = {deg}° outside [{}, {}]",
                l.min_deg,
                l.max_deg
            );
            if drive.counts_per_deg == 1.0 / gaze::STEP_DEG {
                // One count per step: the command is the setpoint, step for step.
                ensure!(
                    i64::from(c) - i64::from(drive.zero_counts) == i64::from(steps[i]),
                    "tick {t}: {axis:?}: {c} counts for setpoint step {}",
                    steps[i]
                );
            }
            counts[i] = c;
        }
        if let Some(prev) = self.last_counts {
            for axis in Axis::ALL {
                let i = axis.index();
                let per_step = f64::from(self.mcdc.0[i].counts_per_deg).abs() * 0.18;
                let d = f64::from((counts[i] - prev[i]).abs());
                ensure!(
                    d <= f64::from(max[i]) * per_step + 1.0,
                    "tick {t}: {axis:?}: MCDC counts jumped by {d}"
                );
            }
        }
        self.last_counts = Some(counts);
        // PWM: pulses within 1000-2000 µs and between the pulses of the axis' end stops.
        for axis in Axis::ALL {
            let l = limits.axis(axis);
            let p = self.pwm.pulse_us(&limits, axis, sp[axis]);
            let a = self.pwm.pulse_us(&limits, axis, l.min_deg);
            let b = self.pwm.pulse_us(&limits, axis, l.max_deg);
            ensure!(
                p >= a.min(b) && p <= a.max(b) && (1000..=2000).contains(&p),
                "tick {t}: {axis:?}: pulse {p} µs outside [{}, {}]",
                a.min(b),
                a.max(b)
            );
        }
        Ok(())
    }

    /// Checks the head still answers: a `0x00` (ending any partial frame) and a `Ping` must be
    /// answered by `Pong` with the ping's id, as the last response.
    pub fn still_answers(&mut self, id: u32) -> Result<(), Violation> {
        let mut got = self.feed(&[0])?;
        got.extend(self.request(&Request { id, body: RequestBody::Ping })?);
        let last = got.last().copied();
        ensure!(
            last == Some(Response { id, body: ResponseBody::Pong }),
            "a Ping after the stream got {last:?}"
        );
        Ok(())
    }

    /// Runs ticks until the head is at rest (at most `max` ticks); fails if it is still
    /// moving then.
    pub fn settle(&mut self, max: u32) -> Result<(), Violation> {
        for _ in 0..max {
            if !self.head.controller.is_moving() {
                return Ok(());
            }
            self.tick(1)?;
        }
        ensure!(!self.head.controller.is_moving(), "still moving after {max} ticks");
        Ok(())
    }
}
