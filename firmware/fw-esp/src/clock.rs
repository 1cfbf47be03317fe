//! Time for the domain and the OBSW: milliseconds since boot, from the embassy time
//! driver (esp-rtos on SYSTIMER/TIMG0).

/// Milliseconds since boot.
pub fn now_ms() -> u64 {
    embassy_time::Instant::now().as_millis()
}
