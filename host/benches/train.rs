//! Criterion benchmark of the default training (4-5-3, 10 restarts, Levenberg-Marquardt) on
//! the thesis' case-IV board set (72 points): `cargo bench -p hvs-host --bench train`.
//! The goal is under 0.1 s wall on the project's 2-core machine.

mod common;

use common::board_set;
use criterion::{criterion_group, criterion_main, Criterion};
use hvs_host::train::{train, Algo, TrainConfig};
use std::hint::black_box;
use std::time::Duration;

fn bench(c: &mut Criterion) {
    let data = board_set();
    let mut g = c.benchmark_group("train");
    g.measurement_time(Duration::from_secs(10));
    g.bench_function("default_lm_case4_board72", |b| {
        b.iter(|| train(black_box(&data), &TrainConfig::default()).unwrap())
    });
    g.sample_size(10);
    g.measurement_time(Duration::from_secs(30));
    g.bench_function("bp_case4_board72_10restarts", |b| {
        let cfg = TrainConfig {
            algo: Algo::Bp,
            ..TrainConfig::default()
        };
        b.iter(|| train(black_box(&data), &cfg).unwrap())
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
