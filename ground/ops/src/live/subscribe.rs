//! Is the robot sending to this ground? The one re-subscription rule of every front end.
//!
//! Over a UDP lab link a robot sends TM only to a ground whose TC it accepted (its
//! subscription, `mib::host_config::SUBSCRIPTION_LEASE_MS`); a TC lost or damaged on the
//! way leaves the ground unsubscribed (a damaged one's refusal reaches it, without
//! subscribing it). Until TM only a subscriber gets has come ([`Subscription::on_tm`]), a
//! watching ground sends a heartbeat every [`mib::ground_config::SUBSCRIBE_RETRY_MS`]
//! ([`Subscription::retry_due`]), so that its own lost TCs never make a live robot silent
//! for the link-loss time. A robot whose link is lost is not retried at that pace: the
//! front end's own pacing (the CLI stops, the collector backs off) decides.

use crate::pus::Tm;

/// [`mib::ground_config::SUBSCRIBE_RETRY_MS`] in ms.
pub const SUBSCRIBE_RETRY_MS: i64 = mib::ground_config::SUBSCRIBE_RETRY_MS as i64;

/// Whether a robot streams to this ground (see the module).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Subscription {
    streaming: bool,
}

impl Subscription {
    /// Whether `tm` shows the robot sending to this ground as to a subscriber of its UDP
    /// lab link: HK and successful verification reports go only to subscribers (the
    /// refusal of a TC that did not pass acceptance also goes to its sender, without
    /// subscribing it).
    pub fn subscribed_by(tm: &Tm) -> bool {
        tm.service == 3 || (tm.service == 1 && tm.subservice % 2 == 1)
    }

    /// A TM of the robot arrived.
    pub fn on_tm(&mut self, tm: &Tm) {
        self.streaming |= Self::subscribed_by(tm);
    }

    /// TM only a subscriber gets has come.
    pub fn streaming(&self) -> bool {
        self.streaming
    }

    /// The robot's subscription may be gone (its link was lost): retry again until it
    /// streams.
    pub fn lapse(&mut self) {
        self.streaming = false;
    }

    /// Whether a heartbeat is due now: the link subscribes (`subscribes`: UDP lab link),
    /// the robot does not stream yet, its link is not lost (`lost`) and the last TC went
    /// to it `since_last_tc_ms` ago, at least [`SUBSCRIBE_RETRY_MS`] (`None`: no TC yet).
    pub fn retry_due(&self, subscribes: bool, lost: bool, since_last_tc_ms: Option<i64>) -> bool {
        subscribes && !lost && !self.streaming && since_last_tc_ms.is_none_or(|t| t >= SUBSCRIBE_RETRY_MS)
    }
}
