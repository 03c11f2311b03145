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

/// A head controller on a link (the firmware in QEMU or a real head), protocol 3 or later.
pub struct RemoteHead {
    link: Link,
    hz: u32,
    /// The head's tick count when the loop started.
    t0_ticks: u32,
    state: StateData,
    goal: Option<Joints>,
    /// With [`RemoteHead::boot_qemu`]: QEMU and its servo log's folder, kept as long as the
    /// head (dropped after the link).
    _qemu: Option<(crate::device::qemu::Emulator, tempfile::TempDir)>,
}

impl RemoteHead {
    /// Takes over the head on `link`: checks that it speaks protocol 3 or later (`Posture`,
    /// `State`), then starts the loop's clock at the head's current tick. `control_hz` is the
    /// head's control rate (the firmware's: [`hvs_shared::runtime::trajectory::ControllerConfig`]).
    pub fn new(mut link: Link, control_hz: u32) -> Result<RemoteHead> {
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
        let dir = tempfile::tempdir()
            .map_err(|e| anyhow::anyhow!("a temporary folder for QEMU's servo log: {e}"))?;
        let cfg = EmulatorConfig {
            firmware: find_firmware(firmware),
            slot_a: Some(model.to_path_buf()),
            slot_b: None,
            listen: format!("127.0.0.1:{}", free_port()?),
            servo_log: dir.path().join("servo.log"),
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
        Ok(RemoteHead { _qemu: Some((emu, dir)), ..RemoteHead::new(link, control_hz)? })
    }

    fn elapsed_s(&self, s: &StateData) -> f64 {
        f64::from(s.ticks.wrapping_sub(self.t0_ticks)) / f64::from(self.hz)
    }
}

impl ServoHead for RemoteHead {
    fn advance_to(&mut self, t_s: f64) -> Result<()> {
        let mut last = (self.state.ticks, Instant::now());
        loop {
            self.state = client::state(&mut self.link)?;
            let now = self.elapsed_s(&self.state);
            if now + 1e-9 >= t_s {
                return Ok(());
            }
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
