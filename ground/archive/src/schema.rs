//! Versioned schema. `schema_version` holds one row; [`prepare`] creates a new archive,
//! migrates an older one (the turn-1 layout, version 1, is rebuilt from its raw packets)
//! or refuses a newer one with what to do.

use super::db::{scalar, Db, Dialect, Val};
use super::ArchiveError;

/// The schema this build writes.
pub const VERSION: i64 = 5;

/// Longest time span of one parameter chunk (ms); range queries rely on it.
pub const CHUNK_SPAN_MS: i64 = 3_600_000;
/// Most samples in one parameter chunk.
pub const CHUNK_MAX: usize = 1024;

/// The columns of a chunk table (`hk_chunk` and `hk_open` have the same), in order.
macro_rules! chunk_columns {
    () => {
        "robot, param, t0, cid, t1, n, data"
    };
}
pub(super) use chunk_columns;

/// Every parameter chunk, closed (`hk_chunk`) or being filled (`hk_open`): what reads
/// select from (`FROM {CHUNKS} c`).
pub const CHUNKS: &str = concat!(
    "(SELECT ",
    chunk_columns!(),
    " FROM hk_chunk UNION ALL SELECT ",
    chunk_columns!(),
    " FROM hk_open)"
);

/// The definition of a chunk table, for both `hk_chunk` and `hk_open`.
const CHUNK_TABLE: &str = "(
    robot {int} NOT NULL, param {int} NOT NULL, t0 {int} NOT NULL, cid {int} NOT NULL,
    t1 {int} NOT NULL, n {int} NOT NULL, data {blob} NOT NULL,
    PRIMARY KEY (robot, param, t0, cid)){norowid}";

/// Tables of version 5. `{chunk_table}`, then `{int}`, `{real}`, `{blob}`, `{id}` and
/// `{norowid}` are filled per dialect. Version 5 (over 4): the index `packet_received`
/// on a robot's packets by ground receive time, which `Store::last_received_seq` (where a
/// resumed run's replay starts) sorts by — without it every packet of the robot's APID was
/// read and sorted. Version 4 (over 3): chunks being filled live in `hk_open` and move to
/// `hk_chunk` when closed, so that rewriting them after every batch touches a small table
/// instead of pages spread over the whole history. Version 3 (over 2): the alarm table
/// holds the ISA-18.2 state of every alarm (`condition`, `acked`, `kind`, `message`, a
/// numeric `value`) and `link` holds the collector's view of each robot's link; the
/// collector's own SQLite-only tables (`collect_alarm`, `collect_robot`, `collect_gap`)
/// are gone.
const TABLES: &str = "
CREATE TABLE IF NOT EXISTS schema_version (version {int} NOT NULL);
CREATE TABLE IF NOT EXISTS packet (
    robot {int} NOT NULL, apid {int} NOT NULL, obt_ms {int} NOT NULL, seq {int} NOT NULL,
    t_ms {int} NOT NULL, link_robot {int}, raw {blob} NOT NULL,
    PRIMARY KEY (robot, apid, obt_ms, seq)){norowid};
CREATE INDEX IF NOT EXISTS packet_received ON packet (robot, apid, t_ms, obt_ms);
CREATE TABLE IF NOT EXISTS hk_chunk {chunk_table};
CREATE TABLE IF NOT EXISTS hk_open {chunk_table};
CREATE TABLE IF NOT EXISTS event (
    id {id}, robot {int} NOT NULL, apid {int} NOT NULL, seq {int} NOT NULL,
    obt_ms {int} NOT NULL, t_ms {int} NOT NULL, event_id {int} NOT NULL, name TEXT,
    severity TEXT, level {int}, fault {int}, params TEXT, description TEXT);
CREATE INDEX IF NOT EXISTS event_t ON event (obt_ms);
CREATE TABLE IF NOT EXISTS verification (
    id {id}, robot {int} NOT NULL, apid {int} NOT NULL, seq {int} NOT NULL,
    obt_ms {int} NOT NULL, t_ms {int} NOT NULL, req_apid {int}, req_seq {int}, stage TEXT,
    success {int}, step {int}, code {int}, code_name TEXT, failure TEXT);
CREATE INDEX IF NOT EXISTS verification_t ON verification (obt_ms);
CREATE TABLE IF NOT EXISTS tc (
    id {id}, t_ms {int} NOT NULL, robot {int}, apid {int}, seq {int}, service {int},
    subservice {int}, name TEXT, args TEXT, step TEXT, attempt {int}, raw {blob});
CREATE INDEX IF NOT EXISTS tc_apid ON tc (apid, id);
CREATE TABLE IF NOT EXISTS bad_packet (
    id {id}, t_ms {int} NOT NULL, link_robot {int}, reason TEXT, raw {blob});
CREATE TABLE IF NOT EXISTS stream (
    robot {int} NOT NULL, apid {int} NOT NULL, seq {int} NOT NULL, obt_ms {int} NOT NULL,
    t_ms {int} NOT NULL, packets {int} NOT NULL, duplicates {int} NOT NULL,
    PRIMARY KEY (robot, apid));
CREATE TABLE IF NOT EXISTS health (
    robot {int} PRIMARY KEY, last_heard_ms {int} NOT NULL, last_obt_ms {int} NOT NULL,
    packets {int} NOT NULL);
CREATE TABLE IF NOT EXISTS alarm (
    id {id}, robot {int} NOT NULL, kind TEXT NOT NULL, source TEXT NOT NULL,
    severity TEXT NOT NULL, state TEXT NOT NULL, condition {int} NOT NULL,
    acked {int} NOT NULL, first_ms {int} NOT NULL, last_ms {int} NOT NULL,
    shelved_until_ms {int}, value {real}, message TEXT, count {int} NOT NULL,
    ack_ms {int}, cleared_ms {int});
CREATE INDEX IF NOT EXISTS alarm_t ON alarm (first_ms);
CREATE INDEX IF NOT EXISTS alarm_open ON alarm (robot, kind, source, state);
CREATE TABLE IF NOT EXISTS gap_note (
    robot {int} NOT NULL, apid {int} NOT NULL, after_obt_ms {int} NOT NULL,
    after_seq {int} NOT NULL, reason TEXT NOT NULL, note TEXT, t_ms {int} NOT NULL,
    PRIMARY KEY (robot, apid, after_obt_ms, after_seq));
CREATE TABLE IF NOT EXISTS link (
    robot {int} PRIMARY KEY, addr TEXT NOT NULL, state TEXT NOT NULL, last_heard_ms {int},
    last_hk_ms {int}, packets {int} NOT NULL, filled {int} NOT NULL, lost {int} NOT NULL,
    duplicates {int} NOT NULL, corrupt {int} NOT NULL, reboots {int} NOT NULL,
    updated_ms {int} NOT NULL);
";

/// The DDL of the current version in `d`'s dialect.
pub fn ddl(d: Dialect) -> String {
    let (int, real, blob, id, norowid) = match d {
        Dialect::Sqlite => ("INTEGER", "REAL", "BLOB", "INTEGER PRIMARY KEY", " WITHOUT ROWID"),
        Dialect::Postgres => ("BIGINT", "DOUBLE PRECISION", "BYTEA", "BIGSERIAL PRIMARY KEY", ""),
    };
    TABLES
        .replace("{chunk_table}", CHUNK_TABLE)
        .replace("{int}", int)
        .replace("{real}", real)
        .replace("{blob}", blob)
        .replace("{id}", id)
        .replace("{norowid}", norowid)
}

/// What [`prepare`] found.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Prepared {
    Created,
    Current,
    /// Migrated from this version.
    Migrated(i64),
}

fn begin(db: &mut dyn Db) -> Result<(), ArchiveError> {
    match db.dialect() {
        Dialect::Sqlite => db.batch("BEGIN IMMEDIATE")?,
        // One migrator at a time when several collectors start together.
        Dialect::Postgres => db.batch("BEGIN; SELECT pg_advisory_xact_lock(7253914)")?,
    }
    Ok(())
}

fn version(db: &mut dyn Db) -> Result<Option<i64>, ArchiveError> {
    if !db.has_table("schema_version")? {
        return Ok(None);
    }
    Ok(scalar(db, "SELECT MAX(version) FROM schema_version", &[])?.and_then(|v| v.int()))
}

/// Creates or migrates the schema so that it is [`VERSION`].
pub fn prepare(db: &mut dyn Db) -> Result<Prepared, ArchiveError> {
    if version(db)? == Some(VERSION) {
        return Ok(Prepared::Current);
    }
    begin(db)?;
    let r = prepare_locked(db);
    match r {
        Ok(p) => {
            db.batch("COMMIT")?;
            if p == Prepared::Migrated(1) && db.dialect() == Dialect::Sqlite {
                db.batch("VACUUM")?;
            }
            Ok(p)
        }
        Err(e) => {
            let _ = db.batch("ROLLBACK");
            Err(e)
        }
    }
}

fn prepare_locked(db: &mut dyn Db) -> Result<Prepared, ArchiveError> {
    match version(db)? {
        Some(VERSION) => Ok(Prepared::Current),
        Some(v) if v > VERSION => Err(ArchiveError::Schema(format!(
            "archive {} has schema version {v}, newer than this ground tool's {VERSION}: use a newer \
             `ground` (or another --archive)",
            db.location()
        ))),
        Some(2) => {
            super::migrate::from_v2(db)?;
            set_version(db)?;
            Ok(Prepared::Migrated(2))
        }
        // Version 4 only adds `hk_open` (created by `set_version`); the chunks a version-3
        // writer left open stay in `hk_chunk`, where they read the same.
        Some(3) => {
            set_version(db)?;
            Ok(Prepared::Migrated(3))
        }
        // Version 5 only adds the index `packet_received` (created by `set_version`).
        Some(4) => {
            set_version(db)?;
            Ok(Prepared::Migrated(4))
        }
        Some(v) => Err(ArchiveError::Schema(format!(
            "archive {} has schema version {v}, which no migration of this ground tool ({VERSION}) \
             knows: export it with the ground tool that wrote it",
            db.location()
        ))),
        None if db.has_table("tm")? && db.has_table("hk")? => {
            super::migrate::from_v1(db)?;
            set_version(db)?;
            Ok(Prepared::Migrated(1))
        }
        None if db.has_table("packet")? || db.has_table("tm")? => Err(ArchiveError::Schema(format!(
            "{} has archive-like tables but no schema_version: not an archive this tool wrote; \
             move it away or pass another --archive",
            db.location()
        ))),
        None => {
            db.batch(&ddl(db.dialect()))?;
            set_version(db)?;
            Ok(Prepared::Created)
        }
    }
}

fn set_version(db: &mut dyn Db) -> Result<(), ArchiveError> {
    db.batch(&ddl(db.dialect()))?;
    db.exec("DELETE FROM schema_version", &[])?;
    db.exec("INSERT INTO schema_version (version) VALUES (?1)", &[Val::Int(VERSION)])?;
    Ok(())
}
