//! Acceptance, second half: a [`Tc`] whose header and arguments passed `accept` becomes
//! a typed [`Request`] of one PUS service, with every look-up the MIB allows done once
//! here (an HK structure, an event, a monitor, a node...). A request that names
//! something the MIB does not define is refused at acceptance with its failure code;
//! a request that was made can always be executed without looking anything up again.

use mib::tc::service;

use crate::accept::Tc;
use crate::failure::Failure;
use crate::services::{
    event, event_action, function, hk, link, mode, modules, monitoring, parameter, plan, scheduling, storage, team,
    test, time, update,
};
use crate::time::OnboardTime;

/// What acceptance needs to know of the OBSW's state.
#[derive(Clone, Copy, Debug)]
pub struct Ctx {
    pub apid: u16,
    pub time: OnboardTime,
    /// Latest on-board time seen.
    pub now: u64,
    /// Free entries in the time-based schedule.
    pub sched_free: usize,
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

/// The refusal of a subservice the MIB defines but no handler knows.
pub(crate) fn unknown(tc: &Tc) -> Failure {
    Failure::unknown_subservice(tc.service, tc.subservice)
}
