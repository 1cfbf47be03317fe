//! The page's and the plan runs' TCs, numbered with this thread's sequence counter and
//! sent on its link; what the following plan run and the dashboard are told.

use std::time::Instant;

use crate::archive::now_ms;
use crate::dash::DashCmd;
use crate::ops::book::{Due, Pending, Verdict};
use crate::ops::SendError;
use crate::planrun::PlanInput;
use crate::pus::{self, BuiltTc};

use super::Worker;

impl Worker {
    /// Sends the page's TCs, numbered with this thread's own sequence counter.
    pub(super) fn dash_commands(&mut self) {
        let Some(d) = &self.dash else { return };
        let cmds: Vec<DashCmd> = d.cmds.try_iter().take(64).collect();
        for c in cmds {
            match c {
                // The page's answer channel may be gone (it timed out): nothing to tell.
                DashCmd::Tc { name, args, reply } => {
                    let r = mib::tc::by_name(&name)
                        .ok_or_else(|| format!("no TC named {name}"))
                        .and_then(|def| self.dash_tc(def, &args, "page").map_err(|e| e.to_string()))
                        .map(|tc| {
                            let id = ground_dashboard::request_id(self.robot(), tc.apid, tc.seq);
                            let p = Pending::sent(self.robot(), tc, None, Some("page".into()), Instant::now());
                            self.page_tcs.insert(p);
                            id
                        });
                    let _ = reply.send(r);
                }
                DashCmd::PlanTc {
                    def,
                    args,
                    origin,
                    reply,
                } => {
                    let kind = self.link.as_ref().map(crate::link::Link::kind);
                    let r = self.dash_tc(def, &args, &origin).and_then(|tc| {
                        // dash_tc refuses without a link, so there is a kind here.
                        kind.map(|k| (tc, k)).ok_or(SendError::NoLink(self.robot()))
                    });
                    let _ = reply.send(r);
                }
                DashCmd::Resend { bytes } => self.send(&bytes),
                DashCmd::Follow(tx) => self.plan = Some(tx),
            }
        }
    }

    /// Numbers a TC of the page or a plan with this thread's sequence counter, shows it
    /// in the dashboard's history and sends it.
    pub(super) fn dash_tc(
        &mut self,
        def: &'static mib::tc::TcDef,
        args: &[i64],
        origin: &str,
    ) -> Result<BuiltTc, SendError> {
        if self.link.is_none() {
            return Err(SendError::NoLink(self.robot()));
        }
        // Check the arguments before using up a sequence count.
        pus::build_tc(self.robot(), 0, def, args)?;
        if def.name == "ACCEPT_CONFIG" {
            // The robot's configuration state changes: its module report is asked for
            // again (after ASK_AGAIN_MS, the TC executed by then) instead of waiting up to
            // 10 s for the MODULES housekeeping.
            self.modules.forget_report();
            self.modules_asked_ms = now_ms();
        }
        let seq = self.next_seq();
        let tc = pus::build_tc(self.robot(), seq, def, args)?;
        match &self.dash {
            Some(d) => ground_dashboard::tc_sent(&d.hub, self.robot(), &tc, def, args, origin),
            None => return Err(SendError::NoPage),
        };
        match &self.link {
            Some(l) => l.send(&tc.bytes).map_err(|error| SendError::Io {
                robot: self.robot(),
                error,
            })?,
            None => return Err(SendError::NoLink(self.robot())),
        }
        // It subscribes as any TC does (the re-subscription rule counts from it).
        self.last_sent_ms = Some(now_ms());
        self.archive_tc(&tc, origin);
        Ok(tc)
    }

    /// The page's TCs: a verification report about one of them (a damaged copy is sent
    /// again at once on a lab link).
    pub(super) fn page_verification(&mut self, v: &crate::pus::Verification) {
        let lab = self.link.as_ref().is_some_and(crate::link::Link::resends_packets);
        let robot = self.robot();
        match self.page_tcs.on_verification(robot, v, Instant::now(), lab) {
            Verdict::DamagedCopy {
                resend: Some(bytes), ..
            } => self.send(&bytes),
            Verdict::DamagedCopy { resend: None, .. } | Verdict::Report { .. } | Verdict::Unknown => {}
        }
    }

    /// The page's TCs whose wait ended: resent (lab link, until accepted), or given up.
    pub(super) fn page_tick(&mut self) {
        // Once accepted a page TC is never resent, and its later reports reach the page
        // through the hub whether or not it is still in the book.
        self.page_tcs.retain(|p| !p.accepted);
        let lab = self.link.as_ref().is_some_and(crate::link::Link::resends_packets);
        for d in self.page_tcs.on_tick(Instant::now(), |_| lab) {
            match d {
                Due::Resend { tc, send, .. } => {
                    tracing::info!(robot = self.robot(), "page TC {} resent (send {send})", tc.def.name);
                    self.send(&tc.bytes);
                }
                Due::Waited { .. } => {}
                Due::GaveUp(p) => tracing::warn!(
                    robot = self.robot(),
                    "page TC {} (seq {}): no {} after {} waits; its outcome is asked of the on-board store with every hole",
                    p.tc.def.name,
                    p.tc.seq,
                    if p.accepted { "completion" } else { "acceptance" },
                    p.sends
                ),
            }
        }
    }

    /// Hands the following plan run `msg`; a run that ended stops being followed.
    pub(super) fn tell_plan(&mut self, msg: PlanInput) {
        if let Some(tx) = &self.plan {
            if tx.send(msg).is_err() {
                self.plan = None;
            }
        }
    }

    pub(super) fn dash_link(&self) {
        if let Some(d) = &self.dash {
            // One enum: the page's state is the watch's (ground_dashboard re-exports it).
            d.hub.link(self.cfg.number, self.watch.state());
        }
    }
}
