//! Bolter fastener-pair multiplexer: two GPIOs A0/A1 route the bolter drive to pair 1..4.
//! The select code is the one `mmic_domain::types::mux_bits` produces (pair n = n−1,
//! A0 = bit 0, A1 = bit 1).

use super::{HwError, PairSelect};
use embedded_hal::digital::OutputPin;

/// Levels of (A0, A1) for select code `bits` (0..=3).
pub const fn mux_levels(bits: u8) -> Option<(bool, bool)> {
    if bits > 3 {
        return None;
    }
    Some((bits & 1 != 0, bits & 2 != 0))
}

pub struct BolterMux<P0, P1> {
    a0: P0,
    a1: P1,
    code: Option<u8>,
}

impl<P0: OutputPin, P1: OutputPin> BolterMux<P0, P1> {
    pub fn new(a0: P0, a1: P1) -> Self {
        Self { a0, a1, code: None }
    }
    /// Select code currently driven (`None` before the first selection).
    pub fn code(&self) -> Option<u8> {
        self.code
    }
}

impl<P0: OutputPin, P1: OutputPin> PairSelect for BolterMux<P0, P1> {
    fn select(&mut self, bits: u8) -> Result<(), HwError> {
        if self.code == Some(bits) {
            return Ok(());
        }
        let (l0, l1) = mux_levels(bits).ok_or(HwError::OutOfRange)?;
        self.a0.set_state(l0.into()).map_err(|_| HwError::Driver)?;
        self.a1.set_state(l1.into()).map_err(|_| HwError::Driver)?;
        self.code = Some(bits);
        Ok(())
    }
}
