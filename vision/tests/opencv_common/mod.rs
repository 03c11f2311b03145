//! Shared by the tests on OpenCV's 13 real stereo pairs (`tests/fixtures/opencv-stereo`,
//! Apache-2.0, see its README): the fixture folder and its pairs with their detected corners.
#![allow(dead_code)]

use hvs_vision::board::Board;
use hvs_vision::detect::{self, StereoCorners};
use image::GrayImage;
use std::path::PathBuf;

/// The fixture folder.
pub fn dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/opencv-stereo")
}

/// One pair of `captures.csv`: the left image's file name, both images, their corners.
pub struct Pair {
    pub name: String,
    pub left: GrayImage,
    pub right: GrayImage,
    pub corners: StereoCorners,
}

/// Every pair of `captures.csv`, in its order, with the board of `board.json` detected in
/// both images (a pair where it is not found panics, naming the pair).
pub fn load() -> Vec<Pair> {
    let board = Board::from_path(&dir().join("board.json")).unwrap();
    let text = std::fs::read_to_string(dir().join("captures.csv")).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some("left,right"));
    lines
        .filter(|l| !l.trim().is_empty())
        .map(|l| {
            let (a, b) = l.split_once(',').unwrap();
            let left = image::open(dir().join(a)).unwrap().to_luma8();
            let right = image::open(dir().join(b)).unwrap().to_luma8();
            let corners = detect::detect_pair(&left, &right, &board)
                .unwrap_or_else(|e| panic!("{a} / {b}: {e}"));
            Pair { name: a.to_string(), left, right, corners }
        })
        .collect()
}
