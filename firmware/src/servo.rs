//! The two `ServoOutput` implementations (conversions and clamping are `hvs_shared::runtime::servo`'s):
//!
//! - [`Mcdc`]: Faulhaber MCDC 3006 S drives on USART2 (PA2 TX, [`MCDC_BAUD`] 8N1), one node per
//!   axis: `<node>LA<counts>\r<node>M\r` for each axis whose counts changed since the last
//!   command (a head at rest sends nothing). Halt: `<node>V0\r` (stop and hold).
//! - [`Pwm`] (feature `pwm`): 50 Hz hobby servos on five timer channels through
//!   `embedded_hal::pwm::SetDutyCycle`. Halt: the timers keep the last pulses (hold).
//!
//! Every angle goes through `McdcConfig::counts` / `PwmConfig::pulse_us`, which clamp to the
//! joint limits whatever the setpoint is.

use hvs_shared::runtime::gaze::{Axis, JointLimits, Joints};
use hvs_shared::runtime::servo::ServoOutput;

/// The MCDC drives of this head (nodes, counts per degree, zero offsets).
#[cfg(not(feature = "pwm"))]
pub const MCDC: hvs_shared::runtime::servo::McdcConfig =
    hvs_shared::runtime::servo::McdcConfig::DEFAULT;

/// The hobby servos of this head (centre pulses, microseconds per degree).
#[cfg(feature = "pwm")]
pub const PWM: hvs_shared::runtime::servo::PwmConfig =
    hvs_shared::runtime::servo::PwmConfig::DEFAULT;

/// Baud rate of the MCDC line. The drives ship at 9600; 115200 (`BAUD115200`, `EEPSAV` once
/// per drive) leaves room for five axes at 100 Hz.
#[cfg(not(feature = "pwm"))]
pub const MCDC_BAUD: u32 = 115_200;

/// MCDC drives on a byte sink (USART2's transmit half).
#[cfg(not(feature = "pwm"))]
pub struct Mcdc<W: embedded_io::Write> {
    tx: W,
    cfg: hvs_shared::runtime::servo::McdcConfig,
    limits: JointLimits,
    last: [Option<i32>; 5],
}

#[cfg(not(feature = "pwm"))]
impl<W: embedded_io::Write> Mcdc<W> {
    /// Drives on `tx`; nothing is sent until the first command.
    pub fn new(tx: W, cfg: hvs_shared::runtime::servo::McdcConfig, limits: JointLimits) -> Self {
        Mcdc {
            tx,
            cfg,
            limits,
            last: [None; 5],
        }
    }
}

#[cfg(not(feature = "pwm"))]
impl<W: embedded_io::Write> ServoOutput for Mcdc<W> {
    type Error = W::Error;

    fn command(&mut self, joints: &Joints) -> Result<(), W::Error> {
        use hvs_shared::runtime::servo::{format_mcdc, McdcCmd};
        for axis in Axis::ALL {
            let i = axis.index();
            let counts = self.cfg.counts(&self.limits, axis, joints[axis]);
            if self.last[i] == Some(counts) {
                continue;
            }
            let node = self.cfg.0[i].node;
            self.tx
                .write_all(&format_mcdc(node, McdcCmd::LoadAbsolute(counts)))?;
            self.tx.write_all(&format_mcdc(node, McdcCmd::Move))?;
            self.last[i] = Some(counts);
        }
        Ok(())
    }

    fn halt(&mut self) -> Result<(), W::Error> {
        for line in self.cfg.halt_commands() {
            self.tx.write_all(&line)?;
        }
        Ok(())
    }
}

/// Hobby servos on five PWM channels (any timers), in `Axis` order.
#[cfg(feature = "pwm")]
pub struct Pwm<'a, E: embedded_hal::pwm::Error> {
    channels: [&'a mut dyn embedded_hal::pwm::SetDutyCycle<Error = E>; 5],
    cfg: hvs_shared::runtime::servo::PwmConfig,
    limits: JointLimits,
}

#[cfg(feature = "pwm")]
impl<'a, E: embedded_hal::pwm::Error> Pwm<'a, E> {
    /// Servos on `channels`, each a timer channel running at `hvs_shared::runtime::servo::PWM_HZ`.
    pub fn new(
        channels: [&'a mut dyn embedded_hal::pwm::SetDutyCycle<Error = E>; 5],
        cfg: hvs_shared::runtime::servo::PwmConfig,
        limits: JointLimits,
    ) -> Self {
        Pwm {
            channels,
            cfg,
            limits,
        }
    }
}

#[cfg(feature = "pwm")]
impl<E: embedded_hal::pwm::Error> ServoOutput for Pwm<'_, E> {
    type Error = E;

    fn command(&mut self, joints: &Joints) -> Result<(), E> {
        use hvs_shared::runtime::servo::{duty_for, PWM_PERIOD_US};
        for axis in Axis::ALL {
            let ch = &mut self.channels[axis.index()];
            let pulse = self.cfg.pulse_us(&self.limits, axis, joints[axis]);
            let duty = duty_for(pulse, ch.max_duty_cycle(), PWM_PERIOD_US);
            ch.set_duty_cycle(duty)?;
        }
        Ok(())
    }

    fn halt(&mut self) -> Result<(), E> {
        // The timers keep producing the last pulses: the servos hold where they are.
        Ok(())
    }
}

/// Panic-time halt of the MCDC drives: `V0` to every node on USART2 by polling its registers
/// (the `Mcdc` value is out of reach in the panic handler).
#[cfg(not(feature = "pwm"))]
pub fn panic_halt() {
    use stm32f4xx_hal::pac;
    // SAFETY: called once with interrupts disabled, when no other code runs any more; the
    // USART2 registers are only polled and written byte by byte, as the HAL's writer does.
    let usart = unsafe { &*pac::USART2::ptr() };
    if usart.cr1().read().te().bit_is_clear() {
        return; // Never configured: nothing was commanded.
    }
    for line in MCDC.halt_commands() {
        for &b in line.iter() {
            let mut spins = 0u32;
            while usart.sr().read().txe().bit_is_clear() {
                spins += 1;
                if spins > 1_000_000 {
                    return;
                }
            }
            usart.dr().write(|w| unsafe { w.dr().bits(u16::from(b)) });
        }
    }
}

/// Panic-time halt for PWM: nothing to do, the timers hold the last pulses.
#[cfg(feature = "pwm")]
pub fn panic_halt() {}
