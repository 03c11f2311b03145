//! Simulated point sets: the thesis' board protocol and random points of the training
//! volume, projected through a rig with `hvs_shared::sim::camera` (optionally with seeded Gaussian
//! pixel noise before the rounding, or unrounded pixels), on the thesis' board or a larger grid
//! board ([`crate::sim::board`]), and their CSV form.

use crate::sim::board::{Pixels, TrainingBoard};
use anyhow::{bail, Result};
use hvs_shared::sim::camera::{Rig, StereoPixels, Vec3};
use hvs_shared::sim::presets;
use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use rand_distr::{Distribution, StandardNormal};
use std::io::Write;

/// Which set to produce.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SetKind {
    /// The 12 board points at each training depth (65..165 cm, step 20): 72 points.
    Train,
    /// The two test points P1, P2 at each test depth (65..165 cm, step 10): 22 points.
    Test,
    /// Uniform random points in the box the training boards span.
    Volume,
}

/// One simulated point: its pixels and its true position.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sample {
    /// `[u_l, v_l, u_r, v_r]` (px).
    pub px: StereoPixels,
    /// `[x, y, z]` (cm).
    pub xyz: Vec3,
}

/// Options of a simulation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SimOptions {
    /// Points of a volume set.
    pub points: usize,
    /// Standard deviation of the Gaussian pixel noise added before rounding (px); 0 = none.
    pub noise_px: f64,
    /// Seed of every random draw.
    pub seed: u64,
    /// The training board (`train` sets, and the box of `volume` sets).
    pub board: TrainingBoard,
    /// Rounded (the thesis) or exact pixels.
    pub pixels: Pixels,
}

impl Default for SimOptions {
    fn default() -> Self {
        SimOptions {
            points: 500,
            noise_px: 0.0,
            seed: 0,
            board: TrainingBoard::Thesis,
            pixels: Pixels::Rounded,
        }
    }
}

/// The box spanned by the training boards: `(min, max)` of X, Y, Z in cm.
pub fn training_volume() -> (Vec3, Vec3) {
    let (x, y, z) = (&presets::TRAIN_BOARD_X, &presets::TRAIN_BOARD_Y, &presets::TRAIN_DEPTHS);
    let lo = |s: &[f64]| s.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = |s: &[f64]| s.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    ([lo(x), lo(y), lo(z)], [hi(x), hi(y), hi(z)])
}

/// Most points one `--set volume` run writes (about 450 MB of CSV): a larger request is an
/// error, not an allocation failure. Runs with other seeds give more.
pub const MAX_POINTS: usize = 10_000_000;

/// Checks a `--points` request: 1 to [`MAX_POINTS`].
pub fn check_points(n: usize) -> Result<()> {
    if n == 0 {
        bail!("--points must be at least 1");
    }
    if n > MAX_POINTS {
        bail!("--points must be at most {MAX_POINTS} per file, got {n} (use several --seed values for more)");
    }
    Ok(())
}

/// The true positions of a board set, in the order of the thesis' data files.
pub fn board_points(kind: SetKind) -> Vec<Vec3> {
    match kind {
        SetKind::Train => {
            presets::TRAIN_DEPTHS.iter().flat_map(|&z| presets::board_points(z)).collect()
        }
        SetKind::Test => presets::TEST_DEPTHS
            .iter()
            .flat_map(|&z| presets::TEST_POINTS_XY.map(|[x, y]| [x, y, z]))
            .collect(),
        SetKind::Volume => Vec::new(),
    }
}

/// The true positions of a board set on `board`: [`board_points`] for the thesis board; a
/// grid board has training boards only (its test points P1, P2 are the thesis'), so
/// `test` with a grid board is an error.
pub fn set_points(kind: SetKind, board: &TrainingBoard) -> Result<Vec<Vec3>> {
    match (kind, board) {
        (_, TrainingBoard::Thesis) => Ok(board_points(kind)),
        (SetKind::Train, b) => Ok(b.train_points()),
        (SetKind::Test, b) => bail!(
            "--set test is the thesis' test points P1, P2; --board {} applies to --set train and --set volume",
            b.name()
        ),
        (SetKind::Volume, _) => Ok(Vec::new()),
    }
}

/// The box random volume points come from: [`training_volume`] for the thesis board, the box
/// a grid board spans otherwise.
pub fn volume_of(board: &TrainingBoard) -> (Vec3, Vec3) {
    match board {
        TrainingBoard::Thesis => training_volume(),
        b => b.volume(),
    }
}

/// Simulates a set through `rig`. Every random draw comes from one ChaCha8 stream seeded
/// with `opt.seed`, so the same arguments give the same bytes.
pub fn simulate(rig: &Rig, kind: SetKind, opt: &SimOptions) -> Result<Vec<Sample>> {
    check_noise_px(opt.noise_px, rig)?;
    let mut rng = ChaCha8Rng::seed_from_u64(opt.seed);
    let noise = |rng: &mut ChaCha8Rng| pixel_noise(rng, opt.noise_px);
    let project = |p: &Vec3, n: &[f64; 4]| match opt.pixels {
        Pixels::Exact => rig.project(p).map(|e| core::array::from_fn(|k| e[k] + n[k])),
        Pixels::Rounded if opt.noise_px == 0.0 => rig.project_rounded(p),
        Pixels::Rounded => rig.project_rounded_noisy(p, n),
    };
    match kind {
        SetKind::Train | SetKind::Test => {
            let mut out = Vec::new();
            for p in set_points(kind, &opt.board)? {
                let n = noise(&mut rng);
                let px = match project(&p, &n) {
                    Ok(px) => px,
                    Err(e) => {
                        bail!("board point ({}, {}, {}) cm has no image: {e}", p[0], p[1], p[2])
                    }
                };
                if !rig.in_image(&px) {
                    bail!(
                        "board point ({}, {}, {}) cm falls outside the {}x{} image (u_l={}, v_l={}, u_r={}, v_r={})",
                        p[0], p[1], p[2], rig.width, rig.height, px[0], px[1], px[2], px[3]
                    );
                }
                out.push(Sample { px, xyz: p });
            }
            Ok(out)
        }
        SetKind::Volume => {
            let (lo, hi) = volume_of(&opt.board);
            sample_volume(opt.points, "rig", &mut rng, |rng, _| {
                let p = volume_point(rng, &lo, &hi).map(to_written_precision);
                let n = noise(rng);
                let px = project(&p, &n).ok().filter(|px| rig.in_image(px))?;
                Some(Sample { px, xyz: p })
            })
        }
    }
}

/// Checks a `--noise-px` value: a finite number from 0 to the image size of `rig` (the
/// simulators check it, `hvs simulate` before anything else).
pub fn check_noise_px(noise_px: f64, rig: &Rig) -> Result<()> {
    let image = rig.width.max(rig.height) as f64;
    if !(noise_px.is_finite() && (0.0..=image).contains(&noise_px)) {
        bail!(
            "--noise-px must be a finite number >= 0 and at most the image size ({image} px), got {}",
            crate::fmt::given(noise_px)
        );
    }
    Ok(())
}

/// One draw of the Gaussian pixel noise (standard deviation `noise_px`) for the four pixel
/// coordinates; with `noise_px == 0` none, and nothing is drawn from `rng`.
pub(crate) fn pixel_noise(rng: &mut ChaCha8Rng, noise_px: f64) -> [f64; 4] {
    if noise_px == 0.0 {
        return [0.0; 4];
    }
    core::array::from_fn(|_| {
        let n: f64 = StandardNormal.sample(rng);
        n * noise_px
    })
}

/// A uniform random point of the box `lo..hi` (three draws from `rng`, X, Y, Z; the box of
/// [`volume_of`]).
pub(crate) fn volume_point(rng: &mut ChaCha8Rng, lo: &Vec3, hi: &Vec3) -> Vec3 {
    core::array::from_fn(|k| {
        let u: f64 = rng.random();
        lo[k] + (hi[k] - lo[k]) * u
    })
}

/// Rejection sampling of a volume set: calls `draw(rng, kept)` (`kept` = samples so far)
/// until `points` samples are kept, `None` being a draw that fell outside an image. Checks
/// `points` ([`check_points`]) and gives up, naming `viewer` ("rig", "head"), after
/// `max(1000 points, 10 000)` draws.
pub(crate) fn sample_volume<T>(
    points: usize,
    viewer: &str,
    rng: &mut ChaCha8Rng,
    mut draw: impl FnMut(&mut ChaCha8Rng, usize) -> Option<T>,
) -> Result<Vec<T>> {
    check_points(points)?;
    let max_tries = points.saturating_mul(1000).max(10_000);
    let mut out = Vec::with_capacity(points);
    let mut tries = 0usize;
    while out.len() < points {
        if tries == max_tries {
            bail!(
                "only {} of {points} random points fell inside both images after {tries} draws; the {viewer} does not see the training volume",
                out.len(),
            );
        }
        tries += 1;
        if let Some(sample) = draw(rng, out.len()) {
            out.push(sample);
        }
    }
    Ok(out)
}

/// Rounds a coordinate to the 1e-4 cm the CSV holds, so that the written ground truth is
/// exactly the point that was projected (`k / 1e4` is the double nearest the decimal).
pub(crate) fn to_written_precision(v: f64) -> f64 {
    let k = (v * 1e4).round();
    k / 1e4 + 0.0
}

/// Samples as a stereo data set (pixels in, true positions out).
pub fn dataset(samples: &[Sample]) -> crate::data::dataset::Dataset {
    let mut d = crate::data::dataset::Dataset::new(hvs_shared::runtime::blob::InputKind::Stereo);
    for s in samples {
        d.push(&s.px, Some(s.xyz));
    }
    d
}

/// Writes samples as CSV: header `u_l,v_l,u_r,v_r,x,y,z`, pixels in the shortest form that
/// reads back to the same double (integers when they are rounded), positions with four
/// decimals, as in the thesis' data files.
pub fn write_csv(w: &mut dyn Write, samples: &[Sample]) -> std::io::Result<()> {
    writeln!(w, "u_l,v_l,u_r,v_r,x,y,z")?;
    for s in samples {
        let [x, y, z] = s.xyz.map(|v| v + 0.0);
        writeln!(w, "{},{},{},{},{x:.4},{y:.4},{z:.4}", s.px[0], s.px[1], s.px[2], s.px[3])?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn protocol_sizes_and_volume_box() {
        assert_eq!(board_points(SetKind::Train).len(), 72);
        assert_eq!(board_points(SetKind::Test).len(), 22);
        assert_eq!(training_volume(), ([-3.0, -2.0, 65.0], [3.0, 2.0, 165.0]));
    }

    #[test]
    fn volume_is_seeded_inside_the_box_and_consistent() {
        let rig = presets::CASE_4;
        let opt = SimOptions { points: 300, ..Default::default() };
        let a = simulate(&rig, SetKind::Volume, &opt).unwrap();
        assert_eq!(a, simulate(&rig, SetKind::Volume, &opt).unwrap());
        let b = simulate(&rig, SetKind::Volume, &SimOptions { seed: 1, ..opt }).unwrap();
        assert_ne!(a, b);
        let (lo, hi) = training_volume();
        for s in &a {
            for k in 0..3 {
                assert!(s.xyz[k] >= lo[k] && s.xyz[k] <= hi[k]);
            }
            // The written position is the projected one.
            assert_eq!(rig.project_rounded(&s.xyz).unwrap(), s.px);
            let text = format!("{:.4}", s.xyz[0]);
            assert_eq!(text.parse::<f64>().unwrap(), s.xyz[0]);
        }
    }

    #[test]
    fn noise_moves_pixels_and_is_seeded() {
        let rig = presets::CASE_1;
        let clean = simulate(&rig, SetKind::Train, &SimOptions::default()).unwrap();
        let opt = SimOptions { noise_px: 1.0, seed: 3, ..Default::default() };
        let noisy = simulate(&rig, SetKind::Train, &opt).unwrap();
        assert_eq!(noisy, simulate(&rig, SetKind::Train, &opt).unwrap());
        let moved = clean.iter().zip(&noisy).filter(|(a, b)| a.px != b.px).count();
        // With sigma = 1 px almost every one of 72 points moves in at least one coordinate.
        assert!(moved > 50, "{moved}");
        let max_shift = clean
            .iter()
            .zip(&noisy)
            .flat_map(|(a, b)| (0..4).map(move |k| (a.px[k] - b.px[k]).abs()))
            .fold(0.0, f64::max);
        assert!(max_shift <= 6.0, "{max_shift}");
        assert!(simulate(&rig, SetKind::Train, &SimOptions { noise_px: -1.0, ..opt }).is_err());
    }

    #[test]
    fn exact_pixels_are_the_projection_and_share_the_noise_draws() {
        let rig = presets::CASE_4;
        let exact = SimOptions { pixels: Pixels::Exact, ..SimOptions::default() };
        for s in simulate(&rig, SetKind::Train, &exact).unwrap() {
            assert_eq!(s.px, rig.project(&s.xyz).unwrap());
        }
        let noisy = |pixels| SimOptions {
            pixels,
            noise_px: 0.4,
            seed: 11,
            points: 50,
            ..SimOptions::default()
        };
        let e = simulate(&rig, SetKind::Volume, &noisy(Pixels::Exact)).unwrap();
        let r = simulate(&rig, SetKind::Volume, &noisy(Pixels::Rounded)).unwrap();
        // The same points and draws: the rounded set is the noisy exact one, rounded (the
        // presets' principal point is whole). Rejections could differ only at the image edge.
        assert_eq!(e.len(), r.len());
        for (e, r) in e.iter().zip(&r) {
            assert_eq!(e.xyz, r.xyz);
            assert_eq!(e.px.map(f64::round), r.px);
            assert_ne!(e.px, rig.project(&e.xyz).unwrap());
        }
    }

    #[test]
    fn a_grid_board_trains_at_the_thesis_depths_and_has_no_test_set() {
        let rig = presets::CASE_2;
        let opt = SimOptions {
            board: TrainingBoard::parse("9x6:6").unwrap(),
            points: 200,
            ..SimOptions::default()
        };
        let t = simulate(&rig, SetKind::Train, &opt).unwrap();
        assert_eq!(t.len(), 324);
        assert_eq!(t[0].xyz, [-24.0, -15.0, 65.0]);
        let v = simulate(&rig, SetKind::Volume, &opt).unwrap();
        assert!(v.iter().all(|s| s.xyz[0].abs() <= 24.0 && s.xyz[1].abs() <= 15.0));
        assert!(v.iter().any(|s| s.xyz[0].abs() > 3.0));
        let e = simulate(&rig, SetKind::Test, &opt).unwrap_err().to_string();
        assert!(e.contains("--set test is the thesis' test points"), "{e}");
    }

    #[test]
    fn a_rig_that_misses_the_board_is_an_error() {
        let mut rig = presets::CASE_1;
        rig.alpha_left = 1.2;
        let e = simulate(&rig, SetKind::Train, &SimOptions::default()).unwrap_err();
        assert!(e.to_string().contains("falls outside"), "{e}");
        let e = simulate(&rig, SetKind::Volume, &SimOptions::default()).unwrap_err();
        assert!(e.to_string().contains("does not see"), "{e}");
    }

    #[test]
    fn csv_form() {
        let s = [Sample { px: [330.0, 231.0, 284.0, 231.0], xyz: [-3.0, -0.0, 65.0] }];
        let mut out = Vec::new();
        write_csv(&mut out, &s).unwrap();
        assert_eq!(
            String::from_utf8(out).unwrap(),
            "u_l,v_l,u_r,v_r,x,y,z\n330,231,284,231,-3.0000,0.0000,65.0000\n"
        );
    }
}
