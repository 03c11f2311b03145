//! `hvs-host`: the library behind the `hvs` command line. Each module does one thing; all
//! math comes from `hvs-shared`.
//!
//! - [`dataset`]: the in-memory training/evaluation set.
//! - [`train`]: fits the f32 MLP to a data set (Levenberg-Marquardt, the thesis' BP, Adam),
//!   seeded restarts in parallel, and returns the weights blob.

pub mod dataset;
pub mod train;
