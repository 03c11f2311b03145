//! `hvs emulate`: boots the head firmware in QEMU with models in its weight slots
//! ([`crate::device::qemu`]).

use crate::data::output::check_not_input;
use crate::device::qemu::{find_firmware, Emulator, EmulatorConfig};
use anyhow::{anyhow, bail, Context, Result};
use std::path::PathBuf;
use std::time::Duration;

/// Arguments of `hvs emulate`.
#[derive(Debug, Clone, clap::Args)]
pub struct Args {
    /// Weights blob loaded into slot A (0x080C0000).
    #[arg(long, alias = "slot-a")]
    pub model: Option<PathBuf>,
    /// Weights blob loaded into slot B (0x080E0000).
    #[arg(long)]
    pub slot_b: Option<PathBuf>,
    /// TCP address of the protocol USART (QEMU listens; connect with `hvs head --connect`).
    #[arg(long, default_value = "127.0.0.1:4444")]
    pub listen: String,
    /// File receiving the servo USART (MCDC commands).
    #[arg(long, default_value = "servo.log")]
    pub servo_log: PathBuf,
    /// Firmware ELF [default: $HVS_FIRMWARE, else target/thumbv7em-none-eabihf/firmware/hvs-firmware
    /// next to the hvs executable's target directory or the current directory].
    #[arg(long)]
    pub firmware: Option<PathBuf>,
    /// QEMU executable.
    #[arg(long, default_value = "qemu-system-arm")]
    pub qemu: String,
    /// Stop QEMU after this many seconds (default: run until interrupted).
    #[arg(long, allow_negative_numbers = true, value_parser = crate::cli::whole_u64)]
    pub timeout: Option<u64>,
}

/// `hvs emulate`.
pub fn run(args: &Args) -> Result<()> {
    let cfg = EmulatorConfig {
        firmware: find_firmware(args.firmware.as_deref()),
        slot_a: args.model.clone(),
        slot_b: args.slot_b.clone(),
        listen: args.listen.clone(),
        servo_log: args.servo_log.clone(),
        qemu: args.qemu.clone(),
        extra: Vec::new(),
    };
    preflight(&cfg)?;
    let mut emu = Emulator::start(&cfg)?;
    eprintln!(
        "QEMU netduinoplus2 running {}; protocol on {} (the CPU starts when a client connects), servo USART -> {}",
        cfg.firmware.display(),
        emu.endpoint,
        cfg.servo_log.display()
    );
    let exited = emu.wait(args.timeout.map(Duration::from_secs))?;
    if exited {
        emu.check_alive()?;
    }
    Ok(())
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
    check_not_input("--servo-log", log, &inputs)?;
    let addrs: Vec<std::net::SocketAddr> = std::net::ToSocketAddrs::to_socket_addrs(&cfg.listen)
        .map_err(|e| anyhow!("--listen {}: not a HOST:PORT address ({e})", cfg.listen))?
        .collect();
    let first =
        addrs.first().ok_or_else(|| anyhow!("--listen {}: the host has no address", cfg.listen))?;
    // Bound and released at once: QEMU binds it next.
    std::net::TcpListener::bind(first)
        .map_err(|e| anyhow!("--listen {}: cannot listen there: {e}", cfg.listen))?;
    Ok(())
}

/// The firmware file is a 32-bit little-endian ARM ELF executable.
fn check_firmware(p: &std::path::Path) -> Result<()> {
    use std::io::Read;
    if !p.exists() {
        bail!(
            "{}: firmware ELF not found; build it with `{}`",
            p.display(),
            crate::device::qemu::FIRMWARE_BUILD
        );
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
