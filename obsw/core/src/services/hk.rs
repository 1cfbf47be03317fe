//! PUS 3 housekeeping: periodic reports of the MIB's HK structures (TM[3,25]),
//! enable/disable, one-shot and collection interval.

use mib::hk::HK_STRUCTS;

use crate::accept::Tc;
use crate::failure::Failure;
use crate::request::unknown;

const N_HK: usize = HK_STRUCTS.len();

/// Index of a structure in `mib::hk::HK_STRUCTS`; only made from a defined SID.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct HkIndex(usize);

impl HkIndex {
    fn of(sid: u16) -> Result<Self, Failure> {
        HK_STRUCTS
            .iter()
            .position(|h| h.sid == sid)
            .map(HkIndex)
            .ok_or(Failure::unknown_sid(sid))
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Request {
    /// TC[3,5]
    Enable(HkIndex),
    /// TC[3,6]
    Disable(HkIndex),
    /// TC[3,27]
    OneShot(HkIndex),
    /// TC[3,31]
    SetInterval(HkIndex, u32),
}

impl Request {
    pub fn parse(tc: &Tc) -> Result<Self, Failure> {
        use mib_wire::args;
        Ok(match tc.subservice {
            5 => Request::Enable(HkIndex::of(args::HkEnable::of(&tc.args).sid)?),
            6 => Request::Disable(HkIndex::of(args::HkDisable::of(&tc.args).sid)?),
            27 => Request::OneShot(HkIndex::of(args::HkOneShot::of(&tc.args).sid)?),
            // Range-checked against the MIB's interval limits by `accept`.
            31 => {
                let x = mib_wire::args::HkSetInterval::of(&tc.args);
                Request::SetInterval(HkIndex::of(x.sid)?, x.interval_ms)
            }
            _ => return Err(unknown(tc)),
        })
    }
}

#[derive(Clone, Copy, Debug, Default)]
struct HkState {
    enabled: bool,
    interval: u32,
    next: u64,
}

/// Generation state of every HK structure.
pub struct Hk {
    s: [HkState; N_HK],
}

impl Hk {
    pub fn new() -> Self {
        let mut s = [HkState::default(); N_HK];
        for (h, d) in s.iter_mut().zip(HK_STRUCTS) {
            *h = HkState {
                enabled: d.default_enabled,
                interval: d.default_interval_ms,
                next: d.default_interval_ms as u64,
            };
        }
        Hk { s }
    }

    pub fn next_deadline(&self) -> Option<u64> {
        self.s.iter().filter(|h| h.enabled).map(|h| h.next).min()
    }
}

impl Hk {
    /// Applies a request; the index of a structure to report now (a one-shot), whose
    /// values the obsw gathers from their sources (`Obsw::hk_report`).
    pub fn request(&mut self, now: u64, r: Request) -> Option<usize> {
        match r {
            Request::Enable(HkIndex(i)) => {
                let h = &mut self.s[i];
                h.enabled = true;
                h.next = now + h.interval as u64;
            }
            Request::Disable(HkIndex(i)) => self.s[i].enabled = false,
            Request::OneShot(HkIndex(i)) => return Some(i),
            Request::SetInterval(HkIndex(i), ms) => {
                let h = &mut self.s[i];
                h.interval = ms;
                h.next = now + ms as u64;
            }
        }
        None
    }

    /// Whether structure `i` (an index of `HK_STRUCTS`) is enabled and its interval
    /// elapsed at `now`; if so, its next report is scheduled.
    pub fn take_due(&mut self, now: u64, i: usize) -> bool {
        let Some(h) = self.s.get_mut(i).filter(|h| h.enabled && now >= h.next) else {
            return false;
        };
        let next = h.next + h.interval as u64;
        h.next = if next <= now { now + h.interval as u64 } else { next };
        true
    }
}

impl Default for Hk {
    fn default() -> Self {
        Self::new()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::obsw::tests::{failure, obsw, of, send};
    use mib::FailureCode;

    // verifies: PUS-3-02
    #[test]
    fn one_shot_reports_the_structure_and_an_unknown_sid_is_refused_with_it() {
        let mut o = obsw();
        let sid = HK_STRUCTS[0].sid;
        let pkts = send(&mut o, 10, 1, 3, 27, &sid.to_be_bytes());
        let hk = of(&pkts, 3, 25);
        assert_eq!(hk.len(), 1);
        assert_eq!(&hk[0][20..22], &sid.to_be_bytes());
        let pkts = send(&mut o, 10, 2, 3, 27, &[0xFF, 0xF0]);
        assert_eq!(
            failure(&of(&pkts, 1, 2)[0]),
            (FailureCode::UNKNOWN_SID.code(), vec![0xFF, 0xF0])
        );
    }

    // verifies: PUS-3-02, PUS-3-03
    #[test]
    fn disable_stops_and_interval_paces_periodic_reports() {
        let mut o = obsw();
        let sid = HK_STRUCTS[0].sid;
        let mut sink: Vec<Vec<u8>> = Vec::new();
        let mut app = sid.to_be_bytes().to_vec();
        app.extend_from_slice(&500u32.to_be_bytes());
        send(&mut o, 0, 1, 3, 31, &app);
        for t in (0..=2000).step_by(100) {
            o.hk_tick(t, &mut sink);
        }
        let n = of(&sink, 3, 25)
            .iter()
            .filter(|p| p[20..22] == sid.to_be_bytes())
            .count();
        assert_eq!(n, 4, "every 500 ms over 2 s");
        send(&mut o, 2000, 2, 3, 6, &sid.to_be_bytes());
        sink.clear();
        for t in (2000..=4000).step_by(100) {
            o.hk_tick(t, &mut sink);
        }
        assert!(of(&sink, 3, 25).iter().all(|p| p[20..22] != sid.to_be_bytes()));
    }
}
