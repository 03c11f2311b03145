//! Scene rendering speed: one 640x480 stereo pair of case III looking at a textured sphere, a
//! box and a board in front of a textured wall (what `hvs track` renders every frame), with the
//! default blur and noise.

use criterion::{criterion_group, criterion_main, Criterion};
use hvs_shared::runtime::gaze::Joints;
use hvs_shared::sim::posture::HeadRig;
use hvs_shared::sim::presets;
use hvs_vision::render::RenderOptions;
use hvs_vision::scene::{render_scene, SceneFile};
use std::hint::black_box;

const SCENE: &str = r#"{ "rig": {"case": 3}, "camera_fps": 30,
  "background": {"z_cm": 300, "texture_seed": 1},
  "objects": [
    {"shape": "sphere", "radius_cm": 5, "centre_cm": [4, -2, 90], "texture_seed": 2},
    {"shape": "box", "size_cm": [8, 6, 4], "centre_cm": [-12, 4, 130], "texture_seed": 3},
    {"shape": "board", "board": {"pattern": "chessboard", "inner_corners": [9, 6], "square_cm": 6},
     "centre_cm": [15, 10, 160]}
  ] }"#;

fn bench(c: &mut Criterion) {
    let scene = SceneFile::parse(SCENE).unwrap().scene().unwrap().at(0.0);
    let head = HeadRig::new(presets::CASE_3);
    let opt = RenderOptions::default();
    let joints = Joints([3.0, -2.0, 1.0, 1.0, -1.0]);
    let mut g = c.benchmark_group("scene");
    g.sample_size(10);
    g.bench_function("pair_640x480_three_objects", |b| {
        b.iter(|| render_scene(&head, black_box(&joints), &scene, &opt, 1).unwrap())
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
