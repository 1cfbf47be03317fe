//! The PUS services, one file each: its requests (parsed from an accepted TC), its
//! state, its reports, and its unit tests. This file is the one table that joins them to
//! the TC path: the [`Request`] of every service, its parse by service number, and
//! [`Obsw::route`], the one arm per service that hands an accepted request to its
//! component. A new service is a file here and one line in each of the three.

pub mod event;
pub mod event_action;
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

use mib::tc::service;

use crate::accept::Tc;
use crate::failure::Failure;
use crate::obsw::{Exec, Obsw, Refused};
use crate::request::Ctx;
use crate::tm::{TmSink, TmStore};

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
            // `accept` only lets services of the MIB through; a service added to the
            // MIB without a handler here is refused, never run by another one.
            other => return Err(Failure::unknown_service(other)),
        })
    }
}

impl<S: TmStore> Obsw<S> {
    /// One arm per PUS service: each service file handles its own requests.
    pub(crate) fn route(&mut self, now: u64, request: Request, sink: &mut impl TmSink) -> Result<Exec, Refused> {
        match request {
            Request::Test(r) => test::handle(now, r, &mut self.dl, sink),
            Request::Hk(r) => {
                if let Some(i) = self.hk.request(now, r) {
                    self.hk_report(now, i, sink);
                }
            }
            Request::Event(r) => event::handle(now, r, &mut self.dl, sink),
            Request::Function(r) => return self.function_request(now, r, sink),
            Request::Time(r) => self.time_reports.request(now, r, &mut self.dl, sink),
            Request::Scheduling(r) => self.sched.request(r, &self.dl.tmw.time)?,
            Request::Monitoring(r) => self.monitoring_request(now, r, sink),
            Request::Storage(r) => self.storage_request(now, r, sink)?,
            Request::EventAction(r) => self.event_action_request(now, r, sink),
            Request::Parameter(r) => parameter::handle(now, r, &mut self.ctrl, &mut self.dl, sink)?,
            Request::Mode(r) => return self.mode_request(now, r, sink),
            Request::Modules(r) => self.modules_request(now, r, sink)?,
            Request::Team(r) => self.team_request(now, r, sink)?,
            Request::Link(r) => self.link_select = Some(self.link_keys.select(now, r, &mut self.dl, sink)?),
            Request::Plan(r) => self.plan_request(now, r, sink)?,
        }
        Ok(Exec::Done)
    }
}
