//! Board descriptions (`BOARD.json`) and the corner labelling convention.
//!
//! A board file reads, strictly (unknown fields, duplicate fields and bad values are errors):
//!
//! ```json
//! {"pattern": "chessboard", "inner_corners": [9, 6], "square_cm": 6.0}
//! ```
//!
//! `inner_corners` is `[cols, rows]`, both at least 2: the corners where four squares meet.
//!
//! **Labels.** Inner corner `(i, j)`, `0 <= i < cols`, `0 <= j < rows`: `(0, 0)` is the top-left
//! corner as the cameras see it, `i` grows to the right (image `+u`, head `+X`), `j` downwards
//! (image `+v`, head `+Y`). Corner index `k = j * cols + i` (row by row, as read).
//!
//! **Position.** With the board centre at `(x, y, z)` in the head frame (cm) and the board
//! facing the cameras square-on, corner `(i, j)` is at
//! `X = x + (i - (cols - 1) / 2) * square`, `Y = y + (j - (rows - 1) / 2) * square`, `Z = z`
//! ([`Board::corner_position`]).

use serde::Deserialize;

/// The board patterns this crate can detect.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Pattern {
    /// A chessboard: alternating black and white squares, inner corners detected.
    Chessboard,
}

/// A validated board description.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Board {
    /// The pattern.
    pub pattern: Pattern,
    /// Inner corners along a row (`i` range), at least 2.
    pub cols: u32,
    /// Inner corners along a column (`j` range), at least 2.
    pub rows: u32,
    /// Side of one square (cm), positive and finite.
    pub square_cm: f64,
}

/// A board description as written (`BOARD.json`, or a scene's `board` object), checked by
/// [`Board::from_spec`].
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BoardSpec {
    pattern: Pattern,
    #[serde(deserialize_with = "crate::invalid::numbers")]
    inner_corners: [u32; 2],
    square_cm: f64,
}

/// Why a board description was refused.
#[derive(Debug, Clone, PartialEq)]
pub enum BoardError {
    /// The file could not be read (path, OS message).
    Io(String, String),
    /// The JSON is malformed, has an unknown, missing or duplicate field, or a value of the
    /// wrong type (serde_json's message names the field and position).
    Json(String),
    /// A field has a value out of range (field name, reason).
    Value(&'static str, String),
}

impl core::fmt::Display for BoardError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            BoardError::Io(path, e) => write!(f, "{path}: cannot read the board file: {e}"),
            BoardError::Json(e) => write!(f, "board description: {e}"),
            BoardError::Value(field, why) => write!(f, "board description: {field}: {why}"),
        }
    }
}

impl std::error::Error for BoardError {}

/// The most inner corners along one side we accept (a sanity bound, not a detector limit).
pub const MAX_CORNERS_PER_SIDE: u32 = 1000;

impl Board {
    /// A validated board (the same checks as [`Board::from_json`]).
    pub fn new(cols: u32, rows: u32, square_cm: f64) -> Result<Board, BoardError> {
        for (name, n) in [("inner_corners[0] (cols)", cols), ("inner_corners[1] (rows)", rows)] {
            if !(2..=MAX_CORNERS_PER_SIDE).contains(&n) {
                return Err(BoardError::Value(
                    name,
                    format!("{n} is outside 2..={MAX_CORNERS_PER_SIDE}"),
                ));
            }
        }
        use crate::invalid::{MAX_CM, MIN_SQUARE_CM};
        if !(square_cm.is_finite() && square_cm > 0.0) {
            return Err(BoardError::Value(
                "square_cm",
                format!("{square_cm} is not a positive finite length"),
            ));
        }
        if !(MIN_SQUARE_CM..=MAX_CM).contains(&square_cm) {
            return Err(BoardError::Value(
                "square_cm",
                format!("{square_cm:e} cm is outside {MIN_SQUARE_CM} to {MAX_CM} cm"),
            ));
        }
        Ok(Board { pattern: Pattern::Chessboard, cols, rows, square_cm })
    }

    /// Parse a board description from JSON text.
    pub fn from_json(text: &str) -> Result<Board, BoardError> {
        let f: BoardSpec =
            // A field name may hold a line break: the message stays one line.
            serde_json::from_str(text).map_err(|e| BoardError::Json(e.to_string().replace('\n', "\\n")))?;
        Board::from_spec(&f)
    }

    /// The board of a description read as written: its values checked as [`Board::new`] does.
    pub fn from_spec(f: &BoardSpec) -> Result<Board, BoardError> {
        let mut b = Board::new(f.inner_corners[0], f.inner_corners[1], f.square_cm)?;
        b.pattern = f.pattern;
        Ok(b)
    }

    /// Read and parse a board file.
    pub fn from_path(path: &std::path::Path) -> Result<Board, BoardError> {
        let text = std::fs::read_to_string(path)
            .map_err(|e| BoardError::Io(path.display().to_string(), e.to_string()))?;
        Board::from_json(&text).map_err(|e| match e {
            BoardError::Json(m) => BoardError::Json(format!("{}: {m}", path.display())),
            BoardError::Value(field, m) => {
                BoardError::Value(field, format!("{m} (in {})", path.display()))
            }
            other => other,
        })
    }

    /// The board as a `BOARD.json` text (what [`Board::from_json`] reads), one line.
    pub fn to_json(&self) -> String {
        format!(
            "{{\"pattern\": \"chessboard\", \"inner_corners\": [{}, {}], \"square_cm\": {}}}\n",
            self.cols, self.rows, self.square_cm
        )
    }

    /// Number of inner corners, `cols * rows`.
    pub fn corner_count(&self) -> usize {
        self.cols as usize * self.rows as usize
    }

    /// Index of corner `(i, j)` in row-major order (`j * cols + i`).
    pub fn index(&self, i: u32, j: u32) -> usize {
        j as usize * self.cols as usize + i as usize
    }

    /// Label `(i, j)` of corner index `k` (inverse of [`Board::index`]).
    pub fn label(&self, k: usize) -> (u32, u32) {
        ((k % self.cols as usize) as u32, (k / self.cols as usize) as u32)
    }

    /// Corner `(i, j)` in board coordinates (cm) relative to the board centre: `i` to the
    /// right, `j` down.
    pub fn corner_offset(&self, i: u32, j: u32) -> [f64; 2] {
        [
            (i as f64 - (self.cols as f64 - 1.0) / 2.0) * self.square_cm,
            (j as f64 - (self.rows as f64 - 1.0) / 2.0) * self.square_cm,
        ]
    }

    /// Head-frame position (cm) of corner `(i, j)` with the board centre at `centre = [x, y, z]`
    /// and the board square-on: `[x + (i - (cols-1)/2) s, y + (j - (rows-1)/2) s, z]`.
    pub fn corner_position(&self, centre: [f64; 3], i: u32, j: u32) -> [f64; 3] {
        let o = self.corner_offset(i, j);
        [centre[0] + o[0], centre[1] + o[1], centre[2]]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_the_documented_example() {
        let b = Board::from_json(
            r#"{"pattern": "chessboard", "inner_corners": [9, 6], "square_cm": 6.0}"#,
        )
        .unwrap();
        assert_eq!((b.cols, b.rows, b.square_cm), (9, 6, 6.0));
        assert_eq!(b.pattern, Pattern::Chessboard);
        assert_eq!(b.corner_count(), 54);
    }

    #[test]
    fn refuses_bad_descriptions_with_the_reason() {
        // A chessboard description with these corners and square size (JSON text).
        let chess = |corners: &str, square: &str| {
            format!(
                r#"{{"pattern": "chessboard", "inner_corners": {corners}, "square_cm": {square}}}"#
            )
        };
        let cases = [
            (
                r#"{"pattern": "chessboard", "inner_corners": [9, 6], "square_cm": 6.0, "x": 1}"#.into(),
                "unknown field",
            ),
            (
                r#"{"pattern": "chessboard", "inner_corners": [9, 6], "inner_corners": [9, 6], "square_cm": 6.0}"#.into(),
                "duplicate field",
            ),
            (
                r#"{"pattern": "circles", "inner_corners": [9, 6], "square_cm": 6.0}"#.into(),
                "unknown variant",
            ),
            (chess("[9]", "6.0"), "expected 2 numbers in brackets, got 1"),
            (chess("[9, 6, 2]", "6.0"), "expected 2 numbers in brackets, got 3 at line 1"),
            (chess("[9, -6]", "6.0"), "invalid value"),
            (
                r#"{"pattern": "chessboard", "inner_corners": [9, 6]}"#.into(),
                "missing field `square_cm`",
            ),
            (chess("[1, 6]", "6.0"), "cols"),
            (chess("[9, 0]", "6.0"), "rows"),
            (chess("[9, 6]", "0.0"), "square_cm"),
            (chess("[9, 6]", "-1.0"), "square_cm"),
            (chess("[9, 6]", "1e400"), "number out of range"),
            // Finite but absurd: named, not left to fail the geometry as "degenerate".
            (chess("[9, 6]", "1e300"), "1e300 cm is outside 0.01 to 100000 cm"),
            (chess("[9, 6]", "1e-300"), "1e-300 cm is outside 0.01 to 100000 cm"),
            (chess("[9, 6]", "\"6\""), "invalid type"),
            (String::new(), "EOF"),
        ];
        for (text, needle) in cases {
            let e = Board::from_json(&text).unwrap_err().to_string();
            assert!(e.contains(needle), "{text}: {e:?} lacks {needle:?}");
        }
    }

    #[test]
    fn labels_and_positions_follow_the_convention() {
        let b = Board::new(9, 6, 6.0).unwrap();
        assert_eq!(b.index(0, 0), 0);
        assert_eq!(b.index(8, 0), 8);
        assert_eq!(b.index(0, 1), 9);
        for k in 0..54 {
            let (i, j) = b.label(k);
            assert_eq!(b.index(i, j), k);
        }
        // Top-left is left (-X) and up (-Y) of the centre; symmetric about it.
        assert_eq!(b.corner_position([1.0, 2.0, 150.0], 0, 0), [1.0 - 24.0, 2.0 - 15.0, 150.0]);
        assert_eq!(b.corner_position([1.0, 2.0, 150.0], 8, 5), [1.0 + 24.0, 2.0 + 15.0, 150.0]);
        assert_eq!(
            b.corner_position([0.0, 0.0, 10.0], 1, 0)[0]
                - b.corner_position([0.0, 0.0, 10.0], 0, 0)[0],
            6.0
        );
    }

    #[test]
    fn from_path_names_the_file() {
        let e = Board::from_path(std::path::Path::new("/nonexistent/BOARD.json"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("/nonexistent/BOARD.json"), "{e}");
    }
}
