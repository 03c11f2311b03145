//! `hvs experiment`: regenerates studies as CSV, plots and a report. `hvs experiment thesis`
//! reruns every experiment of the thesis' chapter 4 on the simulated HVS
//! ([`crate::study::thesis`]) and writes `RESULTS.md` with the thesis' values beside ours;
//! `hvs experiment posture` runs the posture study
//! ([`crate::study::posture`]) and writes `POSTURE.md`; `hvs experiment accuracy`
//! compares the default of `hvs train` with the thesis net, a DLT fit and the floor in every
//! pixel regime ([`crate::study::accuracy`]) and writes `ACCURACY.md`.

use crate::fmt::{join, roman};
use crate::study::accuracy::{self as accuracy, AccuracyConfig};
use crate::study::engine::{self, Progress, Report};
use crate::study::posture::{self, StudyConfig};
use crate::study::thesis::{self, Config};
use anyhow::Result;
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::sync::LazyLock;

/// The long help of `hvs experiment posture`, written from the settings the command runs
/// (case, net size, hidden-neuron sweep, goal, lenses), so it cannot drift from them.
fn posture_long_about() -> String {
    let s = StudyConfig::experiment(posture::DEFAULT_SEED, false);
    let k1 = |v: Option<&f64>| v.map_or("-".to_string(), |k| k.to_string());
    format!(
        "The posture study (hvs_host::study::posture) on thesis case {}: the \
         thesis' 4-5-3 net, trained at the home posture, evaluated at verged and turned \
         postures; a posture-aware 9-{}-3 net of family {} (pixels and the five joint angles) per posture \
         band of the working range against the optimal-triangulation floor at the same \
         posture (goal: within {:.0} %); the hidden-neuron count it needs ({}); lens \
         distortion k1 {} to {} for the networks, a DLT fit and the floor. Each part writes a \
         CSV and a plot (SVG, PNG) into DIR, plus timing.csv and POSTURE.md. Under a minute in \
         release on 2 cores. Same seed, same CSV bytes.",
        roman(s.case),
        s.hidden,
        s.family.name(),
        (posture::GOAL_RATIO - 1.0) * 100.0,
        join(&s.sweep, ", "),
        k1(s.k1.first()),
        k1(s.k1.last()),
    )
}

static POSTURE_ABOUT: LazyLock<String> = LazyLock::new(posture_long_about);

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
    #[command(long_about = "Every experiment of the thesis' chapter 4 on the simulated HVS: \
        Phi by eq. 4.1-3 (Figs. 4.3, 4.4), the traditional method in cases I-IV (4.8-4.11), the \
        4-5-3 net and ten nets on case IV (4.12, 4.13), hidden neurons 1-10 with one or three \
        outputs (4.14, 4.15), the proposed net in cases I-IV (4.16-4.19), fewer training depths \
        (4.20-4.22); beyond the thesis, back-propagation vs. Levenberg-Marquardt and e_ma vs. \
        pixel noise. Each writes a CSV and a plot (SVG, PNG) into DIR, and RESULTS.md puts \
        the thesis' reported values beside ours. Same seed, same CSV bytes.")]
    Thesis(ThesisArgs),
    /// Beyond the thesis: depth while the eyes move. The thesis net at other head postures, a
    /// posture-aware net per posture band against the floor, its hidden neurons, lens
    /// distortion.
    #[command(long_about = POSTURE_ABOUT.as_str())]
    Posture(PostureArgs),
    /// Beyond the thesis: the default of `hvs train`, the thesis net, a DLT fit and the floor
    /// in every pixel regime (rounded, sub-pixel, exact, barrel lens; thesis and 9x6 boards),
    /// against pixel noise and lens distortion, and on corners detected in rendered images.
    #[command(long_about = "Depth accuracy in every pixel regime: for each training board \
        (the thesis' 4x3 at 2 cm, a 9x6 board at 6 cm), pixel regime (int: rounded; sub: \
        Gaussian 0.05 px, unrounded; exact; barrel: rounded through k1 = -0.1 lenses) and thesis \
        case I-IV, the e_ma on random volume points of the floor (optimal triangulation with the \
        true rig and lenses), a DLT fit, the thesis' 4-5-3 net and the default of hvs train, and \
        their ratios to the floor; the thesis protocol (P1, P2 at 11 depths); e_ma against pixel \
        noise 0-0.5 px and against k1 0 to -0.2 (case IV, plots); corners detected in rendered \
        images of the 9x6 board (mild, heavy blur and noise, barrel). Writes DIR/ACCURACY.md and \
        DIR/accuracy/ (CSVs, SVG and PNG plots, timing.csv). Seeds from --seed-base, the \
        held-out 1000000 by default. Same seeds, same CSV bytes.")]
    Accuracy(AccuracyArgs),
}

/// Arguments of `hvs experiment accuracy`.
#[derive(Debug, clap::Args)]
struct AccuracyArgs {
    /// Output directory of ACCURACY.md (created if missing); CSVs and plots go to DIR/accuracy.
    #[arg(
        short = 'o',
        long = "output-dir",
        visible_alias = "output",
        value_name = "DIR",
        default_value = "docs"
    )]
    output: PathBuf,
    /// Base of every set's seed (1000000: the held-out draws nothing was tuned on).
    #[arg(long, visible_alias = "seed", value_name = "S", default_value_t = accuracy::HELD_OUT_SEED_BASE, value_parser = crate::cli::whole_u64)]
    seed_base: u64,
    /// Reduced run (case IV only, 2 restarts, 60 test points, 2 sweep levels, one image
    /// regime on 2 depths): seconds, for tests.
    #[arg(long)]
    quick: bool,
}

/// Arguments of `hvs experiment posture`.
#[derive(Debug, clap::Args)]
struct PostureArgs {
    /// Output directory (created if missing).
    #[arg(short = 'o', long, value_name = "DIR", default_value = "docs/results/posture")]
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
        Which::Accuracy(a) => accuracy_study(a),
    }
}

fn accuracy_study(a: AccuracyArgs) -> Result<()> {
    let cfg = AccuracyConfig {
        default_family: crate::train::DEFAULT_FAMILY,
        seed_base: a.seed_base,
        quick: a.quick,
    };
    study(&a.output, |p| accuracy::run(&cfg, p))
}

fn posture_study(a: PostureArgs) -> Result<()> {
    study(&a.output, |p| posture::run(&StudyConfig::experiment(a.seed, a.quick), p))
}

fn thesis(a: ThesisArgs) -> Result<()> {
    study(&a.output, |p| thesis::run(&Config { seed: a.seed, quick: a.quick }, p))
}

/// Runs a study into `output` with progress bars on a terminal and says what it wrote and
/// where its page is.
fn study<R: Report>(output: &Path, compute: impl FnOnce(&dyn Progress) -> Result<R>) -> Result<()> {
    let bars = Bars::new(std::io::stderr().is_terminal());
    let ran = engine::run(output, &bars, compute)?;
    crate::cli::say(format_args!(
        "wrote {} files ({}) to {} in {:.1} s with {} threads",
        ran.files.len(),
        ran.kinds(),
        output.display(),
        ran.seconds,
        ran.threads,
    ))?;
    crate::cli::say(format_args!("see {}", output.join(R::PAGE).display()))
}

/// `indicatif` bars on stderr, one per stage, left on screen when done.
pub struct Bars {
    multi: indicatif::MultiProgress,
    current: std::sync::Mutex<Option<indicatif::ProgressBar>>,
}

impl Bars {
    /// Bars drawn on stderr when `visible` (normally: stderr is a terminal), else hidden.
    pub fn new(visible: bool) -> Self {
        let target = if visible {
            indicatif::ProgressDrawTarget::stderr()
        } else {
            indicatif::ProgressDrawTarget::hidden()
        };
        Bars {
            multi: indicatif::MultiProgress::with_draw_target(target),
            current: std::sync::Mutex::new(None),
        }
    }
}

impl engine::Progress for Bars {
    fn start(&self, name: &str, units: u64) {
        let b = self.multi.add(indicatif::ProgressBar::new(units));
        b.set_style(
            indicatif::ProgressStyle::with_template(
                "{prefix:<26} {bar:30} {pos:>3}/{len:<3} [{elapsed_precise}]",
            )
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
        );
        b.set_prefix(name.to_string());
        if let Ok(mut c) = self.current.lock() {
            *c = Some(b);
        }
    }
    fn inc(&self) {
        if let Ok(c) = self.current.lock() {
            if let Some(b) = c.as_ref() {
                b.inc(1);
            }
        }
    }
    fn finish(&self) {
        if let Ok(mut c) = self.current.lock() {
            if let Some(b) = c.take() {
                b.finish();
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::{Args as _, Command};

    #[test]
    fn posture_help_names_the_settings_it_runs() {
        let cmd = Args::augment_args(Command::new("experiment"));
        let help = cmd
            .find_subcommand("posture")
            .and_then(|c| c.get_long_about())
            .expect("posture has a long help")
            .to_string();
        assert!(help.contains("on thesis case III: the thesis'"), "{help}");
        assert!(help.contains("(5, 8, 12, 16, 24, 32)"), "{help}");
        assert!(help.contains("9-16-3 net") && help.contains("within 20 %"), "{help}");
        assert!(help.contains("k1 0 to -0.5"), "{help}");
        assert!(!help.contains("  "), "a lost line continuation: {help}");
    }
}
