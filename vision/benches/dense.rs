//! Dense matching speed: [`dense_match`] on a 741 x 500 pair with 66 disparities (the
//! Motorcycle pair's size and its model's disparity range 2..=67), 8 paths; on the real pair
//! also with `hvs locate`'s settings (`DenseParams::thorough`). Run with
//! `RAYON_NUM_THREADS=1` for one core. With `HVS_MOTORCYCLE_DIR` set (see
//! `vision/tests/dense_real.rs`) the real pair is used, PNG decoding included; else a
//! synthetic textured pair of the same size. And a verged pair: the spheres-and-boxes scene of
//! `vision/tests/dense_scene.rs` rendered through case IV at 640 x 480 (the right focal length
//! 0.8 times the left: unrectified, the warped refinement), 137 disparities.

#[path = "../tests/dense_common/mod.rs"]
mod dense_common;

use criterion::{criterion_group, criterion_main, Criterion};
use hvs_shared::runtime::gaze::Joints;
use hvs_shared::sim::posture::HeadRig;
use hvs_shared::sim::presets;
use hvs_vision::dense::{dense_match, DenseParams};
use hvs_vision::geometry::{pinhole_fundamental, Fundamental};
use hvs_vision::render::RenderOptions;
use hvs_vision::scene::{render_scene, SceneFile};
use std::hint::black_box;

fn rectified() -> Fundamental {
    Fundamental { m: [[0.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]] }
}

fn bench(c: &mut Criterion) {
    let f = rectified();
    let d_range = [2, 67];
    let mut g = c.benchmark_group("dense");
    g.sample_size(10);
    if let Ok(dir) = std::env::var("HVS_MOTORCYCLE_DIR") {
        let dir = std::path::PathBuf::from(dir);
        let (l, r) = (dir.join("motorcycle_left.png"), dir.join("motorcycle_right.png"));
        for (name, p) in [
            ("motorcycle_741x500_decode_and_match", DenseParams::default()),
            ("motorcycle_741x500_decode_and_match_thorough", DenseParams::thorough()),
        ] {
            g.bench_function(name, |b| {
                b.iter(|| {
                    let left = hvs_vision::image_file::read_grey(&l).unwrap();
                    let right = hvs_vision::image_file::read_grey(&r).unwrap();
                    black_box(dense_match(&left, &right, &f, d_range, &p).unwrap())
                })
            });
        }
    }
    let pair = dense_common::scene(741, 500, 20.0, 20.0, 55.0, 1, 0.0, 0.0);
    for (name, eight) in [("synthetic_741x500_8_paths", true), ("synthetic_741x500_4_paths", false)]
    {
        let p = DenseParams { eight_paths: eight, ..DenseParams::default() };
        g.bench_function(name, |b| {
            b.iter(|| black_box(dense_match(&pair.left, &pair.right, &f, d_range, &p).unwrap()))
        });
    }
    // The verged pair, its disparities those the scene spans widened by 3 px (as the test).
    let rig = presets::case(4).expect("case IV");
    let scene = include_str!("../tests/fixtures/scenes/spheres_and_boxes.json");
    let scene = SceneFile::parse(scene).expect("scene").scene().expect("scene");
    let head = HeadRig::new(rig);
    let r = render_scene(&head, &Joints::HOME, &scene.at(0.0), &RenderOptions::default(), 5)
        .expect("render");
    let f = pinhole_fundamental(&r.cameras[0].camera, &r.cameras[1].camera);
    let right_scale =
        [(rig.phi_u_right / rig.phi_u_left) as f32, (rig.phi_v_right / rig.phi_v_left) as f32];
    let p = DenseParams { right_scale, ..DenseParams::default() };
    g.bench_function("verged_case4_640x480", |b| {
        b.iter(|| black_box(dense_match(&r.left, &r.right, &f, [-103, 33], &p).unwrap()))
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
