//! `hvs-shared`: the `no_std`, allocation-free core of hvs-depth.
//!
//! Everything that computes lives here, as pure functions over fixed-size arrays, so that the
//! host CLI (`hvs`) and the Cortex-M4F head controller compute the same bits (`libm`, never
//! `std` float methods). Two layers, one way (`sim` may use `runtime`, never the reverse):
//!
//! - [`runtime`]: what the head runs.
//!   - [`runtime::mlp`]: fixed-size f32 MLP inference with scaling inside the model.
//!   - [`runtime::blob`]: the one weights format, on flash and on disk (postcard + CRC-32),
//!     decoded in place on the head (its small stack).
//!   - [`runtime::activation`]: micromath's `exp` as a candidate fast sigmoid (evaluated).
//!   - [`runtime::layout`]: flash addresses of the weight slots (`memory.x` agrees, tested).
//!   - [`runtime::slots`]: pure rules: which slot boots, which one a new model is written to.
//!   - [`runtime::head`]: the head controller's logic without I/O (slot classification, boot,
//!     estimates, `Look`, `Info`, and `MainLoop`: the main loop's step the firmware runs).
//!   - [`runtime::protocol`]: the wire protocol (postcard messages in COBS frames).
//!   - [`runtime::traditional`]: the traditional depth (eqs. 3.1-16, 3.1-17, 4.1-3), the
//!     head's fallback without a model.
//!   - [`runtime::gaze`]: head axes, joint limits, 0.18° steps, fixation and forward kinematics.
//!   - [`runtime::trajectory`]: minimum-jerk, rate-limited, quantised setpoints.
//!   - [`runtime::servo`]: MCDC 3006 S ASCII commands, 50 Hz servo PWM, `ServoOutput`.
//! - [`sim`]: what only the host needs (ground truth in `f64`).
//!   - [`sim::camera`]: the thesis' HVS camera model (eqs. 3.1-3 to 3.1-9) and radial lenses.
//!   - [`sim::posture`]: the thesis rig on the five-axis head, at any posture.
//!   - [`sim::triangulate`]: optimal triangulation with the true cameras (the accuracy floor).
//!   - [`sim::presets`]: the thesis' four camera cases and its board protocol.
//!   - [`sim::metrics`]: e_ma (eq. 4.1-5) and its percentage form.
//!
//! With the `test-support` feature (tests of every crate), [`test_support`] builds the sample
//! models the tests share.
#![no_std]
#![forbid(unsafe_code)]
#![warn(missing_docs)]

pub mod runtime;
pub mod sim;
#[cfg(any(test, feature = "test-support"))]
pub mod test_support;
