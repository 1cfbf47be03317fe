//! Acceptance, second half: a [`Tc`] whose header and arguments passed `accept` becomes
//! a typed [`Request`] of one PUS service (the table is in `crate::services`), with every
//! look-up the MIB allows done once (an HK structure, an event, a monitor, a node...). A request that names
//! something the MIB does not define is refused at acceptance with its failure code;
//! a request that was made can always be executed without looking anything up again.

use crate::accept::Tc;
use crate::failure::Failure;
use crate::time::OnboardTime;

pub use crate::services::Request;

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

/// The refusal of a subservice the MIB defines but no handler knows.
pub(crate) fn unknown(tc: &Tc) -> Failure {
    Failure::unknown_subservice(tc.service, tc.subservice)
}
