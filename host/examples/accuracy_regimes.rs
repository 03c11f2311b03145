//! Depth accuracy of a model family against the floor in every pixel regime (issue 14): the
//! regime table and the thesis protocol of `hvs experiment accuracy`
//! ([`hvs_host::study::accuracy`]), without its sweeps and images, for tuning a family.
//!
//! `cargo run --release -p hvs-host --example accuracy_regimes [-- --eval] [--family NAME]`
//! prints, for the thesis board and the 9x6 board at 6 cm, the regimes int, sub, exact and
//! barrel and cases I-IV, the e_ma of the floor, a DLT fit, the thesis 4-5-3 net and NAME's
//! 4-5-3 net (`hvs train --arch NAME`; default: `hvs train`'s default) and their ratios to
//! the floor. Seeds: base 0 (tuning) or, with `--eval`, the held-out base 1_000_000 of
//! `docs/ACCURACY.md`.

use clap::Parser;
use hvs_host::cli::train::ArchArg;
use hvs_host::fmt::{roman, times};
use hvs_host::study::accuracy::report::{case_table, summary_table};
use hvs_host::study::accuracy::{
    protocol_rows, regime_rows, Accuracy, AccuracyConfig, HELD_OUT_SEED_BASE,
};
use hvs_host::study::engine::Quiet;

#[derive(Parser)]
struct Args {
    /// Use the held-out evaluation seeds instead of the tuning ones.
    #[arg(long)]
    eval: bool,
    /// The family compared with the thesis net.
    #[arg(long, value_enum, default_value_t = ArchArg::DEFAULT)]
    family: ArchArg,
    /// Reduced run (case IV, 2 restarts, 60 test points).
    #[arg(long)]
    quick: bool,
}

fn main() -> anyhow::Result<()> {
    let a = Args::parse();
    let cfg = AccuracyConfig {
        default_family: a.family.family(),
        seed_base: if a.eval { HELD_OUT_SEED_BASE } else { 0 },
        quick: a.quick,
    };
    let run = Accuracy {
        config: cfg,
        regimes: regime_rows(&cfg, &Quiet)?,
        protocol: protocol_rows(&cfg)?,
        noise: Vec::new(),
        lens: Vec::new(),
        images: Vec::new(),
        real_pair: None,
        stage_s: Vec::new(),
        threads: rayon::current_num_threads(),
    };
    println!(
        "seed base {} ({}); nets: seed 0, {} restarts, LM; {} volume test points\n",
        cfg.seed_base,
        if a.eval { "held out" } else { "tuning" },
        cfg.restarts(),
        cfg.test_points()
    );
    println!("{}", summary_table(&run));
    println!("{}", case_table(&run));
    for p in &run.protocol {
        let r = p.scores.ratios();
        println!(
            "protocol case {}: worst depth / floor's: DLT {}, thesis {}, {} {}",
            roman(p.case),
            times(r[0]),
            times(r[1]),
            cfg.default_family.name(),
            times(r[2])
        );
    }
    Ok(())
}
