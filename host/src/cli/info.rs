//! `hvs info`: what is in a weights blob, and whether it is intact.

use crate::data::model;
use anyhow::Result;
use std::io::Write;
use std::path::PathBuf;

/// Arguments of `hvs info`.
#[derive(Debug, clap::Args)]
#[command(
    about = "Show what is in a weights blob: topology, metadata, fallback, CRC state",
    long_about = "Show what is in a weights blob: topology, training metadata, fallback \
    calibration, generation, training input box, size and CRC state. A damaged file is \
    reported with the check that failed (magic, version, length, CRC, payload, topology, \
    parameters) and a non-zero exit code."
)]
pub struct Args {
    /// The blob file.
    #[arg(value_name = "MODEL")]
    model: PathBuf,
}

/// Runs `hvs info`.
pub fn run(a: Args) -> Result<()> {
    let f = model::load(&a.model)?;
    let mut o = std::io::stdout().lock();
    o.write_all(crate::train::describe::describe(&a.model, &f).as_bytes())?;
    o.flush()?;
    Ok(())
}
