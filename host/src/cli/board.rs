//! `hvs board detect`: stereo photos of a board at known positions into a training set
//! (sub-pixel corners found in both images), through [`crate::vision`] and `hvs-vision`.

use crate::data::captures;
use crate::data::output::Batch;
use crate::data::output::{check_dir_output, check_outputs};
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
    /// when the captures give z, then the passed-through columns, then image_width,
    /// image_height (px; a model trained on it keeps the size). `hvs train` takes it as is.
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
    /// (created if missing, in a folder that exists).
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
    if let Some(dir) = &a.overlays {
        check_dir_output("--overlays", dir)?;
    }
    let board = Board::from_path(&a.board).map_err(|e| anyhow::anyhow!("{e}"))?;
    let set = captures::read(&a.captures)?;
    // Every output is checked against every input (the board, the captures, each image) and
    // against the others before any work; they are written last.
    let overlay_names: Vec<PathBuf> = match &a.overlays {
        Some(dir) => set
            .captures
            .iter()
            .enumerate()
            .flat_map(|(k, c)| {
                [
                    overlay_path(dir, k + 1, "left", &c.left_name),
                    overlay_path(dir, k + 1, "right", &c.right_name),
                ]
            })
            .collect(),
        None => Vec::new(),
    };
    let mut inputs: Vec<(&str, &Path)> = vec![("--board", &a.board), ("--captures", &a.captures)];
    for c in &set.captures {
        inputs.push(("--captures image", &c.left));
        inputs.push(("--captures image", &c.right));
    }
    let mut outputs: Vec<(&str, &Path)> = vec![("-o", &a.output)];
    if a.overlays.as_deref().is_some_and(Path::is_dir) {
        outputs.extend(overlay_names.iter().map(|p| ("--overlays", p.as_path())));
    }
    check_outputs(&outputs, &inputs)?;
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
    for ((c, out), epi) in set.captures.iter().zip(&det.outcomes).zip(&det.epipolar) {
        let name = set.name(c);
        match out {
            PairOutcome::Found(p) => {
                let epi = epi.map_or(String::new(), |[median, max]| {
                    format!(", epipolar median {median:.3} px (max {max:.3})")
                });
                eprintln!(
                    "{name}: {n}/{n} corners, {:.1} px squares, homography rms left {:.3} px right {:.3} px{epi}",
                    p.left.square_px, p.left.homography_rms, p.right.homography_rms
                );
                usable += 1;
            }
            PairOutcome::Skipped(why) => eprintln!("warning: {name}: skipped: {why}"),
        }
    }
    if usable == 0 {
        bail!("{}: no usable stereo pair ({} skipped)", a.captures.display(), set.captures.len());
    }
    let check = det.fundamental_check();
    let check = if det.groups.is_empty() { format!(" ({check})") } else { format!("; {check}") };
    let pairs = crate::fmt::count(set.captures.len(), "pair");
    eprintln!("{usable} of {pairs}, {} corners{check}", usable * n);
    // The overlays and the points replaced together: a failure or a signal leaves them all
    // as they were.
    let batch = Batch::new();
    if let Some(dir) = &a.overlays {
        let mut pngs = Vec::new();
        for ((out, pair), names) in det.outcomes.iter().zip(&images).zip(overlay_names.chunks(2)) {
            let (PairOutcome::Found(p), Some([left, right])) = (out, pair) else {
                continue;
            };
            for ((image, corners), path) in
                [(left, &p.left), (right, &p.right)].into_iter().zip(names)
            {
                let img = hvs_vision::overlay::draw_corners(image, corners);
                pngs.push((path.clone(), png_bytes(&img)?));
            }
        }
        std::fs::create_dir_all(dir)
            .with_context(|| format!("--overlays {}: cannot create the folder", dir.display()))?;
        for (path, bytes) in &pngs {
            batch.add(path, bytes)?;
        }
    }
    batch.add(&a.output, points_csv(&board, &set, &det).as_bytes())?;
    batch.commit()
}

/// `DIR/NN-SIDE-<image stem>.overlay.png`: the capture's number (from 1) and side keep two
/// images of one stem (`a/img.png` and `b/img.png`, `x.png` and `x.jpg`) apart.
fn overlay_path(dir: &Path, capture: usize, side: &str, image: &str) -> PathBuf {
    let stem = Path::new(image)
        .file_stem()
        .map_or_else(|| image.to_string(), |s| s.to_string_lossy().into_owned());
    dir.join(format!("{capture:02}-{side}-{stem}.overlay.png"))
}
