//! `hvs render`: stereo photos of a chessboard through a rig, with exact corner truth
//! (`hvs_vision::render`), as a capture set `hvs board detect` reads; or, with `--scene`, one
//! pair of a scene file with its per-pixel truth (`hvs_vision::scene`) in `hvs depth`'s
//! formats.

use super::{RenderArgs, RigArgs};
use crate::vision::write_capture_set;
use anyhow::{anyhow, Result};
use hvs_shared::runtime::gaze::{Axis, GazeConfig, Joints};
use hvs_shared::sim::camera::Distortion;
use hvs_shared::sim::posture::HeadRig;
use hvs_shared::sim::presets;
use hvs_vision::render;
use std::io::IsTerminal;
use std::path::{Path, PathBuf};

/// Arguments of `hvs render`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The cameras.
    #[command(flatten)]
    pub rig: RigArgs,
    /// Output folder (created if missing, in a folder that exists): leftNN.png, rightNN.png,
    /// captures.csv (left,right,z,x,y and the joints with --joints), truth.csv (the exact,
    /// unrounded corner pixels) and board.json; with --scene: left.png, right.png, depth.pfm
    /// and matches.pfm.
    #[arg(short = 'o', long, value_name = "DIR")]
    pub output: PathBuf,
    /// Inner corners per row and column.
    #[arg(long, value_name = "COLSxROWS", default_value = "9x6")]
    pub inner_corners: String,
    /// Side of one square (cm).
    #[arg(long, value_name = "CM", default_value_t = 6.0)]
    pub square_cm: f64,
    /// Board depths (cm), one stereo pair each [default: the thesis' training depths
    /// 65,85,105,125,145,165].
    #[arg(long, value_name = "Z,...", value_delimiter = ',')]
    pub depths: Option<Vec<f64>>,
    /// Board centre X, Y (cm).
    #[arg(
        long,
        value_name = "X,Y",
        value_delimiter = ',',
        allow_hyphen_values = true,
        default_value = "0,0"
    )]
    pub centre: Vec<f64>,
    /// Head posture, degrees: neck_pan,neck_tilt,eye_tilt,left_eye_pan,right_eye_pan
    /// (written to captures.csv as the joint columns) [default: home, no joint columns].
    #[arg(long, value_name = "NP,NT,ET,LP,RP", value_delimiter = ',', allow_hyphen_values = true)]
    pub joints: Option<Vec<f32>>,
    /// Radial lens distortion of both cameras: K1 or K1,K2 (r in units of half the image width).
    #[arg(long, value_name = "K1[,K2]", value_delimiter = ',', allow_hyphen_values = true)]
    pub distortion: Option<Vec<f64>>,
    #[command(flatten)]
    pub camera: RenderArgs,
    /// Seed of the sensor noise (same seed, same bytes).
    #[arg(long, value_name = "S", default_value_t = 0)]
    pub seed: u64,
    /// Render one pair of a scene file instead of boards (the format of `hvs track --scene`,
    /// its rig inside; at --joints or home), with its truth in the formats `hvs depth` writes,
    /// to score it against: depth.pfm (Z in cm of the point each left pixel sees, +inf where
    /// none) and matches.pfm (where the right camera sees that point: u_r, v_r and 1; +inf,
    /// +inf, 0 where it does not).
    #[arg(
        long,
        value_name = "SCENE.json",
        conflicts_with_all = ["case", "rig", "inner_corners", "square_cm", "depths", "centre", "distortion"]
    )]
    pub scene: Option<PathBuf>,
    /// With --scene: the time (s) the scene is rendered at [default: 0].
    #[arg(long, value_name = "S", allow_hyphen_values = true)]
    pub time: Option<f64>,
}

/// The five angles of `--joints`, checked: finite, and each within the head's limits (the
/// ones its firmware and `hvs_shared::runtime::gaze` hold every joint to: the head never
/// takes another posture).
fn joints_arg(j: Option<&[f32]>) -> Result<Option<Joints>> {
    let joints = match j {
        None => return Ok(None),
        Some(j) if j.len() == 5 && j.iter().all(|v| v.is_finite()) => {
            Joints([j[0], j[1], j[2], j[3], j[4]])
        }
        Some(_) => return Err(crate::cli::usage("--joints takes five finite angles (degrees): neck_pan,neck_tilt,eye_tilt,left_eye_pan,right_eye_pan")),
    };
    let limits = GazeConfig::DEFAULT.limits;
    for (axis, name) in Axis::ALL.into_iter().zip(crate::data::dataset::JOINT_COLUMNS) {
        let (v, l) = (joints[axis], limits.axis(axis));
        if !(l.min_deg..=l.max_deg).contains(&v) {
            return Err(crate::cli::usage(format!(
                "--joints: {name} {v} degrees is outside its limits, {} to {} (the head's)",
                l.min_deg, l.max_deg
            )));
        }
    }
    Ok(Some(joints))
}

/// Refuses an input (`(flag, path)`) that is one of the files `names` this run writes into
/// the folder `dir` ([`crate::data::output::check_outputs`]), before any work: a new folder
/// holds no input.
fn check_inputs_not_written(
    dir: &Path,
    names: &[impl AsRef<str>],
    inputs: &[(&str, &Path)],
) -> Result<()> {
    if !dir.is_dir() {
        return Ok(());
    }
    let written: Vec<PathBuf> = names.iter().map(|n| dir.join(n.as_ref())).collect();
    let outputs: Vec<(&str, &Path)> = written.iter().map(|p| ("-o", p.as_path())).collect();
    crate::data::output::check_outputs(&outputs, inputs)
}

/// `hvs render --scene`: one pair of the scene and its truth images.
fn run_scene(a: &Args, path: &Path) -> Result<()> {
    crate::data::output::check_dir_output("-o", &a.output)?;
    check_inputs_not_written(&a.output, &crate::vision::SCENE_PAIR_FILES, &[("--scene", path)])?;
    let loaded = crate::track::scene_file::load(path)?;
    let t = a.time.unwrap_or(0.0);
    if !t.is_finite() {
        return Err(crate::cli::usage("--time must be finite"));
    }
    let defaults = render::RenderOptions::default();
    let opt = a.camera.options(defaults.margin_cm, defaults.supersample)?;
    let joints = joints_arg(a.joints.as_deref())?.unwrap_or(Joints::HOME);
    let r = hvs_vision::scene::render_scene(
        &HeadRig::new(loaded.rig),
        &joints,
        &loaded.scene.at(t),
        &opt,
        a.seed,
    )
    .map_err(|e| anyhow!("{}: {e}", path.display()))?;
    let seen = crate::vision::write_scene_pair(&a.output, &r)?;
    for k in r.unseen_objects() {
        eprintln!(
            "warning: {}: objects[{k}] is in neither image (behind the head, out of view or hidden)",
            path.display()
        );
    }
    if seen == 0 {
        eprintln!("warning: the right camera sees none of the points the left one sees");
    }
    eprintln!(
        "rendered {} at t = {} s into {}: {}x{}, {seen} left pixels seen by the right camera",
        path.display(),
        crate::fmt::given(t),
        a.output.display(),
        r.left.width(),
        r.left.height()
    );
    Ok(())
}

/// A warning when the folder `dir` holds images of pairs past this run's `pairs` (an earlier
/// run of more depths): they stay beside this run's, and `captures.csv` lists only this run's
/// (QA, 2026-12-08: `left02..06.png` of a six-depth set stayed under a one-depth render).
fn later_pairs_warning(dir: &Path, pairs: usize) -> Option<String> {
    let stale: Vec<String> = (pairs..render::MAX_DEPTHS)
        .flat_map(render::capture_names)
        .filter(|n| dir.join(n).is_file())
        .collect();
    (!stale.is_empty()).then(|| {
        format!(
            "-o {}: {} image(s) of an earlier set stay beside this one ({} ...): captures.csv lists only this run's {pairs} pair(s)",
            dir.display(),
            stale.len(),
            stale[0]
        )
    })
}

/// `hvs render`.
pub fn run(a: Args) -> Result<()> {
    if let Some(path) = &a.scene {
        return run_scene(&a, path);
    }
    if a.time.is_some() {
        return Err(crate::cli::usage("--time goes with --scene (boards stand still)"));
    }
    crate::data::output::check_dir_output("-o", &a.output)?;
    let depths = a.depths.clone().unwrap_or_else(|| presets::TRAIN_DEPTHS.to_vec());
    render::check_depths(&depths).map_err(crate::cli::render_error)?;
    let written = crate::vision::capture_set_files(depths.len());
    check_inputs_not_written(&a.output, &written, &a.rig.inputs())?;
    let rig = a
        .rig
        .rig()?
        .ok_or_else(|| crate::cli::usage("choose a rig with --case N or --rig FILE.json"))?;
    let (cols, rows) = parse_size(&a.inner_corners)?;
    // The corner counts are checked by `parse_size`: what is left is the square.
    let board = hvs_vision::board::Board::new(cols, rows, a.square_cm).map_err(|e| match e {
        hvs_vision::board::BoardError::Value(_, why) => {
            crate::cli::usage(format!("--square-cm: {why}"))
        }
        other => anyhow!("{other}"),
    })?;
    let opt = a.camera.options(a.square_cm, render::RenderOptions::default().supersample)?;
    let distortion = match a.distortion.as_deref() {
        None => Distortion::NONE,
        Some([k1]) => Distortion { k1: *k1, k2: 0.0 },
        Some([k1, k2]) => Distortion { k1: *k1, k2: *k2 },
        Some(_) => return Err(crate::cli::usage("--distortion takes K1 or K1,K2")),
    };
    if !distortion.is_finite() {
        return Err(crate::cli::usage("--distortion must be finite"));
    }
    let joints = joints_arg(a.joints.as_deref())?;
    let [x, y] = match a.centre.as_slice() {
        [x, y] if x.is_finite() && y.is_finite() => [*x, *y],
        _ => return Err(crate::cli::usage("--centre takes X,Y (cm)")),
    };
    if let Some(w) = later_pairs_warning(&a.output, depths.len()) {
        eprintln!("warning: {w}");
    }
    let head = HeadRig::new(rig).with_distortion(distortion);
    let bar = std::io::stderr().is_terminal().then(|| {
        let b = indicatif::ProgressBar::new_spinner();
        b.set_message(format!("rendering {} stereo pairs", depths.len()));
        b.enable_steady_tick(std::time::Duration::from_millis(120));
        b
    });
    let set = render::render_capture_set(
        &head,
        &joints.unwrap_or(Joints::HOME),
        &board,
        [x, y],
        &depths,
        &opt,
        a.seed,
    )
    .map_err(|e| anyhow!("{e}"))?;
    if let Some(b) = bar {
        b.finish_and_clear();
    }
    write_capture_set(&a.output, &set, joints.as_ref())?;
    let hidden = set.truth_rows().iter().filter(|r| !r.corner.in_image).count();
    eprintln!(
        "rendered {} of a {cols}x{rows} board ({} cm squares) into {}{}",
        crate::fmt::count(set.captures.len(), "stereo pair"),
        a.square_cm,
        a.output.display(),
        if hidden > 0 {
            format!("; warning: {hidden} corners fall outside an image")
        } else {
            String::new()
        }
    );
    Ok(())
}

/// `9x6` -> (9, 6).
fn parse_size(s: &str) -> Result<(u32, u32)> {
    let bad = || crate::cli::usage(format!("--inner-corners: {s:?} is not COLSxROWS (e.g. 9x6)"));
    let (c, r) = s.split_once(['x', 'X']).ok_or_else(bad)?;
    let (c, r): (u32, u32) =
        (c.trim().parse().map_err(|_| bad())?, r.trim().parse().map_err(|_| bad())?);
    let most = crate::sim::board::MAX_SIDE as u32;
    if c < 2 || r < 2 || c > most || r > most {
        return Err(crate::cli::usage(format!(
            "--inner-corners: {c}x{r}: each side must be from 2 to {most} corners"
        )));
    }
    Ok((c, r))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn joints_outside_the_heads_limits_are_bad_usage_naming_the_joint() {
        let home = joints_arg(Some(&[0.0; 5])).unwrap();
        assert_eq!(home, Some(Joints::HOME));
        let edge = [60.0, -35.0, 30.0, -35.0, 35.0];
        assert_eq!(joints_arg(Some(&edge)).unwrap(), Some(Joints(edge)));
        for (j, want) in [
            ([360.0, 0.0, 0.0, 0.0, 0.0], "neck_pan 360 degrees is outside its limits, -60 to 60"),
            (
                [0.0, 0.0, 0.0, 720.0, 0.0],
                "left_eye_pan 720 degrees is outside its limits, -35 to 35",
            ),
            ([100.0, 0.0, 0.0, 0.0, 0.0], "neck_pan 100 degrees"),
            (
                [0.0, 0.0, -30.5, 0.0, 0.0],
                "eye_tilt -30.5 degrees is outside its limits, -30 to 30",
            ),
        ] {
            let e = joints_arg(Some(&j)).unwrap_err();
            assert_eq!(crate::cli::exit_code(&e), 2, "{e}");
            let e = e.to_string();
            assert!(e.starts_with("--joints: ") && e.contains(want), "{j:?}: {e}");
        }
        let e = joints_arg(Some(&[f32::NAN, 0.0, 0.0, 0.0, 0.0])).unwrap_err();
        assert_eq!(crate::cli::exit_code(&e), 2, "{e}");
    }

    #[test]
    fn board_sizes() {
        assert_eq!(parse_size("9x6").unwrap(), (9, 6));
        assert_eq!(parse_size("7X4").unwrap(), (7, 4));
        for bad in ["9", "9x", "x6", "1x6", "9x-1", "axb"] {
            assert!(parse_size(bad).is_err(), "{bad}");
        }
    }
}
