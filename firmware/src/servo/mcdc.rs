//! Servo backend: Faulhaber MCDC 3006 S drives on USART2 (PA2 TX, [`MCDC_BAUD`] 8N1), one node
//! per axis: `<node>LA<counts>\r<node>M\r` for each axis whose counts changed since the last
//! command (a head at rest sends nothing). Halt: `<node>V0\r` (stop and hold), also from the
//! panic and HardFault handlers ([`panic_halt`]).
//!
//! Every angle goes through `McdcConfig::counts`, which clamps to the joint limits whatever
//! the setpoint is. The other backend is `pwm.rs` (feature `pwm`), with the same interface.

use crate::ServoParts;
use hvs_shared::runtime::gaze::{Axis, JointLimits, Joints};
use hvs_shared::runtime::servo::{format_mcdc, McdcCmd, McdcConfig, ServoOutput};
use stm32f4xx_hal::{pac, prelude::*, rcc::Rcc, serial};

/// The MCDC drives of this head (nodes, counts per degree, zero offsets).
pub const MCDC: McdcConfig = McdcConfig::DEFAULT;

/// Baud rate of the MCDC line. The drives ship at 9600; 115200 (`BAUD115200`, `EEPSAV` once
/// per drive) leaves room for five axes at 100 Hz.
pub const MCDC_BAUD: u32 = 115_200;

/// The servos of this build.
pub type Servos = Mcdc<serial::Tx<pac::USART2>>;

/// Configures USART2 (transmit only) for the drives; nothing is sent until the first command.
pub fn init(parts: ServoParts, limits: JointLimits, rcc: &mut Rcc) -> Servos {
    let ServoParts { usart2, pa2, .. } = parts;
    let tx = match usart2.tx(pa2, MCDC_BAUD.bps(), rcc) {
        Ok(tx) => tx,
        Err(_) => crate::halt(crate::HaltReason::ServoInit),
    };
    Mcdc::new(tx, MCDC, limits)
}

/// MCDC drives on a byte sink (USART2's transmit half).
pub struct Mcdc<W: embedded_io::Write> {
    tx: W,
    cfg: McdcConfig,
    limits: JointLimits,
    last: [Option<i32>; 5],
}

impl<W: embedded_io::Write> Mcdc<W> {
    /// Drives on `tx`; nothing is sent until the first command.
    pub fn new(tx: W, cfg: McdcConfig, limits: JointLimits) -> Self {
        Mcdc { tx, cfg, limits, last: [None; 5] }
    }
}

impl<W: embedded_io::Write> ServoOutput for Mcdc<W> {
    type Error = W::Error;

    fn command(&mut self, joints: &Joints) -> Result<(), W::Error> {
        for axis in Axis::ALL {
            let i = axis.index();
            let counts = self.cfg.counts(&self.limits, axis, joints[axis]);
            if self.last[i] == Some(counts) {
                continue;
            }
            let node = self.cfg.0[i].node;
            self.tx.write_all(&format_mcdc(node, McdcCmd::LoadAbsolute(counts)))?;
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

/// Panic-time halt of the MCDC drives: `V0` to every node on USART2 by polling its registers
/// (the `Mcdc` value is out of reach in the panic handler).
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
