//! `hvs depth`: every pixel of a stereo pair to X, Y, Z by the model
//! ([`crate::depth::depth_files`]), written as PFM images, a colour-mapped PNG and a PLY cloud.

use super::StereoArgs;
use crate::data::output::check_outputs;
use crate::data::output::Batch;
use crate::depth::{depth_files, Depth};
use crate::vision::png_bytes;
use anyhow::{anyhow, Result};
use hvs_vision::dense::DenseParams;
use hvs_vision::pfm::{pfm_bytes, FloatImage};
use std::path::{Path, PathBuf};

/// Arguments of `hvs depth`.
#[derive(Debug, clap::Args)]
#[command(
    about = "Depth of every pixel of a stereo pair (dense matching + the model)",
    long_about = "Match every pixel of the left image in the right one (census costs, \
    semi-global matching along the model's epipolar lines, inside the disparities its depth \
    box allows, with uniqueness, left-right and speckle checks) and give the model's Z (and \
    X, Y) of each confident match. Unknown pixels are +inf (Middlebury's convention). A blank \
    or saturated image gives all +inf and a warning, with exit status 0."
)]
pub struct Args {
    #[command(flatten)]
    pub pair: StereoArgs,
    /// Depth: one-channel PFM (little-endian, bottom row first), Z in cm per left pixel.
    #[arg(short = 'o', long, value_name = "DEPTH.pfm")]
    pub output: PathBuf,
    /// Matches: three-channel PFM, u_r, v_r and a confidence 0..1 (+inf, +inf, 0 where none).
    #[arg(long, value_name = "MATCHES.pfm")]
    pub matches: Option<PathBuf>,
    /// X, Y, Z in cm: three-channel PFM (X and Y NaN for a Z-only model).
    #[arg(long, value_name = "XYZ.pfm")]
    pub xyz: Option<PathBuf>,
    /// A colour-mapped depth image with a legend in cm (the model's depth box).
    #[arg(long, value_name = "DEPTH.png")]
    pub colour: Option<PathBuf>,
    /// A point cloud: binary PLY, X Y Z in cm with the left image's grey levels.
    #[arg(long, value_name = "CLOUD.ply")]
    pub ply: Option<PathBuf>,
    /// Fewer wrong matches beside depth edges, for about 40 % more time: the left-right check
    /// aggregates the right image on its own (instead of reading it off the left image's
    /// sums), and the first nearer match past a run of unmatched pixels is dropped (what `hvs
    /// locate` and `hvs view` use).
    #[arg(long)]
    pub thorough: bool,
}

fn image(d: &Depth, channels: u8, data: Vec<f32>) -> FloatImage {
    FloatImage { width: d.matches.width, height: d.matches.height, channels, data }
}

/// `hvs depth`.
pub fn run(a: Args) -> Result<()> {
    let inputs: Vec<(&str, &Path)> = a.pair.inputs().to_vec();
    let mut outputs: Vec<(&str, &Path)> = vec![("-o", &a.output)];
    for (flag, p) in
        [("--matches", &a.matches), ("--xyz", &a.xyz), ("--colour", &a.colour), ("--ply", &a.ply)]
    {
        if let Some(p) = p {
            outputs.push((flag, p));
        }
    }
    check_outputs(&outputs, &inputs)?;
    if let Some(p) = &a.colour {
        crate::cli::check_png_name("--colour", p)?;
    }
    let params = if a.thorough { DenseParams::thorough() } else { DenseParams::default() };
    let (d, left) = depth_files(&a.pair.model, &a.pair.left, &a.pair.right, &params)?;
    // The cloud first: a Z-only model has none, and nothing is written then.
    let cloud = match &a.ply {
        Some(_) => {
            Some(d.cloud(&left).map_err(|e| anyhow!("--ply: {}: {e}", a.pair.model.display()))?)
        }
        None => None,
    };
    // Every output staged, then all replaced together (a run stopped half-way or an output
    // that cannot be written leaves every output as it was).
    let batch = Batch::new();
    let z: Vec<f32> = d.xyz.iter().map(|p| p[2]).collect();
    batch.add(&a.output, &pfm_bytes(&image(&d, 1, z)))?;
    if let Some(p) = &a.matches {
        let m = &d.matches;
        let data = (0..m.ur.len()).flat_map(|k| [m.ur[k], m.vr[k], m.conf[k]]).collect();
        batch.add(p, &pfm_bytes(&image(&d, 3, data)))?;
    }
    if let Some(p) = &a.xyz {
        let data = d.xyz.iter().flatten().copied().collect();
        batch.add(p, &pfm_bytes(&image(&d, 3, data)))?;
    }
    if let Some(p) = &a.colour {
        batch.add(p, &png_bytes(&d.colour())?)?;
    }
    if let (Some(p), Some(cloud)) = (&a.ply, cloud) {
        batch.add(p, &cloud)?;
    }
    batch.commit()?;
    for w in &d.warnings {
        eprintln!("warning: {w}");
    }
    eprintln!("{}; {} warning(s)", d.summary(), d.warnings.len());
    if let Some(note) =
        crate::infer::extrapolation_note(d.outside_box, d.returned(), "pixels with a depth")
    {
        eprintln!("{note}");
    }
    Ok(())
}
