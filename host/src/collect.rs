//! The head collects its own posture-aware training set (`hvs collect`): the board stays where
//! the user put it, the head visits the postures, and every pair in which both cameras see the
//! whole board is a capture with the five joints the head reports.
//!
//! The steps, each its own function so the CLI, the viewer and the tests share them:
//! - [`visit`]: the head's moves on the control clock (any [`ServoHead`], the trajectories the
//!   firmware runs): command the posture, wait until the servos have settled (the controller
//!   says the move is over, then [`Plan::settle_s`] more), read the joints.
//! - [`board_in_view`]: whether the whole board (its outer squares included) projects inside
//!   both images with a margin, before anything is rendered.
//! - [`capture`]: the pair, rendered from the scene with the board in it; refused when
//!   something in the scene hides a corner.
//! - [`captures_csv`]: `CAPTURES.csv` (`left,right,z,x,y` and the five joint columns), the
//!   capture set `hvs board detect` reads.
//!
//! Renders are independent (each pair's sensor noise has its own seed, from the run's seed and
//! the pair's place in the visit), so they run in parallel and the same seed gives the same
//! bytes whatever the thread count.

use crate::data::captures::CaptureRow;
use crate::data::positions::Placement;
use crate::track::frames::mix;
use crate::track::frames::FrameSource;
use crate::track::servo_head::ServoHead;
use anyhow::{anyhow, bail, Result};
use hvs_shared::runtime::gaze::Joints;
use hvs_shared::sim::posture::HeadRig;
use hvs_vision::board::Board;
use hvs_vision::render::RenderOptions;
use hvs_vision::scene::{render_scene, Motion, Object, Scene, Shape, MAX_OBJECTS};
use image::GrayImage;

/// Margin (px) the whole board must keep from every image border to count as seen.
pub const VIEW_MARGIN_PX: f64 = 4.0;

/// Default wait after the controller reports the move over (s).
pub const SETTLE_S: f64 = 0.1;

/// Longest a single move may take before the head is reported stuck (s).
pub const MOVE_TIMEOUT_S: f64 = 10.0;

/// What to collect.
#[derive(Debug, Clone)]
pub struct Plan {
    /// The board the user placed.
    pub board: Board,
    /// Where, one placement after the other.
    pub placements: Vec<Placement>,
    /// The postures the head visits at every placement, in order.
    pub postures: Vec<Joints>,
    /// Blur, noise, supersampling of the virtual cameras.
    pub render: RenderOptions,
    /// Seed of the sensor noise.
    pub seed: u64,
    /// Wait after each move (s).
    pub settle_s: f64,
}

/// One stop of the head: which placement and posture, when, and the joints it reports there.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Stop {
    /// Index into [`Plan::placements`].
    pub placement: usize,
    /// Index into [`Plan::postures`].
    pub posture: usize,
    /// Time of the control clock when the pair is taken (s since start).
    pub t_s: f64,
    /// The joints the head reports (degrees).
    pub joints: Joints,
}

/// Drives `head` through every posture at every placement (placement-major), waiting for the
/// servos to settle at each. Errors if a move does not end within [`MOVE_TIMEOUT_S`].
pub fn visit(head: &mut dyn ServoHead, plan: &Plan) -> Result<Vec<Stop>> {
    let mut stops = Vec::with_capacity(plan.placements.len() * plan.postures.len());
    for placement in 0..plan.placements.len() {
        for posture in 0..plan.postures.len() {
            stops.push(stop_at(head, plan, placement, posture)?);
        }
    }
    Ok(stops)
}

/// Checks a settle time ([`Plan::settle_s`]): 0 to 60 s.
pub fn check_settle(settle_s: f64) -> Result<()> {
    if !(settle_s.is_finite() && (0.0..=60.0).contains(&settle_s)) {
        bail!("the settle time must be 0 to 60 s, got {}", crate::fmt::given(settle_s));
    }
    Ok(())
}

/// Moves `head` to posture `posture` of `plan`, waits until the move has ended and
/// [`Plan::settle_s`] more, and reads its joints.
pub fn stop_at(
    head: &mut dyn ServoHead,
    plan: &Plan,
    placement: usize,
    posture: usize,
) -> Result<Stop> {
    check_settle(plan.settle_s)?;
    let goal = &plan.postures[posture];
    let dt = 1.0 / f64::from(head.control_hz().max(1));
    head.command(goal)?;
    let start = head.time_s();
    // At least one tick: the command is taken at the next control tick.
    head.advance_to(head.time_s() + dt)?;
    while head.is_moving() {
        if head.time_s() - start > MOVE_TIMEOUT_S {
            bail!("the head did not reach posture {:?} within {MOVE_TIMEOUT_S} s", goal.0);
        }
        head.advance_to(head.time_s() + dt)?;
    }
    head.advance_to(head.time_s() + plan.settle_s)?;
    Ok(Stop { placement, posture, t_s: head.time_s(), joints: head.joints() })
}

/// Cameras on a head (real ones, or any [`FrameSource`]): at placement `placement`, visits
/// every posture ([`stop_at`]), grabs a pair there and keeps it when the whole board is
/// detected in both images ([`hvs_vision::detect::detect_pair`]); `on_pair` gets each kept
/// stop with its pair (to write it at once) and the count of postures skipped comes back.
pub fn visit_with_cameras(
    head: &mut dyn ServoHead,
    cameras: &mut dyn FrameSource,
    plan: &Plan,
    placement: usize,
    mut on_pair: impl FnMut(&Stop, &[GrayImage; 2]) -> Result<()>,
) -> Result<usize> {
    let mut skipped = 0;
    for posture in 0..plan.postures.len() {
        let stop = stop_at(head, plan, placement, posture)?;
        let frame = cameras.grab(stop.t_s, &stop.joints)?;
        match hvs_vision::detect::detect_pair(&frame.left, &frame.right, &plan.board) {
            Ok(_) => on_pair(&stop, &[frame.left, frame.right])?,
            Err(_) => skipped += 1,
        }
    }
    Ok(skipped)
}

/// How many of the board's corners each image of a pair shows (what the user watches while
/// placing the board): `[left, right]`, 0 where the board is not found whole.
pub fn corners_seen(left: &GrayImage, right: &GrayImage, board: &Board) -> [usize; 2] {
    [left, right].map(|img| hvs_vision::detect::detect(img, board).map_or(0, |c| c.points.len()))
}

/// The board's outline points in the head frame: its inner corners and the outer corners of
/// its outermost squares, with the centre at `centre`.
fn outline(board: &Board, centre: [f64; 3]) -> Vec<[f64; 3]> {
    let s = board.square_cm;
    let (cols, rows) = (i64::from(board.cols), i64::from(board.rows));
    let mut pts = Vec::with_capacity(((cols + 2) * (rows + 2)) as usize);
    for j in -1..=rows {
        for i in -1..=cols {
            pts.push([
                centre[0] + (i as f64 - (cols as f64 - 1.0) / 2.0) * s,
                centre[1] + (j as f64 - (rows as f64 - 1.0) / 2.0) * s,
                centre[2],
            ]);
        }
    }
    pts
}

/// Whether both cameras of `head` at `joints` see the whole board centred at `centre` (every
/// inner corner and the outer corners of the outer squares in front of the camera and at least
/// [`VIEW_MARGIN_PX`] inside the image).
pub fn board_in_view(head: &HeadRig, joints: &Joints, board: &Board, centre: [f64; 3]) -> bool {
    let (w, h) = (f64::from(head.rig.width), f64::from(head.rig.height));
    let m = VIEW_MARGIN_PX;
    let cams = head.cameras(joints);
    outline(board, centre).iter().all(|p| {
        cams.iter().all(|c| {
            c.project(p).is_some_and(|[u, v]| {
                u >= m - 0.5 && u <= w - 0.5 - m && v >= m - 0.5 && v <= h - 0.5 - m
            })
        })
    })
}

/// `scene` with the board added as its last object, at rest at `centre`.
pub fn with_board(scene: &Scene, board: &Board, centre: [f64; 3]) -> Result<Scene> {
    if scene.objects.len() >= MAX_OBJECTS {
        bail!("the scene has {MAX_OBJECTS} objects already: no room for the board");
    }
    // The board faces the head upright, all of it at the centre's Z: at the wall's depth or
    // behind it the wall hides it (at the same depth every ray meets both, and the render
    // shows the wall; the occlusion test, which compares distances, passed such pairs).
    let wall = scene.background.z_cm;
    if centre[2] >= wall {
        bail!(
            "the board at z = {} cm is not in front of the scene's wall (background.z_cm = {wall}):              the wall would hide it; place the board nearer or the wall farther",
            centre[2]
        );
    }
    let mut s = scene.clone();
    s.objects.push(Object {
        shape: Shape::Board { board: *board },
        motion: Motion::Linear { centre_cm: centre, velocity_cm_s: [0.0; 3] },
        texture_seed: 0,
    });
    Ok(s)
}

/// What one stop gave.
#[derive(Debug, Clone)]
pub enum Shot {
    /// Both images, the whole board seen.
    Pair(Box<[GrayImage; 2]>),
    /// The board is not fully inside both images at this posture.
    OutOfView,
    /// Something in the scene hides part of the board.
    Hidden,
}

/// The pair at `stop`: the scene (with the board at the stop's placement) rendered through
/// `head` at the reported joints, at the stop's time. Out of view is decided before rendering.
pub fn capture(head: &HeadRig, scene: &Scene, plan: &Plan, stop: &Stop) -> Result<Shot> {
    let centre = plan.placements[stop.placement].xyz;
    if !board_in_view(head, &stop.joints, &plan.board, centre) {
        return Ok(Shot::OutOfView);
    }
    let scene = with_board(scene, &plan.board, centre)?;
    let index = (stop.placement * plan.postures.len() + stop.posture) as u64;
    let seed = mix(plan.seed ^ mix(index));
    let r = render_scene(head, &stop.joints, &scene.at(stop.t_s), &plan.render, seed)
        .map_err(|e| anyhow!("virtual cameras: {e}"))?;
    // The outline's outer points lie on the board's edge squares, inside its white border:
    // a ray to one of them meets the board itself unless something stands in front.
    let seen_by_both = outline(&plan.board, centre)
        .iter()
        .all(|p| r.visible_in(0, p).is_some() && r.visible_in(1, p).is_some());
    if !seen_by_both {
        return Ok(Shot::Hidden);
    }
    Ok(Shot::Pair(Box::new([r.left, r.right])))
}

/// Image file names of a stop: `left_PPP_KKKK.png`, `right_PPP_KKKK.png` (placement and
/// posture numbers from 1).
pub fn image_names(stop: &Stop) -> [String; 2] {
    let tag = format!("{:03}_{:04}", stop.placement + 1, stop.posture + 1);
    [format!("left_{tag}.png"), format!("right_{tag}.png")]
}

/// Whether `name` has the form of [`image_names`] (`left_PPP_KKKK.png`, `right_PPP_KKKK.png`,
/// more digits for larger numbers): one of the images `hvs collect` may write, whatever the
/// postures seen.
pub fn is_image_name(name: &str) -> bool {
    let digits = |s: &str, n: usize| s.len() >= n && s.bytes().all(|b| b.is_ascii_digit());
    ["left_", "right_"].iter().any(|side| {
        name.strip_prefix(side)
            .and_then(|r| r.strip_suffix(".png"))
            .and_then(|r| r.split_once('_'))
            .is_some_and(|(p, k)| digits(p, 3) && digits(k, 4))
    })
}

/// `CAPTURES.csv` of the captured stops ([`crate::data::captures::captures_csv`]):
/// `left,right,z,x,y` and the five joint columns the head reported, one row per pair.
pub fn captures_csv(plan: &Plan, captured: &[Stop]) -> String {
    let names: Vec<[String; 2]> = captured.iter().map(image_names).collect();
    let rows: Vec<CaptureRow<'_>> = captured
        .iter()
        .zip(&names)
        .map(|(stop, [l, r])| CaptureRow {
            left: l,
            right: r,
            centre: plan.placements[stop.placement].xyz,
            joints: stop.joints,
        })
        .collect();
    crate::data::captures::captures_csv(&rows, true)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::track::head_sim::VirtualHead;
    use hvs_shared::runtime::trajectory::ControllerConfig;
    use hvs_shared::sim::presets;

    #[test]
    fn the_images_written_are_known_by_their_names() {
        for (placement, posture) in [(0, 1), (11, 344), (1000, 10000)] {
            let stop = Stop { placement, posture, t_s: 0.0, joints: Joints::HOME };
            for name in image_names(&stop) {
                assert!(is_image_name(&name), "{name}");
            }
        }
        for other in [
            "left01.png",
            "left_01_0002.png",
            "left_001_002.png",
            "left_001_0002.jpg",
            "left_001_0002.png.bak",
            "up_001_0002.png",
            "left_a01_0002.png",
            "CAPTURES.csv",
            "board.json",
        ] {
            assert!(!is_image_name(other), "{other}");
        }
    }

    fn plan(postures: Vec<Joints>) -> Plan {
        Plan {
            board: Board::new(9, 6, 6.0).unwrap(),
            placements: vec![
                Placement { line: 2, xyz: [0.0, 0.0, 105.0] },
                Placement { line: 3, xyz: [10.0, -5.0, 145.0] },
            ],
            postures,
            render: RenderOptions::default(),
            seed: 7,
            settle_s: SETTLE_S,
        }
    }

    #[test]
    fn the_head_settles_at_every_posture_and_reports_it() {
        let postures = vec![
            Joints([10.0, -5.04, 3.06, -2.88, 2.88]),
            Joints::HOME,
            Joints([-20.16, 10.08, 0.0, 1.8, 5.04]),
        ];
        let p = plan(postures.clone());
        let mut head = VirtualHead::new(&ControllerConfig::DEFAULT).unwrap();
        let stops = visit(&mut head, &p).unwrap();
        assert_eq!(stops.len(), 6);
        for (k, s) in stops.iter().enumerate() {
            assert_eq!((s.placement, s.posture), (k / 3, k % 3));
            let want = postures[s.posture].0.map(hvs_shared::runtime::gaze::quantize);
            assert_eq!(s.joints.0, want, "stop {k}");
        }
        assert!(stops.windows(2).all(|w| w[1].t_s > w[0].t_s + SETTLE_S));
    }

    #[test]
    fn the_board_is_in_view_at_home_and_not_when_the_head_turns_away() {
        let head = HeadRig::new(presets::case(3).unwrap());
        let p = plan(vec![]);
        // 60 x 42 cm at 40 cm: 37 degrees each side of the axis; the cameras see 48.
        let at = [0.0, 0.0, 40.0];
        assert!(board_in_view(&head, &Joints::HOME, &p.board, at));
        let away = Joints([30.0, 0.0, 0.0, 0.0, 0.0]);
        assert!(!board_in_view(&head, &away, &p.board, at));
        // Too near: the board overflows the images.
        assert!(!board_in_view(&head, &Joints::HOME, &p.board, [0.0, 0.0, 20.0]));
    }

    #[test]
    fn a_board_hidden_by_an_object_is_refused_and_a_clear_one_is_rendered() {
        let head = HeadRig::new(presets::case(3).unwrap());
        let mut p = plan(vec![Joints::HOME]);
        p.render.supersample = 1;
        let stop = Stop { placement: 0, posture: 0, t_s: 0.0, joints: Joints::HOME };
        let wall = |objects: &str| {
            hvs_vision::scene::SceneFile::parse(&format!(
                r#"{{"rig": {{"case": 3}}, "camera_fps": 30, "background": {{"z_cm": 300}}, "objects": [{objects}]}}"#
            ))
            .unwrap()
            .scene()
            .unwrap()
        };
        let clear = wall("");
        match capture(&head, &clear, &p, &stop).unwrap() {
            Shot::Pair(pair) => assert_eq!(pair[0].dimensions(), (640, 480)),
            other => panic!("expected a pair, got {other:?}"),
        }
        // A box between the head and the board (at 105 cm) hides its middle.
        let boxed = wall(r#"{"shape": "box", "size_cm": [10, 10, 10], "centre_cm": [0, 0, 60]}"#);
        assert!(matches!(capture(&head, &boxed, &p, &stop).unwrap(), Shot::Hidden));
        // A board at the wall's depth (300 cm here) or behind it is refused, not captured as
        // wall (a QA pass: 3 pairs of wall "collected" at z = 300).
        for z in [300.0, 350.0] {
            let e = with_board(&boxed, &p.board, [0.0, 0.0, z]).unwrap_err().to_string();
            assert!(e.contains("not in front of the scene's wall"), "{e}");
        }
        assert!(with_board(&boxed, &p.board, [0.0, 0.0, 299.0]).is_ok());
        // Turned away: refused before rendering.
        let away = Stop { joints: Joints([30.0, 0.0, 0.0, 0.0, 0.0]), ..stop };
        p.placements[0].xyz = [0.0, 0.0, 40.0];
        assert!(matches!(capture(&head, &clear, &p, &away).unwrap(), Shot::OutOfView));
    }

    /// Cameras on a head (here the virtual ones, as a real head's would be used): the pairs
    /// where both cameras find the whole board are kept with the joints the head reported,
    /// the one turned away is skipped.
    #[test]
    fn cameras_on_a_head_keep_the_pairs_that_show_the_whole_board() {
        let rig = presets::case(3).unwrap();
        let postures = vec![
            Joints::HOME,
            Joints([3.06, -1.98, 0.0, 1.08, 1.08]),
            Joints([30.0, 0.0, 0.0, 0.0, 0.0]),
        ];
        let mut p = plan(postures);
        p.placements.truncate(1);
        p.placements[0].xyz = [0.0, 0.0, 60.0];
        let scene = hvs_vision::scene::SceneFile::parse(
            r#"{"rig": {"case": 3}, "camera_fps": 30, "background": {"z_cm": 300, "texture_seed": 3}}"#,
        )
        .unwrap()
        .scene()
        .unwrap();
        let scene = with_board(&scene, &p.board, p.placements[0].xyz).unwrap();
        let opt = crate::track::frames::loop_render_options();
        let mut cams = crate::track::frames::VirtualCameras::new(HeadRig::new(rig), scene, opt, 1);
        let mut head = VirtualHead::new(&ControllerConfig::DEFAULT).unwrap();
        let mut kept = Vec::new();
        let skipped = visit_with_cameras(&mut head, &mut cams, &p, 0, |stop, pair| {
            assert_eq!(corners_seen(&pair[0], &pair[1], &p.board), [54, 54]);
            kept.push(*stop);
            Ok(())
        })
        .unwrap();
        assert_eq!((kept.len(), skipped), (2, 1));
        assert_eq!(kept.iter().map(|s| s.posture).collect::<Vec<_>>(), [0, 1]);
        assert_eq!(kept[1].joints.0, p.postures[1].0.map(hvs_shared::runtime::gaze::quantize));
    }

    #[test]
    fn captures_csv_is_what_board_detect_reads() {
        let p = plan(vec![Joints::HOME]);
        let stops = [Stop {
            placement: 1,
            posture: 0,
            t_s: 1.0,
            joints: Joints([1.8, 0.0, 0.0, -0.18, 0.18]),
        }];
        let text = captures_csv(&p, &stops);
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("CAPTURES.csv");
        std::fs::write(&path, &text).unwrap();
        let set = crate::data::captures::read(&path).unwrap();
        assert_eq!(set.extra_columns, crate::data::dataset::JOINT_COLUMNS);
        let c = &set.captures[0];
        assert_eq!(
            (c.left_name.as_str(), c.right_name.as_str()),
            ("left_002_0001.png", "right_002_0001.png")
        );
        assert_eq!((c.xy, c.z), ([10.0, -5.0], Some(145.0)));
        assert_eq!(c.extra, ["1.8", "0", "0", "-0.18", "0.18"]);
    }
}
