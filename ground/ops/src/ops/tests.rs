use std::net::{SocketAddr, UdpSocket};
use std::time::{Duration, Instant};

use mib::ground_config::{tc_retry_wait_ms, LINK_QUALITY_WINDOW, TC_RETRY_MAX};

use super::*;
use crate::link::Transport;
use crate::plan::Plan;
use crate::pus::{self, build_tm, BuiltTc, CdsShort, Stage, TmBody};

/// A minimal fake OBSW speaking real PUS: answers each TC with TM[1,1] and TM[1,7],
/// after first sending a TM of another robot's APID; ignores the first `drop` TCs.
fn fake_obsw(drop: usize) -> (SocketAddr, std::thread::JoinHandle<Vec<(u16, u16)>>) {
    let s = UdpSocket::bind("127.0.0.1:0").unwrap();
    s.set_read_timeout(Some(Duration::from_secs(3))).unwrap();
    let addr = s.local_addr().unwrap();
    let h = std::thread::spawn(move || {
        let mut seen = Vec::new();
        let mut buf = [0u8; 2048];
        let t = CdsShort::now().to_bytes();
        while let Ok((n, from)) = s.recv_from(&mut buf) {
            let Ok(tc) = pus::decode_tc(&buf[..n]) else { continue };
            seen.push((tc.apid, tc.seq));
            if seen.len() <= drop {
                continue;
            }
            let rid = [buf[0], buf[1], buf[2], buf[3]];
            let other = build_tm(0x1FE, 0, 17, 2, 0, &t, &[]);
            let acc = build_tm(tc.apid, 1, 1, 1, 0, &t, &rid);
            let done = build_tm(tc.apid, 2, 1, 7, 0, &t, &rid);
            for p in [other, acc, done] {
                s.send_to(&p, from).unwrap();
            }
            if seen.len() > drop {
                break;
            }
        }
        seen
    });
    (addr, h)
}

// verifies: GND-01
#[test]
fn session_resends_with_the_same_count_and_skips_foreign_apids() {
    let (addr, fake) = fake_obsw(1);
    let mut s = Session::connect(&[(1, addr)], Transport::Udp, None, |_| Some(100)).unwrap();
    s.set_ack_timeout(Duration::from_millis(150));
    let tc = s
        .send(1, mib::tc::by_name("PING").unwrap(), &[], Some(7), None)
        .unwrap();
    assert_eq!(tc.seq, 100);
    let mut stages = Vec::new();
    let mut resent = 0;
    let mut foreign = 0;
    let t0 = Instant::now();
    while t0.elapsed() < Duration::from_secs(3) && !stages.contains(&Stage::Completion) {
        for u in s.poll(Duration::from_millis(50)) {
            match u {
                Update::Verification { tag: Some(7), v, .. } => stages.push(v.stage),
                Update::Resent { send, .. } => resent = send,
                Update::Foreign { apid, .. } => foreign += (apid == 0x1FE) as u32,
                _ => {}
            }
        }
    }
    assert_eq!(stages, vec![Stage::Acceptance, Stage::Completion]);
    assert_eq!((resent, foreign), (2, 1));
    assert!(!s.busy(1));
    let st = &s.robots[&1];
    // one exchange timed out, the resend was accepted
    assert_eq!(st.link_quality(), Some(0.5));
    assert_eq!(st.foreign, 1);
    assert_eq!(fake.join().unwrap(), vec![(0x101, 100), (0x101, 100)]);
}

fn plan(src: &str) -> Plan {
    crate::plan::parse(src).unwrap_or_else(|e| panic!("{e:?}"))
}

const TWO_STEPS: &str = r#"
name = "t"
[[robot]]
number = 1
initial_state = "Xneg"
[[step]]
id = "ping1"
robot = 1
action = "command"
tc = "PING"
[[step]]
id = "ping2"
robot = 1
action = "command"
tc = "PING"
timeout = 5
"#;

/// A verification update for `tc` as the session would give it.
fn verification(tc: &BuiltTc, step: usize, subservice: u8) -> Update {
    let t = CdsShort::now().to_bytes();
    let rid = &tc.bytes[..4];
    let mut data = rid.to_vec();
    if subservice.is_multiple_of(2) {
        data.extend_from_slice(&mib::failure::FailureCode::NOT_ALLOWED_IN_MODE.code().to_be_bytes());
        data.push(0); // mode: standby
    }
    let tm = pus::decode_tm(&build_tm(tc.apid, 9, 1, subservice, 0, &t, &data)).unwrap();
    let TmBody::Verification(v) = tm.body else {
        panic!("not a verification")
    };
    Update::Verification {
        robot: 1,
        tag: Some(step),
        tc: Some(tc.def.name),
        v,
        after: None,
        at_ms: None,
    }
}

fn sends(fx: &[Effect]) -> Vec<usize> {
    fx.iter()
        .filter_map(|e| match e {
            Effect::Send { step, .. } => Some(*step),
            _ => None,
        })
        .collect()
}

// verifies: GND-05
#[test]
fn executor_runs_steps_in_order_with_a_mock_clock() {
    let pl = plan(TWO_STEPS);
    let opts = RunOptions {
        step_timeout: Duration::from_secs(60),
        ping_period: Some(Duration::from_secs(1)),
        display: false,
        ..RunOptions::default()
    };
    let t0 = Instant::now();
    let mut ex = Executor::new(&pl, &opts, &[], t0);
    let fx = ex.on_tick(t0);
    assert_eq!(sends(&fx), vec![0], "only the first step: the second depends on it");
    assert!(fx.iter().any(|e| matches!(e, Effect::Heartbeat(1))));
    let ping = mib::tc::by_name("PING").unwrap();
    let tc0 = pus::build_tc(1, 10, ping, &[]).unwrap();
    ex.on_sent(0, Ok(tc0.clone()), t0);
    // Nothing new before the completion, and no heartbeat before its period.
    let fx = ex.on_tick(t0 + Duration::from_millis(500));
    assert!(sends(&fx).is_empty() && !fx.iter().any(|e| matches!(e, Effect::Heartbeat(_))));
    assert!(ex
        .on_update(t0 + Duration::from_millis(600), verification(&tc0, 0, 1))
        .is_empty());
    let fx = ex.on_update(t0 + Duration::from_millis(700), verification(&tc0, 0, 7));
    assert!(fx.iter().any(|e| matches!(e, Effect::Finished)));
    assert_eq!(ex.state[0], StepState::Done { secs: 0.7 });
    let fx = ex.on_tick(t0 + Duration::from_millis(1100));
    assert_eq!(sends(&fx), vec![1]);
    assert!(fx.iter().any(|e| matches!(e, Effect::Heartbeat(1))));
    let tc1 = pus::build_tc(1, 11, ping, &[]).unwrap();
    ex.on_sent(1, Ok(tc1.clone()), t0 + Duration::from_millis(1100));
    // Step 2's own timeout (5 s) passes on the mock clock: it fails and its TC is
    // forgotten.
    let fx = ex.on_tick(t0 + Duration::from_millis(6200));
    assert!(
        fx.iter().any(|e| matches!(e, Effect::Forget(tc) if tc.seq == 11)),
        "{fx:?}"
    );
    assert!(matches!(&ex.state[1], StepState::Failed(w) if w.contains("within 5 s")));
    assert!(ex.finished());
    let fx = ex.on_tick(t0 + Duration::from_secs(60));
    assert!(fx.is_empty(), "no heartbeat after the end: {fx:?}");
}

// verifies: GND-09
#[test]
fn executor_stops_a_robot_on_link_loss_and_resumes_past_done_steps() {
    let pl = plan(TWO_STEPS);
    let opts = RunOptions {
        display: false,
        ..RunOptions::default()
    };
    let t0 = Instant::now();
    let mut ex = Executor::new(&pl, &opts, &[], t0);
    ex.on_tick(t0);
    let ping = mib::tc::by_name("PING").unwrap();
    ex.on_sent(0, Ok(pus::build_tc(1, 10, ping, &[]).unwrap()), t0);
    let fx = ex.on_update(
        t0,
        Update::LinkLost {
            robot: 1,
            why: "robot 1: no TM".into(),
        },
    );
    assert!(fx.iter().any(|e| matches!(e, Effect::Forget(_))));
    assert!(matches!(&ex.state[0], StepState::Failed(w) if w.contains("link lost")));
    assert!(matches!(&ex.state[1], StepState::Blocked(_)));
    assert_eq!(ex.lost.len(), 1);

    // Resumed with the first step done: only the second is sent.
    let mut ex = Executor::new(&pl, &opts, &[0], t0);
    assert_eq!(sends(&ex.on_tick(t0)), vec![1]);
    assert_eq!(ex.resumed, 1);
}

// verifies: OPS-RUN-02
#[test]
fn an_interrupted_executor_sends_nothing_new_and_waits_a_bounded_time() {
    let pl = plan(TWO_STEPS);
    let opts = RunOptions {
        display: false,
        ping_period: None,
        ..RunOptions::default()
    };
    let t0 = Instant::now();
    let mut ex = Executor::new(&pl, &opts, &[], t0);
    ex.on_tick(t0);
    let tc0 = pus::build_tc(1, 10, mib::tc::by_name("PING").unwrap(), &[]).unwrap();
    ex.on_sent(0, Ok(tc0.clone()), t0);
    let fx = ex.interrupt(t0 + Duration::from_millis(100), Duration::from_secs(2));
    assert!(
        fx.iter().any(|e| matches!(e, Effect::Log(l) if l.contains("ping1"))),
        "{fx:?}"
    );
    assert!(
        !ex.stopped(t0 + Duration::from_secs(1)),
        "the step in flight is awaited"
    );
    assert!(ex.stopped(t0 + Duration::from_millis(2200)), "for a bounded time");
    // Its completion still counts; the next step is never sent.
    ex.on_update(t0 + Duration::from_millis(500), verification(&tc0, 0, 7));
    assert!(ex.stopped(t0 + Duration::from_millis(600)));
    assert!(sends(&ex.on_tick(t0 + Duration::from_secs(1))).is_empty());
    assert_eq!(ex.state[1], StepState::Waiting);
}

// verifies: OPS-RUN-03
#[test]
fn an_adopted_step_ends_by_its_reports_or_is_requeued() {
    let pl = plan(TWO_STEPS);
    let opts = RunOptions {
        display: false,
        ping_period: None,
        ..RunOptions::default()
    };
    let t0 = Instant::now();
    let mut ex = Executor::new(&pl, &opts, &[], t0);
    let tc0 = pus::build_tc(1, 10, mib::tc::by_name("PING").unwrap(), &[]).unwrap();
    ex.adopt(0, tc0.clone(), "outcome asked of the store", t0);
    assert!(
        sends(&ex.on_tick(t0)).is_empty(),
        "nothing sent while its outcome is unknown"
    );
    ex.on_update(t0, verification(&tc0, 0, 7));
    assert!(matches!(ex.state[0], StepState::Done { .. }));
    assert_eq!(sends(&ex.on_tick(t0)), vec![1]);
    let mut ex = Executor::new(&pl, &opts, &[], t0);
    ex.adopt(0, tc0, "outcome asked of the store", t0);
    ex.requeue(0);
    assert_eq!(sends(&ex.on_tick(t0)), vec![0], "never arrived: sent as a new TC");
}

// verifies: GND-06
#[test]
fn executor_failure_report_fails_the_step_and_blocks_dependents() {
    let pl = plan(TWO_STEPS);
    let opts = RunOptions {
        display: false,
        ping_period: None,
        ..RunOptions::default()
    };
    let t0 = Instant::now();
    let mut ex = Executor::new(&pl, &opts, &[], t0);
    ex.on_tick(t0);
    let tc0 = pus::build_tc(1, 10, mib::tc::by_name("PING").unwrap(), &[]).unwrap();
    ex.on_sent(0, Ok(tc0.clone()), t0);
    ex.on_update(t0, verification(&tc0, 0, 4));
    assert!(matches!(&ex.state[0], StepState::Failed(w) if w.contains("NOT_ALLOWED_IN_MODE")));
    assert!(matches!(&ex.state[1], StepState::Blocked(_)));
    assert!(ex.finished());
}

/// A fake OBSW that answers every copy of a TC like the real one's duplicate window:
/// the first `corrupt` copies get TM[1,2] CRC_MISMATCH (damaged on the way), the
/// next `lose` copies are lost on the way, then TM[1,1] + TM[1,7].
fn lossy_obsw(corrupt: usize, lose: usize) -> (SocketAddr, std::thread::JoinHandle<Vec<Vec<u8>>>) {
    let s = UdpSocket::bind("127.0.0.1:0").unwrap();
    s.set_read_timeout(Some(Duration::from_secs(5))).unwrap();
    let addr = s.local_addr().unwrap();
    let h = std::thread::spawn(move || {
        let mut copies = Vec::new();
        let mut buf = [0u8; 2048];
        let t = CdsShort::now().to_bytes();
        let mut seq = 0;
        while let Ok((n, from)) = s.recv_from(&mut buf) {
            copies.push(buf[..n].to_vec());
            let k = copies.len();
            let rid = [buf[0], buf[1], buf[2], buf[3]];
            let mut out = Vec::new();
            if k <= corrupt {
                let mut d = rid.to_vec();
                d.extend_from_slice(&mib::failure::FailureCode::CRC_MISMATCH.code().to_be_bytes());
                d.extend_from_slice(&[0, 1, 0, 2]);
                out.push((1, 2, d));
            } else if k > corrupt + lose {
                out.push((1, 1, rid.to_vec()));
                out.push((1, 7, rid.to_vec()));
            }
            for (sv, sub, d) in out {
                seq += 1;
                s.send_to(&build_tm(0x101, seq, sv, sub, 0, &t, &d), from).unwrap();
            }
            if k > corrupt + lose {
                break;
            }
        }
        copies
    });
    (addr, h)
}

// verifies: GND-01
#[test]
fn a_tc_is_resent_identically_until_its_acceptance_and_a_damaged_copy_is_no_verdict() {
    let (addr, fake) = lossy_obsw(1, 2);
    let mut s = Session::connect(&[(1, addr)], Transport::Udp, None, |_| Some(200)).unwrap();
    s.set_ack_timeout(Duration::from_millis(60));
    let tc = s
        .send(1, mib::tc::by_name("PING").unwrap(), &[], Some(3), None)
        .unwrap();
    let mut stages = Vec::new();
    let mut damaged = 0;
    let t0 = Instant::now();
    while t0.elapsed() < Duration::from_secs(5) && !stages.contains(&Stage::Completion) {
        for u in s.poll(Duration::from_millis(20)) {
            match u {
                Update::Verification { tag: Some(3), v, .. } => {
                    assert!(v.success, "a damaged copy's TM[1,2] is not the TC's verdict");
                    stages.push(v.stage);
                }
                Update::DamagedCopy { tag: Some(3), .. } => damaged += 1,
                Update::GaveUp { .. } => panic!("gave up"),
                _ => {}
            }
        }
    }
    assert_eq!(damaged, 1);
    assert_eq!(stages.last(), Some(&Stage::Completion));
    assert!(!s.busy(1));
    let copies = fake.join().unwrap();
    assert_eq!(copies.len(), 4, "1 damaged + 2 lost + 1 accepted and complete");
    assert!(
        copies.iter().all(|c| *c == tc.bytes),
        "every copy identical (same seq, same bytes)"
    );
}

// verifies: OPS-LINK-01
#[test]
fn an_accepted_tc_is_not_resent_while_its_completion_is_awaited() {
    // A fake that accepts at once and completes after 800 ms: with a first wait of
    // 60 ms the old rule resent it ("no outcome yet") about eight times.
    let sock = UdpSocket::bind("127.0.0.1:0").unwrap();
    sock.set_read_timeout(Some(Duration::from_millis(1500))).unwrap();
    let addr = sock.local_addr().unwrap();
    let fake = std::thread::spawn(move || {
        let t = CdsShort::now().to_bytes();
        let mut buf = [0u8; 2048];
        let mut copies = 0;
        let mut from = None;
        let t0 = Instant::now();
        while t0.elapsed() < Duration::from_millis(1500) {
            let Ok((n, f)) = sock.recv_from(&mut buf) else { break };
            copies += 1;
            let rid = [buf[0], buf[1], buf[2], buf[3]];
            if from.is_none() {
                from = Some((f, rid));
                sock.send_to(&build_tm(0x101, 1, 1, 1, 0, &t, &rid), f).unwrap();
                sock.set_read_timeout(Some(Duration::from_millis(800))).unwrap();
            }
            let _ = n;
        }
        if let Some((f, rid)) = from {
            sock.send_to(&build_tm(0x101, 2, 1, 7, 0, &t, &rid), f).unwrap();
        }
        copies
    });
    let mut s = Session::connect(&[(1, addr)], Transport::Udp, None, |_| Some(300)).unwrap();
    s.set_ack_timeout(Duration::from_millis(60));
    s.send(1, mib::tc::by_name("PING").unwrap(), &[], Some(1), None)
        .unwrap();
    let (mut done, mut resent) = (false, 0);
    let t0 = Instant::now();
    while t0.elapsed() < Duration::from_secs(4) && !done {
        for u in s.poll(Duration::from_millis(20)) {
            match u {
                Update::Verification { tag: Some(1), v, .. } => done |= v.stage == Stage::Completion,
                Update::Resent { .. } => resent += 1,
                _ => {}
            }
        }
    }
    assert!(done, "completion awaited and received");
    assert_eq!(resent, 0);
    assert_eq!(fake.join().unwrap(), 1, "one copy on the wire");
    assert_eq!(s.robots[&1].link_quality(), Some(1.0));
}

/// A fake lab-link OBSW that refuses the first `refuse` TCs (TM[1,2] to their sender, as
/// the obsw answers a damaged copy: the sender hears it but is not subscribed), then
/// subscribes the sender of the next: TM[1,1] for it and a TM[17,2] every 100 ms until
/// `run_for` after the first TC. Returns the times the TCs came, from the first.
fn subscribing_obsw(refuse: usize, run_for: Duration) -> (SocketAddr, std::thread::JoinHandle<Vec<Duration>>) {
    let s = UdpSocket::bind("127.0.0.1:0").unwrap();
    s.set_read_timeout(Some(Duration::from_millis(100))).unwrap();
    let addr = s.local_addr().unwrap();
    let h = std::thread::spawn(move || {
        let t = CdsShort::now().to_bytes();
        let mut buf = [0u8; 2048];
        let mut came = Vec::new();
        let mut t0 = None;
        let mut subscriber = None;
        let mut seq = 0u16;
        while t0.is_none_or(|t: Instant| t.elapsed() < run_for) {
            if let Ok((n, from)) = s.recv_from(&mut buf) {
                let t0 = *t0.get_or_insert_with(Instant::now);
                came.push(t0.elapsed());
                let rid = [buf[0], buf[1], buf[2], buf[3]];
                let _ = n;
                seq += 1;
                if came.len() <= refuse {
                    // Refused: the report to the sender only (rid, failure code, no data).
                    let body = [rid[0], rid[1], rid[2], rid[3], 0, 1];
                    s.send_to(&build_tm(0x101, seq, 1, 2, 0, &t, &body), from).unwrap();
                } else {
                    subscriber = Some(from);
                    s.send_to(&build_tm(0x101, seq, 1, 1, 0, &t, &rid), from).unwrap();
                }
            }
            if let Some(to) = subscriber {
                seq += 1;
                s.send_to(&build_tm(0x101, seq, 17, 2, 0, &t, &[]), to).unwrap();
            }
        }
        came
    });
    (addr, h)
}

// verifies: OPS-LIVE-LINK-04
#[test]
fn over_a_udp_lab_link_a_watching_ground_resubscribes_until_the_robot_streams_and_never_calls_it_lost() {
    // Six TCs in a row refused (20/5/5 loses or damages a quarter of the TCs: about one
    // run start in 4000 through the relay): with only the start marker and its resends
    // (0, 0.7, 1.75 s) the ground heard the first refusal, then nothing for the loss time.
    let (addr, fake) = subscribing_obsw(6, Duration::from_secs(5));
    let mut s = Session::connect(&[(1, addr)], Transport::Udp, None, |_| Some(100)).unwrap();
    s.watch_links();
    s.send(1, mib::tc::by_name("PING").unwrap(), &[], Some(1), None)
        .unwrap();
    let mut lost = Vec::new();
    let t0 = Instant::now();
    while t0.elapsed() < Duration::from_secs(4) {
        for u in s.poll(Duration::from_millis(50)) {
            if let Update::LinkLost { why, .. } = u {
                lost.push(why);
            }
        }
    }
    let came = fake.join().unwrap();
    assert!(lost.is_empty(), "{lost:?}; TCs came at {came:?}");
    assert!(s.robots[&1].subscription.streaming());
    // The seventh TC (the one subscribed) within the loss time, then no more retries.
    let loss = Duration::from_millis(u64::from(mib::ground_config::LINK_LOSS_MS));
    assert!(came.len() > 6 && came[6] < loss, "{came:?}");
    let retry = Duration::from_millis(u64::from(mib::ground_config::SUBSCRIBE_RETRY_MS));
    assert!(
        came.iter().filter(|&&t| t > came[6] + retry).count() <= 3,
        "heartbeats only, once streaming: {came:?}"
    );
}

// verifies: GND-01, DD-ROBUST-02
#[test]
fn the_retry_span_fits_in_the_obsw_duplicate_window() {
    let total: u32 = (0..=TC_RETRY_MAX).map(tc_retry_wait_ms).sum();
    assert_eq!(total, mib::ground_config::TC_RETRY_SPAN_MS);
    const { assert!(mib::ground_config::TC_RETRY_SPAN_MS <= mib::config::DUPLICATE_MAX_AGE_MS) };
    assert!(tc_retry_wait_ms(1) > tc_retry_wait_ms(0), "backoff");
    assert_eq!(tc_retry_wait_ms(100), mib::ground_config::TC_RETRY_CAP_MS);
}

// verifies: MMIC-VAL-02
#[test]
fn link_quality_is_over_the_last_window_of_exchanges() {
    let mut r = RobotStatus::new(1, "127.0.0.1:1".parse().unwrap());
    assert_eq!(r.link_quality(), None);
    for i in 0..(LINK_QUALITY_WINDOW + 50) {
        r.exchange(i >= 50 + LINK_QUALITY_WINDOW / 2);
    }
    assert_eq!(r.quality.len(), LINK_QUALITY_WINDOW);
    assert_eq!(r.link_quality(), Some(0.5));
}

// verifies: OPS-ERR-01
#[test]
fn a_step_whose_tc_cannot_be_sent_fails_with_the_typed_reason() {
    let pl = plan(TWO_STEPS);
    let opts = RunOptions::default();
    let t0 = Instant::now();
    let mut ex = Executor::new(&pl, &opts, &[], t0);
    assert_eq!(sends(&ex.on_tick(t0)), vec![0]);
    let fx = ex.on_sent(0, Err(SendError::NotFollowed(1)), t0);
    let said: Vec<&String> = fx
        .iter()
        .filter_map(|e| match e {
            Effect::Log(l) => Some(l),
            _ => None,
        })
        .collect();
    assert!(
        said.iter()
            .any(|l| l.contains("could not be sent: robot 1 is not followed by this collector")),
        "{said:?}"
    );
    assert!(matches!(ex.state[0], StepState::Failed { .. }), "{:?}", ex.state[0]);
    // A session's error keeps its own words.
    let e = SendError::from(OpsError::NoLink(3));
    assert_eq!(e.to_string(), "robot 3 has no link (give --robot 3=HOST:PORT)");
}

// verifies: OPS-ERR-01
#[test]
fn a_plan_load_error_says_whether_the_file_was_unreadable_or_invalid() {
    let dir = std::env::temp_dir().join(format!("ops-load-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let missing = crate::plan::load(&dir.join("none.toml")).unwrap_err();
    assert!(missing.io_error().is_some() && missing.diagnostics().is_none());
    assert!(missing.to_string().starts_with("cannot read"), "{missing}");
    let bad = dir.join("bad.toml");
    std::fs::write(&bad, "[[step]]\nid = 1\n").unwrap();
    let invalid = crate::plan::load(&bad).unwrap_err();
    assert!(invalid.io_error().is_none());
    assert!(!invalid.diagnostics().unwrap_or_default().is_empty(), "{invalid}");
    assert!(invalid.to_string().contains("error(s) in the plan"), "{invalid}");
    let _ = std::fs::remove_dir_all(&dir);
}

// verifies: OPS-PACE-01
#[test]
fn a_session_sends_one_store_retrieval_at_a_time_paced_by_the_one_rule() {
    // A fake robot: its reports to the first TC (a PING) leave counts 11..=13 missing;
    // the second TC (the retrieval) gets its completion report; the rest is counted.
    let sock = UdpSocket::bind("127.0.0.1:0").unwrap();
    sock.set_read_timeout(Some(Duration::from_millis(1000))).unwrap();
    let addr = sock.local_addr().unwrap();
    let fake = std::thread::spawn(move || {
        let t = CdsShort::now().to_bytes();
        let mut buf = [0u8; 2048];
        let mut tcs = Vec::new();
        while let Ok((n, f)) = sock.recv_from(&mut buf) {
            let Ok(tc) = pus::decode_tc(&buf[..n]) else { continue };
            tcs.push((tc.service, tc.subservice));
            let rid = [buf[0], buf[1], buf[2], buf[3]];
            let reports: &[(u16, u8)] = match tcs.len() {
                1 => &[(10, 1), (14, 7)],
                2 => &[(15, 1), (16, 7)],
                _ => &[],
            };
            for &(seq, sub) in reports {
                sock.send_to(&build_tm(0x101, seq, 1, sub, 0, &t, &rid), f).unwrap();
            }
        }
        tcs
    });
    let mut s = Session::connect(&[(1, addr)], Transport::Udp, None, |_| Some(500)).unwrap();
    s.send(1, mib::tc::by_name("PING").unwrap(), &[], None, None).unwrap();
    let t0 = Instant::now();
    while t0.elapsed() < Duration::from_secs(2) && s.robots[&1].seq.newest() != Some(14) {
        s.poll(Duration::from_millis(20));
    }
    assert_eq!(s.robots[&1].seq.missing_ranges(), vec![(11, 13)]);
    assert!(s.may_retrieve(1) && !s.retrieving(1), "nothing retrieved yet");
    let sent = Instant::now();
    assert_eq!(s.request_gaps(1, None, GAP_REQUESTS_MAX), vec![(11, 13)]);
    // In flight: nothing more goes, however it is asked for.
    assert!(s.retrieving(1) && !s.may_retrieve(1));
    assert!(s.request_gaps(1, None, GAP_REQUESTS_MAX).is_empty());
    assert!(s.request_missing_reports(1, 1).is_empty());
    // Its completion report ends it; the next waits the least gap after it went out.
    while t0.elapsed() < Duration::from_secs(4) && s.retrieving(1) {
        s.poll(Duration::from_millis(20));
    }
    assert!(!s.retrieving(1), "ended by its completion report");
    let min_gap = Duration::from_millis(u64::from(mib::ground_config::STORE_REQUEST_MIN_GAP_MS));
    while !s.may_retrieve(1) && sent.elapsed() < min_gap * 4 {
        s.poll(Duration::from_millis(10));
    }
    // The session's clock is the wall clock in ms: allow its rounding.
    assert!(
        sent.elapsed() + Duration::from_millis(2) >= min_gap,
        "{:?}",
        sent.elapsed()
    );
    assert!(s.may_retrieve(1));
    assert_eq!(s.robots[&1].pacer.sent, 1);
    drop(s);
    let tcs = fake.join().unwrap();
    assert_eq!(
        tcs,
        vec![(17, 1), (15, 9)],
        "one PING, one retrieval (by the hole's time window)"
    );
}

// verifies: OPS-LIVE-GAP-02
#[test]
fn reports_sent_before_the_first_tm_heard_are_asked_of_the_store_by_time() {
    // A fake robot over frames' worst case: the TC's acceptance (16) and completion (17)
    // are lost on the way and the first TM heard is the next one (18); its store answers
    // a TC[15,9] with the packets whose time stamp lies in the span asked for.
    let sock = UdpSocket::bind("127.0.0.1:0").unwrap();
    sock.set_read_timeout(Some(Duration::from_millis(1500))).unwrap();
    let addr = sock.local_addr().unwrap();
    let fake = std::thread::spawn(move || {
        let mut buf = [0u8; 2048];
        let mut store: Vec<(i64, Vec<u8>)> = Vec::new();
        let mut tcs = Vec::new();
        let mut seq = 18;
        // Sent before the TC: outside any span the ground may ask for.
        let old = CdsShort::from_unix_ms(CdsShort::now().unix_ms() - 5_000);
        store.push((old.unix_ms(), build_tm(0x101, 15, 17, 2, 0, &old.to_bytes(), &[])));
        while let Ok((n, f)) = sock.recv_from(&mut buf) {
            let Ok(tc) = pus::decode_tc(&buf[..n]) else { continue };
            tcs.push((tc.service, tc.subservice));
            let rid = [buf[0], buf[1], buf[2], buf[3]];
            let t = CdsShort::now();
            match (tc.service, tc.subservice) {
                (17, 1) => {
                    for (k, sub) in [(16, 1), (17, 7)] {
                        store.push((t.unix_ms(), build_tm(0x101, k, 1, sub, 0, &t.to_bytes(), &rid)));
                    }
                    std::thread::sleep(Duration::from_millis(30));
                    let later = CdsShort::now().to_bytes();
                    sock.send_to(&build_tm(0x101, seq, 17, 2, 0, &later, &[]), f).unwrap();
                }
                (15, 9) => {
                    let arg = |i: usize| tc.args[i].value;
                    let at = |d: i64, ms: i64| CdsShort {
                        days: d as u16,
                        ms_of_day: ms as u32,
                    };
                    let (a, b) = (at(arg(0), arg(1)).unix_ms(), at(arg(2), arg(3)).unix_ms());
                    for (_, p) in store.iter().filter(|(ms, _)| (a..=b).contains(ms)) {
                        sock.send_to(p, f).unwrap();
                    }
                    seq += 1;
                    sock.send_to(&build_tm(0x101, seq, 1, 7, 0, &t.to_bytes(), &rid), f)
                        .unwrap();
                }
                _ => {}
            }
        }
        tcs
    });
    let mut s = Session::connect(&[(1, addr)], Transport::Udp, None, |_| Some(700)).unwrap();
    // No resend: the robot executed the TC; only its reports were lost.
    s.set_ack_timeout(Duration::from_secs(20));
    s.send(1, mib::tc::by_name("PING").unwrap(), &[], Some(4), None)
        .unwrap();
    let t0 = Instant::now();
    while t0.elapsed() < Duration::from_secs(2) && s.robots[&1].seq.newest() != Some(18) {
        s.poll(Duration::from_millis(20));
    }
    assert_eq!(
        s.robots[&1].seq.missing_ranges(),
        vec![],
        "no hole after the first TM heard"
    );
    assert!(s.awaited_gaps(1).is_empty());
    s.request_missing_reports(1, 1);
    let mut stages = Vec::new();
    while t0.elapsed() < Duration::from_secs(4) && !stages.contains(&Stage::Completion) {
        for u in s.poll(Duration::from_millis(20)) {
            if let Update::Verification { tag: Some(4), v, .. } = u {
                stages.push(v.stage);
            }
        }
    }
    assert_eq!(stages, vec![Stage::Acceptance, Stage::Completion]);
    // The packet from before the TC was not asked for (outside the span).
    assert_eq!(s.robots[&1].seq.filled, 2);
    drop(s);
    assert_eq!(
        fake.join().unwrap(),
        vec![(17, 1), (15, 9)],
        "one PING, one retrieval by time"
    );
}

// verifies: OPS-LIVE-GAP-02
#[test]
fn a_span_asked_of_the_store_by_time_is_asked_again_only_until_its_packets_have_come() {
    // A fake robot: a PING's acceptance (16) is lost on the way, the first TM heard is the
    // next packet (17), the completion comes live 2.5 s later. The store's first answer
    // to the span loses the acceptance again (only 17 and the end report, which says the
    // span held 2, come); its second answer brings both. The ground asks at every chance
    // while the PING waits: once more after the first answer (a packet missing), never
    // after the second (all came) — not once per gap round.
    let sock = UdpSocket::bind("127.0.0.1:0").unwrap();
    sock.set_read_timeout(Some(Duration::from_millis(50))).unwrap();
    let addr = sock.local_addr().unwrap();
    let fake = std::thread::spawn(move || {
        let mut buf = [0u8; 2048];
        let mut store: Vec<(i64, u16, Vec<u8>)> = Vec::new();
        let mut tcs = Vec::new();
        let mut seq = 17;
        let mut ground = None;
        let mut ping: Option<(Instant, [u8; 4])> = None;
        let end = Instant::now() + Duration::from_millis(4_500);
        while Instant::now() < end {
            if let (Some((at, rid)), Some(f)) = (ping, ground) {
                if at.elapsed() >= Duration::from_millis(2_500) {
                    seq += 1;
                    let t = CdsShort::now().to_bytes();
                    sock.send_to(&build_tm(0x101, seq, 1, 7, 0, &t, &rid), f).unwrap();
                    ping = None;
                }
            }
            let Ok((n, f)) = sock.recv_from(&mut buf) else { continue };
            ground = Some(f);
            let Ok(tc) = pus::decode_tc(&buf[..n]) else { continue };
            tcs.push((tc.service, tc.subservice));
            let rid = [buf[0], buf[1], buf[2], buf[3]];
            let t = CdsShort::now();
            match (tc.service, tc.subservice) {
                (17, 1) => {
                    store.push((t.unix_ms(), 16, build_tm(0x101, 16, 1, 1, 0, &t.to_bytes(), &rid)));
                    std::thread::sleep(Duration::from_millis(30));
                    let later = CdsShort::now();
                    let first = build_tm(0x101, seq, 17, 2, 0, &later.to_bytes(), &[]);
                    store.push((later.unix_ms(), seq, first.clone()));
                    sock.send_to(&first, f).unwrap();
                    ping = Some((Instant::now(), rid));
                }
                (15, 9) => {
                    let arg = |i: usize| tc.args[i].value;
                    let at = |d: i64, ms: i64| CdsShort {
                        days: d as u16,
                        ms_of_day: ms as u32,
                    };
                    let (a, b) = (at(arg(0), arg(1)).unix_ms(), at(arg(2), arg(3)).unix_ms());
                    let span: Vec<_> = store.iter().filter(|(ms, _, _)| (a..=b).contains(ms)).collect();
                    let first_answer = tcs.iter().filter(|&&k| k == (15, 9)).count() == 1;
                    for (_, k, p) in &span {
                        if !(first_answer && *k == 16) {
                            sock.send_to(p, f).unwrap();
                        }
                    }
                    let mut done = (span.len() as u32).to_be_bytes().to_vec();
                    done.extend_from_slice(&CdsShort::from_unix_ms(store[0].0).to_bytes());
                    done.extend_from_slice(&16u16.to_be_bytes());
                    done.extend_from_slice(&0u32.to_be_bytes());
                    seq += 1;
                    sock.send_to(&build_tm(0x101, seq, 15, 19, 0, &t.to_bytes(), &done), f)
                        .unwrap();
                    seq += 1;
                    sock.send_to(&build_tm(0x101, seq, 1, 7, 0, &t.to_bytes(), &rid), f)
                        .unwrap();
                }
                _ => {}
            }
        }
        tcs
    });
    let mut s = Session::connect(&[(1, addr)], Transport::Udp, None, |_| Some(900)).unwrap();
    // No resend: the robot executed the TC; only its reports were lost.
    s.set_ack_timeout(Duration::from_secs(20));
    s.send(1, mib::tc::by_name("PING").unwrap(), &[], Some(5), None)
        .unwrap();
    let t0 = Instant::now();
    let mut stages = Vec::new();
    while t0.elapsed() < Duration::from_secs(4) && !stages.contains(&Stage::Completion) {
        // Every gap round the pacing rule lets go.
        if s.robots[&1].seq.first().is_some() {
            s.request_missing_reports(1, 1);
        }
        for u in s.poll(Duration::from_millis(20)) {
            if let Update::Verification { tag: Some(5), v, .. } = u {
                stages.push(v.stage);
            }
        }
    }
    assert_eq!(stages, vec![Stage::Acceptance, Stage::Completion]);
    drop(s);
    assert_eq!(
        fake.join().unwrap(),
        vec![(17, 1), (15, 9), (15, 9)],
        "one PING, the span asked twice: again only while a packet it held was missing"
    );
}

// verifies: OPS-LIVE-GAP-02
#[test]
fn an_on_board_step_about_to_start_awaits_the_gaps_after_the_tm_heard_so_far() {
    // A fake robot answers a PING with TM 0..=5, then (after the step is tracked) sends 8:
    // 6 and 7, where the step's reports may be, are the gaps its outcome waits on — the
    // live gap check asks for them first, not for the oldest gap of the session.
    let sock = UdpSocket::bind("127.0.0.1:0").unwrap();
    sock.set_read_timeout(Some(Duration::from_millis(1500))).unwrap();
    let addr = sock.local_addr().unwrap();
    let (go_tx, go_rx) = std::sync::mpsc::channel::<()>();
    let fake = std::thread::spawn(move || {
        let mut buf = [0u8; 2048];
        let (_, f) = sock.recv_from(&mut buf).unwrap();
        let t = CdsShort::now().to_bytes();
        for seq in 0..=5 {
            sock.send_to(&build_tm(0x101, seq, 17, 2, 0, &t, &[]), f).unwrap();
        }
        go_rx.recv().unwrap();
        sock.send_to(&build_tm(0x101, 8, 17, 2, 0, &t, &[]), f).unwrap();
    });
    let mut s = Session::connect(&[(1, addr)], Transport::Udp, None, |_| Some(700)).unwrap();
    let ping = s
        .send(1, mib::tc::by_name("PING").unwrap(), &[], Some(1), None)
        .unwrap();
    let t0 = Instant::now();
    while t0.elapsed() < Duration::from_secs(2) && s.robots[&1].seq.newest() != Some(5) {
        s.poll(Duration::from_millis(20));
    }
    // The PING's outcome no longer awaited (only the step's is).
    s.forget(&ping);
    let step = pus::build_tc(1, 900, mib::tc::by_name("PING").unwrap(), &[]).unwrap();
    s.adopt_new(1, step.clone(), Some(0), Some("r1-operational".into()));
    let old = pus::build_tc(1, 901, mib::tc::by_name("PING").unwrap(), &[]).unwrap();
    go_tx.send(()).unwrap();
    while t0.elapsed() < Duration::from_secs(4) && s.robots[&1].seq.newest() != Some(8) {
        s.poll(Duration::from_millis(20));
    }
    fake.join().unwrap();
    assert_eq!(s.robots[&1].seq.newest(), Some(8));
    assert_eq!(s.awaited_gaps(1), vec![(6, 7)]);
    // The same TC adopted as one an earlier session sent (reports anywhere): no such gaps.
    s.forget(&step);
    s.adopt(1, old, Some(0), None, false);
    let unanchored: Vec<(u16, u16)> = s.awaited_gaps(1);
    assert!(unanchored.is_empty(), "{unanchored:?}");
}

// verifies: OPS-LIVE-GAP-03
#[test]
fn a_control_tc_awaited_on_its_own_asks_the_gaps_after_its_send_before_the_older_ones() {
    // A fake robot answers a PING with TM 0..=5; once a plan step is tracked it sends
    // 6..=40 without 7; once a control TC comes it sends 41 and 43..=45 (42: its lost
    // completion). The step awaits gap 7; the control TC's own retrieval asks for 42.
    let sock = UdpSocket::bind("127.0.0.1:0").unwrap();
    sock.set_read_timeout(Some(Duration::from_millis(3000))).unwrap();
    let addr = sock.local_addr().unwrap();
    let (go_tx, go_rx) = std::sync::mpsc::channel::<()>();
    let fake = std::thread::spawn(move || {
        let mut buf = [0u8; 2048];
        let (_, f) = sock.recv_from(&mut buf).unwrap();
        let t = CdsShort::now().to_bytes();
        let send = |seqs: &mut dyn Iterator<Item = u16>| {
            for seq in seqs {
                sock.send_to(&build_tm(0x101, seq, 17, 2, 0, &t, &[]), f).unwrap();
            }
        };
        send(&mut (0..=5));
        go_rx.recv().unwrap();
        send(&mut (6..=40).filter(|&s| s != 7));
        // The control TC (resends of the PING may come first).
        let _ = sock.recv_from(&mut buf);
        send(&mut [41, 43, 44, 45].into_iter());
    });
    let mut s = Session::connect(&[(1, addr)], Transport::Udp, None, |_| Some(700)).unwrap();
    let ping = s
        .send(1, mib::tc::by_name("PING").unwrap(), &[], Some(1), None)
        .unwrap();
    let t0 = Instant::now();
    let upto = |s: &mut Session, n: u16| {
        while t0.elapsed() < Duration::from_secs(4) && s.robots[&1].seq.newest() != Some(n) {
            s.poll(Duration::from_millis(20));
        }
    };
    upto(&mut s, 5);
    s.forget(&ping);
    let step = pus::build_tc(1, 900, mib::tc::by_name("PING").unwrap(), &[]).unwrap();
    s.adopt_new(1, step, Some(0), Some("r1-operational".into()));
    go_tx.send(()).unwrap();
    upto(&mut s, 40);
    let control = s
        .send(
            1,
            mib::tc::by_name("PING").unwrap(),
            &[],
            None,
            Some("on-board plan".into()),
        )
        .unwrap();
    upto(&mut s, 45);
    fake.join().unwrap();
    assert_eq!(s.robots[&1].seq.newest(), Some(45));
    // The book's oldest awaited TC (the step) puts gap 7 first...
    assert_eq!(s.awaited_gaps(1).first(), Some(&(7, 7)));
    // ... the control TC's own ask goes where its reports are.
    assert_eq!(s.request_reports_of(1, &control, 1), vec![(42, 42)]);
}

// verifies: PLAN-GROUND-01
#[test]
fn an_on_board_step_whose_acceptance_comes_after_its_completion_is_timed_from_its_start_report() {
    let pl = plan(TWO_STEPS);
    let opts = RunOptions {
        display: false,
        ..RunOptions::default()
    };
    let t0 = Instant::now();
    let mut ex = Executor::new(&pl, &opts, &[], t0);
    let ping = mib::tc::by_name("PING").unwrap();
    let tc0 = pus::build_tc(1, 10, ping, &[]).unwrap();
    ex.run_on_board(0, tc0.clone());
    ex.on_tick(t0);
    let at = |u: Update, ms: i64| match u {
        Update::Verification {
            robot,
            tag,
            tc,
            v,
            after,
            ..
        } => Update::Verification {
            robot,
            tag,
            tc,
            v,
            after,
            at_ms: Some(ms),
        },
        other => other,
    };
    // The acceptance is lost live: the start report (on board at 38 356 ms) and the
    // completion (43 846 ms) come, the acceptance later from the store.
    ex.on_update(t0, at(verification(&tc0, 0, 3), 38_356));
    ex.on_update(t0, at(verification(&tc0, 0, 7), 43_846));
    ex.on_update(t0, at(verification(&tc0, 0, 1), 38_356));
    assert_eq!(ex.state[0], StepState::Done { secs: 5.49 });
}

// verifies: PLAN-GROUND-01
#[test]
fn the_upload_keeps_every_update_of_the_batch_its_control_tc_completed_in() {
    // A fake robot answers each control TC with TM[1,1], then one datagram holding the
    // TC's TM[1,7] and, after it, a TM[17,2] (as a store replay brings a step's report
    // with the control TC's own): the reports after the completion reach the executor.
    let sock = UdpSocket::bind("127.0.0.1:0").unwrap();
    sock.set_read_timeout(Some(Duration::from_millis(1500))).unwrap();
    let addr = sock.local_addr().unwrap();
    let fake = std::thread::spawn(move || {
        let t = CdsShort::now().to_bytes();
        let mut buf = [0u8; 2048];
        let mut seq = 0;
        let mut controls = 0;
        while let Ok((n, f)) = sock.recv_from(&mut buf) {
            let Ok(tc) = pus::decode_tc(&buf[..n]) else { continue };
            let rid = [buf[0], buf[1], buf[2], buf[3]];
            seq += 3;
            sock.send_to(&build_tm(tc.apid, seq, 1, 1, 0, &t, &rid), f).unwrap();
            if tc.service == 17 {
                continue;
            }
            controls += 1;
            let mut both = build_tm(tc.apid, seq + 1, 1, 7, 0, &t, &rid);
            both.extend(build_tm(tc.apid, seq + 2, 17, 2, 0, &t, &[]));
            sock.send_to(&both, f).unwrap();
        }
        controls
    });
    let mut s = Session::connect(&[(1, addr)], Transport::Udp, None, |_| Some(100)).unwrap();
    let c = crate::plan::onboard::Compiled {
        plan_id: 7,
        images: vec![crate::plan::onboard::RobotImage {
            robot: 1,
            bytes: vec![0; 8],
        }],
        tcs: Vec::new(),
    };
    let (early, r) = upload_and_start(&mut s, &c);
    assert_eq!(r, Ok(()));
    let after: usize = early
        .iter()
        .filter(|u| matches!(u, Update::Tm { tm, .. } if tm.service == 17))
        .count();
    assert_eq!(fake.join().unwrap(), 3, "PLAN_LOAD, PLAN_COMMIT, PLAN_START");
    assert_eq!(after, 3, "the TM after each completion kept: {early:?}");
}
