//! Semi-global aggregation (Hirschmueller 2008) of a cost volume along 8 (or 4) straight
//! paths: `L_r(p, d) = C(p, d) + min(L_r(p-r, d), L_r(p-r, d+-1) + P1, min_k L_r(p-r, k) + P2)
//! - min_k L_r(p-r, k)`, summed over the paths. `P2` shrinks where the reference image's grey
//! level jumps between `p - r` and `p` (depth edges are usually intensity edges).
//!
//! The paths are run as two passes, each over the whole image once: top-left to bottom-right
//! (from the left, top-left, top, top-right) and back (from the right, bottom-right, bottom,
//! bottom-left); with two cores the passes run side by side ([`rayon::join`]) and meet at
//! each row ([`aggregate_rows`]). Costs are `u8` (on one thread packed with the forward
//! pass's sums in a `u16`), path costs and sums `i16` (bounded by `8 (MAX_COST + P2)`),
//! stored disparities innermost and computed 16 (or 32) disparities at a time; where the CPU
//! has AVX2, a pixel's paths are stepped together in AVX2 registers and summed in the same
//! pass (`avx`). The same integers on every path.

use rayon::prelude::*;

/// Penalties of the aggregation.
#[derive(Debug, Clone, Copy)]
pub struct Penalties {
    /// For a 1-px disparity step.
    pub p1: i16,
    /// `P2` for every grey-level difference `0..=255` between neighbours.
    pub p2: [i16; 256],
    /// 8 paths, or 4 (left, right, top, bottom).
    pub eight: bool,
}

/// Padding of the path-cost rows: each holds `BIG` before disparity 0 and after the last, so
/// that one loop serves every disparity (`BIG + P1` is never the minimum: a path cost is at
/// most `MAX_COST + P2 <= 2034`).
const BIG: i16 = 0x3FFF;

/// Disparities per chunk of the inner loops (16 `i16` lanes: one AVX2 register). A range of
/// at least this many is covered by whole chunks, the last one overlapping its predecessor
/// (its cells are computed twice from the same inputs, so the same values).
pub(crate) const LANES: usize = 16;

/// The starts of chunks of `lanes` covering `0..n`, `lanes` apart, the last one at `n - lanes`
/// (overlapping its predecessor unless `lanes` divides `n`), for `n >= lanes`.
#[inline(always)]
pub(crate) fn chunk_starts(n: usize, lanes: usize) -> impl Iterator<Item = usize> {
    (0..n.div_ceil(lanes)).map(move |i| (i * lanes).min(n - lanes))
}

/// One path step over the `d` disparities: `out = c + min(prev, prev+-1 + p1, pmin + p2) -
/// pmin`; returns `min(out)`. `prev` and `out` are padded (`d + 2` long, `BIG` at both ends;
/// `out`'s ends are left alone). Chunks of [`WIDE`] disparities where the range has that
/// many, of [`LANES`] otherwise (the same integers either way).
#[inline(always)]
fn step(prev: &[i16], pmin: i16, c: &[u8], p1: i16, p2: i16, out: &mut [i16]) -> i16 {
    let d = c.len();
    if d >= WIDE {
        return step_in::<WIDE>(prev, pmin, c, p1, p2, out);
    }
    if d >= LANES {
        return step_in::<LANES>(prev, pmin, c, p1, p2, out);
    }
    let cap = pmin + p2;
    let mut m = i16::MAX;
    for k in 0..d {
        let v = i16::from(c[k]) + prev[k + 1].min(prev[k].min(prev[k + 2]) + p1).min(cap) - pmin;
        out[k + 1] = v;
        m = m.min(v);
    }
    m
}

/// Disparities per chunk of [`step`] where the range has at least this many: two AVX2
/// registers of `i16`, which halves the loop's overhead on the usual ranges (62 disparities
/// of Motorcycle: 2 chunks instead of 4).
const WIDE: usize = 32;

/// [`step`] over chunks of `L` disparities (`d >= L`; the last chunk overlaps its
/// predecessor).
#[inline(always)]
fn step_in<const L: usize>(
    prev: &[i16],
    pmin: i16,
    c: &[u8],
    p1: i16,
    p2: i16,
    out: &mut [i16],
) -> i16 {
    let d = c.len();
    let cap = pmin + p2;
    let mut m = [i16::MAX; L];
    for k0 in chunk_starts(d, L) {
        let cc: &[u8; L] = c[k0..k0 + L].try_into().expect("chunk");
        let below: &[i16; L] = prev[k0..k0 + L].try_into().expect("chunk");
        let centre: &[i16; L] = prev[k0 + 1..k0 + 1 + L].try_into().expect("chunk");
        let above: &[i16; L] = prev[k0 + 2..k0 + 2 + L].try_into().expect("chunk");
        let o: &mut [i16; L] = (&mut out[k0 + 1..k0 + 1 + L]).try_into().expect("chunk");
        for i in 0..L {
            let v = i16::from(cc[i]) + centre[i].min(below[i].min(above[i]) + p1).min(cap) - pmin;
            o[i] = v;
            m[i] = m[i].min(v);
        }
    }
    m.iter().fold(i16::MAX, |a, &b| a.min(b))
}

/// How a pass steps a pixel's `P` paths (`P` = 4: along the row and from the three cells
/// of the previous row; 2 with four paths): `outs[p]` from `prevs[p]`, `pmins[p]` and `p2s[p]`
/// by [`step`]'s recursion, and their sum into `s`.
/// Returns each path's `min(out)`. A path with nothing before it (its first pixel) comes with
/// [`zero_row`] and `pmin = 0`, which gives `out = c`. Integer sums, so the order of the terms
/// does not matter (none overflows: eight paths of at most `MAX_COST + P2` each).
trait Paths {
    #[allow(clippy::too_many_arguments)]
    fn paths<const P: usize>(
        &self,
        prevs: [&[i16]; P],
        pmins: [i16; P],
        p2s: [i16; P],
        c: &[u8],
        p1: i16,
        outs: [&mut [i16]; P],
        s: &mut [i16],
    ) -> [i16; P];
}

/// [`Paths`] one path at a time ([`step`]), then the sum.
struct Portable;

impl Paths for Portable {
    #[inline(always)]
    fn paths<const P: usize>(
        &self,
        prevs: [&[i16]; P],
        pmins: [i16; P],
        p2s: [i16; P],
        c: &[u8],
        p1: i16,
        mut outs: [&mut [i16]; P],
        s: &mut [i16],
    ) -> [i16; P] {
        let mut m = [0i16; P];
        for p in 0..P {
            m[p] = step(prevs[p], pmins[p], c, p1, p2s[p], outs[p]);
        }
        for (k, v) in s.iter_mut().enumerate() {
            let mut t = 0;
            for o in outs.iter_mut() {
                t += o[k + 1];
            }
            *v = t;
        }
        m
    }
}

/// The previous cells of a path's first pixel: `d + 2` long, `BIG` at both ends and 0
/// between, so that a step from it with `pmin = 0` gives the costs themselves.
fn zero_row(dp: usize) -> Vec<i16> {
    let mut z = vec![0i16; dp];
    z[0] = BIG;
    z[dp - 1] = BIG;
    z
}

/// One pass (forward: rows top to bottom, left to right; backward: the reverse), each
/// pixel's paths stepped by `paths` and their sums written into `sum`: the whole volume
/// (`w * h * d`) when `whole`, else one row (`w * d`) used for every row; the costs from
/// `costs`, row by row. `on_row(y, sums, costs)` is called with each row once it is done.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn pass_body(
    paths: &impl Paths,
    costs: PassCosts,
    img: &[u8],
    (w, h, d): (usize, usize, usize),
    pen: &Penalties,
    backward: bool,
    (sum, whole): (&mut [i16], bool),
    on_row: OnRow,
) {
    // Row buffers of the three paths that come from the previous row, by iteration column:
    // slot 0 from the same column, 1 from the column before, 2 from the column after. Each
    // cell is `d + 2` long (padded, see [`BIG`]).
    let dp = d + 2;
    let slots = if pen.eight { 3 } else { 1 };
    let mut prev = vec![BIG; slots * w * dp];
    let mut cur = vec![BIG; slots * w * dp];
    let mut prev_min = vec![0i16; slots * w];
    let mut cur_min = vec![0i16; slots * w];
    let mut lprev = vec![BIG; dp];
    let mut lcur = vec![BIG; dp];
    let mut lmin = 0i16;
    let zero = zero_row(dp);
    // The row's costs when they come a row at a time.
    let mut row_costs = match costs {
        PassCosts::Volume(_) => Vec::new(),
        PassCosts::Rows(_) => vec![0u8; w * d],
    };
    // Plain functions, not closures: these run for every pixel, and closures were left as
    // calls in the vectorised body.
    #[inline(always)]
    fn at((w, h): (usize, usize), backward: bool, xi: usize, yi: usize) -> usize {
        if backward {
            (h - 1 - yi) * w + (w - 1 - xi)
        } else {
            yi * w + xi
        }
    }
    #[inline(always)]
    fn p2(pen: &Penalties, a: u8, b: u8) -> i16 {
        pen.p2[usize::from(a.abs_diff(b))]
    }
    /// The cells, the smallest cell and `P2` of slot `slot`'s path at column `xi` of row
    /// `yi` (from the previous row), or of a path's start ([`zero_row`]).
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    fn from<'a>(
        (w, h, dp): (usize, usize, usize),
        backward: bool,
        (prev, prev_min, zero): (&'a [i16], &[i16], &'a [i16]),
        (img, g, pen): (&[u8], u8, &Penalties),
        slot: usize,
        xi: usize,
        yi: usize,
    ) -> (&'a [i16], i16, i16) {
        let fx = match slot {
            0 => Some(xi),
            1 => xi.checked_sub(1),
            _ => (xi + 1 < w).then_some(xi + 1),
        };
        match fx {
            Some(fx) if yi > 0 => (
                &prev[(slot * w + fx) * dp..(slot * w + fx + 1) * dp],
                prev_min[slot * w + fx],
                p2(pen, g, img[at((w, h), backward, fx, yi - 1)]),
            ),
            _ => (zero, 0, pen.p2[0]),
        }
    }
    for yi in 0..h {
        let y = if backward { h - 1 - yi } else { yi };
        let crow: &[u8] = match costs {
            PassCosts::Volume(v) => &v[y * w * d..(y + 1) * w * d],
            PassCosts::Rows(fill) => {
                fill(y, &mut row_costs);
                &row_costs
            }
        };
        for xi in 0..w {
            let p = at((w, h), backward, xi, yi);
            let x = p - y * w;
            let c = &crow[x * d..(x + 1) * d];
            let g = img[p];
            let at_s = if whole { p } else { p % w } * d;
            let s = &mut sum[at_s..at_s + d];
            // Along the row, then from the previous row: the same column, the column before
            // and the column after (the slots).
            let row_in = if xi == 0 {
                (&zero[..], 0, pen.p2[0])
            } else {
                (&lprev[..], lmin, p2(pen, g, img[at((w, h), backward, xi - 1, yi)]))
            };
            let bufs = (&prev[..], &prev_min[..], &zero[..]);
            let from = |slot| from((w, h, dp), backward, bufs, (img, g, pen), slot, xi, yi);
            let (r0, rest) = cur.split_at_mut(w * dp);
            let cell0 = &mut r0[xi * dp..(xi + 1) * dp];
            if slots == 3 {
                let (r1, r2) = rest.split_at_mut(w * dp);
                let cell1 = &mut r1[xi * dp..(xi + 1) * dp];
                let cell2 = &mut r2[xi * dp..(xi + 1) * dp];
                let (a, b, e, f) = (row_in, from(0), from(1), from(2));
                let m = paths.paths::<4>(
                    [a.0, b.0, e.0, f.0],
                    [a.1, b.1, e.1, f.1],
                    [a.2, b.2, e.2, f.2],
                    c,
                    pen.p1,
                    [&mut lcur[..], cell0, cell1, cell2],
                    s,
                );
                lmin = m[0];
                for slot in 0..3 {
                    cur_min[slot * w + xi] = m[slot + 1];
                }
            } else {
                let (a, b) = (row_in, from(0));
                let m = paths.paths::<2>(
                    [a.0, b.0],
                    [a.1, b.1],
                    [a.2, b.2],
                    c,
                    pen.p1,
                    [&mut lcur[..], cell0],
                    s,
                );
                lmin = m[0];
                cur_min[xi] = m[1];
            }
            std::mem::swap(&mut lprev, &mut lcur);
        }
        std::mem::swap(&mut prev, &mut cur);
        std::mem::swap(&mut prev_min, &mut cur_min);
        let at_row = if whole { y * w * d } else { 0 };
        on_row(y, &mut sum[at_row..at_row + w * d], crow);
    }
}

/// What a pass does with each row once done: `(y, the row's sums, the row's costs)`.
type OnRow<'a> = &'a mut dyn FnMut(usize, &mut [i16], &[u8]);

/// Where a pass reads its costs: a whole volume (`w * h * d`), or a row at a time, written
/// by the function into a row of the pass's own (`w * d`).
#[derive(Clone, Copy)]
enum PassCosts<'a> {
    Volume(&'a [u8]),
    Rows(&'a (dyn Fn(usize, &mut [u8]) + Sync)),
}

/// [`pass_body`], compiled for AVX2 where the CPU has it ([`super::fast`]: the same
/// integers either way).
#[allow(clippy::too_many_arguments)]
fn pass(
    costs: PassCosts,
    img: &[u8],
    dims: (usize, usize, usize),
    pen: &Penalties,
    backward: bool,
    sum: (&mut [i16], bool),
    on_row: OnRow,
) {
    #[cfg(target_arch = "x86_64")]
    if dims.2 >= LANES {
        if let Some(simd) = pulp::x86::V3::try_new() {
            return simd.vectorize(
                #[inline(always)]
                || pass_body(&avx::Avx2(simd), costs, img, dims, pen, backward, sum, on_row),
            );
        }
    }
    super::fast(
        #[inline(always)]
        || pass_body(&Portable, costs, img, dims, pen, backward, sum, on_row),
    );
}

/// [`Paths`] in AVX2 registers for ranges of [`LANES`] disparities or more: a pixel's paths
/// stepped together, 16 disparities a register, their sum added in the same pass (one pass
/// over the pixel's costs and sums instead of one per path and another for the sum). Integer
/// arithmetic: the same sums as [`Portable`] (a unit test compares the passes).
#[cfg(target_arch = "x86_64")]
mod avx {
    use super::{Paths, LANES};
    use core::arch::x86_64::{__m128i, __m256i};
    use pulp::x86::V3;

    #[inline(always)]
    fn load(s: &[i16], at: usize) -> __m256i {
        let a: [i16; LANES] = s[at..at + LANES].try_into().expect("chunk");
        pulp::cast(a)
    }

    #[inline(always)]
    fn store(s: &mut [i16], at: usize, v: __m256i) {
        let a: [i16; LANES] = pulp::cast(v);
        s[at..at + LANES].copy_from_slice(&a);
    }

    /// The costs `c[at..at + 16]` widened to `i16`.
    #[inline(always)]
    fn load_costs(simd: V3, c: &[u8], at: usize) -> __m256i {
        let a: [u8; LANES] = c[at..at + LANES].try_into().expect("chunk");
        simd.avx2._mm256_cvtepu8_epi16(pulp::cast::<[u8; LANES], __m128i>(a))
    }

    /// The smallest lane (every lane `0..=i16::MAX`, so the unsigned minimum is it).
    #[inline(always)]
    fn min_lane(simd: V3, v: __m256i) -> i16 {
        let lo = simd.avx._mm256_castsi256_si128(v);
        let hi = simd.avx2._mm256_extracti128_si256::<1>(v);
        let m = simd.sse4_1._mm_minpos_epu16(simd.sse2._mm_min_epi16(lo, hi));
        (simd.sse2._mm_cvtsi128_si32(m) & 0xFFFF) as i16
    }

    /// [`Paths`] in AVX2 registers, 16 disparities a register (`d = c.len() >= 16`).
    pub(super) struct Avx2(pub V3);

    impl Paths for Avx2 {
        #[inline(always)]
        fn paths<const P: usize>(
            &self,
            prevs: [&[i16]; P],
            pmins: [i16; P],
            p2s: [i16; P],
            c: &[u8],
            p1: i16,
            outs: [&mut [i16]; P],
            s: &mut [i16],
        ) -> [i16; P] {
            let (simd, d) = (self.0, c.len());
            let (avx, avx2) = (simd.avx, simd.avx2);
            let p1v = avx._mm256_set1_epi16(p1);
            let mut pminv = [avx._mm256_setzero_si256(); P];
            let mut capv = [avx._mm256_setzero_si256(); P];
            let mut m = [avx._mm256_set1_epi16(i16::MAX); P];
            for p in 0..P {
                pminv[p] = avx._mm256_set1_epi16(pmins[p]);
                capv[p] = avx._mm256_set1_epi16(pmins[p] + p2s[p]);
            }
            // The last chunk may overlap its predecessor: the same sums computed twice.
            let last = d - LANES;
            let mut k0 = 0;
            loop {
                let k = k0.min(last);
                let cc = load_costs(simd, c, k);
                let mut acc = avx._mm256_setzero_si256();
                for p in 0..P {
                    let prev = prevs[p];
                    let (below, centre, above) =
                        (load(prev, k), load(prev, k + 1), load(prev, k + 2));
                    let jump = avx2._mm256_add_epi16(avx2._mm256_min_epi16(below, above), p1v);
                    let best = avx2._mm256_min_epi16(avx2._mm256_min_epi16(centre, jump), capv[p]);
                    let v = avx2._mm256_sub_epi16(avx2._mm256_add_epi16(cc, best), pminv[p]);
                    store(outs[p], k + 1, v);
                    m[p] = avx2._mm256_min_epi16(m[p], v);
                    acc = avx2._mm256_add_epi16(acc, v);
                }
                store(s, k, acc);
                if k == last {
                    break;
                }
                k0 += LANES;
            }
            let mut out = [0i16; P];
            for p in 0..P {
                out[p] = min_lane(simd, m[p]);
            }
            out
        }
    }
}

/// A cost volume (`w * h * d`, `u8`, rows first, disparities innermost, each cost at most
/// [`super::census::MAX_COST`]), given a row at a time: [`aggregate_rows`] asks for each row
/// once, on any thread, in any order.
pub trait CostRows: Sync {
    /// Writes row `y`'s `w * d` costs into `out`.
    fn row(&self, y: usize, out: &mut [u8]);
    /// The whole volume, where it is already in memory (then read in place).
    fn volume(&self) -> Option<&[u8]> {
        None
    }
}

/// A cost volume already in memory.
pub struct Volume<'a> {
    /// The costs, `w * h * d`.
    pub cost: &'a [u8],
    /// Cells per row, `w * d`.
    pub row_len: usize,
}

impl CostRows for Volume<'_> {
    fn row(&self, y: usize, out: &mut [u8]) {
        out.copy_from_slice(&self.cost[y * self.row_len..(y + 1) * self.row_len]);
    }
    fn volume(&self) -> Option<&[u8]> {
        Some(self.cost)
    }
}

/// Bits of a packed cell ([`aggregate_rows`] on one thread) that hold the cost.
const COST_BITS: u32 = 6;
const _: () = assert!((super::census::MAX_COST as u32) < 1 << COST_BITS);

/// The aggregated cost `S(p, d)` of `costs` with `img` the reference image's grey levels
/// (for the adaptive `P2`), handed row by row to `per_row(y, S of row y)` (`w * d`) as soon
/// as the row is complete; its answers by row. Every row's costs have been asked for before
/// the first row is handed over.
///
/// With one thread the forward pass asks for each row's costs as it reaches the row and keeps
/// them with its sums, both packed in one `u16` cell (`sum << 6 | cost`: the forward pass's
/// paths sum to under 1,024 with the usual `P2`, else a cost volume and a volume of sums as
/// below); the backward pass takes the costs back from it, sums its paths into a row of its
/// own, adds the forward row and hands it over (in cache). One volume of `u16` in all, and the
/// costs computed once. With two or more threads the cost volume is filled first (rows in
/// parallel), then the passes run side by side, each into a row of its own, and meet at each
/// row: the first to finish it leaves a copy of its sums there, the second adds them to its
/// own and hands the row over (on its thread: the rows are handed over in parallel, each
/// while in cache, with no adding pass after the passes). One volume of sums is held at most
/// (when the passes meet in the middle of the image), not one per pass. The same integers
/// every way.
pub fn aggregate_rows<R: Send>(
    costs: &impl CostRows,
    img: &[u8],
    (w, h, d): (usize, usize, usize),
    pen: &Penalties,
    per_row: impl Fn(usize, &[i16]) -> R + Sync,
) -> Vec<R> {
    use std::sync::Mutex;
    let n = w * d;
    let dims = (w, h, d);
    let one_thread = rayon::current_num_threads() < 2;
    // The forward pass's paths: each at most MAX_COST + P2.
    let forward_paths = if pen.eight { 4 } else { 2 };
    let most_p2 = i32::from(pen.p2.iter().copied().max().unwrap_or(0));
    let packs =
        forward_paths * (i32::from(super::census::MAX_COST) + most_p2) < 1 << (16 - COST_BITS);
    // A pass whose sums go into a row of its own, handed to `on_row` row by row.
    let by_rows = |costs: PassCosts, backward: bool, on_row: OnRow| {
        pass(costs, img, dims, pen, backward, (&mut vec![0; n], false), on_row)
    };
    if one_thread && costs.volume().is_none() && packs {
        let mut packed = vec![0u16; w * h * d];
        let fill = |y: usize, out: &mut [u8]| costs.row(y, out);
        by_rows(PassCosts::Rows(&fill), false, &mut |y, f, c| {
            pack_row(&mut packed[y * n..(y + 1) * n], f, c)
        });
        let packed = &packed;
        let unpack = |y: usize, out: &mut [u8]| unpack_costs(&packed[y * n..(y + 1) * n], out);
        let mut out: Vec<Option<R>> = (0..h).map(|_| None).collect();
        by_rows(PassCosts::Rows(&unpack), true, &mut |y, r, _| {
            add_packed_sums(r, &packed[y * n..(y + 1) * n]);
            out[y] = Some(per_row(y, r));
        });
        return out.into_iter().map(|r| r.expect("every row is handed over")).collect();
    }
    let filled: Vec<u8>;
    let cost = match costs.volume() {
        Some(v) => v,
        None => {
            let mut v = vec![0u8; w * h * d];
            v.par_chunks_mut(n).enumerate().for_each(|(y, row)| costs.row(y, row));
            filled = v;
            &filled
        }
    };
    let cost = PassCosts::Volume(cost);
    if one_thread {
        // One pass after the other: the first's sums in one volume.
        let mut first = vec![0i16; w * h * d];
        pass(cost, img, dims, pen, false, (&mut first, true), &mut |_, _, _| {});
        let mut out: Vec<Option<R>> = (0..h).map(|_| None).collect();
        by_rows(cost, true, &mut |y, r, _| {
            add_row(r, &first[y * n..(y + 1) * n]);
            out[y] = Some(per_row(y, r));
        });
        return out.into_iter().map(|r| r.expect("every row is handed over")).collect();
    }
    // Each row: the first pass's sums until the second comes, then the row's answer.
    enum Meeting<R> {
        Empty,
        Half(Vec<i16>),
        Done(R),
    }
    let meetings: Vec<Mutex<Meeting<R>>> = (0..h).map(|_| Mutex::new(Meeting::Empty)).collect();
    let meet = |y: usize, row: &mut [i16]| {
        let mut m = meetings[y].lock().expect("a pass panicked");
        match std::mem::replace(&mut *m, Meeting::Empty) {
            Meeting::Empty => *m = Meeting::Half(row.to_vec()),
            Meeting::Half(first) => {
                drop(m);
                add_row(row, &first);
                let answer = per_row(y, row);
                *meetings[y].lock().expect("a pass panicked") = Meeting::Done(answer);
            }
            Meeting::Done(_) => unreachable!("each pass meets a row once"),
        }
    };
    rayon::join(
        || by_rows(cost, false, &mut |y, r, _| meet(y, r)),
        || by_rows(cost, true, &mut |y, r, _| meet(y, r)),
    );
    meetings
        .into_iter()
        .map(|m| match m.into_inner().expect("a pass panicked") {
            Meeting::Done(r) => r,
            _ => unreachable!("both passes met every row"),
        })
        .collect()
}

/// `row += other`, cell by cell (two passes' sums of one row).
fn add_row(row: &mut [i16], other: &[i16]) {
    for (s, &t) in row.iter_mut().zip(other) {
        *s += t;
    }
}

/// One row of packed cells: each forward sum (non-negative, under `1 << 10`) above its cost.
fn pack_row(packed: &mut [u16], sums: &[i16], costs: &[u8]) {
    super::fast(
        #[inline(always)]
        move || {
            let packed = packed;
            for ((p, &s), &c) in packed.iter_mut().zip(sums).zip(costs) {
                debug_assert!((0..1 << (16 - COST_BITS)).contains(&s) && c < 1 << COST_BITS);
                *p = (s as u16) << COST_BITS | u16::from(c);
            }
        },
    )
}

/// The costs of one row of packed cells.
fn unpack_costs(packed: &[u16], out: &mut [u8]) {
    super::fast(
        #[inline(always)]
        move || {
            let out = out;
            for (o, &p) in out.iter_mut().zip(packed) {
                *o = (p & ((1 << COST_BITS) - 1)) as u8;
            }
        },
    )
}

/// Adds the forward sums of one row of packed cells to `row`.
fn add_packed_sums(row: &mut [i16], packed: &[u16]) {
    super::fast(
        #[inline(always)]
        move || {
            let row = row;
            for (s, &p) in row.iter_mut().zip(packed) {
                *s += (p >> COST_BITS) as i16;
            }
        },
    )
}

/// The whole aggregated volume `S` (`w * h * d`) of [`aggregate_rows`].
pub fn aggregate(
    cost: &[u8],
    img: &[u8],
    w: usize,
    h: usize,
    d: usize,
    pen: &Penalties,
) -> Vec<i16> {
    let costs = Volume { cost, row_len: w * d };
    aggregate_rows(&costs, img, (w, h, d), pen, |_, row| row.to_vec()).concat()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pen(eight: bool) -> Penalties {
        Penalties { p1: 3, p2: [20; 256], eight }
    }

    #[test]
    fn step_follows_the_recursion() {
        let prev = [BIG, 5i16, 0, 9, 30, BIG];
        let c = [1u8, 2, 3, 4];
        let mut out = [BIG; 6];
        let m = step(&prev, 0, &c, 3, 20, &mut out);
        // d0: 1 + min(5, 0+3, 20) = 4; d1: 2 + 0; d2: 3 + min(9, 0+3) = 6; d3: 4 + min(30, 9+3, 20) = 16.
        assert_eq!(out, [BIG, 4, 2, 6, 16, BIG]);
        assert_eq!(m, 2);
    }

    /// The step as first written, disparity by disparity with its two ends apart.
    fn step_reference(prev: &[i16], pmin: i16, c: &[u8], p1: i16, p2: i16) -> Vec<i16> {
        let d = c.len();
        let cap = pmin + p2;
        (0..d)
            .map(|k| {
                let mut v = prev[k].min(cap);
                if k > 0 {
                    v = v.min(prev[k - 1] + p1);
                }
                if k + 1 < d {
                    v = v.min(prev[k + 1] + p1);
                }
                i16::from(c[k]) + v - pmin
            })
            .collect()
    }

    /// The chunked step (the last chunk overlapping) gives the reference's values for every
    /// range length, below one chunk, at it and above.
    #[test]
    fn chunked_step_matches_the_reference() {
        let mut s = 7u64;
        for d in [1usize, 2, 5, 15, 16, 17, 31, 33, 62, 66, 137] {
            for _ in 0..20 {
                let c: Vec<u8> = (0..d)
                    .map(|_| (hvs_shared::test_support::splitmix64(&mut s) % 63) as u8)
                    .collect();
                let prev: Vec<i16> = (0..d)
                    .map(|_| (hvs_shared::test_support::splitmix64(&mut s) % 300) as i16)
                    .collect();
                let pmin = *prev.iter().min().unwrap();
                let mut padded = vec![BIG; d + 2];
                padded[1..d + 1].copy_from_slice(&prev);
                let mut out = vec![BIG; d + 2];
                let m = step(&padded, pmin, &c, 7, 40, &mut out);
                let want = step_reference(&prev, pmin, &c, 7, 40);
                assert_eq!(&out[1..d + 1], &want[..], "d = {d}");
                assert_eq!((out[0], out[d + 1]), (BIG, BIG));
                assert_eq!(m, *want.iter().min().unwrap());
            }
        }
    }

    /// The aggregation compiled for this CPU's best instruction set (AVX2 here) and for plain
    /// x86-64 give the same sums, one thread or more.
    #[test]
    fn every_instruction_set_and_thread_count_gives_the_same_sums() {
        let mut s = 11u64;
        for (w, h, d, eight) in [
            (23usize, 9usize, 7usize, true),
            (17, 12, 40, true),
            (19, 8, 33, false),
            (13, 7, 16, true),
            (11, 6, 64, true),
            (9, 5, 21, false),
        ] {
            // Costs up to the census' most (what a packed cell holds), a few at it.
            let most = u64::from(crate::dense::census::MAX_COST);
            let cost: Vec<u8> = (0..w * h * d)
                .map(|_| {
                    (hvs_shared::test_support::splitmix64(&mut s) % (most + 3)).min(most) as u8
                })
                .collect();
            let img: Vec<u8> =
                (0..w * h).map(|_| hvs_shared::test_support::splitmix64(&mut s) as u8).collect();
            // The usual P2 (the one-thread forward pass packs its sums with the costs) and a
            // large one (its sums do not fit: a cost volume and a volume of sums instead).
            for top in [96, 400] {
                let mut p2 = [0i16; 256];
                for (g, v) in p2.iter_mut().enumerate() {
                    *v = (top * 8 / (8 + g as i32)).max(17) as i16;
                }
                let pen = Penalties { p1: 16, p2, eight };
                let dims = (w, h, d);
                // Each pass's rows, then their sum.
                let mut plain = vec![0i16; w * h * d];
                for backward in [false, true] {
                    let row = (&mut vec![0; w * d][..], false);
                    let costs = PassCosts::Volume(&cost);
                    pass_body(&Portable, costs, &img, dims, &pen, backward, row, &mut |y, r, _| {
                        add_row(&mut plain[y * w * d..(y + 1) * w * d], r)
                    });
                }
                let by_rows = RowsOnly(Volume { cost: &cost, row_len: w * d });
                let one = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
                let two = rayon::ThreadPoolBuilder::new().num_threads(2).build().unwrap();
                for pool in [one, two] {
                    let threads = pool.current_num_threads();
                    let fast = pool.install(|| aggregate(&cost, &img, w, h, d, &pen));
                    assert_eq!(fast, plain, "{w}x{h}x{d}, eight paths: {eight}, {threads} threads");
                    let rows = pool.install(|| {
                        aggregate_rows(&by_rows, &img, dims, &pen, |_, r| r.to_vec()).concat()
                    });
                    let what = format!("{w}x{h}x{d}, eight: {eight}, P2 {top}, {threads} threads");
                    assert_eq!(rows, plain, "costs by row, {what}");
                }
            }
        }
    }

    /// Costs given by row only (no volume in memory): what the dense matcher's census costs
    /// are.
    struct RowsOnly<'a>(Volume<'a>);

    impl CostRows for RowsOnly<'_> {
        fn row(&self, y: usize, out: &mut [u8]) {
            self.0.row(y, out)
        }
    }

    #[test]
    fn a_lone_wrong_cost_is_outvoted_by_its_neighbours() {
        // 9 x 9 pixels, 5 disparities: every pixel prefers d = 2 except the centre, which
        // prefers d = 4 by a small margin; aggregation brings it back to 2.
        let (w, h, d) = (9, 9, 5);
        let mut cost = vec![10u8; w * h * d];
        for p in 0..w * h {
            cost[p * d + 2] = 0;
        }
        let centre = 4 * w + 4;
        cost[centre * d + 2] = 6;
        cost[centre * d + 4] = 4;
        let img = vec![0u8; w * h];
        for eight in [false, true] {
            let s = aggregate(&cost, &img, w, h, d, &pen(eight));
            let best = (0..d).min_by_key(|&k| s[centre * d + k]).unwrap();
            assert_eq!(best, 2, "eight paths: {eight}");
            // Four or eight paths, each with the pixel's own cost once.
            let paths = if eight { 8 } else { 4 };
            assert_eq!(s[2], 0);
            assert!(s[0] >= paths * 10, "{}", s[0]);
        }
    }
}
