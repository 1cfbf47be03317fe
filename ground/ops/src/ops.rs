//! Live operations, one per-robot engine for the CLI verbs:
//! - [`Session`] (`session.rs`): the links to several robots, TCs with per-APID sequence
//!   counts, PUS 1 verification per TC, resends of the same bytes until *acceptance*
//!   (never after: a lost completion report is a TM gap, filled from the on-board
//!   store), the archive; [`RobotStatus`] and the three [`NoAnswer`] cases
//!   (`status.rs`); link state, sequence tracking and gap retrieval of every robot by
//!   the components every front end uses ([`crate::live`]);
//! - [`Executor`] (`executor.rs`): plan execution as a pure state machine on a mock clock;
//! - [`run_plan`] (`run.rs`): drives both, with start markers, interruption, resolution
//!   of a resumed run's unknown TCs and the final gap retrieval; its [`RunSummary`]
//!   (`summary.rs`);
//! - [`runs`]: run IDs and what `--resume` reads from the archive;
//! - [`policy`]: TC and argument names, hazardous-TC confirmation.

use std::time::Duration;

pub mod book;
mod executor;
mod onboard;
pub mod policy;
mod run;
pub mod runs;
mod session;
mod span;
mod status;
mod summary;
#[cfg(test)]
mod tests;

pub use book::{Pending, TcBook};
pub use executor::{Effect, Executor, RunOptions, SendError, StepState, INTERRUPT_GRACE};
pub use onboard::{upload_and_start, OnBoard};
pub use run::{run_plan, InFlight, Resume};
pub use session::{failure_words, first_tc_seq, OpsError, Session, Update, SEQ_SKIP_AFTER_RESTART};
pub use span::SpanAsk;
pub use status::{NoAnswer, RobotStatus};
pub use summary::{BoltStats, LinkSummary, RunSummary, StepOutcome, TmCompleteness};

/// Label of the connection test that starts a run's TM accounting.
pub const START_LABEL: &str = "start marker";

/// Label of the store retrievals a session sends for TM gaps.
pub const GAP_LABEL: &str = "gap retrieval";
pub use mib::ground_config::{GAP_MERGE_DISTANCE, GAP_REQUESTS_MAX};

/// [`mib::ground_config::UNTAGGED_COMPLETION_WAIT_MS`]: how long an accepted TC that no step
/// waits for (a marker, a store retrieval) is tracked for its completion.
pub const UNTAGGED_COMPLETION_WAIT: Duration =
    Duration::from_millis(mib::ground_config::UNTAGGED_COMPLETION_WAIT_MS as u64);
