//! PUS 5 event reporting: enable/disable per event and the list of disabled events
//! (TM[5,8]). Emission, enable mask and throttling live in `crate::downlink::Events`.

use mib::events::EVENTS;
use mib::tc::service;
use mib_wire::tm;

use crate::accept::Tc;
use crate::downlink::{Downlink, EventIndex};
use crate::failure::Failure;
use crate::request::unknown;
use crate::services::{Component, Contract};
use crate::tm::{TmSink, TmStore};
use mib_wire::args;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Request {
    /// TC[5,5]
    Enable(EventIndex),
    /// TC[5,6]
    Disable(EventIndex),
    /// TC[5,7]: answered with TM[5,8].
    ReportDisabled,
}

impl Request {
    pub fn parse(tc: &Tc) -> Result<Self, Failure> {
        let ev = |id: u16| EventIndex::of(id).ok_or(Failure::unknown_event(id));
        Ok(match tc.subservice {
            5 => Request::Enable(ev(args::EventEnable::of(&tc.args).event_id)?),
            6 => Request::Disable(ev(args::EventDisable::of(&tc.args).event_id)?),
            7 => Request::ReportDisabled,
            _ => return Err(unknown(tc)),
        })
    }
}

/// Event reporting's state is the downlink's enable mask (`Downlink::events`), which every
/// emission asks.
pub struct EventReporting;

impl Component for EventReporting {
    const CONTRACT: Contract = Contract::new("event", Some(service::EVENT), &[]);
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
            Request::Enable(e) => dl.events.set_enabled(e, true),
            Request::Disable(e) => dl.events.set_enabled(e, false),
            Request::ReportDisabled => {
                let mut r = tm::DisabledEvents {
                    events: heapless::Vec::new(),
                };
                for e in EVENTS {
                    let disabled = EventIndex::of(e.id).is_some_and(|i| !dl.events.is_enabled(i));
                    // The list holds every event of the MIB (N_EVENTS <= its capacity).
                    if disabled && r.events.push(tm::DisabledEventsEvents { event_id: e.id }).is_err() {
                        break;
                    }
                }
                dl.emit_tm(now, &r, sink);
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use crate::obsw::tests::{kind, obsw, of, send};
    use mib::events::eid;

    // verifies: PUS-5-02
    #[test]
    fn a_disabled_event_is_listed_and_no_longer_reported() {
        let mut o = obsw();
        send(&mut o, 1, 1, 5, 6, &eid::BOOT.to_be_bytes());
        let pkts = send(&mut o, 2, 2, 5, 7, &[]);
        let list = of(&pkts, 5, 8);
        assert_eq!(kind(&list[0]).2, [&[0u8, 1][..], &eid::BOOT.to_be_bytes()].concat());
        let mut sink: Vec<Vec<u8>> = Vec::new();
        o.boot(3, 0, &mut sink);
        assert!(sink.is_empty());
        send(&mut o, 4, 3, 5, 5, &eid::BOOT.to_be_bytes());
        o.boot(5, 0, &mut sink);
        assert_eq!(sink.len(), 1);
    }
}
