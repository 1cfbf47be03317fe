//! The backend interface: one SQL connection (SQLite or PostgreSQL) that executes the
//! archive's statements. The archive's logic (schema versions, ingest, queries) is
//! written once above it; statements are written with numbered `?N` placeholders and
//! the few dialect differences are asked of [`Dialect`].

use std::fmt;

/// A parameter or result value.
#[derive(Clone, Debug, PartialEq)]
pub enum Val {
    Null,
    Int(i64),
    Real(f64),
    Text(String),
    Blob(Vec<u8>),
}

impl Val {
    pub fn int(&self) -> Option<i64> {
        match self {
            Val::Int(v) => Some(*v),
            Val::Real(r) => Some(*r as i64),
            Val::Null | Val::Text(_) | Val::Blob(_) => None,
        }
    }
    pub fn text(&self) -> Option<&str> {
        match self {
            Val::Text(s) => Some(s),
            Val::Null | Val::Int(_) | Val::Real(_) | Val::Blob(_) => None,
        }
    }
    pub fn blob(&self) -> Option<&[u8]> {
        match self {
            Val::Blob(b) => Some(b),
            Val::Null | Val::Int(_) | Val::Real(_) | Val::Text(_) => None,
        }
    }
}

impl From<i64> for Val {
    fn from(v: i64) -> Val {
        Val::Int(v)
    }
}
impl From<&str> for Val {
    fn from(v: &str) -> Val {
        Val::Text(v.to_string())
    }
}
impl From<String> for Val {
    fn from(v: String) -> Val {
        Val::Text(v)
    }
}
impl<T: Into<Val>> From<Option<T>> for Val {
    fn from(v: Option<T>) -> Val {
        v.map_or(Val::Null, Into::into)
    }
}

/// Which SQL dialect a backend speaks.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Dialect {
    Sqlite,
    Postgres,
}

impl Dialect {
    /// The larger of two values.
    pub fn greatest(self) -> &'static str {
        match self {
            Dialect::Sqlite => "MAX",
            Dialect::Postgres => "GREATEST",
        }
    }
}

/// A backend failure, with the backend's own message.
#[derive(Debug)]
pub struct DbError {
    pub backend: &'static str,
    pub message: String,
    /// The transaction may succeed if retried (PostgreSQL deadlock or serialisation).
    pub retryable: bool,
}

impl fmt::Display for DbError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: {}", self.backend, self.message)
    }
}

impl std::error::Error for DbError {}

pub type DbResult<T> = Result<T, DbError>;

/// One connection to an archive database.
pub trait Db: Send {
    fn dialect(&self) -> Dialect;
    /// Where the archive is, for messages (a path or a URL without its password).
    fn location(&self) -> String;
    /// Runs statements without parameters (schema, `BEGIN`, `COMMIT`).
    fn batch(&mut self, sql: &str) -> DbResult<()>;
    /// Runs one statement; returns the number of rows it changed.
    fn exec(&mut self, sql: &str, params: &[Val]) -> DbResult<u64>;
    /// Runs a query and hands every row to `each`.
    fn rows(&mut self, sql: &str, params: &[Val], each: &mut dyn FnMut(&[Val]) -> DbResult<()>) -> DbResult<()>;
    /// Whether a table exists.
    fn has_table(&mut self, name: &str) -> DbResult<bool>;
    /// Bytes the archive takes on disk (database files, WAL and indexes included).
    fn size_bytes(&mut self) -> DbResult<u64>;
}

/// Runs a query and collects its rows.
pub fn collect(db: &mut dyn Db, sql: &str, params: &[Val]) -> DbResult<Vec<Vec<Val>>> {
    let mut out = Vec::new();
    db.rows(sql, params, &mut |r| {
        out.push(r.to_vec());
        Ok(())
    })?;
    Ok(out)
}

/// First column of the first row, if any.
pub fn scalar(db: &mut dyn Db, sql: &str, params: &[Val]) -> DbResult<Option<Val>> {
    let mut out = None;
    db.rows(sql, params, &mut |r| {
        if out.is_none() {
            out = r.first().cloned();
        }
        Ok(())
    })?;
    Ok(out)
}
