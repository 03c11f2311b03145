//! Matching speed: 1000 points of a rendered 640x480 pair (case III, board at 105 cm),
//! each with its narrow disparity interval (true disparity +- 10 %), on one core.
//! Goal: <= 50 ms per 1000 points. Also a wide interval (10..60 px) for comparison.

use criterion::{criterion_group, criterion_main, Criterion};
use hvs_shared::sim::presets;
use hvs_vision::matching::{pinhole_fundamental, MatchParams, Matcher, Query};
use hvs_vision::render::{render_rig, Board, RenderOptions};
use std::hint::black_box;

fn bench(c: &mut Criterion) {
    let rig = presets::CASE_3;
    let board = Board::default();
    let z = 105.0;
    let r = render_rig(&rig, &board, [0.0, 0.0, z], &RenderOptions::default(), 1).unwrap();
    let f = pinhole_fundamental(&rig.left(), &rig.right());
    let m = Matcher::new(&r.left, &r.right, &f, MatchParams::default()).unwrap();
    // 1000 points on a grid over the board (40 x 25), truth from the board plane.
    let mut narrow = Vec::new();
    let mut wide = Vec::new();
    for a in 0..40 {
        for b in 0..25 {
            let p = [
                -28.0 + 56.0 * f64::from(a) / 39.0,
                -19.0 + 38.0 * f64::from(b) / 24.0,
                z,
            ];
            let px = rig.project(&p).unwrap();
            let d = px[0] - px[2];
            let h = (0.1 * d.abs()).max(1.0);
            narrow.push(Query {
                ul: px[0],
                vl: px[1],
                d_min: d - h,
                d_max: d + h,
            });
            wide.push(Query {
                ul: px[0],
                vl: px[1],
                d_min: 10.0,
                d_max: 60.0,
            });
        }
    }
    let mut g = c.benchmark_group("matching");
    g.sample_size(20);
    g.bench_function("1000_points_narrow", |b| {
        b.iter(|| m.find_all(black_box(&narrow)))
    });
    g.bench_function("1000_points_10_60px", |b| {
        b.iter(|| m.find_all(black_box(&wide)))
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
