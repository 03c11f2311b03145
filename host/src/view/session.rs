//! What one `hvs view` serves: the model (with what `hvs info` says about it), the frames
//! ([`super::frames`]) and, for a capture set, its detection; and the two actions the page
//! asks for, each a call of the function the CLI uses: [`Session::locate`] is
//! `hvs locate --at` ([`crate::depth::locate_in`] on the pair's kept depth), [`Session::retrain`] is
//! `hvs board detect` + `hvs train` on the ticked pairs ([`crate::train::model::train_table`]);
//! [`Session::depth`], the dense depth of a pair, is `hvs depth --thorough --colour`
//! ([`crate::depth`]), the matches `hvs locate` answers from.

use super::frames::{PairStore, StillFrames, StillPair};
use super::live::{Goal, HeadState, LiveHead};
use crate::data::captures::{self, CaptureSet};
use crate::data::csv::{read_set_from, Inputs};
use crate::data::model::ModelFile;
use crate::track;
use crate::track::servo_head::HeadChoice;
use crate::train::model::{train_table, Plan};
use crate::train::{self, TrainConfig};
use crate::vision::{self, Detection, Located, PairOutcome};
use anyhow::{anyhow, Result};
use hvs_vision::board::Board;
use std::path::{Path, PathBuf};
use std::sync::{Arc, OnceLock};
use std::time::Instant;

/// What to show.
#[derive(Debug, Clone)]
pub enum Source {
    /// One still stereo pair (`--left L --right R`).
    Pair {
        /// The left image.
        left: PathBuf,
        /// The right image.
        right: PathBuf,
    },
    /// A capture set (`--board BOARD.json --captures CAPTURES.csv`).
    Captures {
        /// The board.
        board: PathBuf,
        /// The captures.
        captures: PathBuf,
    },
    /// The virtual head in a scene, live (`--scene SCENE.json`).
    Scene {
        /// The scene file (`hvs track`'s).
        scene: PathBuf,
        /// Seed of the cameras' sensor noise.
        seed: u64,
        /// The head the cameras stand on: emulated, or the firmware in QEMU (`--head qemu`).
        head: HeadChoice,
    },
    /// Real cameras on no head, live (`--cameras v4l:A,B`).
    Cameras {
        /// The two devices.
        spec: track::cameras::CameraSpec,
        /// Their image size (`None`: the model's, else 640 x 480).
        size: Option<(u32, u32)>,
        /// The head they stand on (`--port`), or `None`: no head.
        port: Option<crate::device::link::Endpoint>,
    },
}

/// How a retrain trains (the `hvs train` options it takes; the rest are its defaults).
#[derive(Debug, Clone, Copy)]
pub struct RetrainOptions {
    /// Restarts (`hvs train --restarts`; `None`: its default for the set,
    /// [`train::default_size`]).
    pub restarts: Option<usize>,
    /// Seed (`hvs train --seed`).
    pub seed: u64,
}

/// One pair as the page lists it.
#[derive(Debug, Clone)]
pub struct PairMeta {
    /// A short name: the image file names.
    pub name: String,
    /// The board depth (cm) a capture gives.
    pub z: Option<f64>,
}

/// A capture set and its detection.
pub struct CaptureData {
    /// The board.
    pub board: Board,
    /// The captures, as read.
    pub set: CaptureSet,
    /// What `hvs board detect` found.
    pub detection: Detection,
}

/// Everything `hvs view` serves.
pub struct Session {
    /// The model file, as given.
    pub model_path: PathBuf,
    /// The model.
    pub model: ModelFile,
    /// What `hvs info` prints about it.
    pub info: String,
    /// Why a click cannot be located (a posture-aware model), if it cannot.
    pub locate_refused: Option<String>,
    /// The pictures.
    pub frames: Arc<dyn PairStore>,
    /// The pairs, in order.
    pub pairs: Vec<PairMeta>,
    /// The capture set, with `--captures`.
    pub captures: Option<CaptureData>,
    /// How a retrain trains.
    pub retrain: RetrainOptions,
    /// Each pair's depth map, computed when first asked for (a live source's, every time).
    depth: Vec<OnceLock<Result<Arc<DepthView>, Refused>>>,
    /// The virtual head of a live scene.
    pub head: Option<Arc<LiveHead>>,
}

/// A pair's dense depth as the page shows it.
#[derive(Debug, Clone)]
pub struct DepthView {
    /// The colour-mapped depth image with its legend (PNG; `hvs depth --thorough --colour`).
    pub png: Arc<Vec<u8>>,
    /// The depth itself (the count with a depth, the depth box, the disparities searched,
    /// the warnings), whose matches clicks are located in.
    pub depth: crate::depth::Depth,
    /// Time it took (ms).
    pub ms: f64,
    /// The left image the depth is of (the cloud's grey levels).
    left: Arc<image::GrayImage>,
    /// The point cloud (PLY, `hvs depth --thorough --ply`), made when first asked for.
    cloud: OnceLock<Result<Arc<Vec<u8>>, String>>,
}

impl DepthView {
    /// The pair's point cloud as `hvs depth --thorough --ply` writes it (binary PLY, grey
    /// levels).
    pub fn cloud(&self) -> Result<Arc<Vec<u8>>, Refused> {
        self.cloud
            .get_or_init(|| self.depth.cloud(&self.left).map(Arc::new).map_err(|e| e.to_string()))
            .clone()
            .map_err(Refused::Unprocessable)
    }
}

/// What a retrain gave.
#[derive(Debug, Clone)]
pub struct Retrained {
    /// Pairs trained on (ticked and detected).
    pub pairs: usize,
    /// Training points.
    pub points: usize,
    /// Training e_ma (%).
    pub train_error_pct: f64,
    /// What `hvs train` prints ([`crate::train::model::summary`]).
    pub summary: String,
}

/// Why an action was refused: the request (`Bad`, `NotFound`, 4xx) or the inputs
/// (`Unprocessable`).
#[derive(Debug, Clone, PartialEq)]
pub enum Refused {
    /// A bad pixel, a ticked list of the wrong length, not a capture set.
    Bad(String),
    /// No such pair (404, as `/api/frame` of one).
    NotFound(String),
    /// The request is well formed but cannot be done with these inputs.
    Unprocessable(String),
    /// The live head cannot take it now (its latest frame failed).
    Unavailable(String),
}

impl Session {
    /// Reads the model and the source (and detects the board in a capture set). Errors name
    /// the file.
    pub fn open(model_path: &Path, source: &Source, retrain: RetrainOptions) -> Result<Session> {
        let (model, locate_refused) = match vision::load_stereo_model(model_path) {
            Ok(m) => (m, None),
            Err(e) => (crate::data::model::load(model_path)?, Some(format!("{e:#}"))),
        };
        let info = train::describe::describe(model_path, &model);
        let (frames, pairs, captures, head): (Arc<dyn PairStore>, _, _, _) = match source {
            Source::Pair { left, right } => {
                let (l, r) = vision::read_pair(left, right)?;
                // Every click and the depth would be refused: say so at the start.
                crate::depth::check_pair_size(model_path, &model.blob, left, l.dimensions())?;
                let name = format!("{} | {}", file_name(left), file_name(right));
                (
                    Arc::new(StillFrames::new(vec![StillPair::new(Some([l, r]), None)])),
                    vec![PairMeta { name, z: None }],
                    None,
                    None,
                )
            }
            Source::Captures { board, captures } => {
                let b = Board::from_path(board).map_err(|e| anyhow!("{e}"))?;
                let set = captures::read(captures)?;
                let (detection, images) = vision::detect_set_with_images(&b, &set, &|| {})?;
                let frames = detection
                    .outcomes
                    .iter()
                    .zip(images)
                    .map(|(o, img)| {
                        let corners = match o {
                            PairOutcome::Found(p) => Some(p.clone()),
                            PairOutcome::Skipped(_) => None,
                        };
                        StillPair::new(img, corners)
                    })
                    .collect();
                let pairs = set
                    .captures
                    .iter()
                    .map(|c| PairMeta {
                        name: format!("{} | {}", c.left_name, c.right_name),
                        z: c.z,
                    })
                    .collect();
                (
                    Arc::new(StillFrames::new(frames)),
                    pairs,
                    Some(CaptureData { board: b, set, detection }),
                    None,
                )
            }
            Source::Scene { scene, seed, head } => {
                let loaded = track::scene_file::load(scene)?;
                let estimator = track::estimator_of(model.blob.clone())
                    .map_err(|e| anyhow!("{}: {e}", model_path.display()))?;
                let cameras = loaded.cameras(*seed);
                let size = loaded.image_size();
                crate::depth::check_pair_size(model_path, &model.blob, scene, size)?;
                let who = match head {
                    HeadChoice::Qemu(_) => "head firmware in QEMU",
                    _ => "virtual head",
                };
                let head = track::servo_head::open(head, model_path)?;
                let live = LiveHead::start(
                    Box::new(cameras),
                    size,
                    estimator,
                    Some((head, track::loop_config(&loaded.rig, track::DEFAULT_CORRECTION_GAIN))),
                    loaded.scene.camera_fps,
                )
                .map_err(|e| anyhow!("{}: {e:#}", scene.display()))?;
                let name = format!("{who}: {}", file_name(scene));
                (
                    live.clone() as Arc<dyn PairStore>,
                    vec![PairMeta { name, z: None }],
                    None,
                    Some(live),
                )
            }
            Source::Cameras { spec, size, port } => {
                let estimator = track::estimator_of(model.blob.clone())
                    .map_err(|e| anyhow!("{}: {e}", model_path.display()))?;
                let size = track::cameras::size_for(*size, Some(&model.blob));
                let cameras = track::cameras::open(spec, size)?;
                // With no head the cameras stay where they are (the home posture); frames as
                // fast as the cameras give them.
                let head = match port {
                    Some(p) => Some((
                        track::servo_head::open(
                            &track::servo_head::HeadChoice::Port(p.clone()),
                            model_path,
                        )?,
                        track::loop_config_for_cameras(
                            &model.blob,
                            size,
                            track::DEFAULT_CORRECTION_GAIN,
                        ),
                    )),
                    None => None,
                };
                let live = LiveHead::start(cameras, size, estimator, head, 240.0)?;
                let on = port.as_ref().map_or(String::new(), |p| format!(" on the head at {p}"));
                let name =
                    format!("cameras: {} | {}{on}", spec.left.display(), spec.right.display());
                (
                    live.clone() as Arc<dyn PairStore>,
                    vec![PairMeta { name, z: None }],
                    None,
                    Some(live),
                )
            }
        };
        let depth = (0..pairs.len()).map(|_| OnceLock::new()).collect();
        Ok(Session {
            depth,
            model_path: model_path.to_path_buf(),
            model,
            info,
            locate_refused,
            frames,
            head,
            pairs,
            captures,
            retrain,
        })
    }

    /// Refuses (`NotFound`) a pair number the session does not have.
    pub fn check_pair(&self, pair: usize) -> Result<(), Refused> {
        if pair < self.frames.len() {
            Ok(())
        } else {
            Err(no_such_pair(pair))
        }
    }

    /// The capture set a retrain trains on; a still pair or a live head has none (`Bad`).
    pub fn capture_set(&self) -> Result<&CaptureData, Refused> {
        self.captures.as_ref().ok_or_else(|| {
            Refused::Bad("not a capture set: start hvs view with --board and --captures".into())
        })
    }

    /// `hvs locate --at U,V` on pair `pair`: the left pixel `(u, v)` found in the right image
    /// and turned into X, Y, Z by the model.
    pub fn locate(&self, pair: usize, u: f64, v: f64) -> Result<Located, Refused> {
        if let Some(why) = &self.locate_refused {
            return Err(Refused::Unprocessable(why.clone()));
        }
        self.check_pair(pair)?;
        let (l, _) = self.frames.grey(pair).ok_or_else(|| unreadable(pair))?;
        check_pixel(u, v, l.dimensions())?;
        // The pair's dense matches (kept for a still pair), as `hvs locate` finds its points.
        let d = self.depth(pair)?;
        let found = crate::depth::locate_in(&d.depth, &self.model.blob, &[[u, v]])
            .map_err(|e| Refused::Unprocessable(format!("{}: {e:#}", self.model_path.display())))?;
        found.into_iter().next().ok_or_else(|| Refused::Unprocessable("no result".into()))
    }

    /// `hvs depth --thorough --colour` on pair `pair` ([`crate::depth::depth`] with
    /// [`crate::depth::locate_params`], so that a click answers what `hvs locate` would):
    /// computed once per still pair, then kept; a live pair's every time.
    pub fn depth(&self, pair: usize) -> Result<Arc<DepthView>, Refused> {
        if let Some(why) = &self.locate_refused {
            return Err(Refused::Unprocessable(why.clone()));
        }
        self.check_pair(pair)?;
        let cell = self.depth.get(pair).ok_or_else(|| no_such_pair(pair))?;
        let compute = || {
            let (l, r) = self.frames.grey(pair).ok_or_else(|| unreadable(pair))?;
            let t0 = Instant::now();
            let d = crate::depth::depth(&self.model.blob, &l, &r, &crate::depth::locate_params())
                .map_err(|e| {
                Refused::Unprocessable(format!("{}: {e:#}", self.model_path.display()))
            })?;
            let png = crate::vision::png_bytes_fast(&d.colour())
                .map_err(|e| Refused::Unprocessable(format!("{e:#}")))?;
            Ok(Arc::new(DepthView {
                png: Arc::new(png),
                ms: t0.elapsed().as_secs_f64() * 1e3,
                depth: d,
                left: l,
                cloud: OnceLock::new(),
            }))
        };
        if self.frames.live() {
            return compute();
        }
        cell.get_or_init(compute).clone()
    }

    /// Asks the live head to do `goal`; its state then (the goal applies from the next frame).
    pub fn look(&self, goal: Goal) -> Result<HeadState, Refused> {
        let head = self
            .head
            .as_ref()
            .ok_or_else(|| Refused::Bad("not a live head: start hvs view with --scene".into()))?;
        if !head.moves() {
            return Err(Refused::Bad(
                "these cameras are on no head: nothing to turn (a real head in the loop is not \
                 supported by hvs view yet)"
                    .into(),
            ));
        }
        if let Goal::Pixel([u, v]) = goal {
            check_pixel(u, v, head.size())?;
        }
        head.look(goal)
            .map_err(|e| {
                Refused::Unavailable(format!(
                    "the head's latest frame failed ({e}): nothing was asked of it; try again once it answers"
                ))
            })?
            .ok_or_else(|| Refused::Unprocessable("the head has no frame yet".into()))
    }

    /// `hvs board detect` + `hvs train` (its defaults, [`RetrainOptions`]) on the pairs of the
    /// capture set whose `ticked` entry is true: the detection is the one made at start (its
    /// set-wide checks included); unticked pairs are left out of the points.
    pub fn retrain(&self, ticked: &[bool]) -> Result<Retrained, Refused> {
        let c = self.capture_set()?;
        if ticked.len() != c.set.captures.len() {
            return Err(Refused::Bad(format!(
                "{} ticks for {} pairs",
                ticked.len(),
                c.set.captures.len()
            )));
        }
        let mut det = c.detection.clone();
        for (o, &t) in det.outcomes.iter_mut().zip(ticked) {
            if !t {
                *o = PairOutcome::Skipped("unticked".into());
            }
        }
        let pairs = det.usable();
        if pairs == 0 {
            return Err(Refused::Unprocessable("no ticked pair has detected corners".into()));
        }
        let name = format!("{} (ticked pairs)", c.set.path.display());
        let points = vision::points_csv(&c.board, &c.set, &det);
        let table = read_set_from(Path::new(&name), points.as_bytes(), Inputs::Auto, true)
            .map_err(|e| Refused::Unprocessable(format!("{e:#}")))?;
        let defaults = TrainConfig::for_set(train::DEFAULT_FAMILY, &table.data, table.image_size);
        let config = TrainConfig {
            restarts: self.retrain.restarts.unwrap_or(defaults.restarts),
            seed: self.retrain.seed,
            ..defaults
        };
        let plan = Plan { config, ..Plan::default() };
        let t = train_table(&table, &plan).map_err(|e| Refused::Unprocessable(format!("{e:#}")))?;
        Ok(Retrained {
            pairs,
            points: table.data.len(),
            train_error_pct: t.outcome.train_error_pct,
            summary: crate::train::model::summary(&name, &t),
        })
    }
}

/// Pair `pair` is not one of the session's.
pub fn no_such_pair(pair: usize) -> Refused {
    Refused::NotFound(format!("pair {pair}: no such pair"))
}

/// Pair `pair` has no images to match: unreadable files, or a live source with no frame yet.
fn unreadable(pair: usize) -> Refused {
    Refused::Bad(format!("pair {pair}: its images are unreadable, or there is no frame yet"))
}

/// Refuses a left pixel that is not finite or lies outside a `w x h` image (pixel-centre
/// convention: from -0.5 to the size - 0.5), for a click and for a look.
fn check_pixel(u: f64, v: f64, (w, h): (u32, u32)) -> Result<(), Refused> {
    if crate::depth::inside_image(u, v, (w, h)) {
        Ok(())
    } else {
        Err(Refused::Bad(format!(
            "pixel ({}, {}) is outside the {w}x{h} left image",
            crate::fmt::given(u),
            crate::fmt::given(v)
        )))
    }
}

fn file_name(p: &Path) -> String {
    p.file_name().map_or_else(|| p.display().to_string(), |n| n.to_string_lossy().into_owned())
}
