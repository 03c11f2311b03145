//! The posture study of `hvs_host::study::posture` with settings of your own: the one runner
//! and writer of `hvs experiment posture` write its CSVs, plots and `POSTURE.md` into `--out
//! DIR` (default `posture-study`), and the page is printed.
//!
//! ```sh
//! cargo run --release -p hvs-host --example posture_study                 # about 1-2 min
//! cargo run --release -p hvs-host --example posture_study -- --sweep      # + hidden sweep, lattice
//! cargo run --release -p hvs-host --example posture_study -- --quick      # smaller, seconds
//! ```
//!
//! Options: `--case N` (1-4, default 3), `--seed S`, `--hidden H` (default 16), `--restarts R`,
//! `--sweep` (also train 5, 8, 12, 24, 32 hidden neurons and the regular lattice of postures),
//! `--arch A` (family of the posture-aware nets, as `hvs train --arch`; default
//! `inverse-depth-skip`, `hvs train`'s), `--frame F` (`head`, `eye-platform` or `cyclopean`, as `hvs train
//! --frame`; default `hvs train`'s for the family), `--lattice` (also train the chosen size on the regular lattice of postures),
//! `--quick` (a 2-level training grid and fewer test points: a smoke run), `--out DIR`.

use anyhow::{bail, Context, Result};
use clap::ValueEnum;
use hvs_host::cli::train::{ArchArg, FrameArg};
use hvs_host::study::engine::{self, Quiet, Report};
use hvs_host::study::posture::{self, Posture, StudyConfig};
use hvs_host::train::default_frame;
use hvs_shared::runtime::blob::InputKind;
use std::path::PathBuf;

fn main() -> Result<()> {
    let mut cfg = StudyConfig::default();
    let mut out = PathBuf::from("posture-study");
    let mut frame_set = false;
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        let mut value = |name: &str| -> Result<String> {
            args.next().with_context(|| format!("{name} needs a value"))
        };
        match a.as_str() {
            "--case" => cfg.case = value("--case")?.parse().context("--case")?,
            "--seed" => cfg.seed = value("--seed")?.parse().context("--seed")?,
            "--hidden" => cfg.hidden = value("--hidden")?.parse().context("--hidden")?,
            "--restarts" => cfg.restarts = value("--restarts")?.parse().context("--restarts")?,
            "--arch" => {
                let v = value("--arch")?;
                cfg.family = ArchArg::from_str(&v, false)
                    .map_err(|e| anyhow::anyhow!("--arch: {e}"))?
                    .family();
                if !frame_set {
                    cfg.frame = default_frame(cfg.family, InputKind::StereoJoints);
                }
            }
            "--frame" => {
                let v = value("--frame")?;
                cfg.frame = FrameArg::from_str(&v, false)
                    .map_err(|e| anyhow::anyhow!("--frame: {e}"))?
                    .frame();
                frame_set = true;
            }
            "--out" => out = PathBuf::from(value("--out")?),
            "--sweep" => {
                cfg.sweep = vec![5, 8, 12, 16, 24, 32];
                cfg.lattice = true;
            }
            "--lattice" => cfg.lattice = true,
            "--quick" => {
                cfg.quick = true;
                cfg.train_levels = [2, 2, 2, 2, 2];
                cfg.hidden = cfg.hidden.min(10);
                cfg.restarts = 1;
                cfg.test_postures = 200;
                cfg.test_points = 600;
                cfg.extreme_points = 200;
                cfg.fixed_points = 100;
                cfg.distortion_hidden = vec![5];
            }
            "-h" | "--help" => {
                println!("see the doc comment of host/examples/posture_study.rs");
                return Ok(());
            }
            other => bail!("unknown argument {other}"),
        }
    }
    engine::run(&out, &Quiet, |p| posture::run(&cfg, p))?;
    let page = out.join(Posture::PAGE);
    let text = std::fs::read_to_string(&page)
        .with_context(|| format!("{}: cannot read", page.display()))?;
    print!("{text}");
    Ok(())
}
