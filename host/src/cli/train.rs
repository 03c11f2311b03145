//! `hvs train`: fit a net on a CSV training set, add the traditional-method fallback, write
//! the weights blob; with `--from OLD.hvsw`, update that model with new points instead.

use crate::data::csv::{read_set, Inputs};
use crate::data::model;
use crate::data::output::check_not_input;
use crate::train::model::{train_table, Plan, Trained};
use crate::train::update::{next_generation, update, CameraCheck};
use crate::train::{self, Algo, BpParams, TrainConfig};
use anyhow::{bail, Context, Result};
use hvs_shared::runtime::blob::{Family, InputKind, OutputFrame, OutputKind, MAX_HIDDEN};
use hvs_shared::runtime::mlp::Activation;
use hvs_shared::runtime::traditional::Calibration;
use std::io::{IsTerminal, Write};
use std::path::{Path, PathBuf};

/// Training algorithm (command-line form).
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum AlgoArg {
    /// Levenberg-Marquardt (the default: fastest and most accurate here).
    Lm,
    /// The thesis' per-pattern back-propagation (learning rate, E_max, learning cycles).
    Bp,
    /// Adam.
    Adam,
}

/// Outputs of the net (command-line form).
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum OutputsArg {
    /// X, Y, Z (the thesis' choice).
    Xyz,
    /// Z only.
    Z,
}

impl OutputsArg {
    /// The net's outputs.
    pub fn kind(self) -> OutputKind {
        match self {
            OutputsArg::Xyz => OutputKind::Xyz,
            OutputsArg::Z => OutputKind::Z,
        }
    }
}

/// Model family (command-line form).
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum ArchArg {
    /// The thesis' net, kept exactly: X, Y, Z outputs (what `hvs experiment thesis` uses).
    Thesis,
    /// The same net trained to output X/Z, Y/Z, 1/Z; the model divides (X = o0/o2, Y = o1/o2,
    /// Z = 1/o2).
    InverseDepth,
    /// Inverse-depth outputs over an affine map of the pixels (a linear skip term from the
    /// inputs to the outputs) plus the sigmoid net's residual: the default.
    InverseDepthSkip,
}

/// The frame a posture-aware net gives its points in (command-line form).
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum FrameArg {
    /// The head frame (the thesis family's, and every stereo model's).
    Head,
    /// The eye platform's frame (the head frame turned by the neck pan, neck tilt and eye
    /// tilt inputs); the model turns its points back into the head frame.
    EyePlatform,
    /// The cyclopean frame: the eye platform's turned by the version (the mean of the eye
    /// pans); the model turns its points back into the head frame
    Cyclopean,
}

impl FrameArg {
    /// The blob's frame.
    pub fn frame(self) -> OutputFrame {
        match self {
            FrameArg::Head => OutputFrame::Head,
            FrameArg::EyePlatform => OutputFrame::EyePlatform,
            FrameArg::Cyclopean => OutputFrame::Cyclopean,
        }
    }
}

impl ArchArg {
    /// `--arch`'s default: [`train::DEFAULT_FAMILY`].
    pub const DEFAULT: ArchArg = match ArchArg::of(train::DEFAULT_FAMILY) {
        Some(a) => a,
        None => panic!("the default family has no --arch value"),
    };

    /// The `--arch` value of a family, if it has one.
    pub const fn of(f: Family) -> Option<ArchArg> {
        match f {
            Family::THESIS => Some(ArchArg::Thesis),
            Family::INVERSE_DEPTH => Some(ArchArg::InverseDepth),
            Family::INVERSE_DEPTH_SKIP => Some(ArchArg::InverseDepthSkip),
            _ => None,
        }
    }

    /// The blob's family.
    pub fn family(self) -> Family {
        match self {
            ArchArg::Thesis => Family::THESIS,
            ArchArg::InverseDepth => Family::INVERSE_DEPTH,
            ArchArg::InverseDepthSkip => Family::INVERSE_DEPTH_SKIP,
        }
    }
}

/// Arguments of `hvs train`.
#[derive(Debug, clap::Args)]
#[command(
    about = "Train a depth net on a CSV of matched pixels and true positions",
    long_about = "Train a depth net on a CSV of matched pixels and true positions \
    (u_l,v_l,u_r,v_r,x,y,z; with the five joint columns, a posture-aware 9-input net). \
    Restarts run from seeded random starts; the best by training e_ma is kept, restarts above \
    --threshold are not enrolled (as in the thesis; where the best is then fitted to synthetic \
    points, the model written is what the threshold judges). The same seed gives the same bytes. \
    The blob also holds the traditional method's calibration (Phi by eq. 4.1-3) fitted on \
    the nearest board of the data that is symmetric about X = 0, if there is one."
)]
pub struct Args {
    /// Training CSV (with --from: the new points). Give --data again to train on several
    /// sets as one (the same columns in each, e.g. a board placement per file).
    #[arg(long, value_name = "FILE.csv", required = true)]
    data: Vec<PathBuf>,
    /// Update this model with the points of --data instead of training from nothing: its
    /// weights, family, topology, inputs and scaling are kept (any of --hidden, --outputs,
    /// --arch, --frame, --algo given must match it); one board at one depth is enough.
    /// --restarts, --threshold and the back-propagation options do not apply (given, they are
    /// bad usage).
    #[arg(long, value_name = "OLD.hvsw", conflicts_with_all = ["restarts", "threshold", "learning_rate", "e_max", "max_cycles"])]
    from: Option<PathBuf>,
    /// Model file to write (atomically).
    #[arg(short = 'o', long, value_name = "MODEL")]
    output: PathBuf,
    /// Hidden units [default: 5; unless --arch thesis: 32 for a posture-aware set of detected,
    /// sub-pixel corners (`hvs collect` + `hvs board detect`), 12 for a stereo set whose left
    /// pixels span 60 % of its images' width and height (boards over the whole view, from `hvs
    /// board detect`, which writes the image size)].
    #[arg(long, value_name = "H", allow_negative_numbers = true, value_parser = crate::cli::whole_usize)]
    hidden: Option<usize>,
    /// Outputs of the net [default: xyz].
    #[arg(long, value_enum)]
    outputs: Option<OutputsArg>,
    /// Model family [default: inverse-depth-skip; thesis with --algo bp].
    #[arg(long, value_enum)]
    arch: Option<ArchArg>,
    /// Frame of a posture-aware net's points [default: cyclopean for a posture-aware set
    /// (9 inputs) outside the thesis family; head otherwise].
    #[arg(long, value_enum)]
    frame: Option<FrameArg>,
    /// Training algorithm [default: lm]; bp trains the families without a skip term only
    /// (thesis, inverse-depth).
    #[arg(long, value_enum)]
    algo: Option<AlgoArg>,
    /// Restarts from random starts [default: 10; 1 for a posture-aware set of detected,
    /// sub-pixel corners outside the thesis family].
    #[arg(long, value_name = "R", allow_negative_numbers = true, value_parser = crate::cli::whole_usize)]
    restarts: Option<usize>,
    /// Enrol only restarts whose training e_ma is at most T percent (the default family on
    /// integer pixels: write no model whose reported training e_ma, after the best restart's
    /// fit to the synthetic points, is above T).
    #[arg(long, value_name = "T")]
    threshold: Option<f64>,
    /// Seed of the random starts.
    #[arg(long, value_name = "S", default_value_t = 0, allow_negative_numbers = true, value_parser = crate::cli::whole_u64)]
    seed: u64,
    /// Back-propagation (--algo bp): learning rate.
    #[arg(long, value_name = "ETA", default_value_t = BpParams::default().learning_rate)]
    learning_rate: f64,
    /// Back-propagation (--algo bp): stop when a cycle's error E falls below E_max.
    #[arg(long, value_name = "E", default_value_t = BpParams::default().e_max)]
    e_max: f64,
    /// Back-propagation (--algo bp): most learning cycles.
    #[arg(long, value_name = "N", default_value_t = BpParams::default().max_cycles, allow_negative_numbers = true, value_parser = crate::cli::whole_usize)]
    max_cycles: usize,
    /// Half baseline d (cm) stored with the fallback calibration.
    #[arg(long, value_name = "CM", help = fallback_help("Half baseline d (cm)", Calibration::BUILT_IN.half_baseline))]
    half_baseline: Option<f64>,
    /// Principal point u0 (px) stored with the fallback calibration.
    #[arg(long, value_name = "PX", help = fallback_help("Principal point u0 (px)", Calibration::BUILT_IN.u0))]
    u0: Option<f64>,
    /// Principal point v0 (px) stored with the fallback calibration.
    #[arg(long, value_name = "PX", help = fallback_help("Principal point v0 (px)", Calibration::BUILT_IN.v0))]
    v0: Option<f64>,
}

/// The help line of a fallback calibration value, with its default.
fn fallback_help(what: &str, default: f32) -> String {
    format!("{what} stored with the fallback calibration [default: {}]", f64::from(default))
}

impl Args {
    /// `--half-baseline`, `--u0`, `--v0` with their defaults, checked.
    fn fallback_values(&self) -> Result<(f64, f64, f64)> {
        let c = Calibration::BUILT_IN;
        let hb = self.half_baseline.unwrap_or(f64::from(c.half_baseline));
        let (u0, v0) = (self.u0.unwrap_or(f64::from(c.u0)), self.v0.unwrap_or(f64::from(c.v0)));
        if !(hb.is_finite() && hb > 0.0) {
            bail!("--half-baseline must be a positive number, got {}", crate::fmt::given(hb));
        }
        if !(u0.is_finite() && v0.is_finite()) {
            bail!("--u0 and --v0 must be finite");
        }
        Ok((hb, u0, v0))
    }

    /// Whether any of `--half-baseline`, `--u0`, `--v0` was given.
    fn fallback_given(&self) -> bool {
        self.half_baseline.is_some() || self.u0.is_some() || self.v0.is_some()
    }
}

/// Runs `hvs train`.
pub fn run(a: Args) -> Result<()> {
    let (half_baseline, u0, v0) = a.fallback_values()?;
    if let Some(from) = &a.from {
        return run_update(&a, from);
    }
    if let Some(hidden) = a.hidden {
        if hidden == 0 || hidden > MAX_HIDDEN {
            bail!("--hidden must be 1..={MAX_HIDDEN}, got {hidden}");
        }
    }
    a.restarts.map(crate::cli::check_restarts).transpose()?;
    if let Some(t) = a.threshold {
        if !(t.is_finite() && t > 0.0) {
            bail!("--threshold must be a positive percentage, got {}", crate::fmt::given(t));
        }
    }
    if !(a.learning_rate.is_finite() && a.learning_rate > 0.0) {
        bail!(
            "--learning-rate must be a positive number, got {}",
            crate::fmt::given(a.learning_rate)
        );
    }
    // As `BpParams::check` has it: 0 runs every cycle up to --max-cycles.
    if !(a.e_max.is_finite() && a.e_max >= 0.0) {
        bail!("--e-max must be a finite number >= 0, got {}", crate::fmt::given(a.e_max));
    }
    check_not_input("-o", &a.output, &data_inputs(&a.data))?;
    let table = read_data(&a.data)?;
    let algo = match a.algo.unwrap_or(AlgoArg::Lm) {
        AlgoArg::Lm => Algo::Lm,
        AlgoArg::Bp => Algo::Bp,
        AlgoArg::Adam => Algo::Adam,
    };
    let family = a.arch.map_or(train::default_family_for(algo), ArchArg::family);
    let defaults = TrainConfig::for_set(family, &table.data, table.image_size);
    let config = TrainConfig {
        hidden: a.hidden.unwrap_or(defaults.hidden),
        outputs: a.outputs.unwrap_or(OutputsArg::Xyz).kind(),
        algo,
        restarts: a.restarts.unwrap_or(defaults.restarts),
        threshold_pct: a.threshold,
        seed: a.seed,
        bp: BpParams { learning_rate: a.learning_rate, e_max: a.e_max, max_cycles: a.max_cycles },
        progress: std::io::stderr().is_terminal(),
        // A posture frame on a set without joint columns is refused by `train` itself.
        frame: a.frame.map_or(defaults.frame, |f| f.frame()),
        ..defaults
    };
    // Only `train::wide_field` gives this default, and only with an image size.
    if let (None, Some((w, h))) = (a.hidden, table.image_size) {
        if config.hidden == train::WIDE_FIELD_HIDDEN {
            eprintln!(
                "note: the left pixels cover most of the images ({w}x{h}): {} hidden units, for depth over the whole image (--hidden sets another number)",
                config.hidden
            );
        }
    }
    let plan = Plan { config, half_baseline, u0, v0 };
    let t = train_table(&table, &plan)?;
    let n = model::save(&a.output, &t.blob)?;
    if t.blob.matcher.is_none() && t.blob.topology.inputs == InputKind::Stereo {
        eprintln!(
            "warning: {} has no matcher geometry (the image commands and `hvs train --from` need it): {}",
            a.output.display(),
            crate::train::matcher::NO_MATCHER_WHY
        );
    }
    print_summary(&table.name(), &a.output, n, &t).with_context(|| {
        format!("wrote {} ({n} bytes), but cannot print the summary to stdout", a.output.display())
    })
}

/// The `--data` files as the inputs an output must not overwrite.
fn data_inputs(paths: &[PathBuf]) -> Vec<(&'static str, &Path)> {
    paths.iter().map(|p| ("--data", p.as_path())).collect()
}

/// The `--data` files read and joined into one set ([`crate::data::csv::Table::join`]); a file
/// given twice is refused (its points would count double).
fn read_data(paths: &[PathBuf]) -> Result<crate::data::csv::Table> {
    let mut seen: Vec<std::fs::Metadata> = Vec::new();
    let mut tables = Vec::new();
    for p in paths {
        // The same file under another name (`./`, a symbolic or a hard link).
        if let Ok(m) = std::fs::metadata(p) {
            if seen.iter().any(|s| crate::data::output::same_file(s, &m)) {
                bail!("--data {}: given twice (its points would count double)", p.display());
            }
            seen.push(m);
        }
        tables.push(read_set(p, Inputs::Auto, true)?);
    }
    crate::data::csv::Table::join(tables)
}

fn print_summary(data: &str, out: &Path, bytes: usize, t: &Trained) -> Result<()> {
    let mut o = std::io::stdout().lock();
    o.write_all(crate::train::model::summary(data, t).as_bytes())?;
    writeln!(o, "wrote {} ({bytes} bytes, generation {})", out.display(), t.blob.generation)?;
    o.flush()?;
    Ok(())
}

/// Runs `hvs train --from OLD.hvsw`: updates a trained model with new points
/// ([`crate::train::update`]) and writes the next generation.
fn run_update(a: &Args, from_path: &Path) -> Result<()> {
    let mut inputs = data_inputs(&a.data);
    inputs.push(("--from", from_path));
    check_not_input("-o", &a.output, &inputs)?;
    let old = model::load(from_path)?;
    let b = &old.blob;
    let from = from_path.display();
    if let Some(h) = a.hidden {
        if h != b.topology.hidden as usize {
            bail!(
                "--hidden {h} does not match {from} ({} hidden units): an update keeps the old model's topology",
                b.topology.hidden
            );
        }
    }
    if let Some(o) = a.outputs.map(OutputsArg::kind) {
        if o != b.topology.outputs {
            bail!("--outputs does not match {from}'s outputs: an update keeps the old model's topology");
        }
    }
    if let Some(f) = a.arch.map(ArchArg::family) {
        if f != b.family {
            bail!(
                "--arch {} does not match {from} ({}): an update keeps the old model's family",
                f.name(),
                b.family.name()
            );
        }
    }
    if let Some(f) = a.frame.map(FrameArg::frame) {
        if f != b.frame {
            bail!("--frame does not match {from}'s output frame: an update keeps it");
        }
    }
    if let Some(algo) = a.algo {
        // The update trains as the old model was trained: its net's output layer says how
        // (linear: lm, sigmoid: the thesis' bp).
        let sigmoid = b.topology.output_activation == Activation::Sigmoid;
        let (update_algo, name) = if sigmoid { (AlgoArg::Bp, "bp") } else { (AlgoArg::Lm, "lm") };
        if algo != update_algo {
            bail!(
                "--algo {} does not match {from} (trained with {}, {} output layer, which an update trains with {name}): an update keeps the old model's training; leave --algo out",
                algo_arg_name(algo),
                crate::train::algo_name(b.meta.algorithm),
                if sigmoid { "a sigmoid" } else { "a linear" }
            );
        }
    }
    let table = read_data(&a.data)?;
    crate::data::validate::plausible_values(&table)?;
    let data_name = table.name();
    if let (Some(new), Some(old)) = (table.image_size, b.image_size()) {
        if new != old {
            bail!(
                "{}: its points come from {}x{} px images, {from} was trained on {}x{}: an update keeps the image size",
                data_name,
                new.0,
                new.1,
                old.0,
                old.1
            );
        }
    }
    let up = update(b, &table.data, a.seed, &|r| table.at(r))
        .with_context(|| format!("{data_name}: cannot update {from} with these points"))?;
    let blob = next_generation(
        b,
        old.crc,
        &up,
        &table.data,
        table.image_size,
        a.fallback_values()?,
        a.fallback_given(),
    );
    let n = model::save(&a.output, &blob)?;
    let print = || -> Result<()> {
        let mut o = std::io::stdout().lock();
        writeln!(
            o,
            "updated {} {} from {from} (generation {}, CRC {:08x}) with {} points of {} in {:.3} s ({} LM steps)",
            model::shape(&blob),
            blob.family.name(),
            b.generation,
            old.crc,
            table.data.len(),
            data_name,
            up.elapsed.as_secs_f64(),
            up.iterations
        )?;
        writeln!(
            o,
            "e_ma on the new points: {:.4} % before, {:.4} % after",
            up.old_error_pct, up.new_error_pct
        )?;
        for (side, c) in ["left", "right"].iter().zip(&up.cameras) {
            writeln!(o, "{side} camera: {}", camera_line(c))?;
        }
        writeln!(o, "learned {} samples of the old volume through the cameras", up.learned.len())?;
        writeln!(o, "wrote {} ({n} bytes, generation {})", a.output.display(), blob.generation)?;
        o.flush()?;
        Ok(())
    };
    print().with_context(|| {
        format!("wrote {} ({n} bytes), but cannot print the summary to stdout", a.output.display())
    })
}

/// `algo`'s name on the command line.
fn algo_arg_name(algo: AlgoArg) -> String {
    use clap::ValueEnum;
    algo.to_possible_value().map_or_else(|| format!("{algo:?}"), |v| v.get_name().to_string())
}

fn camera_line(c: &CameraCheck) -> String {
    let what =
        if c.moved { format!("moved (up to {:.2} px)", c.max_move_px) } else { "held".to_string() };
    format!(
        "{what}: old camera {:.3} px rms on the new points, a homography {:.3} px (F = {:.1})",
        c.old_rms_px, c.fit_rms_px, c.f
    )
}
