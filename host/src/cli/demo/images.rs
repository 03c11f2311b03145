//! `hvs demo --images`: the image front end end to end, for one camera case: render the
//! training boards (stereo PNGs), detect their corners, train the default model on the detected
//! corners, render and detect test boards at other positions, predict, and compare the depth
//! error with the floor (optimal triangulation with the true rig on the same detected corners).

use crate::data::captures;
use crate::data::dataset::Dataset;
use crate::data::model;
use crate::data::output::write_bytes;
use crate::evaluate::{evaluate, model_depths, optimal_depths, text_table, Evaluation, Method};
use crate::fmt::pct;
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
use std::fmt::Write as _;
use std::path::Path;

/// Test board depths (cm): the thesis' test depths.
pub const TEST_DEPTHS: [f64; 11] = presets::TEST_DEPTHS;
/// Where the test boards' centre is (cm): off the training boards' axis, so that no test
/// corner is a training corner.
pub const TEST_CENTRE: [f64; 2] = [3.0, -2.0];

/// What the image demo found for one case.
#[derive(Debug, Clone)]
pub struct ImageDemo {
    /// The case.
    pub case: u8,
    /// Training corners detected (of those rendered).
    pub train_corners: [usize; 2],
    /// Test corners detected (of those rendered).
    pub test_corners: [usize; 2],
    /// Mean distance (px) of the detected corners from the exact ones, over every image
    /// coordinate of the training set.
    pub corner_error_px: f64,
    /// The test evaluation: the default model, then the floor.
    pub test: Evaluation,
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
pub fn run_case(case: u8, dir: &Path, seed: u64, restarts: usize) -> Result<ImageDemo> {
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
        render_and_detect(case, &dir.join("test"), &TEST_DEPTHS, TEST_CENTRE, test_seed)?;
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
    Ok(ImageDemo {
        case,
        train_corners: [found(&det), det.outcomes.len() * n],
        test_corners: [found(&tdet), tdet.outcomes.len() * n],
        corner_error_px,
        test: ev,
    })
}

/// `hvs demo --images`: every case, a summary table, and each case's per-depth table.
pub fn run(out: &Path, seed: u64, restarts: usize) -> Result<()> {
    let mut report = String::from(
        "# hvs demo --images: render -> detect -> train -> predict\n\n\
         Stereo PNGs of a 9x6 chessboard (6 cm squares, blur 0.8 px, sensor noise 2 grey levels) at \
         the thesis' training depths, corners detected with sub-pixel accuracy, the default model \
         trained on them, then tested on boards at the thesis' test depths, 3 cm right and 2 cm up, \
         detected the same way. Floor: optimal triangulation with the true rig on the same detected \
         corners.\n\n",
    );
    println!(
        "{:<5} {:>14} {:>14} {:>12} {:>12} {:>12} {:>8}",
        "case", "train corners", "test corners", "corner err", "network", "floor", "ratio"
    );
    let mut rows = Vec::new();
    for case in 1..=4u8 {
        let dir = out.join(format!("case{case}_images"));
        let r = run_case(case, &dir, seed, restarts)?;
        let (net, floor) = (r.test.methods[0].mean.e_ma_pct, r.test.methods[1].mean.e_ma_pct);
        let label = presets::LABELS[usize::from(case) - 1];
        println!(
            "{:<5} {:>14} {:>14} {:>9.3} px {:>12} {:>12} {:>7.2}x",
            label.split(':').next().unwrap_or(label),
            format!("{}/{}", r.train_corners[0], r.train_corners[1]),
            format!("{}/{}", r.test_corners[0], r.test_corners[1]),
            r.corner_error_px,
            pct(net),
            pct(floor),
            net / floor
        );
        let _ = writeln!(
            report,
            "## Case {}\n\nTraining corners {}/{}, mean corner error {:.3} px; test corners {}/{}.\n\n```text\n{}```\n",
            presets::LABELS[usize::from(case) - 1],
            r.train_corners[0],
            r.train_corners[1],
            r.corner_error_px,
            r.test_corners[0],
            r.test_corners[1],
            text_table(&r.test)
        );
        rows.push(r);
    }
    write_bytes(&out.join("IMAGES.md"), report.as_bytes())?;
    println!(
        "(mean depth e_ma on the test boards; images, points.csv and model.hvsw in {}/caseN_images, per-depth tables in IMAGES.md)",
        out.display()
    );
    Ok(())
}
