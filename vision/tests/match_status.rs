//! The matcher's refusals: each status where it belongs, and errors naming the field.

use hvs_shared::sim::presets;
use hvs_vision::geometry::pinhole_fundamental;
use hvs_vision::geometry::Fundamental;
use hvs_vision::matching::{match_points, MatchParams, MatchStatus, Matcher, Query};
use hvs_vision::render::{opencv_board, render_rig, RenderOptions};
use image::GrayImage;

fn rectified() -> Fundamental {
    Fundamental { m: [[0.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]] }
}

/// A textured image: a smooth pseudo-random pattern.
fn texture(w: u32, h: u32, shift: u32) -> GrayImage {
    GrayImage::from_fn(w, h, |x, y| {
        let x = x + shift;
        let v = 128.0
            + 50.0 * ((x as f64) * 0.37).sin() * ((y as f64) * 0.23).cos()
            + 40.0 * ((x as f64 * 0.11 + y as f64 * 0.19).sin());
        image::Luma([v as u8])
    })
}

/// The query of the left point `(ul, vl)` for disparities in `[d_min, d_max]`.
fn query(ul: f64, vl: f64, d_min: f64, d_max: f64) -> Query {
    Query { ul, vl, d_min, d_max }
}

#[test]
fn a_shifted_texture_is_found_at_its_shift() {
    // Right image = left shifted by 12 px: u_r = u_l - 12.
    let l = texture(200, 120, 0);
    let r = texture(200, 120, 12);
    // r(x) = pattern(x + 12) = l(x + 12): the left point u_l is at u_r = u_l - 12.
    let m = Matcher::new(&l, &r, &rectified(), MatchParams::default()).unwrap();
    let got = m.find(&query(100.0, 60.0, 5.0, 20.0));
    assert_eq!(got.status, MatchStatus::Ok, "{got:?}");
    // The parabola through an asymmetric ZNCC peak is biased by up to ~0.15 px.
    assert!((got.ur - 88.0).abs() < 0.2 && (got.vr - 60.0).abs() < 1e-9, "{got:?}");
    assert!(got.score > 0.99);
    // The true disparity outside the interval: no peak inside it (the pattern's 17 px
    // period would repeat at 29 and 46 px: the interval avoids both).
    let got = m.find(&query(100.0, 60.0, 32.0, 40.0));
    assert_ne!(got.status, MatchStatus::Ok, "{got:?}");
}

#[test]
fn refusals_have_their_status() {
    let l = texture(200, 120, 0);
    let r = texture(200, 120, 12);
    let q = query;
    let m = Matcher::new(&l, &r, &rectified(), MatchParams::default()).unwrap();
    assert_eq!(m.find(&q(f64::NAN, 60.0, 5.0, 20.0)).status, MatchStatus::NanInput);
    assert_eq!(m.find(&q(100.0, 60.0, 5.0, f64::INFINITY)).status, MatchStatus::NanInput);
    // Points off the image.
    for (u, v) in [(-0.5, 60.0), (199.5, 60.0), (100.0, -1.0), (100.0, 119.2)] {
        assert_eq!(m.find(&q(u, v, 5.0, 20.0)).status, MatchStatus::Outside);
    }
    // Near the borders the window is clipped to the image and the match still found.
    for (u, v) in [(30.0, 1.0), (100.0, 118.0), (196.0, 60.0), (190.0, 117.5)] {
        let got = m.find(&q(u, v, 5.0, 20.0));
        assert_eq!(got.status, MatchStatus::Ok, "({u}, {v}): {got:?}");
        assert!((got.ur - (u - 12.0)).abs() < 0.3, "({u}, {v}): {got:?}");
    }
    // Every candidate window off the right image's left edge.
    assert_eq!(m.find(&q(20.0, 60.0, 30.0, 40.0)).status, MatchStatus::Outside);
    assert_eq!(m.find(&q(100.0, 60.0, 20.0, 5.0)).status, MatchStatus::NoCandidate);
    // A flat image has no texture.
    let flat = GrayImage::from_pixel(200, 120, image::Luma([90]));
    let m = Matcher::new(&flat, &r, &rectified(), MatchParams::default()).unwrap();
    assert_eq!(m.find(&q(100.0, 60.0, 5.0, 20.0)).status, MatchStatus::NoTexture);
    // A vertical stripe pattern with a 6 px period, searched over 30 px: ambiguous.
    let stripes = |shift: u32| {
        GrayImage::from_fn(200, 120, |x, _| {
            image::Luma([if ((x + shift) / 3) % 2 == 0 { 40 } else { 200 }])
        })
    };
    let m = Matcher::new(&stripes(0), &stripes(2), &rectified(), MatchParams::default()).unwrap();
    assert_eq!(m.find(&q(100.0, 60.0, 0.0, 30.0)).status, MatchStatus::Ambiguous);
}

#[test]
fn an_occluded_corner_is_not_returned() {
    let rig = presets::CASE_1;
    let board = opencv_board();
    let r = render_rig(&rig, &board, [0.0, 0.0, 85.0], &RenderOptions::default(), 4).unwrap();
    let f = pinhole_fundamental(&rig.left(), &rig.right());
    let c = &r.corners[20];
    let d = c.px[0] - c.px[2];
    let q = query(c.px[0], c.px[1], d - 3.0, d + 3.0);
    let all = match_points(&r.left, &r.right, &f, &[q], MatchParams::default()).unwrap();
    assert_eq!(all[0].status, MatchStatus::Ok);
    // Occlude the corner in the right image with flat grey: the best candidate then is
    // weak or refused, never ok at the wrong place.
    let mut right = r.right.clone();
    let (uc, vc) = (c.px[2].round() as i64, c.px[3].round() as i64);
    for y in vc - 8..=vc + 8 {
        for x in uc - 8..=uc + 8 {
            right.put_pixel(x as u32, y as u32, image::Luma([128]));
        }
    }
    let got = match_points(&r.left, &right, &f, &[q], MatchParams::default()).unwrap()[0];
    assert_ne!(got.status, MatchStatus::Ok, "{got:?}");
}

#[test]
fn bad_setup_is_an_error_naming_the_field() {
    let l = texture(100, 80, 0);
    let small = texture(90, 80, 0);
    let e = Matcher::new(&l, &small, &rectified(), MatchParams::default()).err().unwrap();
    assert!(e.to_string().starts_with("right"), "{e}");
    let e = Matcher::new(&l, &l, &Fundamental { m: [[0.0; 3]; 3] }, MatchParams::default())
        .err()
        .unwrap();
    assert!(e.to_string().starts_with("fundamental"), "{e}");
    let p = MatchParams { lr_tolerance_px: -1.0, ..MatchParams::default() };
    let e = Matcher::new(&l, &l, &rectified(), p).err().unwrap();
    assert!(e.to_string().starts_with("params.lr_tolerance_px"), "{e}");
}

#[test]
fn a_right_image_scaled_along_u_is_matched_with_right_scale() {
    // Right = left stretched by 1.4 along u about u = 100 and moved: the left point u_l is
    // seen at u_r = 100 + 1.4 (u_l - 112) (a right camera with a 1.4 x longer focal length).
    let pattern = |x: f64, y: f64| {
        128.0 + 50.0 * (x * 0.37).sin() * (y * 0.23).cos() + 40.0 * (x * 0.11 + y * 0.19).sin()
    };
    let l = GrayImage::from_fn(300, 120, |x, y| image::Luma([pattern(x as f64, y as f64) as u8]));
    let r = GrayImage::from_fn(300, 120, |x, y| {
        let xs = (x as f64 - 100.0) / 1.4 + 112.0;
        image::Luma([pattern(xs, y as f64) as u8])
    });
    let scaled = MatchParams { right_scale: [1.4, 1.0], ..MatchParams::default() };
    let plain = Matcher::new(&l, &r, &rectified(), MatchParams::default()).unwrap();
    let m = Matcher::new(&l, &r, &rectified(), scaled).unwrap();
    let (mut ok, mut plain_score, mut scaled_score) = (0, 0.0, 0.0);
    for ul in (140..=200).step_by(6) {
        let ul = f64::from(ul);
        let truth = 100.0 + 1.4 * (ul - 112.0);
        let d = ul - truth;
        let q = query(ul, 60.0, d - 4.0, d + 4.0);
        let got = m.find(&q);
        if got.is_ok() {
            ok += 1;
            assert!((got.ur - truth).abs() < 0.5, "{ul}: {got:?} truth {truth}");
        }
        scaled_score += got.score;
        plain_score += plain.find(&q).score;
    }
    assert!(ok >= 9, "{ok} of 11");
    assert!(scaled_score > plain_score, "{scaled_score} vs {plain_score}");
    // The scale is validated.
    let bad = MatchParams { right_scale: [0.0, 1.0], ..MatchParams::default() };
    let e = Matcher::new(&l, &r, &rectified(), bad).err().unwrap();
    assert!(e.to_string().starts_with("params.right_scale[0]"), "{e}");
}
