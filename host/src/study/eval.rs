//! A model's depth error on a set read from a file (`hvs eval`): the network next to the
//! traditional method with the model's fallback calibration and, given the true rig, the
//! floor; a posture-aware model's error per posture band against the floor's too (the posture
//! study's bands, [`super::posture::bands_with_floor`]).

use super::posture;
use crate::data::csv::{read_set, Inputs, Table};
use crate::evaluate::{evaluate, optimal_depths_lens, traditional_depths, Evaluation, Method};
use anyhow::Result;
use hvs_shared::runtime::blob::{InputKind, ModelBlob};
use hvs_shared::sim::camera::{Distortion, Rig};
use serde::Serialize;

/// One posture band of `--json`.
#[derive(Debug, Serialize)]
pub struct BandReport {
    /// The gaze term (`all`, `neck pan`, ... `vergence`).
    pub term: String,
    /// Its band, e.g. `20.0 to 30.0 (either side)`.
    pub band: String,
    /// Rows in the band.
    pub points: usize,
    /// The model's depth e_ma (percent).
    pub network_pct: f64,
    /// The floor's depth e_ma (percent).
    pub optimal_pct: f64,
    /// The model's over the floor's.
    pub ratio: f64,
}

/// What [`eval_model`] finds.
#[derive(Debug)]
pub struct ModelEval {
    /// Per-depth errors of every method.
    pub evaluation: Evaluation,
    /// A posture-aware model with a floor: its error and the floor's per posture band.
    pub bands: Option<Vec<BandReport>>,
}

/// `blob` on `table` (read for its inputs, with targets), beside the traditional method with
/// its fallback calibration and, with `floor` (the true rig and its lenses), the optimal
/// triangulation: at each row's posture when the file has the joint columns (re-read from
/// `table.path` for a 4-input model, which sees only the pixels), and for a posture-aware
/// model the posture bands.
pub fn eval_model(
    blob: &ModelBlob,
    table: &Table,
    floor: Option<(&Rig, Distortion)>,
) -> Result<ModelEval> {
    let (_, y) = crate::infer::infer_table(blob, table)?;
    let mut methods = vec![Method {
        name: "network".into(),
        z: crate::evaluate::depth_column(&y, blob.n_outputs()),
    }];
    if let Some(cal) = &blob.fallback {
        methods
            .push(Method { name: "traditional".into(), z: traditional_depths(cal, &table.data) });
    }
    // A posture-aware model: its samples, the true head and the floor's point of each row,
    // triangulated once for the table and the posture bands.
    let posed_floor = match floor {
        Some((rig, lens)) if blob.topology.inputs == InputKind::StereoJoints => {
            let head = hvs_shared::sim::posture::HeadRig::new(*rig).with_distortion(lens);
            let samples = posture::samples(&table.data);
            let points = posture::floor_points(&head, &samples);
            Some((head, samples, points))
        }
        _ => None,
    };
    if let Some((rig, lens)) = floor {
        let z = match &posed_floor {
            // Every row has its joints and its truth (`read_set` with targets): the same
            // triangulation as `optimal_depths_lens` row by row.
            Some((_, samples, points)) if samples.len() == table.data.len() => {
                points.iter().map(|p| p.map_or(f64::NAN, |p| p[2])).collect()
            }
            _ => {
                // The floor triangulates at each row's posture when the file has the joint
                // columns, also for a 4-input model (which sees only the pixels).
                let posed;
                let floor_data = if table.data.input_kind() == Some(InputKind::Stereo) {
                    posed = read_set(&table.path, Inputs::Auto, true)?;
                    &posed.data
                } else {
                    &table.data
                };
                optimal_depths_lens(rig, lens, floor_data)
            }
        };
        methods.push(Method { name: "optimal".into(), z });
    }
    let evaluation = evaluate(&table.data, &methods);
    // A posture-aware model: its error per posture band against the floor's.
    let bands: Option<Vec<BandReport>> = match &posed_floor {
        Some((head, samples, points)) => {
            let rows = posture::bands_with_floor(blob, head, samples, points, &[]);
            Some(
                rows.iter()
                    .map(|r| BandReport {
                        term: r.term.to_string(),
                        band: r.band.clone(),
                        points: r.net.points,
                        network_pct: r.net.z_pct,
                        optimal_pct: r.floor.z_pct,
                        ratio: r.ratio(),
                    })
                    .collect(),
            )
        }
        _ => None,
    };
    Ok(ModelEval { evaluation, bands })
}

/// The posture bands as `hvs eval` prints them: a heading, a row per band, the worst band.
pub fn bands_text(bands: &[BandReport]) -> String {
    use std::fmt::Write as _;
    let mut o = String::new();
    let _ = writeln!(o, "per posture band (thirds of each gaze term's range; e_ma of the depth):");
    let _ = writeln!(
        o,
        "{:>10} {:<37} {:>6} {:>10} {:>10} {:>8}",
        "term", "band", "points", "network", "optimal", "x floor"
    );
    for b in bands {
        let _ = writeln!(
            o,
            "{:>10} {:<37} {:>6} {:>9.4}% {:>9.4}% {:>8.3}",
            b.term, b.band, b.points, b.network_pct, b.optimal_pct, b.ratio
        );
    }
    if let Some(w) = bands.iter().max_by(|a, b| a.ratio.total_cmp(&b.ratio)) {
        let _ = writeln!(o, "worst band: {} {}, {:.3} x the floor", w.term, w.band, w.ratio);
    }
    o
}
