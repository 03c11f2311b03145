//! The scene renderer's truth: hit points project back to their pixels, the true match of a
//! left pixel is where the right camera sees the same point (and `None` when occluded), strict
//! scene JSON, and the same seed gives the same bytes.

use hvs_shared::runtime::gaze::Joints;
use hvs_shared::sim::camera::Rig;
use hvs_shared::sim::posture::HeadRig;
use hvs_shared::sim::presets;
use hvs_vision::render::RenderOptions;
use hvs_vision::scene::{field_line, render_scene, SceneFile, SceneRender, BACKGROUND, NONE};

const SCENE: &str = r#"{ "rig": {"case": 3}, "camera_fps": 30,
  "background": {"z_cm": 300, "texture_seed": 1},
  "objects": [
    {"shape": "sphere", "radius_cm": 5, "centre_cm": [4, -2, 90], "velocity_cm_s": [10, 0, 0], "texture_seed": 2},
    {"shape": "box", "size_cm": [8, 6, 4], "centre_cm": [-12, 4, 130], "texture_seed": 3},
    {"shape": "board", "board": {"pattern": "chessboard", "inner_corners": [5, 4], "square_cm": 3},
     "path": [{"t_s": 0, "centre_cm": [15, 10, 160]}, {"t_s": 1, "centre_cm": [10, 10, 160]}]},
    {"shape": "plane", "side_cm": [30, 16], "pitch_deg": 55, "yaw_deg": -20, "centre_cm": [-8, 16, 200], "texture_seed": 6}
  ] }"#;

/// Case III at a quarter of the size (160 x 120), to keep the test fast.
fn small_rig() -> Rig {
    let mut r = presets::CASE_3;
    r.width = 160;
    r.height = 120;
    r.u0 = 80.0;
    r.v0 = 60.0;
    r.phi_u_left *= 0.25;
    r.phi_u_right *= 0.25;
    r.phi_v_left *= 0.25;
    r.phi_v_right *= 0.25;
    r
}

fn render(joints: &Joints, t: f64, seed: u64) -> SceneRender {
    let scene = SceneFile::parse(SCENE).unwrap().scene().unwrap();
    let head = HeadRig::new(small_rig());
    render_scene(&head, joints, &scene.at(t), &RenderOptions::default(), seed).unwrap()
}

const POSTURE: Joints = Joints([4.0, -3.0, 2.0, 1.5, -1.0]);

#[test]
fn hit_points_project_back_to_their_pixels() {
    let r = render(&POSTURE, 0.3, 7);
    let mut seen = [0usize; 5];
    for (cam, truth) in [(0, &r.truth_left), (1, &r.truth_right)] {
        for row in 0..truth.height {
            for c in 0..truth.width {
                let (p, obj) = truth.hit(c, row).expect("the wall is everywhere");
                seen[usize::from(obj)] += 1;
                let px = r.cameras[cam].project(&p.map(f64::from)).expect("in front");
                let e = (px[0] - f64::from(c)).hypot(px[1] - f64::from(row));
                // f32 storage of points up to 300 cm: ~1e-3 px.
                assert!(e < 5e-3, "cam {cam} pixel ({c},{row}) back at {px:?}");
            }
        }
    }
    // Every object is seen.
    assert!(seen.iter().all(|&n| n > 20), "pixels per object {seen:?}");
    // The slanted plane's depth changes across it (its pitch and yaw), as its hit points say.
    let z: Vec<f32> = (0..160 * 120)
        .filter(|&k| r.truth_left.object[k] == 4)
        .map(|k| r.truth_left.point[k][2])
        .collect();
    let (lo, hi) = z.iter().fold((f32::MAX, f32::MIN), |(a, b), &v| (a.min(v), b.max(v)));
    assert!(hi - lo > 10.0, "plane depths {lo}..{hi}");
    assert!(seen[BACKGROUND as usize] > seen[1]);
}

#[test]
fn true_match_sees_the_same_point_or_is_occluded() {
    let r = render(&POSTURE, 0.0, 7);
    let (mut matched, mut occluded) = (0, 0);
    for row in (0..120).step_by(3) {
        for c in (0..160).step_by(3) {
            let (p, obj) = r.truth_left.hit(c, row).unwrap();
            match r.true_match(c, row) {
                Some([ur, vr]) => {
                    matched += 1;
                    // The right pixel nearest the match sees the same object at nearly the
                    // same depth (neighbouring points on one smooth surface).
                    let (q, o2) = r.truth_right.hit(ur.round() as u32, vr.round() as u32).unwrap();
                    if o2 == obj {
                        let dz = (q[2] - p[2]).abs();
                        assert!(dz < 0.02 * p[2], "({c},{row}) z {} vs {}", p[2], q[2]);
                    }
                    // And the depth agrees with the right camera's projection of the point.
                    let back = r.cameras[1].project(&p.map(f64::from)).unwrap();
                    assert!((back[0] - ur).abs() < 5e-3 && (back[1] - vr).abs() < 5e-3);
                }
                None => occluded += 1,
            }
        }
    }
    assert!(matched > 1000, "matched {matched}");
    // The sphere and the box hide some of the wall from the right camera.
    assert!(occluded > 10, "occluded {occluded}");
    assert!(r.true_match(1000, 0).is_none());
}

#[test]
fn objects_move_in_time() {
    let scene = SceneFile::parse(SCENE).unwrap().scene().unwrap();
    assert_eq!(scene.at(1.0).objects[0].centre, [14.0, -2.0, 90.0]);
    assert_eq!(scene.at(0.5).objects[2].centre, [12.5, 10.0, 160.0]);
    let a = render(&Joints::HOME, 0.0, 1);
    let b = render(&Joints::HOME, 0.5, 1);
    assert_ne!(a.left, b.left);
    assert_eq!(a.truth_left.object.iter().filter(|&&o| o == NONE).count(), 0);
}

#[test]
fn same_seed_same_bytes() {
    let a = render(&POSTURE, 0.2, 11);
    let b = render(&POSTURE, 0.2, 11);
    assert_eq!(a.left, b.left);
    assert_eq!(a.right, b.right);
    assert_eq!(a.truth_left, b.truth_left);
    let c = render(&POSTURE, 0.2, 12);
    assert_ne!(a.left, c.left);
    assert_eq!(a.truth_left, c.truth_left);
}

#[test]
fn textured_surfaces_have_contrast() {
    let opt = RenderOptions::clean();
    let scene = SceneFile::parse(SCENE).unwrap().scene().unwrap();
    let r =
        render_scene(&HeadRig::new(small_rig()), &Joints::HOME, &scene.at(0.0), &opt, 0).unwrap();
    // Grey levels on the sphere and on the slanted plane vary (textured surfaces, not flat
    // discs).
    for (id, what) in [(1, "sphere"), (4, "plane")] {
        let vals: Vec<f64> = (0..160 * 120)
            .filter(|&k| r.truth_left.object[k] == id)
            .map(|k| f64::from(r.left.as_raw()[k]))
            .collect();
        let mean = vals.iter().sum::<f64>() / vals.len() as f64;
        let sd = (vals.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / vals.len() as f64).sqrt();
        assert!(sd > 15.0, "{what} texture sd {sd}");
    }
}

fn refused(text: &str, needle: &str) {
    let e = SceneFile::parse(text).and_then(|f| f.scene()).expect_err("must be refused");
    assert!(e.to_string().contains(needle), "{e} does not name {needle}");
}

#[test]
fn strict_scene_json() {
    let base =
        r#"{"rig": {"case": 3}, "camera_fps": 30, "background": {"z_cm": 300}, "objects": [OBJ]}"#;
    let with = |o: &str| base.replace("OBJ", o);
    refused(&base.replace("\"camera_fps\"", "\"fps\""), "unknown field `fps`");
    refused(
        &with(r#"{"shape": "sphere", "radius_cm": 5, "centre_cm": [0,0,90], "colour": 1}"#),
        "colour",
    );
    refused(&with(r#"{"shape": "cone", "centre_cm": [0,0,90]}"#), "cone");
    refused(&with(r#"{"shape": "sphere", "centre_cm": [0,0,90]}"#), "objects[0].radius_cm");
    refused(
        &with(r#"{"shape": "sphere", "radius_cm": -1, "centre_cm": [0,0,90]}"#),
        "objects[0].radius_cm",
    );
    refused(
        &with(r#"{"shape": "sphere", "radius_cm": 5, "size_cm": [1,1,1], "centre_cm": [0,0,90]}"#),
        "objects[0].size_cm",
    );
    refused(
        &with(r#"{"shape": "box", "size_cm": [1,0,1], "centre_cm": [0,0,90]}"#),
        "objects[0].size_cm[1]",
    );
    refused(
        &with(
            r#"{"shape": "board", "board": {"pattern": "chessboard", "inner_corners": [1, 4], "square_cm": 3}, "centre_cm": [0,0,90]}"#,
        ),
        "objects[0].board",
    );
    refused(&with(r#"{"shape": "sphere", "radius_cm": 5}"#), "objects[0].centre_cm");
    refused(
        &with(
            r#"{"shape": "sphere", "radius_cm": 5, "centre_cm": [0,0,90], "path": [{"t_s": 0, "centre_cm": [0,0,90]}]}"#,
        ),
        "objects[0].path",
    );
    refused(
        &with(
            r#"{"shape": "sphere", "radius_cm": 5, "path": [{"t_s": 1, "centre_cm": [0,0,90]}, {"t_s": 1, "centre_cm": [0,0,90]}]}"#,
        ),
        "objects[0].path[1].t_s",
    );
    refused(
        &with(r#"{"shape": "sphere", "radius_cm": 5, "radius_cm": 6, "centre_cm": [0,0,90]}"#),
        "duplicate field `radius_cm`",
    );
    refused(&base.replace("\"z_cm\": 300", "\"z_cm\": 0").replace("OBJ", ""), "background.z_cm");
    refused(
        &base.replace("\"camera_fps\": 30", "\"camera_fps\": 0").replace("OBJ", ""),
        "camera_fps",
    );
    refused(&base.replace("OBJ", "").replace("\"rig\": {\"case\": 3},", ""), "missing field `rig`");
}

#[test]
fn a_refused_value_is_found_on_its_line() {
    let text = r#"{"rig": {"case": 3},
 "camera_fps": 30,
 "background": {"z_cm": 300},
 "objects": [
  {"shape": "sphere", "radius_cm": 5, "centre_cm": [0, 0, 90]},
  {"shape": "box",
   "size_cm": [4,
               0,
               4],
   "centre_cm": [0, 0, 90]},
  {"shape": "sphere", "path": [{"t_s": 0, "centre_cm": [0, 0, 90]},
    {"t_s": 0, "centre_cm": [0, 0, 90]}]}
 ]}"#;
    let e = SceneFile::parse(text).unwrap().scene().unwrap_err();
    assert_eq!(e.field.as_deref(), Some("objects[1].size_cm[1]"), "{e}");
    assert_eq!(e.line(text), Some(8));
    assert_eq!(field_line(text, "background.z_cm"), Some(3));
    assert_eq!(field_line(text, "objects[2].path[1].t_s"), Some(12));
    // A field that is not there (a sphere without its radius): the line of its object.
    assert_eq!(field_line(text, "objects[2].radius_cm"), Some(11));
    assert_eq!(field_line(text, "objects[7]"), Some(4), "the array that lacks it");
    assert_eq!(field_line(text, "nothing"), None);
    assert_eq!(field_line("{not json", "objects"), None);
    // A value of the wrong type: its field named, and serde's line; JSON that does not parse
    // names no field.
    let e = SceneFile::parse("{\n\"camera_fps\": \"x\"}").unwrap_err();
    assert!(e.field.as_deref() == Some("camera_fps") && e.to_string().contains("line 2"), "{e}");
    let e = SceneFile::parse("{\n\"camera_fps\": 30,,}").unwrap_err();
    assert!(e.field.is_none() && e.to_string().contains("line 2"), "{e}");
}
