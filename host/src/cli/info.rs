//! `hvs info`: what is in a weights blob, and whether it is intact.

use crate::data::model::{self, input_names, output_names};
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
    let b = &f.blob;
    let mut o = std::io::stdout().lock();
    writeln!(o, "file:        {}", a.model.display())?;
    let trailing = f.file_len - f.blob_len;
    writeln!(
        o,
        "size:        {} bytes (HVSW v{}, payload {} bytes{})",
        f.file_len,
        f.version,
        f.blob_len - hvs_shared::runtime::blob::HEADER_LEN - hvs_shared::runtime::blob::CRC_LEN,
        if trailing > 0 {
            format!(", {trailing} trailing bytes ignored")
        } else {
            String::new()
        }
    )?;
    writeln!(o, "crc:         ok ({:#010x}); all checks passed", f.crc)?;
    writeln!(o, "generation:  {}", b.generation)?;
    writeln!(
        o,
        "topology:    {} ({} -> {} sigmoid hidden -> {}, {:?} output), {} parameters",
        model::shape(b),
        input_names(b.topology.inputs).join(","),
        b.topology.hidden,
        output_names(b.topology.outputs).join(","),
        b.topology.output_activation,
        b.params.len()
    )?;
    writeln!(
        o,
        "family:      {} ({}{}, sigmoid exp {:?})",
        b.family.name(),
        match b.family.output_map {
            hvs_shared::runtime::mlp::OutputMap::Direct => "outputs are X, Y, Z in cm",
            hvs_shared::runtime::mlp::OutputMap::InverseDepth =>
                "outputs are X/Z, Y/Z, 1/Z: X = o0/o2, Y = o1/o2, Z = 1/o2",
        },
        match b.family.skip {
            hvs_shared::runtime::blob::Skip::None => "",
            hvs_shared::runtime::blob::Skip::Linear =>
                "; a linear skip term adds an affine map of the inputs",
        },
        b.family.exp
    )?;
    writeln!(
        o,
        "frame:       {} ({})",
        b.frame.name(),
        match b.frame {
            hvs_shared::runtime::blob::OutputFrame::Head => "the net gives head-frame points",
            hvs_shared::runtime::blob::OutputFrame::EyePlatform =>
                "the net gives points in the eye platform's frame (the head frame turned by the \
                 neck pan, neck tilt and eye tilt inputs); the model turns them into the head frame",
        }
    )?;
    match b.image_size() {
        Some((w, h)) => writeln!(o, "images:      {w}x{h} px (the training images' size)"),
        None => writeln!(
            o,
            "images:      none recorded (trained from points, not images)"
        ),
    }?;
    match b.parent() {
        Some((crc, generation)) => writeln!(
            o,
            "parent:      updated from the model with CRC {crc:#010x}, generation {generation}"
        ),
        None => writeln!(o, "parent:      none (trained from scratch)"),
    }?;
    if let Some(g) = &b.matcher {
        writeln!(
            o,
            "matcher:     fundamental matrix {:?}, training box {:?} .. {:?} cm, disparities {} .. {} px, right/left image scale {:?}",
            g.fundamental, g.out_min, g.out_max, g.disparity[0], g.disparity[1], g.right_scale
        )?;
    }
    let m = &b.meta;
    writeln!(
        o,
        "training:    {}, seed {}, {} restarts, {} points (set hash {:#018x}), train e_ma {} %",
        crate::train::algo_name(m.algorithm),
        m.seed,
        m.restarts,
        m.train_points,
        m.train_hash,
        m.train_error_pct
    )?;
    writeln!(o, "input box:")?;
    for (k, name) in input_names(b.topology.inputs).iter().enumerate() {
        writeln!(
            o,
            "  {name:>13}  {} .. {}",
            b.in_min.get(k).copied().unwrap_or(f32::NAN),
            b.in_max.get(k).copied().unwrap_or(f32::NAN)
        )?;
    }
    match &b.fallback {
        Some(c) => writeln!(
            o,
            "fallback:    traditional method, Phi = {} px, d = {} cm, principal point ({}, {})",
            c.phi, c.half_baseline, c.u0, c.v0
        ),
        None => writeln!(
            o,
            "fallback:    none (a head would use its built-in calibration)"
        ),
    }?;
    o.flush()?;
    Ok(())
}
