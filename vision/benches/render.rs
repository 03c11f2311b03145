//! Rendering speed: one 640x480 stereo pair of the default board (9x6 inner corners, 6 cm
//! squares) through case III, with the default blur and noise. Goal: <= 0.5 s per pair.

use criterion::{criterion_group, criterion_main, Criterion};
use hvs_shared::sim::presets;
use hvs_vision::render::{opencv_board, render_rig, RenderOptions};
use std::hint::black_box;

fn bench(c: &mut Criterion) {
    let rig = presets::CASE_3;
    let board = opencv_board();
    let opt = RenderOptions::default();
    let mut g = c.benchmark_group("render");
    g.sample_size(10);
    for z in [65.0, 165.0] {
        g.bench_function(format!("pair_640x480_z{z}"), |b| {
            b.iter(|| render_rig(&rig, &board, black_box([0.0, 0.0, z]), &opt, 1).unwrap())
        });
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
