//! The thesis' reported values (its chapter 4 text and figures), exactly as printed: the one
//! table `RESULTS.md`, `hvs demo` and the tests compare our numbers against.

/// Fig. 4.3: mean Phi_L (px, on the thesis' images, whose resolution it does not state).
pub const PHI_L_MEAN: f64 = 142.918;
/// Fig. 4.3: the "variation" of Phi_L over the depths (%; the thesis does not define it).
pub const PHI_L_VARIATION_PCT: f64 = 0.24116;
/// Fig. 4.4: difference between the mean Phi_L and Phi_R (%).
pub const PHI_LR_PCT: f64 = 0.27821;
/// Figs. 4.8-4.11: the traditional method's per-depth e_ma range (%), lowest and highest, per
/// case I-IV.
pub const TRADITIONAL_PCT: [[f64; 2]; 4] =
    [[0.017387, 1.7834], [15.1465, 18.9796], [58.3189, 1145.9954], [155.1946, 2653.9037]];
/// Fig. 4.12: per-depth e_ma range of the 4-5-3 net on case IV (%).
pub const NET_CASE4_PCT: [f64; 2] = [0.48455, 2.4771];
/// Figs. 4.16-4.19 (section 4.2.2): the bound on the proposed net's worst per-depth e_ma (%),
/// "even in the worst case ... well below 4 %".
pub const NET_BOUND_PCT: f64 = 4.0;
/// Fig. 4.20: mean test e_ma when trained at 65 and 165 cm only (%).
pub const TWO_DEPTHS_MEAN_PCT: f64 = 53.0081;
/// Fig. 4.22: "around 5 %" with four training depths.
pub const FOUR_DEPTHS_PCT: f64 = 5.0;

/// The thesis' traditional-method range of case `case` (1-4) as printed, `lo .. hi %`.
pub fn traditional_range(case: u8) -> Option<String> {
    let [lo, hi] = TRADITIONAL_PCT.get(usize::from(case).checked_sub(1)?)?;
    Some(format!("{lo} .. {hi} %"))
}

/// The thesis' result for Figs. 4.20-4.22 by the number of training depths (2, 3, 4): what it
/// prints, for a table cell.
pub fn fewer_depths(depths: usize) -> String {
    match depths {
        2 => format!("mean {TWO_DEPTHS_MEAN_PCT} %"),
        4 => format!("about {FOUR_DEPTHS_PCT} %"),
        _ => "(no number)".to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cells_print_the_table() {
        assert_eq!(traditional_range(1).unwrap(), "0.017387 .. 1.7834 %");
        assert_eq!(traditional_range(4).unwrap(), "155.1946 .. 2653.9037 %");
        assert_eq!(traditional_range(0), None);
        assert_eq!(traditional_range(5), None);
        assert_eq!(fewer_depths(2), "mean 53.0081 %");
        assert_eq!(fewer_depths(4), "about 5 %");
        assert_eq!(fewer_depths(3), "(no number)");
    }
}
