//! `hvs-host`: the library behind the `hvs` command line. Each module does one thing; all
//! math comes from `hvs-shared`.
//!
//! - [`dataset`]: the in-memory training/evaluation set.
//! - [`csv_io`]: CSV point sets in (errors name file, line, column) and atomic output.
//! - [`rigfile`]: camera rigs from `cases.json`-style JSON.
//! - [`simulate`]: the thesis' board protocol and random volume sets through a rig.
//! - [`posture`]: the same sets seen at many head postures (and through distorting lenses),
//!   with the five joint columns, for posture-aware models.
//! - [`posture_study`]: the fixed-posture net at other postures, the posture-aware net per
//!   posture band against the floor, and lens distortion (net, DLT, floor), as rows.
//! - [`fallback`]: the traditional method's calibration (eq. 4.1-3) fitted on a board set.
//! - [`infer`]: batch inference, bit-identical to the head's.
//! - [`evaluate`]: e_ma per depth for several estimators side by side.
//! - [`experiment`]: `hvs experiment thesis`, the thesis' chapter-4 experiments with plots
//!   (`plotters`) and `RESULTS.md`; `hvs experiment posture`, the posture study's report.
//! - [`model`]: model files on disk (checked reads, atomic writes).
//! - [`cmd`]: one module per `hvs` subcommand.
//! - [`train`]: fits the f32 MLP to a data set (Levenberg-Marquardt, the thesis' BP, Adam),
//!   seeded restarts in parallel, and returns the weights blob.
//! - [`link`]: client of the head protocol over TCP or a serial port.
//! - [`emulate`]: `hvs emulate`, the firmware in QEMU.
//! - [`head`]: `hvs head`, requests to a head.
//! - [`flash`]: `hvs image` and `hvs flash` (probe-rs).

pub mod cmd;
pub mod csv_io;
pub mod dataset;
pub mod emulate;
pub mod evaluate;
pub mod experiment;
pub mod fallback;
pub mod flash;
pub mod head;
pub mod infer;
pub mod link;
pub mod model;
pub mod posture;
pub mod posture_study;
pub mod rigfile;
pub mod simulate;
pub mod train;
