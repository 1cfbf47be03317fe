//! PostgreSQL backend (`--archive postgresql://…`): several collectors and operators
//! share one archive server. Statements are the SQLite ones with `?N` turned into `$N`.

use std::collections::HashMap;

use postgres::types::{IsNull, ToSql, Type};
use postgres::{Client, NoTls, Statement};

use super::db::{Db, DbError, DbResult, Dialect, Val};

pub struct Postgres {
    client: Client,
    url: String,
    stmts: HashMap<String, Statement>,
}

fn err(e: postgres::Error) -> DbError {
    let retryable = e.code().is_some_and(|c| {
        *c == postgres::error::SqlState::T_R_DEADLOCK_DETECTED
            || *c == postgres::error::SqlState::T_R_SERIALIZATION_FAILURE
    });
    DbError {
        backend: "postgresql",
        message: match e.as_db_error() {
            Some(d) => format!("{} ({})", d.message(), d.code().code()),
            None => e.to_string(),
        },
        retryable,
    }
}

impl ToSql for Val {
    fn to_sql(
        &self,
        ty: &Type,
        out: &mut postgres::types::private::BytesMut,
    ) -> Result<IsNull, Box<dyn std::error::Error + Sync + Send>> {
        match self {
            Val::Null => Ok(IsNull::Yes),
            Val::Int(v) => match *ty {
                Type::INT2 => (*v as i16).to_sql(ty, out),
                Type::INT4 => (*v as i32).to_sql(ty, out),
                Type::FLOAT8 => (*v as f64).to_sql(ty, out),
                Type::BOOL => (*v != 0).to_sql(ty, out),
                _ => v.to_sql(ty, out),
            },
            Val::Real(v) => v.to_sql(ty, out),
            Val::Text(s) => s.to_sql(ty, out),
            Val::Blob(b) => b.to_sql(ty, out),
        }
    }
    fn accepts(_ty: &Type) -> bool {
        true
    }
    postgres::types::to_sql_checked!();
}

/// `?N` placeholders as PostgreSQL's `$N`.
pub fn placeholders(sql: &str) -> String {
    let mut out = String::with_capacity(sql.len());
    let mut chars = sql.chars().peekable();
    while let Some(c) = chars.next() {
        if c == '?' && chars.peek().is_some_and(|d| d.is_ascii_digit()) {
            out.push('$');
        } else {
            out.push(c);
        }
    }
    out
}

/// The URL without its password, for messages.
fn redact(url: &str) -> String {
    match (url.find("://"), url.rfind('@')) {
        (Some(s), Some(at)) if at > s => {
            let cred = &url[s + 3..at];
            match cred.find(':') {
                Some(c) => format!("{}{}:***{}", &url[..s + 3], &cred[..c], &url[at..]),
                None => url.to_string(),
            }
        }
        _ => url.to_string(),
    }
}

impl Postgres {
    pub fn connect(url: &str) -> DbResult<Postgres> {
        let client = Client::connect(url, NoTls).map_err(|e| DbError {
            backend: "postgresql",
            message: format!("cannot connect to {}: {e}", redact(url)),
            retryable: false,
        })?;
        Ok(Postgres {
            client,
            url: url.to_string(),
            stmts: HashMap::new(),
        })
    }
    fn stmt(&mut self, sql: &str) -> DbResult<Statement> {
        if let Some(s) = self.stmts.get(sql) {
            return Ok(s.clone());
        }
        let s = self.client.prepare(&placeholders(sql)).map_err(err)?;
        self.stmts.insert(sql.to_string(), s.clone());
        Ok(s)
    }
}

fn params(p: &[Val]) -> Vec<&(dyn ToSql + Sync)> {
    p.iter().map(|v| v as &(dyn ToSql + Sync)).collect()
}

fn cell(row: &postgres::Row, i: usize) -> DbResult<Val> {
    let ty = row.columns()[i].type_().clone();
    let e = |e: postgres::Error| err(e);
    Ok(match ty {
        Type::INT8 => row.try_get::<_, Option<i64>>(i).map_err(e)?.map_or(Val::Null, Val::Int),
        Type::INT4 => row
            .try_get::<_, Option<i32>>(i)
            .map_err(e)?
            .map_or(Val::Null, |v| Val::Int(v as i64)),
        Type::INT2 => row
            .try_get::<_, Option<i16>>(i)
            .map_err(e)?
            .map_or(Val::Null, |v| Val::Int(v as i64)),
        Type::BOOL => row
            .try_get::<_, Option<bool>>(i)
            .map_err(e)?
            .map_or(Val::Null, |v| Val::Int(v as i64)),
        Type::FLOAT8 => row
            .try_get::<_, Option<f64>>(i)
            .map_err(e)?
            .map_or(Val::Null, Val::Real),
        Type::FLOAT4 => row
            .try_get::<_, Option<f32>>(i)
            .map_err(e)?
            .map_or(Val::Null, |v| Val::Real(v as f64)),
        Type::BYTEA => row
            .try_get::<_, Option<Vec<u8>>>(i)
            .map_err(e)?
            .map_or(Val::Null, Val::Blob),
        Type::NUMERIC => {
            return Err(DbError {
                backend: "postgresql",
                message: format!("column {} is NUMERIC; cast it to BIGINT", row.columns()[i].name()),
                retryable: false,
            })
        }
        _ => row
            .try_get::<_, Option<String>>(i)
            .map_err(e)?
            .map_or(Val::Null, Val::Text),
    })
}

impl Db for Postgres {
    fn dialect(&self) -> Dialect {
        Dialect::Postgres
    }
    fn location(&self) -> String {
        redact(&self.url)
    }
    fn batch(&mut self, sql: &str) -> DbResult<()> {
        self.client.batch_execute(sql).map_err(err)
    }
    fn exec(&mut self, sql: &str, p: &[Val]) -> DbResult<u64> {
        let st = self.stmt(sql)?;
        self.client.execute(&st, &params(p)).map_err(err)
    }
    fn rows(&mut self, sql: &str, p: &[Val], each: &mut dyn FnMut(&[Val]) -> DbResult<()>) -> DbResult<()> {
        let st = self.stmt(sql)?;
        let rows = self.client.query(&st, &params(p)).map_err(err)?;
        let mut buf = Vec::new();
        for r in &rows {
            buf.clear();
            for i in 0..r.len() {
                buf.push(cell(r, i)?);
            }
            each(&buf)?;
        }
        Ok(())
    }
    fn has_table(&mut self, name: &str) -> DbResult<bool> {
        let r = self
            .client
            .query_one("SELECT to_regclass($1) IS NOT NULL", &[&name])
            .map_err(err)?;
        r.try_get::<_, bool>(0).map_err(err)
    }
    fn size_bytes(&mut self) -> DbResult<u64> {
        let r = self
            .client
            .query_one(
                "SELECT COALESCE(SUM(pg_total_relation_size(c.oid)), 0)::BIGINT FROM pg_class c \
                 JOIN pg_namespace n ON n.oid = c.relnamespace \
                 WHERE n.nspname = current_schema() AND c.relkind = 'r'",
                &[],
            )
            .map_err(err)?;
        Ok(r.try_get::<_, i64>(0).map_err(err)? as u64)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    // verifies: GND-02
    #[test]
    fn placeholders_and_redaction() {
        assert_eq!(
            placeholders("a = ?1 AND b = ?12 OR c = '?'"),
            "a = $1 AND b = $12 OR c = '?'"
        );
        assert_eq!(redact("postgresql://u:secret@h/db"), "postgresql://u:***@h/db");
        assert_eq!(redact("postgresql:///db?host=/tmp"), "postgresql:///db?host=/tmp");
    }
}
