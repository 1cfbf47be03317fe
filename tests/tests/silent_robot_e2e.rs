//! A robot that really goes silent, over the space link: the real `ground watch` follows
//! the real `obsw` over TC/TM frames through a lossy path (20 % drop, 5 % duplicate, 5 %
//! corrupt, both ways), is never told the robot is lost while it runs, and once the obsw is
//! stopped (SIGSTOP: the process still exists, its socket stays open, nothing more is sent)
//! says "heard, then lost" within the link-loss time plus one poll, stating the silence it
//! measured. The path is the tests' relay, which keeps the time the last intact TM frame
//! went on to the ground, so the time in the message is judged against the truth.

use std::io::{BufRead, BufReader};
use std::net::UdpSocket;
use std::process::{Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use e2e_tests::relay::{Config, Faults, Relay};
use e2e_tests::{bin, create_keys, free_udp, tmpdir, Obsw};

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
    let dir = tmpdir("silent-robot-e2e", "stop");
    let keys = create_keys(&dir);
    // The lossy path (the tests' relay, its faults seeded): the ground's TC frames up to
    // the obsw's frame port, the obsw's TM frames down to the ground's TM port, the time
    // of the last one passed on intact kept.
    let faults = Faults::new(0.20, 0.05, 0.05);
    let down = UdpSocket::bind("127.0.0.1:0").unwrap();
    let obsw = Obsw::start_frames(&keys, down.local_addr().unwrap(), &[]);
    let mut relay = Relay::start(Config::both_ways(obsw.frame(), obsw.frame(), faults, 37)).unwrap();
    let ground_tm = free_udp();
    relay.add_downlink_socket(down, ground_tm).unwrap();
    let up_addr = relay.udp;
    let last_tm = |r: &Relay| *r.counts.down.last_intact.lock().unwrap();
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
    assert!(last_tm(&relay).is_some(), "TM frames reached the ground");

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
    relay.stop();
    let last = last_tm(&relay).expect("a TM frame");
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
    drop(obsw);
    let _ = std::fs::remove_dir_all(&dir);
}

// verifies: OPS-LIVE-LINK-03
#[test]
fn a_ground_stopped_for_twice_the_loss_time_does_not_call_its_live_robot_lost() {
    let loss = Duration::from_millis(u64::from(mib::ground_config::link_loss_ms(
        mib::hk::by_sid(mib::hk::sid::ROBOT_STATUS)
            .expect("status HK in the MIB")
            .default_interval_ms,
    )));
    let dir = tmpdir("silent-robot-e2e", "ground-stop");
    let keys = create_keys(&dir);
    // The obsw's TM frames straight to the ground's TM port: the robot never falls silent.
    let ground_tm = free_udp();
    let obsw = Obsw::start_frames(&keys, ground_tm, &[]);
    let mut ground = Command::new(bin("ground"))
        .current_dir(&dir)
        .args(["--no-archive", "watch", "--keys", keys.to_str().unwrap()])
        .args([
            "--robot",
            &format!("1={}", obsw.frame()),
            "--tm-listen",
            &format!("1={ground_tm}"),
        ])
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("ground watch");
    let (tx, rx) = mpsc::channel::<String>();
    let err = ground.stderr.take().unwrap();
    std::thread::spawn(move || {
        for line in BufReader::new(err).lines().map_while(Result::ok) {
            let _ = tx.send(line);
        }
    });
    std::thread::sleep(Duration::from_secs(3));
    let pid = ground.id().to_string();
    // The ground process is not scheduled (as on a loaded machine, here SIGSTOP) for twice
    // the loss time while the robot's frames wait in its socket; when it runs again its
    // main loop and its link's reader wake together. Three times: it must never judge the
    // silence past what its reader had read.
    for round in 0..3 {
        assert!(Command::new("kill").args(["-STOP", &pid]).status().unwrap().success());
        std::thread::sleep(loss * 2);
        assert!(Command::new("kill").args(["-CONT", &pid]).status().unwrap().success());
        std::thread::sleep(Duration::from_secs(2));
        let lines: Vec<String> = rx.try_iter().collect();
        let running = ground.try_wait().unwrap().is_none();
        assert!(
            running && !lines.iter().any(|l| l.contains("lost") || l.contains("nothing heard")),
            "round {round}: ground watch called the live robot lost after its own stop: {lines:?}"
        );
    }
    let _ = ground.kill();
    let _ = ground.wait();
    drop(obsw);
    let _ = std::fs::remove_dir_all(&dir);
}
