//! What a simulated set is made of besides the rig: the calibration board ([`TrainingBoard`]:
//! the thesis' 4x3 points at 2 cm, or any `NXxNY:PITCH` grid of inner corners such as the 9x6
//! chessboard at 6 cm; the board of photos is `hvs_vision::board::Board`) and how the camera
//! reports its pixels ([`Pixels`]: rounded as the thesis' cameras do, or exact, unrounded, as
//! a sub-pixel corner detector gives them).

use anyhow::{bail, Result};
use hvs_shared::sim::camera::Vec3;
use hvs_shared::sim::presets;

/// Most inner corners along one side of a simulated or rendered grid board (`hvs simulate
/// --board`, `hvs render --inner-corners`: a larger board is a typo, not a board). A board
/// file for detection (`hvs_vision::board`) may describe larger ones.
pub const MAX_SIDE: usize = 100;

/// The calibration board of a training set, centred on the optical axis of the stereo frame
/// (X right, Y down) at each of the thesis' training depths.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum TrainingBoard {
    /// The thesis' board: X in `presets::TRAIN_BOARD_X`, Y in `presets::TRAIN_BOARD_Y`
    /// (4 x 3 points at 2 cm).
    Thesis,
    /// `nx` x `ny` inner corners `pitch` cm apart, row by row (X fastest), centred on the axis.
    Grid {
        /// Corners along X.
        nx: usize,
        /// Corners along Y.
        ny: usize,
        /// Distance of neighbouring corners (cm).
        pitch: f64,
    },
}

impl TrainingBoard {
    /// Parses `thesis` or `NXxNY:PITCH` (e.g. `9x6:6`: 9 x 6 inner corners at 6 cm); errors
    /// say what was expected.
    pub fn parse(s: &str) -> Result<TrainingBoard> {
        if s == "thesis" {
            return Ok(TrainingBoard::Thesis);
        }
        let form = "takes `thesis` or NXxNY:PITCH (e.g. 9x6:6: 9 x 6 inner corners 6 cm apart)";
        let Some((grid, pitch)) = s.split_once(':') else {
            bail!("--board {form}, got `{s}`");
        };
        let Some((nx, ny)) = grid.split_once(['x', 'X']) else {
            bail!("--board {form}, got `{s}`");
        };
        let side = |t: &str, what: &str| -> Result<usize> {
            match t.parse::<usize>() {
                Ok(n) if (2..=MAX_SIDE).contains(&n) => Ok(n),
                _ => {
                    bail!("--board `{s}`: {what} must be a whole number 2 to {MAX_SIDE}, got `{t}`")
                }
            }
        };
        let (nx, ny) = (side(nx, "NX")?, side(ny, "NY")?);
        let pitch: f64 = match pitch.parse() {
            Ok(p) if f64::is_finite(p) && p > 0.0 && p <= 100.0 => p,
            _ => bail!("--board `{s}`: PITCH must be a number of cm above 0 and at most 100, got `{pitch}`"),
        };
        Ok(TrainingBoard::Grid { nx, ny, pitch })
    }

    /// The name `parse` takes back (`thesis`, `9x6:6`).
    pub fn name(&self) -> String {
        match self {
            TrainingBoard::Thesis => "thesis".into(),
            TrainingBoard::Grid { nx, ny, pitch } => format!("{nx}x{ny}:{pitch}"),
        }
    }

    /// Points per board.
    pub fn len(&self) -> usize {
        match self {
            TrainingBoard::Thesis => presets::TRAIN_BOARD_X.len() * presets::TRAIN_BOARD_Y.len(),
            TrainingBoard::Grid { nx, ny, .. } => nx * ny,
        }
    }

    /// Always false: a board has at least 2 x 2 points.
    pub fn is_empty(&self) -> bool {
        false
    }

    /// The board's points at depth `z` (cm), row by row; the thesis board exactly as
    /// `presets::board_points`.
    pub fn points(&self, z: f64) -> Vec<Vec3> {
        match *self {
            TrainingBoard::Thesis => presets::board_points(z).to_vec(),
            TrainingBoard::Grid { nx, ny, pitch } => {
                let (cx, cy) = ((nx - 1) as f64 / 2.0, (ny - 1) as f64 / 2.0);
                (0..ny)
                    .flat_map(|j| {
                        (0..nx).map(move |i| {
                            [(i as f64 - cx) * pitch + 0.0, (j as f64 - cy) * pitch + 0.0, z]
                        })
                    })
                    .collect()
            }
        }
    }

    /// The board at every training depth (`presets::TRAIN_DEPTHS`), nearest first.
    pub fn train_points(&self) -> Vec<Vec3> {
        presets::TRAIN_DEPTHS.iter().flat_map(|&z| self.points(z)).collect()
    }

    /// The box the training boards span: `(min, max)` of X, Y, Z (cm).
    pub fn volume(&self) -> (Vec3, Vec3) {
        let pts = self.train_points();
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        for p in &pts {
            for k in 0..3 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
        (lo, hi)
    }
}

/// How the camera reports pixel coordinates.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Pixels {
    /// Rounded to whole pixels after any noise, as the thesis' cameras report them.
    #[default]
    Rounded,
    /// Unrounded: the exact projection plus any noise (a sub-pixel detector's output).
    Exact,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn thesis_board_is_the_presets() {
        let b = TrainingBoard::parse("thesis").unwrap();
        assert_eq!(b.len(), 12);
        assert_eq!(b.points(85.0), presets::board_points(85.0).to_vec());
        assert_eq!(b.volume(), ([-3.0, -2.0, 65.0], [3.0, 2.0, 165.0]));
        assert_eq!(b.train_points().len(), 72);
    }

    #[test]
    fn grid_board_is_centred_and_round_trips() {
        let b = TrainingBoard::parse("9x6:6").unwrap();
        assert_eq!(b, TrainingBoard::Grid { nx: 9, ny: 6, pitch: 6.0 });
        assert_eq!(b.name(), "9x6:6");
        assert_eq!(TrainingBoard::parse(&b.name()).unwrap(), b);
        assert_eq!(b.train_points().len(), 324);
        assert_eq!(b.volume(), ([-24.0, -15.0, 65.0], [24.0, 15.0, 165.0]));
        let p = b.points(65.0);
        assert_eq!(p[0], [-24.0, -15.0, 65.0]);
        assert_eq!(p[1], [-18.0, -15.0, 65.0]);
        assert_eq!(p[53], [24.0, 15.0, 65.0]);
        assert_eq!(TrainingBoard::parse("4X3:2.5").unwrap().name(), "4x3:2.5");
    }

    #[test]
    fn bad_boards_say_what_is_wrong() {
        for (s, needle) in [
            ("9x6", "NXxNY:PITCH"),
            ("9:6", "NXxNY:PITCH"),
            ("1x6:6", "NX must be"),
            ("9x0:6", "NY must be"),
            ("9x6:0", "PITCH must be"),
            ("9x6:-1", "PITCH must be"),
            ("9x6:nan", "PITCH must be"),
            ("axb:6", "NX must be"),
            ("101x6:1", "NX must be"),
        ] {
            let e = TrainingBoard::parse(s).unwrap_err().to_string();
            assert!(e.contains(needle), "{s}: {e}");
        }
    }
}
