//! Flash layout of the head controller (STM32F405/407, 1 MiB): where the code and the two
//! weight slots live. The root `memory.x` states the same numbers; a test checks they agree.

/// Start of the internal flash.
pub const FLASH_BASE: u32 = 0x0800_0000;
/// Bytes of flash for code (sectors 0-9).
pub const CODE_LEN: u32 = 768 * 1024;
/// Weight slot A: flash sector 10.
pub const SLOT_A_ADDR: u32 = 0x080C_0000;
/// Weight slot B: flash sector 11.
pub const SLOT_B_ADDR: u32 = 0x080E_0000;
/// Size of each weight slot (one 128 KiB sector).
pub const SLOT_LEN: u32 = 128 * 1024;
/// Flash sector number of slot A.
pub const SLOT_A_SECTOR: u8 = 10;
/// Flash sector number of slot B.
pub const SLOT_B_SECTOR: u8 = 11;
/// Start of SRAM.
pub const RAM_BASE: u32 = 0x2000_0000;
/// Bytes of SRAM (SRAM1 + SRAM2).
pub const RAM_LEN: u32 = 128 * 1024;

/// One of the two weight slots.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum Slot {
    /// Sector 10.
    A,
    /// Sector 11.
    B,
}

impl Slot {
    /// First byte of the slot.
    pub const fn addr(self) -> u32 {
        match self {
            Slot::A => SLOT_A_ADDR,
            Slot::B => SLOT_B_ADDR,
        }
    }
    /// Flash sector of the slot.
    pub const fn sector(self) -> u8 {
        match self {
            Slot::A => SLOT_A_SECTOR,
            Slot::B => SLOT_B_SECTOR,
        }
    }
    /// The other slot.
    pub const fn other(self) -> Slot {
        match self {
            Slot::A => Slot::B,
            Slot::B => Slot::A,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn slots_are_sectors_after_code() {
        assert_eq!(FLASH_BASE + CODE_LEN, SLOT_A_ADDR);
        assert_eq!(SLOT_A_ADDR + SLOT_LEN, SLOT_B_ADDR);
        assert_eq!(SLOT_B_ADDR + SLOT_LEN, FLASH_BASE + 1024 * 1024);
        assert!(crate::runtime::blob::MAX_BLOB_LEN as u32 <= SLOT_LEN);
    }
}
