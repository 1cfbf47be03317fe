//! Deterministic harness: the board A [`Controller`] and the [`Sim`] driven together by
//! a mock clock. No real time anywhere: `advance` runs control periods back to back, so
//! simulated time runs as fast as the CPU allows.

use crate::{Sim, SimConfig};
use mib::config::CONTROL_PERIOD_MS;
use mib::modes::module_mode::ON;
use mib::robot::{servo, STATES};
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
    /// knows its arm and gripper positions.
    pub fn new(cfg: SimConfig) -> Self {
        let s = STATES.get(cfg.initial_state as usize).copied().unwrap_or(STATES[0]);
        Harness {
            ctrl: Controller::with_positions(s.arm_pwm(), servo::GRIP_CLOSED_US),
            sim: Sim::new(cfg),
            now_ms: 0,
            out: TickOut::new(),
            b_to_a: Vec::new(),
            events: Vec::new(),
            reports: Vec::new(),
        }
    }

    /// Powers every module (ON) and runs one second so that the moving averages fill
    /// and board B reports.
    pub fn power_on(&mut self) {
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
                .any(|(_, r)| matches!(r, ActionReport::Completed | ActionReport::Failed { .. }))
        });
        if !done {
            return Ok(None);
        }
        Ok(self.reports[first..]
            .iter()
            .map(|(_, r)| *r)
            .find(|r| matches!(r, ActionReport::Completed | ActionReport::Failed { .. })))
    }

    /// Events since index `from`.
    pub fn events_since(&self, from: usize) -> impl Iterator<Item = &DomainEvent> {
        self.events[from..].iter().map(|(_, e)| e)
    }
}
