//! The studies: experiments that compute facts, plot them and write a report.
//!
//! - [`accuracy`]: depth accuracy per pixel regime against the floor (`hvs experiment accuracy`,
//!   `ACCURACY.md`).
//! - [`thesis`]: the thesis' chapter-4 experiments (`hvs experiment thesis`, `RESULTS.md`).
//! - [`posture`]: the posture study (`hvs experiment posture`, `POSTURE.md`).
//! - [`demo`]: the results and files of `hvs demo` (`REPORT.md`, the printed summary).
//! - [`engine`]: what every study shares: the runner, the file writer, the table formatter.
//! - [`plot`]: the figures (SVG and PNG through `plotters`).
//! - [`template`]: report prose from `host/templates/*.md`, placeholders filled by [`template::fill`].
//! - [`reported`]: the thesis' reported values, the one table our numbers are compared with.

pub mod accuracy;
pub mod demo;
pub mod engine;
pub mod eval;
pub mod plot;
pub mod posture;
pub mod reported;
pub mod template;
pub mod thesis;
