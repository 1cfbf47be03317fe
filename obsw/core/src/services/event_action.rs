//! PUS 19 event-action: each fault event of Table 8 is linked to a mode change (now or
//! after the running motion). This file raises faults and applies their links; the
//! links can be disabled, enabled and reported (TM[19,9]).

use mib::fdir::FAULTS;
use mib::modes::robot_mode;
use mib::params::Source;
use mib::tc::service;
use mib_wire::tm;

use crate::accept::Tc;
use crate::downlink::Downlink;
use crate::failure::Failure;
use crate::fdir::{Faults, Response};
use crate::request::unknown;
use crate::robot::{Ports, Robot};
use crate::services::{Component, Contract};
use crate::tm::{TmSink, TmStore};
use mib_wire::args;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Request {
    /// TC[19,4]: enable the link of a fault event.
    Enable(u16),
    /// TC[19,5]
    Disable(u16),
    /// TC[19,8]: answered with TM[19,9].
    Report,
}

impl Request {
    pub fn parse(tc: &Tc) -> Result<Self, Failure> {
        let link = |ev: u16| {
            mib::fdir::fault_by_event(ev)
                .map(|f| f.event)
                .ok_or(Failure::unknown_action_link(ev))
        };
        Ok(match tc.subservice {
            4 => Request::Enable(link(args::EaEnable::of(&tc.args).event_id)?),
            5 => Request::Disable(link(args::EaDisable::of(&tc.args).event_id)?),
            8 => Request::Report,
            _ => return Err(unknown(tc)),
        })
    }
}

/// Applies a PUS 19 request to the event-action links; their report goes out through
/// the downlink. Raising a fault and its action join FDIR with the mode tree, the running
/// action and the plan (`Robot::fault`).
impl Component for Faults {
    const CONTRACT: Contract = Contract::new(
        "event_action (FDIR's faults)",
        Some(service::EVENT_ACTION),
        &[Source::Faults],
    );
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
            // The event was looked up in the fault table at acceptance.
            Request::Enable(ev) => {
                self.set_link_enabled(ev, true);
            }
            Request::Disable(ev) => {
                self.set_link_enabled(ev, false);
            }
            Request::Report => self.report_links(now, dl, sink),
        }
        Ok(())
    }
}

impl Faults {
    fn report_links<S: TmStore>(&self, now: u64, dl: &mut Downlink<S>, sink: &mut impl TmSink) {
        let mut r = tm::EaDefinitions {
            links: heapless::Vec::new(),
        };
        for (i, f) in FAULTS.iter().enumerate() {
            let link = tm::EaDefinitionsLinks {
                event: f.event,
                enabled: self.link_enabled(i) as u8,
                mode: f.mode,
                deferred: (f.timing == mib::fdir::Timing::AfterMotion) as u8,
            };
            // The list holds every fault of the MIB (FAULTS.len() <= its capacity).
            if r.links.push(link).is_err() {
                break;
            }
        }
        dl.emit_tm(now, &r, sink);
    }
}

impl Robot {
    /// Raises a fault event from its typed parameters and applies its event-action link.
    pub(crate) fn raise_fault<E: mib_wire::EventArgs, S: TmStore, K: TmSink>(
        &mut self,
        now: u64,
        e: E,
        p: &mut Ports<S, K>,
    ) {
        self.fault(now, E::ID, e.values().as_ref(), false, p);
    }

    /// Raises a fault event (by ID, values in MIB order: FDIR's table), suspends the
    /// on-board plan and applies the event's link: FDIR's decision ([`Faults::raise`],
    /// data) becomes a mode change now or after the running motion. A `monitored` fault
    /// (a continuous monitor's violation) is acted on each time it is raised.
    pub(crate) fn fault<S: TmStore, K: TmSink>(
        &mut self,
        now: u64,
        event: u16,
        args: &[i64],
        monitored: bool,
        p: &mut Ports<S, K>,
    ) {
        p.dl.event(now, event, args, p.sink);
        p.plan.fault(now, p.dl, p.sink);
        let bit = mib::fdir::fault_by_event(event).map_or(0, |f| 1u32 << f.bit);
        if !monitored && self.faults.oneshot & bit != 0 {
            // Already active and being dealt with (e.g. every command left unacknowledged
            // by a silent board B): reported, not counted or acted on again.
            return;
        }
        match self.faults.raise(event, monitored) {
            Response::None => {}
            // Standby already has every module unpowered and the robot resting on its
            // grippers: a fault never powers the servos up just to hold (safed).
            Response::Now(m) if m == robot_mode::SAFED && self.modes.root_target() == robot_mode::STANDBY => {
                self.clear_oneshot(now, event, p);
            }
            Response::Now(m) => self.set_mode(now, m, event, p),
            Response::AfterMotion(m) => {
                if self.running.is_some() {
                    self.faults.pending_mode = Some(match self.faults.pending_mode {
                        Some(pending) if pending == robot_mode::SAFED => pending,
                        _ => m,
                    });
                } else if self.modes.root_target() != m {
                    self.set_mode(now, m, event, p);
                } else {
                    self.clear_oneshot(now, event, p);
                }
            }
        }
    }

    /// A one-shot fault dealt with by its mode change: FAULT_CLEARED.
    pub(crate) fn clear_oneshot<S: TmStore, K: TmSink>(&mut self, now: u64, event: u16, p: &mut Ports<S, K>) {
        if let Some(f) = mib::fdir::fault_by_event(event) {
            if self.faults.oneshot & (1 << f.bit) != 0 {
                self.faults.oneshot &= !(1 << f.bit);
                p.dl.raise(now, mib_wire::ev::FaultCleared { event_id: event }, p.sink);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use crate::obsw::tests::{failure, kind, obsw, of, send};
    use mib::events::eid;
    use mib::fdir::FAULTS;
    use mib::FailureCode;

    // verifies: PUS-19-01
    #[test]
    fn a_link_can_be_disabled_and_is_reported_so_and_an_unknown_link_is_refused() {
        let mut o = obsw();
        let ev = FAULTS[0].event;
        send(&mut o, 1, 1, 19, 5, &ev.to_be_bytes());
        let pkts = send(&mut o, 2, 2, 19, 8, &[]);
        let d = kind(&of(&pkts, 19, 9)[0]).2.to_vec();
        assert_eq!((&d[2..4], d[4]), (&ev.to_be_bytes()[..], 0));
        let pkts = send(&mut o, 3, 3, 19, 4, &eid::BOOT.to_be_bytes());
        assert_eq!(
            failure(&of(&pkts, 1, 2)[0]),
            (
                FailureCode::UNKNOWN_ACTION_LINK.code(),
                eid::BOOT.to_be_bytes().to_vec()
            )
        );
    }
}
