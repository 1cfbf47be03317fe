//! End-to-end tests of the OBSW issue: the real `obsw` binary over real UDP and TCP
//! sockets. Each test is named after the requirement it verifies.

use std::time::Duration;

use e2e_tests::{request_of, tc, Client, Obsw, Tm};
use mib::events::eid;
use mib::modes::{module_mode, node, robot_mode};
use mib::params::pid;
use mib::tc::function;
use mib::FailureCode as F;

const T: Duration = Duration::from_secs(5);

fn set_mode(c: &mut Client, mode: u32) -> Tm {
    let raw = c.send("MODE_SET", &[node::ROBOT as i64, mode as i64, 0]);
    c.wait_done(&raw, Duration::from_secs(20))
        .expect("mode change completes")
}

fn code(t: &Tm) -> u16 {
    t.failure_code().expect("a failure report")
}

// verifies: PUS-1-01, PUS-17-01
#[test]
fn ping_is_verified_in_order_over_udp() {
    let o = Obsw::start(&[]);
    let mut c = Client::udp(&o);
    let ping = c.send("PING", &[]);
    let done = c.wait_done(&ping, T).expect("completion");
    assert_eq!(done.subservice, 7);
    assert_eq!(c.verifications(&ping), vec![1, 3, 7]);
    assert!(
        c.log.iter().any(|t| t.service == 17 && t.subservice == 2),
        "TM[17,2] answers the ping"
    );
}

// verifies: PUS-17-01
#[test]
fn ping_is_verified_in_order_over_tcp_with_cobs() {
    let o = Obsw::start(&[]);
    let mut c = Client::tcp(&o);
    let ping = c.send("PING", &[]);
    assert_eq!(c.wait_done(&ping, T).expect("completion").subservice, 7);
    assert_eq!(c.verifications(&ping), vec![1, 3, 7]);
}

// verifies: DD-STOP-01
#[test]
fn sigterm_stops_the_obsw_with_exit_0_and_a_complete_tm_log() {
    let dir = std::env::temp_dir().join(format!("obsw-sigterm-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let log = dir.join("tm.hex");
    let mut o = Obsw::start(&["--tm-log", log.to_str().unwrap()]);
    let mut c = Client::udp(&o);
    let ping = c.send("PING", &[]);
    c.wait_done(&ping, T).expect("ping completes");
    let st = std::process::Command::new("kill")
        .args(["-TERM", &o.pid().to_string()])
        .status()
        .unwrap();
    assert!(st.success());
    let exit = o
        .wait_exit(Duration::from_secs(1))
        .expect("exits within 1 s of SIGTERM");
    assert_eq!(exit.code(), Some(0), "exit code after SIGTERM");
    // Everything it sent is in its log, the ping's four reports among it.
    let lines: Vec<Tm> = std::fs::read_to_string(&log)
        .unwrap()
        .lines()
        .filter_map(|l| Tm::parse(&hex_bytes(l)))
        .collect();
    let req = request_of(&ping);
    let reports: Vec<u8> = lines
        .iter()
        .filter(|t| t.request() == Some(req))
        .map(|t| t.subservice)
        .collect();
    assert_eq!(reports, vec![1, 3, 7], "the ping's PUS 1 reports in the log");
    assert!(
        lines.iter().any(|t| (t.service, t.subservice) == (17, 2)),
        "TM[17,2] in the log"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

fn hex_bytes(s: &str) -> Vec<u8> {
    (0..s.len() / 2)
        .filter_map(|i| u8::from_str_radix(&s[2 * i..2 * i + 2], 16).ok())
        .collect()
}

// verifies: PUS-PKT-03
#[test]
fn tm_sequence_count_is_continuous() {
    let o = Obsw::start(&[]);
    let mut c = Client::udp(&o);
    for _ in 0..20 {
        c.send("PING", &[]);
    }
    c.recv_for(Duration::from_millis(500));
    let seqs: Vec<u16> = c.log.iter().map(|t| t.seq).collect();
    assert!(seqs.len() >= 80, "4 reports per ping, got {}", seqs.len());
    for w in seqs.windows(2) {
        assert_eq!(
            w[1],
            mib::headers::SeqCount::new(w[0]).next().get(),
            "sequence counts {seqs:?}"
        );
    }
    assert!(c.log.iter().all(|t| t.apid == 0x101));
}

// verifies: MMIC-FW-02, PUS-3-03
#[test]
fn hk_arrives_at_the_configured_rate_without_request() {
    let o = Obsw::start(&[]);
    let mut c = Client::udp(&o);
    // The ground's first packet tells the OBSW where to send; it is not an HK request.
    let raw = c.send("HK_SET_INTERVAL", &[1, 100]);
    c.wait_done(&raw, T).expect("interval set");
    let got = c.recv_for(Duration::from_millis(2000));
    let hk: Vec<&Tm> = got.iter().filter(|t| t.sid() == Some(1)).collect();
    assert!((17..=23).contains(&hk.len()), "10 Hz for 2 s gave {} reports", hk.len());
    let mode = hk[0].hk(pid::MODE).unwrap();
    assert_eq!(mode, robot_mode::STANDBY as i64, "boots in standby");
    let v = hk[0].hk(pid::V_BAT_A).unwrap();
    assert!(v > mib::params::CAL_VOLT.raw(10.0), "battery voltage reported: {v}");
}

// verifies: PUS-1-02
#[test]
fn every_acceptance_failure_code_is_reachable_from_a_real_packet() {
    let o = Obsw::start(&[]);
    let mut c = Client::udp(&o);
    let apid = c.apid;
    // Refused TCs do not subscribe: their reports go to the grounds already subscribed.
    c.subscribe();
    let check = |c: &mut Client, raw: Vec<u8>, want: F| {
        c.send_raw(&raw);
        let r = request_of(&raw);
        let t = c
            .wait_for(T, |t| t.request() == Some(r) && t.subservice.is_multiple_of(2))
            .unwrap_or_else(|| panic!("no failure report for {want:?}"));
        assert_eq!(code(&t), want.code(), "{want:?}");
        assert!(
            c.wait_for(T, |t| t.event_id() == Some(eid::TC_REJECTED)).is_some(),
            "event for {want:?}"
        );
    };
    let ping = tc(apid, 101, 17, 1, &[]);
    let mut bad_crc = ping.clone();
    *bad_crc.last_mut().unwrap() ^= 1;
    check(&mut c, bad_crc, F::CRC_MISMATCH);
    check(&mut c, ping[..ping.len() - 1].to_vec(), F::MALFORMED_PACKET);
    let mut not_tc = tc(apid, 2, 17, 1, &[]);
    not_tc[0] &= !0x10;
    check(&mut c, not_tc, F::NOT_A_PUS_TC);
    check(&mut c, tc(apid + 1, 3, 17, 1, &[]), F::WRONG_APID);
    check(&mut c, tc(apid, 4, 99, 1, &[]), F::UNKNOWN_SERVICE);
    check(&mut c, tc(apid, 5, 17, 42, &[]), F::UNKNOWN_SUBSERVICE);
    check(&mut c, tc(apid, 6, 8, 1, &[0, 200]), F::UNKNOWN_FUNCTION);
    check(&mut c, tc(apid, 7, 8, 1, &[0, 1, 0]), F::BAD_ARG_LENGTH);
    check(&mut c, tc(apid, 8, 8, 1, &[0, 1, 0, 99]), F::ARG_OUT_OF_RANGE);
    check(&mut c, tc(apid, 9, 3, 27, &[0, 99]), F::UNKNOWN_SID);
    check(&mut c, tc(apid, 10, 5, 6, &[0x7F, 0x7F]), F::UNKNOWN_EVENT);
    check(&mut c, tc(apid, 11, 20, 1, &[0, 99]), F::UNKNOWN_PARAMETER);
    check(&mut c, tc(apid, 12, 20, 3, &[0, 1, 0, 0, 0, 1]), F::PARAM_OUT_OF_RANGE);
    check(&mut c, tc(apid, 13, 12, 1, &[0, 99]), F::UNKNOWN_MONITOR);
    check(&mut c, tc(apid, 14, 19, 4, &[0x02, 0x01]), F::UNKNOWN_ACTION_LINK);
    check(&mut c, tc(apid, 15, 200, 3, &[0, 0, 0, 99]), F::UNKNOWN_MODE_TARGET);
    check(
        &mut c,
        tc(apid, 16, 200, 1, &[0, 0, 0, 5, 0, 0, 0, 1, 0, 0]),
        F::INVALID_MODE,
    );
    // TC[11,4] with a release time in the past (CDS day 0) and with a bad inner TC.
    let inner = tc(apid, 17, 17, 1, &[]);
    let mut past = vec![1u8];
    past.extend_from_slice(&[0x40, 0, 1, 0, 0, 0, 0]); // CDS: P-field, day 1
    past.extend_from_slice(&inner);
    check(&mut c, tc(apid, 18, 11, 4, &past), F::RELEASE_TIME_PASSED);
    let mut bad_inner = vec![1u8];
    bad_inner.extend_from_slice(&[0x40, 0xFF, 0xFF, 0, 0, 0, 0]); // CDS: day 65535
    bad_inner.extend_from_slice(&tc(apid + 1, 19, 17, 1, &[]));
    check(&mut c, tc(apid, 20, 11, 4, &bad_inner), F::SCHEDULED_TC_INVALID);
    // Still alive and answering (a sequence count not used above).
    let ping = tc(apid, 100, 17, 1, &[]);
    c.send_raw(&ping);
    assert_eq!(c.wait_done(&ping, T).unwrap().subservice, 7);
}

// verifies: MMIC-MODE-01
#[test]
fn table7_standby_accepts_only_mode_changes() {
    let o = Obsw::start(&[]);
    let mut c = Client::udp(&o);
    for (name, args) in [
        ("RECONFIGURE", vec![0, 1]),
        ("MOVE_ARM", vec![0, 1500]),
        ("BOLT_FACE", vec![0, 15]),
        ("HOME", vec![]),
    ] {
        let raw = c.send(name, &args);
        let t = c.wait_done(&raw, T).expect("a report");
        assert_eq!(t.subservice, 4, "{name} refused at start");
        assert_eq!(code(&t), F::NOT_ALLOWED_IN_MODE.code(), "{name}");
        assert_eq!(t.data[6], robot_mode::STANDBY as u8);
    }
}

// verifies: MMIC-MODE-02
#[test]
fn table7_safed_accepts_only_hip_and_arm_commands() {
    let o = Obsw::start(&["--speed", "20"]);
    let mut c = Client::udp(&o);
    assert_eq!(set_mode(&mut c, robot_mode::SAFED).subservice, 7);
    let raw = c.send("BOLT_FACE", &[0, 15]);
    assert_eq!(code(&c.wait_done(&raw, T).unwrap()), F::NOT_ALLOWED_IN_MODE.code());
    let raw = c.send("RECONFIGURE", &[0, 1]);
    assert_eq!(code(&c.wait_done(&raw, T).unwrap()), F::NOT_ALLOWED_IN_MODE.code());
    // Gripped to one face the hip cannot turn, but a hold-in-place command is accepted
    // and completes (a rotation would stall against the structure).
    let raw = c.send("ROTATE_HIP", &[0]);
    let done = c.wait_done(&raw, Duration::from_secs(20)).unwrap();
    assert_eq!(
        done.subservice,
        7,
        "hip command accepted and completed in safed: {:?}",
        done.failure_code()
    );
}

// verifies: MMIC-MODE-03, PUS-200-01
#[test]
fn mode_tree_propagates_and_reports_every_node() {
    let o = Obsw::start(&["--speed", "20"]);
    let mut c = Client::udp(&o);
    assert_eq!(set_mode(&mut c, robot_mode::OPERATIONAL).subservice, 7);
    assert!(
        c.log
            .iter()
            .any(|t| t.service == 200 && t.subservice == 6 && t.data[..8] == [0, 0, 0, 1, 0, 0, 0, 1]),
        "robot reported operational"
    );
    let changed: Vec<u32> = c
        .log
        .iter()
        .filter(|t| t.event_id() == Some(eid::MODE_CHANGED))
        .map(|t| u32::from_be_bytes([t.data[2], t.data[3], t.data[4], t.data[5]]))
        .collect();
    for n in mib::modes::NODES {
        assert!(changed.contains(&n.id), "MODE_CHANGED for {}", n.name);
    }
    c.send("MODE_ANNOUNCE", &[node::ROBOT as i64]);
    let replies = c.recv_for(Duration::from_millis(500));
    let modes: Vec<(u32, u32)> = replies
        .iter()
        .filter(|t| t.service == 200 && t.subservice == 6)
        .map(|t| {
            (
                u32::from_be_bytes(t.data[..4].try_into().unwrap()),
                u32::from_be_bytes(t.data[4..8].try_into().unwrap()),
            )
        })
        .collect();
    assert_eq!(modes.len(), mib::modes::NODES.len());
    assert!(modes.contains(&(node::ARM_B, module_mode::ON)));
    assert_eq!(set_mode(&mut c, robot_mode::SAFED).subservice, 7);
    c.send("MODE_READ", &[node::BOLTER_A as i64]);
    let t = c
        .wait_for(T, |t| {
            t.service == 200 && t.subservice == 6 && t.data[..4] == node::BOLTER_A.to_be_bytes()
        })
        .unwrap();
    assert_eq!(u32::from_be_bytes(t.data[4..8].try_into().unwrap()), module_mode::OFF);
    c.send("MODE_READ", &[node::HIP as i64]);
    let t = c
        .wait_for(T, |t| {
            t.service == 200 && t.subservice == 6 && t.data[..4] == node::HIP.to_be_bytes()
        })
        .unwrap();
    assert_eq!(u32::from_be_bytes(t.data[4..8].try_into().unwrap()), module_mode::HOLD);
}

// verifies: MMIC-CMD-01, PUS-1-03
#[test]
fn full_reconfiguration_reports_every_verification_stage_in_order() {
    let o = Obsw::start(&["--speed", "50"]);
    let mut c = Client::udp(&o);
    assert_eq!(set_mode(&mut c, robot_mode::OPERATIONAL).subservice, 7);
    // Xneg (0) -> Xpos (1): extend A, contract B.
    let raw = c.send("RECONFIGURE", &[0, 1]);
    let done = c.wait_done(&raw, Duration::from_secs(30)).expect("completion");
    assert_eq!(done.subservice, 7, "failure {:?}", done.failure_code());
    assert_eq!(c.verifications(&raw), vec![1, 3, 5, 5, 7]);
    let r = request_of(&raw);
    let steps: Vec<u8> = c
        .log
        .iter()
        .filter(|t| t.request() == Some(r) && t.subservice == 5)
        .filter_map(|t| t.step())
        .collect();
    assert_eq!(steps, vec![1, 2]);
    let reached = c.wait_for(T, |t| t.event_id() == Some(eid::STATE_REACHED)).or_else(|| {
        c.log
            .iter()
            .rev()
            .find(|t| t.event_id() == Some(eid::STATE_REACHED))
            .cloned()
    });
    assert_eq!(reached.expect("STATE_REACHED").data[2], 1);
    c.send("HK_ONE_SHOT", &[1]);
    let hk = c.wait_for(T, |t| t.sid() == Some(1)).unwrap();
    assert_eq!(hk.hk(pid::CONFIG_STATE), Some(1), "state computed from sensors");
    // The ground's belief is now wrong: Xneg is not where the robot is.
    let raw = c.send("RECONFIGURE", &[0, 2]);
    let t = c.wait_done(&raw, T).unwrap();
    assert_eq!(code(&t), F::INITIAL_STATE_MISMATCH.code());
    assert_eq!(&t.data[6..8], &[0, 1], "believed 0, computed 1");
}

// verifies: MMIC-CMD-08
#[test]
fn a_second_action_while_one_runs_is_busy() {
    let o = Obsw::start(&["--speed", "5"]);
    let mut c = Client::udp(&o);
    assert_eq!(set_mode(&mut c, robot_mode::OPERATIONAL).subservice, 7);
    let first = c.send("RECONFIGURE", &[0, 1]);
    let second = c.send("BOLT_PAIR", &[0, 1]);
    let t = c.wait_done(&second, T).unwrap();
    assert_eq!(code(&t), F::BUSY.code());
    assert_eq!(u16::from_be_bytes([t.data[6], t.data[7]]), function::RECONFIGURE);
    let stop = c.send("STOP", &[]);
    assert_eq!(c.wait_done(&stop, T).unwrap().subservice, 7);
    let t = c.wait_done(&first, T).unwrap_or_else(|| {
        panic!(
            "no completion of the reconfiguration: {:?}",
            c.log
                .iter()
                .filter(|t| t.service == 1)
                .map(|t| (t.subservice, t.request()))
                .collect::<Vec<_>>()
        )
    });
    assert_eq!(code(&t), F::ABORTED_BY_COMMAND.code());
}

// verifies: DD-ROBUST-02, GND-01
#[test]
fn a_duplicate_tc_is_acknowledged_again_but_never_executed_twice() {
    let o = Obsw::start(&["--speed", "50"]);
    let mut c = Client::udp(&o);
    assert_eq!(set_mode(&mut c, robot_mode::OPERATIONAL).subservice, 7);
    let seq = c.next_seq();
    let bolt = e2e_tests::tc_named(c.apid, seq, "BOLT_PAIR", &[0, 1]);
    c.send_raw(&bolt);
    c.send_raw(&bolt);
    let done = c.wait_done(&bolt, Duration::from_secs(60)).expect("bolt completes");
    assert!(matches!(done.subservice, 7 | 8));
    c.send_raw(&bolt);
    c.recv_for(Duration::from_millis(500));
    let v = c.verifications(&bolt);
    assert_eq!(
        v.iter().filter(|s| **s == 1).count(),
        3,
        "acknowledged three times: {v:?}"
    );
    assert_eq!(v.iter().filter(|s| **s == 3).count(), 1, "started once: {v:?}");
    let results = c
        .log
        .iter()
        .filter(|t| matches!(t.event_id(), Some(eid::BOLT_PAIR_DONE) | Some(eid::BOLT_FAILURE)))
        .count();
    assert_eq!(results, 1, "the pair was bolted once");
    c.send("HK_ONE_SHOT", &[4]);
    let hk = c.wait_for(T, |t| t.sid() == Some(4)).unwrap();
    assert_eq!(hk.hk(pid::TC_DUPLICATE), Some(2));
}

// verifies: DD-ROBUST-01
#[test]
fn garbage_never_stalls_the_obsw() {
    let o = Obsw::start(&[]);
    let mut c = Client::udp(&o);
    let mut x: u32 = 12345;
    for i in 0..500 {
        let len = (i * 7) % 90;
        let junk: Vec<u8> = (0..len)
            .map(|_| {
                x ^= x << 13;
                x ^= x >> 17;
                x ^= x << 5;
                x as u8
            })
            .collect();
        c.send_raw(&junk);
        if i % 50 == 0 {
            // Read the refusals as they come, as a ground would.
            c.recv_for(Duration::from_millis(20));
        }
    }
    let mut t = Client::tcp(&o);
    if let e2e_tests::Link::Tcp(s, _) = &mut t.link {
        use std::io::Write;
        s.write_all(&[1, 2, 3, 0, 0, 0xFF, 0xFE, 0]).unwrap();
    }
    let ping = c.send("PING", &[]);
    assert_eq!(c.wait_done(&ping, T).expect("still answering").subservice, 7);
    let ping = t.send("PING", &[]);
    assert_eq!(t.wait_done(&ping, T).expect("TCP still answering").subservice, 7);
}
