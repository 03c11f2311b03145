//! `hvs simulate --postures/--distortion` driven from outside: columns, sizes, determinism,
//! a posture-aware model trained and evaluated through the CLI, and the bad-flag errors.

use crate::common::{fails, ok, ok_line, posture_model, simulate_into, Scratch};

#[test]
fn posture_sets_have_joint_columns_and_are_seeded() {
    let grid = ok_line("simulate --case 3 --set test --postures grid --seed 5");
    let mut lines = grid.lines();
    assert_eq!(
        lines.next(),
        Some("u_l,v_l,u_r,v_r,neck_pan,neck_tilt,eye_tilt,left_eye_pan,right_eye_pan,x,y,z")
    );
    // 3*3*3*3*4 postures, 22 test points at each.
    assert_eq!(lines.count(), 324 * 22);
    assert_eq!(grid, ok_line("simulate --case 3 --set test --postures grid --seed 5"));
    assert_ne!(grid, ok_line("simulate --case 3 --set test --postures grid --seed 6"));
    let random =
        ok_line("simulate --case 1 --set volume --points 50 --postures random --posture-count 7");
    assert_eq!(random.lines().count(), 51);
    let lattice =
        ok_line("simulate --case 2 --set train --postures lattice --posture-levels 2,1,1,1,2");
    assert_eq!(lattice.lines().count(), 1 + 4 * 72);
    // Distortion alone keeps the thesis columns; zero distortion is the thesis set.
    let plain = ok(&["simulate", "--case", "4", "--set", "train"]);
    assert_eq!(ok_line("simulate --case 4 --set train --distortion 0"), plain);
    let bent = ok_line("simulate --case 4 --set train --distortion -0.5,0.1");
    assert!(bent.starts_with("u_l,v_l,u_r,v_r,x,y,z\n"));
    assert_ne!(bent, plain);
}

#[test]
fn bad_posture_flags_are_refused() {
    let base = ["simulate", "--case", "1", "--set", "train"];
    let with = |extra: &[&'static str]| -> Vec<&'static str> {
        base.iter().copied().chain(extra.iter().copied()).collect()
    };
    // The posture flags are bad usage (exit 2), named.
    let usage: [(&[&'static str], &str); 7] = [
        (&["--posture-count", "3"], "need --postures"),
        (&["--postures", "grid", "--posture-levels", "3,3"], "five counts"),
        (&["--postures", "grid", "--posture-levels", "3,0,3,3,3"], "at least 1"),
        (&["--postures", "random", "--posture-levels", "3,3,3,3,3"], "grid or lattice"),
        (&["--postures", "grid", "--posture-count", "4"], "random"),
        (&["--postures", "random", "--posture-count", "0"], "--posture-count must be 1 to"),
        (&["--postures", "grid", "--posture-levels", "99,99,99,99,99"], "--posture-levels give"),
    ];
    for (extra, want) in usage {
        let e = crate::common::stderr_with_code(with(extra), 2);
        assert!(e.starts_with("error: ") && e.contains(want), "{extra:?}: {e}");
    }
    let cases: [(&[&'static str], &str); 2] =
        [(&["--distortion", "1,2,3"], "K1 or K1,K2"), (&["--distortion", "nan"], "finite")];
    for (extra, want) in cases {
        fails(&with(extra), want);
    }
}

#[test]
fn a_posture_aware_model_trains_and_evaluates_through_the_cli() {
    let dir = Scratch::new();
    // A coarse grid (2 cells per axis, 32 postures), so the test stays quick.
    let info = posture_model(
        &dir,
        "--case 1",
        "--postures grid --posture-levels 2,2,2,2,2",
        "--postures random --posture-count 20",
        "--hidden 8 --restarts 2",
    );
    assert!(info.contains("9-8-3"), "{info}");
    // Without --arch and --frame a posture-aware set gets the default family with its points
    // in the cyclopean frame.
    let default = hvs_host::train::DEFAULT_FAMILY.name();
    assert!(info.contains(&format!("family:      {default} ")), "{info}");
    assert!(info.contains("frame:       cyclopean"), "{info}");
    let json =
        ok_line(&format!("eval --model {} --data {} --json", dir.p("m.hvsw"), dir.p("test.csv")));
    let v: serde_json::Value = serde_json::from_str(&json).unwrap();
    let net = &v["evaluation"]["methods"][0];
    assert_eq!(net["name"], "network");
    let e = net["mean"]["e_ma_pct"].as_f64().unwrap();
    eprintln!("posture-aware 9-8-3 on 20 random postures: mean e_ma {e} %");
    // The optimal triangulation floor of these points is about 1.3 %.
    assert!(e < 2.5, "mean e_ma {e} %");
    // predict reads the joint columns of a posture-aware model.
    let pred =
        ok_line(&format!("predict --model {} --points {}", dir.p("m.hvsw"), dir.p("test.csv")));
    assert_eq!(pred.lines().count(), 1 + 20 * 22);
}

/// `--arch inverse-depth-skip --frame head`: the default family on a posture-aware set with
/// its points in the head frame (the frame the default would not choose), a 9-H-3 net with 27
/// skip weights.
#[test]
fn arch_gives_the_default_family_on_a_posture_aware_set() {
    let dir = Scratch::new();
    let info = posture_model(
        &dir,
        "--case 3",
        "--postures grid --posture-levels 1,1,1,1,2",
        "--postures random --posture-count 4",
        "--hidden 4 --restarts 1 --arch inverse-depth-skip --frame head",
    );
    assert!(info.contains("9-4-3"), "{info}");
    assert!(info.contains("inverse-depth-skip"), "{info}");
    assert!(info.contains("frame:       head "), "{info}");
}

/// `--frame eye-platform` needs the joint columns: on a stereo set it is one clear error
/// naming the file, and no model is written.
#[test]
fn eye_platform_frame_on_a_stereo_set_is_refused() {
    let dir = Scratch::new();
    let (train, model) = (dir.p("train.csv"), dir.p("m.hvsw"));
    simulate_into("--case 1 --set train", &train);
    let err = fails(
        &["train", "--data", &train, "-o", &model, "--frame", "eye-platform"],
        "eye-platform frame is for posture-aware sets",
    );
    assert!(err.contains("train.csv"), "{err}");
    assert!(!std::path::Path::new(&model).exists());
}
