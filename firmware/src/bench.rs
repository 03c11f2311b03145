//! The `Bench` request: times many inferences with SysTick (feature `bench`).
//!
//! Under QEMU with `-icount shift=0` one instruction takes 1 ns of virtual time and SysTick
//! counts at 168 MHz, so `ticks * 1e9 / tick_hz / count` is instructions per inference
//! (`firmware/measure.sh` does this). The loop runs with interrupts off; an empty loop of the
//! same shape is timed too and subtracted.

use hvs_shared::runtime::head::Boot;
use hvs_shared::runtime::protocol::{ErrorCode, ResponseBody, StereoPoint};

/// Most inferences per request: 2000 4-5-3 inferences stay well inside one SysTick period
/// (10 ms = 10 M instructions in QEMU), so at most one wrap has to be accounted for.
#[cfg(feature = "bench")]
pub const MAX_COUNT: u32 = 2000;

/// The inference timed: the head's own (`Network::infer`).
#[cfg(all(feature = "bench", not(feature = "bench-micromath")))]
fn infer(
    net: &hvs_shared::runtime::head::Network,
    x: &[f32; 4],
    joints: &hvs_shared::runtime::gaze::Joints,
) -> Result<[f32; 3], hvs_shared::runtime::mlp::MlpError> {
    net.infer(x, joints)
}

/// The inference timed with `bench-micromath` (an evaluation build, not a head build): the
/// 4-5-3 net with `hvs_shared::runtime::activation`'s micromath sigmoid, out of line and in
/// place like `Network::infer`'s fast path, then the family's output map; other nets as the
/// head runs them.
#[cfg(feature = "bench-micromath")]
#[inline(never)]
fn infer(
    net: &hvs_shared::runtime::head::Network,
    x: &[f32; 4],
    joints: &hvs_shared::runtime::gaze::Joints,
) -> Result<[f32; 3], hvs_shared::runtime::mlp::MlpError> {
    use hvs_shared::runtime::activation::sigmoid_micromath;
    use hvs_shared::runtime::mlp::infer_fixed_into;
    if net.fast {
        let mut y = [0.0f32; 3];
        infer_fixed_into::<4, 5, 3>(&net.blob.flat(), x, &mut y, sigmoid_micromath)?;
        net.blob.family.output_map.apply(&mut y)?;
        return Ok(y);
    }
    net.infer(x, joints)
}

/// Answers `Bench`.
#[cfg(not(feature = "bench"))]
pub fn run(_: &Boot, _: &StereoPoint, _: u32, _: u32) -> ResponseBody {
    ResponseBody::Error(ErrorCode::Unsupported)
}

/// Answers `Bench`: `count` (capped) network inferences of `point`.
#[cfg(feature = "bench")]
pub fn run(boot: &Boot, point: &StereoPoint, count: u32, tick_hz: u32) -> ResponseBody {
    use core::hint::black_box;
    use cortex_m::peripheral::SYST;
    use hvs_shared::runtime::gaze::Joints;
    use hvs_shared::runtime::head::Estimator;
    use hvs_shared::runtime::protocol::BenchData;

    let Estimator::Network(net) = &boot.estimator else {
        return ResponseBody::Error(ErrorCode::Unsupported);
    };
    if !point.is_finite() {
        return ResponseBody::Error(ErrorCode::NonFinite);
    }
    let count = count.clamp(1, MAX_COUNT);
    let x = point.to_array();
    let reload = SYST::get_reload() + 1;
    // Elapsed ticks of `f`, from the down-counting SysTick and its COUNTFLAG (read-to-clear).
    let time = |f: &dyn Fn()| -> u32 {
        cortex_m::interrupt::free(|_| {
            // SAFETY: reading SYST_CSR only clears COUNTFLAG, which nothing else uses.
            let csr = || unsafe { (*SYST::PTR).csr.read() };
            let _ = csr();
            let t0 = SYST::get_current();
            f();
            let t1 = SYST::get_current();
            let wrapped = csr() & (1 << 16) != 0;
            if wrapped {
                t0 + reload - t1
            } else {
                t0.wrapping_sub(t1)
            }
        })
    };
    let overhead = time(&|| {
        for _ in 0..count {
            black_box(black_box(&x));
        }
    });
    let total = time(&|| {
        for _ in 0..count {
            let _ = black_box(infer(net, black_box(&x), black_box(&Joints::HOME)));
        }
    });
    ResponseBody::Bench(BenchData {
        count,
        ticks: total.saturating_sub(overhead),
        overhead_ticks: overhead,
        tick_hz,
    })
}
