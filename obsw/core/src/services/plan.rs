//! Service 18, on-board plans: the obsw hosts a `mmic_plan::Plan` (its own state and
//! rules) and connects it to the TC path.
//!
//! - TCs PLAN_LOAD .. PLAN_STATUS_REQUEST go to the plan's methods; every refusal is a
//!   MIB failure code of the TC. PLAN_COMMIT checks each step's TC as acceptance would
//!   (header, CRC, APID, service, arguments), refuses PUS 18 and PUS 11 insert TCs inside a
//!   plan, reconfigurations the map cannot do and hazardous TCs without the operator's flag.
//! - The component ([`OnboardPlan`]) owns the plan and the changes waiting to be
//!   reported; it reports through the downlink it is handed. Each control period the obsw
//!   (`Obsw::plan_tick`) asks it what to do; a step's TC goes through the ground TC path
//!   itself (mode, initial state, modules, busy checks; PUS 1 reports under the TC's own
//!   request ID), without the duplicate window and without counting as ground contact. Its
//!   outcome comes back from the one place outcomes are recorded (`Obsw::set_outcome`).
//! - A fault raised by FDIR suspends a running plan.
//! - Dependencies: the platform calls `Obsw::plan_team` every period to send the
//!   progress announcement over its authenticated team link, and the team service hands
//!   it every TM[211,7] it receives.

use mib::params::Source;
use mib::plan::TEAM_SUBSERVICE_PROGRESS;
use mib::tc::{function, service};
use mib::team::TEAM_SERVICE;
use mib_wire::{ev, tm, Failure as W, RequestId};
use mmic_plan::{Change, Plan, Poll, Refusal, StepKind, StepView};
use mmic_team::Dest;

use crate::accept::{accept, Tc};
use crate::downlink::Downlink;
use crate::failure::Failure;
use crate::obsw::Outcome;
use crate::request::unknown;
use crate::services::team::TeamLink;
use crate::services::{Component, Contract};
use crate::tm::{TmSink, TmStore, TmWriter};

/// The plan component and the state changes waiting to be reported.
pub struct OnboardPlan {
    pub plan: Plan,
    /// Changes learnt where no sink is at hand (an outcome), reported at the next tick.
    changes: heapless::Deque<Change, 4>,
}

impl OnboardPlan {
    pub fn new(robot: u8) -> Self {
        OnboardPlan {
            plan: Plan::new(robot),
            changes: heapless::Deque::new(),
        }
    }
}

/// A PUS 18 request.
#[derive(Clone, Copy, Debug)]
pub enum Request<'a> {
    Load { offset: u16, data: &'a [u8] },
    Commit { len: u16, crc: u32 },
    Start { plan_id: u32 },
    Suspend,
    Resume,
    Abort,
    Skip { step: u8 },
    Status,
}

impl<'a> Request<'a> {
    pub fn parse(tc: &Tc<'a>) -> Result<Self, Failure> {
        use mib::plan::sub;
        Ok(match tc.subservice {
            sub::LOAD => {
                let a = mib_wire::args::PlanLoad::of(&tc.args);
                if tc.rest.len() != usize::from(a.count) {
                    return Err(Failure::bad_arg_length(
                        tc.def.fixed_len() + tc.rest.len(),
                        tc.def.fixed_len() + usize::from(a.count),
                    ));
                }
                Request::Load {
                    offset: a.offset,
                    data: tc.rest,
                }
            }
            sub::COMMIT => {
                let a = mib_wire::args::PlanCommit::of(&tc.args);
                Request::Commit {
                    len: a.length,
                    crc: a.crc,
                }
            }
            sub::START => Request::Start {
                plan_id: mib_wire::args::PlanStart::of(&tc.args).plan_id,
            },
            sub::SUSPEND => Request::Suspend,
            sub::RESUME => Request::Resume,
            sub::ABORT => Request::Abort,
            sub::SKIP => Request::Skip {
                step: mib_wire::args::PlanSkip::of(&tc.args).step,
            },
            sub::STATUS_REQUEST => Request::Status,
            _ => return Err(unknown(tc)),
        })
    }
}

/// The PUS 1 failure of a plan refusal.
pub(crate) fn failure(r: Refusal) -> Failure {
    Failure(match r {
        Refusal::Busy(s) => W::PlanBusy { state: s.code() },
        Refusal::TooLarge { end } => W::PlanTooLarge {
            end,
            max: mib::plan::MAX_IMAGE_LEN as u16,
        },
        Refusal::Checksum {
            expected,
            computed,
            staged,
        } => W::PlanChecksum {
            expected,
            computed,
            staged,
        },
        Refusal::Invalid { reason, offset } => W::PlanInvalid { reason, offset },
        Refusal::WrongRobot(robot) => W::PlanWrongRobot { robot },
        Refusal::StepInvalid { step, code } => W::PlanStepInvalid { step, inner_code: code },
        Refusal::Unreachable { step, from, to } => W::PlanUnreachable { step, from, to },
        Refusal::HazardUnconfirmed { step } => W::PlanHazardUnconfirmed { step },
        Refusal::NotLoaded => W::PlanNotLoaded {},
        Refusal::BadState(s) => W::PlanBadState { state: s.code() },
        Refusal::StepMismatch { next, given } => W::PlanStepMismatch { next, given },
    })
}

/// PLAN_COMMIT's check of one step: what the robot can know before anything moves.
fn check_step(apid: u16, s: &StepView<'_>) -> Result<(), Refusal> {
    let StepKind::Tc(raw) = s.kind else { return Ok(()) };
    let step = s.index;
    let tc = accept(raw, apid).map_err(|r| Refusal::StepInvalid {
        step,
        code: r.code().code(),
    })?;
    // A plan does not load plans or schedules: what runs is what was checked here.
    if tc.service == service::PLAN || (tc.service == service::SCHEDULING && tc.subservice == 4) {
        return Err(Refusal::StepInvalid {
            step,
            code: mib::FailureCode::UNKNOWN_SERVICE.code(),
        });
    }
    if tc.def.hazard.is_some() && !s.confirmed {
        return Err(Refusal::HazardUnconfirmed { step });
    }
    if tc.def.service == service::FUNCTION && tc.def.function == function::RECONFIGURE {
        let (from, to) = (tc.args[0] as u8, tc.args[1] as u8);
        let near = mmic_domain::search::distance(from, to)
            .is_some_and(|d| usize::from(d) <= mib::config::MAX_RECONFIG_PRIMITIVES);
        if !near {
            return Err(Refusal::Unreachable { step, from, to });
        }
    }
    Ok(())
}

impl Component for OnboardPlan {
    const CONTRACT: Contract = Contract::new("plan", Some(service::PLAN), &[Source::Plan]);
    type Request<'a> = Request<'a>;
    type Output = Option<Change>;
    /// A PUS 18 request. `Ok(Some(change))`: an ABORT while a step's TC runs, whose action
    /// the obsw stops (as a ground STOP: its TC reports ABORTED_BY_COMMAND) before the
    /// change is reported ([`Self::report`]).
    fn handle<S: TmStore>(
        &mut self,
        now: u64,
        r: Request<'_>,
        dl: &mut Downlink<S>,
        sink: &mut impl TmSink,
    ) -> Result<Option<Change>, Failure> {
        let apid = dl.tmw.apid();
        let p = &mut self.plan;
        let change = match r {
            Request::Load { offset, data } => {
                p.load(offset, data).map_err(failure)?;
                return Ok(None);
            }
            Request::Commit { len, crc } => {
                let l = p.commit(len, crc, |s| check_step(apid, s)).map_err(failure)?;
                let e = ev::PlanLoaded {
                    plan_id: l.plan_id,
                    steps: l.steps,
                    crc: l.crc,
                };
                dl.raise(now, e, sink);
                return Ok(None);
            }
            Request::Start { plan_id } => p.start(plan_id).map_err(failure)?,
            Request::Suspend => p.suspend().map_err(failure)?,
            Request::Resume => p.resume().map_err(failure)?,
            Request::Skip { step } => p.skip(step).map_err(failure)?,
            Request::Abort => {
                let (c, tc_running) = p.abort().map_err(failure)?;
                if tc_running {
                    return Ok(Some(c));
                }
                c
            }
            Request::Status => {
                self.status(now, dl, sink);
                return Ok(None);
            }
        };
        Self::report(now, change, dl, sink);
        Ok(None)
    }
}

impl OnboardPlan {
    fn status<S: TmStore>(&self, now: u64, dl: &mut Downlink<S>, sink: &mut impl TmSink) {
        let b = self.plan.status();
        let r = tm::PlanStatus {
            plan_id: u32::from_be_bytes([b[0], b[1], b[2], b[3]]),
            state: b[4],
            steps: b[5],
            next_step: b[6],
            done: b[7],
            wait_robot: b[8],
            wait_step: b[9],
        };
        dl.emit_tm(now, &r, sink);
    }

    /// Reports a change of the plan's state (PLAN_STATE_CHANGED).
    pub(crate) fn report<S: TmStore>(now: u64, c: Change, dl: &mut Downlink<S>, sink: &mut impl TmSink) {
        let e = ev::PlanStateChanged {
            plan_id: c.plan_id,
            state: c.state.code(),
            step: c.step,
            cause: c.cause,
        };
        dl.raise(now, e, sink);
    }

    /// The outcome of request `req` was decided (from `Obsw::set_outcome`). `Err` when the
    /// change it made could not be kept for the next tick (counted by the obsw).
    pub(crate) fn outcome(&mut self, req: RequestId, outcome: &Outcome) -> Result<(), Change> {
        let ok = match outcome {
            Outcome::Pending => return Ok(()),
            Outcome::Done => true,
            Outcome::Failed(..) => false,
        };
        match self.plan.outcome(req.raw(), ok) {
            // Four changes in one period cannot happen (one step per period); should it,
            // the count says so.
            Some(c) => self.changes.push_back(c),
            None => Ok(()),
        }
    }

    /// FDIR raised a fault: a running plan is suspended.
    pub(crate) fn fault<S: TmStore>(&mut self, now: u64, dl: &mut Downlink<S>, sink: &mut impl TmSink) {
        if let Some(c) = self.plan.fault() {
            Self::report(now, c, dl, sink);
        }
    }

    /// Reports the changes learnt since the last report.
    pub(crate) fn report_pending<S: TmStore>(&mut self, now: u64, dl: &mut Downlink<S>, sink: &mut impl TmSink) {
        while let Some(c) = self.changes.pop_front() {
            Self::report(now, c, dl, sink);
        }
    }

    /// One control period of the plan: pending changes reported, then at most one thing
    /// the plan asks for (a wait to report, a change, or a step's TC, copied to `buf`
    /// with PLAN_STEP_STARTED raised: its length is returned, the obsw runs it through
    /// the TC path).
    pub(crate) fn tick<S: TmStore>(
        &mut self,
        now: u64,
        buf: &mut [u8; mib::plan::MAX_STEP_TC_LEN],
        dl: &mut Downlink<S>,
        sink: &mut impl TmSink,
    ) -> Option<usize> {
        self.report_pending(now, dl, sink);
        let plan_id = self.plan.plan_id();
        let (step, n) = match self.plan.poll(now) {
            Poll::Idle => return None,
            Poll::Waiting { step, on } => {
                let e = ev::PlanWaiting {
                    plan_id,
                    step,
                    robot: on.robot,
                    robot_step: on.step,
                };
                dl.raise(now, e, sink);
                return None;
            }
            Poll::Changed(c) => {
                Self::report(now, c, dl, sink);
                return None;
            }
            Poll::RunTc { step, tc } => {
                let n = tc.len().min(buf.len());
                buf[..n].copy_from_slice(&tc[..n]);
                (step, n)
            }
        };
        let seq_count = RequestId::of_tc(&buf[..n]).map_or(0, |r| r.seq());
        let e = ev::PlanStepStarted {
            plan_id,
            step,
            seq_count,
        };
        dl.raise(now, e, sink);
        Some(n)
    }

    /// A step's TC that acceptance refused (reported there): the step failed.
    pub(crate) fn step_refused<S: TmStore>(
        &mut self,
        now: u64,
        raw: &[u8],
        dl: &mut Downlink<S>,
        sink: &mut impl TmSink,
    ) {
        if let Ok(req) = RequestId::of_tc(raw) {
            if let Some(c) = self.plan.outcome(req.raw(), false) {
                Self::report(now, c, dl, sink);
            }
        }
    }

    /// Restores a plan the platform stored (`Plan::take_record`) at start; reports the
    /// state it comes back in. False when the record is no valid image of this robot.
    pub(crate) fn restore<S: TmStore>(
        &mut self,
        now: u64,
        image: &[u8],
        p: mmic_plan::exec::Progress,
        dl: &mut Downlink<S>,
        sink: &mut impl TmSink,
    ) -> bool {
        match self.plan.restore(image, p) {
            Some(c) => {
                Self::report(now, c, dl, sink);
                true
            }
            None => false,
        }
    }

    /// Sends the plan's progress announcement to every robot of the team link when due,
    /// written by the team's TM writer.
    pub(crate) fn announce(&mut self, now: u64, tmw: &mut TmWriter, link: &mut impl TeamLink) {
        let Some(data) = self.plan.announcement(now) else {
            return;
        };
        let mut out = [0u8; mib::config::MAX_PACKET_LEN];
        if let Some(n) = tmw.build(now, TEAM_SERVICE, TEAM_SUBSERVICE_PROGRESS, &data, &mut out) {
            let sent = link.send(Dest::All, &out[..n]);
            self.plan.sent(sent);
        }
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use crate::accept::tests::tc_bytes;
    use crate::obsw::tests::{failure, kind, obsw, of, send, TestObsw, APID};
    use mib::plan::{flag, state, MAX_IMAGE_LEN};
    use mib::FailureCode as F;
    use mmic_plan::image::{emit, StepRepr};
    use mmic_plan::{Dep, StepKind};

    /// One failure of each refusal of the plan, through the one mapping the service uses.
    pub(crate) fn every_failure() -> Vec<crate::failure::Failure> {
        use mmic_plan::{Refusal as R, State};
        [
            R::Busy(State::Running),
            R::TooLarge { end: 1030 },
            R::Checksum {
                expected: 1,
                computed: 2,
                staged: 3,
            },
            R::Invalid { reason: 1, offset: 9 },
            R::WrongRobot(2),
            R::StepInvalid { step: 1, code: 3 },
            R::Unreachable {
                step: 1,
                from: 0,
                to: 2,
            },
            R::HazardUnconfirmed { step: 1 },
            R::NotLoaded,
            R::BadState(State::Aborted),
            R::StepMismatch { next: 1, given: 2 },
        ]
        .into_iter()
        .map(super::failure)
        .collect()
    }

    /// An image of TCs for robot `robot`; `confirmed` sets every step's flag.
    fn image(robot: u8, tcs: &[Vec<u8>], confirmed: bool, deps: &[(usize, Dep)]) -> Vec<u8> {
        let steps: Vec<StepRepr> = tcs
            .iter()
            .enumerate()
            .map(|(i, t)| StepRepr {
                index: i as u8,
                confirmed,
                timeout_s: 10,
                deps: deps.iter().filter(|(s, _)| *s == i).map(|(_, d)| *d).collect(),
                kind: StepKind::Tc(t),
            })
            .collect();
        let mut out = [0u8; MAX_IMAGE_LEN];
        let n = emit(robot, 0x0A0B_0C0D, &steps, &mut out).unwrap();
        out[..n].to_vec()
    }

    /// Uploads `img` in chunks of 50 and commits it; returns the commit's packets.
    fn upload(o: &mut TestObsw, img: &[u8], seq: &mut u16) -> Vec<Vec<u8>> {
        for (i, c) in img.chunks(50).enumerate() {
            let mut app = ((i * 50) as u16).to_be_bytes().to_vec();
            app.push(c.len() as u8);
            app.extend_from_slice(c);
            *seq += 1;
            assert_eq!(of(&send(o, 10, *seq, 18, 1, &app), 1, 7).len(), 1, "chunk {i}");
        }
        let mut app = (img.len() as u16).to_be_bytes().to_vec();
        app.extend_from_slice(&img[img.len() - 4..]);
        *seq += 1;
        send(o, 10, *seq, 18, 2, &app)
    }

    fn start(o: &mut TestObsw, seq: u16) -> Vec<Vec<u8>> {
        send(o, 20, seq, 18, 3, &0x0A0B_0C0Du32.to_be_bytes())
    }

    fn ticks(o: &mut TestObsw, from: u64, n: u64) -> Vec<Vec<u8>> {
        let mut sink = Vec::new();
        for t in 0..n {
            let _ = o.tick(from + t * 10, &Default::default(), &[], &mut sink);
        }
        sink
    }

    // verifies: PLAN-EXEC-04
    #[test]
    fn each_step_runs_through_the_tc_path_with_its_own_pus1_reports_and_the_plan_completes() {
        let mut o = obsw();
        let sid = mib::hk::HK_STRUCTS[0].sid.to_be_bytes();
        let tcs = [tc_bytes(APID, 500, 17, 1, &[]), tc_bytes(APID, 501, 3, 27, &sid)];
        let mut seq = 0;
        let c = upload(&mut o, &image(1, &tcs, false, &[]), &mut seq);
        assert_eq!(of(&c, 1, 7).len(), 1, "committed");
        assert_eq!(o.param::<{ mib::params::pid::PLAN_STATE }>(), i64::from(state::LOADED));
        assert_eq!(of(&start(&mut o, 99), 1, 7).len(), 1);
        let out = ticks(&mut o, 30, 5);
        // Each step's reports carry its own request ID, as the ground would have seen them.
        for t in &tcs {
            let mine: Vec<(u8, u8)> = out
                .iter()
                .filter(|p| kind(p).0 == 1 && kind(p).2[..4] == t[..4])
                .map(|p| (kind(p).0, kind(p).1))
                .collect();
            assert_eq!(mine, [(1, 1), (1, 3), (1, 7)]);
        }
        assert_eq!(of(&out, 17, 2).len(), 1);
        assert_eq!(of(&out, 3, 25).len(), 1);
        assert_eq!(
            o.param::<{ mib::params::pid::PLAN_STATE }>(),
            i64::from(state::COMPLETED)
        );
        assert_eq!(o.param::<{ mib::params::pid::PLAN_DONE }>(), 2);
    }

    // verifies: PLAN-EXEC-04, MMIC-MODE-01
    #[test]
    fn a_step_refused_by_the_mode_check_suspends_the_plan_and_resume_runs_it_again() {
        let mut o = obsw();
        // RECONFIGURE in standby: refused NOT_ALLOWED_IN_MODE, as from the ground.
        let tcs = [tc_bytes(APID, 600, 8, 1, &[0, 1, 0, 1])];
        let mut seq = 0;
        upload(&mut o, &image(1, &tcs, false, &[]), &mut seq);
        start(&mut o, 98);
        let out = ticks(&mut o, 30, 3);
        let f = of(&out, 1, 4);
        assert_eq!(failure(&f[0]).0, F::NOT_ALLOWED_IN_MODE.code());
        assert_eq!(
            o.param::<{ mib::params::pid::PLAN_STATE }>(),
            i64::from(state::SUSPENDED)
        );
        assert!(of(&ticks(&mut o, 100, 5), 1, 4).is_empty(), "suspended: not sent again");
        assert_eq!(of(&send(&mut o, 200, 97, 18, 5, &[]), 1, 7).len(), 1);
        assert_eq!(
            of(&ticks(&mut o, 210, 2), 1, 4).len(),
            1,
            "resumed: the same step again"
        );
    }

    // verifies: PLAN-LOAD-02
    #[test]
    fn a_corrupted_plan_another_robots_plan_and_an_unconfirmed_hazard_are_refused_with_their_codes() {
        let mut o = obsw();
        let mut app = mib::modes::node::ROBOT.to_be_bytes().to_vec();
        app.extend_from_slice(&[0, 0, 0, 1, 0, 0]);
        let mode_set = tc_bytes(APID, 700, 200, 1, &app);
        let ping = tc_bytes(APID, 701, 17, 1, &[]);
        let mut seq = 0;
        let code = |p: &[Vec<u8>]| failure(&of(p, 1, 4)[0]).0;
        // Corrupted in transit: one byte of the staged image flipped.
        let mut img = image(1, std::slice::from_ref(&ping), false, &[]);
        let crc = img[img.len() - 4..].to_vec();
        img[12] ^= 1;
        img.truncate(img.len() - 4);
        img.extend_from_slice(&crc);
        assert_eq!(code(&upload(&mut o, &img, &mut seq)), F::PLAN_CHECKSUM.code());
        assert_eq!(
            code(&upload(
                &mut o,
                &image(2, std::slice::from_ref(&ping), false, &[]),
                &mut seq
            )),
            F::PLAN_WRONG_ROBOT.code()
        );
        let c = upload(
            &mut o,
            &image(1, &[ping.clone(), mode_set.clone()], false, &[]),
            &mut seq,
        );
        assert_eq!(failure(&of(&c, 1, 4)[0]), (F::PLAN_HAZARD_UNCONFIRMED.code(), vec![1]));
        // A step for another APID is what its acceptance would refuse.
        let c = upload(
            &mut o,
            &image(1, &[tc_bytes(0x102, 1, 17, 1, &[])], false, &[]),
            &mut seq,
        );
        let (code2, data) = failure(&of(&c, 1, 4)[0]);
        assert_eq!(
            (code2, u16::from_be_bytes([data[1], data[2]])),
            (F::PLAN_STEP_INVALID.code(), F::WRONG_APID.code())
        );
        // Nothing loaded, nothing moves.
        assert_eq!(o.param::<{ mib::params::pid::PLAN_STATE }>(), i64::from(state::EMPTY));
        assert_eq!(failure(&of(&start(&mut o, 90), 1, 4)[0]).0, F::PLAN_NOT_LOADED.code());
        // Confirmed: loaded.
        let c = upload(&mut o, &image(1, &[ping, mode_set], true, &[]), &mut seq);
        assert_eq!(of(&c, 1, 7).len(), 1);
        let _ = flag::CONFIRMED;
    }

    // verifies: PLAN-TEAM-01
    #[test]
    fn a_step_after_another_robots_step_waits_for_its_announcement_over_the_team_link() {
        use crate::services::team::{TeamLink, TeamRecord};
        #[derive(Default)]
        struct Wire(Vec<Vec<u8>>);
        impl TeamLink for Wire {
            fn persist(&mut self, _: &TeamRecord) -> bool {
                true
            }
            fn send(&mut self, _: mmic_team::Dest, p: &[u8]) -> u32 {
                self.0.push(p.to_vec());
                1
            }
        }
        let mut r1 = obsw();
        let mut r2: TestObsw = crate::obsw::Obsw::new(
            crate::obsw::Config {
                robot: 2,
                epoch_unix_ms: 1_790_000_000_000,
            },
            Default::default(),
        );
        let mut seq = 0;
        upload(
            &mut r1,
            &image(1, &[tc_bytes(APID, 800, 17, 1, &[])], false, &[]),
            &mut seq,
        );
        let mut sink = Vec::new();
        for (i, b) in image(
            2,
            &[tc_bytes(0x102, 900, 17, 1, &[])],
            false,
            &[(0, Dep { robot: 1, step: 0 })],
        )
        .chunks(50)
        .enumerate()
        {
            let mut app = ((i * 50) as u16).to_be_bytes().to_vec();
            app.push(b.len() as u8);
            app.extend_from_slice(b);
            r2.handle_tc(10, &tc_bytes(0x102, 1 + i as u16, 18, 1, &app), &mut sink);
        }
        let img2 = image(
            2,
            &[tc_bytes(0x102, 900, 17, 1, &[])],
            false,
            &[(0, Dep { robot: 1, step: 0 })],
        );
        let mut app = (img2.len() as u16).to_be_bytes().to_vec();
        app.extend_from_slice(&img2[img2.len() - 4..]);
        r2.handle_tc(10, &tc_bytes(0x102, 20, 18, 2, &app), &mut sink);
        r2.handle_tc(
            10,
            &tc_bytes(0x102, 21, 18, 3, &0x0A0B_0C0Du32.to_be_bytes()),
            &mut sink,
        );
        sink.clear();
        // Robot 2 alone: waits, however long.
        let mut w2 = Wire::default();
        // The plan's part of the control period only: without a simulator the rest of
        // the obsw would raise faults (board B silent), which suspend a plan.
        for t in 0..20 {
            r2.plan_tick(20 + t * 10, &mut sink);
            r2.plan_team(20 + t * 10, &mut w2);
        }
        assert!(of(&sink, 17, 2).is_empty(), "robot 2 did not start");
        assert_eq!(
            r2.param::<{ mib::params::pid::PLAN_STATE }>(),
            i64::from(state::RUNNING)
        );
        assert_eq!(r2.param::<{ mib::params::pid::PLAN_WAIT_ROBOT }>(), 1);
        // Robot 1 runs its step; its announcement reaches robot 2 (a forged sender does not).
        start(&mut r1, 50);
        let mut w1 = Wire::default();
        let mut s1 = Vec::new();
        for t in 0..5 {
            r1.plan_tick(30 + t * 10, &mut s1);
            r1.plan_team(30 + t * 10, &mut w1);
        }
        assert_eq!(of(&s1, 17, 2).len(), 1);
        let ann = w1.0.last().unwrap().clone();
        r2.team_packet(250, 0, Some(3), &ann, &mut w2, &mut sink);
        r2.plan_tick(260, &mut sink);
        assert!(of(&sink, 17, 2).is_empty(), "claimed by robot 3: ignored");
        r2.team_packet(270, 0, Some(1), &ann, &mut w2, &mut sink);
        assert_eq!(r2.param::<{ mib::params::pid::PLAN_PROGRESS_RECEIVED }>(), 1);
        for t in 0..3 {
            r2.plan_tick(280 + t * 10, &mut sink);
        }
        assert_eq!(of(&sink, 17, 2).len(), 1, "robot 2 ran its step after robot 1's");
        assert_eq!(
            r2.param::<{ mib::params::pid::PLAN_STATE }>(),
            i64::from(state::COMPLETED)
        );
        assert_eq!(r2.param::<{ mib::params::pid::PLAN_PROGRESS_IGNORED }>(), 1);
    }
}
