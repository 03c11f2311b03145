//! Accuracy and speed of `hvs_host::train` on the thesis' four cases.
//!
//! `cargo run --release -p hvs-host --example train_accuracy` prints, per case:
//! - the thesis protocol: train on the 72 board points (6 depths x 12 points, rounded
//!   pixels), test on the 22 test points (P1, P2 at 11 depths): training e_ma and worst
//!   per-depth test e_ma (%), next to the worst per-depth e_ma of the optimal triangulation
//!   with the true rig on the same pixels (what rounding alone costs on these 22 points);
//! - the volume check: train on `--volume-train` uniform random points of the board
//!   protocol's volume (X in [-3, 3], Y in [-2, 2], Z in [65, 165] cm; seed 1000 + case),
//!   test on `--volume-test` other ones (seed 2000 + case): mean e_ma (%) of the net next to
//!   the floor, the optimal triangulation with the true rig on the same rounded pixels, and
//!   their ratio;
//! - the board-trained net of the protocol on the same volume test points, and its ratio to
//!   the floor (how far 72 board points generalise over the volume);
//! - the wall time of the default training (4-5-3, 10 restarts, LM) on the 72 case-IV board
//!   points (median of `--repeats` runs).
//!
//! `--per-depth` adds the per-depth errors; `--sweep N` instead trains one restart for each
//! of the seeds 0..N and prints the spread of the protocol result. Other options change the
//! training configuration (`--help`).

use clap::Parser;
use hvs_host::data::dataset::Dataset;
use hvs_host::train::{train, Algo, TrainConfig};
use hvs_shared::runtime::blob::{InputKind, ModelBlob, OutputKind};
use hvs_shared::sim::camera::Rig;
use hvs_shared::sim::metrics::EmaAcc;
use hvs_shared::sim::{presets, triangulate};
use hvs_shared::test_support::splitmix64;
use std::time::Instant;

use hvs_host::cli::train::AlgoArg;

#[derive(Parser)]
struct Args {
    /// Hidden units.
    #[arg(long, default_value_t = 5)]
    hidden: usize,
    /// Train the Z-only net instead of X, Y, Z.
    #[arg(long)]
    z_only: bool,
    /// Algorithm.
    #[arg(long, value_enum, default_value_t = AlgoArg::Lm)]
    algo: AlgoArg,
    /// Restarts.
    #[arg(long, default_value_t = 10)]
    restarts: usize,
    /// Training seed.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Random volume points to train on.
    #[arg(long, default_value_t = 1000)]
    volume_train: usize,
    /// Random volume points to test on.
    #[arg(long, default_value_t = 500)]
    volume_test: usize,
    /// Timed repetitions of the default training.
    #[arg(long, default_value_t = 21)]
    repeats: usize,
    /// Only these cases (1-4); all by default.
    #[arg(long)]
    case: Vec<u8>,
    /// Print the per-depth test errors (net / optimal triangulation).
    #[arg(long)]
    per_depth: bool,
    /// Train single restarts with seeds 0..N on the protocol and print the spread.
    #[arg(long)]
    sweep: Option<u64>,
}

/// Board protocol volume (cm).
const VOLUME: [[f64; 2]; 3] = [[-3.0, 3.0], [-2.0, 2.0], [65.0, 165.0]];

/// SplitMix64, uniform in [0, 1).
struct SplitMix(u64);
impl SplitMix {
    fn next(&mut self) -> f64 {
        (splitmix64(&mut self.0) >> 11) as f64 / (1u64 << 53) as f64
    }
}

fn set(rig: &Rig, points: &[[f64; 3]]) -> Dataset {
    let mut d = Dataset::new(InputKind::Stereo);
    for p in points {
        let px = rig.project_rounded(p).expect("point in front of the rig");
        d.push(&px, Some(*p));
    }
    d
}

fn board_train(rig: &Rig) -> Dataset {
    let pts: Vec<[f64; 3]> =
        presets::TRAIN_DEPTHS.iter().flat_map(|z| presets::board_points(*z)).collect();
    set(rig, &pts)
}

fn board_test(rig: &Rig) -> Dataset {
    let mut pts = Vec::new();
    for z in presets::TEST_DEPTHS {
        for [x, y] in presets::TEST_POINTS_XY {
            pts.push([x, y, z]);
        }
    }
    set(rig, &pts)
}

fn volume(rig: &Rig, n: usize, seed: u64) -> Dataset {
    let mut g = SplitMix(seed);
    let pts: Vec<[f64; 3]> = (0..n)
        .map(|_| {
            let mut p = [0.0; 3];
            for (c, [lo, hi]) in p.iter_mut().zip(VOLUME) {
                *c = lo + (hi - lo) * g.next();
            }
            p
        })
        .collect();
    set(rig, &pts)
}

fn z_hat(blob: &ModelBlob, x: &[f64]) -> f64 {
    let xf: Vec<f32> = x.iter().map(|v| *v as f32).collect();
    let mut out = vec![0.0f32; blob.n_outputs()];
    match blob.infer(&xf, &mut out) {
        Ok(()) => out[blob.n_outputs() - 1] as f64,
        Err(_) => f64::INFINITY,
    }
}

fn optimal_z(rig: &Rig, x: &[f64]) -> f64 {
    let px: [f64; 4] = x.try_into().expect("four pixel inputs");
    triangulate::optimal_rig(rig, &px).map_or(f64::INFINITY, |p| p[2])
}

/// Per test depth: e_ma (%) of `estimate` over the test points at that depth.
fn per_depth(test: &Dataset, estimate: impl Fn(&[f64]) -> f64) -> Vec<(f64, f64)> {
    presets::TEST_DEPTHS
        .iter()
        .map(|&z| {
            let mut acc = EmaAcc::default();
            for r in 0..test.len() {
                if test.targets[r][2] == z {
                    acc.add(z, estimate(test.row(r)));
                }
            }
            (z, acc.e_ma_pct())
        })
        .collect()
}

fn worst(v: &[(f64, f64)]) -> f64 {
    v.iter().map(|(_, e)| *e).fold(0.0, f64::max)
}

fn main() -> anyhow::Result<()> {
    let args = Args::parse();
    let cfg = TrainConfig {
        hidden: args.hidden,
        outputs: if args.z_only { OutputKind::Z } else { OutputKind::Xyz },
        algo: match args.algo {
            AlgoArg::Lm => Algo::Lm,
            AlgoArg::Bp => Algo::Bp,
            AlgoArg::Adam => Algo::Adam,
        },
        restarts: args.restarts,
        seed: args.seed,
        ..TrainConfig::default()
    };
    let cases: Vec<u8> = if args.case.is_empty() { vec![1, 2, 3, 4] } else { args.case.clone() };
    if let Some(n) = args.sweep {
        println!(
            "protocol, one restart per seed 0..{n}: train e_ma % / worst per-depth test e_ma %"
        );
        for c in cases {
            let rig = presets::case(c).ok_or_else(|| anyhow::anyhow!("no case {c}"))?;
            let (tr, te) = (board_train(&rig), board_test(&rig));
            let mut line = Vec::new();
            let (mut fails, mut sum) = (0, 0.0);
            for seed in 0..n {
                let one = TrainConfig { restarts: 1, seed, ..cfg.clone() };
                let out = train(&tr, &one)?;
                let w = worst(&per_depth(&te, |x| z_hat(&out.blob, x)));
                fails += usize::from(w >= 4.0);
                sum += w;
                line.push(format!("{:.2}/{:.2}", out.train_error_pct, w));
            }
            println!(
                "case {c}: {fails}/{n} at or above 4 %, mean worst {:.2} %: {}",
                sum / n as f64,
                line.join(" ")
            );
        }
        return Ok(());
    }
    println!(
        "config: {}-{}-{} {:?}, {} restarts, seed {}; volume: train {} / test {} points",
        4,
        cfg.hidden,
        cfg.outputs.len(),
        cfg.algo,
        cfg.restarts,
        cfg.seed,
        args.volume_train,
        args.volume_test
    );
    println!(
        "case | protocol: train e_ma % | worst depth: net % | optimal tri. % | volume: net e_ma % | floor % | ratio | train s | board net on vol. % | ratio"
    );
    for n in cases {
        let rig = presets::case(n).ok_or_else(|| anyhow::anyhow!("no case {n}"))?;
        // (a) thesis protocol.
        let (tr, te) = (board_train(&rig), board_test(&rig));
        let out = train(&tr, &cfg)?;
        let net = per_depth(&te, |x| z_hat(&out.blob, x));
        let tri = per_depth(&te, |x| optimal_z(&rig, x));
        // (b) volume.
        let vtr = volume(&rig, args.volume_train, 1000 + n as u64);
        let vte = volume(&rig, args.volume_test, 2000 + n as u64);
        let t0 = Instant::now();
        let vout = train(&vtr, &cfg)?;
        let vtime = t0.elapsed().as_secs_f64();
        let (mut vnet, mut floor, mut bnet) =
            (EmaAcc::default(), EmaAcc::default(), EmaAcc::default());
        for r in 0..vte.len() {
            let z = vte.targets[r][2];
            vnet.add(z, z_hat(&vout.blob, vte.row(r)));
            bnet.add(z, z_hat(&out.blob, vte.row(r)));
            floor.add(z, optimal_z(&rig, vte.row(r)));
        }
        println!(
            "{n:>4} | {:>22.4} | {:>18.4} | {:>14.4} | {:>18.4} | {:>7.4} | {:>5.3} | {:>7.3} | {:>16.4} | {:>5.3}",
            out.train_error_pct,
            worst(&net),
            worst(&tri),
            vnet.e_ma_pct(),
            floor.e_ma_pct(),
            vnet.e_ma_pct() / floor.e_ma_pct(),
            vtime,
            bnet.e_ma_pct(),
            bnet.e_ma_pct() / floor.e_ma_pct()
        );
        if args.per_depth {
            let cells: Vec<String> =
                net.iter().zip(&tri).map(|((z, e), (_, f))| format!("{z}:{e:.2}/{f:.2}")).collect();
            println!("       per depth, net/optimal %: {}", cells.join(" "));
        }
    }
    // (c) speed of the default training on the case IV board set.
    let tr = board_train(&presets::CASE_4);
    let mut times = Vec::new();
    for _ in 0..args.repeats.max(1) {
        let t0 = Instant::now();
        let out = train(&tr, &TrainConfig::default())?;
        times.push(t0.elapsed().as_secs_f64());
        std::hint::black_box(out);
    }
    times.sort_by(f64::total_cmp);
    println!(
        "default train (4-5-3, 10 restarts, LM) on the 72 case-IV board points: median {:.1} ms, min {:.1} ms, max {:.1} ms over {} runs ({} rayon threads)",
        times[times.len() / 2] * 1e3,
        times[0] * 1e3,
        times[times.len() - 1] * 1e3,
        times.len(),
        rayon::current_num_threads()
    );
    Ok(())
}
