//! `hvs-vision`: what hvs-depth does with images, on the host only (never on the head).
//!
//! - [`board`]: board descriptions (`BOARD.json`) and the corner labelling convention.
//! - [`detect`]: chessboard corners in a stereo pair, sub-pixel, validated and labelled.
//! - [`image_file`]: image files in: PNG and JPEG only, one pixel limit checked before decoding.
//! - [`geometry`]: homographies and the fundamental matrix (normalised 8-point + refinement,
//!   or from two pinhole cameras).
//! - [`render`]: stereo images of a board through a rig, with exact corner truth.
//! - [`scene`]: textured objects in front of a wall, moving in time, rendered with per-pixel
//!   truth (depth, object, the true match of a left pixel).
//! - [`matching`]: one point of the left image found in the right one (ZNCC on the epipolar line).
//! - [`dense`]: every pixel of the left image matched in the right one (census + semi-global
//!   matching along the epipolar lines).
//! - [`pfm`]: depth files out: PFM (Middlebury's float images), binary PLY point clouds and a
//!   colour-mapped depth image with a legend.
//! - [`overlay`]: drawing what was found, for a user to look at.
//! - [`invalid`]: the out-of-range parameter error of [`matching`] and [`render`].
#![forbid(unsafe_code)]

pub mod board;
pub mod dense;
pub mod detect;
pub mod geometry;
pub mod image_file;
pub mod invalid;
pub mod matching;
pub mod overlay;
pub mod pfm;
pub mod render;
pub mod scene;
