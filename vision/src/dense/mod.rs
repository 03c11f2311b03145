//! Dense matching: every pixel of the left image found in the right one by semi-global
//! matching on census costs, in the original (unrectified) images.
//!
//! # Method
//!
//! 1. [`census`]: a 7 x 5 census word per pixel of both images; the right image's from a
//!    window scaled by [`DenseParams::right_scale`] where the cameras' focal lengths differ
//!    ([`census::census_scaled`]), so that both words cover about the same patch.
//! 2. Cost volume: for left pixel `(x, y)` and each whole disparity `d` of the range
//!    (`d = u_l - u_r`, bounded by the caller, e.g. from the model's depth box), the candidate
//!    is the right pixel on the epipolar line `F (x, y, 1)^T` at `u_r = x - d`, `v_r` rounded
//!    to the nearest row; the cost is the Hamming distance of the two census words
//!    ([`census::MAX_COST`] at most). Sampling along the epipolar line instead of rectifying
//!    first leaves the images unresampled and gives matches in the original pixel
//!    coordinates directly; lines steeper than 45 degrees are refused, like
//!    [`crate::matching`] does.
//! 3. [`sgm`]: semi-global aggregation along 8 (or 4) paths, `P2` adaptive to the grey-level
//!    step.
//! 4. Winner takes all, with a uniqueness ratio against the best disparity more than one
//!    step away; a minimum at either end of the range is refused (the match lies outside the
//!    depth box); sub-pixel by an equiangular fit through the three sums around the minimum.
//! 5. Left-right check: the same with the right image as reference (`F^T`); when every
//!    candidate of step 2 lay on its left pixel's own row (a rectified pair, or lines that
//!    round to their own rows) read off the same aggregated volume unless
//!    [`DenseParams::aggregate_right`] asks for its own, otherwise a second aggregation. A
//!    left match whose right pixel disagrees by more than
//!    [`DenseParams::lr_tolerance_px`] is dropped (where the right image's scale is not 1:
//!    the round trip's miss at that scale, in the pixels of the coarser image), and so is
//!    one whose census window, or its right pixel's, is one grey level
//!    ([`census::flat_windows`]: blank, or clipped to black or white): the aggregation
//!    carries an answer into such a window from its neighbours or the image border, with no
//!    evidence of its own (a quarter of such matches lay 2 px or more off in over-exposed
//!    copies of the Motorcycle pair). So an image of one
//!    grey level, every window of it flat, gets no match at all.
//! 6. Speckle filter: connected regions of similar disparity smaller than
//!    [`DenseParams::speckle_size`] pixels are dropped. Then, for a rectified pair of
//!    cameras alike, depth edges are put back where the grey levels say: a pixel beside a
//!    farther neighbour takes that neighbour's winner when shifted 5 x 5 windows fit its
//!    disparity better than its own (the foreground spreads onto the background across an
//!    edge; `post::edge_switch`).
//! 7. Sub-pixel refinement on the grey levels: a 1-D Lucas-Kanade fit of a 7 x 7 window
//!    (9 x 9 where warped) along the epipolar line (zero-mean, gain-matched), at most half a
//!    pixel. For a rectified pair of cameras alike, two steps of the window shifted along its
//!    row, with the left window's derivative (inverse-compositional), in `f32` with a window
//!    row per 8-lane vector. Otherwise (verged or rolled cameras, another right scale) one step of the
//!    window warped as the matches around the pixel say: the least-squares plane of `u_r`
//!    over its 9 x 9 neighbourhood gives where each window pixel lies in the right image, on
//!    its own epipolar line, sampled bicubically; a window of fixed shape misses the local
//!    roll, scale and slant of verged cameras by a few hundredths of a pixel at its corners,
//!    which was most of the depth error at 3 m.
//! 8. When asked for ([`DenseParams::refuse_past_gaps`]), the first match past a run of
//!    unmatched pixels along a row is dropped where it is nearer than the match before the
//!    run: the run is mostly the strip the right camera does not see beside a nearer object,
//!    and that match most often the nearer object spread over it.
//! 9. A confidence in `0..1` per kept pixel ([`confidence`]).
//!
//! Memory: 3 bytes per cell of the volume at most. With one thread 2 (the forward pass keeps
//! each cell's cost and its sum packed in one `u16`; the costs are computed as the pass
//! reaches each row, no volume of costs), or 3 with a `P2` too large to pack (`u8` costs and
//! the forward pass's `i16` sums). With two threads, `u8` costs and one volume of `i16` sums
//! at most (the passes run side by side; the rows one pass has finished and the other not
//! yet reached, all of them when they meet in the middle of the image). [`MAX_CELLS`] bounds
//! it.
//!
//! Speed: the loops over disparities are written for the compiler to vectorise (fixed-size
//! chunks, every lane stored: the winner is the smallest key `sum << 16 | index`, the right
//! image's disparities running minima over the volume in its own order) and run
//! compiled for AVX-512 or AVX2 where the CPU has them ([`pulp`]'s runtime check; the same
//! integers and floats as without), census costs by hardware popcount (AVX-512's `VPOPCNTQ`,
//! eight at a time, where present); rows go to the winners as soon as the aggregation
//! completes them. Every stage is the same arithmetic on one thread or many,
//! so the output does not depend on the thread count.

pub mod census;
mod post;
pub mod sgm;

use crate::geometry::Fundamental;
use crate::invalid::InvalidField;
use image::GrayImage;

pub use post::confidence;

/// The most cells (`width * height * disparities`) a volume may have: 64 million, a 640 x 480
/// pair over 208 disparities (a verged pair over 66-332 cm searches 171 there; its peak resident
/// size with two threads was 178 MB).
pub const MAX_CELLS: u64 = 64_000_000;

/// The knobs of [`dense_match`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DenseParams {
    /// 8 aggregation paths (`true`) or 4.
    pub eight_paths: bool,
    /// Penalty of a 1-px disparity step (census cost units, 0..34 per pixel).
    pub p1: u16,
    /// Penalty of a larger jump where the grey level does not change.
    pub p2: u16,
    /// `P2` falls as `p2 * g / (g + |dI|)` with the grey-level step `dI`, never below
    /// `p1 + 1`; `0` keeps `P2` constant.
    pub p2_gamma: f32,
    /// The best sum must be below `(1 - uniqueness)` times the best one more than one
    /// disparity away.
    pub uniqueness: f32,
    /// Most disagreement (px) of the left-right check.
    pub lr_tolerance_px: f32,
    /// Regions of fewer pixels than this are dropped by the speckle filter (0: no filter).
    pub speckle_size: usize,
    /// Most disparity step (px) between neighbours of one speckle region.
    pub speckle_range_px: f32,
    /// The right image's scale against the left's along `u` and `v` (the right camera's
    /// focal lengths over the left's; a model's matcher geometry carries it): the right
    /// image's census windows ([`census::census_scaled`]) and the sub-pixel refinement's
    /// right windows are of that scale. `[1, 1]` for cameras alike.
    pub right_scale: [f32; 2],
    /// How `right_scale` changes across the right image (per px of its column `u_r`, about
    /// its centre column `(w - 1) / 2`): the scale of column `u_r` is `right_scale +
    /// right_scale_slope (u_r - (w - 1) / 2)`, quantised to steps of 1/128 (a verged pair of
    /// unequal focal lengths sees nearer to the focal ratio in the middle than at the
    /// edges; `hvs depth` fits it from the model). Used only where `right_scale` differs
    /// from 1 ([`matcher_scale`]); `[0, 0]` for one scale everywhere.
    pub right_scale_slope: [f32; 2],
    /// The left-right check's right-image disparities from an aggregation of their own, the
    /// right image as reference (Hirschmueller's check; `true`), instead of read off the
    /// left image's aggregated volume (OpenCV's way, for a rectified pair: one aggregation
    /// instead of two). Its own aggregation spreads the foreground over the background on
    /// the other side of an object, so the two disagree where either spread it. A pair that
    /// is not rectified always gets its own.
    pub aggregate_right: bool,
    /// Drop the first match past each run of unmatched pixels along a row when it is more
    /// than 1.5 px nearer (larger disparity) than the match before the run: the run is
    /// mostly the strip beside a nearer object that the right camera does not see, and the
    /// match past it most often that object spread over the strip.
    pub refuse_past_gaps: bool,
}

impl Default for DenseParams {
    /// Chosen on the synthetic pairs of the tests and on the Motorcycle pair (see the README's
    /// `hvs depth` section for the measurement).
    fn default() -> Self {
        DenseParams {
            eight_paths: true,
            p1: 18,
            p2: 96,
            p2_gamma: 8.0,
            uniqueness: 0.02,
            lr_tolerance_px: 1.5,
            speckle_size: 50,
            speckle_range_px: 1.0,
            right_scale: [1.0, 1.0],
            right_scale_slope: [0.0, 0.0],
            aggregate_right: false,
            refuse_past_gaps: false,
        }
    }
}

impl DenseParams {
    /// The default with the left-right check by an aggregation of the right image of its own
    /// and the first nearer match past a gap dropped: fewer wrong matches beside depth edges,
    /// for about 40 % more time on a rectified pair (`hvs locate`, `hvs view`, `hvs depth
    /// --thorough`). Chosen on six held-out Middlebury scenes (`scripts/depth_heldout.py`,
    /// not the Motorcycle pair of the goals): mean 2.39 -> 1.80 % of the returned more than
    /// 2 px off, 4.59 -> 4.03 % more than 1 px, 93.35 -> 93.25 % returned.
    pub fn thorough() -> Self {
        DenseParams { aggregate_right: true, refuse_past_gaps: true, ..DenseParams::default() }
    }

    /// Checks every field's range.
    pub fn validate(&self) -> Result<(), InvalidField> {
        use crate::invalid::in_range;
        for (field, v) in [
            ("params.p2_gamma", self.p2_gamma),
            ("params.uniqueness", self.uniqueness),
            ("params.lr_tolerance_px", self.lr_tolerance_px),
            ("params.speckle_range_px", self.speckle_range_px),
        ] {
            if !v.is_finite() {
                return Err(InvalidField::new(field, format!("must be finite, got {v}")));
            }
        }
        in_range("params.p1", self.p1, 1, 500)?;
        in_range("params.p2", self.p2, self.p1, 2000)?;
        in_range("params.p2_gamma", self.p2_gamma, 0.0, 255.0)?;
        in_range("params.uniqueness", self.uniqueness, 0.0, 0.99)?;
        in_range("params.lr_tolerance_px", self.lr_tolerance_px, 0.0, 100.0)?;
        in_range("params.speckle_range_px", self.speckle_range_px, 0.0, 100.0)?;
        for (field, v) in [
            ("params.right_scale[0]", self.right_scale[0]),
            ("params.right_scale[1]", self.right_scale[1]),
        ] {
            if !v.is_finite() {
                return Err(InvalidField::new(field, format!("must be finite, got {v}")));
            }
            in_range(field, v, 0.25, 4.0)?;
        }
        for (field, v) in [
            ("params.right_scale_slope[0]", self.right_scale_slope[0]),
            ("params.right_scale_slope[1]", self.right_scale_slope[1]),
        ] {
            if !v.is_finite() {
                return Err(InvalidField::new(field, format!("must be finite, got {v}")));
            }
        }
        Ok(())
    }
}

/// Why [`dense_match`] did not run.
#[derive(Debug, Clone, PartialEq)]
pub enum DenseError {
    /// A parameter or input is out of range.
    Invalid(InvalidField),
    /// The volume would have more than [`MAX_CELLS`] cells (width, height, disparities).
    TooLarge(u32, u32, usize),
}

impl std::fmt::Display for DenseError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            DenseError::Invalid(e) => write!(f, "{e}"),
            DenseError::TooLarge(w, h, d) => write!(
                f,
                "{w}x{h} pixels x {d} disparities is {} cells, more than the {MAX_CELLS} the cost volume may have (scale the images down, or narrow the disparities searched)",
                u64::from(*w) * u64::from(*h) * *d as u64
            ),
        }
    }
}

impl std::error::Error for DenseError {}

impl From<InvalidField> for DenseError {
    fn from(e: InvalidField) -> Self {
        DenseError::Invalid(e)
    }
}

/// Every left pixel's match. Vectors are rows first, `width * height` long.
#[derive(Debug, Clone, PartialEq)]
pub struct DenseMap {
    /// Image width (px).
    pub width: u32,
    /// Image height (px).
    pub height: u32,
    /// Right `u` of each left pixel's match (`+inf` where none).
    pub ur: Vec<f32>,
    /// Right `v`, on the epipolar line (`+inf` where none).
    pub vr: Vec<f32>,
    /// Confidence `0..1` (`0` where none).
    pub conf: Vec<f32>,
}

impl DenseMap {
    /// A `width x height` map without a match: `+inf` everywhere, confidence 0.
    pub fn none(width: u32, height: u32) -> Self {
        let n = width as usize * height as usize;
        let ur = vec![f32::INFINITY; n];
        DenseMap { width, height, vr: ur.clone(), ur, conf: vec![0.0; n] }
    }

    /// How many pixels have a match.
    pub fn matched(&self) -> usize {
        self.ur.iter().filter(|u| u.is_finite()).count()
    }
}

/// The epipolar geometry of one reference image: the line in the other image is
/// `m (x, y, 1)^T`, the other image's `u` is `x + sign * d`.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Geo {
    pub m: [[f64; 3]; 3],
    pub sign: i32,
    pub d_min: i32,
    pub d: usize,
    pub w: usize,
    pub h: usize,
}

impl Geo {
    /// `v = alpha + beta u` of the line of `(x, y)` in the other image, `None` when it is
    /// steeper than 45 degrees or not finite.
    #[inline]
    pub fn line(&self, x: usize, y: usize) -> Option<(f64, f64)> {
        let (x, y) = (x as f64, y as f64);
        let l: [f64; 3] =
            core::array::from_fn(|i| self.m[i][0] * x + self.m[i][1] * y + self.m[i][2]);
        if !(l[1].abs() >= l[0].abs() && l[1] != 0.0) {
            return None;
        }
        let (alpha, beta) = (-l[2] / l[1], -l[0] / l[1]);
        (alpha.is_finite() && beta.is_finite()).then_some((alpha, beta))
    }

    /// The other image's `u` at disparity index `k`.
    #[inline]
    pub fn u_at(&self, x: usize, k: usize) -> i64 {
        x as i64 + i64::from(self.sign) * (i64::from(self.d_min) + k as i64)
    }

    /// The other image's row at its column `u` on `line`, if inside it (rounded to the
    /// nearest row).
    #[inline]
    pub fn v_at(&self, line: (f64, f64), u: i64) -> Option<usize> {
        let v = line.0 + line.1 * u as f64 + 0.5;
        // Truncation is the floor for v >= 0 (no libm call).
        (v >= 0.0 && v < self.h as f64).then_some(v as usize)
    }

    /// The other image's pixel at disparity index `k`, if inside it.
    #[inline]
    pub fn target(&self, x: usize, line: (f64, f64), k: usize) -> Option<(usize, usize)> {
        let u = self.u_at(x, k);
        if u < 0 || u >= self.w as i64 {
            return None;
        }
        self.v_at(line, u).map(|v| (u as usize, v))
    }

    /// The disparity indices `k_lo..=k_hi` whose target lies inside the other image (one run:
    /// `u` and `v` are monotonic in `k`), `None` when there is none.
    pub fn valid_range(&self, x: usize, line: (f64, f64)) -> Option<(usize, usize)> {
        // u = x + sign (d_min + k) in 0..w.
        let (w, d) = (self.w as i64, self.d as i64);
        let base = x as i64 + i64::from(self.sign) * i64::from(self.d_min);
        let (mut lo, mut hi) =
            if self.sign < 0 { (base - (w - 1), base) } else { (-base, w - 1 - base) };
        lo = lo.max(0);
        hi = hi.min(d - 1);
        while lo <= hi && self.target(x, line, lo as usize).is_none() {
            lo += 1;
        }
        while hi >= lo && self.target(x, line, hi as usize).is_none() {
            hi -= 1;
        }
        (lo <= hi).then_some((lo as usize, hi as usize))
    }
}

/// The census costs of `geo` a row at a time ([`cost_row`]; [`sgm::aggregate_rows`] asks for
/// them): out-of-image candidates cost half the most, so that the aggregation carries the
/// neighbours' answer across them (they are never chosen). It records whether every
/// candidate of the rows asked for lay on its reference pixel's own row (the volume is then
/// that of a rectified pair, whatever `geo`'s lines are before rounding). Compiled for
/// AVX-512's vector population count where the CPU has it, else as [`fast`].
struct CensusCosts<'a> {
    geo: &'a Geo,
    reference: &'a [u64],
    /// The other image's census words, each row reversed when `reversed`.
    words: std::borrow::Cow<'a, [u64]>,
    reversed: bool,
    own_rows: std::sync::atomic::AtomicBool,
}

impl<'a> CensusCosts<'a> {
    fn new(geo: &'a Geo, reference: &'a [u64], other: &'a [u64]) -> Self {
        let w = geo.w;
        // With the left image as reference (`sign < 0`) a pixel's candidates run right to
        // left along the other image's row: its rows reversed, so that each run is read
        // forwards.
        let reversed = geo.sign < 0;
        let words = if reversed {
            other.chunks_exact(w).flat_map(|r| r.iter().rev().copied()).collect::<Vec<_>>().into()
        } else {
            other.into()
        };
        CensusCosts {
            geo,
            reference,
            words,
            reversed,
            own_rows: std::sync::atomic::AtomicBool::new(true),
        }
    }

    /// Whether every candidate of the rows computed so far lay on its own row.
    fn own_rows(&self) -> bool {
        self.own_rows.load(std::sync::atomic::Ordering::Relaxed)
    }
}

impl sgm::CostRows for CensusCosts<'_> {
    fn row(&self, y: usize, out: &mut [u8]) {
        let other = Rows { words: &self.words, reversed: self.reversed };
        let (geo, reference) = (self.geo, self.reference);
        // Every row is computed (no short cut on the first row off its line).
        let own = 'own: {
            #[cfg(target_arch = "x86_64")]
            if let Some(simd) = Popcnt512::try_new() {
                break 'own simd.vectorize(
                    #[inline(always)]
                    move || {
                        let out = out;
                        cost_row(geo, reference, other, y, out)
                    },
                );
            }
            fast(
                #[inline(always)]
                move || {
                    let out = out;
                    cost_row(geo, reference, other, y, out)
                },
            )
        };
        if !own {
            self.own_rows.store(false, std::sync::atomic::Ordering::Relaxed);
        }
    }
}

/// The whole census cost volume of `geo` (`w * h * d`, [`CensusCosts`]) and whether every
/// candidate lay on its own row.
#[cfg(test)]
fn cost_volume(geo: &Geo, reference: &[u64], other: &[u64]) -> (Vec<u8>, bool) {
    use sgm::CostRows;
    let costs = CensusCosts::new(geo, reference, other);
    let mut cost = vec![0u8; geo.w * geo.h * geo.d];
    for (y, row) in cost.chunks_mut(geo.w * geo.d).enumerate() {
        costs.row(y, row);
    }
    let own = costs.own_rows();
    (cost, own)
}

#[cfg(target_arch = "x86_64")]
pulp::simd_type! {
    /// AVX-512 with its 64-bit population count (`VPOPCNTQ`), for [`cost_row`]'s census
    /// costs: eight Hamming distances an instruction (the same integers as `popcnt`).
    struct Popcnt512 {
        pub sse: "sse",
        pub sse2: "sse2",
        pub sse3: "sse3",
        pub ssse3: "ssse3",
        pub sse4_1: "sse4.1",
        pub sse4_2: "sse4.2",
        pub popcnt: "popcnt",
        pub avx: "avx",
        pub avx2: "avx2",
        pub bmi1: "bmi1",
        pub bmi2: "bmi2",
        pub avx512f: "avx512f",
        pub avx512bw: "avx512bw",
        pub avx512vl: "avx512vl",
        pub avx512vpopcntdq: "avx512vpopcntdq",
    }
}

/// The other image's census words by row, each row stored reversed (`reversed`) or not.
#[derive(Clone, Copy)]
struct Rows<'a> {
    words: &'a [u64],
    reversed: bool,
}

/// Row `y` of [`cost_volume`] (`row`: `w * d` cells); whether every candidate lay on row `y`
/// of the other image.
#[inline(always)]
fn cost_row(geo: &Geo, reference: &[u64], other: Rows, y: usize, row: &mut [u8]) -> bool {
    let (w, d) = (geo.w, geo.d);
    let mut own_row = true;
    for x in 0..w {
        let cells = &mut row[x * d..(x + 1) * d];
        let Some((line, (lo, hi))) =
            geo.line(x, y).and_then(|line| Some((line, geo.valid_range(x, line)?)))
        else {
            cells.fill(census::MAX_COST / 2);
            continue;
        };
        // Candidates outside the other image.
        cells[..lo].fill(census::MAX_COST / 2);
        cells[hi + 1..].fill(census::MAX_COST / 2);
        let c = reference[y * w + x];
        // The other image's row `v` is a monotonic step function of `k` (`u` and the line's
        // `v` are linear in `k`, and rounding is monotonic): runs of one row, each found by
        // bisection, then a contiguous stretch of that row. A rectified pair has one run.
        let v_of = |k: usize| geo.v_at(line, geo.u_at(x, k)).expect("inside: valid_range");
        let mut k = lo;
        while k <= hi {
            let v = v_of(k);
            // The last `k` of this row: v_of(end) == v, v_of(end + 1) != v (or end == hi).
            let (mut end, mut past) = (k, hi + 1);
            // The whole rest on one row (always, for a rectified pair): no bisection.
            if v_of(hi) == v {
                end = hi;
            }
            while past - end > 1 {
                let mid = end + (past - end) / 2;
                if v_of(mid) == v {
                    end = mid;
                } else {
                    past = mid;
                }
            }
            own_row &= v == y;
            let other_row = &other.words[v * w..(v + 1) * w];
            // The first candidate's place in the stored row: `u` runs backwards with `k` when
            // the row is stored reversed, forwards otherwise.
            let u = geo.u_at(x, k) as usize;
            let first = if other.reversed { w - 1 - u } else { u };
            let run = &mut cells[k..end + 1];
            let n = run.len();
            for (cell, &o) in run.iter_mut().zip(&other_row[first..first + n]) {
                *cell = (c ^ o).count_ones() as u8;
            }
            k = end + 1;
        }
    }
    own_row
}

/// The checks [`dense_match`] makes before matching: the parameters, the images (the same
/// size, not empty), `f` and `d_range`, and the volume's size against [`MAX_CELLS`]. Returns
/// the number of disparities.
pub fn check_inputs(
    left: &GrayImage,
    right: &GrayImage,
    f: &Fundamental,
    d_range: [i32; 2],
    params: &DenseParams,
) -> Result<usize, DenseError> {
    params.validate()?;
    crate::invalid::same_size(left, right)?;
    let (w, h) = (left.width() as usize, left.height() as usize);
    if w == 0 || h == 0 {
        return Err(InvalidField::new("left", "image is empty").into());
    }
    if !f.m.iter().flatten().all(|x| x.is_finite()) || f.m.iter().flatten().all(|&x| x == 0.0) {
        return Err(InvalidField::new("fundamental", "must be finite and not all zero").into());
    }
    if d_range[0] > d_range[1] {
        return Err(InvalidField::new(
            "d_range",
            format!("{}..{} is empty", d_range[0], d_range[1]),
        )
        .into());
    }
    let d = (i64::from(d_range[1]) - i64::from(d_range[0]) + 1) as usize;
    if (w * h) as u64 * d as u64 > MAX_CELLS {
        return Err(DenseError::TooLarge(left.width(), left.height(), d));
    }
    Ok(d)
}

/// The right/left image scale as the matcher takes it: each axis within 0.5 % of 1 is 1
/// (across the 7-px window, under 0.02 px), the faster path; `[1, 1]` means the plain census
/// and refinement.
pub fn matcher_scale(right_scale: [f32; 2]) -> [f64; 2] {
    right_scale.map(|s| if (s - 1.0).abs() < 0.005 { 1.0 } else { f64::from(s) })
}

/// Matches every pixel of `left` in `right` (same size) with `f` (`r^T F l = 0`) over the
/// whole disparities `d_range[0]..=d_range[1]` (`d = u_l - u_r`, px). See the module
/// documentation for the method.
pub fn dense_match(
    left: &GrayImage,
    right: &GrayImage,
    f: &Fundamental,
    d_range: [i32; 2],
    params: &DenseParams,
) -> Result<DenseMap, DenseError> {
    let d = check_inputs(left, right, f, d_range, params)?;
    let (w, h) = (left.width() as usize, left.height() as usize);
    let scale = matcher_scale(params.right_scale);
    // The right image's census windows at its scale (per column when it has a slope), so that
    // they cover the same patch of the scene as the left ones (the candidates and matches
    // stay in its own pixels).
    let ((cl, flat_l), (cr, flat_r)) = rayon::join(
        || (census::census(left), census::flat_windows(left)),
        || {
            let words = if scale == [1.0, 1.0] {
                census::census(right)
            } else {
                census::census_scaled(right, scale, params.right_scale_slope.map(f64::from))
            };
            (words, census::flat_windows(right))
        },
    );
    let pen = penalties(params);
    let lgeo = Geo { m: f.m, sign: -1, d_min: d_range[0], d, w, h };
    // Rectified when every candidate lay on its own row: the right image's disparities are
    // then read off the same volume (no second aggregation). Every row's costs are computed
    // before the first row of sums is handed over, so the answer is known by then.
    let costs = CensusCosts::new(&lgeo, &cl, &cr);
    // Each row of the aggregated volume as soon as it is complete: its winners and, for a
    // rectified pair, the right image's disparities of the same row.
    let rows = sgm::aggregate_rows(&costs, left.as_raw(), (w, h, d), &pen, |y, sums| {
        let best = post::winners_row(&lgeo, y, sums, params.uniqueness);
        let read_right = costs.own_rows() && !params.aggregate_right;
        (best, read_right.then(|| post::right_from_left_row(&lgeo, sums)))
    });
    let rectified = costs.own_rows();
    drop(costs);
    let mut best = Vec::with_capacity(w * h);
    let mut right_disp = Vec::with_capacity(if rectified { w * h } else { 0 });
    for (b, r) in rows {
        best.extend(b);
        right_disp.extend(r.into_iter().flatten());
    }
    // The right image's disparities for the left-right check, by a second aggregation when
    // the pair is not rectified or when asked for.
    if !rectified || params.aggregate_right {
        let mt = core::array::from_fn(|i| core::array::from_fn(|j| f.m[j][i]));
        let rgeo = Geo { m: mt, sign: 1, ..lgeo };
        let costs = CensusCosts::new(&rgeo, &cr, &cl);
        let rows = sgm::aggregate_rows(&costs, right.as_raw(), (w, h, d), &pen, |y, sums| {
            post::winners_row(&rgeo, y, sums, 0.0)
        });
        drop(costs);
        right_disp = rows.into_iter().flatten().map(|b| b.map(|b| b.disparity)).collect();
    }
    // The left-right check's round trip at the right image's scale along u where it is not 1.
    let lr_scale = (scale != [1.0, 1.0]).then(|| post::ColumnScale {
        scale: scale[0],
        slope: f64::from(params.right_scale_slope[0]),
        centre: (w as f64 - 1.0) / 2.0,
    });
    post::left_right_check(
        &lgeo,
        &mut best,
        &right_disp,
        (&flat_l, &flat_r),
        params.lr_tolerance_px,
        lr_scale,
    );
    post::speckle_filter(w, h, &mut best, params.speckle_size, params.speckle_range_px);
    if rectified && scale == [1.0, 1.0] {
        post::edge_switch(&lgeo, (left.as_raw(), right.as_raw()), &mut best);
    }
    post::refine(&lgeo, (left.as_raw(), right.as_raw()), scale, rectified, &mut best);
    if params.refuse_past_gaps {
        post::past_gaps(w, &mut best);
    }
    Ok(post::to_map(&lgeo, &best, params.lr_tolerance_px))
}

/// Runs `f` compiled for the best instruction set of this CPU (AVX-512 or AVX2 and their
/// companions where present, by [`pulp`]'s runtime check; plain x86-64 otherwise). Only the
/// speed differs: integer code gives the same integers, and float code the same floats (Rust
/// does not fuse or reorder float operations).
#[inline(always)]
pub(crate) fn fast<R>(f: impl FnOnce() -> R) -> R {
    struct Op<F>(F);
    impl<R, F: FnOnce() -> R> pulp::WithSimd for Op<F> {
        type Output = R;
        #[inline(always)]
        fn with_simd<S: pulp::Simd>(self, _: S) -> R {
            (self.0)()
        }
    }
    pulp::Arch::new().dispatch(Op(f))
}

fn penalties(p: &DenseParams) -> sgm::Penalties {
    let mut p2 = [p.p2 as i16; 256];
    if p.p2_gamma > 0.0 {
        for (di, v) in p2.iter_mut().enumerate() {
            let g = p.p2_gamma;
            let s = f32::from(p.p2) * g / (g + di as f32);
            *v = (s.round() as i16).max(p.p1 as i16 + 1);
        }
    }
    sgm::Penalties { p1: p.p1 as i16, p2, eight: p.eight_paths }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bad_input_is_refused_with_its_field() {
        let img = GrayImage::new(20, 10);
        let f = Fundamental { m: [[0.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]] };
        let p = DenseParams::default();
        let e = dense_match(&img, &GrayImage::new(21, 10), &f, [0, 4], &p).unwrap_err();
        assert!(e.to_string().starts_with("right: image is 21x10"), "{e}");
        let e = dense_match(&img, &img, &f, [5, 4], &p).unwrap_err();
        assert!(e.to_string().starts_with("d_range"), "{e}");
        let e = dense_match(&img, &img, &Fundamental { m: [[0.0; 3]; 3] }, [0, 4], &p).unwrap_err();
        assert!(e.to_string().starts_with("fundamental"), "{e}");
        let big = GrayImage::new(4000, 4000);
        let e = dense_match(&big, &big, &f, [0, 4], &p).unwrap_err();
        assert_eq!(e, DenseError::TooLarge(4000, 4000, 5));
        assert!(e.to_string().contains("more than the 64000000"), "{e}");
        let bad = DenseParams { p2: 1, ..p };
        let e = dense_match(&img, &img, &f, [0, 4], &bad).unwrap_err();
        assert!(e.to_string().starts_with("params.p2"), "{e}");
        // A blank pair: nothing matched, no error.
        let m = dense_match(&img, &img, &f, [0, 4], &p).unwrap();
        assert_eq!((m.matched(), m.ur.len()), (0, 200));
        assert!(m.ur.iter().all(|u| *u == f32::INFINITY) && m.conf.iter().all(|c| *c == 0.0));
    }

    /// A patch of one grey level gets no match (the aggregation would carry its neighbours'
    /// disparity into it), and a right image of one level none at all; the texture around the
    /// patch is matched.
    #[test]
    fn flat_windows_and_one_level_images_are_not_matched() {
        let (w, h, shift) = (90u32, 60u32, 5u32);
        let mut seed = 21u64;
        let noise: Vec<u8> = (0..(w + shift) * h)
            .map(|_| (hvs_shared::test_support::splitmix64(&mut seed) >> 56) as u8)
            .collect();
        // The scene seen from the left at column x is seen from the right at x - 5; a flat
        // patch on it (scene columns 40..60, rows 20..40).
        let scene = |x: u32, y: u32| {
            let flat = (40..60).contains(&x) && (20..40).contains(&y);
            image::Luma([if flat { 90 } else { noise[(y * (w + shift) + x) as usize] }])
        };
        let left = GrayImage::from_fn(w, h, scene);
        let right = GrayImage::from_fn(w, h, |x, y| scene(x + shift, y));
        let f = Fundamental { m: [[0.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]] };
        let p = DenseParams::default();
        let m = dense_match(&left, &right, &f, [0, 10], &p).unwrap();
        let at = |x: u32, y: u32| m.ur[(y * w + x) as usize];
        // Windows wholly on the patch (7 x 5: 3 columns and 2 rows in from its edges).
        for y in 22..38 {
            for x in 43..57 {
                assert_eq!(at(x, y), f32::INFINITY, "({x}, {y})");
            }
        }
        // Around it, on the texture: the true match.
        let mut right_ones = 0;
        for y in 5..55 {
            for x in 15..85 {
                if !((36..64).contains(&x) && (17..43).contains(&y)) {
                    right_ones += usize::from((at(x, y) - (x - shift) as f32).abs() < 0.5);
                }
            }
        }
        assert!(right_ones > 2_600, "{right_ones} of 2,772");
        let blank = GrayImage::from_pixel(w, h, image::Luma([90]));
        for (l, r) in [(&left, &blank), (&blank, &right)] {
            let m = dense_match(l, r, &f, [0, 10], &p).unwrap();
            assert_eq!(m, DenseMap::none(w, h));
        }
    }

    /// Every cell of the cost volume is its definition: the Hamming distance to the candidate
    /// on the epipolar line ([`Geo::target`]), half the most outside the other image; for
    /// either image as reference (the other's rows read reversed or not) and lines on their
    /// rows, shifted and tilted across rows.
    #[test]
    fn every_cost_is_the_hamming_distance_to_its_candidate() {
        let (w, h) = (57, 23);
        let mut seed = 3u64;
        let mut words = || -> Vec<u64> {
            (0..w * h)
                .map(|_| hvs_shared::test_support::splitmix64(&mut seed) & ((1 << 34) - 1))
                .collect()
        };
        let (a, b) = (words(), words());
        for m in [
            [[0.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]],
            [[0.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 2.4]],
            [[0.0, 0.0, 0.05], [0.0, 0.0, -1.0], [0.0, 1.0, -0.7]],
        ] {
            for (sign, d_min, d) in [(-1, 3, 19), (1, -2, 20), (-1, -4, 7)] {
                let geo = Geo { m, sign, d_min, d, w, h };
                let (cost, _) = cost_volume(&geo, &a, &b);
                for y in 0..h {
                    for x in 0..w {
                        for k in 0..d {
                            let want = geo
                                .line(x, y)
                                .and_then(|line| geo.target(x, line, k))
                                .map_or(census::MAX_COST / 2, |(u, v)| {
                                    (a[y * w + x] ^ b[v * w + u]).count_ones() as u8
                                });
                            assert_eq!(
                                cost[(y * w + x) * d + k],
                                want,
                                "{m:?} {sign} ({x}, {y}) {k}"
                            );
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn a_volume_on_its_own_rows_is_recognised_as_rectified() {
        let (w, h) = (100, 80);
        let census = vec![0u64; w * h];
        let geo = |f: Fundamental| Geo { m: f.m, sign: -1, d_min: 0, d: 8, w, h };
        let rectified = Fundamental { m: [[0.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]] };
        assert!(cost_volume(&geo(rectified), &census, &census).1);
        // Lines 0.3 px below their rows round to them: still rectified.
        let near = Fundamental { m: [[0.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.3]] };
        assert!(cost_volume(&geo(near), &census, &census).1);
        let shifted = Fundamental { m: [[0.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 2.0]] };
        assert!(!cost_volume(&geo(shifted), &census, &census).1);
        // A line tilted by 1 px over the image's width leaves its row somewhere.
        let tilted = Fundamental { m: [[0.0, 0.0, 0.01], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]] };
        assert!(!cost_volume(&geo(tilted), &census, &census).1);
    }
}
