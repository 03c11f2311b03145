//! The integration tests of `hvs`, driven from outside through the built binary: one test
//! binary (probe-rs and plotters are linked once), one module per area.
//!
//! `cargo test -p hvs-host --test cli` runs them all; `cargo test -p hvs-host --test cli
//! qemu_cli -- --ignored` runs the QEMU ones (the firmware built for thumbv7em-none-eabihf
//! and `qemu-system-arm` on PATH).

#[path = "../common/mod.rs"]
mod common;

mod cli;
mod collect;
mod depth;
mod eval_posture;
mod experiment;
mod experiment_accuracy;
mod experiment_posture;
mod flash;
mod image_safety;
mod images;
mod pixel_regimes;
mod posture_cli;
mod qemu_cli;
mod real_pair;
mod safe_outputs_and_strict_inputs;
mod track;
mod train_update;
mod view;
