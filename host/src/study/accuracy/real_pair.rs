//! The `real_pair` part of the accuracy study: a real stereo pair with ground truth,
//! Middlebury 2014's Motorcycle as scikit-image ships it (741 x 500; the points are in
//! `host/tests/fixtures/motorcycle/`, whose README says where they come from and how they were
//! made): 1000 training pixels and 2000 others, positions from the structured-light
//! disparities and the pair's calibration. The four estimators as elsewhere; the floor is
//! triangulation with the pair's true (rectified, calibrated) cameras, which is exact here up
//! to the file's 1e-4 rounding: the ground truth is projective, so the DLT is exact too, and
//! what the page shows is how close each net gets to 0.

use super::{estimate_with_floor, mean_scores, AccuracyConfig, Scores};
use crate::data::csv::{read_set_from, Inputs};
use crate::data::dataset::Dataset;
use anyhow::Result;
use hvs_vision::geometry::triangulate_dlt;
use nalgebra::Matrix3x4;
use std::path::Path;

/// The training points (1000).
pub const TRAIN_CSV: &str = include_str!("../../../tests/fixtures/motorcycle/train.csv");
/// The test points (2000 other pixels).
pub const TEST_CSV: &str = include_str!("../../../tests/fixtures/motorcycle/test.csv");

/// The pair's calibration (Middlebury's `calib.txt` of Motorcycle, divided by 4 as the
/// images are): focal length, principal points of the left and right camera (px), baseline
/// (cm).
pub const CALIB: PairCalib = PairCalib {
    f: 3979.911 / 4.0,
    c_left: [1244.772 / 4.0, 1019.507 / 4.0],
    c_right: [1369.115 / 4.0, 1019.507 / 4.0],
    baseline_cm: 19.3001,
};

/// A rectified, calibrated pair.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PairCalib {
    /// Focal length (px), both cameras.
    pub f: f64,
    /// Principal point of the left camera (px).
    pub c_left: [f64; 2],
    /// Principal point of the right camera (px).
    pub c_right: [f64; 2],
    /// Baseline (cm), along X.
    pub baseline_cm: f64,
}

impl PairCalib {
    /// The two 3x4 projection matrices in the left camera's frame (cm).
    pub fn cameras(&self) -> [Matrix3x4<f64>; 2] {
        let cam = |c: [f64; 2], tx: f64| {
            Matrix3x4::new(
                self.f,
                0.0,
                c[0],
                self.f * tx,
                0.0,
                self.f,
                c[1],
                0.0,
                0.0,
                0.0,
                1.0,
                0.0,
            )
        };
        [cam(self.c_left, 0.0), cam(self.c_right, -self.baseline_cm)]
    }
}

/// What the page shows of the pair.
#[derive(Debug, Clone, PartialEq)]
pub struct RealPairRow {
    /// Training points.
    pub train_points: usize,
    /// Test points.
    pub test_points: usize,
    /// Depth range of the test points (cm).
    pub z_range: [f64; 2],
    /// Mean e_ma of the four estimators on the test points.
    pub scores: Scores,
}

fn parse(name: &str, text: &str) -> Result<Dataset> {
    Ok(read_set_from(Path::new(name), text.as_bytes(), Inputs::Stereo, true)?.data)
}

/// The training and test set.
pub fn sets() -> Result<(Dataset, Dataset)> {
    Ok((parse("motorcycle/train.csv", TRAIN_CSV)?, parse("motorcycle/test.csv", TEST_CSV)?))
}

/// Depths of `test` triangulated with the pair's true cameras (NaN where it fails).
pub fn floor_depths(test: &Dataset) -> Vec<f64> {
    let p = CALIB.cameras();
    (0..test.len())
        .map(|n| {
            let r = test.row(n);
            triangulate_dlt(&p, &[r[0], r[1], r[2], r[3]]).map_or(f64::NAN, |x| x[2])
        })
        .collect()
}

/// Fits and scores the four estimators on the pair.
pub fn real_pair_row(cfg: &AccuracyConfig) -> Result<RealPairRow> {
    let (train_set, test) = sets()?;
    let ev = estimate_with_floor(cfg, floor_depths(&test), &train_set, &test)?;
    let depths = test.targets.iter().map(|t| t[2]);
    let z_range =
        [depths.clone().fold(f64::INFINITY, f64::min), depths.fold(f64::NEG_INFINITY, f64::max)];
    Ok(RealPairRow {
        train_points: train_set.len(),
        test_points: test.len(),
        z_range,
        scores: mean_scores(&ev),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_true_cameras_reproject_the_fixture_within_its_rounding() {
        let (train_set, test) = sets().unwrap();
        assert_eq!((train_set.len(), test.len()), (1000, 2000));
        let p = CALIB.cameras();
        for d in [&train_set, &test] {
            for n in 0..d.len() {
                let (r, t) = (d.row(n), d.targets[n]);
                for (c, m) in p.iter().enumerate() {
                    let h = m * nalgebra::Vector4::new(t[0], t[1], t[2], 1.0);
                    let (u, v) = (h[0] / h[2], h[1] / h[2]);
                    assert!(
                        (u - r[2 * c]).abs() < 2e-3,
                        "row {n} camera {c}: u {u} vs {}",
                        r[2 * c]
                    );
                    assert!((v - r[2 * c + 1]).abs() < 2e-3, "row {n} camera {c}: v {v}");
                }
            }
        }
        let z = floor_depths(&test);
        let worst = (0..test.len())
            .map(|n| (z[n] - test.targets[n][2]).abs() / test.targets[n][2])
            .fold(0.0, f64::max);
        assert!(worst < 1e-5, "{worst}");
    }
}
