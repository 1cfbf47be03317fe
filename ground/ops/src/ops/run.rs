//! [`run_plan`]: drives the [`Executor`] with a [`Session`]: start markers, resolution
//! of a resumed run's unknown TCs, interruption, gap retrieval, the live display.

use std::collections::{BTreeMap, BTreeSet, HashMap, VecDeque};
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

use mib::headers::SeqCount;

use crate::plan::Plan;
use crate::pus::BuiltTc;

use super::*;

/// How long one wait for the robots' TM lasts in the run's loops (the executor's tick).
const POLL: Duration = Duration::from_millis(50);

struct Display {
    mp: indicatif::MultiProgress,
    total: indicatif::ProgressBar,
    robots: BTreeMap<u8, indicatif::ProgressBar>,
    visible: bool,
}

impl Display {
    fn new(plan: &Plan, robots: &[u8], want: bool) -> Display {
        use indicatif::{MultiProgress, ProgressBar, ProgressDrawTarget, ProgressStyle};
        let target = if want {
            ProgressDrawTarget::stderr_with_hz(10)
        } else {
            ProgressDrawTarget::hidden()
        };
        let mp = MultiProgress::with_draw_target(target);
        let total = mp.add(ProgressBar::new(plan.steps.len() as u64));
        total.set_style(
            ProgressStyle::with_template("{prefix:>9} [{bar:30}] {pos}/{len} steps {elapsed} {msg}")
                .unwrap_or_else(|_| ProgressStyle::default_bar())
                .progress_chars("=> "),
        );
        total.set_prefix(plan.name.clone());
        let mut bars = BTreeMap::new();
        for &r in robots {
            let b = mp.add(ProgressBar::new_spinner());
            b.set_style(
                ProgressStyle::with_template("{prefix:>9} {spinner} {msg}")
                    .unwrap_or_else(|_| ProgressStyle::default_spinner()),
            );
            b.set_prefix(format!("robot {r}"));
            bars.insert(r, b);
        }
        let visible = !mp.is_hidden();
        Display {
            mp,
            total,
            robots: bars,
            visible,
        }
    }
    fn log(&self, line: String) {
        if self.visible {
            let _ = self.mp.println(line);
        } else {
            // A closed stderr must not stop a run.
            use std::io::Write as _;
            let _ = writeln!(std::io::stderr().lock(), "{line}");
        }
    }
}

/// What `--resume` hands to [`run_plan`]: the state of the run's earlier session(s).
#[derive(Clone, Debug, Default)]
pub struct Resume {
    /// Steps completed earlier: not sent again.
    pub done: Vec<usize>,
    /// Steps whose TC was sent earlier but whose outcome the archive does not show.
    pub in_flight: Vec<InFlight>,
    /// Per robot, the last TM sequence count of its APID in the archive: the on-board
    /// store is asked for everything after it before anything is sent.
    pub last_seq: Vec<(u8, u16)>,
    /// The robots run the plan themselves (`--on-board`): its step TCs are tracked,
    /// never sent by the ground.
    pub on_board: Option<super::onboard::OnBoard>,
    /// Steps whose TC failed earlier, with why: a ground-driven resume sends them again;
    /// on board they are the robot's (its plan is suspended there), so they stay failed.
    pub failed: Vec<(usize, String)>,
}

/// A step whose TC an earlier session sent, outcome unknown.
#[derive(Clone, Debug)]
pub struct InFlight {
    pub step: usize,
    pub tc: BuiltTc,
    /// The archive has its acceptance report.
    pub accepted: bool,
}

/// Executes a plan: each step is sent once every step it depends on has completed.
/// `resume` holds what earlier sessions of the same run did (`--resume`).
pub fn run_plan(plan: &Plan, session: &mut Session, opts: &RunOptions, resume: &Resume) -> RunSummary {
    let robots: Vec<u8> = plan.robots.iter().map(|r| r.number).collect();
    let disp = Display::new(plan, &robots, opts.display);
    let mut exec = Executor::new(plan, opts, &resume.done, Instant::now());
    let mut last_gap_check = Instant::now();
    // Robots whose periodic gap check waits for the pacing rule to let a retrieval go.
    let mut gap_check_due: BTreeSet<u8> = BTreeSet::new();
    disp.total.inc(exec.resumed as u64);
    if exec.resumed > 0 {
        disp.log(format!(
            "  resume   {} steps completed earlier in this run are not sent again",
            exec.resumed
        ));
    }
    let stop_asked = || opts.stop.as_ref().is_some_and(|f| f.load(Ordering::SeqCst));
    // TCs of the earlier session whose outcome is unknown: tracked again (never resent),
    // and the TM the ground missed since is asked of the on-board store first.
    for f in &resume.in_flight {
        let Some(st) = plan.steps.get(f.step) else { continue };
        session.adopt(st.robot, f.tc.clone(), Some(f.step), Some(st.id.clone()), f.accepted);
        exec.adopt(f.step, f.tc.clone(), "outcome asked of the store", Instant::now());
        disp.log(format!(
            "  resume   {} robot {}: {} (seq {}) was sent before the interruption, {}; resolving its outcome before anything is sent",
            st.id,
            st.robot,
            f.tc.def.name,
            f.tc.seq,
            if f.accepted { "accepted, no completion archived" } else { "no report archived" }
        ));
        if let Some((_, last)) = resume.last_seq.iter().find(|(r, _)| *r == st.robot) {
            if let Some(s) = session.robots.get_mut(&st.robot) {
                if s.seq.newest().is_none() {
                    s.seq.expect_from(SeqCount::new(*last).next().get());
                }
            }
        }
    }
    // Reattached to a plan on board: what the robots sent while the ground was away (after
    // the last TM the archive has) is asked of their stores, as for a resumed TC.
    if resume.on_board.is_some() {
        for (r, last) in &resume.last_seq {
            if let Some(s) = session.robots.get_mut(r) {
                if s.seq.newest().is_none() {
                    s.seq.expect_from(SeqCount::new(*last).next().get());
                }
            }
        }
    }
    // Every session of a run starts with a start marker per robot: it names the run in
    // the archive (see `runs`) and, answered, starts the TM accounting.
    let watch = opts.ping_period.is_some() || !resume.in_flight.is_empty();
    if watch {
        session.watch_links();
    }
    let mut early = start_markers(session, &robots, watch, &stop_asked);
    let detach = on_board(plan, session, &mut exec, resume, &disp, &mut early);
    if opts.tm_from_boot {
        // Robots booted for this run: everything from their first packet is the run's
        // TM; what they sent before the ground listened is asked of their store.
        for &r in &robots {
            if let Some(s) = session.robots.get_mut(&r) {
                s.run_first_seq = Some(crate::live::BOOT_FIRST_SEQ);
                s.seq.expect_from(crate::live::BOOT_FIRST_SEQ);
            }
        }
    }
    let apply = |fx: Vec<Effect>, exec: &mut Executor, session: &mut Session| {
        let mut queue: VecDeque<Effect> = fx.into();
        while let Some(e) = queue.pop_front() {
            match e {
                Effect::Send { step, robot, def, args } => {
                    let label = Some(plan.steps[step].id.clone());
                    let sent = session
                        .send(robot, def, &args, Some(step), label)
                        .map_err(SendError::from);
                    queue.extend(exec.on_sent(step, sent, Instant::now()));
                }
                Effect::Forget(tc) => session.forget(&tc),
                Effect::Heartbeat(r) => {
                    // Not when another TC just went out: every TC enters the OBSW's
                    // duplicate window, which must keep the plan's TCs for their whole
                    // retry span. A failed send shows as silence: the link-loss check
                    // reports it.
                    let period = opts.ping_period.unwrap_or_default();
                    if !session.sent_within(r, period) {
                        let _ = session.send_heartbeat(r);
                    }
                }
                // Sent when the pacing rule lets one go (`Session::may_retrieve`).
                Effect::Retrieve(r) => {
                    session.request_missing_reports(r, mib::ground_config::GAP_REQUESTS_LIVE);
                }
                Effect::Log(line) => disp.log(line),
                Effect::Finished => disp.total.inc(1),
            }
        }
    };
    for u in early {
        let fx = exec.on_update(Instant::now(), u);
        apply(fx, &mut exec, session);
    }
    if !resume.in_flight.is_empty() {
        let fx = resolve_in_flight(session, &mut exec, resume, &stop_asked);
        apply(fx, &mut exec, session);
    }
    loop {
        if detach {
            // The robots carry on alone; `--on-board --resume` follows them later.
            break;
        }
        if stop_asked() {
            let fx = exec.interrupt(Instant::now(), opts.grace);
            apply(fx, &mut exec, session);
        }
        let fx = exec.on_tick(Instant::now());
        apply(fx, &mut exec, session);
        if exec.finished() || exec.stopped(Instant::now()) {
            break;
        }
        for u in session.poll(POLL) {
            let fx = exec.on_update(Instant::now(), u);
            apply(fx, &mut exec, session);
        }
        // TM gaps are filled from the on-board store while the plan runs, those after the
        // oldest TC awaiting its outcome first (its reports are there).
        // Over frames a gap where an awaited TC's reports are is asked for at once.
        if session.over_frames() {
            for &r in &robots {
                if session.may_retrieve(r) && !session.awaited_gaps(r).is_empty() {
                    session.request_missing_reports(r, mib::ground_config::GAP_REQUESTS_AWAITED);
                }
            }
        }
        let period = if session.over_frames() {
            GAP_CHECK_PERIOD_FRAMES
        } else {
            GAP_CHECK_PERIOD
        };
        if last_gap_check.elapsed() >= period {
            last_gap_check = Instant::now();
            gap_check_due.extend(&robots);
        }
        // A check is done when the pacing rule lets its retrieval go (at once, unless one
        // is in flight or went out less than the least gap ago).
        gap_check_due.retain(|&r| {
            if session.robots.get(&r).is_none_or(|s| s.lost.is_some()) {
                return false;
            }
            if !session.may_retrieve(r) {
                return true;
            }
            // One range per period: over bare packets plan TCs may still be resent (the
            // duplicate window holds a bounded number of TCs), over frames retrievals
            // queued in FOP-1 would hold the plan's next TC back. The rest at the end.
            session.request_missing_reports(r, mib::ground_config::GAP_REQUESTS_LIVE);
            false
        });
        for (&r, bar) in &disp.robots {
            let st = session.robots.get(&r).map(|s| s.line()).unwrap_or_default();
            bar.set_message(format!("{} | {st}", exec.robot_line(r)));
            bar.tick();
        }
    }
    // An interrupted run ends at once: the TM it missed is filled by the next session.
    let tm = if opts.ping_period.is_some() && !stop_asked() && !detach {
        // The events the retrieval brings (a bolt's or unbolt's report lost live) count in
        // the summary like those heard live.
        let mut seen = Vec::new();
        let tm = complete_tm(session, &robots, &disp, &stop_asked, &mut seen);
        for u in seen {
            if matches!(u, Update::Event { .. }) {
                let _ = exec.on_update(Instant::now(), u);
            }
        }
        tm
    } else {
        Vec::new()
    };
    disp.total.finish();
    for b in disp.robots.values() {
        b.finish();
    }
    let _ = disp.mp.clear();
    let mut summary = exec.summary(session, Instant::now());
    summary.tm = tm;
    summary
}

/// A plan the robots run themselves: every step TC not completed yet is tracked under its
/// request ID (never sent), the archive gets the TCs of a new upload (`--resume` finds
/// them), the images are uploaded and started. A refusal fails every step: nothing moved.
/// Returns true when the run detaches once the robots started.
fn on_board(
    plan: &Plan,
    session: &mut Session,
    exec: &mut Executor,
    resume: &Resume,
    disp: &Display,
    early: &mut Vec<Update>,
) -> bool {
    let Some(ob) = &resume.on_board else { return false };
    for (i, why) in &resume.failed {
        for e in exec.fail_step(*i, format!("failed on board: {why}")) {
            if let Effect::Log(l) = e {
                disp.log(l);
            }
        }
    }
    for (i, tc) in &ob.compiled.tcs {
        let Some(st) = plan.steps.get(*i) else { continue };
        if matches!(exec.state[*i], StepState::Done { .. }) {
            continue;
        }
        if ob.upload {
            session.adopt_new(st.robot, tc.clone(), Some(*i), Some(st.id.clone()));
            session.archive_tc(tc, &st.id);
        } else {
            session.adopt(st.robot, tc.clone(), Some(*i), Some(st.id.clone()), false);
        }
        exec.run_on_board(*i, tc.clone());
    }
    if !ob.upload {
        disp.log(format!(
            "  on board plan {:#010x}: following the robots' progress",
            ob.compiled.plan_id
        ));
        return false;
    }
    let (seen, r) = super::onboard::upload_and_start(session, &ob.compiled);
    early.extend(seen);
    match r {
        Ok(()) => {
            let sizes: Vec<String> = ob
                .compiled
                .images
                .iter()
                .map(|i| format!("robot {}: {} bytes", i.robot, i.bytes.len()))
                .collect();
            disp.log(format!(
                "  on board plan {:#010x} loaded and started ({})",
                ob.compiled.plan_id,
                sizes.join(", ")
            ));
            ob.detach
        }
        Err(why) => {
            disp.log(format!("  REFUSED  on-board plan: {why}"));
            for i in 0..plan.steps.len() {
                if !exec.state[i].terminal() {
                    for e in exec.fail_step(i, format!("not started on board: {why}")) {
                        if let Effect::Log(l) = e {
                            disp.log(l);
                        }
                    }
                }
            }
            false
        }
    }
}

/// Starts every robot's TM accounting: a connection test (resent until answered) whose
/// reports give the first sequence count of the run; every TM from there on is expected.
/// Returns what happened meanwhile (a link found lost, reports of adopted TCs).
fn start_markers(session: &mut Session, robots: &[u8], wait: bool, stop: &dyn Fn() -> bool) -> Vec<Update> {
    let Some(ping) = mib::tc::by_name("PING") else {
        return Vec::new();
    };
    // A first TM from each robot (at most FIRST_TM_WAIT) gives the count a marker whose
    // reports are all lost is placed after.
    let mut seen: Vec<Update> = Vec::new();
    let t0 = Instant::now();
    while wait
        && session.over_frames()
        && t0.elapsed() < FIRST_TM_WAIT
        && !stop()
        && robots
            .iter()
            .any(|r| session.robots.get(r).is_some_and(|s| s.seq.newest().is_none()))
    {
        seen.extend(session.poll(POLL));
    }
    // Over frames a marker is delivered once (COP-1), not resent like on the lab links;
    // when all its reports are lost and no TM came before it, nothing fixes the run's
    // first count. Then another marker goes out (the TM heard meanwhile bounds its count
    // from below), up to the MIB's number of sends: the frame link's way of what the lab
    // link's resend of the marker did.
    let mut pending: Vec<u8> = robots.to_vec();
    for _ in 0..=mib::ground_config::TC_RETRY_MAX {
        let mut markers = Vec::new();
        for &r in &pending {
            // The newest count before the marker: over frames, a marker whose reports are
            // lost still bounds the run's TM from below by the one after it.
            let before = session.robots.get(&r).and_then(|s| s.seq.newest());
            if let Ok(m) = session.send(r, ping, &[], None, Some(START_LABEL.into())) {
                markers.push((r, m, before));
            }
        }
        let t0 = Instant::now();
        let limit = Duration::from_millis(mib::ground_config::TC_RETRY_SPAN_MS as u64);
        let mut delivered_at: HashMap<u8, Instant> = HashMap::new();
        while wait
            && t0.elapsed() < limit
            && !stop()
            && markers.iter().any(|(r, m, _)| {
                // Answered once accepted: its first report gives the run's first count.
                // Over frames, delivered (CLCW) and settled is enough.
                let settled = delivered_at.get(r).is_some_and(|t| t.elapsed() >= MARKER_SETTLE);
                !settled
                    && session.accepted(m) == Some(false)
                    && session.robots.get(r).is_some_and(|s| s.lost.is_none())
            })
        {
            seen.extend(session.poll(POLL));
            for (r, m, _) in &markers {
                if session.delivered(*r, m) {
                    delivered_at.entry(*r).or_insert_with(Instant::now);
                }
            }
        }
        pending.clear();
        for (r, _, before) in markers {
            if let Some(s) = session.robots.get_mut(&r) {
                if s.run_first_seq.is_none() && delivered_at.contains_key(&r) {
                    s.run_first_seq = before.map(|b| SeqCount::new(b).next().get());
                }
                if let Some(f) = s.run_first_seq {
                    s.seq.expect_from(f);
                } else if wait && delivered_at.contains_key(&r) && s.lost.is_none() && !stop() {
                    pending.push(r);
                }
            }
        }
        if pending.is_empty() {
            break;
        }
    }
    seen
}

/// Resolves the TCs of an interrupted session (`--resume`) before anything is sent: the
/// on-board store is asked for every TM the ground missed since its last archived one,
/// until none is missing. Then a TC with a report ends as it says; one accepted without
/// completion is still running on board (its completion is awaited); one with no report
/// at all in a complete TM stream never reached the robot and is sent again as a new TC;
/// one whose TM cannot be completed (overwritten, not answered) fails as "outcome
/// unknown" and is never sent again.
fn resolve_in_flight(
    session: &mut Session,
    exec: &mut Executor,
    resume: &Resume,
    stop: &dyn Fn() -> bool,
) -> Vec<Effect> {
    let in_flight = &resume.in_flight;
    let mut fx = Vec::new();
    let robots: Vec<u8> = {
        let mut r: Vec<u8> = in_flight
            .iter()
            .filter_map(|f| exec.plan.steps.get(f.step))
            .map(|s| s.robot)
            .collect();
        r.dedup();
        r
    };
    let expired0: HashMap<u8, u64> = robots
        .iter()
        .map(|&r| (r, session.robots.get(&r).map_or(0, |s| s.seq.lost_packets)))
        .collect();
    let t0 = Instant::now();
    let limit = Duration::from_millis(mib::ground_config::TC_RETRY_SPAN_MS as u64);
    let mut idle_rounds = 0;
    loop {
        let open: Vec<u8> = robots
            .iter()
            .copied()
            .filter(|&r| {
                session
                    .robots
                    .get(&r)
                    .is_some_and(|s| s.lost.is_none() && s.seq.holes() > 0)
                    && in_flight.iter().any(|f| session.is_pending(&f.tc))
            })
            .collect();
        if open.is_empty() || t0.elapsed() >= limit || stop() || idle_rounds >= GAP_ROUNDS_IDLE_MAX {
            break;
        }
        let before: usize = open
            .iter()
            .map(|r| session.robots.get(r).map_or(0, |s| s.seq.holes()))
            .sum();
        // The pacing rule: the last retrieval ended and the least gap since it.
        let wait = Instant::now();
        while wait.elapsed() < GAP_ROUND_WAIT && !open.iter().all(|&r| session.may_retrieve(r)) && !stop() {
            for u in session.poll(POLL) {
                fx.extend(exec.on_update(Instant::now(), u));
            }
        }
        for &r in &open {
            session.request_gaps(r, None, GAP_REQUESTS_MAX);
        }
        let round = Instant::now();
        while round.elapsed() < GAP_ROUND_WAIT && open.iter().any(|&r| session.retrieving(r)) {
            for u in session.poll(POLL) {
                fx.extend(exec.on_update(Instant::now(), u));
            }
        }
        let settle = Instant::now();
        while settle.elapsed() < GAP_SETTLE {
            for u in session.poll(POLL) {
                fx.extend(exec.on_update(Instant::now(), u));
            }
        }
        let after: usize = open
            .iter()
            .map(|r| session.robots.get(r).map_or(0, |s| s.seq.holes()))
            .sum();
        idle_rounds = if after < before { 0 } else { idle_rounds + 1 };
    }
    for f in in_flight {
        if !session.is_pending(&f.tc) {
            continue; // ended by its reports (or the link loss)
        }
        let Some(step) = exec.plan.steps.get(f.step) else {
            continue;
        };
        let r = step.robot;
        // Complete: every count from the last archived one up to the newest received,
        // the newest ahead of it (a robot that restarted counts from 0 again: its TM
        // does not continue the archive's, and the TC's fate is unknown).
        let last = resume.last_seq.iter().find(|(x, _)| *x == r).map(|(_, q)| *q);
        let complete = session.robots.get(&r).is_some_and(|s| {
            let ahead = match (s.seq.newest(), last) {
                (Some(n), Some(l)) => {
                    (1..crate::live::RECENT_WINDOW as u16).contains(&SeqCount::new(n).since(SeqCount::new(l)))
                }
                (Some(_), None) => true,
                (None, _) => false,
            };
            s.lost.is_none()
                && ahead
                && s.seq.holes() == 0
                && s.seq.lost_packets == expired0.get(&r).copied().unwrap_or(0)
        });
        match (complete, session.accepted(&f.tc).unwrap_or(f.accepted)) {
            (true, true) => fx.push(Effect::Log(format!(
                "  resume   {}: accepted and still running on board; its completion is awaited",
                step.id
            ))),
            (true, false) => {
                session.forget(&f.tc);
                exec.requeue(f.step);
                fx.push(Effect::Log(format!(
                    "  resume   {}: its TC (seq {}) never reached the robot (no report in the complete TM since): sent as a new TC",
                    step.id, f.tc.seq
                )));
            }
            (false, _) => {
                session.forget(&f.tc);
                fx.extend(exec.fail_step(
                    f.step,
                    format!(
                        "outcome unknown: {} (seq {}) may have executed, and the robot's TM since the interruption cannot be completed (store overwritten, robot restarted or not answering); not sent again: check the robot, then send the step by hand",
                        f.tc.def.name, f.tc.seq
                    ),
                ));
            }
        }
    }
    fx
}

/// The MIB's ground timing (`mib::config`) as durations.
const GAP_CHECK_PERIOD: Duration = Duration::from_millis(mib::ground_config::GAP_CHECK_PERIOD_MS as u64);
const GAP_CHECK_PERIOD_FRAMES: Duration = Duration::from_millis(mib::ground_config::GAP_CHECK_PERIOD_FRAMES_MS as u64);
const FIRST_TM_WAIT: Duration = Duration::from_millis(mib::ground_config::FIRST_TM_WAIT_MS as u64);
const MARKER_SETTLE: Duration = Duration::from_millis(mib::ground_config::MARKER_SETTLE_MS as u64);
/// [`mib::ground_config::GAP_ROUNDS_IDLE_MAX`]: retrieval rounds at the end of a run that bring
/// nothing back before the rest counts as not recovered.
const GAP_ROUNDS_IDLE_MAX: u32 = mib::ground_config::GAP_ROUNDS_IDLE_MAX;
/// [`mib::ground_config::GAP_ROUNDS_MAX`]: retrieval rounds at the end of a run at most.
const GAP_ROUNDS_MAX: u32 = mib::ground_config::GAP_ROUNDS_MAX;
/// [`mib::ground_config::GAP_ROUND_WAIT_MS`]: longest wait for one round's requests to end.
const GAP_ROUND_WAIT: Duration = Duration::from_millis(mib::ground_config::GAP_ROUND_WAIT_MS as u64);
/// [`mib::ground_config::GAP_SETTLE_MS`]: replays still on their way after a round.
const GAP_SETTLE: Duration = Duration::from_millis(mib::ground_config::GAP_SETTLE_MS as u64);

/// Ends a run's TM: an end marker (a connection test, resent until answered) fixes how
/// far the TM must be complete; then every gap up to it is asked of the on-board store
/// until it is filled, found overwritten, or `GAP_ROUNDS_MAX` rounds passed.
fn complete_tm(
    session: &mut Session,
    robots: &[u8],
    disp: &Display,
    stop: &dyn Fn() -> bool,
    seen: &mut Vec<Update>,
) -> Vec<TmCompleteness> {
    let mut out = Vec::new();
    let Some(ping) = mib::tc::by_name("PING") else {
        return out;
    };
    for &r in robots {
        let mut c = TmCompleteness {
            robot: r,
            from: session.robots.get(&r).and_then(|s| s.run_first_seq),
            upto: None,
            overwritten: Vec::new(),
            not_received: Vec::new(),
            retrievals: 0,
        };
        if session.robots.get(&r).is_none_or(|s| s.lost.is_some()) {
            out.push(c);
            continue;
        }
        let marker = session.send(r, ping, &[], None, Some("end marker".into()));
        let limit = Duration::from_millis(mib::ground_config::TC_RETRY_SPAN_MS as u64);
        if let Ok(m) = &marker {
            let t0 = Instant::now();
            // Over frames a marker whose acceptance report was lost is known delivered
            // from the CLCW: after MARKER_SETTLE the TM received covers it (its own
            // reports are then a gap below the cut, filled like any other).
            let mut delivered_at: Option<Instant> = None;
            while t0.elapsed() < limit && session.accepted(m) == Some(false) && !stop() {
                seen.extend(session.poll(POLL));
                if session.robots.get(&r).is_some_and(|s| s.lost.is_some()) {
                    break;
                }
                if delivered_at.is_none() && session.delivered(r, m) {
                    delivered_at = Some(Instant::now());
                }
                if delivered_at.is_some_and(|t| t.elapsed() >= MARKER_SETTLE) {
                    break;
                }
            }
        }
        let upto = session.robots.get(&r).and_then(|s| s.seq.newest());
        c.upto = upto;
        let Some(cut) = upto else {
            out.push(c);
            continue;
        };
        let mut rounds = 0;
        let mut idle_rounds = 0;
        let mut before = usize::MAX;
        loop {
            let missing = session
                .robots
                .get(&r)
                .map(|s| s.seq.missing_upto(cut))
                .unwrap_or_default();
            let count = session.robots.get(&r).map_or(0, |s| s.seq.holes());
            if count >= before {
                idle_rounds += 1;
            } else {
                idle_rounds = 0;
            }
            before = count;
            // A Ctrl-C here ends the retrieval: the next session fills the rest.
            if missing.is_empty() || rounds >= GAP_ROUNDS_MAX || idle_rounds >= GAP_ROUNDS_IDLE_MAX || stop() {
                break;
            }
            // The pacing rule: the last retrieval ended and the least gap since it.
            let t0 = Instant::now();
            while t0.elapsed() < limit && !session.may_retrieve(r) && !stop() {
                seen.extend(session.poll(POLL));
            }
            let asked = session.request_gaps(r, Some(cut), GAP_REQUESTS_MAX);
            if asked.is_empty() {
                break;
            }
            rounds += 1;
            c.retrievals += asked.len() as u32;
            disp.log(format!(
                "  gaps     robot {r}: {} ranges missing, retrieval round {rounds}",
                missing.len()
            ));
            let t0 = Instant::now();
            // Until the ranges asked for are filled or their retrievals ended.
            let filled = |session: &Session| {
                session.robots.get(&r).is_some_and(|s| {
                    !s.seq.missing().any(|m| {
                        let m = SeqCount::new(m);
                        asked.iter().any(|&(x, y)| {
                            let x = SeqCount::new(x);
                            m.since(x) <= SeqCount::new(y).since(x)
                        })
                    })
                })
            };
            while t0.elapsed() < limit && session.retrieving(r) && !filled(session) && !stop() {
                seen.extend(session.poll(POLL));
            }
            // Replays still on their way.
            let settle = Instant::now();
            while settle.elapsed() < GAP_SETTLE {
                seen.extend(session.poll(POLL));
            }
        }
        if let Some(s) = session.robots.get(&r) {
            for (a, b) in s.seq.missing_upto(cut) {
                // Older than the oldest packet still stored: overwritten on board (by
                // time where the holes' window is known, the tracker's rule).
                let gone = s.store_oldest.is_some_and(|o| s.seq.overwritten(a, b, o));
                if gone {
                    c.overwritten.push((a, b));
                } else {
                    c.not_received.push((a, b));
                }
            }
        }
        out.push(c);
    }
    out
}
