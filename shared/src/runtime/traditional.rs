//! Depth from matched pixels without a network.
//!
//! - [`traditional_depth`]: eq. 3.1-17, `Z = Phi 2d / u_sd`, for parallel cameras with equal
//!   focal lengths; [`traditional_xyz`] adds X and Y the same way (this is the firmware's
//!   fallback when no valid model is on flash).
//! - [`general_depth`]: eq. 3.1-16, `Z = (Phi_L X_L - Phi_R X_R) / u_sd`.
//! - [`phi_estimate`]: eq. 4.1-3, `Phi = mean(u_sd Z / 2d)` over board points at a known depth.
//!
//! This is what the head runs when no model is on flash. The accuracy floor (optimal
//! triangulation with the true cameras) is the simulator's (`sim::triangulate`).

use serde::{Deserialize, Serialize};

/// Why a triangulation has no answer.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum TriError {
    /// Disparity `u_l - u_r` is zero or negative: the point would be at infinity or behind.
    NonPositiveDisparity,
    /// An input or a calibration value is NaN or infinite, or a calibration value is not positive.
    NonFinite,
    /// No samples were given.
    Empty,
    /// The rays are parallel or the solver diverged.
    Degenerate,
}

impl core::fmt::Display for TriError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            TriError::NonPositiveDisparity => "zero or negative disparity",
            TriError::NonFinite => "non-finite input or invalid calibration",
            TriError::Empty => "no samples",
            TriError::Degenerate => "degenerate geometry",
        })
    }
}

/// The traditional method's calibration: one `Phi = k_u f` for both cameras and the half
/// baseline, plus the principal point. Stored in the weights blob as the fallback.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
pub struct Calibration {
    /// `Phi = k_u f` (px).
    pub phi: f32,
    /// Half baseline `d` (cm).
    pub half_baseline: f32,
    /// Principal point u (px).
    pub u0: f32,
    /// Principal point v (px).
    pub v0: f32,
}

/// The derive's encoding, written with one `f32` serializer: a compact format (postcard: the
/// blob, the protocol) gets the four fields in order, exactly the derive's bytes, from a loop
/// over an array instead of four inlined copies (flash on the head); a human-readable one
/// (JSON) gets the derive's map.
impl Serialize for Calibration {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        if s.is_human_readable() {
            use serde::ser::SerializeStruct;
            let mut st = s.serialize_struct("Calibration", 4)?;
            st.serialize_field("phi", &self.phi)?;
            st.serialize_field("half_baseline", &self.half_baseline)?;
            st.serialize_field("u0", &self.u0)?;
            st.serialize_field("v0", &self.v0)?;
            st.end()
        } else {
            [self.phi, self.half_baseline, self.u0, self.v0].serialize(s)
        }
    }
}

impl Calibration {
    /// Phi of case I estimated by eq. 4.1-3 at Z = 65 cm (`cases.json`), the thesis' HVS with
    /// its 640x480 images: the firmware's built-in calibration when no valid model is on flash.
    pub const BUILT_IN: Calibration = Calibration {
        phi: 284.761_9,
        half_baseline: super::gaze::HALF_BASELINE_CM as f32,
        u0: 320.0,
        v0: 240.0,
    };

    /// Whether every value is finite and `phi`, `half_baseline` are positive.
    pub fn is_valid(&self) -> bool {
        self.phi.is_finite()
            && self.phi > 0.0
            && self.half_baseline.is_finite()
            && self.half_baseline > 0.0
            && self.u0.is_finite()
            && self.v0.is_finite()
    }
}

/// Eq. 3.1-17: `Z = Phi * 2d / (u_l - u_r)`.
pub fn traditional_depth(
    phi: f64,
    half_baseline: f64,
    u_l: f64,
    u_r: f64,
) -> Result<f64, TriError> {
    depth_eq_3_1_17(phi, half_baseline, u_l, u_r, |u_sd| u_sd <= 0.0)
}

/// Eq. 3.1-17 evaluated as printed, whatever the sign of the disparity: a negative disparity
/// gives a negative depth. This is how the thesis plots the traditional method's error
/// (Figs. 4.8-4.11); the head's fallback ([`traditional_xyz`]) refuses such pixels instead.
pub fn traditional_depth_signed(
    phi: f64,
    half_baseline: f64,
    u_l: f64,
    u_r: f64,
) -> Result<f64, TriError> {
    depth_eq_3_1_17(phi, half_baseline, u_l, u_r, |u_sd| u_sd == 0.0)
}

/// Eq. 3.1-17 for finite inputs whose disparity `u_l - u_r` is not `refused`.
fn depth_eq_3_1_17(
    phi: f64,
    half_baseline: f64,
    u_l: f64,
    u_r: f64,
    refused: fn(f64) -> bool,
) -> Result<f64, TriError> {
    if !(phi.is_finite() && half_baseline.is_finite() && u_l.is_finite() && u_r.is_finite()) {
        return Err(TriError::NonFinite);
    }
    let u_sd = u_l - u_r;
    if refused(u_sd) {
        return Err(TriError::NonPositiveDisparity);
    }
    Ok(phi * 2.0 * half_baseline / u_sd)
}

/// Eq. 3.1-16: `Z = (Phi_L X_L - Phi_R X_R) / u_sd`, with `X_L`, `X_R` the point's X in the
/// left and right camera frames.
pub fn general_depth(
    phi_l: f64,
    phi_r: f64,
    x_l: f64,
    x_r: f64,
    u_sd: f64,
) -> Result<f64, TriError> {
    if ![phi_l, phi_r, x_l, x_r, u_sd].iter().all(|v| v.is_finite()) {
        return Err(TriError::NonFinite);
    }
    if u_sd <= 0.0 {
        return Err(TriError::NonPositiveDisparity);
    }
    Ok((phi_l * x_l - phi_r * x_r) / u_sd)
}

/// Eq. 4.1-3: `Phi = (1/n) sum (u_sd)_i Z / 2d` over `(u_l, u_r)` pixel pairs of board points
/// at the known depth `z` (the board symmetric about the centre line).
pub fn phi_estimate(pairs: &[(f64, f64)], z: f64, half_baseline: f64) -> Result<f64, TriError> {
    if pairs.is_empty() {
        return Err(TriError::Empty);
    }
    if !(z.is_finite() && half_baseline.is_finite() && half_baseline > 0.0) {
        return Err(TriError::NonFinite);
    }
    let mut sum = 0.0;
    for &(u_l, u_r) in pairs {
        if !(u_l.is_finite() && u_r.is_finite()) {
            return Err(TriError::NonFinite);
        }
        sum += (u_l - u_r) * z / (2.0 * half_baseline);
    }
    let phi = sum / pairs.len() as f64;
    if phi <= 0.0 {
        return Err(TriError::NonPositiveDisparity);
    }
    Ok(phi)
}

/// The traditional method in f32 for all three coordinates (the firmware's fallback):
/// `Z` by eq. 3.1-17, then `X = Z ((u_l-u0) + (u_r-u0)) / 2 Phi` and
/// `Y = Z ((v_l-v0) + (v_r-v0)) / 2 Phi` (the same similar triangles, averaged over both eyes).
pub fn traditional_xyz(cal: &Calibration, px: &[f32; 4]) -> Result<[f32; 3], TriError> {
    if !cal.is_valid() || !px.iter().all(|v| v.is_finite()) {
        return Err(TriError::NonFinite);
    }
    let u_sd = px[0] - px[2];
    if u_sd <= 0.0 {
        return Err(TriError::NonPositiveDisparity);
    }
    let z = cal.phi * 2.0 * cal.half_baseline / u_sd;
    let x = z * ((px[0] - cal.u0) + (px[2] - cal.u0)) / (2.0 * cal.phi);
    let y = z * ((px[1] - cal.v0) + (px[3] - cal.v0)) / (2.0 * cal.phi);
    let out = [x, y, z];
    if out.iter().all(|v| v.is_finite()) {
        Ok(out)
    } else {
        Err(TriError::NonFinite)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn traditional_by_hand() {
        // Phi = 300, 2d = 10.5, disparity 31.5 -> Z = 100.
        assert_eq!(traditional_depth(300.0, 5.25, 335.75, 304.25), Ok(100.0));
        assert_eq!(
            traditional_depth(300.0, 5.25, 300.0, 300.0),
            Err(TriError::NonPositiveDisparity)
        );
        assert_eq!(
            traditional_depth(300.0, 5.25, 299.0, 300.0),
            Err(TriError::NonPositiveDisparity)
        );
        assert_eq!(traditional_depth(f64::NAN, 5.25, 310.0, 300.0), Err(TriError::NonFinite));
    }

    #[test]
    fn signed_traditional_keeps_negative_disparities() {
        assert_eq!(traditional_depth_signed(300.0, 5.25, 335.75, 304.25), Ok(100.0));
        assert_eq!(traditional_depth_signed(300.0, 5.25, 304.25, 335.75), Ok(-100.0));
        assert_eq!(
            traditional_depth_signed(300.0, 5.25, 300.0, 300.0),
            Err(TriError::NonPositiveDisparity)
        );
        assert_eq!(
            traditional_depth_signed(300.0, f64::INFINITY, 310.0, 300.0),
            Err(TriError::NonFinite)
        );
    }

    #[test]
    fn general_reduces_to_traditional_when_phis_equal() {
        // X_L - X_R = 2d.
        let z = general_depth(300.0, 300.0, 7.25, -3.25, 31.5).unwrap();
        assert!((z - 100.0).abs() < 1e-12);
        assert_eq!(
            general_depth(300.0, 300.0, 7.25, -3.25, 0.0),
            Err(TriError::NonPositiveDisparity)
        );
    }

    #[test]
    fn phi_estimate_by_hand() {
        // Disparities 30 and 32 at Z = 105, 2d = 10.5 -> Phi = mean(300, 320) = 310.
        let phi = phi_estimate(&[(330.0, 300.0), (352.0, 320.0)], 105.0, 5.25).unwrap();
        assert!((phi - 310.0).abs() < 1e-12);
        assert_eq!(phi_estimate(&[], 105.0, 5.25), Err(TriError::Empty));
    }
}
