//! What a collector (`ground collect`) keeps in the archive beside the data, on either
//! backend: each robot's link as the collector last saw it, where each robot's TM
//! stands (to resume after a restart), which packets a failed writer did not commit,
//! and retention.

use serde::Serialize;

use super::db::{collect, Db, Val};
use super::{ArchiveError, Store};
use ground_pus as pus;

/// A robot's TM counts as a collector's sequence trackers sum them: its live status shows
/// them, its link row ([`LinkHealth`]) keeps them.
#[derive(Clone, Copy, Debug, Default, Serialize, PartialEq, Eq)]
pub struct TmCounts {
    /// Packets received (new and filled).
    pub packets: u64,
    /// Holes filled (from the on-board store or late).
    pub filled: u64,
    /// Packets declared unrecoverable.
    pub lost: u64,
    pub duplicates: u64,
    pub corrupt: u64,
    pub reboots: u64,
}

/// A robot's link, as the collector last wrote it.
#[derive(Clone, Debug, Default, Serialize, PartialEq)]
pub struct LinkHealth {
    pub robot: u8,
    pub addr: String,
    /// `up`, `lost`, `connecting`, … (the collector's link state).
    pub link: String,
    pub last_heard_ms: Option<i64>,
    pub last_hk_ms: Option<i64>,
    #[serde(flatten)]
    pub tm: TmCounts,
    pub updated_ms: i64,
}

/// A packet the collector handed to a writer: `(ground ms, link robot, raw bytes)`.
pub type Handed = (i64, u8, Vec<u8>);

/// One APID's newest archived packets, oldest first: `(apid, [(seq, on-board ms)])`.
pub type Recent = (u16, Vec<(u16, i64)>);

impl Store {
    /// Writes the links' health in one transaction, stamped `now_ms`.
    pub fn write_links(&mut self, links: &[LinkHealth], now_ms: i64) -> Result<(), ArchiveError> {
        self.write_tx(|db| {
            for h in links {
                db.exec(
                    "INSERT INTO link (robot, addr, state, last_heard_ms, last_hk_ms, packets, filled, lost, duplicates, \
                     corrupt, reboots, updated_ms) VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, ?12) \
                     ON CONFLICT (robot) DO UPDATE SET addr = excluded.addr, state = excluded.state, \
                     last_heard_ms = excluded.last_heard_ms, last_hk_ms = excluded.last_hk_ms, \
                     packets = excluded.packets, filled = excluded.filled, lost = excluded.lost, \
                     duplicates = excluded.duplicates, corrupt = excluded.corrupt, reboots = excluded.reboots, \
                     updated_ms = excluded.updated_ms",
                    &[
                        Val::Int(h.robot as i64),
                        h.addr.as_str().into(),
                        h.link.as_str().into(),
                        h.last_heard_ms.into(),
                        h.last_hk_ms.into(),
                        Val::Int(h.tm.packets as i64),
                        Val::Int(h.tm.filled as i64),
                        Val::Int(h.tm.lost as i64),
                        Val::Int(h.tm.duplicates as i64),
                        Val::Int(h.tm.corrupt as i64),
                        Val::Int(h.tm.reboots as i64),
                        Val::Int(now_ms),
                    ],
                )?;
            }
            Ok(())
        })
    }

    /// Every robot's link as last written, by robot.
    pub fn links(&mut self) -> Result<Vec<LinkHealth>, ArchiveError> {
        let n = |v: &Val| v.int().unwrap_or(0) as u64;
        Ok(collect(
            self.db.as_mut(),
            "SELECT robot, addr, state, last_heard_ms, last_hk_ms, packets, filled, lost, duplicates, corrupt, \
             reboots, updated_ms FROM link ORDER BY robot",
            &[],
        )?
        .iter()
        .map(|r| LinkHealth {
            robot: r[0].int().unwrap_or(0) as u8,
            addr: r[1].text().unwrap_or("").to_string(),
            link: r[2].text().unwrap_or("").to_string(),
            last_heard_ms: r[3].int(),
            last_hk_ms: r[4].int(),
            tm: TmCounts {
                packets: n(&r[5]),
                filled: n(&r[6]),
                lost: n(&r[7]),
                duplicates: n(&r[8]),
                corrupt: n(&r[9]),
                reboots: n(&r[10]),
            },
            updated_ms: r[11].int().unwrap_or(0),
        })
        .collect())
    }

    /// The newest archived packets of `robot` per APID, at most `n` each, oldest first,
    /// per [`Recent`]; with the intact packets kept raw because their
    /// body did not decode (they were received too).
    pub fn recent_positions(&mut self, robot: u8, n: usize) -> Result<Vec<Recent>, ArchiveError> {
        let db = self.db.as_mut();
        let apids: Vec<i64> = collect(
            db,
            "SELECT apid FROM stream WHERE robot = ?1 ORDER BY apid",
            &[Val::Int(robot as i64)],
        )?
        .iter()
        .filter_map(|r| r[0].int())
        .collect();
        let mut out = Vec::new();
        for apid in apids {
            let mut v: Vec<(u16, i64)> = collect(
                db,
                "SELECT seq, obt_ms FROM packet WHERE robot = ?1 AND apid = ?2 ORDER BY obt_ms DESC, seq DESC LIMIT ?3",
                &[Val::Int(robot as i64), Val::Int(apid), Val::Int(n as i64)],
            )?
            .iter()
            .map(|r| (r[0].int().unwrap_or(0) as u16, r[1].int().unwrap_or(0)))
            .collect();
            v.reverse();
            out.push((apid as u16, v));
        }
        let raws = collect(
            db,
            "SELECT raw FROM bad_packet WHERE link_robot = ?1 ORDER BY id DESC LIMIT ?2",
            &[Val::Int(robot as i64), Val::Int(n as i64)],
        )?;
        for r in &raws {
            let Some((apid, seq, obt)) = r[0].blob().and_then(pus::intact_position) else {
                continue;
            };
            match out.iter_mut().find(|(a, _)| *a == apid) {
                Some((_, v)) => v.push((seq, obt)),
                None => out.push((apid, vec![(seq, obt)])),
            }
        }
        for (_, v) in out.iter_mut() {
            v.sort_by_key(|&(seq, obt)| (obt, seq));
        }
        Ok(out)
    }

    /// Of `handed` (given to a writer that then failed), those the archive does not
    /// hold. One range scan over the ground-time column, however many packets.
    pub fn not_archived(&mut self, handed: Vec<Handed>) -> Result<Vec<Handed>, ArchiveError> {
        let Some(since) = handed.iter().map(|r| r.0).min() else {
            return Ok(handed);
        };
        let db = self.db.as_mut();
        let mut keys = std::collections::HashSet::new();
        db.rows(
            "SELECT apid, seq, obt_ms FROM packet WHERE t_ms >= ?1",
            &[Val::Int(since)],
            &mut |r| {
                keys.insert((
                    r[0].int().unwrap_or(-1),
                    r[1].int().unwrap_or(-1),
                    r[2].int().unwrap_or(-1),
                ));
                Ok(())
            },
        )?;
        let mut raws = std::collections::HashSet::new();
        db.rows(
            "SELECT raw FROM bad_packet WHERE t_ms >= ?1",
            &[Val::Int(since)],
            &mut |r| {
                if let Some(b) = r[0].blob() {
                    raws.insert(b.to_vec());
                }
                Ok(())
            },
        )?;
        Ok(handed
            .into_iter()
            .filter(|(_, _, raw)| match pus::decode_tm(raw) {
                Ok(tm) => !keys.contains(&(tm.apid as i64, tm.seq as i64, tm.time.unix_ms())),
                Err(_) => !raws.contains(raw),
            })
            .collect())
    }

    /// Deletes archived data older than `before_ms` (ground time): packets, parameter
    /// chunks, events, reports, TCs, damaged packets, gap notes and closed alarms. Open
    /// alarms stay whatever their age. Returns the rows deleted.
    pub fn prune(&mut self, before_ms: i64) -> Result<u64, ArchiveError> {
        self.write_tx(|db: &mut dyn Db| {
            let mut n = 0;
            for (table, cond) in [
                ("hk_chunk", "t1 < ?1"),
                ("hk_open", "t1 < ?1"),
                ("event", "t_ms < ?1"),
                ("verification", "t_ms < ?1"),
                ("packet", "t_ms < ?1"),
                ("tc", "t_ms < ?1"),
                ("bad_packet", "t_ms < ?1"),
                ("gap_note", "t_ms < ?1"),
                ("alarm", "state = 'normal' AND last_ms < ?1"),
            ] {
                n += db.exec(&format!("DELETE FROM {table} WHERE {cond}"), &[Val::Int(before_ms)])?;
            }
            Ok(n)
        })
    }

    /// Whether the archive shows the TC of plan step `step` for `robot` (named `tc`)
    /// completed: a successful TM[1,7] for its request ID after it was sent.
    pub fn step_completed(&mut self, step: &str, robot: u8, tc: &str) -> Result<bool, ArchiveError> {
        Ok(!collect(
            self.db.as_mut(),
            "SELECT 1 FROM tc JOIN verification v ON v.req_apid = tc.apid AND v.req_seq = tc.seq \
             WHERE tc.step = ?1 AND tc.robot = ?2 AND tc.name = ?3 AND v.stage = 'completion' \
             AND v.success = 1 AND v.t_ms >= tc.t_ms LIMIT 1",
            &[step.into(), Val::Int(robot as i64), tc.into()],
        )?
        .is_empty())
    }
}
