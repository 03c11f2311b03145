//! The head the loop commands: [`ServoHead`], implemented by the simulated head
//! ([`super::head_sim::VirtualHead`], on a simulated clock) and by a head controller on a link
//! ([`RemoteHead`]: the firmware in QEMU, or a real head on a serial port), which moves on its
//! own clock and is driven with the protocol's `Posture` and `State` requests.

use super::head_sim::VirtualHead;
use crate::device::client;
use crate::device::link::Link;
use anyhow::{bail, Context, Result};
use hvs_shared::runtime::gaze::Joints;
use hvs_shared::runtime::protocol::{RequestBody, ResponseBody, StateData, PROTOCOL_VERSION};
use std::time::{Duration, Instant};

/// A head whose servos the loop commands.
pub trait ServoHead {
    /// Lets the head's clock run up to `t_s` (s since the loop started): a simulated head
    /// runs its control ticks; a real one is waited for (at once when it is already there).
    fn advance_to(&mut self, t_s: f64) -> Result<()>;
    /// Commands a new goal (a repeated goal does not re-plan the move).
    fn command(&mut self, goal: &Joints) -> Result<()>;
    /// Where the servos are (degrees), as of the last [`ServoHead::advance_to`].
    fn joints(&self) -> Joints;
    /// Whether a move is still under way.
    fn is_moving(&self) -> bool;
    /// The head's clock (s since the loop started).
    fn time_s(&self) -> f64;
    /// Control ticks per second of the head's clock.
    fn control_hz(&self) -> u32;
    /// The time a frame taken now is at: the asked `t_s` on a simulated clock, the head's
    /// own clock for a head that runs on its own.
    fn frame_time(&self, t_s: f64) -> f64 {
        t_s
    }
    /// Whether the head keeps its own time (a head controller on a link), so that a loop on
    /// the wall clock (`hvs view`) takes its frames at the head's time instead of waiting for
    /// the head's clock to reach the wall clock's: QEMU's clock runs slower than the wall clock
    /// on a busy machine, and `hvs view --head qemu` had sunk from 17 to 2 frames/s within 90 s,
    /// every frame waiting out the lag.
    fn own_clock(&self) -> bool {
        false
    }
}

impl ServoHead for VirtualHead {
    fn advance_to(&mut self, t_s: f64) -> Result<()> {
        VirtualHead::advance_to(self, t_s)
    }
    fn command(&mut self, goal: &Joints) -> Result<()> {
        VirtualHead::command(self, goal);
        Ok(())
    }
    fn joints(&self) -> Joints {
        VirtualHead::joints(self)
    }
    fn is_moving(&self) -> bool {
        VirtualHead::is_moving(self)
    }
    fn time_s(&self) -> f64 {
        VirtualHead::time_s(self)
    }
    fn control_hz(&self) -> u32 {
        VirtualHead::control_hz(self)
    }
}

/// The longest a head's clock may stand still while the loop waits for it.
pub const CLOCK_TIMEOUT: Duration = Duration::from_secs(3);

/// How long the loop waits for the answer to one request to a [`RemoteHead`]: a `State` or
/// `Posture` exchange takes milliseconds, so a head that has not answered by then is stopped or
/// gone, and the loop says so (`hvs view` shows the error and goes on asking).
pub const REQUEST_TIMEOUT: Duration = Duration::from_secs(2);

/// How far (s) a head's clock, running again, may lag the loop's time before the lag is taken
/// as time the head lost ([`RemoteHead`]'s `advance_to`): a head that stood still (QEMU
/// stopped and continued, a paused controller) comes back with its clock behind by as long as
/// it stood, and waiting for it to catch up would hold every later frame back as long.
pub const CLOCK_RESYNC_S: f64 = 0.5;

/// A head controller on a link (the firmware in QEMU or a real head), protocol 3 or later.
pub struct RemoteHead {
    link: Link,
    hz: u32,
    /// The head's tick count when the loop started.
    t0_ticks: u32,
    state: StateData,
    goal: Option<Joints>,
    /// With [`RemoteHead::boot_qemu`]: QEMU, kept as long as the head (dropped after the
    /// link).
    _qemu: Option<crate::device::qemu::Emulator>,
}

impl RemoteHead {
    /// Takes over the head on `link`: checks that it speaks protocol 3 or later (`Posture`,
    /// `State`), then starts the loop's clock at the head's current tick. `control_hz` is the
    /// head's control rate (the firmware's: [`hvs_shared::runtime::trajectory::ControllerConfig`]).
    /// Requests from then on wait [`REQUEST_TIMEOUT`] for their answer.
    pub fn new(mut link: Link, control_hz: u32) -> Result<RemoteHead> {
        link.timeout = REQUEST_TIMEOUT;
        let info = client::expect(link.request(RequestBody::Info)?, "Info", |b| match b {
            ResponseBody::Info(i) => Some(i),
            _ => None,
        })?;
        if info.protocol < 3 {
            bail!(
                "{}: the head speaks protocol {} and cannot take posture commands (protocol 3, this hvs speaks {PROTOCOL_VERSION}): flash a newer firmware",
                link.endpoint(),
                info.protocol
            );
        }
        if control_hz == 0 {
            bail!("control rate 0 Hz");
        }
        let state = client::state(&mut link)?;
        Ok(RemoteHead {
            link,
            hz: control_hz,
            t0_ticks: state.ticks,
            state,
            goal: None,
            _qemu: None,
        })
    }

    /// The head firmware in QEMU (`firmware`, or the default build path as `hvs emulate` finds
    /// it) with `model` in slot A, taken over as [`RemoteHead::new`] does: what `--head qemu`
    /// runs. QEMU lives as long as the head.
    pub fn boot_qemu(
        model: &std::path::Path,
        firmware: Option<&std::path::Path>,
        control_hz: u32,
    ) -> Result<RemoteHead> {
        use crate::device::qemu::{
            find_firmware, free_port, preflight, Emulator, EmulatorConfig, DEFAULT_QEMU,
        };
        // Nothing reads the servo log of this QEMU: it goes nowhere (a temporary folder for
        // it was left behind when `hvs view` ended on SIGINT with the head's thread still
        // running).
        let cfg = EmulatorConfig {
            firmware: find_firmware(firmware),
            slot_a: Some(model.to_path_buf()),
            slot_b: None,
            listen: format!("127.0.0.1:{}", free_port()?),
            servo_log: std::path::PathBuf::from("/dev/null"),
            qemu: DEFAULT_QEMU.into(),
            extra: Vec::new(),
        };
        preflight(&cfg)?;
        let emu = Emulator::start(&cfg)?;
        let endpoint = emu.endpoint.parse()?;
        // This QEMU serves this run alone: a head that never answers is firmware that does not
        // run in QEMU (the board build, which writes the same path as the QEMU one).
        let link = client::connect(&endpoint, Duration::from_secs(20)).with_context(|| {
            format!(
                "the firmware {} does not answer in QEMU: is it the `--features qemu` build? (the board build writes the same path)",
                cfg.firmware.display()
            )
        })?;
        Ok(RemoteHead { _qemu: Some(emu), ..RemoteHead::new(link, control_hz)? })
    }

    fn elapsed_s(&self, s: &StateData) -> f64 {
        f64::from(s.ticks.wrapping_sub(self.t0_ticks)) / f64::from(self.hz)
    }
}

impl ServoHead for RemoteHead {
    fn advance_to(&mut self, t_s: f64) -> Result<()> {
        let before = self.state.ticks;
        let mut last = (self.state.ticks, Instant::now());
        let mut first = true;
        loop {
            self.state = client::state(&mut self.link)?;
            let now = self.elapsed_s(&self.state);
            if now + 1e-9 >= t_s {
                return Ok(());
            }
            // A clock that runs again far behind: the head lost that time ([`CLOCK_RESYNC_S`]).
            // Its clock is taken to be at `t_s` now. One that stands still is waited for.
            if first && t_s - now > CLOCK_RESYNC_S && self.state.ticks != before {
                let lag = ((t_s - now) * f64::from(self.hz)).round() as u64;
                self.t0_ticks = self.t0_ticks.wrapping_sub(lag as u32);
                return Ok(());
            }
            first = false;
            if self.state.ticks != last.0 {
                last = (self.state.ticks, Instant::now());
            } else if last.1.elapsed() > CLOCK_TIMEOUT {
                bail!(
                    "{}: the head's clock stood still for {CLOCK_TIMEOUT:?} (tick {})",
                    self.link.endpoint(),
                    self.state.ticks
                );
            }
            std::thread::sleep(Duration::from_secs_f64((t_s - now).clamp(0.0, 0.005)));
        }
    }

    fn command(&mut self, goal: &Joints) -> Result<()> {
        if self.goal == Some(*goal) {
            return Ok(());
        }
        self.state = client::posture(&mut self.link, goal)
            .with_context(|| format!("the posture {:?}", goal.0))?;
        self.goal = Some(*goal);
        Ok(())
    }

    fn joints(&self) -> Joints {
        self.state.joints
    }

    fn is_moving(&self) -> bool {
        self.state.moving
    }

    fn time_s(&self) -> f64 {
        self.elapsed_s(&self.state)
    }

    fn control_hz(&self) -> u32 {
        self.hz
    }

    fn frame_time(&self, _t_s: f64) -> f64 {
        self.time_s()
    }

    fn own_clock(&self) -> bool {
        true
    }
}

/// Which head the loop runs on.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum HeadChoice {
    /// The head's logic on the host, on a simulated clock ([`VirtualHead`]).
    Emulate,
    /// The head firmware in QEMU ([`RemoteHead::boot_qemu`]; `None`: the default firmware path).
    Qemu(Option<std::path::PathBuf>),
    /// A head controller on a link ([`RemoteHead`]): a real head's serial port, or
    /// `tcp:HOST:PORT` (e.g. `hvs emulate`'s QEMU).
    Port(crate::device::link::Endpoint),
}

/// `--port`'s value: `tcp:HOST:PORT`, `serial:PATH[@BAUD]`, or a bare serial port path (at the
/// protocol's baud rate).
pub fn parse_port(s: &str) -> Result<crate::device::link::Endpoint> {
    use crate::device::link::Endpoint;
    if s.starts_with("tcp:") || s.starts_with("serial:") {
        return s.parse();
    }
    if s.is_empty() {
        bail!("--port: empty");
    }
    Ok(Endpoint::Serial { path: s.to_string(), baud: hvs_shared::runtime::protocol::BAUD_RATE })
}

/// Opens the head of `choice` (`model`: the model QEMU boots with).
pub fn open(choice: &HeadChoice, model: &std::path::Path) -> Result<Box<dyn ServoHead + Send>> {
    let control = hvs_shared::runtime::trajectory::ControllerConfig::DEFAULT;
    Ok(match choice {
        HeadChoice::Emulate => Box::new(VirtualHead::new(&control)?),
        HeadChoice::Qemu(firmware) => {
            Box::new(RemoteHead::boot_qemu(model, firmware.as_deref(), control.control_hz)?)
        }
        HeadChoice::Port(endpoint) => {
            let link = client::connect(endpoint, Duration::from_secs(10))?;
            Box::new(RemoteHead::new(link, control.control_hz)?)
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::device::link::Endpoint;
    use hvs_shared::runtime::gaze::GazeConfig;
    use hvs_shared::runtime::head::{boot, Head};
    use hvs_shared::runtime::protocol::{
        decode_request, encode_response, FirmwareVersion, MAX_FRAME_LEN,
    };
    use hvs_shared::runtime::trajectory::ControllerConfig;
    use std::io::Write;
    use std::sync::atomic::{AtomicBool, AtomicU32, Ordering};
    use std::sync::Arc;

    /// A head on a TCP socket (the host-side head logic) whose clock is `ticks` and which,
    /// while `stopped`, answers nothing (QEMU under SIGSTOP), then answers what it was asked
    /// meanwhile, in order.
    fn head_on_tcp(ticks: Arc<AtomicU32>, stopped: Arc<AtomicBool>) -> String {
        let l = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
        let addr = l.local_addr().unwrap().to_string();
        std::thread::spawn(move || {
            let (s, _) = l.accept().unwrap();
            let control = ControllerConfig::DEFAULT;
            let mut head = Head::new(boot(&[], &[]), GazeConfig::DEFAULT, &control).unwrap();
            let version = FirmwareVersion { major: 0, minor: 1, patch: 0 };
            let mut out = [0u8; MAX_FRAME_LEN];
            crate::device::link::serve_frames(s, |f, s| {
                while stopped.load(Ordering::SeqCst) {
                    std::thread::sleep(Duration::from_millis(5));
                }
                head.ticks = ticks.load(Ordering::SeqCst);
                let r = head.respond(&decode_request(f).unwrap(), version);
                s.write_all(encode_response(&r, &mut out).unwrap())
            });
        });
        addr
    }

    /// A head that stood still (QEMU stopped, then continued) comes back with its clock
    /// behind the loop's by as long as it stood: the loop takes that time as lost and goes on
    /// at once. Before, every later frame waited as long again for the clock to catch up (`hvs
    /// view --head qemu`'s frames stopped after a SIGSTOP and SIGCONT of QEMU), and a request
    /// waited 20 s (the boot's connect timeout) before the head's silence was reported. A
    /// clock that stands still is still an error.
    #[test]
    fn a_head_that_stood_still_is_taken_up_where_it_is() {
        let (ticks, stopped) = (Arc::new(AtomicU32::new(1000)), Arc::new(AtomicBool::new(false)));
        let addr = head_on_tcp(ticks.clone(), stopped.clone());
        let mut link = Link::open(&Endpoint::Tcp(addr), Duration::from_secs(5)).unwrap();
        // As `boot_qemu` hands it over: its requests had waited as long as the boot may take.
        link.timeout = Duration::from_secs(20);
        let hz = ControllerConfig::DEFAULT.control_hz;
        let mut head = RemoteHead::new(link, hz).unwrap();
        let at = |s: f64| 1000 + (s * f64::from(hz)) as u32;
        ticks.store(at(0.2), Ordering::SeqCst);
        head.advance_to(0.1).unwrap();
        assert!((head.time_s() - 0.2).abs() < 1e-9, "{}", head.time_s());
        // Stopped: the request's answer does not come within REQUEST_TIMEOUT.
        stopped.store(true, Ordering::SeqCst);
        let t0 = Instant::now();
        let e = head.advance_to(0.3).unwrap_err().to_string();
        assert!(e.contains("no response"), "{e}");
        assert!(t0.elapsed() < REQUEST_TIMEOUT + Duration::from_secs(1), "{:?}", t0.elapsed());
        // Continued, its clock 0.1 s on from where it stood, the loop 10 s on.
        ticks.store(at(0.3), Ordering::SeqCst);
        stopped.store(false, Ordering::SeqCst);
        let t0 = Instant::now();
        head.advance_to(10.0).unwrap();
        assert!(t0.elapsed() < Duration::from_secs(1), "{:?}", t0.elapsed());
        assert!((head.time_s() - 10.0).abs() < 1.5 / f64::from(hz), "{}", head.time_s());
        // From there on its clock runs as before.
        ticks.fetch_add(hz / 10, Ordering::SeqCst);
        head.advance_to(10.05).unwrap();
        assert!((head.time_s() - 10.1).abs() < 1.5 / f64::from(hz), "{}", head.time_s());
        // A clock that stands still is waited for, then reported.
        let e = head.advance_to(12.0).unwrap_err().to_string();
        assert!(e.contains("stood still"), "{e}");
    }
}
