//! Images on the host, around `hvs-vision`, one module per job: image files in and out
//! ([`files`]), board photos of a capture set into a training set ([`detection`], `hvs board
//! detect`), and the model's side of locating pixels in a stereo pair ([`mod@locate`]).
//! The detection, rendering and matching themselves live in the `hvs-vision` crate; the
//! capture-set file (`CAPTURES.csv`) is read and written in [`crate::data::captures`].

pub mod detection;
pub mod files;
pub mod locate;

pub use detection::{
    detect_set, detect_set_with_images, detected_set, found_corners, points_csv, Detection,
    FoundCorner, GroupFit, PairImages, PairOutcome, MAX_HELD_OUT_EPIPOLAR_PX,
};
pub use files::{
    capture_set_files, check_same_size, png_bytes, png_bytes_fast, read_grey, read_pair,
    write_capture_set, write_scene_pair, SCENE_PAIR_FILES,
};
pub use locate::{
    check_image_size, load_stereo_model, locate_overlay, matcher_geometry, model_fundamental,
    model_trusted, model_xyz, outside_box, training_disparities, Located, DISPARITY_SLACK,
    STATUSES, TRUSTED_INPUT_MARGIN,
};
