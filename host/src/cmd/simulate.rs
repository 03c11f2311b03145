//! `hvs simulate`: point sets from the thesis camera model (board protocol or random volume).

use crate::cmd::RigArgs;
use crate::csv_io::write_output;
use crate::simulate::{simulate, write_csv, SetKind, SimOptions};
use anyhow::{anyhow, bail, Context, Result};
use std::path::PathBuf;

/// Arguments of `hvs simulate`.
#[derive(Debug, clap::Args)]
#[command(
    about = "Simulate matched stereo pixels of known points through a camera rig",
    long_about = "Simulate matched stereo pixels of known points through a camera rig.\n\n\
    --set train: the thesis' training boards (12 points at Z = 65..165 cm, step 20; 72 rows).\n\
    --set test: the test points P1, P2 (X = -+1.75 cm) at Z = 65..165 cm, step 10 (22 rows).\n\
    --set volume: --points uniform random points in the box the training boards span\n\
    (X -3..3, Y -2..2, Z 65..165 cm), kept only when both images see them.\n\n\
    Output columns: u_l,v_l,u_r,v_r,x,y,z (pixels rounded as a camera reports them; cm)."
)]
pub struct Args {
    #[command(flatten)]
    rig: RigArgs,
    /// Which set.
    #[arg(long, value_enum)]
    set: SetKind,
    /// Number of points (volume set only) [default: 500].
    #[arg(long, value_name = "N")]
    points: Option<usize>,
    /// Standard deviation of Gaussian pixel noise added before rounding (px).
    #[arg(long, value_name = "S", default_value_t = 0.0)]
    noise_px: f64,
    /// Seed of the random points and the noise.
    #[arg(long, value_name = "S", default_value_t = 0)]
    seed: u64,
    /// Output CSV (written atomically); stdout if absent.
    #[arg(short = 'o', long, value_name = "FILE.csv")]
    output: Option<PathBuf>,
}

/// Runs `hvs simulate`.
pub fn run(a: Args) -> Result<()> {
    let rig = a
        .rig
        .rig()?
        .ok_or_else(|| anyhow!("choose a rig with --case N or --rig FILE.json"))?;
    if a.points.is_some() && a.set != SetKind::Volume {
        bail!("--points applies to --set volume only (the board sets have a fixed size)");
    }
    let opt = SimOptions {
        points: a.points.unwrap_or(SimOptions::default().points),
        noise_px: a.noise_px,
        seed: a.seed,
    };
    let samples = simulate(&rig, a.set, &opt).with_context(|| a.rig.label())?;
    write_output(a.output.as_deref(), |w| {
        write_csv(w, &samples).context("cannot write the CSV")
    })
}
