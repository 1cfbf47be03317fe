//! Alarm records (ISA-18.2 style states) kept beside the data they are about. The
//! collector raises and clears them; operators acknowledge and shelve them.

use serde::Serialize;

use super::db::{collect, scalar, Val};
use super::{ArchiveError, Store};

/// The state of an alarm.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum AlarmState {
    /// The condition holds and nobody has acknowledged it.
    Active,
    /// An operator has seen it; the condition may still hold.
    Acknowledged,
    /// Hidden from the active list until `shelved_until_ms`.
    Shelved,
    /// The condition no longer holds (final).
    Cleared,
}

impl AlarmState {
    pub fn name(self) -> &'static str {
        match self {
            AlarmState::Active => "active",
            AlarmState::Acknowledged => "acknowledged",
            AlarmState::Shelved => "shelved",
            AlarmState::Cleared => "cleared",
        }
    }
    pub fn parse(s: &str) -> Option<AlarmState> {
        [
            AlarmState::Active,
            AlarmState::Acknowledged,
            AlarmState::Shelved,
            AlarmState::Cleared,
        ]
        .into_iter()
        .find(|a| a.name() == s)
    }
}

/// One alarm.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Alarm {
    pub id: i64,
    pub robot: u8,
    /// Parameter or event name (or `LINK`, `STALE`, `DISK` for the collector's own).
    pub source: String,
    pub severity: String,
    pub state: AlarmState,
    pub first_ms: i64,
    pub last_ms: i64,
    pub value: Option<String>,
    pub limit: Option<String>,
    /// How many times the condition was reported while the alarm was open.
    pub count: i64,
    pub ack_ms: Option<i64>,
    pub shelved_until_ms: Option<i64>,
    pub cleared_ms: Option<i64>,
}

/// A report of an alarm condition.
#[derive(Clone, Debug, PartialEq)]
pub struct AlarmUpdate<'a> {
    pub robot: u8,
    pub source: &'a str,
    pub severity: &'a str,
    pub value: &'a str,
    pub limit: &'a str,
    pub t_ms: i64,
}

const COLUMNS: &str = "id, robot, source, severity, state, first_ms, last_ms, value, limit_text, count, ack_ms, \
                       shelved_until_ms, cleared_ms";

fn alarm_of(r: &[Val]) -> Result<Alarm, ArchiveError> {
    let state = r[4].text().unwrap_or("");
    Ok(Alarm {
        id: r[0].int().unwrap_or(0),
        robot: r[1].int().unwrap_or(0) as u8,
        source: r[2].text().unwrap_or("").to_string(),
        severity: r[3].text().unwrap_or("").to_string(),
        state: AlarmState::parse(state).ok_or_else(|| {
            ArchiveError::Damaged(format!(
                "alarm {} has unknown state \"{state}\"",
                r[0].int().unwrap_or(0)
            ))
        })?,
        first_ms: r[5].int().unwrap_or(0),
        last_ms: r[6].int().unwrap_or(0),
        value: r[7].text().map(str::to_string),
        limit: r[8].text().map(str::to_string),
        count: r[9].int().unwrap_or(0),
        ack_ms: r[10].int(),
        shelved_until_ms: r[11].int(),
        cleared_ms: r[12].int(),
    })
}

impl Store {
    /// Raises (or refreshes) the open alarm of `(robot, source)`; returns its id. An
    /// acknowledged or shelved alarm keeps its state; its value and last time move on.
    pub fn raise_alarm(&mut self, u: &AlarmUpdate<'_>) -> Result<i64, ArchiveError> {
        let open = scalar(
            self.db.as_mut(),
            "SELECT id FROM alarm WHERE robot = ?1 AND source = ?2 AND state <> 'cleared' ORDER BY id DESC LIMIT 1",
            &[Val::Int(u.robot as i64), u.source.into()],
        )?
        .and_then(|v| v.int());
        if let Some(id) = open {
            self.db.exec(
                "UPDATE alarm SET last_ms = ?1, value = ?2, limit_text = ?3, severity = ?4, count = count + 1 \
                 WHERE id = ?5",
                &[
                    Val::Int(u.t_ms),
                    u.value.into(),
                    u.limit.into(),
                    u.severity.into(),
                    Val::Int(id),
                ],
            )?;
            return Ok(id);
        }
        scalar(
            self.db.as_mut(),
            "INSERT INTO alarm (robot, source, severity, state, first_ms, last_ms, value, limit_text, count) \
             VALUES (?1, ?2, ?3, 'active', ?4, ?4, ?5, ?6, 1) RETURNING id",
            &[
                Val::Int(u.robot as i64),
                u.source.into(),
                u.severity.into(),
                Val::Int(u.t_ms),
                u.value.into(),
                u.limit.into(),
            ],
        )?
        .and_then(|v| v.int())
        .ok_or_else(|| ArchiveError::Damaged("alarm insert returned no id".into()))
    }

    /// Clears the open alarm of `(robot, source)`; returns its id if there was one.
    pub fn clear_alarm(&mut self, robot: u8, source: &str, t_ms: i64) -> Result<Option<i64>, ArchiveError> {
        Ok(scalar(
            self.db.as_mut(),
            "UPDATE alarm SET state = 'cleared', cleared_ms = ?1, last_ms = ?1 \
             WHERE robot = ?2 AND source = ?3 AND state <> 'cleared' RETURNING id",
            &[Val::Int(t_ms), Val::Int(robot as i64), source.into()],
        )?
        .and_then(|v| v.int()))
    }

    fn alarm_by_id(&mut self, id: i64) -> Result<Alarm, ArchiveError> {
        let rows = collect(
            self.db.as_mut(),
            &format!("SELECT {COLUMNS} FROM alarm WHERE id = ?1"),
            &[Val::Int(id)],
        )?;
        match rows.first() {
            Some(r) => alarm_of(r),
            None => Err(ArchiveError::NotFound(format!("no alarm {id}"))),
        }
    }

    /// Acknowledges alarm `id` (active or shelved); a cleared alarm stays cleared.
    pub fn ack_alarm(&mut self, id: i64, t_ms: i64) -> Result<Alarm, ArchiveError> {
        self.db.exec(
            "UPDATE alarm SET state = 'acknowledged', ack_ms = ?1, shelved_until_ms = NULL \
             WHERE id = ?2 AND state IN ('active', 'shelved')",
            &[Val::Int(t_ms), Val::Int(id)],
        )?;
        self.alarm_by_id(id)
    }

    /// Shelves alarm `id` until `until_ms` (not a cleared one).
    pub fn shelve_alarm(&mut self, id: i64, until_ms: i64) -> Result<Alarm, ArchiveError> {
        self.db.exec(
            "UPDATE alarm SET state = 'shelved', shelved_until_ms = ?1 WHERE id = ?2 AND state <> 'cleared'",
            &[Val::Int(until_ms), Val::Int(id)],
        )?;
        self.alarm_by_id(id)
    }

    /// Returns shelved alarms whose time is up to active; returns how many.
    pub fn unshelve_expired(&mut self, now_ms: i64) -> Result<u64, ArchiveError> {
        Ok(self.db.exec(
            "UPDATE alarm SET state = 'active', shelved_until_ms = NULL WHERE state = 'shelved' AND shelved_until_ms <= ?1",
            &[Val::Int(now_ms)],
        )?)
    }

    /// Alarms of `robot` (all if `None`), optionally only those not cleared, oldest first.
    pub fn alarms(&mut self, robot: Option<u8>, open_only: bool) -> Result<Vec<Alarm>, ArchiveError> {
        let mut sql = format!("SELECT {COLUMNS} FROM alarm WHERE 1=1");
        let mut args = Vec::new();
        if let Some(r) = robot {
            args.push(Val::Int(r as i64));
            sql.push_str(" AND robot = ?1");
        }
        if open_only {
            sql.push_str(" AND state <> 'cleared'");
        }
        sql.push_str(" ORDER BY first_ms, id");
        collect(self.db.as_mut(), &sql, &args)?
            .iter()
            .map(|r| alarm_of(r))
            .collect()
    }
}
