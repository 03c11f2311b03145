//! Clock configuration: 168 MHz from the HSE through the PLL on real boards, the 16 MHz HSI
//! under QEMU (feature `qemu`: QEMU models no RCC, a PLL request would wait forever).

#[cfg(not(feature = "qemu"))]
use stm32f4xx_hal::prelude::*;
use stm32f4xx_hal::rcc::{Config, Rcc};

/// External crystal of the board (Netduino Plus 2 and many STM32F405 boards: 25 MHz; boards
/// with an 8 MHz crystal change this one line).
#[cfg(not(feature = "qemu"))]
const HSE_HZ: u32 = 25_000_000;

/// The RCC configuration of this build.
pub fn config() -> Config {
    #[cfg(feature = "qemu")]
    {
        Config::hsi()
    }
    #[cfg(not(feature = "qemu"))]
    {
        Config::hse(HSE_HZ.Hz()).sysclk(168.MHz())
    }
}

/// Rate at which SysTick counts with the core clock as source. QEMU's netduinoplus2 counts
/// SysTick at 168 MHz whatever RCC says, so the emulated build uses that figure.
pub fn systick_hz(rcc: &Rcc) -> u32 {
    #[cfg(feature = "qemu")]
    {
        let _ = rcc;
        168_000_000
    }
    #[cfg(not(feature = "qemu"))]
    {
        rcc.clocks.sysclk().raw()
    }
}
