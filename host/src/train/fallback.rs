//! Fitting the traditional method's calibration (the blob's fallback) on a training set,
//! the way the thesis calibrates its HVS (eq. 4.1-3): `Phi = mean(u_sd Z / 2d)` over board
//! points at one known depth that are symmetric about the centre line, so that the
//! `X_R (Phi_L - Phi_R)` terms of eq. 4.1-2 cancel.
//!
//! Which rows: rows are grouped by their exact ground-truth `z`; in a group, a point
//! `(x, y)` is used only together with its mirror `(-x, y)` (points with `x = 0` are their
//! own mirror). The nearest depth whose symmetric subset has at least two points off the
//! centre line is used: the rounding error of `u_sd Z` grows with `Z`, so the nearest board
//! gives the best estimate (on case I's training board at 65 cm this is the `phi_px` of
//! `cases.json`). In posture-aware sets only rows at the home posture (all joint angles 0)
//! count. No such group: no fallback. The arithmetic is `hvs_shared::runtime::traditional::phi_estimate`.

use crate::data::dataset::Dataset;
use hvs_shared::runtime::traditional::{phi_estimate, Calibration};
use std::collections::{BTreeMap, HashMap};

/// A fitted fallback and where it came from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FallbackFit {
    /// The calibration to store.
    pub calibration: Calibration,
    /// Phi before conversion to f32 (px).
    pub phi: f64,
    /// Depth of the board used (cm).
    pub depth: f64,
    /// Number of symmetric points used.
    pub points: usize,
}

/// Fits the fallback on `data` (which must have ground truth), with the rig's half baseline
/// and principal point (not learnable from board points alone). `None` when the data hold no
/// symmetric board (e.g. random volume points).
pub fn fit(data: &Dataset, half_baseline: f64, u0: f64, v0: f64) -> Option<FallbackFit> {
    if !data.has_targets() {
        return None;
    }
    // Rows by depth (exact value), nearest first.
    let mut by_depth: BTreeMap<u64, Vec<usize>> = BTreeMap::new();
    for (i, t) in data.targets.iter().enumerate() {
        let home = data.row(i)[4..].iter().all(|a| *a == 0.0);
        if home && t[2] > 0.0 {
            // Positive finite f64 order like their bit patterns.
            by_depth.entry(t[2].to_bits()).or_default().push(i);
        }
    }
    for rows in by_depth.values() {
        let key = |x: f64, y: f64| ((x + 0.0).to_bits(), (y + 0.0).to_bits());
        let mut count: HashMap<(u64, u64), usize> = HashMap::new();
        for &i in rows {
            let t = data.targets[i];
            *count.entry(key(t[0], t[1])).or_default() += 1;
        }
        let mut used: HashMap<(u64, u64), usize> = HashMap::new();
        let mut pairs = Vec::new();
        let mut off_centre = 0;
        for &i in rows {
            let t = data.targets[i];
            let k = key(t[0], t[1]);
            let mirror = count.get(&key(-t[0], t[1])).copied().unwrap_or(0);
            let allowed = count[&k].min(mirror);
            let u = used.entry(k).or_default();
            if *u < allowed {
                *u += 1;
                let r = data.row(i);
                pairs.push((r[0], r[2]));
                if t[0] != 0.0 {
                    off_centre += 1;
                }
            }
        }
        if off_centre < 2 {
            continue;
        }
        let z = data.targets[rows[0]][2];
        if let Ok(phi) = phi_estimate(&pairs, z, half_baseline) {
            let calibration = Calibration {
                phi: phi as f32,
                half_baseline: half_baseline as f32,
                u0: u0 as f32,
                v0: v0 as f32,
            };
            if calibration.is_valid() {
                return Some(FallbackFit { calibration, phi, depth: z, points: pairs.len() });
            }
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::sets::{simulate, SetKind, SimOptions};
    use hvs_shared::runtime::blob::InputKind;
    use hvs_shared::sim::presets;

    fn set(rig: &hvs_shared::sim::camera::Rig, kind: SetKind) -> Dataset {
        let mut d = Dataset::new(InputKind::Stereo);
        for s in simulate(rig, kind, &SimOptions::default()).unwrap() {
            d.push(&s.px, Some(s.xyz));
        }
        d
    }

    #[test]
    fn case_one_board_gives_the_phi_of_cases_json() {
        let f = fit(&set(&presets::CASE_1, SetKind::Train), 5.25, 320.0, 240.0).unwrap();
        assert_eq!(f.depth, 65.0);
        assert_eq!(f.points, 12);
        assert!((f.phi - 284.761_904_761_904_7).abs() < 1e-9, "{}", f.phi);
        assert_eq!(f.calibration, Calibration::BUILT_IN);
    }

    #[test]
    fn asymmetric_points_are_left_out() {
        let mut d = set(&presets::CASE_1, SetKind::Train);
        let full = fit(&d, 5.25, 320.0, 240.0).unwrap();
        // An extra point at 65 cm without a mirror must not change Phi.
        d.push(&[400.0, 240.0, 350.0, 240.0], Some([7.0, 0.0, 65.0]));
        assert_eq!(fit(&d, 5.25, 320.0, 240.0).unwrap(), full);
        // Test sets are symmetric too (P1, P2 at +-1.75 cm): the nearest depth is used.
        let t = fit(&set(&presets::CASE_2, SetKind::Test), 5.25, 320.0, 240.0).unwrap();
        assert_eq!((t.depth, t.points), (65.0, 2));
    }

    #[test]
    fn no_symmetric_board_no_fallback() {
        let mut d = Dataset::new(InputKind::Stereo);
        let rig = presets::CASE_1;
        for s in simulate(&rig, SetKind::Volume, &SimOptions { points: 50, ..Default::default() })
            .unwrap()
        {
            d.push(&s.px, Some(s.xyz));
        }
        assert_eq!(fit(&d, 5.25, 320.0, 240.0), None);
        assert_eq!(fit(&Dataset::new(InputKind::Stereo), 5.25, 320.0, 240.0), None);
    }
}
