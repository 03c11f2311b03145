//! `hvs demo`: the thesis' experiment end to end, with no arguments: simulate the four
//! camera cases, train the default net on each, evaluate it next to the traditional method,
//! print the comparison with the thesis' own numbers and write models, data and a report.

pub mod images;

use crate::data::dataset::Dataset;
use crate::data::model;
use crate::data::output::{write_atomically, write_output};
use crate::evaluate::{evaluate, model_depths, optimal_depths, traditional_depths, Method};
use crate::sim::sets::{simulate, write_csv, Sample, SetKind, SimOptions};
use crate::study::demo::{
    self, volume_test_seed, volume_train_seed, CaseResult, Demo, VOLUME_POINTS, VOLUME_TRAIN_POINTS,
};
use crate::study::engine::Files;
use crate::train::model::{train_model, Plan};
use crate::train::TrainConfig;
use anyhow::{anyhow, Context, Result};
use hvs_shared::runtime::blob::InputKind;
use hvs_shared::runtime::traditional::Calibration;
use hvs_shared::sim::presets;
use rayon::prelude::*;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Arguments of `hvs demo`.
#[derive(Debug, clap::Args)]
#[command(
    about = "The thesis' experiment end to end: 4 camera cases, traditional vs. network",
    long_about = "The thesis' experiment end to end, no arguments needed. For each of the four \
    camera cases: simulate the training boards (72 points), the test points (22) and 500 random \
    points of the training volume; train the default 4-5-3 net; compare its depth error with \
    the traditional method (eq. 3.1-17 with the Phi calibrated on case I as in the thesis, and \
    with Phi refitted on the case's own boards) and with optimal triangulation using the true \
    rig; train a second net on 1000 random points of the training volume and compare it with \
    that floor on 500 others. Prints the table next to the thesis' numbers and writes the data \
    (caseN_{train,test,volume_train,volume_test}.csv), the models (caseN.hvsw, \
    caseN_volume.hvsw) and REPORT.md into the output directory."
)]
pub struct Args {
    /// Output directory (created if missing).
    #[arg(short = 'o', long, value_name = "DIR", default_value = "hvs-demo")]
    output: PathBuf,
    /// Seed of the training restarts and of the random volume points.
    #[arg(long, value_name = "S", default_value_t = 0, allow_negative_numbers = true, value_parser = crate::cli::whole_u64)]
    seed: u64,
    /// Restarts per net (the default net's 10; fewer for a quick run).
    #[arg(long, value_name = "R", default_value_t = TrainConfig::default().restarts, allow_negative_numbers = true, value_parser = crate::cli::whole_usize)]
    restarts: usize,
    /// Instead, the image front end end to end: render stereo photos of a 9x6 board, detect
    /// the corners, train the default model on them, predict on other rendered boards and
    /// compare with the floor on the same detected corners (writes caseN_images/ and IMAGES.md).
    #[arg(long)]
    images: bool,
}

fn dataset(samples: &[Sample]) -> Dataset {
    let mut d = Dataset::new(InputKind::Stereo);
    for s in samples {
        d.push(&s.px, Some(s.xyz));
    }
    d
}

fn write_set(dir: &Path, name: &str, samples: &[Sample]) -> Result<()> {
    let p = dir.join(name);
    write_atomically(&p, |w| {
        write_csv(w, samples).with_context(|| format!("{}: cannot write", p.display()))
    })
}

/// The training plan of every net of the demo: `hvs train`'s default family.
fn plan(seed: u64, restarts: usize) -> Plan {
    let mut plan = Plan::default();
    plan.config.family = crate::train::DEFAULT_FAMILY;
    plan.config.seed = seed;
    plan.config.progress = false;
    plan.config.restarts = restarts;
    plan
}

/// Runs one case, writing its files into `dir`.
pub fn run_case(n: u8, dir: &Path, seed: u64, restarts: usize) -> Result<CaseResult> {
    let rig = presets::case(n).ok_or_else(|| anyhow!("no case {n}"))?;
    let sim = |kind, points, seed| {
        simulate(&rig, kind, &SimOptions { points, noise_px: 0.0, seed, ..SimOptions::default() })
    };
    let train = sim(SetKind::Train, 0, 0)?;
    let test = sim(SetKind::Test, 0, 0)?;
    let vtrain = sim(SetKind::Volume, VOLUME_TRAIN_POINTS, volume_train_seed(seed, n))?;
    let vtest = sim(SetKind::Volume, VOLUME_POINTS, volume_test_seed(seed, n))?;
    write_set(dir, &format!("case{n}_train.csv"), &train)?;
    write_set(dir, &format!("case{n}_test.csv"), &test)?;
    write_set(dir, &format!("case{n}_volume_train.csv"), &vtrain)?;
    write_set(dir, &format!("case{n}_volume_test.csv"), &vtest)?;
    let (train, test) = (dataset(&train), dataset(&test));
    let (vtrain, vtest) = (dataset(&vtrain), dataset(&vtest));

    let plan = plan(seed, restarts);
    let t = train_model(&train, &plan).with_context(|| format!("case {n}: training failed"))?;
    model::save(&dir.join(format!("case{n}.hvsw")), &t.blob)?;
    let tv = train_model(&vtrain, &plan)
        .with_context(|| format!("case {n}: training on the volume set failed"))?;
    model::save(&dir.join(format!("case{n}_volume.hvsw")), &tv.blob)?;

    let net = |b: &hvs_shared::runtime::blob::ModelBlob, d: &Dataset| {
        model_depths(b, d).map_err(|e| anyhow!("case {n}: the model failed: {e:?}"))
    };
    let mut test_methods = vec![
        Method { name: "network".into(), z: net(&t.blob, &test)? },
        Method {
            name: "trad. (thesis Phi)".into(),
            z: traditional_depths(&Calibration::BUILT_IN, &test),
        },
        Method { name: "optimal (true rig)".into(), z: optimal_depths(&rig, &test) },
    ];
    if let Some(c) = &t.blob.fallback {
        test_methods
            .push(Method { name: "trad. (refit Phi)".into(), z: traditional_depths(c, &test) });
    }
    let vol_methods = [
        Method { name: "net (volume-trained)".into(), z: net(&tv.blob, &vtest)? },
        Method { name: "net (board-trained)".into(), z: net(&t.blob, &vtest)? },
        Method { name: "optimal (true rig)".into(), z: optimal_depths(&rig, &vtest) },
    ];
    Ok(CaseResult {
        case: n,
        test: evaluate(&test, &test_methods),
        volume: evaluate(&vtest, &vol_methods),
        train_pct: t.outcome.train_error_pct,
        volume_train_pct: tv.outcome.train_error_pct,
        refit_phi: t.fallback.map(|f| f.phi),
        train_s: [t.outcome.elapsed.as_secs_f64(), tv.outcome.elapsed.as_secs_f64()],
    })
}

/// Runs `hvs demo`.
pub fn run(a: Args) -> Result<()> {
    let start = Instant::now();
    // Every argument is checked before any work (a bad one found after case I would leave a
    // partial folder).
    if a.restarts == 0 || a.restarts > usize::from(u16::MAX) {
        return Err(crate::cli::usage(format!(
            "--restarts must be from 1 to {}, got {}",
            u16::MAX,
            a.restarts
        )));
    }
    crate::data::output::check_dir_output("-o", &a.output)?;
    std::fs::create_dir_all(&a.output)
        .with_context(|| format!("{}: cannot create the directory", a.output.display()))?;
    if a.images {
        return images::run(&a.output, a.seed, a.restarts);
    }
    // Cases run in parallel; each is deterministic on its own, so the output does not
    // depend on the scheduling.
    let results = (1..=4u8)
        .into_par_iter()
        .map(|n| run_case(n, &a.output, a.seed, a.restarts))
        .collect::<Result<Vec<_>>>()?;
    let demo = Demo {
        cases: results,
        config: plan(a.seed, a.restarts).config,
        total_s: start.elapsed().as_secs_f64(),
    };
    let mut files = Files::new(&a.output)?;
    demo::write(&mut files, &demo)?;
    let out = demo::summary(&demo, &a.output)?;
    write_output(None, |w| Ok(w.write_all(out.as_bytes())?))
}
