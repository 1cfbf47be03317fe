//! Each board's stack high-water mark. Both control periods run on the one stack of this
//! loop, so each is measured on its own: the stack below the measuring frame is painted
//! with `mib::memory::STACK_PAINT` ([`fw_core::stack::PAINT_WORD`]), the period runs, and
//! the lowest word no longer holding the paint is the deepest it went — the method board
//! A's image uses over its whole stack (`fw_core::stack::StackWatch`). Only what a period
//! dirtied is painted again before the next, so a period costs its own depth twice.
#![allow(unsafe_code)]

use fw_core::stack::PAINT_WORD;

/// Bytes below the measuring frame watched: a period deeper than this is reported as
/// this deep (a full probe).
pub const PROBE_BYTES: usize = 64 * 1024;
/// Bytes just below the measuring frame left unpainted (`paint`'s own frame, a leaf of a
/// few words): a period shallower than this reads as this deep.
const GAP: usize = 128;

/// The paint below the measuring frame and the deepest use of each measured period.
pub struct Probe {
    /// Lowest word that may not hold the paint (`None`: nothing painted yet).
    dirty_low: Option<usize>,
}

impl Probe {
    pub const fn new() -> Self {
        Probe { dirty_low: None }
    }

    /// Runs `f` and returns how deep it used the stack below this function's frame, in
    /// bytes. Call it from the same frame every time (the loop), so the depths compare.
    #[inline(never)]
    pub fn depth<R>(&mut self, f: impl FnOnce() -> R) -> (R, usize) {
        let sp: usize;
        // SAFETY: reads the stack pointer register.
        unsafe { core::arch::asm!("mv {}, sp", out(reg) sp) };
        let (low, high) = (sp - PROBE_BYTES, sp - GAP);
        paint(self.dirty_low.unwrap_or(low).max(low), high);
        let r = f();
        let mut a = low;
        // SAFETY: [low, high) is free stack below this frame (QEMU's 32 MiB of RAM hold
        // the stack far deeper than the probe), read word by word.
        while a < high && unsafe { core::ptr::read_volatile(a as *const u32) } == PAINT_WORD {
            a += 4;
        }
        self.dirty_low = Some(a);
        (r, sp - a)
    }
}

#[inline(never)]
fn paint(from: usize, to: usize) {
    let mut a = from & !3;
    while a < to {
        // SAFETY: free stack below the caller's frame and above `paint`'s own (GAP).
        unsafe { core::ptr::write_volatile(a as *mut u32, PAINT_WORD) };
        a += 4;
    }
}
