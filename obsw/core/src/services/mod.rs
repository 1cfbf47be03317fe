//! The PUS services, one file each: its requests (parsed from an accepted TC), its
//! state, its reports, and its unit tests. This file is the one table that joins them to
//! the TC path: the [`Request`] of every service, its parse by service number, and
//! [`Obsw::route`], the one arm per service that hands an accepted request to its
//! component. A new service is a file here and one line in each of the three, plus its
//! contract in [`COMPONENTS`] and its state in [`Services`].
//!
//! A service that owns its state is a [`Component`]: its declared interface
//! ([`Contract`]: the PUS service whose TCs it takes and the parameter sources it answers
//! for, `mib::params::Source`; the MIB's parameter rows name them, `Obsw::param_from` asks
//! them), its typed request, and `handle`, the one way a request reaches it, with the
//! downlink as its output port. Its events and reports are the MIB's rows its code names
//! through `mib_wire::ev` and `mib_wire::tm`. Tests check the table against the MIB: every
//! TC the MIB defines reaches a handler, every source is one component's, every
//! component's service is one of the MIB's.

pub mod event;
pub mod event_action;
pub mod files;
pub mod function;
pub mod hk;
pub mod link;
pub mod mode;
pub mod modules;
pub mod monitoring;
pub mod parameter;
pub mod plan;
pub mod scheduling;
pub mod storage;
pub mod team;
pub mod test;
pub mod time;
pub mod update;

use mib::params::{pid, NotSupplied, Source, Supplied};
use mib::tc::service;

use crate::accept::Tc;
use crate::downlink::Downlink;
use crate::failure::Failure;
use crate::obsw::{Exec, Obsw, Refused};
use crate::request::Ctx;
use crate::tm::{TmSink, TmStore};

/// A component of the obsw that takes the requests of one PUS service (see the module's
/// documentation): `Obsw::route` hands each accepted request to its component's `handle`
/// with the time and the downlink (TM reports, events, the store). What the obsw still
/// has to do after a request — gather an HK report from every source, hand a key
/// selection to the platform — comes back as the request's `Output`.
pub trait Component {
    /// What it takes and supplies (its row of [`COMPONENTS`]).
    const CONTRACT: Contract;
    /// Its typed request, made by its service's `Request::parse` from an accepted TC.
    type Request<'a>;
    /// What the obsw does next with an executed request (`()`: nothing).
    type Output;
    /// Executes an accepted request: its reports and events through `dl`, a refusal as
    /// the failure the obsw reports at the start stage.
    fn handle<S: TmStore>(
        &mut self,
        now: u64,
        r: Self::Request<'_>,
        dl: &mut Downlink<S>,
        sink: &mut impl TmSink,
    ) -> Result<Self::Output, Failure>;

    /// Its own periodic work, once per control period (nothing by default).
    fn tick<S: TmStore>(&mut self, _now: u64, _dl: &mut Downlink<S>, _sink: &mut impl TmSink) {}

    /// The earliest time it has periodic work (`None`: none).
    fn next_deadline(&self) -> Option<u64> {
        None
    }
}

/// A component's declared interface (see the module's documentation).
#[derive(Clone, Copy, Debug)]
pub struct Contract {
    pub name: &'static str,
    /// The PUS service whose TCs it takes (`None`: it takes no TC).
    pub service: Option<u8>,
    /// The parameter sources it is.
    pub sources: &'static [Source],
}

impl Contract {
    pub const fn new(name: &'static str, service: Option<u8>, sources: &'static [Source]) -> Contract {
        Contract { name, service, sources }
    }
}

const fn c(name: &'static str, service: Option<u8>, sources: &'static [Source]) -> Contract {
    Contract::new(name, service, sources)
}

/// Every component of the obsw: the services of this folder (each declares its own
/// contract), and the parts of the obsw and the domain that supply parameters without
/// taking TCs of their own.
pub const COMPONENTS: &[Contract] = &[
    test::Test::CONTRACT,
    hk::Hk::CONTRACT,
    event::EventReporting::CONTRACT,
    function::CONTRACT,
    time::TimeReports::CONTRACT,
    scheduling::Schedule::CONTRACT,
    crate::fdir::Monitoring::CONTRACT,
    // The contract is the same whatever the store's mark type.
    storage::Replays::<()>::CONTRACT,
    crate::fdir::Faults::CONTRACT,
    <mmic_domain::controller::Controller as Component>::CONTRACT,
    crate::modes::ModeTree::CONTRACT,
    modules::Modules::CONTRACT,
    team::Team::CONTRACT,
    link::LinkKeys::CONTRACT,
    plan::OnboardPlan::CONTRACT,
    update::Update::CONTRACT,
    files::Files::CONTRACT,
    c("tc path", None, &[Source::Counters]),
    c("downlink", None, &[Source::Downlink]),
    c("platform I/O", None, &[Source::Io]),
    c("domain: board A", None, &[Source::BoardA]),
    c("domain: board B heartbeat", None, &[Source::BoardB]),
];

/// The state of the components that only the obsw reaches (the ones the platform or the
/// tests reach directly are fields of `Obsw`): a new component's state goes here, beside
/// its contract and its arm of [`Obsw::route`].
pub struct Services {
    pub hk: hk::Hk,
    pub time_reports: time::TimeReports,
    /// What the platform's file service reported (`Obsw::files_report`).
    pub files: files::Files,
}

impl Services {
    pub fn new() -> Self {
        Services {
            hk: hk::Hk::new(),
            time_reports: time::TimeReports::new(),
            files: files::Files::default(),
        }
    }
}

impl Services {
    /// The periodic work of the components here that have their own: one line each.
    pub(crate) fn tick<S: TmStore>(&mut self, now: u64, dl: &mut Downlink<S>, sink: &mut impl TmSink) {
        self.time_reports.tick(now, dl, sink);
    }

    /// The earliest time one of them has periodic work.
    pub(crate) fn next_deadline(&self) -> Option<u64> {
        self.time_reports.next_deadline()
    }
}

impl Default for Services {
    fn default() -> Self {
        Self::new()
    }
}

/// An accepted request, one variant per PUS service.
#[derive(Clone, Copy, Debug)]
pub enum Request<'a> {
    Test(test::Request),
    Hk(hk::Request),
    Event(event::Request),
    Function(function::Request),
    Time(time::Request),
    Scheduling(scheduling::Request<'a>),
    Monitoring(monitoring::Request),
    Storage(storage::Request),
    EventAction(event_action::Request),
    Parameter(parameter::Request),
    Mode(mode::Request),
    Modules(modules::Request),
    Team(team::Request),
    Link(link::Request),
    Plan(plan::Request<'a>),
    Update(update::Request<'a>),
}

impl<'a> Request<'a> {
    pub fn parse(tc: &Tc<'a>, ctx: &Ctx) -> Result<Self, Failure> {
        Ok(match tc.service {
            service::TEST => Request::Test(test::Request::parse(tc)?),
            service::HOUSEKEEPING => Request::Hk(hk::Request::parse(tc)?),
            service::EVENT => Request::Event(event::Request::parse(tc)?),
            service::FUNCTION => Request::Function(function::Request::parse(tc)?),
            service::TIME => Request::Time(time::Request::parse(tc)?),
            service::SCHEDULING => Request::Scheduling(scheduling::Request::parse(tc, ctx)?),
            service::MONITORING => Request::Monitoring(monitoring::Request::parse(tc)?),
            service::STORAGE => Request::Storage(storage::Request::parse(tc)?),
            service::EVENT_ACTION => Request::EventAction(event_action::Request::parse(tc)?),
            service::PARAMETER => Request::Parameter(parameter::Request::parse(tc)?),
            service::MODE => Request::Mode(mode::Request::parse(tc)?),
            service::MODULES => Request::Modules(modules::Request::parse(tc)?),
            service::TEAM => Request::Team(team::Request::parse(tc)?),
            service::SPACE_LINK => Request::Link(link::Request::parse(tc)?),
            service::PLAN => Request::Plan(plan::Request::parse(tc)?),
            service::UPDATE => Request::Update(update::Request::parse(tc)?),
            // `accept` only lets services of the MIB through; a service added to the
            // MIB without a handler here is refused, never run by another one.
            other => return Err(Failure::unknown_service(other)),
        })
    }
}

impl<S: TmStore> Obsw<S> {
    /// Asks the component `src` for parameter `id`: `Err` unless the MIB names `src` the
    /// parameter's source (checked for every parameter by a test).
    pub fn param_from(&self, src: Source, id: u16) -> Supplied {
        match src {
            Source::Modes | Source::Faults | Source::Monitoring | Source::BoardA | Source::BoardB => {
                self.robot.param_from(src, id)
            }
            Source::Counters => self.counters.param(id),
            Source::Downlink => self.dl.param(id),
            Source::Scheduler => self.sched.param(id),
            Source::Clock => match id {
                pid::UPTIME_S => Ok(Some((self.last_now / 1000) as i64)),
                _ => Err(NotSupplied(id)),
            },
            Source::Io => self.io.param(id),
            Source::SpaceLink => self.space_link_param(id),
            Source::Modules => self.modules.param(id),
            Source::Team => self.team.param(id),
            Source::Plan => self.plan.plan.param(id),
            Source::Update => self.update.param(id),
            Source::Files => self.svc.files.param(id),
        }
    }

    /// One arm per PUS service: a [`Component`] gets the request with the downlink (and
    /// the obsw does what its output asks); a function, and a commanded mode once the mode
    /// tree has handed it back, go to the robot with its ports (`crate::robot`).
    pub(crate) fn route(&mut self, now: u64, request: Request, sink: &mut impl TmSink) -> Result<Exec, Refused> {
        let dl = &mut self.dl;
        match request {
            Request::Test(r) => test::Test.handle(now, r, dl, sink)?,
            Request::Hk(r) => {
                if let Some(i) = self.svc.hk.handle(now, r, dl, sink)? {
                    self.hk_report(now, i, sink);
                }
            }
            Request::Event(r) => event::EventReporting.handle(now, r, dl, sink)?,
            Request::Function(r) => {
                let (robot, mut p) = self.robot(sink);
                return robot.function_request(now, r, &mut p);
            }
            Request::Time(r) => self.svc.time_reports.handle(now, r, dl, sink)?,
            Request::Scheduling(r) => self.sched.handle(now, r, dl, sink)?,
            Request::Monitoring(r) => self.robot.monitoring.handle(now, r, dl, sink)?,
            Request::Storage(r) => {
                if let Some(range) = self.replays.handle(now, r, dl, sink)? {
                    return Ok(Exec::Replay(range));
                }
            }
            Request::EventAction(r) => self.robot.faults.handle(now, r, dl, sink)?,
            Request::Parameter(r) => self.robot.ctrl.handle(now, r, dl, sink)?,
            Request::Mode(r) => {
                if let Some(target) = self.robot.modes.handle(now, r, dl, sink)? {
                    let (robot, mut p) = self.robot(sink);
                    return robot.mode_command(now, target, &mut p);
                }
            }
            Request::Modules(r) => self.modules.handle(now, r, dl, sink)?,
            Request::Team(r) => self.team.handle(now, r, dl, sink)?,
            Request::Link(r) => self.link_select = Some(self.link_keys.handle(now, r, dl, sink)?),
            Request::Plan(r) => {
                if let Some(change) = self.plan.handle(now, r, dl, sink)? {
                    // As a ground STOP: the action ends, its TC reports ABORTED_BY_COMMAND.
                    let (robot, mut p) = self.robot(sink);
                    let _ = robot.function_request(now, function::Request::Stop, &mut p);
                    plan::OnboardPlan::report(now, change, &mut self.dl, sink);
                }
            }
            Request::Update(r) => self.update.handle(now, r, dl, sink)?,
        }
        Ok(Exec::Done)
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// The failures the services make themselves (their own codes, beside the core's
    /// constructors in `crate::failure`): one line per such service, for the test that
    /// every MIB failure code is made somewhere with the data the MIB lists.
    pub(crate) fn own_failures() -> Vec<Failure> {
        let mut all = plan::tests::every_failure();
        all.extend(update::tests::every_failure());
        all.extend(link::tests::every_failure());
        all
    }
    use crate::accept::tests::tc_bytes;
    use crate::accept::Ack;
    use mib::FailureCode;

    /// The component that takes the TCs of `svc`.
    fn taking(svc: u8) -> Vec<&'static str> {
        COMPONENTS
            .iter()
            .filter(|c| c.service == Some(svc))
            .map(|c| c.name)
            .collect()
    }

    // verifies: PUS-1-05
    #[test]
    fn every_tc_of_the_mib_reaches_the_handler_of_exactly_one_component() {
        let ctx = Ctx {
            apid: 0x101,
            time: crate::time::OnboardTime::new(0),
            now: 0,
            sched_free: 1,
        };
        for def in mib::tc::TCS {
            assert_eq!(taking(def.service).len(), 1, "{}: {:?}", def.name, taking(def.service));
            let raw = tc_bytes(0x101, 1, def.service, def.subservice, &def.function.to_be_bytes());
            let tc = Tc {
                req: mib_wire::RequestId::of_tc(&raw).unwrap(),
                ack: Ack::ALL,
                service: def.service,
                subservice: def.subservice,
                source_id: 0,
                def,
                args: [0; mib_wire::codec::MAX_ARGS],
                rest: &[],
                raw: &raw,
            };
            // Zero arguments may be refused by the service (an unknown SID, a value out
            // of range), never as a TC nobody handles.
            if let Err(f) = Request::parse(&tc, &ctx) {
                let code = f.code();
                assert!(
                    code != FailureCode::UNKNOWN_SERVICE && code != FailureCode::UNKNOWN_SUBSERVICE,
                    "{} has no handler: {}",
                    def.name,
                    code.name()
                );
            }
        }
    }

    // verifies: PUS-3-05
    #[test]
    fn every_parameter_source_and_service_is_one_components() {
        for s in Source::ALL {
            let owners: Vec<_> = COMPONENTS
                .iter()
                .filter(|c| c.sources.contains(&s))
                .map(|c| c.name)
                .collect();
            assert_eq!(owners.len(), 1, "{s:?}: {owners:?}");
        }
        for c in COMPONENTS {
            if let Some(svc) = c.service {
                assert!(
                    mib::tc::TCS.iter().any(|d| d.service == svc),
                    "{}: service {svc}",
                    c.name
                );
                assert_eq!(taking(svc), [c.name]);
            }
        }
    }
}
