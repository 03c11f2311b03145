//! A tiny deterministic random source for weight initialisation: SplitMix64.
//!
//! Each restart gets its own generator from `(seed, restart index)` alone, so no state is
//! shared between threads and the result does not depend on how rayon schedules restarts.

/// SplitMix64 (Steele, Lea, Flood 2014): 64-bit state, full period, passes BigCrush.
#[derive(Debug, Clone)]
pub(crate) struct SplitMix64 {
    state: u64,
}

impl SplitMix64 {
    /// A generator seeded with `seed`.
    pub(crate) fn new(seed: u64) -> Self {
        SplitMix64 { state: seed }
    }

    /// The generator of restart `index` of a run seeded with `seed`: the two are mixed through
    /// one SplitMix64 step each, so neighbouring seeds and indices give unrelated streams.
    pub(crate) fn for_restart(seed: u64, index: usize) -> Self {
        let a = SplitMix64::new(seed).next_u64();
        let b = SplitMix64::new(a ^ (index as u64).wrapping_mul(0xD1B5_4A32_D192_ED03)).next_u64();
        SplitMix64::new(b)
    }

    /// Next 64 random bits.
    pub(crate) fn next_u64(&mut self) -> u64 {
        self.state = self.state.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.state;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in `[0, 1)` with 53 random bits.
    pub(crate) fn next_f64(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }

    /// Uniform in `[lo, hi)`.
    pub(crate) fn uniform(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.next_f64()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reference_values_and_independent_streams() {
        // First outputs of SplitMix64 seeded with 0 (the reference implementation's values).
        let mut g = SplitMix64::new(0);
        assert_eq!(g.next_u64(), 0xE220_A839_7B1D_CDAF);
        assert_eq!(g.next_u64(), 0x6E78_9E6A_A1B9_65F4);
        let a: Vec<u64> = (0..4).map(|i| SplitMix64::for_restart(7, i).next_u64()).collect();
        for i in 0..4 {
            for j in 0..i {
                assert_ne!(a[i], a[j]);
            }
        }
        assert_ne!(
            SplitMix64::for_restart(7, 0).next_u64(),
            SplitMix64::for_restart(8, 0).next_u64()
        );
        let mut g = SplitMix64::new(3);
        for _ in 0..1000 {
            let v = g.uniform(-2.0, 5.0);
            assert!((-2.0..5.0).contains(&v));
        }
    }
}
