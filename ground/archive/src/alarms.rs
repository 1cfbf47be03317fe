//! The alarm records: one table, whichever backend, for everything that raises alarms
//! (the collector's limit checks, events, link loss, stale data, the archive itself) and
//! everything that reads or answers them (`ground alarms`, `archive query --type alarm`,
//! the dashboard). Every transition goes through the ISA-18.2 state machine
//! [`crate::alarm_model::AlarmState`], read and written back in one transaction.

use serde::Serialize;

use super::db::{collect, Db, Dialect, Val};
use super::{ArchiveError, Store};
use crate::alarm_model::{AlarmState, Input, Severity, Source, State};

/// One alarm.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Alarm {
    pub id: i64,
    /// 0 for the collector's own alarms (the archive).
    pub robot: u8,
    /// `param`, `event`, `link`, `stale`, `archive`, `config` ([`Source::kind`]).
    pub kind: String,
    /// Parameter or event name, or `LINK_LOSS`, `STALE_DATA`, `ARCHIVE_WRITE`.
    pub source: String,
    pub severity: String,
    pub state: State,
    pub first_ms: i64,
    pub last_ms: i64,
    pub shelved_until_ms: Option<i64>,
    /// The value that raised or last refreshed it (engineering units), if any.
    pub value: Option<f64>,
    pub message: String,
    /// How many times the condition was reported while the alarm was open.
    pub count: i64,
    pub ack_ms: Option<i64>,
    /// When the condition went away (the alarm may still wait for an acknowledgement).
    pub cleared_ms: Option<i64>,
}

/// A condition report from a checker.
#[derive(Clone, Debug, PartialEq)]
pub struct AlarmUpdate<'a> {
    pub robot: u8,
    pub source: &'a Source,
    pub severity: Severity,
    pub input: Input,
    pub t_ms: i64,
    pub value: Option<f64>,
    pub message: &'a str,
}

/// The columns of [`Alarm`], in its order (also `archive query --type alarm`'s).
pub const COLUMNS: &str = "id, robot, kind, source, severity, state, first_ms, last_ms, shelved_until_ms, value, \
                           message, count, ack_ms, cleared_ms";

fn alarm_of(r: &[Val]) -> Result<Alarm, ArchiveError> {
    let id = r[0].int().unwrap_or(0);
    let state = r[5].text().unwrap_or("");
    Ok(Alarm {
        id,
        robot: r[1].int().unwrap_or(0) as u8,
        kind: r[2].text().unwrap_or("").to_string(),
        source: r[3].text().unwrap_or("").to_string(),
        severity: r[4].text().unwrap_or("").to_string(),
        state: State::parse(state)
            .ok_or_else(|| ArchiveError::Damaged(format!("alarm {id} has unknown state \"{state}\"")))?,
        first_ms: r[6].int().unwrap_or(0),
        last_ms: r[7].int().unwrap_or(0),
        shelved_until_ms: r[8].int(),
        value: match r[9] {
            Val::Real(v) => Some(v),
            Val::Int(v) => Some(v as f64),
            Val::Null | Val::Text(_) | Val::Blob(_) => None,
        },
        message: r[10].text().unwrap_or("").to_string(),
        count: r[11].int().unwrap_or(0),
        ack_ms: r[12].int(),
        cleared_ms: r[13].int(),
    })
}

/// The state machine's view of a stored alarm (`condition, acked, shelved_until_ms, state`).
fn machine_of(r: &[Val]) -> AlarmState {
    AlarmState {
        condition: r[0].int().unwrap_or(0) != 0,
        acked: r[1].int().unwrap_or(0) != 0,
        shelved_until_ms: r[2].int(),
        open: r[3].text() != Some(State::Normal.name()),
    }
}

const MACHINE: &str = "condition, acked, shelved_until_ms, state";

fn for_update(d: Dialect) -> &'static str {
    match d {
        // SQLite: the transaction already holds the write lock (BEGIN IMMEDIATE).
        Dialect::Sqlite => "",
        Dialect::Postgres => " FOR UPDATE",
    }
}

impl Store {
    /// Runs `f` in one write transaction (rolled back if it fails).
    pub(crate) fn write_tx<R>(
        &mut self,
        f: impl FnOnce(&mut dyn Db) -> Result<R, ArchiveError>,
    ) -> Result<R, ArchiveError> {
        let db = self.db.as_mut();
        db.batch(match db.dialect() {
            Dialect::Sqlite => "BEGIN IMMEDIATE",
            Dialect::Postgres => "BEGIN",
        })?;
        match f(db) {
            Ok(r) => {
                db.batch("COMMIT")?;
                Ok(r)
            }
            Err(e) => {
                let _ = db.batch("ROLLBACK");
                Err(e)
            }
        }
    }

    /// Applies a condition report to the open alarm of (robot, source), opening a new
    /// alarm if there is none and the condition is present. Returns the alarm's ID, or
    /// `None` for a clear with nothing open.
    pub fn apply_alarm(&mut self, u: &AlarmUpdate<'_>) -> Result<Option<i64>, ArchiveError> {
        self.write_tx(|db| {
            let lock = for_update(db.dialect());
            let open = collect(
                db,
                &format!(
                    "SELECT id, {MACHINE} FROM alarm WHERE robot = ?1 AND kind = ?2 AND source = ?3 \
                     AND state <> 'normal' ORDER BY id DESC LIMIT 1{lock}"
                ),
                &[Val::Int(u.robot as i64), u.source.kind().into(), u.source.name().into()],
            )?;
            let raise = u.input == Input::Activate;
            match open.first() {
                Some(row) => {
                    let id = row[0].int().unwrap_or(0);
                    let mut st = machine_of(&row[1..]);
                    st.apply(u.input, u.t_ms)
                        .map_err(|e| ArchiveError::Refused(format!("alarm {id}: {e}")))?;
                    let value = u.value.map_or(Val::Null, Val::Real);
                    db.exec(
                        "UPDATE alarm SET condition = ?2, acked = ?3, shelved_until_ms = ?4, state = ?5, last_ms = ?6, \
                         value = COALESCE(?7, value), message = ?8, count = count + ?9, \
                         severity = CASE WHEN ?9 > 0 AND ?10 = 'high' THEN 'high' ELSE severity END, \
                         cleared_ms = CASE WHEN ?9 > 0 THEN NULL WHEN cleared_ms IS NULL THEN ?6 ELSE cleared_ms END \
                         WHERE id = ?1",
                        &[
                            Val::Int(id),
                            Val::Int(st.condition as i64),
                            Val::Int(st.acked as i64),
                            st.shelved_until_ms.into(),
                            st.state().name().into(),
                            Val::Int(u.t_ms),
                            value,
                            u.message.into(),
                            Val::Int(raise as i64),
                            u.severity.name().into(),
                        ],
                    )?;
                    Ok(Some(id))
                }
                None if raise => {
                    let mut st = AlarmState::default();
                    st.apply(u.input, u.t_ms)
                        .map_err(|e| ArchiveError::Refused(e.to_string()))?;
                    let id = collect(
                        db,
                        "INSERT INTO alarm (robot, kind, source, severity, state, condition, acked, first_ms, last_ms, \
                         value, message, count) VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?8, ?9, ?10, 1) RETURNING id",
                        &[
                            Val::Int(u.robot as i64),
                            u.source.kind().into(),
                            u.source.name().into(),
                            u.severity.name().into(),
                            st.state().name().into(),
                            Val::Int(st.condition as i64),
                            Val::Int(st.acked as i64),
                            Val::Int(u.t_ms),
                            u.value.map_or(Val::Null, Val::Real),
                            u.message.into(),
                        ],
                    )?
                    .first()
                    .and_then(|r| r[0].int())
                    .ok_or_else(|| ArchiveError::Damaged("alarm insert returned no id".into()))?;
                    Ok(Some(id))
                }
                None => Ok(None),
            }
        })
    }

    /// Applies an operator input (acknowledge, shelve, unshelve) or a tick to alarm
    /// `id`; returns the state it is in afterwards. A refused input changes nothing and
    /// is an [`ArchiveError::Refused`] saying why.
    pub fn alarm_input(&mut self, id: i64, input: Input, now_ms: i64) -> Result<State, ArchiveError> {
        self.write_tx(|db| {
            let lock = for_update(db.dialect());
            let rows = collect(
                db,
                &format!("SELECT {MACHINE} FROM alarm WHERE id = ?1{lock}"),
                &[Val::Int(id)],
            )?;
            let Some(row) = rows.first() else {
                return Err(ArchiveError::NotFound(format!("no alarm with ID {id}")));
            };
            let mut st = machine_of(row);
            st.apply(input, now_ms)
                .map_err(|e| ArchiveError::Refused(format!("alarm {id}: {e}")))?;
            let ack_ms = (input == Input::Ack).then_some(now_ms);
            db.exec(
                "UPDATE alarm SET condition = ?2, acked = ?3, shelved_until_ms = ?4, state = ?5, \
                 ack_ms = COALESCE(?6, ack_ms) WHERE id = ?1",
                &[
                    Val::Int(id),
                    Val::Int(st.condition as i64),
                    Val::Int(st.acked as i64),
                    st.shelved_until_ms.into(),
                    st.state().name().into(),
                    ack_ms.into(),
                ],
            )?;
            Ok(st.state())
        })
    }

    /// Ends the shelves whose time is up; returns how many alarms changed.
    pub fn expire_shelves(&mut self, now_ms: i64) -> Result<u64, ArchiveError> {
        let ids: Vec<i64> = collect(
            self.db.as_mut(),
            "SELECT id FROM alarm WHERE state = 'shelved' AND shelved_until_ms <= ?1",
            &[Val::Int(now_ms)],
        )?
        .iter()
        .filter_map(|r| r[0].int())
        .collect();
        let mut n = 0;
        for id in ids {
            self.alarm_input(id, Input::Tick, now_ms)?;
            n += 1;
        }
        Ok(n)
    }

    /// Alarms of `robot` (all robots if `None`), newest first; closed (normal) ones
    /// only with `all`.
    pub fn alarms(&mut self, robot: Option<u8>, all: bool) -> Result<Vec<Alarm>, ArchiveError> {
        let mut sql = format!("SELECT {COLUMNS} FROM alarm WHERE 1=1");
        let mut args = Vec::new();
        if let Some(r) = robot {
            args.push(Val::Int(r as i64));
            sql.push_str(" AND robot = ?1");
        }
        if !all {
            sql.push_str(" AND state <> 'normal'");
        }
        sql.push_str(" ORDER BY id DESC");
        collect(self.db.as_mut(), &sql, &args)?
            .iter()
            .map(|r| alarm_of(r))
            .collect()
    }
}
