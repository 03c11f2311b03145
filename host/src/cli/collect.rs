//! `hvs collect`: the head collects its own posture-aware training set ([`crate::collect`]).

use super::{usage, PostureArgs, RenderArgs};
use crate::collect::{self, Plan, Shot, Stop};
use crate::data::output::{
    check_dir_output, check_not_input, create_folder, remove_if_created, Batch,
};
use crate::fmt::count;
use crate::track::head_sim::VirtualHead;
use crate::vision::png_bytes;
use anyhow::{anyhow, bail, Result};
use hvs_shared::runtime::trajectory::ControllerConfig;
use hvs_shared::sim::posture::HeadRig;
use hvs_vision::board::Board;
use rayon::prelude::*;
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

/// Arguments of `hvs collect`.
#[derive(Debug, clap::Args)]
#[command(
    about = "The head collects its own posture-aware training set: board photos at many postures",
    long_about = "The head collects its own posture-aware training set.\n\n\
    The board stays where the user put it (each row of --positions), the head visits the\n\
    postures (--postures grid|lattice|random as `hvs simulate --postures`), waits until the\n\
    servos have settled and takes a pair. Pairs in which both cameras see the whole board are\n\
    written to DIR with CAPTURES.csv (left,right,z,x,y and the five joint columns the head\n\
    reports) and board.json; postures that do not see the board are skipped and counted. Then:\n\n\
    \x20 hvs board detect --board DIR/board.json --captures DIR/CAPTURES.csv -o POINTS.csv\n\
    \x20 hvs train --data POINTS.csv -o MODEL.hvsw\n\n\
    --scene: the virtual head (a scene file as `hvs track` reads; the board of --board is put\n\
    into it at each position). --port/--cameras: a real head with live cameras."
)]
pub struct Args {
    /// The board: {"pattern": "chessboard", "inner_corners": [9, 6], "square_cm": 6.0}.
    #[arg(long, value_name = "BOARD.json")]
    pub board: PathBuf,
    /// Board placements: x,y,z per row (board centre, head frame, cm; the board upright and
    /// facing the head).
    #[arg(long, value_name = "POSITIONS.csv")]
    pub positions: PathBuf,
    #[command(flatten)]
    pub postures: PostureArgs,
    /// The virtual head: the scene its cameras see (the rig and the objects; the board is
    /// added at each position).
    #[arg(long, value_name = "SCENE.json", conflicts_with_all = ["port", "cameras"])]
    pub scene: Option<PathBuf>,
    /// A real head: its serial port (`/dev/ttyUSB0`, `serial:PATH[@BAUD]`, or `tcp:HOST:PORT`),
    /// moved with posture commands (protocol 3).
    #[arg(long, value_name = "PATH", requires = "cameras")]
    pub port: Option<String>,
    /// A real head: its two cameras, v4l:LEFT,RIGHT (device numbers or paths; a build with
    /// the `v4l` feature).
    #[arg(long, value_name = "v4l:A,B", requires = "port")]
    pub cameras: Option<String>,
    /// With --cameras: their image size [default: 640x480].
    #[arg(long, value_name = "WxH", requires = "cameras")]
    pub camera_size: Option<String>,
    /// Output folder (created if missing, in a folder that exists): the images, CAPTURES.csv
    /// and board.json.
    #[arg(short = 'o', long, value_name = "DIR")]
    pub output: PathBuf,
    #[command(flatten)]
    pub camera: RenderArgs,
    /// Wait after each move has ended before the pair is taken (ms).
    #[arg(long, value_name = "MS", default_value_t = 100, value_parser = super::whole_u64)]
    pub settle_ms: u64,
    /// Seed of the postures (grid, random) and of the sensor noise (same seed, same bytes).
    #[arg(long, value_name = "S", default_value_t = 0, allow_negative_numbers = true, value_parser = super::whole_u64)]
    pub seed: u64,
}

/// What became of one stop.
enum Outcome {
    Written,
    OutOfView,
    Hidden,
}

/// `hvs collect`.
pub fn run(a: Args) -> Result<()> {
    let Some(scene_path) = &a.scene else {
        if let (Some(port), Some(cameras)) = (&a.port, &a.cameras) {
            return run_real_head(&a, port, cameras);
        }
        return Err(usage(
            "choose the head: --scene SCENE.json (virtual) or --port PATH --cameras v4l:A,B",
        ));
    };
    let plan = plan_of(&a, Some(scene_path))?;
    let loaded = crate::track::scene_file::load(scene_path)?;
    let head_rig = HeadRig::new(loaded.rig);
    let mut head = VirtualHead::new(&ControllerConfig::DEFAULT)?;
    let stops = collect::visit(&mut head, &plan)?;

    let bar = std::io::stderr().is_terminal().then(|| {
        let b = indicatif::ProgressBar::new(stops.len() as u64);
        b.set_style(
            indicatif::ProgressStyle::with_template(
                "collecting {bar:30} {pos}/{len} postures, {msg} [{elapsed_precise}]",
            )
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
        );
        b
    });
    let captured_count = AtomicU64::new(0);
    let created = create_folder("-o", &a.output)?;
    // Render and write in parallel, each image to its temporary file; the outcomes come back
    // in visit order. The set replaces what the folder held only when complete ([`Batch`]):
    // a run stopped or failed half-way leaves the last set as it was, not its CAPTURES.csv
    // over this run's images.
    let batch = Batch::new();
    let outcomes: Vec<Result<Outcome>> = stops
        .par_iter()
        .map(|stop| {
            let shot = collect::capture(&head_rig, &loaded.scene, &plan, stop)?;
            let out = match shot {
                Shot::OutOfView => Outcome::OutOfView,
                Shot::Hidden => Outcome::Hidden,
                Shot::Pair(pair) => {
                    let [l, r] = collect::image_names(stop);
                    batch.add(&a.output.join(l), &png_bytes(&pair[0])?)?;
                    batch.add(&a.output.join(r), &png_bytes(&pair[1])?)?;
                    let n = captured_count.fetch_add(1, Ordering::Relaxed) + 1;
                    if let Some(b) = &bar {
                        b.set_message(format!("{n} pairs"));
                    }
                    Outcome::Written
                }
            };
            if let Some(b) = &bar {
                b.inc(1);
            }
            Ok(out)
        })
        .collect();
    if let Some(b) = &bar {
        b.finish_and_clear();
    }
    let (mut captured, mut out_of_view, mut hidden) = (Vec::<Stop>::new(), 0usize, 0usize);
    for (stop, o) in stops.iter().zip(outcomes) {
        match o? {
            Outcome::Written => captured.push(*stop),
            Outcome::OutOfView => out_of_view += 1,
            Outcome::Hidden => hidden += 1,
        }
    }
    if captured.is_empty() {
        remove_if_created(&a.output, created);
        bail!(
            "no posture saw the whole board with both cameras ({} x {}; {out_of_view} out of view, {hidden} hidden): {}",
            count(plan.postures.len(), "posture"),
            count(plan.placements.len(), "placement"),
            match (out_of_view, hidden) {
                (_, 0) => "place the board nearer the middle of the working range",
                (0, _) => "the scene's objects hide the board: move them or the board",
                _ => "place the board nearer the middle of the working range, where the scene's objects do not hide it",
            }
        );
    }
    write_set(batch, &a.output, &plan, &captured)?;
    eprintln!(
        "collected {} into {} ({} x {}; skipped {out_of_view} where the board was not fully in both images, {hidden} where the scene hid part of it; {:.1} s of head time)",
        count(captured.len(), "pair"),
        a.output.display(),
        count(plan.placements.len(), "placement"),
        count(plan.postures.len(), "posture"),
        head.time_s()
    );
    Ok(())
}

/// `board.json` and `CAPTURES.csv` of the captured stops into `dir`, the set's images staged
/// in `batch` before them: the whole set replaces the folder's files together.
fn write_set(batch: Batch, dir: &Path, plan: &Plan, captured: &[Stop]) -> Result<()> {
    batch.add(&dir.join("board.json"), plan.board.to_json().as_bytes())?;
    batch.add(&dir.join("CAPTURES.csv"), collect::captures_csv(plan, captured).as_bytes())?;
    batch.commit()
}

/// The output folder checked against the inputs (and `scene`), the board, placements and
/// postures read: what to collect.
fn plan_of(a: &Args, scene: Option<&Path>) -> Result<Plan> {
    let settle_s = a.settle_ms as f64 / 1000.0;
    collect::check_settle(settle_s)
        .map_err(|e| usage(format!("--settle-ms {}: {e}", a.settle_ms)))?;
    check_dir_output("-o", &a.output)?;
    if let Some(w) = crate::data::output::leftover_files_warning("-o", &a.output) {
        eprintln!("warning: {w}");
    }
    let mut inputs: Vec<(&str, &Path)> = vec![("--board", &a.board), ("--positions", &a.positions)];
    inputs.extend(scene.map(|s| ("--scene", s)));
    if a.output.is_dir() {
        // A new folder cannot hold an input; an existing one might.
        for name in ["CAPTURES.csv", "board.json"] {
            check_not_input("-o", &a.output.join(name), &inputs)?;
        }
    }
    // Nor may an input have the name of one of the set's images there.
    crate::cli::check_inputs_not_written_in(
        "-o",
        &a.output,
        "the set's",
        &inputs,
        collect::is_image_name,
    )?;
    let board = Board::from_path(&a.board).map_err(|e| anyhow!("{e}"))?;
    let placements = crate::data::positions::read(&a.positions)?;
    let postures = a
        .postures
        .postures(a.seed)?
        .ok_or_else(|| usage("choose the postures: --postures grid, lattice or random"))?;
    Ok(Plan {
        render: a.camera.options(board.square_cm, 4)?,
        board,
        placements,
        postures,
        seed: a.seed,
        settle_s,
    })
}

/// `hvs collect --port PATH --cameras v4l:A,B`: a real head. At each placement the user is
/// asked to place the board (the corners both cameras see are counted live) and to press
/// Enter; the head then visits the postures and every pair in which both cameras find the
/// whole board is written at once to a temporary file; the set replaces the folder's files
/// when the last placement is done ([`Batch`]).
fn run_real_head(a: &Args, port: &str, cameras: &str) -> Result<()> {
    use crate::track::servo_head::{self, HeadChoice};
    let endpoint = crate::cli::port_arg(port)?;
    let spec =
        crate::track::cameras::CameraSpec::parse(cameras).map_err(|e| usage(e.to_string()))?;
    let asked = a.camera_size.as_deref().map(super::parse_camera_size).transpose()?;
    let size = crate::track::cameras::size_for(asked, None);
    let plan = plan_of(a, None)?;
    let mut cams = crate::track::cameras::open(&spec, size)?;
    let mut head = servo_head::open(&HeadChoice::Port(endpoint), Path::new(""))?;
    let created = create_folder("-o", &a.output)?;
    let (mut captured, mut skipped) = (Vec::<Stop>::new(), 0usize);
    let batch = Batch::new();
    for (k, p) in plan.placements.iter().enumerate() {
        wait_for_board(&mut *cams, &*head, &plan.board, p.xyz, k + 1, plan.placements.len())?;
        skipped += collect::visit_with_cameras(&mut *head, &mut *cams, &plan, k, |stop, pair| {
            let [l, r] = collect::image_names(stop);
            batch.add(&a.output.join(l), &png_bytes(&pair[0])?)?;
            batch.add(&a.output.join(r), &png_bytes(&pair[1])?)?;
            captured.push(*stop);
            eprint!("\r  {} pairs", captured.len());
            Ok(())
        })?;
        eprintln!();
    }
    if captured.is_empty() {
        remove_if_created(&a.output, created);
        bail!(
            "no posture saw the whole board with both cameras ({} skipped)",
            count(skipped, "posture")
        );
    }
    write_set(batch, &a.output, &plan, &captured)?;
    eprintln!(
        "collected {} into {} ({} x {}; skipped {skipped} where a camera did not find the whole board)",
        count(captured.len(), "pair"),
        a.output.display(),
        count(plan.placements.len(), "placement"),
        count(plan.postures.len(), "posture")
    );
    Ok(())
}

/// Asks the user to place the board at `xyz` and press Enter, showing meanwhile how many of
/// its corners each camera finds.
fn wait_for_board(
    cams: &mut dyn crate::track::frames::FrameSource,
    head: &dyn crate::track::servo_head::ServoHead,
    board: &Board,
    xyz: [f64; 3],
    k: usize,
    n: usize,
) -> Result<()> {
    use std::sync::mpsc::{channel, TryRecvError};
    eprintln!(
        "placement {k} of {n}: put the board's centre at x = {}, y = {}, z = {} cm (upright, facing the head), then press Enter",
        xyz[0], xyz[1], xyz[2]
    );
    let (tx, rx) = channel();
    std::thread::spawn(move || {
        let mut line = String::new();
        let _ = tx.send(std::io::stdin().read_line(&mut line));
    });
    let all = (board.cols * board.rows) as usize;
    loop {
        match rx.try_recv() {
            Ok(Ok(0)) | Err(TryRecvError::Disconnected) => {
                bail!("standard input closed before the board was placed (placement {k})")
            }
            Ok(Ok(_)) => return Ok(()),
            Ok(Err(e)) => bail!("reading standard input: {e}"),
            Err(TryRecvError::Empty) => {}
        }
        let f = cams.grab(head.time_s(), &head.joints())?;
        let [l, r] = collect::corners_seen(&f.left, &f.right, board);
        eprint!("\r  corners seen: left {l}/{all}, right {r}/{all}   ");
    }
}
