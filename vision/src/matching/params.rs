//! The matcher's knobs and their checks.

use crate::invalid::{in_range, InvalidField};

/// Knobs of the matcher.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MatchParams {
    /// Half window `r`: windows are `(2r + 1) x (2r + 1)` pixels (1..=30).
    pub half_window: u32,
    /// Smallest score of a grown window's answer (a large window fits a plane, such as a
    /// board, well; across the depth changes of a real scene it scores lower and is then
    /// not trusted).
    pub grown_min_score: f64,
    /// How much larger the scene looks in the right image than in the left, along `u` and
    /// `v` (the right window's pixel offsets are the left one's times this, sampled
    /// bilinearly): the ratio of the focal lengths, e.g. [`pinhole_right_scale`](super::pinhole_right_scale); `[1, 1]`
    /// for cameras alike (0.25..=4).
    pub right_scale: [f64; 2],
    /// Largest half window tried when the `half_window` one is ambiguous: the window doubles
    /// (`2r`, `4r`, ... up to this) until it is unique or fails otherwise (`half_window` or
    /// less: never grow). At most 60.
    pub max_half_window: u32,
    /// Smallest standard deviation of the left window (grey levels) worth correlating.
    pub min_std: f64,
    /// Smallest acceptable best ZNCC.
    pub min_score: f64,
    /// A second peak within this much ZNCC of the best makes the point ambiguous.
    pub uniqueness_margin: f64,
    /// Peaks at least this far apart (px along `u`) count as distinct.
    pub min_peak_separation_px: f64,
    /// Largest distance (px) of the left-right check's answer from the left point.
    pub lr_tolerance_px: f64,
    /// Widest disparity interval accepted (px; wider queries are an error).
    pub max_interval_px: f64,
    /// The peak may lie this far (px) beyond either end of the disparity interval.
    pub interval_slack_px: f64,
    /// When the centred window finds no acceptable peak or fails the left-right check, try
    /// four windows moved left, right, up and down by `shift_fraction * half_window` px.
    pub shifted_windows: bool,
    /// How far the shifted windows move, as a fraction of `half_window` (0..=1).
    pub shift_fraction: f64,
    /// A shifted window's answer counts only if another window's best candidate (the
    /// centred one's or another shifted one's, acceptable or not) lies within
    /// `lr_tolerance_px` of it.
    pub shifted_must_agree: bool,
    /// Adaptive support weights: a window pixel counts `exp(-|I - I_centre| / gamma)` (grey
    /// levels; `0` = every pixel counts the same), so a window across a depth edge is ruled
    /// by the pixels that look like the point, on its own surface.
    pub support_gamma: f64,
    /// The smallest support weight (0..=1): every pixel keeps at least this share, so a
    /// point whose own grey level is rare in its window (a chessboard's saddle) still
    /// correlates its whole window.
    pub support_floor: f64,
}

impl Default for MatchParams {
    /// `r = 5` (11 x 11 windows: on the development Motorcycle pair 77 % of points came back
    /// within 1 px against 73 % with 15 x 15 and 69 % with 19 x 19, and it still spans a full
    /// period of the 10 px squares at 165 cm), `min_std = 1` grey level (only truly flat
    /// windows are refused as such), `min_score = 0.5`, `uniqueness_margin = 0.05`, peaks
    /// 2 px apart are distinct, left-right tolerance 1 px, intervals up to 256 px, no
    /// interval slack (1 px of slack admitted more wrong peaks than it found right ones with
    /// intervals that hold the truth), shifted windows on (moved by a whole `r`, and they
    /// must agree), support weights `gamma = 10` grey levels with a floor of 0.2 (without a
    /// floor a chessboard saddle, whose own grey is rare in its window, lost its accuracy).
    /// Ambiguous points grow their window up to `r = 40`, trusted from a score of 0.9 (0.8
    /// and 0.95 differed by 0.1 % of points on the real pair). On the Motorcycle development
    /// seeds 1-4 (4000 points, interval true disparity +- 10 %) this took the points
    /// returned within 1 px from 77.5 % (the previous defaults) to 83.4 % with 1.3 %
    /// returned 2 px or more off. Chosen on development seeds
    /// only (rendered boards seeds 1-4, Motorcycle point seeds 1-4; tests use other seeds).
    fn default() -> Self {
        MatchParams {
            half_window: 5,
            max_half_window: 40,
            right_scale: [1.0, 1.0],
            grown_min_score: 0.9,
            min_std: 1.0,
            min_score: 0.5,
            uniqueness_margin: 0.05,
            min_peak_separation_px: 2.0,
            lr_tolerance_px: 1.0,
            max_interval_px: 256.0,
            interval_slack_px: 0.0,
            shifted_windows: true,
            shift_fraction: 1.0,
            shifted_must_agree: true,
            support_gamma: 10.0,
            support_floor: 0.2,
        }
    }
}

/// Why a matcher could not be built or a batch not run: a parameter or input is out of
/// range, and the error names it.
pub type MatchError = InvalidField;

impl MatchParams {
    /// Checks the parameters (field names in the error).
    pub fn validate(&self) -> Result<(), MatchError> {
        in_range("params.half_window", self.half_window, 1, 30)?;
        if self.max_half_window > 60 {
            return Err(InvalidField::new(
                "params.max_half_window",
                format!("must be at most 60, got {}", self.max_half_window),
            ));
        }
        let checks: [(&'static str, f64, f64, f64); 13] = [
            ("params.grown_min_score", self.grown_min_score, -1.0, 1.0),
            ("params.right_scale[0]", self.right_scale[0], 0.25, 4.0),
            ("params.right_scale[1]", self.right_scale[1], 0.25, 4.0),
            ("params.support_floor", self.support_floor, 0.0, 1.0),
            ("params.support_gamma", self.support_gamma, 0.0, 1000.0),
            ("params.interval_slack_px", self.interval_slack_px, 0.0, 100.0),
            ("params.shift_fraction", self.shift_fraction, 0.0, 1.0),
            ("params.min_std", self.min_std, 0.0, 255.0),
            ("params.min_score", self.min_score, -1.0, 1.0),
            ("params.uniqueness_margin", self.uniqueness_margin, 0.0, 2.0),
            ("params.min_peak_separation_px", self.min_peak_separation_px, 1.0, 1000.0),
            ("params.lr_tolerance_px", self.lr_tolerance_px, 0.0, 1000.0),
            ("params.max_interval_px", self.max_interval_px, 0.0, 100_000.0),
        ];
        for (field, v, lo, hi) in checks {
            if !(v.is_finite() && v >= lo && v <= hi) {
                return Err(InvalidField::new(field, format!("must be in {lo}..={hi}, got {v}")));
            }
        }
        Ok(())
    }
}
