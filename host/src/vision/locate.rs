//! What `hvs locate` answers ([`Located`]) and draws ([`locate_overlay`]), and the model's side
//! of every image command: its matcher geometry, the disparities it was trained on, its X, Y,
//! Z of a stereo pixel pair, the image size it holds for. The points themselves are found in
//! the dense matches of the pair ([`crate::depth::locate`]).

use anyhow::{anyhow, bail, Result};
use hvs_shared::runtime::blob::{MatcherGeometry, ModelBlob};
use image::{GrayImage, Rgb, RgbImage};
use std::path::Path;

/// The model's X, Y, Z (cm) of a stereo pixel pair, `None` where it gives no finite estimate;
/// a Z-only model (`hvs train --outputs z`) gives Z, and X, Y as NaN.
pub fn model_xyz(blob: &ModelBlob) -> impl Fn([f32; 4]) -> Option<[f32; 3]> + Sync + '_ {
    let n_out = blob.n_outputs().min(3);
    move |x: [f32; 4]| {
        let mut out = [0.0f32; 3];
        blob.infer(&x, &mut out[..n_out]).ok()?;
        if !out[..n_out].iter().all(|v| v.is_finite()) {
            return None;
        }
        Some(if n_out == 1 { [f32::NAN, f32::NAN, out[0]] } else { out })
    }
}

/// Share of each input's training span by which [`model_trusted`] widens the model's training
/// box on either side.
pub const TRUSTED_INPUT_MARGIN: f32 = 0.1;

/// Whether `blob` may be asked about a pixel quadruple when the matcher looks beyond the
/// training disparities: every input inside the model's training box (its `in_min` ..
/// `in_max`) widened by [`TRUSTED_INPUT_MARGIN`] of its span. Far outside the box a net's
/// answers are extrapolation (a 4-5-3 net trained on the thesis' 72 middle points puts the
/// training depths at hundreds of disparities near the image edges).
pub fn model_trusted(blob: &ModelBlob) -> impl Fn([f32; 4]) -> bool + Sync + '_ {
    move |x: [f32; 4]| {
        x.iter().zip(blob.in_min.iter().zip(blob.in_max.iter())).all(|(&v, (&lo, &hi))| {
            let m = TRUSTED_INPUT_MARGIN * (hi - lo);
            v >= lo - m && v <= hi + m
        })
    }
}

/// How many of `found` have an estimate from a quadruple `(u_l, v_l, u_r, v_r)` outside
/// `blob`'s input box: the net extrapolated them.
pub fn outside_box(blob: &ModelBlob, found: &[Located]) -> usize {
    found
        .iter()
        .filter(|f| f.xyz.is_some())
        .filter_map(|f| f.right.map(|r| [f.left[0], f.left[1], r[0], r[1]].map(|v| v as f32)))
        .filter(|x| !blob.in_range(x))
        .count()
}

/// Refuses images of another size than the model's training images (when the model records
/// it: `hvs train` on `hvs board detect`'s points): its geometry and depths are for that size.
pub fn check_image_size(blob: &ModelBlob, (w, h): (u32, u32)) -> Result<()> {
    match blob.image_size() {
        Some((mw, mh)) if (u32::from(mw), u32::from(mh)) != (w, h) => bail!(
            "the images are {w}x{h} px, the model was trained on {mw}x{mh} px images: its \
             matcher geometry and depths hold for that size only (resize the images, or train \
             on points found in images of this size)"
        ),
        _ => Ok(()),
    }
}

/// Every status of a located point: `ok`, or why there is no trustworthy match (the pixel is
/// outside the image or not a number; the dense matching kept no match there; the match lies
/// outside the depths the model was trained on at that pixel; the model gives no estimate).
pub const STATUSES: [&str; 6] =
    ["ok", "outside", "nan_input", "no_match", "out_of_depth_range", "no_estimate"];

/// One point located in the right image and triangulated by the model.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Located {
    /// The left pixel asked for.
    pub left: [f64; 2],
    /// The match in the right image, when trustworthy.
    pub right: Option<[f64; 2]>,
    /// The model's X, Y, Z (cm) of the matched pair (X and Y NaN for a Z-only model).
    pub xyz: Option<[f32; 3]>,
    /// The dense match's confidence, 0..1 (NaN when there is no match).
    pub score: f64,
    /// `ok`, or why there is no trustworthy match ([`STATUSES`]).
    pub status: &'static str,
}

impl Located {
    /// The numbers `hvs locate --at` prints for a trustworthy match, as it prints them:
    /// `[u_r, v_r, x, y, z, score]` (the right pixel as an `f32`, X, Y, Z in shortest
    /// round-trip form, the score with 3 decimals); `None` without one.
    pub fn texts(&self) -> Option<[String; 6]> {
        self.right?;
        self.xyz?;
        let [ur, vr, x, y, z] = self.fields();
        Some([ur, vr, x, y, z, format!("{:.3}", self.score)])
    }

    /// `u_r, v_r, x, y, z` as `hvs locate` writes and prints them: the right pixel as an
    /// `f32`, X, Y, Z in shortest round-trip form; empty where there is none (X and Y of a
    /// Z-only model, all five without a match).
    fn fields(&self) -> [String; 5] {
        let text = |v: Option<f32>| {
            v.filter(|v| v.is_finite()).map_or_else(String::new, |v| v.to_string())
        };
        let (r, x) = (self.right, self.xyz);
        [
            text(r.map(|r| r[0] as f32)),
            text(r.map(|r| r[1] as f32)),
            text(x.map(|x| x[0])),
            text(x.map(|x| x[1])),
            text(x.map(|x| x[2])),
        ]
    }

    /// The point's row of `hvs locate`'s CSV (`u_l,v_l,u_r,v_r,x,y,z,score,status`, without
    /// the passed-through columns): [`Located::texts`]' fields, the score with 4 decimals.
    pub fn csv_row(&self) -> String {
        let [ur, vr, x, y, z] = self.fields();
        let score =
            if self.score.is_finite() { format!("{:.4}", self.score) } else { String::new() };
        format!("{},{},{ur},{vr},{x},{y},{z},{score},{}", self.left[0], self.left[1], self.status)
    }

    /// The line `hvs locate --at` prints for this point (and `hvs view` shows): the match,
    /// X, Y, Z and the score ([`Located::texts`]), or why there is none.
    pub fn line(&self) -> String {
        match self.texts() {
            Some([ur, vr, x, _, z, score]) if x.is_empty() => {
                format!("u_r={ur} v_r={vr} z={z} cm (score {score})")
            }
            Some([ur, vr, x, y, z, score]) => {
                format!("u_r={ur} v_r={vr} x={x} y={y} z={z} cm (score {score})")
            }
            None => format!("no trustworthy match: {}", self.status),
        }
    }
}

/// The training set's disparities widened by this share of their span on each side, as the
/// search range the model's depth range is looked for in.
pub const DISPARITY_SLACK: f64 = 0.1;

/// The model's matcher geometry, or the error every image command gives without it.
pub fn matcher_geometry(blob: &ModelBlob) -> Result<MatcherGeometry> {
    blob.matcher.ok_or_else(|| {
        anyhow!("the model has no matcher geometry: {}", crate::train::matcher::NO_MATCHER_WHY)
    })
}

/// The model's fundamental matrix (fitted to its training points, kept in `f32`) in `f64`.
pub fn model_fundamental(g: &MatcherGeometry) -> hvs_vision::geometry::Fundamental {
    hvs_vision::geometry::Fundamental { m: g.fundamental.map(|r| r.map(f64::from)) }
}

/// The training set's disparities (`u_l - u_r`, px) widened by [`DISPARITY_SLACK`] of their
/// span on each side.
pub fn training_disparities(g: &MatcherGeometry) -> [f64; 2] {
    let span = f64::from(g.disparity[1] - g.disparity[0]);
    [
        f64::from(g.disparity[0]) - DISPARITY_SLACK * span,
        f64::from(g.disparity[1]) + DISPARITY_SLACK * span,
    ]
}

/// What to do with a posture-aware model where an image command needs a pixels-only one.
pub const PIXELS_ONLY_HOW: &str = "train a pixels-only model for these images: board pairs \
    taken at one head posture, `hvs board detect` on a captures file without joint columns, \
    then `hvs train`";

/// Loads a model that can locate from an image pair alone (4 inputs: u_l, v_l, u_r, v_r).
pub fn load_stereo_model(model_path: &Path) -> Result<crate::data::model::ModelFile> {
    let m = crate::data::model::load(model_path)?;
    if m.blob.n_inputs() != 4 {
        bail!(
            "{}: a posture-aware model (9 inputs) cannot locate from images alone: its epipolar geometry moves with the eyes; {PIXELS_ONLY_HOW}",
            model_path.display()
        );
    }
    Ok(m)
}

/// The two images side by side, each located point drawn in both (a cross, a line between
/// them, its row number) in green, refused ones as a red cross in the left image only. The
/// lines go first, then the numbers (up and right of each point; the small font when points
/// lie closer than 40 px), then the crosses, so that no number hides a point.
pub fn locate_overlay(left: &GrayImage, right: &GrayImage, found: &[Located]) -> RgbImage {
    use hvs_vision::overlay::{draw_cross, draw_line, draw_text};
    let (w, h) = left.dimensions();
    let mut img = RgbImage::new(2 * w, h.max(right.height()));
    for (x, y, p) in left.enumerate_pixels() {
        img.put_pixel(x, y, Rgb([p[0]; 3]));
    }
    for (x, y, p) in right.enumerate_pixels() {
        img.put_pixel(x + w, y, Rgb([p[0]; 3]));
    }
    let (ok, bad) = (Rgb([40, 220, 60]), Rgb([230, 40, 40]));
    let drawn: Vec<(usize, &Located)> = found
        .iter()
        .enumerate()
        .filter(|(_, l)| l.left[0].is_finite() && l.left[1].is_finite())
        .collect();
    let pair = |l: &Located| l.right.map(|r| (l.left, [r[0] + f64::from(w), r[1]]));
    for (_, l) in &drawn {
        if let Some((a, b)) = pair(l) {
            draw_line(&mut img, a, b, Rgb([40, 140, 220]));
        }
    }
    // The large font only for a few points well apart.
    let near = |a: [f64; 2], b: [f64; 2]| (a[0] - b[0]).hypot(a[1] - b[1]) < 40.0;
    let crowded = drawn.len() > 64
        || drawn
            .iter()
            .enumerate()
            .any(|(i, (_, a))| drawn[i + 1..].iter().any(|(_, b)| near(a.left, b.left)));
    let (scale, up) = if crowded { (1, 8) } else { (2, 13) };
    for (k, l) in &drawn {
        if let Some((a, b)) = pair(l) {
            let label = (k + 1).to_string();
            for p in [a, b] {
                draw_text(&mut img, p[0] as i64 + 4, p[1] as i64 - up, &label, scale, ok);
            }
        }
    }
    for (_, l) in &drawn {
        match pair(l) {
            Some((a, b)) => {
                draw_cross(&mut img, a, 4.0, ok);
                draw_cross(&mut img, b, 4.0, ok);
            }
            None => draw_cross(&mut img, l.left, 4.0, bad),
        }
    }
    img
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at(left: [f64; 2], right: Option<[f64; 2]>) -> Located {
        Located {
            left,
            right,
            xyz: None,
            score: 1.0,
            status: if right.is_some() { "ok" } else { "no_match" },
        }
    }

    /// Only answered points count, and only those whose quadruple leaves the input box (0 to
    /// 640 on every input for the test blob); the note names the count.
    #[test]
    fn answers_outside_the_input_box_are_counted_as_extrapolations() {
        use hvs_shared::runtime::blob::{InputKind, OutputKind};
        let blob = crate::infer::tests::blob(5, OutputKind::Xyz, InputKind::Stereo);
        let with = |left: [f64; 2], right: Option<[f64; 2]>, xyz: bool| Located {
            xyz: xyz.then_some([0.0, 0.0, 100.0]),
            ..at(left, right)
        };
        let found = [
            with([300.0, 200.0], Some([280.0, 200.0]), true),
            with([630.0, 200.0], Some([650.0, 200.0]), true),
            with([-0.4, 10.0], Some([-20.0, 10.0]), true),
            with([630.0, 200.0], Some([650.0, 200.0]), false),
            with([700.0, 200.0], None, false),
        ];
        assert_eq!(outside_box(&blob, &found), 2);
        assert_eq!(outside_box(&blob, &found[..1]), 0);
        let note = crate::infer::extrapolation_note(2, 3, "located points").unwrap();
        assert!(note.starts_with("note: 2 of 3 located points lie outside the input box"));
        assert!(crate::infer::extrapolation_note(0, 3, "located points").is_none());
    }

    /// Every cross is drawn over the numbers, however close the points (a grid 12 px apart, as
    /// the corners of a far board), in green where matched and red where refused.
    #[test]
    fn numbers_never_hide_a_point() {
        let (l, r) = (GrayImage::new(120, 80), GrayImage::new(120, 80));
        let mut found = Vec::new();
        for j in 0..4 {
            for i in 0..6 {
                let p = [20.0 + 12.0 * f64::from(i), 20.0 + 12.0 * f64::from(j)];
                found.push(at(p, (i != 3).then_some([p[0] - 8.0, p[1]])));
            }
        }
        let img = locate_overlay(&l, &r, &found);
        let (ok, bad) = (Rgb([40, 220, 60]), Rgb([230, 40, 40]));
        for f in &found {
            let [x, y] = f.left.map(|v| v as u32);
            let want = if f.right.is_some() { ok } else { bad };
            // The cross's centre and the ends of its arms.
            for (dx, dy) in [(0i32, 0i32), (-3, 0), (3, 0), (0, -3), (0, 3)] {
                let p = *img.get_pixel((x as i32 + dx) as u32, (y as i32 + dy) as u32);
                assert_eq!(p, want, "({x}, {y}) + ({dx}, {dy})");
            }
            if let Some([u, v]) = f.right {
                assert_eq!(*img.get_pixel(u as u32 + 120, v as u32), ok);
            }
        }
    }
}
