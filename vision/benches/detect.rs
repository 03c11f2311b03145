//! Board detection speed: one 640x480 image of OpenCV's real stereo set (9 x 6 corners),
//! grey decode excluded, and the fundamental-matrix fit over the whole set.

use criterion::{criterion_group, criterion_main, Criterion};
use hvs_vision::board::Board;
use hvs_vision::detect;
use std::hint::black_box;
use std::path::PathBuf;

fn fixture(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures/opencv-stereo")
        .join(name)
}

fn bench(c: &mut Criterion) {
    let board = Board::from_path(&fixture("board.json")).expect("board.json");
    let left = image::open(fixture("left01.jpg"))
        .expect("left01.jpg")
        .to_luma8();
    let right = image::open(fixture("right01.jpg"))
        .expect("right01.jpg")
        .to_luma8();
    assert_eq!(left.dimensions(), (640, 480));
    c.bench_function("detect one 640x480 image (left01)", |b| {
        b.iter(|| detect::detect(black_box(&left), &board).expect("left01 detects"))
    });
    c.bench_function("detect_pair 640x480 (pair 01)", |b| {
        b.iter(|| detect::detect_pair(black_box(&left), black_box(&right), &board).expect("pair"))
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
