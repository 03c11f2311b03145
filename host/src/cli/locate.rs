//! `hvs locate`: points of the left image found in the right one and turned into X, Y, Z by the
//! model, with nothing but the model and the two images ([`crate::depth::locate()`]).

use super::StereoArgs;
use crate::data::output::{check_outputs, write_output, Batch};
use crate::data::pixels::{read_pixels, Pixels};
use crate::depth::{locate_files_with, LocatedFiles};
use crate::vision::{locate_overlay, png_bytes};
use anyhow::Result;
use std::path::{Path, PathBuf};

/// Arguments of `hvs locate`.
#[derive(Debug, clap::Args)]
#[command(
    about = "Find left-image points in the right image and give their X, Y, Z",
    long_about = "Find points of the left image in the right one and give the model's X, Y, Z \
    of each trustworthy match. The points are answered from the dense matches of the pair, \
    those of `hvs depth --thorough` (census and semi-global matching along the model's epipolar lines, \
    inside the disparities its depth box allows, with uniqueness, left-right and speckle \
    checks, sub-pixel), interpolated between pixels. The model carries the geometry the search \
    needs, learned from its training pixels (`hvs train` stores it); no camera parameter is \
    used. A point without a trustworthy match keeps u_r..z empty and says why in `status`: \
    outside, nan_input, no_match, out_of_depth_range, no_estimate; `score` is the match's \
    confidence (0..1). A Z-only model gives z and leaves x, y empty."
)]
#[command(group(clap::ArgGroup::new("pixels").required(true).args(["points", "at"])))]
pub struct Args {
    #[command(flatten)]
    pub pair: StereoArgs,
    /// Points to locate: a CSV with columns u_l,v_l (other columns passed through, but for
    /// those named as the output's own, which are replaced).
    #[arg(long, value_name = "PIXELS.csv", conflicts_with = "at")]
    pub points: Option<PathBuf>,
    /// One point U,V of the left image, printed.
    #[arg(long, value_name = "U,V", allow_hyphen_values = true)]
    pub at: Option<String>,
    /// Output CSV: u_l,v_l,u_r,v_r,x,y,z,score,status then the passed-through columns
    /// (default: standard output). Not with --at, which prints its one point.
    #[arg(short = 'o', long, value_name = "OUT.csv", conflicts_with = "at")]
    pub output: Option<PathBuf>,
    /// The two images side by side with each match drawn and labelled by its row number.
    #[arg(long, value_name = "OUT.png")]
    pub overlay: Option<PathBuf>,
}

/// `hvs locate`.
pub fn run(a: Args) -> Result<()> {
    let mut inputs: Vec<(&str, &Path)> = a.pair.inputs().to_vec();
    if let Some(p) = &a.points {
        inputs.push(("--points", p));
    }
    let mut outputs: Vec<(&str, &Path)> = Vec::new();
    if let Some(o) = &a.output {
        outputs.push(("-o", o));
    }
    if let Some(o) = &a.overlay {
        outputs.push(("--overlay", o));
        crate::cli::check_png_name("--overlay", o)?;
    }
    check_outputs(&outputs, &inputs)?;
    let pixels = match (&a.points, &a.at) {
        (Some(p), _) => {
            let px = read_pixels(p)?;
            if !px.replaced.is_empty() {
                eprintln!(
                    "warning: {}: its columns {} are replaced by the located values (rename them to keep them)",
                    p.display(),
                    px.replaced.join(",")
                );
            }
            px
        }
        (None, Some(at)) => Pixels {
            extra_names: Vec::new(),
            points: vec![crate::cli::parse_at(at)?],
            extra: vec![Vec::new()],
            replaced: Vec::new(),
        },
        (None, None) => return Err(crate::cli::usage("give --points PIXELS.csv or --at U,V")),
    };
    // The one point asked for with --at must lie in the image.
    let m = crate::vision::load_stereo_model(&a.pair.model)?;
    if a.at.is_some() {
        crate::cli::check_at(&a.pair.model, &m.blob, &a.pair.left, pixels.points[0])?;
    }
    let LocatedFiles { found, warnings, left: l, right: r } =
        locate_files_with(&a.pair.model, &m.blob, &a.pair.left, &a.pair.right, &pixels.points)?;
    for w in &warnings {
        eprintln!("warning: {w}");
    }
    let answered = found.iter().filter(|f| f.xyz.is_some()).count();
    let outside = crate::vision::outside_box(&m.blob, &found);
    if let Some(note) = crate::infer::extrapolation_note(outside, answered, "located points") {
        eprintln!("{note}");
    }
    // The overlay and the points file replaced together ([`Batch`]).
    let batch = Batch::new();
    if let Some(p) = &a.overlay {
        batch.add(p, &png_bytes(&locate_overlay(&l, &r, &found))?)?;
    }
    if a.points.is_none() {
        batch.commit()?;
        let text = found[0].line();
        return crate::cli::say(format_args!("{text}"));
    }
    let mut header = format!("u_l,v_l,{}", crate::data::pixels::WRITTEN.join(","));
    for n in &pixels.extra_names {
        header.push(',');
        header.push_str(n);
    }
    let mut text = format!("{header}\n");
    for (l, extra) in found.iter().zip(&pixels.extra) {
        text.push_str(&l.csv_row());
        for e in extra {
            text.push(',');
            text.push_str(e);
        }
        text.push('\n');
    }
    match a.output.as_deref() {
        Some(p) => {
            batch.add(p, text.as_bytes())?;
            batch.commit()?;
        }
        None => {
            batch.commit()?;
            write_output(None, |w| Ok(w.write_all(text.as_bytes())?))?;
        }
    }
    let ok = found.iter().filter(|f| f.status == "ok").count();
    eprintln!("{ok} of {} points located", found.len());
    Ok(())
}
