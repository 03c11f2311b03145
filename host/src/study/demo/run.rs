//! The demos' runs (`hvs demo`, `hvs demo --images`): each case simulated or rendered and
//! detected, trained, evaluated, its files written into its folder; [`super`] reports on
//! the results.

use super::{
    image_test_seed, image_train_seed, volume_test_seed, volume_train_seed, CaseResult, ImageCase,
    VOLUME_POINTS, VOLUME_TRAIN_POINTS,
};
use crate::data::captures;
use crate::data::dataset::Dataset;
use crate::data::model;
use crate::data::output::{write_atomically, write_bytes};
use crate::evaluate::{evaluate, model_depths, optimal_depths, traditional_depths, Method};
use crate::sim::sets::{dataset, simulate, write_csv, Sample, SetKind, SimOptions};
use crate::study::accuracy::images::{Detected, TEST_CENTRE};
use crate::train::model::{train_model, Plan};
use crate::vision::{
    detect_set, detected_set, found_corners, points_csv, write_capture_set, Detection,
};
use anyhow::{anyhow, bail, Context, Result};
use hvs_shared::runtime::gaze::Joints;
use hvs_shared::runtime::traditional::Calibration;
use hvs_shared::sim::posture::HeadRig;
use hvs_shared::sim::presets;
use hvs_vision::board::Board;
use hvs_vision::render::{self, RenderOptions};
use std::path::Path;

fn write_set(dir: &Path, name: &str, samples: &[Sample]) -> Result<()> {
    let p = dir.join(name);
    write_atomically(&p, |w| {
        write_csv(w, samples).with_context(|| format!("{}: cannot write", p.display()))
    })
}

/// The training plan of every net of the demo: `hvs train`'s default family.
pub fn plan(seed: u64, restarts: usize) -> Plan {
    let mut plan = Plan::default();
    plan.config.family = crate::train::DEFAULT_FAMILY;
    plan.config.seed = seed;
    plan.config.progress = false;
    plan.config.restarts = restarts;
    plan
}

/// Runs one case, writing its files into `dir`.
pub fn case(n: u8, dir: &Path, seed: u64, restarts: usize) -> Result<CaseResult> {
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

/// Renders `depths` at `centre` into `dir` (PNGs, `captures.csv`, `truth.csv`, `board.json`)
/// and detects the corners there, through the files, as a user's photos would go; the mean
/// corner error of the detected corners (px).
fn render_and_detect(
    case: u8,
    dir: &Path,
    depths: &[f64],
    centre: [f64; 2],
    seed: u64,
) -> Result<(Board, Dataset, Detection, f64)> {
    let rig = presets::case(case).ok_or_else(|| anyhow!("no case {case}"))?;
    let rboard = render::opencv_board();
    let set = render::render_capture_set(
        &HeadRig::new(rig),
        &Joints::HOME,
        &rboard,
        centre,
        depths,
        &RenderOptions::default(),
        seed,
    )
    .map_err(|e| anyhow!("{e}"))?;
    write_capture_set(dir, &set, None)?;
    let board =
        Board::new(rboard.cols, rboard.rows, rboard.square_cm).map_err(|e| anyhow!("{e}"))?;
    let cset = captures::read(&dir.join("captures.csv"))?;
    let det = detect_set(&board, &cset, &|| {})?;
    write_bytes(&dir.join("points.csv"), points_csv(&board, &cset, &det).as_bytes())?;
    let corners = found_corners(&board, &cset, &det).map(|c| {
        let xyz = c.xyz.context("captures.csv gives every board's depth")?;
        Ok((c.px, xyz, set.captures[c.capture].render.corners[board.index(c.i, c.j)].px))
    });
    let (data, corner_error_px) = detected_set(corners.collect::<Result<Vec<_>>>()?);
    Ok((board, data, det, corner_error_px))
}

/// Runs the image demo for `case`, writing images, points and the model into `dir`.
pub fn image_case(case: u8, dir: &Path, seed: u64, restarts: usize) -> Result<ImageCase> {
    let (train_seed, test_seed) = (image_train_seed(seed, case), image_test_seed(seed, case));
    let (board, train, det, corner_error_px) = render_and_detect(
        case,
        &dir.join("train"),
        &presets::TRAIN_DEPTHS,
        [0.0, 0.0],
        train_seed,
    )?;
    let n = board.corner_count();
    if train.is_empty() {
        bail!("case {case}: no training board was detected");
    }
    let trained = train_model(&train, &plan(seed, restarts))?;
    model::save(&dir.join("model.hvsw"), &trained.blob)?;
    let (_, test, tdet, _) =
        render_and_detect(case, &dir.join("test"), &presets::TEST_DEPTHS, TEST_CENTRE, test_seed)?;
    if test.is_empty() {
        bail!("case {case}: no test board was detected");
    }
    let rig = presets::case(case).ok_or_else(|| anyhow!("no case {case}"))?;
    let net = model_depths(&trained.blob, &test).map_err(|e| anyhow!("{e:?}"))?;
    let ev = evaluate(
        &test,
        &[
            Method { name: "network (default)".into(), z: net },
            Method { name: "optimal (true rig)".into(), z: optimal_depths(&rig, &test) },
        ],
    );
    let train_corners = [det.usable() * n, det.outcomes.len() * n];
    let test_corners = [tdet.usable() * n, tdet.outcomes.len() * n];
    let detected = Detected { train_corners, test_corners, corner_error_px };
    Ok(ImageCase { case, detected, test: ev })
}
