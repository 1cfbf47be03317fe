//! Space link management (mission service 212, docs/space-link.md): key change without downtime.
//! LINK_SPI_SELECT chooses the TM SPI and the TC SPIs accepted. The core checks the
//! selection against the keys the platform reported ([`LinkKeys`]), answers PUS 1, raises
//! LINK_SPI_SELECTED and leaves the selection in `Obsw::link_select` for the platform's
//! frame endpoint to apply (and store) before it handles the next input.

use mib::link::sdls::{TC_SPIS, TM_SPIS};
use mib::params::Source;
use mib::tc::service;

use crate::accept::Tc;
use crate::downlink::Downlink;
use crate::failure::Failure;
use crate::request::unknown;
use crate::services::{Component, Contract};
use crate::tm::{TmSink, TmStore};

/// Keys the platform holds: bit i of `tm` = `TM_SPIS[i]`, of `tc` = `TC_SPIS[i]`.
/// Zero (the default): no space link, every selection is refused with NO_KEY_FOR_SPI.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LinkKeys {
    pub tm: u8,
    pub tc: u8,
}

/// A selection for the platform: TM under `tm_spi`, TC accepted under the SPIs of the
/// `tc_spis` mask (bit i = `TC_SPIS[i]`), the others retired.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LinkSelect {
    pub tm_spi: u16,
    pub tc_spis: u8,
}

impl LinkSelect {
    /// The TC SPIs of the mask.
    pub fn tc_spi_list(&self) -> heapless::Vec<u16, 8> {
        TC_SPIS
            .iter()
            .enumerate()
            .filter(|(i, _)| self.tc_spis & (1 << i) != 0)
            .map(|(_, s)| *s)
            .collect()
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Request {
    /// TC[212,1] LINK_SPI_SELECT (arguments range-checked by `accept`).
    Select(LinkSelect),
}

impl Request {
    pub fn parse(tc: &Tc) -> Result<Self, Failure> {
        match tc.subservice {
            1 => {
                let x = mib_wire::args::LinkSpiSelect::of(&tc.args);
                Ok(Request::Select(LinkSelect {
                    tm_spi: x.tm_spi,
                    tc_spis: x.tc_spis,
                }))
            }
            _ => Err(unknown(tc)),
        }
    }
}

/// Checks a selection against the keys held; the selection for the platform to apply
/// (`Obsw::link_select`).
impl Component for LinkKeys {
    const CONTRACT: Contract = Contract::new("link", Some(service::SPACE_LINK), &[Source::SpaceLink]);
    type Request<'a> = Request;
    type Output = LinkSelect;
    fn handle<S: TmStore>(
        &mut self,
        now: u64,
        r: Request,
        dl: &mut Downlink<S>,
        sink: &mut impl TmSink,
    ) -> Result<LinkSelect, Failure> {
        let Request::Select(sel) = r;
        let has = |spis: &[u16], mask: u8, spi: u16| {
            spis.iter()
                .position(|s| *s == spi)
                .is_some_and(|i| mask & (1 << i) != 0)
        };
        if !has(&TM_SPIS, self.tm, sel.tm_spi) {
            return Err(no_key_for_spi(sel.tm_spi));
        }
        if let Some(s) = sel.tc_spi_list().iter().find(|s| !has(&TC_SPIS, self.tc, **s)) {
            return Err(no_key_for_spi(*s));
        }
        let e = mib_wire::ev::LinkSpiSelected {
            tm_spi: sel.tm_spi,
            tc_spis: sel.tc_spis,
        };
        dl.raise(now, e, sink);
        Ok(sel)
    }
}

/// The refusal of a selection naming an SPI the robot holds no key for.
fn no_key_for_spi(spi: u16) -> Failure {
    Failure(mib_wire::Failure::NoKeyForSpi { spi })
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::obsw::tests::{failure, obsw, of, send};

    /// One failure of each code the service makes.
    pub(crate) fn every_failure() -> Vec<Failure> {
        std::vec![no_key_for_spi(18)]
    }

    // verifies: LINK-KEYCHG-02
    #[test]
    fn a_selection_is_refused_without_the_key_and_handed_to_the_platform_with_it() {
        let mut o = obsw();
        // No space link: refused at start (TM[1,4]), nothing handed on.
        let p = send(&mut o, 10, 1, 212, 1, &[0, 18, 2]);
        let f = of(&p, 1, 4);
        assert_eq!(f.len(), 1, "{p:?}");
        assert_eq!(failure(&f[0]), (53, vec![0, 18]));
        assert_eq!(o.link_select, None);
        // Keys for TM 17 and 18, TC 2 only: selecting TC 1 and 2 is refused naming SPI 1.
        o.link_keys = LinkKeys { tm: 0b11, tc: 0b10 };
        let p = send(&mut o, 20, 2, 212, 1, &[0, 18, 3]);
        assert_eq!(failure(&of(&p, 1, 4)[0]), (53, vec![0, 1]));
        // TM 18, TC 2: completed, evented, handed to the platform.
        let p = send(&mut o, 30, 3, 212, 1, &[0, 18, 2]);
        assert_eq!(of(&p, 1, 7).len(), 1, "{p:?}");
        assert_eq!(of(&p, 5, 3).len(), 1, "LINK_SPI_SELECTED (medium severity)");
        let sel = o.link_select.take().unwrap();
        assert_eq!((sel.tm_spi, sel.tc_spi_list().as_slice()), (18, &[2u16][..]));
        // Out of range (TM SPI 19, empty TC set): refused at acceptance.
        assert_eq!(of(&send(&mut o, 40, 4, 212, 1, &[0, 19, 1]), 1, 2).len(), 1);
        assert_eq!(of(&send(&mut o, 50, 5, 212, 1, &[0, 17, 0]), 1, 2).len(), 1);
        assert_eq!(o.link_select, None);
    }
}
