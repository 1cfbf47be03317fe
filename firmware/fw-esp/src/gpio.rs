//! GPIO helpers: the arm-switch line with a switchable internal pull, for module
//! discovery's probe (`fw_core::modules::PullProbe`).

use esp_hal::delay::Delay;
use esp_hal::gpio::{Input, InputConfig, Pull};
use fw_core::modules::PullProbe;
use fw_core::periph::HwError;

/// Settling time after a pull change: the internal pull (≈ 45 kΩ) charges the line's
/// few tens of pF in well under a microsecond; 20 µs leaves margin for a cable.
const SETTLE_US: u32 = 20;

/// An input pin whose internal pull-up or pull-down is selected for a read.
pub struct PullLine<'a, 'd>(pub &'a mut Input<'d>);

impl PullProbe for PullLine<'_, '_> {
    fn level_with_pull(&mut self, pull_up: bool) -> Result<bool, HwError> {
        let pull = if pull_up { Pull::Up } else { Pull::Down };
        self.0.apply_config(&InputConfig::default().with_pull(pull));
        Delay::new().delay_micros(SETTLE_US);
        Ok(self.0.is_high())
    }
}
