//! The posture study of `hvs_host::study::posture`, printed as the markdown section of the
//! experiments report (and, with `--out DIR`, its tables as CSV files).
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
//! `inverse-depth-skip`, `hvs train`'s), `--frame F` (`head` or `eye-platform`, as `hvs train
//! --frame`; default `hvs train`'s for the family), `--lattice` (also train the chosen size on the regular lattice of postures),
//! `--quick` (a 2-level training grid and fewer test points: a smoke run), `--out DIR`.

use anyhow::{bail, Context, Result};
use clap::ValueEnum;
use hvs_host::cli::train::{ArchArg, FrameArg};
use hvs_host::study::posture::{csv_tables, markdown, run, StudyConfig};
use hvs_host::train::default_frame;
use hvs_shared::runtime::blob::InputKind;
use std::path::PathBuf;

fn main() -> Result<()> {
    let mut cfg = StudyConfig::default();
    let mut out: Option<PathBuf> = None;
    let mut frame_set = false;
    let mut args = std::env::args().skip(1);
    let mut command =
        vec!["cargo run --release -p hvs-host --example posture_study --".to_string()];
    while let Some(a) = args.next() {
        command.push(a.clone());
        let mut value = |name: &str| -> Result<String> {
            let v = args
                .next()
                .with_context(|| format!("{name} needs a value"))?;
            command.push(v.clone());
            Ok(v)
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
            "--out" => out = Some(PathBuf::from(value("--out")?)),
            "--sweep" => {
                cfg.sweep = vec![5, 8, 12, 16, 24, 32];
                cfg.lattice = true;
            }
            "--lattice" => cfg.lattice = true,
            "--quick" => {
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
    let report = run(&cfg)?;
    let command = command.join(" ");
    print!("{}", markdown(&report, &command));
    if let Some(dir) = out {
        std::fs::create_dir_all(&dir)
            .with_context(|| format!("{}: cannot create", dir.display()))?;
        for (name, text) in csv_tables(&report) {
            let path = dir.join(name);
            hvs_host::data::csv::write_output(Some(&path), |w| {
                w.write_all(text.as_bytes()).context("cannot write")
            })?;
        }
        let md = dir.join("posture.md");
        hvs_host::data::csv::write_output(Some(&md), |w| {
            w.write_all(markdown(&report, &command).as_bytes())
                .context("cannot write")
        })?;
    }
    Ok(())
}
