//! Inference speed on the host (`cargo bench -p hvs-shared --bench inference`):
//!
//! - `one_point/mlp_4_5_3`: the head's 4-5-3 network, `Mlp<4,5,3>::infer`, one point;
//! - `one_point/fixed_mlp_4_5_3`: `FixedMlp<4,5,3>::infer_into`, the head's fast path;
//! - `one_point/infer_flat_4_5_3`: the runtime-sized `infer_flat` a blob of any topology runs;
//! - `one_point/sigmoid_x5`: five sigmoids (`mlp::sigmoid`, its polynomial exp), a hidden
//!   layer's worth; `one_point/sigmoid_libm_x5`: the same over `libm::expf`, the exp before;
//! - `one_point/fallback_traditional_xyz`: the traditional method the head falls back to;
//! - `batch_1e6/mlp_4_5_3_one_core`: 10^6 points through `Mlp<4,5,3>::infer` on one core
//!   (target: at least 10 M points/s per core);
//! - `batch_1e6_cpu_time/mlp_4_5_3_one_core`: the same, timed in the benchmark thread's CPU
//!   time (`CLOCK_THREAD_CPUTIME_ID`) instead of wall time, so that other processes sharing
//!   the cores do not count: the per-core figure on a busy machine.
//!
//! Weights and points are seeded: every run measures the same work.

use cpu_time::ThreadTime;
use criterion::measurement::{Measurement, ValueFormatter};
use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use hvs_shared::runtime::head::{NET_HIDDEN, NET_INPUTS, NET_OUTPUTS};
use hvs_shared::runtime::mlp::{
    infer_flat, param_count, sigmoid, Activation, FixedMlp, FlatMlp, Mlp,
};
use hvs_shared::runtime::traditional::{traditional_xyz, Calibration};
use std::hint::black_box;
use std::time::Duration;

/// Batch size of the throughput benchmark.
const BATCH: usize = 1_000_000;

/// Seeded uniform numbers in [-1, 1) (64-bit LCG, top 24 bits).
struct Lcg(u64);

impl Lcg {
    fn next(&mut self) -> f32 {
        self.0 = self.0.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        ((self.0 >> 40) as f32 / (1u64 << 24) as f32) * 2.0 - 1.0
    }
}

const IN_OFFSET: [f32; 4] = [343.0, 240.0, 297.0, 240.0];
const IN_SCALE: [f32; 4] = [1.0 / 30.0, 1.0 / 12.0, 1.0 / 30.0, 1.0 / 12.0];
const OUT_OFFSET: [f32; 3] = [0.0, 0.0, 115.0];
const OUT_SCALE: [f32; 3] = [3.0, 2.0, 50.0];

fn params(seed: u64) -> Vec<f32> {
    let mut r = Lcg(seed);
    (0..param_count(NET_INPUTS, NET_HIDDEN, NET_OUTPUTS)).map(|_| 2.0 * r.next()).collect()
}

fn model(p: &[f32]) -> Mlp<4, 5, 3> {
    Mlp::from_params(p, Activation::Linear, IN_OFFSET, IN_SCALE, OUT_OFFSET, OUT_SCALE)
        .expect("4-5-3 parameter count")
}

/// Points spread over the training box of case I (about ±30 px around the offsets).
fn points(n: usize, seed: u64) -> Vec<[f32; 4]> {
    let mut r = Lcg(seed);
    (0..n)
        .map(|_| {
            let du = 18.0 * r.next();
            let dv = 12.0 * r.next();
            let disp = 46.0 + 10.0 * r.next();
            [343.0 + du, 240.0 + dv, 343.0 + du - disp, 240.0 + dv]
        })
        .collect()
}

fn inference(c: &mut Criterion) {
    let p = params(42);
    let m = model(&p);
    let x = points(1, 7)[0];

    let mut g = c.benchmark_group("one_point");
    g.throughput(Throughput::Elements(1));
    g.bench_function("mlp_4_5_3", |b| b.iter(|| m.infer(black_box(&x))));
    let flat = FlatMlp {
        hidden: 5,
        params: &p,
        skip: &[],
        output: Activation::Linear,
        in_offset: &IN_OFFSET,
        in_scale: &IN_SCALE,
        out_offset: &OUT_OFFSET,
        out_scale: &OUT_SCALE,
    };
    g.bench_function("infer_flat_4_5_3", |b| {
        let mut y = [0.0f32; 3];
        b.iter(|| infer_flat(&flat, black_box(&x), &mut y).map(|_| y))
    });
    let fixed = FixedMlp::<4, 5, 3>::from_flat(&flat).expect("a 4-5-3 net");
    g.bench_function("fixed_mlp_4_5_3", |b| {
        let mut y = [0.0f32; 3];
        b.iter(|| fixed.infer_into(black_box(&x), &mut y).map(|_| y))
    });
    let a: [f32; 5] = core::array::from_fn(|j| 1.7 * j as f32 - 3.1);
    g.bench_function("sigmoid_x5", |b| b.iter(|| black_box(&a).map(sigmoid)));
    g.bench_function("sigmoid_libm_x5", |b| {
        b.iter(|| black_box(&a).map(|v| 1.0 / (1.0 + libm::expf(-v))))
    });
    g.bench_function("fallback_traditional_xyz", |b| {
        b.iter(|| traditional_xyz(&Calibration::BUILT_IN, black_box(&x)))
    });
    g.finish();

    batch(c, "batch_1e6");
}

/// 10^6 points through `Mlp<4,5,3>::infer`, in group `group`.
fn batch<M: Measurement>(c: &mut Criterion<M>, group: &str) {
    let m = model(&params(42));
    let xs = points(BATCH, 11);
    let mut ys = vec![[0.0f32; 3]; BATCH];
    let mut g = c.benchmark_group(group);
    g.sample_size(20);
    g.throughput(Throughput::Elements(BATCH as u64));
    g.bench_function("mlp_4_5_3_one_core", |b| {
        b.iter(|| {
            for (x, y) in black_box(&xs).iter().zip(ys.iter_mut()) {
                if let Ok(v) = m.infer(x) {
                    *y = v;
                }
            }
            black_box(&ys);
        })
    });
    g.finish();
}

fn batch_cpu_time(c: &mut Criterion<ThreadCpuTime>) {
    batch(c, "batch_1e6_cpu_time");
}

/// CPU time of the benchmark thread: time the thread was descheduled (other processes on a
/// shared machine) does not count.
struct ThreadCpuTime;

impl Measurement for ThreadCpuTime {
    type Intermediate = ThreadTime;
    type Value = Duration;
    fn start(&self) -> ThreadTime {
        ThreadTime::now()
    }
    fn end(&self, i: ThreadTime) -> Duration {
        i.elapsed()
    }
    fn add(&self, v1: &Duration, v2: &Duration) -> Duration {
        *v1 + *v2
    }
    fn zero(&self) -> Duration {
        Duration::ZERO
    }
    fn to_f64(&self, v: &Duration) -> f64 {
        v.as_nanos() as f64
    }
    fn formatter(&self) -> &dyn ValueFormatter {
        &CpuFormatter
    }
}

/// Nanoseconds of CPU time, shown in ms; throughput in million elements per CPU second.
struct CpuFormatter;

impl ValueFormatter for CpuFormatter {
    fn scale_values(&self, _typical_ns: f64, values: &mut [f64]) -> &'static str {
        for v in values {
            *v /= 1e6;
        }
        "ms (CPU)"
    }
    fn scale_throughputs(&self, _typical: f64, t: &Throughput, values: &mut [f64]) -> &'static str {
        let n = match *t {
            Throughput::Elements(n) | Throughput::Bytes(n) | Throughput::BytesDecimal(n) => n,
            Throughput::Bits(n) => n,
        } as f64;
        for v in values {
            *v = n / *v * 1e9 / 1e6;
        }
        "M/s (CPU)"
    }
    fn scale_for_machines(&self, _values: &mut [f64]) -> &'static str {
        "ns"
    }
}

criterion_group!(benches, inference);
criterion_group! {
    name = cpu_benches;
    config = Criterion::default().with_measurement(ThreadCpuTime);
    targets = batch_cpu_time
}
criterion_main!(benches, cpu_benches);
