//! Stereo images of a chessboard through the simulator's camera model, with exact corner truth.
//!
//! # Scene
//!
//! A planar chessboard with `cols x rows` **inner corners** (so `(cols + 1) x (rows + 1)`
//! squares of `square_cm`; a [`crate::board::Board`]) and a white border
//! [`RenderOptions::margin_cm`] wide around the squares stands
//! upright, perpendicular to the head frame's `Z` axis, its centre at `(x, y, z)` cm (head
//! frame: `X` right, `Y` down, `Z` forward). Everything off the board is a uniform background
//! grey.
//!
//! # Labels and polarity
//!
//! Inner corner `(i, j)`, `i` in `0..cols`, `j` in `0..rows`, lies at
//! `X = x + (i - (cols - 1) / 2) square`, `Y = y + (j - (rows - 1) / 2) square`, `Z = z`:
//! `(0, 0)` is the top-left inner corner as the cameras see it, `i` grows to the right
//! (`+X`, `+u`), `j` downwards (`+Y`, `+v`). Square `(a, b)` (`a` in `0..=cols`, `b` in
//! `0..=rows`, from the top-left square) is **black when `a + b` is even**: the square up and
//! to the left of corner `(0, 0)`, the board's top-left square, is black, and so is the square
//! up-left of every corner with `i + j` even.
//!
//! # Cameras and pixels
//!
//! The cameras are those of `hvs simulate`: a [`HeadRig`] (a thesis [`Rig`] on the five-axis
//! head, with a radial lens per camera) at a posture [`Joints`]. At [`Joints::HOME`] without
//! lenses they are exactly [`Rig::left`] / [`Rig::right`], and the truth is exactly
//! [`Rig::project`].
//!
//! **Pixel convention:** image coordinates are the camera model's continuous, unrounded
//! `(u, v)`, with integer values at pixel **centres**: pixel `(c, r)` (column `c`, row `r` of
//! the [`GrayImage`]) covers `u` in `[c - 0.5, c + 0.5)` and `v` in `[r - 0.5, r + 0.5)`.
//! A point the model projects to `(u, v)` is seen at `(u, v)` in the image's pixel grid.
//!
//! # Rendering
//!
//! Inverse mapping: each output sample's viewing ray ([`LensCamera::ray`], which undoes the
//! lens) is intersected with the board plane and the board's colour is looked up. The
//! colour class (black, white, background) is evaluated at every pixel **corner**; a pixel
//! whose four corners agree is filled with that class, the others (edge pixels, a few
//! percent) are supersampled with `n x n` samples on a sheared grid (each sample with its
//! own `u` and `v` offset, so axis-aligned edges are resolved to `1/n^2` px). This is exact for every feature larger than
//! one pixel, which squares of a few pixels are. Then an optional Gaussian blur (`sigma` px,
//! separable, edges clamped) models the optics, additive Gaussian sensor noise (grey levels,
//! one seeded ChaCha8 stream per image pair, as `hvs simulate` draws its noise) models the
//! sensor, and the result is rounded and clamped to 8 bits.

use crate::invalid::{finite_in, in_range, InvalidField};
use hvs_shared::runtime::gaze::Joints;
use hvs_shared::sim::camera::LensCamera;
use hvs_shared::sim::camera::{CameraError, Rig, StereoPixels, Vec3};
use hvs_shared::sim::posture::HeadRig;
use hvs_shared::sim::presets;
use image::GrayImage;
use rand::{RngExt, SeedableRng};
use rand_distr::{Distribution, StandardNormal};
use std::fmt;

/// Why a render was refused.
#[derive(Debug, Clone, PartialEq)]
pub enum RenderError {
    /// A parameter is out of its range; names the field.
    Invalid(InvalidField),
    /// The board centre has no image (behind a camera or not finite).
    Camera(CameraError),
}

impl fmt::Display for RenderError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            RenderError::Invalid(e) => e.fmt(f),
            RenderError::Camera(e) => write!(f, "board centre: {e}"),
        }
    }
}

impl std::error::Error for RenderError {}

impl From<InvalidField> for RenderError {
    fn from(e: InvalidField) -> Self {
        RenderError::Invalid(e)
    }
}

fn invalid(field: &'static str, reason: impl Into<String>) -> RenderError {
    InvalidField::new(field, reason).into()
}

/// The chessboard: [`crate::board::Board`] (what `BOARD.json` describes: inner corners and
/// square size; the white border is a render option, [`RenderOptions::margin_cm`]).
pub use crate::board::Board;

/// 9 x 6 inner corners of 6 cm (OpenCV's sample board), the board the tests render.
pub fn opencv_board() -> Board {
    Board::new(9, 6, 6.0).expect("a valid board")
}

/// Colour class of a board point.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Class {
    Black,
    White,
    Background,
}

/// Checks `board` for rendering (field names in the error; the fields of [`Board`] are
/// public, so a board need not have come through [`Board::new`]).
fn validate_board(board: &Board) -> Result<(), RenderError> {
    in_range("board.cols", board.cols, 1, 1000)?;
    in_range("board.rows", board.rows, 1, 1000)?;
    if !(board.square_cm.is_finite() && board.square_cm > 0.0) {
        return Err(invalid(
            "board.square_cm",
            format!("must be a finite number > 0, got {}", board.square_cm),
        ));
    }
    Ok(())
}

/// Checks the border width `margin_cm` against `board`'s squares.
fn validate_margin(board: &Board, margin_cm: f64) -> Result<(), RenderError> {
    if !(margin_cm.is_finite() && margin_cm >= board.square_cm) {
        return Err(invalid(
            "margin_cm",
            format!(
                "must be finite and at least one square ({} cm), got {margin_cm}",
                board.square_cm
            ),
        ));
    }
    Ok(())
}

/// Colour of the point of `board` (white border `margin_cm` wide) at offset `(bx, by)` from
/// its centre.
pub(crate) fn class(board: &Board, margin_cm: f64, bx: f64, by: f64) -> Class {
    let hx = (f64::from(board.cols) + 1.0) * 0.5 * board.square_cm;
    let hy = (f64::from(board.rows) + 1.0) * 0.5 * board.square_cm;
    let fx = bx + hx;
    let fy = by + hy;
    let (wx, wy) = (2.0 * hx, 2.0 * hy);
    if fx >= 0.0 && fx < wx && fy >= 0.0 && fy < wy {
        let a = (fx / board.square_cm) as i64;
        let b = (fy / board.square_cm) as i64;
        return if (a + b) % 2 == 0 { Class::Black } else { Class::White };
    }
    let m = margin_cm;
    if fx >= -m && fx < wx + m && fy >= -m && fy < wy + m {
        Class::White
    } else {
        Class::Background
    }
}

/// How the images are made.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RenderOptions {
    /// Supersampling of edge pixels: `n x n` samples (1..=16).
    pub supersample: u32,
    /// Standard deviation of the Gaussian blur (px, 0 = none, at most 10).
    pub blur_sigma_px: f64,
    /// Standard deviation of the additive sensor noise (grey levels, 0 = none, at most 100).
    pub noise_sigma: f64,
    /// Grey level of the black squares.
    pub black: u8,
    /// Grey level of the white squares and border.
    pub white: u8,
    /// Grey level off the board.
    pub background: u8,
    /// Width of the white border around the squares (cm, at least one square).
    pub margin_cm: f64,
}

impl Default for RenderOptions {
    /// 8 x 8 samples on edges, blur 0.8 px, noise 2 grey levels, black 30, white 220,
    /// background 110, a 6 cm border (one square of [`opencv_board`]).
    fn default() -> Self {
        RenderOptions {
            supersample: 8,
            blur_sigma_px: 0.8,
            noise_sigma: 2.0,
            black: 30,
            white: 220,
            background: 110,
            margin_cm: 6.0,
        }
    }
}

impl RenderOptions {
    /// Noise-free, blur-free images (for exact geometric checks).
    pub fn clean() -> Self {
        RenderOptions { blur_sigma_px: 0.0, noise_sigma: 0.0, ..RenderOptions::default() }
    }

    /// Checks the parameters (field names in the error).
    pub fn validate(&self) -> Result<(), RenderError> {
        in_range("supersample", self.supersample, 1, 16)?;
        finite_in("blur_sigma_px", self.blur_sigma_px, 0.0, 10.0)?;
        finite_in("noise_sigma", self.noise_sigma, 0.0, 100.0)?;
        Ok(())
    }

    fn level(&self, c: Class) -> f32 {
        f32::from(match c {
            Class::Black => self.black,
            Class::White => self.white,
            Class::Background => self.background,
        })
    }
}

/// The exact image of one inner corner.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CornerTruth {
    /// Column label (grows with `X` and `u`).
    pub i: u32,
    /// Row label (grows with `Y` and `v`).
    pub j: u32,
    /// Position in the head frame (cm).
    pub xyz: Vec3,
    /// Unrounded `[u_l, v_l, u_r, v_r]` (px, pixel-centre convention of this module).
    pub px: StereoPixels,
    /// Whether both projections fall inside the images ([`Rig::in_image`]).
    pub in_image: bool,
}

/// One rendered stereo pair and its truth.
#[derive(Debug, Clone, PartialEq)]
pub struct StereoRender {
    /// Left image.
    pub left: GrayImage,
    /// Right image.
    pub right: GrayImage,
    /// Every inner corner, `j` outer, `i` inner (row by row from the top-left).
    pub corners: Vec<CornerTruth>,
}

/// The truth of every inner corner of `board` centred at `centre`, through `head` at
/// `joints` ([`HeadRig::project`]; at home without lenses exactly [`Rig::project`]).
pub fn corner_truth(
    head: &HeadRig,
    joints: &Joints,
    board: &Board,
    centre: Vec3,
) -> Result<Vec<CornerTruth>, RenderError> {
    validate_board(board)?;
    let mut out = Vec::with_capacity((board.cols * board.rows) as usize);
    for j in 0..board.rows {
        for i in 0..board.cols {
            let [dx, dy] = board.corner_offset(i, j);
            let xyz = [centre[0] + dx, centre[1] + dy, centre[2]];
            let px = head.project(joints, &xyz).map_err(RenderError::Camera)?;
            out.push(CornerTruth { i, j, xyz, px, in_image: head.rig.in_image(&px) });
        }
    }
    Ok(out)
}

/// Renders the pair of `board` centred at `centre` (cm) through `head` at `joints`. The
/// sensor noise comes from a ChaCha8 stream seeded with `seed` (left image first, raster
/// order): the same arguments give the same bytes.
pub fn render_pair(
    head: &HeadRig,
    joints: &Joints,
    board: &Board,
    centre: Vec3,
    opt: &RenderOptions,
    seed: u64,
) -> Result<StereoRender, RenderError> {
    validate_board(board)?;
    opt.validate()?;
    validate_margin(board, opt.margin_cm)?;
    if !centre.iter().all(|c| c.is_finite()) {
        return Err(invalid("centre", format!("must be finite, got {centre:?}")));
    }
    let (w, h) = (head.rig.width, head.rig.height);
    if w == 0 || h == 0 || u64::from(w) * u64::from(h) > crate::image_file::MAX_PIXELS {
        return Err(invalid(
            "rig.width/height",
            format!(
                "the image must have from 1 to {} pixels (the limit of every image input), got {w}x{h}",
                crate::image_file::MAX_PIXELS
            ),
        ));
    }
    if !head.distortion.iter().all(|d| d.is_finite()) {
        return Err(invalid("distortion", "k1 and k2 must be finite"));
    }
    let corners = corner_truth(head, joints, board, centre)?;
    let cams = head.cameras(joints);
    let mut rng = rand::rngs::ChaCha8Rng::seed_from_u64(seed);
    let mut imgs = cams.iter().map(|cam| {
        let mut buf = shade(cam, board, centre, opt, w, h);
        if opt.blur_sigma_px > 0.0 {
            blur(&mut buf, w as usize, h as usize, opt.blur_sigma_px);
        }
        quantise(&buf, w, h, opt.noise_sigma, &mut rng)
    });
    let left = imgs.next().expect("two cameras");
    let right = imgs.next().expect("two cameras");
    Ok(StereoRender { left, right, corners })
}

/// [`render_pair`] through a thesis rig at home without lenses (the cameras of
/// `hvs simulate --case N`).
pub fn render_rig(
    rig: &Rig,
    board: &Board,
    centre: Vec3,
    opt: &RenderOptions,
    seed: u64,
) -> Result<StereoRender, RenderError> {
    render_pair(&HeadRig::new(*rig), &Joints::HOME, board, centre, opt, seed)
}

/// The board's colour class seen along the ray of pixel coordinate `(u, v)`.
fn sample(cam: &LensCamera, board: &Board, margin_cm: f64, centre: &Vec3, u: f64, v: f64) -> Class {
    let Some((o, d)) = cam.ray(u, v) else {
        return Class::Background;
    };
    sample_ray(board, margin_cm, centre, &o, &d)
}

/// The board's colour class seen along the ray from `o` along `d`.
#[inline(always)]
fn sample_ray(board: &Board, margin_cm: f64, centre: &Vec3, o: &Vec3, d: &Vec3) -> Class {
    if d[2].is_nan() || d[2] <= 0.0 {
        return Class::Background;
    }
    let t = (centre[2] - o[2]) / d[2];
    if t.is_nan() || t <= 0.0 {
        return Class::Background;
    }
    let x = o[0] + t * d[0] - centre[0];
    let y = o[1] + t * d[1] - centre[1];
    if !(x.is_finite() && y.is_finite()) {
        return Class::Background;
    }
    class(board, margin_cm, x, y)
}

/// Noise-free, blur-free grey levels of one camera, row-major `f32`.
fn shade(
    cam: &LensCamera,
    board: &Board,
    centre: Vec3,
    opt: &RenderOptions,
    w: u32,
    h: u32,
) -> Vec<f32> {
    let (wu, hu) = (w as usize, h as usize);
    // Classes at the pixel corners (c - 0.5, r - 0.5), (w + 1) x (h + 1).
    let mut corner = Vec::with_capacity((wu + 1) * (hu + 1));
    let grid = RayGrid::new(cam, wu + 1, hu + 1, -0.5, -0.5);
    for r in 0..=hu {
        let v = r as f64 - 0.5;
        for c in 0..=wu {
            corner.push(match &grid {
                Some(g) => {
                    let (o, d) = g.ray(c, r);
                    sample_ray(board, opt.margin_cm, &centre, &o, &d)
                }
                None => sample(cam, board, opt.margin_cm, &centre, c as f64 - 0.5, v),
            });
        }
    }
    let n = opt.supersample as usize;
    let mut out = Vec::with_capacity(wu * hu);
    for r in 0..hu {
        for c in 0..wu {
            let k = r * (wu + 1) + c;
            let q = [corner[k], corner[k + 1], corner[k + wu + 1], corner[k + wu + 2]];
            if q.iter().all(|&x| x == q[0]) {
                out.push(opt.level(q[0]));
                continue;
            }
            out.push(supersample(c, r, n, |u, v| {
                opt.level(sample(cam, board, opt.margin_cm, &centre, u, v))
            }));
        }
    }
    out
}

/// The mean grey of pixel `(c, r)` over a sheared `n` x `n` grid of samples (`grey(u, v)`):
/// every sample has its own u and its own v (n^2 distinct offsets on each axis), so an edge
/// along either axis is resolved to 1/n^2 px.
pub(crate) fn supersample(
    c: usize,
    r: usize,
    n: usize,
    mut grey: impl FnMut(f64, f64) -> f32,
) -> f32 {
    let inv = 1.0 / n as f64;
    let mut sum = 0.0f32;
    for sy in 0..n {
        for sx in 0..n {
            let u = c as f64 - 0.5 + (sx as f64 + (sy as f64 + 0.5) * inv) * inv;
            let v = r as f64 - 0.5 + (sy as f64 + (sx as f64 + 0.5) * inv) * inv;
            sum += grey(u, v);
        }
    }
    sum / (n * n) as f32
}

/// Separable Gaussian blur in place (radius `ceil(3 sigma)`, edges clamped).
pub(crate) fn blur(buf: &mut [f32], w: usize, h: usize, sigma: f64) {
    let radius = libm::ceil(3.0 * sigma).max(1.0) as usize;
    let mut k: Vec<f32> = (0..=2 * radius)
        .map(|t| {
            let x = t as f64 - radius as f64;
            libm::exp(-x * x / (2.0 * sigma * sigma)) as f32
        })
        .collect();
    let s: f32 = k.iter().sum();
    k.iter_mut().for_each(|x| *x /= s);
    let mut tmp = vec![0.0f32; buf.len()];
    let clamp = |x: isize, n: usize| x.clamp(0, n as isize - 1) as usize;
    // Every output is the same sum as ever (taps in order from 0.0); only the clamping of the
    // index is skipped inside the row and the vertical pass runs along rows.
    for r in 0..h {
        let row = &buf[r * w..(r + 1) * w];
        let out = &mut tmp[r * w..(r + 1) * w];
        for (c, o) in out.iter_mut().enumerate() {
            let mut acc = 0.0;
            if c >= radius && c + radius < w {
                for (kt, x) in k.iter().zip(&row[c - radius..=c + radius]) {
                    acc += kt * x;
                }
            } else {
                for (t, kt) in k.iter().enumerate() {
                    acc += kt * row[clamp(c as isize + t as isize - radius as isize, w)];
                }
            }
            *o = acc;
        }
    }
    for r in 0..h {
        let out = &mut buf[r * w..(r + 1) * w];
        out.fill(0.0);
        for (t, kt) in k.iter().enumerate() {
            let src = clamp(r as isize + t as isize - radius as isize, h) * w;
            for (o, x) in out.iter_mut().zip(&tmp[src..src + w]) {
                *o += kt * x;
            }
        }
    }
}

/// Adds the sensor noise, rounds half away from zero and clamps to 0..=255.
pub(crate) fn quantise(
    buf: &[f32],
    w: u32,
    h: u32,
    noise: f64,
    rng: &mut rand::rngs::ChaCha8Rng,
) -> GrayImage {
    let data = buf
        .iter()
        .map(|&x| {
            let mut x = f64::from(x);
            if noise > 0.0 {
                let n: f64 = StandardNormal.sample(rng);
                x += n * noise;
            }
            libm::round(x).clamp(0.0, 255.0) as u8
        })
        .collect();
    GrayImage::from_raw(w, h, data).expect("buffer has w * h pixels")
}

/// The image file names of pair `k` (from 0) of a capture set: `leftNN.png`, `rightNN.png`
/// (NN from 01).
pub fn capture_names(k: usize) -> [String; 2] {
    [format!("left{:02}.png", k + 1), format!("right{:02}.png", k + 1)]
}

/// One pair of a capture set.
#[derive(Debug, Clone, PartialEq)]
pub struct Capture {
    /// File name of the left image (`left01.png`, ...).
    pub left_name: String,
    /// File name of the right image.
    pub right_name: String,
    /// Board centre (cm).
    pub centre: Vec3,
    /// The images and corner truth.
    pub render: StereoRender,
}

/// One corner of one capture: a row of `truth.csv`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TruthRow {
    /// Index of the capture in [`RenderedSet::captures`].
    pub capture: usize,
    /// The corner.
    pub corner: CornerTruth,
}

/// A set of rendered captures in memory: images, the captures table and the truth rows
/// (written out as a capture set by `hvs render`; read back as `hvs_host::data::captures`).
#[derive(Debug, Clone, PartialEq)]
pub struct RenderedSet {
    /// The board every capture shows.
    pub board: Board,
    /// The pairs, in order of depth as given.
    pub captures: Vec<Capture>,
}

impl RenderedSet {
    /// Every corner of every capture, capture by capture.
    pub fn truth_rows(&self) -> Vec<TruthRow> {
        self.captures
            .iter()
            .enumerate()
            .flat_map(|(k, c)| {
                c.render.corners.iter().map(move |&corner| TruthRow { capture: k, corner })
            })
            .collect()
    }

    /// `board.json` of the board the set shows (what `hvs board detect --board` reads).
    pub fn board_json(&self) -> String {
        self.board.to_json()
    }

    /// The truth table: `left,i,j,x,y,z,u_l,v_l,u_r,v_r,in_image`, the pixels unrounded
    /// (shortest round-trip decimal form) in this module's pixel-centre convention.
    pub fn truth_csv(&self) -> String {
        let mut s = String::from("left,i,j,x,y,z,u_l,v_l,u_r,v_r,in_image\n");
        for row in self.truth_rows() {
            let c = &row.corner;
            s.push_str(&format!(
                "{},{},{},{},{},{},{},{},{},{},{}\n",
                self.captures[row.capture].left_name,
                c.i,
                c.j,
                c.xyz[0],
                c.xyz[1],
                c.xyz[2],
                c.px[0],
                c.px[1],
                c.px[2],
                c.px[3],
                c.in_image
            ));
        }
        s
    }
}

/// Most depths (pairs) of one capture set: its images are numbered with two digits.
pub const MAX_DEPTHS: usize = 99;

/// Checks the board depths of [`render_capture_set`] (cm): 1 to [`MAX_DEPTHS`] of them, each
/// > 0 and within the one bound of every length ([`crate::invalid::MAX_CM`]).
pub fn check_depths(depths: &[f64]) -> Result<(), RenderError> {
    if depths.is_empty() || depths.len() > MAX_DEPTHS {
        return Err(invalid(
            "depths",
            format!("need 1..={MAX_DEPTHS} depths, got {}", depths.len()),
        ));
    }
    let most = crate::invalid::MAX_CM;
    if let Some(z) = depths.iter().find(|z| !(z.is_finite() && **z > 0.0 && **z <= most)) {
        return Err(invalid("depths", format!("must be > 0 and at most {most}, got {z}")));
    }
    Ok(())
}

/// Renders one pair per depth of `depths` (cm), the board centred at `(xy[0], xy[1], z)`,
/// through `head` at `joints`. Pair `k` is named `left{k+1:02}.png` / `right{k+1:02}.png` and
/// gets its own noise seed, drawn in order from a ChaCha8 stream seeded with `seed`: the same
/// arguments give the same bytes.
pub fn render_capture_set(
    head: &HeadRig,
    joints: &Joints,
    board: &Board,
    xy: [f64; 2],
    depths: &[f64],
    opt: &RenderOptions,
    seed: u64,
) -> Result<RenderedSet, RenderError> {
    check_depths(depths)?;
    let mut seeds = rand::rngs::ChaCha8Rng::seed_from_u64(seed);
    let mut captures = Vec::with_capacity(depths.len());
    for (k, &z) in depths.iter().enumerate() {
        let s: u64 = seeds.random();
        let centre = [xy[0], xy[1], z];
        let render = render_pair(head, joints, board, centre, opt, s)?;
        let [left_name, right_name] = capture_names(k);
        captures.push(Capture { left_name, right_name, centre, render });
    }
    Ok(RenderedSet { board: *board, captures })
}

/// The thesis' training captures: the board centred on the optic axis of the head
/// (`x = y = 0`) at each training depth (65..165 cm, step 20), through a thesis rig at home.
pub fn training_captures(
    rig: &Rig,
    board: &Board,
    opt: &RenderOptions,
    seed: u64,
) -> Result<RenderedSet, RenderError> {
    render_capture_set(
        &HeadRig::new(*rig),
        &Joints::HOME,
        board,
        [0.0, 0.0],
        &presets::TRAIN_DEPTHS,
        opt,
        seed,
    )
}

/// The rays of a grid of pixel coordinates `u = c + off_u`, `v = r + off_v` of a camera
/// without lens distortion, with the per-column and per-row parts of
/// [`LensCamera::ray`] computed once: `d = Omega^T [x, y, 1]` is summed as that function sums it
/// (`(m0 x + m1 y) + m2 * 1`), from the same products, so every ray has the same bits.
pub(crate) struct RayGrid {
    center: Vec3,
    /// `Omega[0][k] x(u)` per column.
    col: Vec<[f64; 3]>,
    /// `Omega[1][k] y(v)` per row.
    row: Vec<[f64; 3]>,
    /// `Omega[2][k] * 1`.
    z: [f64; 3],
}

impl RayGrid {
    /// The grid of `cols x rows` coordinates `(c + off_u, r + off_v)`, or `None` when the lens
    /// distorts (then [`LensCamera::ray`] is the way).
    pub(crate) fn new(
        cam: &LensCamera,
        cols: usize,
        rows: usize,
        off_u: f64,
        off_v: f64,
    ) -> Option<RayGrid> {
        if !cam.distortion.is_none() {
            return None;
        }
        let k = &cam.camera;
        let m = &k.rotation;
        // LensCamera::ray: the offset from (u0, v0), undone (the identity), back to a pixel.
        let x = |u: f64| ((u - k.u0) + k.u0 - k.u0) / k.phi_u;
        let y = |v: f64| ((v - k.v0) + k.v0 - k.v0) / k.phi_v;
        let col = (0..cols)
            .map(|c| {
                let x = x(c as f64 + off_u);
                [m[0][0] * x, m[0][1] * x, m[0][2] * x]
            })
            .collect();
        let row = (0..rows)
            .map(|r| {
                let y = y(r as f64 + off_v);
                [m[1][0] * y, m[1][1] * y, m[1][2] * y]
            })
            .collect();
        Some(RayGrid {
            center: k.center,
            col,
            row,
            z: [m[2][0] * 1.0, m[2][1] * 1.0, m[2][2] * 1.0],
        })
    }

    /// The ray of grid point `(c, r)`, as [`LensCamera::ray`] gives it.
    #[inline(always)]
    pub(crate) fn ray(&self, c: usize, r: usize) -> (Vec3, Vec3) {
        let (a, b) = (&self.col[c], &self.row[r]);
        let d = [a[0] + b[0] + self.z[0], a[1] + b[1] + self.z[1], a[2] + b[2] + self.z[2]];
        let n = libm::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
        (self.center, [d[0] / n, d[1] / n, d[2] / n])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn polarity_top_left_square_is_black() {
        let b = opencv_board();
        let m = RenderOptions::default().margin_cm;
        let class = |x, y| class(&b, m, x, y);
        let [dx, dy] = b.corner_offset(0, 0);
        let e = 0.1 * b.square_cm;
        assert_eq!(class(dx - e, dy - e), Class::Black);
        assert_eq!(class(dx + e, dy - e), Class::White);
        assert_eq!(class(dx - e, dy + e), Class::White);
        assert_eq!(class(dx + e, dy + e), Class::Black);
        // Corner (1, 0): up-left square white.
        let [dx, dy] = b.corner_offset(1, 0);
        assert_eq!(class(dx - e, dy - e), Class::White);
        // Border is white, beyond it background.
        let hx = 5.0 * b.square_cm;
        assert_eq!(class(-hx - 0.5 * m, 0.0), Class::White);
        assert_eq!(class(-hx - 1.5 * m, 0.0), Class::Background);
    }

    #[test]
    fn bad_parameters_name_the_field() {
        let o = RenderOptions { margin_cm: 1.0, ..RenderOptions::default() };
        let r = render_rig(&presets::CASE_1, &opencv_board(), [0.0, 0.0, 100.0], &o, 0);
        crate::invalid::assert_refused(r, "margin_cm");
        let o = RenderOptions { blur_sigma_px: f64::NAN, ..RenderOptions::default() };
        crate::invalid::assert_refused(o.validate(), "blur_sigma_px");
    }

    #[test]
    fn blur_keeps_a_constant_image_and_the_mean() {
        let mut b = vec![7.0f32; 30 * 20];
        blur(&mut b, 30, 20, 1.3);
        assert!(b.iter().all(|&x| (x - 7.0).abs() < 1e-4));
        let mut b = vec![0.0f32; 41 * 41];
        b[20 * 41 + 20] = 1.0;
        blur(&mut b, 41, 41, 1.0);
        let s: f32 = b.iter().sum();
        assert!((s - 1.0).abs() < 1e-5);
        assert!(b[20 * 41 + 20] > b[20 * 41 + 21] && b[20 * 41 + 21] > b[20 * 41 + 22]);
    }
}
