//! `hvs-shared`: the `no_std`, allocation-free core of hvs-depth.
//!
//! Everything that computes lives here, as pure functions over fixed-size arrays, so that the
//! host CLI (`hvs`) and the Cortex-M4F head controller compute the same bits (`libm`, never
//! `std` float methods). This crate owns:
//!
//! - [`camera`]: the thesis' HVS camera model (eqs. 3.1-3 to 3.1-9), projection with and
//!   without rounding.
//! - [`triangulate`]: the traditional depth (eqs. 3.1-16, 3.1-17), the Phi estimate (eq. 4.1-3)
//!   and the optimal (least reprojection error) triangulation used as the accuracy floor.
//! - [`mlp`]: fixed-size f32 MLP inference with scaling inside the model.
//! - [`activation`]: a candidate fast sigmoid (micromath's exp) and an inference over it.
//! - [`blob`]: the one weights format, on flash and on disk (postcard + CRC-32).
//! - [`blob_in_place`]: [`blob::decode`] into an existing blob (the head's boot, small stack).
//! - [`layout`]: flash addresses of the weight slots (`memory.x` agrees, tested).
//! - [`head`]: the head controller's logic without I/O (boot slot choice, estimates, Info).
//! - [`protocol`]: head-controller wire protocol (postcard messages in COBS frames).
//! - [`posture`]: the simulator's head postures (the thesis rig on the five-axis head), radial
//!   lens distortion, and optimal triangulation over two arbitrary cameras.
//! - [`presets`]: the thesis' four camera cases and its board protocol.
//! - [`slots`]: which weight slot boots, which one a new model is written to.
//! - [`metrics`]: e_ma (eq. 4.1-5) and its percentage form.
//! - [`gaze`]: head axes, joint limits, 0.18° steps, fixation (vergence) and forward kinematics.
//! - [`trajectory`]: minimum-jerk, rate-limited, quantised setpoints at the control rate.
//! - [`servo`]: MCDC 3006 S ASCII commands, 50 Hz servo PWM, the `ServoOutput` trait.
#![no_std]
#![forbid(unsafe_code)]
#![warn(missing_docs)]

pub mod activation;
pub mod blob;
pub mod blob_in_place;
pub mod camera;
pub mod gaze;
pub mod head;
pub mod layout;
pub mod metrics;
pub mod mlp;
pub mod posture;
pub mod presets;
pub mod protocol;
pub mod servo;
pub mod slots;
pub mod trajectory;
pub mod triangulate;
