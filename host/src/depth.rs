//! Dense depth of a stereo pair through the model (`hvs depth`, and a library call for the
//! viewer and the tracker): both images matched pixel by pixel by
//! [`hvs_vision::dense`] (census + semi-global matching along the model's epipolar lines,
//! inside the disparities its depth box allows), then every matched `(u_l, v_l, u_r, v_r)`
//! through the model (the same bits as `hvs predict`: [`crate::infer`]) into X, Y, Z.
//! Nothing but the model and the two images is used. `hvs locate` answers its points from the
//! same matches ([`locate`]).

use crate::infer::Predictor;
use crate::vision::{
    matcher_geometry, model_fundamental, model_xyz, training_disparities, Located,
};
use anyhow::{anyhow, bail, Result};
use hvs_shared::runtime::blob::{MatcherGeometry, ModelBlob};
use hvs_vision::dense::{
    check_inputs, dense_match, matcher_scale, DenseError, DenseMap, DenseParams,
};
use hvs_vision::matching::{line_point, model_disparity_interval_in_image};
use image::GrayImage;
use std::path::Path;

/// Left pixels per side of the grid on which the model's disparity interval is sampled to
/// bound the whole image's disparity range.
pub const RANGE_GRID: usize = 9;

/// The dense depth of a pair.
#[derive(Debug, Clone)]
pub struct Depth {
    /// Every left pixel's match (right pixel and confidence; `+inf`/0 where none).
    pub matches: DenseMap,
    /// X, Y, Z (cm) by the model per left pixel, rows first (`+inf` where none; X and Y NaN
    /// for a Z-only model).
    pub xyz: Vec<[f32; 3]>,
    /// The whole disparities searched (`u_l - u_r`, px).
    pub d_range: [i32; 2],
    /// The model's training depths (cm).
    pub z_box: [f32; 2],
    /// Things a user should know (a blank or saturated image, matches the model has no
    /// estimate for), one line each.
    pub warnings: Vec<String>,
    /// Pixels with a depth whose `(u_l, v_l, u_r, v_r)` lies outside the model's input box:
    /// their X, Y, Z are the net's extrapolations.
    pub outside_box: usize,
}

impl Depth {
    /// Pixels with a depth.
    pub fn returned(&self) -> usize {
        self.xyz.iter().filter(|p| p[2].is_finite()).count()
    }

    /// What was found, in a line (`hvs depth` prints it, `hvs view` shows it):
    /// `N of M pixels (P %) with a depth, disparities A..B px searched`.
    pub fn summary(&self) -> String {
        let (k, n) = (self.returned(), self.xyz.len());
        format!(
            "{k} of {n} pixels ({:.1} %) with a depth, disparities {}..{} px searched",
            100.0 * k as f64 / n.max(1) as f64,
            self.d_range[0],
            self.d_range[1]
        )
    }

    /// The point cloud as a binary PLY ([`hvs_vision::pfm::ply_bytes`]): every pixel with a
    /// depth, coloured with `left`'s grey level (`hvs depth --ply` and `hvs view`'s 3-D view).
    /// A Z-only model gives no X and Y, so no cloud: an error.
    pub fn cloud(&self, left: &GrayImage) -> Result<Vec<u8>> {
        if self.xyz.iter().any(|p| p[2].is_finite() && p[0].is_nan()) {
            bail!("a Z-only model (hvs train --outputs z) gives no X and Y, so no point cloud");
        }
        let (pts, grey): (Vec<[f32; 3]>, Vec<u8>) = self
            .xyz
            .iter()
            .zip(left.as_raw())
            .filter(|(p, _)| p[2].is_finite())
            .map(|(p, &g)| (*p, g))
            .unzip();
        Ok(hvs_vision::pfm::ply_bytes(&pts, &grey))
    }

    /// The colour-mapped depth image with its legend in cm over the model's depth box
    /// ([`hvs_vision::pfm::colour_depth`]): `hvs depth --colour` and `hvs view`'s overlay.
    pub fn colour(&self) -> image::RgbImage {
        let z: Vec<f32> = self.xyz.iter().map(|p| p[2]).collect();
        hvs_vision::pfm::colour_depth(self.matches.width, self.matches.height, &z, self.z_box)
    }
}

/// The whole disparities the model allows anywhere in a `w x h` left image: the union of
/// [`model_disparity_interval_in_image`] on a [`RANGE_GRID`]-square grid of pixels, widened by one
/// pixel; the training disparities ([`training_disparities`]) when no grid pixel has
/// an interval.
pub fn disparity_range(
    g: &MatcherGeometry,
    predict: &dyn Fn([f32; 4]) -> Option<[f32; 3]>,
    trusted: &dyn Fn([f32; 4]) -> bool,
    w: u32,
    h: u32,
) -> [i32; 2] {
    let f = model_fundamental(g);
    let d_range = training_disparities(g);
    let z_range = [f64::from(g.out_min[2]), f64::from(g.out_max[2])];
    let mut lo = f64::INFINITY;
    let mut hi = f64::NEG_INFINITY;
    let n = RANGE_GRID;
    for i in 0..n {
        for j in 0..n {
            let ul = (f64::from(w) - 1.0) * i as f64 / (n - 1) as f64;
            let vl = (f64::from(h) - 1.0) * j as f64 / (n - 1) as f64;
            let line = f.line_in_right([ul, vl]);
            if let Some((a, b)) = model_disparity_interval_in_image(
                predict, trusted, ul, vl, line, z_range, d_range, w,
            ) {
                lo = lo.min(a);
                hi = hi.max(b);
            }
        }
    }
    if !(lo.is_finite() && hi.is_finite()) {
        (lo, hi) = (d_range[0], d_range[1]);
    }
    [(lo.floor() as i32) - 1, (hi.ceil() as i32) + 1]
}

/// Left pixels across the image ([`scale_profile`]'s grid: columns, rows).
pub const SCALE_GRID: [usize; 2] = [9, 3];

/// Left-pixel step (px) of [`scale_profile`]'s finite differences (each side).
pub const SCALE_STEP_PX: f64 = 8.0;

/// The right image's scale against the left's across the right image as the model sees it:
/// for [`SCALE_GRID`] left pixels over a `w x h` image, the right pixel on the epipolar line
/// at which the model's Z is the middle depth of its box (the mean of the inverse depths),
/// and the same for the left pixel [`SCALE_STEP_PX`] px to either side along u and v: the
/// differences give `du_r / du_l` and `dv_r / dv_l` there. Each fitted as a line in the
/// right column `u_r` (least squares): `[su, sv]` at the centre column `(w - 1) / 2` and
/// their slopes per px ([`DenseParams::right_scale_slope`]). `None` when fewer than five
/// pixels solve, they span under a third of the width, or a line leaves 0.25..4 inside the
/// image. For a verged pair of unequal focal lengths the scale runs from well under the
/// focal ratio at one edge to well over it at the other, nearly whatever the depth and row.
pub fn scale_profile(
    g: &MatcherGeometry,
    predict: &dyn Fn([f32; 4]) -> Option<[f32; 3]>,
    trusted: &dyn Fn([f32; 4]) -> bool,
    w: u32,
    h: u32,
) -> Option<([f32; 2], [f32; 2])> {
    let f = model_fundamental(g);
    let d_range = training_disparities(g);
    let z_range = [f64::from(g.out_min[2]), f64::from(g.out_max[2])];
    if !(z_range[0] > 0.0 && z_range[1] > z_range[0]) {
        return None;
    }
    let z_mid = 2.0 / (1.0 / z_range[0] + 1.0 / z_range[1]);
    // The right pixel of left pixel (ul, vl) at the middle depth: the first disparity of its
    // interval where the model's Z crosses it (0.5 px scan), then bisection.
    let solve = |ul: f64, vl: f64| -> Option<[f64; 2]> {
        let line = f.line_in_right([ul, vl]);
        let (lo, hi) =
            model_disparity_interval_in_image(predict, trusted, ul, vl, line, z_range, d_range, w)?;
        let at = |d: f64| {
            let [ur, vr] = line_point(ul, line, d);
            let x = [ul as f32, vl as f32, ur as f32, vr as f32];
            let z = if trusted(x) { predict(x).map(|p| f64::from(p[2]) - z_mid) } else { None };
            z.filter(|z| z.is_finite()).map(|z| (z, [ur, vr]))
        };
        let n = ((hi - lo) / 0.5).ceil().max(1.0) as usize;
        let mut prev: Option<(f64, f64)> = None;
        for k in 0..=n {
            let d = (lo + k as f64 * 0.5).min(hi);
            let Some((z, _)) = at(d) else {
                prev = None;
                continue;
            };
            if let Some((d0, z0)) = prev.filter(|&(_, z0)| (z0 <= 0.0) != (z <= 0.0)) {
                let (mut d0, mut z0, mut d1) = (d0, z0, d);
                for _ in 0..40 {
                    let m = 0.5 * (d0 + d1);
                    let (zm, _) = at(m)?;
                    if (zm <= 0.0) == (z0 <= 0.0) {
                        (d0, z0) = (m, zm);
                    } else {
                        d1 = m;
                    }
                }
                return at(0.5 * (d0 + d1)).map(|(_, p)| p);
            }
            prev = Some((d, z));
        }
        None
    };
    let [nu, nv] = SCALE_GRID;
    let step = SCALE_STEP_PX;
    let (wf, hf) = (f64::from(w), f64::from(h));
    if wf < 4.0 * step || hf < 4.0 * step {
        return None;
    }
    // (u_r, su, sv) of every pixel that solves.
    let mut points: Vec<(f64, f64, f64)> = Vec::new();
    for i in 0..nu {
        for j in 0..nv {
            let ul = step + (wf - 1.0 - 2.0 * step) * i as f64 / (nu - 1) as f64;
            let vl = step + (hf - 1.0 - 2.0 * step) * j as f64 / (nv - 1) as f64;
            let got = (|| {
                let centre = solve(ul, vl)?;
                let (l, r) = (solve(ul - step, vl)?, solve(ul + step, vl)?);
                let (t, bo) = (solve(ul, vl - step)?, solve(ul, vl + step)?);
                let s = [(r[0] - l[0]) / (2.0 * step), (bo[1] - t[1]) / (2.0 * step)];
                s.iter().all(|s| (0.25..=4.0).contains(s)).then_some((centre[0], s[0], s[1]))
            })();
            points.extend(got);
        }
    }
    let n = points.len() as f64;
    let (u_min, u_max) = points
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), p| (a.min(p.0), b.max(p.0)));
    if points.len() < 5 || u_max - u_min < wf / 3.0 {
        return None;
    }
    let centre = (wf - 1.0) / 2.0;
    let mean_u = points.iter().map(|p| p.0 - centre).sum::<f64>() / n;
    let var_u = points.iter().map(|p| (p.0 - centre - mean_u).powi(2)).sum::<f64>();
    let fit = |s: fn(&(f64, f64, f64)) -> f64| {
        let mean_s = points.iter().map(s).sum::<f64>() / n;
        let cov = points.iter().map(|p| (p.0 - centre - mean_u) * (s(p) - mean_s)).sum::<f64>();
        let slope = cov / var_u;
        (mean_s - slope * mean_u, slope)
    };
    let ((au, bu), (av, bv)) = (fit(|p| p.1), fit(|p| p.2));
    for (a, b) in [(au, bu), (av, bv)] {
        for end in [a - b * centre, a + b * centre] {
            if !(0.25..=4.0).contains(&end) {
                return None;
            }
        }
    }
    Some(([au as f32, av as f32], [bu as f32, bv as f32]))
}

/// Why an image cannot give depth: blank (one grey level, or nearly) or saturated (over 90 %
/// of its pixels black or white); `None` for an image with something to match. [`depth`]
/// matches neither.
pub fn image_warning(img: &GrayImage) -> Option<&'static str> {
    let px = img.as_raw();
    let n = px.len().max(1) as f64;
    let mean = px.iter().map(|&v| f64::from(v)).sum::<f64>() / n;
    let var = px.iter().map(|&v| (f64::from(v) - mean).powi(2)).sum::<f64>() / n;
    let clipped = px.iter().filter(|&&v| v == 0 || v == 255).count() as f64 / n;
    if var.sqrt() < 1.0 {
        Some("is blank (one grey level): nothing to match")
    } else if clipped > 0.9 {
        Some("is saturated (over 90 % of its pixels black or white): not matched")
    } else {
        None
    }
}

/// Dense depth of `left` and `right` by `blob` with `params` (its `right_scale` replaced by
/// the model's). The images must be the model's
/// size (when the model records it) and each other's; the model needs matcher geometry and 4
/// inputs.
pub fn depth(
    blob: &ModelBlob,
    left: &GrayImage,
    right: &GrayImage,
    params: &DenseParams,
) -> Result<Depth> {
    if blob.n_inputs() != 4 {
        bail!(
            "a posture-aware model (9 inputs) cannot give depth from images alone: its epipolar geometry moves with the eyes; {}",
            crate::vision::locate::PIXELS_ONLY_HOW
        );
    }
    let g = matcher_geometry(blob)?;
    crate::vision::check_same_size(left, right)?;
    crate::vision::check_image_size(blob, left.dimensions())?;
    let predict = crate::vision::model_xyz(blob);
    let (w, h) = left.dimensions();
    let trusted = crate::vision::model_trusted(blob);
    let d_range = disparity_range(&g, &predict, &trusted, w, h);
    let f = model_fundamental(&g);
    // The right census windows at the model's right/left image scale; where it is not 1, the
    // scale across the right image as the model sees it at a middle depth (the global scale
    // when that does not solve).
    let mut params = DenseParams { right_scale: g.right_scale, ..*params };
    if matcher_scale(g.right_scale) != [1.0, 1.0] {
        if let Some((scale, slope)) = scale_profile(&g, &predict, &trusted, w, h) {
            (params.right_scale, params.right_scale_slope) = (scale, slope);
        }
    }
    let mut warnings = Vec::new();
    for (side, img) in [("left", left), ("right", right)] {
        if let Some(why) = image_warning(img) {
            warnings.push(format!("the {side} image {why}"));
        }
    }
    // One image given twice: nothing to match (a textured one, a board's squares, would give
    // confident matches at its period); not matched, as a blank image is not.
    if warnings.is_empty() && left.as_raw() == right.as_raw() {
        warnings.push(
            "the right image is the left one again (the same pixels): a stereo pair needs the two cameras' views; not matched"
                .to_string(),
        );
    }
    // Too many disparities for the cost volume: say where they come from.
    let why = |e: DenseError| {
        if !matches!(e, DenseError::TooLarge(..)) {
            return anyhow!("{e}");
        }
        anyhow!(
            "{e}: the model's depths, {:.0} to {:.0} cm, map to disparities {} to {} px over this image (a model trained on boards at more places across the image and more depths bounds them tighter)",
            g.out_min[2],
            g.out_max[2],
            d_range[0],
            d_range[1]
        )
    };
    // A blank or saturated image is not matched: what the aggregation makes of a blank image's
    // noise, or carries across a clipped one, is not depth.
    let mut matches = if !warnings.is_empty() {
        check_inputs(left, right, &f, d_range, &params).map_err(why)?;
        DenseMap::none(w, h)
    } else {
        dense_match(left, right, &f, d_range, &params).map_err(why)?
    };
    let (xyz, no_estimate, outside_box) = model_over_matches(blob, w as usize, &mut matches)?;
    if no_estimate > 0 {
        warnings.push(format!(
            "{no_estimate} matched pixels have no estimate from the model (left +inf)"
        ));
    }
    Ok(Depth { matches, xyz, d_range, z_box: [g.out_min[2], g.out_max[2]], warnings, outside_box })
}

/// The dense matcher's settings every answer about single points comes from (`hvs locate`,
/// `hvs head look`, `hvs view`'s depth and clicks): [`DenseParams::thorough`], whose
/// left-right check aggregates the right image on its own and refuses more of the
/// foreground spread over the background beside depth edges (the wrong answers a point
/// query gets), for about 40 % more time than `hvs depth`'s default.
pub fn locate_params() -> DenseParams {
    DenseParams::thorough()
}

/// Rows of matches that [`model_over_matches`] takes at a time.
const MODEL_ROWS: usize = 8;

/// Every match of `m` (`w` pixels a row) through the model: X, Y, Z per pixel (bit-identical
/// to `hvs predict`; a Z-only model gives Z alone, X and Y NaN; `+inf` where none), a few rows
/// at a time in parallel, each with its own small batch (no image-sized temporaries). A match
/// without an estimate is dropped from `m`; returns how many were, too.
fn model_over_matches(
    blob: &ModelBlob,
    w: usize,
    m: &mut DenseMap,
) -> Result<(Vec<[f32; 3]>, usize, usize)> {
    use rayon::prelude::*;
    let predictor = Predictor::new(blob);
    let mut xyz = vec![[f32::INFINITY; 3]; m.ur.len()];
    let no = blob.n_outputs().min(3);
    let chunk = w.max(1) * MODEL_ROWS;
    let counts: Vec<Result<[usize; 2]>> = xyz
        .par_chunks_mut(chunk)
        .zip(m.ur.par_chunks_mut(chunk))
        .zip(m.vr.par_chunks_mut(chunk))
        .zip(m.conf.par_chunks_mut(chunk))
        .enumerate()
        .map(|(c, (((xyz, ur), vr), conf))| {
            let first = c * chunk;
            let idx: Vec<usize> = (0..ur.len()).filter(|&k| ur[k].is_finite()).collect();
            let mut inputs = Vec::with_capacity(idx.len() * 4);
            for &k in &idx {
                let p = first + k;
                let (x, y) = ((p % w) as f32, (p / w) as f32);
                inputs.extend_from_slice(&[x, y, ur[k], vr[k]]);
            }
            let mut out = vec![0.0f32; idx.len() * no];
            // A point without an estimate gets +inf (counted below); the others go on.
            predictor.run_each(&inputs, &mut out).map_err(|e| anyhow!("{e:?}"))?;
            let (mut failed, mut outside) = (0, 0);
            for ((&k, o), x) in idx.iter().zip(out.chunks_exact(no)).zip(inputs.chunks_exact(4)) {
                if o.iter().all(|v| v.is_finite()) {
                    xyz[k] = if no == 3 { [o[0], o[1], o[2]] } else { [f32::NAN, f32::NAN, o[0]] };
                    outside += usize::from(!blob.in_range(x));
                } else {
                    failed += 1;
                    (ur[k], vr[k], conf[k]) = (f32::INFINITY, f32::INFINITY, 0.0);
                }
            }
            Ok([failed, outside])
        })
        .collect();
    let (mut failed, mut outside) = (0, 0);
    for c in counts {
        let [f, o] = c?;
        (failed, outside) = (failed + f, outside + o);
    }
    Ok((xyz, failed, outside))
}

/// Loads the model and both images (PNG or JPEG, checked by [`hvs_vision::image_file`]),
/// then [`depth`] with `params` (`DenseParams::default()` for `hvs depth`, `thorough()` for
/// `hvs depth --thorough`). Errors name the file at fault. Returns the left image too (the
/// grey levels of a point cloud).
pub fn depth_files(
    model_path: &Path,
    left: &Path,
    right: &Path,
    params: &DenseParams,
) -> Result<(Depth, GrayImage)> {
    let m = crate::data::model::load(model_path)?;
    if m.blob.n_inputs() == 4 {
        matcher_geometry(&m.blob).map_err(|e| anyhow!("{}: {e:#}", model_path.display()))?;
    }
    let (l, r) = crate::vision::read_pair(left, right)?;
    // `depth` refuses images of another size than the model's first, named as
    // `check_pair_size` names them.
    let d = depth(&m.blob, &l, &r, params)
        .map_err(|e| anyhow!("{} with {}: {e:#}", left.display(), model_path.display()))?;
    Ok((d, l))
}

/// Refuses images of another size than the model's training images
/// ([`crate::vision::check_image_size`]), naming where they come from (`source`: the left
/// image, a scene file, the cameras) and the model.
pub fn check_pair_size(
    model_path: &Path,
    blob: &ModelBlob,
    source: &Path,
    size: (u32, u32),
) -> Result<()> {
    crate::vision::check_image_size(blob, size)
        .map_err(|e| anyhow!("{} with {}: {e:#}", source.display(), model_path.display()))
}

/// Where the left pixels `points` are seen in the right image, answered from the dense
/// matches `d` of the pair (`hvs locate`, `hvs head look`, a click in `hvs view`), and the
/// model's X, Y, Z of each: a whole pixel takes its own match; between pixels the disparity
/// is interpolated from the four around it when all four have a match within a pixel of each
/// other, else the nearest one's is taken, and `v_r` lies on the point's epipolar line. A
/// match outside the disparities the model maps into its training depths at that pixel is
/// refused (`out_of_depth_range`), as is a pixel without one (`no_match`).
pub fn locate_in(d: &Depth, blob: &ModelBlob, points: &[[f64; 2]]) -> Result<Vec<Located>> {
    let g = matcher_geometry(blob)?;
    let f = model_fundamental(&g);
    let (d_range, z_range) =
        (training_disparities(&g), [f64::from(g.out_min[2]), f64::from(g.out_max[2])]);
    let predict = model_xyz(blob);
    let trusted = crate::vision::model_trusted(blob);
    let m = &d.matches;
    let (w, h) = (m.width as usize, m.height as usize);
    // The disparity `u_l - u_r` of whole pixel (x, y), if it has a match.
    let disparity = |x: usize, y: usize| {
        let ur = m.ur[y * w + x];
        ur.is_finite().then(|| x as f64 - f64::from(ur))
    };
    let one = |[ul, vl]: [f64; 2]| -> Located {
        let none =
            |status| Located { left: [ul, vl], right: None, xyz: None, score: f64::NAN, status };
        if !(ul.is_finite() && vl.is_finite()) {
            return none("nan_input");
        }
        if !inside_image(ul, vl, (m.width, m.height)) {
            return none("outside");
        }
        let (x, y) = (ul.round() as usize, vl.round() as usize);
        let Some(nearest) = disparity(x, y) else { return none("no_match") };
        let (x0, y0) = (ul.floor().max(0.0) as usize, vl.floor().max(0.0) as usize);
        let (x1, y1) = ((x0 + 1).min(w - 1), (y0 + 1).min(h - 1));
        let (fx, fy) = (ul - x0 as f64, vl - y0 as f64);
        let four = [disparity(x0, y0), disparity(x1, y0), disparity(x0, y1), disparity(x1, y1)];
        let disp = match four {
            [Some(a), Some(b), Some(c), Some(e)]
                if [b, c, e].iter().all(|v| (v - a).abs() <= 1.0) =>
            {
                (a * (1.0 - fx) + b * fx) * (1.0 - fy) + (c * (1.0 - fx) + e * fx) * fy
            }
            _ => nearest,
        };
        let line = f.line_in_right([ul, vl]);
        let within = model_disparity_interval_in_image(
            &predict, &trusted, ul, vl, line, z_range, d_range, m.width,
        )
        .is_some_and(|(lo, hi)| disp >= lo - 1.0 && disp <= hi + 1.0);
        let score = f64::from(m.conf[y * w + x]);
        if !within {
            return Located { score, ..none("out_of_depth_range") };
        }
        let ur = ul - disp;
        let vr = if line[1] != 0.0 { -(line[0] * ur + line[2]) / line[1] } else { f64::NAN };
        match predict([ul as f32, vl as f32, ur as f32, vr as f32]).filter(|_| vr.is_finite()) {
            Some(xyz) => Located {
                left: [ul, vl],
                right: Some([ur, vr]),
                xyz: Some(xyz),
                score,
                status: "ok",
            },
            None => Located { score, ..none("no_estimate") },
        }
    };
    Ok(points.iter().map(|&p| one(p)).collect())
}

/// Whether left pixel `(u, v)` lies inside a `w x h` image (pixel centres: from -0.5 to the
/// size - 0.5, both finite): where [`locate_in`] can answer, and what `hvs locate --at` and a
/// click in `hvs view` check.
pub fn inside_image(u: f64, v: f64, (w, h): (u32, u32)) -> bool {
    let (wf, hf) = (f64::from(w), f64::from(h));
    u > -0.5 && v > -0.5 && u < wf - 0.5 && v < hf - 0.5
}

/// Dense matches of `left` and `right` ([`depth`] with [`locate_params`]), then
/// [`locate_in`]: every point of `points` found in the right image, and the dense matcher's
/// warnings (a blank or saturated image).
pub fn locate(
    blob: &ModelBlob,
    left: &GrayImage,
    right: &GrayImage,
    points: &[[f64; 2]],
) -> Result<(Vec<Located>, Vec<String>)> {
    let d = depth(blob, left, right, &locate_params())?;
    Ok((locate_in(&d, blob, points)?, d.warnings))
}

/// [`locate`] with a model read from `model_path`: its errors name the file.
pub fn locate_with(
    model_path: &Path,
    blob: &ModelBlob,
    left: &GrayImage,
    right: &GrayImage,
    points: &[[f64; 2]],
) -> Result<(Vec<Located>, Vec<String>)> {
    locate(blob, left, right, points).map_err(|e| anyhow!("{}: {e:#}", model_path.display()))
}

/// What [`locate_files`] found: the points, the dense matcher's warnings, and both images.
pub struct LocatedFiles {
    /// Every point, in order.
    pub found: Vec<Located>,
    /// Why some or all points have no match, when the images say why (blank, saturated).
    pub warnings: Vec<String>,
    /// The left image.
    pub left: GrayImage,
    /// The right image.
    pub right: GrayImage,
}

/// Loads the model and both images, then locates `points` (`hvs locate`, `hvs head look`).
pub fn locate_files(
    model_path: &Path,
    left: &Path,
    right: &Path,
    points: &[[f64; 2]],
) -> Result<LocatedFiles> {
    let m = crate::vision::load_stereo_model(model_path)?;
    locate_files_with(model_path, &m.blob, left, right, points)
}

/// [`locate_files`] with the model already loaded (by
/// [`crate::vision::load_stereo_model`]) from `model_path`.
pub fn locate_files_with(
    model_path: &Path,
    blob: &ModelBlob,
    left: &Path,
    right: &Path,
    points: &[[f64; 2]],
) -> Result<LocatedFiles> {
    let (l, r) = crate::vision::read_pair(left, right)?;
    check_pair_size(model_path, blob, left, l.dimensions())?;
    let (found, warnings) = locate_with(model_path, blob, &l, &r, points)?;
    Ok(LocatedFiles { found, warnings, left: l, right: r })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A model whose right scale along u grows across the image (du_r/du_l = 0.8 +
    /// 2 q (u_l - c), 0.65 to 0.95) and is 0.8 along v: [`scale_profile`] fits those lines.
    #[test]
    fn the_scale_profile_follows_the_model_across_the_image() {
        let (w, h, c, cy, q, k) = (640u32, 480u32, 319.5, 239.5, 0.15 / 640.0, 3000.0);
        let g_u = |u: f64| c + 0.8 * (u - c) + q * (u - c).powi(2);
        let predict = |x: [f32; 4]| {
            let [ul, _, ur, _] = x.map(f64::from);
            let gap = g_u(ul) - ur;
            (gap > 0.0).then(|| [0.0, 0.0, (k / gap) as f32])
        };
        let trusted = |_: [f32; 4]| true;
        // The right line of (ul, vl): v = 0.8 vl + 0.2 cy.
        let g = MatcherGeometry {
            fundamental: [[0.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -0.8, -0.2 * cy as f32]],
            out_min: [0.0, 0.0, 50.0],
            out_max: [0.0, 0.0, 150.0],
            disparity: [-100.0, 120.0],
            right_scale: [0.8, 0.8],
        };
        let (scale, slope) = scale_profile(&g, &predict, &trusted, w, h).expect("solves");
        assert!((scale[1] - 0.8).abs() < 1e-3 && slope[1].abs() < 1e-6, "{scale:?} {slope:?}");
        let z_mid = 2.0 / (1.0 / 50.0 + 1.0 / 150.0);
        for ul in [40.0, 320.0, 600.0] {
            let ur = g_u(ul) - k / z_mid;
            let fit = f64::from(scale[0]) + f64::from(slope[0]) * (ur - c);
            let truth = 0.8 + 2.0 * q * (ul - c);
            assert!((fit - truth).abs() < 0.01, "at u_l {ul}: {fit} against {truth}");
        }
    }

    /// [`model_over_matches`] in row chunks gives every match the model's point by point answer
    /// ([`model_xyz`], `ModelBlob::infer`) to the bit, and drops the matches it has none for.
    #[test]
    fn the_model_over_the_matches_is_the_point_by_point_answer() {
        let path =
            Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/tests/golden/v4_4_5_3.hvsw");
        let blob = crate::data::model::load(&path).unwrap().blob;
        let point = model_xyz(&blob);
        // 37 x 21 pixels: three chunks of MODEL_ROWS rows, the last one short.
        let (w, h) = (37usize, 21usize);
        let mut rng = 12345u64;
        let mut next =
            || (hvs_shared::test_support::splitmix64(&mut rng) >> 40) as f32 / (1u64 << 24) as f32;
        let n = w * h;
        let mut m = DenseMap {
            width: w as u32,
            height: h as u32,
            ur: vec![f32::INFINITY; n],
            vr: vec![f32::INFINITY; n],
            conf: vec![0.0; n],
        };
        let mut refused = 0;
        for p in 0..n {
            match p % 5 {
                0 => continue,
                // Not a number where the matcher would have given one: refused by the model.
                1 if p % 3 == 0 => {
                    refused += 1;
                    (m.ur[p], m.vr[p]) = (100.0, f32::NAN);
                }
                _ => {
                    let x = (p % w) as f32;
                    (m.ur[p], m.vr[p]) = (x - 10.0 - 20.0 * next(), (p / w) as f32 + next());
                }
            }
            m.conf[p] = 0.5 + 0.5 * next();
        }
        let before = m.clone();
        let (xyz, dropped, outside) = model_over_matches(&blob, w, &mut m).unwrap();
        assert_eq!(dropped, refused);
        let mut want_outside = 0;
        for (p, got) in xyz.iter().enumerate() {
            let want = before.ur[p]
                .is_finite()
                .then(|| point([(p % w) as f32, (p / w) as f32, before.ur[p], before.vr[p]]));
            match want.flatten() {
                Some(q) => {
                    let x = [(p % w) as f32, (p / w) as f32, before.ur[p], before.vr[p]];
                    want_outside += usize::from(!blob.in_range(&x));
                    assert_eq!(got.map(f32::to_bits), q.map(f32::to_bits), "pixel {p}");
                    assert_eq!(
                        (m.ur[p], m.vr[p], m.conf[p]),
                        (before.ur[p], before.vr[p], before.conf[p])
                    );
                }
                None => {
                    assert_eq!(*got, [f32::INFINITY; 3], "pixel {p}");
                    assert!(
                        m.ur[p] == f32::INFINITY && m.vr[p] == f32::INFINITY && m.conf[p] == 0.0
                    );
                }
            }
        }
        // The golden model's box is the thesis' middle pixels, far from these 37 x 21 (the
        // mixed case: `vision::locate`'s test).
        assert_eq!(outside, want_outside);
    }
}
