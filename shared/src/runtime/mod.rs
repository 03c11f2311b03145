//! What the head runs: everything here is on the firmware's path, `no_std`, allocation-free,
//! `f32` through `libm` where the host must compute the same bits.
//!
//! Nothing here depends on [`crate::sim`]; the dependencies inside run one way:
//! - `mlp`, `gaze` and `traditional` <- `blob` (a blob holds the net, the frame of its points
//!   and the fallback calibration); `mlp` <- `activation`;
//! - `blob` and `layout` <- `slots`; `gaze` <- `trajectory` and `servo`;
//! - `blob`, `gaze`, `layout` and `traditional` <- `protocol`; all of these <- `head`;
//! - `head` and `gaze` <- `fixation` (the closed loop's step: pixels and joints to joint
//!   targets).

pub mod activation;
pub mod blob;
pub mod fixation;
pub mod gaze;
pub mod head;
pub mod layout;
pub mod mlp;
pub mod protocol;
pub mod servo;
pub mod slots;
pub mod traditional;
pub mod trajectory;
