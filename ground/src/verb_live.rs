//! The verbs that talk to robots one TC at a time: `ping`, `send`, `mode`, `watch`.

use std::collections::BTreeMap;
use std::path::Path;
use std::time::{Duration, Instant};

use anyhow::{anyhow, Result};
use ground::archive;
use ground::ops::{self, Session, Update};
use ground::pus::{self, Packet, Stage, TmBody};

use crate::exit::{self, coded};
use crate::links::{close_archive, open_one, robots_given, Links};
use crate::output::{err_line, out};
use clap::Args;

pub(crate) fn ping(a: &PingArgs, archive_path: Option<&Path>) -> Result<u8> {
    let def = mib::tc::by_name("PING").ok_or_else(|| anyhow!("PING not in the MIB"))?;
    let links = robots_given(&a.links)?;
    let (mut s, arch) = a.links.open(&links, archive_path)?;
    // A PING is not resent on the lab links (the next one follows). Over frames nothing
    // is resent by packet anyway, and the PING stays awaited on the book's schedule: its
    // reports, lost before the first TM heard, are asked of the store by time while it
    // waits (`Session::awaited_span`).
    if !s.over_frames() {
        s.max_resends = 0;
    }
    let mut answered: BTreeMap<u8, (u32, bool)> = BTreeMap::new(); // robot -> (replies, last answered)
    let mut silent: Vec<u8> = Vec::new(); // never answered: not pinged again
    for k in 0..a.count {
        for &(r, addr) in &links {
            if silent.contains(&r) {
                continue;
            }
            let tc = s.send(r, def, &[], Some(r as usize), None)?;
            let t0 = Instant::now();
            let mut got = None;
            let mut from_store = false;
            let mut completed = None;
            let mut foreign = false;
            let live_wait = s.ack_timeout() * 2;
            let mut last_ask = Instant::now();
            loop {
                let waited = t0.elapsed();
                // The PING's completion report without its reply: answered, once the reply
                // had its live wait.
                if got.is_none() && waited >= live_wait && completed.is_some() {
                    got = completed;
                    from_store = true;
                }
                // Over frames, a PING whose frame a CLCW acknowledged reached the robot:
                // a reply lost on the way is asked of the on-board store (its reply or
                // completion report), while the robot is heard, for at most a store
                // request's time more.
                // On any link a robot still heard after the live wait is waited for until
                // it is silent for the loss time (then it is lost, said with that silence)
                // or the store wait ends (then it answers, but not this PING: exit 4).
                // A robot not heard at all yet gets the loss time from the first TC
                // before it is "nothing heard" (a slow start is not silence).
                let heard = waited >= live_wait && s.heard_recently(r);
                let fetch = heard && s.over_frames() && s.delivered(r, &tc);
                let unheard_wait = s
                    .robots
                    .get(&r)
                    .filter(|st| st.link.last_heard_ms().is_none())
                    .map_or(Duration::ZERO, |st| {
                        Duration::from_millis(u64::try_from(st.link.loss_after_ms()).unwrap_or(0))
                    });
                let limit = if heard {
                    live_wait + STORE_WAIT
                } else {
                    live_wait.max(unheard_wait)
                };
                if got.is_some() || foreign || waited >= limit {
                    break;
                }
                if fetch && waited >= live_wait && last_ask.elapsed() >= GAP_CHECK_PERIOD_FRAMES && s.may_retrieve(r) {
                    last_ask = Instant::now();
                    s.request_missing_reports(r, 1);
                }
                for u in s.poll(Duration::from_millis(50)) {
                    match u {
                        Update::Tm { robot, tm }
                            if robot == r && matches!(tm.body.report(), Some(mib_wire::Tm::PingReply(_))) =>
                        {
                            // After the live wait it came from the store.
                            from_store = t0.elapsed() >= live_wait;
                            got = Some(t0.elapsed());
                        }
                        // Its completion (live or from the store): the reply was sent and
                        // lost on the way.
                        Update::Verification { robot, v, .. }
                            if robot == r
                                && v.request.seq() == tc.seq
                                && v.request.apid() == tc.apid
                                && v.stage == Stage::Completion
                                && v.success =>
                        {
                            completed.get_or_insert(t0.elapsed());
                        }
                        Update::Foreign { robot, .. } if robot == r => {
                            foreign = s.robots.get(&r).is_some_and(|st| st.last_tm.is_none());
                        }
                        _ => {}
                    }
                }
            }
            s.forget(&tc);
            let e = answered.entry(r).or_insert((0, false));
            e.1 = got.is_some();
            match got {
                Some(rtt) if from_store => {
                    e.0 += 1;
                    out(&format!(
                        "robot {r} ({addr}) seq {}: answered after {:.1} ms (the live reply was lost; its report came from the on-board store or the completion report)",
                        tc.seq,
                        rtt.as_secs_f64() * 1000.0
                    ))?
                }
                Some(rtt) => {
                    e.0 += 1;
                    out(&format!(
                        "robot {r} ({addr}) seq {}: reply in {:.1} ms",
                        tc.seq,
                        rtt.as_secs_f64() * 1000.0
                    ))?
                }
                None => {
                    out(&format!(
                        "robot {r} ({addr}) seq {}: no reply within {} ms",
                        tc.seq,
                        (s.ack_timeout() * 2).as_millis()
                    ))?;
                    if e.0 == 0 {
                        silent.push(r);
                    }
                }
            }
        }
        if k + 1 < a.count && silent.len() < links.len() {
            std::thread::sleep(Duration::from_secs_f64(a.interval));
        }
    }
    for st in s.robots.values() {
        out(&format!("robot {}: {}", st.robot, st.line()))?;
    }
    // The verdict: the same three cases as every verb; a robot heard within the loss
    // time (TM, or over frames a valid frame) answers, its missing reply is a timeout.
    let mut code = exit::OK;
    let robots: Vec<u8> = s.robots.keys().copied().collect();
    for r in robots {
        let (replies, last) = answered.get(&r).copied().unwrap_or((0, false));
        if replies == 0 || !last {
            s.heard_recently(r);
            let Some(st) = s.robots.get(&r) else { continue };
            match st.no_answer(false) {
                Some((kind, why)) => {
                    err_line!("ground: {why}");
                    code = code.max(kind.exit_code());
                }
                None => {
                    err_line!("ground: {}", st.no_report("no reply to the last PING"));
                    code = code.max(exit::FAILED);
                }
            }
        }
    }
    drop(s);
    close_archive(arch)?;
    Ok(code)
}

/// A "robot does not answer" error for `robot` of session `s` (one of the three cases,
/// with its exit code).
/// `what`: the report awaited, said when the robot still answers (then a timeout, exit 4).
pub(crate) fn no_answer_error(s: &mut Session, robot: u8, what: &str) -> anyhow::Error {
    s.heard_recently(robot);
    match s.robots.get(&robot) {
        Some(st) => match (&st.lost, st.lost_kind) {
            (Some(w), Some(k)) => coded(k.exit_code(), w.clone()),
            _ => match st.no_answer(false) {
                Some((kind, why)) => coded(kind.exit_code(), why),
                None => coded(exit::FAILED, st.no_report(what)),
            },
        },
        None => coded(exit::NO_ANSWER, format!("robot {robot}: no link")),
    }
}

pub(crate) fn policy_error(e: ops::policy::PolicyError) -> anyhow::Error {
    coded(exit::INVALID, e.to_string())
}

/// How often `send`/`mode` ask the on-board store for the reports they miss (the MIB's
/// gap-check periods).
const GAP_CHECK_PERIOD: Duration = Duration::from_millis(mib::ground_config::GAP_CHECK_PERIOD_MS as u64);
const GAP_CHECK_PERIOD_FRAMES: Duration = Duration::from_millis(mib::ground_config::GAP_CHECK_PERIOD_FRAMES_MS as u64);
/// `ping`: how much longer it waits, while the robot is heard, for a reply that did not
/// come in the live wait (over frames asked of the store): the time of as many store
/// requests as a hole is asked before it is given up (`GAP_MAX_TRIES`, each answered or
/// given up within `STORE_REQUEST_TIMEOUT_MS`): through the 20/5/5 relay a reply lost live
/// and in two replays is about 1 PING in 50, and a wait of fewer tries calls that robot
/// unanswering (exit 4) while the next replay is on its way.
const STORE_WAIT: Duration = Duration::from_millis(
    mib::ground_config::GAP_MAX_TRIES as u64 * mib::ground_config::STORE_REQUEST_TIMEOUT_MS as u64,
);

/// Sends one TC and reports its verification until completion or failure.
pub(crate) fn send_and_follow(
    s: &mut Session,
    robot: u8,
    def: &'static mib::tc::TcDef,
    args: &[i64],
    wait: bool,
    timeout: Duration,
) -> Result<u8> {
    // A robot that does not answer is reported within LINK_LOSS_MS, not after every resend.
    s.watch_links();
    let tc = s.send(robot, def, args, Some(0), None)?;
    out(&format!(
        "robot {robot}: sent {} seq {} ({} bytes)",
        def.name,
        tc.seq,
        tc.bytes.len()
    ))?;
    let t0 = Instant::now();
    let mut accepted = false;
    let mut last_gap_check = Instant::now();
    while t0.elapsed() < timeout {
        for u in s.poll(Duration::from_millis(100)) {
            match u {
                // By request ID: a report replayed from the store after the book gave the
                // TC up comes without its tag.
                Update::Verification { v, after, .. } if v.request.seq() == tc.seq && v.request.apid() == tc.apid => {
                    out(&format!(
                        "robot {robot}: {} {}{}{} after {:.0} ms",
                        v.stage.name(),
                        if v.success { "ok" } else { "FAILED" },
                        v.step.map_or(String::new(), |st| format!(" step {st}")),
                        v.failure.as_ref().map_or(String::new(), |f| format!(": {f}")),
                        after.unwrap_or_default().as_secs_f64() * 1000.0
                    ))?;
                    if !v.success {
                        return Ok(exit::FAILED);
                    }
                    if v.stage == Stage::Acceptance {
                        accepted = true;
                        if !wait {
                            return Ok(exit::OK);
                        }
                    }
                    if v.stage == Stage::Completion {
                        return Ok(exit::OK);
                    }
                }
                Update::Resent { send, .. } => out(&format!(
                    "robot {robot}: no acceptance yet, resent the same bytes (send {send})"
                ))?,
                Update::DamagedCopy { .. } => out(&format!(
                    "robot {robot}: a copy arrived damaged (TM[1,2] CRC), resent the same bytes"
                ))?,
                Update::LinkLost { .. } => return Err(no_answer_error(s, robot, "")),
                // Over frames a TC whose frame a CLCW acknowledged reached the robot: its
                // reports are in the on-board store, asked for below until --timeout.
                Update::GaveUp { tag: Some(0), .. } if s.delivered(robot, &tc) => {}
                Update::GaveUp { tag: Some(0), .. } => {
                    return Err(no_answer_error(
                        s,
                        robot,
                        &format!("{} seq {}: no report after every send", def.name, tc.seq),
                    ))
                }
                Update::Event { robot: r, event } if r == robot => out(&format!("robot {robot}: event {event}"))?,
                _ => {}
            }
        }
        // An accepted TC is not resent: a completion report lost on the way is a TM gap,
        // asked of the on-board store. Over frames the same once a CLCW acknowledged the
        // TC's frame (it reached the robot; its acceptance may be the report lost).
        let (period, delivered) = if s.over_frames() {
            (GAP_CHECK_PERIOD_FRAMES, s.delivered(robot, &tc))
        } else {
            (GAP_CHECK_PERIOD, false)
        };
        if (accepted || delivered) && last_gap_check.elapsed() >= period {
            last_gap_check = Instant::now();
            if s.may_retrieve(robot) {
                s.request_missing_reports(robot, 1);
            }
        }
    }
    // Over frames, what COP-1 did for this robot (why no report came is often there).
    if let Some(f) = s.frame_stats(robot) {
        out(&format!(
            "robot {robot}: frames: {} TC packets, {} acknowledged by CLCW, {} AD frames ({} retransmissions), {} initialisations, {} alerts, {} pending, last N(R) {}",
            f.packets,
            f.acknowledged,
            f.ad_frames,
            f.retransmissions,
            f.initialisations,
            f.alerts,
            f.pending,
            f.nr.map_or("-".into(), |n| n.to_string())
        ))?;
    }
    if !accepted {
        let what = format!(
            "{} seq {}: no acceptance within {:.0} s (--timeout)",
            def.name,
            tc.seq,
            timeout.as_secs_f64()
        );
        return Err(no_answer_error(s, robot, &what));
    }
    Err(coded(
        exit::FAILED,
        format!(
            "robot {robot}: {} accepted, but no completion within {:.0} s (--timeout)",
            def.name,
            timeout.as_secs_f64()
        ),
    ))
}

pub(crate) fn send(a: &SendArgs, archive_path: Option<&Path>) -> Result<u8> {
    let def = ops::policy::tc_by_name(&a.tc).map_err(policy_error)?;
    let args = ops::policy::parse_arg_words(def, &a.args).map_err(policy_error)?;
    ops::policy::check_confirmed(def, a.confirm, "add --confirm").map_err(policy_error)?;
    let (robot, mut s, arch) = open_one(&a.links, archive_path)?;
    let r = send_and_follow(
        &mut s,
        robot,
        def,
        &args,
        !a.no_wait,
        Duration::from_secs_f64(a.timeout),
    );
    drop(s);
    close_archive(arch)?;
    r
}

pub(crate) fn mode(a: &ModeArgs, archive_path: Option<&Path>) -> Result<u8> {
    let def = mib::tc::by_name("MODE_SET").ok_or_else(|| anyhow!("MODE_SET not in the MIB"))?;
    let m = mib::modes::root_mode_by_name(&a.mode)
        .map(i64::from)
        .or_else(|| a.mode.parse().ok())
        .ok_or_else(|| {
            coded(
                exit::INVALID,
                format!("unknown mode \"{}\" (standby, operational, safed)", a.mode),
            )
        })?;
    ops::policy::check_confirmed(def, a.confirm, "add --confirm").map_err(policy_error)?;
    let (robot, mut s, arch) = open_one(&a.links, archive_path)?;
    let r = send_and_follow(
        &mut s,
        robot,
        def,
        &[mib::modes::node::ROBOT as i64, m, 0],
        true,
        Duration::from_secs_f64(a.timeout),
    );
    if let Some(st) = s.robots.get(&robot) {
        out(&format!("robot {robot}: {}", st.line()))?;
    }
    drop(s);
    close_archive(arch)?;
    r
}

pub(crate) fn watch(a: &WatchArgs, archive_path: Option<&Path>) -> Result<u8> {
    let links = robots_given(&a.links)?;
    let (mut s, arch) = a.links.open(&links, archive_path)?;
    // A robot that does not answer ends the watch with its case's message and code.
    s.watch_links();
    // The OBSW sends TM to the grounds whose TC it accepted: subscribe with a ping, and
    // renew the lease well before it ends.
    if let Some(ping) = mib::tc::by_name("PING") {
        for &(r, _) in &links {
            s.send(r, ping, &[], None, Some("watch".into()))?;
        }
    }
    let renew = Duration::from_millis(mib::host_config::SUBSCRIPTION_LEASE_MS as u64 / 3);
    let mut renewed = Instant::now();
    let t0 = Instant::now();
    let mut n = 0u64;
    let result = (|| -> Result<()> {
        loop {
            if renewed.elapsed() >= renew {
                renewed = Instant::now();
                for &(r, _) in &links {
                    // A lost renewal is made good by the next one, a third of a lease later.
                    let _ = s.send_heartbeat(r);
                }
            }
            // A quiet robot (slow HK) is asked once a heartbeat period, so the link-loss
            // watch tells silence from a dead link.
            let beat = Duration::from_millis(mib::ground_config::GROUND_HEARTBEAT_MS as u64);
            for &(r, _) in &links {
                let quiet = s
                    .robots
                    .get(&r)
                    .and_then(|st| st.last_tm)
                    .is_some_and(|t| t.elapsed() >= beat);
                if quiet && !s.sent_within(r, beat) {
                    let _ = s.send_heartbeat(r);
                }
            }
            if a.duration.is_some_and(|d| t0.elapsed().as_secs_f64() >= d) || a.count.is_some_and(|c| n >= c) {
                return Ok(());
            }
            for u in s.poll(Duration::from_millis(200)) {
                let (robot, line, json) = match &u {
                    Update::Verification { robot, v, .. } => (
                        *robot,
                        pus::describe_body(&TmBody::Verification(v.clone())),
                        serde_json::to_value(v)?,
                    ),
                    Update::Hk { robot, hk } => {
                        if a.no_hk {
                            continue;
                        }
                        (
                            *robot,
                            pus::describe_body(&TmBody::Hk(hk.clone())),
                            serde_json::to_value(hk)?,
                        )
                    }
                    Update::Event { robot, event } => (*robot, format!("EVENT {event}"), serde_json::to_value(event)?),
                    Update::Tm { robot, tm } => (
                        *robot,
                        pus::describe(&Packet::Tm(tm.clone())),
                        serde_json::to_value(tm)?,
                    ),
                    Update::Corrupt { robot, error } => (
                        *robot,
                        format!("CORRUPT {error}"),
                        serde_json::json!({"corrupt": error.to_string()}),
                    ),
                    Update::LinkLost { robot, .. } => return Err(no_answer_error(&mut s, *robot, "")),
                    Update::Foreign {
                        robot,
                        apid,
                        service,
                        subservice,
                    } => (
                        *robot,
                        format!("FOREIGN TM[{service},{subservice}] of APID 0x{apid:03X}"),
                        serde_json::json!({"foreign_apid": apid, "service": service, "subservice": subservice}),
                    ),
                    _ => continue,
                };
                n += 1;
                if a.json {
                    out(&serde_json::json!({"robot": robot, "t_ms": archive::now_ms(), "tm": json}).to_string())?;
                } else {
                    out(&format!(
                        "{} robot {robot}: {line}",
                        chrono::Utc::now().format("%H:%M:%S%.3f")
                    ))?;
                }
            }
        }
    })();
    drop(s);
    close_archive(arch)?;
    result.map(|_| exit::OK)
}

#[derive(Args, Debug)]
pub(crate) struct PingArgs {
    #[command(flatten)]
    links: Links,
    /// Pings per robot.
    #[arg(long, short = 'c', default_value_t = 3)]
    count: u32,
    /// Pause between pings (seconds).
    #[arg(long, default_value_t = 0.2)]
    interval: f64,
}

#[derive(Args, Debug)]
pub(crate) struct SendArgs {
    #[command(flatten)]
    links: Links,
    /// TC name from the MIB (e.g. RECONFIGURE, HK_SET_INTERVAL, PING).
    tc: String,
    /// Arguments as NAME=VALUE (state names allowed for from/to).
    args: Vec<String>,
    /// Do not wait for completion.
    #[arg(long)]
    no_wait: bool,
    /// Longest wait for completion (seconds).
    #[arg(long, default_value_t = 60.0)]
    timeout: f64,
    /// Confirm a hazardous TC (the MIB's hazard flag); without it one is refused.
    #[arg(long)]
    confirm: bool,
}

#[derive(Args, Debug)]
pub(crate) struct ModeArgs {
    #[command(flatten)]
    links: Links,
    /// standby, operational or safed.
    mode: String,
    #[arg(long, default_value_t = 60.0)]
    timeout: f64,
    /// Confirm the mode change (MODE_SET is hazardous in the MIB); refused without it.
    #[arg(long)]
    confirm: bool,
}

#[derive(Args, Debug)]
pub(crate) struct WatchArgs {
    #[command(flatten)]
    links: Links,
    /// One JSON object per packet.
    #[arg(long)]
    json: bool,
    /// Hide housekeeping reports.
    #[arg(long)]
    no_hk: bool,
    /// Stop after this many seconds.
    #[arg(long)]
    duration: Option<f64>,
    /// Stop after this many packets.
    #[arg(long)]
    count: Option<u64>,
}
