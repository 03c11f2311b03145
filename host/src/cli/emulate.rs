//! `hvs emulate`: boots the head firmware in QEMU with models in its weight slots
//! ([`crate::device::qemu`]).

use crate::device::qemu::{find_firmware, preflight, Emulator, EmulatorConfig, DEFAULT_QEMU};
use anyhow::Result;
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
    #[arg(long, default_value = DEFAULT_QEMU)]
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
