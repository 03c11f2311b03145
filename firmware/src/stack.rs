//! Stack high-water mark, measured on the head: cortex-m-rt's `paint-stack` fills the whole
//! stack region (`_stack_end` .. `_stack_start`, everything in RAM above the statics) with
//! [`STACK_PAINT_VALUE`] at reset, before `main`; [`peak`] finds the lowest word that no longer
//! holds it. The answer is a lower bound only if code wrote the paint value itself at the
//! deepest word, which no code here does on purpose.

use cortex_m_rt::STACK_PAINT_VALUE;

extern "C" {
    static _stack_end: u32;
    static _stack_start: u32;
}

/// Deepest the stack has been since reset, in bytes.
pub fn peak() -> u32 {
    // Only the addresses of the linker symbols are taken, never their values.
    let (lo, hi) =
        (core::ptr::addr_of!(_stack_end) as usize, core::ptr::addr_of!(_stack_start) as usize);
    let mut p = lo;
    // SAFETY: every word in `lo..hi` is RAM (cortex-m-rt's linker script checks the bounds);
    // volatile, because the stack is written behind the compiler's back.
    while p < hi && unsafe { core::ptr::read_volatile(p as *const u32) } == STACK_PAINT_VALUE {
        p += 4;
    }
    (hi - p) as u32
}
