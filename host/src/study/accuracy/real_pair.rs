//! The `real_pair` part: Middlebury 2014's Motorcycle as scikit-image ships it (741 x 500;
//! the points and their provenance in `host/tests/fixtures/motorcycle/`), 1000 training pixels
//! and 2000 others. The floor triangulates with the pair's true cameras; the ground truth is
//! projective, so the floor and the DLT are exact up to the file's 1e-4 rounding.

use super::{estimate, triangulated_depths, AccuracyConfig, Scores};
use crate::data::csv::{read_set_from, Inputs};
use crate::data::dataset::Dataset;
use anyhow::Result;
use nalgebra::Matrix3x4;
use std::path::Path;

/// The pair's two 3x4 projection matrices in the left camera's frame (cm), from Middlebury's
/// `calib.txt` of Motorcycle divided by 4 as the images are: focal length, principal points
/// (px), baseline 19.3001 cm along X.
pub fn cameras() -> [Matrix3x4<f64>; 2] {
    let (f, cy) = (3979.911 / 4.0, 1019.507 / 4.0);
    let cam = |cx: f64, tx: f64| {
        Matrix3x4::from_row_slice(&[f, 0.0, cx, f * tx, 0.0, f, cy, 0.0, 0.0, 0.0, 1.0, 0.0])
    };
    [cam(1244.772 / 4.0, 0.0), cam(1369.115 / 4.0, -19.3001)]
}

/// What the page shows of the pair: its points, the depth range of the test points (cm) and
/// the mean e_ma of the four estimators on them.
#[derive(Debug, Clone, PartialEq)]
pub struct RealPairRow {
    pub train_points: usize,
    pub test_points: usize,
    pub z_range: [f64; 2],
    pub scores: Scores,
}

/// The training set (1000 points) and the test set (2000 other pixels).
pub fn sets() -> Result<(Dataset, Dataset)> {
    let parse = |name: &str, text: &str| -> Result<Dataset> {
        Ok(read_set_from(Path::new(name), text.as_bytes(), Inputs::Stereo, true)?.data)
    };
    let train = include_str!("../../../tests/fixtures/motorcycle/train.csv");
    let test = include_str!("../../../tests/fixtures/motorcycle/test.csv");
    Ok((parse("motorcycle/train.csv", train)?, parse("motorcycle/test.csv", test)?))
}

/// Depths of `test` triangulated with the pair's true cameras (NaN where it fails).
pub fn floor_depths(test: &Dataset) -> Vec<f64> {
    triangulated_depths(&cameras(), test)
}

/// Fits and scores the four estimators on the pair.
pub fn real_pair_row(cfg: &AccuracyConfig) -> Result<RealPairRow> {
    let (train_set, test) = sets()?;
    let ev = estimate(cfg, floor_depths(&test), &train_set, &test)?;
    let (lo, hi) = crate::fmt::span(test.targets.iter().map(|t| t[2]));
    Ok(RealPairRow {
        train_points: train_set.len(),
        test_points: test.len(),
        z_range: [lo, hi],
        scores: Scores::mean(&ev),
    })
}
