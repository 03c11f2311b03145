//! Criterion benchmark of the training `hvs train` runs (4-5-3, 10 restarts,
//! Levenberg-Marquardt): the default family (`hvs_host::train::DEFAULT_FAMILY`, the one definition)
//! side by side with the thesis family, on the thesis' case-IV board set (72 points) and on
//! the 9x6 board at 6 cm (324 points, `hvs simulate --board 9x6:6`); and the thesis'
//! back-propagation on the 72 points; and a 9-16-3 posture-aware net on the 23,328 rows of
//! `hvs simulate --case 3 --set train --postures grid --seed 1`, trained as `hvs train --hidden
//! 16 --restarts 1` trains it (goal: at most 3 s). `cargo bench -p hvs-host --bench train`.
//! Goals for the whole `hvs train` command: under 0.1 s wall on 72 points and
//! under 1 s on 324 on the project's 2-core machine.

mod common;

use common::{board_set, grid_board_set};
use criterion::{criterion_group, criterion_main, Criterion};
use hvs_host::sim::board::TrainingBoard;
use hvs_host::train::{train, Algo, TrainConfig};
use hvs_shared::runtime::blob::Family;
use std::hint::black_box;
use std::time::Duration;

fn bench(c: &mut Criterion) {
    let sets = [
        ("board72", board_set()),
        ("board324_9x6", grid_board_set(TrainingBoard::Grid { nx: 9, ny: 6, pitch: 6.0 })),
    ];
    let families = [("default", hvs_host::train::DEFAULT_FAMILY), ("thesis", Family::THESIS)];
    let mut g = c.benchmark_group("train");
    g.measurement_time(Duration::from_secs(10));
    for (set, data) in &sets {
        for (name, family) in families {
            let cfg = TrainConfig { family, ..TrainConfig::default() };
            g.bench_function(format!("{name}_lm_case4_{set}"), |b| {
                b.iter(|| train(black_box(data), &cfg).unwrap())
            });
        }
    }
    g.sample_size(10);
    g.measurement_time(Duration::from_secs(30));
    g.bench_function("bp_case4_board72_10restarts", |b| {
        let cfg = TrainConfig { algo: Algo::Bp, ..TrainConfig::default() };
        b.iter(|| train(black_box(&sets[0].1), &cfg).unwrap())
    });
    g.bench_function("posture_9_16_3_grid23328_1restart", |b| {
        let data = common::posture_grid_set();
        let kind = data.input_kind().expect("joint columns");
        let cfg = TrainConfig {
            hidden: 16,
            restarts: 1,
            family: hvs_host::train::DEFAULT_FAMILY,
            frame: hvs_host::train::default_frame(hvs_host::train::DEFAULT_FAMILY, kind),
            ..TrainConfig::default()
        };
        b.iter(|| train(black_box(&data), &cfg).unwrap())
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
