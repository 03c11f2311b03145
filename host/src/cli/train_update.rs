//! `hvs train --from OLD.hvsw`: update a trained model with new points
//! ([`crate::train::update`]), write the next generation.

use super::train::AlgoArg;
use crate::data::csv::{read_set, Inputs};
use crate::data::model;
use crate::data::output::check_not_input;
use crate::train::fallback;
use crate::train::update::{update, CameraCheck};
use anyhow::{bail, Context, Result};
use hvs_shared::runtime::blob::{Family, OutputFrame, OutputKind, Parent};
use hvs_shared::runtime::mlp::Activation;
use std::io::Write;
use std::path::PathBuf;

/// What `hvs train` passes on with `--from`.
#[derive(Debug, Clone)]
pub struct UpdateArgs {
    /// The new points.
    pub data: PathBuf,
    /// The model to update.
    pub from: PathBuf,
    /// The updated model.
    pub output: PathBuf,
    /// Seed of the samples of the old volume.
    pub seed: u64,
    /// `--hidden`, if given.
    pub hidden: Option<usize>,
    /// `--outputs`, if given.
    pub outputs: Option<OutputKind>,
    /// `--arch`, if given.
    pub family: Option<Family>,
    /// `--frame`, if given.
    pub frame: Option<OutputFrame>,
    /// `--algo`, if given.
    pub algo: Option<AlgoArg>,
    /// Half baseline, u0, v0 of a fallback fitted on the new points.
    pub fallback: (f64, f64, f64),
}

/// Runs the update.
pub fn run(a: &UpdateArgs) -> Result<()> {
    check_not_input("-o", &a.output, &[("--data", &a.data), ("--from", &a.from)])?;
    let old = model::load(&a.from)?;
    let b = &old.blob;
    let from = a.from.display();
    if let Some(h) = a.hidden {
        if h != b.topology.hidden as usize {
            bail!(
                "--hidden {h} does not match {from} ({} hidden units): an update keeps the old model's topology",
                b.topology.hidden
            );
        }
    }
    if let Some(o) = a.outputs {
        if o != b.topology.outputs {
            bail!("--outputs does not match {from}'s outputs: an update keeps the old model's topology");
        }
    }
    if let Some(f) = a.family {
        if f != b.family {
            bail!(
                "--arch {} does not match {from} ({}): an update keeps the old model's family",
                f.name(),
                b.family.name()
            );
        }
    }
    if let Some(f) = a.frame {
        if f != b.frame {
            bail!("--frame does not match {from}'s output frame: an update keeps it");
        }
    }
    if let Some(algo) = a.algo {
        let sigmoid = b.topology.output_activation == Activation::Sigmoid;
        if (algo == AlgoArg::Bp) != sigmoid {
            bail!(
                "--algo does not match {from} ({} output layer): an update keeps the old model's net",
                if sigmoid { "a sigmoid" } else { "a linear" }
            );
        }
    }
    let table = read_set(&a.data, Inputs::Auto, true)?;
    crate::data::validate::plausible_values(&table)?;
    if let (Some(new), Some(old)) = (table.image_size, b.image_size()) {
        if new != old {
            bail!(
                "{}: its points come from {}x{} px images, {from} was trained on {}x{}: an update keeps the image size",
                a.data.display(),
                new.0,
                new.1,
                old.0,
                old.1
            );
        }
    }
    let up = update(b, &table.data, a.seed).with_context(|| {
        format!(
            "{}: cannot update {from} with these points",
            a.data.display()
        )
    })?;
    let mut blob = up.blob.clone();
    blob.generation = b.generation.saturating_add(1);
    // The chain back to the model this one came from, and the images' size it was trained at.
    blob.set_parent(Some(Parent {
        crc: old.crc,
        generation: b.generation,
    }));
    blob.set_image_size(b.image_size().or(table.image_size));
    blob.matcher = crate::train::matcher::matcher_geometry(&up.learned).or(b.matcher);
    let (half_baseline, u0, v0) = a.fallback;
    // The traditional method's calibration follows a camera that moved; otherwise it stays.
    if up.cameras.iter().any(|c| c.moved) {
        blob.fallback = fallback::fit(&table.data, half_baseline, u0, v0)
            .map(|f| f.calibration)
            .or(b.fallback);
    }
    let n = model::save(&a.output, &blob)?;
    let print = || -> Result<()> {
        let mut o = std::io::stdout().lock();
        writeln!(
            o,
            "updated {} {} from {from} (generation {}, CRC {:08x}) with {} points of {} in {:.3} s ({} LM steps)",
            model::shape(&blob),
            blob.family.name(),
            b.generation,
            old.crc,
            table.data.len(),
            a.data.display(),
            up.elapsed.as_secs_f64(),
            up.iterations
        )?;
        writeln!(
            o,
            "e_ma on the new points: {:.4} % before, {:.4} % after",
            up.old_error_pct, up.new_error_pct
        )?;
        for (side, c) in ["left", "right"].iter().zip(&up.cameras) {
            writeln!(o, "{side} camera: {}", camera_line(c))?;
        }
        writeln!(
            o,
            "learned {} samples of the old volume through the cameras",
            up.learned.len()
        )?;
        writeln!(
            o,
            "wrote {} ({n} bytes, generation {})",
            a.output.display(),
            blob.generation
        )?;
        o.flush()?;
        Ok(())
    };
    print().with_context(|| {
        format!(
            "wrote {} ({n} bytes), but cannot print the summary to stdout",
            a.output.display()
        )
    })
}

fn camera_line(c: &CameraCheck) -> String {
    let what = if c.moved {
        format!("moved (up to {:.2} px)", c.max_move_px)
    } else {
        "held".to_string()
    };
    format!(
        "{what}: old camera {:.3} px rms on the new points, a homography {:.3} px (F = {:.1})",
        c.old_rms_px, c.fit_rms_px, c.f
    )
}
