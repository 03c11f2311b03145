//! The head's `f32` kinematics (`runtime::gaze`) against the simulator's `f64` camera model
//! (`sim::camera`): the same poses, the same images of a fixated target.

use hvs_shared::runtime::gaze::{eye_pose, fixate, Eye, EyePose, GazeConfig, HeadGeometry, Joints};

fn camera_at(pose: &EyePose) -> hvs_shared::sim::camera::Camera {
    hvs_shared::sim::camera::Camera {
        center: pose.centre.map(f64::from),
        rotation: pose.rot.map(|r| r.map(f64::from)),
        phi_u: 285.836,
        phi_v: 285.836,
        u0: 320.0,
        v0: 240.0,
    }
}

#[test]
fn pose_agrees_with_the_camera_module() {
    for (pan, tilt) in [(0.0f32, 0.0f32), (12.0, -7.0), (-30.0, 25.0)] {
        let j = Joints([0.0, 0.0, tilt, pan, -pan]);
        let l = eye_pose(&HeadGeometry::DEFAULT, &j, Eye::Left);
        let r = eye_pose(&HeadGeometry::DEFAULT, &j, Eye::Right);
        let (a, b) = (f64::from(pan).to_radians(), f64::from(tilt).to_radians());
        let wl = hvs_shared::sim::camera::omega(a, b, 0.0);
        let wr = hvs_shared::sim::camera::omega(-a, b, 0.0);
        for (got, want) in l.rot.iter().flatten().zip(wl.iter().flatten()) {
            assert!((f64::from(*got) - want).abs() < 1e-6);
        }
        for (got, want) in r.rot.iter().flatten().zip(wr.iter().flatten()) {
            assert!((f64::from(*got) - want).abs() < 1e-6);
        }
        assert_eq!(r.centre, [5.25, 0.0, 0.0]);
    }
}

#[test]
fn fixated_target_images_at_both_principal_points() {
    let g = HeadGeometry { neck_centre_cm: [0.0, 7.0, -5.0], ..HeadGeometry::DEFAULT };
    let cfg = GazeConfig { geometry: g, ..GazeConfig::DEFAULT };
    for t in [[-20.0f32, 10.0, 90.0], [35.0, -25.0, 60.0], [3.0, 2.0, 400.0]] {
        let f = fixate(&cfg, t).unwrap();
        assert!(!f.clamped);
        let p = t.map(f64::from);
        for eye in [Eye::Left, Eye::Right] {
            let uv = camera_at(&eye_pose(&g, &f.joints, eye)).project(&p).unwrap();
            assert!((uv[0] - 320.0).abs() < 2e-3, "{eye:?} {t:?} {uv:?}");
            assert!((uv[1] - 240.0).abs() < 2e-3, "{eye:?} {t:?} {uv:?}");
        }
    }
}
