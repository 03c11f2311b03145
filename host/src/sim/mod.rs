//! Simulated point sets with ground truth, through the camera model of `hvs_shared::sim`.
//!
//! - [`sets`]: the thesis' board protocol (train, test) and random volume points through a rig.
//! - [`posture`]: the same sets at many head postures, with the five joint columns.

pub mod posture;
pub mod sets;
