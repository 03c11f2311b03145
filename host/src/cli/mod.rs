//! The command line: one module per `hvs` subcommand, each a clap `Args` struct and a
//! `run(args)` that parses, wires library modules together and does I/O; none holds math.
//! This is the only layer that uses clap. Adding a command is one module here, one variant of
//! `Command` and one match arm in `main.rs`.

pub mod board;
pub mod demo;
pub mod demo_images;
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
pub mod train;

use anyhow::{bail, Result};
use hvs_shared::sim::camera::Rig;
use std::path::PathBuf;

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
