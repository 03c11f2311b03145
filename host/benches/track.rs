//! The closed loop's perception against its rendering, per 640x480 frame of the README's
//! scene (`hvs track`'s `static.json`: case III, a 5 cm sphere at (20, -8, 100) cm before a
//! wall at 300 cm, the head at home):
//! - `track/find_nearest`: a scan frame of the target finder in `nearest` mode (the whole
//!   front region's grid, then the target's region matched densely);
//! - `track/find_nearest_steady`: `nearest` frame after frame (a scan every 6th frame, the
//!   target followed in between);
//! - `track/find_followed`: a `U,V` target after its first frame (only the region around the
//!   last centroid is matched);
//! - `track/render_pair`: the virtual cameras' pair (4x4 supersampling), reported on its own.
//!
//! `RAYON_NUM_THREADS=1 cargo bench -p hvs-host --bench track` (one core, as the loop's rate
//! goal is stated; without the variable, both cores).

use criterion::{criterion_group, criterion_main, Criterion};
use hvs_host::data::dataset::Dataset;
use hvs_host::sim::sets::{simulate, SetKind, SimOptions};
use hvs_host::track::frames::{loop_render_options, FrameSource, VirtualCameras};
use hvs_host::track::target::{Finder, TargetMode};
use hvs_host::track::{estimator_of, scene_file};
use hvs_shared::runtime::blob::InputKind;
use hvs_shared::runtime::gaze::Joints;
use hvs_shared::sim::{posture::HeadRig, presets};
use std::hint::black_box;

const SCENE: &str = r#"{ "rig": {"case": 3}, "camera_fps": 30,
  "background": {"z_cm": 300, "texture_seed": 1},
  "objects": [ {"shape": "sphere", "radius_cm": 5, "centre_cm": [20, -8, 100],
                "velocity_cm_s": [0, 0, 0], "texture_seed": 2} ] }"#;

fn bench(c: &mut Criterion) {
    let loaded = scene_file::parse(SCENE).unwrap();
    let mut cams =
        VirtualCameras::new(HeadRig::new(loaded.rig), loaded.scene, loop_render_options(), 2);
    let joints = Joints::HOME;
    let frame = cams.grab(0.0, &joints).unwrap();
    // A stereo model of case III (the head stays at home here).
    let mut d = Dataset::new(InputKind::Stereo);
    for s in simulate(&presets::CASE_3, SetKind::Train, &SimOptions::default()).unwrap() {
        d.push(&s.px, Some(s.xyz));
    }
    let est = estimator_of(hvs_host::train::train(&d, &Default::default()).unwrap().blob).unwrap();
    let found = Finder::new(TargetMode::Nearest)
        .find(&frame.left, &frame.right, &joints, &est)
        .expect("the sphere is found");

    let mut g = c.benchmark_group("track");
    g.sample_size(20);
    g.bench_function("find_nearest", |b| {
        b.iter(|| {
            Finder::new(TargetMode::Nearest).find(
                black_box(&frame.left),
                &frame.right,
                &joints,
                &est,
            )
        })
    });
    // `nearest` frame after frame: a scan every 6th frame, the target followed in between.
    let mut steady = Finder::new(TargetMode::Nearest);
    g.bench_function("find_nearest_steady", |b| {
        b.iter(|| steady.find(black_box(&frame.left), &frame.right, &joints, &est))
    });
    let mut followed = Finder::new(TargetMode::Pixel([found.px[0], found.px[1]]));
    followed.find(&frame.left, &frame.right, &joints, &est).expect("the pixel's object is found");
    g.bench_function("find_followed", |b| {
        b.iter(|| followed.find(black_box(&frame.left), &frame.right, &joints, &est))
    });
    g.bench_function("render_pair", |b| b.iter(|| cams.grab(0.0, black_box(&joints))));
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
