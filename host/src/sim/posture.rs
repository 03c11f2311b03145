//! Posture-aware point sets: the sets of [`crate::sim::sets`] (the thesis' board protocol, its
//! test points, random points of the training volume) seen by the thesis rig on the five-axis
//! head at many postures ([`hvs_shared::sim::posture`]), optionally through distorting lenses, with
//! the five joint angles as extra columns.
//!
//! At each posture the points are placed in the posture's cyclopean gaze frame
//! ([`hvs_shared::sim::posture::gaze_frame`]): the board sits in front of wherever the head looks,
//! at the thesis' distances from the eyes, and its ground truth is written in the head frame
//! (the body-fixed stereo frame of the home posture), which is what a posture-aware model
//! outputs and what the head's `Look` fixates.
//!
//! Postures ([`Sampling`]) come from [`PostureRange::WORKING`] (or any range):
//! - `grid`: a stratified grid: each interval is cut into `levels` equal cells and one posture
//!   is drawn uniformly inside every cell of the product (seeded), so the training postures
//!   cover the range without repeating the same few joint values;
//! - `lattice`: the regular grid of `levels` evenly spaced values per interval, ends included;
//! - `random`: `count` uniform random postures.
//!
//! Every posture is quantised to the drives' 0.18 degree steps, as the head's setpoints are.

use crate::data::dataset::{Dataset, JOINT_COLUMNS};
use crate::sim::board::Pixels;
use crate::sim::sets::{
    check_noise_px, pixel_noise, sample_volume, set_points, to_written_precision, volume_of,
    volume_point, SetKind, SimOptions,
};
use anyhow::{bail, Result};
use hvs_shared::runtime::blob::InputKind;
use hvs_shared::runtime::gaze::Joints;
use hvs_shared::sim::camera::{StereoPixels, Vec3};
use hvs_shared::sim::posture::{gaze_frame, grid_len, to_head, HeadRig, PostureRange};
use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use std::io::Write;

/// How the postures of a set are chosen.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Sampling {
    /// One uniform random posture inside every cell of a `levels` grid (stratified).
    Grid,
    /// The regular grid: `levels` evenly spaced values per interval, ends included.
    Lattice,
    /// `count` uniform random postures.
    Random,
}

/// Default grid levels per interval (neck pan, neck tilt, eye tilt, version, vergence):
/// 324 postures.
pub const DEFAULT_LEVELS: [u8; 5] = [3, 3, 3, 3, 4];
/// Default number of random postures.
pub const DEFAULT_COUNT: usize = 100;

/// Which postures a set is seen at.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PostureOptions {
    /// How they are chosen.
    pub sampling: Sampling,
    /// Grid levels per interval (`grid`, `lattice`).
    pub levels: [u8; 5],
    /// Number of postures (`random`).
    pub count: usize,
    /// The box they come from.
    pub range: PostureRange,
}

impl Default for PostureOptions {
    fn default() -> Self {
        PostureOptions {
            sampling: Sampling::Grid,
            levels: DEFAULT_LEVELS,
            count: DEFAULT_COUNT,
            range: PostureRange::WORKING,
        }
    }
}

/// One simulated point: its pixels, the posture they were seen at, and its true position in
/// the head frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PostureSample {
    /// `[u_l, v_l, u_r, v_r]` (px).
    pub px: StereoPixels,
    /// The joint angles (degrees).
    pub joints: Joints,
    /// `[x, y, z]` in the head frame (cm).
    pub xyz: Vec3,
}

impl PostureSample {
    /// The nine model inputs: pixels, then the joint angles.
    pub fn inputs(&self) -> [f64; 9] {
        let j = self.joints.0.map(f64::from);
        [self.px[0], self.px[1], self.px[2], self.px[3], j[0], j[1], j[2], j[3], j[4]]
    }
}

/// Most postures one set may have (grid cells or random postures).
pub const MAX_POSTURES: usize = 100_000;

/// What the commands that draw postures and pixel noise from one `--seed` (`hvs simulate`
/// and `hvs collect`) mix into it for the postures (`seed ^ POSTURE_SEED_MIX`), so
/// that the two do not share one random stream.
pub const POSTURE_SEED_MIX: u64 = 0x706f_7374_7572_6573;

/// The postures of `opt`, drawn from a ChaCha8 stream seeded with `seed` (the lattice uses
/// none).
pub fn postures(opt: &PostureOptions, seed: u64) -> Result<Vec<Joints>> {
    if !opt.range.is_valid() {
        bail!("the posture range is not a set of finite [min, max] intervals");
    }
    let mut rng = rand::rngs::ChaCha8Rng::seed_from_u64(seed);
    match opt.sampling {
        Sampling::Grid | Sampling::Lattice => {
            let n = grid_len(opt.levels);
            if n == 0 {
                bail!("--posture-levels must all be at least 1");
            }
            if n > MAX_POSTURES {
                bail!("--posture-levels give {n} postures; at most {MAX_POSTURES}");
            }
            let mut out = Vec::with_capacity(n);
            for index in 0..n {
                // Cell coordinates, the last interval varying fastest (as PostureRange::grid).
                let mut rest = index;
                let mut t = [0.0; 5];
                for k in (0..5).rev() {
                    let levels = usize::from(opt.levels[k]);
                    let i = rest % levels;
                    rest /= levels;
                    t[k] = i as f64;
                }
                let j = match opt.sampling {
                    Sampling::Lattice => opt.range.grid(opt.levels, index),
                    _ => {
                        let t: [f64; 5] = core::array::from_fn(|k| {
                            let u: f64 = rng.random();
                            (t[k] + u) / f64::from(opt.levels[k])
                        });
                        Some(opt.range.at(t))
                    }
                };
                out.extend(j);
            }
            Ok(out)
        }
        Sampling::Random => {
            if opt.count == 0 || opt.count > MAX_POSTURES {
                bail!("--posture-count must be 1 to {MAX_POSTURES}, got {}", opt.count);
            }
            Ok((0..opt.count)
                .map(|_| opt.range.at(core::array::from_fn(|_| rng.random())))
                .collect())
        }
    }
}

/// Simulates set `kind` through `head` at each posture of `joints`: the whole board set
/// (`train`, `test`) at every posture, or (`volume`) `opt.points` random points of the
/// training volume, point `k` at posture `k mod n`. Pixel noise as in
/// [`crate::sim::sets::simulate`]. The same arguments give the same bytes.
pub fn simulate(
    head: &HeadRig,
    kind: SetKind,
    joints: &[Joints],
    opt: &SimOptions,
) -> Result<Vec<PostureSample>> {
    check_noise_px(opt.noise_px, &head.rig)?;
    if !head.distortion.iter().all(|d| d.is_finite()) {
        bail!("the lens distortion coefficients must be finite");
    }
    if joints.is_empty() {
        bail!("no postures to simulate at");
    }
    let mut rng = ChaCha8Rng::seed_from_u64(opt.seed);
    let rig = &head.rig;
    let noise = |rng: &mut ChaCha8Rng| pixel_noise(rng, opt.noise_px);
    let frame = |j: &Joints| gaze_frame(j, head.neck_centre_cm, rig.half_baseline);
    let project = |j: &Joints, p: &Vec3, n: &[f64; 4]| match opt.pixels {
        Pixels::Rounded => head.project_rounded_noisy(j, p, n),
        Pixels::Exact => head.project(j, p).map(|e| core::array::from_fn(|k| e[k] + n[k])),
    };
    match kind {
        SetKind::Train | SetKind::Test => {
            let points = set_points(kind, &opt.board)?;
            let mut out = Vec::new();
            for j in joints {
                let f = frame(j);
                for &q in &points {
                    let p = to_head(&f, &q).map(to_written_precision);
                    let n = noise(&mut rng);
                    let px = match project(j, &p, &n) {
                        Ok(px) => px,
                        Err(e) => bail!(
                            "board point ({}, {}, {}) cm at posture {:?} has no image: {e}",
                            p[0],
                            p[1],
                            p[2],
                            j.0
                        ),
                    };
                    if !rig.in_image(&px) {
                        bail!(
                            "board point ({}, {}, {}) cm at posture {:?} falls outside the {}x{} image (u_l={}, v_l={}, u_r={}, v_r={})",
                            p[0], p[1], p[2], j.0, rig.width, rig.height, px[0], px[1], px[2], px[3]
                        );
                    }
                    out.push(PostureSample { px, joints: *j, xyz: p });
                }
            }
            Ok(out)
        }
        SetKind::Volume => {
            let (lo, hi) = volume_of(&opt.board);
            sample_volume(opt.points, "head", &mut rng, |rng, kept| {
                let j = &joints[kept % joints.len()];
                let p = to_head(&frame(j), &volume_point(rng, &lo, &hi)).map(to_written_precision);
                let n = noise(rng);
                let px = project(j, &p, &n).ok().filter(|px| rig.in_image(px))?;
                Some(PostureSample { px, joints: *j, xyz: p })
            })
        }
    }
}

/// The samples as a 9-input data set with ground truth.
pub fn dataset(samples: &[PostureSample]) -> Dataset {
    let mut d = Dataset::new(InputKind::StereoJoints);
    for s in samples {
        d.push(&s.inputs(), Some(s.xyz));
    }
    d
}

/// Writes samples as CSV: `u_l,v_l,u_r,v_r`, the five joint columns of
/// [`crate::data::dataset::JOINT_COLUMNS`] (degrees, printed so that they parse back to the same
/// f32 the head uses), then `x,y,z` (cm, four decimals, as [`crate::sim::sets::write_csv`]).
/// With `joints` false the joint columns are left out (a fixed-posture set, e.g. home with
/// lens distortion).
pub fn write_csv(
    w: &mut dyn Write,
    samples: &[PostureSample],
    joints: bool,
) -> std::io::Result<()> {
    if joints {
        writeln!(w, "u_l,v_l,u_r,v_r,{},x,y,z", JOINT_COLUMNS.join(","))?;
    } else {
        writeln!(w, "u_l,v_l,u_r,v_r,x,y,z")?;
    }
    for s in samples {
        write!(w, "{},{},{},{},", s.px[0], s.px[1], s.px[2], s.px[3])?;
        if joints {
            for v in s.joints.0 {
                write!(w, "{},", v + 0.0)?;
            }
        }
        let [x, y, z] = s.xyz.map(|v| v + 0.0);
        writeln!(w, "{x:.4},{y:.4},{z:.4}")?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::data::csv::{read_set_from, Inputs};
    use hvs_shared::sim::camera::Distortion;
    use hvs_shared::sim::presets;
    use std::path::Path;

    #[test]
    fn grid_lattice_and_random_postures() {
        let opt = PostureOptions::default();
        let g = postures(&opt, 1).unwrap();
        assert_eq!(g.len(), 324);
        assert_eq!(g, postures(&opt, 1).unwrap());
        assert_ne!(g, postures(&opt, 2).unwrap());
        let w = PostureRange::WORKING;
        // Stratified: posture i lies in its own cell of every interval.
        let cells = |i: usize| {
            let mut rest = i;
            let mut c = [0usize; 5];
            for k in (0..5).rev() {
                let n = DEFAULT_LEVELS[k] as usize;
                c[k] = rest % n;
                rest /= n;
            }
            c
        };
        for (i, j) in g.iter().enumerate() {
            assert!(w.contains(j, 0.18), "{j:?}");
            let terms = PostureRange::gaze_terms(j);
            let c = cells(i);
            for k in 0..5 {
                let [lo, hi] = w.intervals()[k];
                let n = f32::from(DEFAULT_LEVELS[k]);
                let (a, b) =
                    (lo + (hi - lo) * c[k] as f32 / n, lo + (hi - lo) * (c[k] + 1) as f32 / n);
                // Quantisation moves each eye pan by up to 0.09 degrees.
                assert!(
                    terms[k] >= a - 0.19 && terms[k] <= b + 0.19,
                    "posture {i} term {k}: {} not in [{a}, {b}]",
                    terms[k]
                );
            }
        }
        let lattice = postures(&PostureOptions { sampling: Sampling::Lattice, ..opt }, 1).unwrap();
        assert_eq!(lattice[5], w.grid(DEFAULT_LEVELS, 5).unwrap());
        let r =
            postures(&PostureOptions { sampling: Sampling::Random, count: 50, ..opt }, 9).unwrap();
        assert_eq!(r.len(), 50);
        assert!(r.iter().all(|j| w.contains(j, 0.18)));
        for bad in [
            PostureOptions { levels: [3, 0, 3, 3, 3], ..opt },
            PostureOptions { sampling: Sampling::Random, count: 0, ..opt },
        ] {
            assert!(postures(&bad, 0).is_err());
        }
    }

    #[test]
    fn board_at_every_posture_round_trips_through_the_csv() {
        let head = HeadRig::new(presets::CASE_3);
        let js = postures(
            &PostureOptions { sampling: Sampling::Random, count: 4, ..PostureOptions::default() },
            5,
        )
        .unwrap();
        let s = simulate(&head, SetKind::Train, &js, &SimOptions::default()).unwrap();
        assert_eq!(s.len(), 4 * 72);
        for (k, x) in s.iter().enumerate() {
            assert_eq!(x.joints, js[k / 72]);
            // The written ground truth is the projected point.
            assert_eq!(head.project_rounded(&x.joints, &x.xyz).unwrap(), x.px);
        }
        let mut bytes = Vec::new();
        write_csv(&mut bytes, &s, true).unwrap();
        let text = String::from_utf8(bytes.clone()).unwrap();
        assert!(text.starts_with(
            "u_l,v_l,u_r,v_r,neck_pan,neck_tilt,eye_tilt,left_eye_pan,right_eye_pan,x,y,z\n"
        ));
        let t = read_set_from(Path::new("mem.csv"), bytes.as_slice(), Inputs::Auto, true).unwrap();
        assert_eq!(t.data.n_inputs, 9);
        assert_eq!(t.data.len(), s.len());
        for (r, x) in s.iter().enumerate() {
            let row = t.data.row(r);
            assert_eq!(row[..4], x.px);
            // Joint angles parse back to the f32 the head uses.
            for k in 0..5 {
                assert_eq!(row[4 + k] as f32, x.joints.0[k]);
            }
            assert_eq!(t.data.targets[r], x.xyz);
        }
        assert_eq!(dataset(&s).len(), s.len());
    }

    #[test]
    fn home_without_lens_is_the_thesis_set_and_lenses_move_pixels() {
        let rig = presets::CASE_4;
        let head = HeadRig::new(rig);
        let home = [Joints::HOME];
        let a = simulate(&head, SetKind::Test, &home, &SimOptions::default()).unwrap();
        let b = crate::sim::sets::simulate(&rig, SetKind::Test, &SimOptions::default()).unwrap();
        assert_eq!(a.len(), b.len());
        for (x, y) in a.iter().zip(&b) {
            assert_eq!((x.px, x.xyz), (y.px, y.xyz));
        }
        // The thesis board spans at most 46 px from the principal point (r < 0.15): even
        // k1 = -0.5 moves its images by about a pixel at most; seen 30 degrees off-axis (the
        // eyes turned away from it) the same board moves by tens of pixels.
        let bent = head.with_distortion(Distortion { k1: -0.5, k2: 0.0 });
        let c = simulate(&bent, SetKind::Train, &home, &SimOptions::default()).unwrap();
        let d = simulate(&head, SetKind::Train, &home, &SimOptions::default()).unwrap();
        let shift = |c: &[PostureSample], d: &[PostureSample]| {
            c.iter().zip(d).map(|(p, q)| (p.px[0] - q.px[0]).abs()).fold(0.0, f64::max)
        };
        assert!(shift(&c, &d) <= 1.0, "{}", shift(&c, &d));
        let far = [Joints([0.0, 0.0, 0.0, 30.0, 30.0])];
        let sees_far = |h: &HeadRig| {
            // The board straight ahead of the head, seen with the eyes turned 30 degrees.
            let mut out = Vec::new();
            for q in crate::sim::sets::board_points(SetKind::Train) {
                out.push(PostureSample {
                    px: h.project_rounded(&far[0], &q).unwrap(),
                    joints: far[0],
                    xyz: q,
                });
            }
            out
        };
        let (c, d) = (sees_far(&bent), sees_far(&head));
        assert!(shift(&c, &d) >= 10.0, "{}", shift(&c, &d));
        // Barrel distortion pulls every point towards the principal point.
        for (p, q) in c.iter().zip(&d) {
            assert!((p.px[0] - 320.0).abs() <= (q.px[0] - 320.0).abs());
        }
        let mut bytes = Vec::new();
        write_csv(&mut bytes, &c[..1], false).unwrap();
        assert!(String::from_utf8(bytes).unwrap().starts_with("u_l,v_l,u_r,v_r,x,y,z\n"));
    }

    #[test]
    fn volume_cycles_through_the_postures_and_is_seeded() {
        let head = HeadRig::new(presets::CASE_1);
        let js = postures(&PostureOptions::default(), 3).unwrap();
        let opt = SimOptions { points: 700, noise_px: 0.5, seed: 4, ..SimOptions::default() };
        let a = simulate(&head, SetKind::Volume, &js, &opt).unwrap();
        assert_eq!(a, simulate(&head, SetKind::Volume, &js, &opt).unwrap());
        assert_eq!(a.len(), 700);
        for (k, s) in a.iter().enumerate() {
            assert_eq!(s.joints, js[k % js.len()]);
        }
        let bad = SimOptions { noise_px: f64::NAN, ..opt };
        assert!(simulate(&head, SetKind::Volume, &js, &bad).is_err());
        assert!(simulate(&head, SetKind::Train, &[], &opt).is_err());
    }
}
