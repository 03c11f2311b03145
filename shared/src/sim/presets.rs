//! The thesis' four experimental cases as rig presets, and its board protocol.
//!
//! The values are those of the project's `cases.json` (a copy lives in
//! `shared/tests/fixtures/`, and a test checks these constants against it): rigs that
//! reproduce the traditional-method error ranges of the thesis' Figs. 4.8-4.11.

use crate::runtime::gaze::HALF_BASELINE_CM;
use crate::sim::camera::Rig;

const ONE_HALF_DEG: f64 = 0.008_726_646_259_971_648;

const fn rig(phi_l: f64, phi_r: f64, alpha_l: f64, alpha_r: f64, beta0: f64, phi0: f64) -> Rig {
    Rig {
        half_baseline: HALF_BASELINE_CM,
        phi_u_left: phi_l,
        phi_u_right: phi_r,
        phi_v_left: phi_l,
        phi_v_right: phi_r,
        alpha_left: alpha_l,
        alpha_right: alpha_r,
        beta0,
        phi0,
        u0: 320.0,
        v0: 240.0,
        width: 640,
        height: 480,
    }
}

/// Case I: parallel optic axes, same focal length.
pub const CASE_1: Rig = rig(285.836, 285.350_078_8, 0.0, 0.0, 0.0, 0.0);
/// Case II: parallel optic axes, distinct focal lengths.
pub const CASE_2: Rig = rig(285.836, 406.887_546, 0.0, 0.0, 0.0, 0.0);
/// Case III: slight deflection between the optic axes (pan, tilt, roll).
pub const CASE_3: Rig = rig(285.836, 285.350_078_8, -0.0299, 0.0299, ONE_HALF_DEG, ONE_HALF_DEG);
/// Case IV: distinct focal lengths and deflected optic axes.
pub const CASE_4: Rig =
    rig(285.836, 228.668_800_000_000_03, -0.0455, 0.0455, ONE_HALF_DEG, ONE_HALF_DEG);

/// Human-readable labels of the cases.
pub const LABELS: [&str; 4] = [
    "I: parallel optic axes, same focal length",
    "II: parallel optic axes, distinct focal lengths",
    "III: slight deflection between the optic axes (pan/tilt/roll)",
    "IV: distinct focal lengths and deflected optic axes",
];

/// Case `n` (1-4).
pub fn case(n: u8) -> Option<Rig> {
    match n {
        1 => Some(CASE_1),
        2 => Some(CASE_2),
        3 => Some(CASE_3),
        4 => Some(CASE_4),
        _ => None,
    }
}

/// Board X positions of the training points (cm).
pub const TRAIN_BOARD_X: [f64; 4] = [-3.0, -1.0, 1.0, 3.0];
/// Board Y positions of the training points (cm).
pub const TRAIN_BOARD_Y: [f64; 3] = [-2.0, 0.0, 2.0];
/// Depths of the training boards (cm).
pub const TRAIN_DEPTHS: [f64; 6] = [65.0, 85.0, 105.0, 125.0, 145.0, 165.0];
/// The two test points P1, P2 (X, Y in cm).
pub const TEST_POINTS_XY: [[f64; 2]; 2] = [[-1.75, 0.0], [1.75, 0.0]];
/// Depths of the test boards (cm).
pub const TEST_DEPTHS: [f64; 11] =
    [65.0, 75.0, 85.0, 95.0, 105.0, 115.0, 125.0, 135.0, 145.0, 155.0, 165.0];

/// The 12 training-board points at depth `z`, row by row (Y outer, X inner), as in the data files.
pub fn board_points(z: f64) -> [[f64; 3]; 12] {
    let mut out = [[0.0; 3]; 12];
    let mut k = 0;
    for y in TRAIN_BOARD_Y {
        for x in TRAIN_BOARD_X {
            out[k] = [x, y, z];
            k += 1;
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::camera::CameraError;

    #[test]
    fn noisy_projection_is_exact_without_noise_and_shifts_with_it() {
        for n in 1..=4 {
            let rig = case(n).unwrap();
            for p in [[-3.0, -2.0, 65.0], [1.75, 0.0, 165.0], [2.9, 1.3, 97.3]] {
                assert_eq!(rig.project_rounded_noisy(&p, &[0.0; 4]), rig.project_rounded(&p));
            }
        }
        // Parallel rig, Phi X / Z = 15.75 on the left: +0.3 px of noise rounds to 16, -0.3 to 15.
        let rig = Rig::parallel(300.0);
        let p = [0.0, 0.0, 100.0];
        assert_eq!(rig.project_rounded_noisy(&p, &[0.3, 0.0, 0.0, 0.0]).unwrap()[0], 336.0);
        assert_eq!(rig.project_rounded_noisy(&p, &[-0.3, 0.0, 0.0, 0.0]).unwrap()[0], 335.0);
        assert_eq!(rig.project_rounded_noisy(&p, &[0.0, -0.6, 0.0, 0.0]).unwrap()[1], 239.0);
        assert_eq!(rig.project_rounded_noisy(&p, &[0.0, 0.0, 0.0, 1.6]).unwrap()[3], 242.0);
        assert_eq!(
            rig.project_rounded_noisy(&p, &[f64::NAN, 0.0, 0.0, 0.0]),
            Err(CameraError::NonFinite)
        );
        assert_eq!(
            rig.project_rounded_noisy(&[0.0, 0.0, -1.0], &[0.0; 4]),
            Err(CameraError::BehindLeft)
        );
    }
}
