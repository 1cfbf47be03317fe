//! Board images' stack paint and high-water words (`fw_core::stack` sweeps them): the one
//! stack of esp-hal's linker script (`_stack_end`, lowest, to `_stack_start`), above
//! esp-hal's stack guard word (`__stack_chk_guard`, watched by a data watchpoint: never
//! written here).

extern "C" {
    static mut __stack_chk_guard: u32;
    static _stack_start: u32;
}

/// Words just below the stack pointer left alone when painting (this function's frame).
const GAP: usize = 256;

/// The painted range: the first word above the guard, and the stack's top.
pub fn bounds() -> (usize, usize) {
    // Addresses of linker symbols, not read.
    let guard = core::ptr::addr_of!(__stack_chk_guard) as usize;
    let top = core::ptr::addr_of!(_stack_start) as usize;
    (guard + 4, top)
}

/// Paints the stack below the caller's frame with `mib::memory::STACK_PAINT`. Call once,
/// first thing at start-up.
#[inline(never)]
pub fn paint() {
    let sp: usize;
    // SAFETY: reads the stack pointer.
    unsafe { core::arch::asm!("mv {}, sp", out(reg) sp) };
    let (mut a, _) = bounds();
    while a + GAP < sp {
        // SAFETY: free stack between the guard word and the current frame.
        unsafe { core::ptr::write_volatile(a as *mut u32, fw_core::stack::PAINT_WORD) };
        a += 4;
    }
}

/// The stack word at `addr` (inside [`bounds`]).
pub fn word(addr: usize) -> u32 {
    // SAFETY: `fw_core::stack::StackWatch` only reads inside the bounds given to it.
    unsafe { core::ptr::read_volatile(addr as *const u32) }
}
