//! The [`Session`]: links to several robots, TCs with per-APID sequence counts, PUS 1
//! verification, resends until acceptance, link-loss watch, archive.

use std::collections::{BTreeMap, HashMap};
use std::net::SocketAddr;
use std::time::{Duration, Instant};

use crossbeam_channel::Receiver;
use mib::events::eid;
use mib::ground_config::TC_RETRY_MAX;
use mib::headers::SeqCount;
use mib::params::pid;
use mib::tc::TcDef;

use crate::archive::{now_ms, ArchiveSender, Record};
use crate::link::{FrameOptions, FrameStats, Incoming, Link, Transport};
use crate::live::{self, GapPlan, Verdict as SeqVerdict};
use crate::pus::{self, BuiltTc, DecodeError, Event, Hk, SeqCounters, Stage, Tm, TmBody, Verification};

use super::book::{Due, Pending, TcBook, Verdict};
use super::*;

/// [`mib::ground_config::SEQ_SKIP_AFTER_RESTART`]. Over frames the robot would still execute a
/// reused count (COP-1 delivers once; frame TCs bypass its duplicate window), but that TC's
/// old reports, replayed from the store, would be taken for the new one's; on the lab links
/// a reused count with the same bytes (a PING) would be answered as a duplicate.
pub use mib::ground_config::SEQ_SKIP_AFTER_RESTART;

/// The first TC sequence count a ground process uses on a robot's APID — one rule for
/// every front end (CLI verbs, demo, the collector and its page) and every link: after
/// the last one its archive holds (`archived_next`, [`crate::archive::next_seq`]),
/// [`SEQ_SKIP_AFTER_RESTART`] further; with no archive, from the clock.
pub fn first_tc_seq(archived_next: Option<u16>) -> u16 {
    match archived_next {
        Some(n) => SeqCount::new(n).add(SEQ_SKIP_AFTER_RESTART).get(),
        None => {
            let n = std::time::SystemTime::now()
                .duration_since(std::time::UNIX_EPOCH)
                .map_or(0, |d| d.subsec_nanos() ^ d.as_secs() as u32);
            // The low 14 bits of the clock's mix.
            SeqCount::new(n as u16).get()
        }
    }
}

/// Something that happened on the links.
#[derive(Clone, Debug)]
pub enum Update {
    Verification {
        robot: u8,
        tag: Option<usize>,
        tc: Option<&'static str>,
        v: Verification,
        /// Time from the first send of the TC.
        after: Option<Duration>,
        /// The report's own time stamp (the robot's clock, Unix ms).
        at_ms: Option<i64>,
    },
    Event {
        robot: u8,
        event: Event,
    },
    Hk {
        robot: u8,
        hk: Hk,
    },
    Tm {
        robot: u8,
        tm: Tm,
    },
    Resent {
        robot: u8,
        tag: Option<usize>,
        tc: &'static str,
        send: u32,
    },
    GaveUp {
        robot: u8,
        tag: Option<usize>,
        tc: &'static str,
        sends: u32,
        /// The TC was accepted (so it may have executed): its outcome is unknown.
        accepted: bool,
    },
    /// A TM[1,2] for a copy of a TC that was damaged on the way (CRC or length): not the
    /// TC's verdict; the TC is resent.
    DamagedCopy {
        robot: u8,
        tag: Option<usize>,
        tc: &'static str,
    },
    /// No TM from the robot for the link-loss time ([`crate::live::LinkWatch`]), or its
    /// TCP connection closed.
    LinkLost {
        robot: u8,
        why: String,
    },
    Corrupt {
        robot: u8,
        error: DecodeError,
    },
    /// A TM whose APID is not the link's robot's (archived, otherwise ignored).
    Foreign {
        robot: u8,
        apid: u16,
        service: u8,
        subservice: u8,
    },
}

impl Update {
    /// A TC given up after its last wait ([`super::book::Due::GaveUp`]); `delivered`: a CLCW
    /// acknowledged its frame (over frames), so it reached the robot like an accepted one.
    pub fn gave_up(p: &Pending, delivered: bool) -> Update {
        Update::GaveUp {
            robot: p.robot,
            tag: p.tag,
            tc: p.tc.def.name,
            sends: if p.waits_only { 1 } else { p.sends },
            accepted: p.accepted || delivered,
        }
    }

    /// What a wait that ended ([`Due`]) tells the front end: a resend (the caller sends
    /// the bytes), a TC given up ([`Update::gave_up`]), or nothing (a wait over frames).
    /// The one reading of the commanding book's ticks. `delivered(apid, seq)`: a CLCW
    /// acknowledged the TC's frame (the robot's link, [`crate::link::Link::delivered`] or
    /// [`crate::link::LinkKind::delivered`]): over frames it reached the on-board
    /// software, so given up, like an accepted one, its outcome is asked of the store.
    pub fn of_due(d: &Due, delivered: impl FnOnce(u8, u16, u16) -> bool) -> Option<Update> {
        match d {
            Due::Resend {
                robot, tag, tc, send, ..
            } => Some(Update::Resent {
                robot: *robot,
                tag: *tag,
                tc: tc.def.name,
                send: *send,
            }),
            Due::Waited { .. } => None,
            Due::GaveUp(p) => Some(Update::gave_up(p, delivered(p.robot, p.tc.apid, p.tc.seq))),
        }
    }
}

#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum OpsError {
    #[error("robot {0} has no link (give --robot {0}=HOST:PORT)")]
    NoLink(u8),
    #[error("cannot open link to robot {robot} at {addr}: {err}")]
    Connect {
        robot: u8,
        addr: SocketAddr,
        err: std::io::Error,
    },
    #[error("sending to robot {robot}: {err}")]
    Send { robot: u8, err: std::io::Error },
    #[error(transparent)]
    Build(#[from] pus::BuildError),
    #[error("the MIB has no PING telecommand")]
    NoPing,
}

/// Links to several robots with verification tracking.
pub struct Session {
    links: BTreeMap<u8, Link>,
    rx: Receiver<Incoming>,
    seq: SeqCounters,
    /// The TCs awaited, with the one set of commanding rules ([`TcBook`]).
    book: TcBook,
    archive: Option<ArchiveSender>,
    pub robots: BTreeMap<u8, RobotStatus>,
    /// Resends of a TC after the first send.
    pub max_resends: u32,
    /// Robots' links are watched for loss ([`Session::watch_links`]; the rule is
    /// [`crate::live::LinkWatch`]'s).
    watching: bool,
    /// When each robot last got a new TC (not a resend).
    last_new_tc: HashMap<u8, Instant>,
    /// When each robot's first TM packet was heard ([`Session::awaited_span`]).
    first_heard: HashMap<u8, Instant>,
    /// The span each robot's store was last asked for by time ([`Session::awaited_span`]):
    /// asked once, again only while its packets have not all come.
    spans: HashMap<u8, SpanAsk>,
    /// The run this session's TCs belong to (`ground run`): archived with every TC as
    /// `LABEL@RUN_ID` in the TC's step column (see [`runs`]).
    pub run_id: Option<String>,
}

impl Session {
    /// Opens a link per robot. `first_seq` gives the starting sequence count per APID
    /// (e.g. from the archive), otherwise a time-derived value is used.
    pub fn connect(
        robots: &[(u8, SocketAddr)],
        transport: Transport,
        archive: Option<ArchiveSender>,
        first_seq: impl Fn(u16) -> Option<u16>,
    ) -> Result<Session, OpsError> {
        Session::connect_with(robots, transport, None, archive, first_seq)
    }

    /// [`Session::connect`] with the frame link's options (required for
    /// [`Transport::Frames`]).
    pub fn connect_with(
        robots: &[(u8, SocketAddr)],
        transport: Transport,
        frames: Option<&FrameOptions>,
        archive: Option<ArchiveSender>,
        first_seq: impl Fn(u16) -> Option<u16>,
    ) -> Result<Session, OpsError> {
        let (tx, rx) = crossbeam_channel::unbounded();
        let mut links = BTreeMap::new();
        let mut status = BTreeMap::new();
        let mut seq = SeqCounters::new();
        for &(robot, addr) in robots {
            let apid = mib::apid::robot_apid(robot).ok_or(pus::BuildError::UnknownRobot(robot))?;
            let link = Link::open_with(robot, addr, transport, frames, tx.clone())
                .map_err(|err| OpsError::Connect { robot, addr, err })?;
            links.insert(robot, link);
            status.insert(robot, RobotStatus::new(robot, addr));
            seq.set(apid, first_seq(apid).unwrap_or_else(|| first_tc_seq(None)));
        }
        Ok(Session {
            links,
            rx,
            seq,
            book: TcBook::default(),
            archive,
            robots: status,
            max_resends: TC_RETRY_MAX,
            watching: false,
            last_new_tc: HashMap::new(),
            first_heard: HashMap::new(),
            spans: HashMap::new(),
            run_id: None,
        })
    }

    /// First wait for a report before a TC is resent (later waits grow, see
    /// `mib::ground_config::tc_retry_wait_ms`): the commanding book's.
    pub fn ack_timeout(&self) -> Duration {
        self.book.first_wait
    }

    /// Sets [`Session::ack_timeout`].
    pub fn set_ack_timeout(&mut self, wait: Duration) {
        self.book.first_wait = wait;
    }

    /// Builds and sends a TC; verification reports come back through [`Session::poll`]
    /// with `tag`.
    pub fn send(
        &mut self,
        robot: u8,
        def: &'static TcDef,
        args: &[i64],
        tag: Option<usize>,
        label: Option<String>,
    ) -> Result<BuiltTc, OpsError> {
        self.send_limited(robot, def, args, tag, label, None)
    }

    /// The next sequence count of `robot`'s APID, used up: for a TC the robot will run from
    /// its on-board plan (the ground tracks its reports under that request ID).
    pub fn next_seq(&mut self, robot: u8) -> Option<u16> {
        mib::apid::robot_apid(robot).map(|apid| self.seq.next(apid))
    }

    /// Archives `tc` as sent for step `label` without sending it: a step TC that travels
    /// inside an on-board plan (so that `--resume` finds the run's steps and outcomes).
    pub fn archive_tc(&self, tc: &BuiltTc, label: &str) {
        if let Some(a) = &self.archive {
            a.send(Record::Tc {
                t_ms: now_ms(),
                tc: tc.clone(),
                step: Some(label.to_string()),
                attempt: 1,
            });
        }
    }

    /// Builds and sends a TC whose application data continues after its fixed arguments
    /// with `tail` (a TC with variable data, such as PLAN_LOAD's image bytes); tracked and
    /// resent like [`Session::send`].
    pub fn send_with_tail(
        &mut self,
        robot: u8,
        def: &'static TcDef,
        args: &[i64],
        tail: &[u8],
        label: Option<String>,
    ) -> Result<BuiltTc, OpsError> {
        let link = self.links.get(&robot).ok_or(OpsError::NoLink(robot))?;
        let apid = mib::apid::robot_apid(robot).ok_or(pus::BuildError::UnknownRobot(robot))?;
        pus::build_tc(robot, 0, def, args)?;
        let mut tc = pus::build_tc(robot, self.seq.next(apid), def, args)?;
        // Fixed arguments as built (after the 6 + 5 header bytes, before the CRC), then the tail.
        let mut app = tc.bytes[11..tc.bytes.len() - 2].to_vec();
        app.extend_from_slice(tail);
        tc.bytes = pus::build_raw_tc(apid, tc.seq, def.service, def.subservice, pus::ack_flags_for(def), &app)?;
        link.send(&tc.bytes).map_err(|err| OpsError::Send { robot, err })?;
        self.last_new_tc.insert(robot, Instant::now());
        if let Some(a) = &self.archive {
            a.send(Record::Tc {
                t_ms: now_ms(),
                tc: tc.clone(),
                step: runs::archived_label(label.as_deref(), self.run_id.as_deref()),
                attempt: 1,
            });
        }
        let mut p = Pending::sent(robot, tc.clone(), None, label, Instant::now());
        p.max_sends = self.max_resends + 1;
        p.tm_seq_at_send = self.robots.get(&robot).and_then(|s| s.seq.newest());
        self.book.insert(p);
        Ok(tc)
    }

    /// Sends a connection test that is not resent (a heartbeat: the next one follows).
    pub fn send_heartbeat(&mut self, robot: u8) -> Result<BuiltTc, OpsError> {
        let def = mib::tc::by_name("PING").ok_or(OpsError::NoPing)?;
        self.send_limited(robot, def, &[], None, Some("heartbeat".into()), Some(1))
    }

    fn send_limited(
        &mut self,
        robot: u8,
        def: &'static TcDef,
        args: &[i64],
        tag: Option<usize>,
        label: Option<String>,
        max_sends: Option<u32>,
    ) -> Result<BuiltTc, OpsError> {
        let link = self.links.get(&robot).ok_or(OpsError::NoLink(robot))?;
        let apid = mib::apid::robot_apid(robot).ok_or(pus::BuildError::UnknownRobot(robot))?;
        // Check the arguments before using up a sequence count.
        pus::build_tc(robot, 0, def, args)?;
        let tc = pus::build_tc(robot, self.seq.next(apid), def, args)?;
        let tm_seq_at_send = self.robots.get(&robot).and_then(|s| s.seq.newest());
        link.send(&tc.bytes).map_err(|err| OpsError::Send { robot, err })?;
        self.last_new_tc.insert(robot, Instant::now());
        if let Some(a) = &self.archive {
            a.send(Record::Tc {
                t_ms: now_ms(),
                tc: tc.clone(),
                step: runs::archived_label(label.as_deref(), self.run_id.as_deref()),
                attempt: 1,
            });
        }
        let mut p = Pending::sent(robot, tc.clone(), tag, label, Instant::now());
        p.max_sends = max_sends.unwrap_or(self.max_resends + 1);
        p.tm_seq_at_send = tm_seq_at_send;
        self.book.insert(p);
        Ok(tc)
    }

    /// Tracks a TC that an earlier, interrupted session of the same run sent (same
    /// request ID), without sending it again: its reports, live or replayed from the
    /// on-board store, come back through [`Session::poll`] with `tag`. It is never resent.
    pub fn adopt(&mut self, robot: u8, tc: BuiltTc, tag: Option<usize>, label: Option<String>, accepted: bool) {
        // Sent by an earlier session: its reports may be anywhere in the store
        // (`tm_seq_at_send` unknown); never resent.
        self.book.insert(Self::adopted(robot, tc, tag, label, accepted));
    }

    /// Tracks a step TC of an on-board plan this session is about to upload and start
    /// (never sent by the ground): its reports come after the TM heard so far, so the gaps
    /// after it are where they are, and the live gap check asks for those first (without
    /// this, a run through a lossy link asked for the oldest HK gaps one a period and a
    /// step's lost completion waited out its timeout).
    pub fn adopt_new(&mut self, robot: u8, tc: BuiltTc, tag: Option<usize>, label: Option<String>) {
        let mut p = Self::adopted(robot, tc, tag, label, false);
        p.tm_seq_at_send = self.robots.get(&robot).and_then(|s| s.seq.newest());
        self.book.insert(p);
    }

    fn adopted(robot: u8, tc: BuiltTc, tag: Option<usize>, label: Option<String>, accepted: bool) -> Pending {
        let mut p = Pending::sent(robot, tc, tag, label, Instant::now());
        p.accepted = accepted;
        p.max_sends = 1;
        p.exhausted = true;
        p
    }

    /// True if the TC with this request ID is still waiting for its outcome.
    pub fn is_pending(&self, tc: &BuiltTc) -> bool {
        self.book.contains(tc)
    }

    /// Whether the TC with this request ID was accepted (`None`: not tracked).
    pub fn accepted(&self, tc: &BuiltTc) -> Option<bool> {
        self.book.get(tc.apid, tc.seq).map(|p| p.accepted)
    }

    /// True if a CLCW acknowledged the TC's frame (frame links only): COP-1 delivered it.
    pub fn delivered(&self, robot: u8, tc: &BuiltTc) -> bool {
        self.links.get(&robot).is_some_and(|l| l.delivered(tc.apid, tc.seq))
    }

    /// True if a TC of `robot` is still waiting for acceptance or completion.
    pub fn busy(&self, robot: u8) -> bool {
        self.book.values().any(|p| p.robot == robot)
    }

    /// True if a TC of `robot` other than a heartbeat is waiting for its outcome.
    pub fn commanding(&self, robot: u8) -> bool {
        self.book.values().any(|p| p.robot == robot && p.max_sends > 1)
    }

    /// Forgets a pending TC (e.g. after its step timed out).
    pub fn forget(&mut self, tc: &BuiltTc) {
        self.book.forget(tc);
    }

    /// Waits up to `max_wait` for traffic; handles resends. Returns what happened.
    pub fn poll(&mut self, max_wait: Duration) -> Vec<Update> {
        let mut out = Vec::new();
        let deadline = Instant::now() + max_wait;
        loop {
            let now = Instant::now();
            let next_resend = self.book.next_due();
            let until = next_resend.map_or(deadline, |r| r.min(deadline));
            let until = until.min(now + Duration::from_millis(100));
            let wait = until.saturating_duration_since(now);
            match self.rx.recv_timeout(wait) {
                Ok(inc) => {
                    self.handle(inc, &mut out);
                    // Drain what is already there without waiting.
                    while let Ok(inc) = self.rx.try_recv() {
                        self.handle(inc, &mut out);
                    }
                }
                Err(crossbeam_channel::RecvTimeoutError::Timeout) => {}
                Err(crossbeam_channel::RecvTimeoutError::Disconnected) => {
                    std::thread::sleep(wait);
                }
            }
            self.check_resends(&mut out);
            self.check_links(&mut out);
            self.keep_subscribed();
            if !out.is_empty() || Instant::now() >= deadline {
                return out;
            }
        }
    }

    /// Link loss: a closed TCP connection, or nothing heard (no TM, over frames no valid
    /// frame) for the link-loss time ([`crate::live::LinkWatch`], the rule of every front
    /// end).
    fn check_links(&mut self, out: &mut Vec<Update>) {
        // The silence is known up to when each link's reader last came back from its
        // socket (`Link::listened_ms`, read first), with what it had read by then taken
        // from the channel: a ground that was not scheduled does not call the robot silent
        // for its own stall (`LinkWatch::on_listened`).
        let listened: Vec<(u8, Option<i64>)> = self.links.iter().map(|(r, l)| (*r, l.listened_ms())).collect();
        while let Ok(inc) = self.rx.try_recv() {
            self.handle(inc, out);
        }
        for (r, t) in listened {
            if let Some(s) = self.robots.get_mut(&r) {
                // Before its reader's first read nothing is known of the silence.
                let t = t.unwrap_or(s.link.since_ms());
                s.link.on_listened(t);
            }
        }
        self.hear_frames();
        if !self.watching {
            return;
        }
        let now = now_ms();
        let mut lost = Vec::new();
        for (robot, s) in self.robots.iter_mut() {
            if s.lost.is_some() {
                continue;
            }
            let closed = self.links.get(robot).is_some_and(|l| l.closed());
            // Replies with another APID and none with ours: the wrong robot, said at once.
            let wrong = s.link.last_heard_ms().is_none() && s.foreign_apid.is_some();
            let loss = match s.link.tick(now, closed || wrong) {
                Some(loss) => loss,
                None => continue,
            };
            let (kind, why) = s.no_answer_after(live::LinkLoss { closed, ..loss });
            s.lost_kind = Some(kind);
            s.lost = Some(why.clone());
            out.push(Update::LinkLost { robot: *robot, why });
            lost.push(*robot);
        }
        // Nothing more is resent to a robot that does not answer; its steps end with the
        // link loss.
        self.book.retain(|p| !lost.contains(&p.robot));
    }

    /// Over a UDP lab link a robot sends TM only to a ground whose TC it accepted: until it
    /// does, a watched robot gets a heartbeat every
    /// [`mib::ground_config::SUBSCRIBE_RETRY_MS`] (the rule of every front end,
    /// [`crate::live::Subscription`]). A robot that does not answer is still lost in the
    /// link-loss time, and then no longer retried.
    fn keep_subscribed(&mut self) {
        if !self.watching {
            return;
        }
        let due: Vec<u8> = self
            .robots
            .iter()
            .filter(|(r, s)| {
                let since = self.last_new_tc.get(r).map(|t| t.elapsed().as_millis() as i64);
                let subscribes = self.links.get(r).is_some_and(Link::subscribes);
                s.subscription.retry_due(subscribes, s.lost.is_some(), since)
            })
            .map(|(r, _)| *r)
            .collect();
        for r in due {
            // A failed send shows as silence: the link-loss check reports it.
            let _ = self.send_heartbeat(r);
        }
    }

    /// Over frames, the robots are heard while their valid TM frames arrive
    /// ([`Link::last_heard_ms`]), whatever happens to their packets.
    fn hear_frames(&mut self) {
        for (robot, s) in self.robots.iter_mut() {
            if let Some(t) = self.links.get(robot).and_then(Link::last_heard_ms) {
                s.link.on_heard(t);
            }
        }
    }

    /// Whether `robot` was heard (TM, or over frames a valid frame) within the link-loss
    /// time: it answers, whatever became of a TC's reports.
    pub fn heard_recently(&mut self, robot: u8) -> bool {
        self.hear_frames();
        self.robots
            .get(&robot)
            .is_some_and(|s| s.link.heard_within_loss_time(now_ms()))
    }

    /// What COP-1 did on `robot`'s frame link (`None`: a bare-packet link).
    pub fn frame_stats(&self, robot: u8) -> Option<FrameStats> {
        self.links.get(&robot).and_then(Link::frame_stats)
    }

    /// True if the links carry frames (COP-1 delivers; no packet resends).
    pub fn over_frames(&self) -> bool {
        self.links.values().any(|l| !l.resends_packets())
    }

    /// True if `robot` got a new TC within `period` (its answers check the link as a
    /// heartbeat would).
    pub fn sent_within(&self, robot: u8, period: Duration) -> bool {
        self.last_new_tc.get(&robot).is_some_and(|t| t.elapsed() < period)
    }

    /// True while a store retrieval of `robot` is in flight: the pacing rule of every
    /// front end ([`crate::live::RetrievalPacer`]: until its end report, its TC's outcome
    /// or [`mib::ground_config::STORE_REQUEST_TIMEOUT_MS`]).
    pub fn retrieving(&self, robot: u8) -> bool {
        self.robots.get(&robot).is_some_and(|s| s.pacer.in_flight(now_ms()))
    }

    /// True if a store retrieval of `robot` may go now ([`crate::live::RetrievalPacer`]:
    /// none in flight, the last at least [`mib::ground_config::STORE_REQUEST_MIN_GAP_MS`] ago).
    pub fn may_retrieve(&self, robot: u8) -> bool {
        self.robots.get(&robot).is_some_and(|s| s.pacer.may_send(now_ms()))
    }

    /// Asks `robot`'s on-board store first for the TM missing since its oldest TC still
    /// waiting for an outcome went out (that TC's reports are among it): by time for the
    /// span before the first TM heard ([`Session::awaited_span`]; once, again only while
    /// its packets have not all come, [`SpanAsk`]), by count for the holes after it, at
    /// most `max_ranges` ranges; with no such TC or no such gap, for the
    /// oldest missing TM ([`Session::request_gaps`]). Nothing while the pacing rule holds
    /// the next retrieval back ([`Session::may_retrieve`]). Returns the ranges asked for.
    pub fn request_missing_reports(&mut self, robot: u8, max_ranges: usize) -> Vec<(u16, u16)> {
        // A span asked before is asked again only while its packets have not all come
        // ([`SpanAsk::wanted`]): each ask replays all of it.
        let span = self
            .awaited_span(robot)
            .filter(|&(from, to)| self.spans.get(&robot).is_none_or(|a| !a.covers(from, to) || a.wanted()));
        let ranges = self.awaited_gaps(robot);
        if ranges.is_empty() && span.is_none() {
            return self.request_gaps(robot, None, max_ranges);
        }
        self.send_retrievals(robot, span, ranges, max_ranges)
    }

    /// Asks `robot`'s on-board store first for the TM missing since `tc` went out, where
    /// its reports are (oldest first, at most `max_ranges` ranges); with none missing
    /// there, as [`Session::request_missing_reports`]. For a TC awaited on its own (the
    /// on-board plan's upload and start): behind the older TCs the book tracks (the
    /// plan's step TCs, from the upload on) its lost completion waited for every gap since
    /// them, asked a range a period, and through the 20/5/5 lab relay a PLAN_START's
    /// completion was still not asked for after 30 s. Nothing while the pacing rule holds
    /// the next retrieval back.
    pub fn request_reports_of(&mut self, robot: u8, tc: &BuiltTc, max_ranges: usize) -> Vec<(u16, u16)> {
        let since = self.book.get(tc.apid, tc.seq).and_then(|p| p.tm_seq_at_send);
        let ranges = match (since, self.robots.get(&robot)) {
            (Some(from), Some(st)) => st.seq.missing_after(from),
            _ => Vec::new(),
        };
        if ranges.is_empty() {
            return self.request_missing_reports(robot, max_ranges);
        }
        self.send_retrievals(robot, None, ranges, max_ranges)
    }

    /// The on-board time span (Unix ms, inclusive) between `robot`'s oldest TC still
    /// waiting for an outcome that went out before any of its TM was heard, and the first
    /// TM heard: the TC's reports are there or after it. Nothing tells their counts (the
    /// robot's count at the send is unknown), so the span is bounded by time: the robot
    /// got the TC after it went out and sent the first packet heard before it arrived, so
    /// on its clock the TC came at least the ground's time between the two before that
    /// packet's time stamp. `None` if no such TC waits.
    pub fn awaited_span(&self, robot: u8) -> Option<(i64, i64)> {
        let heard_at = *self.first_heard.get(&robot)?;
        let first = self.robots.get(&robot)?.seq.first()?;
        let sent = self
            .book
            .values()
            .filter(|p| p.robot == robot && p.label.as_deref() != Some(GAP_LABEL))
            .filter(|p| p.tm_seq_at_send.is_none() && p.first_sent <= heard_at)
            .map(|p| p.first_sent)
            .min()?;
        // Rounded up to whole ms, one more for the time stamp's truncation.
        let before_ms =
            i64::try_from(heard_at.saturating_duration_since(sent).as_micros().div_ceil(1000)).unwrap_or(i64::MAX / 4);
        Some((first.obt_ms - before_ms - 1, first.obt_ms))
    }

    /// TM missing since `robot`'s oldest TC still waiting for an outcome went out (where
    /// its reports are), oldest first; empty if none waits or nothing is missing.
    pub fn awaited_gaps(&self, robot: u8) -> Vec<(u16, u16)> {
        // A TC sent before anything was heard: its reports after the first TM heard are
        // holes after it (those before it, [`Session::awaited_span`]).
        let first = self.robots.get(&robot).and_then(|s| s.seq.first()).map(|p| p.seq);
        let heard_at = self.first_heard.get(&robot).copied();
        let since = self
            .book
            .values()
            .filter(|p| p.robot == robot && p.label.as_deref() != Some(GAP_LABEL))
            .filter_map(|p| {
                let unheard = first.filter(|_| heard_at.is_some_and(|t| p.first_sent <= t));
                p.tm_seq_at_send.or(unheard).map(|s| (p.first_sent, s))
            })
            .min()
            .map(|(_, s)| s);
        match (since, self.robots.get(&robot)) {
            (Some(from), Some(st)) => st.seq.missing_after(from),
            _ => Vec::new(),
        }
    }

    /// Asks `robot`'s on-board store for every missing TM at or before `cutoff` (all
    /// missing if `None`), by APID and sequence range (TC[15,128]); at most
    /// `GAP_REQUESTS_MAX` ranges at a time. Returns the ranges asked for.
    pub fn request_gaps(&mut self, robot: u8, cutoff: Option<u16>, max_ranges: usize) -> Vec<(u16, u16)> {
        let Some(st) = self.robots.get(&robot) else {
            return Vec::new();
        };
        let ranges = match cutoff.or(st.seq.newest()) {
            Some(c) => st.seq.missing_upto(c),
            None => Vec::new(),
        };
        self.send_retrievals(robot, None, ranges, max_ranges)
    }

    /// The retrievals [`GapPlan`] plans for these gaps (merged, cut, at most
    /// `max_ranges`): one TC[15,128] each for `robot`'s own APID, and a TC[15,9] for the
    /// on-board time `span` (its packets before the first TM heard are then taken,
    /// [`crate::live::ApidTracker::accept_before_first`]), together one retrieval of the
    /// pacing rule, sent only when it lets one go ([`Session::may_retrieve`]). Returns
    /// the ranges asked for.
    fn send_retrievals(
        &mut self,
        robot: u8,
        span: Option<(i64, i64)>,
        ranges: Vec<(u16, u16)>,
        max_ranges: usize,
    ) -> Vec<(u16, u16)> {
        let ranges = GapPlan::default().round(&ranges, max_ranges);
        let Some(def) = mib::tc::by_name("STORE_DOWNLINK_SEQ") else {
            return Vec::new();
        };
        if (ranges.is_empty() && span.is_none()) || !self.may_retrieve(robot) {
            return Vec::new();
        }
        let apid = mib::apid::robot_apid(robot).unwrap_or(0);
        let mut sent = Vec::new();
        if let (Some((from, to)), Some(by_time)) = (span, mib::tc::by_name("STORE_DOWNLINK_TIME")) {
            if let Some(s) = self.robots.get_mut(&robot) {
                s.seq.accept_before_first(from);
            }
            let args = live::store_time_args(from, to);
            let request = self
                .send(robot, by_time, &args, None, Some(GAP_LABEL.into()))
                .ok()
                .map(|tc| tc.request_id());
            sent.extend(request);
            let first = self.robots.get(&robot).and_then(|s| s.seq.first());
            if let Some(first) = first {
                let ask = self
                    .spans
                    .entry(robot)
                    .and_modify(|a| {
                        if !a.covers(from, to) {
                            *a = SpanAsk::new(from, to, (apid, first.seq));
                        }
                    })
                    .or_insert_with(|| SpanAsk::new(from, to, (apid, first.seq)));
                ask.on_asked(request);
            }
        }
        let by_time = mib::tc::by_name("STORE_DOWNLINK_TIME");
        for &(a, b) in &ranges {
            // By the holes' time window where it is known (the tracker's `window`: no
            // older packet with the same counts comes with them), else by count.
            let window = self.robots.get(&robot).and_then(|s| s.seq.window(a, b));
            let (tc_def, args) = match (window, by_time) {
                (Some((from, to)), Some(t)) => (t, live::store_time_args(from, to).to_vec()),
                _ => (def, vec![apid as i64, a as i64, b as i64]),
            };
            // A failed send shows as a retrieval without result: asked again later.
            if let Ok(tc) = self.send(robot, tc_def, &args, None, Some(GAP_LABEL.into())) {
                sent.push(tc.request_id());
            }
        }
        if let Some(s) = self.robots.get_mut(&robot) {
            s.pacer.on_sent(now_ms(), sent);
        }
        ranges
    }

    /// Starts watching every robot's link for loss ([`crate::live::LinkWatch`]: no TM
    /// for [`mib::ground_config::link_loss_ms`] of the robot's status-HK interval).
    pub fn watch_links(&mut self) {
        self.watching = true;
        let now = now_ms();
        for s in self.robots.values_mut() {
            s.link.restart(now);
        }
    }

    fn check_resends(&mut self, out: &mut Vec<Update>) {
        let now = Instant::now();
        // An untagged accepted TC (`send`, a heartbeat) is awaited a little, not forever.
        self.book.retain(|p| {
            p.tag.is_some() || !p.accepted || now.saturating_duration_since(p.last_sent) < UNTAGGED_COMPLETION_WAIT
        });
        let links = &self.links;
        let due = self
            .book
            .on_tick(now, |robot| links.get(&robot).is_some_and(Link::resends_packets));
        for d in due {
            if let Some(r) = self.robots.get_mut(&d.robot()) {
                r.exchange(false);
            }
            out.extend(Update::of_due(&d, |r, apid, seq| {
                links.get(&r).is_some_and(|l| l.delivered(apid, seq))
            }));
            if let Due::Resend {
                robot, tc, label, send, ..
            } = d
            {
                if let Some(link) = self.links.get(&robot) {
                    // A failing send is the same as a lost packet: the next wait retries.
                    let _ = link.send(&tc.bytes);
                }
                if let Some(a) = &self.archive {
                    a.send(Record::Tc {
                        t_ms: now_ms(),
                        tc,
                        step: runs::archived_label(label.as_deref(), self.run_id.as_deref()),
                        attempt: send,
                    });
                }
            }
        }
    }

    fn handle(&mut self, inc: Incoming, out: &mut Vec<Update>) {
        let decoded = pus::decode_tm(&inc.bytes);
        // A packet received again (same APID, sequence count and on-board time) is
        // counted, neither archived nor acted on twice.
        if let (Ok(tm), Some(s)) = (&decoded, self.robots.get_mut(&inc.robot)) {
            if tm.robot == Some(inc.robot) {
                s.link.on_tm(now_ms());
                s.subscription.on_tm(tm);
                if s.seq.first().is_none() {
                    self.first_heard.insert(inc.robot, Instant::now());
                }
                let verdict = s.seq.on_packet(live::position(tm), live::is_boot(tm), now_ms());
                // What the store replays is old: a packet new to the tracker was made
                // after the ask (its own reports, even in the span's last millisecond).
                if let (Some(a), SeqVerdict::Filled | SeqVerdict::Duplicate) = (self.spans.get_mut(&inc.robot), verdict)
                {
                    a.on_packet(tm.apid, tm.seq, tm.time.unix_ms());
                }
                if verdict == SeqVerdict::Duplicate {
                    s.duplicates += 1;
                    s.last_tm = Some(Instant::now());
                    return;
                }
                // The pacing rule's ends of a retrieval (a replayed end report is not one);
                // a span's end report says how many packets it held.
                if let (Some(d), Some(a), true) = (
                    live::store_done(tm),
                    self.spans.get_mut(&inc.robot),
                    verdict != SeqVerdict::Filled,
                ) {
                    a.on_end_report(s.pacer.oldest_open(), d.packets);
                }
                s.pacer.on_tm(tm, verdict != SeqVerdict::Filled);
            }
        }
        if let Some(a) = &self.archive {
            a.send(Record::Tm {
                t_ms: inc.t_ms,
                link_robot: Some(inc.robot),
                raw: inc.bytes,
                decoded: decoded.clone(),
            });
        }
        let robot = inc.robot;
        let st = self.robots.get_mut(&robot);
        let tm = match decoded {
            Ok(tm) => tm,
            Err(error) => {
                if let Some(s) = st {
                    s.corrupt += 1;
                }
                out.push(Update::Corrupt { robot, error });
                return;
            }
        };
        if let Some(s) = st {
            s.tm_count += 1;
            if tm.robot == Some(robot) {
                s.last_tm = Some(Instant::now());
            }
            if tm.robot != Some(robot) && tm.apid != mib::apid::IDLE_APID {
                s.foreign += 1;
                s.foreign_apid = Some(tm.apid);
                out.push(Update::Foreign {
                    robot,
                    apid: tm.apid,
                    service: tm.service,
                    subservice: tm.subservice,
                });
                return;
            }
        }
        match tm.body {
            TmBody::Verification(v) => {
                if let Some(p) = self
                    .book
                    .get(v.request.apid(), v.request.seq())
                    .filter(|p| p.label.as_deref() == Some(START_LABEL))
                {
                    // A start marker's reports follow each other on board: TM[1,1] has
                    // the first count of the run, TM[1,7] two more (TM[17,2] between).
                    let first = match v.stage {
                        Stage::Acceptance => Some(tm.seq),
                        Stage::Completion => Some(SeqCount::new(tm.seq).prev().prev().get()),
                        Stage::Start | Stage::Progress => None,
                    };
                    if let (Some(f), Some(s)) = (first, self.robots.get_mut(&p.robot)) {
                        s.run_first_seq.get_or_insert(f);
                    }
                }
                let lab = self.links.get(&robot).is_some_and(Link::resends_packets);
                match self.book.on_verification(robot, &v, Instant::now(), lab) {
                    Verdict::DamagedCopy { robot, tag, tc, resend } => {
                        if let (Some(bytes), Some(link)) = (resend, self.links.get(&robot)) {
                            let _ = link.send(&bytes);
                        }
                        out.push(Update::DamagedCopy { robot, tag, tc });
                    }
                    Verdict::Report {
                        robot: r,
                        tag,
                        tc,
                        after,
                        newly_accepted,
                        finished: _,
                    } => {
                        if newly_accepted {
                            if let Some(s) = self.robots.get_mut(&r) {
                                s.exchange(true);
                            }
                        }
                        out.push(Update::Verification {
                            robot,
                            tag,
                            tc: Some(tc),
                            v,
                            after: Some(after),
                            at_ms: Some(tm.time.unix_ms()),
                        });
                    }
                    Verdict::Unknown => out.push(Update::Verification {
                        robot,
                        tag: None,
                        tc: None,
                        v,
                        after: None,
                        at_ms: Some(tm.time.unix_ms()),
                    }),
                }
            }
            TmBody::Report(ref r) => {
                if let Some(s) = self.robots.get_mut(&robot) {
                    match r.as_ref() {
                        mib_wire::Tm::StoreDownlinkDone(d) => {
                            s.store_overwritten = d.overwritten;
                            // Holes older than what the store holds are gone (the rule of
                            // every front end).
                            if let Some(oldest) = live::store_done(&tm).and_then(|d| d.oldest) {
                                s.store_oldest = Some(oldest);
                                s.seq.store_oldest(oldest);
                            }
                        }
                        mib_wire::Tm::ModeReply(m) if m.node == mib::modes::node::ROBOT => s.mode = Some(m.mode),
                        // The other reports change nothing the session follows.
                        _ => {}
                    }
                }
                out.push(Update::Tm {
                    robot,
                    tm: Tm { body: tm.body, ..tm },
                });
            }
            TmBody::Hk(hk) => {
                if hk.sid == mib::hk::sid::ROBOT_STATUS {
                    if let Some(s) = self.robots.get_mut(&robot) {
                        s.mode = hk.raw(pid::MODE).map(|m| m as u32);
                        s.state = hk
                            .raw(pid::CONFIG_STATE)
                            .filter(|&v| v != mib::robot::STATE_UNKNOWN as i64)
                            .map(|v| v as u8);
                        s.target = hk
                            .raw(pid::TARGET_STATE)
                            .filter(|&v| v != mib::robot::STATE_UNKNOWN as i64)
                            .map(|v| v as u8);
                        s.battery_v = hk.eng(pid::V_BAT_A);
                    }
                }
                out.push(Update::Hk { robot, hk });
            }
            TmBody::Event(event) => {
                if let Some(s) = self.robots.get_mut(&robot) {
                    if event.id == eid::MODE_CHANGED && event.param("node") == Some(mib::modes::node::ROBOT as i64) {
                        s.mode = event.param("to").map(|m| m as u32);
                    }
                    if event.id == eid::STATE_REACHED {
                        s.state = event.param("state").map(|v| v as u8);
                    }
                }
                out.push(Update::Event { robot, event });
            }
            body => out.push(Update::Tm {
                robot,
                tm: Tm { body, ..tm },
            }),
        }
    }
}

/// Words for a verification failure.
pub fn failure_words(v: &Verification) -> String {
    match &v.failure {
        Some(f) => format!("{} failed: {f}", v.stage.name()),
        None => format!("{} failed", v.stage.name()),
    }
}
