//! `hvs simulate`: point sets from the thesis camera model (board protocol or random volume).

use super::value_enum;
use crate::cli::{usage, RigArgs};
use crate::data::output::check_not_input;
use crate::data::output::write_output;
use crate::sim::board::{Pixels, TrainingBoard};
use crate::sim::posture;
use crate::sim::sets::{simulate, write_csv, SetKind, SimOptions};

value_enum! {
    /// Which set to produce.
    SetArg => SetKind {
        /// The 12 board points at each training depth (65..165 cm, step 20): 72 points.
        Train,
        /// The two test points P1, P2 at each test depth (65..165 cm, step 10): 22 points.
        Test,
        /// Uniform random points in the box the training boards span.
        Volume,
    }
}

value_enum! {
    /// How the camera reports pixel coordinates.
    PixelsArg => Pixels {
        /// Rounded to whole pixels (after any noise), as the thesis' cameras report them.
        Rounded,
        /// Unrounded: the exact projection plus any noise, as a sub-pixel corner detector.
        Exact,
    }
}

use crate::cli::{LensArgs, PostureArgs};
use anyhow::{Context, Result};
use hvs_shared::sim::posture::HeadRig;
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
    --board NXxNY:PITCH: a bigger training board instead of the thesis' 4x3 at 2 cm, e.g.\n\
    9x6:6 (9 x 6 inner corners 6 cm apart, centred on the axis like the thesis board) at the\n\
    same six depths (--set train: 324 rows), or --set volume in the box that board spans\n\
    (9x6:6: X -24..24, Y -15..15, Z 65..165 cm). --set test is the thesis' P1, P2 only.\n\n\
    Output columns: u_l,v_l,u_r,v_r,x,y,z (pixels; cm). --pixels rounded (the default):\n\
    whole pixels as a camera reports them; --pixels exact: the unrounded projection, as a\n\
    sub-pixel corner detector gives it, written in full precision. --noise-px S adds\n\
    Gaussian noise of S px to every coordinate, before the rounding when rounded.\n\n\
    --postures grid|lattice|random: the rig on the five-axis head, the set repeated at many\n\
    postures of the working range (neck pan +-30, neck tilt +-20, eye tilt +-15, version +-15,\n\
    vergence 0..10 degrees; quantised to the drives' 0.18 degree steps), the points placed in\n\
    front of where the head looks, their x,y,z in the head frame (the body-fixed stereo frame\n\
    of the home posture). grid: one random posture in every cell of a --posture-levels grid;\n\
    lattice: the regular grid itself; random: --posture-count postures. volume sets put point\n\
    k at posture k mod n. Extra columns: neck_pan,neck_tilt,eye_tilt,left_eye_pan,\n\
    right_eye_pan (degrees).\n\n\
    --distortion K1[,K2]: radial lens distortion of both cameras, 1 + K1 r^2 + K2 r^4 with r\n\
    the distance from the principal point in units of half the image width (K1 < 0: barrel),\n\
    applied before any rounding."
)]
pub struct Args {
    #[command(flatten)]
    rig: RigArgs,
    /// Which set.
    #[arg(long, value_enum)]
    set: SetArg,
    /// Number of points (volume set only) [default: 500].
    #[arg(long, value_name = "N", allow_negative_numbers = true, value_parser = crate::cli::whole_usize)]
    points: Option<usize>,
    /// Standard deviation of Gaussian pixel noise (px), added before any rounding.
    #[arg(long, value_name = "S", default_value_t = 0.0, allow_negative_numbers = true)]
    noise_px: f64,
    /// Seed of the random points and the noise.
    #[arg(long, value_name = "S", default_value_t = 0, allow_negative_numbers = true, value_parser = crate::cli::whole_u64)]
    seed: u64,
    /// Output CSV (written atomically); stdout if absent.
    #[arg(short = 'o', long, value_name = "FILE.csv")]
    output: Option<PathBuf>,
    #[command(flatten)]
    postures: PostureArgs,
    #[command(flatten)]
    lens: LensArgs,
    /// Rounded (whole pixels, the thesis) or exact (unrounded) pixel coordinates.
    #[arg(long, value_enum, value_name = "HOW", default_value_t = PixelsArg::Rounded)]
    pixels: PixelsArg,
    /// Training board: `thesis` (4 x 3 points at 2 cm) or NXxNY:PITCH, e.g. 9x6:6 (inner
    /// corners, cm) [default: thesis].
    #[arg(long, value_name = "thesis|NXxNY:PITCH", value_parser = parse_board)]
    board: Option<TrainingBoard>,
}

/// clap's parser of `--board`: [`TrainingBoard::parse`], its error as the message.
fn parse_board(s: &str) -> Result<TrainingBoard, String> {
    TrainingBoard::parse(s).map_err(|e| {
        let m = e.to_string();
        m.strip_prefix("--board ").unwrap_or(&m).to_string()
    })
}

/// Runs `hvs simulate`.
pub fn run(a: Args) -> Result<()> {
    if let Some(out) = &a.output {
        check_not_input("-o", out, &a.rig.inputs())?;
    }
    let rig = a.rig.rig()?.ok_or_else(|| usage("choose a rig with --case N or --rig FILE.json"))?;
    if a.points.is_some() && SetKind::from(a.set) != SetKind::Volume {
        return Err(usage(
            "--points applies to --set volume only (the board sets have a fixed size)",
        ));
    }
    // Before the simulation, whose errors name the rig: the noise is the problem.
    crate::sim::sets::check_noise_px(a.noise_px, &rig)?;
    let opt = SimOptions {
        points: a.points.unwrap_or(SimOptions::default().points),
        noise_px: a.noise_px,
        seed: a.seed,
        board: a.board.unwrap_or(TrainingBoard::Thesis),
        pixels: a.pixels.into(),
    };
    let postures = a.postures.postures(a.seed)?;
    if postures.is_some() || a.lens.given() {
        return run_postures(&a, rig, &opt, postures);
    }
    let samples = simulate(&rig, a.set.into(), &opt).with_context(|| a.rig.label())?;
    write_output(a.output.as_deref(), |w| write_csv(w, &samples).context("cannot write the CSV"))
}

/// `hvs simulate` with `--postures` and/or `--distortion`.
fn run_postures(
    a: &Args,
    rig: hvs_shared::sim::camera::Rig,
    opt: &SimOptions,
    postures: Option<Vec<hvs_shared::runtime::gaze::Joints>>,
) -> Result<()> {
    let distortion = a.lens.lens()?;
    let head = HeadRig::new(rig).with_distortion(distortion);
    let with_joints = postures.is_some();
    let joints = postures.unwrap_or_else(|| vec![hvs_shared::runtime::gaze::Joints::HOME]);
    let samples =
        posture::simulate(&head, a.set.into(), &joints, opt).with_context(|| a.rig.label())?;
    write_output(a.output.as_deref(), |w| {
        posture::write_csv(w, &samples, with_joints).context("cannot write the CSV")
    })
}
