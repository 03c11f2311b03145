//! `hvs demo`: the thesis' experiment end to end, with no arguments: simulate the four
//! camera cases, train the default net on each, evaluate it next to the traditional method,
//! print the comparison with the thesis' own numbers and write models, data and a report.

use crate::data::output::write_output;
use crate::study::demo::{self, Demo};
use crate::study::engine::Files;
use crate::train::TrainConfig;
use anyhow::{Context, Result};
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
    /// Output directory (created if missing, in a folder that exists).
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

/// Runs `hvs demo`.
pub fn run(a: Args) -> Result<()> {
    let start = Instant::now();
    // Every argument is checked before any work (a bad one found after case I would leave a
    // partial folder).
    crate::cli::check_restarts(a.restarts)?;
    crate::data::output::check_dir_output("-o", &a.output)?;
    std::fs::create_dir_all(&a.output)
        .with_context(|| format!("{}: cannot create the directory", a.output.display()))?;
    if a.images {
        return run_images(&a.output, a.seed, a.restarts);
    }
    // Cases run in parallel; each is deterministic on its own, so the output does not
    // depend on the scheduling.
    let results = (1..=4u8)
        .into_par_iter()
        .map(|n| demo::run::case(n, &a.output, a.seed, a.restarts))
        .collect::<Result<Vec<_>>>()?;
    let demo = Demo {
        cases: results,
        config: demo::run::plan(a.seed, a.restarts).config,
        total_s: start.elapsed().as_secs_f64(),
    };
    let mut files = Files::new(&a.output)?;
    demo::write(&mut files, &demo)?;
    let out = demo::summary(&demo, &a.output)?;
    write_output(None, |w| Ok(w.write_all(out.as_bytes())?))
}

/// `hvs demo --images`: every case, then `IMAGES.md` and the printed table.
fn run_images(out: &Path, seed: u64, restarts: usize) -> Result<()> {
    let mut cases = Vec::new();
    for case in 1..=4u8 {
        let dir = out.join(format!("case{case}_images"));
        cases.push(demo::run::image_case(case, &dir, seed, restarts)?);
    }
    let text = demo::write_images(&mut Files::new(out)?, &cases, out)?;
    write_output(None, |w| Ok(w.write_all(text.as_bytes())?))
}
