//! PUS 12 on-board monitoring: the limit and persistence checks of `crate::fdir` run
//! each cycle (and at the instants the paper names); every check transition is
//! reported (TM[12,12]) and a violation raises its fault event. Monitors can be
//! enabled, disabled, modified and reported (TM[12,9]).

use mib::events::eid;
use mib::fdir::{Phase, MONITORS};
use mib::params::{pid, Source};
use mib::tc::service;
use mib_wire::tm;

use crate::accept::Tc;
use crate::downlink::Downlink;
use crate::failure::Failure;
use crate::fdir::{self, Monitor, Monitoring, N_MONITORS};
use crate::request::unknown;
use crate::robot::{Ports, Robot};
use crate::services::{Component, Contract};
use crate::tm::{TmSink, TmStore};

/// Index of a monitor in `mib::fdir::MONITORS` (and `Monitoring::mons`, built from it
/// in the same order); only made from a defined monitor ID.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MonitorIndex(usize);

impl MonitorIndex {
    fn of(id: u16) -> Result<Self, Failure> {
        MONITORS
            .iter()
            .position(|m| m.id == id)
            .map(MonitorIndex)
            .ok_or(Failure::unknown_monitor(id))
    }
}

impl Monitoring {
    fn at(&mut self, i: MonitorIndex) -> &mut Monitor {
        &mut self.mons[i.0]
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Request {
    /// TC[12,1]
    Enable(MonitorIndex),
    /// TC[12,2]
    Disable(MonitorIndex),
    /// TC[12,7]: new limits (low <= high) and persistence.
    Modify {
        mon: MonitorIndex,
        low: i32,
        high: i32,
        persistence: u16,
    },
    /// TC[12,8]: answered with TM[12,9].
    Report,
}

impl Request {
    pub fn parse(tc: &Tc) -> Result<Self, Failure> {
        use mib_wire::args;
        Ok(match tc.subservice {
            1 => Request::Enable(MonitorIndex::of(args::MonEnable::of(&tc.args).monitor_id)?),
            2 => Request::Disable(MonitorIndex::of(args::MonDisable::of(&tc.args).monitor_id)?),
            7 => {
                let x = mib_wire::args::MonModify::of(&tc.args);
                let m = MonitorIndex::of(x.monitor_id)?;
                if x.low > x.high {
                    return Err(Failure::param_out_of_range(MONITORS[m.0].param, x.low));
                }
                Request::Modify {
                    mon: m,
                    low: x.low,
                    high: x.high,
                    persistence: x.persistence,
                }
            }
            8 => Request::Report,
            _ => return Err(unknown(tc)),
        })
    }
}

/// Applies a PUS 12 request to the monitors; the definitions report goes out through
/// the downlink. The monitors' checks run in the control period (`Robot::run_monitors`).
impl Component for Monitoring {
    const CONTRACT: Contract = Contract::new("monitoring", Some(service::MONITORING), &[Source::Monitoring]);
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
            Request::Enable(i) | Request::Disable(i) => {
                let m = self.at(i);
                m.enabled = matches!(r, Request::Enable(_));
                m.state = fdir::check::OK;
            }
            Request::Modify {
                mon,
                low,
                high,
                persistence,
            } => {
                let m = self.at(mon);
                m.def.low = low;
                m.def.high = high;
                m.def.persistence = persistence;
            }
            Request::Report => self.report(now, dl, sink),
        }
        Ok(())
    }
}

impl Monitoring {
    fn report<S: TmStore>(&self, now: u64, dl: &mut Downlink<S>, sink: &mut impl TmSink) {
        let mut r = tm::MonDefinitions {
            monitors: heapless::Vec::new(),
        };
        for m in &self.mons {
            let d = tm::MonDefinitionsMonitors {
                monitor_id: m.def.id,
                param: m.def.param,
                enabled: m.enabled as u8,
                low: m.def.low,
                high: m.def.high,
                persistence: m.def.persistence,
                event: m.def.event,
            };
            // The list holds every monitor of the MIB (N_MONITORS <= its capacity).
            if r.monitors.push(d).is_err() {
                break;
            }
        }
        dl.emit_tm(now, &r, sink);
    }
}

impl Robot {
    /// Runs the idle-phase monitors once; returns the fault event if one fired.
    pub(crate) fn idle_check<S: TmStore, K: TmSink>(&mut self, now: u64, p: &mut Ports<S, K>) -> Option<u16> {
        self.run_monitors(now, |ph| ph == Phase::Idle, p)
    }

    /// Runs the monitors of the accepted phases; emits TM[12,12] for each transition
    /// and raises the fault of each new violation. Returns the last fault event raised.
    pub(crate) fn run_monitors<S: TmStore, K: TmSink>(
        &mut self,
        now: u64,
        phases: impl Fn(Phase) -> bool,
        p: &mut Ports<S, K>,
    ) -> Option<u16> {
        let mut tr: heapless::Vec<fdir::Transition, N_MONITORS> = heapless::Vec::new();
        {
            let this = &*self;
            // A parameter without a valid value (board B never heard) is not checked.
            // Values of every monitored parameter and of the parameters deciding whether
            // its MIB limits apply (mode, active primitive): at most 3 per monitor, so
            // the list cannot fill.
            let mut vals: heapless::Vec<(u16, Option<i64>), { 3 * N_MONITORS }> = heapless::Vec::new();
            for m in &this.monitoring.mons {
                let param = m.def.param;
                let context = mib::params::by_id(param)
                    .into_iter()
                    .flat_map(mib::params::limit_context);
                for id in core::iter::once(param).chain(context) {
                    if !vals.iter().any(|(i, _)| *i == id) && vals.push((id, this.param_opt(id, p.modules))).is_err() {
                        break;
                    }
                }
            }
            self.monitoring.check(
                phases,
                |id| vals.iter().find(|(i, _)| *i == id).and_then(|(_, v)| *v),
                &mut tr,
            );
        }
        self.faults.monitored = self.monitoring.violated_fault_bits();
        let mut raised = None;
        for t in &tr {
            let r = tm::MonTransition {
                monitor_id: t.monitor,
                param: t.param,
                value: t.value.clamp(i32::MIN as i64, i32::MAX as i64) as i32,
                limit: t.limit,
                state: t.state,
            };
            p.dl.emit_tm(now, &r, p.sink);
            let continuous = mib::fdir::monitor_by_id(t.monitor).is_some_and(|m| fdir::is_continuous(m.phase));
            if t.state != fdir::check::OK {
                let args: [i64; 3] = if t.event == eid::HIP_MISMATCH {
                    // Board A's encoder: always a value.
                    let hip = self.param_opt(pid::HIP_ANGLE, p.modules).unwrap_or(0);
                    [hip, hip - t.value, 0]
                } else {
                    [t.param as i64, t.value, t.limit as i64]
                };
                self.fault(now, t.event, &args, continuous, p);
                raised = Some(t.event);
            } else if continuous
                && self.faults.monitored & mib::fdir::fault_by_event(t.event).map_or(0, |f| 1 << f.bit) == 0
            {
                p.dl.raise(now, mib_wire::ev::FaultCleared { event_id: t.event }, p.sink);
            }
        }
        raised
    }
}

#[cfg(test)]
mod tests {
    use crate::obsw::tests::{failure, kind, obsw, of, send};
    use mib::fdir::MONITORS;
    use mib::FailureCode;

    // verifies: PUS-12-02
    #[test]
    fn modify_changes_the_reported_limits_and_inverted_limits_are_refused() {
        let mut o = obsw();
        let m = MONITORS[0];
        let mut app = m.id.to_be_bytes().to_vec();
        for v in [-5i32, 5] {
            app.extend_from_slice(&v.to_be_bytes());
        }
        app.extend_from_slice(&3u16.to_be_bytes());
        send(&mut o, 1, 1, 12, 7, &app);
        let d = kind(&of(&send(&mut o, 2, 2, 12, 8, &[]), 12, 9)[0]).2.to_vec();
        assert_eq!(&d[7..15], &[(-5i32).to_be_bytes(), 5i32.to_be_bytes()].concat()[..]);
        let mut bad = m.id.to_be_bytes().to_vec();
        for v in [5i32, -5] {
            bad.extend_from_slice(&v.to_be_bytes());
        }
        bad.extend_from_slice(&3u16.to_be_bytes());
        let pkts = send(&mut o, 3, 3, 12, 7, &bad);
        let mut data = m.param.to_be_bytes().to_vec();
        data.extend_from_slice(&5i32.to_be_bytes());
        assert_eq!(
            failure(&of(&pkts, 1, 2)[0]),
            (FailureCode::PARAM_OUT_OF_RANGE.code(), data)
        );
    }
}
