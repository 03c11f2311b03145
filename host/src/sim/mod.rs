//! Simulated point sets with ground truth, through the camera model of `hvs_shared::sim`.
//!
//! - [`sets`]: the thesis' board protocol (train, test) and random volume points through a rig.
//! - [`board`]: the training board (the thesis' or a grid such as 9x6 at 6 cm) and rounded or
//!   exact pixels.
//! - [`head`]: the simulated head: the firmware's loop step, servos following the setpoints,
//!   every safety rule checked on every tick.
//! - [`posture`]: the same sets at many head postures, with the five joint columns.

pub mod board;
pub mod head;
pub mod posture;
pub mod sets;
