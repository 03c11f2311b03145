//! The command line: one module per `hvs` subcommand, each a clap `Args` struct and a
//! `run(args)` that parses, wires library modules together and does I/O; none holds math.
//! This is the only layer that uses clap. Adding a command is one module here, one variant of
//! `Command` and one match arm in `main.rs`.

pub mod board;
pub mod collect;
pub mod demo;
pub mod depth;
pub mod emulate;
pub mod eval;
pub mod experiment;
pub mod flash;
pub mod head;
pub mod image;
pub mod info;
pub mod locate;
pub mod predict;
pub mod render;
pub mod simulate;
pub mod track;
pub mod train;
pub mod view;

use crate::sim::posture::Sampling;
use anyhow::{bail, Result};
use hvs_shared::sim::camera::Distortion;
use hvs_shared::sim::camera::Rig;
use std::path::{Path, PathBuf};

/// Choice of a camera rig: a built-in thesis case or a rig file.
#[derive(Debug, Clone, clap::Args)]
pub struct RigArgs {
    /// Thesis case 1-4 (the presets of cases.json); with --rig, the case of a
    /// cases.json-like file.
    #[arg(long, value_name = "N")]
    pub case: Option<u8>,
    /// Rig JSON file: one rig object or a cases.json-like file (see README).
    #[arg(long, value_name = "FILE.json")]
    pub rig: Option<PathBuf>,
}

impl RigArgs {
    /// The chosen rig, `None` if neither option is given.
    pub fn rig(&self) -> Result<Option<Rig>> {
        match (&self.rig, self.case) {
            (Some(path), case) => Ok(Some(crate::data::rig::load(path, case)?)),
            (None, Some(n)) => match hvs_shared::sim::presets::case(n) {
                Some(r) => Ok(Some(r)),
                None => bail!("--case must be 1-4, got {n}"),
            },
            (None, None) => Ok(None),
        }
    }

    /// The rig file, if given, as an input an output must not overwrite.
    pub fn inputs(&self) -> Vec<(&'static str, &Path)> {
        self.rig.iter().map(|r| ("--rig", r.as_path())).collect()
    }

    /// A short name of the choice for messages.
    pub fn label(&self) -> String {
        match (&self.rig, self.case) {
            (Some(p), Some(n)) => format!("{} case {n}", p.display()),
            (Some(p), None) => p.display().to_string(),
            (None, Some(n)) => format!("case {n}"),
            (None, None) => "no rig".to_string(),
        }
    }
}

/// A model and a stereo pair of images (`hvs locate`, `hvs depth`).
#[derive(Debug, Clone, clap::Args)]
pub struct StereoArgs {
    /// The model (from `hvs train`, with its matcher geometry).
    #[arg(long, value_name = "M.hvsw")]
    pub model: PathBuf,
    /// The left image (PNG or JPEG).
    #[arg(long, value_name = "L.png")]
    pub left: PathBuf,
    /// The right image, the same size.
    #[arg(long, value_name = "R.png")]
    pub right: PathBuf,
}

impl StereoArgs {
    /// The three inputs with their flags, for the output-overwrites-input checks.
    pub fn inputs(&self) -> [(&'static str, &std::path::Path); 3] {
        [
            ("--model", self.model.as_path()),
            ("--left", self.left.as_path()),
            ("--right", self.right.as_path()),
        ]
    }
}

/// `--distortion K1[,K2]` (`hvs simulate`, `hvs eval`).
#[derive(Debug, clap::Args)]
pub struct LensArgs {
    /// Radial lens distortion of both cameras: K1 or K1,K2 (r in units of half the image width).
    #[arg(long, value_name = "K1[,K2]", value_delimiter = ',', allow_hyphen_values = true)]
    distortion: Option<Vec<f64>>,
}

impl LensArgs {
    /// Whether `--distortion` was given.
    pub fn given(&self) -> bool {
        self.distortion.is_some()
    }
    /// The lens: none when absent; one or two finite coefficients.
    pub fn lens(&self) -> Result<Distortion> {
        distortion_arg(self.distortion.as_deref())
    }
}

fn distortion_arg(v: Option<&[f64]>) -> Result<Distortion> {
    let d = match v {
        None => Distortion::NONE,
        Some([k1]) => Distortion { k1: *k1, k2: 0.0 },
        Some([k1, k2]) => Distortion { k1: *k1, k2: *k2 },
        Some(v) => bail!("--distortion takes K1 or K1,K2, got {} values", v.len()),
    };
    if !d.is_finite() {
        bail!("--distortion coefficients must be finite numbers");
    }
    Ok(d)
}

value_enum! {
    /// How the postures of a set are chosen.
    SamplingArg => Sampling {
        /// One uniform random posture inside every cell of a `levels` grid (stratified).
        Grid,
        /// The regular grid: `levels` evenly spaced values per interval, ends included.
        Lattice,
        /// `count` uniform random postures.
        Random,
    }
}

/// Which head postures (`hvs simulate --postures`, `hvs collect`).
#[derive(Debug, clap::Args)]
pub struct PostureArgs {
    /// Head postures (adds the five joint columns): grid, lattice or random, from the working
    /// range (neck pan +-30, neck tilt +-20, eye tilt +-15, version +-15, vergence 0-10
    /// degrees), every posture quantised to the drives' 0.18 degree steps.
    #[arg(long, value_enum, value_name = "HOW")]
    pub postures: Option<SamplingArg>,
    /// Grid levels of neck pan, neck tilt, eye tilt, version, vergence (grid, lattice)
    /// [default: 3,3,3,3,4].
    #[arg(long, value_name = "A,B,C,D,E", value_delimiter = ',')]
    pub posture_levels: Option<Vec<u8>>,
    /// Number of random postures (random) [default: 100].
    #[arg(long, value_name = "N", allow_negative_numbers = true, value_parser = whole_usize)]
    pub posture_count: Option<usize>,
}

impl PostureArgs {
    /// The postures asked for (drawn with `seed ^` [`crate::sim::posture::POSTURE_SEED_MIX`]), `None` without
    /// `--postures`; `--posture-levels`/`--posture-count` without it, or with the wrong
    /// sampling, or out of range, are bad usage.
    pub fn postures(&self, seed: u64) -> Result<Option<Vec<hvs_shared::runtime::gaze::Joints>>> {
        use crate::sim::posture::{postures, PostureOptions};
        let Some(sampling) = self.postures else {
            if self.posture_levels.is_some() || self.posture_count.is_some() {
                return Err(usage("--posture-levels and --posture-count need --postures"));
            }
            return Ok(None);
        };
        let sampling = Sampling::from(sampling);
        let mut p = PostureOptions { sampling, ..PostureOptions::default() };
        if let Some(l) = &self.posture_levels {
            if sampling == Sampling::Random {
                return Err(usage("--posture-levels applies to --postures grid or lattice"));
            }
            p.levels = l.as_slice().try_into().map_err(|_| {
                usage(format!(
                    "--posture-levels takes five counts (neck pan, neck tilt, eye tilt, version, vergence), got {}",
                    l.len()
                ))
            })?;
        }
        if let Some(n) = self.posture_count {
            if sampling != Sampling::Random {
                return Err(usage("--posture-count applies to --postures random"));
            }
            p.count = n;
        }
        // Only the flags' values can be wrong here (the range is the working range).
        let drawn = postures(&p, seed ^ crate::sim::posture::POSTURE_SEED_MIX)
            .map_err(|e| usage(format!("{e:#}")))?;
        Ok(Some(drawn))
    }
}

/// The virtual cameras' image formation (`hvs render`, `hvs collect`).
#[derive(Debug, clap::Args)]
pub struct RenderArgs {
    /// Gaussian blur, standard deviation (px).
    #[arg(long, value_name = "PX", default_value_t = hvs_vision::render::RenderOptions::default().blur_sigma_px)]
    pub blur: f64,
    /// Sensor noise, standard deviation (grey levels).
    #[arg(long, value_name = "GREY", default_value_t = hvs_vision::render::RenderOptions::default().noise_sigma)]
    pub noise: f64,
    /// Supersampling of edge pixels (N x N samples, 1-16) [default: 4 in `hvs collect`, whose
    /// thousands of pairs it renders in two thirds of the time; 8 elsewhere].
    #[arg(long, value_name = "N")]
    pub supersample: Option<u32>,
}

impl RenderArgs {
    /// The render options (a board border of `margin_cm`, `supersample` unless given),
    /// checked: a bad value is bad usage naming its flag.
    pub fn options(
        &self,
        margin_cm: f64,
        supersample: u32,
    ) -> Result<hvs_vision::render::RenderOptions> {
        use hvs_vision::render::RenderOptions;
        let opt = RenderOptions {
            margin_cm,
            supersample: self.supersample.unwrap_or(supersample),
            blur_sigma_px: self.blur,
            noise_sigma: self.noise,
            ..RenderOptions::default()
        };
        opt.validate().map_err(render_error)?;
        Ok(opt)
    }
}

/// A renderer's error as `hvs` reports it: a parameter out of range is bad usage naming its
/// flag (`hvs render`, `hvs collect`); anything else is an error.
pub fn render_error(e: hvs_vision::render::RenderError) -> anyhow::Error {
    use hvs_vision::render::RenderError;
    match e {
        RenderError::Invalid(f) => {
            let flag = match f.field {
                "supersample" => "--supersample",
                "blur_sigma_px" => "--blur",
                "noise_sigma" => "--noise",
                "margin_cm" => "--square-cm",
                "depths" => "--depths",
                other => other,
            };
            usage(format!("{flag}: {}", f.reason))
        }
        other => anyhow::anyhow!("{other}"),
    }
}

/// `U,V` -> `[u, v]`, two finite numbers; anything else is bad usage (exit 2).
pub fn parse_at(s: &str) -> Result<[f64; 2]> {
    parse_pixel("--at", s)
}

/// A pixel `U,V` given to `flag` (`--at`, `--target`); bad usage naming the flag otherwise.
pub fn parse_pixel(flag: &str, s: &str) -> Result<[f64; 2]> {
    let bad = || {
        usage(format!("{flag}: {s:?} is not U,V (two finite pixel coordinates, e.g. 320.5,240)"))
    };
    let (u, v) = s.split_once(',').ok_or_else(bad)?;
    let (u, v): (f64, f64) =
        (u.trim().parse().map_err(|_| bad())?, v.trim().parse().map_err(|_| bad())?);
    if !(u.is_finite() && v.is_finite()) {
        return Err(bad());
    }
    Ok([u, v])
}

/// Refuses (bad usage) a `--restarts` outside 1 to [`crate::train::MAX_RESTARTS`] (`hvs
/// train`, `hvs demo`, `hvs view`'s retrain), before any work.
pub fn check_restarts(restarts: usize) -> Result<()> {
    let most = crate::train::MAX_RESTARTS;
    if !(1..=most).contains(&restarts) {
        return Err(usage(format!("--restarts must be from 1 to {most}, got {restarts}")));
    }
    Ok(())
}

/// Refuses (bad usage) an `--at` pixel `at` outside the left image `left` (`hvs locate --at`,
/// `hvs head look --at`), before any matching: the image's size read from its header, checked
/// first to be the one the model `blob` (read from `model`) was trained on. A file whose header
/// cannot be read is left to the full read, which names the problem.
pub fn check_at(
    model: &Path,
    blob: &hvs_shared::runtime::blob::ModelBlob,
    left: &Path,
    [u, v]: [f64; 2],
) -> Result<()> {
    if let Ok((_, w, h)) = hvs_vision::image_file::probe(left) {
        crate::depth::check_pair_size(model, blob, left, (w, h))?;
        if !crate::depth::inside_image(u, v, (w, h)) {
            return Err(usage(format!(
                "--at {u},{v}: outside the {w}x{h} left image {}",
                left.display()
            )));
        }
    }
    Ok(())
}

/// clap value parsers of whole numbers: `-5` or `1e99` gets the accepted range, not clap's
/// `unexpected argument '-5'` (the args also set `allow_negative_numbers`).
macro_rules! whole_parsers {
    ($($(#[$m:meta])* $name:ident: $t:ty),+ $(,)?) => {
        $(
            $(#[$m])*
            pub fn $name(s: &str) -> Result<$t, String> {
                let range = format!("a whole number from {} to {}", <$t>::MIN, <$t>::MAX);
                match s.trim().parse::<i128>() {
                    Ok(v) => <$t>::try_from(v).map_err(|_| format!("{v} is out of range: expected {range}")),
                    Err(_) => Err(format!("expected {range}")),
                }
            }
        )+
    };
}
whole_parsers! {
    /// A `u8` argument.
    whole_u8: u8,
    /// A `u32` argument.
    whole_u32: u32,
    /// A `u64` argument.
    whole_u64: u64,
    /// A `usize` argument.
    whole_usize: usize,
}

/// A clap value enum mirroring a library enum variant for variant (help text per variant), with
/// the conversion into it: clap stays in this layer, the libraries keep plain enums.
macro_rules! value_enum {
    ($(#[$em:meta])* $name:ident => $target:ident { $($(#[$m:meta])* $v:ident),+ $(,)? }) => {
        $(#[$em])*
        #[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
        pub enum $name {
            $($(#[$m])* $v),+
        }
        impl From<$name> for $target {
            fn from(a: $name) -> $target {
                match a {
                    $($name::$v => $target::$v),+
                }
            }
        }
    };
}
pub(crate) use value_enum;

/// Prints one line to stdout; a failed write is an error naming stdout (`println!` would
/// panic).
pub fn say(line: std::fmt::Arguments) -> Result<()> {
    use std::io::Write;
    let mut o = std::io::stdout().lock();
    writeln!(o, "{line}")
        .and_then(|()| o.flush())
        .map_err(|e| anyhow::Error::new(e).context("cannot write to stdout"))
}

/// Bad usage: a malformed or out-of-range argument value. `hvs` exits with 2 for it (as for
/// every error clap finds), 1 for every other error. The one rule: what the arguments alone
/// show to be wrong is bad usage.
#[derive(Debug)]
pub struct Usage(pub String);

impl std::fmt::Display for Usage {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for Usage {}

/// A [`Usage`] error with `msg`.
pub fn usage(msg: impl Into<String>) -> anyhow::Error {
    anyhow::Error::new(Usage(msg.into()))
}

/// Refuses (bad usage) an input that one of the files a command writes into the folder `dir`
/// (`out_flag`) would replace: `written` says which names it writes there
/// ([`crate::data::output::names_file_in`]); `whose` names them in the message ("the
/// record's"). Checked before any work.
pub fn check_inputs_not_written_in(
    out_flag: &str,
    dir: &Path,
    whose: &str,
    inputs: &[(&str, &Path)],
    written: impl Fn(&str) -> bool,
) -> Result<()> {
    for (flag, p) in inputs {
        if crate::data::output::names_file_in(dir, p, &written) {
            return Err(usage(format!(
                "{out_flag} {}: {whose} files would replace the {flag} file {}",
                dir.display(),
                p.display()
            )));
        }
    }
    Ok(())
}

/// Refuses (bad usage) a PNG output `path` (`flag`) named as another image format: `hvs`
/// writes PNG bytes whatever the name, so `d.jpg` would hold a PNG that some viewers refuse.
/// Other names (no extension, `.png`, anything not an image format) are left to the user.
pub fn check_png_name(flag: &str, path: &Path) -> Result<()> {
    const OTHER: [&str; 9] = ["jpg", "jpeg", "bmp", "gif", "tif", "tiff", "webp", "pgm", "ppm"];
    let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
    match ext {
        Some(e) if OTHER.contains(&e.as_str()) => Err(usage(format!(
            "{flag} {}: hvs writes PNG images only, and this name says .{e}; name it .png",
            path.display()
        ))),
        _ => Ok(()),
    }
}

/// A run stopped by Ctrl-C (SIGINT) or SIGTERM after writing what it had (`hvs track`'s log):
/// `hvs` exits with 130, as a shell reports a command killed by SIGINT, so that a script can
/// tell it from a whole run, and prints nothing more (the command said so itself).
#[derive(Debug)]
pub struct Interrupted;

impl std::fmt::Display for Interrupted {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("interrupted")
    }
}

impl std::error::Error for Interrupted {}

/// glibc's allocator told to keep freed memory for the next allocation instead of handing it
/// back to the kernel: called once, first thing in `main`.
///
/// By default glibc adapts its thresholds: a freed block of a few MB goes back to the kernel
/// (`munmap`, or the heap's top trimmed), and the next frame's allocation of the same size
/// takes every page afresh, a page fault each. `hvs track`'s loop allocates its frames' planes
/// and matches anew every frame: on the 2-core AMD EPYC of 2026-12-08, 780,000 minor faults in
/// a 3 s run of the README's rate command, 8,950 with these two settings (`/usr/bin/time -f
/// %R`), and its perception median went from 11-15 ms to 4-6 ms a frame. The mmap threshold,
/// 32 MiB, is the largest glibc accepts (blocks above it, as `hvs depth`'s cost volumes, are
/// still mapped and unmapped); the trim threshold keeps up to 512 MiB free at the heap's top.
/// Peak resident size does not grow with it (what is kept is reused). No effect on any output;
/// nothing to do on other C libraries.
pub fn keep_freed_memory() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    {
        const MMAP_THRESHOLD: libc::c_int = 32 << 20;
        const TRIM_THRESHOLD: libc::c_int = 512 << 20;
        // SAFETY: `mallopt` only sets the allocator's parameters; called before any thread
        // starts. A refused value (it returns 0) leaves glibc's default, which is harmless.
        unsafe {
            libc::mallopt(libc::M_MMAP_THRESHOLD, MMAP_THRESHOLD);
            libc::mallopt(libc::M_TRIM_THRESHOLD, TRIM_THRESHOLD);
        }
    }
}

/// Whether `e` is [`Interrupted`].
pub fn is_interrupted(e: &anyhow::Error) -> bool {
    e.chain().any(|c| c.downcast_ref::<Interrupted>().is_some())
}

/// The exit code of a failed command: 2 for bad usage ([`Usage`] anywhere in the chain), 130
/// for an [`Interrupted`] run, 1 otherwise.
pub fn exit_code(e: &anyhow::Error) -> i32 {
    if e.chain().any(|c| c.downcast_ref::<Usage>().is_some()) {
        2
    } else if is_interrupted(e) {
        130
    } else {
        1
    }
}

/// Where the loop's logic runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum HeadKind {
    /// The `shared::runtime` logic on the host.
    Emulate,
    /// The firmware in QEMU, moved with posture commands.
    Qemu,
}

impl HeadKind {
    /// The head to open for this kind (`firmware`: `--firmware`, for QEMU).
    pub fn choice(self, firmware: Option<PathBuf>) -> crate::track::servo_head::HeadChoice {
        use crate::track::servo_head::HeadChoice;
        match self {
            HeadKind::Emulate => HeadChoice::Emulate,
            HeadKind::Qemu => HeadChoice::Qemu(firmware),
        }
    }
}

/// `--port`: a head controller on a link (a serial device, `serial:PATH[@BAUD]`,
/// `tcp:HOST:PORT`); a bad one is bad usage.
pub fn port_arg(p: &str) -> Result<crate::device::link::Endpoint> {
    crate::track::servo_head::parse_port(p).map_err(|e| usage(format!("{e:#}")))
}

/// `WxH` of `--camera-size`: two whole numbers from 16 to 8192.
pub fn parse_camera_size(s: &str) -> Result<(u32, u32)> {
    let parsed = s
        .split_once(['x', 'X'])
        .and_then(|(w, h)| Some((w.trim().parse::<u32>().ok()?, h.trim().parse::<u32>().ok()?)));
    match parsed {
        Some((w, h)) if (16..=8192).contains(&w) && (16..=8192).contains(&h) => Ok((w, h)),
        _ => Err(crate::cli::usage(format!(
            "--camera-size: expected WxH, two whole numbers from 16 to 8192 (e.g. 640x480), got {s:?}"
        ))),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn at_takes_two_numbers() {
        assert_eq!(parse_at("320.5,-2").unwrap(), [320.5, -2.0]);
        for bad in ["", "3", "a,b", "1,2,3", "inf,240", "NaN,3"] {
            assert!(parse_at(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn exit_codes_say_usage_interruption_or_failure() {
        use anyhow::Context;
        assert_eq!(exit_code(&usage("--x: bad")), 2);
        let stopped: anyhow::Error = Interrupted.into();
        assert_eq!(exit_code(&stopped), 130);
        assert_eq!(exit_code(&Err::<(), _>(Interrupted).context("frame 3").unwrap_err()), 130);
        assert_eq!(exit_code(&anyhow::anyhow!("cannot read")), 1);
    }
}
