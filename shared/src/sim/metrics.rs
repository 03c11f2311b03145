//! Error measures of the thesis: e_ma (eq. 4.1-5), the mean absolute depth error, and the
//! percentage form used in its figures, `mean(|Z - Z^| / Z) * 100`.

/// Running e_ma accumulator, usable without allocation.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct EmaAcc {
    sum_abs: f64,
    sum_pct: f64,
    max_pct: f64,
    n: u64,
}

impl EmaAcc {
    /// Adds one (true depth, estimated depth) pair. A non-finite estimate counts as an
    /// infinite error, so a broken estimator can never look good.
    pub fn add(&mut self, z: f64, z_hat: f64) {
        let abs = if z_hat.is_finite() { libm::fabs(z - z_hat) } else { f64::INFINITY };
        let pct = abs / libm::fabs(z) * 100.0;
        self.sum_abs += abs;
        self.sum_pct += pct;
        if pct.is_nan() || pct > self.max_pct {
            self.max_pct = pct;
        }
        self.n += 1;
    }
    /// Number of pairs.
    pub fn count(&self) -> u64 {
        self.n
    }
    /// e_ma in cm (eq. 4.1-5), NaN when empty.
    pub fn e_ma(&self) -> f64 {
        self.sum_abs / self.n as f64
    }
    /// e_ma in percent of the true depth, NaN when empty.
    pub fn e_ma_pct(&self) -> f64 {
        self.sum_pct / self.n as f64
    }
    /// Largest single percentage error.
    pub fn max_pct(&self) -> f64 {
        self.max_pct
    }
}

/// e_ma (eq. 4.1-5) of paired slices, in cm. NaN if empty or of unequal length.
pub fn e_ma(z: &[f64], z_hat: &[f64]) -> f64 {
    fold(z, z_hat).map_or(f64::NAN, |a| a.e_ma())
}

/// e_ma in percent: `mean(|Z - Z^| / Z) * 100`. NaN if empty or of unequal length.
pub fn e_ma_pct(z: &[f64], z_hat: &[f64]) -> f64 {
    fold(z, z_hat).map_or(f64::NAN, |a| a.e_ma_pct())
}

fn fold(z: &[f64], z_hat: &[f64]) -> Option<EmaAcc> {
    if z.is_empty() || z.len() != z_hat.len() {
        return None;
    }
    let mut acc = EmaAcc::default();
    for (a, b) in z.iter().zip(z_hat) {
        acc.add(*a, *b);
    }
    Some(acc)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn by_hand() {
        assert_eq!(e_ma(&[100.0, 50.0], &[98.0, 53.0]), 2.5);
        // 2 % and 6 % -> 4 %.
        assert!((e_ma_pct(&[100.0, 50.0], &[98.0, 53.0]) - 4.0).abs() < 1e-12);
        assert!(e_ma(&[], &[]).is_nan());
        assert!(e_ma(&[1.0], &[]).is_nan());
        assert_eq!(e_ma_pct(&[100.0], &[f64::NAN]), f64::INFINITY);
        let mut a = EmaAcc::default();
        a.add(100.0, 90.0);
        a.add(100.0, 101.0);
        assert_eq!(a.max_pct(), 10.0);
        assert_eq!(a.count(), 2);
    }
}
