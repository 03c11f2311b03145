//! `hvs eval`: depth error of a model, and of the traditional method with the model's
//! fallback calibration, per ground-truth depth; a posture-aware model's per posture band too
//! (`study::posture::bands`).

use crate::cli::RigArgs;
use crate::data::csv::read_set;
use crate::data::model;
use crate::evaluate::{text_table, Evaluation};
use crate::study::{self, eval::BandReport, eval::ModelEval};
use anyhow::{bail, Result};
use hvs_shared::runtime::traditional::Calibration;
use serde::Serialize;
use std::io::Write;
use std::path::PathBuf;

/// Arguments of `hvs eval`.
#[derive(Debug, clap::Args)]
#[command(
    about = "Depth error (e_ma) per true depth: the model next to the traditional method",
    long_about = "Depth error (e_ma, eq. 4.1-5, in cm and % of the true depth) per ground-truth \
    depth, with the mean over all points and the worst depth, for the model and for the \
    traditional method (eq. 3.1-17 with the fallback calibration stored in the model) side by \
    side. With --case/--rig, also the optimal triangulation with that true rig on the same \
    pixels: the floor no calibration-free method can beat, on rounded, noisy or exact pixels \
    and on any board (`hvs simulate --pixels`, `--noise-px`, `--board`). A set simulated \
    with `--distortion K1[,K2]` needs the same --distortion here, so that the floor \
    triangulates through the true lenses. Sets with more than 50 distinct depths are grouped \
    into 10 depth bins. A posture-aware model (the five joint columns) with --case/--rig also \
    gets its depth error per posture band against the floor's: all rows, then thirds of each \
    gaze term's working range (neck pan, neck tilt, eye tilt, version by magnitude; vergence), \
    as the posture study reports them."
)]
pub struct Args {
    /// The model (weights blob).
    #[arg(long, value_name = "MODEL")]
    model: PathBuf,
    /// CSV with pixels and ground truth (u_l,v_l,u_r,v_r,x,y,z).
    #[arg(long, value_name = "FILE.csv")]
    data: PathBuf,
    /// Machine-readable JSON instead of a table.
    #[arg(long)]
    json: bool,
    #[command(flatten)]
    floor: RigArgs,
    // The true lenses of the floor's rig (as the set was simulated); needs --case or --rig.
    #[command(flatten)]
    lens: crate::cli::LensArgs,
}

/// What `--json` prints.
#[derive(Debug, Serialize)]
pub struct Report {
    /// The model file.
    pub model: String,
    /// The data file.
    pub data: String,
    /// The model's topology, e.g. `4-5-3`.
    pub topology: String,
    /// The fallback calibration used for the traditional method, if the model has one.
    pub fallback: Option<Calibration>,
    /// The rig of the optimal triangulation, if one was given.
    pub floor_rig: Option<String>,
    /// The floor's lens distortion `[k1, k2]`, if one was given.
    pub floor_distortion: Option<[f64; 2]>,
    /// Per-depth errors (non-finite values are written as null).
    pub evaluation: Evaluation,
    /// A posture-aware model with --case/--rig: its depth e_ma and the floor's per posture
    /// band (the posture study's bands).
    pub posture_bands: Option<Vec<BandReport>>,
}

/// Runs `hvs eval`.
pub fn run(a: Args) -> Result<()> {
    let m = model::load(&a.model)?;
    let blob = &m.blob;
    let table = read_set(&a.data, blob.topology.inputs.into(), true)?;
    crate::data::validate::plausible_values(&table)?;
    let floor = a.floor.rig()?;
    let lens = a.lens.lens()?;
    if floor.is_none() && a.lens.given() {
        bail!("--distortion is the true lens of the floor: it needs --case N or --rig FILE.json");
    }
    let ModelEval { evaluation: ev, bands } =
        study::eval::eval_model(blob, &table, floor.as_ref().map(|r| (r, lens)))?;
    let mut o = std::io::stdout().lock();
    if a.json {
        let r = Report {
            model: a.model.display().to_string(),
            data: a.data.display().to_string(),
            topology: model::shape(blob),
            fallback: blob.fallback,
            floor_rig: floor.map(|_| a.floor.label()),
            floor_distortion: a.lens.given().then_some([lens.k1, lens.k2]),
            evaluation: ev,
            posture_bands: bands,
        };
        writeln!(o, "{}", serde_json::to_string_pretty(&r)?)?;
        o.flush()?;
        return Ok(());
    }
    writeln!(
        o,
        "model {} ({}), data {} ({} points)",
        a.model.display(),
        model::shape(blob),
        a.data.display(),
        ev.points
    )?;
    match &blob.fallback {
        Some(c) => writeln!(
            o,
            "traditional: eq. 3.1-17 with the model's fallback Phi = {} px, 2d = {} cm",
            c.phi,
            2.0 * c.half_baseline
        ),
        None => writeln!(o, "traditional: none (the model holds no fallback calibration)"),
    }?;
    if floor.is_some() {
        writeln!(
            o,
            "optimal: least-reprojection-error triangulation with the true rig ({}){}",
            a.floor.label(),
            if lens.is_none() {
                String::new()
            } else {
                format!(" through lenses k1 = {}, k2 = {}", lens.k1, lens.k2)
            }
        )?;
    }
    writeln!(o)?;
    write!(o, "{}", text_table(&ev))?;
    if let Some(bands) = &bands {
        writeln!(o)?;
        write!(o, "{}", study::eval::bands_text(bands))?;
    }
    for s in &ev.methods {
        if s.missing > 0 {
            writeln!(o, "{}: no estimate for {} points (zero disparity or failure), counted as infinite error", s.name, s.missing)?;
        }
    }
    o.flush()?;
    Ok(())
}
