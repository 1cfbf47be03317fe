//! PUS 3 housekeeping: periodic reports of the MIB's HK structures (TM[3,25]),
//! enable/disable, one-shot and collection interval. Each structure reports at its own
//! phase within the second (`mib::hk::phase_ms`), so that structures with whole-second
//! intervals never report, and write to the store, in the same control period.

use mib::hk::{phase_ms, HK_STRUCTS, PHASE_CYCLE_MS};
use mib::tc::service;

use crate::accept::Tc;
use crate::downlink::Downlink;
use crate::failure::Failure;
use crate::request::unknown;
use crate::services::{Component, Contract};
use crate::tm::{TmSink, TmStore};

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
        for (i, (h, d)) in s.iter_mut().zip(HK_STRUCTS).enumerate() {
            *h = HkState {
                enabled: d.default_enabled,
                interval: d.default_interval_ms,
                next: first_after(0, i, d.default_interval_ms),
            };
        }
        Hk { s }
    }

    pub fn next_deadline(&self) -> Option<u64> {
        self.s.iter().filter(|h| h.enabled).map(|h| h.next).min()
    }
}

/// The first instant at or after `t` that is structure `i`'s phase within the second.
fn at_phase(t: u64, i: usize) -> u64 {
    let cycle = PHASE_CYCLE_MS as u64;
    t + (phase_ms(i) as u64 + cycle - t % cycle) % cycle
}

/// Structure `i`'s report an interval from `t`: from its next phase instant when the
/// interval is whole cycles (the phase is kept for good), else from `t` itself (an interval
/// shorter than, or not a multiple of, the cycle cannot keep a phase, and waiting for one
/// would slow a 50 ms structure to one report a second).
fn first_after(t: u64, i: usize, interval: u32) -> u64 {
    let start = if interval.is_multiple_of(PHASE_CYCLE_MS) {
        at_phase(t, i)
    } else {
        t
    };
    start + interval as u64
}

impl Hk {
    /// Applies a request; the index of a structure to report now (a one-shot), whose
    /// values the obsw gathers from their sources (`Obsw::hk_report`).
    pub fn request(&mut self, now: u64, r: Request) -> Option<usize> {
        match r {
            Request::Enable(HkIndex(i)) => {
                let h = &mut self.s[i];
                h.enabled = true;
                h.next = first_after(now, i, h.interval);
            }
            Request::Disable(HkIndex(i)) => self.s[i].enabled = false,
            Request::OneShot(HkIndex(i)) => return Some(i),
            Request::SetInterval(HkIndex(i), ms) => {
                let h = &mut self.s[i];
                h.interval = ms;
                h.next = first_after(now, i, ms);
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
        h.next = if next <= now {
            first_after(now, i, h.interval)
        } else {
            next
        };
        true
    }
}

/// The structures' generation state; a one-shot's report is the obsw's to gather from
/// every source (`Obsw::hk_report`), so the index comes back.
impl Component for Hk {
    const CONTRACT: Contract = Contract::new("hk", Some(service::HOUSEKEEPING), &[]);
    type Request<'a> = Request;
    type Output = Option<usize>;
    fn handle<S: TmStore>(
        &mut self,
        now: u64,
        r: Request,
        _dl: &mut Downlink<S>,
        _sink: &mut impl TmSink,
    ) -> Result<Option<usize>, Failure> {
        Ok(self.request(now, r))
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

    // verifies: PUS-3-06
    #[test]
    fn structures_with_whole_second_intervals_report_in_periods_of_their_own() {
        let mut hk = Hk::new();
        for i in 0..N_HK {
            hk.s[i].enabled = true;
        }
        let period = mib::config::CONTROL_PERIOD_MS as u64;
        let mut first = [0u64; N_HK];
        let mut reports = 0;
        let mut check = |hk: &mut Hk, from: u64, to: u64, first: &mut [u64; N_HK], stalled: Option<usize>| {
            for t in (from..to).step_by(period as usize) {
                let due: Vec<usize> = (0..N_HK).filter(|&i| Some(i) != stalled && hk.take_due(t, i)).collect();
                assert!(due.len() <= 1, "structures {due:?} report together at {t} ms");
                for i in due {
                    if first[i] == 0 {
                        first[i] = t;
                    }
                    reports += 1;
                }
            }
        };
        check(&mut hk, 0, 60_000, &mut first, None);
        for (i, d) in HK_STRUCTS.iter().enumerate() {
            // The first report one interval after the structure's phase.
            let due = (phase_ms(i) + d.default_interval_ms) as u64;
            assert_eq!(first[i], due.next_multiple_of(period), "SID {}", d.sid);
        }
        // Re-enabling and new whole-second intervals keep every structure on its phase.
        hk.request(60_003, Request::SetInterval(HkIndex(1), 3000));
        hk.request(60_007, Request::Enable(HkIndex(2)));
        hk.request(61_234, Request::SetInterval(HkIndex(0), 2000));
        check(&mut hk, 60_010, 120_000, &mut first, None);
        // A structure whose reports were held up for seconds comes back on its phase.
        check(&mut hk, 120_000, 125_550, &mut first, Some(3));
        assert!(hk.take_due(125_555, 3));
        check(&mut hk, 125_560, 180_000, &mut first, None);
        assert!(reports > 100, "{reports} reports");
    }

    // verifies: PUS-3-02
    #[test]
    fn an_interval_shorter_than_the_phase_cycle_reports_at_its_own_rate() {
        let mut hk = Hk::new();
        hk.request(10_237, Request::SetInterval(HkIndex(3), 50));
        let due: Vec<u64> = (10_240..11_240).step_by(10).filter(|&t| hk.take_due(t, 3)).collect();
        // Every 50 ms from the TC on (10,290 … 11,190), not once a second on a phase.
        assert_eq!(due.len(), 19, "{due:?}");
        assert_eq!(due[0], 10_290);
        assert!(due.windows(2).all(|w| w[1] - w[0] == 50), "{due:?}");
    }
}
