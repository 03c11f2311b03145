//! `hvs image` and `hvs flash`: put a weights blob into a head's weight slot.
//!
//! `image` writes a flashable file (raw binary or Intel HEX) for other flashers; `flash` uses
//! the `probe-rs` library to read both slots through a debug probe, write the model into the
//! slot that is not running with the next generation number (the rules of
//! [`hvs_shared::slots`]), verify it by reading it back, and reset the head. Only the target
//! slot's sector is erased: a write cut off half-way leaves the running model in place.

use anyhow::{anyhow, bail, Context, Result};
use clap::{Args, ValueEnum};
use hvs_shared::blob::{self, ModelBlob, MAX_BLOB_LEN};
use hvs_shared::layout::{Slot, SLOT_LEN};
use hvs_shared::slots::{plan_write, SlotRequest, SlotState};
use std::io::Write;
use std::path::{Path, PathBuf};

/// The head controller's chip.
pub const DEFAULT_CHIP: &str = "STM32F405RGTx";

/// A slot on the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum SlotArg {
    /// Slot A, flash sector 10 at 0x080C0000.
    A,
    /// Slot B, flash sector 11 at 0x080E0000.
    B,
}

impl From<SlotArg> for Slot {
    fn from(s: SlotArg) -> Slot {
        match s {
            SlotArg::A => Slot::A,
            SlotArg::B => Slot::B,
        }
    }
}

/// `--slot` of `hvs flash`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum SlotChoice {
    /// The slot that is not running (A if none is valid).
    Auto,
    /// Slot A.
    A,
    /// Slot B.
    B,
}

/// Output format of `hvs image`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum ImageFormat {
    /// Raw bytes, to be loaded at the slot address (`--base-address`).
    Bin,
    /// Intel HEX carrying its own addresses.
    Hex,
}

/// Arguments of `hvs image`.
#[derive(Debug, Args)]
pub struct ImageArgs {
    /// The weights blob (from `hvs train`).
    #[arg(long)]
    pub model: PathBuf,
    /// The slot the image is for.
    #[arg(long, value_enum)]
    pub slot: SlotArg,
    /// Generation number to stamp into the blob (default: keep the model's).
    #[arg(long)]
    pub generation: Option<u32>,
    /// Output format.
    #[arg(long, value_enum)]
    pub format: ImageFormat,
    /// Output file.
    #[arg(short = 'o', long)]
    pub output: PathBuf,
}

/// Arguments of `hvs flash`.
#[derive(Debug, Args)]
pub struct FlashArgs {
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

/// Reads and validates a blob file; errors name the file.
pub fn read_model(path: &Path) -> Result<(ModelBlob, Vec<u8>)> {
    let bytes = std::fs::read(path).with_context(|| format!("{}: cannot read", path.display()))?;
    let blob = blob::decode(&bytes).map_err(|e| anyhow!("{}: {e}", path.display()))?;
    let len = blob::framed_len(&bytes).map_err(|e| anyhow!("{}: {e}", path.display()))?;
    Ok((blob, bytes[..len].to_vec()))
}

/// The blob re-encoded with a new generation number.
pub fn with_generation(blob: &ModelBlob, generation: u32) -> Result<Vec<u8>> {
    let mut b = blob.clone();
    b.generation = generation;
    let mut buf = vec![0u8; MAX_BLOB_LEN];
    let n = b
        .encode(&mut buf)
        .map_err(|e| anyhow!("cannot encode blob: {e}"))?;
    buf.truncate(n);
    Ok(buf)
}

/// Intel HEX of `bytes` placed at `addr`: extended linear address records and 16-byte data
/// records, then end-of-file.
pub fn intel_hex(addr: u32, bytes: &[u8]) -> Result<String> {
    use ihex::Record;
    let mut records = Vec::new();
    let mut upper: Option<u16> = None;
    let mut pos = 0usize;
    while pos < bytes.len() {
        let a = addr + pos as u32;
        let hi = (a >> 16) as u16;
        if upper != Some(hi) {
            records.push(Record::ExtendedLinearAddress(hi));
            upper = Some(hi);
        }
        // Stay inside the 64 KiB window and in 16-byte records.
        let room = 0x1_0000 - (a & 0xFFFF) as usize;
        let n = (bytes.len() - pos).min(16).min(room);
        records.push(Record::Data {
            offset: (a & 0xFFFF) as u16,
            value: bytes[pos..pos + n].to_vec(),
        });
        pos += n;
    }
    records.push(Record::EndOfFile);
    ihex::create_object_file_representation(&records)
        .map_err(|e| anyhow!("cannot write Intel HEX: {e}"))
}

/// Writes `data` to `path` atomically (temporary file in the same directory, then rename).
pub fn write_atomic(path: &Path, data: &[u8]) -> Result<()> {
    let dir = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let mut tmp = tempfile::NamedTempFile::new_in(dir)
        .with_context(|| format!("{}: cannot create", path.display()))?;
    tmp.write_all(data)
        .with_context(|| format!("{}: cannot write", path.display()))?;
    tmp.as_file().sync_all().ok();
    tmp.persist(path)
        .map_err(|e| anyhow!("{}: cannot write: {}", path.display(), e.error))?;
    Ok(())
}

/// `hvs image`.
pub fn run_image(args: &ImageArgs) -> Result<()> {
    let (blob, bytes) = read_model(&args.model)?;
    let bytes = match args.generation {
        Some(g) => with_generation(&blob, g)?,
        None => bytes,
    };
    let slot = Slot::from(args.slot);
    let out = match args.format {
        ImageFormat::Bin => bytes.clone(),
        ImageFormat::Hex => intel_hex(slot.addr(), &bytes)?.into_bytes(),
    };
    write_atomic(&args.output, &out)?;
    let generation = args.generation.unwrap_or(blob.generation);
    println!(
        "wrote {} ({:?}, {} blob bytes) for slot {:?} at {:#010x}, generation {}",
        args.output.display(),
        args.format,
        bytes.len(),
        slot,
        slot.addr(),
        generation
    );
    Ok(())
}

/// Checks that the chip is known to probe-rs and that both slots lie in its flash.
fn check_chip(chip: &str) -> Result<()> {
    let target = probe_rs::config::Registry::from_builtin_families()
        .get_target_by_name(chip)
        .map_err(|e| anyhow!("--chip {chip}: {e}"))?;
    for slot in [Slot::A, Slot::B] {
        let (lo, hi) = (slot.addr() as u64, slot.addr() as u64 + SLOT_LEN as u64);
        let inside = target.memory_map.iter().any(|r| match r {
            probe_rs::config::MemoryRegion::Nvm(n) => n.range.start <= lo && hi <= n.range.end,
            _ => false,
        });
        if !inside {
            bail!(
                "--chip {chip}: slot {slot:?} ({lo:#010x}..{hi:#010x}) is not in this chip's flash"
            );
        }
    }
    Ok(())
}

/// `hvs flash`.
pub fn run_flash(args: &FlashArgs) -> Result<()> {
    let (blob, bytes) = read_model(&args.model)?;
    check_chip(&args.chip)?;
    let req = match args.slot {
        SlotChoice::Auto => SlotRequest::Auto,
        SlotChoice::A => SlotRequest::Exactly(Slot::A),
        SlotChoice::B => SlotRequest::Exactly(Slot::B),
    };
    if args.dry_run {
        print!(
            "{}",
            dry_run_plan(&args.model, &blob, bytes.len(), &args.chip, args.slot)
        );
        return Ok(());
    }
    flash_with_probe(args, &blob, req)
}

/// The text `--dry-run` prints: no probe is touched, so the running slot is not known yet.
pub fn dry_run_plan(
    model: &Path,
    blob: &ModelBlob,
    size: usize,
    chip: &str,
    slot: SlotChoice,
) -> String {
    let t = &blob.topology;
    let (slot_line, gen_line) = match slot {
        SlotChoice::Auto => (
            format!(
                "slot: auto = the slot not running (A at {:#010x} if none is valid, else the other of A {:#010x} / B {:#010x})",
                Slot::A.addr(),
                Slot::A.addr(),
                Slot::B.addr()
            ),
            "generation: 1 + the highest valid generation read from the head (1 if none)".to_string(),
        ),
        SlotChoice::A | SlotChoice::B => {
            let s = if slot == SlotChoice::A { Slot::A } else { Slot::B };
            (
                format!("slot: {s:?} at {:#010x} (sector {})", s.addr(), s.sector()),
                "generation: 1 + the highest valid generation read from the head (1 if none)".to_string(),
            )
        }
    };
    format!(
        "dry run: nothing written, no probe touched\nmodel: {} ({} bytes, CRC ok, {}-{}-{}, generation in file {})\nchip: {chip}\n{slot_line}\nerase: that slot's 128 KiB sector only\nwrite: {size} bytes, then read back and check the CRC\n{gen_line}\n",
        model.display(),
        size,
        t.inputs.len(),
        t.hidden,
        t.outputs.len(),
        blob.generation
    )
}

fn parse_selector(s: &str) -> Result<probe_rs::probe::DebugProbeSelector> {
    s.parse()
        .map_err(|e| anyhow!("--probe {s}: expected VID:PID or VID:PID:SERIAL ({e})"))
}

fn read_slot(session: &mut probe_rs::Session, slot: Slot) -> Result<Vec<u8>> {
    use probe_rs::MemoryInterface;
    let mut buf = vec![0u8; MAX_BLOB_LEN];
    let mut core = session.core(0).context("cannot access the core")?;
    core.read(slot.addr() as u64, &mut buf)
        .with_context(|| format!("cannot read slot {slot:?}"))?;
    Ok(buf)
}

fn flash_with_probe(args: &FlashArgs, blob: &ModelBlob, req: SlotRequest) -> Result<()> {
    let lister = probe_rs::probe::list::Lister::new();
    let probes = lister.list_all();
    let info = match &args.probe {
        Some(s) => {
            let sel = parse_selector(s)?;
            probes
                .iter()
                .find(|p| {
                    p.vendor_id == sel.vendor_id
                        && p.product_id == sel.product_id
                        && (sel.serial_number.is_none() || p.serial_number == sel.serial_number)
                })
                .ok_or_else(|| anyhow!("no debug probe matches --probe {s} ({} connected)", probes.len()))?
        }
        None => match probes.as_slice() {
            [] => bail!("no debug probe found: connect an ST-Link, J-Link or CMSIS-DAP probe to the head (or use --dry-run)"),
            [one] => one,
            many => bail!(
                "{} debug probes found, choose one with --probe VID:PID[:SERIAL]: {}",
                many.len(),
                many.iter().map(|p| p.to_string()).collect::<Vec<_>>().join("; ")
            ),
        },
    };
    let probe = info
        .open()
        .with_context(|| format!("cannot open probe {info}"))?;
    let mut session = probe
        .attach(args.chip.as_str(), probe_rs::Permissions::default())
        .with_context(|| format!("cannot attach to {}", args.chip))?;
    let a = SlotState::of(&read_slot(&mut session, Slot::A)?);
    let b = SlotState::of(&read_slot(&mut session, Slot::B)?);
    println!("slot A: {a:?}\nslot B: {b:?}");
    let plan = plan_write(a, b, req).map_err(|e| anyhow!("{e}"))?;
    let bytes = with_generation(blob, plan.generation)?;
    println!(
        "writing {} bytes to slot {:?} at {:#010x}, generation {} (running: {:?})",
        bytes.len(),
        plan.slot,
        plan.slot.addr(),
        plan.generation,
        plan.running
    );
    let mut loader = session.target().flash_loader();
    loader
        .add_data(plan.slot.addr() as u64, &bytes)
        .context("cannot stage the blob")?;
    let mut opts = probe_rs::flashing::DownloadOptions::default();
    opts.verify = true;
    loader
        .commit(&mut session, opts)
        .context("flash write failed; the running slot was not touched")?;
    let back = read_slot(&mut session, plan.slot)?;
    match SlotState::of(&back) {
        SlotState::Valid { generation } if generation == plan.generation => {}
        other => bail!(
            "read-back of slot {:?} is {other:?}; the previous model still boots",
            plan.slot
        ),
    }
    println!(
        "verified: slot {:?} holds generation {} (CRC ok)",
        plan.slot, plan.generation
    );
    if !args.no_reset {
        session
            .core(0)
            .context("cannot access the core")?
            .reset()
            .context("cannot reset the head")?;
        println!("head reset: it now boots slot {:?}", plan.slot);
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn intel_hex_has_addresses_and_checksums() {
        let data: Vec<u8> = (0..40u8).collect();
        let hex = intel_hex(0x080C_0000, &data).unwrap();
        let lines: Vec<&str> = hex.lines().collect();
        assert_eq!(lines[0], ":02000004080CE6");
        assert!(lines[1].starts_with(":10000000000102030405060708090A0B0C0D0E0F"));
        assert_eq!(lines.last().copied(), Some(":00000001FF"));
        // Parse it back.
        let mut got = Vec::new();
        let mut base = 0u32;
        for r in ihex::Reader::new(&hex) {
            match r.unwrap() {
                ihex::Record::ExtendedLinearAddress(h) => base = (h as u32) << 16,
                ihex::Record::Data { offset, value } => {
                    assert_eq!(base + offset as u32, 0x080C_0000 + got.len() as u32);
                    got.extend(value);
                }
                _ => {}
            }
        }
        assert_eq!(got, data);
    }

    #[test]
    fn hex_records_never_cross_a_64k_window() {
        let data = vec![0xAB; 64];
        let hex = intel_hex(0x0800_FFF8, &data).unwrap();
        assert!(hex.contains(":020000040801F1"));
    }

    #[test]
    fn chip_check() {
        check_chip(DEFAULT_CHIP).unwrap();
        assert!(check_chip("NOT_A_CHIP").is_err());
        // 256 KiB part: the slots are not in its flash.
        assert!(check_chip("STM32F401CCUx").is_err());
    }
}
