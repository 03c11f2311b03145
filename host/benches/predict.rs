//! Throughput of `hvs predict`'s inference (CSV parsing excluded): a batch of 1e6 points
//! through a 4-5-3 net trained on case IV, on one core (the per-core figure the goal is
//! stated in: at least 10 M points/s) and on all cores, plus the runtime-sized path for
//! comparison; then the default family's net (with its skip term) through the lanes and
//! through `ModelBlob::infer` (which `hvs predict` and `hvs depth` ran it through before).
//!
//! `cargo bench -p hvs-host --bench predict`

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use hvs_host::data::dataset::Dataset;
use hvs_host::infer::Predictor;
use hvs_host::sim::sets::{simulate, SetKind, SimOptions};
use hvs_host::train::{TrainConfig, DEFAULT_FAMILY};
use hvs_shared::runtime::blob::{Family, InputKind, ModelBlob};
use hvs_shared::sim::presets;
use std::hint::black_box;

const N: usize = 1_000_000;

fn model(family: Family) -> ModelBlob {
    let mut d = Dataset::new(InputKind::Stereo);
    for s in simulate(&presets::CASE_4, SetKind::Train, &SimOptions::default()).unwrap() {
        d.push(&s.px, Some(s.xyz));
    }
    let cfg = TrainConfig { family, ..Default::default() };
    hvs_host::train::train(&d, &cfg).unwrap().blob
}

fn points() -> Vec<f32> {
    let opt = SimOptions { points: N, noise_px: 0.0, seed: 1, ..SimOptions::default() };
    simulate(&presets::CASE_4, SetKind::Volume, &opt)
        .unwrap()
        .iter()
        .flat_map(|s| s.px.map(|v| v as f32))
        .collect()
}

fn bench(c: &mut Criterion) {
    let blob = model(Family::THESIS);
    let x = points();
    let mut y = vec![0.0f32; N * 3];
    let p = Predictor::new(&blob);
    assert!(p.is_fixed());
    let mut g = c.benchmark_group("predict 4-5-3");
    g.throughput(Throughput::Elements(N as u64));
    g.sample_size(20);
    g.bench_function("1e6 points, one core (Mlp<4,5,3>)", |b| {
        b.iter(|| p.run_serial(black_box(&x), &mut y).unwrap())
    });
    g.bench_function("1e6 points, all cores (rayon)", |b| {
        b.iter(|| p.run(black_box(&x), &mut y).unwrap())
    });
    g.bench_function("1e6 points, one core (runtime-sized infer_flat)", |b| {
        b.iter(|| {
            for (xi, yi) in x.chunks_exact(4).zip(y.chunks_exact_mut(3)) {
                blob.infer(black_box(xi), yi).unwrap();
            }
        })
    });
    g.finish();

    // The default family (inverse depth with a linear skip term, what `hvs train` writes
    // without `--arch`): the same lanes with the skip term, then the output map per point.
    let blob = model(DEFAULT_FAMILY);
    let p = Predictor::new(&blob);
    assert!(p.is_fixed());
    let mut g = c.benchmark_group("predict 4-5-3 inverse-depth-skip");
    g.throughput(Throughput::Elements(N as u64));
    g.sample_size(20);
    g.bench_function("1e6 points, one core (lanes)", |b| {
        b.iter(|| p.run_serial(black_box(&x), &mut y).unwrap())
    });
    g.bench_function("1e6 points, one core (runtime-sized ModelBlob::infer)", |b| {
        b.iter(|| {
            for (xi, yi) in x.chunks_exact(4).zip(y.chunks_exact_mut(3)) {
                blob.infer(black_box(xi), yi).unwrap();
            }
        })
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
