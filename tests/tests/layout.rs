//! memory.x and hvs_shared::runtime::layout state the same flash layout.
use hvs_shared::runtime::layout::*;
use hvs_tests::{memory_region, workspace_root};

#[test]
fn memory_x_agrees_with_shared_layout() {
    let text =
        std::fs::read_to_string(workspace_root().join("memory.x")).expect("memory.x at the root");
    assert_eq!(memory_region(&text, "FLASH"), Some((FLASH_BASE, CODE_LEN)));
    assert_eq!(memory_region(&text, "SLOT_A"), Some((SLOT_A_ADDR, SLOT_LEN)));
    assert_eq!(memory_region(&text, "SLOT_B"), Some((SLOT_B_ADDR, SLOT_LEN)));
    assert_eq!(memory_region(&text, "RAM"), Some((RAM_BASE, RAM_LEN)));
    assert_eq!(Slot::A.addr(), 0x080C_0000);
    assert_eq!(Slot::B.addr(), 0x080E_0000);
}

#[test]
fn region_parser_rejects_what_it_cannot_read() {
    assert_eq!(
        memory_region("FLASH : ORIGIN = 0x08000000, LENGTH = 1M", "FLASH"),
        Some((0x0800_0000, 1 << 20))
    );
    assert_eq!(memory_region("FLASHX : ORIGIN = 0x0, LENGTH = 1K", "FLASH"), None);
    assert_eq!(memory_region("FLASH : ORIGIN = zz, LENGTH = 1K", "FLASH"), None);
}
