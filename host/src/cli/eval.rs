//! `hvs eval`: depth error of a model, and of the traditional method with the model's
//! fallback calibration, per ground-truth depth.

use crate::cli::RigArgs;
use crate::data::csv::{read_set, Inputs};
use crate::data::model;
use crate::evaluate::{
    evaluate, optimal_depths_lens, text_table, traditional_depths, Evaluation, Method,
};
use anyhow::{bail, Result};
use hvs_shared::runtime::blob::InputKind;
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
    into 10 depth bins."
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
}

/// Runs `hvs eval`.
pub fn run(a: Args) -> Result<()> {
    let m = model::load(&a.model)?;
    let blob = &m.blob;
    let table = read_set(&a.data, blob.topology.inputs.into(), true)?;
    let (_, y) = crate::infer::infer_table(blob, &table)?;
    let no = blob.n_outputs();
    let mut methods = vec![Method {
        name: "network".into(),
        z: y.chunks_exact(no).map(|o| o[no - 1] as f64).collect(),
    }];
    if let Some(cal) = &blob.fallback {
        methods
            .push(Method { name: "traditional".into(), z: traditional_depths(cal, &table.data) });
    }
    let floor = a.floor.rig()?;
    let lens = a.lens.lens()?;
    if floor.is_none() && a.lens.given() {
        bail!("--distortion is the true lens of the floor: it needs --case N or --rig FILE.json");
    }
    if let Some(rig) = &floor {
        // The floor triangulates at each row's posture when the file has the joint columns,
        // also for a 4-input model (which sees only the pixels).
        let posed;
        let floor_data = if table.data.input_kind() == Some(InputKind::Stereo) {
            posed = read_set(&a.data, Inputs::Auto, true)?;
            &posed.data
        } else {
            &table.data
        };
        methods
            .push(Method { name: "optimal".into(), z: optimal_depths_lens(rig, lens, floor_data) });
    }
    let ev = evaluate(&table.data, &methods);
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
    for s in &ev.methods {
        if s.missing > 0 {
            writeln!(o, "{}: no estimate for {} points (zero disparity or failure), counted as infinite error", s.name, s.missing)?;
        }
    }
    o.flush()?;
    Ok(())
}
