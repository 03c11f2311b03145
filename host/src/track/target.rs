//! Finding the target in a stereo pair: the nearest object in the front region, or the
//! object under a left pixel at the start, then followed.
//!
//! The head's epipolar geometry changes with every posture (vergence, the case's camera
//! errors), and a posture-aware model carries no fundamental matrix, so points are matched by
//! a small 2-D ZNCC search: along the row within a disparity range and a few rows up and
//! down (the vertical offset of deflected cameras), first at half resolution on a coarse grid
//! of the front region, then refined to a sub-pixel match at full resolution.
//!
//! - **Nearest**: the front region is scanned (below), then the target is followed like a
//!   pixel's for [`RESCAN_FRAMES`] frames, then scanned for again (at once when it is lost).
//!   In a scan every grid point that matches is estimated (X, Y, Z by the model at the
//!   current posture); the cluster of the largest disparity `u_l - u_r` (at least
//!   [`MIN_CLUSTER`] points within a few pixels of one disparity and a few percent of one
//!   depth) is the target (nearest by disparity: a net's depth outside its training box is
//!   not to be trusted for the order); its region is then matched densely (every
//!   [`DENSE_STEP`] px) and the target's pixels are the centroid of the matched points at that
//!   depth, in the left and in the right image.
//! - **Pixel `(U, V)`**: the first frame matches `(U, V)` and grows the region of its depth
//!   around it; later frames look for the same depth band around the last centroid
//!   (followed).

use hvs_shared::runtime::gaze::Joints;
use hvs_shared::runtime::head::Estimator;
use hvs_shared::runtime::protocol::StereoPoint;
use image::GrayImage;
use rayon::prelude::*;

/// Fewest matched points that make an object.
pub const MIN_CLUSTER: usize = 3;
/// Spacing of the dense matches in the target's region (px).
pub const DENSE_STEP: i32 = 3;
/// Spacing of the coarse grid (full-resolution px): an 80th of the image width, at least 4
/// (8 px at 640: a 5 cm sphere at 90 cm, 32 px across, gets a dozen grid points).
fn grid_step(w: i32) -> i32 {
    (w / 80).max(4)
}
/// Share of the image width and height, around the centre, searched for the nearest object.
const FRONT_SHARE: f64 = 0.7;
/// Largest |disparity| searched at half resolution (half-resolution px).
const HALF_DISPARITY: i32 = 48;
/// Rows searched above and below at half resolution.
const HALF_ROWS: i32 = 4;
/// Smallest accepted ZNCC.
const MIN_SCORE: f32 = 0.85;
/// A second peak (more than 2 px away) within this of the best makes a match ambiguous.
const UNIQUENESS: f32 = 0.05;
/// Largest radius of a target's region (px).
const MAX_EXTENT: f64 = 60.0;
/// Smallest grey-level standard deviation of a window worth matching.
const MIN_STD: f32 = 4.0;
/// Disparity band of one object on the coarse grid (px).
const DISPARITY_BAND_PX: f64 = 3.0;
/// Relative depth band of one object (plus 1 cm).
const DEPTH_BAND: f32 = 0.06;

/// Which target to hold.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum TargetMode {
    /// The nearest object in the front region.
    Nearest,
    /// The object under this left pixel at the start.
    Pixel([f64; 2]),
}

/// The target found in one frame.
#[derive(Debug, Clone, PartialEq)]
pub struct Found {
    /// Its pixels: the centroids of its matched points, left and right.
    pub px: [f64; 4],
    /// Its depth (the median of its points' estimates, cm).
    pub z: f32,
    /// The matched left pixels of its region (for the log's truth lookup).
    pub points: Vec<[i32; 2]>,
}

/// A grey image as `f32`, with its size and its integral images (window sums in four
/// lookups).
struct Plane {
    w: i32,
    h: i32,
    p: Vec<f32>,
    /// `(w + 1) x (h + 1)`: the sums of the grey levels above and left of each corner, and of
    /// their squares. Exact in `f64`: the levels are multiples of 1/4 below 256 (full and half
    /// resolution), so every sum is a multiple of 1/16 below 2^37.
    sum: Vec<f64>,
    sq: Vec<f64>,
}

impl Plane {
    fn new(img: &GrayImage) -> Plane {
        Plane::with(
            img.width() as i32,
            img.height() as i32,
            img.as_raw().iter().map(|&x| f32::from(x)).collect(),
        )
    }

    fn with(w: i32, h: i32, p: Vec<f32>) -> Plane {
        let (wu, hu) = (w as usize, h as usize);
        let mut sum = vec![0.0f64; (wu + 1) * (hu + 1)];
        let mut sq = vec![0.0f64; (wu + 1) * (hu + 1)];
        for y in 0..hu {
            let (mut rs, mut rq) = (0.0f64, 0.0f64);
            for x in 0..wu {
                let v = f64::from(p[y * wu + x]);
                rs += v;
                rq += v * v;
                let k = (y + 1) * (wu + 1) + x + 1;
                sum[k] = sum[k - wu - 1] + rs;
                sq[k] = sq[k - wu - 1] + rq;
            }
        }
        Plane { w, h, p, sum, sq }
    }

    /// Half resolution: 2 x 2 means.
    fn half(&self) -> Plane {
        let (w, h) = (self.w / 2, self.h / 2);
        let mut p = Vec::with_capacity((w * h) as usize);
        for r in 0..h {
            for c in 0..w {
                let k = (2 * r * self.w + 2 * c) as usize;
                let wu = self.w as usize;
                p.push(0.25 * (self.p[k] + self.p[k + 1] + self.p[k + wu] + self.p[k + wu + 1]));
            }
        }
        Plane::with(w, h, p)
    }

    fn inside(&self, c: i32, r: i32, rad: i32) -> bool {
        c - rad >= 0 && r - rad >= 0 && c + rad < self.w && r + rad < self.h
    }

    /// Mean and centred norm of the window of radius `rad` at `(c, r)` (inside the image),
    /// from the integral images.
    fn stats(&self, c: i32, r: i32, rad: i32) -> (f32, f32) {
        let ld = (self.w + 1) as usize;
        let (x0, x1) = ((c - rad) as usize, (c + rad + 1) as usize);
        let (y0, y1) = ((r - rad) as usize, (r + rad + 1) as usize);
        let window =
            |t: &[f64]| t[y1 * ld + x1] - t[y0 * ld + x1] - t[y1 * ld + x0] + t[y0 * ld + x0];
        let (s, s2) = (window(&self.sum), window(&self.sq));
        let n = f64::from((2 * rad + 1) * (2 * rad + 1));
        ((s / n) as f32, (s2 - s * s / n).max(0.0).sqrt() as f32)
    }
}

/// A left window, centred (its mean taken off), for [`zncc`] against many right windows.
struct Centred {
    /// `(2 rad + 1)^2` values, row by row.
    v: Vec<f32>,
    /// Their sum (zero but for rounding).
    sum: f32,
    /// Their norm.
    norm: f32,
    rad: i32,
}

impl Centred {
    fn new(l: &Plane, (cl, rl): (i32, i32), (mean, norm): (f32, f32), rad: i32) -> Centred {
        let mut v = Vec::with_capacity(((2 * rad + 1) * (2 * rad + 1)) as usize);
        for y in rl - rad..=rl + rad {
            let a = (y * l.w + cl - rad) as usize;
            v.extend(l.p[a..a + (2 * rad + 1) as usize].iter().map(|x| x - mean));
        }
        let sum = v.iter().sum();
        Centred { v, sum, norm, rad }
    }
}

/// ZNCC scores of the centred left window `lc` against the right windows of row `rr` at the
/// columns `c0..=c1` (all inside the image), into `out`: `sum lc (r - mr) = sum lc r - mr sum
/// lc`, the products summed for the whole row of candidates at once (one multiply-add per
/// window pixel and candidate, in a fixed order, so a candidate's score does not depend on
/// the range it is computed in), the right windows' means and norms from the integral images.
fn zncc_row(lc: &Centred, r: &Plane, rr: i32, (c0, c1): (i32, i32), out: &mut Vec<f32>) {
    let rad = lc.rad;
    let wd = (2 * rad + 1) as usize;
    let nc = (c1 - c0 + 1) as usize;
    out.clear();
    out.resize(nc, 0.0);
    for (dy, lrow) in lc.v.chunks_exact(wd).enumerate() {
        let base = ((rr - rad + dy as i32) * r.w + c0 - rad) as usize;
        for (dx, &lv) in lrow.iter().enumerate() {
            let src = &r.p[base + dx..base + dx + nc];
            for (o, v) in out.iter_mut().zip(src) {
                *o += lv * v;
            }
        }
    }
    for (k, o) in out.iter_mut().enumerate() {
        let (mr, nr) = r.stats(c0 + k as i32, rr, rad);
        *o = if lc.norm <= 0.0 || nr <= 0.0 { -1.0 } else { (*o - mr * lc.sum) / (lc.norm * nr) };
    }
}

/// The best right window for the left window at `(cl, rl)` over columns `cols` and rows
/// `rows` (inclusive), with a parabola's sub-pixel offset on each axis: `(u, v, score)`;
/// `None` below [`MIN_SCORE`] or without [`UNIQUENESS`].
fn search(
    l: &Plane,
    r: &Plane,
    cl: i32,
    rl: i32,
    cols: [i32; 2],
    rows: [i32; 2],
    rad: i32,
) -> Option<(f64, f64, f32)> {
    if !l.inside(cl, rl, rad) {
        return None;
    }
    let st = l.stats(cl, rl, rad);
    let n = (2 * rad + 1) as f32;
    if st.1 / n < MIN_STD {
        return None;
    }
    let lc = Centred::new(l, (cl, rl), st, rad);
    let c0 = cols[0].max(rad + 1);
    let c1 = cols[1].min(r.w - rad - 2);
    let r0 = rows[0].max(rad + 1);
    let r1 = rows[1].min(r.h - rad - 2);
    if c0 > c1 || r0 > r1 {
        return None;
    }
    // Every candidate's score, a row at a time.
    let nc = (c1 - c0 + 1) as usize;
    let mut scores = Vec::with_capacity(nc * (r1 - r0 + 1) as usize);
    let mut row = Vec::with_capacity(nc);
    for y in r0..=r1 {
        zncc_row(&lc, r, y, (c0, c1), &mut row);
        scores.extend_from_slice(&row);
    }
    // The best score per column, then the best column and the best other column.
    let mut best = (-2.0f32, 0, 0);
    let mut per_col = Vec::with_capacity(nc);
    for x in c0..=c1 {
        let mut col = -2.0f32;
        for y in r0..=r1 {
            let s = scores[(y - r0) as usize * nc + (x - c0) as usize];
            col = col.max(s);
            if s > best.0 {
                best = (s, x, y);
            }
        }
        per_col.push(col);
    }
    let (s, x, y) = best;
    if s < MIN_SCORE {
        return None;
    }
    let second = per_col
        .iter()
        .enumerate()
        .filter(|(k, _)| (c0 + *k as i32 - x).abs() > 2)
        .map(|(_, v)| *v)
        .fold(-2.0f32, f32::max);
    if second > s - UNIQUENESS {
        return None;
    }
    let sub = |a: f32, b: f32, c: f32| {
        let d = a - 2.0 * b + c;
        if d < 0.0 {
            (0.5 * (a - c) / d).clamp(-0.5, 0.5)
        } else {
            0.0
        }
    };
    // The neighbours: from the scores where the range has them, computed otherwise (the
    // same bits either way; inside the image: the range keeps a pixel of margin).
    let at = |x: i32, y: i32| {
        if (c0..=c1).contains(&x) && (r0..=r1).contains(&y) {
            return scores[(y - r0) as usize * nc + (x - c0) as usize];
        }
        let mut one = Vec::with_capacity(1);
        zncc_row(&lc, r, y, (x, x), &mut one);
        one[0]
    };
    let sx = sub(at(x - 1, y), s, at(x + 1, y));
    let sy = sub(at(x, y - 1), s, at(x, y + 1));
    Some((f64::from(x) + f64::from(sx), f64::from(y) + f64::from(sy), s))
}

/// One matched point: left pixel, right pixel (sub-pixel), depth.
#[derive(Debug, Clone, Copy)]
struct Pt {
    l: [i32; 2],
    r: [f64; 2],
    z: f32,
}

/// What the finder remembers.
#[derive(Debug, Clone, PartialEq)]
struct Last {
    centre: [f64; 2],
    offset: [f64; 2],
    z: f32,
    extent: f64,
    /// Matched points when it was last found (0 for a seed not yet matched densely).
    points: usize,
}

/// Frames a `nearest` target is followed (only its region matched, as a `U,V` target is)
/// before the whole front region is scanned again for a nearer object: at 30 frames/s a scan
/// every 0.2 s, so a nearer object is taken within that. A target found nowhere is scanned for
/// in the very next frame; one that leaves may leave matches of the background's texture at
/// its depth in its region, followed until the scan.
pub const RESCAN_FRAMES: u32 = 5;

/// The target finder of one run.
pub struct Finder {
    mode: TargetMode,
    last: Option<Last>,
    /// `nearest`: frames followed since the last scan.
    followed: u32,
}

impl Last {
    /// What a frame's target leaves for the next frame.
    fn of(f: &Found, extent: f64) -> Last {
        Last {
            centre: [f.px[0], f.px[1]],
            offset: [f.px[0] - f.px[2], f.px[1] - f.px[3]],
            z: f.z,
            extent: extent.min(MAX_EXTENT),
            points: f.points.len(),
        }
    }
}

fn depth_of(est: &Estimator, joints: &Joints, l: [i32; 2], r: [f64; 2]) -> Option<f32> {
    let p = StereoPoint { u_l: l[0] as f32, v_l: l[1] as f32, u_r: r[0] as f32, v_r: r[1] as f32 };
    // Only estimates inside the model's training box: far outside it (the wall behind the
    // objects) a net extrapolates to anything, nearer than the nearest object included.
    // (The outputs only: the pixels of a board protocol cover a small box of the image.)
    let e = est.estimate(&p, joints).ok()?;
    let plausible = match est {
        Estimator::Network(n) => {
            let mut x = [0.0f32; 9];
            x[..4].copy_from_slice(&p.to_array());
            x[4..].copy_from_slice(&joints.0);
            let k = n.blob.n_inputs().min(9);
            hvs_shared::runtime::head::outputs_in_range(&n.blob, &x[..k], &[e.x, e.y, e.z])
        }
        Estimator::Fallback(_) => true,
    };
    (plausible && e.z.is_finite() && e.z > 0.0).then_some(e.z)
}

fn in_band(z: f32, zc: f32) -> bool {
    (z - zc).abs() <= DEPTH_BAND * zc + 1.0
}

fn median(mut v: Vec<f32>) -> f32 {
    v.sort_by(f32::total_cmp);
    v[v.len() / 2]
}

impl Finder {
    /// A finder for `mode`.
    pub fn new(mode: TargetMode) -> Finder {
        Finder { mode, last: None, followed: 0 }
    }

    /// Forgets the target (it is found afresh in the next frame).
    pub fn reset(&mut self) {
        self.last = None;
    }

    /// The target in `left`/`right` seen at posture `joints`, or `None`.
    pub fn find(
        &mut self,
        left: &GrayImage,
        right: &GrayImage,
        joints: &Joints,
        est: &Estimator,
    ) -> Option<Found> {
        if left.dimensions() != right.dimensions() || left.width() < 32 || left.height() < 32 {
            return None;
        }
        let (l, r) = (Plane::new(left), Plane::new(right));
        let seed = match (self.mode, &self.last) {
            (TargetMode::Pixel(_), Some(last)) => Some(last.clone()),
            (TargetMode::Pixel([u, v]), None) => {
                let c = [u.round() as i32, v.round() as i32];
                let p = coarse_match(&l, &r, c, joints, est)?;
                Some(Last {
                    centre: [f64::from(c[0]), f64::from(c[1])],
                    offset: [f64::from(c[0]) - p.r[0], f64::from(c[1]) - p.r[1]],
                    z: p.z,
                    extent: 40.0,
                    points: 0,
                })
            }
            (TargetMode::Nearest, Some(last)) if self.followed < RESCAN_FRAMES => {
                self.followed += 1;
                Some(last.clone())
            }
            (TargetMode::Nearest, last) => {
                self.followed = 0;
                let scanned = nearest_seed(&l, &r, joints, est);
                // The object held stays held while it is still there and the scan found nothing
                // nearer: a scan whose grid misses a small object would otherwise drop it for
                // the wall behind it. Still there: at least half the points it had, and its
                // points matched again over the scan's whole disparity range land at its
                // disparity ([`confirmed`]); one that left keeps only the background's matches
                // in its narrow band (a periodic texture matches there), and the scan's is taken.
                match (scanned, last) {
                    (Some(s), Some(held)) if s.offset[0] < held.offset[0] - DISPARITY_BAND_PX => {
                        let kept = dense(&l, &r, held, joints, est).filter(|(f, _)| {
                            2 * f.points.len() >= held.points && confirmed(&l, &r, f, joints, est)
                        });
                        if kept.is_some() {
                            self.last = kept.as_ref().map(|(f, extent)| Last::of(f, *extent));
                            return kept.map(|(f, _)| f);
                        }
                        Some(s)
                    }
                    (None, Some(held)) => Some(held.clone()),
                    (scanned, _) => scanned,
                }
            }
        };
        let found = seed.and_then(|s| dense(&l, &r, &s, joints, est));
        self.last = found.as_ref().map(|(f, extent)| Last::of(f, *extent));
        found.map(|(f, _)| f)
    }
}

/// The half-resolution match of full-resolution left pixel `c`, refined at full resolution.
fn coarse_match(l: &Plane, r: &Plane, c: [i32; 2], joints: &Joints, est: &Estimator) -> Option<Pt> {
    let (lh, rh) = (l.half(), r.half());
    coarse_match_in(&lh, &rh, l, r, c, joints, est)
}

fn coarse_match_in(
    lh: &Plane,
    rh: &Plane,
    l: &Plane,
    r: &Plane,
    c: [i32; 2],
    joints: &Joints,
    est: &Estimator,
) -> Option<Pt> {
    let (ch, rw) = (c[0] / 2, c[1] / 2);
    let (u, v, _) = search(
        lh,
        rh,
        ch,
        rw,
        [ch - HALF_DISPARITY, ch + HALF_DISPARITY],
        [rw - HALF_ROWS, rw + HALF_ROWS],
        3,
    )?;
    let (u2, v2) = ((2.0 * u).round() as i32, (2.0 * v).round() as i32);
    let (ur, vr, _) = search(l, r, c[0], c[1], [u2 - 2, u2 + 2], [v2 - 2, v2 + 2], 5)?;
    let z = depth_of(est, joints, c, [ur, vr])?;
    Some(Pt { l: c, r: [ur, vr], z })
}

/// Whether a followed target's points, matched afresh over the scan's whole disparity range
/// (up to nine of them, spread over its points), land at its disparity: at least
/// [`MIN_CLUSTER`] do.
fn confirmed(l: &Plane, r: &Plane, f: &Found, joints: &Joints, est: &Estimator) -> bool {
    let (lh, rh) = (l.half(), r.half());
    let d = f.px[0] - f.px[2];
    let every = f.points.len().div_ceil(9).max(1);
    f.points
        .iter()
        .step_by(every)
        .filter_map(|&p| coarse_match_in(&lh, &rh, l, r, p, joints, est))
        .filter(|q| ((f64::from(q.l[0]) - q.r[0]) - d).abs() <= DISPARITY_BAND_PX)
        .count()
        >= MIN_CLUSTER
}

/// The nearest depth cluster on the coarse grid of the front region.
fn nearest_seed(l: &Plane, r: &Plane, joints: &Joints, est: &Estimator) -> Option<Last> {
    let (lh, rh) = (l.half(), r.half());
    let (w, h) = (f64::from(l.w), f64::from(l.h));
    let (mx, my) = ((0.5 * (1.0 - FRONT_SHARE) * w) as i32, (0.5 * (1.0 - FRONT_SHARE) * h) as i32);
    // The grid's matches, rows in parallel, in row-major order (the same on any number of
    // threads).
    let step = grid_step(l.w).max(1) as usize;
    let xs: Vec<i32> = (mx..(l.w - mx).max(mx)).step_by(step).collect();
    let mut pts: Vec<Pt> = (my..(l.h - my).max(my))
        .step_by(step)
        .collect::<Vec<i32>>()
        .par_iter()
        .flat_map_iter(|&y| {
            let (lh, rh) = (&lh, &rh);
            xs.iter().filter_map(move |&x| coarse_match_in(lh, rh, l, r, [x, y], joints, est))
        })
        .collect();
    // Nearest first by disparity, not by the model's depth: along every left ray the right
    // image's match moves one way as the point recedes, whatever the cameras' deflections,
    // while a net's depth far outside its training box (the wall behind the objects) can be
    // anything, nearer than the nearest object included.
    let disparity = |q: &Pt| f64::from(q.l[0]) - q.r[0];
    pts.sort_by(|a, b| disparity(b).total_cmp(&disparity(a)));
    for p in &pts {
        // The points within the disparity band of `p` are one run of the sorted list.
        let d = disparity(p);
        let lo = pts.partition_point(|q| disparity(q) > d + DISPARITY_BAND_PX);
        let hi = pts.partition_point(|q| disparity(q) >= d - DISPARITY_BAND_PX);
        let members: Vec<&Pt> = pts[lo..hi].iter().filter(|q| in_band(q.z, p.z)).collect();
        if members.len() >= MIN_CLUSTER {
            let n = members.len() as f64;
            let cu = members.iter().map(|q| f64::from(q.l[0])).sum::<f64>() / n;
            let cv = members.iter().map(|q| f64::from(q.l[1])).sum::<f64>() / n;
            let du = members.iter().map(|q| f64::from(q.l[0]) - q.r[0]).sum::<f64>() / n;
            let dv = members.iter().map(|q| f64::from(q.l[1]) - q.r[1]).sum::<f64>() / n;
            let extent = members
                .iter()
                .map(|q| (f64::from(q.l[0]) - cu).hypot(f64::from(q.l[1]) - cv))
                .fold(0.0, f64::max);
            return Some(Last {
                centre: [cu, cv],
                offset: [du, dv],
                z: median(members.iter().map(|q| q.z).collect()),
                extent: extent + f64::from(grid_step(l.w)),
                points: 0,
            });
        }
    }
    None
}

/// The dense matches of the region around `s` at its depth: the target and its extent.
fn dense(l: &Plane, r: &Plane, s: &Last, joints: &Joints, est: &Estimator) -> Option<(Found, f64)> {
    let ext = (s.extent + 12.0).min(MAX_EXTENT);
    let (c0, c1) = ((s.centre[0] - ext).floor() as i32, (s.centre[0] + ext).ceil() as i32);
    let (r0, r1) = ((s.centre[1] - ext).floor() as i32, (s.centre[1] + ext).ceil() as i32);
    // Rows in parallel, matches in row-major order (the same on any number of threads).
    let xs: Vec<i32> = (c0..=c1).step_by(DENSE_STEP as usize).collect();
    let pts: Vec<Pt> = (r0..=r1)
        .step_by(DENSE_STEP as usize)
        .collect::<Vec<i32>>()
        .par_iter()
        .flat_map_iter(|&y| {
            xs.iter().filter_map(move |&x| {
                let ur = f64::from(x) - s.offset[0];
                let vr = f64::from(y) - s.offset[1];
                let (uc, vc) = (ur.round() as i32, vr.round() as i32);
                let (u, v, _) = search(l, r, x, y, [uc - 5, uc + 5], [vc - 2, vc + 2], 4)?;
                let z = depth_of(est, joints, [x, y], [u, v])?;
                in_band(z, s.z).then_some(Pt { l: [x, y], r: [u, v], z })
            })
        })
        .collect();
    if pts.len() < MIN_CLUSTER {
        return None;
    }
    let n = pts.len() as f64;
    let mean = |f: &dyn Fn(&Pt) -> f64| pts.iter().map(f).sum::<f64>() / n;
    let px = [
        mean(&|p| f64::from(p.l[0])),
        mean(&|p| f64::from(p.l[1])),
        mean(&|p| p.r[0]),
        mean(&|p| p.r[1]),
    ];
    let extent = pts
        .iter()
        .map(|p| (f64::from(p.l[0]) - px[0]).hypot(f64::from(p.l[1]) - px[1]))
        .fold(0.0, f64::max);
    let z = median(pts.iter().map(|p| p.z).collect());
    Some((Found { px, z, points: pts.iter().map(|p| p.l).collect() }, extent))
}

#[cfg(test)]
mod tests {
    use super::*;
    use hvs_shared::runtime::traditional::Calibration;
    use hvs_shared::sim::posture::HeadRig;
    use hvs_shared::sim::presets;
    use hvs_vision::render::RenderOptions;
    use hvs_vision::scene::{render_scene, SceneFile, SceneRender};

    const SCENE: &str = r#"{ "rig": {"case": 1}, "camera_fps": 30,
      "background": {"z_cm": 300, "texture_seed": 1},
      "objects": [ {"shape": "sphere", "radius_cm": 8, "centre_cm": [10, -5, 90], "texture_seed": 2} ] }"#;

    /// `nearest` follows the object it holds for `RESCAN_FRAMES` frames, then scans and takes
    /// a nearer one that came into view; when the held one leaves, a scan within
    /// `RESCAN_FRAMES + 1` frames takes the nearest left.
    #[test]
    fn the_nearest_is_followed_then_scanned_for_again() {
        let render = |objects: &str| {
            let text = format!(
                r#"{{ "rig": {{"case": 1}}, "camera_fps": 30,
                  "background": {{"z_cm": 300, "texture_seed": 1}}, "objects": [ {objects} ] }}"#
            );
            let scene = SceneFile::parse(&text).unwrap().scene().unwrap().at(0.0);
            let head = HeadRig::new(presets::case(1).unwrap());
            let r = render_scene(&head, &Joints::HOME, &scene, &RenderOptions::default(), 5);
            (head, r.unwrap())
        };
        let a =
            r#"{"shape": "sphere", "radius_cm": 8, "centre_cm": [10, -5, 90], "texture_seed": 2}"#;
        let b =
            r#"{"shape": "sphere", "radius_cm": 8, "centre_cm": [-20, 5, 70], "texture_seed": 3}"#;
        let (head, only_a) = render(a);
        let (_, both) = render(&format!("{a}, {b}"));
        let est = Estimator::Fallback(Calibration::BUILT_IN);
        let near = |f: &Option<Found>, centre: [f64; 3]| {
            let t = head.project(&Joints::HOME, &centre).unwrap();
            f.as_ref().is_some_and(|f| (f.px[0] - t[0]).hypot(f.px[1] - t[1]) < 6.0)
        };
        let (at_a, at_b) = ([10.0, -5.0, 90.0], [-20.0, 5.0, 70.0]);
        let mut f = Finder::new(TargetMode::Nearest);
        let mut find = |r: &SceneRender| f.find(&r.left, &r.right, &Joints::HOME, &est);
        assert!(near(&find(&only_a), at_a), "A, the only object");
        for k in 0..RESCAN_FRAMES {
            assert!(near(&find(&both), at_a), "A followed in frame {k} after the scan");
        }
        assert!(near(&find(&both), at_b), "the scan takes the nearer B");
        assert!(near(&find(&both), at_b), "B followed");
        let mut g = Finder::new(TargetMode::Nearest);
        let mut find = |r: &SceneRender| g.find(&r.left, &r.right, &Joints::HOME, &est);
        assert!(near(&find(&both), at_b));
        let (_, only_a_again) = render(a);
        // When B leaves, its region may still give matches at its depth for a few frames
        // (the wall's texture, in the narrow search around B's old offset); the next scan, at
        // the latest `RESCAN_FRAMES` frames on, takes A.
        let took_a = (0..=RESCAN_FRAMES).position(|_| near(&find(&only_a_again), at_a));
        assert!(took_a.is_some(), "A taken within {} frames", RESCAN_FRAMES + 1);
    }

    #[test]
    fn the_nearest_is_the_largest_disparity_even_when_depths_are_wrong() {
        // Case III's deflected cameras with the built-in (parallel-camera) calibration: its
        // depths are wrong everywhere, the wall's nearer than the sphere's in places, but the
        // order of the disparities is not. A small sphere (5 cm at 90 cm, 32 px across).
        const SMALL: &str = r#"{ "rig": {"case": 3}, "camera_fps": 30,
          "background": {"z_cm": 300, "texture_seed": 1},
          "objects": [ {"shape": "sphere", "radius_cm": 5, "centre_cm": [20, -8, 90], "texture_seed": 2} ] }"#;
        let scene = SceneFile::parse(SMALL).unwrap().scene().unwrap().at(0.0);
        let head = HeadRig::new(presets::case(3).unwrap());
        let r = render_scene(&head, &Joints::HOME, &scene, &RenderOptions::default(), 5).unwrap();
        let est = Estimator::Fallback(Calibration::BUILT_IN);
        let found = Finder::new(TargetMode::Nearest)
            .find(&r.left, &r.right, &Joints::HOME, &est)
            .expect("a target");
        let truth = head.project(&Joints::HOME, &[20.0, -8.0, 90.0]).unwrap();
        let e = (found.px[0] - truth[0]).hypot(found.px[1] - truth[1]);
        assert!(e < 6.0, "centroid {:?} vs the sphere's centre {:?}", found.px, truth);
    }

    #[test]
    fn matches_are_true_and_the_nearest_is_the_sphere() {
        // Case I at home: the traditional method's depth is right, so this checks the
        // matcher and the clustering alone.
        let scene = SceneFile::parse(SCENE).unwrap().scene().unwrap().at(0.0);
        let head = HeadRig::new(presets::CASE_1);
        let r = render_scene(&head, &Joints::HOME, &scene, &RenderOptions::default(), 3).unwrap();
        let (l, rr) = (Plane::new(&r.left), Plane::new(&r.right));
        let est = Estimator::Fallback(Calibration::BUILT_IN);
        let (mut n, mut bad) = (0, 0);
        for y in (100..380).step_by(40) {
            for x in (100..540).step_by(40) {
                if let Some(p) = coarse_match(&l, &rr, [x, y], &Joints::HOME, &est) {
                    n += 1;
                    if let Some(t) = r.true_match(x as u32, y as u32) {
                        if (t[0] - p.r[0]).abs() > 1.0 || (t[1] - p.r[1]).abs() > 1.0 {
                            bad += 1;
                        }
                    }
                }
            }
        }
        assert!(n > 40 && bad * 20 <= n, "{bad} wrong of {n}");
        let mut f = Finder::new(TargetMode::Nearest);
        let found = f.find(&r.left, &r.right, &Joints::HOME, &est).expect("a target");
        let truth = head.project(&Joints::HOME, &[10.0, -5.0, 90.0]).unwrap();
        let e = (found.px[0] - truth[0]).hypot(found.px[1] - truth[1]);
        assert!(e < 3.0, "centroid {:?} vs {:?}", found.px, truth);
        assert!((found.z - 82.0).abs() < 6.0, "z {}", found.z);
    }
}
