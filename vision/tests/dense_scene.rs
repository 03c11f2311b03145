//! Dense matching through the thesis' verged cameras (cases III and IV: deflected optic axes,
//! IV with a right focal length 0.8 times the left one), on textured scenes rendered with
//! exact per-pixel truth by [`hvs_vision::scene`]: spheres and boxes, and slanted planes and a
//! sphere, before a wall at 300 cm, 70-300 cm. The matcher gets the pinhole pair's fundamental matrix (what a trained model
//! carries), its right/left image scale, and the disparity range the scene's depths span
//! widened by 3 px (what a model trained over 70-300 cm bounds); nothing per pixel. Scored against the true match of every
//! left pixel seen by both cameras; depth by optimal triangulation with the true cameras (the
//! model's part is tested in `host/tests/cli/depth.rs`).

use hvs_shared::runtime::gaze::Joints;
use hvs_shared::sim::posture::HeadRig;
use hvs_shared::sim::presets;
use hvs_shared::sim::triangulate::optimal;
use hvs_vision::dense::{dense_match, DenseParams};
use hvs_vision::geometry::pinhole_fundamental;
use hvs_vision::render::RenderOptions;
use hvs_vision::scene::{render_scene, SceneFile};

const SCENE: &str = include_str!("fixtures/scenes/spheres_and_boxes.json");

/// Slanted planes (a floor-like ramp, a wall turned away, a panel tilted both ways) and a
/// sphere before the wall: disparities that change across a surface.
const SLANTED: &str = include_str!("fixtures/scenes/slanted_planes.json");

struct Rates {
    returned_pct: f64,
    within_1_pct: f64,
    median_depth_err_pct: f64,
}

/// `scene` through case `case`'s rig, scaled by `scale` (image size and focal lengths),
/// matched with `base` (its right scale the rig's).
fn run(text: &str, case: u8, scale: f64, base: DenseParams) -> Rates {
    let mut rig = presets::case(case).unwrap();
    rig.width = (f64::from(rig.width) * scale) as u32;
    rig.height = (f64::from(rig.height) * scale) as u32;
    rig.u0 *= scale;
    rig.v0 *= scale;
    rig.phi_u_left *= scale;
    rig.phi_u_right *= scale;
    rig.phi_v_left *= scale;
    rig.phi_v_right *= scale;
    let head = HeadRig::new(rig);
    let scene = SceneFile::parse(text).unwrap().scene().unwrap();
    let r =
        render_scene(&head, &Joints::HOME, &scene.at(0.0), &RenderOptions::default(), 5).unwrap();
    let (w, h) = r.left.dimensions();
    let f = pinhole_fundamental(&r.cameras[0].camera, &r.cameras[1].camera);
    // Every left pixel's true match, and the disparity extent of the scene.
    let mut truth = Vec::with_capacity((w * h) as usize);
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for y in 0..h {
        for x in 0..w {
            let t = r.true_match(x, y);
            if let Some([ur, _]) = t {
                lo = lo.min(f64::from(x) - ur);
                hi = hi.max(f64::from(x) - ur);
            }
            truth.push(t);
        }
    }
    let d_range = [lo.floor() as i32 - 3, hi.ceil() as i32 + 3];
    // The right/left image scale, as a model reads it off its training set.
    let right_scale =
        [(rig.phi_u_right / rig.phi_u_left) as f32, (rig.phi_v_right / rig.phi_v_left) as f32];
    let params = DenseParams { right_scale, ..base };
    let m = dense_match(&r.left, &r.right, &f, d_range, &params).unwrap();
    let (mut seen, mut ret, mut within, mut errs) = (0usize, 0usize, 0usize, Vec::new());
    let border = 4;
    for y in border..h - border {
        for x in border..w - border {
            let p = (y * w + x) as usize;
            let Some(t) = truth[p] else { continue };
            seen += 1;
            if !m.ur[p].is_finite() {
                continue;
            }
            ret += 1;
            let (ur, vr) = (f64::from(m.ur[p]), f64::from(m.vr[p]));
            if (ur - t[0]).hypot(vr - t[1]) <= 1.0 {
                within += 1;
            }
            let z_true = f64::from(r.truth_left.z(x, y).unwrap());
            if let Ok(q) = optimal(&r.cameras, &[f64::from(x), f64::from(y), ur, vr]) {
                errs.push(((q[2] - z_true) / z_true).abs() * 100.0);
            }
        }
    }
    errs.sort_by(f64::total_cmp);
    let rates = Rates {
        returned_pct: 100.0 * ret as f64 / seen as f64,
        within_1_pct: 100.0 * within as f64 / ret.max(1) as f64,
        median_depth_err_pct: errs.get(errs.len() / 2).copied().unwrap_or(f64::NAN),
    };
    eprintln!(
        "{} case {case}{}: {w}x{h}, disparities {d_range:?}; {seen} pixels seen by both cameras, returned {:.2} %, within 1 px {:.2} %, median depth error {:.3} %",
        if text == SLANTED { "slanted planes," } else { "spheres and boxes," },
        if base.refuse_past_gaps { " (thorough)" } else { "" },
        rates.returned_pct,
        rates.within_1_pct,
        rates.median_depth_err_pct
    );
    rates
}

/// Case III at half size (320 x 240, half the focal lengths) to keep the test fast: the
/// matching goals (case IV and full size: the ignored measurement below).
#[test]
fn case_3_at_half_size_matches_within_1_px() {
    let r = run(SCENE, 3, 0.5, DenseParams::default());
    assert!(r.returned_pct >= 95.0, "returned {}", r.returned_pct);
    assert!(r.within_1_pct >= 98.0, "within 1 px {}", r.within_1_pct);
    assert!(r.median_depth_err_pct.is_finite());
}

/// The thesis' cameras at full size (640 x 480), all three goals, with the default settings
/// and `hvs locate`'s (`DenseParams::thorough`); slow in the dev profile: `cargo test
/// --release -p hvs-vision --test dense_scene -- --ignored --nocapture`.
#[test]
#[ignore = "a measurement: run in release"]
fn cases_3_and_4_full_size_goals() {
    let mut failed = Vec::new();
    let _ = run(SCENE, 4, 0.5, DenseParams::default());
    for scene in [SCENE, SLANTED] {
        for case in [3, 4] {
            for base in [DenseParams::default(), DenseParams::thorough()] {
                let r = run(scene, case, 1.0, base);
                if r.returned_pct < 95.0 || r.within_1_pct < 98.0 || r.median_depth_err_pct > 0.5 {
                    failed.push((scene == SLANTED, case, base.refuse_past_gaps));
                }
            }
        }
    }
    assert!(
        failed.is_empty(),
        "goals missed in (slanted, case, thorough) {failed:?} (rates above)"
    );
}
