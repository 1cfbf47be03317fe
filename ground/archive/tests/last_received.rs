//! `Store::last_received_seq`: where a ground that stopped left a robot's TM (the start
//! of a resumed run's store replay), read through the `packet_received` index.

use std::path::PathBuf;

use ground_archive::{Archive, Record, Store};
use ground_pus::{build_tm, decode_tm, CdsShort};

const T0: i64 = 1_767_225_600_000;

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("ground-archive-last-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    let p = d.join(name);
    for suffix in ["", "-wal", "-shm"] {
        let _ = std::fs::remove_file(format!("{}{suffix}", p.display()));
    }
    p
}

/// A connection test report (TM[17,2]) of `apid` with sequence count `seq`, on-board time
/// `obt_ms`, received at `t_ms`.
fn pong(apid: u16, seq: u16, obt_ms: i64, t_ms: i64) -> Record {
    let raw = build_tm(apid, seq, 17, 2, 0, &CdsShort::from_unix_ms(obt_ms).to_bytes(), &[]);
    Record::Tm {
        t_ms,
        link_robot: Some(1),
        decoded: decode_tm(&raw),
        raw,
    }
}

// verifies: OPS-RUN-03
#[test]
fn the_last_received_seq_is_the_newest_by_ground_time_not_by_on_board_time() {
    let p = tmp("last.db");
    let apid = mib::apid::robot_apid(1).unwrap();
    let other = mib::apid::robot_apid(2).unwrap();
    let a = Archive::open(&p).unwrap();
    let tx = a.sender();
    // Before a reboot: counts up to 500 with a late on-board clock.
    for i in 0..=500u16 {
        assert!(tx.send(pong(apid, i, T0 + 900_000 + i as i64 * 100, T0 + i as i64 * 100)));
    }
    // After it: the clock restarted, counts 0..=7 received later.
    for i in 0..=7u16 {
        assert!(tx.send(pong(apid, i, T0 + i as i64 * 100, T0 + 100_000 + i as i64 * 100)));
    }
    // Two received in the same millisecond: the newer on-board time wins.
    assert!(tx.send(pong(apid, 9, T0 + 1_000, T0 + 200_000)));
    assert!(tx.send(pong(apid, 8, T0 + 900, T0 + 200_000)));
    // Another robot's TM received later still does not count.
    assert!(tx.send(pong(other, 42, T0, T0 + 300_000)));
    drop(tx);
    a.close().unwrap();

    let mut s = Store::open(p.to_str().unwrap()).unwrap();
    assert_eq!(s.last_received_seq(1, apid).unwrap(), Some(9));
    assert_eq!(s.last_received_seq(2, other).unwrap(), Some(42));
    assert_eq!(s.last_received_seq(3, mib::apid::robot_apid(3).unwrap()).unwrap(), None);
    drop(s);

    // The query reads the index, not a sort of every packet of the APID.
    let c = rusqlite::Connection::open(&p).unwrap();
    let plan: Vec<String> = c
        .prepare(
            "EXPLAIN QUERY PLAN SELECT seq FROM packet WHERE robot = ?1 AND apid = ?2 \
             ORDER BY t_ms DESC, obt_ms DESC LIMIT 1",
        )
        .unwrap()
        .query_map([1i64, apid as i64], |r| r.get::<_, String>(3))
        .unwrap()
        .map(Result::unwrap)
        .collect();
    let plan = plan.join("; ");
    assert!(plan.contains("packet_received"), "{plan}");
    assert!(!plan.contains("TEMP B-TREE"), "{plan}");
}

// verifies: OPS-RUN-03
#[test]
fn a_version_4_archive_gets_the_index_on_open() {
    let p = tmp("v4.db");
    let apid = mib::apid::robot_apid(1).unwrap();
    let a = Archive::open(&p).unwrap();
    let tx = a.sender();
    assert!(tx.send(pong(apid, 5, T0, T0)));
    drop(tx);
    a.close().unwrap();
    {
        let c = rusqlite::Connection::open(&p).unwrap();
        c.execute_batch("DROP INDEX packet_received; UPDATE schema_version SET version = 4;")
            .unwrap();
    }
    let mut s = Store::open(p.to_str().unwrap()).unwrap();
    assert_eq!(s.last_received_seq(1, apid).unwrap(), Some(5));
    drop(s);
    let c = rusqlite::Connection::open(&p).unwrap();
    let n: i64 = c
        .query_row(
            "SELECT count(*) FROM sqlite_master WHERE type = 'index' AND name = 'packet_received'",
            [],
            |r| r.get(0),
        )
        .unwrap();
    assert_eq!(n, 1);
    let v: i64 = c
        .query_row("SELECT version FROM schema_version", [], |r| r.get(0))
        .unwrap();
    assert_eq!(v, ground_archive::schema::VERSION);
}
