//! Corner accuracy against exact truth on synthetic boards, and the pixel convention.
//!
//! A tiny renderer of its own (independent of `hvs_vision::render`): a 9 x 6 chessboard posed
//! in 3-D in front of a pinhole camera (f = 600 px, principal point (319.5, 239.5)), so the
//! board -> image map is an exact homography. Pixel (c, r) covers `[c - 0.5, c + 0.5] x
//! [r - 0.5, r + 0.5]` (integer coordinates at pixel centres); pixels whose four corners see
//! the same colour are filled, the others are area-sampled on a 16 x 16 grid. Then optional
//! Gaussian blur (sigma px), seeded Gaussian noise (grey levels), rounding to 8 bits.
//!
//! Run with `cargo test --release -p hvs-vision --test detect_accuracy -- --nocapture` to see
//! the table.

use hvs_shared::test_support::splitmix64;
use hvs_vision::board::Board;
use hvs_vision::detect;
use image::GrayImage;

const W: u32 = 640;
const H: u32 = 480;
const F: f64 = 600.0;
const CU: f64 = 319.5;
const CV: f64 = 239.5;

/// Board pose: square side `s` (board units = cm), centre distance `z`, rotations (rad) about
/// the camera's y axis (`yaw`), x axis (`pitch`) and z axis (`roll`), centre offset (cm).
#[derive(Clone, Copy)]
struct Pose {
    z: f64,
    yaw: f64,
    pitch: f64,
    roll: f64,
    off: [f64; 2],
}

fn rot(p: &Pose) -> [[f64; 3]; 3] {
    let (sy, cy) = p.yaw.sin_cos();
    let (sp, cp) = p.pitch.sin_cos();
    let (sr, cr) = p.roll.sin_cos();
    let ry = [[cy, 0.0, sy], [0.0, 1.0, 0.0], [-sy, 0.0, cy]];
    let rx = [[1.0, 0.0, 0.0], [0.0, cp, -sp], [0.0, sp, cp]];
    let rz = [[cr, -sr, 0.0], [sr, cr, 0.0], [0.0, 0.0, 1.0]];
    mul(&mul(&ry, &rx), &rz)
}

fn mul(a: &[[f64; 3]; 3], b: &[[f64; 3]; 3]) -> [[f64; 3]; 3] {
    let mut m = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            m[i][j] = (0..3).map(|k| a[i][k] * b[k][j]).sum();
        }
    }
    m
}

/// Homography board (x, y) (unit: one square, origin at the board centre) -> pixel.
fn homography(p: &Pose) -> [[f64; 3]; 3] {
    let r = rot(p);
    // X = R [x, y, 0] + t, pixel = K X.
    let t = [p.off[0], p.off[1], p.z];
    let cols = [[r[0][0], r[1][0], r[2][0]], [r[0][1], r[1][1], r[2][1]], t];
    let mut h = [[0.0; 3]; 3];
    for (c, col) in cols.iter().enumerate() {
        h[0][c] = F * col[0] + CU * col[2];
        h[1][c] = F * col[1] + CV * col[2];
        h[2][c] = col[2];
    }
    h
}

fn apply(h: &[[f64; 3]; 3], x: f64, y: f64) -> [f64; 2] {
    let w = h[2][0] * x + h[2][1] * y + h[2][2];
    [(h[0][0] * x + h[0][1] * y + h[0][2]) / w, (h[1][0] * x + h[1][1] * y + h[1][2]) / w]
}

fn inverse(m: &[[f64; 3]; 3]) -> [[f64; 3]; 3] {
    let det = m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
        - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
        + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
    let c = |a: usize, b: usize, cc: usize, d: usize| m[a][b] * m[cc][d] - m[a][d] * m[cc][b];
    [
        [c(1, 1, 2, 2) / det, -c(0, 1, 2, 2) / det, c(0, 1, 1, 2) / det],
        [-c(1, 0, 2, 2) / det, c(0, 0, 2, 2) / det, -c(0, 0, 1, 2) / det],
        [c(1, 0, 2, 1) / det, -c(0, 0, 2, 1) / det, c(0, 0, 1, 1) / det],
    ]
}

const COLS: u32 = 9;
const ROWS: u32 = 6;

/// Intensity class at board point (x, y) in squares from the centre: 0 black, 1 white
/// (squares and a one-square white margin), 2 background.
fn class(x: f64, y: f64) -> u8 {
    // Squares span [-(cols+1)/2, (cols+1)/2] x [-(rows+1)/2, (rows+1)/2].
    let (hx, hy) = ((COLS + 1) as f64 / 2.0, (ROWS + 1) as f64 / 2.0);
    if x.abs() > hx + 1.0 || y.abs() > hy + 1.0 || !x.is_finite() || !y.is_finite() {
        return 2;
    }
    if x.abs() > hx || y.abs() > hy {
        return 1;
    }
    let a = (x + hx).floor() as i64;
    let b = (y + hy).floor() as i64;
    if (a + b) % 2 == 0 {
        0
    } else {
        1
    }
}

fn level(c: u8) -> f64 {
    [30.0, 220.0, 128.0][c as usize]
}

struct Rng(u64);
impl Rng {
    fn next(&mut self) -> f64 {
        let z = splitmix64(&mut self.0);
        ((z >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    }
    fn gauss(&mut self) -> f64 {
        let (a, b) = (self.next(), self.next());
        (-2.0 * a.ln()).sqrt() * (2.0 * std::f64::consts::PI * b).cos()
    }
}

fn blur(img: &mut [f64], sigma: f64) {
    if sigma <= 0.0 {
        return;
    }
    let r = (3.5 * sigma).ceil() as i64;
    let k: Vec<f64> = (-r..=r).map(|d| (-(d * d) as f64 / (2.0 * sigma * sigma)).exp()).collect();
    let tmp = blur_pass(img, &k, r, true);
    let out = blur_pass(&tmp, &k, r, false);
    img.copy_from_slice(&out);
}

/// One pass of the separable blur with kernel `k` (radius `r`): along the rows (`along_x`)
/// or the columns, the edges clamped.
fn blur_pass(src: &[f64], k: &[f64], r: i64, along_x: bool) -> Vec<f64> {
    let ks: f64 = k.iter().sum();
    let (w, h) = (W as i64, H as i64);
    let mut out = vec![0.0; src.len()];
    for y in 0..h {
        for x in 0..w {
            let mut s = 0.0;
            for (i, kv) in k.iter().enumerate() {
                let d = i as i64 - r;
                let at = if along_x {
                    y * w + (x + d).clamp(0, w - 1)
                } else {
                    (y + d).clamp(0, h - 1) * w + x
                };
                s += kv * src[at as usize];
            }
            out[(y * w + x) as usize] = s / ks;
        }
    }
    out
}

/// The rendered image and the exact corners `(i, j)` in row-major label order.
fn render(p: &Pose, blur_sigma: f64, noise: f64, seed: u64) -> (GrayImage, Vec<[f64; 2]>) {
    let hm = homography(p);
    let inv = inverse(&hm);
    let cls = |u: f64, v: f64| {
        let b = apply(&inv, u, v);
        // Behind the camera: background.
        let w = inv[2][0] * u + inv[2][1] * v + inv[2][2];
        if w.abs() < 1e-12 {
            2
        } else {
            class(b[0], b[1])
        }
    };
    let (w, h) = (W as usize, H as usize);
    let mut corner_cls = vec![0u8; (w + 1) * (h + 1)];
    for y in 0..=h {
        for x in 0..=w {
            corner_cls[y * (w + 1) + x] = cls(x as f64 - 0.5, y as f64 - 0.5);
        }
    }
    let mut img = vec![0.0; w * h];
    const N: usize = 16;
    for y in 0..h {
        for x in 0..w {
            let c = [
                corner_cls[y * (w + 1) + x],
                corner_cls[y * (w + 1) + x + 1],
                corner_cls[(y + 1) * (w + 1) + x],
                corner_cls[(y + 1) * (w + 1) + x + 1],
            ];
            img[y * w + x] = if c.iter().all(|k| *k == c[0]) {
                level(c[0])
            } else {
                let mut s = 0.0;
                for sy in 0..N {
                    for sx in 0..N {
                        let u = x as f64 - 0.5 + (sx as f64 + 0.5) / N as f64;
                        let v = y as f64 - 0.5 + (sy as f64 + 0.5) / N as f64;
                        s += level(cls(u, v));
                    }
                }
                s / (N * N) as f64
            };
        }
    }
    blur(&mut img, blur_sigma);
    let mut rng = Rng(seed);
    let out = GrayImage::from_fn(W, H, |x, y| {
        let v = img[(y * W + x) as usize] + noise * rng.gauss();
        image::Luma([v.round().clamp(0.0, 255.0) as u8])
    });
    let mut truth = Vec::new();
    for j in 0..ROWS {
        for i in 0..COLS {
            let bx = i as f64 - (COLS - 1) as f64 / 2.0;
            let by = j as f64 - (ROWS - 1) as f64 / 2.0;
            truth.push(apply(&hm, bx, by));
        }
    }
    (out, truth)
}

struct Stats {
    mean: f64,
    max: f64,
    bias: [f64; 2],
    n: usize,
}

/// Mean corner error over a set of poses at one condition; panics if any image fails.
fn measure(poses: &[Pose], blur_sigma: f64, noise: f64, seed: u64) -> Stats {
    let board = Board::new(COLS, ROWS, 1.0).unwrap();
    let (mut sum, mut max, mut bias, mut n) = (0.0, 0.0f64, [0.0; 2], 0);
    for (k, p) in poses.iter().enumerate() {
        let (img, truth) = render(p, blur_sigma, noise, seed + k as u64);
        let c = detect::detect(&img, &board).unwrap_or_else(|e| {
            panic!("pose {k} (z {}, blur {blur_sigma}, noise {noise}): {e}", p.z)
        });
        for (d, t) in c.points.iter().zip(&truth) {
            let e = ((d[0] - t[0]).powi(2) + (d[1] - t[1]).powi(2)).sqrt();
            sum += e;
            max = max.max(e);
            bias[0] += d[0] - t[0];
            bias[1] += d[1] - t[1];
            n += 1;
        }
    }
    Stats { mean: sum / n as f64, max, bias: [bias[0] / n as f64, bias[1] / n as f64], n }
}

/// Poses with squares of about `square_px` pixels at the board centre, tilted up to 40 deg.
fn poses(square_px: f64) -> Vec<Pose> {
    let z = F / square_px; // 1 unit squares
    let d = std::f64::consts::PI / 180.0;
    vec![
        Pose { z, yaw: 0.0, pitch: 0.0, roll: 2.0 * d, off: [0.1, -0.2] },
        Pose { z, yaw: 40.0 * d, pitch: 5.0 * d, roll: -3.0 * d, off: [0.3, 0.1] },
        Pose { z, yaw: -25.0 * d, pitch: -20.0 * d, roll: 6.0 * d, off: [-0.2, 0.3] },
        Pose { z, yaw: 10.0 * d, pitch: 30.0 * d, roll: -8.0 * d, off: [0.05, -0.1] },
    ]
}

#[test]
fn pixel_convention_integer_coordinates_are_pixel_centres() {
    // Fronto-parallel board, corners at known sub-pixel places: a half-pixel convention slip
    // would show as a 0.5 px bias in both coordinates.
    let s = measure(
        &[Pose { z: F / 30.0, yaw: 0.0, pitch: 0.0, roll: 0.0, off: [0.013, -0.027] }],
        0.0,
        0.0,
        1,
    );
    eprintln!(
        "fronto-parallel 30 px squares: mean {:.4} px, bias ({:.4}, {:.4})",
        s.mean, s.bias[0], s.bias[1]
    );
    assert!(s.bias[0].abs() < 0.05 && s.bias[1].abs() < 0.05, "bias {:?}", s.bias);
    assert!(s.mean < 0.05, "mean {}", s.mean);
}

#[test]
fn corner_accuracy_table() {
    let conditions = [(0.0, 0.0, "clean"), (0.8, 2.0, "mild"), (1.5, 4.0, "strong")];
    eprintln!("square px | condition | mean err px | max err px | bias px | corners");
    let mut worst_small: f64 = 0.0;
    let mut worst_large: f64 = 0.0;
    for square in [8.0, 20.0, 45.0] {
        for (b, n, name) in conditions {
            let s = measure(&poses(square), b, n, 7);
            eprintln!(
                "{square:9.0} | {name:9} | {:11.4} | {:10.4} | ({:.3}, {:.3}) | {}",
                s.mean, s.max, s.bias[0], s.bias[1], s.n
            );
            if square < 15.0 {
                worst_small = worst_small.max(s.mean);
            } else {
                worst_large = worst_large.max(s.mean);
            }
        }
    }
    // Regression guards at the measured level (see the report for the numbers).
    // Goal: <= 0.75 x OpenCV's 0.076 px, i.e. 0.057 px, in every condition.
    assert!(worst_large < 0.057, "large squares: worst mean {worst_large}");
    assert!(worst_small < 0.057, "small squares: worst mean {worst_small}");
}
