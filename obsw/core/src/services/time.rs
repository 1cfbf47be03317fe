//! PUS 9 time management: periodic time reports (TM[9,2], every 2^n s) and a report on
//! request.

use mib::config;
use mib::params::Source;
use mib::tc::service;
use mib_wire::tm;

use crate::accept::Tc;
use crate::downlink::Downlink;
use crate::failure::Failure;
use crate::request::unknown;
use crate::services::{Component, Contract};
use crate::tm::{TmSink, TmStore};

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Request {
    /// TC[9,1]: report every 2^exp seconds (0..=8, range-checked by `accept`).
    SetRate(u8),
    /// TC[9,128]
    ReportNow,
}

impl Request {
    pub fn parse(tc: &Tc) -> Result<Self, Failure> {
        Ok(match tc.subservice {
            1 => Request::SetRate(mib_wire::args::TimeSetRate::of(&tc.args).rate_exp),
            128 => Request::ReportNow,
            _ => return Err(unknown(tc)),
        })
    }
}

/// Rate and next due time of the periodic time report.
pub struct TimeReports {
    exp: u8,
    next: u64,
}

impl TimeReports {
    pub fn new() -> Self {
        TimeReports {
            exp: config::TIME_REPORT_DEFAULT_EXP,
            next: 1000u64 << config::TIME_REPORT_DEFAULT_EXP,
        }
    }
    fn period(&self) -> u64 {
        1000u64 << self.exp
    }
}

impl Default for TimeReports {
    fn default() -> Self {
        Self::new()
    }
}

impl Component for TimeReports {
    const CONTRACT: Contract = Contract::new("time", Some(service::TIME), &[Source::Clock]);
    type Request<'a> = Request;
    type Output = ();
    fn handle<S: TmStore>(
        &mut self,
        now: u64,
        r: Request,
        dl: &mut Downlink<S>,
        sink: &mut impl TmSink,
    ) -> Result<(), Failure> {
        match r {
            Request::SetRate(exp) => {
                self.exp = exp;
                self.next = now + self.period();
                self.report(now, dl, sink);
            }
            Request::ReportNow => self.report(now, dl, sink),
        }
        Ok(())
    }

    /// Sends the periodic report when it is due.
    fn tick<S: TmStore>(&mut self, now: u64, dl: &mut Downlink<S>, sink: &mut impl TmSink) {
        if now >= self.next {
            self.report(now, dl, sink);
            self.next = now + self.period();
        }
    }

    fn next_deadline(&self) -> Option<u64> {
        Some(self.next)
    }
}

impl TimeReports {
    fn report<S: TmStore>(&self, now: u64, dl: &mut Downlink<S>, sink: &mut impl TmSink) {
        let r = tm::TimeReport {
            rate_exp: self.exp,
            time: dl.tmw.time.cds_time(now),
        };
        dl.emit_tm(now, &r, sink);
    }
}

#[cfg(test)]
mod tests {
    use crate::obsw::tests::{kind, obsw, of, send};

    // verifies: PUS-9-01
    #[test]
    fn the_rate_sets_the_period_and_the_report_carries_exponent_and_time() {
        let mut o = obsw();
        let pkts = send(&mut o, 1000, 1, 9, 1, &[0]);
        let r = of(&pkts, 9, 2);
        assert_eq!(kind(&r[0]).2[0], 0);
        assert_eq!(&kind(&r[0]).2[1..], &o.dl.tmw.time.cds(1000));
        let mut sink: Vec<Vec<u8>> = Vec::new();
        for t in (1000..=3000).step_by(10) {
            o.svc.tick(t, &mut o.dl, &mut sink);
        }
        assert_eq!(of(&sink, 9, 2).len(), 2, "every second");
    }
}
