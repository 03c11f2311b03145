//! `hvs flash`: a model into the head's idle weight slot through a debug probe
//! ([`crate::device::flash_image`] plans, `device::debug_probe` writes; feature `probe`).

#[cfg(feature = "probe")]
use crate::device::debug_probe::{check_chip, flash_with_probe, FlashTarget};
#[cfg(feature = "probe")]
use crate::device::flash_image::dry_run_plan;
use crate::device::flash_image::{read_model, DEFAULT_CHIP};
use anyhow::Result;
use hvs_shared::runtime::layout::Slot;
use hvs_shared::runtime::slots::SlotRequest;
use std::path::PathBuf;

/// `--slot` of `hvs flash`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum SlotChoice {
    /// The slot that is not running (A if none is valid).
    Auto,
    /// Slot A.
    A,
    /// Slot B.
    B,
}

impl From<SlotChoice> for SlotRequest {
    fn from(c: SlotChoice) -> SlotRequest {
        match c {
            SlotChoice::Auto => SlotRequest::Auto,
            SlotChoice::A => SlotRequest::Exactly(Slot::A),
            SlotChoice::B => SlotRequest::Exactly(Slot::B),
        }
    }
}

/// Arguments of `hvs flash`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The weights blob (from `hvs train`).
    #[arg(long)]
    pub model: PathBuf,
    /// Target chip, any name probe-rs knows.
    #[arg(long, default_value = DEFAULT_CHIP)]
    pub chip: String,
    /// Debug probe as VID:PID or VID:PID:SERIAL (hex ids), when several are connected.
    #[arg(long)]
    pub probe: Option<String>,
    /// Which slot to write.
    #[arg(long, value_enum, default_value_t = SlotChoice::Auto)]
    pub slot: SlotChoice,
    /// Print the plan (slot, address, size, generation) without touching a probe.
    #[arg(long)]
    pub dry_run: bool,
    /// Do not reset the head after writing (it keeps running the old model until its next boot).
    #[arg(long)]
    pub no_reset: bool,
}

/// `hvs flash`.
#[cfg(feature = "probe")]
pub fn run(args: &Args) -> Result<()> {
    let (blob, bytes) = read_model(&args.model)?;
    check_chip(&args.chip)?;
    let req = SlotRequest::from(args.slot);
    if args.dry_run {
        print!("{}", dry_run_plan(&args.model, &blob, bytes.len(), &args.chip, req)?);
        return Ok(());
    }
    let target =
        FlashTarget { chip: args.chip.clone(), probe: args.probe.clone(), no_reset: args.no_reset };
    flash_with_probe(&target, &blob, req)
}

/// `hvs flash` in a build without the `probe` feature: the model is still checked, then a
/// clear error (the chip cannot be checked against probe-rs's database, so no plan either).
#[cfg(not(feature = "probe"))]
pub fn run(args: &Args) -> Result<()> {
    read_model(&args.model)?;
    anyhow::bail!(
        "hvs flash: this hvs was built without the `probe` feature (probe-rs); \
         rebuild with default features, or write `hvs image` output with another flasher"
    )
}
