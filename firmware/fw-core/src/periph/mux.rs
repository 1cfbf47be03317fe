//! Bolter fastener-pair multiplexer: two GPIOs A0/A1 select pair 1..4.

use super::{HwError, PairSelect};
use embedded_hal::digital::OutputPin;

/// Levels of (A0, A1) for `pair` 1..=4: pair n is the binary code n−1.
pub const fn mux_levels(pair: u8) -> Option<(bool, bool)> {
    if pair < 1 || pair > mib::robot::bolter::PAIRS_PER_FACE {
        return None;
    }
    let code = pair - 1;
    Some((code & 1 != 0, code & 2 != 0))
}

pub struct BolterMux<P0, P1> {
    a0: P0,
    a1: P1,
    selected: u8,
}

impl<P0: OutputPin, P1: OutputPin> BolterMux<P0, P1> {
    pub fn new(a0: P0, a1: P1) -> Self {
        Self {
            a0,
            a1,
            selected: 0,
        }
    }
    /// Pair currently routed (0 before the first selection).
    pub fn selected(&self) -> u8 {
        self.selected
    }
}

impl<P0: OutputPin, P1: OutputPin> PairSelect for BolterMux<P0, P1> {
    fn select_pair(&mut self, pair: u8) -> Result<(), HwError> {
        let (l0, l1) = mux_levels(pair).ok_or(HwError::OutOfRange)?;
        self.a0.set_state(l0.into()).map_err(|_| HwError::Driver)?;
        self.a1.set_state(l1.into()).map_err(|_| HwError::Driver)?;
        self.selected = pair;
        Ok(())
    }
}
