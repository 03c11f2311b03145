//! What only the host needs: the thesis' camera model, head postures and lenses, the thesis
//! presets, the accuracy floor and the error metric. `no_std` like the rest of the crate (so it
//! is testable on the same terms), but never on the head's path: the firmware uses nothing
//! from here. `f64` ground truth through `libm`.

pub mod camera;
pub mod metrics;
pub mod posture;
pub mod presets;
pub mod triangulate;
