//! Opening an SQLite archive from several processes at once (a collector starting while
//! an operator runs `ground collect --status`) never fails with "database is locked":
//! seen once in ground/tests/alarm_nominal.rs, where a `--status` opened the archive the
//! collector was creating and the collector exited.

use std::sync::{Arc, Barrier};

use ground::archive::Store;

// verifies: GND-02
#[test]
fn concurrent_opens_of_a_new_sqlite_archive_all_succeed() {
    let dir = std::env::temp_dir().join(format!("ground-alarm-open-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let mut failures = Vec::new();
    for round in 0..40 {
        let path = dir.join(format!("a{round}.db"));
        let loc = path.display().to_string();
        let n = 6;
        let barrier = Arc::new(Barrier::new(n));
        let threads: Vec<_> = (0..n)
            .map(|_| {
                let (b, loc) = (barrier.clone(), loc.clone());
                std::thread::spawn(move || {
                    b.wait();
                    Store::open(&loc).map(drop).map_err(|e| e.to_string())
                })
            })
            .collect();
        for t in threads {
            if let Err(e) = t.join().unwrap() {
                failures.push(format!("round {round}: {e}"));
            }
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
    assert!(failures.is_empty(), "{} failed opens: {failures:?}", failures.len());
}
