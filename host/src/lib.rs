//! `hvs-host`: the library behind the `hvs` command line. Each module does one thing; all
//! math comes from `hvs-shared`.
//!
//! - [`dataset`]: the in-memory training/evaluation set.
//! - [`train`]: fits the f32 MLP to a data set (Levenberg-Marquardt, the thesis' BP, Adam),
//!   seeded restarts in parallel, and returns the weights blob.
//! - [`link`]: client of the head protocol over TCP or a serial port.
//! - [`emulate`]: `hvs emulate`, the firmware in QEMU.
//! - [`head`]: `hvs head`, requests to a head.
//! - [`flash`]: `hvs image` and `hvs flash` (probe-rs).

pub mod dataset;
pub mod emulate;
pub mod flash;
pub mod head;
pub mod link;
pub mod train;
