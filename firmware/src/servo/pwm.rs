//! Servo backend (feature `pwm`): 50 Hz hobby servos on five timer channels, TIM3 CH1-4 (PA6,
//! PA7, PB0, PB1) and TIM4 CH1 (PB6), through `embedded_hal::pwm::SetDutyCycle`. Halt: the
//! timers keep the last pulses (the servos hold), so [`panic_halt`] has nothing to do.
//!
//! Every angle goes through `PwmConfig::pulse_us`, which clamps to the joint limits whatever
//! the setpoint is. The other backend is `mcdc.rs`, with the same interface.

use crate::ServoParts;
use core::convert::Infallible;
use embedded_hal::pwm::SetDutyCycle;
use hvs_shared::runtime::gaze::{Axis, JointLimits, Joints};
use hvs_shared::runtime::servo::{duty_for, PwmConfig, ServoOutput, PWM_HZ, PWM_PERIOD_US};
use stm32f4xx_hal::{pac, prelude::*, rcc::Rcc, timer::PwmChannel};

/// The hobby servos of this head (centre pulses, microseconds per degree).
pub const PWM: PwmConfig = PwmConfig::DEFAULT;

/// The five timer channels, in `Axis` order.
type Channels = (
    PwmChannel<pac::TIM3, 0>,
    PwmChannel<pac::TIM3, 1>,
    PwmChannel<pac::TIM3, 2>,
    PwmChannel<pac::TIM3, 3>,
    PwmChannel<pac::TIM4, 0>,
);

/// The servos of this build.
pub struct Servos {
    channels: Channels,
    cfg: PwmConfig,
    limits: JointLimits,
}

/// Starts TIM3 and TIM4 at `PWM_HZ` on the five servo pins (duty 0 until the first command).
pub fn init(parts: ServoParts, limits: JointLimits, rcc: &mut Rcc) -> Servos {
    let ServoParts { tim3, tim4, pa6, pa7, gpiob, .. } = parts;
    let gpiob = gpiob.split(rcc);
    let (_, (t3c1, t3c2, t3c3, t3c4)) = tim3.pwm_hz(PWM_HZ.Hz(), rcc);
    let (_, (t4c1, ..)) = tim4.pwm_hz(PWM_HZ.Hz(), rcc);
    let mut channels = (
        t3c1.with(pa6),
        t3c2.with(pa7),
        t3c3.with(gpiob.pb0),
        t3c4.with(gpiob.pb1),
        t4c1.with(gpiob.pb6),
    );
    channels.0.enable();
    channels.1.enable();
    channels.2.enable();
    channels.3.enable();
    channels.4.enable();
    Servos { channels, cfg: PWM, limits }
}

impl ServoOutput for Servos {
    type Error = Infallible;

    fn command(&mut self, joints: &Joints) -> Result<(), Infallible> {
        let (cfg, limits) = (self.cfg, self.limits);
        // One call per channel type, no `dyn`: a trait object would link every default method
        // of `SetDutyCycle` five times (about 700 B of flash) for the two used here.
        let (a, b, c, d, e) = &mut self.channels;
        set(a, &cfg, &limits, Axis::NeckPan, joints)?;
        set(b, &cfg, &limits, Axis::NeckTilt, joints)?;
        set(c, &cfg, &limits, Axis::EyeTilt, joints)?;
        set(d, &cfg, &limits, Axis::LeftEyePan, joints)?;
        set(e, &cfg, &limits, Axis::RightEyePan, joints)
    }

    fn halt(&mut self) -> Result<(), Infallible> {
        // The timers keep producing the last pulses: the servos hold where they are.
        Ok(())
    }
}

/// Axis `axis`'s pulse on channel `ch`, clamped to its limits by `PwmConfig::pulse_us`.
fn set<C: SetDutyCycle<Error = Infallible>>(
    ch: &mut C,
    cfg: &PwmConfig,
    limits: &JointLimits,
    axis: Axis,
    joints: &Joints,
) -> Result<(), Infallible> {
    let pulse = cfg.pulse_us(limits, axis, joints[axis]);
    ch.set_duty_cycle(duty_for(pulse, ch.max_duty_cycle(), PWM_PERIOD_US))
}

/// Panic-time halt for PWM: nothing to do, the timers hold the last pulses.
pub fn panic_halt() {}
