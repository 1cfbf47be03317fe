//! Time on the `virt` machine: the CLINT's `mtime` (10 MHz, following the host's clock
//! without `-icount`), and a wait for the next millisecond (`wfi` on the machine timer,
//! so an idle board does not spin the host's CPU).
#![allow(unsafe_code)]

const MTIME: usize = 0x0200_BFF8;
const MTIMECMP: usize = 0x0200_4000;
const TICKS_PER_MS: u64 = 10_000;

fn mtime() -> u64 {
    loop {
        // SAFETY: the CLINT's mtime register pair (read-only here), word-wide.
        let (hi, lo, hi2) = unsafe {
            (
                core::ptr::read_volatile((MTIME + 4) as *const u32),
                core::ptr::read_volatile(MTIME as *const u32),
                core::ptr::read_volatile((MTIME + 4) as *const u32),
            )
        };
        if hi == hi2 {
            return (u64::from(hi) << 32) | u64::from(lo);
        }
    }
}

/// Milliseconds since the machine started.
pub fn now_ms() -> u64 {
    mtime() / TICKS_PER_MS
}

/// Sleeps until the next millisecond at most: the machine timer's compare register is
/// set 1 ms ahead and its interrupt enabled in `mie` (but not taken: `mstatus.MIE` stays
/// clear), so `wfi` returns when it is pending.
pub fn idle_1ms() {
    let at = mtime() + TICKS_PER_MS;
    // SAFETY: hart 0's mtimecmp (the high word first at its maximum, so that no
    // intermediate value fires early); `wfi` only waits.
    unsafe {
        core::ptr::write_volatile((MTIMECMP + 4) as *mut u32, u32::MAX);
        core::ptr::write_volatile(MTIMECMP as *mut u32, at as u32);
        core::ptr::write_volatile((MTIMECMP + 4) as *mut u32, (at >> 32) as u32);
        riscv::register::mie::set_mtimer();
    }
    riscv::asm::wfi();
}
