//! Matching speed: 1000 points of a rendered 640x480 pair (case III, board at 105 cm),
//! each with its narrow disparity interval (true disparity +- 10 %), on one core.
//! Goal: <= 50 ms per 1000 points. Also each point's interval from an exact model
//! ([`model_disparity_interval`] over optimal triangulation: the training depths 65-165 cm,
//! about 30 px wide), a wide interval (10..60 px) for comparison, and the interval itself.

use criterion::{criterion_group, criterion_main, Criterion};
use hvs_shared::sim::presets;
use hvs_shared::sim::triangulate;
use hvs_vision::geometry::pinhole_fundamental;
use hvs_vision::matching::{model_disparity_interval, MatchParams, Matcher, Query};
use hvs_vision::render::{opencv_board, render_rig, RenderOptions};
use std::hint::black_box;

fn bench(c: &mut Criterion) {
    let rig = presets::CASE_3;
    let board = opencv_board();
    let z = 105.0;
    let r = render_rig(&rig, &board, [0.0, 0.0, z], &RenderOptions::default(), 1).unwrap();
    let f = pinhole_fundamental(&rig.left(), &rig.right());
    let m = Matcher::new(&r.left, &r.right, &f, MatchParams::default()).unwrap();
    // 1000 points on a grid over the board (40 x 25), truth from the board plane.
    let mut narrow = Vec::new();
    let mut wide = Vec::new();
    for a in 0..40 {
        for b in 0..25 {
            let p = [-28.0 + 56.0 * f64::from(a) / 39.0, -19.0 + 38.0 * f64::from(b) / 24.0, z];
            let px = rig.project(&p).unwrap();
            let d = px[0] - px[2];
            let h = (0.1 * d.abs()).max(1.0);
            narrow.push(Query { ul: px[0], vl: px[1], d_min: d - h, d_max: d + h });
            wide.push(Query { ul: px[0], vl: px[1], d_min: 10.0, d_max: 60.0 });
        }
    }
    let model = |x: [f32; 4]| {
        triangulate::optimal_rig(&rig, &x.map(f64::from)).ok().map(|p| p.map(|c| c as f32))
    };
    let interval = |q: &Query| {
        let line = f.line_in_right([q.ul, q.vl]);
        model_disparity_interval(model, q.ul, q.vl, line, [65.0, 165.0], [-5.0, 40.0])
    };
    let modelled: Vec<Query> = narrow
        .iter()
        .filter_map(|q| interval(q).map(|(d_min, d_max)| Query { d_min, d_max, ..*q }))
        .collect();
    assert_eq!(modelled.len(), narrow.len());
    let mut g = c.benchmark_group("matching");
    g.sample_size(20);
    g.bench_function("1000_points_narrow", |b| b.iter(|| m.find_all(black_box(&narrow))));
    g.bench_function("1000_points_model_interval", |b| b.iter(|| m.find_all(black_box(&modelled))));
    g.bench_function("1000_model_intervals_exact_triangulation", |b| {
        b.iter(|| narrow.iter().map(&interval).collect::<Vec<_>>())
    });
    g.bench_function("1000_points_10_60px", |b| b.iter(|| m.find_all(black_box(&wide))));
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
