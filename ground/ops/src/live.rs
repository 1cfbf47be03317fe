//! The live link of one robot, the same for every front end (the CLI's
//! [`crate::ops::Session`], the collector's per-robot worker and the page it feeds):
//! - [`LinkWatch`] (`watch.rs`): is the link up? One link-loss rule
//!   ([`mib::ground_config::link_loss_ms`]: no TM for 2.5 status-HK intervals, at least
//!   [`mib::ground_config::LINK_LOSS_MS`]);
//! - [`ApidTracker`] (`track.rs`): is the TM complete? Sequence counts of one APID:
//!   new, filled, duplicate, restart; the holes to retrieve and the ones that can no
//!   longer be had;
//! - [`GapPlan`] (`gaps.rs`): which store retrievals to send for the holes — one merge
//!   distance and one set of request limits, all from the MIB;
//! - [`RetrievalPacer`] (`pace.rs`): when a store retrieval is in flight and when the next
//!   may go — one in flight per robot, ended by its end report, its TC's outcome or
//!   [`mib::ground_config::STORE_REQUEST_TIMEOUT_MS`], spaced by
//!   [`mib::ground_config::STORE_REQUEST_MIN_GAP_MS`];
//! - [`Subscription`] (`subscribe.rs`): is the robot sending to this ground? Over a UDP lab
//!   link a heartbeat every [`mib::ground_config::SUBSCRIBE_RETRY_MS`] until it streams.
//!
//! Pure: no I/O, times passed in (ms).

mod gaps;
mod pace;
mod subscribe;
mod tm;
mod track;
mod watch;

pub use gaps::GapPlan;
pub use pace::RetrievalPacer;
pub use subscribe::{Subscription, SUBSCRIBE_RETRY_MS};
pub use tm::{is_boot, position, store_done, store_time_args, StoreDone};
pub use track::{ApidTracker, Lost, LostRun, Pos, Verdict, BOOT_FIRST_SEQ, MAX_MISSING, RECENT_WINDOW};
pub use watch::{LinkLoss, LinkState, LinkWatch};

#[cfg(test)]
mod tests;
