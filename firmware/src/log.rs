//! Bring-up logging (feature `defmt`): `defmt` messages over RTT, printed by `probe-rs run`.
//! Without the feature [`log!`] expands to nothing (its arguments are not even compiled), so
//! the measured builds carry no logging code or strings.
//!
//! Logged: the boot slot decision with what each slot held and the model that runs (or why
//! the head fell back to the traditional method), protocol errors, the reason of a halt, and
//! a panic's message.

#[cfg(feature = "defmt")]
use defmt_rtt as _;
use hvs_shared::runtime::head::Boot;

/// `defmt::info!` with the `defmt` feature, nothing without it.
#[cfg(feature = "defmt")]
macro_rules! log {
    ($($arg:tt)*) => {
        defmt::info!($($arg)*)
    };
}

/// `defmt::info!` with the `defmt` feature, nothing without it.
#[cfg(not(feature = "defmt"))]
macro_rules! log {
    ($($arg:tt)*) => {};
}

/// Logs what boot found and what runs.
#[cfg(feature = "defmt")]
pub fn boot(boot: &Boot) {
    use defmt::Debug2Format;
    use hvs_shared::runtime::head::Estimator;
    log!("boot: slot A {}, slot B {}", Debug2Format(&boot.slot_a), Debug2Format(&boot.slot_b));
    match &boot.estimator {
        Estimator::Network(n) => log!(
            "boot: running slot {} generation {}: {}-{}-{} net, seed {}, fast path {}",
            Debug2Format(&n.slot),
            n.generation,
            n.model.inputs,
            n.model.hidden,
            n.model.outputs,
            n.model.seed,
            n.fast
        ),
        Estimator::Fallback(_) => log!(
            "boot: fallback (traditional method, built-in calibration): no slot holds a valid blob this head can run"
        ),
    }
}

/// Logs what boot found and what runs (nothing without the `defmt` feature).
#[cfg(not(feature = "defmt"))]
#[inline(always)]
pub fn boot(_: &Boot) {}
