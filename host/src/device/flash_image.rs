//! A weights blob into a head's weight slot, the part that needs no probe.
//!
//! Flash images (`hvs image`: raw binary or Intel HEX) for other flashers, the checks that the
//! head would run a model, the exact blob bytes at a generation, and the slot plan of `hvs
//! flash` (the rules of [`hvs_shared::runtime::slots`] over the slot states the head's own boot
//! sees: [`hvs_shared::runtime::head::slot_state`]). Writing through a debug probe is
//! `device::debug_probe` (feature `probe`). Only the target slot's sector is erased: a write
//! cut off half-way leaves the running model in place. Both refuse a model the head would not
//! run ([`hvs_shared::runtime::head::Network::new`]).

use anyhow::{anyhow, bail, Context, Result};
use hvs_shared::runtime::blob::{self, InputKind, ModelBlob, OutputKind, MAX_BLOB_LEN};
use hvs_shared::runtime::head::Network;
use hvs_shared::runtime::layout::Slot;
use hvs_shared::runtime::slots::{plan_write, SlotRequest, WritePlan};
use std::path::Path;

/// The head controller's chip.
pub const DEFAULT_CHIP: &str = "STM32F405RGTx";

/// Output format of a flash image.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ImageFormat {
    /// Raw bytes, to be loaded at the slot address (`--base-address`).
    Bin,
    /// Intel HEX carrying its own addresses.
    Hex,
}

/// The image of a blob (its file bytes, re-stamped with `generation` if given) for `slot`.
pub fn image(
    blob: &ModelBlob,
    bytes: Vec<u8>,
    generation: Option<u32>,
    slot: Slot,
    format: ImageFormat,
) -> Result<(Vec<u8>, usize)> {
    let bytes = match generation {
        Some(g) => with_generation(blob, g)?,
        None => bytes,
    };
    let out = match format {
        ImageFormat::Bin => bytes.clone(),
        ImageFormat::Hex => intel_hex(slot.addr(), &bytes)?.into_bytes(),
    };
    Ok((out, bytes.len()))
}

/// Reads and validates a blob file and checks that the head would run it
/// ([`check_runnable`]); errors name the file.
pub fn read_model(path: &Path) -> Result<(ModelBlob, Vec<u8>)> {
    let bytes = std::fs::read(path).with_context(|| format!("{}: cannot read", path.display()))?;
    let blob = blob::decode(&bytes).map_err(|e| anyhow!("{}: {e}", path.display()))?;
    let len = blob::framed_len(&bytes).map_err(|e| anyhow!("{}: {e}", path.display()))?;
    check_runnable(path, &blob)?;
    Ok((blob, bytes[..len].to_vec()))
}

/// Errors unless the head would run `blob` (the firmware's rule, [`Network::new`]): a slot
/// holding anything else is reported by `Info` but never booted, so flashing it is useless.
pub fn check_runnable(path: &Path, blob: &ModelBlob) -> Result<()> {
    if Network::new(Slot::A, blob.clone()).is_some() {
        return Ok(());
    }
    let inputs = match blob.topology.inputs {
        InputKind::Stereo => "the 4 pixels",
        InputKind::StereoJoints => "the 4 pixels and 5 joint angles",
    };
    let outputs = match blob.topology.outputs {
        OutputKind::Xyz => "X, Y, Z",
        OutputKind::Z => "Z only",
    };
    bail!(
        "{}: the head would not run this {}-{}-{} model (inputs {inputs}, outputs {outputs}; it runs X, Y, Z outputs from the 4 pixels, or from them and the 5 joint angles), so flashing it would change nothing",
        path.display(),
        blob.n_inputs(),
        blob.topology.hidden,
        blob.n_outputs()
    )
}

/// The blob re-encoded with a new generation number.
pub fn with_generation(blob: &ModelBlob, generation: u32) -> Result<Vec<u8>> {
    let mut b = blob.clone();
    b.generation = generation;
    let mut buf = vec![0u8; MAX_BLOB_LEN];
    let n = b.encode(&mut buf).map_err(|e| anyhow!("cannot encode blob: {e}"))?;
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

/// The plan for slots holding `a` and `b` (raw bytes read from the head): the head's own
/// boot classification ([`hvs_shared::runtime::head::slot_state`]) fed to
/// [`plan_write`], so the slot it calls running is the one the head runs.
pub fn plan_for_slots(a: &[u8], b: &[u8], req: SlotRequest) -> Result<WritePlan> {
    plan_write(
        hvs_shared::runtime::head::slot_state(a),
        hvs_shared::runtime::head::slot_state(b),
        req,
    )
    .map_err(|e| anyhow!("{e}"))
}

/// The exact size of `blob` written with each generation, as `(first, last, bytes)` ranges
/// covering `1..=u32::MAX` (the generation is a varint in the payload, so the size grows with
/// it). Each range is found by bisection on the real encoder's output.
pub fn sizes_by_generation(blob: &ModelBlob) -> Result<Vec<(u32, u32, usize)>> {
    let size = |g: u32| with_generation(blob, g).map(|b| b.len());
    let mut out = Vec::new();
    let mut lo = 1u32;
    loop {
        let s = size(lo)?;
        // Largest generation with size s (sizes never shrink as the generation grows).
        let (mut ok, mut bad) = (lo, None::<u32>);
        if size(u32::MAX)? == s {
            ok = u32::MAX;
        } else {
            let mut hi = u32::MAX;
            while hi - ok > 1 {
                let mid = ok + (hi - ok) / 2;
                if size(mid)? == s {
                    ok = mid;
                } else {
                    hi = mid;
                }
            }
            bad = Some(hi);
        }
        out.push((lo, ok, s));
        match bad {
            Some(next) => lo = next,
            None => return Ok(out),
        }
    }
}

/// The size of `blob` written with generation `g`, from [`sizes_by_generation`]'s ranges.
fn size_for(sizes: &[(u32, u32, usize)], g: u32) -> usize {
    sizes.iter().find(|(lo, hi, _)| (*lo..=*hi).contains(&g)).map_or(0, |r| r.2)
}

/// The text `--dry-run` prints. No probe is touched, so what the slots hold is not known:
/// for `--slot auto` it gives the plan for each possible running slot (A, B, none), for
/// `--slot a|b` the one plan, each with the written slot, its address, the generation and the
/// exact size of the re-encoded blob.
pub fn dry_run_plan(
    model: &Path,
    blob: &ModelBlob,
    file_size: usize,
    chip: &str,
    slot: SlotRequest,
) -> Result<String> {
    let sizes = sizes_by_generation(blob)?;
    let t = &blob.topology;
    let mut o = format!(
        "dry run: nothing written, no probe touched\nmodel: {} ({file_size} bytes, CRC ok, {}-{}-{}, the head runs it, generation in file {})\nchip: {chip}\n",
        model.display(),
        t.inputs.len(),
        t.hidden,
        t.outputs.len(),
        blob.generation
    );
    let at = |s: Slot| format!("{s:?} at {:#010x} (sector {})", s.addr(), s.sector());
    // With a model running (G >= 1) the written generation G+1 is at least 2: the size for
    // the range holding 2, the one every realistic G+1 falls in (the others are listed below).
    let (_, hi2, n2) = sizes
        .iter()
        .copied()
        .find(|(lo, hi, _)| (*lo..=*hi).contains(&2))
        .unwrap_or((1, u32::MAX, 0));
    let g_plus_1 = format!("generation G+1, {n2} bytes if G+1 <= {hi2}");
    match slot {
        SlotRequest::Auto => {
            o += "slot: auto, the slot the head is not running (known only once the probe has read both slots):\n";
            o += &format!("  if A runs (generation G): write slot {}, {g_plus_1}\n", at(Slot::B));
            o += &format!("  if B runs (generation G): write slot {}, {g_plus_1}\n", at(Slot::A));
            o += &format!(
                "  if neither runs a model: write slot {}, generation 1, {} bytes\n",
                at(Slot::A),
                size_for(&sizes, 1)
            );
        }
        SlotRequest::Exactly(s) => {
            o += &format!("slot: {}\n", at(s));
            o += &format!(
                "  write generation G+1 if the head runs a model (generation G), {n2} bytes if G+1 <= {hi2}; generation 1, {} bytes if it runs none\n",
                size_for(&sizes, 1)
            );
            o += &format!(
                "  refused if slot {s:?} holds the only model the head runs (use --slot auto)\n"
            );
        }
    }
    o += "generation rule: 1 + the highest generation among the slots the head can run (G), read through the probe; 1 if it runs none. The head then boots the written slot.\n";
    let ranges: Vec<String> =
        sizes.iter().map(|(lo, hi, n)| format!("{n} bytes for {lo}..={hi}")).collect();
    o += &format!("size by generation written: {}\n", ranges.join(", "));
    o += "erase: the written slot's 128 KiB sector only; the running slot stays intact\n";
    o += "verify: read the slot back and check the CRC and the generation, then reset the head\n";
    Ok(o)
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

    use hvs_shared::runtime::head;

    const V: hvs_shared::runtime::protocol::FirmwareVersion =
        hvs_shared::runtime::protocol::FirmwareVersion { major: 0, minor: 1, patch: 0 };

    fn model(generation: u32, outputs: OutputKind) -> ModelBlob {
        hvs_shared::test_support::SampleSpec::THESIS.outputs(outputs).generation(generation).build()
    }

    #[test]
    fn the_plan_never_overwrites_the_slot_the_head_runs() {
        // A: a valid Z-only blob at generation 9 (the head does not run it), B: a runnable
        // 4-5-3 at generation 7. The head boots B; the plan must write A, above 7.
        let a = with_generation(&model(0, OutputKind::Z), 9).unwrap();
        let b = with_generation(&model(0, OutputKind::Xyz), 7).unwrap();
        let booted = head::boot(&a, &b).info(V).slot;
        assert_eq!(booted, Some(Slot::B));
        let p = plan_for_slots(&a, &b, SlotRequest::Auto).unwrap();
        assert_eq!((p.slot, p.generation, p.running), (Slot::A, 8, Some(Slot::B)));
        // Explicitly writing B would destroy the only model the head runs.
        let e = plan_for_slots(&a, &b, SlotRequest::Exactly(Slot::B)).unwrap_err();
        assert!(e.to_string().contains("only model the head can run"), "{e}");
        // After the write, the new model is what boots.
        let new = with_generation(&model(0, OutputKind::Xyz), p.generation).unwrap();
        assert_eq!(head::boot(&new, &b).info(V).slot, Some(Slot::A));
    }

    #[test]
    fn a_model_the_head_would_not_run_is_refused() {
        let e = check_runnable(Path::new("z.hvsw"), &model(1, OutputKind::Z)).unwrap_err();
        let e = e.to_string();
        assert!(e.starts_with("z.hvsw: the head would not run"), "{e}");
        assert!(e.contains("4-5-1") && e.contains("Z only"), "{e}");
        assert_eq!(e.lines().count(), 1);
        check_runnable(Path::new("m.hvsw"), &model(1, OutputKind::Xyz)).unwrap();
    }

    #[test]
    fn sizes_by_generation_are_the_encoded_sizes() {
        let m = model(1, OutputKind::Xyz);
        let sizes = sizes_by_generation(&m).unwrap();
        assert_eq!(sizes.first().map(|r| r.0), Some(1));
        assert_eq!(sizes.last().map(|r| r.1), Some(u32::MAX));
        for w in sizes.windows(2) {
            assert_eq!(w[0].1 + 1, w[1].0);
            assert!(w[0].2 < w[1].2);
        }
        for &(lo, hi, n) in &sizes {
            for g in [lo, hi, lo + (hi - lo) / 2] {
                assert_eq!(with_generation(&m, g).unwrap().len(), n, "generation {g}");
            }
        }
        // postcard's varint: 7 bits per byte.
        assert_eq!((sizes[0].1, sizes[1].1), (127, 16383));
    }
}
