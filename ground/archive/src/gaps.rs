//! Holes per robot and APID, the last archived position, and the notes a collector adds
//! about holes it could not fill.
//!
//! Packets are followed in on-board time order. Between two stored packets of one APID
//! the next sequence count is expected (modulo 2^14); each step is judged by the one rule
//! the live grounds use too (`ground_pus::seq::step`): a count ahead (less than half the
//! 14-bit circle) is a gap of the counts between; a restart of the on-board software —
//! a BOOT event, or a count not ahead with a later on-board time — is reported as a
//! reboot with the packets of the new boot that are missing, never as a 16k-packet gap,
//! and never as duplicates (the key holds the on-board time, so equal counts of two boots
//! are two packets).

use serde::Serialize;

use ground_pus::seq::{step, Pos, Step};

use super::db::{collect, Val};
use super::{ArchiveError, Store};

/// Why packets are missing.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum GapReason {
    /// Not received and not (yet) retrieved from the on-board store.
    Lost,
    /// The on-board software restarted; the first packets of the new boot are missing.
    Rebooted,
    /// The collector asked the on-board store and it no longer held them.
    StoreOverwritten,
    /// Other reason given by the collector (see the note).
    Unrecoverable,
}

impl GapReason {
    pub fn name(self) -> &'static str {
        match self {
            GapReason::Lost => "lost",
            GapReason::Rebooted => "rebooted",
            GapReason::StoreOverwritten => "store_overwritten",
            GapReason::Unrecoverable => "unrecoverable",
        }
    }
    pub fn parse(s: &str) -> Option<GapReason> {
        [
            GapReason::Lost,
            GapReason::Rebooted,
            GapReason::StoreOverwritten,
            GapReason::Unrecoverable,
        ]
        .into_iter()
        .find(|r| r.name() == s)
    }
}

/// A hole in one robot's APID: the packets strictly between `after` and `before`.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct Gap {
    pub robot: u8,
    pub apid: u16,
    pub after_seq: u16,
    pub after_obt_ms: i64,
    pub before_seq: u16,
    pub before_obt_ms: i64,
    /// Sequence counts missing (for a reboot: those of the new boot before `before`).
    pub missing: u32,
    pub reason: GapReason,
    /// What the collector noted about it, if anything.
    pub note: Option<String>,
}

/// Why the packets after one archived packet cannot be had (a collector's finding).
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct GapNote {
    pub robot: u8,
    pub apid: u16,
    /// The archived packet the hole follows.
    pub after_obt_ms: i64,
    pub after_seq: u16,
    pub reason: GapReason,
    pub note: Option<String>,
    /// Ground time of the finding.
    pub t_ms: i64,
}

/// The newest archived packet of one robot's APID.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct Position {
    pub robot: u8,
    pub apid: u16,
    pub seq: u16,
    pub obt_ms: i64,
    /// Ground time it was archived.
    pub t_ms: i64,
    pub packets: i64,
    pub duplicates: i64,
}

/// The step from the archived packet `(obt_ms, seq)` `prev` to `cur`: `None` if
/// contiguous (or not ahead), else `(missing, reason)` — the rule of
/// [`ground_pus::seq::step`].
pub fn classify(prev: (i64, u16), cur: (i64, u16), boot_at_cur: bool) -> Option<(u32, GapReason)> {
    let pos = |(obt_ms, seq): (i64, u16)| Pos { seq, obt_ms };
    match step(pos(prev), pos(cur), boot_at_cur) {
        Step::Next | Step::Behind => None,
        Step::Gap(n) | Step::Resumed(n) => Some((n, GapReason::Lost)),
        Step::Restart(n) => Some((n, GapReason::Rebooted)),
    }
}

impl Store {
    /// The last archived position of each robot's APIDs (all robots if `None`).
    pub fn positions(&mut self, robot: Option<u8>) -> Result<Vec<Position>, ArchiveError> {
        let mut sql = String::from("SELECT robot, apid, seq, obt_ms, t_ms, packets, duplicates FROM stream WHERE 1=1");
        let mut args = Vec::new();
        if let Some(r) = robot {
            args.push(Val::Int(r as i64));
            sql.push_str(" AND robot = ?1");
        }
        sql.push_str(" ORDER BY robot, apid");
        Ok(collect(self.db.as_mut(), &sql, &args)?
            .iter()
            .map(|r| Position {
                robot: r[0].int().unwrap_or(0) as u8,
                apid: r[1].int().unwrap_or(0) as u16,
                seq: r[2].int().unwrap_or(0) as u16,
                obt_ms: r[3].int().unwrap_or(0),
                t_ms: r[4].int().unwrap_or(0),
                packets: r[5].int().unwrap_or(0),
                duplicates: r[6].int().unwrap_or(0),
            })
            .collect())
    }

    /// Remaining holes per robot and APID, oldest first.
    pub fn gaps(&mut self, robot: Option<u8>) -> Result<Vec<Gap>, ArchiveError> {
        let mut out = Vec::new();
        for p in self.positions(robot)? {
            let key = [Val::Int(p.robot as i64), Val::Int(p.apid as i64)];
            let boots: std::collections::HashSet<(i64, i64)> = collect(
                self.db.as_mut(),
                "SELECT obt_ms, seq FROM event WHERE robot = ?1 AND apid = ?2 AND event_id = ?3",
                &[key[0].clone(), key[1].clone(), Val::Int(mib::events::eid::BOOT as i64)],
            )?
            .iter()
            .map(|r| (r[0].int().unwrap_or(0), r[1].int().unwrap_or(0)))
            .collect();
            let notes: std::collections::HashMap<(i64, i64), (String, Option<String>)> = collect(
                self.db.as_mut(),
                "SELECT after_obt_ms, after_seq, reason, note FROM gap_note WHERE robot = ?1 AND apid = ?2",
                &key,
            )?
            .iter()
            .map(|r| {
                (
                    (r[0].int().unwrap_or(0), r[1].int().unwrap_or(0)),
                    (r[2].text().unwrap_or("").to_string(), r[3].text().map(str::to_string)),
                )
            })
            .collect();
            let mut prev: Option<(i64, i64)> = None;
            self.db.rows(
                "SELECT obt_ms, seq FROM packet WHERE robot = ?1 AND apid = ?2 ORDER BY obt_ms, seq",
                &key,
                &mut |r| {
                    let cur = (r[0].int().unwrap_or(0), r[1].int().unwrap_or(0));
                    if let Some(pv) = prev {
                        let boot = boots.contains(&cur);
                        if let Some((missing, mut reason)) = classify((pv.0, pv.1 as u16), (cur.0, cur.1 as u16), boot)
                        {
                            let note = notes.get(&pv).map(|(why, n)| {
                                if let Some(r) = GapReason::parse(why) {
                                    reason = r;
                                }
                                n.clone()
                            });
                            if missing > 0 {
                                out.push(Gap {
                                    robot: p.robot,
                                    apid: p.apid,
                                    after_seq: pv.1 as u16,
                                    after_obt_ms: pv.0,
                                    before_seq: cur.1 as u16,
                                    before_obt_ms: cur.0,
                                    missing,
                                    reason,
                                    note: note.flatten(),
                                });
                            }
                        }
                    }
                    prev = Some(cur);
                    Ok(())
                },
            )?;
        }
        Ok(out)
    }

    /// Records why `gap` cannot be filled (the collector calls this when the on-board
    /// store no longer holds the packets); [`Store::gaps`] then reports that reason.
    pub fn note_gap(
        &mut self,
        gap: &Gap,
        reason: GapReason,
        note: Option<&str>,
        t_ms: i64,
    ) -> Result<(), ArchiveError> {
        self.note_hole(&GapNote {
            robot: gap.robot,
            apid: gap.apid,
            after_obt_ms: gap.after_obt_ms,
            after_seq: gap.after_seq,
            reason,
            note: note.map(str::to_string),
            t_ms,
        })
    }

    /// Records why the hole after packet (`after_obt_ms`, `after_seq`) of a robot's
    /// APID cannot be filled; a later note on the same hole replaces it.
    pub fn note_hole(&mut self, n: &GapNote) -> Result<(), ArchiveError> {
        self.db.exec(
            "INSERT INTO gap_note (robot, apid, after_obt_ms, after_seq, reason, note, t_ms) \
             VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7) ON CONFLICT (robot, apid, after_obt_ms, after_seq) \
             DO UPDATE SET reason = excluded.reason, note = excluded.note, t_ms = excluded.t_ms",
            &[
                Val::Int(n.robot as i64),
                Val::Int(n.apid as i64),
                Val::Int(n.after_obt_ms),
                Val::Int(n.after_seq as i64),
                n.reason.name().into(),
                n.note.as_deref().into(),
                Val::Int(n.t_ms),
            ],
        )?;
        Ok(())
    }

    /// The newest `limit` gap notes (of `robot`, or all), newest first.
    pub fn gap_notes(&mut self, robot: Option<u8>, limit: usize) -> Result<Vec<GapNote>, ArchiveError> {
        let mut sql =
            String::from("SELECT robot, apid, after_obt_ms, after_seq, reason, note, t_ms FROM gap_note WHERE 1=1");
        let mut args = Vec::new();
        if let Some(r) = robot {
            args.push(Val::Int(r as i64));
            sql.push_str(" AND robot = ?1");
        }
        sql.push_str(&format!(" ORDER BY t_ms DESC LIMIT {limit}"));
        collect(self.db.as_mut(), &sql, &args)?
            .iter()
            .map(|r| {
                let why = r[4].text().unwrap_or("");
                Ok(GapNote {
                    robot: r[0].int().unwrap_or(0) as u8,
                    apid: r[1].int().unwrap_or(0) as u16,
                    after_obt_ms: r[2].int().unwrap_or(0),
                    after_seq: r[3].int().unwrap_or(0) as u16,
                    reason: GapReason::parse(why)
                        .ok_or_else(|| ArchiveError::Damaged(format!("gap note with unknown reason \"{why}\"")))?,
                    note: r[5].text().map(str::to_string),
                    t_ms: r[6].int().unwrap_or(0),
                })
            })
            .collect()
    }

    /// How many gap notes there are (of `robot`, or all).
    pub fn gap_note_count(&mut self, robot: Option<u8>) -> Result<u64, ArchiveError> {
        let (sql, args) = match robot {
            Some(r) => (
                "SELECT COUNT(*) FROM gap_note WHERE robot = ?1",
                vec![Val::Int(r as i64)],
            ),
            None => ("SELECT COUNT(*) FROM gap_note", vec![]),
        };
        Ok(collect(self.db.as_mut(), sql, &args)?
            .first()
            .and_then(|r| r[0].int())
            .unwrap_or(0) as u64)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    // verifies: GND-02, OPS-LIVE-SEQ-01, PUS-15-03
    #[test]
    fn steps_are_classified_by_the_rule_of_the_live_trackers() {
        // Each step one second later on board.
        let c = |a: u16, b: u16, boot| classify((0, a), (1000, b), boot);
        assert_eq!(c(5, 6, false), None);
        assert_eq!(c(16383, 0, false), None);
        assert_eq!(c(5, 9, false), Some((3, GapReason::Lost)));
        assert_eq!(c(16380, 3, false), Some((6, GapReason::Lost)));
        // A restart: the count goes back; not 16k lost.
        assert_eq!(c(500, 0, false), Some((0, GapReason::Rebooted)));
        assert_eq!(c(500, 4, false), Some((4, GapReason::Rebooted)));
        assert_eq!(c(16000, 0, true), Some((0, GapReason::Rebooted)));
        // A BOOT event ahead: the obsw went on from its kept store; the counts between
        // are an ordinary gap.
        assert_eq!(c(16000, 2, true), Some((385, GapReason::Lost)));
        // Ahead by less than half the circle is a gap (across the wrap too), more than
        // half with a later time a restart: the live trackers' rule.
        assert_eq!(c(12_000, 3_000, false), Some((7_383, GapReason::Lost)));
        assert_eq!(c(100, 9_000, false), Some((9_000, GapReason::Rebooted)));
        // The same count at the same on-board time: not a gap.
        assert_eq!(classify((5, 7), (5, 7), false), None);
    }
}
