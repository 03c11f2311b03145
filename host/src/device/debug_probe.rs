//! The debug-probe side of `hvs flash` (the `probe` feature, on by default): checking the chip
//! against probe-rs's target database and writing a blob into the idle slot through a probe.
//! Everything that only prepares bytes (images, plans, sizes) is in [`super::flash_image`], which
//! builds without probe-rs.

use super::flash_image::{plan_for_slots, with_generation};
use anyhow::{anyhow, bail, Context, Result};
use hvs_shared::runtime::blob::{ModelBlob, MAX_BLOB_LEN};
use hvs_shared::runtime::layout::{Slot, SLOT_LEN};
use hvs_shared::runtime::slots::{SlotRequest, SlotState};

/// Checks that the chip is known to probe-rs and that both slots lie in its flash.
pub fn check_chip(chip: &str) -> Result<()> {
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

fn parse_selector(s: &str) -> Result<probe_rs::probe::DebugProbeSelector> {
    s.parse().map_err(|e| anyhow!("--probe {s}: expected VID:PID or VID:PID:SERIAL ({e})"))
}

fn read_slot(session: &mut probe_rs::Session, slot: Slot) -> Result<Vec<u8>> {
    use probe_rs::MemoryInterface;
    let mut buf = vec![0u8; MAX_BLOB_LEN];
    let mut core = session.core(0).context("cannot access the core")?;
    core.read(slot.addr() as u64, &mut buf)
        .with_context(|| format!("cannot read slot {slot:?}"))?;
    Ok(buf)
}

/// Where and how `hvs flash` writes (the probe-rs side of it).
#[derive(Debug, Clone)]
pub struct FlashTarget {
    /// Target chip, any name probe-rs knows.
    pub chip: String,
    /// Debug probe as VID:PID or VID:PID:SERIAL (hex ids), when several are connected.
    pub probe: Option<String>,
    /// Do not reset the head after writing.
    pub no_reset: bool,
}

/// Writes `blob` into the slot chosen by `req` through a debug probe: reads both slots, plans
/// the write with the head's own rules, writes, verifies by reading back, resets the head.
pub fn flash_with_probe(args: &FlashTarget, blob: &ModelBlob, req: SlotRequest) -> Result<()> {
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
    let probe = info.open().with_context(|| format!("cannot open probe {info}"))?;
    let mut session = probe
        .attach(args.chip.as_str(), probe_rs::Permissions::default())
        .with_context(|| format!("cannot attach to {}", args.chip))?;
    let (a, b) = (read_slot(&mut session, Slot::A)?, read_slot(&mut session, Slot::B)?);
    println!(
        "slot A: {}\nslot B: {}",
        describe(hvs_shared::runtime::head::slot_state(&a)),
        describe(hvs_shared::runtime::head::slot_state(&b))
    );
    let plan = plan_for_slots(&a, &b, req)?;
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
    loader.add_data(plan.slot.addr() as u64, &bytes).context("cannot stage the blob")?;
    let mut opts = probe_rs::flashing::DownloadOptions::default();
    opts.verify = true;
    loader
        .commit(&mut session, opts)
        .context("flash write failed; the running slot was not touched")?;
    let back = read_slot(&mut session, plan.slot)?;
    match hvs_shared::runtime::head::slot_state(&back) {
        SlotState::Valid { generation } if generation == plan.generation => {}
        other => {
            bail!("read-back of slot {:?} is {other:?}; the previous model still boots", plan.slot)
        }
    }
    println!("verified: slot {:?} holds generation {} (CRC ok)", plan.slot, plan.generation);
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

/// One slot's state as `hvs flash` reports it.
fn describe(s: SlotState) -> String {
    match s {
        SlotState::Empty => "empty".into(),
        SlotState::Invalid(e) => format!("invalid ({e})"),
        SlotState::Valid { generation } => format!("runnable model, generation {generation}"),
        SlotState::Unrunnable { generation } => {
            format!("model the head does not run, generation {generation}")
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::device::flash_image::DEFAULT_CHIP;

    #[test]
    fn chip_check() {
        check_chip(DEFAULT_CHIP).unwrap();
        assert!(check_chip("NOT_A_CHIP").is_err());
        // 256 KiB part: the slots are not in its flash.
        assert!(check_chip("STM32F401CCUx").is_err());
    }
}
