//! Run identity and what `ground run --resume` reads back from the archive.
//!
//! Every `ground run` gets a run ID ([`new_run_id`]). The session archives it with
//! every TC it sends, in the TC's `step` column as `LABEL@RUN_ID` (`r1-bolt@20261124-
//! 061502-3fa2`, `heartbeat@…`): no schema change, and a step's TCs of one run are told
//! from those of another. A resume continues one run under the same ID: [`find_run`]
//! picks it (the latest run of the plan, or the one named) and says, per step, whether
//! its TC completed, failed, was accepted or has no report at all.

use std::collections::BTreeMap;

use crate::archive::db::{collect, Val};
use crate::archive::{ArchiveError, Store};
use crate::plan::Plan;

/// Separates a TC's label from its run ID in the archive's `step` column.
pub const RUN_SEP: char = '@';

/// A fresh run ID: UTC start time and 16 bits that differ between two runs started in
/// the same second (process ID and clock nanoseconds).
pub fn new_run_id() -> String {
    let now = chrono::Utc::now();
    let salt = (std::process::id() ^ now.timestamp_subsec_nanos()) & 0xFFFF;
    format!("{}-{salt:04x}", now.format("%Y%m%d-%H%M%S"))
}

/// The text archived in a TC's `step` column: its label, and `@RUN_ID` when the TC
/// belongs to a run.
pub fn archived_label(label: Option<&str>, run: Option<&str>) -> Option<String> {
    match (label, run) {
        (l, Some(r)) => Some(format!("{}{RUN_SEP}{r}", l.unwrap_or(""))),
        (Some(l), None) => Some(l.to_string()),
        (None, None) => None,
    }
}

/// `(label, run ID)` of an archived `step` column.
pub fn split_label(s: &str) -> (&str, Option<&str>) {
    match s.rsplit_once(RUN_SEP) {
        Some((l, r)) if !r.is_empty() => (l, Some(r)),
        _ => (s, None),
    }
}

/// What the archive knows of a step's TC in a run.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Outcome {
    /// A successful completion report (TM[1,7]).
    Completed,
    /// A failure report (TM[1,2], [1,4], [1,6] or [1,8]), in words.
    Failed(String),
    /// Accepted (TM[1,1]) but neither completed nor failed: it may still run on board,
    /// or its last report was not received.
    Accepted,
    /// Sent, no report at all: the TC may never have arrived, or its reports were lost.
    NoReport,
}

/// The last TC a run sent for one step.
#[derive(Clone, Debug)]
pub struct StepTc {
    pub robot: u8,
    pub name: String,
    pub apid: u16,
    pub seq: u16,
    pub raw: Vec<u8>,
    /// Ground time of its first send (ms since the Unix epoch).
    pub sent_ms: i64,
    pub outcome: Outcome,
}

/// One run of a plan as the archive shows it.
#[derive(Clone, Debug)]
pub struct RunRecord {
    pub run_id: String,
    /// Ground time of the run's first and last TC.
    pub first_ms: i64,
    pub last_ms: i64,
    /// Steps of the plan whose TC the run sent, by step ID.
    pub steps: BTreeMap<String, StepTc>,
}

/// Why a run cannot be resumed.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ResumeError {
    #[error("the archive has no run of plan \"{0}\" (a run's TCs are archived with its run ID)")]
    NoRun(String),
    #[error("the archive has no run {0}")]
    UnknownRun(String),
    #[error("run {run} did not run plan \"{plan}\" (none of its TCs belong to a step of this plan)")]
    OtherPlan { run: String, plan: String },
    #[error(transparent)]
    Archive(#[from] ArchiveError),
}

/// Picks the run to resume: `wanted`, or else the run of `plan` that sent a TC last.
pub fn find_run(store: &mut Store, plan: &Plan, wanted: Option<&str>) -> Result<RunRecord, ResumeError> {
    let is_step = |l: &str| plan.steps.iter().any(|s| s.id == l);
    // One row per (label, run): steps × runs rows, not one per TC sent.
    let rows = collect(
        store.db(),
        "SELECT step, MIN(t_ms), MAX(t_ms) FROM tc WHERE step LIKE '%@%' GROUP BY step",
        &[],
    )
    .map_err(ArchiveError::from)?;
    // run -> (first, last, has a step of this plan)
    let mut runs: BTreeMap<String, (i64, i64, bool)> = BTreeMap::new();
    for r in &rows {
        let Some(step) = r.first().and_then(Val::text) else {
            continue;
        };
        let (label, Some(run)) = split_label(step) else {
            continue;
        };
        let first = r.get(1).and_then(Val::int).unwrap_or(0);
        let last = r.get(2).and_then(Val::int).unwrap_or(0);
        let e = runs.entry(run.to_string()).or_insert((first, last, false));
        e.0 = e.0.min(first);
        e.1 = e.1.max(last);
        e.2 |= is_step(label);
    }
    let (run_id, (first_ms, last_ms, _)) = match wanted {
        Some(w) => {
            let (k, v) = runs
                .get_key_value(w)
                .ok_or_else(|| ResumeError::UnknownRun(w.to_string()))?;
            if !v.2 {
                return Err(ResumeError::OtherPlan {
                    run: w.to_string(),
                    plan: plan.name.clone(),
                });
            }
            (k.clone(), *v)
        }
        None => runs
            .iter()
            .filter(|(_, v)| v.2)
            .max_by_key(|(_, v)| v.1)
            .map(|(k, v)| (k.clone(), *v))
            .ok_or_else(|| ResumeError::NoRun(plan.name.clone()))?,
    };
    let mut steps = BTreeMap::new();
    let tcs = collect(
        store.db(),
        "SELECT step, robot, name, apid, seq, raw, MIN(t_ms) FROM tc WHERE step LIKE ?1 \
         GROUP BY step, robot, name, apid, seq, raw ORDER BY MIN(t_ms)",
        &[Val::Text(format!("%{RUN_SEP}{run_id}"))],
    )
    .map_err(ArchiveError::from)?;
    for r in tcs {
        let Some(step) = r.first().and_then(Val::text) else {
            continue;
        };
        let (label, Some(run)) = split_label(step) else {
            continue;
        };
        if run != run_id || !is_step(label) {
            continue;
        }
        let int = |i: usize| r.get(i).and_then(Val::int).unwrap_or(0);
        let tc = StepTc {
            robot: int(1) as u8,
            name: r.get(2).and_then(Val::text).unwrap_or("").to_string(),
            apid: int(3) as u16,
            seq: int(4) as u16,
            raw: r.get(5).and_then(Val::blob).map(<[u8]>::to_vec).unwrap_or_default(),
            sent_ms: int(6),
            outcome: Outcome::NoReport,
        };
        // Later TCs of the same step (sent after a resume) replace earlier ones.
        steps.insert(label.to_string(), tc);
    }
    for tc in steps.values_mut() {
        tc.outcome = outcome(store, tc)?;
    }
    Ok(RunRecord {
        run_id,
        first_ms,
        last_ms,
        steps,
    })
}

/// The archive's verdict on one TC: its reports received after it was sent.
fn outcome(store: &mut Store, tc: &StepTc) -> Result<Outcome, ArchiveError> {
    let rows = collect(
        store.db(),
        "SELECT stage, success, code_name, failure FROM verification \
         WHERE req_apid = ?1 AND req_seq = ?2 AND t_ms >= ?3 ORDER BY t_ms",
        &[Val::Int(tc.apid as i64), Val::Int(tc.seq as i64), Val::Int(tc.sent_ms)],
    )?;
    let mut accepted = false;
    for r in rows {
        let stage = r.first().and_then(Val::text).unwrap_or("");
        let ok = r.get(1).and_then(Val::int) == Some(1);
        if !ok {
            let code = r.get(2).and_then(Val::text).unwrap_or("?");
            let why = r.get(3).and_then(Val::text).unwrap_or("");
            return Ok(Outcome::Failed(
                format!("{stage} failed: {code} {why}").trim_end().to_string(),
            ));
        }
        match stage {
            "completion" => return Ok(Outcome::Completed),
            "acceptance" => accepted = true,
            _ => {}
        }
    }
    Ok(if accepted { Outcome::Accepted } else { Outcome::NoReport })
}

/// Last TM sequence count archived from `robot`'s own APID (where its store replay of
/// a resumed run starts), if any.
pub fn last_tm_seq(store: &mut Store, robot: u8) -> Result<Option<u16>, ArchiveError> {
    let apid = mib::apid::robot_apid(robot).unwrap_or(0);
    Ok(store
        .positions(Some(robot))?
        .into_iter()
        .find(|p| p.apid == apid)
        .map(|p| p.seq))
}

#[cfg(test)]
mod tests {
    use super::*;

    // verifies: OPS-RUN-01
    #[test]
    fn labels_carry_the_run_and_split_back() {
        assert_eq!(
            archived_label(Some("r1-bolt"), Some("R1")).as_deref(),
            Some("r1-bolt@R1")
        );
        assert_eq!(archived_label(None, Some("R1")).as_deref(), Some("@R1"));
        assert_eq!(archived_label(Some("watch"), None).as_deref(), Some("watch"));
        assert_eq!(split_label("r1@bolt@R1"), ("r1@bolt", Some("R1")));
        assert_eq!(split_label("heartbeat"), ("heartbeat", None));
        let (a, b) = (new_run_id(), new_run_id());
        assert!(!a.contains(RUN_SEP) && a.len() >= 20, "{a}");
        assert_eq!(a[..15], b[..15]);
    }
}
