//! The studies: experiments that compute facts, plot them and write a report.
//!
//! - [`thesis`]: the thesis' chapter-4 experiments (`hvs experiment thesis`, `RESULTS.md`).
//! - [`posture`]: the posture study (`hvs experiment posture`, `POSTURE.md`).
//! - [`plot`]: the figures (SVG and PNG through `plotters`).

pub mod plot;
pub mod posture;
pub mod thesis;
