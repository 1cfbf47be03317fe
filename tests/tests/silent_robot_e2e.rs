//! A robot that really goes silent, over the space link: the real `ground watch` follows
//! the real `obsw` over TC/TM frames through a lossy path (20 % drop, 5 % duplicate, 5 %
//! corrupt, both ways), is never told the robot is lost while it runs, and once the obsw is
//! stopped (SIGSTOP: the process still exists, its socket stays open, nothing more is sent)
//! says "heard, then lost" within the link-loss time plus one poll, stating the silence it
//! measured. The path is this test's own, so it knows when the last intact TM frame reached
//! the ground and can judge the time in the message against the truth.

use std::io::{BufRead, BufReader};
use std::net::{SocketAddr, UdpSocket};
use std::path::PathBuf;
use std::process::{Command, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{mpsc, Arc, Mutex};
use std::time::{Duration, Instant};

use e2e_tests::relay::{decide, DirCounts, Fate, Faults, Rng};
use e2e_tests::{bin, Obsw};

fn tmpdir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("silent-robot-e2e-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn free_udp() -> SocketAddr {
    UdpSocket::bind("127.0.0.1:0").unwrap().local_addr().unwrap()
}

/// One direction of the lossy path: what arrives on `sock` goes to `to` under `faults`.
/// `last_intact` is the time the last datagram went out unaltered (a flipped bit fails the
/// frame CRC: the receiver does not hear it).
fn forward(
    sock: UdpSocket,
    to: SocketAddr,
    faults: Faults,
    seed: u64,
    stop: Arc<AtomicBool>,
    last_intact: Arc<Mutex<Option<Instant>>>,
) -> std::thread::JoinHandle<()> {
    std::thread::spawn(move || {
        sock.set_read_timeout(Some(Duration::from_millis(20))).unwrap();
        let out = UdpSocket::bind("127.0.0.1:0").unwrap();
        let counts = DirCounts::default();
        let mut rng = Rng::new(seed);
        let mut buf = [0u8; 4096];
        while !stop.load(Ordering::SeqCst) {
            let Ok(n) = sock.recv(&mut buf) else {
                continue;
            };
            let d = &buf[..n];
            if let Fate::Send(copies) = decide(&mut rng, &faults, d, &counts) {
                for c in copies {
                    if out.send_to(&c, to).is_ok() && c == d {
                        *last_intact.lock().unwrap() = Some(Instant::now());
                    }
                }
            }
        }
    })
}

/// The seconds in "nothing heard from ADDR for X s".
fn stated_silence(line: &str) -> Option<f64> {
    let rest = line.split(" for ").nth(1)?;
    rest.split_whitespace().next()?.parse().ok()
}

// verifies: OPS-LIVE-LINK-02, OPS-ANSWER-01
#[test]
fn a_robot_stopped_over_the_frame_link_is_reported_lost_within_the_loss_time_stating_the_silence_measured() {
    let loss = Duration::from_millis(u64::from(mib::ground_config::link_loss_ms(
        mib::hk::by_sid(mib::hk::sid::ROBOT_STATUS)
            .expect("status HK in the MIB")
            .default_interval_ms,
    )));
    // The ground checks the link at least this often (the bound `link_e2e` holds the
    // bare-packet link to: the loss time plus one poll).
    let poll = Duration::from_millis(500);
    let dir = tmpdir("stop");
    let keys = dir.join("TEST-KEYS");
    let k = Command::new(bin("ground"))
        .args(["--no-archive", "keys", "create", keys.to_str().unwrap(), "--robot", "1"])
        .output()
        .unwrap();
    assert!(k.status.success(), "{}", String::from_utf8_lossy(&k.stderr));
    let rd = keys.join("robot-1");
    let p = |f: &str| rd.join(f).to_str().unwrap().to_string();

    let stop = Arc::new(AtomicBool::new(false));
    let faults = Faults::new(0.20, 0.05, 0.05);
    // Uplink: the ground's TC frames to the obsw's frame port.
    let (up, frame_port) = (UdpSocket::bind("127.0.0.1:0").unwrap(), free_udp());
    let up_addr = up.local_addr().unwrap();
    let up_t = forward(up, frame_port, faults, 37, stop.clone(), Arc::default());
    // Downlink: the obsw's TM frames to the ground's TM port, the last intact one timed.
    let (down, ground_tm) = (UdpSocket::bind("127.0.0.1:0").unwrap(), free_udp());
    let down_addr = down.local_addr().unwrap();
    let last_tm: Arc<Mutex<Option<Instant>>> = Arc::default();
    let down_t = forward(down, ground_tm, faults, 38, stop.clone(), last_tm.clone());

    let (fs, ts) = (frame_port.to_string(), down_addr.to_string());
    let (tc, tm, st) = (p("tc-spi1.key"), p("tm-spi17.key"), p("obsw-link.state"));
    let obsw = Obsw::start(&[
        "--frame-udp",
        &fs,
        "--frame-tm-to",
        &ts,
        "--tc-key",
        &tc,
        "--tm-key",
        &tm,
        "--link-state",
        &st,
    ]);
    let mut ground = Command::new(bin("ground"))
        .current_dir(&dir)
        .args(["--no-archive", "watch", "--keys", keys.to_str().unwrap()])
        .args([
            "--robot",
            &format!("1={up_addr}"),
            "--tm-listen",
            &format!("1={ground_tm}"),
        ])
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("ground watch");
    // Every stderr line with the time it came.
    let (tx, rx) = mpsc::channel::<(Instant, String)>();
    let err = ground.stderr.take().unwrap();
    std::thread::spawn(move || {
        for line in BufReader::new(err).lines().map_while(Result::ok) {
            let _ = tx.send((Instant::now(), line));
        }
    });

    // Heard for 6 s through the lossy path (frames at least every 100 ms, HK every 1 s):
    // never called lost.
    std::thread::sleep(Duration::from_secs(6));
    assert!(
        ground.try_wait().unwrap().is_none(),
        "ground watch ended while the robot ran: {:?}",
        rx.try_iter().map(|(_, l)| l).collect::<Vec<_>>()
    );
    assert!(last_tm.lock().unwrap().is_some(), "TM frames reached the ground");

    let pid = obsw.pid().to_string();
    let stopped = Instant::now();
    assert!(Command::new("kill").args(["-STOP", &pid]).status().unwrap().success());

    let deadline = stopped + loss + poll + Duration::from_secs(5);
    let status = loop {
        if let Some(s) = ground.try_wait().unwrap() {
            break Some(s);
        }
        if Instant::now() > deadline {
            break None;
        }
        std::thread::sleep(Duration::from_millis(10));
    };
    // The last frame the ground could hear, taken before the obsw runs again (it then
    // sends what it held).
    stop.store(true, Ordering::SeqCst);
    let last = last_tm.lock().unwrap().expect("a TM frame");
    let _ = Command::new("kill").args(["-CONT", &pid]).status();
    if status.is_none() {
        let _ = ground.kill();
    }
    let lines: Vec<(Instant, String)> = rx.try_iter().collect();
    let all: Vec<&str> = lines.iter().map(|(_, l)| l.as_str()).collect();
    let (said_at, msg) = lines
        .iter()
        .find(|(_, l)| l.contains("heard, then lost"))
        .unwrap_or_else(|| {
            panic!(
                "no loss message within {:?} of the stop: {all:?}",
                loss + poll + Duration::from_secs(5)
            )
        });
    let after_stop = said_at.duration_since(stopped);
    let true_silence = said_at.duration_since(last);
    let stated = stated_silence(msg).unwrap_or_else(|| panic!("no silence in {msg:?}"));
    eprintln!(
        "silent_robot_e2e: loss time {:.1} s; last intact TM frame {:.2} s before the stop; \
         reported {:.2} s after the stop, {:.2} s after that frame; message: {msg}",
        loss.as_secs_f64(),
        stopped.saturating_duration_since(last).as_secs_f64(),
        after_stop.as_secs_f64(),
        true_silence.as_secs_f64()
    );
    assert_eq!(
        status.and_then(|s| s.code()),
        Some(5),
        "heard, then lost is exit 5: {all:?}"
    );
    assert!(msg.contains("nothing heard from"), "{msg}");
    // Within the documented time: the loss time after the robot went silent, plus one poll.
    assert!(
        after_stop <= loss + poll,
        "reported {after_stop:?} after the stop (loss time {loss:?})"
    );
    // Not before the loss time had passed since the last frame the ground could hear.
    assert!(
        true_silence + Duration::from_millis(50) >= loss,
        "reported after {true_silence:?} of silence"
    );
    // The time in the message is the silence measured: never less than the loss time,
    // and the truth to the message's 0.1 s (plus scheduling).
    assert!(stated >= loss.as_secs_f64(), "{msg}");
    assert!(
        (stated - true_silence.as_secs_f64()).abs() <= 0.2,
        "stated {stated} s, true silence {:.2} s: {msg}",
        true_silence.as_secs_f64()
    );
    up_t.join().unwrap();
    down_t.join().unwrap();
    drop(obsw);
    let _ = std::fs::remove_dir_all(&dir);
}
