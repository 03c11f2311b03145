//! `hvs-host`: the library behind the `hvs` command line. All math the head runs comes from
//! `hvs-shared`; this crate does the host's work around it, in layers (each may use the ones
//! listed before it, never one after it; unit tests may use any):
//!
//! - [`fmt`]: the number formats of every report and table (CSV numbers, percentages, lists).
//! - `simd` (private): the run-time choice of instruction set (AVX-512F, AVX, portable) for
//!   the hot loops of training and target finding, in one macro.
//! - [`data`]: data sets, CSV in and out (errors name file, line, column), rig files, model
//!   files, and the one atomic writer every output goes through.
//! - [`sim`]: simulated point sets through a rig: the thesis' board protocol, random volumes,
//!   at many head postures and through distorting lenses; and the simulated head (the
//!   firmware's loop step, every safety rule checked on every tick).
//! - [`train`]: fits the f32 MLP (Levenberg-Marquardt, the thesis' back-propagation, Adam),
//!   seeded restarts in parallel, and the traditional method's fallback calibration.
//! - [`infer`]: batch inference, bit-identical to the head's.
//! - [`evaluate`]: e_ma per depth for several estimators side by side.
//! - [`vision`]: images around `hvs-vision`: image files, board photos into a training set,
//!   pixels located in a stereo pair through a model.
//! - [`study`]: the thesis' chapter-4 experiments, the posture and accuracy studies and `hvs
//!   demo`'s runs and report, on one engine: results computed, plots (`plotters`), pages from
//!   templates.
//! - [`device`]: the head as a device: the protocol link (TCP or serial), the client of its
//!   requests, QEMU emulation, and flash images / probe-rs.
//! - [`track`]: the head in the loop: scene files, the simulated head and its virtual
//!   cameras, target finding, the loop of `hvs track`.
//! - [`collect`]: the head collects its own posture-aware training set (`hvs collect`): it
//!   visits the postures with the board in place and keeps the pairs that see the whole board.
//! - [`depth`]: dense depth of a stereo pair through the model (`hvs depth`).
//! - [`view`]: `hvs view`'s local web page (axum on tokio) over the libraries above.
//! - [`cli`]: one module per `hvs` subcommand, clap `Args` + `run`; the only place clap is used.

pub mod cli;
pub mod collect;
pub mod data;
pub mod depth;
pub mod device;
pub mod evaluate;
pub mod fmt;
pub mod infer;
pub mod sim;
mod simd;
pub mod study;
pub mod track;
pub mod train;
pub mod view;
pub mod vision;
