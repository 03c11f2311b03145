//! `hvs`: the host side of hvs-depth. Commands parse arguments and do I/O; all math is in
//! `hvs-shared`.

use anyhow::{Context, Result};
use clap::{Parser, Subcommand};
use std::path::PathBuf;

#[derive(Parser)]
#[command(
    name = "hvs",
    version,
    about = "Calibration-free stereo depth for a humanoid vision system"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Show what is in a weights blob: topology, metadata, CRC state.
    Info {
        /// The blob file.
        model: PathBuf,
    },
    /// Boot the head firmware in QEMU with a model in slot A.
    Emulate(hvs_host::emulate::EmulateArgs),
    /// Talk to a head (QEMU over TCP, or a serial port).
    Head(hvs_host::head::HeadArgs),
    /// Write a flashable image (bin or Intel HEX) of a model for one weight slot.
    Image(hvs_host::flash::ImageArgs),
    /// Write a model into the head's idle weight slot through a debug probe (probe-rs).
    Flash(hvs_host::flash::FlashArgs),
}

fn main() {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Info { model } => info(&model),
        Command::Emulate(a) => hvs_host::emulate::run(&a),
        Command::Head(a) => hvs_host::head::run(&a),
        Command::Image(a) => hvs_host::flash::run_image(&a),
        Command::Flash(a) => hvs_host::flash::run_flash(&a),
    };
    if let Err(e) = result {
        eprintln!("error: {e:#}");
        std::process::exit(1);
    }
}

fn info(path: &PathBuf) -> Result<()> {
    let bytes = std::fs::read(path).with_context(|| format!("{}: cannot read", path.display()))?;
    let blob =
        hvs_shared::blob::decode(&bytes).map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
    println!("file: {}", path.display());
    println!("crc: ok");
    println!("generation: {}", blob.generation);
    println!("topology: {:?}", blob.topology);
    println!("meta: {:?}", blob.meta);
    println!("fallback: {:?}", blob.fallback);
    Ok(())
}
