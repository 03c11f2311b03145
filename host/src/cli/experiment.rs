//! `hvs experiment`: regenerates studies as CSV, plots and a report. `hvs experiment thesis`
//! reruns every experiment of the thesis' chapter 4 on the simulated HVS
//! ([`crate::study::thesis`]) and writes `RESULTS.md` with the thesis' values beside ours;
//! `hvs experiment posture` runs the posture study of issue 8
//! ([`crate::study::posture::report`]) and writes `POSTURE.md`.

use crate::study::posture::report::{self as posture, PostureConfig};
use crate::study::thesis::{self as experiment, report, Bars, Config};
use anyhow::{Context, Result};
use std::io::IsTerminal;
use std::path::PathBuf;
use std::time::Instant;

/// Arguments of `hvs experiment`.
#[derive(Debug, clap::Args)]
#[command(about = "Regenerate the thesis' experiments as CSV files, plots and RESULTS.md")]
pub struct Args {
    #[command(subcommand)]
    which: Which,
}

#[derive(Debug, clap::Subcommand)]
enum Which {
    /// Every experiment of the thesis' chapter 4 (Figs. 4.3-4.22) plus BP vs. LM and pixel
    /// noise, on the four simulated camera cases.
    #[command(
        long_about = "Every experiment of the thesis' chapter 4 on the simulated HVS: \
        Phi by eq. 4.1-3 (Figs. 4.3, 4.4), the traditional method in cases I-IV (4.8-4.11), the \
        4-5-3 net and ten nets on case IV (4.12, 4.13), hidden neurons 1-10 with one or three \
        outputs (4.14, 4.15), the proposed net in cases I-IV (4.16-4.19), fewer training depths \
        (4.20-4.22); beyond the thesis, back-propagation vs. Levenberg-Marquardt and e_ma vs. \
        pixel noise. Each writes a CSV and a plot (SVG, PNG) into DIR, and RESULTS.md puts \
        the thesis' reported values beside ours. Same seed, same CSV bytes."
    )]
    Thesis(ThesisArgs),
    /// Beyond the thesis: depth while the eyes move. The thesis net at other head postures, a
    /// posture-aware net per posture band against the floor, its hidden neurons, lens
    /// distortion.
    #[command(
        long_about = "The posture study of issue 8 (hvs_host::posture_study) on thesis case         III: the thesis' 4-5-3 net, trained at the home posture, evaluated at verged and         turned postures; a posture-aware 9-16-3 net (pixels and the five joint angles) per         posture band of the working range against the optimal-triangulation floor at the same         posture (goal: within 20 %); the hidden-neuron count it needs (5, 8, 12, 16, 24); lens         distortion k1 0 to -0.5 for the networks, a DLT fit and the floor. Each part writes a         CSV and a plot (SVG, PNG) into DIR, plus timing.csv and POSTURE.md. About two minutes         in release on 2 cores. Same seed, same CSV bytes."
    )]
    Posture(PostureArgs),
}

/// Arguments of `hvs experiment posture`.
#[derive(Debug, clap::Args)]
struct PostureArgs {
    /// Output directory (created if missing).
    #[arg(
        short = 'o',
        long,
        value_name = "DIR",
        default_value = "docs/results/posture"
    )]
    output: PathBuf,
    /// Seed of every random step (postures, points, training starts); 1 is the seed of
    /// docs/posture-study.md.
    #[arg(long, value_name = "S", default_value_t = posture::DEFAULT_SEED)]
    seed: u64,
    /// Reduced run (8 training postures, small nets, 300 test points): seconds, for tests.
    #[arg(long)]
    quick: bool,
}

/// Arguments of `hvs experiment thesis`.
#[derive(Debug, clap::Args)]
struct ThesisArgs {
    /// Output directory (created if missing).
    #[arg(short = 'o', long, value_name = "DIR", default_value = "docs/results")]
    output: PathBuf,
    /// Seed of every random step (training starts, noise, random test points).
    #[arg(long, value_name = "S", default_value_t = 0)]
    seed: u64,
    /// Reduced run (2 restarts, 2 nets per shape, 3 noise levels, 100 noise test points):
    /// seconds instead of a minute, for tests.
    #[arg(long)]
    quick: bool,
}

/// Runs `hvs experiment`.
pub fn run(a: Args) -> Result<()> {
    match a.which {
        Which::Thesis(t) => thesis(t),
        Which::Posture(p) => posture_study(p),
    }
}

fn posture_study(a: PostureArgs) -> Result<()> {
    let start = Instant::now();
    std::fs::create_dir_all(&a.output)
        .with_context(|| format!("{}: cannot create the directory", a.output.display()))?;
    let cfg = PostureConfig {
        seed: a.seed,
        quick: a.quick,
    };
    let bars = Bars::new(std::io::stderr().is_terminal());
    let r = posture::run(&cfg, &bars)?;
    let total = start.elapsed().as_secs_f64();
    let files = posture::write(&a.output, &r, total)?;
    crate::cli::say(format_args!(
        "wrote {} files ({} parts: CSV, SVG, PNG; timing.csv, POSTURE.md) to {} in {:.1} s with {} threads",
        files.len(),
        posture::STEMS.len(),
        a.output.display(),
        start.elapsed().as_secs_f64(),
        r.threads
    ))?;
    crate::cli::say(format_args!(
        "see {}",
        a.output.join("POSTURE.md").display()
    ))?;
    Ok(())
}

fn thesis(a: ThesisArgs) -> Result<()> {
    let start = Instant::now();
    std::fs::create_dir_all(&a.output)
        .with_context(|| format!("{}: cannot create the directory", a.output.display()))?;
    let cfg = Config {
        seed: a.seed,
        quick: a.quick,
    };
    let bars = Bars::new(std::io::stderr().is_terminal());
    let t = experiment::run(&cfg, &bars)?;
    let total = start.elapsed().as_secs_f64();
    let files = report::write(&a.output, &t, total)?;
    crate::cli::say(format_args!(
        "wrote {} files ({} experiments: CSV, SVG, PNG; RESULTS.md) to {} in {:.1} s with {} threads",
        files.len(),
        report::STEMS.len(),
        a.output.display(),
        start.elapsed().as_secs_f64(),
        t.threads
    ))?;
    crate::cli::say(format_args!(
        "see {}",
        a.output.join("RESULTS.md").display()
    ))?;
    Ok(())
}
