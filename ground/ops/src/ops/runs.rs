//! Run identity and what `ground run --resume` reads back from the archive.
//!
//! Every `ground run` gets a run ID ([`new_run_id`]). Each session of a run (the first
//! one and every `--resume`) starts with a *start marker* per robot (a connection test),
//! archived with the label `start marker@RUN_ID` in the TC's `step` column: the TCs that
//! follow it on that robot's APID, up to the next start marker of any run, belong to that
//! run. Step TCs keep their plain step ID as label, so no schema change is needed and
//! `step = 'r1-bolt'` still finds a step's TCs. A resume continues one run under the same
//! ID: [`find_run`] picks it (the latest run of the plan, or the one named) and says, per
//! step, whether its TC completed, failed, was accepted or has no report at all.

use std::collections::BTreeMap;

use crate::archive::db::{collect, Val};
use crate::archive::{ArchiveError, Store};
use crate::plan::Plan;

use super::START_LABEL;

/// Separates the start marker's label from its run ID in the archive's `step` column.
pub const RUN_SEP: char = '@';

/// A fresh run ID: UTC start time and 16 bits that differ between two runs started in
/// the same second (process ID and clock nanoseconds).
pub fn new_run_id() -> String {
    let now = chrono::Utc::now();
    let salt = (std::process::id() ^ now.timestamp_subsec_nanos()) & 0xFFFF;
    format!("{}-{salt:04x}", now.format("%Y%m%d-%H%M%S"))
}

/// The text archived in a TC's `step` column: its label, and for a start marker of a
/// run, `start marker@RUN_ID`.
pub fn archived_label(label: Option<&str>, run: Option<&str>) -> Option<String> {
    match (label, run) {
        (Some(START_LABEL), Some(r)) => Some(format!("{START_LABEL}{RUN_SEP}{r}")),
        (l, _) => l.map(str::to_string),
    }
}

/// The run ID of an archived start marker's `step` column.
pub fn marker_run(step: &str) -> Option<&str> {
    step.strip_prefix(START_LABEL)
        .and_then(|r| r.strip_prefix(RUN_SEP))
        .filter(|r| !r.is_empty())
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

/// A start marker: where a session of a run begins on one robot.
struct Marker {
    id: i64,
    robot: u8,
    run: String,
    t_ms: i64,
}

/// Picks the run to resume: `wanted`, or else the latest run of `plan` (one whose
/// sessions sent a TC for a step of the plan).
pub fn find_run(store: &mut Store, plan: &Plan, wanted: Option<&str>) -> Result<RunRecord, ResumeError> {
    let robots: Vec<u8> = plan.robots.iter().map(|r| r.number).collect();
    // Every start marker of a run, oldest first: a small table (one row per session and
    // robot), read once.
    let rows = collect(
        store.db(),
        "SELECT id, robot, step, t_ms FROM tc WHERE step LIKE ?1 ORDER BY id",
        &[Val::Text(format!("{START_LABEL}{RUN_SEP}%"))],
    )
    .map_err(ArchiveError::from)?;
    let markers: Vec<Marker> = rows
        .iter()
        .filter_map(|r| {
            Some(Marker {
                id: r.first()?.int()?,
                robot: r.get(1)?.int()? as u8,
                run: marker_run(r.get(2)?.text()?)?.to_string(),
                t_ms: r.get(3)?.int()?,
            })
        })
        .filter(|m| robots.contains(&m.robot))
        .collect();
    // Runs, the latest first.
    let mut runs: Vec<&str> = Vec::new();
    for m in markers.iter().rev() {
        if !runs.contains(&m.run.as_str()) {
            runs.push(&m.run);
        }
    }
    let candidates: Vec<&str> = match wanted {
        Some(w) if runs.contains(&w) => vec![w],
        Some(w) => return Err(ResumeError::UnknownRun(w.to_string())),
        None => runs,
    };
    for run in candidates {
        let rec = read_run(store, plan, &markers, run)?;
        if !rec.steps.is_empty() {
            return Ok(rec);
        }
        if wanted.is_some() {
            return Err(ResumeError::OtherPlan {
                run: run.to_string(),
                plan: plan.name.clone(),
            });
        }
    }
    Err(ResumeError::NoRun(plan.name.clone()))
}

/// The step TCs of `run`: on each robot, those after each of its start markers up to
/// the next start marker (of any run) of that robot.
fn read_run(store: &mut Store, plan: &Plan, markers: &[Marker], run: &str) -> Result<RunRecord, ResumeError> {
    let mut steps: BTreeMap<String, StepTc> = BTreeMap::new();
    let (mut first_ms, mut last_ms) = (i64::MAX, i64::MIN);
    for (k, m) in markers.iter().enumerate().filter(|(_, m)| m.run == run) {
        first_ms = first_ms.min(m.t_ms);
        let end = markers[k + 1..]
            .iter()
            .find(|n| n.robot == m.robot)
            .map_or(i64::MAX, |n| n.id);
        let tcs = collect(
            store.db(),
            "SELECT step, name, apid, seq, raw, MIN(t_ms), MAX(t_ms) FROM tc \
             WHERE robot = ?1 AND id > ?2 AND id < ?3 AND step IS NOT NULL \
             GROUP BY step, name, apid, seq, raw ORDER BY MIN(t_ms)",
            &[Val::Int(m.robot as i64), Val::Int(m.id), Val::Int(end)],
        )
        .map_err(ArchiveError::from)?;
        for r in tcs {
            let int = |i: usize| r.get(i).and_then(Val::int).unwrap_or(0);
            last_ms = last_ms.max(int(6));
            let Some(label) = r.first().and_then(Val::text) else {
                continue;
            };
            if !plan.steps.iter().any(|s| s.id == label && s.robot == m.robot) {
                continue;
            }
            // Later TCs of the same step (sent after a resume) replace earlier ones.
            steps.insert(
                label.to_string(),
                StepTc {
                    robot: m.robot,
                    name: r.get(1).and_then(Val::text).unwrap_or("").to_string(),
                    apid: int(2) as u16,
                    seq: int(3) as u16,
                    raw: r.get(4).and_then(Val::blob).map(<[u8]>::to_vec).unwrap_or_default(),
                    sent_ms: int(5),
                    outcome: Outcome::NoReport,
                },
            );
        }
    }
    for tc in steps.values_mut() {
        tc.outcome = outcome(store, tc)?;
    }
    Ok(RunRecord {
        run_id: run.to_string(),
        first_ms,
        last_ms: last_ms.max(first_ms),
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

/// Last TM sequence count received from `robot`'s own APID (by ground time,
/// [`Store::last_received_seq`]: where its store replay of a resumed run starts), if any.
pub fn last_tm_seq(store: &mut Store, robot: u8) -> Result<Option<u16>, ArchiveError> {
    let apid = mib::apid::robot_apid(robot).unwrap_or(0);
    store.last_received_seq(robot, apid)
}

#[cfg(test)]
mod tests {
    use super::*;

    // verifies: OPS-RUN-01
    #[test]
    fn start_markers_carry_the_run_and_step_labels_stay_plain() {
        assert_eq!(
            archived_label(Some(START_LABEL), Some("R1")).as_deref(),
            Some("start marker@R1")
        );
        assert_eq!(archived_label(Some("r1-bolt"), Some("R1")).as_deref(), Some("r1-bolt"));
        assert_eq!(archived_label(None, Some("R1")), None);
        assert_eq!(marker_run("start marker@R1"), Some("R1"));
        assert_eq!(marker_run("start marker"), None);
        assert_eq!(marker_run("r1-bolt"), None);
        let (a, b) = (new_run_id(), new_run_id());
        assert!(!a.contains(RUN_SEP) && a.len() >= 20, "{a}");
        assert_eq!(a[..15], b[..15]);
    }
}
