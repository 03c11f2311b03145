//! The live source of `hvs view --scene` and `hvs view --cameras`: the virtual head in the
//! loop on the wall clock, or real cameras on no head. A thread grabs a frame from the
//! cameras (the virtual ones, [`crate::track::frames::VirtualCameras`], at the servos'
//! posture; or real ones, [`crate::track::cameras`]) every camera frame (the scene's
//! `camera_fps`, or as fast as the cameras allow), runs the loop's frame
//! ([`crate::track::Tracker::frame`], the one `hvs track` runs) while the page has asked the
//! head to look at something, and keeps the latest pair and the head's state for the page.
//! [`LiveHead`] is the page's [`PairStore`]: one pair, live.

use super::frames::{Frame, GreyPair, PairStore, View};
use crate::track::frames::FrameSource;
use crate::track::servo_head::ServoHead;
use crate::track::target::TargetMode;
use crate::track::Tracker;
use crate::vision::png_bytes_fast;
use hvs_shared::runtime::fixation::LoopConfig;
use hvs_shared::runtime::gaze::Joints;
use hvs_shared::runtime::head::Estimator;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, OnceLock};
use std::time::{Duration, Instant};

/// What the head is asked to do.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Goal {
    /// Hold still where it is (at start: at home).
    Idle,
    /// Look at the object under this left pixel, then follow it.
    Pixel([f64; 2]),
    /// Look at the nearest object in the front region and follow it.
    Nearest,
    /// Go home and hold.
    Home,
}

/// The head's state after the latest frame.
#[derive(Debug, Clone, PartialEq)]
pub struct HeadState {
    /// Seconds since the head started, at the latest frame or failed attempt at one.
    pub t_s: f64,
    /// Frames grabbed so far.
    pub frames: u64,
    /// What it was asked to do.
    pub goal: Goal,
    /// `idle`, or the loop's status: `tracking`, `image_only`, `lost`.
    pub status: &'static str,
    /// The joints when the latest frame was taken (degrees).
    pub joints: Joints,
    /// Whether the servos are still moving (as the head last told, also after a failed frame).
    pub moving: bool,
    /// The target's pixels in the latest frame (`u_l, v_l, u_r, v_r`).
    pub target_px: Option<[f64; 4]>,
    /// The loop's estimate of the target (cm, head frame).
    pub xyz: Option<[f32; 3]>,
    /// With the scene's truth: each image's distance from its centre to the tracked
    /// object's true centre (px).
    pub err_px: Option<[f64; 2]>,
    /// Frames per second over the last second or so.
    pub fps: f64,
    /// The right camera's scale against the left one's, once the loop has measured it
    /// ([`Tracker::right_scale`]; from the first frame of a look).
    pub right_scale: Option<f64>,
    /// The latest frame error (the cameras could not render), if any.
    pub error: Option<String>,
}

struct Latest {
    seq: u64,
    grey: GreyPair,
    png: [OnceLock<Option<Arc<Vec<u8>>>>; 2],
    state: HeadState,
}

/// How many of the latest frames a [`LiveHead`] keeps for [`PairStore::frame_at`].
const KEPT: usize = 4;

/// The virtual head in the loop, running on its own thread until dropped.
pub struct LiveHead {
    /// The latest frames, newest last (at most [`KEPT`]).
    latest: Mutex<std::collections::VecDeque<Arc<Latest>>>,
    goal: Mutex<Option<Goal>>,
    stop: AtomicBool,
    size: (u32, u32),
    moves: bool,
}

impl LiveHead {
    /// Starts with `cameras` (images of `size`) on `head` (any [`ServoHead`], at home), whose
    /// loop (`hvs track`'s) runs with the given settings, or with `None` no head (the cameras
    /// stay where they are, taken to be at the home posture). `estimator` is the loop's. Returns
    /// once the first frame is there (or its error).
    pub fn start(
        cameras: Box<dyn FrameSource + Send>,
        size: (u32, u32),
        estimator: Estimator,
        head: Option<(Box<dyn ServoHead + Send>, LoopConfig)>,
        fps: f64,
    ) -> anyhow::Result<Arc<LiveHead>> {
        let moves = head.is_some();
        let live = Arc::new(LiveHead {
            latest: Mutex::new(Default::default()),
            goal: Mutex::new(None),
            stop: AtomicBool::new(false),
            size,
            moves,
        });
        let weak = Arc::downgrade(&live);
        let (first_tx, first_rx) = std::sync::mpsc::channel();
        std::thread::Builder::new()
            .name("hvs-view-head".into())
            .spawn(move || run(weak, Loop { cameras, head, estimator, fps }, first_tx))?;
        match first_rx.recv_timeout(Duration::from_secs(60)) {
            Ok(Ok(())) => Ok(live),
            Ok(Err(e)) => Err(anyhow::anyhow!("{e}")),
            Err(_) => Err(anyhow::anyhow!("the cameras gave no first frame within 60 s")),
        }
    }

    /// Asks the head to do `goal` from the next frame on.
    fn set_goal(&self, goal: Goal) {
        *self.goal.lock().unwrap_or_else(|e| e.into_inner()) = Some(goal);
    }

    /// Asks the head to do `goal` from the next frame on, and answers its state, unless its
    /// latest frame failed (a stopped camera, a head link with no answer): then nothing is
    /// asked, and the error is the answer. `Ok(None)`: no frame yet.
    pub fn look(&self, goal: Goal) -> Result<Option<HeadState>, String> {
        if let Some(e) = self.state().and_then(|s| s.error) {
            return Err(e);
        }
        self.set_goal(goal);
        Ok(self.state())
    }

    /// The head's state after the latest frame.
    pub fn state(&self) -> Option<HeadState> {
        self.latest().map(|l| l.state.clone())
    }

    /// The left image's size (px).
    pub fn size(&self) -> (u32, u32) {
        self.size
    }

    /// Whether there is a head to move the cameras (`false`: cameras on no head).
    pub fn moves(&self) -> bool {
        self.moves
    }

    fn latest(&self) -> Option<Arc<Latest>> {
        self.latest.lock().unwrap_or_else(|e| e.into_inner()).back().cloned()
    }

    /// Frame `seq`, if it is one of the [`KEPT`] latest.
    fn kept(&self, seq: u64) -> Option<Arc<Latest>> {
        let kept = self.latest.lock().unwrap_or_else(|e| e.into_inner());
        kept.iter().rev().find(|l| l.seq == seq).cloned()
    }

    fn push(&self, next: Latest) {
        let mut kept = self.latest.lock().unwrap_or_else(|e| e.into_inner());
        // A failed grab keeps the last pair's number: it replaces it.
        if kept.back().is_some_and(|l| l.seq == next.seq) {
            kept.pop_back();
        }
        kept.push_back(Arc::new(next));
        while kept.len() > KEPT {
            kept.pop_front();
        }
    }
}

impl Drop for LiveHead {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
    }
}

impl PairStore for LiveHead {
    fn len(&self) -> usize {
        1
    }

    fn live(&self) -> bool {
        true
    }

    fn frame(&self, pair: usize, view: View) -> Option<Frame> {
        self.latest()?.encoded(pair, view)
    }

    fn frame_at(&self, pair: usize, view: View, seq: u64) -> Option<Frame> {
        self.kept(seq)?.encoded(pair, view)
    }

    fn latest_seq(&self) -> u64 {
        self.latest().map_or(0, |l| l.seq)
    }

    fn kept_seqs(&self) -> Option<(u64, u64)> {
        let kept = self.latest.lock().unwrap_or_else(|e| e.into_inner());
        Some((kept.front()?.seq, kept.back()?.seq))
    }

    fn grey(&self, pair: usize) -> Option<GreyPair> {
        (pair == 0).then(|| self.latest().map(|l| l.grey.clone()))?
    }
}

impl Latest {
    /// Its `view` of pair `pair` (only pair 0, left or right), encoded once when first asked.
    fn encoded(&self, pair: usize, view: View) -> Option<Frame> {
        let side = match (pair, view) {
            (0, View::Left) => 0,
            (0, View::Right) => 1,
            _ => return None,
        };
        let png = self.png[side]
            .get_or_init(|| {
                let img = if side == 0 { &self.grey.0 } else { &self.grey.1 };
                png_bytes_fast(&**img).ok().map(Arc::new)
            })
            .clone()?;
        Some(Frame { seq: self.seq, png })
    }
}

/// What the head's thread owns.
struct Loop {
    cameras: Box<dyn FrameSource + Send>,
    /// The head and its loop's settings (`None`: cameras on no head).
    head: Option<(Box<dyn ServoHead + Send>, LoopConfig)>,
    estimator: Estimator,
    fps: f64,
}

/// The head's thread: a frame every `1 / fps` s of the wall clock (or as soon as the last one
/// is done when rendering is slower), until the [`LiveHead`] is dropped or stopped.
fn run(
    live: std::sync::Weak<LiveHead>,
    mut lp: Loop,
    first: std::sync::mpsc::Sender<Result<(), String>>,
) {
    let start = Instant::now();
    let period = 1.0 / lp.fps.clamp(1.0, 240.0);
    let (mut goal, mut tracker) = (Goal::Idle, None::<Tracker>);
    let mut times: std::collections::VecDeque<f64> = Default::default();
    let mut first = Some(first);
    let mut seq = 0u64;
    loop {
        let Some(me) = live.upgrade() else { return };
        if me.stop.load(Ordering::SeqCst) {
            return;
        }
        let mut failed = None;
        if let Some(g) = me.goal.lock().unwrap_or_else(|e| e.into_inner()).take() {
            goal = g;
            if let Some((head, cfg)) = lp.head.as_mut() {
                tracker = match g {
                    Goal::Pixel(px) => Some(Tracker::new(TargetMode::Pixel(px), *cfg)),
                    Goal::Nearest => Some(Tracker::new(TargetMode::Nearest, *cfg)),
                    Goal::Idle | Goal::Home => None,
                };
                if g == Goal::Home {
                    failed = head.command(&Joints::HOME).err();
                }
            }
        }
        // The frame's time: the wall clock's, or the head's own where it keeps one (it is
        // not waited for: see `ServoHead::own_clock`).
        let wall = start.elapsed().as_secs_f64();
        let t = match lp.head.as_ref() {
            Some((h, _)) if h.own_clock() => h.time_s(),
            _ => wall,
        };
        let grabbed = match (failed, tracker.as_mut(), lp.head.as_mut().map(|(h, _)| h)) {
            (Some(e), _, _) => Err(e),
            (None, Some(tr), Some(head)) => tr
                .frame(&mut *lp.cameras, &mut **head, &lp.estimator, t)
                .map(|(f, row)| (f, row.status, row.joints, row.px, row.xyz, row.err_px)),
            (None, _, head) => {
                let advanced = match head {
                    Some(head) => head.advance_to(t).map(|()| head.joints()),
                    None => Ok(Joints::HOME),
                };
                advanced.and_then(|joints| {
                    lp.cameras.grab(t, &joints).map(|f| (f, "idle", joints, None, None, None))
                })
            }
        };
        let previous = me.latest();
        let next = match grabbed {
            Ok((frame, status, joints, target_px, xyz, err_px)) => {
                times.push_back(wall);
                while times.len() > 2 && wall - times[0] > 1.0 {
                    times.pop_front();
                }
                let fps = if times.len() > 1 {
                    (times.len() - 1) as f64 / (wall - times[0]).max(1e-6)
                } else {
                    0.0
                };
                seq += 1;
                Latest {
                    seq,
                    grey: (Arc::new(frame.left), Arc::new(frame.right)),
                    png: Default::default(),
                    state: HeadState {
                        t_s: t,
                        frames: seq,
                        goal,
                        status,
                        joints,
                        moving: lp.head.as_ref().is_some_and(|(h, _)| h.is_moving()),
                        target_px,
                        xyz,
                        err_px,
                        fps,
                        right_scale: tracker.as_ref().and_then(Tracker::right_scale),
                        error: None,
                    },
                }
            }
            Err(e) => {
                let msg = format!("{e:#}");
                if let Some(tx) = first.take() {
                    let _ = tx.send(Err(msg));
                    return;
                }
                let Some(p) = previous else { return };
                let mut state = p.state.clone();
                // No frame since: none a second. The time and the servos' motion are the
                // head's own (as of its last answer, for a head on a link), not the last
                // frame's.
                (state.error, state.fps, state.t_s) = (Some(msg), 0.0, t);
                if let Some((h, _)) = lp.head.as_ref() {
                    state.moving = h.is_moving();
                }
                times.clear();
                Latest { seq: p.seq, grey: p.grey.clone(), png: Default::default(), state }
            }
        };
        me.push(next);
        if let Some(tx) = first.take() {
            let _ = tx.send(Ok(()));
        }
        drop(me);
        // The next frame at the next multiple of the period (none skipped when behind).
        let next_t = ((wall / period).floor() + 1.0) * period;
        let wait = next_t - start.elapsed().as_secs_f64();
        if wait > 0.0 {
            std::thread::sleep(Duration::from_secs_f64(wait));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::track::frames::Frame as Pair;
    use hvs_shared::runtime::blob::{InputKind, OutputKind};
    use image::GrayImage;
    use std::sync::atomic::AtomicU64;

    /// Cameras whose frames carry their number in the first pixel, and that give errors
    /// while `broken` is set (a camera that stops, then comes back).
    struct Fake {
        grabs: Arc<AtomicU64>,
        broken: Arc<AtomicBool>,
    }

    impl FrameSource for Fake {
        fn grab(&mut self, _t_s: f64, joints: &Joints) -> anyhow::Result<Pair> {
            assert_eq!(*joints, Joints::HOME, "cameras on no head stay at home");
            if self.broken.load(Ordering::SeqCst) {
                anyhow::bail!("/dev/video9: no frame within 2 s");
            }
            let n = self.grabs.fetch_add(1, Ordering::SeqCst);
            let mut left = GrayImage::new(32, 24);
            left.as_mut()[0] = (n % 256) as u8;
            Ok(Pair { right: left.clone(), left, truth: None })
        }
    }

    fn wait_for(what: &str, mut ok: impl FnMut() -> bool) {
        let start = Instant::now();
        while !ok() {
            assert!(start.elapsed() < Duration::from_secs(20), "waited 20 s for {what}");
            std::thread::sleep(Duration::from_millis(5));
        }
    }

    #[test]
    fn cameras_on_no_head_stream_report_a_stop_and_recover() {
        let (grabs, broken) = (Arc::new(AtomicU64::new(0)), Arc::new(AtomicBool::new(false)));
        let fake = Fake { grabs: grabs.clone(), broken: broken.clone() };
        let blob = crate::infer::tests::blob(5, OutputKind::Xyz, InputKind::Stereo);
        let estimator = crate::track::estimator_of(blob).unwrap();
        let live = LiveHead::start(Box::new(fake), (32, 24), estimator, None, 240.0).unwrap();
        assert!(!live.moves() && live.size() == (32, 24));
        wait_for("five frames", || live.state().is_some_and(|s| s.frames >= 5));
        let s = live.state().unwrap();
        assert_eq!(
            (s.status, s.joints, s.moving, s.error.is_none()),
            ("idle", Joints::HOME, false, true)
        );
        // A goal is ignored without a head (the session refuses it before it gets here).
        live.set_goal(Goal::Nearest);
        // The camera stops: the last pair stays, the error is reported.
        broken.store(true, Ordering::SeqCst);
        wait_for("the error", || live.state().is_some_and(|s| s.error.is_some()));
        let stopped = live.state().unwrap();
        assert!(stopped.error.as_deref().unwrap().contains("/dev/video9"), "{stopped:?}");
        assert_eq!(stopped.status, "idle");
        let seq = stopped.frames;
        // It comes back: new frames, no error.
        broken.store(false, Ordering::SeqCst);
        wait_for("new frames", || {
            live.state().is_some_and(|s| s.error.is_none() && s.frames > seq)
        });
        assert!(live.grey(0).is_some() && live.frame(0, View::Left).is_some());
        drop(live);
        // The thread stops once the head is dropped: no more grabs.
        std::thread::sleep(Duration::from_millis(50));
        let after = grabs.load(Ordering::SeqCst);
        std::thread::sleep(Duration::from_millis(100));
        assert_eq!(grabs.load(Ordering::SeqCst), after);
    }

    /// A head for the tests: its clock `lag_s` behind the wall clock, its own (`own`: a head
    /// on a link, waited for like a real one) or the loop's, and its motion set by the test.
    struct TestHead {
        start: Instant,
        lag_s: f64,
        own: bool,
        moving: Arc<AtomicBool>,
    }

    impl TestHead {
        fn boxed(lag_s: f64, own: bool, moving: Arc<AtomicBool>) -> Box<dyn ServoHead + Send> {
            Box::new(TestHead { start: Instant::now(), lag_s, own, moving })
        }
    }

    impl ServoHead for TestHead {
        fn advance_to(&mut self, t_s: f64) -> anyhow::Result<()> {
            while self.time_s() < t_s {
                std::thread::sleep(Duration::from_millis(1));
            }
            Ok(())
        }
        fn command(&mut self, _goal: &Joints) -> anyhow::Result<()> {
            Ok(())
        }
        fn joints(&self) -> Joints {
            Joints::HOME
        }
        fn is_moving(&self) -> bool {
            self.moving.load(Ordering::SeqCst)
        }
        fn time_s(&self) -> f64 {
            (self.start.elapsed().as_secs_f64() - self.lag_s).max(0.0)
        }
        fn control_hz(&self) -> u32 {
            1000
        }
        fn frame_time(&self, t_s: f64) -> f64 {
            if self.own {
                self.time_s()
            } else {
                t_s
            }
        }
        fn own_clock(&self) -> bool {
            self.own
        }
    }

    /// A head whose clock lags the wall clock is not waited for: frames come at the scene's
    /// rate. Before, every frame waited out the lag (a frame a second here; `hvs view --head
    /// qemu` sank to 2 frames/s).
    #[test]
    fn a_head_on_a_late_clock_is_not_waited_for() {
        let (grabs, broken) = (Arc::new(AtomicU64::new(0)), Arc::new(AtomicBool::new(false)));
        let fake = Fake { grabs: grabs.clone(), broken };
        let blob = crate::infer::tests::blob(5, OutputKind::Xyz, InputKind::Stereo);
        let estimator = crate::track::estimator_of(blob).unwrap();
        // A second behind the wall clock, as QEMU's on a busy machine.
        let head = TestHead::boxed(1.0, true, Arc::new(AtomicBool::new(false)));
        let cfg = LoopConfig::DEFAULT;
        let live =
            LiveHead::start(Box::new(fake), (32, 24), estimator, Some((head, cfg)), 60.0).unwrap();
        let t0 = Instant::now();
        wait_for("twenty frames", || live.state().is_some_and(|s| s.frames >= 20));
        assert!(t0.elapsed() < Duration::from_secs(3), "{:?}", t0.elapsed());
    }

    /// While the cameras fail, the state's time and the servos' motion stay the head's, not
    /// the last good frame's (they had stood still at its values).
    #[test]
    fn a_stopped_camera_keeps_the_heads_time_and_motion_current() {
        let (grabs, broken) = (Arc::new(AtomicU64::new(0)), Arc::new(AtomicBool::new(false)));
        let fake = Fake { grabs, broken: broken.clone() };
        let blob = crate::infer::tests::blob(5, OutputKind::Xyz, InputKind::Stereo);
        let estimator = crate::track::estimator_of(blob).unwrap();
        let moving = Arc::new(AtomicBool::new(false));
        let head = TestHead::boxed(0.0, false, moving.clone());
        let cfg = LoopConfig::DEFAULT;
        let live =
            LiveHead::start(Box::new(fake), (32, 24), estimator, Some((head, cfg)), 240.0).unwrap();
        wait_for("three frames", || live.state().is_some_and(|s| s.frames >= 3));
        broken.store(true, Ordering::SeqCst);
        wait_for("the error", || live.state().is_some_and(|s| s.error.is_some()));
        let first = live.state().unwrap();
        assert!(!first.moving, "{first:?}");
        moving.store(true, Ordering::SeqCst);
        wait_for("the motion and a later time", || {
            live.state().is_some_and(|s| s.moving && s.t_s > first.t_s + 0.02)
        });
        let s = live.state().unwrap();
        assert_eq!((s.frames, s.error.is_some(), s.fps), (first.frames, true, 0.0), "{s:?}");
        // Nothing is asked of a head whose frames fail; once they come again, it is.
        let refused = live.look(Goal::Home).unwrap_err();
        assert!(refused.contains("/dev/video9"), "{refused}");
        assert!(live.goal.lock().unwrap().is_none());
        broken.store(false, Ordering::SeqCst);
        wait_for("a frame", || live.state().is_some_and(|s| s.error.is_none()));
        assert!(live.look(Goal::Nearest).unwrap().is_some());
        wait_for("the goal", || live.state().is_some_and(|s| s.goal == Goal::Nearest));
    }

    /// The first pixel of a frame's PNG (the fake camera's frame number).
    fn first_pixel(f: &Frame) -> u8 {
        image::load_from_memory(&f.png).unwrap().to_luma8().as_raw()[0]
    }

    #[test]
    fn the_last_frames_are_kept_by_number() {
        let (grabs, broken) = (Arc::new(AtomicU64::new(0)), Arc::new(AtomicBool::new(false)));
        let fake = Fake { grabs: grabs.clone(), broken: broken.clone() };
        let blob = crate::infer::tests::blob(5, OutputKind::Xyz, InputKind::Stereo);
        let estimator = crate::track::estimator_of(blob).unwrap();
        let live = LiveHead::start(Box::new(fake), (32, 24), estimator, None, 240.0).unwrap();
        wait_for("ten frames", || live.latest_seq() >= 10);
        // A stopped camera keeps the frames still (its errors replace no kept frame).
        broken.store(true, Ordering::SeqCst);
        wait_for("the error", || live.state().is_some_and(|s| s.error.is_some()));
        let newest = live.latest_seq();
        // Frame `seq` is grab `seq - 1`: the last KEPT are given by number, left and right.
        for seq in newest + 1 - KEPT as u64..=newest {
            let (l, r) = (live.frame_at(0, View::Left, seq), live.frame_at(0, View::Right, seq));
            let (l, r) = (l.unwrap(), r.unwrap());
            assert_eq!((l.seq, r.seq), (seq, seq));
            assert_eq!(first_pixel(&l), ((seq - 1) % 256) as u8);
        }
        assert_eq!(live.kept_seqs(), Some((newest + 1 - KEPT as u64, newest)));
        // One long gone (or never grabbed): none, never another frame.
        for seq in [0, newest - KEPT as u64, newest + 1] {
            assert!(live.frame_at(0, View::Left, seq).is_none(), "{seq}");
            assert!(live.frame_at(0, View::Right, seq).is_none(), "{seq}");
        }
        assert!(live.frame_at(0, View::LeftCorners, newest).is_none());
        assert!(live.frame_at(1, View::Left, newest).is_none());
        assert!(live.latest.lock().unwrap().len() <= KEPT);
        drop(live);
        // The thread stops once the head is dropped: no more grabs.
        std::thread::sleep(Duration::from_millis(50));
        let after = grabs.load(Ordering::SeqCst);
        std::thread::sleep(Duration::from_millis(100));
        assert_eq!(grabs.load(Ordering::SeqCst), after);
    }
}
