//! `hvs track`: the head in the loop (`host::track`): keeps the nearest object (or the one
//! under a pixel) in the middle of both eyes, one log row per frame. Frames from a scene's
//! virtual cameras or real ones; the head emulated, the firmware in QEMU, or on a port.

use crate::data::captures::{captures_csv, CaptureRow};
use crate::data::output::{create_folder, remove_if_created, write_atomically, Batch};
use crate::track::frames::FrameSource;
use crate::track::servo_head::{self, HeadChoice};
use crate::track::{self, target::TargetMode};
use anyhow::{anyhow, Result};
use hvs_shared::runtime::fixation::LoopConfig;
use std::path::PathBuf;

/// Arguments of `hvs track`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The model (.hvsw): a stereo or posture-aware net.
    #[arg(long, value_name = "M.hvsw")]
    pub model: PathBuf,
    /// The scene (JSON: rig, camera_fps, background, objects; see README): the virtual cameras.
    #[arg(long, value_name = "SCENE.json", required_unless_present = "cameras")]
    pub scene: Option<PathBuf>,
    /// Real cameras (`v4l:LEFT,RIGHT`, device paths or numbers; a build with the `v4l`
    /// feature), on the head of --port.
    #[arg(long, value_name = "v4l:A,B", conflicts_with = "scene", requires = "port")]
    pub cameras: Option<String>,
    /// With --cameras: their image size [default: the model's training images', else 640x480].
    #[arg(long, value_name = "WxH", requires = "cameras")]
    pub camera_size: Option<String>,
    /// A head controller on a link: a real head's serial port (`/dev/ttyUSB0`,
    /// `serial:PATH[@BAUD]`) or `tcp:HOST:PORT` (e.g. `hvs emulate`'s QEMU), moved with
    /// posture commands (protocol 3).
    #[arg(long, value_name = "PATH")]
    pub port: Option<String>,
    /// How long to run (s), as a number of frames: seconds times the cameras' frame rate (a
    /// scene's `camera_fps`). With `--head emulate` that is the simulated time; a head in
    /// QEMU or on a port keeps its own clock, so its log's `t_s` runs longer when a frame
    /// takes longer than one frame period to make and match.
    #[arg(long, value_name = "S", allow_negative_numbers = true)]
    pub seconds: f64,
    /// The log: one row per frame.
    #[arg(long, value_name = "LOG.csv")]
    pub log: PathBuf,
    /// The head: `emulate` (the head's logic on the host, on a simulated clock: same seed,
    /// same log bytes) or `qemu` (the head firmware in QEMU, moved with posture commands on
    /// its own clock, which runs in real time: the log's `t_s` is the head's time).
    #[arg(long, value_enum, default_value = "emulate")]
    pub head: super::HeadKind,
    /// With `--head qemu`: the firmware ELF [default: as `hvs emulate`].
    #[arg(long, value_name = "ELF")]
    pub firmware: Option<PathBuf>,
    /// `nearest` (the nearest object in the front region) or `U,V` (the object under this left
    /// pixel at the start, then followed).
    #[arg(long, value_name = "nearest|U,V", default_value = "nearest", allow_hyphen_values = true)]
    pub target: String,
    /// Writes every frame (leftNNNN.png, rightNNNN.png) and CAPTURES.csv with the joint columns.
    #[arg(long, value_name = "DIR")]
    pub record: Option<PathBuf>,
    /// Share of the kinematics' measured miss taken into the correction per frame (0 = the
    /// kinematics alone, no image correction).
    #[arg(long, value_name = "G", default_value_t = f64::from(track::DEFAULT_CORRECTION_GAIN), allow_negative_numbers = true)]
    pub correction_gain: f64,
    /// Frames of a moving target's motion the fixation leads it by (0: aim where it is seen).
    #[arg(long, value_name = "F", default_value_t = f64::from(track::DEFAULT_LEAD_FRAMES), allow_negative_numbers = true)]
    pub lead_frames: f64,
    /// Frames in a row without a target after which the head turns home (straight ahead,
    /// the widest view) to look for one again; 0: hold the last command.
    #[arg(long, value_name = "FRAMES", default_value_t = LoopConfig::DEFAULT.home_after_frames)]
    pub home_after: u32,
    /// Seed of the cameras' sensor noise (same seed, same log bytes).
    #[arg(long, value_name = "S", default_value_t = 0)]
    pub seed: u64,
}

fn parse_target(s: &str) -> Result<TargetMode> {
    if s == "nearest" {
        return Ok(TargetMode::Nearest);
    }
    crate::cli::parse_pixel("--target", s).map(TargetMode::Pixel).map_err(|_| {
        crate::cli::usage(format!("--target: expected nearest or U,V (two numbers), got {s:?}"))
    })
}

/// Frames per second the loop asks real cameras for (they give what they give; the loop runs
/// on the head's clock).
const REAL_CAMERA_FPS: f64 = 30.0;

/// `hvs track`.
pub fn run(a: Args) -> Result<()> {
    if !(a.seconds.is_finite() && a.seconds > 0.0 && a.seconds <= 3600.0) {
        return Err(crate::cli::usage(format!(
            "--seconds: must be > 0 and at most 3600, got {}",
            crate::fmt::given(a.seconds)
        )));
    }
    if !(a.correction_gain.is_finite() && (0.0..=1.0).contains(&a.correction_gain)) {
        return Err(crate::cli::usage(format!(
            "--correction-gain: must be from 0 to 1, got {}",
            crate::fmt::given(a.correction_gain)
        )));
    }
    let most = hvs_shared::runtime::fixation::MAX_LEAD_FRAMES;
    if !(a.lead_frames.is_finite() && (0.0..=f64::from(most)).contains(&a.lead_frames)) {
        return Err(crate::cli::usage(format!(
            "--lead-frames: must be from 0 to {most}, got {}",
            crate::fmt::given(a.lead_frames)
        )));
    }
    // Within their ranges: the loop's `f32` settings.
    let (correction_gain, lead_frames) = (a.correction_gain as f32, a.lead_frames as f32);
    let target = parse_target(&a.target)?;
    let choice = match (&a.port, a.head) {
        (Some(_), super::HeadKind::Qemu) => {
            return Err(crate::cli::usage("--port and --head qemu: give one head"));
        }
        (Some(p), _) => HeadChoice::Port(crate::cli::port_arg(p)?),
        (None, kind) => kind.choice(a.firmware.clone()),
    };
    let spec = a
        .cameras
        .as_deref()
        .map(crate::track::cameras::CameraSpec::parse)
        .transpose()
        .map_err(|e| crate::cli::usage(e.to_string()))?;
    let camera_size = a.camera_size.as_deref().map(crate::cli::parse_camera_size).transpose()?;
    let mut inputs = vec![("--model", a.model.as_path())];
    if let Some(scene) = &a.scene {
        inputs.push(("--scene", scene.as_path()));
    }
    crate::data::output::check_outputs(&[("--log", a.log.as_path())], &inputs)?;
    if let Some(dir) = &a.record {
        crate::data::output::check_dir_output("--record", dir)?;
        if let Some(w) = crate::data::output::leftover_files_warning("--record", dir) {
            eprintln!("warning: {w}");
        }
        inputs.push(("--log", a.log.as_path()));
        crate::cli::check_inputs_not_written_in(
            "--record",
            dir,
            "the record's",
            &inputs,
            record_file_name,
        )?;
    }
    let model = crate::data::model::load(&a.model)?;
    let blob = model.blob.clone();
    let estimator =
        track::estimator_of(model.blob).map_err(|e| anyhow!("{}: {e}", a.model.display()))?;
    // The frames: the virtual cameras of a scene, or real ones.
    let (mut cameras, (w, h), fps, loop_cfg): (Box<dyn FrameSource>, _, _, _) =
        match (&a.scene, &spec) {
            (Some(scene), _) => {
                let loaded = track::scene_file::load(scene)?;
                let loop_cfg = track::loop_config(&loaded.rig, correction_gain);
                let cams = loaded.cameras(a.seed);
                (Box::new(cams), loaded.image_size(), loaded.scene.camera_fps, loop_cfg)
            }
            (None, Some(spec)) => {
                let size = track::cameras::size_for(camera_size, Some(&blob));
                let loop_cfg = track::loop_config_for_cameras(&blob, size, correction_gain);
                (track::cameras::open(spec, size)?, size, REAL_CAMERA_FPS, loop_cfg)
            }
            (None, None) => return Err(crate::cli::usage("give --scene or --cameras")),
        };
    if (a.seconds * fps).floor() < 1.0 {
        return Err(crate::cli::usage(format!(
            "--seconds: {} s is less than one frame at {fps} frames/s",
            crate::fmt::given(a.seconds)
        )));
    }
    // The model's depths hold for the images it was trained on (as `hvs depth` and `hvs
    // locate` refuse other sizes).
    let source = a.scene.as_deref().unwrap_or(std::path::Path::new("--cameras"));
    crate::depth::check_pair_size(&a.model, &blob, source, (w, h))?;
    if let TargetMode::Pixel([u, v]) = target {
        if !crate::depth::inside_image(u, v, (w, h)) {
            return Err(crate::cli::usage(format!(
                "--target: {u},{v} is outside the {w}x{h} left image"
            )));
        }
    }
    let cfg = track::TrackConfig {
        seconds: a.seconds,
        fps,
        target,
        loop_cfg: LoopConfig { lead_frames, home_after_frames: a.home_after, ..loop_cfg },
    };
    let mut head = servo_head::open(&choice, &a.model)?;
    // Every input checked: the run starts.
    if let Some(w) = track::fixed_posture_warning(&blob) {
        eprintln!("warning: {}: {w}", a.model.display());
    }
    let stop = track::stop_on_interrupt();
    // Recorded frames go to temporary files in the folder as they are taken (memory stays
    // flat however long the run), and replace the folder's files together at the end.
    let batch = Batch::new();
    let made_record = match &a.record {
        Some(dir) => create_folder("--record", dir)?,
        None => false,
    };
    let mut recorded = Vec::new();
    let mut times = Vec::new();
    // The rows as they come: a head or cameras that stop mid-run end the command with an
    // error, and the log still gets the frames before.
    let mut rows = Vec::new();
    let result = track::run(&mut *cameras, &mut *head, &estimator, &cfg, stop, |frame, row, t| {
        rows.push(row.clone());
        times.push(t);
        if let Some(dir) = &a.record {
            let k = recorded.len();
            let names = [format!("left{k:04}.png"), format!("right{k:04}.png")];
            batch.add(&dir.join(&names[0]), &crate::vision::png_bytes(&frame.left)?)?;
            batch.add(&dir.join(&names[1]), &crate::vision::png_bytes(&frame.right)?)?;
            recorded.push((
                names,
                row.joints,
                frame.truth.as_ref().and_then(|t| t.scene.objects.first().map(|o| o.centre)),
            ));
        }
        Ok(())
    });
    drop(head);
    let text = track::log_csv(&rows);
    write_atomically(&a.log, |w| Ok(w.write_all(text.as_bytes())?))?;
    let run = match result {
        Ok(run) => run,
        Err(e) => {
            // No record of a failed run: its temporary files go with the batch, and a folder this
            // run made goes too (left alone unless empty).
            drop(batch);
            if let Some(dir) = &a.record {
                remove_if_created(dir, made_record);
            }
            let n = rows.len();
            return Err(e.context(format!(
                "frame {n}: the run stopped; {} has the {n} frames before",
                a.log.display()
            )));
        }
    };
    if let Some(dir) = &a.record {
        let mut rows = Vec::with_capacity(recorded.len());
        for ([ln, rn], joints, centre) in &recorded {
            rows.push(CaptureRow {
                left: ln,
                right: rn,
                centre: centre.unwrap_or([f64::NAN; 3]),
                joints: *joints,
            });
        }
        let csv = captures_csv(&rows, true);
        batch.add(&dir.join("CAPTURES.csv"), csv.as_bytes())?;
        batch.commit()?;
    }
    let tracked = rows.iter().filter(|r| r.status == "tracking").count();
    match run.right_scale {
        Some(s) if s != 1.0 => eprintln!(
            "the right camera sees at {s:.3} times the left one's scale (measured from the \
             images); its image was matched resampled by that"
        ),
        None if !rows.is_empty() => eprintln!(
            "note: the right camera's scale against the left one's was not measured (too few \
             windows of the front region matched at any scale from 0.65 to 1.54, or the best \
             lay at an end of that range); its image was matched as it is"
        ),
        _ => {}
    }
    let interrupted = stop.load(std::sync::atomic::Ordering::Relaxed);
    if let Some(line) = rate_line(&times) {
        eprintln!("{line}");
    }
    eprintln!(
        "{} frames ({} tracking) -> {}{}",
        rows.len(),
        tracked,
        a.log.display(),
        if interrupted { " (interrupted)" } else { "" }
    );
    if let (TargetMode::Pixel([u, v]), 0, false) = (target, tracked, rows.is_empty()) {
        eprintln!(
            "warning: --target {u},{v}: no object was found at that pixel in any frame (no \
             unique match near it, or none the model gives a depth for: outside the depths and \
             the image region it was trained on at that posture)"
        );
    }
    if interrupted {
        // The log is whole; the exit code says the run is not.
        return Err(crate::cli::Interrupted.into());
    }
    Ok(())
}

/// The run's wall times a frame: perception and control (median, 95th percentile, worst)
/// and, on its own, the virtual cameras' render.
fn rate_line(times: &[track::FrameTimes]) -> Option<String> {
    let ms = |f: &dyn Fn(&track::FrameTimes) -> f64| {
        let mut v: Vec<f64> = times.iter().map(|t| 1e3 * f(t)).collect();
        v.sort_by(f64::total_cmp);
        v
    };
    let (p, g) = (ms(&|t| t.perceive_s), ms(&|t| t.grab_s));
    let at = |v: &[f64], q: f64| v[((v.len() - 1) as f64 * q).round() as usize];
    (!p.is_empty()).then(|| {
        format!(
            "perception and control: {:.1} ms a frame (median; 95th percentile {:.1}, worst {:.1}: {:.0} frames/s at the median); rendering the pair: {:.1} ms (median, not perception)",
            at(&p, 0.5),
            at(&p, 0.95),
            at(&p, 1.0),
            1e3 / at(&p, 0.5).max(1e-3),
            at(&g, 0.5)
        )
    })
}

/// Whether `name` is one of the names `hvs track --record DIR` writes into `DIR`
/// (`CAPTURES.csv`, `leftNNNN.png`, `rightNNNN.png`).
fn record_file_name(name: &str) -> bool {
    let numbered = |prefix: &str| {
        name.strip_prefix(prefix)
            .and_then(|r| r.strip_suffix(".png"))
            .is_some_and(|n| n.len() >= 4 && n.bytes().all(|b| b.is_ascii_digit()))
    };
    name == "CAPTURES.csv" || numbered("left") || numbered("right")
}
