//! A complete model from a training set: the net ([`super::train`]), the traditional
//! method's fallback calibration ([`super::fallback`]) and the run-time matcher's geometry
//! ([`super::matcher`]) in one blob, as `hvs train` writes it.

use super::fallback::{self, FallbackFit};
use super::{TrainConfig, TrainOutcome};
use crate::data::dataset::Dataset;
use anyhow::Result;
use hvs_shared::runtime::blob::ModelBlob;
use hvs_shared::runtime::traditional::Calibration;

/// Everything needed to train a complete model (`hvs train`, both demos).
#[derive(Debug, Clone)]
pub struct Plan {
    /// Engine configuration.
    pub config: TrainConfig,
    /// Half baseline and principal point for the fallback.
    pub half_baseline: f64,
    /// Principal point u0 (px).
    pub u0: f64,
    /// Principal point v0 (px).
    pub v0: f64,
}

impl Default for Plan {
    fn default() -> Self {
        Plan {
            config: TrainConfig::default(),
            half_baseline: Calibration::BUILT_IN.half_baseline as f64,
            u0: Calibration::BUILT_IN.u0 as f64,
            v0: Calibration::BUILT_IN.v0 as f64,
        }
    }
}

/// A trained model ready to write, with how it came about.
#[derive(Debug, Clone)]
pub struct Trained {
    /// The blob (generation 1, fallback set when fitted).
    pub blob: ModelBlob,
    /// The engine's report.
    pub outcome: TrainOutcome,
    /// The fallback fit, if the data allowed one.
    pub fallback: Option<FallbackFit>,
}

/// Trains on `data` and completes the blob: fallback calibration and generation 1.
pub fn train_model(data: &Dataset, plan: &Plan) -> Result<Trained> {
    let outcome = super::train(data, &plan.config)?;
    let fit = fallback::fit(data, plan.half_baseline, plan.u0, plan.v0);
    let mut blob = outcome.blob.clone();
    blob.fallback = fit.map(|f| f.calibration);
    blob.matcher = super::matcher::matcher_geometry(data);
    blob.generation = 1;
    Ok(Trained { blob, outcome, fallback: fit })
}

/// A training set read from a file (`hvs train`, `hvs view`'s retrain): checked
/// ([`crate::data::validate::training_set`]: a set that cannot determine the net, or holds
/// absurd values, is refused as it is), trained ([`train_model`]; its errors after
/// `FILE: training failed`) and stamped with the size of the images its pixels come from.
pub fn train_table(table: &crate::data::csv::Table, plan: &Plan) -> Result<Trained> {
    use anyhow::Context as _;
    let c = &plan.config;
    crate::data::validate::training_set(table, c.hidden, c.outputs.len())?;
    let mut t = train_model(&table.data, plan)
        .with_context(|| format!("{}: training failed", table.name()))?;
    t.blob.set_image_size(table.image_size);
    Ok(t)
}

/// What `hvs train` prints about a trained model (`data` names the training set), without the
/// line about the file written; `hvs view` shows the same after a retrain.
pub fn summary(data: &str, t: &Trained) -> String {
    use std::fmt::Write as _;
    let mut o = String::new();
    let oc = &t.outcome;
    let enrolled = oc.restarts.iter().filter(|r| r.enrolled).count();
    let _ = writeln!(
        o,
        "trained {} {} ({}) on {} points of {} in {:.3} s",
        crate::data::model::shape(&t.blob),
        t.blob.family.name(),
        super::algo_name(t.blob.meta.algorithm),
        t.blob.meta.train_points,
        data,
        oc.elapsed.as_secs_f64()
    );
    let _ = writeln!(
        o,
        "training e_ma {:.4} % (f32 model), best of {}, {enrolled} enrolled",
        oc.train_error_pct,
        crate::fmt::count(oc.restarts.len(), "restart")
    );
    if let Some(n) = oc.synthetic_points {
        let (pixels, cameras) = if oc.synthetic_lenses {
            ("sub-pixel pixels", "two 3x4 cameras with radial lenses")
        } else {
            ("integer pixels", "two 3x4 cameras")
        };
        let _ = writeln!(
            o,
            "{pixels}: the net learned {n} synthetic points of {cameras} fitted to them"
        );
    }
    let _ = match &t.fallback {
        Some(f) => writeln!(
            o,
            "fallback: Phi = {:.4} px (eq. 4.1-3, {} symmetric points at Z = {} cm)",
            f.phi, f.points, f.depth
        ),
        None => writeln!(o, "fallback: none (no board symmetric about X = 0 in the data)"),
    };
    o
}
