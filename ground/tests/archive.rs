//! The archive suite, run against both backends: an SQLite file and a throwaway
//! PostgreSQL server that the suite starts itself (`scripts/postgres-test.sh`: Debian's
//! package, a temporary data directory, a Unix socket; stopped when this process ends).

use std::path::{Path, PathBuf};
use std::process::Command;

use ground::archive::{
    self, import, Alarm, AlarmUpdate, Archive, ArchiveError, Filter, GapReason, Kind, LinkHealth, Record, Store,
};
use ground::pus::{build_tc, build_tm, decode_tm, CdsShort};

mod common;
use common::{pg_db, pg_drop};

const T0: i64 = 1_767_225_600_000;

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("ground-archive-test-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    let p = d.join(name);
    let _ = std::fs::remove_file(&p);
    p
}

/// Removes files when dropped (the suite's archives are tens of MB).
struct Rm(Vec<PathBuf>);
impl Drop for Rm {
    fn drop(&mut self) {
        for p in &self.0 {
            for suffix in ["", "-wal", "-shm"] {
                let _ = std::fs::remove_file(format!("{}{suffix}", p.display()));
            }
        }
    }
}

/// The same test on both backends: `f(location, backend name)`.
fn both(name: &str, f: impl Fn(&str, &str)) {
    let file = tmp(&format!("{name}.db"));
    let _rm = Rm(vec![file.clone()]);
    f(file.to_str().unwrap(), "sqlite");
    drop(_rm);
    f(&pg_db(name), "postgresql");
    pg_drop(name);
}

fn hk_packet(robot: u8, seq: u16, t_ms: i64, i: i64) -> Vec<u8> {
    let def = mib::hk::by_sid(mib::hk::sid::ROBOT_STATUS).unwrap();
    let mut src = [0u8; 512];
    let n = mib_wire::codec::encode_hk(def, |id| (id as i64 * 131 + i * 7) % 4000, &mut src).unwrap();
    let apid = mib::apid::robot_apid(robot).unwrap();
    build_tm(apid, seq, 3, 25, 0, &CdsShort::from_unix_ms(t_ms).to_bytes(), &src[..n])
}

fn event_packet(robot: u8, seq: u16, t_ms: i64, id: u16, args: &[i64]) -> Vec<u8> {
    let ev = mib::events::by_id(id).unwrap();
    let mut src = [0u8; 256];
    let n = mib_wire::codec::encode_event(ev, args, &mut src).unwrap();
    let apid = mib::apid::robot_apid(robot).unwrap();
    build_tm(
        apid,
        seq,
        5,
        ev.severity.subservice(),
        0,
        &CdsShort::from_unix_ms(t_ms).to_bytes(),
        &src[..n],
    )
}

/// `n` HK packets of `robot` at 10 Hz from `T0`, sequence counts from 0.
fn hk_file(name: &str, robot: u8, n: usize) -> PathBuf {
    let p = tmp(name);
    let mut buf = Vec::new();
    for i in 0..n {
        buf.extend(hk_packet(
            robot,
            mib::headers::SeqCount::new(i as u16).get(),
            T0 + i as i64 * 100,
            i as i64,
        ));
    }
    std::fs::write(&p, buf).unwrap();
    p
}

fn tm(raw: Vec<u8>, t_ms: i64) -> Record {
    Record::Tm {
        t_ms,
        link_robot: Some(1),
        decoded: decode_tm(&raw),
        raw,
    }
}

fn ground(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_ground")).args(args).output().unwrap()
}

// verifies: GND-02
#[test]
fn every_record_lands_in_its_tables() {
    both("records", |loc, backend| {
        let a = Archive::open(Path::new(loc)).unwrap();
        let s = a.sender();
        let tc = build_tc(1, 41, mib::tc::by_name("PING").unwrap(), &[]).unwrap();
        s.send(Record::Tc {
            t_ms: 1,
            tc,
            step: Some("x".into()),
            attempt: 1,
        });
        for i in 0..500 {
            s.send(tm(hk_packet(1, i as u16, T0 + i * 100, i), T0 + i * 100 + 3));
        }
        s.send(tm(
            event_packet(1, 500, T0 + 50_000, mib::events::eid::BOLT_FAILURE, &[0, 1, 3]),
            T0,
        ));
        let t = CdsShort::from_unix_ms(T0 + 50_001).to_bytes();
        s.send(tm(build_tm(0x101, 501, 1, 1, 0, &t, &[0x19, 0x01, 0xC0, 41]), T0));
        s.send(tm(vec![1, 2, 3], T0));
        s.sync().unwrap();
        drop(s);
        let st = a.close().unwrap();
        assert_eq!(st.tm, 502, "{backend}");
        assert_eq!(st.tm_corrupt, 1, "{backend}");
        assert_eq!(st.hk_rows, 500, "{backend}");
        let mut c = Store::open(loc).unwrap();
        let ev = c
            .query(
                Kind::Event,
                &Filter {
                    min_level: Some(4),
                    ..Default::default()
                },
            )
            .unwrap();
        assert_eq!(ev.rows.len(), 1, "{backend}");
        assert_eq!(ev.rows[0][4], "BOLT_FAILURE", "{backend}");
        let hk = c.hk_series("v_bat_a", &Filter::default()).unwrap();
        assert_eq!(hk[0].1.len(), 500, "{backend}");
        let v = c.query(Kind::Verification, &Filter::default()).unwrap();
        let req_seq = v.columns.iter().position(|c| c == "req_seq").unwrap();
        assert_eq!(v.rows[0][req_seq], 41, "{backend}");
        assert_eq!(c.next_tc_seq(0x101).unwrap(), Some(42), "{backend}");
        assert_eq!(c.next_tc_seq(0x102).unwrap(), None, "{backend}");
        let csv = archive::to_csv(&c.query(Kind::Tc, &Filter::default()).unwrap());
        assert!(csv.starts_with("id,t_ms,robot"), "{backend}");
        assert!(csv.contains("PING"), "{backend}");
        let bad = c.query(Kind::Corrupt, &Filter::default()).unwrap();
        assert_eq!(bad.rows.len(), 1, "{backend}");
        // One line per stored packet with its key, times and decoded body.
        let rows = c.query(Kind::Tm, &Filter::default()).unwrap();
        assert_eq!(rows.rows.len(), 502, "{backend}");
        let col = |n: &str| rows.columns.iter().position(|c| c == n).unwrap();
        let first = &rows.rows[0];
        assert_eq!(first[col("robot")], 1);
        assert_eq!(first[col("apid")], 0x101);
        assert_eq!(first[col("seq")], 0);
        assert_eq!(first[col("obt_ms")], T0);
        assert_eq!(first[col("t_ms")], T0 + 3);
        assert_eq!(first[col("decoded")]["kind"], "hk", "{backend}");
        assert!(first[col("decoded")]["values"][0]["name"].is_string(), "{backend}");
        // Latest values and the health record.
        let latest = c.latest(Some(1)).unwrap();
        let vbat = latest.iter().find(|l| l.name == "V_BAT_A").unwrap();
        assert_eq!(vbat.t_ms, T0 + 499 * 100, "{backend}");
        let h = c.health().unwrap();
        assert_eq!(h.len(), 1);
        assert_eq!(h[0].last_obt_ms, T0 + 50_001, "{backend}");
        let check = c.check(None).unwrap();
        assert!(
            check.bad.is_empty() && check.chunk_mismatch.is_empty(),
            "{backend}: {check:?}"
        );
    });
}

/// Chunks a writer is filling are in `hk_open` and read like closed ones; full chunks
/// move to `hk_chunk` as they fill and a clean stop moves the rest, so `hk_open` keeps
/// only what a writer is filling (one chunk per parameter here).
// verifies: GND-02
#[test]
fn open_chunks_are_read_and_a_clean_stop_closes_them() {
    both("open_chunks", |loc, backend| {
        let rows = |s: &mut Store, table: &str| {
            archive::db::scalar(s.db(), &format!("SELECT COUNT(*) FROM {table}"), &[])
                .unwrap()
                .and_then(|v| v.int())
                .unwrap()
        };
        let params = mib::hk::by_sid(mib::hk::sid::ROBOT_STATUS).unwrap().params.len() as i64;
        let a = Archive::open(Path::new(loc)).unwrap();
        let s = a.sender();
        // 2.5 chunks of every parameter: two full ones, one being filled.
        let n = 1024 * 2 + 500;
        for i in 0..n {
            s.send(tm(hk_packet(1, i as u16, T0 + i * 100, i), T0 + i * 100 + 3));
        }
        s.sync().unwrap();
        let mut r = Store::open(loc).unwrap();
        assert_eq!(rows(&mut r, "hk_open"), params, "{backend}");
        assert_eq!(rows(&mut r, "hk_chunk"), 2 * params, "{backend}");
        let v = r.hk_series("v_bat_a", &Filter::default()).unwrap();
        assert_eq!(v[0].1.len(), n as usize, "{backend}");
        let latest = r.latest(Some(1)).unwrap();
        assert_eq!(
            latest.iter().find(|l| l.name == "V_BAT_A").unwrap().t_ms,
            T0 + (n - 1) * 100,
            "{backend}"
        );
        drop(s);
        a.close().unwrap();
        assert_eq!(rows(&mut r, "hk_open"), 0, "{backend}");
        assert_eq!(rows(&mut r, "hk_chunk"), 3 * params, "{backend}");
        assert_eq!(
            r.hk_series("v_bat_a", &Filter::default()).unwrap()[0].1.len(),
            n as usize
        );
        let check = r.check(None).unwrap();
        assert!(check.chunk_mismatch.is_empty(), "{backend}: {check:?}");
    });
}

// verifies: GND-02
#[test]
fn import_twice_adds_nothing_and_counts_duplicates() {
    let file = hk_file("dup.bin", 2, 5000);
    let _rm = Rm(vec![file.clone()]);
    both("dup", |loc, backend| {
        let r1 = import::import(Path::new(loc), &file, 2).unwrap();
        assert_eq!(
            (r1.tm, r1.archive.tm, r1.archive.duplicates),
            (5000, 5000, 0),
            "{backend}"
        );
        let r2 = import::import(Path::new(loc), &file, 2).unwrap();
        assert_eq!((r2.archive.tm, r2.archive.duplicates), (0, 5000), "{backend}");
        let mut s = Store::open(loc).unwrap();
        assert_eq!(s.packet_totals().unwrap().0, 5000, "{backend}");
        let pos = s.positions(Some(2)).unwrap();
        assert_eq!(pos.len(), 1);
        assert_eq!((pos[0].seq, pos[0].obt_ms), (4999, T0 + 4999 * 100), "{backend}");
        assert_eq!((pos[0].packets, pos[0].duplicates), (5000, 5000), "{backend}");
        let mut csv = Vec::new();
        let n = s
            .export_csv(
                Kind::Hk,
                &Filter {
                    params: vec!["V_BAT_A".into()],
                    ..Default::default()
                },
                &mut csv,
            )
            .unwrap();
        assert_eq!(n, 5000, "{backend}");
        let text = String::from_utf8(csv).unwrap();
        assert!(text.starts_with("t_ms,robot,param,name,raw,eng,unit\n"), "{backend}");
        assert_eq!(text.lines().count(), 5001);
        let check = s.check(None).unwrap();
        assert!(check.bad.is_empty() && check.chunk_mismatch.is_empty() && check.gaps.is_empty());
    });
}

/// Copies of a packet inside one write batch (a store dump overlapping live TM) are
/// stored once and counted, and their HK values enter the chunks once.
// verifies: GND-02
#[test]
fn copies_within_one_batch_are_stored_once() {
    both("dupbatch", |loc, backend| {
        let a = Archive::open_with(Path::new(loc), Some(100_000)).unwrap();
        let s = a.sender();
        for seq in 0..600u16 {
            let t = T0 + seq as i64 * 100;
            for _ in 0..(1 + seq % 3) {
                s.send(tm(hk_packet(4, seq, t, seq as i64), t));
            }
        }
        drop(s);
        let stats = a.close().unwrap();
        // 600 packets, 200 once, 200 twice, 200 three times.
        assert_eq!((stats.tm, stats.duplicates), (600, 600), "{backend}");
        let mut st = Store::open(loc).unwrap();
        assert_eq!(st.packet_totals().unwrap().0, 600, "{backend}");
        assert_eq!(st.hk_series("V_BAT_A", &Filter::default()).unwrap()[0].1.len(), 600);
        let check = st.check(None).unwrap();
        assert!(
            check.chunk_mismatch.is_empty() && check.gaps.is_empty(),
            "{backend}: {check:?}"
        );
    });
}

// verifies: GND-02
#[test]
fn size_is_at_most_three_times_the_raw_packets() {
    let file = hk_file("size.bin", 1, 20_000);
    let loc = tmp("size.db");
    let _rm = Rm(vec![file.clone(), loc.clone()]);
    let r = import::import(&loc, &file, 1).unwrap();
    let mut s = Store::open(loc.to_str().unwrap()).unwrap();
    s.db().batch("PRAGMA wal_checkpoint(TRUNCATE)").unwrap();
    let size = s.size_bytes().unwrap();
    let ratio = size as f64 / r.bytes as f64;
    assert!(
        ratio <= 3.0,
        "archive {size} bytes for {} raw bytes: {ratio:.2}x",
        r.bytes
    );
}

// verifies: GND-02
#[test]
fn holes_reboots_and_store_notes() {
    both("gaps", |loc, backend| {
        let a = Archive::open(Path::new(loc)).unwrap();
        let s = a.sender();
        let mut t = T0;
        // seq 0..=99, then 105..=199 (5 lost), then a reboot: BOOT at 0 and 1..=49, then
        // another restart whose first two packets are missing (seq 2 onward, no BOOT).
        for seq in (0..100).chain(105..200) {
            t += 100;
            s.send(tm(hk_packet(1, seq, t, seq as i64), t));
        }
        t += 5_000;
        s.send(tm(event_packet(1, 0, t, mib::events::eid::BOOT, &[1]), t));
        for seq in 1..50 {
            t += 100;
            s.send(tm(hk_packet(1, seq, t, seq as i64), t));
        }
        t += 5_000;
        for seq in 2..10 {
            t += 100;
            s.send(tm(hk_packet(1, seq, t, seq as i64), t));
        }
        drop(s);
        a.close().unwrap();
        let mut st = Store::open(loc).unwrap();
        let gaps = st.gaps(Some(1)).unwrap();
        assert_eq!(gaps.len(), 2, "{backend}: {gaps:?}");
        assert_eq!(
            (gaps[0].after_seq, gaps[0].before_seq, gaps[0].missing, gaps[0].reason),
            (99, 105, 5, GapReason::Lost)
        );
        assert_eq!(
            (gaps[1].after_seq, gaps[1].before_seq, gaps[1].missing, gaps[1].reason),
            (49, 2, 2, GapReason::Rebooted)
        );
        // The collector found the first hole overwritten in the on-board store.
        st.note_gap(
            &gaps[0],
            GapReason::StoreOverwritten,
            Some("store oldest is seq 200"),
            T0,
        )
        .unwrap();
        let g = st.gaps(None).unwrap();
        assert_eq!(g[0].reason, GapReason::StoreOverwritten, "{backend}");
        assert_eq!(g[0].note.as_deref(), Some("store oldest is seq 200"));
        let pos = st.positions(None).unwrap();
        assert_eq!((pos[0].seq, pos[0].obt_ms), (9, t), "{backend}");
        // Three boots' packets with equal counts are all stored (the key has the time).
        assert_eq!(st.packet_totals().unwrap().0, 195 + 50 + 8, "{backend}");
    });
}

// verifies: GND-02, GND-13, GND-14
#[test]
fn alarms_go_through_their_states() {
    use ground::alarms::{Input, Severity, Source, State};
    both("alarms", |loc, backend| {
        let mut s = Store::open(loc).unwrap();
        let src = Source::Param("V_BAT_A".into());
        let up = |input, t, severity| AlarmUpdate {
            robot: 3,
            source: &src,
            severity,
            input,
            t_ms: t,
            value: Some(9.61),
            message: "< 10.00 V (hard)",
        };
        let id = s
            .apply_alarm(&up(Input::Activate, T0, Severity::Medium))
            .unwrap()
            .unwrap();
        assert_eq!(
            s.apply_alarm(&up(Input::Activate, T0 + 1000, Severity::High)).unwrap(),
            Some(id),
            "{backend}"
        );
        let a: &Alarm = &s.alarms(Some(3), false).unwrap()[0];
        assert_eq!(
            (a.state, a.count, a.severity.as_str(), a.value, a.kind.as_str()),
            (State::Active, 2, "high", Some(9.61), "param"),
            "{backend}"
        );
        assert_eq!(s.alarm_input(id, Input::Ack, T0 + 2000).unwrap(), State::Acknowledged);
        // A second acknowledgement is refused and changes nothing.
        let e = s.alarm_input(id, Input::Ack, T0 + 2500).unwrap_err();
        assert!(matches!(e, ArchiveError::Refused(_)), "{backend}: {e}");
        assert!(e.to_string().contains("nothing to acknowledge"), "{e}");
        assert_eq!(s.alarms(None, true).unwrap()[0].ack_ms, Some(T0 + 2000));
        // Acknowledged and gone: closed (normal), a new condition is a new alarm.
        s.apply_alarm(&up(Input::Clear, T0 + 3000, Severity::Medium)).unwrap();
        assert!(s.alarms(Some(3), false).unwrap().is_empty(), "{backend}");
        let closed = &s.alarms(Some(3), true).unwrap()[0];
        assert_eq!((closed.state, closed.cleared_ms), (State::Normal, Some(T0 + 3000)));
        let id2 = s
            .apply_alarm(&up(Input::Activate, T0 + 4000, Severity::Medium))
            .unwrap()
            .unwrap();
        assert_ne!(id2, id, "{backend}");
        // Gone before anyone looked: cleared, waiting for its acknowledgement.
        s.apply_alarm(&up(Input::Clear, T0 + 5000, Severity::Medium)).unwrap();
        assert_eq!(s.alarms(Some(3), false).unwrap()[0].state, State::Cleared);
        s.apply_alarm(&up(Input::Activate, T0 + 6000, Severity::Medium))
            .unwrap();
        // Shelved, then the shelve runs out: active again (unacknowledged).
        assert_eq!(
            s.alarm_input(id2, Input::Shelve { until_ms: T0 + 60_000 }, T0 + 7000)
                .unwrap(),
            State::Shelved
        );
        assert_eq!(s.expire_shelves(T0 + 59_000).unwrap(), 0, "{backend}");
        assert_eq!(s.expire_shelves(T0 + 60_000).unwrap(), 1, "{backend}");
        assert_eq!(s.alarms(Some(3), false).unwrap()[0].state, State::Active);
        // A clear with nothing open opens nothing; an unknown ID is named.
        assert_eq!(
            s.apply_alarm(&AlarmUpdate {
                robot: 2,
                source: &Source::LinkLoss,
                severity: Severity::High,
                input: Input::Clear,
                t_ms: T0,
                value: None,
                message: "",
            })
            .unwrap(),
            None
        );
        let e = s.alarm_input(999, Input::Ack, T0).unwrap_err();
        assert!(e.to_string().contains("no alarm with ID 999"), "{backend}: {e}");
        let rows = s.query(Kind::Alarm, &Filter::default()).unwrap();
        assert_eq!(
            rows.columns[..8],
            ["id", "robot", "kind", "source", "severity", "state", "first_ms", "last_ms"]
        );
        assert_eq!(rows.rows.len(), 2, "{backend}");
        assert_eq!(rows.rows[0][5], "normal");
        assert_eq!(rows.rows[1][5], "active");
    });
}

/// Retention deletes what is older than the cut in every table, closed alarms too, and
/// keeps open alarms whatever their age; link records survive.
// verifies: GND-14
#[test]
fn prune_deletes_old_rows_and_keeps_open_alarms() {
    use ground::alarms::{Input, Severity, Source};
    both("prune", |loc, backend| {
        let a = Archive::open(Path::new(loc)).unwrap();
        let s = a.sender();
        s.send(tm(hk_packet(1, 0, T0, 0), T0));
        s.send(tm(hk_packet(1, 1, T0 + 100, 1), T0 + 7_200_000));
        drop(s);
        a.close().unwrap();
        let mut st = Store::open(loc).unwrap();
        let raise = |st: &mut Store, robot, input| {
            st.apply_alarm(&AlarmUpdate {
                robot,
                source: &Source::LinkLoss,
                severity: Severity::High,
                input,
                t_ms: T0,
                value: None,
                message: "no TM",
            })
            .unwrap()
        };
        raise(&mut st, 1, Input::Activate);
        let closed = raise(&mut st, 2, Input::Activate).unwrap();
        st.alarm_input(closed, Input::Ack, T0).unwrap();
        raise(&mut st, 2, Input::Clear);
        st.write_links(
            &[LinkHealth {
                robot: 1,
                addr: "127.0.0.1:1".into(),
                link: "up".into(),
                ..Default::default()
            }],
            T0,
        )
        .unwrap();
        let n = st.prune(T0 + 3_600_000).unwrap();
        // One packet, its chunk rows and the closed alarm.
        assert!(n >= 3, "{backend}: {n}");
        assert_eq!(st.packet_totals().unwrap().0, 1, "{backend}");
        let left = st.alarms(None, true).unwrap();
        assert_eq!((left.len(), left[0].robot), (1, 1), "{backend}");
        assert_eq!(st.links().unwrap().len(), 1);
    });
}

// verifies: GND-02
#[test]
fn decimation_keeps_extremes_per_column() {
    both("decimate", |loc, backend| {
        let a = Archive::open(Path::new(loc)).unwrap();
        let s = a.sender();
        for i in 0..3000 {
            s.send(tm(hk_packet(1, i as u16, T0 + i * 100, i), T0));
        }
        drop(s);
        a.close().unwrap();
        let mut st = Store::open(loc).unwrap();
        let cols = st.decimate(1, "V_BAT_A", T0, T0 + 2999 * 100, 100).unwrap();
        assert_eq!(cols.len(), 100, "{backend}");
        assert_eq!(cols.iter().map(|c| c.n).sum::<u32>(), 3000);
        let all = st
            .samples(1, mib::params::by_name("V_BAT_A").unwrap().id, None, None)
            .unwrap();
        let def = mib::params::by_name("V_BAT_A").unwrap();
        let max = all.iter().map(|p| def.calib.eng(p.1)).fold(f64::MIN, f64::max);
        assert_eq!(cols.iter().map(|c| c.max).fold(f64::MIN, f64::max), max);
    });
}

// verifies: GND-02
#[test]
fn concurrent_writers_never_store_a_packet_twice() {
    let file = hk_file("conc.bin", 4, 6000);
    let _rm = Rm(vec![file.clone()]);
    both("concurrent", |loc, backend| {
        // Create the schema first, then four writers race over the same packets.
        drop(Store::open(loc).unwrap());
        let handles: Vec<_> = (0..4)
            .map(|_| {
                let (loc, file) = (loc.to_string(), file.clone());
                std::thread::spawn(move || import::import(Path::new(&loc), &file, 4).unwrap())
            })
            .collect();
        let reps: Vec<_> = handles.into_iter().map(|h| h.join().unwrap()).collect();
        let stored: u64 = reps.iter().map(|r| r.archive.tm).sum();
        let dups: u64 = reps.iter().map(|r| r.archive.duplicates).sum();
        assert_eq!((stored, dups), (6000, 18_000), "{backend}");
        let mut s = Store::open(loc).unwrap();
        assert_eq!(s.packet_totals().unwrap().0, 6000, "{backend}");
        let check = s.check(None).unwrap();
        assert!(
            check.bad.is_empty() && check.chunk_mismatch.is_empty(),
            "{backend}: {check:?}"
        );
        assert_eq!(
            s.samples(4, mib::params::by_name("I_BAT").unwrap().id, None, None)
                .unwrap()
                .len(),
            6000
        );
    });
}

// verifies: GND-02
#[test]
fn kill_9_during_import_leaves_nothing_half_written() {
    let file = hk_file("kill.bin", 5, 150_000);
    let _rm = Rm(vec![file.clone()]);
    both("kill", |loc, backend| {
        drop(Store::open(loc).unwrap());
        let mut child = Command::new(env!("CARGO_BIN_EXE_ground"))
            .args([
                "--archive",
                loc,
                "archive",
                "import",
                file.to_str().unwrap(),
                "--robot",
                "5",
            ])
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::null())
            .spawn()
            .unwrap();
        // Kill it once some batches are committed.
        let deadline = std::time::Instant::now() + std::time::Duration::from_secs(120);
        let mut stored = 0;
        while std::time::Instant::now() < deadline {
            std::thread::sleep(std::time::Duration::from_millis(20));
            stored = Store::open(loc).unwrap().packet_totals().unwrap().0;
            if stored > 0 {
                break;
            }
        }
        child.kill().unwrap(); // SIGKILL
        child.wait().unwrap();
        assert!(stored > 0, "{backend}: nothing committed before the kill");
        let mut s = Store::open(loc).unwrap();
        let check = s.check(None).unwrap();
        assert!(
            check.bad.is_empty() && check.chunk_mismatch.is_empty(),
            "{backend}: {check:?}"
        );
        let out = ground(&["--archive", loc, "archive", "check"]);
        assert_eq!(
            out.status.code(),
            Some(0),
            "{backend}: {}",
            String::from_utf8_lossy(&out.stdout)
        );
        // Importing again completes the archive, each packet once.
        let r = import::import(Path::new(loc), &file, 5).unwrap();
        let total = s.packet_totals().unwrap().0;
        assert_eq!(total, 150_000, "{backend}");
        assert_eq!(r.archive.tm + r.archive.duplicates, 150_000, "{backend}");
        let check = s.check(None).unwrap();
        assert!(check.bad.is_empty() && check.chunk_mismatch.is_empty() && check.gaps.is_empty());
    });
}

// verifies: GND-02
#[test]
fn cli_query_export_plot_check_gaps_status() {
    let file = hk_file("cli.bin", 1, 3000);
    let _rm = Rm(vec![file.clone()]);
    both("cli", |loc, backend| {
        let out = ground(&[
            "--archive",
            loc,
            "archive",
            "import",
            file.to_str().unwrap(),
            "--robot",
            "1",
        ]);
        assert_eq!(
            out.status.code(),
            Some(0),
            "{backend}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        let out = ground(&[
            "--archive",
            loc,
            "archive",
            "query",
            "--type",
            "tm",
            "--json",
            "--limit",
            "5",
        ]);
        let text = String::from_utf8(out.stdout).unwrap();
        assert_eq!(text.lines().count(), 5, "{backend}");
        for l in text.lines() {
            let v: serde_json::Value = serde_json::from_str(l).unwrap();
            for k in ["robot", "apid", "seq", "obt_ms", "t_ms", "decoded"] {
                assert!(!v[k].is_null(), "{backend}: {k} missing in {l}");
            }
        }
        let csv = tmp(&format!("cli-{backend}.csv"));
        let out = ground(&[
            "--archive",
            loc,
            "archive",
            "export",
            "--csv",
            "--type",
            "hk",
            "--param",
            "V_BAT_A",
            "--out",
            csv.to_str().unwrap(),
        ]);
        assert_eq!(out.status.code(), Some(0), "{backend}");
        assert_eq!(std::fs::read_to_string(&csv).unwrap().lines().count(), 3001);
        let svg = tmp(&format!("cli-{backend}.svg"));
        let out = ground(&[
            "--archive",
            loc,
            "archive",
            "plot",
            "V_BAT_A",
            "--out",
            svg.to_str().unwrap(),
        ]);
        assert_eq!(
            out.status.code(),
            Some(0),
            "{backend}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        assert!(String::from_utf8_lossy(&out.stdout).starts_with("3000 points"));
        assert!(std::fs::read_to_string(&svg).unwrap().contains("<svg"));
        let out = ground(&["--archive", loc, "archive", "check"]);
        assert_eq!(out.status.code(), Some(0), "{backend}");
        assert!(String::from_utf8_lossy(&out.stdout).contains("check: ok"));
        let out = ground(&["--archive", loc, "archive", "gaps"]);
        assert!(String::from_utf8_lossy(&out.stdout).contains("0 hole(s)"), "{backend}");
        let out = ground(&["--archive", loc, "archive", "status", "--json"]);
        let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        assert_eq!(v["packets"], 3000, "{backend}");
        assert_eq!(v["positions"][0]["seq"], 2999);
        assert_eq!(v["health"][0]["robot"], 1);
        let out = ground(&["--archive", loc, "archive", "query", "--type", "alarm", "--json"]);
        assert_eq!(out.status.code(), Some(0), "{backend}");
    });
}

// verifies: GND-02
#[test]
fn a_newer_schema_is_refused_with_what_to_do() {
    both("newer", |loc, backend| {
        let mut s = Store::open(loc).unwrap();
        s.db().exec("UPDATE schema_version SET version = 99", &[]).unwrap();
        drop(s);
        let e = Store::open(loc).err().unwrap().to_string();
        assert!(e.contains("version 99") && e.contains("newer"), "{backend}: {e}");
    });
}

/// The turn-1 layout (SQLite only: that is all turn 1 wrote) migrates on open.
// verifies: GND-02
#[test]
fn a_turn_one_archive_is_migrated() {
    let p = tmp("v1.db");
    let _rm = Rm(vec![p.clone()]);
    {
        let c = rusqlite::Connection::open(&p).unwrap();
        c.execute_batch(
            "CREATE TABLE tc (id INTEGER PRIMARY KEY, t_ms INTEGER NOT NULL, robot INTEGER, apid INTEGER, seq INTEGER,
                service INTEGER, subservice INTEGER, name TEXT, args TEXT, step TEXT, attempt INTEGER, raw BLOB);
             CREATE TABLE tm (id INTEGER PRIMARY KEY, t_ms INTEGER NOT NULL, obt_ms INTEGER, link_robot INTEGER,
                robot INTEGER, apid INTEGER, seq INTEGER, service INTEGER, subservice INTEGER, name TEXT,
                ok INTEGER NOT NULL, decoded TEXT, raw BLOB);
             CREATE TABLE verification (id INTEGER PRIMARY KEY, tm_id INTEGER, t_ms INTEGER NOT NULL, robot INTEGER,
                req_apid INTEGER, req_seq INTEGER, stage TEXT, success INTEGER, step INTEGER, code INTEGER,
                code_name TEXT, failure TEXT);
             CREATE TABLE event (id INTEGER PRIMARY KEY, tm_id INTEGER, t_ms INTEGER NOT NULL, robot INTEGER,
                event_id INTEGER, name TEXT, severity TEXT, level INTEGER, fault INTEGER, params TEXT, description TEXT);
             CREATE TABLE hk (tm_id INTEGER, t_ms INTEGER NOT NULL, robot INTEGER, sid INTEGER, param INTEGER,
                name TEXT, raw INTEGER, eng REAL, unit TEXT);
             CREATE INDEX hk_name_t ON hk(name, t_ms);
             CREATE INDEX tm_t ON tm(t_ms);
             CREATE INDEX event_t ON event(t_ms);
             CREATE INDEX tc_apid ON tc(apid, id);",
        )
        .unwrap();
        let tc = build_tc(1, 7, mib::tc::by_name("PING").unwrap(), &[]).unwrap();
        c.execute(
            "INSERT INTO tc (t_ms, robot, apid, seq, service, subservice, name, args, raw) VALUES (1, 1, ?1, 7, 17, 1, 'PING', '{}', ?2)",
            rusqlite::params![tc.apid, tc.bytes],
        )
        .unwrap();
        for i in 0..300i64 {
            let raw = hk_packet(1, i as u16, T0 + i * 100, i);
            c.execute(
                "INSERT INTO tm (t_ms, link_robot, robot, apid, seq, ok, decoded, raw) VALUES (?1, 1, 1, 257, ?2, 1, '{}', ?3)",
                rusqlite::params![T0 + i * 100, i, raw],
            )
            .unwrap();
        }
        c.execute(
            "INSERT INTO tm (t_ms, link_robot, ok, decoded, raw) VALUES (5, 1, 0, 'bad', x'010203')",
            [],
        )
        .unwrap();
    }
    let mut s = Store::open(p.to_str().unwrap()).unwrap();
    assert_eq!(s.packet_totals().unwrap().0, 300);
    assert_eq!(s.next_tc_seq(0x101).unwrap(), Some(8));
    assert_eq!(s.query(Kind::Corrupt, &Filter::default()).unwrap().rows.len(), 1);
    assert_eq!(s.hk_series("I_BAT", &Filter::default()).unwrap()[0].1.len(), 300);
    assert!(!s.db().has_table("v1_tm").unwrap());
    assert!(!s.db().has_table("hk").unwrap());
    let check = s.check(None).unwrap();
    assert!(check.bad.is_empty() && check.chunk_mismatch.is_empty() && check.gaps.is_empty());
}

/// A version-3 archive (no `hk_open`; a writer's open chunks were in `hk_chunk`) is
/// migrated on open and reads the same values.
// verifies: GND-02
#[test]
fn a_version_3_archive_is_migrated() {
    let p = tmp("v3.db");
    let _rm = Rm(vec![p.clone()]);
    let a = Archive::open(&p).unwrap();
    let s = a.sender();
    for i in 0..1500 {
        s.send(tm(hk_packet(2, i as u16, T0 + i * 100, i), T0 + i * 100));
    }
    drop(s);
    a.close().unwrap();
    {
        let c = rusqlite::Connection::open(&p).unwrap();
        c.execute_batch("DROP TABLE hk_open; UPDATE schema_version SET version = 3;")
            .unwrap();
    }
    let mut s = Store::open(p.to_str().unwrap()).unwrap();
    assert!(s.db().has_table("hk_open").unwrap());
    assert_eq!(s.hk_series("v_bat_a", &Filter::default()).unwrap()[0].1.len(), 1500);
    let a = Archive::open(&p).unwrap();
    let tx = a.sender();
    tx.send(tm(hk_packet(2, 1500, T0 + 150_000, 1500), T0 + 150_000));
    drop(tx);
    a.close().unwrap();
    assert_eq!(s.hk_series("v_bat_a", &Filter::default()).unwrap()[0].1.len(), 1501);
    assert!(s.check(None).unwrap().chunk_mismatch.is_empty());
}

/// A version-2 archive (SQLite: the collector kept its alarms, link health and holes in
/// tables of its own) is migrated on open: one alarm table with the ISA-18.2 states, the
/// link table, the collector's tables gone.
// verifies: GND-02, GND-14
#[test]
fn a_version_2_archive_with_collector_tables_is_migrated() {
    use ground::alarms::State;
    let p = tmp("v2.db");
    let _rm = Rm(vec![p.clone()]);
    drop(Store::open(p.to_str().unwrap()).unwrap());
    {
        // Back to version 2's alarm table and the collector's tables of that version.
        let c = rusqlite::Connection::open(&p).unwrap();
        c.execute_batch(
            "DROP TABLE alarm; DROP TABLE link; DROP TABLE hk_open; UPDATE schema_version SET version = 2;
             CREATE TABLE alarm (id INTEGER PRIMARY KEY, robot INTEGER NOT NULL, source TEXT NOT NULL,
                severity TEXT NOT NULL, state TEXT NOT NULL, first_ms INTEGER NOT NULL, last_ms INTEGER NOT NULL,
                value TEXT, limit_text TEXT, count INTEGER NOT NULL, ack_ms INTEGER, shelved_until_ms INTEGER,
                cleared_ms INTEGER);
             CREATE INDEX alarm_t ON alarm (first_ms);
             CREATE INDEX alarm_open ON alarm (robot, source, state);
             CREATE TABLE collect_alarm (id INTEGER PRIMARY KEY, robot INTEGER NOT NULL, kind TEXT NOT NULL,
                source TEXT NOT NULL, severity TEXT NOT NULL, state TEXT NOT NULL, condition INTEGER NOT NULL,
                acked INTEGER NOT NULL, shelved_until_ms INTEGER, first_ms INTEGER NOT NULL, last_ms INTEGER NOT NULL,
                value REAL, message TEXT, count INTEGER NOT NULL);
             CREATE TABLE collect_gap (id INTEGER PRIMARY KEY, t_ms INTEGER NOT NULL, robot INTEGER NOT NULL,
                apid INTEGER NOT NULL, first_seq INTEGER NOT NULL, last_seq INTEGER NOT NULL, count INTEGER NOT NULL,
                after_obt_ms INTEGER, before_obt_ms INTEGER, reason TEXT NOT NULL);
             CREATE TABLE collect_robot (robot INTEGER PRIMARY KEY, addr TEXT, link TEXT, last_heard_ms INTEGER,
                last_hk_ms INTEGER, packets INTEGER, filled INTEGER, lost INTEGER, duplicates INTEGER,
                corrupt INTEGER, reboots INTEGER, updated_ms INTEGER NOT NULL);
             INSERT INTO alarm (robot, source, severity, state, first_ms, last_ms, value, limit_text, count)
                VALUES (1, 'V_BAT_A', 'high', 'cleared', 1, 2, '9.6 V', '< 10 V', 1);
             INSERT INTO collect_alarm (robot, kind, source, severity, state, condition, acked, first_ms, last_ms,
                value, message, count) VALUES (2, 'link', 'LINK_LOSS', 'high', 'active', 1, 0, 3, 4, NULL, 'no TM', 2);
             INSERT INTO collect_robot (robot, addr, link, packets, updated_ms) VALUES (2, '127.0.0.1:9', 'lost', 77, 5);
             INSERT INTO collect_gap (t_ms, robot, apid, first_seq, last_seq, count, reason)
                VALUES (5, 2, 258, 0, 9, 10, 'rebooted');",
        )
        .unwrap();
    }
    let mut s = Store::open(p.to_str().unwrap()).unwrap();
    for t in ["collect_alarm", "collect_robot", "collect_gap", "v2_alarm"] {
        assert!(!s.db().has_table(t).unwrap(), "{t}");
    }
    let all = s.alarms(None, true).unwrap();
    assert_eq!(all.len(), 2, "{all:?}");
    // Newest first: the collector's open link loss, then the closed battery alarm.
    assert_eq!(
        (
            all[0].robot,
            all[0].kind.as_str(),
            all[0].source.as_str(),
            all[0].state,
            all[0].count
        ),
        (2, "link", "LINK_LOSS", State::Active, 2)
    );
    assert_eq!((all[1].state, all[1].message.as_str()), (State::Normal, "9.6 V < 10 V"));
    // The migrated alarm still follows the state machine.
    assert_eq!(
        s.alarm_input(all[0].id, ground::alarms::Input::Ack, 10).unwrap(),
        State::Acknowledged
    );
    let links = s.links().unwrap();
    assert_eq!(
        (links[0].robot, links[0].link.as_str(), links[0].tm.packets),
        (2, "lost", 77)
    );
}
