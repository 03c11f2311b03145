//! `hvs-firmware`: the hvs-depth head controller for an STM32F405 (Cortex-M4F).
//!
//! This crate owns only I/O; every decision and every number comes from `hvs-shared`:
//!
//! - boot: reads both weight slots straight from flash (`hvs_shared::runtime::layout` addresses, at most
//!   `MAX_BLOB_LEN` bytes each) and hands them to `hvs_shared::runtime::head::boot`, which runs the
//!   valid, runnable slot with the higher generation, or the traditional method;
//! - USART1 (PA9 TX, PA10 RX, 115200 8N1): the protocol of `hvs_shared::runtime::protocol`. Bytes are
//!   received by interrupt into a ring buffer; frames are decoded and answered in the main loop;
//!   the head announces itself with `Ready` once it listens;
//! - a 100 Hz SysTick control tick (see [`servo`]) that advances the gaze trajectory and
//!   commands the servos through one `ServoOutput` (MCDC 3006 S on USART2, or PWM with the
//!   `pwm` feature);
//! - panic and HardFault: interrupts off, `V0` (stop and hold) to every MCDC drive (PWM timers
//!   hold the last pulses), halt.
//!
//! Features: `qemu` (16 MHz HSI, SysTick counted at QEMU's fixed 168 MHz), `pwm` (the servo
//! backend `servo/pwm.rs` instead of `servo/mcdc.rs`), `bench`, `defmt` (bring-up logging over
//! RTT, see [`log`]; off in the measured builds).
#![no_std]
#![no_main]

mod bench;
mod clock;
mod link;
#[macro_use]
mod log;
#[cfg(not(feature = "pwm"))]
#[path = "servo/mcdc.rs"]
mod servo;
#[cfg(feature = "pwm")]
#[path = "servo/pwm.rs"]
mod servo;
mod stack;

use core::mem::MaybeUninit;
use core::sync::atomic::{AtomicU32, Ordering};
use cortex_m::peripheral::syst::SystClkSource;
use cortex_m_rt::{entry, exception};
use hvs_shared::runtime::blob::MAX_BLOB_LEN;
use hvs_shared::runtime::gaze::GazeConfig;
use hvs_shared::runtime::head::{self, Boot, Estimator, Head, MainLoop};
use hvs_shared::runtime::layout::{SLOT_A_ADDR, SLOT_B_ADDR};
use hvs_shared::runtime::protocol::{
    self, ErrorCode, FirmwareVersion, FrameAccumulator, Request, RequestBody, Response,
    ResponseBody, SlotStatus, MAX_FRAME_LEN, PROTOCOL_VERSION, UNSOLICITED_ID,
};
use hvs_shared::runtime::servo::ServoOutput;
use hvs_shared::runtime::traditional::Calibration;
use hvs_shared::runtime::trajectory::{ControllerConfig, GazeController};
use stm32f4xx_hal::{pac, prelude::*};

/// This firmware's version (the crate version).
const VERSION: FirmwareVersion = FirmwareVersion {
    major: parse_u16(env!("CARGO_PKG_VERSION_MAJOR")),
    minor: parse_u16(env!("CARGO_PKG_VERSION_MINOR")),
    patch: parse_u16(env!("CARGO_PKG_VERSION_PATCH")),
};

const fn parse_u16(s: &str) -> u16 {
    let b = s.as_bytes();
    let mut v: u16 = 0;
    let mut i = 0;
    while i < b.len() {
        v = v * 10 + (b[i] - b'0') as u16;
        i += 1;
    }
    v
}

/// Control ticks since boot, counted by the SysTick exception.
static TICKS: AtomicU32 = AtomicU32::new(0);

/// The bytes of a weight slot as the CPU sees them in flash.
fn slot_bytes(addr: u32) -> &'static [u8] {
    // SAFETY: the slot addresses are inside the STM32F405's 1 MiB flash (memory.x reserves
    // them; `hvs_shared::runtime::layout` tests check they lie within flash), which is always mapped
    // and readable, never written by this firmware, and `MAX_BLOB_LEN` (4 KiB) is less than
    // the 128 KiB slot.
    unsafe { core::slice::from_raw_parts(addr as *const u8, MAX_BLOB_LEN) }
}

/// Fixation settings of this head (neck/eye split, geometry, joint limits).
const GAZE: GazeConfig = GazeConfig::DEFAULT;
/// Trajectory settings (0.7 s neck, 0.2 s eyes, the same joint limits, 100 Hz).
const CONTROL: ControllerConfig =
    ControllerConfig { limits: GAZE.limits, ..ControllerConfig::DEFAULT };

#[entry]
fn main() -> ! {
    // The head (with the running network's decoded blob, about 2.5 KB) lives in static RAM,
    // not in main's frame. cortex-m-rt turns this into a `&'static mut` (main runs once).
    static mut HEAD: MaybeUninit<Head> = MaybeUninit::uninit();

    let dp = pac::Peripherals::take().unwrap_or_else(|| halt(HaltReason::Peripherals));
    let cp = cortex_m::Peripherals::take().unwrap_or_else(|| halt(HaltReason::CorePeripherals));
    let mut rcc = dp.RCC.freeze(clock::config());

    // Boot decision first: nothing is commanded before it is known what runs. The head starts
    // in fallback mode, then boots in place from the two slots.
    let head = init_head(HEAD);
    head.boot.boot_in_place(slot_bytes(SLOT_A_ADDR), slot_bytes(SLOT_B_ADDR));
    log::boot(&head.boot);

    let gpioa = dp.GPIOA.split(&mut rcc);
    let parts = ServoParts {
        usart2: dp.USART2,
        tim3: dp.TIM3,
        tim4: dp.TIM4,
        pa2: gpioa.pa2,
        pa6: gpioa.pa6,
        pa7: gpioa.pa7,
        gpiob: dp.GPIOB,
    };
    let mut servos = servo::init(parts, GAZE.limits, &mut rcc);

    let mut tx = link::init(dp.USART1, gpioa.pa9, gpioa.pa10, &mut rcc);

    let tick_hz = clock::systick_hz(&rcc);
    let mut syst = cp.SYST;
    syst.set_clock_source(SystClkSource::Core);
    syst.set_reload(tick_hz / CONTROL.control_hz - 1);
    syst.clear_current();
    syst.enable_counter();
    syst.enable_interrupt();

    let mut out = [0u8; MAX_FRAME_LEN];
    send(
        &mut tx,
        &mut out,
        &Response { id: UNSOLICITED_ID, body: ResponseBody::Ready { protocol: PROTOCOL_VERSION } },
    );

    let mut acc = FrameAccumulator::<MAX_FRAME_LEN>::new();
    // The servos are left alone until the first Look or Home (the loop's arming rule).
    let mut main_loop = MainLoop::new();
    let mut ticks_done = TICKS.load(Ordering::Relaxed);
    loop {
        // Control ticks first (every one, so the per-tick rate limit holds on the wire too).
        let now = TICKS.load(Ordering::Relaxed);
        while ticks_done != now {
            ticks_done = ticks_done.wrapping_add(1);
            let tick = main_loop.tick(head);
            if tick.command {
                // A transport error loses this tick's commands; the next tick resends.
                let _ = servos.command(&tick.setpoint);
            }
        }
        let Some(byte) = link::pop() else {
            cortex_m::asm::wfi();
            continue;
        };
        let resp = match acc.push(byte) {
            None => continue,
            Some(frame) => {
                let r = main_loop.frame(frame, |req| answer(head, req, tick_hz));
                if r.id == UNSOLICITED_ID {
                    log!("protocol error: {}", defmt::Debug2Format(&r.body));
                }
                r
            }
        };
        send(&mut tx, &mut out, &resp);
    }
}

/// A head at rest in fallback mode, built in `place` (out of line: the temporaries are gone
/// before boot decodes the slots).
#[inline(never)]
fn init_head(place: &'static mut MaybeUninit<Head>) -> &'static mut Head {
    let controller =
        GazeController::new(&CONTROL).unwrap_or_else(|_| halt(HaltReason::ControllerConfig));
    // Field by field (what `Head::new` does), so the compiler writes straight into `place`.
    place.write(Head {
        boot: Boot {
            slot_a: SlotStatus::Empty,
            slot_b: SlotStatus::Empty,
            estimator: Estimator::Fallback(Calibration::BUILT_IN),
        },
        gaze: GAZE,
        controller,
        ticks: 0,
    })
}

fn answer(head: &mut Head, req: &Request, tick_hz: u32) -> Response {
    match req.body {
        RequestBody::Bench { point, count } => {
            Response { id: req.id, body: bench::run(&head.boot, &point, count, tick_hz) }
        }
        RequestBody::Info => Response {
            id: req.id,
            body: ResponseBody::Info(protocol::InfoData {
                stack_peak: Some(stack::peak()),
                ..head.boot.info(VERSION)
            }),
        },
        _ => head.respond(req, VERSION),
    }
}

fn send(tx: &mut link::Tx, buf: &mut [u8], resp: &Response) {
    // Every response fits MAX_FRAME_LEN (tested in hvs-shared); if one ever did not, say so.
    let frame = match protocol::encode_response(resp, buf) {
        Ok(f) => f,
        Err(_) => match protocol::encode_response(&head::frame_error(ErrorCode::Malformed), buf) {
            Ok(f) => f,
            Err(_) => return,
        },
    };
    link::write_all(tx, frame);
}

#[exception]
fn SysTick() {
    TICKS.fetch_add(1, Ordering::Relaxed);
}

/// The peripherals a servo backend may take (each backend takes the ones it drives).
pub struct ServoParts {
    /// MCDC line (transmit only).
    pub usart2: pac::USART2,
    /// PWM channels 1-4.
    pub tim3: pac::TIM3,
    /// PWM channel 5.
    pub tim4: pac::TIM4,
    /// USART2 TX.
    pub pa2: stm32f4xx_hal::gpio::PA2,
    /// TIM3 CH1.
    pub pa6: stm32f4xx_hal::gpio::PA6,
    /// TIM3 CH2.
    pub pa7: stm32f4xx_hal::gpio::PA7,
    /// TIM3 CH3-4 (PB0, PB1), TIM4 CH1 (PB6).
    pub gpiob: pac::GPIOB,
}

/// Why the firmware stopped for good (logged with the `defmt` feature).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum HaltReason {
    /// The device peripherals were already taken.
    Peripherals,
    /// The core peripherals were already taken.
    CorePeripherals,
    /// The trajectory settings are unusable.
    ControllerConfig,
    /// The servo backend could not be configured.
    ServoInit,
    /// The protocol USART could not be configured.
    LinkInit,
    /// A panic.
    Panic,
    /// A HardFault.
    HardFault,
}

/// Stops here for good: no interrupt runs again, so no servo is commanded again.
fn halt(reason: HaltReason) -> ! {
    cortex_m::interrupt::disable();
    log!("halt: {}", reason);
    #[cfg(not(feature = "defmt"))]
    let _ = reason;
    loop {
        cortex_m::asm::nop();
    }
}

#[panic_handler]
fn panic(_info: &core::panic::PanicInfo) -> ! {
    // No formatting of the message without `defmt`: it would pull core::fmt into the image.
    // MCDC drives get V0 (stop and hold); PWM timers run on without the CPU (hold the last
    // pulses).
    cortex_m::interrupt::disable();
    servo::panic_halt();
    log!("panic: {}", defmt::Display2Format(_info));
    halt(HaltReason::Panic)
}

/// A fault (bus, memory management, usage escalated to HardFault) ends like a panic: the MCDC
/// drives get `V0`, then the core halts, instead of the default handler's silent spin.
#[exception]
unsafe fn HardFault(_frame: &cortex_m_rt::ExceptionFrame) -> ! {
    cortex_m::interrupt::disable();
    servo::panic_halt();
    halt(HaltReason::HardFault)
}
