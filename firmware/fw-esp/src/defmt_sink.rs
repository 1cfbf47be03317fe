//! Where the defmt frames of esp-hal, esp-rtos and embassy go: nowhere.
//!
//! The images build those crates with their `defmt` feature (firmware/Cargo.toml): their
//! panics, `unwrap!`s and log lines are then encoded by defmt, whose format strings stay in
//! the ELF's non-loaded `.defmt` section, instead of being formatted with `core::fmt` and
//! `Debug` (the GPIO signal-name tables, panic strings and locations: ≈ 9.8 KB of flash and
//! 1.2 KB of RAM on board A). Neither board has a defmt transport (board A's USB port is
//! the ground link, board B's prints its boot report as text), so this logger drops every
//! frame — as the same crates' `log` output was dropped before (no `log` feature).
//!
//! A panic inside those crates goes through defmt's panic path to [`defmt_panic`], which
//! panics again with a static message: the panic record then holds this file and line
//! (board A's PREVIOUS_PANIC: CRC-32 of `fw-esp/src/defmt_sink.rs`), not the line inside
//! esp-hal, and board B's console prints this message instead of esp-hal's text.

/// The global defmt logger: drops every frame.
#[defmt::global_logger]
struct Discard;

// SAFETY: every method is a no-op; there is no state to protect, so the contract (acquire
// before write, no re-entrancy) holds trivially.
unsafe impl defmt::Logger for Discard {
    fn acquire() {}
    unsafe fn flush() {}
    unsafe fn release() {}
    unsafe fn write(_bytes: &[u8]) {}
}

/// defmt's panic path (`defmt::panic!`, `defmt::unwrap!`, `defmt::assert!` in esp-hal,
/// esp-rtos and embassy) ends here; the message was a defmt frame, dropped above.
#[defmt::panic_handler]
fn defmt_panic() -> ! {
    panic!("panic in esp-hal, esp-rtos or embassy (defmt; message not kept)")
}
