//! Criterion benchmark of the thesis' hidden-neuron sweep: 4-H-3 nets for H = 1..=10, ten
//! restarts (nets) each, Levenberg-Marquardt with the default settings, on the case-IV board
//! set (72 points), restarts in parallel on all cores as `hvs train` runs them; and the
//! experiments' own sweep (`hvs_host::study::thesis::hidden_sweep`, Figs. 4.13-4.15: one and three
//! outputs, H = 1..=10, ten single-start nets each, 200 nets, evaluated on the test points):
//! `cargo bench -p hvs-host --bench sweep`.

mod common;

use common::board_set;
use criterion::{criterion_group, criterion_main, Criterion, SamplingMode};
use hvs_host::study::engine::Quiet;
use hvs_host::study::thesis as experiment;
use hvs_host::train::{train, TrainConfig};
use std::hint::black_box;
use std::time::Duration;

fn bench(c: &mut Criterion) {
    let data = board_set();
    let mut g = c.benchmark_group("sweep");
    // One sweep takes a fraction of a second to seconds: ten samples of one sweep each.
    g.sampling_mode(SamplingMode::Flat);
    g.sample_size(10);
    g.measurement_time(Duration::from_secs(10));
    g.bench_function("hidden_1_to_10_x10_nets_case4_board72", |b| {
        b.iter(|| {
            for hidden in 1..=10 {
                let cfg = TrainConfig { hidden, restarts: 10, ..TrainConfig::default() };
                black_box(train(black_box(&data), &cfg).unwrap());
            }
        })
    });
    g.bench_function("experiment_hidden_sweep_z_and_xyz_200_nets", |b| {
        let cfg = experiment::Config { seed: 0, quick: false };
        b.iter(|| black_box(experiment::hidden_sweep(&cfg, &Quiet).unwrap()))
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
