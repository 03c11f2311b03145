//! `hvs eval --case N` on a posture set (the five joint columns): the optimal-triangulation
//! floor uses the cameras at each row's posture, so it has an estimate for every point and
//! stays at the rounding floor (it used to triangulate with the home-posture rig, and most
//! points of verged or turned postures came out "no estimate").

use crate::common::{ok_line, posture_model, simulate_into, train_into, Scratch};

/// `hvs eval --model model --data data --case 3 --json`, parsed.
fn eval_case_3(model: &str, data: &str) -> serde_json::Value {
    let json = ok_line(&format!("eval --model {model} --data {data} --case 3 --json"));
    serde_json::from_str(&json).unwrap()
}

#[test]
fn the_floor_of_a_posture_set_is_triangulated_at_each_rows_posture() {
    let dir = Scratch::new();
    // Any posture-aware model will do: the floor does not depend on it. Two postures and
    // two hidden neurons keep the training short.
    posture_model(
        &dir,
        "--case 3",
        "--postures grid --posture-levels 1,1,1,1,2",
        "--postures random --posture-count 12 --seed 3",
        "--hidden 2 --restarts 1",
    );
    let v = eval_case_3(&dir.p("m.hvsw"), &dir.p("test.csv"));
    let methods = v["evaluation"]["methods"].as_array().unwrap();
    let floor =
        methods.iter().find(|m| m["name"] == "optimal").expect("an optimal method with --case");
    assert_eq!(v["evaluation"]["points"], 12 * 22);
    assert_eq!(floor["missing"], 0, "{floor}");
    let e = floor["mean"]["e_ma_pct"].as_f64().unwrap();
    // Case III's rounding floor on the test points is about 1.3-1.5 %.
    assert!(e > 0.5 && e < 2.5, "floor mean e_ma {e} %");
    let worst = floor["worst_depth_pct"].as_f64().unwrap();
    assert!(worst < 5.0, "floor worst depth {worst} %");

    // The table says the same, without "no estimate".
    let text =
        ok_line(&format!("eval --model {} --data {} --case 3", dir.p("m.hvsw"), dir.p("test.csv")));
    assert!(text.contains("optimal"), "{text}");
    assert!(!text.contains("optimal: no estimate"), "{text}");
    // A posture-aware model also gets its error per posture band against the floor's: the
    // first band is every row, with the floor of the table above.
    assert!(text.contains("per posture band") && text.contains("worst band:"), "{text}");
    let bands = v["posture_bands"].as_array().expect("posture bands");
    assert_eq!(bands[0]["term"], "all");
    assert_eq!(bands[0]["points"], 12 * 22);
    let (net, opt) =
        (bands[0]["network_pct"].as_f64().unwrap(), bands[0]["optimal_pct"].as_f64().unwrap());
    assert!((opt - e).abs() < 1e-9, "{opt} against the table's {e}");
    let ratio = bands[0]["ratio"].as_f64().unwrap();
    assert!((ratio - net / opt).abs() < 1e-12 && net > 0.0, "{}", bands[0]);
    let terms: std::collections::BTreeSet<&str> =
        bands.iter().map(|b| b["term"].as_str().unwrap()).collect();
    for t in ["neck pan", "neck tilt", "eye tilt", "version", "vergence"] {
        assert!(terms.contains(t), "{terms:?}");
    }

    // A 4-input (fixed-posture) model on the same posture set: the net sees only the pixels,
    // the floor still triangulates at each row's posture, with the same numbers as above.
    simulate_into("--case 3 --set train", &dir.p("home.csv"));
    train_into(&dir.p("home.csv"), &dir.p("home.hvsw"), "--restarts 1");
    let v = eval_case_3(&dir.p("home.hvsw"), &dir.p("test.csv"));
    let home_floor = v["evaluation"]["methods"]
        .as_array()
        .unwrap()
        .iter()
        .find(|m| m["name"] == "optimal")
        .expect("an optimal method with --case")
        .clone();
    assert_eq!(home_floor["missing"], 0, "{home_floor}");
    assert_eq!(home_floor["mean"], floor["mean"]);
    // Its inputs have no joints: no posture bands.
    assert!(v["posture_bands"].is_null(), "{v}");
}
