//! Data for every pixel regime: `hvs simulate --pixels exact|rounded`, `--noise-px` with
//! both, `--board NXxNY:PITCH`, their errors; `hvs eval --case N [--distortion K1]` gives the
//! floor on such sets (zero on exact pixels, through the true lenses on a barrel set).

use crate::common::{fails, fails_line, ok, ok_line, s, stderr_with_code, train_restarts};

use tempfile::TempDir;

/// The data rows of a simulated CSV, as numbers.
fn rows(csv: &str) -> Vec<Vec<f64>> {
    let mut lines = csv.lines();
    assert_eq!(lines.next(), Some("u_l,v_l,u_r,v_r,x,y,z"));
    lines.map(|l| l.split(',').map(|v| v.parse().unwrap()).collect()).collect()
}

fn whole(v: f64) -> bool {
    v == v.round()
}

#[test]
fn pixels_exact_or_rounded_with_and_without_noise() {
    let sim = |extra: &str| rows(&ok_line(&format!("simulate --case 4 --set train{extra}")));
    let rounded = sim("");
    let exact = sim(" --pixels exact");
    let exact_noisy = sim(" --pixels exact --noise-px 0.3 --seed 5");
    let rounded_noisy = sim(" --pixels rounded --noise-px 0.3 --seed 5");
    assert_eq!(rounded, sim(" --pixels rounded"), "rounded is the default");
    for set in [&rounded, &exact, &exact_noisy, &rounded_noisy] {
        assert_eq!(set.len(), 72);
    }
    assert!(rounded.iter().all(|r| r[..4].iter().all(|v| whole(*v))));
    assert!(rounded_noisy.iter().all(|r| r[..4].iter().all(|v| whole(*v))));
    // Exact pixels are not whole, and round to the rounded set (no noise: the same point).
    assert!(exact.iter().all(|r| r[..4].iter().any(|v| !whole(*v))));
    for (e, r) in exact.iter().zip(&rounded) {
        assert_eq!(e[4..], r[4..]);
        for k in 0..4 {
            assert!((e[k] - r[k]).abs() <= 0.5 + 1e-9, "{e:?} {r:?}");
        }
    }
    // The same noise draws on both: the rounded noisy set is the noisy exact one, rounded
    // (the principal point of the presets is whole, so rounding commutes with it).
    let mut moved = 0;
    for ((n, r), e) in exact_noisy.iter().zip(&rounded_noisy).zip(&exact) {
        for k in 0..4 {
            assert!((n[k] - r[k]).abs() <= 0.5 + 1e-9, "{n:?} {r:?}");
            assert!((n[k] - e[k]).abs() < 0.3 * 6.0, "{n:?} {e:?}");
            moved += usize::from(n[k] != e[k]);
        }
    }
    assert_eq!(moved, 4 * 72, "every coordinate gets noise");
    // Full precision: the written pixels are the doubles computed (a second run, same text).
    assert_eq!(
        ok_line("simulate --case 4 --set train --pixels exact --noise-px 0.3 --seed 5"),
        ok_line("simulate --case 4 --set train --pixels exact --noise-px 0.3 --seed 5")
    );
}

#[test]
fn a_grid_board_at_the_thesis_depths_and_its_volume() {
    let train = rows(&ok_line("simulate --case 1 --set train --board 9x6:6"));
    assert_eq!(train.len(), 6 * 54);
    assert_eq!(train[0][4..], [-24.0, -15.0, 65.0]);
    assert_eq!(train[53][4..], [24.0, 15.0, 65.0]);
    assert_eq!(train[54][4..], [-24.0, -15.0, 85.0]);
    assert_eq!(train[323][4..], [24.0, 15.0, 165.0]);
    // The thesis board by name is the default.
    assert_eq!(
        ok_line("simulate --case 1 --set train --board thesis"),
        ok_line("simulate --case 1 --set train")
    );
    let vol = rows(&ok_line("simulate --case 2 --set volume --board 9x6:6 --points 400 --seed 2"));
    assert_eq!(vol.len(), 400);
    let (mut xmax, mut ymax) = (0.0f64, 0.0f64);
    for r in &vol {
        assert!(r[4].abs() <= 24.0 && r[5].abs() <= 15.0 && (65.0..=165.0).contains(&r[6]));
        xmax = xmax.max(r[4].abs());
        ymax = ymax.max(r[5].abs());
    }
    // Far beyond the thesis board's X +-3, Y +-2.
    assert!(xmax > 20.0 && ymax > 12.0, "{xmax} {ymax}");
    // With lenses and postures too.
    let bent = rows(&ok_line(
        "simulate --case 4 --set train --board 9x6:6 --distortion -0.1 --pixels exact",
    ));
    assert_eq!(bent.len(), 324);
    let posed = ok_line(
        "simulate --case 4 --set train --board 4x3:3 --postures lattice --posture-levels 1,1,1,1,2",
    );
    assert_eq!(posed.lines().count(), 1 + 2 * 6 * 12);
}

#[test]
fn bad_pixels_and_boards_are_clear_errors() {
    for (arg, want) in [
        ("9x6", "NXxNY:PITCH"),
        ("9x6:", "PITCH must be"),
        ("1x6:6", "NX must be a whole number 2 to 100"),
        ("9x6:-6", "PITCH must be"),
        ("nine", "NXxNY:PITCH"),
    ] {
        let e = stderr_with_code(["simulate", "--case", "1", "--set", "train", "--board", arg], 2);
        assert!(e.contains("--board") && e.contains(want), "{arg}: {e}");
        assert!(!e.contains("panicked"), "{e}");
    }
    let e = stderr_with_code(["simulate", "--case", "1", "--set", "train", "--pixels", "fuzzy"], 2);
    assert!(e.contains("possible values: rounded, exact"), "{e}");
    fails(
        &["simulate", "--case", "1", "--set", "test", "--board", "9x6:6"],
        "--board 9x6:6 applies to --set train and --set volume",
    );
    fails(
        &["simulate", "--case", "1", "--set", "train", "--pixels", "exact", "--noise-px", "-1"],
        "--noise-px must be",
    );
    // A board too big for the images names the point that falls outside.
    fails(&["simulate", "--case", "1", "--set", "train", "--board", "9x6:20"], "falls outside");
    // The long help says what the flags do.
    let help = ok(&["simulate", "--help"]);
    assert!(help.contains("--pixels exact") && help.contains("9x6:6"), "{help}");
}

/// `hvs eval --json` of `model` on `data` with `floor` arguments: the floor's mean e_ma (%).
fn floor_pct(model: &str, data: &str, floor: &str) -> f64 {
    let json = ok_line(&format!("eval --model {model} --data {data} {floor} --json"));
    let v: serde_json::Value = serde_json::from_str(&json).unwrap();
    let m = v["evaluation"]["methods"].as_array().unwrap();
    let f = m.iter().find(|m| m["name"] == "optimal").unwrap();
    assert_eq!(f["missing"], 0, "{f}");
    f["mean"]["e_ma_pct"].as_f64().unwrap()
}

#[test]
fn eval_gives_the_floor_on_exact_grid_board_and_barrel_sets() {
    let dir = TempDir::new().unwrap();
    let (train, model) = (dir.path().join("train.csv"), dir.path().join("m.hvsw"));
    // Any model: the floor does not depend on it.
    ok(&["simulate", "--case", "4", "--set", "train", "-o", s(&train)]);
    train_restarts(&train, &model, "1");
    let p = |n: &str| dir.path().join(n).to_str().unwrap().to_string();
    let m = p("m.hvsw");
    let sim = |name: &str, args: &str| {
        ok_line(&format!(
            "simulate --case 4 --set volume --points 200 --seed 9 {args} -o {}",
            p(name)
        ));
        p(name)
    };
    // Exact pixels: the true rig triangulates them exactly.
    let exact = sim("exact.csv", "--pixels exact");
    let f = floor_pct(&m, &exact, "--case 4");
    assert!(f < 1e-6, "floor on exact pixels {f} %");
    // Rounded pixels of the 9x6 board's volume: the rounding floor, about 1-2 %.
    let big = sim("big.csv", "--board 9x6:6");
    let f = floor_pct(&m, &big, "--case 4");
    assert!(f > 0.5 && f < 3.0, "floor on the 9x6 volume {f} %");
    // Sub-pixel noise: a floor between the two.
    let sub = sim("sub.csv", "--board 9x6:6 --pixels exact --noise-px 0.05");
    let f = floor_pct(&m, &sub, "--case 4");
    assert!(f > 0.05 && f < 0.5, "floor at 0.05 px {f} %");
    // Barrel lenses: through the true lenses the floor is exact again; without them it
    // is not.
    let barrel = sim("barrel.csv", "--board 9x6:6 --pixels exact --distortion -0.1");
    let f = floor_pct(&m, &barrel, "--case 4 --distortion -0.1");
    assert!(f < 1e-6, "floor through the true lenses {f} %");
    let f = floor_pct(&m, &barrel, "--case 4");
    assert!(f > 0.05, "floor through pinholes on a barrel set {f} %");
    let text = ok_line(&format!("eval --model {m} --data {barrel} --case 4 --distortion -0.1"));
    assert!(text.contains("through lenses k1 = -0.1, k2 = 0"), "{text}");
    fails_line(
        &format!("eval --model {m} --data {barrel} --distortion -0.1"),
        "needs --case N or --rig",
    );
    fails_line(
        &format!("eval --model {m} --data {barrel} --case 4 --distortion -0.1,0,1"),
        "K1 or K1,K2, got 3 values",
    );
}
