use super::*;
use std::time::{Duration, Instant};

use mib::ground_config::{tc_retry_wait_ms, TC_RETRY_MAX};

use crate::ops::book::{Due, Pending, TcBook, Verdict};
use crate::ops::{Effect, Executor, RunOptions, Update};
use crate::pus::{build_tm, CdsShort};
use crate::pus::{BuiltTc, TmBody, Verification};
use mib::failure::FailureCode;

fn ping(seq: u16) -> BuiltTc {
    crate::pus::build_tc(1, seq, mib::tc::by_name("PING").unwrap(), &[]).unwrap()
}

/// A PUS 1 report (`subservice`) about `tc`, failing with `code` if even.
fn report(tc: &BuiltTc, subservice: u8, code: FailureCode) -> Verification {
    let mut data = tc.bytes[..4].to_vec();
    if subservice == 5 || subservice == 6 {
        data.push(2); // progress step
    }
    if subservice.is_multiple_of(2) {
        data.extend_from_slice(&code.code().to_be_bytes());
        data.extend(std::iter::repeat_n(0, mib::layout::fields_len(code.data())));
    }
    let raw = build_tm(tc.apid, 9, 1, subservice, 0, &CdsShort::now().to_bytes(), &data);
    match crate::pus::decode_tm(&raw).unwrap().body {
        TmBody::Verification(v) => v,
        other => panic!("not a verification: {other:?}"),
    }
}

/// The bytes the book asks to resend at `now` (a lab link).
fn resends(b: &mut TcBook, now: Instant) -> Vec<(Option<usize>, Vec<u8>, u32)> {
    b.on_tick(now, |_| true)
        .into_iter()
        .filter_map(|d| match d {
            Due::Resend { tag, tc, send, .. } => Some((tag, tc.bytes, send)),
            Due::Waited { .. } | Due::GaveUp(_) => None,
        })
        .collect()
}

// verifies: GND-19, OPS-ENGINE-01
#[test]
fn resends_identical_bytes_on_the_mib_schedule_until_accepted_then_waits_for_the_outcome() {
    // The run's TCs are awaited in the book `ground run` uses (ops::book).
    let t0 = Instant::now();
    let mut b = TcBook::default();
    let tc = ping(42);
    b.insert(Pending::sent(1, tc.clone(), Some(3), None, t0));
    let first = Duration::from_millis(tc_retry_wait_ms(0) as u64);
    assert!(resends(&mut b, t0 + first - Duration::from_millis(1)).is_empty());
    assert_eq!(resends(&mut b, t0 + first), vec![(Some(3), tc.bytes.clone(), 2)]);
    // The next wait is the MIB's second one, counted from the resend.
    let second = Duration::from_millis(tc_retry_wait_ms(1) as u64);
    assert!(second > first);
    assert!(resends(&mut b, t0 + first + second - Duration::from_millis(1)).is_empty());
    assert_eq!(resends(&mut b, t0 + first + second).len(), 1);

    // Accepted: the report goes to the step; no resend after it; completion ends it.
    let v = b.on_verification(1, &report(&tc, 1, FailureCode::CRC_MISMATCH), t0 + first * 3, true);
    assert!(
        matches!(
            v,
            Verdict::Report {
                tag: Some(3),
                finished: false,
                ..
            }
        ),
        "{v:?}"
    );
    assert!(
        resends(&mut b, t0 + first * 60).is_empty(),
        "never resent once accepted"
    );
    assert_eq!(b.len(), 1);
    let v = b.on_verification(1, &report(&tc, 7, FailureCode::CRC_MISMATCH), t0 + first * 61, true);
    assert!(
        matches!(
            v,
            Verdict::Report {
                tag: Some(3),
                finished: true,
                ..
            }
        ),
        "{v:?}"
    );
    assert!(b.is_empty());
    // Reports of other TCs (the page's, the collector's) are not the run's.
    let other = b.on_verification(1, &report(&ping(7), 1, FailureCode::CRC_MISMATCH), t0, true);
    assert_eq!(other, Verdict::Unknown);
}

// verifies: GND-19, OPS-ENGINE-01
#[test]
fn a_damaged_copy_is_resent_at_once_and_a_silent_tc_is_given_up_after_its_sends() {
    let t0 = Instant::now();
    let mut b = TcBook::default();
    let tc = ping(9);
    b.insert(Pending::sent(1, tc.clone(), Some(0), None, t0));
    let v = b.on_verification(1, &report(&tc, 2, FailureCode::CRC_MISMATCH), t0, true);
    assert!(
        matches!(&v, Verdict::DamagedCopy { tag: Some(0), resend: Some(bytes), .. } if *bytes == tc.bytes),
        "{v:?}"
    );
    // Never answered: every send is made, then the TC is given up (not accepted).
    let mut t = t0;
    let mut sends = 2;
    let mut gave_up = None;
    for _ in 0..100 {
        t += Duration::from_millis(mib::ground_config::TC_RETRY_CAP_MS as u64);
        for d in b.on_tick(t, |_| true) {
            match d {
                Due::Resend { .. } => sends += 1,
                Due::GaveUp(p) => gave_up = Some(p),
                Due::Waited { .. } => panic!("a lab link resends"),
            }
        }
        if gave_up.is_some() {
            break;
        }
    }
    let p = gave_up.expect("given up");
    assert!(!p.accepted);
    assert_eq!(p.sends, TC_RETRY_MAX + 1);
    assert_eq!(sends, TC_RETRY_MAX + 1);
    assert!(b.is_empty());

    // A failure that is the TC's verdict ends it and reaches the executor.
    let tc = ping(10);
    b.insert(Pending::sent(1, tc.clone(), Some(1), None, t0));
    let v = b.on_verification(1, &report(&tc, 4, FailureCode::NOT_ALLOWED_IN_MODE), t0, true);
    assert!(matches!(v, Verdict::Report { finished: true, .. }), "{v:?}");
    assert!(b.is_empty());
}

// verifies: GND-19, GND-18
#[test]
fn starts_are_checked_unknown_hazard_link_and_one_plan_per_robot() {
    let dir = std::env::temp_dir().join(format!("planbook-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let plan = |name: &str, tc: &str| {
        let path = dir.join(format!("{name}.toml"));
        std::fs::write(
            &path,
            format!("name = \"{name}\"\n[[robot]]\nnumber = 1\n[[step]]\nid = \"s\"\nrobot = 1\naction = \"command\"\ntc = \"{tc}\"\n"),
        )
        .unwrap();
        PlanCfg {
            name: name.into(),
            path,
        }
    };
    let hub = Hub::new();
    hub.add_robot(1);
    let (tx, rx) = crossbeam_channel::bounded(64);
    let book = PlanBook::new(
        vec![plan("ping", "PING"), plan("clear", "STORE_DELETE")],
        hub.clone(),
        BTreeMap::from([(1, tx)]),
    );
    assert!(matches!(book.start("nope", true), Err(PlanStartError::Unknown(m)) if m.contains("ping, clear")));
    assert!(matches!(book.start("ping", false), Err(PlanStartError::Refused(m)) if m.contains("not up yet")));
    hub.link(1, ground_dashboard::LinkState::Up);
    let hazards = &book.list()[1].hazards;
    assert_eq!(hazards.len(), 1, "{hazards:?}");
    assert!(matches!(
        book.start("clear", false),
        Err(PlanStartError::NeedsConfirmation(_))
    ));
    let run = book.start("ping", false).unwrap();
    // The run follows the robot's thread, then hands it its TC.
    assert!(matches!(
        rx.recv_timeout(Duration::from_secs(5)),
        Ok(DashCmd::Follow(_))
    ));
    // Held unanswered: a dropped reply channel would end the run before the check.
    let tc = rx.recv_timeout(Duration::from_secs(5));
    assert!(matches!(&tc, Ok(DashCmd::PlanTc { def, .. }) if def.name == "PING"));
    assert!(matches!(book.start("clear", true), Err(PlanStartError::Busy(m)) if m.contains(&run)));
    // The robot's thread is gone: the run ends failed and the robot is free again.
    drop((tc, rx));
    let end = Instant::now() + Duration::from_secs(10);
    while book.busy.lock().unwrap().contains_key(&1) {
        assert!(Instant::now() < end, "robot 1 still busy");
        std::thread::sleep(Duration::from_millis(20));
    }
    let _ = std::fs::remove_dir_all(&dir);
}

fn run(states: &[&str], details: &[&str]) -> PlanRun {
    PlanRun {
        run_id: "p-1".into(),
        plan: "p".into(),
        state: "running".into(),
        detail: String::new(),
        started_ms: 0,
        steps: states
            .iter()
            .zip(details)
            .enumerate()
            .map(|(i, (s, d))| PlanStep {
                id: format!("s{i}"),
                robot: 1,
                label: String::new(),
                state: s.to_string(),
                request_id: None,
                detail: d.to_string(),
            })
            .collect(),
    }
}

// verifies: GND-19
#[test]
fn a_run_ends_done_failed_with_the_failing_step_or_lost() {
    assert_eq!(
        outcome(&run(&["done", "done"], &["", ""]), None),
        ("done".into(), String::new())
    );
    let r = run(
        &["done", "failed", "blocked"],
        &["", "robot 1: start failed: INITIAL_STATE_MISMATCH (…)", "waits for s1"],
    );
    assert_eq!(
        outcome(&r, None),
        (
            "failed".into(),
            "step s1 failed: robot 1: start failed: INITIAL_STATE_MISMATCH (…)".into()
        )
    );
    assert_eq!(outcome(&r, Some("robot 1: no TM for 3000 ms")).0, "lost");
    let r = run(&["blocked"], &["robot 1 reported fault LOW_BATTERY"]);
    assert_eq!(
        outcome(&r, None).1,
        "step s0 blocked: robot 1 reported fault LOW_BATTERY"
    );
}

// verifies: GND-19
#[test]
fn the_page_sees_each_steps_stage_and_progress() {
    let plan = crate::plan::parse(
        "name = \"p\"\n[[robot]]\nnumber = 1\n[[step]]\nid = \"a\"\nrobot = 1\naction = \"command\"\ntc = \"PING\"\n[[step]]\nid = \"b\"\nrobot = 1\naction = \"wait\"\nseconds = 1\n",
    )
    .unwrap();
    let opts = RunOptions {
        ping_period: None,
        display: false,
        ..RunOptions::default()
    };
    let t0 = Instant::now();
    let mut exec = Executor::new(&plan, &opts, &[], t0);
    let mut r = run(&["waiting", "waiting"], &["", ""]);
    let fx = exec.on_tick(t0);
    assert!(matches!(fx[..], [Effect::Send { step: 0, .. }]));
    exec.on_sent(0, Ok(ping(5)), t0);
    view(&mut r, &exec);
    assert_eq!(
        (r.steps[0].state.as_str(), r.steps[0].detail.as_str()),
        ("running", "sent")
    );
    assert_eq!(r.steps[1].state, "waiting");
    let v = report(&ping(5), 5, FailureCode::CRC_MISMATCH);
    exec.on_update(
        t0,
        Update::Verification {
            robot: 1,
            tag: Some(0),
            tc: None,
            v,
            after: None,
            at_ms: None,
        },
    );
    view(&mut r, &exec);
    assert_eq!(r.steps[0].detail, "progress 2");
    exec.on_sent(0, Err(crate::ops::SendError::NoLink(1)), t0);
    view(&mut r, &exec);
    assert_eq!(r.steps[0].state, "failed");
    assert!(r.steps[0].detail.contains("no link"), "{}", r.steps[0].detail);
    assert_eq!(r.steps[1].state, "blocked");
}

/// A plan run whose one TC (`tc`, robot 1) went out on a link of `kind`.
fn run_with(tc: &BuiltTc, kind: crate::link::LinkKind, t0: Instant) -> Run {
    let plan = crate::plan::parse(
        "name = \"p\"\n[[robot]]\nnumber = 1\n[[step]]\nid = \"a\"\nrobot = 1\naction = \"command\"\ntc = \"PING\"\n",
    )
    .unwrap();
    let (_tx, input) = crossbeam_channel::bounded(1);
    let mut book = TcBook::default();
    book.insert(Pending::sent(1, tc.clone(), Some(0), None, t0));
    Run {
        plan,
        run: run(&["running"], &[""]),
        hub: Hub::new(),
        robots: BTreeMap::new(),
        input,
        book,
        links: BTreeMap::from([(1, kind)]),
        lost: None,
    }
}

/// What the run reports when its TC's waits run out, ticking once a second.
fn given_up(r: &mut Run, t0: Instant) -> Update {
    for s in 1..3600 {
        if let Some(u) = r
            .tick(t0 + Duration::from_secs(s))
            .into_iter()
            .find(|u| matches!(u, Update::GaveUp { .. }))
        {
            return u;
        }
    }
    panic!("never given up");
}

// verifies: GND-19
#[test]
fn a_plan_tc_cop1_delivered_is_given_up_as_accepted_like_ground_run() {
    use std::collections::VecDeque;
    use std::sync::{Arc, Mutex};
    let t0 = Instant::now();
    let tc = ping(42);
    // Over frames, a CLCW acknowledged the TC's frame: it reached the robot, its outcome
    // is asked of the store (as ops::Session does), not reported as never accepted.
    let delivered = Arc::new(Mutex::new(VecDeque::from([(tc.apid, tc.seq)])));
    let mut r = run_with(&tc, crate::link::LinkKind::Frames { delivered }, t0);
    assert!(
        matches!(
            given_up(&mut r, t0),
            Update::GaveUp {
                accepted: true,
                sends: 1,
                ..
            }
        ),
        "delivered"
    );
    // Not acknowledged: given up as never accepted.
    let none = Arc::new(Mutex::new(VecDeque::from([(tc.apid, tc.seq.wrapping_add(1))])));
    let mut r = run_with(&tc, crate::link::LinkKind::Frames { delivered: none }, t0);
    assert!(
        matches!(given_up(&mut r, t0), Update::GaveUp { accepted: false, .. }),
        "not delivered"
    );
}
