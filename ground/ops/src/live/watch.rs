//! Is the link up? The one link-loss rule of every front end.

use serde::Serialize;

/// Link state shown to operators.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum LinkState {
    /// Not heard since watching started.
    #[default]
    Connecting,
    Up,
    /// Lost: no TM for the loss time ([`LinkWatch::loss_after_ms`]), or the connection
    /// closed.
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
    /// Time without TM (ms): since the last TM, or since watching started.
    pub silent_ms: i64,
    /// Nothing was heard since watching started.
    pub never_heard: bool,
    /// The connection closed (not a silence).
    pub closed: bool,
}

/// One robot's link: up while TM comes, lost after [`mib::config::link_loss_ms`] of the
/// robot's status-HK interval without any TM (or when its connection closes). Pure: the
/// caller passes the time (ms, any clock that does not go back).
#[derive(Clone, Debug)]
pub struct LinkWatch {
    state: LinkState,
    loss_after_ms: i64,
    /// When watching (re)started: the silence of a link never heard counts from here.
    since_ms: i64,
    last_tm_ms: Option<i64>,
}

impl LinkWatch {
    /// Watches from `now_ms` a robot whose status HK comes every `hk_interval_ms`.
    pub fn new(hk_interval_ms: u32, now_ms: i64) -> LinkWatch {
        LinkWatch {
            state: LinkState::Connecting,
            loss_after_ms: i64::from(mib::config::link_loss_ms(hk_interval_ms)),
            since_ms: now_ms,
            last_tm_ms: None,
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

    /// No TM for this long (ms) is a loss.
    pub fn loss_after_ms(&self) -> i64 {
        self.loss_after_ms
    }

    pub fn state(&self) -> LinkState {
        self.state
    }

    /// When the last TM came (`None`: never since watching started).
    pub fn last_tm_ms(&self) -> Option<i64> {
        self.last_tm_ms
    }

    /// When watching started.
    pub fn since_ms(&self) -> i64 {
        self.since_ms
    }

    /// A TM of this robot arrived. Returns the state it left when the link came up
    /// (`Some(Connecting)` or `Some(Lost)`), `None` if it was up.
    pub fn on_tm(&mut self, now_ms: i64) -> Option<LinkState> {
        self.last_tm_ms = Some(now_ms);
        let was = self.state;
        self.state = LinkState::Up;
        (was != LinkState::Up).then_some(was)
    }

    /// Checks the silence at `now_ms`; `closed`: the transport says the connection
    /// closed. Returns the loss once, when the link becomes lost (latched until the next
    /// TM).
    pub fn tick(&mut self, now_ms: i64, closed: bool) -> Option<LinkLoss> {
        if self.state == LinkState::Lost {
            return None;
        }
        let silent_ms = now_ms - self.last_tm_ms.unwrap_or(self.since_ms);
        if !closed && silent_ms <= self.loss_after_ms {
            return None;
        }
        self.state = LinkState::Lost;
        Some(LinkLoss {
            silent_ms,
            never_heard: self.last_tm_ms.is_none(),
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
