//! Is the link up? The one link-loss rule of every front end.
//!
//! A robot is **heard** when a TM packet of its APID arrives or, over the space link, a
//! valid TM frame (CRC, SCID and SDLS checked; idle frames with only a CLCW included:
//! [`crate::link::Link::last_heard_ms`]). The robot sends a frame at least every
//! `mib::link::cop1::CLCW_REPORT_INTERVAL_MS` (100 ms), so on a lossy link the frames
//! prove it is there long after its packets stop getting through; judging by packets alone
//! (HK at 1 Hz) called a live robot lost whenever two or three HK reports in a row were
//! lost. Lost means nothing heard for the loss time, and the loss states that silence.

use serde::Serialize;

/// Link state shown to operators.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum LinkState {
    /// Not heard since watching started.
    #[default]
    Connecting,
    Up,
    /// Lost: nothing heard (no TM, no valid frame) for the loss time
    /// ([`LinkWatch::loss_after_ms`]), or the connection closed.
    Lost,
}

impl LinkState {
    pub fn name(self) -> &'static str {
        match self {
            LinkState::Connecting => "connecting",
            LinkState::Up => "up",
            LinkState::Lost => "LOST",
        }
    }
}

/// A link found lost by [`LinkWatch::tick`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LinkLoss {
    /// Time with nothing heard (ms): since the last TM or valid frame, or since watching
    /// started.
    pub silent_ms: i64,
    /// Nothing was heard since watching started.
    pub never_heard: bool,
    /// The connection closed (not a silence).
    pub closed: bool,
}

/// One robot's link: up while it is heard (TM, or valid frames over the space link), lost
/// after [`mib::ground_config::link_loss_ms`] of the robot's status-HK interval with nothing
/// heard (or when its connection closes). Pure: the caller passes the time (ms, any clock
/// that does not go back).
#[derive(Clone, Debug)]
pub struct LinkWatch {
    state: LinkState,
    loss_after_ms: i64,
    /// When watching (re)started: the silence of a link never heard counts from here.
    since_ms: i64,
    last_heard_ms: Option<i64>,
    /// Up to when the front end listened (its link's reader last came back from the socket
    /// with everything read by then handed on: `crate::link::Link::listened_ms`); `None`:
    /// up to the time passed in.
    listened_ms: Option<i64>,
}

impl LinkWatch {
    /// Watches from `now_ms` a robot whose status HK comes every `hk_interval_ms`.
    pub fn new(hk_interval_ms: u32, now_ms: i64) -> LinkWatch {
        LinkWatch {
            state: LinkState::Connecting,
            loss_after_ms: i64::from(mib::ground_config::link_loss_ms(hk_interval_ms)),
            since_ms: now_ms,
            last_heard_ms: None,
            listened_ms: None,
        }
    }

    /// [`LinkWatch::new`] at the MIB's default interval of the robot's status HK (what a
    /// robot sends unless a ground changed it).
    pub fn at_mib_interval(now_ms: i64) -> LinkWatch {
        LinkWatch::new(mib_status_hk_interval_ms(), now_ms)
    }

    /// Never reports a loss sooner than `floor_ms` (an operator's choice for a link known
    /// to pause, e.g. the collector's `loss_timeout_ms`); the rule's own floor stays.
    pub fn with_floor(mut self, floor_ms: u64) -> LinkWatch {
        self.loss_after_ms = self.loss_after_ms.max(i64::try_from(floor_ms).unwrap_or(i64::MAX));
        self
    }

    /// Nothing heard for longer than this (ms) is a loss.
    pub fn loss_after_ms(&self) -> i64 {
        self.loss_after_ms
    }

    pub fn state(&self) -> LinkState {
        self.state
    }

    /// When the robot was last heard: TM or valid frame (`None`: never since watching
    /// started).
    pub fn last_heard_ms(&self) -> Option<i64> {
        self.last_heard_ms
    }

    /// When watching started.
    pub fn since_ms(&self) -> i64 {
        self.since_ms
    }

    /// A TM of this robot arrived. Returns the state it left when the link came up
    /// (`Some(Connecting)` or `Some(Lost)`), `None` if it was up.
    pub fn on_tm(&mut self, now_ms: i64) -> Option<LinkState> {
        self.last_heard_ms = Some(now_ms);
        let was = self.state;
        self.state = LinkState::Up;
        (was != LinkState::Up).then_some(was)
    }

    /// The link says the robot was heard at `t_ms` (over frames: its last valid TM frame,
    /// [`crate::link::Link::last_heard_ms`]; may be earlier than the last TM). As
    /// [`LinkWatch::on_tm`] when it is newer than anything heard, else nothing.
    pub fn on_heard(&mut self, t_ms: i64) -> Option<LinkState> {
        if self.last_heard_ms.is_some_and(|l| l >= t_ms) {
            return None;
        }
        self.on_tm(t_ms)
    }

    /// The front end listened to the link up to `t_ms`: its reader came back from the
    /// socket then, and what it had read is already given to [`LinkWatch::on_tm`] /
    /// [`LinkWatch::on_heard`]. Once told, a silence counts only up to the latest such
    /// time: a ground process (or its reader thread) not scheduled for seconds on a loaded
    /// machine, the robot's packets waiting in its socket, does not call the robot silent
    /// for its own stall. A front end that never tells judges up to the time it passes.
    pub fn on_listened(&mut self, t_ms: i64) {
        self.listened_ms = Some(self.listened_ms.map_or(t_ms, |l| l.max(t_ms)));
    }

    /// Nothing heard for this long at `now_ms` (since watching started if never heard), as
    /// far as the front end listened ([`LinkWatch::on_listened`]).
    pub fn silence_ms(&self, now_ms: i64) -> i64 {
        let known = self.listened_ms.map_or(now_ms, |l| l.min(now_ms));
        known - self.last_heard_ms.unwrap_or(self.since_ms)
    }

    /// Whether the silence at `now_ms` is shorter than the loss time (the robot answers).
    pub fn heard_within_loss_time(&self, now_ms: i64) -> bool {
        self.last_heard_ms.is_some() && self.silence_ms(now_ms) <= self.loss_after_ms
    }

    /// Checks the silence at `now_ms`; `closed`: the transport says the connection
    /// closed. Returns the loss once, when the link becomes lost (latched until the next
    /// TM).
    pub fn tick(&mut self, now_ms: i64, closed: bool) -> Option<LinkLoss> {
        if self.state == LinkState::Lost {
            return None;
        }
        let silent_ms = self.silence_ms(now_ms);
        if !closed && silent_ms <= self.loss_after_ms {
            return None;
        }
        self.state = LinkState::Lost;
        Some(LinkLoss {
            silent_ms,
            never_heard: self.last_heard_ms.is_none(),
            closed,
        })
    }

    /// Declares the link lost now (e.g. the wrong robot answers at its address).
    pub fn lose(&mut self) {
        self.state = LinkState::Lost;
    }

    /// Starts watching afresh at `now_ms`: the silence of a link not yet heard counts
    /// from here (what was heard, and a loss found, are kept).
    pub fn restart(&mut self, now_ms: i64) {
        self.since_ms = now_ms;
    }
}

/// The MIB's default interval of the robot's status HK (the SID whose reports every
/// robot sends from boot).
pub fn mib_status_hk_interval_ms() -> u32 {
    mib::hk::by_sid(mib::hk::sid::ROBOT_STATUS).map_or(1000, |h| h.default_interval_ms)
}
