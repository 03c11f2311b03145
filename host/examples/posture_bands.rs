//! A posture-aware model's depth error per posture band against the floor, on a CSV of your
//! own: the bands of the posture study (`hvs_host::study::posture::bands`: all rows, then
//! thirds of each gaze term's working range) on any posture-aware set with ground truth, e.g.
//! test captures of `hvs collect` through `hvs board detect`.
//!
//! ```sh
//! cargo run --release -p hvs-host --example posture_bands -- MODEL.hvsw TEST.csv [--case N | --rig RIG.json]
//! ```
//!
//! The floor is optimal triangulation with the true cameras (thesis case `N`, default 3, or a
//! rig file as `hvs eval --rig` reads) at each row's joints, on the same pixels. Prints one
//! line per band and the worst band's ratio.

use anyhow::{bail, Context, Result};
use hvs_host::data::csv::{read_set, Inputs};
use hvs_host::sim::posture::PostureSample;
use hvs_shared::runtime::gaze::Joints;
use hvs_shared::sim::posture::HeadRig;
use std::path::PathBuf;

fn main() -> Result<()> {
    let mut pos = Vec::new();
    let (mut case, mut rig) = (None, None);
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        match a.as_str() {
            "--case" => {
                case = Some(args.next().context("--case needs N")?.parse().context("--case")?)
            }
            "--rig" => rig = Some(PathBuf::from(args.next().context("--rig needs a file")?)),
            _ => pos.push(PathBuf::from(a)),
        }
    }
    let [model, data] = &pos[..] else {
        bail!("usage: posture_bands MODEL.hvsw TEST.csv [--case N | --rig RIG.json]");
    };
    let blob = hvs_host::data::model::load(model)?.blob;
    let rig = match rig {
        Some(p) => hvs_host::data::rig::load(&p, case)?,
        None => hvs_shared::sim::presets::case(case.unwrap_or(3)).context("--case must be 1-4")?,
    };
    let table = read_set(data, Inputs::StereoJoints, true)?;
    let d = &table.data;
    let set: Vec<PostureSample> = (0..d.len())
        .map(|i| {
            let r = d.row(i);
            PostureSample {
                px: [r[0], r[1], r[2], r[3]],
                joints: Joints(core::array::from_fn(|k| r[4 + k] as f32)),
                xyz: d.targets[i],
            }
        })
        .collect();
    let rows = hvs_host::study::posture::bands(&blob, &HeadRig::new(rig), &set, &[]);
    println!("term,band,points,net_z_pct,floor_z_pct,ratio");
    for r in &rows {
        println!(
            "{},\"{}\",{},{:.4},{:.4},{:.3}",
            r.term,
            r.band,
            r.net.points,
            r.net.z_pct,
            r.floor.z_pct,
            r.ratio()
        );
    }
    let worst = rows.iter().max_by(|a, b| a.ratio().total_cmp(&b.ratio())).context("no rows")?;
    println!("worst band: {} {} at {:.3} x the floor", worst.term, worst.band, worst.ratio());
    Ok(())
}
