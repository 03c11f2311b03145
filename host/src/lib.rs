//! `hvs-host`: the library behind the `hvs` command line. Each module does one thing; all
//! math comes from `hvs-shared`.
//!
//! - [`dataset`]: the in-memory training/evaluation set.

pub mod dataset;
