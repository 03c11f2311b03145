//! The posture simulator at the home posture reproduces the thesis data files exactly: the
//! pixels of every fixture row of the four cases, through `posture::HeadRig` at
//! `Joints::HOME`, equal the file's and `Rig::project_rounded`'s.

use hvs_shared::runtime::gaze::Joints;
use hvs_shared::sim::posture::HeadRig;
use hvs_shared::sim::presets;
use std::path::PathBuf;

#[test]
fn home_posture_reproduces_the_fixture_pixels() {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures");
    let mut rows = 0;
    for n in 1..=4u8 {
        let rig = presets::case(n).unwrap();
        // A neck centre off the baseline must not matter at home.
        let head = HeadRig { neck_centre_cm: [0.0, 6.0, -4.0], ..HeadRig::new(rig) };
        for set in ["train", "test"] {
            let path = dir.join(format!("case{n}_{set}.csv"));
            let text = std::fs::read_to_string(&path).unwrap();
            for line in text.lines().skip(1).filter(|l| !l.trim().is_empty()) {
                let v: Vec<f64> = line.split(',').map(|s| s.trim().parse().unwrap()).collect();
                let p = [v[4], v[5], v[6]];
                let px = head.project_rounded(&Joints::HOME, &p).unwrap();
                assert_eq!(px.to_vec(), v[..4].to_vec(), "{}: {line}", path.display());
                assert_eq!(Ok(px), rig.project_rounded(&p));
                rows += 1;
            }
        }
    }
    assert_eq!(rows, 4 * (72 + 22));
}
