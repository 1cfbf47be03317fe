//! What one robot looks like from the ground, and the three ways it does not answer.

use std::collections::VecDeque;
use std::net::SocketAddr;
use std::time::Instant;

use mib::ground_config::LINK_QUALITY_WINDOW;
use serde::Serialize;

use crate::live::{ApidTracker, LinkLoss, LinkWatch, RetrievalPacer};
use crate::plan::state_name;
use crate::pus;

/// What one robot looks like from the ground.
#[derive(Clone, Debug)]
pub struct RobotStatus {
    pub robot: u8,
    pub addr: SocketAddr,
    pub mode: Option<u32>,
    pub state: Option<u8>,
    /// Last commanded target state (HK `TARGET_STATE`), shown while moving.
    pub target: Option<u8>,
    pub battery_v: Option<f64>,
    pub tm_count: u64,
    pub corrupt: u64,
    /// TM on this robot's link with another robot's APID (archived, not used).
    pub foreign: u64,
    /// Outcome of the last exchanges (TC sent → acceptance within the timeout).
    pub quality: VecDeque<bool>,
    /// When the last TM with this robot's APID came (shown; the link's state is
    /// [`RobotStatus::link`]'s).
    pub last_tm: Option<Instant>,
    /// APID of the last TM with another robot's APID on this link.
    pub foreign_apid: Option<u16>,
    /// TM packets received again (same APID and sequence count): dropped, counted.
    pub duplicates: u64,
    /// Sequence-count tracking of this robot's APID: the tracker of every front end.
    pub seq: ApidTracker,
    /// Is the link up? The link-loss rule of every front end.
    pub link: LinkWatch,
    /// Is a store retrieval in flight, may the next go? The pacing rule of every front end.
    pub pacer: RetrievalPacer,
    /// Why the link counts as lost (latched).
    pub lost: Option<String>,
    /// Which of the "robot does not answer" cases it was (latched with `lost`).
    pub lost_kind: Option<NoAnswer>,
    /// First TM sequence count of the run (from the start marker's reports).
    pub run_first_seq: Option<u16>,
    /// Sequence count and on-board time of the oldest packet in the on-board store (last
    /// TM[15,19]).
    pub store_oldest: Option<crate::live::Pos>,
    /// Stored packets overwritten on board since boot (last TM[15,19]).
    pub store_overwritten: u32,
    /// Over a UDP lab link, does the robot send to this ground? The re-subscription rule
    /// of every front end ([`crate::live::Subscription`]).
    pub subscription: crate::live::Subscription,
}

impl RobotStatus {
    pub(crate) fn new(robot: u8, addr: SocketAddr) -> Self {
        RobotStatus {
            robot,
            addr,
            mode: None,
            state: None,
            target: None,
            battery_v: None,
            tm_count: 0,
            corrupt: 0,
            foreign: 0,
            quality: VecDeque::with_capacity(LINK_QUALITY_WINDOW),
            last_tm: None,
            foreign_apid: None,
            duplicates: 0,
            seq: ApidTracker::new(),
            link: LinkWatch::at_mib_interval(crate::archive::now_ms()),
            pacer: RetrievalPacer::default(),
            lost: None,
            lost_kind: None,
            run_first_seq: None,
            store_oldest: None,
            store_overwritten: 0,
            subscription: crate::live::Subscription::default(),
        }
    }

    pub(crate) fn exchange(&mut self, ok: bool) {
        if self.quality.len() == LINK_QUALITY_WINDOW {
            self.quality.pop_front();
        }
        self.quality.push_back(ok);
    }
    /// Success rate over the last `LINK_QUALITY_WINDOW` exchanges (0..=1).
    pub fn link_quality(&self) -> Option<f64> {
        if self.quality.is_empty() {
            None
        } else {
            Some(self.quality.iter().filter(|&&b| b).count() as f64 / self.quality.len() as f64)
        }
    }
    pub fn mode_name(&self) -> String {
        self.mode
            .map_or_else(|| "?".into(), |m| pus::mode_name(mib::modes::node::ROBOT, m))
    }
    pub fn state_name(&self) -> String {
        match (self.state, self.target) {
            (Some(s), _) => state_name(s),
            (None, Some(t)) => format!("moving to {}", state_name(t)),
            (None, None) => "?".into(),
        }
    }
    /// Which "does not answer" case a robot that stopped answering is in, with the
    /// operator's message and the silence measured now. `closed`: its TCP connection
    /// closed. `None` while the robot was heard (TM, or over frames a valid frame) within
    /// the link-loss time: it answers, so it is not lost (a TC without reports is then a
    /// timeout, [`RobotStatus::no_report`]).
    pub fn no_answer(&self, closed: bool) -> Option<(NoAnswer, String)> {
        let now = crate::archive::now_ms();
        if !closed && self.link.heard_within_loss_time(now) {
            return None;
        }
        Some(self.no_answer_after(LinkLoss {
            silent_ms: self.link.silence_ms(now),
            never_heard: self.link.last_heard_ms().is_none(),
            closed,
        }))
    }

    /// A TC (`what`) without the report awaited while the robot answers (heard within the
    /// link-loss time): the operator's message, with when it was last heard.
    pub fn no_report(&self, what: &str) -> String {
        let now = crate::archive::now_ms();
        format!(
            "robot {}: {what}, though the robot answers (last heard {:.1} s ago: link up)",
            self.robot,
            self.link.silence_ms(now).max(0) as f64 / 1000.0
        )
    }

    /// [`RobotStatus::no_answer`] for a loss [`LinkWatch::tick`] found.
    pub fn no_answer_after(&self, loss: LinkLoss) -> (NoAnswer, String) {
        let robot = self.robot;
        let apid = mib::apid::robot_apid(robot).unwrap_or(0);
        let addr = self.addr;
        let secs = loss.silent_ms as f64 / 1000.0;
        match (loss.never_heard, self.foreign_apid) {
            (true, Some(f)) => (
                NoAnswer::OtherApid(f),
                format!(
                    "robot {robot}: the replies from {addr} carry APID 0x{f:03X}{}, not robot {robot}'s 0x{apid:03X}: another robot answers at this address",
                    mib::apid::apid_robot(f).map_or(String::new(), |r| format!(" (robot {r})"))
                ),
            ),
            (true, None) if loss.closed => (
                NoAnswer::NothingHeard,
                format!("robot {robot}: nothing heard from {addr}: the TCP connection closed before any TM (no OBSW there?)"),
            ),
            (true, None) => (
                NoAnswer::NothingHeard,
                format!(
                    "robot {robot}: nothing heard from {addr} in {secs:.1} s (no OBSW running there, wrong address, or link down)"
                ),
            ),
            (false, _) if loss.closed => (
                NoAnswer::Lost,
                format!("robot {robot}: heard, then lost: the OBSW at {addr} closed the TCP connection"),
            ),
            (false, _) => (
                NoAnswer::Lost,
                format!("robot {robot}: heard, then lost: nothing heard from {addr} for {secs:.1} s (no TM, no valid frame: link down or OBSW stopped)"),
            ),
        }
    }

    /// One-line status.
    pub fn line(&self) -> String {
        format!(
            "mode {} | state {} | battery {} | link {}",
            self.mode_name(),
            self.state_name(),
            self.battery_v.map_or_else(|| "?".into(), |v| format!("{v:.2} V")),
            self.link_quality().map_or_else(
                || "-".into(),
                |q| format!("{:.0}% of {}", q * 100.0, self.quality.len())
            )
        )
    }
}

/// The three ways a robot does not answer, the same for every verb (`run`, `send`,
/// `mode`, `ping`, `watch`); each has its own exit code (docs/operator-guide.md): 5 heard
/// then lost (the link-loss code), 7 another APID, 8 nothing heard.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub enum NoAnswer {
    /// Nothing at all heard from the robot's address within the link-loss time
    /// ([`mib::ground_config::link_loss_ms`]).
    NothingHeard,
    /// Replies came, but only with another APID (another robot at that address):
    /// reported at the first such reply.
    OtherApid(u16),
    /// Heard, then no TM for the link-loss time (or its TCP connection closed).
    Lost,
}

impl NoAnswer {
    /// The exit code of this case.
    pub fn exit_code(self) -> u8 {
        match self {
            NoAnswer::Lost => 5,
            NoAnswer::OtherApid(_) => 7,
            NoAnswer::NothingHeard => 8,
        }
    }
}
