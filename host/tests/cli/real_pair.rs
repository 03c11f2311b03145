//! The real-pair goal: a real stereo pair with ground truth (Middlebury 2014
//! Motorcycle, tests/fixtures/motorcycle), 1000 training points: the default family within
//! 0.15 % e_ma on 2000 other pixels; the thesis net, which cannot follow sub-pixel pixels,
//! stays at about 0.33 %. The data is projective (the depths come from the same disparities),
//! so a DLT fit from the training points is exact.

use crate::common::{ok_line, Scratch};
use hvs_host::data::csv::{read_set, Inputs};
use std::path::PathBuf;

fn fixture(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/motorcycle").join(name)
}

/// Mean e_ma (%) of `model` on `data`, from `hvs eval --json`.
fn e_ma_pct(model: &str, data: &str) -> f64 {
    let json: serde_json::Value =
        serde_json::from_str(&ok_line(&format!("eval --model {model} --data {data} --json")))
            .expect("eval --json prints JSON");
    let methods = json["evaluation"]["methods"].as_array().expect("methods");
    assert_eq!(methods[0]["name"], "network");
    assert_eq!(methods[0]["missing"], 0, "every test point is estimated");
    methods[0]["mean"]["e_ma_pct"].as_f64().expect("a number")
}

#[test]
fn motorcycle_1000_points_default_within_goal() {
    let dir = Scratch::new();
    let (train, test) = (fixture("train.csv"), fixture("test.csv"));
    let (train, test) = (train.to_str().unwrap(), test.to_str().unwrap());
    let mut got = Vec::new();
    for arch in ["", "--arch thesis --restarts 2"] {
        let model = dir.p("m.hvsw");
        ok_line(&format!("train --data {train} -o {model} --seed 7 {arch}"));
        got.push(e_ma_pct(&model, test));
    }
    let (default, thesis) = (got[0], got[1]);
    eprintln!("Motorcycle, 1000 training points: default {default:.4} %, thesis {thesis:.4} %");
    assert!(default <= 0.15, "default family {default} % > 0.15 %");
    assert!(thesis > 0.2, "the thesis net is not expected to follow exact pixels: {thesis} %");

    // The DLT from the same points is exact here (the ground truth is projective).
    let read = |p: &str| read_set(p.as_ref(), Inputs::Stereo, true).unwrap().data;
    let (tr, te) = (read(train), read(test));
    let z = hvs_host::study::accuracy::dlt_depths(&tr, &te).unwrap();
    let method = hvs_host::evaluate::Method { name: "dlt".into(), z };
    let ev = hvs_host::evaluate::evaluate(&te, &[method]);
    assert_eq!(ev.methods[0].missing, 0, "the DLT triangulates every test point");
    let dlt = ev.methods[0].mean.e_ma_pct;
    assert!(dlt < 0.01, "DLT {dlt} %");
}

/// `hvs locate` on the real pair, through the CLI: the 2000 held-back pixels of `test.csv`
/// (seed 8, none of them a training point) located with a model trained on `train.csv`, and
/// scored against their true `u_r`. Not run by default (the images are not in the repository;
/// `vision/tests/dense_real.rs` says how to get them):
/// `HVS_MOTORCYCLE_DIR=/tmp/motorcycle cargo test --release -p hvs-host --test cli locate_on_the_real_pair -- --ignored --nocapture`
#[test]
#[ignore = "needs HVS_MOTORCYCLE_DIR (the Motorcycle images)"]
fn locate_on_the_real_pair() {
    let images = PathBuf::from(std::env::var("HVS_MOTORCYCLE_DIR").expect("HVS_MOTORCYCLE_DIR"));
    let dir = Scratch::new();
    let (train, test) = (fixture("train.csv"), fixture("test.csv"));
    let model = dir.p("m.hvsw");
    ok_line(&format!("train --data {} -o {model} --seed 7", train.display()));
    let truth = std::fs::read_to_string(&test).unwrap();
    let mut pixels = String::from("u_l,v_l,true_u_r\n");
    for l in truth.lines().skip(1) {
        let f: Vec<&str> = l.split(',').collect();
        pixels.push_str(&format!("{},{},{}\n", f[0], f[1], f[2]));
    }
    std::fs::write(dir.p("px.csv"), pixels).unwrap();
    let (l, r) = (images.join("motorcycle_left.png"), images.join("motorcycle_right.png"));
    let out = ok_line(&format!(
        "locate --model {model} --left {} --right {} --points {}",
        l.display(),
        r.display(),
        dir.p("px.csv")
    ));
    let (mut n, mut returned, mut within_1, mut off_2) = (0, 0, 0, 0);
    for row in out.lines().skip(1) {
        let f: Vec<&str> = row.split(',').collect();
        n += 1;
        if f[8] != "ok" {
            continue;
        }
        returned += 1;
        let e = (f[2].parse::<f64>().unwrap() - f[9].parse::<f64>().unwrap()).abs();
        within_1 += usize::from(e <= 1.0);
        off_2 += usize::from(e >= 2.0);
    }
    let pct = |a: usize, b: usize| 100.0 * a as f64 / b as f64;
    let (w1, o2) = (pct(within_1, n), pct(off_2, returned));
    eprintln!(
        "hvs locate, Motorcycle, {n} held-back pixels: {:.1} % returned, {w1:.1} % within 1 px, \
         {o2:.2} % of the returned 2 px or more off",
        pct(returned, n)
    );
    assert_eq!(n, 2000);
    // Regression bounds (the goals are 85 % and 2 %).
    assert!(w1 >= 80.0 && o2 <= 4.0, "{w1} % within 1 px, {o2} % off");
}
