//! A robot's on-board plan (PUS 18) as the page shows it, and the control TCs the page
//! may send for it.
//!
//! Everything is decoded with the MIB: the state and its name from the PLAN housekeeping
//! (`mib::hk::sid::PLAN`: PLAN_STATE, PLAN_ID, PLAN_STEPS, PLAN_NEXT_STEP, PLAN_DONE,
//! PLAN_WAIT_ROBOT, PLAN_WAIT_STEP) and the PLAN_STATUS report; the events
//! PLAN_STATE_CHANGED (state at once, with its cause: a fault suspends a plan, the MIB
//! has no "faulted" state) and PLAN_LOADED (the image's CRC-32). Newer on-board time wins,
//! so a replayed HK report never undoes a later event.
//!
//! [`PlanControl::accepted_in`] is the robot's rule for each control TC (`mmic_plan::State::accepts`,
//! the executor's own; a test drives that executor through every state and checks it): the
//! page enables a button only where the robot accepts its TC, and the server refuses the
//! rest before anything is sent.

use serde::Serialize;

use mib::events::eid;
use mib::params::pid;
use mib::plan::state;

/// A control TC of a robot's on-board plan, as the page's buttons send it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum PlanControl {
    /// PLAN_SUSPEND: the running step finishes, nothing new starts.
    Suspend,
    /// PLAN_RESUME: continues where the plan stopped.
    Resume,
    /// PLAN_ABORT: nothing further starts.
    Abort,
    /// PLAN_SKIP of the suspended plan's next step.
    Skip,
}

impl PlanControl {
    pub const ALL: [PlanControl; 4] = [
        PlanControl::Suspend,
        PlanControl::Resume,
        PlanControl::Abort,
        PlanControl::Skip,
    ];

    /// The word of the API path (`/api/robots/N/onboard/suspend`).
    pub fn word(self) -> &'static str {
        match self {
            PlanControl::Suspend => "suspend",
            PlanControl::Resume => "resume",
            PlanControl::Abort => "abort",
            PlanControl::Skip => "skip",
        }
    }

    pub fn from_word(w: &str) -> Option<PlanControl> {
        PlanControl::ALL.into_iter().find(|c| c.word() == w)
    }

    /// MIB name of its TC.
    pub fn tc_name(self) -> &'static str {
        match self {
            PlanControl::Suspend => "PLAN_SUSPEND",
            PlanControl::Resume => "PLAN_RESUME",
            PlanControl::Abort => "PLAN_ABORT",
            PlanControl::Skip => "PLAN_SKIP",
        }
    }

    /// Its TC in the MIB.
    pub fn tc(self) -> Option<&'static mib::tc::TcDef> {
        mib::tc::by_name(self.tc_name())
    }

    /// Whether the robot accepts the TC with its plan in state `code`
    /// (`mib::plan::state`): SUSPEND while running; RESUME and SKIP while suspended;
    /// ABORT while a plan is loaded, running or suspended (the robot also takes it after
    /// completion or an abort, where it would only turn COMPLETED into ABORTED: the page
    /// does not offer that).
    pub fn accepted_in(self, code: u8) -> bool {
        use mmic_plan::{Control, State};
        let control = match self {
            PlanControl::Suspend => Control::Suspend,
            PlanControl::Resume => Control::Resume,
            PlanControl::Abort => Control::Abort,
            PlanControl::Skip => Control::Skip,
        };
        let ended = matches!(State::from_code(code), Some(State::Completed | State::Aborted));
        State::from_code(code).is_some_and(|s| s.accepts(control)) && !(control == Control::Abort && ended)
    }

    /// The states (MIB names) it is accepted in, for error messages.
    pub fn states(self) -> Vec<&'static str> {
        state_codes()
            .filter(|(c, _)| self.accepted_in(*c))
            .map(|(_, n)| n)
            .collect()
    }
}

/// Every plan state of the MIB: (code, name).
fn state_codes() -> impl Iterator<Item = (u8, &'static str)> {
    let list: &[(i64, &str)] = match mib::plan::STATE_NAMES {
        mib::layout::Names::List(l) => l,
        _ => &[],
    };
    list.iter().filter_map(|(c, n)| Some((u8::try_from(*c).ok()?, *n)))
}

/// Name of a plan state code ("RUNNING"); "UNKNOWN(n)" for a code the MIB does not name.
pub fn state_name(code: u8) -> String {
    mib::plan::STATE_NAMES
        .name(i64::from(code))
        .map_or_else(|| format!("UNKNOWN({code})"), str::to_string)
}

/// A robot's on-board plan.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize)]
pub struct OnBoardView {
    /// MIB state name: EMPTY, LOADED, RUNNING, SUSPENDED, COMPLETED, ABORTED.
    pub state: String,
    /// Its code (`mib::plan::state`).
    pub state_code: u8,
    /// Why the plan entered this state, when a PLAN_STATE_CHANGED event said so (MIB
    /// cause name: COMMAND, STEP_FAILED, STEP_TIMEOUT, FAULT, DONE, RESTART).
    pub cause: Option<String>,
    /// Plan ID (0: none), as `0x` and 8 hex digits.
    pub plan_id: String,
    /// CRC-32 of the loaded image (PLAN_LOADED event), when the collector saw it.
    pub crc: Option<String>,
    /// Steps in this robot's image.
    pub steps: u8,
    /// The step running or to run next (0-based).
    pub next_step: u8,
    /// Steps completed (skipped ones included).
    pub done: u8,
    /// The other robot's step the next step waits for (robot, its step 0-based).
    pub waiting_for: Option<(u8, u8)>,
    /// The control TCs the robot accepts now (the page's enabled buttons).
    pub controls: Vec<PlanControl>,
    /// On-board time of the newest report this view comes from.
    pub t_ms: i64,
}

fn hex32(v: u32) -> String {
    format!("0x{v:08x}")
}

impl OnBoardView {
    fn set_state(&mut self, code: u8) {
        if code != self.state_code || self.state.is_empty() {
            // A cause belongs to the change it came with.
            self.cause = None;
        }
        self.state_code = code;
        self.state = state_name(code);
        self.controls = PlanControl::ALL.into_iter().filter(|c| c.accepted_in(code)).collect();
    }

    fn newer(&mut self, t_ms: i64) -> bool {
        if t_ms < self.t_ms {
            return false;
        }
        self.t_ms = t_ms;
        true
    }

    fn set_plan_id(&mut self, id: u32) {
        let id = hex32(id);
        if id != self.plan_id {
            self.crc = None;
            self.plan_id = id;
        }
    }

    /// Applies the plan parameters among one HK report's raw values (by parameter ID).
    /// Returns false when the report holds none (or is older than the view).
    pub fn apply_hk(&mut self, t_ms: i64, raw: &[(u16, i64)]) -> bool {
        let get = |id| raw.iter().find(|(p, _)| *p == id).map(|(_, v)| *v);
        let u8_of = |id| get(id).and_then(|v| u8::try_from(v).ok());
        let Some(code) = u8_of(pid::PLAN_STATE) else {
            return false;
        };
        if !self.newer(t_ms) {
            return false;
        }
        if let Some(id) = get(pid::PLAN_ID).and_then(|v| u32::try_from(v).ok()) {
            self.set_plan_id(id);
        }
        self.set_state(code);
        self.steps = u8_of(pid::PLAN_STEPS).unwrap_or(self.steps);
        self.next_step = u8_of(pid::PLAN_NEXT_STEP).unwrap_or(self.next_step);
        self.done = u8_of(pid::PLAN_DONE).unwrap_or(self.done);
        if let Some(r) = u8_of(pid::PLAN_WAIT_ROBOT) {
            self.waiting_for = (r != 0).then(|| (r, u8_of(pid::PLAN_WAIT_STEP).unwrap_or(0)));
        }
        true
    }

    /// Applies a PLAN_STATUS report.
    pub fn apply_status(&mut self, t_ms: i64, s: &mib_wire::tm::PlanStatus) -> bool {
        if !self.newer(t_ms) {
            return false;
        }
        self.set_plan_id(s.plan_id);
        self.set_state(s.state);
        self.steps = s.steps;
        self.next_step = s.next_step;
        self.done = s.done;
        self.waiting_for = (s.wait_robot != 0).then_some((s.wait_robot, s.wait_step));
        true
    }

    /// Applies a plan event (PLAN_STATE_CHANGED, PLAN_LOADED) by MIB event ID with its
    /// parameters by name; false for any other event.
    pub fn apply_event(&mut self, t_ms: i64, id: u16, param: impl Fn(&str) -> Option<i64>) -> bool {
        let u8_of = |k| param(k).and_then(|v| u8::try_from(v).ok());
        let u32_of = |k| param(k).and_then(|v| u32::try_from(v).ok());
        match id {
            eid::PLAN_STATE_CHANGED => {
                let Some(code) = u8_of("state") else { return false };
                if !self.newer(t_ms) {
                    return false;
                }
                if let Some(id) = u32_of("plan_id") {
                    self.set_plan_id(id);
                }
                self.set_state(code);
                self.cause = u8_of("cause").map(|c| {
                    mib::plan::CAUSE_NAMES
                        .name(i64::from(c))
                        .map_or_else(|| format!("UNKNOWN({c})"), str::to_string)
                });
                if let Some(step) = u8_of("step") {
                    // The event's step is the plan's next step (= steps done).
                    self.next_step = step;
                    self.done = step;
                }
                if code != state::RUNNING {
                    self.waiting_for = None;
                }
                true
            }
            eid::PLAN_LOADED => {
                if !self.newer(t_ms) {
                    return false;
                }
                if let Some(id) = u32_of("plan_id") {
                    self.set_plan_id(id);
                }
                self.set_state(state::LOADED);
                self.steps = u8_of("steps").unwrap_or(self.steps);
                self.next_step = 0;
                self.done = 0;
                self.waiting_for = None;
                self.crc = u32_of("crc").map(hex32);
                true
            }
            _ => false,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use mmic_plan::{Plan, State, StepKind, StepRepr};

    const PLAN_ID: u32 = 0x1234_5678;

    /// A robot's executor with a two-wait-step plan loaded.
    fn loaded() -> Plan {
        let steps: Vec<StepRepr> = (0..2)
            .map(|i| StepRepr {
                index: i,
                confirmed: false,
                timeout_s: 0,
                deps: Default::default(),
                kind: StepKind::Wait { ms: 1000 },
            })
            .collect();
        let mut out = [0u8; mib::plan::MAX_IMAGE_LEN];
        let n = mmic_plan::image::emit(1, PLAN_ID, &steps, &mut out).unwrap();
        let mut p = Plan::new(1);
        p.load(0, &out[..n]).unwrap();
        let crc = u32::from_be_bytes(out[n - 4..n].try_into().unwrap());
        p.commit(n as u16, crc, |_| Ok(())).unwrap();
        p
    }

    /// The executor in every state the MIB names.
    fn every_state() -> Vec<Plan> {
        let empty = Plan::new(1);
        let l = loaded();
        let mut running = l.clone();
        running.start(PLAN_ID).unwrap();
        let mut suspended = running.clone();
        suspended.suspend().unwrap();
        let mut completed = suspended.clone();
        completed.skip(0).unwrap();
        completed.skip(1).unwrap();
        let mut aborted = running.clone();
        aborted.abort().unwrap();
        vec![empty, l, running, suspended, completed, aborted]
    }

    fn robot_accepts(p: &Plan, c: PlanControl) -> bool {
        let mut p = p.clone();
        match c {
            PlanControl::Suspend => p.suspend().is_ok(),
            PlanControl::Resume => p.resume().is_ok(),
            PlanControl::Abort => p.abort().is_ok(),
            PlanControl::Skip => {
                let next = p.done();
                p.skip(next).is_ok()
            }
        }
    }

    // verifies: GND-ONBOARD-02
    #[test]
    fn the_page_offers_a_control_only_where_the_robots_executor_accepts_it() {
        let states = every_state();
        let codes: Vec<u8> = states.iter().map(|p| p.state().code()).collect();
        let named: Vec<u8> = state_codes().map(|(c, _)| c).collect();
        assert_eq!(codes, named, "every MIB plan state reached");
        for p in &states {
            let code = p.state().code();
            for c in PlanControl::ALL {
                let robot = robot_accepts(p, c);
                if c.accepted_in(code) {
                    assert!(robot, "{c:?} offered in {} but refused", state_name(code));
                } else if !(c == PlanControl::Abort && matches!(p.state(), State::Completed | State::Aborted)) {
                    assert!(!robot, "{c:?} accepted in {} but not offered", state_name(code));
                }
            }
        }
        assert_eq!(PlanControl::Resume.states(), vec!["SUSPENDED"]);
        for c in PlanControl::ALL {
            assert!(c.tc().is_some(), "{} in the MIB", c.tc_name());
            assert_eq!(PlanControl::from_word(c.word()), Some(c));
        }
        assert_eq!(PlanControl::from_word("start"), None);
    }

    // verifies: GND-ONBOARD-01
    #[test]
    fn the_view_decodes_hk_and_events_with_the_mib_and_newer_time_wins() {
        let mut v = OnBoardView::default();
        assert!(!v.apply_hk(10, &[(pid::V_BAT_A, 12)]), "no plan parameters");
        let hk = [
            (pid::PLAN_STATE, i64::from(state::RUNNING)),
            (pid::PLAN_ID, i64::from(PLAN_ID)),
            (pid::PLAN_STEPS, 5),
            (pid::PLAN_NEXT_STEP, 2),
            (pid::PLAN_DONE, 2),
            (pid::PLAN_WAIT_ROBOT, 1),
            (pid::PLAN_WAIT_STEP, 3),
        ];
        assert!(v.apply_hk(100, &hk));
        assert_eq!(
            (v.state.as_str(), v.plan_id.as_str(), v.steps, v.done, v.waiting_for),
            ("RUNNING", "0x12345678", 5, 2, Some((1, 3)))
        );
        assert_eq!(v.controls, vec![PlanControl::Suspend, PlanControl::Abort]);
        let ev = |state: u8, cause: u8| {
            move |k: &str| match k {
                "plan_id" => Some(i64::from(PLAN_ID)),
                "state" => Some(i64::from(state)),
                "step" => Some(2),
                "cause" => Some(i64::from(cause)),
                _ => None,
            }
        };
        assert!(v.apply_event(
            200,
            eid::PLAN_STATE_CHANGED,
            ev(state::SUSPENDED, mib::plan::cause::FAULT)
        ));
        assert_eq!(
            (v.state.as_str(), v.cause.as_deref(), v.waiting_for),
            ("SUSPENDED", Some("FAULT"), None)
        );
        assert_eq!(
            v.controls,
            vec![PlanControl::Resume, PlanControl::Abort, PlanControl::Skip]
        );
        // An HK report sampled before the event changes nothing.
        assert!(!v.apply_hk(150, &hk));
        assert_eq!(v.state, "SUSPENDED");
        // A later one in the same state keeps the cause; another state drops it.
        let mut later = hk;
        later[0].1 = i64::from(state::SUSPENDED);
        assert!(v.apply_hk(300, &later));
        assert_eq!(v.cause.as_deref(), Some("FAULT"));
        later[0].1 = i64::from(state::RUNNING);
        assert!(v.apply_hk(400, &later));
        assert_eq!(v.cause, None);
        let loaded = |k: &str| match k {
            "plan_id" => Some(7),
            "steps" => Some(3),
            "crc" => Some(0xDEAD_BEEF),
            _ => None,
        };
        assert!(v.apply_event(500, eid::PLAN_LOADED, loaded));
        assert_eq!(
            (v.state.as_str(), v.plan_id.as_str(), v.crc.as_deref(), v.done),
            ("LOADED", "0x00000007", Some("0xdeadbeef"), 0)
        );
        assert!(!v.apply_event(600, eid::MODE_CHANGED, |_| Some(1)));
        assert_eq!(state_name(99), "UNKNOWN(99)");
    }
}
