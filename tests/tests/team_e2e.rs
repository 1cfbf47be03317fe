//! Team coordination without the ground (docs/team.md), end to end with three real obsw
//! processes linked by UDP (`--team-udp`, `--peer`, `--team-state`). The roster is
//! uploaded by the ground (TC TEAM_ROSTER to each robot); then the ground is silent.
//! Everything is judged from the TM each obsw wrote to its `--tm-log` (every packet it
//! sent), read every 20 ms: a packet's time is when the test first saw its line.
//!
//! Team datagrams are authenticated with a team key (`--team-key`, 32 random bytes made
//! here, mode 0600). The direct scenario also plays a forger on a robot's team port (random
//! MACs claiming the leader, truncated and unknown-sender datagrams, replays of real
//! datagrams captured by a tap) and restarts the killed leader with `kill -9` to check that
//! roster and authorisation survive.

use std::net::UdpSocket;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use e2e_tests::relay::{Config, Faults, Relay};
use e2e_tests::{free_udp, Client, Obsw, Tm};
use mib::events::eid;
use mib::modes::{node, robot_mode};
use mib::params::pid;
use mib::FailureCode as F;

const ROBOTS: u8 = 3;

/// A fresh random team key file (raw 32 bytes, mode 0600, the space link's key format).
fn team_key(dir: &Path) -> PathBuf {
    let mut k = [0u8; 32];
    std::io::Read::read_exact(&mut std::fs::File::open("/dev/urandom").unwrap(), &mut k).unwrap();
    let p = dir.join("team.key");
    mmic_link::persist::create_key_file(&p, &k).unwrap();
    p
}

/// A UDP tap in front of a robot's team port: forwards every datagram and keeps a copy
/// (for replays).
struct Tap {
    addr: String,
    seen: std::sync::Arc<std::sync::Mutex<Vec<Vec<u8>>>>,
}

impl Tap {
    fn start(target: &str) -> Tap {
        let sock = UdpSocket::bind("127.0.0.1:0").unwrap();
        let addr = sock.local_addr().unwrap().to_string();
        let target: std::net::SocketAddr = target.parse().unwrap();
        let seen = std::sync::Arc::new(std::sync::Mutex::new(Vec::new()));
        let keep = seen.clone();
        std::thread::spawn(move || {
            let mut buf = [0u8; 2048];
            while let Ok((n, _)) = sock.recv_from(&mut buf) {
                keep.lock().unwrap().push(buf[..n].to_vec());
                let _ = sock.send_to(&buf[..n], target);
            }
        });
        Tap { addr, seen }
    }
}

/// TEAM_STATUS (TM[211,2]) fields: (term, leader, auth plan, auth steps, roster).
fn team_status(t: &Tm) -> Option<(u32, u8, u16, u8, Vec<u8>)> {
    let d = &t.data;
    (t.service == mib::team::TEAM_SERVICE && t.subservice == mib::team::TEAM_SUBSERVICE_STATUS && d.len() >= 27).then(
        || {
            let n = usize::from(d[26]);
            (
                u32::from_be_bytes([d[0], d[1], d[2], d[3]]),
                d[5],
                u16::from_be_bytes([d[9], d[10]]),
                d[13],
                d[27..(27 + n).min(d.len())].to_vec(),
            )
        },
    )
}

/// Every packet of one obsw's `--tm-log`, with the time the test first saw it.
struct Log {
    path: PathBuf,
    lines: usize,
    tm: Vec<(Instant, Tm)>,
}

impl Log {
    fn new(path: PathBuf) -> Log {
        Log {
            path,
            lines: 0,
            tm: Vec::new(),
        }
    }
    fn poll(&mut self) {
        let text = std::fs::read_to_string(&self.path).unwrap_or_default();
        let now = Instant::now();
        // Only complete lines (the obsw may be writing the last one).
        let complete: Vec<&str> = text.split_inclusive('\n').filter(|l| l.ends_with('\n')).collect();
        for line in &complete[self.lines..] {
            let hex = line.trim();
            let bytes: Option<Vec<u8>> = (0..hex.len() / 2)
                .map(|i| u8::from_str_radix(&hex[2 * i..2 * i + 2], 16).ok())
                .collect();
            if let Some(t) = bytes.as_deref().and_then(Tm::parse) {
                self.tm.push((now, t));
            }
        }
        self.lines = complete.len();
    }
    /// Events `id` with their parameters (after the event ID) and arrival.
    fn events(&self, id: u16) -> Vec<(Instant, Vec<u8>)> {
        self.tm
            .iter()
            .filter(|(_, t)| t.event_id() == Some(id))
            .map(|(at, t)| (*at, t.data[2..].to_vec()))
            .collect()
    }
    /// The last leader this robot reported (term, leader) with its arrival.
    fn leader(&self) -> Option<(Instant, u32, u8)> {
        self.events(eid::LEADER_ELECTED)
            .into_iter()
            .map(|(at, p)| (at, u32::from_be_bytes([p[0], p[1], p[2], p[3]]), p[4]))
            .max_by_key(|(_, term, _)| *term)
    }
    /// The last TEAM HK report (SID 24), if any.
    fn team_hk(&self) -> Option<&Tm> {
        self.tm
            .iter()
            .rev()
            .map(|(_, t)| t)
            .find(|t| t.sid() == Some(mib::hk::sid::TEAM))
    }
    /// A parameter of the last TEAM HK report.
    fn hk(&self, param: u16) -> Option<i64> {
        self.team_hk().and_then(|t| t.hk(param))
    }
    /// The last TEAM_STATUS report.
    fn status(&self) -> Option<(u32, u8, u16, u8, Vec<u8>)> {
        self.tm.iter().rev().find_map(|(_, t)| team_status(t))
    }
    fn summary(&self) -> String {
        let mut s = String::new();
        for (_, t) in &self.tm {
            if let Some(id) = t.event_id() {
                let name = mib::events::by_id(id).map_or("?", |e| e.name);
                s.push_str(&format!("{name}{:?} ", &t.data[2..]));
            }
        }
        s
    }
}

fn poll_until(logs: &mut [Log], limit: Duration, mut done: impl FnMut(&[Log]) -> bool) -> bool {
    let end = Instant::now() + limit;
    loop {
        for l in logs.iter_mut() {
            l.poll();
        }
        if done(logs) {
            return true;
        }
        if Instant::now() > end {
            return false;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// Starts robot `robot` listening on `listen[robot - 1]` and sending to `peers[n - 1]`
/// (robot 2 sends to robot 1 through `tap` if given), its TM logged to `log`.
fn start(dir: &Path, robot: u8, listen: &[String], addrs: &[String], tap: Option<&str>, log: &str) -> Obsw {
    let mut args: Vec<String> = vec![
        "--tm-log".into(),
        dir.join(log).display().to_string(),
        "--team-udp".into(),
        listen[robot as usize - 1].clone(),
        "--team-state".into(),
        dir.join(format!("team-{robot}.state")).display().to_string(),
        "--team-key".into(),
        dir.join("team.key").display().to_string(),
    ];
    for (i, a) in addrs.iter().enumerate() {
        if i + 1 != robot as usize {
            let a = match tap {
                Some(t) if robot == 2 && i == 0 => t,
                _ => a.as_str(),
            };
            args.push("--peer".into());
            args.push(format!("{}={a}", i + 1));
        }
    }
    let refs: Vec<&str> = args.iter().map(String::as_str).collect();
    Obsw::start_robot(robot, &refs)
}

// verifies: TEAM-E2E-01, TEAM-E2E-02, TEAM-OBSW-02, TEAM-OBSW-03, TEAM-HK-01, TEAM-SEC-01, TEAM-SEC-03
#[test]
fn three_obsw_elect_hold_reelect_after_a_kill_and_obey_the_returning_ground() {
    scenario("direct", None);
}

// verifies: TEAM-E2E-01
#[test]
fn the_same_through_the_lossy_relay_20_percent_drop() {
    // Every inter-robot datagram through the project's relay: 20 % dropped, 5 % duplicated,
    // 1 % corrupted (fails the packet CRC, counted and ignored). The ground link is direct.
    scenario("relay", Some(Faults::new(0.2, 0.05, 0.01)));
}

/// Everything in a robot's on-board store, read back by the ground with TC[15,9].
fn stored(c: &mut Client) -> Vec<Tm> {
    let raw = c.send("STORE_DOWNLINK_TIME", &[0, 0, 65535, 4_294_967_295]);
    let from = c.log.len();
    c.wait_for(Duration::from_secs(10), |t| (t.service, t.subservice) == (15, 19))
        .expect("store downlink ends with TM[15,19]");
    assert_eq!(c.wait_done(&raw, Duration::from_secs(5)).map(|t| t.subservice), Some(7));
    c.log[from..].to_vec()
}

// verifies: TEAM-E2E-03, TEAM-PLAN-01, TEAM-PLAN-02, TEAM-AUTH-02, TEAM-AUTH-03
#[test]
fn without_the_ground_the_leader_continues_exactly_the_authorised_steps_and_the_ground_retrieves_them() {
    use mib::tc::function;
    const K: i64 = 2;
    let dir = std::env::temp_dir().join(format!("team-e2e-plan-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    team_key(&dir);
    let listen: Vec<String> = (0..ROBOTS).map(|_| free_udp().to_string()).collect();
    let obsw: Vec<Obsw> = (1..=ROBOTS)
        .map(|r| start(&dir, r, &listen, &listen, None, &format!("tm-{r}.hex")))
        .collect();
    let mut logs: Vec<Log> = (1..=ROBOTS)
        .map(|r| Log::new(dir.join(format!("tm-{r}.hex"))))
        .collect();
    // The plan: every robot reconfigures from Xneg (0) to state 1 and back. The ground
    // authorises K = 2 steps of it and uploads them; each step names its initial state.
    let steps = [
        mib::team::PlanStep {
            step: 1,
            function: function::RECONFIGURE,
            args: [0, 1],
            initial_state: 0,
        },
        mib::team::PlanStep {
            step: 2,
            function: function::RECONFIGURE,
            args: [1, 0],
            initial_state: 1,
        },
    ];
    let hash = mib::team::plan_hash(7, &steps);
    let mut ground: Vec<Client> = obsw.iter().map(Client::udp).collect();
    let ok = |c: &mut Client, name: &str, args: &[i64]| {
        let raw = c.send(name, args);
        let done = c.wait_done(&raw, Duration::from_secs(30)).expect(name);
        assert_eq!(done.subservice, 7, "{name} {args:?}: {}", c.summary());
    };
    let step_args = |s: &mib::team::PlanStep| -> Vec<i64> {
        vec![
            7,
            i64::from(s.step),
            i64::from(s.function),
            i64::from(s.args[0]),
            i64::from(s.args[1]),
            i64::from(s.initial_state),
        ]
    };
    for (i, c) in ground.iter_mut().enumerate() {
        ok(c, "TEAM_ROSTER", &[1, 2, 3, 0, 0, 0, 0, 0]);
        ok(c, "TEAM_AUTHORISE", &[7, i64::from(hash), 1, K, 600]);
        if i == 0 {
            // Refused uploads: a step outside the authorisation, an unbolt, and steps
            // that do not hash to the authorised plan (all then dropped).
            let refused = |c: &mut Client, s: &mib::team::PlanStep| {
                let raw = c.send("TEAM_PLAN_STEP", &step_args(s));
                c.wait_done(&raw, Duration::from_secs(5)).and_then(|t| t.failure_code())
            };
            let outside = mib::team::PlanStep { step: 3, ..steps[0] };
            assert_eq!(refused(c, &outside), Some(F::PLAN_NOT_AUTHORISED.code()));
            let unbolt = mib::team::PlanStep {
                function: function::UNBOLT_FACE,
                ..steps[0]
            };
            assert_eq!(refused(c, &unbolt), Some(F::PLAN_FORBIDDEN_FUNCTION.code()));
            ok(c, "TEAM_PLAN_STEP", &step_args(&steps[0]));
            let altered = mib::team::PlanStep {
                args: [1, 2],
                ..steps[1]
            };
            assert_eq!(refused(c, &altered), Some(F::PLAN_HASH_MISMATCH.code()));
        }
        for s in &steps {
            ok(c, "TEAM_PLAN_STEP", &step_args(s));
        }
        ok(c, "MODE_SET", &[node::ROBOT as i64, robot_mode::OPERATIONAL as i64, 0]);
    }
    for l in logs.iter_mut() {
        l.poll();
        assert_eq!(l.events(eid::PLAN_UPLOADED).len(), 1, "plan loaded: {}", l.summary());
    }
    let silent = Instant::now();
    // The ground is silent: every robot holds, a leader is elected, and on its CONTINUE
    // every robot runs step 1 then step 2 (each only from its initial state), then holds.
    let steps_of = |l: &Log| -> Vec<u16> {
        l.events(eid::PLAN_STEP_EXECUTED)
            .iter()
            .map(|(_, p)| u16::from_be_bytes([p[2], p[3]]))
            .collect()
    };
    assert!(
        poll_until(&mut logs, Duration::from_secs(120), |l| l
            .iter()
            .all(|x| steps_of(x).len() == K as usize)),
        "every robot ran the {K} authorised steps: {:?}",
        logs.iter().map(Log::summary).collect::<Vec<_>>()
    );
    let done_at = Instant::now();
    // Then the robots stop: back in STANDBY (both grippers hold), nothing more started.
    let standby_after_steps = |l: &Log| {
        let last_step = l.events(eid::PLAN_STEP_EXECUTED).last().map(|(at, _)| *at).unwrap();
        l.events(eid::MODE_CHANGED).iter().any(|(at, p)| {
            *at >= last_step
                && u32::from_be_bytes([p[0], p[1], p[2], p[3]]) == node::ROBOT
                && u32::from_be_bytes([p[8], p[9], p[10], p[11]]) == robot_mode::STANDBY
        })
    };
    assert!(
        poll_until(&mut logs, Duration::from_secs(60), |l| l
            .iter()
            .all(standby_after_steps)),
        "every robot holds after the last authorised step: {:?}",
        logs.iter().map(Log::summary).collect::<Vec<_>>()
    );
    std::thread::sleep(Duration::from_secs(3));
    for (i, l) in logs.iter_mut().enumerate() {
        l.poll();
        assert_eq!(steps_of(l), [1, 2], "robot {}: exactly the K steps, in order", i + 1);
        // Each step started from its initial state: the reconfiguration reached the
        // target state (STATE_REACHED 1, then 0).
        let reached: Vec<u8> = l.events(eid::STATE_REACHED).iter().map(|(_, p)| p[0]).collect();
        assert!(reached.ends_with(&[1, 0]), "robot {}: states {reached:?}", i + 1);
    }
    let leaders: Vec<u8> = logs
        .iter()
        .flat_map(|l| l.events(eid::PLAN_STEP_EXECUTED).into_iter().map(|(_, p)| p[6]))
        .collect();
    eprintln!(
        "plan: ground silent -> every robot ran the {K} authorised steps {:.1} s later (leaders named: {leaders:?}), then held",
        (done_at - silent).as_secs_f64()
    );
    // The ground returns and retrieves what was done from each robot's on-board store.
    for (i, c) in ground.iter_mut().enumerate() {
        c.subscribe();
        let st = stored(c);
        let executed: Vec<(u16, u16, u16)> = st
            .iter()
            .filter(|t| t.event_id() == Some(eid::PLAN_STEP_EXECUTED))
            .map(|t| {
                let p = &t.data[2..];
                (
                    u16::from_be_bytes([p[0], p[1]]),
                    u16::from_be_bytes([p[2], p[3]]),
                    u16::from_be_bytes([p[4], p[5]]),
                )
            })
            .collect();
        assert_eq!(
            executed,
            [(7, 1, function::RECONFIGURE), (7, 2, function::RECONFIGURE)],
            "robot {}: the store holds the executed steps",
            i + 1
        );
        let hk = st.iter().rev().find(|t| t.sid() == Some(mib::hk::sid::TEAM));
        assert_eq!(
            hk.and_then(|t| t.hk(pid::TEAM_STEPS_EXECUTED)),
            Some(K),
            "robot {}",
            i + 1
        );
        // The started-step count is durable (written before each step moved).
        let state = std::fs::read_to_string(dir.join(format!("team-{}.state", i + 1))).unwrap();
        assert!(state.contains(&format!("plan 7 {K} ")), "robot {}: {state}", i + 1);
    }
    drop(obsw);
    let _ = std::fs::remove_dir_all(&dir);
}

/// Returns (election after the first GROUND_LOST, re-election after the kill, slowest
/// GROUND_REGAINED after the ground's TC).
fn scenario(name: &str, faults: Option<Faults>) -> (Duration, Duration, Duration) {
    let dir = std::env::temp_dir().join(format!("team-e2e-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    team_key(&dir);
    let listen: Vec<String> = (0..ROBOTS).map(|_| free_udp().to_string()).collect();
    // Direct: a tap between robot 2 and robot 1 keeps real datagrams for the replay.
    let tap = faults.is_none().then(|| Tap::start(&listen[0]));
    // With faults, robot n's peers send to a relay that forwards to robot n.
    let mut relays: Vec<Relay> = Vec::new();
    let addrs: Vec<String> = match faults {
        None => listen.clone(),
        Some(f) => listen
            .iter()
            .enumerate()
            .map(|(i, a)| {
                let target = a.parse().unwrap();
                let r = Relay::start(Config::both_ways(target, target, f, 100 + i as u64)).unwrap();
                let at = r.udp.to_string();
                relays.push(r);
                at
            })
            .collect(),
    };
    let tap_addr = tap.as_ref().map(|t| t.addr.clone());
    let mut obsw: Vec<Option<Obsw>> = (1..=ROBOTS)
        .map(|r| {
            Some(start(
                &dir,
                r,
                &listen,
                &addrs,
                tap_addr.as_deref(),
                &format!("tm-{r}.hex"),
            ))
        })
        .collect();
    let mut logs: Vec<Log> = (1..=ROBOTS)
        .map(|r| Log::new(dir.join(format!("tm-{r}.hex"))))
        .collect();

    // The ground uploads the roster, then falls silent.
    let mut ground: Vec<Client> = obsw.iter().map(|o| Client::udp(o.as_ref().unwrap())).collect();
    for c in ground.iter_mut() {
        let raw = c.send("TEAM_ROSTER", &[1, 2, 3, 0, 0, 0, 0, 0]);
        let done = c.wait_done(&raw, Duration::from_secs(5)).expect("roster answered");
        assert_eq!(done.subservice, 7, "roster accepted: {}", c.summary());
        // An authorisation for plan 7 (2 steps from step 1, 10 min).
        let raw = c.send("TEAM_AUTHORISE", &[7, 0xC0FFEE, 1, 2, 600]);
        let done = c
            .wait_done(&raw, Duration::from_secs(5))
            .expect("authorisation answered");
        assert_eq!(done.subservice, 7, "authorisation accepted: {}", c.summary());
    }
    // The robots work (OPERATIONAL), so that holding is a visible mode change.
    let ops: Vec<Vec<u8>> = ground
        .iter_mut()
        .map(|c| c.send("MODE_SET", &[node::ROBOT as i64, robot_mode::OPERATIONAL as i64, 0]))
        .collect();
    for (c, raw) in ground.iter_mut().zip(&ops) {
        let done = c.wait_done(raw, Duration::from_secs(30)).expect("operational");
        assert_eq!(done.subservice, 7, "operational: {}", c.summary());
    }
    let silent = Instant::now();

    // 1. Ground loss → every robot holds, one leader agreed by all.
    let agreed = |logs: &[Log]| -> Option<(u32, u8)> {
        let l: Vec<_> = logs.iter().map(Log::leader).collect();
        let (_, term, leader) = l[0]?;
        l.iter()
            .all(|x| x.is_some_and(|(_, t, ld)| t == term && ld == leader))
            .then_some((term, leader))
    };
    assert!(
        poll_until(&mut logs, Duration::from_secs(15), |l| agreed(l).is_some()
            && l.iter().all(|x| !x.events(eid::GROUND_LOST).is_empty())),
        "no agreed leader 15 s after the ground fell silent: {:?}",
        logs.iter().map(Log::summary).collect::<Vec<_>>()
    );
    let (term1, leader1) = agreed(&logs).unwrap();
    let lost_at = logs.iter().map(|l| l.events(eid::GROUND_LOST)[0].0).min().unwrap();
    let elected_at = logs.iter().map(|l| l.leader().unwrap().0).max().unwrap();
    eprintln!(
        "{name}: ground silent -> first GROUND_LOST {:.2} s, all agree on leader {leader1} (term {term1}) {:.2} s after it",
        (lost_at - silent).as_secs_f64(),
        (elected_at - lost_at).as_secs_f64()
    );
    // Every robot holds: its robot node leaves OPERATIONAL for STANDBY (both grippers
    // hold) or SAFED, caused by the team (MODE_CHANGED cause = GROUND_LOST).
    let held = |l: &Log| {
        l.events(eid::MODE_CHANGED).iter().any(|(at, p)| {
            let (nd, to, cause) = (
                u32::from_be_bytes([p[0], p[1], p[2], p[3]]),
                u32::from_be_bytes([p[8], p[9], p[10], p[11]]),
                u16::from_be_bytes([p[12], p[13]]),
            );
            *at > silent
                && nd == node::ROBOT
                && (to == robot_mode::STANDBY || to == robot_mode::SAFED)
                && cause == eid::GROUND_LOST
        })
    };
    assert!(
        poll_until(&mut logs, Duration::from_secs(10), |l| l.iter().all(held)),
        "every robot holds: {:?}",
        logs.iter().map(Log::summary).collect::<Vec<_>>()
    );
    // TEAM HK agrees with the events: term, leader, ground not seen, packets accepted.
    assert!(
        poll_until(&mut logs, Duration::from_secs(12), |l| l.iter().all(|x| x
            .hk(pid::TEAM_TERM)
            == Some(i64::from(term1))
            && x.hk(pid::TEAM_LEADER) == Some(i64::from(leader1))
            && x.hk(pid::TEAM_GROUND_SEEN) == Some(0)
            && x.hk(pid::TEAM_PKT_RECEIVED).is_some_and(|n| n > 0)
            && x.hk(pid::TEAM_PKT_SENT).is_some_and(|n| n > 0))),
        "TEAM HK of every robot: term {term1}, leader {leader1}: {:?}",
        logs.iter()
            .map(|l| l.team_hk().map(|t| t.data.clone()))
            .collect::<Vec<_>>()
    );
    // Every follower executed the leader's HOLD (the leader holds on its own).
    assert!(
        poll_until(&mut logs, Duration::from_secs(3), |l| (1..=ROBOTS).all(|r| r
            == leader1
            || l[r as usize - 1]
                .events(eid::DIRECTIVE_EXECUTED)
                .iter()
                .any(|(_, p)| p[4] == leader1 && p[5] == 1))),
        "every follower holds by the leader's order: {:?}",
        logs.iter().map(Log::summary).collect::<Vec<_>>()
    );

    if let Some(tap) = &tap {
        forge(&listen, tap, leader1, term1, &mut logs);
    }

    // 2. The leader is killed → another leads within 6 s.
    obsw[leader1 as usize - 1].take().unwrap().kill9();
    let killed = Instant::now();
    let survivors: Vec<usize> = (0..ROBOTS as usize).filter(|i| *i + 1 != leader1 as usize).collect();
    let new_leader = |logs: &[Log]| -> Option<(Instant, u32, u8)> {
        let l: Vec<_> = survivors.iter().map(|i| logs[*i].leader()).collect();
        let (_, term, leader) = l[0]?;
        (term > term1 && leader != leader1 && l.iter().all(|x| x.is_some_and(|(_, t, ld)| t == term && ld == leader)))
            .then(|| (l.iter().map(|x| x.unwrap().0).max().unwrap(), term, leader))
    };
    assert!(
        poll_until(&mut logs, Duration::from_secs(12), |l| new_leader(l).is_some()),
        "no new leader 12 s after the kill: {:?}",
        logs.iter().map(Log::summary).collect::<Vec<_>>()
    );
    let (at, term2, leader2) = new_leader(&logs).unwrap();
    let reelect = at - killed;
    eprintln!(
        "{name}: leader {leader1} killed -> robots {:?} agree on leader {leader2} (term {term2}) after {:.2} s",
        survivors.iter().map(|i| i + 1).collect::<Vec<_>>(),
        reelect.as_secs_f64()
    );
    assert!(reelect <= Duration::from_secs(6), "re-election took {reelect:?}");

    // 2b. The killed leader restarts (same state file, new TM log): it keeps roster, term
    // and authorisation without a new upload, and rejoins (follows the new leader once
    // its own ground-loss timeout has run out; the boot counts as ground contact).
    if tap.is_some() {
        let li = leader1 as usize - 1;
        obsw[li] = Some(start(
            &dir,
            leader1,
            &listen,
            &addrs,
            tap_addr.as_deref(),
            "tm-restarted.hex",
        ));
        let mut re = vec![Log::new(dir.join("tm-restarted.hex"))];
        assert!(
            poll_until(&mut re, Duration::from_secs(5), |l| l[0].status().is_some()),
            "TEAM_STATUS of the restarted robot: {}",
            re[0].summary()
        );
        let loaded = re[0].events(eid::TEAM_STATE_LOADED);
        assert_eq!(loaded.len(), 1, "{}", re[0].summary());
        let p = &loaded[0].1;
        // status RESTORED, term >= term1, 3 robots, plan 7.
        assert_eq!((p[0], p[5], u16::from_be_bytes([p[6], p[7]])), (0, 3, 7), "{p:?}");
        assert!(u32::from_be_bytes([p[1], p[2], p[3], p[4]]) >= term1);
        let (term, _, plan, steps, roster) = re[0].status().unwrap();
        assert_eq!((plan, steps, roster.as_slice()), (7, 2, &[1u8, 2, 3][..]));
        assert!(term >= term1);
        eprintln!("{name}: robot {leader1} restarted after kill -9: term {term}, roster {roster:?}, authorisation of plan {plan} ({steps} steps) restored");
        assert!(
            poll_until(&mut re, Duration::from_secs(15), |l| l[0]
                .leader()
                .is_some_and(|(_, t, ld)| t >= term2 && ld == leader2)
                && l[0].hk(pid::TEAM_LEADER) == Some(i64::from(leader2))),
            "the restarted robot follows leader {leader2}: {}",
            re[0].summary()
        );
    }

    // 3. The ground returns (a TC to each robot) → every robot ignores the leader within 1.2 s.
    let mut sent = Vec::new();
    for i in &survivors {
        ground[*i].send("PING", &[]);
        sent.push((*i, Instant::now()));
    }
    assert!(
        poll_until(&mut logs, Duration::from_secs(3), |l| survivors
            .iter()
            .all(|i| !l[*i].events(eid::GROUND_REGAINED).is_empty())),
        "GROUND_REGAINED from every robot: {:?}",
        logs.iter().map(Log::summary).collect::<Vec<_>>()
    );
    let mut slowest = Duration::ZERO;
    for (i, at) in sent {
        let regained = logs[i].events(eid::GROUND_REGAINED)[0].0;
        let d = regained.saturating_duration_since(at);
        slowest = slowest.max(d);
        eprintln!(
            "{name}: robot {}: ground TC -> GROUND_REGAINED after {:.3} s",
            i + 1,
            d.as_secs_f64()
        );
        assert!(d <= Duration::from_millis(1200), "robot {} took {d:?}", i + 1);
    }
    // The leader stepped down because the ground is back (reason 0 GROUND_REGAINED).
    let li = leader2 as usize - 1;
    assert!(
        poll_until(&mut logs, Duration::from_secs(2), |l| l[li]
            .events(eid::STEPPED_DOWN)
            .iter()
            .any(|(_, p)| p[4] == 0)),
        "leader {leader2} stepped down: {}",
        logs[li].summary()
    );
    // The durable term survived on disk for every robot that voted.
    let state = std::fs::read_to_string(dir.join(format!("team-{leader2}.state"))).unwrap();
    let term_on_disk = state
        .lines()
        .find_map(|l| l.strip_prefix("term "))
        .and_then(|t| t.parse::<u32>().ok());
    assert!(term_on_disk.is_some_and(|t| t >= term2), "{state}");
    assert!(state.contains("roster 1,2,3"), "{state}");
    drop(obsw);
    for mut r in relays {
        eprintln!("{name}: relay {}", r.counts);
        r.stop();
    }
    let _ = std::fs::remove_dir_all(&dir);
    (elected_at - lost_at, reelect, slowest)
}

/// A forger on robot 1's team port, without the team key: random MACs on well-formed
/// datagrams claiming to be each robot (with the leader's and higher counters), truncated
/// datagrams, an unknown sender, bare (unauthenticated) packets, and replays of robot 2's
/// real datagrams captured by the tap. Nothing may change: same term, same leader, no
/// directive from anybody but the leader, no new election; every datagram counted.
fn forge(listen: &[String], tap: &Tap, leader: u8, term: u32, logs: &mut [Log]) {
    let sock = UdpSocket::bind("127.0.0.1:0").unwrap();
    let target = &listen[0];
    let before = |l: &Log, p: u16| l.hk(p).unwrap_or(0);
    let base: Vec<i64> = [
        pid::TEAM_REJ_BAD_MAC,
        pid::TEAM_REJ_TRUNCATED,
        pid::TEAM_REJ_UNKNOWN_SENDER,
        pid::TEAM_REJ_REPLAY,
        pid::TEAM_REJ_MALFORMED,
    ]
    .iter()
    .map(|p| before(&logs[0], *p))
    .collect();
    let elections_before: Vec<usize> = logs.iter().map(|l| l.events(eid::LEADER_ELECTED).len()).collect();
    let executed_before: Vec<usize> = logs.iter().map(|l| l.events(eid::DIRECTIVE_EXECUTED).len()).collect();
    let mut rnd = std::fs::File::open("/dev/urandom").unwrap();
    let mut random = |n: usize| {
        let mut b = vec![0u8; n];
        std::io::Read::read_exact(&mut rnd, &mut b).unwrap();
        b
    };
    let replays: Vec<Vec<u8>> = tap.seen.lock().unwrap().clone();
    assert!(replays.len() > 5, "the tap saw robot 2's datagrams");
    let (mut forged, mut short, mut unknown, mut bare) = (0, 0, 0, 0);
    for round in 0..40u32 {
        for claimed in 1..=ROBOTS {
            // version 1 | IV: claimed sender + a high counter | 40 random bytes | random MAC.
            let mut d = vec![mib::team::TEAM_SEC_VERSION, claimed];
            d.extend_from_slice(&(u128::from(round) + (1 << 60)).to_be_bytes()[5..]);
            d.extend_from_slice(&random(40 + 16));
            sock.send_to(&d, target).unwrap();
            // Robot 1 itself is no peer of robot 1.
            if claimed == 1 {
                unknown += 1;
            } else {
                forged += 1;
            }
        }
        sock.send_to(&random(20), target).unwrap();
        short += 1;
        let mut d = vec![mib::team::TEAM_SEC_VERSION, 77];
        d.extend_from_slice(&random(11 + 40 + 16));
        sock.send_to(&d, target).unwrap();
        unknown += 1;
        // A bare packet (what a team packet was before authentication): not version 1.
        let mut d = vec![0x08, 0xE0];
        d.extend_from_slice(&random(60));
        sock.send_to(&d, target).unwrap();
        bare += 1;
        std::thread::sleep(Duration::from_millis(25));
    }
    for r in &replays {
        sock.send_to(r, target).unwrap();
    }
    let replayed = replays.len() as i64;
    // Robot 1 counts every datagram by reason in its next TEAM HK reports.
    let want = [forged, short, unknown, replayed, bare];
    assert!(
        poll_until(logs, Duration::from_secs(12), |l| {
            [
                pid::TEAM_REJ_BAD_MAC,
                pid::TEAM_REJ_TRUNCATED,
                pid::TEAM_REJ_UNKNOWN_SENDER,
                pid::TEAM_REJ_REPLAY,
                pid::TEAM_REJ_MALFORMED,
            ]
            .iter()
            .zip(&base)
            .zip(want)
            .all(|((p, b), w)| l[0].hk(*p).unwrap_or(0) - b >= w)
        }),
        "robot 1 counts forged {forged}, truncated {short}, unknown {unknown}, replayed {replayed}, bare {bare}: HK {:?}",
        logs[0].team_hk().map(|t| t.data.clone())
    );
    assert!(!logs[0].events(eid::TEAM_PACKET_REJECTED).is_empty());
    // Nothing changed: same term and leader everywhere, no new election, no directive
    // executed that did not come from the leader of the term.
    for (i, l) in logs.iter().enumerate() {
        assert_eq!(l.hk(pid::TEAM_TERM), Some(i64::from(term)), "robot {}", i + 1);
        assert_eq!(l.hk(pid::TEAM_LEADER), Some(i64::from(leader)), "robot {}", i + 1);
        assert_eq!(
            l.events(eid::LEADER_ELECTED).len(),
            elections_before[i],
            "robot {}",
            i + 1
        );
        for (_, p) in &l.events(eid::DIRECTIVE_EXECUTED)[executed_before[i]..] {
            assert_eq!(p[4], leader, "robot {}: a directive from {} executed", i + 1, p[4]);
        }
    }
    eprintln!(
        "forger: {forged} forged, {short} truncated, {unknown} unknown-sender, {bare} bare, {replayed} replayed datagrams to robot 1: all refused and counted; term {term} and leader {leader} unchanged"
    );
}
