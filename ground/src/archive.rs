//! The ground archive: every TC sent, every TM packet (raw and decoded), every
//! verification report, every event and every HK parameter, in one SQLite file.
//!
//! Writes go through a dedicated writer thread fed by an unbounded channel: the
//! receiving threads never block on the disk and nothing is dropped (if the disk is
//! slower than the link the queue grows; its high-water mark is reported). The writer
//! commits in batches (one transaction per drain of the queue, at most
//! [`BATCH_MAX`] records) with the database in WAL mode.

use std::fmt;
use std::path::{Path, PathBuf};
use std::thread::JoinHandle;

use crossbeam_channel::{Receiver, Sender};
use rusqlite::{params, Connection, OptionalExtension};
use serde::Serialize;

use crate::pus::{self, BuiltTc, DecodeError, Tm, TmBody};

/// Most records committed in one transaction.
pub const BATCH_MAX: usize = 4096;

const SCHEMA: &str = "
CREATE TABLE IF NOT EXISTS tc (
    id INTEGER PRIMARY KEY, t_ms INTEGER NOT NULL, robot INTEGER, apid INTEGER, seq INTEGER,
    service INTEGER, subservice INTEGER, name TEXT, args TEXT, step TEXT, attempt INTEGER,
    raw BLOB);
CREATE TABLE IF NOT EXISTS tm (
    id INTEGER PRIMARY KEY, t_ms INTEGER NOT NULL, obt_ms INTEGER, link_robot INTEGER,
    robot INTEGER, apid INTEGER, seq INTEGER, service INTEGER, subservice INTEGER, name TEXT,
    ok INTEGER NOT NULL, decoded TEXT, raw BLOB);
CREATE TABLE IF NOT EXISTS verification (
    id INTEGER PRIMARY KEY, tm_id INTEGER, t_ms INTEGER NOT NULL, robot INTEGER,
    req_apid INTEGER, req_seq INTEGER, stage TEXT, success INTEGER, step INTEGER,
    code INTEGER, code_name TEXT, failure TEXT);
CREATE TABLE IF NOT EXISTS event (
    id INTEGER PRIMARY KEY, tm_id INTEGER, t_ms INTEGER NOT NULL, robot INTEGER,
    event_id INTEGER, name TEXT, severity TEXT, level INTEGER, fault INTEGER, params TEXT,
    description TEXT);
CREATE TABLE IF NOT EXISTS hk (
    tm_id INTEGER, t_ms INTEGER NOT NULL, robot INTEGER, sid INTEGER, param INTEGER,
    name TEXT, raw INTEGER, eng REAL, unit TEXT);
CREATE INDEX IF NOT EXISTS hk_name_t ON hk(name, t_ms);
CREATE INDEX IF NOT EXISTS tm_t ON tm(t_ms);
CREATE INDEX IF NOT EXISTS event_t ON event(t_ms);
CREATE INDEX IF NOT EXISTS tc_apid ON tc(apid, id);
";

/// Something to archive.
#[derive(Debug)]
pub enum Record {
    Tc {
        t_ms: i64,
        tc: BuiltTc,
        step: Option<String>,
        attempt: u32,
    },
    Tm {
        t_ms: i64,
        link_robot: Option<u8>,
        raw: Vec<u8>,
        decoded: Result<Tm, DecodeError>,
    },
    /// Flush point: the writer answers once everything before it is committed.
    Sync(Sender<()>),
}

/// Counts of what was written.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize)]
pub struct ArchiveStats {
    pub tc: u64,
    pub tm: u64,
    pub tm_corrupt: u64,
    pub verification: u64,
    pub events: u64,
    pub hk_rows: u64,
    pub transactions: u64,
    pub max_queue: usize,
}

#[derive(Debug)]
pub enum ArchiveError {
    Sql(rusqlite::Error),
    /// The writer thread stopped (its error is returned by `close`).
    WriterGone,
}

impl fmt::Display for ArchiveError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ArchiveError::Sql(e) => write!(f, "archive database: {e}"),
            ArchiveError::WriterGone => write!(f, "archive writer thread stopped"),
        }
    }
}

impl std::error::Error for ArchiveError {}

impl From<rusqlite::Error> for ArchiveError {
    fn from(e: rusqlite::Error) -> Self {
        ArchiveError::Sql(e)
    }
}

/// Opens (creating if needed) an archive database with the schema.
pub fn open_db(path: &Path) -> Result<Connection, ArchiveError> {
    let c = Connection::open(path)?;
    c.busy_timeout(std::time::Duration::from_secs(5))?;
    c.pragma_update(None, "journal_mode", "WAL")?;
    c.pragma_update(None, "synchronous", "NORMAL")?;
    c.execute_batch(SCHEMA)?;
    Ok(c)
}

/// Cheap clonable handle to send records to the writer.
#[derive(Clone, Debug)]
pub struct ArchiveSender {
    tx: Sender<Record>,
}

impl ArchiveSender {
    /// Queues a record; never blocks. Returns false if the writer has stopped.
    pub fn send(&self, r: Record) -> bool {
        self.tx.send(r).is_ok()
    }
    /// Waits until everything queued so far is committed.
    pub fn sync(&self) -> Result<(), ArchiveError> {
        let (tx, rx) = crossbeam_channel::bounded(1);
        self.tx.send(Record::Sync(tx)).map_err(|_| ArchiveError::WriterGone)?;
        rx.recv().map_err(|_| ArchiveError::WriterGone)
    }
}

/// An open archive with its writer thread.
pub struct Archive {
    pub path: PathBuf,
    sender: ArchiveSender,
    handle: JoinHandle<Result<ArchiveStats, ArchiveError>>,
}

impl Archive {
    pub fn open(path: &Path) -> Result<Archive, ArchiveError> {
        let conn = open_db(path)?;
        let (tx, rx) = crossbeam_channel::unbounded();
        let handle = std::thread::Builder::new()
            .name("archive-writer".into())
            .spawn(move || writer(conn, rx))
            .map_err(|_| ArchiveError::WriterGone)?;
        Ok(Archive {
            path: path.to_path_buf(),
            sender: ArchiveSender { tx },
            handle,
        })
    }
    pub fn sender(&self) -> ArchiveSender {
        self.sender.clone()
    }
    /// Commits everything queued and stops the writer. Every [`ArchiveSender`] clone
    /// must be dropped first (the writer runs until the last sender is gone).
    pub fn close(self) -> Result<ArchiveStats, ArchiveError> {
        drop(self.sender);
        self.handle.join().map_err(|_| ArchiveError::WriterGone)?
    }
}

/// Sequence count to start from for `apid`: one after the last TC archived for it, so
/// that a new ground session is not taken for a duplicate by the OBSW.
pub fn next_seq(path: &Path, apid: u16) -> Option<u16> {
    let c = Connection::open(path).ok()?;
    let last: Option<i64> = c
        .query_row(
            "SELECT seq FROM tc WHERE apid = ?1 ORDER BY id DESC LIMIT 1",
            [apid as i64],
            |r| r.get(0),
        )
        .optional()
        .ok()??;
    last.map(|s| ((s + 1) & 0x3FFF) as u16)
}

fn writer(mut conn: Connection, rx: Receiver<Record>) -> Result<ArchiveStats, ArchiveError> {
    let mut st = ArchiveStats::default();
    let mut batch: Vec<Record> = Vec::with_capacity(BATCH_MAX);
    while let Ok(first) = rx.recv() {
        st.max_queue = st.max_queue.max(rx.len() + 1);
        batch.push(first);
        while batch.len() < BATCH_MAX {
            match rx.try_recv() {
                Ok(r) => batch.push(r),
                Err(_) => break,
            }
        }
        let mut syncs = Vec::new();
        let tx = conn.transaction()?;
        for r in batch.drain(..) {
            match r {
                Record::Sync(s) => syncs.push(s),
                other => write_record(&tx, other, &mut st)?,
            }
        }
        tx.commit()?;
        st.transactions += 1;
        for s in syncs {
            let _ = s.send(());
        }
    }
    Ok(st)
}

fn args_json(tc: &BuiltTc) -> String {
    let m: serde_json::Map<String, serde_json::Value> = tc
        .def
        .args
        .iter()
        .zip(&tc.args)
        .map(|(a, v)| (a.name.to_string(), serde_json::Value::from(*v)))
        .collect();
    serde_json::Value::Object(m).to_string()
}

fn write_record(tx: &rusqlite::Transaction<'_>, r: Record, st: &mut ArchiveStats) -> Result<(), ArchiveError> {
    match r {
        Record::Tc {
            t_ms,
            tc,
            step,
            attempt,
        } => {
            tx.prepare_cached(
                "INSERT INTO tc (t_ms, robot, apid, seq, service, subservice, name, args, step, attempt, raw)
                 VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11)",
            )?
            .execute(params![
                t_ms,
                mib::apid::apid_robot(tc.apid),
                tc.apid,
                tc.seq,
                tc.def.service,
                tc.def.subservice,
                tc.def.name,
                args_json(&tc),
                step,
                attempt,
                tc.bytes
            ])?;
            st.tc += 1;
        }
        Record::Tm {
            t_ms,
            link_robot,
            raw,
            decoded,
        } => match decoded {
            Err(e) => {
                tx.prepare_cached("INSERT INTO tm (t_ms, link_robot, ok, decoded, raw) VALUES (?1, ?2, 0, ?3, ?4)")?
                    .execute(params![t_ms, link_robot, e.to_string(), raw])?;
                st.tm += 1;
                st.tm_corrupt += 1;
            }
            Ok(tm) => {
                let json = serde_json::to_string(&tm.body).unwrap_or_default();
                tx.prepare_cached(
                    "INSERT INTO tm (t_ms, obt_ms, link_robot, robot, apid, seq, service, subservice, name, ok, decoded, raw)
                     VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, 1, ?10, ?11)",
                )?
                .execute(params![
                    t_ms,
                    tm.time.unix_ms(),
                    link_robot,
                    tm.robot,
                    tm.apid,
                    tm.seq,
                    tm.service,
                    tm.subservice,
                    tm.name,
                    json,
                    raw
                ])?;
                let tm_id = tx.last_insert_rowid();
                st.tm += 1;
                match &tm.body {
                    TmBody::Verification(v) => {
                        tx.prepare_cached(
                            "INSERT INTO verification (tm_id, t_ms, robot, req_apid, req_seq, stage, success, step, code, code_name, failure)
                             VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11)",
                        )?
                        .execute(params![
                            tm_id,
                            t_ms,
                            tm.robot,
                            v.request.apid(),
                            v.request.seq(),
                            v.stage.name(),
                            v.success,
                            v.step,
                            v.failure.as_ref().map(|f| f.code),
                            v.failure.as_ref().map(|f| f.name),
                            v.failure.as_ref().map(|f| f.to_string())
                        ])?;
                        st.verification += 1;
                    }
                    TmBody::Event(e) => {
                        let params: serde_json::Map<String, serde_json::Value> = e
                            .params
                            .iter()
                            .map(|p| (p.name.clone(), serde_json::Value::from(p.value)))
                            .collect();
                        tx.prepare_cached(
                            "INSERT INTO event (tm_id, t_ms, robot, event_id, name, severity, level, fault, params, description)
                             VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10)",
                        )?
                        .execute(params![
                            tm_id,
                            t_ms,
                            tm.robot,
                            e.id,
                            e.name,
                            e.severity,
                            tm.subservice,
                            e.fault,
                            serde_json::Value::Object(params).to_string(),
                            e.description
                        ])?;
                        st.events += 1;
                    }
                    TmBody::Hk(h) => {
                        let mut stmt = tx.prepare_cached(
                            "INSERT INTO hk (tm_id, t_ms, robot, sid, param, name, raw, eng, unit)
                             VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9)",
                        )?;
                        let t = tm.time.unix_ms();
                        for v in &h.values {
                            stmt.execute(params![tm_id, t, tm.robot, h.sid, v.id, v.name, v.raw, v.eng, v.unit])?;
                            st.hk_rows += 1;
                        }
                    }
                    _ => {}
                }
            }
        },
        Record::Sync(_) => {}
    }
    Ok(())
}

// ---------------------------------------------------------------------------
// Reading

/// What `archive query` / `export` select.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Kind {
    Tc,
    Tm,
    Verification,
    Event,
    Hk,
}

/// Filters of `archive query` / `export`.
#[derive(Clone, Debug, Default)]
pub struct Filter {
    pub robot: Option<u8>,
    pub since_ms: Option<i64>,
    pub until_ms: Option<i64>,
    pub service: Option<u8>,
    /// Lowest event severity level (1 info .. 4 high).
    pub min_level: Option<u8>,
    /// HK parameter names (any of).
    pub params: Vec<String>,
    pub limit: Option<u64>,
}

/// A result table.
#[derive(Clone, Debug, Default, Serialize)]
pub struct Rows {
    pub columns: Vec<String>,
    pub rows: Vec<Vec<serde_json::Value>>,
}

fn cols(kind: Kind) -> (&'static str, &'static str) {
    match kind {
        Kind::Tc => (
            "tc",
            "id, t_ms, robot, apid, seq, service, subservice, name, args, step, attempt, hex(raw) AS raw",
        ),
        Kind::Tm => (
            "tm",
            "id, t_ms, obt_ms, robot, apid, seq, service, subservice, name, ok, decoded, hex(raw) AS raw",
        ),
        Kind::Verification => (
            "verification",
            "id, t_ms, robot, req_apid, req_seq, stage, success, step, code, code_name, failure",
        ),
        Kind::Event => (
            "event",
            "id, t_ms, robot, event_id, name, severity, fault, params, description",
        ),
        Kind::Hk => ("hk", "tm_id, t_ms, robot, sid, param, name, raw, eng, unit"),
    }
}

/// Runs a filtered query on the archive.
pub fn query(conn: &Connection, kind: Kind, f: &Filter) -> Result<Rows, ArchiveError> {
    let (table, columns) = cols(kind);
    let mut sql = format!("SELECT {columns} FROM {table} WHERE 1=1");
    let mut args: Vec<rusqlite::types::Value> = Vec::new();
    let mut push = |cond: &str, v: rusqlite::types::Value, sql: &mut String| {
        args.push(v);
        sql.push_str(&format!(" AND {cond} ?{}", args.len()));
    };
    if let Some(r) = f.robot {
        push("robot =", (r as i64).into(), &mut sql);
    }
    if let Some(t) = f.since_ms {
        push("t_ms >=", t.into(), &mut sql);
    }
    if let Some(t) = f.until_ms {
        push("t_ms <=", t.into(), &mut sql);
    }
    if let Some(s) = f.service {
        if matches!(kind, Kind::Tc | Kind::Tm) {
            push("service =", (s as i64).into(), &mut sql);
        }
    }
    if let Some(l) = f.min_level {
        if kind == Kind::Event {
            push("level >=", (l as i64).into(), &mut sql);
        }
    }
    if !f.params.is_empty() && kind == Kind::Hk {
        let mut ors = Vec::new();
        for p in &f.params {
            args.push(p.to_ascii_uppercase().into());
            ors.push(format!("name = ?{}", args.len()));
        }
        sql.push_str(&format!(" AND ({})", ors.join(" OR ")));
    }
    sql.push_str(" ORDER BY t_ms, rowid");
    if let Some(l) = f.limit {
        sql.push_str(&format!(" LIMIT {l}"));
    }
    let mut stmt = conn.prepare(&sql)?;
    let columns: Vec<String> = stmt.column_names().iter().map(|s| s.to_string()).collect();
    let n = columns.len();
    let rows = stmt
        .query_map(rusqlite::params_from_iter(args.iter()), |r| {
            (0..n)
                .map(|i| {
                    Ok(match r.get_ref(i)? {
                        rusqlite::types::ValueRef::Null => serde_json::Value::Null,
                        rusqlite::types::ValueRef::Integer(v) => v.into(),
                        rusqlite::types::ValueRef::Real(v) => v.into(),
                        rusqlite::types::ValueRef::Text(t) => String::from_utf8_lossy(t).into_owned().into(),
                        rusqlite::types::ValueRef::Blob(b) => pus::hex(b).into(),
                    })
                })
                .collect::<Result<Vec<_>, rusqlite::Error>>()
        })?
        .collect::<Result<Vec<_>, _>>()?;
    Ok(Rows { columns, rows })
}

/// A robot number and its `(t_ms, engineering value)` points.
pub type RobotSeries = (u8, Vec<(i64, f64)>);

/// One HK parameter's series per robot: `(robot, [(t_ms, eng)])`.
pub fn hk_series(conn: &Connection, param: &str, f: &Filter) -> Result<Vec<RobotSeries>, ArchiveError> {
    let mut ff = f.clone();
    ff.params = vec![param.to_string()];
    ff.limit = None;
    let rows = query(conn, Kind::Hk, &ff)?;
    let mut out: Vec<RobotSeries> = Vec::new();
    for r in rows.rows {
        let robot = r[2].as_i64().unwrap_or(0) as u8;
        let t = r[1].as_i64().unwrap_or(0);
        let v = r[7].as_f64().unwrap_or(f64::NAN);
        match out.iter_mut().find(|(n, _)| *n == robot) {
            Some((_, s)) => s.push((t, v)),
            None => out.push((robot, vec![(t, v)])),
        }
    }
    Ok(out)
}

/// CSV text of a result table (RFC 4180 quoting).
pub fn to_csv(rows: &Rows) -> String {
    fn field(v: &serde_json::Value) -> String {
        let s = match v {
            serde_json::Value::Null => String::new(),
            serde_json::Value::String(s) => s.clone(),
            other => other.to_string(),
        };
        if s.contains([',', '"', '\n', '\r']) {
            format!("\"{}\"", s.replace('"', "\"\""))
        } else {
            s
        }
    }
    let mut out = rows.columns.join(",");
    out.push('\n');
    for r in &rows.rows {
        let line: Vec<String> = r.iter().map(field).collect();
        out.push_str(&line.join(","));
        out.push('\n');
    }
    out
}

/// Current wall-clock time in ms since the Unix epoch.
pub fn now_ms() -> i64 {
    chrono::Utc::now().timestamp_millis()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pus::{build_tc, build_tm, decode_tm, CdsShort};

    fn tmp(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("ground-test-{}-{name}", std::process::id()));
        let _ = std::fs::remove_file(&d);
        d
    }

    // verifies: GND-02
    #[test]
    fn every_record_lands_in_its_tables() {
        let path = tmp("a.db");
        let a = Archive::open(&path).unwrap();
        let s = a.sender();
        let tc = build_tc(1, 41, mib::tc::by_name("PING").unwrap(), &[]).unwrap();
        s.send(Record::Tc {
            t_ms: 1,
            tc,
            step: Some("x".into()),
            attempt: 1,
        });
        let def = mib::hk::by_sid(1).unwrap();
        let mut src = [0u8; 256];
        let t = CdsShort::from_unix_ms(1_000).to_bytes();
        let mut n_hk = 0;
        for i in 0..500 {
            let n = mib::codec::encode_hk(def, |id| id as i64 + i, &mut src).unwrap();
            let raw = build_tm(0x101, i as u16, 3, 25, 0, &t, &src[..n]);
            let decoded = decode_tm(&raw);
            s.send(Record::Tm {
                t_ms: 2 + i,
                link_robot: Some(1),
                raw,
                decoded,
            });
            n_hk += 1;
        }
        let ev = mib::events::by_id(mib::events::eid::BOLT_FAILURE).unwrap();
        let n = mib::codec::encode_event(ev, &[0, 1, 3], &mut src).unwrap();
        let raw = build_tm(0x101, 9, 5, 4, 0, &t, &src[..n]);
        s.send(Record::Tm {
            t_ms: 900,
            link_robot: Some(1),
            decoded: decode_tm(&raw),
            raw,
        });
        let raw = build_tm(0x101, 10, 1, 1, 0, &t, &[0x19, 0x01, 0xC0, 41]);
        s.send(Record::Tm {
            t_ms: 901,
            link_robot: Some(1),
            decoded: decode_tm(&raw),
            raw,
        });
        s.send(Record::Tm {
            t_ms: 902,
            link_robot: Some(1),
            raw: vec![1, 2, 3],
            decoded: decode_tm(&[1, 2, 3]),
        });
        s.sync().unwrap();
        drop(s);
        let st = a.close().unwrap();
        assert_eq!(st.tm, n_hk + 3);
        assert_eq!(st.tm_corrupt, 1);
        assert_eq!(st.hk_rows, n_hk * def.params.len() as u64);
        let c = open_db(&path).unwrap();
        let ev = query(
            &c,
            Kind::Event,
            &Filter {
                min_level: Some(4),
                ..Default::default()
            },
        )
        .unwrap();
        assert_eq!(ev.rows.len(), 1);
        assert_eq!(ev.rows[0][4], "BOLT_FAILURE");
        let hk = hk_series(&c, "v_bat_a", &Filter::default()).unwrap();
        assert_eq!(hk[0].1.len(), 500);
        let v = query(&c, Kind::Verification, &Filter::default()).unwrap();
        assert_eq!(v.rows[0][4], 41);
        assert_eq!(next_seq(&path, 0x101), Some(42));
        assert_eq!(next_seq(&path, 0x102), None);
        let csv = to_csv(&query(&c, Kind::Tc, &Filter::default()).unwrap());
        assert!(csv.starts_with("id,t_ms,robot"));
        assert!(csv.contains("PING"));
    }
}
