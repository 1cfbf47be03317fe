//! `ground collect` with a robot on a serial line (`[[robot]] serial = "PATH"`): the real
//! collector and the real `obsw --frame-serial`, each connected to a Unix socket of this
//! test, which is the cable between them (it copies the bytes both ways). Every TC and TM
//! frame crosses as one COBS frame, through the same FOP-1, SDLS and FARM-1 as over UDP.
//! Judged from the archive: the robot's HK and the answers to the collector's TCs.

use std::io::BufRead;
use std::os::unix::net::UnixListener;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

mod common;
use common::{frame_keys, ground, obsw_bin, text, wait_for, Proc, GROUND};

/// Accepts one connection on each listener and copies bytes both ways until one side
/// closes.
fn cable(robot: UnixListener, ground: UnixListener) {
    std::thread::spawn(move || {
        let (r, _) = robot.accept().unwrap();
        let (g, _) = ground.accept().unwrap();
        let (mut r2, mut g2) = (r.try_clone().unwrap(), g.try_clone().unwrap());
        let (mut r1, mut g1) = (r, g);
        std::thread::spawn(move || std::io::copy(&mut r2, &mut g2));
        let _ = std::io::copy(&mut g1, &mut r1);
    });
}

// verifies: LINK-STREAM-04, GND-10
#[test]
fn the_collector_follows_a_robot_over_a_serial_line() {
    let dir = common::tmpdir("collect_serial", "unix");
    let keys = frame_keys(&dir, &[1]);
    let (robot_sock, ground_sock) = (dir.join("robot.sock"), dir.join("ground.sock"));
    let _ = std::fs::remove_file(&robot_sock);
    let _ = std::fs::remove_file(&ground_sock);
    cable(
        UnixListener::bind(&robot_sock).unwrap(),
        UnixListener::bind(&ground_sock).unwrap(),
    );

    let rd = keys.join("robot-1");
    let s = |f: &str| rd.join(f).to_str().unwrap().to_string();
    let mut child = Command::new(obsw_bin())
        .args(["--robot", "1", "--sim-ctl", "127.0.0.1:0"])
        .args(["--udp", "127.0.0.1:0", "--tcp", "127.0.0.1:0"])
        .args(["--frame-serial", robot_sock.to_str().unwrap()])
        .args(["--tc-key", &s("tc-spi1.key"), "--tm-key", &s("tm-spi17.key")])
        .args(["--link-state", &s("obsw-link.state")])
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .expect("starting obsw");
    let mut ready = String::new();
    std::io::BufReader::new(child.stdout.take().unwrap())
        .read_line(&mut ready)
        .unwrap();
    let _obsw = Proc(child);
    assert!(ready.starts_with("READY"), "obsw did not start: {ready:?}");

    // The robot's serial line, relative to the file's folder like the keys.
    std::fs::write(
        dir.join("collect.toml"),
        "keys = \"TEST-KEYS\"\n[[robot]]\nnumber = 1\nserial = \"ground.sock\"\n",
    )
    .unwrap();
    let out = ground(&dir, &["collect", "--check-config", "collect.toml"]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out));
    let log = std::fs::File::create(dir.join("collect.log")).unwrap();
    let mut collector = Proc(
        Command::new(GROUND)
            .current_dir(&dir)
            .args(["--archive", "a.db", "collect", "--plain", "--config", "collect.toml"])
            .stdout(Stdio::null())
            .stderr(Stdio::from(log))
            .spawn()
            .expect("starting ground collect"),
    );

    // HK (3,25) comes on its own; a connection-test report (17,2) or a TC's acceptance
    // (1,1) answers a TC the collector sent over the line.
    let tm = |dir: &std::path::Path| -> Vec<(i64, i64)> {
        let o = ground(
            dir,
            &["--archive", "a.db", "archive", "query", "--type", "tm", "--json"],
        );
        String::from_utf8_lossy(&o.stdout)
            .lines()
            .filter_map(|l| serde_json::from_str::<serde_json::Value>(l).ok())
            .filter_map(|t| Some((t["service"].as_i64()?, t["subservice"].as_i64()?)))
            .collect()
    };
    wait_for(30, "HK and the answer to a TC archived over the serial line", || {
        let t = tm(&dir);
        let hk = t.iter().filter(|&&s| s == (3, 25)).count();
        let answered = t.iter().any(|&s| s == (17, 2) || s == (1, 1));
        (hk >= 3 && answered).then_some(())
    });

    let _ = Command::new("kill")
        .args(["-TERM", &collector.0.id().to_string()])
        .status();
    let t0 = Instant::now();
    let code = loop {
        if let Some(s) = collector.0.try_wait().unwrap() {
            break s.code();
        }
        assert!(
            t0.elapsed() < Duration::from_secs(10),
            "the collector did not exit on SIGTERM"
        );
        std::thread::sleep(Duration::from_millis(20));
    };
    assert_eq!(
        code,
        Some(0),
        "{}",
        std::fs::read_to_string(dir.join("collect.log")).unwrap_or_default()
    );
}
