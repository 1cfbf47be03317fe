//! The collector's side of the archive, in one place: where TM goes, where the last
//! archived position of each robot comes from, and the collector's own records (alarms,
//! unrecoverable holes, robot health).
//!
//! TM goes through the archive's writer ([`Archive`]). The sink keeps every record it
//! handed over until the writer confirmed the commit (a sync once a second); if the
//! writer fails (disk full, I/O error) the uncommitted records stay in memory, an
//! `ARCHIVE_WRITE` alarm is raised and the archive is reopened every few seconds;
//! records are then written again unless the archive already holds them. SQLite rolls a
//! failed transaction back, so the file is never half-written.

use std::path::{Path, PathBuf};
use std::time::Duration;

use anyhow::{Context, Result};
use crossbeam_channel::{Receiver, RecvTimeoutError, Sender};
use rusqlite::{params, Connection, OptionalExtension};
use serde::Serialize;

use crate::alarms::{AlarmState, Input, Refused, Severity, Source, State};
use crate::archive::{self, Archive, ArchiveSender, Record};
use crate::pus;

use super::tracker::{Lost, LostRun, Pos, SEQ_MOD};
use crate::archive::GapReason;

/// Most TM records kept in memory while the archive cannot be written; beyond, the
/// oldest are dropped and counted (`dropped_unwritable`).
pub const MAX_PENDING: usize = 200_000;
/// Commit confirmation period.
const SYNC_MS: i64 = 1_000;
/// Reopen attempts while the archive fails.
const REOPEN_MS: i64 = 3_000;
/// Check of expired shelves.
const SHELVE_TICK_MS: i64 = 5_000;

const SCHEMA: &str = "
CREATE TABLE IF NOT EXISTS collect_alarm (
    id INTEGER PRIMARY KEY, robot INTEGER NOT NULL, kind TEXT NOT NULL, source TEXT NOT NULL,
    severity TEXT NOT NULL, state TEXT NOT NULL, condition INTEGER NOT NULL, acked INTEGER NOT NULL,
    shelved_until_ms INTEGER, first_ms INTEGER NOT NULL, last_ms INTEGER NOT NULL,
    value REAL, message TEXT, count INTEGER NOT NULL);
CREATE INDEX IF NOT EXISTS collect_alarm_open ON collect_alarm(robot, kind, source, state);
CREATE TABLE IF NOT EXISTS collect_gap (
    id INTEGER PRIMARY KEY, t_ms INTEGER NOT NULL, robot INTEGER NOT NULL, apid INTEGER NOT NULL,
    first_seq INTEGER NOT NULL, last_seq INTEGER NOT NULL, count INTEGER NOT NULL,
    after_obt_ms INTEGER, before_obt_ms INTEGER, reason TEXT NOT NULL);
CREATE TABLE IF NOT EXISTS collect_robot (
    robot INTEGER PRIMARY KEY, addr TEXT, link TEXT, last_heard_ms INTEGER, last_hk_ms INTEGER,
    packets INTEGER, filled INTEGER, lost INTEGER, duplicates INTEGER, corrupt INTEGER,
    reboots INTEGER, updated_ms INTEGER NOT NULL);
";

/// Opens the archive's database with the collector's tables.
pub fn open_conn(path: &Path) -> Result<Connection> {
    let c = archive::open_db(path).with_context(|| format!("archive {}", path.display()))?;
    c.execute_batch(SCHEMA)?;
    Ok(c)
}

/// Opens an existing archive for reading (never creates one).
pub fn open_existing(path: &Path) -> Result<Connection> {
    if !path.exists() {
        anyhow::bail!("archive {} does not exist", path.display());
    }
    open_conn(path)
}

/// The newest archived packets of a robot per APID (at most `n` each, oldest first),
/// from which the collector resumes after a restart: the last position and the holes
/// among them.
pub fn recent_positions(c: &Connection, robot: u8, n: usize) -> Result<Vec<(u16, Vec<Pos>)>> {
    let mut out = Vec::new();
    let apids: Vec<i64> = c
        .prepare("SELECT DISTINCT apid FROM packet WHERE robot = ?1")?
        .query_map([robot as i64], |r| r.get(0))?
        .collect::<Result<_, _>>()?;
    for apid in apids {
        let mut v: Vec<Pos> = c
            .prepare(
                "SELECT seq, obt_ms FROM packet WHERE robot = ?1 AND apid = ?2
                 ORDER BY obt_ms DESC, seq DESC LIMIT ?3",
            )?
            .query_map(params![robot as i64, apid, n as i64], |r| {
                Ok(Pos {
                    seq: r.get::<_, i64>(0)? as u16,
                    obt_ms: r.get(1)?,
                })
            })?
            .collect::<Result<_, _>>()?;
        v.reverse();
        out.push((apid as u16, v));
    }
    // Packets kept raw (intact, but their body did not decode) count as received too.
    let raws: Vec<Vec<u8>> = c
        .prepare("SELECT raw FROM bad_packet WHERE link_robot = ?1 ORDER BY id DESC LIMIT ?2")?
        .query_map(params![robot as i64, n as i64], |r| r.get(0))?
        .collect::<Result<_, _>>()?;
    for raw in raws {
        let Some((apid, pos)) = super::onboard::intact_position(&raw) else {
            continue;
        };
        match out.iter_mut().find(|(a, _)| *a == apid) {
            Some((_, v)) => v.push(pos),
            None => out.push((apid, vec![pos])),
        }
    }
    for (_, v) in out.iter_mut() {
        v.sort_by_key(|p| (p.obt_ms, p.seq));
    }
    Ok(out)
}

/// Of `records` (handed to a writer that then failed), those the archive does not hold.
/// One range scan over the ground-time index, however many records.
fn not_archived(c: &Connection, records: Vec<(i64, u8, Vec<u8>)>) -> rusqlite::Result<Vec<(i64, u8, Vec<u8>)>> {
    let Some(since) = records.iter().map(|r| r.0).min() else {
        return Ok(records);
    };
    let mut keys = std::collections::HashSet::new();
    let mut st = c.prepare("SELECT apid, seq, obt_ms FROM packet WHERE t_ms >= ?1")?;
    let mut rows = st.query([since])?;
    while let Some(r) = rows.next()? {
        keys.insert((r.get::<_, i64>(0)?, r.get::<_, i64>(1)?, r.get::<_, i64>(2)?));
    }
    let mut raws = std::collections::HashSet::new();
    let mut st = c.prepare("SELECT raw FROM bad_packet WHERE t_ms >= ?1")?;
    let mut rows = st.query([since])?;
    while let Some(r) = rows.next()? {
        if let Some(raw) = r.get::<_, Option<Vec<u8>>>(0)? {
            raws.insert(raw);
        }
    }
    Ok(records
        .into_iter()
        .filter(|(_, _, raw)| match pus::decode_tm(raw) {
            Ok(tm) => !keys.contains(&(tm.apid as i64, tm.seq as i64, tm.time.unix_ms())),
            Err(_) => !raws.contains(raw),
        })
        .collect())
}

/// A robot's health, as the collector last wrote it.
#[derive(Clone, Debug, Default, Serialize, PartialEq)]
pub struct Health {
    pub robot: u8,
    pub addr: String,
    pub link: String,
    pub last_heard_ms: Option<i64>,
    pub last_hk_ms: Option<i64>,
    pub packets: u64,
    pub filled: u64,
    pub lost: u64,
    pub duplicates: u64,
    pub corrupt: u64,
    pub reboots: u64,
    pub updated_ms: i64,
}

/// What the robot threads hand to the sink.
#[derive(Debug)]
pub enum SinkMsg {
    Tm {
        t_ms: i64,
        robot: u8,
        raw: Vec<u8>,
    },
    Alarm {
        robot: u8,
        source: Source,
        severity: Severity,
        input: Input,
        t_ms: i64,
        value: Option<f64>,
        message: String,
    },
    Lost {
        robot: u8,
        apid: u16,
        run: LostRun,
        t_ms: i64,
    },
    Health(Health),
    /// Answered once everything before it is committed (or kept for later).
    Flush(Sender<()>),
}

/// Counters of the sink.
#[derive(Clone, Debug, Default, Serialize)]
pub struct SinkStats {
    pub tm_written: u64,
    pub tm_skipped_present: u64,
    pub pending: usize,
    pub dropped_unwritable: u64,
    pub write_failures: u64,
    pub pruned_rows: u64,
}

/// Settings of the sink.
#[derive(Clone, Debug)]
pub struct SinkCfg {
    pub path: PathBuf,
    /// Delete archived data older than this (ms); `None` keeps everything.
    pub retain_ms: Option<i64>,
    pub prune_every_ms: i64,
}

struct Sink {
    cfg: SinkCfg,
    archive: Option<Archive>,
    sender: Option<ArchiveSender>,
    conn: Option<Connection>,
    /// Handed to the writer, not yet confirmed committed.
    unconfirmed: Vec<(i64, u8, Vec<u8>)>,
    /// Handed to a writer that then failed: committed or not, checked on reopening.
    suspect: Vec<(i64, u8, Vec<u8>)>,
    /// Not handed over (archive failing).
    pending: std::collections::VecDeque<(i64, u8, Vec<u8>)>,
    /// Collector records waiting for a writable archive.
    deferred: Vec<SinkMsg>,
    failing_since: Option<i64>,
    last_reopen_ms: i64,
    /// Latest health per robot, written together once a second.
    health: std::collections::BTreeMap<u8, Health>,
    stats: SinkStats,
}

/// Runs the sink until every sender of `rx` is gone; returns its counters.
pub fn run_sink(cfg: SinkCfg, rx: Receiver<SinkMsg>) -> SinkStats {
    let mut s = Sink {
        cfg,
        archive: None,
        sender: None,
        conn: None,
        unconfirmed: Vec::new(),
        suspect: Vec::new(),
        pending: Default::default(),
        deferred: Vec::new(),
        failing_since: None,
        last_reopen_ms: 0,
        health: Default::default(),
        stats: SinkStats::default(),
    };
    s.reopen(archive::now_ms());
    let mut last_sync = archive::now_ms();
    let mut last_tick = last_sync;
    let mut last_prune = i64::MIN / 2;
    loop {
        let msg = rx.recv_timeout(Duration::from_millis(200));
        let now = archive::now_ms();
        match msg {
            Ok(m) => s.handle(m, now),
            Err(RecvTimeoutError::Timeout) => {}
            Err(RecvTimeoutError::Disconnected) => break,
        }
        if now - last_sync >= SYNC_MS {
            last_sync = now;
            s.confirm(now);
            s.write_health(now);
        }
        if s.failing_since.is_some() && now - s.last_reopen_ms >= REOPEN_MS {
            s.reopen(now);
        }
        if now - last_tick >= SHELVE_TICK_MS {
            last_tick = now;
            s.tick_shelves(now);
        }
        if s.cfg.retain_ms.is_some() && now - last_prune >= s.cfg.prune_every_ms {
            last_prune = now;
            s.prune(now);
        }
    }
    let now = archive::now_ms();
    s.confirm(now);
    if let Some(a) = s.archive.take() {
        drop(s.sender.take());
        if let Err(e) = a.close() {
            tracing::error!("archive: closing: {e}");
        }
    }
    s.stats.pending = s.pending.len() + s.unconfirmed.len() + s.suspect.len();
    if s.stats.pending > 0 {
        tracing::error!(
            "archive: {} TM packets could not be written (they stay in the on-board stores)",
            s.stats.pending
        );
    }
    s.stats
}

impl Sink {
    fn handle(&mut self, m: SinkMsg, now: i64) {
        match m {
            SinkMsg::Tm { t_ms, robot, raw } => {
                self.pending.push_back((t_ms, robot, raw));
                while self.pending.len() > MAX_PENDING {
                    self.pending.pop_front();
                    self.stats.dropped_unwritable += 1;
                }
                self.forward();
            }
            SinkMsg::Flush(tx) => {
                self.confirm(now);
                self.write_health(now);
                let _ = tx.send(());
            }
            SinkMsg::Health(h) => {
                self.health.insert(h.robot, h);
            }
            other => {
                if self.write_own(&other).is_err() {
                    self.deferred.push(other);
                }
            }
        }
    }

    /// Hands pending TM to the archive writer.
    fn forward(&mut self) {
        let Some(snd) = &self.sender else { return };
        while let Some((t_ms, robot, raw)) = self.pending.pop_front() {
            let decoded = pus::decode_tm(&raw);
            let ok = snd.send(Record::Tm {
                t_ms,
                link_robot: Some(robot),
                raw: raw.clone(),
                decoded,
            });
            if !ok {
                self.pending.push_front((t_ms, robot, raw));
                self.failed(archive::now_ms(), "archive writer stopped".into());
                return;
            }
            self.unconfirmed.push((t_ms, robot, raw));
        }
    }

    /// Waits for the writer to commit what it was given.
    fn confirm(&mut self, now: i64) {
        self.forward();
        let Some(snd) = &self.sender else { return };
        match snd.sync() {
            Ok(()) => {
                self.stats.tm_written += self.unconfirmed.len() as u64;
                self.unconfirmed.clear();
                if self.failing_since.is_some() || !self.deferred.is_empty() {
                    self.retry_deferred(now);
                }
            }
            Err(e) => self.failed(now, e.to_string()),
        }
    }

    fn failed(&mut self, now: i64, why: String) {
        self.stats.write_failures += 1;
        let detail = match self.archive.take() {
            Some(a) => {
                drop(self.sender.take());
                match a.close() {
                    Err(e) => e.to_string(),
                    Ok(_) => why,
                }
            }
            None => why,
        };
        // Records the failed writer had: checked against the archive on reopening.
        self.suspect.append(&mut self.unconfirmed);
        if self.failing_since.is_none() {
            self.failing_since = Some(now);
            tracing::error!("archive: cannot write ({detail}); keeping TM in memory and retrying");
            self.deferred.push(SinkMsg::Alarm {
                robot: 0,
                source: Source::Archive,
                severity: Severity::High,
                input: Input::Activate,
                t_ms: now,
                value: None,
                message: format!("archive cannot be written: {detail}"),
            });
        }
        self.conn = None;
        self.last_reopen_ms = now;
    }

    fn reopen(&mut self, now: i64) {
        self.last_reopen_ms = now;
        let conn = match open_conn(&self.cfg.path) {
            Ok(c) => c,
            Err(e) => {
                if self.failing_since.is_none() {
                    self.failed(now, format!("{e:#}"));
                }
                return;
            }
        };
        let archive = match Archive::open(&self.cfg.path) {
            Ok(a) => a,
            Err(e) => {
                if self.failing_since.is_none() {
                    self.failed(now, e.to_string());
                }
                return;
            }
        };
        // What a failed writer may have committed before failing is not written twice.
        let suspect = std::mem::take(&mut self.suspect);
        let n = suspect.len();
        match not_archived(&conn, suspect.clone()) {
            Ok(missing) => {
                self.stats.tm_skipped_present += (n - missing.len()) as u64;
                for r in missing.into_iter().rev() {
                    self.pending.push_front(r);
                }
            }
            Err(e) => {
                self.suspect = suspect;
                tracing::debug!("archive: checking what the failed writer committed: {e}");
                return;
            }
        }
        self.sender = Some(archive.sender());
        self.archive = Some(archive);
        self.conn = Some(conn);
        self.forward();
        if let Some(snd) = &self.sender {
            if snd.sync().is_ok() {
                self.stats.tm_written += self.unconfirmed.len() as u64;
                self.unconfirmed.clear();
                self.retry_deferred(now);
                return;
            }
        }
        self.failed(now, "archive writer failed after reopening".into());
    }

    fn retry_deferred(&mut self, now: i64) {
        if let Some(since) = self.failing_since.take() {
            tracing::info!("archive: writable again after {} s", (now - since) / 1000);
            self.deferred.push(SinkMsg::Alarm {
                robot: 0,
                source: Source::Archive,
                severity: Severity::High,
                input: Input::Clear,
                t_ms: now,
                value: None,
                message: "archive writable again".into(),
            });
        }
        let items = std::mem::take(&mut self.deferred);
        for (i, m) in items.iter().enumerate() {
            if self.write_own(m).is_err() {
                self.deferred.extend(items.into_iter().skip(i));
                return;
            }
        }
    }

    fn write_own(&mut self, m: &SinkMsg) -> Result<()> {
        let Some(c) = self.conn.as_mut() else {
            anyhow::bail!("archive not open")
        };
        match m {
            SinkMsg::Alarm {
                robot,
                source,
                severity,
                input,
                t_ms,
                value,
                message,
            } => {
                let tx = c.transaction()?;
                let r = apply_alarm(&tx, *robot, source, *severity, *input, *t_ms, *value, message);
                tx.commit()?;
                if let Err(e) = r {
                    tracing::debug!("alarm {source} robot {robot}: {e}");
                }
            }
            SinkMsg::Lost { robot, apid, run, t_ms } => {
                // The archive's own gap report (`ground archive gaps`) gives the reason
                // too; its note is keyed by the packet before the hole.
                if run.after_obt_ms > i64::MIN {
                    let reason = match run.why {
                        Lost::Rebooted => GapReason::Rebooted,
                        Lost::Overwritten => GapReason::StoreOverwritten,
                        Lost::NotDelivered | Lost::TooMany => GapReason::Unrecoverable,
                    };
                    let after_seq = (run.first as u32 + SEQ_MOD - 1) % SEQ_MOD;
                    c.execute(
                        "INSERT INTO gap_note (robot, apid, after_obt_ms, after_seq, reason, note, t_ms)
                         VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7) ON CONFLICT (robot, apid, after_obt_ms, after_seq)
                         DO UPDATE SET reason = excluded.reason, note = excluded.note, t_ms = excluded.t_ms",
                        params![
                            robot,
                            apid,
                            run.after_obt_ms,
                            after_seq,
                            reason.name(),
                            format!("collector: {} ({} packets)", run.why.reason(), run.count),
                            t_ms
                        ],
                    )?;
                }
                c.execute(
                    "INSERT INTO collect_gap (t_ms, robot, apid, first_seq, last_seq, count, after_obt_ms, before_obt_ms, reason)
                     VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9)",
                    params![
                        t_ms,
                        robot,
                        apid,
                        run.first,
                        run.last,
                        run.count,
                        run.after_obt_ms,
                        run.before_obt_ms,
                        run.why.reason()
                    ],
                )?;
            }
            SinkMsg::Tm { .. } | SinkMsg::Flush(_) | SinkMsg::Health(_) => {}
        }
        Ok(())
    }

    /// Writes the robots' health in one transaction (kept for later if it fails).
    fn write_health(&mut self, now: i64) {
        if self.health.is_empty() {
            return;
        }
        let Some(c) = self.conn.as_mut() else { return };
        let r = (|| -> rusqlite::Result<()> {
            let tx = c.transaction()?;
            {
                let mut st = tx.prepare_cached(
                    "INSERT OR REPLACE INTO collect_robot (robot, addr, link, last_heard_ms, last_hk_ms, packets, filled, lost, duplicates, corrupt, reboots, updated_ms)
                     VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, ?12)",
                )?;
                for h in self.health.values() {
                    st.execute(params![
                        h.robot,
                        h.addr,
                        h.link,
                        h.last_heard_ms,
                        h.last_hk_ms,
                        h.packets as i64,
                        h.filled as i64,
                        h.lost as i64,
                        h.duplicates as i64,
                        h.corrupt as i64,
                        h.reboots as i64,
                        now
                    ])?;
                }
            }
            tx.commit()
        })();
        match r {
            Ok(()) => self.health.clear(),
            Err(e) => tracing::debug!("health: {e}"),
        }
    }

    fn tick_shelves(&mut self, now: i64) {
        let Some(c) = self.conn.as_mut() else { return };
        let ids: Vec<i64> = match c
            .prepare("SELECT id FROM collect_alarm WHERE state = 'shelved' AND shelved_until_ms <= ?1")
            .and_then(|mut s| s.query_map([now], |r| r.get(0))?.collect())
        {
            Ok(v) => v,
            Err(_) => return,
        };
        for id in ids {
            if let Err(e) = alarm_input(c, id, Input::Tick, now) {
                tracing::debug!("shelve expiry of alarm {id}: {e:#}");
            }
        }
    }

    fn prune(&mut self, now: i64) {
        let (Some(c), Some(keep)) = (self.conn.as_mut(), self.cfg.retain_ms) else {
            return;
        };
        match prune(c, now - keep) {
            Ok(n) => {
                self.stats.pruned_rows += n;
                if n > 0 {
                    tracing::info!("retention: deleted {n} rows older than {} days", keep / 86_400_000);
                }
            }
            Err(e) => tracing::warn!("retention: {e:#}"),
        }
    }
}

/// Deletes archived data older than `before_ms` (closed alarms and gap records too).
/// Returns the rows deleted.
pub fn prune(c: &Connection, before_ms: i64) -> Result<u64> {
    let mut n = 0u64;
    for (table, cond) in [
        ("hk_chunk", "t1 < ?1"),
        ("event", "t_ms < ?1"),
        ("verification", "t_ms < ?1"),
        ("packet", "t_ms < ?1"),
        ("tc", "t_ms < ?1"),
        ("collect_gap", "t_ms < ?1"),
        ("collect_alarm", "state = 'normal' AND last_ms < ?1"),
    ] {
        let exists: bool = c
            .query_row(
                "SELECT 1 FROM sqlite_master WHERE type = 'table' AND name = ?1",
                [table],
                |_| Ok(()),
            )
            .optional()?
            .is_some();
        if exists {
            n += c.execute(&format!("DELETE FROM {table} WHERE {cond}"), [before_ms])? as u64;
        }
    }
    Ok(n)
}

/// One alarm row.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct AlarmRow {
    pub id: i64,
    pub robot: u8,
    pub source: String,
    pub kind: String,
    pub severity: String,
    pub state: String,
    pub first_ms: i64,
    pub last_ms: i64,
    pub shelved_until_ms: Option<i64>,
    pub value: Option<f64>,
    pub count: i64,
    pub message: String,
}

fn row_state(r: &rusqlite::Row<'_>, base: usize) -> rusqlite::Result<AlarmState> {
    let condition: bool = r.get(base)?;
    let acked: bool = r.get(base + 1)?;
    let shelved: Option<i64> = r.get(base + 2)?;
    let state: String = r.get(base + 3)?;
    Ok(AlarmState {
        condition,
        acked,
        open: state != State::Normal.name(),
        shelved_until_ms: shelved,
    })
}

/// Applies a condition input to the open alarm of (robot, source), opening a new alarm
/// if there is none and the input is an activation.
#[allow(clippy::too_many_arguments)]
pub fn apply_alarm(
    c: &Connection,
    robot: u8,
    source: &Source,
    severity: Severity,
    input: Input,
    t_ms: i64,
    value: Option<f64>,
    message: &str,
) -> Result<Option<i64>> {
    let open = c
        .query_row(
            "SELECT id, condition, acked, shelved_until_ms, state FROM collect_alarm
             WHERE robot = ?1 AND kind = ?2 AND source = ?3 AND state != 'normal' ORDER BY id DESC LIMIT 1",
            params![robot, source.kind(), source.name()],
            |r| Ok((r.get::<_, i64>(0)?, row_state(r, 1)?)),
        )
        .optional()?;
    match open {
        Some((id, mut st)) => {
            st.apply(input, t_ms)?;
            let raise = input == Input::Activate;
            c.execute(
                "UPDATE collect_alarm SET condition = ?2, acked = ?3, shelved_until_ms = ?4, state = ?5,
                   last_ms = ?6, value = COALESCE(?7, value), message = ?8, count = count + ?9,
                   severity = CASE WHEN ?10 > 0 AND ?11 = 'high' THEN 'high' ELSE severity END
                 WHERE id = ?1",
                params![
                    id,
                    st.condition,
                    st.acked,
                    st.shelved_until_ms,
                    st.state().name(),
                    t_ms,
                    value,
                    message,
                    raise as i64,
                    raise as i64,
                    severity.name()
                ],
            )?;
            Ok(Some(id))
        }
        None if input == Input::Activate => {
            let mut st = AlarmState::default();
            st.apply(input, t_ms)?;
            c.execute(
                "INSERT INTO collect_alarm (robot, kind, source, severity, state, condition, acked, shelved_until_ms, first_ms, last_ms, value, message, count)
                 VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, NULL, ?8, ?8, ?9, ?10, 1)",
                params![
                    robot,
                    source.kind(),
                    source.name(),
                    severity.name(),
                    st.state().name(),
                    st.condition,
                    st.acked,
                    t_ms,
                    value,
                    message
                ],
            )?;
            Ok(Some(c.last_insert_rowid()))
        }
        None => Ok(None),
    }
}

/// Applies an operator input (ack, shelve, unshelve) or a tick to alarm `id`.
pub fn alarm_input(c: &mut Connection, id: i64, input: Input, now: i64) -> Result<State> {
    let tx = c.transaction()?;
    let st = tx
        .query_row(
            "SELECT condition, acked, shelved_until_ms, state FROM collect_alarm WHERE id = ?1",
            [id],
            |r| row_state(r, 0),
        )
        .optional()?;
    let Some(mut st) = st else {
        anyhow::bail!("no alarm with ID {id}")
    };
    st.apply(input, now)
        .map_err(|e: Refused| anyhow::anyhow!("alarm {id}: {e}"))?;
    tx.execute(
        "UPDATE collect_alarm SET condition = ?2, acked = ?3, shelved_until_ms = ?4, state = ?5 WHERE id = ?1",
        params![id, st.condition, st.acked, st.shelved_until_ms, st.state().name()],
    )?;
    tx.commit()?;
    Ok(st.state())
}

/// Alarms, newest first; closed ones only with `all`.
pub fn alarms(c: &Connection, robot: Option<u8>, all: bool) -> Result<Vec<AlarmRow>> {
    let mut sql = String::from(
        "SELECT id, robot, source, kind, severity, state, first_ms, last_ms, shelved_until_ms, value, count, message
         FROM collect_alarm WHERE 1=1",
    );
    if !all {
        sql.push_str(" AND state != 'normal'");
    }
    if robot.is_some() {
        sql.push_str(" AND robot = ?1");
    }
    sql.push_str(" ORDER BY id DESC");
    let mut st = c.prepare(&sql)?;
    let map = |r: &rusqlite::Row<'_>| {
        Ok(AlarmRow {
            id: r.get(0)?,
            robot: r.get::<_, i64>(1)? as u8,
            source: r.get(2)?,
            kind: r.get(3)?,
            severity: r.get(4)?,
            state: r.get(5)?,
            first_ms: r.get(6)?,
            last_ms: r.get(7)?,
            shelved_until_ms: r.get(8)?,
            value: r.get(9)?,
            count: r.get(10)?,
            message: r.get::<_, Option<String>>(11)?.unwrap_or_default(),
        })
    };
    let rows = match robot {
        Some(n) => st.query_map([n as i64], map)?.collect::<Result<Vec<_>, _>>()?,
        None => st.query_map([], map)?.collect::<Result<Vec<_>, _>>()?,
    };
    Ok(rows)
}

/// Robot health rows.
pub fn health(c: &Connection) -> Result<Vec<Health>> {
    let mut st = c.prepare(
        "SELECT robot, addr, link, last_heard_ms, last_hk_ms, packets, filled, lost, duplicates, corrupt, reboots, updated_ms
         FROM collect_robot ORDER BY robot",
    )?;
    let rows = st
        .query_map([], |r| {
            Ok(Health {
                robot: r.get::<_, i64>(0)? as u8,
                addr: r.get::<_, Option<String>>(1)?.unwrap_or_default(),
                link: r.get::<_, Option<String>>(2)?.unwrap_or_default(),
                last_heard_ms: r.get(3)?,
                last_hk_ms: r.get(4)?,
                packets: r.get::<_, Option<i64>>(5)?.unwrap_or(0) as u64,
                filled: r.get::<_, Option<i64>>(6)?.unwrap_or(0) as u64,
                lost: r.get::<_, Option<i64>>(7)?.unwrap_or(0) as u64,
                duplicates: r.get::<_, Option<i64>>(8)?.unwrap_or(0) as u64,
                corrupt: r.get::<_, Option<i64>>(9)?.unwrap_or(0) as u64,
                reboots: r.get::<_, Option<i64>>(10)?.unwrap_or(0) as u64,
                updated_ms: r.get(11)?,
            })
        })?
        .collect::<Result<Vec<_>, _>>()?;
    Ok(rows)
}

/// Unrecoverable holes recorded by the collector.
pub fn lost_runs(c: &Connection, robot: Option<u8>) -> Result<Vec<serde_json::Value>> {
    let mut st = c.prepare(
        "SELECT robot, apid, first_seq, last_seq, count, after_obt_ms, before_obt_ms, reason, t_ms
         FROM collect_gap WHERE ?1 IS NULL OR robot = ?1 ORDER BY id",
    )?;
    let rows = st
        .query_map([robot.map(|r| r as i64)], |r| {
            Ok(serde_json::json!({
                "robot": r.get::<_, i64>(0)?, "apid": r.get::<_, i64>(1)?,
                "first_seq": r.get::<_, i64>(2)?, "last_seq": r.get::<_, i64>(3)?,
                "count": r.get::<_, i64>(4)?, "after_obt_ms": r.get::<_, Option<i64>>(5)?,
                "before_obt_ms": r.get::<_, Option<i64>>(6)?, "reason": r.get::<_, String>(7)?,
                "t_ms": r.get::<_, i64>(8)?,
            }))
        })?
        .collect::<Result<Vec<_>, _>>()?;
    Ok(rows)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tmp(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("collect-store-{}-{name}", std::process::id()));
        let _ = std::fs::remove_file(&d);
        d
    }

    // verifies: GND-13, GND-14
    #[test]
    fn alarm_rows_follow_the_state_machine_and_reopen_after_closing() {
        let path = tmp("alarm.db");
        let mut c = open_conn(&path).unwrap();
        let src = Source::Param("V_BAT_A".into());
        let id = apply_alarm(&c, 1, &src, Severity::Medium, Input::Activate, 10, Some(10.3), "low")
            .unwrap()
            .unwrap();
        assert_eq!(
            apply_alarm(&c, 1, &src, Severity::High, Input::Activate, 11, Some(9.9), "lower").unwrap(),
            Some(id)
        );
        assert_eq!(alarm_input(&mut c, id, Input::Ack, 12).unwrap(), State::Acknowledged);
        assert!(alarm_input(&mut c, id, Input::Ack, 13).is_err());
        apply_alarm(&c, 1, &src, Severity::Medium, Input::Clear, 14, Some(12.0), "ok").unwrap();
        let all = alarms(&c, Some(1), true).unwrap();
        assert_eq!((all[0].state.as_str(), all[0].severity.as_str()), ("normal", "high"));
        assert!(alarms(&c, Some(1), false).unwrap().is_empty());
        let id2 = apply_alarm(&c, 1, &src, Severity::Medium, Input::Activate, 20, None, "again")
            .unwrap()
            .unwrap();
        assert_ne!(id, id2);
        // A clear without an open alarm opens nothing.
        assert_eq!(
            apply_alarm(&c, 2, &Source::LinkLoss, Severity::High, Input::Clear, 1, None, "").unwrap(),
            None
        );
        assert_eq!(
            alarm_input(&mut c, id2, Input::Shelve { until_ms: 100 }, 30).unwrap(),
            State::Shelved
        );
        assert_eq!(alarm_input(&mut c, id2, Input::Tick, 100).unwrap(), State::Active);
    }

    // verifies: GND-12, GND-14, GND-02
    #[test]
    fn unrecoverable_holes_reach_the_archives_gap_notes() {
        let path = tmp("gapnote.db");
        drop(open_conn(&path).unwrap());
        let (tx, rx) = crossbeam_channel::unbounded();
        let run = LostRun {
            first: 0,
            last: 9,
            count: 10,
            after_obt_ms: 5_000,
            before_obt_ms: 9_000,
            why: Lost::Rebooted,
        };
        tx.send(SinkMsg::Lost {
            robot: 3,
            apid: 0x103,
            run,
            t_ms: 10_000,
        })
        .unwrap();
        drop(tx);
        run_sink(
            SinkCfg {
                path: path.clone(),
                retain_ms: None,
                prune_every_ms: 3_600_000,
            },
            rx,
        );
        let c = open_conn(&path).unwrap();
        let (seq, reason): (i64, String) = c
            .query_row(
                "SELECT after_seq, reason FROM gap_note WHERE robot = 3 AND apid = 259 AND after_obt_ms = 5000",
                [],
                |r| Ok((r.get(0)?, r.get(1)?)),
            )
            .unwrap();
        assert_eq!((seq, reason.as_str()), (16383, "rebooted"));
        assert_eq!(lost_runs(&c, Some(3)).unwrap().len(), 1);
    }

    // verifies: GND-14
    #[test]
    fn prune_deletes_old_rows_and_keeps_open_alarms() {
        let path = tmp("prune.db");
        let c = open_conn(&path).unwrap();
        c.execute(
            "INSERT INTO packet (robot, apid, obt_ms, seq, t_ms, raw) VALUES (1, 257, 1, 0, 1, x'00'), (1, 257, 5000, 1, 5000, x'00')",
            [],
        )
        .unwrap();
        apply_alarm(&c, 1, &Source::LinkLoss, Severity::High, Input::Activate, 1, None, "").unwrap();
        assert_eq!(prune(&c, 100).unwrap(), 1);
        assert_eq!(alarms(&c, None, false).unwrap().len(), 1);
    }
}
