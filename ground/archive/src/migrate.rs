//! Migrations to the current schema, each inside the caller's transaction.
//!
//! - From the turn-1 layout (version 1: `tm` rows with a JSON body, one `hk` row per
//!   parameter value): its TCs are copied; its TM packets are ingested again from their
//!   raw bytes, so the new archive holds exactly what a fresh import would.
//! - From version 2: the alarm table takes the ISA-18.2 state columns; the collector's
//!   SQLite-only tables of that version (`collect_alarm`, `collect_robot`,
//!   `collect_gap`) are moved into `alarm` and `link` and dropped.

use super::db::{collect, Db, Val};
use super::ingest::Ingest;
use super::schema::ddl;
use super::{ArchiveError, Record};
use ground_pus::decode_tm;

const PAGE: i64 = 10_000;

/// Runs inside the caller's transaction.
pub fn from_v1(db: &mut dyn Db) -> Result<(), ArchiveError> {
    db.batch(
        "DROP INDEX IF EXISTS hk_name_t; DROP INDEX IF EXISTS tm_t; DROP INDEX IF EXISTS event_t;
         DROP INDEX IF EXISTS tc_apid;
         ALTER TABLE tm RENAME TO v1_tm; ALTER TABLE tc RENAME TO v1_tc;
         ALTER TABLE verification RENAME TO v1_verification; ALTER TABLE event RENAME TO v1_event;
         ALTER TABLE hk RENAME TO v1_hk;",
    )?;
    db.batch(&ddl(db.dialect()))?;
    db.exec(
        "INSERT INTO tc (t_ms, robot, apid, seq, service, subservice, name, args, step, attempt, raw) \
         SELECT t_ms, robot, apid, seq, service, subservice, name, args, step, attempt, raw FROM v1_tc ORDER BY id",
        &[],
    )?;
    let mut ingest = Ingest::new();
    let mut last = i64::MIN;
    loop {
        let rows = collect(
            db,
            "SELECT id, t_ms, link_robot, raw FROM v1_tm WHERE id > ?1 ORDER BY id LIMIT ?2",
            &[Val::Int(last), Val::Int(PAGE)],
        )?;
        if rows.is_empty() {
            break;
        }
        let mut batch = Vec::with_capacity(rows.len());
        for r in &rows {
            last = r[0].int().unwrap_or(last);
            let raw = r[3].blob().map(<[u8]>::to_vec).unwrap_or_default();
            batch.push(Record::Tm {
                t_ms: r[1].int().unwrap_or(0),
                link_robot: r[2].int().and_then(|v| u8::try_from(v).ok()),
                decoded: decode_tm(&raw),
                raw,
            });
        }
        ingest.write_in_tx(db, &batch)?;
        ingest.after_commit();
    }
    ingest.close_all_in_tx(db)?;
    db.batch(
        "DROP TABLE v1_tm; DROP TABLE v1_tc; DROP TABLE v1_verification; DROP TABLE v1_event;
         DROP TABLE v1_hk;",
    )?;
    Ok(())
}

/// Runs inside the caller's transaction.
pub fn from_v2(db: &mut dyn Db) -> Result<(), ArchiveError> {
    db.batch(
        "DROP INDEX IF EXISTS alarm_t; DROP INDEX IF EXISTS alarm_open;
         ALTER TABLE alarm RENAME TO v2_alarm;",
    )?;
    db.batch(&ddl(db.dialect()))?;
    // Version 2's own alarm states: active, acknowledged, shelved, cleared (= closed).
    db.exec(
        "INSERT INTO alarm (robot, kind, source, severity, state, condition, acked, first_ms, last_ms, \
         shelved_until_ms, value, message, count, ack_ms, cleared_ms) \
         SELECT robot, 'param', source, severity, CASE state WHEN 'cleared' THEN 'normal' ELSE state END, \
         CASE state WHEN 'cleared' THEN 0 ELSE 1 END, CASE state WHEN 'active' THEN 0 ELSE 1 END, \
         first_ms, last_ms, shelved_until_ms, NULL, TRIM(COALESCE(value, '') || ' ' || COALESCE(limit_text, '')), \
         count, ack_ms, cleared_ms FROM v2_alarm ORDER BY id",
        &[],
    )?;
    db.batch("DROP TABLE v2_alarm")?;
    if db.has_table("collect_alarm")? {
        db.exec(
            "INSERT INTO alarm (robot, kind, source, severity, state, condition, acked, first_ms, last_ms, \
             shelved_until_ms, value, message, count) \
             SELECT robot, kind, source, severity, state, condition, acked, first_ms, last_ms, shelved_until_ms, \
             value, message, count FROM collect_alarm ORDER BY id",
            &[],
        )?;
        db.batch("DROP TABLE collect_alarm")?;
    }
    if db.has_table("collect_robot")? {
        db.exec(
            "INSERT INTO link (robot, addr, state, last_heard_ms, last_hk_ms, packets, filled, lost, duplicates, \
             corrupt, reboots, updated_ms) \
             SELECT robot, COALESCE(addr, ''), COALESCE(link, ''), last_heard_ms, last_hk_ms, COALESCE(packets, 0), \
             COALESCE(filled, 0), COALESCE(lost, 0), COALESCE(duplicates, 0), COALESCE(corrupt, 0), \
             COALESCE(reboots, 0), updated_ms FROM collect_robot",
            &[],
        )?;
        db.batch("DROP TABLE collect_robot")?;
    }
    // Its holes with a packet before them are in gap_note already (written together).
    if db.has_table("collect_gap")? {
        db.batch("DROP TABLE collect_gap")?;
    }
    Ok(())
}
