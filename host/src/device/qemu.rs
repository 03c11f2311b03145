//! Boots the head firmware in QEMU (`netduinoplus2`, an STM32F405) with weight
//! blobs loaded into the flash slots, the protocol USART on a TCP port and the servo USART
//! logged to a file.
//!
//! [`Emulator`] is the library form used by `hvs emulate` and the tests: it starts QEMU and
//! kills it when dropped. QEMU waits for a client on the TCP port before it starts the CPU
//! (`server=on,wait=on`), so nothing the firmware sends is lost.

use anyhow::{bail, Context, Result};
use hvs_shared::runtime::layout::{SLOT_A_ADDR, SLOT_B_ADDR};
use std::net::TcpListener;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// Where the firmware ELF is built (relative to the workspace's target directory).
pub const FIRMWARE_REL: &str = "thumbv7em-none-eabihf/firmware/hvs-firmware";
/// The command that builds it (from the workspace root).
pub const FIRMWARE_BUILD: &str =
    "cargo build --profile firmware -p hvs-firmware --target thumbv7em-none-eabihf --features qemu";

/// The QEMU executable run unless another is given (`hvs emulate --qemu`).
pub const DEFAULT_QEMU: &str = "qemu-system-arm";

/// What to boot.
#[derive(Debug, Clone)]
pub struct EmulatorConfig {
    /// Firmware ELF.
    pub firmware: PathBuf,
    /// Blob for slot A.
    pub slot_a: Option<PathBuf>,
    /// Blob for slot B.
    pub slot_b: Option<PathBuf>,
    /// `HOST:PORT` QEMU listens on for the protocol USART.
    pub listen: String,
    /// Servo USART log file.
    pub servo_log: PathBuf,
    /// QEMU executable.
    pub qemu: String,
    /// Extra QEMU arguments (for example `-icount shift=0,sleep=off`).
    pub extra: Vec<String>,
}

/// Makes the child get SIGKILL when this process dies, however it dies (SIGTERM, SIGKILL,
/// a crash): `Drop` alone only covers a normal exit, and an orphaned QEMU would keep the TCP
/// port and the servo log.
#[cfg(target_os = "linux")]
fn die_with_parent(cmd: &mut Command) {
    use std::os::unix::process::CommandExt;
    // SAFETY: the closure runs in the forked child before exec and only makes the
    // async-signal-safe prctl(2) call; it touches no memory of the parent.
    unsafe {
        cmd.pre_exec(|| {
            if libc::prctl(libc::PR_SET_PDEATHSIG, libc::SIGKILL) == -1 {
                return Err(std::io::Error::last_os_error());
            }
            Ok(())
        });
    }
}

#[cfg(not(target_os = "linux"))]
fn die_with_parent(_: &mut Command) {}

/// A running QEMU; killed on drop.
pub struct Emulator {
    child: Child,
    /// The `tcp:HOST:PORT` endpoint of the protocol USART.
    pub endpoint: String,
}

/// The QEMU command line for `cfg` (without the executable).
pub fn qemu_args(cfg: &EmulatorConfig) -> Vec<String> {
    let mut a: Vec<String> =
        ["-machine", "netduinoplus2", "-display", "none", "-monitor", "none", "-nodefaults"]
            .iter()
            .map(|s| s.to_string())
            .collect();
    a.push("-serial".into());
    a.push(format!("tcp:{},server=on,wait=on,nodelay=on", cfg.listen));
    a.push("-serial".into());
    a.push(format!("file:{}", cfg.servo_log.display()));
    for (blob, addr) in [(&cfg.slot_a, SLOT_A_ADDR), (&cfg.slot_b, SLOT_B_ADDR)] {
        if let Some(b) = blob {
            a.push("-device".into());
            a.push(format!("loader,file={},addr={addr:#010x},force-raw=on", b.display()));
        }
    }
    a.push("-kernel".into());
    a.push(cfg.firmware.display().to_string());
    a.extend(cfg.extra.iter().cloned());
    a
}

impl Emulator {
    /// Starts QEMU. Fails with a clear message when QEMU or a file is missing.
    pub fn start(cfg: &EmulatorConfig) -> Result<Emulator> {
        for (what, p) in [
            ("firmware", Some(&cfg.firmware)),
            ("slot A model", cfg.slot_a.as_ref()),
            ("slot B model", cfg.slot_b.as_ref()),
        ] {
            if let Some(p) = p {
                if !p.is_file() {
                    if what == "firmware" {
                        bail!(
                            "{}: firmware ELF not found; build it with `{FIRMWARE_BUILD}`",
                            p.display()
                        );
                    }
                    bail!("{}: {what} not found", p.display());
                }
                // QEMU's option parser splits on commas.
                if p.display().to_string().contains(',') {
                    bail!("{}: QEMU cannot take a path containing ','", p.display());
                }
            }
        }
        let mut cmd = Command::new(&cfg.qemu);
        cmd.args(qemu_args(cfg)).stdin(Stdio::null()).stdout(Stdio::null()).stderr(Stdio::piped());
        die_with_parent(&mut cmd);
        let child = cmd.spawn().with_context(|| {
            format!("cannot run {:?} (install it: apt-get install qemu-system-arm)", cfg.qemu)
        })?;
        let mut emu = Emulator { child, endpoint: format!("tcp:{}", cfg.listen) };
        // QEMU exits at once on a bad option or file; report its message.
        std::thread::sleep(Duration::from_millis(100));
        emu.check_alive()?;
        Ok(emu)
    }

    /// Errors with QEMU's own message if it has exited.
    pub fn check_alive(&mut self) -> Result<()> {
        if let Some(status) = self.child.try_wait()? {
            let mut msg = String::new();
            if let Some(mut e) = self.child.stderr.take() {
                use std::io::Read;
                let _ = e.read_to_string(&mut msg);
            }
            bail!("QEMU exited ({status}): {}", msg.trim());
        }
        Ok(())
    }

    /// Waits for QEMU to exit, at most `limit` (then kills it). Returns whether it exited
    /// on its own.
    pub fn wait(&mut self, limit: Option<Duration>) -> Result<bool> {
        let start = Instant::now();
        loop {
            if self.child.try_wait()?.is_some() {
                return Ok(true);
            }
            if limit.is_some_and(|l| start.elapsed() >= l) {
                self.kill();
                return Ok(false);
            }
            std::thread::sleep(Duration::from_millis(100));
        }
    }

    /// Stops QEMU.
    pub fn kill(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

impl Drop for Emulator {
    fn drop(&mut self) {
        self.kill();
    }
}

/// A TCP port on 127.0.0.1 that was free a moment ago.
pub fn free_port() -> Result<u16> {
    let l = TcpListener::bind("127.0.0.1:0").context("cannot bind a local TCP port")?;
    Ok(l.local_addr()?.port())
}

/// The firmware ELF to use: `explicit`, else `$HVS_FIRMWARE`, else the first existing of
/// `<target dir of this executable>/FIRMWARE_REL` and `./target/FIRMWARE_REL`.
pub fn find_firmware(explicit: Option<&Path>) -> PathBuf {
    if let Some(p) = explicit {
        return p.to_path_buf();
    }
    if let Some(p) = std::env::var_os("HVS_FIRMWARE") {
        return PathBuf::from(p);
    }
    let mut candidates = Vec::new();
    if let Ok(exe) = std::env::current_exe() {
        // target/<profile>/hvs or target/<profile>/deps/test-binary
        for up in exe.ancestors().skip(1).take(3) {
            candidates.push(up.join(FIRMWARE_REL));
        }
    }
    candidates.push(Path::new("target").join(FIRMWARE_REL));
    candidates
        .iter()
        .find(|p| p.is_file())
        .cloned()
        .unwrap_or_else(|| candidates.pop().unwrap_or_default())
}

/// `EM_ARM`, the ELF machine of the Cortex-M4F firmware.
const EM_ARM: u16 = 40;

/// Checks everything QEMU would otherwise stumble on after `hvs emulate` reported it running
/// (the first client then sees only "connection closed by the head"): the models decode,
/// the firmware is a 32-bit ARM ELF, the servo log's directory exists, the listen address
/// can be bound.
pub fn preflight(cfg: &EmulatorConfig) -> Result<()> {
    for (flag, p) in [("--model", &cfg.slot_a), ("--slot-b", &cfg.slot_b)] {
        if let Some(p) = p {
            crate::data::model::load(p).with_context(|| flag.to_string())?;
            // The file is loaded into the slot as it is: one longer than the slot would
            // spill into the next slot (or past the flash).
            let len = std::fs::metadata(p).map(|m| m.len()).unwrap_or(0);
            let slot = u64::from(hvs_shared::runtime::layout::SLOT_LEN);
            if len > slot {
                bail!(
                    "{flag} {}: {len} bytes, more than a weight slot holds ({slot} bytes): write the model alone (hvs train -o, hvs image)",
                    p.display()
                );
            }
        }
    }
    check_firmware(&cfg.firmware)?;
    let log = &cfg.servo_log;
    let dir = match log.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => std::path::Path::new("."),
    };
    if !dir.is_dir() {
        bail!("--servo-log {}: the directory {} does not exist", log.display(), dir.display());
    }
    if log.is_dir() {
        bail!("--servo-log {}: is a directory", log.display());
    }
    let mut inputs = vec![("--firmware", cfg.firmware.as_path())];
    inputs.extend(cfg.slot_a.as_deref().map(|p| ("--model", p)));
    inputs.extend(cfg.slot_b.as_deref().map(|p| ("--slot-b", p)));
    crate::data::output::check_not_input("--servo-log", log, &inputs)?;
    let addrs: Vec<std::net::SocketAddr> = std::net::ToSocketAddrs::to_socket_addrs(&cfg.listen)
        .map_err(|e| anyhow::anyhow!("--listen {}: not a HOST:PORT address ({e})", cfg.listen))?
        .collect();
    let first = addrs
        .first()
        .ok_or_else(|| anyhow::anyhow!("--listen {}: the host has no address", cfg.listen))?;
    // Bound and released at once: QEMU binds it next.
    std::net::TcpListener::bind(first)
        .map_err(|e| anyhow::anyhow!("--listen {}: cannot listen there: {e}", cfg.listen))?;
    Ok(())
}

/// The firmware file is a 32-bit little-endian ARM ELF executable.
fn check_firmware(p: &std::path::Path) -> Result<()> {
    use std::io::Read;
    if !p.exists() {
        bail!("{}: firmware ELF not found; build it with `{}`", p.display(), FIRMWARE_BUILD);
    }
    let mut head = Vec::with_capacity(20);
    std::fs::File::open(p)
        .and_then(|f| f.take(20).read_to_end(&mut head))
        .with_context(|| format!("--firmware {}: cannot read", p.display()))?;
    if head.len() < 20 || head[..4] != *b"\x7fELF" {
        bail!(
            "--firmware {}: not an ELF file (first bytes {:02x?}); give the hvs-firmware ELF",
            p.display(),
            &head[..head.len().min(4)]
        );
    }
    let machine = u16::from_le_bytes([head[18], head[19]]);
    if head[4] != 1 || head[5] != 1 || machine != EM_ARM {
        bail!(
            "--firmware {}: an ELF for another machine (class {}, data {}, e_machine {machine}); \
             the head runs a 32-bit little-endian ARM ELF (e_machine {EM_ARM})",
            p.display(),
            head[4],
            head[5]
        );
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn command_line_loads_slots_at_the_layout_addresses() {
        let cfg = EmulatorConfig {
            firmware: "fw.elf".into(),
            slot_a: Some("a.bin".into()),
            slot_b: Some("b.bin".into()),
            listen: "127.0.0.1:5555".into(),
            servo_log: "s.log".into(),
            qemu: "qemu-system-arm".into(),
            extra: vec![],
        };
        let a = qemu_args(&cfg).join(" ");
        assert!(a.contains("loader,file=a.bin,addr=0x080c0000,force-raw=on"), "{a}");
        assert!(a.contains("loader,file=b.bin,addr=0x080e0000,force-raw=on"), "{a}");
        // USART1 = first -serial = protocol, USART2 = servo log.
        let i_tcp = a.find("tcp:127.0.0.1:5555,server=on,wait=on,nodelay=on").unwrap();
        let i_file = a.find("file:s.log").unwrap();
        assert!(i_tcp < i_file);
        assert!(a.ends_with("-kernel fw.elf"));
    }

    #[test]
    fn missing_files_are_clear_errors() {
        let cfg = EmulatorConfig {
            firmware: "/nonexistent/fw.elf".into(),
            slot_a: None,
            slot_b: None,
            listen: "127.0.0.1:1".into(),
            servo_log: "s.log".into(),
            qemu: "qemu-system-arm".into(),
            extra: vec![],
        };
        let e = Emulator::start(&cfg).err().unwrap().to_string();
        assert!(e.contains("/nonexistent/fw.elf") && e.contains("cargo build"), "{e}");
    }
}
