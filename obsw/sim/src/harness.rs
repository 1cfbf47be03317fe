//! Deterministic harness: the board A [`Controller`] and the [`Sim`] driven together by
//! a mock clock. No real time anywhere: `advance` runs control periods back to back, so
//! simulated time runs as fast as the CPU allows.

use crate::{Sim, SimConfig};
use mib::config::CONTROL_PERIOD_MS;
use mib::modes::module_mode::ON;
use mmic_domain::controller::{Action, ActionReport, Controller, DomainEvent, ModuleModes, StartError, TickOut};

/// Controller + simulator on a mock clock.
pub struct Harness {
    pub ctrl: Controller,
    pub sim: Sim,
    now_ms: u64,
    out: TickOut,
    b_to_a: Vec<u8>,
    /// Every domain event with its time.
    pub events: Vec<(u64, DomainEvent)>,
    /// Every action report with its time.
    pub reports: Vec<(u64, ActionReport)>,
}

impl Harness {
    /// A robot at rest in `cfg.initial_state`, every module unpowered; the controller
    /// boots as on the robot (`Controller::new`): it learns the arm positions from the
    /// sensors while the modules are off.
    pub fn new(cfg: SimConfig) -> Self {
        Harness {
            ctrl: Controller::new(),
            sim: Sim::new(cfg),
            now_ms: 0,
            out: TickOut::new(),
            b_to_a: Vec::new(),
            events: Vec::new(),
            reports: Vec::new(),
        }
    }

    /// Boots (one second with every module off: filters fill, board B reports, arm
    /// positions are recovered), then powers every module (ON) for one second.
    pub fn power_on(&mut self) {
        self.advance(1000);
        self.ctrl.set_module_modes(ModuleModes::all(ON));
        self.advance(1000);
    }

    pub fn now_ms(&self) -> u64 {
        self.now_ms
    }

    /// The outputs of the last control period.
    pub fn last_out(&self) -> &TickOut {
        &self.out
    }

    /// One control period: controller, then physics and board B.
    pub fn tick(&mut self) {
        let sensors = self.sim.sensors_a();
        self.ctrl.tick(self.now_ms, &sensors, &self.b_to_a, &mut self.out);
        self.b_to_a.clear();
        for e in &self.out.events {
            self.events.push((self.now_ms, *e));
        }
        for r in &self.out.reports {
            self.reports.push((self.now_ms, *r));
        }
        self.sim.step(
            CONTROL_PERIOD_MS,
            &self.out.actuators,
            &self.out.link_tx,
            &mut self.b_to_a,
        );
        self.now_ms += CONTROL_PERIOD_MS as u64;
    }

    /// Runs for `ms` of simulated time.
    pub fn advance(&mut self, ms: u64) {
        let end = self.now_ms + ms;
        while self.now_ms < end {
            self.tick();
        }
    }

    /// Runs until `pred` holds (checked after every period) or `max_ms` pass.
    pub fn run_until(&mut self, max_ms: u64, mut pred: impl FnMut(&Harness) -> bool) -> bool {
        let end = self.now_ms + max_ms;
        while self.now_ms < end {
            self.tick();
            if pred(self) {
                return true;
            }
        }
        false
    }

    /// Starts an action and runs until it completes or fails (or `max_ms` pass);
    /// returns the final report (`None` on time-out).
    pub fn run_action(&mut self, action: Action, max_ms: u64) -> Result<Option<ActionReport>, StartError> {
        self.ctrl.start(action, self.now_ms)?;
        let first = self.reports.len();
        let done = self.run_until(max_ms, |h| {
            h.reports[first..]
                .iter()
                .any(|(_, r)| matches!(r, ActionReport::Completed | ActionReport::Failed(_)))
        });
        if !done {
            return Ok(None);
        }
        Ok(self.reports[first..]
            .iter()
            .map(|(_, r)| *r)
            .find(|r| matches!(r, ActionReport::Completed | ActionReport::Failed(_))))
    }

    /// Events since index `from`.
    pub fn events_since(&self, from: usize) -> impl Iterator<Item = &DomainEvent> {
        self.events[from..].iter().map(|(_, e)| e)
    }
}
