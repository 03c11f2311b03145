//! `hvs demo --images`: the image front end end to end, for one camera case: render the
//! training boards (stereo PNGs), detect their corners, train the default model on the detected
//! corners, render and detect test boards at other positions, predict, and compare the depth
//! error with the floor (optimal triangulation with the true rig on the same detected corners).

use crate::data::captures;
use crate::data::dataset::Dataset;
use crate::data::model;
use crate::data::output::write_bytes;
use crate::data::output::write_output;
use crate::evaluate::{evaluate, model_depths, optimal_depths, Method};
use crate::study::accuracy::images::{Detected, TEST_CENTRE};
use crate::study::demo::{self, ImageCase};
use crate::study::engine::Files;
use crate::train::model::{train_model, Plan};
use crate::vision::{
    detect_set, detected_set, found_corners, points_csv, write_capture_set, Detection, PairOutcome,
};
use anyhow::{anyhow, bail, Context, Result};
use hvs_shared::runtime::gaze::Joints;
use hvs_shared::sim::posture::HeadRig;
use hvs_shared::sim::presets;
use hvs_vision::board::Board;
use hvs_vision::render::{self, RenderOptions};
use std::path::Path;

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
pub fn run_case(case: u8, dir: &Path, seed: u64, restarts: usize) -> Result<ImageCase> {
    let train_seed = seed.wrapping_mul(10_000).wrapping_add(3000 + u64::from(case));
    let test_seed = seed.wrapping_mul(10_000).wrapping_add(4000 + u64::from(case));
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
    let mut plan = Plan::default();
    plan.config.family = crate::train::DEFAULT_FAMILY;
    plan.config.restarts = restarts;
    plan.config.seed = seed;
    let trained = train_model(&train, &plan)?;
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
    let found = |d: &Detection| {
        d.outcomes.iter().filter(|o| matches!(o, PairOutcome::Found(_))).count() * n
    };
    let train_corners = [found(&det), det.outcomes.len() * n];
    let test_corners = [found(&tdet), tdet.outcomes.len() * n];
    let detected = Detected { train_corners, test_corners, corner_error_px };
    Ok(ImageCase { case, detected, test: ev })
}

/// `hvs demo --images`: every case, then `IMAGES.md` and the printed table.
pub fn run(out: &Path, seed: u64, restarts: usize) -> Result<()> {
    let mut cases = Vec::new();
    for case in 1..=4u8 {
        cases.push(run_case(case, &out.join(format!("case{case}_images")), seed, restarts)?);
    }
    let text = demo::write_images(&mut Files::new(out)?, &cases, out)?;
    write_output(None, |w| Ok(w.write_all(text.as_bytes())?))
}
