//! `hvs image`: a flashable file (raw binary or Intel HEX) of a model for one weight slot, for
//! other flashers ([`crate::device::flash_image`]).

use super::value_enum;
use crate::data::output::check_not_input;
use crate::data::output::write_bytes;
use crate::device::flash_image::{image, read_model, ImageFormat};
use anyhow::Result;
use hvs_shared::runtime::layout::Slot;
use std::path::PathBuf;

value_enum! {
    /// A slot on the command line.
    SlotArg => Slot {
        /// Slot A, flash sector 10 at 0x080C0000.
        A,
        /// Slot B, flash sector 11 at 0x080E0000.
        B,
    }
}

value_enum! {
    /// Output format of `hvs image`.
    FormatArg => ImageFormat {
        /// Raw bytes, to be loaded at the slot address (`--base-address`).
        Bin,
        /// Intel HEX carrying its own addresses.
        Hex,
    }
}

/// Arguments of `hvs image`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The weights blob (from `hvs train`).
    #[arg(long)]
    pub model: PathBuf,
    /// The slot the image is for.
    #[arg(long, value_enum)]
    pub slot: SlotArg,
    /// Generation number to stamp into the blob (default: keep the model's).
    #[arg(long, allow_negative_numbers = true, value_parser = crate::cli::whole_u32)]
    pub generation: Option<u32>,
    /// Output format.
    #[arg(long, value_enum)]
    pub format: FormatArg,
    /// Output file.
    #[arg(short = 'o', long)]
    pub output: PathBuf,
}

/// `hvs image`.
pub fn run(args: &Args) -> Result<()> {
    check_not_input("-o", &args.output, &[("--model", &args.model)])?;
    let (blob, bytes) = read_model(&args.model)?;
    let slot = Slot::from(args.slot);
    let format = ImageFormat::from(args.format);
    let (out, blob_len) = image(&blob, bytes, args.generation, slot, format)?;
    write_bytes(&args.output, &out)?;
    let generation = args.generation.unwrap_or(blob.generation);
    crate::cli::say(format_args!(
        "wrote {} ({}, {} blob bytes) for slot {:?} at {:#010x}, generation {}",
        args.output.display(),
        match format {
            ImageFormat::Bin => "raw binary",
            ImageFormat::Hex => "Intel HEX",
        },
        blob_len,
        slot,
        slot.addr(),
        generation
    ))?;
    Ok(())
}
