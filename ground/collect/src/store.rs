//! The collector's side of the archive, in one place: where TM goes and where the
//! collector's records go (alarms, unrecoverable holes, link health) — all through the
//! archive's backend-neutral [`Store`], so a collector works on SQLite and PostgreSQL
//! alike.
//!
//! TM goes through the archive's writer ([`Archive`]). The sink keeps every record it
//! handed over until the writer confirmed the commit (a sync once a second); if the
//! writer fails (disk full, I/O error) the uncommitted records stay in memory, an
//! `ARCHIVE_WRITE` alarm is raised and the archive is reopened every few seconds;
//! records are then written again unless the archive already holds them. Both backends
//! roll a failed transaction back, so the archive is never half-written.

use std::path::PathBuf;
use std::time::Duration;

use crossbeam_channel::{Receiver, RecvTimeoutError, Sender};
use mib::headers::SeqCount;
use serde::Serialize;

use crate::alarms::{Input, Severity, Source};
use crate::archive::{self, AlarmUpdate, Archive, ArchiveSender, GapNote, GapReason, Handed, Record, Store};
use crate::pus;

use super::tracker::{Lost, LostRun};

/// A robot's link health as the collector writes it (the archive's `link` table).
pub use crate::archive::LinkHealth as Health;

/// Most TM records kept in memory while the archive cannot be written; beyond, the
/// oldest are dropped and counted (`dropped_unwritable`).
pub const MAX_PENDING: usize = 200_000;
/// Commit confirmation period.
const SYNC_MS: i64 = 1_000;
/// Reopen attempts while the archive fails.
const REOPEN_MS: i64 = 3_000;
/// Check of expired shelves.
const SHELVE_TICK_MS: i64 = 5_000;

/// What the robot threads hand to the sink.
#[derive(Debug)]
pub enum SinkMsg {
    Tm {
        t_ms: i64,
        robot: u8,
        raw: Vec<u8>,
    },
    Alarm {
        robot: u8,
        source: Source,
        severity: Severity,
        input: Input,
        t_ms: i64,
        value: Option<f64>,
        message: String,
    },
    Lost {
        robot: u8,
        apid: u16,
        run: LostRun,
        t_ms: i64,
    },
    Health(Health),
    /// A TC the collector sent (its page's, its plan runs', its own subscriptions and
    /// store requests): archived like `ground send`'s.
    Tc {
        t_ms: i64,
        tc: crate::pus::BuiltTc,
        label: Option<String>,
    },
    /// Answered once everything before it is committed (or kept for later).
    Flush(Sender<()>),
}

/// Counters of the sink.
#[derive(Clone, Debug, Default, Serialize)]
pub struct SinkStats {
    pub tm_written: u64,
    pub tm_skipped_present: u64,
    pub pending: usize,
    pub dropped_unwritable: u64,
    /// TCs handed to the archive writer.
    pub tc_written: u64,
    /// TCs not archived because the archive writer had stopped.
    pub tc_dropped: u64,
    pub write_failures: u64,
    pub pruned_rows: u64,
}

/// Settings of the sink.
#[derive(Clone, Debug)]
pub struct SinkCfg {
    pub path: PathBuf,
    /// Delete archived data older than this (ms); `None` keeps everything.
    pub retain_ms: Option<i64>,
    pub prune_every_ms: i64,
}

struct Sink {
    cfg: SinkCfg,
    archive: Option<Archive>,
    sender: Option<ArchiveSender>,
    store: Option<Store>,
    /// Handed to the writer, not yet confirmed committed.
    unconfirmed: Vec<Handed>,
    /// Handed to a writer that then failed: committed or not, checked on reopening.
    suspect: Vec<Handed>,
    /// Not handed over (archive failing).
    pending: std::collections::VecDeque<Handed>,
    /// Collector records waiting for a writable archive.
    deferred: Vec<SinkMsg>,
    failing_since: Option<i64>,
    last_reopen_ms: i64,
    /// Latest health per robot, written together once a second.
    health: std::collections::BTreeMap<u8, Health>,
    stats: SinkStats,
}

/// Runs the sink until every sender of `rx` is gone; returns its counters.
pub fn run_sink(cfg: SinkCfg, rx: Receiver<SinkMsg>) -> SinkStats {
    let mut s = Sink {
        cfg,
        archive: None,
        sender: None,
        store: None,
        unconfirmed: Vec::new(),
        suspect: Vec::new(),
        pending: Default::default(),
        deferred: Vec::new(),
        failing_since: None,
        last_reopen_ms: 0,
        health: Default::default(),
        stats: SinkStats::default(),
    };
    s.reopen(archive::now_ms());
    let mut last_sync = archive::now_ms();
    let mut last_tick = last_sync;
    let mut last_prune = i64::MIN / 2;
    loop {
        let msg = rx.recv_timeout(Duration::from_millis(200));
        let now = archive::now_ms();
        match msg {
            Ok(m) => s.handle(m, now),
            Err(RecvTimeoutError::Timeout) => {}
            Err(RecvTimeoutError::Disconnected) => break,
        }
        if now - last_sync >= SYNC_MS {
            last_sync = now;
            s.confirm(now);
            s.write_health(now);
        }
        if s.failing_since.is_some() && now - s.last_reopen_ms >= REOPEN_MS {
            s.reopen(now);
        }
        if now - last_tick >= SHELVE_TICK_MS {
            last_tick = now;
            s.tick_shelves(now);
        }
        if s.cfg.retain_ms.is_some() && now - last_prune >= s.cfg.prune_every_ms {
            last_prune = now;
            s.prune(now);
        }
    }
    let now = archive::now_ms();
    s.confirm(now);
    s.write_health(now);
    if let Some(a) = s.archive.take() {
        drop(s.sender.take());
        if let Err(e) = a.close() {
            tracing::error!("archive: closing: {e}");
        }
    }
    s.stats.pending = s.pending.len() + s.unconfirmed.len() + s.suspect.len();
    if s.stats.pending > 0 {
        tracing::error!(
            "archive: {} TM packets could not be written (they stay in the on-board stores)",
            s.stats.pending
        );
    }
    s.stats
}

impl Sink {
    fn handle(&mut self, m: SinkMsg, now: i64) {
        match m {
            SinkMsg::Tm { t_ms, robot, raw } => {
                self.pending.push_back((t_ms, robot, raw));
                while self.pending.len() > MAX_PENDING {
                    self.pending.pop_front();
                    self.stats.dropped_unwritable += 1;
                }
                self.forward();
            }
            SinkMsg::Flush(tx) => {
                self.confirm(now);
                self.write_health(now);
                let _ = tx.send(());
            }
            SinkMsg::Health(h) => {
                self.health.insert(h.robot, h);
            }
            SinkMsg::Tc { t_ms, tc, label } => {
                let rec = Record::Tc {
                    t_ms,
                    tc,
                    step: label,
                    attempt: 1,
                };
                match &self.sender {
                    Some(snd) if snd.send(rec) => self.stats.tc_written += 1,
                    Some(_) | None => {
                        self.stats.tc_dropped += 1;
                        tracing::warn!("archive: a TC could not be archived (writer stopped)");
                    }
                }
            }
            other => {
                if self.write_own(&other).is_err() {
                    self.deferred.push(other);
                }
            }
        }
    }

    /// Hands pending TM to the archive writer.
    fn forward(&mut self) {
        let Some(snd) = &self.sender else { return };
        while let Some((t_ms, robot, raw)) = self.pending.pop_front() {
            let decoded = pus::decode_tm(&raw);
            let ok = snd.send(Record::Tm {
                t_ms,
                link_robot: Some(robot),
                raw: raw.clone(),
                decoded,
            });
            if !ok {
                self.pending.push_front((t_ms, robot, raw));
                self.failed(archive::now_ms(), "archive writer stopped".into());
                return;
            }
            self.unconfirmed.push((t_ms, robot, raw));
        }
    }

    /// Waits for the writer to commit what it was given.
    fn confirm(&mut self, now: i64) {
        self.forward();
        let Some(snd) = &self.sender else { return };
        match snd.sync() {
            Ok(()) => {
                self.stats.tm_written += self.unconfirmed.len() as u64;
                self.unconfirmed.clear();
                if self.failing_since.is_some() || !self.deferred.is_empty() {
                    self.retry_deferred(now);
                }
            }
            Err(e) => self.failed(now, e.to_string()),
        }
    }

    fn failed(&mut self, now: i64, why: String) {
        self.stats.write_failures += 1;
        let detail = match self.archive.take() {
            Some(a) => {
                drop(self.sender.take());
                match a.close() {
                    Err(e) => e.to_string(),
                    Ok(_) => why,
                }
            }
            None => why,
        };
        // Records the failed writer had: checked against the archive on reopening.
        self.suspect.append(&mut self.unconfirmed);
        if self.failing_since.is_none() {
            self.failing_since = Some(now);
            tracing::error!("archive: cannot write ({detail}); keeping TM in memory and retrying");
            self.deferred.push(SinkMsg::Alarm {
                robot: 0,
                source: Source::Archive,
                severity: Severity::High,
                input: Input::Activate,
                t_ms: now,
                value: None,
                message: format!("archive cannot be written: {detail}"),
            });
        }
        self.store = None;
        self.last_reopen_ms = now;
    }

    fn reopen(&mut self, now: i64) {
        self.last_reopen_ms = now;
        let mut store = match Store::open(&self.cfg.path.to_string_lossy()) {
            Ok(c) => c,
            Err(e) => {
                if self.failing_since.is_none() {
                    self.failed(now, e.to_string());
                }
                return;
            }
        };
        let archive = match Archive::open(&self.cfg.path) {
            Ok(a) => a,
            Err(e) => {
                if self.failing_since.is_none() {
                    self.failed(now, e.to_string());
                }
                return;
            }
        };
        // What a failed writer may have committed before failing is not written twice.
        let suspect = std::mem::take(&mut self.suspect);
        let n = suspect.len();
        match store.not_archived(suspect.clone()) {
            Ok(missing) => {
                self.stats.tm_skipped_present += (n - missing.len()) as u64;
                for r in missing.into_iter().rev() {
                    self.pending.push_front(r);
                }
            }
            Err(e) => {
                self.suspect = suspect;
                tracing::debug!("archive: checking what the failed writer committed: {e}");
                return;
            }
        }
        self.sender = Some(archive.sender());
        self.archive = Some(archive);
        self.store = Some(store);
        self.forward();
        if let Some(snd) = &self.sender {
            if snd.sync().is_ok() {
                self.stats.tm_written += self.unconfirmed.len() as u64;
                self.unconfirmed.clear();
                self.retry_deferred(now);
                return;
            }
        }
        self.failed(now, "archive writer failed after reopening".into());
    }

    fn retry_deferred(&mut self, now: i64) {
        if let Some(since) = self.failing_since.take() {
            tracing::info!("archive: writable again after {} s", (now - since) / 1000);
            self.deferred.push(SinkMsg::Alarm {
                robot: 0,
                source: Source::Archive,
                severity: Severity::High,
                input: Input::Clear,
                t_ms: now,
                value: None,
                message: "archive writable again".into(),
            });
        }
        let items = std::mem::take(&mut self.deferred);
        for (i, m) in items.iter().enumerate() {
            if self.write_own(m).is_err() {
                self.deferred.extend(items.into_iter().skip(i));
                return;
            }
        }
    }

    fn write_own(&mut self, m: &SinkMsg) -> Result<(), archive::ArchiveError> {
        let Some(st) = self.store.as_mut() else {
            return Err(archive::ArchiveError::NotFound("archive not open".into()));
        };
        match m {
            SinkMsg::Alarm {
                robot,
                source,
                severity,
                input,
                t_ms,
                value,
                message,
            } => {
                let r = st.apply_alarm(&AlarmUpdate {
                    robot: *robot,
                    source,
                    severity: *severity,
                    input: *input,
                    t_ms: *t_ms,
                    value: *value,
                    message,
                });
                match r {
                    Ok(_) => {}
                    // The state machine refused the input: nothing to keep for later.
                    Err(archive::ArchiveError::Refused(e)) => tracing::debug!("alarm {source} robot {robot}: {e}"),
                    Err(e) => return Err(e),
                }
            }
            SinkMsg::Lost { robot, apid, run, t_ms } => {
                // The archive's gap report (`ground archive gaps`) gives the reason; its
                // note is keyed by the packet before the hole. A hole with no archived
                // packet before it (older than anything archived) is logged only.
                if run.after_obt_ms > i64::MIN {
                    st.note_hole(&GapNote {
                        robot: *robot,
                        apid: *apid,
                        after_obt_ms: run.after_obt_ms,
                        after_seq: SeqCount::new(run.first).prev().get(),
                        reason: match run.why {
                            Lost::Rebooted => GapReason::Rebooted,
                            Lost::Overwritten => GapReason::StoreOverwritten,
                            Lost::NotDelivered | Lost::TooMany => GapReason::Unrecoverable,
                        },
                        note: Some(format!(
                            "collector: {} (seq {}..={}, {} packets)",
                            run.why.reason(),
                            run.first,
                            run.last,
                            run.count
                        )),
                        t_ms: *t_ms,
                    })?;
                }
            }
            SinkMsg::Tm { .. } | SinkMsg::Flush(_) | SinkMsg::Health(_) | SinkMsg::Tc { .. } => {}
        }
        Ok(())
    }

    /// Writes the robots' health in one transaction (kept for later if it fails).
    fn write_health(&mut self, now: i64) {
        if self.health.is_empty() {
            return;
        }
        let Some(st) = self.store.as_mut() else { return };
        let links: Vec<Health> = self.health.values().cloned().collect();
        match st.write_links(&links, now) {
            Ok(()) => self.health.clear(),
            Err(e) => tracing::debug!("health: {e}"),
        }
    }

    fn tick_shelves(&mut self, now: i64) {
        let Some(st) = self.store.as_mut() else { return };
        if let Err(e) = st.expire_shelves(now) {
            tracing::debug!("shelve expiry: {e}");
        }
    }

    fn prune(&mut self, now: i64) {
        let (Some(st), Some(keep)) = (self.store.as_mut(), self.cfg.retain_ms) else {
            return;
        };
        match st.prune(now - keep) {
            Ok(n) => {
                self.stats.pruned_rows += n;
                if n > 0 {
                    tracing::info!(
                        "retention: deleted {n} rows older than {}",
                        super::config::format_duration_ms(keep)
                    );
                }
            }
            Err(e) => tracing::warn!("retention: {e}"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tmp(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("collect-store-{}-{name}", std::process::id()));
        let _ = std::fs::remove_file(&d);
        d
    }

    // verifies: GND-12, GND-14, GND-02
    #[test]
    fn the_sink_writes_alarms_holes_and_link_health_to_the_archive() {
        let path = tmp("sink.db");
        let (tx, rx) = crossbeam_channel::unbounded();
        let run = LostRun {
            first: 0,
            last: 9,
            count: 10,
            after_obt_ms: 5_000,
            before_obt_ms: 9_000,
            why: Lost::Rebooted,
        };
        tx.send(SinkMsg::Lost {
            robot: 3,
            apid: 0x103,
            run,
            t_ms: 10_000,
        })
        .unwrap();
        let alarm = |input, t_ms| SinkMsg::Alarm {
            robot: 3,
            source: Source::LinkLoss,
            severity: Severity::High,
            input,
            t_ms,
            value: None,
            message: "no TM".into(),
        };
        tx.send(alarm(Input::Activate, 11_000)).unwrap();
        tx.send(alarm(Input::Activate, 12_000)).unwrap();
        // A clear of a condition nothing raised opens nothing.
        tx.send(SinkMsg::Alarm {
            robot: 2,
            source: Source::StaleData,
            severity: Severity::Medium,
            input: Input::Clear,
            t_ms: 12_000,
            value: None,
            message: String::new(),
        })
        .unwrap();
        tx.send(SinkMsg::Health(Health {
            robot: 3,
            addr: "127.0.0.1:9".into(),
            link: "lost".into(),
            last_heard_ms: Some(9_500),
            tm: crate::archive::TmCounts {
                packets: 42,
                ..Default::default()
            },
            ..Default::default()
        }))
        .unwrap();
        drop(tx);
        run_sink(
            SinkCfg {
                path: path.clone(),
                retain_ms: None,
                prune_every_ms: 3_600_000,
            },
            rx,
        );
        let mut st = Store::open(path.to_str().unwrap()).unwrap();
        let notes = st.gap_notes(Some(3), 10).unwrap();
        assert_eq!(notes.len(), 1);
        assert_eq!(
            (
                notes[0].apid,
                notes[0].after_obt_ms,
                notes[0].after_seq,
                notes[0].reason
            ),
            (0x103, 5_000, 16383, GapReason::Rebooted)
        );
        assert!(notes[0].note.as_deref().unwrap().contains("10 packets"), "{notes:?}");
        let alarms = st.alarms(None, true).unwrap();
        assert_eq!(alarms.len(), 1, "{alarms:?}");
        assert_eq!(
            (
                alarms[0].robot,
                alarms[0].source.as_str(),
                alarms[0].count,
                alarms[0].last_ms
            ),
            (3, "LINK_LOSS", 2, 12_000)
        );
        let links = st.links().unwrap();
        assert_eq!(links.len(), 1);
        assert_eq!((links[0].link.as_str(), links[0].tm.packets), ("lost", 42));
        let _ = std::fs::remove_file(&path);
    }
}
