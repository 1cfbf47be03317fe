//! Plan runs started from the dashboard under `ground collect --http`.
//!
//! A run is the pure plan [`Executor`] (`ops`, the one `ground run` uses) driven by
//! a thread of its own. Each step's TC goes out through the robot's collector thread
//! ([`DashCmd::PlanTc`]): its link and its TC sequence counter, the same as the page's
//! single TCs, so a request ID is never used twice on an APID. That thread hands the
//! run every verification report and event it receives and tells it when the link is
//! lost ([`PlanInput`]). The run awaits its TCs in an [`crate::ops::TcBook`], the book
//! `ground run`'s session uses: the same resend, acceptance, damaged-copy and give-up
//! rules (no packet resend over frames, none after acceptance). The collector's thread
//! already renews the downlink lease, watches the link and asks the on-board store for
//! every hole, so the run sends no heartbeats of its own. Every
//! change of the run is published to the hub ([`Hub::plan`]), which streams it to the
//! page.
//!
//! [`PlanBook`] is what the dashboard's commander holds: the configured plans
//! (`plans = [...]`, `config::PlanCfg`), which robots are busy, and the start checks
//! (unknown plan, robot not followed, hazardous TCs not confirmed, robot busy).

mod run;

#[cfg(test)]
mod tests;

use std::collections::BTreeMap;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};

use crossbeam_channel::Sender;

use crate::plan::Plan;
use crate::pus::Tm;
use ground_dashboard::{Hub, PlanInfo, PlanRun, PlanStartError, PlanStep};

use super::config::PlanCfg;
use super::dash::DashCmd;

use run::Run;
pub use run::{outcome, view};

/// What a robot's collector thread hands a plan run that follows it.
#[derive(Clone, Debug)]
pub enum PlanInput {
    /// A verification report or an event (live or replayed from the on-board store).
    Tm { robot: u8, tm: Tm },
    /// The collector declared the robot's link lost.
    LinkLost { robot: u8, why: String },
}

/// The plans the collector offers and the runs it has going.
pub struct PlanBook {
    plans: Vec<PlanCfg>,
    hub: Hub,
    robots: BTreeMap<u8, Sender<DashCmd>>,
    /// Robot → run ID of the plan it is running.
    busy: Arc<Mutex<BTreeMap<u8, String>>>,
    runs: AtomicU64,
}

impl PlanBook {
    pub fn new(plans: Vec<PlanCfg>, hub: Hub, robots: BTreeMap<u8, Sender<DashCmd>>) -> PlanBook {
        PlanBook {
            plans,
            hub,
            robots,
            busy: Arc::new(Mutex::new(BTreeMap::new())),
            runs: AtomicU64::new(1),
        }
    }

    fn load(&self, cfg: &PlanCfg) -> Result<Plan, String> {
        crate::plan::load(&cfg.path).map_err(|e| format!("plan {}: {e}", cfg.path.display()))
    }

    /// The configured plans as they are on disk now (a file that no longer reads is
    /// left out and logged).
    pub fn list(&self) -> Vec<PlanInfo> {
        self.plans
            .iter()
            .filter_map(|c| match self.load(c) {
                Ok(p) => Some(PlanInfo::of(&c.name, &p)),
                Err(e) => {
                    tracing::warn!("{e}");
                    None
                }
            })
            .collect()
    }

    /// Starts plan `name`; returns its run ID.
    pub fn start(&self, name: &str, confirmed: bool) -> Result<String, PlanStartError> {
        let cfg = self.plans.iter().find(|c| c.name == name).ok_or_else(|| {
            let names: Vec<&str> = self.plans.iter().map(|c| c.name.as_str()).collect();
            PlanStartError::Unknown(format!(
                "no plan named \"{name}\" (this collector offers: {}; list plan files with `plans = [...]` in its configuration)",
                if names.is_empty() { "none".into() } else { names.join(", ") }
            ))
        })?;
        let plan = self.load(cfg).map_err(PlanStartError::Refused)?;
        if let Some(r) = plan.robots.iter().find(|r| !self.robots.contains_key(&r.number)) {
            return Err(PlanStartError::Refused(format!(
                "plan {name} commands robot {}, which this collector does not follow",
                r.number
            )));
        }
        if let Some((r, st)) = plan
            .robots
            .iter()
            .map(|r| (r.number, self.hub.link_state(r.number)))
            .find(|(_, st)| *st != Some(ground_dashboard::LinkState::Up))
        {
            let st = match st {
                Some(ground_dashboard::LinkState::Lost) => "lost",
                Some(ground_dashboard::LinkState::Connecting) | None => "not up yet",
                Some(ground_dashboard::LinkState::Up) => "up",
            };
            return Err(PlanStartError::Refused(format!(
                "plan {name} not started: robot {r}'s link is {st}"
            )));
        }
        let info = PlanInfo::of(name, &plan);
        if !info.hazards.is_empty() && !confirmed {
            return Err(PlanStartError::NeedsConfirmation(format!(
                "plan {name} sends hazardous TCs ({}): resend with \"confirm\": true",
                info.hazards.join("; ")
            )));
        }
        let run_id = format!("{name}-{}", self.runs.fetch_add(1, Ordering::Relaxed));
        {
            let Ok(mut busy) = self.busy.lock() else {
                return Err(PlanStartError::Refused("plan bookkeeping lock poisoned".into()));
            };
            if let Some((r, other)) = info.robots.iter().find_map(|r| busy.get(r).map(|o| (r, o))) {
                return Err(PlanStartError::Busy(format!(
                    "robot {r} is running plan run {other}: one plan per robot at a time"
                )));
            }
            for r in &info.robots {
                busy.insert(*r, run_id.clone());
            }
        }
        let release = {
            let busy = self.busy.clone();
            let id = run_id.clone();
            move || {
                if let Ok(mut b) = busy.lock() {
                    b.retain(|_, v| *v != id);
                }
            }
        };
        let release = Arc::new(release);
        // The robots' threads hand the run what they receive from now on.
        let (tx, input) = crossbeam_channel::unbounded();
        let mut robots = BTreeMap::new();
        for r in &info.robots {
            if let Some(cmd) = self.robots.get(r) {
                if cmd.send(DashCmd::Follow(tx.clone())).is_err() {
                    release();
                    return Err(PlanStartError::Refused(format!(
                        "robot {r}: the collector's thread has stopped"
                    )));
                }
                robots.insert(*r, cmd.clone());
            }
        }
        drop(tx);
        let run = Run {
            run: PlanRun {
                run_id: run_id.clone(),
                plan: name.to_string(),
                state: "running".into(),
                detail: String::new(),
                started_ms: crate::archive::now_ms(),
                steps: plan
                    .steps
                    .iter()
                    .map(|s| PlanStep {
                        id: s.id.clone(),
                        robot: s.robot,
                        label: s.action.describe(),
                        state: "waiting".into(),
                        request_id: None,
                        detail: String::new(),
                    })
                    .collect(),
            },
            plan,
            hub: self.hub.clone(),
            robots,
            input,
            book: crate::ops::TcBook::default(),
            links: BTreeMap::new(),
            lost: None,
        };
        tracing::info!("plan run {run_id}: started from the dashboard");
        let done = release.clone();
        std::thread::Builder::new()
            .name(format!("plan-{run_id}"))
            .spawn(move || {
                run.execute();
                done();
            })
            .map_err(|e| {
                release();
                PlanStartError::Refused(format!("starting the plan: {e}"))
            })?;
        Ok(run_id)
    }
}
