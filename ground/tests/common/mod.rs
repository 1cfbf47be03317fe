//! Shared by the ground test suites: a throwaway PostgreSQL server that a suite starts
//! itself (`scripts/postgres-test.sh`: Debian's package, a temporary data directory, a
//! Unix socket; stopped when the test process ends).
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// URL of the suite's PostgreSQL server (database `postgres`).
pub fn pg_server() -> &'static str {
    static URL: OnceLock<String> = OnceLock::new();
    URL.get_or_init(|| {
        let dir = format!("/tmp/ground-pg-{}", std::process::id());
        let out = Command::new("bash")
            .arg(root().join("scripts/postgres-test.sh"))
            .args(["start", &dir, &std::process::id().to_string()])
            .output()
            .expect("running scripts/postgres-test.sh");
        assert!(
            out.status.success(),
            "starting PostgreSQL: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        String::from_utf8(out.stdout).unwrap().trim().to_string()
    })
}

/// A fresh database on the suite's server.
pub fn pg_db(name: &str) -> String {
    let base = pg_server();
    let mut c = postgres::Client::connect(base, postgres::NoTls).unwrap();
    c.batch_execute(&format!("DROP DATABASE IF EXISTS {name}")).unwrap();
    c.batch_execute(&format!("CREATE DATABASE {name}")).unwrap();
    base.replace("/postgres?", &format!("/{name}?"))
}

/// Drops a database made by [`pg_db`].
pub fn pg_drop(name: &str) {
    let mut c = postgres::Client::connect(pg_server(), postgres::NoTls).unwrap();
    c.batch_execute(&format!("DROP DATABASE IF EXISTS {name} WITH (FORCE)"))
        .unwrap();
}
