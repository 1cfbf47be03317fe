//! Operator dashboard: a live web page over the fleet, served by the collector.
//!
//! The collector (or any other feed) keeps a [`Hub`] up to date through plain methods
//! with plain data types — robot link state, modes, configuration state, housekeeping
//! values by MIB name, events, alarms, the PUS 1 stages of every TC and plan progress.
//! The page reads a snapshot of the hub and then follows it through server-sent
//! events that resume without loss after a reconnect. Commands from the page go back
//! to the collector through the [`Commander`] trait; plots read the archive through
//! the [`Series`] trait (min/max per pixel column) and are extended live from the hub.
//!
//! ```text
//!  collector ──(Hub methods)──► Hub ──(snapshot + SSE)──► page
//!  collector ◄──(Commander)──── server ◄──(JSON API)───── page
//!  archive   ◄──(Series)─────── server
//! ```
//!
//! [`serve`] runs the HTTP server (axum on tokio). `ground collect --http` mounts it
//! with the collector's robot threads as the feed (`collect::dash`), and runs plans from
//! the page through them (`collect::planrun`).

mod hub;
pub mod mibinfo;
pub mod onboard;
mod server;

use ground_archive as archive;
use ground_ops::plan;
use ground_pus as pus;

pub use hub::{Hub, HubStats, DEFAULT_LIVE_SAMPLES, DEFAULT_REPLAY};
pub use onboard::{OnBoardView, PlanControl};
pub use server::{serve, spawn, Running, ServeError};

use serde::Serialize;

/// Link state of one robot: the one enum of every front end (`ground_ops::live`, the rule
/// of [`ground_ops::live::LinkWatch`]). The page reads it as `"connecting"`, `"up"` or
/// `"lost"` (`ground/web/src/app.js`).
pub use ground_ops::live::LinkState;

/// Configuration state of a robot: the MIB state and the faces its two sides grip.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct ConfigState {
    /// MIB state name ("Xneg", "Xneg Xpos", …), or "unknown".
    pub name: String,
    /// Kind: "matched", "stretch", "turn" or "unknown".
    pub kind: String,
    /// Face gripped by side A ("Xpos", "Ypos", "Xneg", "Yneg"), if known.
    pub face_a: Option<String>,
    /// Face gripped by side B, if known.
    pub face_b: Option<String>,
}

impl ConfigState {
    /// The configuration state with MIB ID `id` (`mib::robot::STATES`); any other
    /// value (e.g. `STATE_UNKNOWN`) gives an "unknown" state.
    pub fn from_mib(id: u8) -> ConfigState {
        match mib::robot::STATES.get(id as usize) {
            Some(s) => ConfigState {
                name: s.name.to_string(),
                kind: s.kind().name().to_string(),
                face_a: Some(s.a.name().to_string()),
                face_b: Some(s.b.name().to_string()),
            },
            None => ConfigState {
                name: "unknown".into(),
                kind: "unknown".into(),
                face_a: None,
                face_b: None,
            },
        }
    }
}

/// A robot's module set and the state of its configuration (docs/modules.md), as the collector
/// follows it: the module report TM[210,3] (slots, descriptors, why a set is invalid)
/// and the MODULES housekeeping (SID 23: hash, configuration, state, present slots).
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize)]
pub struct ModuleView {
    /// Configuration hash, `0x` and 8 hex digits ("0x00000000" before discovery).
    pub hash: String,
    /// The hash the collector saw before this one, when it changed.
    pub previous_hash: Option<String>,
    /// Supported configuration by MIB name ("FULL", "LOCOMOTION_ONLY"), "NONE" for an
    /// invalid set.
    pub config: String,
    /// Configuration state by MIB name: NOT_DISCOVERED, ACCEPTED, NOT_ACCEPTED, INVALID.
    pub status: String,
    /// Against the configuration the ground accepted: NONE_ACCEPTED, SAME, CHANGED
    /// (from the module report).
    pub replacement: String,
    /// Why the set is invalid (MIB name, "NONE" when valid) and the slot it names.
    pub reason: String,
    pub reason_slot: Option<String>,
    /// Every slot of the topology, present or not.
    pub slots: Vec<SlotView>,
    /// On-board time of the last module report (None: only HK seen so far).
    pub report_t_ms: Option<i64>,
    /// On-board time of the last MODULES housekeeping report.
    pub hk_t_ms: Option<i64>,
}

/// One slot of a robot's module set.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize)]
pub struct SlotView {
    pub slot: u8,
    /// MIB slot name (BOARD_A, GRIPPER_B, …).
    pub name: String,
    /// Module type of the slot (hip, arm, gripper, …).
    pub kind: String,
    pub present: bool,
    pub variant: Option<u8>,
    pub revision: Option<u8>,
    pub serial: Option<u32>,
    /// "ok", "absent", "invalid" (the reason names this slot) or "changed" (presence,
    /// serial or revision differ from the set the collector saw before).
    pub state: String,
}

/// A robot's team status (docs/team.md): TEAM_STATUS TM[211,2].
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize)]
pub struct TeamView {
    pub term: u32,
    /// FOLLOWER, CANDIDATE or LEADER.
    pub role: String,
    /// Leader of the term (None: none known).
    pub leader: Option<u8>,
    pub ground_seen: bool,
    /// This robot leads and holds the lease.
    pub lease: bool,
    pub voted_for: Option<u8>,
    /// Robot numbers in order of preference (empty: no team).
    pub roster: Vec<u8>,
    /// Authorised plan steps (0: HOLD only).
    pub auth_steps: u8,
    pub refused: u32,
    /// On-board time of the report.
    pub t_ms: i64,
}

/// Limit state of a housekeeping value against the MIB's soft and hard limits.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum LimitState {
    /// The parameter has no limits in the MIB.
    None,
    /// Inside the soft limits.
    Ok,
    /// Outside the soft limits, inside the hard limits.
    Soft,
    /// Outside the hard limits.
    Hard,
    /// The parameter has limits, but they do not apply in the robot's current state (the
    /// MIB's `limits_in` and `limits_if`: e.g. V_REG only in OPERATIONAL and SAFED, the
    /// hip deviation only while no primitive runs).
    Off,
}

impl LimitState {
    /// The state of `value` of parameter `p` in the robot state `ctx` (raw values by
    /// parameter ID, `None` when not known) — the same applicability rule as the
    /// collector's alarms and the on-board monitors (`mib::params::limits_apply`).
    pub fn of(p: &mib::params::ParamDef, value: f64, ctx: impl Fn(u16) -> Option<i64>) -> LimitState {
        let applies = mib::params::limits_apply(p, ctx);
        match p.limits {
            Some(_) if !applies => LimitState::Off,
            l => Self::check(l, value),
        }
    }

    /// Checks `value` against `limits`.
    fn check(limits: Option<&mib::Limits>, value: f64) -> LimitState {
        match limits {
            None => LimitState::None,
            Some(l) if value < l.hard_lo || value > l.hard_hi => LimitState::Hard,
            Some(l) if value < l.soft_lo || value > l.soft_hi => LimitState::Soft,
            Some(_) => LimitState::Ok,
        }
    }
}

/// An event report (PUS 5) by MIB name.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct EventRecord {
    pub robot: u8,
    pub t_ms: i64,
    /// MIB event name.
    pub name: String,
    /// "info", "low", "medium" or "high".
    pub severity: String,
    pub description: String,
    /// Parameters by name.
    pub params: Vec<(String, i64)>,
}

/// Alarm state, ISA-18.2 style.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum AlarmState {
    /// Raised and not yet acknowledged.
    Active,
    /// Acknowledged by an operator; the condition may still be present.
    Acknowledged,
    /// The condition is gone.
    Cleared,
    /// Hidden by an operator until `shelved_until_ms`.
    Shelved,
}

/// One alarm.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct AlarmRecord {
    pub id: u64,
    pub robot: u8,
    /// Parameter or event name (or "LINK" for link loss).
    pub source: String,
    /// "low", "medium" or "high".
    pub severity: String,
    pub state: AlarmState,
    pub message: String,
    pub first_ms: i64,
    pub last_ms: i64,
    pub shelved_until_ms: Option<i64>,
}

/// PUS 1 verification stage: the decoder's (`ground_pus::Stage`, serialised in lowercase,
/// as the page reads it).
pub use ground_pus::Stage;

/// A PUS 1 failure: code name and decoded data.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct FailureInfo {
    pub code: u16,
    /// MIB failure code name.
    pub name: String,
    pub description: String,
    /// Failure data fields by name (decoded with the MIB layout).
    pub fields: Vec<(String, i64)>,
    /// Raw failure data in hex.
    pub data_hex: String,
}

/// One PUS 1 report of a TC.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct StageReport {
    pub stage: Stage,
    /// Step number of a progress report.
    pub step: Option<u8>,
    pub t_ms: i64,
    pub success: bool,
    pub failure: Option<FailureInfo>,
}

impl StageReport {
    /// The dashboard's view of a decoded PUS 1 report received at on-board time `t_ms`.
    pub fn from_verification(v: &crate::pus::Verification, t_ms: i64) -> StageReport {
        let failure = v.failure.as_ref().map(|f| FailureInfo {
            code: f.code,
            name: f.name.to_string(),
            description: f.description.to_string(),
            fields: f.fields.iter().map(|x| (x.name.clone(), x.value)).collect(),
            data_hex: crate::pus::hex(&f.data),
        });
        StageReport {
            stage: v.stage,
            step: v.step,
            t_ms,
            success: v.success,
            failure,
        }
    }
}

/// A TC and every verification report received for it.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct CommandRecord {
    pub request_id: String,
    pub robot: u8,
    /// MIB TC name.
    pub name: String,
    /// Arguments by MIB name.
    pub args: Vec<(String, i64)>,
    pub sent_ms: i64,
    /// Who sent it ("page", "plan NAME", "cli", …).
    pub origin: String,
    pub stages: Vec<StageReport>,
}

impl CommandRecord {
    /// True once a completion report arrived, or any failure.
    pub fn finished(&self) -> bool {
        self.stages.iter().any(|s| s.stage == Stage::Completion || !s.success)
    }
}

/// Progress of a plan run.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct PlanRun {
    pub run_id: String,
    pub plan: String,
    /// "running", "done", "failed" (a step failed or was blocked) or "lost" (a robot's
    /// link was lost).
    pub state: String,
    /// Why the run ended as it did (the failing step and its failure name, the lost
    /// link); empty while it runs and when it completed.
    pub detail: String,
    pub started_ms: i64,
    pub steps: Vec<PlanStep>,
}

#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct PlanStep {
    pub id: String,
    pub robot: u8,
    /// What the step does ("RECONFIGURE Xneg → Xpos", …).
    pub label: String,
    /// "waiting", "running", "done", "failed" or "blocked" (it waited for a step that
    /// failed, or its robot's link was lost).
    pub state: String,
    pub request_id: Option<String>,
    pub detail: String,
}

/// A plan the commander can start.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct PlanInfo {
    pub name: String,
    pub description: String,
    /// Robots the plan commands.
    pub robots: Vec<u8>,
    pub steps: usize,
    /// One line per step that sends a TC the MIB marks hazardous (`TcDef::hazard`):
    /// starting the plan then needs the operator's confirmation.
    pub hazards: Vec<String>,
}

impl PlanInfo {
    /// What the page shows of `plan`, offered as `name`.
    pub fn of(name: &str, plan: &crate::plan::Plan) -> PlanInfo {
        PlanInfo {
            name: name.to_string(),
            description: plan.description.clone(),
            robots: plan.robots.iter().map(|r| r.number).collect(),
            steps: plan.steps.len(),
            hazards: plan
                .steps
                .iter()
                .filter_map(|s| {
                    let (def, _) = s.action.tc()?;
                    let why = mibinfo::hazard(def)?;
                    Some(format!("step {} (robot {}): {} — {why}", s.id, s.robot, def.name))
                })
                .collect(),
        }
    }
}

/// Why a plan was not started.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum PlanStartError {
    /// No plan by that name is offered (HTTP 404).
    Unknown(String),
    /// A robot of the plan is running another plan (HTTP 409).
    Busy(String),
    /// The plan sends hazardous TCs and the start was not confirmed (HTTP 409).
    NeedsConfirmation(String),
    /// Anything else: plan file unreadable, robot not followed, … (HTTP 400).
    Refused(String),
}

impl std::fmt::Display for PlanStartError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            PlanStartError::Unknown(m)
            | PlanStartError::Busy(m)
            | PlanStartError::NeedsConfirmation(m)
            | PlanStartError::Refused(m) => f.write_str(m),
        }
    }
}

impl std::error::Error for PlanStartError {}

/// Why the commander refused a request (shown on the page as is).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct CommandError(pub String);

impl std::fmt::Display for CommandError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for CommandError {}

/// What the page asks of the collector. Implementations must not block for long: each
/// call runs on a blocking thread of the server.
pub trait Commander: Send + Sync + 'static {
    /// Sends the TC `name` (MIB name) with `args` (raw values in MIB argument order,
    /// already range-checked against the MIB) to `robot`. Returns the request ID the
    /// hub's command history uses for it.
    fn send_tc(&self, robot: u8, name: &str, args: &[i64]) -> Result<String, CommandError>;
    /// Acknowledges an alarm. A refusal names the alarm itself (the page shows it as
    /// is, without a prefix of its own).
    fn ack_alarm(&self, id: u64) -> Result<(), CommandError>;
    /// Shelves an alarm for `for_ms`.
    fn shelve_alarm(&self, id: u64, for_ms: i64) -> Result<(), CommandError>;
    /// Plans that can be started.
    fn plans(&self) -> Vec<PlanInfo>;
    /// Starts a plan; returns its run ID (progress arrives through [`Hub::plan`]).
    /// `confirmed`: the operator confirmed the plan's hazardous TCs
    /// ([`PlanInfo::hazards`]); a plan with any is refused without it.
    fn start_plan(&self, name: &str, confirmed: bool) -> Result<String, PlanStartError>;
}

/// Archived samples of one parameter, decimated for plotting.
pub trait Series: Send + Sync + 'static {
    /// Minimum and maximum of `param` (MIB name, engineering value) of `robot` in each
    /// of `columns` equal slices of `[t0_ms, t1_ms)`; one `(slice start, min, max)` per
    /// slice that holds samples, in time order. See [`decimate`] for the reference.
    fn decimate(&self, robot: u8, param: &str, t0_ms: i64, t1_ms: i64, columns: usize) -> Vec<(i64, f64, f64)>;
}

/// A [`Series`] with no archive (plots show what the hub holds live).
pub struct NoArchive;

impl Series for NoArchive {
    fn decimate(&self, _: u8, _: &str, _: i64, _: i64, _: usize) -> Vec<(i64, f64, f64)> {
        Vec::new()
    }
}

/// Reference decimation: min/max of `samples` (time-ordered `(t_ms, value)`) per
/// column of `[t0_ms, t1_ms)` split into `columns` equal slices. Non-finite values are
/// skipped (a NaN never blanks a column); returns the points and the number skipped.
pub fn decimate(samples: &[(i64, f64)], t0_ms: i64, t1_ms: i64, columns: usize) -> (Vec<(i64, f64, f64)>, usize) {
    let mut out: Vec<(i64, f64, f64)> = Vec::new();
    let mut skipped = 0;
    if columns == 0 || t1_ms <= t0_ms {
        return (out, 0);
    }
    let span = (t1_ms - t0_ms) as i128;
    let cols = columns as i128;
    let mut cur: Option<(i128, f64, f64)> = None;
    let start = samples.partition_point(|s| s.0 < t0_ms);
    for &(t, v) in &samples[start..] {
        if t >= t1_ms {
            break;
        }
        if !v.is_finite() {
            skipped += 1;
            continue;
        }
        let col = (t - t0_ms) as i128 * cols / span;
        match &mut cur {
            Some((c, lo, hi)) if *c == col => {
                *lo = lo.min(v);
                *hi = hi.max(v);
            }
            _ => {
                if let Some((c, lo, hi)) = cur.take() {
                    out.push((column_start(t0_ms, span, cols, c), lo, hi));
                }
                cur = Some((col, v, v));
            }
        }
    }
    if let Some((c, lo, hi)) = cur {
        out.push((column_start(t0_ms, span, cols, c), lo, hi));
    }
    (out, skipped)
}

fn column_start(t0_ms: i64, span: i128, cols: i128, c: i128) -> i64 {
    t0_ms + (c * span / cols) as i64
}

/// Request ID as the hub and the page show it: robot, APID and sequence count.
pub fn request_id(robot: u8, apid: u16, seq: u16) -> String {
    format!("{robot}-{apid:03x}-{seq}")
}

/// Records a TC the robot's thread is about to send from the page.
pub fn tc_sent(
    hub: &Hub,
    robot: u8,
    tc: &crate::pus::BuiltTc,
    def: &mib::tc::TcDef,
    args: &[i64],
    origin: &str,
) -> String {
    let id = request_id(robot, tc.apid, tc.seq);
    hub.tc_sent(CommandRecord {
        request_id: id.clone(),
        robot,
        name: def.name.to_string(),
        args: def
            .args
            .iter()
            .map(|a| a.name.to_string())
            .zip(args.iter().copied())
            .collect(),
        sent_ms: crate::archive::now_ms(),
        origin: origin.to_string(),
        stages: Vec::new(),
    });
    id
}

pub fn node_mode(hub: &Hub, robot: u8, node: u32, mode: u32) {
    if let Some(n) = mib::modes::node_by_id(node) {
        if let Some(m) = mib::modes::mode_name(n.kind, mode) {
            hub.mode(robot, n.name, m);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    // verifies: OPS-LIVE-LINK-01
    #[test]
    fn the_page_reads_the_one_link_state_as_lowercase_words() {
        let json = |s: LinkState| serde_json::to_string(&s).unwrap();
        assert_eq!(json(LinkState::Connecting), "\"connecting\"");
        assert_eq!(json(LinkState::Up), "\"up\"");
        assert_eq!(json(LinkState::Lost), "\"lost\"");
        // The collector's watch and the page hold the same type.
        let from_watch: LinkState = ground_ops::live::LinkWatch::new(1000, 0).state();
        assert_eq!(json(from_watch), "\"connecting\"");
    }

    // verifies: GND-17
    #[test]
    fn decimation_keeps_min_and_max_of_every_column() {
        let s: Vec<(i64, f64)> = (0..1000).map(|i| (i, (i % 10) as f64)).collect();
        let (d, skipped) = decimate(&s, 0, 1000, 10);
        assert_eq!(skipped, 0);
        assert_eq!(d.len(), 10);
        for (i, p) in d.iter().enumerate() {
            assert_eq!(*p, (i as i64 * 100, 0.0, 9.0));
        }
    }

    // verifies: GND-17
    #[test]
    fn one_outlier_stays_a_spike_and_a_nan_blanks_nothing() {
        let mut s: Vec<(i64, f64)> = (0..100).map(|i| (i, 12.0)).collect();
        s[50].1 = 1.0e9;
        s[70].1 = f64::NAN;
        let (d, skipped) = decimate(&s, 0, 100, 10);
        assert_eq!(skipped, 1);
        assert_eq!(d.len(), 10, "every column drawn");
        assert_eq!(d[5], (50, 12.0, 1.0e9));
        assert_eq!(d[7], (70, 12.0, 12.0));
    }

    // verifies: GND-17
    #[test]
    fn empty_columns_are_left_out_and_range_is_half_open() {
        let s = vec![(0, 1.0), (5, 2.0), (99, 3.0), (100, 4.0)];
        let (d, _) = decimate(&s, 0, 100, 4);
        assert_eq!(d, vec![(0, 1.0, 2.0), (75, 3.0, 3.0)]);
        assert!(decimate(&s, 100, 100, 4).0.is_empty());
        assert!(decimate(&s, 0, 100, 0).0.is_empty());
    }

    // verifies: GND-16, GND-13, ALM-COND-01
    #[test]
    fn limit_state_follows_the_mib_bands() {
        let p = mib::params::by_name("V_BAT_A").unwrap();
        let l = p.limits;
        assert_eq!(LimitState::check(l, 12.0), LimitState::Ok);
        assert_eq!(LimitState::check(l, 10.2), LimitState::Soft);
        assert_eq!(LimitState::check(l, 9.5), LimitState::Hard);
        assert_eq!(LimitState::check(None, 9.5), LimitState::None);
        // V_REG's limits hold in OPERATIONAL and SAFED only: off in STANDBY, unknown mode.
        let v_reg = mib::params::by_name("V_REG").unwrap();
        use mib::modes::robot_mode;
        use mib::params::pid;
        let state = |mode: Option<u32>, prim: i64| {
            move |id| match id {
                pid::MODE => mode.map(i64::from),
                pid::ACTIVE_PRIMITIVE => Some(prim),
                _ => None,
            }
        };
        assert_eq!(
            LimitState::of(v_reg, 0.0, state(Some(robot_mode::STANDBY), 0)),
            LimitState::Off
        );
        assert_eq!(LimitState::of(v_reg, 0.0, state(None, 0)), LimitState::Off);
        assert_eq!(
            LimitState::of(v_reg, 0.0, state(Some(robot_mode::OPERATIONAL), 0)),
            LimitState::Hard
        );
        assert_eq!(LimitState::of(p, 9.5, state(None, 0)), LimitState::Hard);
        let mode = mib::params::by_name("MODE").unwrap();
        assert_eq!(LimitState::of(mode, 1.0, state(Some(1), 0)), LimitState::None);
        // The hip deviation is off while a primitive turns the hip.
        let hip = mib::params::by_name("HIP_DEVIATION").unwrap();
        assert_eq!(LimitState::of(hip, -55.0, state(Some(1), 4)), LimitState::Off);
        assert_eq!(LimitState::of(hip, -55.0, state(Some(1), 0)), LimitState::Hard);
    }

    // verifies: GND-16, MMIC-MOT-01
    #[test]
    fn config_state_names_faces_from_the_mib() {
        let c = ConfigState::from_mib(0);
        assert_eq!(c.name, mib::robot::STATES[0].name);
        assert_eq!(c.face_a.as_deref(), Some(mib::robot::STATES[0].a.name()));
        assert_eq!(ConfigState::from_mib(mib::robot::STATE_UNKNOWN).name, "unknown");
    }
}
