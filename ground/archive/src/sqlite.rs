//! SQLite backend: one file, WAL mode, the embedded default.

use std::path::{Path, PathBuf};

use rusqlite::types::{ToSqlOutput, ValueRef};
use rusqlite::Connection;

use super::db::{Db, DbError, DbResult, Dialect, Val};

pub struct Sqlite {
    conn: Connection,
    path: PathBuf,
}

fn err(e: rusqlite::Error) -> DbError {
    DbError {
        backend: "sqlite",
        message: e.to_string(),
        retryable: false,
    }
}

impl rusqlite::ToSql for Val {
    fn to_sql(&self) -> rusqlite::Result<ToSqlOutput<'_>> {
        Ok(match self {
            Val::Null => ToSqlOutput::Borrowed(ValueRef::Null),
            Val::Int(v) => ToSqlOutput::Borrowed(ValueRef::Integer(*v)),
            Val::Real(v) => ToSqlOutput::Borrowed(ValueRef::Real(*v)),
            Val::Text(s) => ToSqlOutput::Borrowed(ValueRef::Text(s.as_bytes())),
            Val::Blob(b) => ToSqlOutput::Borrowed(ValueRef::Blob(b)),
        })
    }
}

/// How long a statement waits for another connection's lock.
const BUSY_TIMEOUT: std::time::Duration = std::time::Duration::from_secs(10);

impl Sqlite {
    pub fn open(path: &Path) -> DbResult<Sqlite> {
        let conn = Connection::open(path).map_err(err)?;
        conn.busy_timeout(BUSY_TIMEOUT).map_err(err)?;
        // 16 KiB pages: a parameter chunk (up to ~2 KB) then fits in its B-tree page
        // instead of spilling into a mostly empty overflow page (2.9x -> under 2x the raw
        // bytes). Only takes effect when the file is created (before WAL mode).
        conn.pragma_update(None, "page_size", 16384).map_err(err)?;
        // Switching a new file to WAL needs it alone for a moment, and SQLite answers
        // "database is locked" at once, without its busy handler, when another process
        // opens the same new file then (a collector starting while `collect --status`
        // runs). Retried for as long as the busy timeout.
        let t0 = std::time::Instant::now();
        loop {
            match conn.pragma_update(None, "journal_mode", "WAL") {
                Err(rusqlite::Error::SqliteFailure(e, _))
                    if e.code == rusqlite::ErrorCode::DatabaseBusy && t0.elapsed() < BUSY_TIMEOUT =>
                {
                    std::thread::sleep(std::time::Duration::from_millis(10));
                }
                r => break r.map_err(err)?,
            }
        }
        conn.pragma_update(None, "synchronous", "NORMAL").map_err(err)?;
        // 32 MiB of page cache (the default is 2 MiB): a collector appends to every
        // robot's part of the packet and chunk trees at once, and with a small cache each
        // insert reads its leaf pages back through the OS once the file is large.
        conn.pragma_update(None, "cache_size", -32768).map_err(err)?;
        conn.set_prepared_statement_cache_capacity(64);
        Ok(Sqlite {
            conn,
            path: path.to_path_buf(),
        })
    }
}

impl Db for Sqlite {
    fn dialect(&self) -> Dialect {
        Dialect::Sqlite
    }
    fn location(&self) -> String {
        self.path.display().to_string()
    }
    fn batch(&mut self, sql: &str) -> DbResult<()> {
        self.conn.execute_batch(sql).map_err(err)
    }
    fn exec(&mut self, sql: &str, params: &[Val]) -> DbResult<u64> {
        let mut st = self.conn.prepare_cached(sql).map_err(err)?;
        st.execute(rusqlite::params_from_iter(params.iter()))
            .map(|n| n as u64)
            .map_err(err)
    }
    fn rows(&mut self, sql: &str, params: &[Val], each: &mut dyn FnMut(&[Val]) -> DbResult<()>) -> DbResult<()> {
        let mut st = self.conn.prepare_cached(sql).map_err(err)?;
        let n = st.column_count();
        let mut rows = st.query(rusqlite::params_from_iter(params.iter())).map_err(err)?;
        let mut buf = Vec::with_capacity(n);
        while let Some(r) = rows.next().map_err(err)? {
            buf.clear();
            for i in 0..n {
                buf.push(match r.get_ref(i).map_err(err)? {
                    ValueRef::Null => Val::Null,
                    ValueRef::Integer(v) => Val::Int(v),
                    ValueRef::Real(v) => Val::Real(v),
                    ValueRef::Text(t) => Val::Text(String::from_utf8_lossy(t).into_owned()),
                    ValueRef::Blob(b) => Val::Blob(b.to_vec()),
                });
            }
            each(&buf)?;
        }
        Ok(())
    }
    fn has_table(&mut self, name: &str) -> DbResult<bool> {
        let n: i64 = self
            .conn
            .query_row(
                "SELECT count(*) FROM sqlite_master WHERE type = 'table' AND name = ?1",
                [name],
                |r| r.get(0),
            )
            .map_err(err)?;
        Ok(n > 0)
    }
    fn size_bytes(&mut self) -> DbResult<u64> {
        let mut total = 0;
        for suffix in ["", "-wal", "-shm"] {
            let p = PathBuf::from(format!("{}{suffix}", self.path.display()));
            total += std::fs::metadata(&p).map(|m| m.len()).unwrap_or(0);
        }
        Ok(total)
    }
}
