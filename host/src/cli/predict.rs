//! `hvs predict`: run a model over a CSV of matched pixels.

use crate::data::csv::read_set;
use crate::data::model::{self, input_names};
use crate::data::output::check_not_input;
use crate::data::output::write_output;
use crate::infer::infer_table;
use anyhow::{Context, Result};
use hvs_shared::runtime::blob::{ModelBlob, OutputKind};
use hvs_shared::runtime::head::outputs_in_range;
use std::io::Write;
use std::path::PathBuf;

/// Arguments of `hvs predict`.
#[derive(Debug, clap::Args)]
#[command(
    about = "Estimate X, Y, Z of matched pixels with a trained model",
    long_about = "Estimate X, Y, Z of matched pixels with a trained model.\n\n\
    Reads u_l,v_l,u_r,v_r (and the five joint columns for a posture-aware model) by name;\n\
    writes u_l,v_l,u_r,v_r,x,y,z, one row per input row: the inputs as the f32 the model\n\
    saw, then its estimates, printed so that they parse back to the same f32 bits\n\
    (the head's computation, hvs-shared inference). A Z-only model leaves x and y empty."
)]
pub struct Args {
    /// The model (weights blob).
    #[arg(long, value_name = "MODEL")]
    model: PathBuf,
    /// CSV with the pixel columns.
    #[arg(long, value_name = "FILE.csv")]
    points: PathBuf,
    /// Output CSV (written atomically); stdout if absent.
    #[arg(short = 'o', long, value_name = "FILE.csv")]
    output: Option<PathBuf>,
}

/// Runs `hvs predict`.
pub fn run(a: Args) -> Result<()> {
    if let Some(out) = &a.output {
        check_not_input("-o", out, &[("--points", &a.points), ("--model", &a.model)])?;
    }
    let m = model::load(&a.model)?;
    let blob = &m.blob;
    let table = read_set(&a.points, blob.topology.inputs.into(), false)?;
    crate::data::validate::plausible_values(&table)?;
    let (x, y) = infer_table(blob, &table)?;
    let outside = x.chunks_exact(blob.n_inputs()).filter(|p| !blob.in_range(p)).count();
    if let Some(note) = crate::infer::extrapolation_note(outside, table.data.len(), "points") {
        eprintln!("{note}");
    }
    let no = blob.n_outputs();
    let mut far = y
        .chunks_exact(no)
        .zip(x.chunks_exact(blob.n_inputs()))
        .enumerate()
        .filter(|(_, (o, xi))| !outputs_in_range(blob, xi, o))
        .map(|(r, (o, _))| (r, o));
    if let Some((first, o)) = far.next() {
        let names = model::output_names(blob.topology.outputs);
        let shown: Vec<String> = names.iter().zip(o).map(|(n, v)| format!("{n} = {v}")).collect();
        eprintln!(
            "warning: {} of {} estimates lie far outside the outputs the model was trained on (first: {}: {} cm): out of range; is the model damaged, or not for these points?",
            far.count() + 1,
            table.data.len(),
            table.at(first),
            shown.join(", ")
        );
    }
    write_output(a.output.as_deref(), |w| {
        write_rows(w, blob, &x, &y).context("cannot write the CSV")
    })
}

fn write_rows(w: &mut dyn Write, blob: &ModelBlob, x: &[f32], y: &[f32]) -> std::io::Result<()> {
    let names = input_names(blob.topology.inputs);
    writeln!(w, "{},x,y,z", names.join(","))?;
    let (ni, no) = (blob.n_inputs(), blob.n_outputs());
    for (xi, yi) in x.chunks_exact(ni).zip(y.chunks_exact(no)) {
        for v in xi {
            write!(w, "{v},")?;
        }
        match blob.topology.outputs {
            OutputKind::Xyz => writeln!(w, "{},{},{}", yi[0], yi[1], yi[2])?,
            OutputKind::Z => writeln!(w, ",,{}", yi[0])?,
        }
    }
    Ok(())
}
