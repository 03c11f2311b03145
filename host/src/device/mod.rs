//! The head as a device, seen from the host.
//!
//! - [`link`]: the protocol over TCP (QEMU) or a serial port.
//! - [`client`]: requests to a head (`hvs head`): ping, info, estimates, look.
//! - [`qemu`]: the firmware in QEMU with models in its weight slots (`hvs emulate`).
//! - [`flash_image`]: flash images of a model for one slot, slot plans (no probe-rs).
//! - `debug_probe` (feature `probe`, on by default): the chip check and the write through probe-rs.

pub mod client;
#[cfg(feature = "probe")]
pub mod debug_probe;
pub mod flash_image;
pub mod link;
pub mod qemu;
