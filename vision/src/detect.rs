//! Chessboard corners in one image and in a stereo pair: found, refined to sub-pixel,
//! validated and labelled by the [`crate::board`] convention.
//!
//! **Pixel coordinates.** `(u, v)` are continuous, `u` to the right, `v` down, and integer
//! values are pixel *centres*: pixel `(0, 0)`'s centre is `(0.0, 0.0)` and it covers
//! `[-0.5, 0.5]^2`. This is the convention of [`hvs_shared::camera::Camera::project`] (integer
//! `u, v` are the pixels a camera reports) and of the renderer.
//!
//! **Pipeline.** The ChESS corner detector and the chessboard grid builder of `calib-targets`
//! (with the `chess-corners` saddle-point refiner) find and connect the corners. This module
//! then refuses anything but a complete `cols x rows` grid, relabels it so `(0, 0)` is the top
//! left corner as seen (`i` grows with `u`, `j` with `v`, whatever the detector's own labels),
//! checks the grid's geometry, and fits a homography board -> pixels whose RMS residual is
//! reported per image.
//!
//! **Stereo.** [`detect_pair`] detects both images, requires the same size, and checks that the
//! left and right labellings agree (a left -> right homography over the shared labels must fit
//! to a fraction of a square). [`check_set`] fits one fundamental matrix over all pairs of a
//! capture set and reports each pair's epipolar residual, which exposes a pair whose labels
//! are shifted or flipped.

use crate::board::Board;
use crate::geometry::{self, Fundamental, FundamentalFit, GeomError, HomographyFit};
use calib_targets::chessboard::{ChessboardDetector, ChessboardParams};
use calib_targets::detect::{DetectorConfig, ImageRefiner, OnRefinerReject};
use image::{DynamicImage, GrayImage};

/// Which image of a stereo pair.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Side {
    /// The left camera's image.
    Left,
    /// The right camera's image.
    Right,
}

impl core::fmt::Display for Side {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            Side::Left => "left",
            Side::Right => "right",
        })
    }
}

/// Why no labelled board came out of an image or a pair.
#[derive(Debug, Clone, PartialEq)]
pub enum DetectError {
    /// The image is too small to hold a board (width, height).
    ImageTooSmall(u32, u32),
    /// No chessboard grid was found at all.
    BoardNotFound,
    /// A grid was found, but not with `cols x rows` corners.
    WrongCornerCount {
        /// Corners the grid builder labelled.
        found: usize,
        /// `cols * rows` of the board description.
        expected: usize,
        /// The extent of the labels found, `(along the first detector axis, second)`.
        extent: (u32, u32),
    },
    /// The corners are there but do not form a consistent grid (the reason).
    InconsistentGrid(String),
    /// The board's orientation in the image cannot be told (the reason), for example a
    /// board seen rotated by about 90 degrees.
    AmbiguousOrientation(String),
    /// One image of a pair failed.
    InImage(Side, Box<DetectError>),
    /// The two images of a pair differ in size.
    SizeMismatch {
        /// Left image (width, height).
        left: (u32, u32),
        /// Right image (width, height).
        right: (u32, u32),
    },
    /// The left and right labellings disagree: a left -> right homography over the labels
    /// leaves a residual too large for one board.
    LabelMismatch {
        /// Largest residual (px).
        max_px: f64,
        /// The limit it exceeded (px).
        limit_px: f64,
        /// Label `(i, j)` with the largest residual.
        worst: (u32, u32),
    },
    /// A geometric fit failed.
    Geometry(GeomError),
}

impl core::fmt::Display for DetectError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            DetectError::ImageTooSmall(w, h) => {
                write!(f, "image {w}x{h} is too small to hold a board")
            }
            DetectError::BoardNotFound => f.write_str("board not found"),
            DetectError::WrongCornerCount {
                found,
                expected,
                extent,
            } => write!(
                f,
                "wrong corner count: found {found} labelled corners spanning {}x{}, the board has {expected}",
                extent.0, extent.1
            ),
            DetectError::InconsistentGrid(why) => write!(f, "inconsistent grid: {why}"),
            DetectError::AmbiguousOrientation(why) => {
                write!(f, "board orientation ambiguous: {why}")
            }
            DetectError::InImage(side, e) => write!(f, "{side} image: {e}"),
            DetectError::SizeMismatch { left, right } => write!(
                f,
                "image size mismatch: left {}x{}, right {}x{}",
                left.0, left.1, right.0, right.1
            ),
            DetectError::LabelMismatch {
                max_px,
                limit_px,
                worst,
            } => write!(
                f,
                "left and right labels disagree: corner ({}, {}) is {max_px:.2} px off the left -> right homography (limit {limit_px:.2} px)",
                worst.0, worst.1
            ),
            DetectError::Geometry(e) => write!(f, "geometry: {e}"),
        }
    }
}

impl std::error::Error for DetectError {}

impl From<GeomError> for DetectError {
    fn from(e: GeomError) -> Self {
        DetectError::Geometry(e)
    }
}

/// A labelled board in one image.
#[derive(Debug, Clone, PartialEq)]
pub struct Corners {
    /// The board that was looked for.
    pub board: Board,
    /// Image width (px).
    pub width: u32,
    /// Image height (px).
    pub height: u32,
    /// Corner positions `(u, v)` (px, pixel-centre convention), index `j * cols + i`.
    pub points: Vec<[f64; 2]>,
    /// RMS residual (px) of the homography fit board coordinates -> `points`.
    pub homography_rms: f64,
    /// Largest residual (px) of that fit.
    pub homography_max: f64,
    /// Median distance between neighbouring corners (px), the apparent square size.
    pub square_px: f64,
}

impl Corners {
    /// Position of corner `(i, j)`.
    pub fn at(&self, i: u32, j: u32) -> [f64; 2] {
        self.points[self.board.index(i, j)]
    }
}

/// A labelled board in both images of a stereo pair, labels checked to agree.
#[derive(Debug, Clone, PartialEq)]
pub struct StereoCorners {
    /// The left image's corners.
    pub left: Corners,
    /// The right image's corners.
    pub right: Corners,
    /// RMS residual (px) of the left -> right homography over all labels.
    pub lr_homography_rms: f64,
}

impl StereoCorners {
    /// `(left, right)` position pairs in label order, as [`geometry::fit_fundamental`] takes.
    pub fn pairs(&self) -> Vec<([f64; 2], [f64; 2])> {
        self.left
            .points
            .iter()
            .copied()
            .zip(self.right.points.iter().copied())
            .collect()
    }
}

/// The largest tolerated second difference along a row or column, as a fraction of the local
/// square size: lens distortion and perspective bend a row far less than this, a corner from
/// the wrong place does not.
const MAX_BEND: f64 = 0.3;
/// Neighbouring edges along one axis may differ in length by at most this factor.
const MAX_EDGE_RATIO: f64 = 1.8;
/// The board's `i` axis must be within this angle (degrees) of `+u`, `j` of `+v`.
const MAX_AXIS_ANGLE_DEG: f64 = 60.0;
/// Left -> right homography residual limit, as a fraction of the square size.
const LR_LIMIT_SQUARES: f64 = 0.25;

/// The corner front end: ChESS corners with the saddle-point refiner (a rejected refinement
/// keeps the centre-of-mass position).
pub fn corner_config() -> DetectorConfig {
    calib_targets::detect::default_chess_config()
        .with_refiner(ImageRefiner::SaddlePoint(
            chess_corners::SaddlePointConfig::default(),
        ))
        .with_chess(|c| c.on_refiner_reject = OnRefinerReject::KeepCenterOfMass)
}

/// Grey level of an RGB(A) or other image: `image`'s luma conversion (Rec. 709 weights).
pub fn to_grey(img: &DynamicImage) -> GrayImage {
    img.to_luma8()
}

/// Detect `board` in a decoded image of any colour type (converted to grey first).
pub fn detect_image(img: &DynamicImage, board: &Board) -> Result<Corners, DetectError> {
    detect(&to_grey(img), board)
}

/// Detect `board` in one grey image: exactly `cols x rows` corners, labelled, sub-pixel.
pub fn detect(img: &GrayImage, board: &Board) -> Result<Corners, DetectError> {
    let (w, h) = img.dimensions();
    if w < 16 || h < 16 {
        return Err(DetectError::ImageTooSmall(w, h));
    }
    let frame = calib_targets::chessboard::detect_corner_frame(
        &calib_targets::detect::gray_view(img),
        &corner_config(),
    );
    let mut params = ChessboardParams::default();
    params.min_labeled_corners = board.corner_count().min(8);
    let detector = ChessboardDetector::new(params)
        .map_err(|e| DetectError::InconsistentGrid(format!("detector parameters: {e}")))?;
    let det = detector
        .detect(&frame.corners)
        .ok_or(DetectError::BoardNotFound)?;
    let labelled: Vec<((i32, i32), [f64; 2])> = det
        .corners
        .iter()
        .map(|c| {
            (
                (c.grid.u, c.grid.v),
                [c.position.x as f64, c.position.y as f64],
            )
        })
        .collect();
    label_grid(&labelled, board, w, h)
}

/// Turn the detector's labelled corners into this crate's labelling, validating the grid.
/// `labelled` holds `((a, b), (u, v))`: the detector's own grid coordinates, which may start
/// anywhere, run in either direction and be transposed.
pub fn label_grid(
    labelled: &[((i32, i32), [f64; 2])],
    board: &Board,
    width: u32,
    height: u32,
) -> Result<Corners, DetectError> {
    let expected = board.corner_count();
    if labelled.is_empty() {
        return Err(DetectError::BoardNotFound);
    }
    let (mut a0, mut a1, mut b0, mut b1) = (i32::MAX, i32::MIN, i32::MAX, i32::MIN);
    for ((a, b), p) in labelled {
        if !(p[0].is_finite() && p[1].is_finite()) {
            return Err(DetectError::InconsistentGrid(
                "a corner has a non-finite position".into(),
            ));
        }
        a0 = a0.min(*a);
        a1 = a1.max(*a);
        b0 = b0.min(*b);
        b1 = b1.max(*b);
    }
    let na = (a1 as i64 - a0 as i64 + 1) as u64;
    let nb = (b1 as i64 - b0 as i64 + 1) as u64;
    let extent = (
        na.min(u32::MAX as u64) as u32,
        nb.min(u32::MAX as u64) as u32,
    );
    let (cols, rows) = (board.cols as u64, board.rows as u64);
    let fits = (na == cols && nb == rows) || (na == rows && nb == cols);
    if labelled.len() != expected || !fits {
        return Err(DetectError::WrongCornerCount {
            found: labelled.len(),
            expected,
            extent,
        });
    }
    let (na, nb) = (na as usize, nb as usize);
    let mut grid: Vec<Option<[f64; 2]>> = vec![None; na * nb];
    for ((a, b), p) in labelled {
        let k = (b - b0) as usize * na + (a - a0) as usize;
        if grid[k].replace(*p).is_some() {
            return Err(DetectError::InconsistentGrid(format!(
                "two corners share the detector label ({a}, {b})"
            )));
        }
    }
    let g = |a: usize, b: usize| grid[b * na + a].expect("complete grid checked above");
    // Mean direction of each detector axis in the image.
    let mut da = [0.0f64; 2];
    let mut db = [0.0f64; 2];
    for b in 0..nb {
        for a in 0..na {
            if a + 1 < na {
                let (p, q) = (g(a, b), g(a + 1, b));
                da[0] += q[0] - p[0];
                da[1] += q[1] - p[1];
            }
            if b + 1 < nb {
                let (p, q) = (g(a, b), g(a, b + 1));
                db[0] += q[0] - p[0];
                db[1] += q[1] - p[1];
            }
        }
    }
    // Which detector axis is the board's i axis: the one with `cols` corners; on a square
    // board, the one nearer the image's u axis.
    let a_is_i = if cols != rows {
        na as u64 == cols
    } else {
        da[0].abs() / norm(da) >= db[0].abs() / norm(db)
    };
    let (di, dj) = if a_is_i { (da, db) } else { (db, da) };
    let flip_i = di[0] < 0.0;
    let flip_j = dj[1] < 0.0;
    let di = if flip_i { [-di[0], -di[1]] } else { di };
    let dj = if flip_j { [-dj[0], -dj[1]] } else { dj };
    let ang_i = (di[1].abs()).atan2(di[0]).to_degrees();
    let ang_j = (dj[0].abs()).atan2(dj[1]).to_degrees();
    if !(ang_i <= MAX_AXIS_ANGLE_DEG && ang_j <= MAX_AXIS_ANGLE_DEG) {
        return Err(DetectError::AmbiguousOrientation(format!(
            "the board's i axis is {ang_i:.0} degrees from +u and its j axis {ang_j:.0} degrees from +v (limit {MAX_AXIS_ANGLE_DEG:.0}): rows and columns cannot be told apart"
        )));
    }
    let (bc, br) = (board.cols as usize, board.rows as usize);
    let mut points = Vec::with_capacity(expected);
    for j in 0..br {
        for i in 0..bc {
            let ii = if flip_i { bc - 1 - i } else { i };
            let jj = if flip_j { br - 1 - j } else { j };
            let (a, b) = if a_is_i { (ii, jj) } else { (jj, ii) };
            points.push(g(a, b));
        }
    }
    let square_px = check_geometry(&points, bc, br)?;
    let pairs: Vec<([f64; 2], [f64; 2])> = (0..expected)
        .map(|k| {
            let (i, j) = board.label(k);
            (board.corner_offset(i, j), points[k])
        })
        .collect();
    let fit = geometry::fit_homography(&pairs)?;
    Ok(Corners {
        board: *board,
        width,
        height,
        points,
        homography_rms: fit.rms,
        homography_max: fit.max,
        square_px,
    })
}

fn norm(v: [f64; 2]) -> f64 {
    (v[0] * v[0] + v[1] * v[1]).sqrt().max(1e-300)
}

fn sub(a: [f64; 2], b: [f64; 2]) -> [f64; 2] {
    [a[0] - b[0], a[1] - b[1]]
}

/// Check the relabelled grid: every edge along `i` points the same way as the mean `i`
/// direction (likewise `j`), neighbouring edges have similar lengths, rows and columns bend
/// little, and every cell has the same handedness. Returns the median edge length.
fn check_geometry(p: &[[f64; 2]], cols: usize, rows: usize) -> Result<f64, DetectError> {
    let at = |i: usize, j: usize| p[j * cols + i];
    let mut edges = Vec::new();
    for j in 0..rows {
        for i in 0..cols {
            if i + 1 < cols {
                edges.push(norm(sub(at(i + 1, j), at(i, j))));
            }
            if j + 1 < rows {
                edges.push(norm(sub(at(i, j + 1), at(i, j))));
            }
        }
    }
    edges.sort_by(f64::total_cmp);
    let median = edges[edges.len() / 2];
    if median < 2.0 {
        return Err(DetectError::InconsistentGrid(format!(
            "squares of {median:.2} px are too small"
        )));
    }
    // Along each row (axis 0) and column (axis 1).
    for axis in 0..2 {
        let (n_lines, n_along) = if axis == 0 {
            (rows, cols)
        } else {
            (cols, rows)
        };
        let pt = |line: usize, k: usize| if axis == 0 { at(k, line) } else { at(line, k) };
        let name = if axis == 0 { "row j" } else { "column i" };
        for line in 0..n_lines {
            for k in 0..n_along - 1 {
                let e = sub(pt(line, k + 1), pt(line, k));
                let good = if axis == 0 { e[0] > 0.0 } else { e[1] > 0.0 };
                if !good {
                    return Err(DetectError::InconsistentGrid(format!(
                        "{name} = {line}: corner {} is not after corner {k} (the grid folds)",
                        k + 1
                    )));
                }
                if k + 2 < n_along {
                    let f = sub(pt(line, k + 2), pt(line, k + 1));
                    let (le, lf) = (norm(e), norm(f));
                    let ratio = le.max(lf) / le.min(lf);
                    if ratio > MAX_EDGE_RATIO {
                        return Err(DetectError::InconsistentGrid(format!(
                            "{name} = {line}: neighbouring spacings {le:.1} px and {lf:.1} px differ by {ratio:.2}x around corner {}",
                            k + 1
                        )));
                    }
                    let bend = norm(sub(f, e)) / (0.5 * (le + lf));
                    if bend > MAX_BEND {
                        return Err(DetectError::InconsistentGrid(format!(
                            "{name} = {line}: the line bends by {bend:.2} squares at corner {}",
                            k + 1
                        )));
                    }
                }
            }
        }
    }
    let mut sign = 0.0f64;
    for j in 0..rows - 1 {
        for i in 0..cols - 1 {
            let e = sub(at(i + 1, j), at(i, j));
            let f = sub(at(i, j + 1), at(i, j));
            let c = e[0] * f[1] - e[1] * f[0];
            if sign == 0.0 {
                sign = c.signum();
            } else if c.signum() != sign || c == 0.0 {
                return Err(DetectError::InconsistentGrid(format!(
                    "cell ({i}, {j}) is mirrored relative to the others"
                )));
            }
        }
    }
    Ok(median)
}

/// Detect `board` in both images of a pair and check that the labels agree.
pub fn detect_pair(
    left: &GrayImage,
    right: &GrayImage,
    board: &Board,
) -> Result<StereoCorners, DetectError> {
    if left.dimensions() != right.dimensions() {
        return Err(DetectError::SizeMismatch {
            left: left.dimensions(),
            right: right.dimensions(),
        });
    }
    let l = detect(left, board).map_err(|e| DetectError::InImage(Side::Left, Box::new(e)))?;
    let r = detect(right, board).map_err(|e| DetectError::InImage(Side::Right, Box::new(e)))?;
    pair_corners(l, r)
}

/// Check two single-image detections of the same board as a stereo pair.
pub fn pair_corners(left: Corners, right: Corners) -> Result<StereoCorners, DetectError> {
    if (left.width, left.height) != (right.width, right.height) {
        return Err(DetectError::SizeMismatch {
            left: (left.width, left.height),
            right: (right.width, right.height),
        });
    }
    if left.board != right.board || left.points.len() != right.points.len() {
        return Err(DetectError::InconsistentGrid(
            "left and right detections are of different boards".into(),
        ));
    }
    let pairs: Vec<([f64; 2], [f64; 2])> = left
        .points
        .iter()
        .copied()
        .zip(right.points.iter().copied())
        .collect();
    let fit: HomographyFit = geometry::fit_homography(&pairs)?;
    let limit = LR_LIMIT_SQUARES * left.square_px.min(right.square_px);
    let mut worst = (0usize, 0.0f64);
    for (k, (l, r)) in pairs.iter().enumerate() {
        let p = fit.h.apply(*l).unwrap_or([f64::INFINITY; 2]);
        let d = norm(sub(p, *r));
        if d.is_nan() || d > worst.1 {
            worst = (k, if d.is_nan() { f64::INFINITY } else { d });
        }
    }
    if worst.1 > limit {
        return Err(DetectError::LabelMismatch {
            max_px: worst.1,
            limit_px: limit,
            worst: left.board.label(worst.0),
        });
    }
    Ok(StereoCorners {
        left,
        right,
        lr_homography_rms: fit.rms,
    })
}

/// One fundamental matrix over a whole capture set, with each pair's residuals.
#[derive(Debug, Clone, PartialEq)]
pub struct SetCheck {
    /// The fit over every corner of every pair.
    pub fit: FundamentalFit,
    /// Per pair: median distance (px) of right corners from their epipolar lines.
    pub pair_median_px: Vec<f64>,
    /// Per pair: largest such distance (px).
    pub pair_max_px: Vec<f64>,
}

impl SetCheck {
    /// The fitted fundamental matrix.
    pub fn fundamental(&self) -> &Fundamental {
        &self.fit.f
    }
}

/// Fit one fundamental matrix over all corners of `pairs` and report each pair's residual: a
/// pair whose labels are shifted or flipped stands out by whole squares. The set needs at
/// least two board poses (one plane does not determine `F`).
pub fn check_set(pairs: &[StereoCorners]) -> Result<SetCheck, DetectError> {
    let all: Vec<([f64; 2], [f64; 2])> = pairs.iter().flat_map(|p| p.pairs()).collect();
    let fit = geometry::fit_fundamental_report(&all)?;
    let mut pair_median_px = Vec::new();
    let mut pair_max_px = Vec::new();
    for p in pairs {
        let mut d: Vec<f64> = p
            .pairs()
            .iter()
            .map(|(l, r)| fit.f.distance_in_right(*l, *r))
            .collect();
        d.sort_by(f64::total_cmp);
        pair_median_px.push(d[d.len() / 2]);
        pair_max_px.push(*d.last().unwrap_or(&0.0));
    }
    Ok(SetCheck {
        fit,
        pair_median_px,
        pair_max_px,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn synthetic(board: &Board) -> Vec<((i32, i32), [f64; 2])> {
        // A slightly rotated, perspective-free grid of 20 px squares, labelled like the detector
        // might: transposed, starting at (-3, 5), running right-to-left.
        let mut out = Vec::new();
        for j in 0..board.rows {
            for i in 0..board.cols {
                let (x, y) = (i as f64 * 20.0, j as f64 * 20.0);
                let p = [100.0 + x * 0.99 - y * 0.1, 80.0 + x * 0.1 + y * 0.99];
                out.push(((5 + j as i32, -3 - i as i32), p));
            }
        }
        out
    }

    #[test]
    fn relabels_any_detector_labelling_to_top_left_origin() {
        let board = Board::new(9, 6, 6.0).unwrap();
        let c = label_grid(&synthetic(&board), &board, 640, 480).unwrap();
        assert_eq!(c.points.len(), 54);
        let p00 = c.at(0, 0);
        assert!((p00[0] - 100.0).abs() < 1e-12 && (p00[1] - 80.0).abs() < 1e-12);
        assert!(c.at(1, 0)[0] > p00[0] && c.at(0, 1)[1] > p00[1]);
        assert!(c.homography_rms < 1e-9);
        assert!((c.square_px - 20.0).abs() < 0.5);
    }

    #[test]
    fn refuses_extra_missing_and_duplicate_corners() {
        let board = Board::new(9, 6, 6.0).unwrap();
        let mut extra = synthetic(&board);
        extra.push(((11, -3), [90.0, 60.0]));
        assert!(matches!(
            label_grid(&extra, &board, 640, 480),
            Err(DetectError::WrongCornerCount { found: 55, .. })
        ));
        let mut missing_row = synthetic(&board);
        missing_row.retain(|((a, _), _)| *a != 5);
        assert!(matches!(
            label_grid(&missing_row, &board, 640, 480),
            Err(DetectError::WrongCornerCount { found: 45, .. })
        ));
        // 54 corners, but one moved to a label outside the range: the extent is wrong.
        let mut shifted = synthetic(&board);
        shifted[0].0 = (20, 20);
        assert!(matches!(
            label_grid(&shifted, &board, 640, 480),
            Err(DetectError::WrongCornerCount { found: 54, .. })
        ));
        let mut dup = synthetic(&board);
        dup[1].0 = dup[0].0;
        assert!(matches!(
            label_grid(&dup, &board, 640, 480),
            Err(DetectError::InconsistentGrid(_))
        ));
    }

    #[test]
    fn refuses_a_corner_in_the_wrong_place_and_a_90_degree_board() {
        let board = Board::new(9, 6, 6.0).unwrap();
        let mut moved = synthetic(&board);
        moved[20].1[0] += 12.0;
        let e = label_grid(&moved, &board, 640, 480).unwrap_err();
        assert!(matches!(e, DetectError::InconsistentGrid(_)), "{e}");
        // Rotate the whole grid by 90 degrees: cols now run down the image.
        let rot: Vec<_> = synthetic(&board)
            .into_iter()
            .map(|(l, p)| (l, [400.0 - p[1], p[0]]))
            .collect();
        let e = label_grid(&rot, &board, 640, 480).unwrap_err();
        assert!(matches!(e, DetectError::AmbiguousOrientation(_)), "{e}");
    }

    #[test]
    fn pair_check_catches_shifted_labels() {
        let board = Board::new(9, 6, 6.0).unwrap();
        let l = label_grid(&synthetic(&board), &board, 640, 480).unwrap();
        let mut r = l.clone();
        for p in r.points.iter_mut() {
            p[0] -= 30.0;
        }
        assert!(pair_corners(l.clone(), r.clone()).is_ok());
        // Swap two labels in the right image.
        r.points.swap(3, 4);
        let e = pair_corners(l.clone(), r).unwrap_err();
        assert!(matches!(e, DetectError::LabelMismatch { .. }), "{e}");
        let mut small = l.clone();
        small.width = 320;
        assert!(matches!(
            pair_corners(l, small),
            Err(DetectError::SizeMismatch { .. })
        ));
    }
}
