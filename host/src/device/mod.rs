//! The head as a device, seen from the host.
//!
//! - [`link`]: the protocol over TCP (QEMU) or a serial port.
//! - [`client`]: requests to a head (`hvs head`): ping, info, estimates, look.
//! - [`qemu`]: the firmware in QEMU with models in its weight slots (`hvs emulate`).
//! - [`probe`]: flash images of a model for one slot, and writing them through probe-rs.

pub mod client;
pub mod link;
pub mod probe;
pub mod qemu;
