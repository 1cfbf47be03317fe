//! Live operations, one per-robot engine for the CLI verbs:
//! - [`Session`] (`session.rs`): the links to several robots, TCs with per-APID sequence
//!   counts, PUS 1 verification per TC, resends of the same bytes until *acceptance*
//!   (never after: a lost completion report is a TM gap, filled from the on-board
//!   store), the archive; [`RobotStatus`] and the three [`NoAnswer`] cases
//!   (`status.rs`); sequence tracking of every APID ([`SeqTrack`], `seq.rs`);
//! - [`Executor`] (`executor.rs`): plan execution as a pure state machine on a mock clock;
//! - [`run_plan`] (`run.rs`): drives both, with start markers, interruption, resolution
//!   of a resumed run's unknown TCs and the final gap retrieval; its [`RunSummary`]
//!   (`summary.rs`);
//! - [`runs`]: run IDs and what `--resume` reads from the archive;
//! - [`policy`]: TC and argument names, hazardous-TC confirmation.

use std::time::Duration;

pub mod book;
mod executor;
pub mod policy;
mod run;
pub mod runs;
mod seq;
mod session;
mod status;
mod summary;
#[cfg(test)]
mod tests;

pub use book::{Pending, TcBook};
pub use executor::{Effect, Executor, RunOptions, StepState, INTERRUPT_GRACE};
pub use run::{run_plan, InFlight, Resume};
pub(crate) use seq::SEQ_MOD;
pub use seq::{SeqKind, SeqTrack, SEQ_TRACK_WINDOW};
pub use session::{failure_words, first_tc_seq, OpsError, Session, Update, SEQ_SKIP_AFTER_RESTART};
pub use status::{NoAnswer, RobotStatus};
pub use summary::{BoltStats, LinkSummary, RunSummary, StepOutcome, TmCompleteness};

/// Label of the connection test that starts a run's TM accounting.
pub const START_LABEL: &str = "start marker";

/// Label of the store retrievals a session sends for TM gaps.
pub const GAP_LABEL: &str = "gap retrieval";
/// Most sequence ranges asked of one robot's store at a time.
pub const GAP_REQUESTS_MAX: usize = 16;
/// Gaps closer than this are asked in one range (the packets between come again and
/// are dropped as duplicates): fewer requests on a link that loses many packets.
pub const GAP_MERGE_DISTANCE: u16 = 16;
pub use mib::config::RETRIEVAL_WAITS;

/// How long an accepted TC that no step waits for (a marker, a store retrieval) is
/// tracked for its completion: it is never resent, and a lost completion report is
/// recovered as a TM gap; after this it is forgotten (a retrieval is asked again).
pub const UNTAGGED_COMPLETION_WAIT: Duration = Duration::from_secs(5);
