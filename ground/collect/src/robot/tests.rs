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
