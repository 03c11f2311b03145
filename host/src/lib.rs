//! `hvs-host`: the library behind the `hvs` command line. Each module does one thing; all
//! math comes from `hvs-shared`.
//!
//! - [`dataset`]: the in-memory training/evaluation set.
//! - [`flash`]: `hvs image` and `hvs flash` (probe-rs).

pub mod dataset;
pub mod flash;
