//! `hvs board detect`: stereo photos of a board at known positions into a training set
//! (sub-pixel corners found in both images), through [`crate::vision`] and `hvs-vision`.

use crate::data::captures;
use crate::data::csv::write_bytes;
use crate::vision::{detect_set, detect_set_with_images, png_bytes, points_csv, PairOutcome};
use anyhow::{bail, Context, Result};
use hvs_vision::board::Board;
use std::io::IsTerminal;
use std::path::{Path, PathBuf};

/// Arguments of `hvs board`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// What to do.
    #[command(subcommand)]
    pub command: BoardCommand,
}

/// `hvs board` subcommands.
#[derive(Debug, clap::Subcommand)]
pub enum BoardCommand {
    /// Find the board's inner corners in every stereo pair of a capture set and write one row
    /// per corner found in both images: capture,i,j,u_l,v_l,u_r,v_r (sub-pixel), then x,y,z
    /// when the captures give z, then the passed-through columns. `hvs train` takes it as is.
    Detect(DetectArgs),
}

/// Arguments of `hvs board detect`.
#[derive(Debug, clap::Args)]
pub struct DetectArgs {
    /// The board: {"pattern": "chessboard", "inner_corners": [9, 6], "square_cm": 6.0}.
    #[arg(long, value_name = "BOARD.json")]
    pub board: PathBuf,
    /// One row per stereo pair: left,right (image paths relative to the CSV's folder),
    /// optionally z (board depth, cm), x,y (board centre, cm, default 0) and other columns
    /// (e.g. the five joint columns), passed through.
    #[arg(long, value_name = "CAPTURES.csv")]
    pub captures: PathBuf,
    /// Output CSV of the corners.
    #[arg(short = 'o', long, value_name = "POINTS.csv")]
    pub output: PathBuf,
    /// Write a PNG per image with the detected corners and their labels into this folder
    /// (created if missing).
    #[arg(long, value_name = "DIR")]
    pub overlays: Option<PathBuf>,
}

/// `hvs board`.
pub fn run(args: Args) -> Result<()> {
    match args.command {
        BoardCommand::Detect(a) => detect(&a),
    }
}

fn detect(a: &DetectArgs) -> Result<()> {
    let board = Board::from_path(&a.board).map_err(|e| anyhow::anyhow!("{e}"))?;
    let set = captures::read(&a.captures)?;
    let bar = std::io::stderr().is_terminal().then(|| {
        let b = indicatif::ProgressBar::new(set.captures.len() as u64);
        b.set_style(
            indicatif::ProgressStyle::with_template(
                "detecting {bar:30} {pos}/{len} pairs [{elapsed_precise}]",
            )
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
        );
        b
    });
    let progress = || {
        if let Some(b) = &bar {
            b.inc(1);
        }
    };
    // With overlays, the images read for detection are drawn on (not decoded twice).
    let (det, images) = if a.overlays.is_some() {
        detect_set_with_images(&board, &set, &progress)?
    } else {
        (detect_set(&board, &set, &progress)?, Vec::new())
    };
    if let Some(b) = bar {
        b.finish_and_clear();
    }
    let n = board.corner_count();
    let mut usable = 0usize;
    let mut slot = 0usize;
    for (c, out) in set.captures.iter().zip(&det.outcomes) {
        let name = format!("{} ({}, {})", set.at(c), c.left_name, c.right_name);
        match out {
            PairOutcome::Found(p) => {
                let epi = det.set.as_ref().map_or(String::new(), |s| {
                    format!(
                        ", epipolar median {:.3} px (max {:.3})",
                        s.pair_median_px[slot], s.pair_max_px[slot]
                    )
                });
                eprintln!(
                    "{name}: {n}/{n} corners, {:.1} px squares, homography rms left {:.3} px right {:.3} px{epi}",
                    p.left.square_px, p.left.homography_rms, p.right.homography_rms
                );
                usable += 1;
                slot += 1;
            }
            PairOutcome::Skipped(why) => eprintln!("warning: {name}: skipped: {why}"),
        }
    }
    if usable == 0 {
        bail!(
            "{}: no usable stereo pair ({} skipped)",
            a.captures.display(),
            set.captures.len()
        );
    }
    match &det.set {
        Some(s) => eprintln!(
            "{usable} of {} pairs, {} corners; one fundamental matrix over all: Sampson rms {:.3} px",
            set.captures.len(),
            usable * n,
            s.fit.rms_sampson
        ),
        None => eprintln!(
            "{usable} of {} pairs, {} corners (one pair: no fundamental-matrix check)",
            set.captures.len(),
            usable * n
        ),
    }
    write_bytes(&a.output, points_csv(&board, &set, &det).as_bytes())?;
    if let Some(dir) = &a.overlays {
        std::fs::create_dir_all(dir)
            .with_context(|| format!("{}: cannot create", dir.display()))?;
        for ((c, out), pair) in set.captures.iter().zip(&det.outcomes).zip(&images) {
            let (PairOutcome::Found(p), Some([left, right])) = (out, pair) else {
                continue;
            };
            for (image, name, corners) in [
                (left, &c.left_name, &p.left),
                (right, &c.right_name, &p.right),
            ] {
                let img = hvs_vision::overlay::draw_corners(image, corners);
                write_bytes(&overlay_path(dir, name), &png_bytes(&img)?)?;
            }
        }
    }
    Ok(())
}

/// `DIR/<image stem>.overlay.png`.
fn overlay_path(dir: &Path, image: &str) -> PathBuf {
    let stem = Path::new(image)
        .file_stem()
        .map_or_else(|| image.to_string(), |s| s.to_string_lossy().into_owned());
    dir.join(format!("{stem}.overlay.png"))
}
