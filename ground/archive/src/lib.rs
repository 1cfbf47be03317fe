//! The ground archive: every TC sent and every TM packet received, stored so that months
//! of a fleet fit on a disk and the questions operators ask are fast.
//!
//! - Raw TM packets are stored once, keyed by (robot, APID, on-board time, sequence
//!   count); a packet seen again (a re-import, a store dump overlapping live TM, two
//!   collectors) is counted as a duplicate and not stored.
//! - HK parameter values live in column chunks per robot and parameter ([`codec`]).
//! - Events, verification reports, TCs, alarms, per-stream positions, per-robot
//!   health and the collector's link records have small tables of their own.
//!
//! Two backends behind one interface ([`db::Db`]): SQLite (a file, the default) and
//! PostgreSQL (`--archive postgresql://…`). The schema is versioned ([`schema`]).
//!
//! Writes go through a dedicated writer thread fed by a channel: the receiving threads
//! never block on the disk and nothing is dropped (the queue's high-water mark is
//! reported). The writer commits in batches (what arrives within [`BATCH_LINGER`] of the
//! first record, at most [`BATCH_MAX`] records, one transaction each).
//!
//! A crate of its own (`ground-archive`): it depends on `ground-pus` and the MIB,
//! never on the collector, the web page or an async runtime. PostgreSQL (whose client
//! runs on tokio) is the optional feature `postgres`; there is no clap here (the binary
//! parses `--type` into [`Kind`] itself). The `ground` crate turns `postgres` on and
//! re-exports this crate as `ground::archive` (and [`alarm_model`] as `ground::alarms`' model).

#![deny(unsafe_code)]

pub mod adapter;
pub mod alarm_model;
pub mod alarms;
pub mod codec;
pub mod db;
pub mod gaps;
pub mod import;
mod ingest;
pub mod links;
mod migrate;
#[cfg(feature = "postgres")]
pub mod postgres;
pub mod read;
pub mod schema;
pub mod sqlite;

use std::path::{Path, PathBuf};
use std::thread::JoinHandle;

use crossbeam_channel::{Receiver, Sender};
use serde::Serialize;

use ground_pus::{BuiltTc, DecodeError, Tm};

pub use alarms::{Alarm, AlarmUpdate};
pub use db::{Db, DbError, Val};
pub use gaps::{Gap, GapNote, GapReason, Position};
pub use links::{Handed, LinkHealth, TmCounts};
pub use read::{CheckReport, Column, Health, Latest, Store};

/// Most records committed in one transaction.
pub const BATCH_MAX: usize = 4096;
/// How long the writer gathers records after the first of a batch before it commits
/// (a flush point commits at once). Each open HK chunk that got samples is written once
/// per batch: at 50 robots × 10 Hz a batch holds ~125 packets and a chunk ~2.5 samples
/// (with 50 ms it was written for every sample). What is not yet committed when the
/// process dies is what the collector asks the on-board store for again at restart.
pub const BATCH_LINGER: std::time::Duration = std::time::Duration::from_millis(250);

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
    /// TM packets stored (new).
    pub tm: u64,
    /// Raw bytes of the TM packets stored.
    pub raw_bytes: u64,
    /// TM packets already in the archive (not stored again).
    pub duplicates: u64,
    /// TM that did not decode (kept in `bad_packet`).
    pub tm_corrupt: u64,
    pub verification: u64,
    pub events: u64,
    /// HK reports whose values went into parameter chunks.
    pub hk_rows: u64,
    pub transactions: u64,
    pub max_queue: usize,
    /// Why the final WAL checkpoint did not run (SQLite), if it did not.
    pub checkpoint_error: Option<String>,
}

#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ArchiveError {
    #[error("archive database: {0}")]
    Db(#[from] DbError),
    /// The schema is not one this build can use; the text says what to do.
    #[error("archive schema: {0}")]
    Schema(String),
    /// A chunk or row that does not read back (a damaged archive).
    #[error("archive damaged: {0}")]
    Damaged(String),
    /// The writer thread stopped (its error is returned by `close`).
    #[error("archive writer thread stopped")]
    WriterGone,
    #[error("archive I/O: {0}")]
    Io(#[from] std::io::Error),
    /// Something asked of the archive that it does not have.
    #[error("{0}")]
    NotFound(String),
    /// An operator input the alarm's state does not allow (the text says why).
    #[error("{0}")]
    Refused(String),
}

/// Whether `--archive` names a PostgreSQL server rather than a file.
pub fn is_url(loc: &str) -> bool {
    loc.starts_with("postgresql://") || loc.starts_with("postgres://")
}

/// Connects to an archive (a SQLite file path or a `postgresql://` URL) and brings its
/// schema to the current version (creating it if new).
pub fn connect(loc: &str) -> Result<Box<dyn Db>, ArchiveError> {
    let mut db: Box<dyn Db> = if is_url(loc) {
        connect_postgres(loc)?
    } else {
        Box::new(sqlite::Sqlite::open(Path::new(loc))?)
    };
    schema::prepare(db.as_mut())?;
    Ok(db)
}

#[cfg(feature = "postgres")]
fn connect_postgres(loc: &str) -> Result<Box<dyn Db>, ArchiveError> {
    Ok(Box::new(postgres::Postgres::connect(loc)?))
}

/// Without the feature `postgres` a server URL is refused, saying why.
#[cfg(not(feature = "postgres"))]
fn connect_postgres(_loc: &str) -> Result<Box<dyn Db>, ArchiveError> {
    Err(ArchiveError::Db(DbError {
        backend: "postgresql",
        message: "this build has no PostgreSQL support (ground-archive's feature `postgres`)".into(),
        retryable: false,
    }))
}

/// Whether an archive exists at `loc` (a server URL always counts: it is asked).
pub fn exists(loc: &str) -> bool {
    is_url(loc) || Path::new(loc).exists()
}

/// Cheap clonable handle to send records to the writer.
#[derive(Clone, Debug)]
pub struct ArchiveSender {
    tx: Sender<Record>,
}

impl ArchiveSender {
    /// Queues a record; never blocks on an archive opened with [`Archive::open`].
    /// Returns false if the writer has stopped.
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
    /// Opens the archive at `path` (a file, or a `postgresql://` URL) with an unbounded
    /// queue: senders never block.
    pub fn open(path: &Path) -> Result<Archive, ArchiveError> {
        Self::open_with(path, None)
    }

    /// Like [`Archive::open`]; with `Some(n)` senders block while `n` records wait (for
    /// imports, which are faster than the disk).
    pub fn open_with(path: &Path, queue: Option<usize>) -> Result<Archive, ArchiveError> {
        let db = connect(&path.to_string_lossy())?;
        let (tx, rx) = match queue {
            Some(n) => crossbeam_channel::bounded(n),
            None => crossbeam_channel::unbounded(),
        };
        let handle = std::thread::Builder::new()
            .name("archive-writer".into())
            .spawn(move || writer(db, rx))
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
    let loc = path.to_string_lossy();
    if !exists(&loc) {
        return None;
    }
    Store::open(&loc).ok()?.next_tc_seq(apid).ok()?
}

fn writer(mut db: Box<dyn Db>, rx: Receiver<Record>) -> Result<ArchiveStats, ArchiveError> {
    let mut ingest = ingest::Ingest::new();
    let mut batch: Vec<Record> = Vec::with_capacity(BATCH_MAX);
    while let Ok(first) = rx.recv() {
        ingest.stats.max_queue = ingest.stats.max_queue.max(rx.len() + 1);
        // Gather what arrives within BATCH_LINGER (or up to a flush point): one
        // transaction, and one rewrite of each open parameter chunk, per batch rather
        // than per packet when packets trickle in one by one.
        let until = std::time::Instant::now() + BATCH_LINGER;
        let mut flush = matches!(first, Record::Sync(_));
        batch.push(first);
        while batch.len() < BATCH_MAX && !flush {
            let left = until.saturating_duration_since(std::time::Instant::now());
            match rx.recv_timeout(left) {
                Ok(r) => {
                    flush = matches!(r, Record::Sync(_));
                    batch.push(r);
                }
                Err(_) => break,
            }
        }
        ingest.write_batch(db.as_mut(), &batch)?;
        batch.clear();
    }
    ingest.close_all(db.as_mut())?;
    if db.dialect() == db::Dialect::Sqlite {
        // Fold the WAL into the database file so it does not stay on disk beside it. A
        // reader holding the WAL open makes this a no-op, which is harmless.
        if let Err(e) = db.batch("PRAGMA wal_checkpoint(TRUNCATE)") {
            ingest.stats.checkpoint_error = Some(e.to_string());
        }
    }
    Ok(ingest.stats)
}

// ---------------------------------------------------------------------------
// Query types

/// What `archive query` / `export` select.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    Tc,
    Tm,
    Verification,
    Event,
    Hk,
    Alarm,
    /// TM that did not decode when it arrived.
    Corrupt,
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

/// A robot number and its `(t_ms, engineering value)` points.
pub type RobotSeries = (u8, Vec<(i64, f64)>);

/// CSV text of a result table (RFC 4180 quoting).
pub fn to_csv(rows: &Rows) -> String {
    let mut out = rows.columns.join(",");
    out.push('\n');
    for r in &rows.rows {
        let line: Vec<String> = r.iter().map(csv_field).collect();
        out.push_str(&line.join(","));
        out.push('\n');
    }
    out
}

/// One CSV field (RFC 4180 quoting).
pub fn csv_field(v: &serde_json::Value) -> String {
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

/// Current wall-clock time in ms since the Unix epoch.
pub fn now_ms() -> i64 {
    chrono::Utc::now().timestamp_millis()
}
