//! The worker against a fake lab-link robot.

use std::net::{SocketAddr, UdpSocket};
use std::sync::atomic::AtomicBool;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use crate::config::{Config, RobotCfg};
use crate::link::Transport;
use crate::pus::{build_tm, CdsShort};

use super::{LinkState, RobotStatus, Worker};

/// A fake lab-link obsw that refuses the first `refuse` TCs (TM[1,2] to their sender, as
/// the obsw answers a damaged copy: the sender hears it but is not subscribed), then
/// subscribes the sender of the next: TM[1,1] for every TC and a TM[17,2] every 100 ms
/// until `run_for` after the first TC. Returns the times the TCs came, from the first.
fn subscribing_obsw(refuse: usize, run_for: Duration) -> (SocketAddr, std::thread::JoinHandle<Vec<Duration>>) {
    let s = UdpSocket::bind("127.0.0.1:0").unwrap();
    s.set_read_timeout(Some(Duration::from_millis(100))).unwrap();
    let addr = s.local_addr().unwrap();
    let apid = crate::onboard::apid(1).unwrap();
    let h = std::thread::spawn(move || {
        let t = CdsShort::now().to_bytes();
        let mut buf = [0u8; 2048];
        let mut came = Vec::new();
        let mut t0: Option<Instant> = None;
        let mut subscriber = None;
        let mut seq = 0u16;
        while t0.is_none_or(|t| t.elapsed() < run_for) {
            if let Ok((_, from)) = s.recv_from(&mut buf) {
                let t0 = *t0.get_or_insert_with(Instant::now);
                came.push(t0.elapsed());
                let rid = [buf[0], buf[1], buf[2], buf[3]];
                seq += 1;
                if came.len() <= refuse {
                    let body = [rid[0], rid[1], rid[2], rid[3], 0, 1];
                    s.send_to(&build_tm(apid, seq, 1, 2, 0, &t, &body), from).unwrap();
                } else {
                    subscriber = Some(from);
                    s.send_to(&build_tm(apid, seq, 1, 1, 0, &t, &rid), from).unwrap();
                }
            }
            if let Some(to) = subscriber {
                seq += 1;
                s.send_to(&build_tm(apid, seq, 17, 2, 0, &t, &[]), to).unwrap();
            }
        }
        came
    });
    (addr, h)
}

// verifies: GND-SUB-01, OPS-LIVE-LINK-04
#[test]
fn over_a_udp_lab_link_the_collector_resubscribes_until_the_robot_streams() {
    // Eight TCs in a row refused: at the lease renewal's pace (1 s) the collector would
    // be subscribed only after about 3 s, beyond the link-loss time.
    let refuse = 8;
    let run_for = Duration::from_secs(5);
    let (addr, fake) = subscribing_obsw(refuse, run_for);
    let cfg = RobotCfg {
        number: 1,
        addr,
        transport: Transport::Udp,
        frames: None,
        hk_interval_ms: None,
        name: None,
    };
    let (sink, _archive) = crossbeam_channel::unbounded();
    let status = Arc::new(Mutex::new(RobotStatus::default()));
    let stop = Arc::new(AtomicBool::new(false));
    let w = Worker::new(
        cfg,
        Arc::new(Config::default()),
        sink,
        status.clone(),
        stop.clone(),
        Vec::new(),
    );
    let worker = std::thread::spawn(move || w.run());
    let t0 = Instant::now();
    let mut states = Vec::new();
    while t0.elapsed() < run_for {
        let s = status.lock().unwrap().link;
        if states.last() != Some(&s) {
            states.push(s);
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    stop.store(true, std::sync::atomic::Ordering::SeqCst);
    worker.join().unwrap();
    let came = fake.join().unwrap();
    assert!(!states.contains(&LinkState::Lost), "link states {states:?}");
    let loss = Duration::from_millis(u64::from(mib::ground_config::LINK_LOSS_MS));
    assert!(
        came.len() > refuse && came[refuse] < loss,
        "subscribed within the loss time: {came:?}"
    );
    // Until subscribed, no pause longer than the retry period (plus the worker's 50 ms
    // loop and scheduling on a shared machine).
    let retry = Duration::from_millis(u64::from(mib::ground_config::SUBSCRIBE_RETRY_MS));
    let slack = Duration::from_millis(500);
    for w in came[..=refuse].windows(2) {
        assert!(w[1] - w[0] <= retry + slack, "pause of {:?}: {came:?}", w[1] - w[0]);
    }
    // Once it streams, no more retries: the renewals (and the module report asked for
    // each lease renewal) only.
    let tail = came
        .iter()
        .filter(|&&t| t > run_for - Duration::from_millis(1500))
        .count();
    assert!(tail <= 5, "{tail} TCs in the last 1.5 s: {came:?}");
}

/// A worker for robot 1 with `history` (per APID, the archive's newest positions), never
/// run.
fn resumed_worker(history: Vec<(u16, Vec<crate::tracker::Pos>)>) -> Worker {
    let cfg = RobotCfg {
        number: 1,
        addr: "127.0.0.1:9".parse().unwrap(),
        transport: Transport::Udp,
        frames: None,
        hk_interval_ms: None,
        name: None,
    };
    let (sink, _archive) = crossbeam_channel::unbounded();
    let status = Arc::new(Mutex::new(RobotStatus::default()));
    Worker::new(
        cfg,
        Arc::new(Config::default()),
        sink,
        status,
        Arc::new(AtomicBool::new(false)),
        history,
    )
}

// verifies: GND-10, GND-12
#[test]
fn after_a_restart_the_counts_of_the_boot_before_the_first_archived_packet_are_asked_again() {
    use crate::tracker::{GapPlan, Pos, Verdict};
    let apid = crate::onboard::apid(1).unwrap();
    let p = |seq: u16| Pos {
        seq,
        obt_ms: 1_000 + 10 * i64::from(seq),
    };
    // The last run archived counts 2..=9 but 5 and was killed before the store gave it
    // 0 and 1 (the BOOT event and the first report, sent before it subscribed) and 5.
    let archived: Vec<Pos> = [2, 3, 4, 6, 7, 8, 9].into_iter().map(p).collect();
    let mut w = resumed_worker(vec![(apid, archived)]);
    let t = w.trackers.get_mut(&apid).unwrap();
    assert_eq!(t.last(), Some(p(9)), "resumes after the newest archived packet");
    assert_eq!(t.missing().collect::<Vec<_>>(), vec![0, 1, 5]);
    // Asked of the store by count: no packet was heard before 0 and 1, so their window is
    // not known.
    let due = t.due(i64::MAX / 2, 0, 1_000, 8, &GapPlan::default(), 1);
    assert_eq!(due, vec![(0, 5)]);
    assert_eq!(t.window(0, 5), None);
    let (tc, ranged) = crate::onboard::store_range_tc(1, 1, apid, due[0], None).unwrap();
    assert_eq!((tc.def.service, tc.def.subservice, ranged), (15, 128, true));
    assert_eq!(tc.args, vec![i64::from(apid), 0, 5]);
    // The store's copies fill them, once.
    assert_eq!(t.on_packet(p(0), false, 0), Verdict::Filled);
    assert_eq!(t.on_packet(p(0), false, 0), Verdict::Duplicate);
    assert_eq!(t.on_packet(p(5), false, 0), Verdict::Filled);
    assert_eq!(t.on_packet(p(10), false, 0), Verdict::New);
    assert_eq!(t.missing().collect::<Vec<_>>(), vec![1]);
    assert!(t.take_lost().is_empty());
}

// verifies: GND-10
#[test]
fn after_a_restart_with_a_full_resume_window_nothing_before_it_is_asked() {
    use crate::tracker::Pos;
    let apid = crate::onboard::apid(1).unwrap();
    // The archive holds older packets than the window it gave: the counts before the
    // window's first are not holes.
    let first = 100u16;
    let archived: Vec<Pos> = (0..crate::RESUME_WINDOW as u16)
        .map(|k| Pos {
            seq: first + k,
            obt_ms: 1_000 + i64::from(k),
        })
        .collect();
    let w = resumed_worker(vec![(apid, archived)]);
    let t = &w.trackers[&apid];
    assert_eq!(t.holes(), 0);
    assert_eq!(t.newest(), Some(first + crate::RESUME_WINDOW as u16 - 1));
    // A boot's first packet archived: nothing before it.
    let w = resumed_worker(vec![(apid, vec![Pos { seq: 0, obt_ms: 5 }, Pos { seq: 1, obt_ms: 6 }])]);
    assert_eq!(w.trackers[&apid].holes(), 0);
}
