//! The space link over a serial line, end to end: the real `obsw` with `--frame-serial`
//! on one pty, the real `ground` with `--serial` on another, and this test as the cable
//! between the two pty masters (it copies bytes both ways and injects junk). Every TC
//! frame and TM frame crosses as one COBS frame (`mmic_link::stream`, board A's framing),
//! through the same FOP-1, SDLS and FARM-1 as over UDP. Judged from the obsw's own
//! `--tm-log`.

use std::fs::File;
use std::io::{BufRead, BufReader, Read, Write};
use std::os::fd::{AsFd, AsRawFd};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use mib::params::pid;
use nix::poll::{PollFd, PollFlags, PollTimeout};

/// One pty: the master (the test's end of the cable) and the slave's path (a process's
/// serial port). The test keeps a slave descriptor open, in raw mode, so the line stays
/// up between the ground's runs.
struct Pty {
    master: File,
    _slave: File,
    path: PathBuf,
}

fn pty() -> Pty {
    let r = nix::pty::openpty(None, None).expect("openpty");
    let slave = File::from(r.slave);
    mmic_link::stream::port::set_raw(&slave).unwrap();
    let path = std::fs::read_link(format!("/proc/self/fd/{}", slave.as_raw_fd())).unwrap();
    let master = File::from(r.master);
    let fl = nix::fcntl::fcntl(master.as_fd(), nix::fcntl::FcntlArg::F_GETFL).unwrap();
    let fl = nix::fcntl::OFlag::from_bits_truncate(fl) | nix::fcntl::OFlag::O_NONBLOCK;
    nix::fcntl::fcntl(master.as_fd(), nix::fcntl::FcntlArg::F_SETFL(fl)).unwrap();
    Pty {
        master,
        _slave: slave,
        path,
    }
}

/// The cable: copies robot ↔ ground, and writes `junk_up` into the robot's line (between
/// two reads, wherever the stream is), `junk_down` into the ground's.
struct Cable {
    stop: Arc<AtomicBool>,
    junk_up: Arc<Mutex<Vec<u8>>>,
    junk_down: Arc<Mutex<Vec<u8>>>,
    /// Bytes carried (up, down) and bytes lost because a side's input was full.
    carried: Arc<[AtomicU64; 3]>,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl Cable {
    fn start(robot: File, ground: File) -> Cable {
        let stop = Arc::new(AtomicBool::new(false));
        let junk_up = Arc::new(Mutex::new(Vec::new()));
        let junk_down = Arc::new(Mutex::new(Vec::new()));
        let carried: Arc<[AtomicU64; 3]> = Arc::new(Default::default());
        let (s, ju, jd, c) = (stop.clone(), junk_up.clone(), junk_down.clone(), carried.clone());
        let thread = std::thread::spawn(move || {
            let (mut robot, mut ground) = (robot, ground);
            let mut buf = [0u8; 8192];
            while !s.load(Ordering::Relaxed) {
                for (junk, to) in [(&ju, &mut robot), (&jd, &mut ground)] {
                    let j = std::mem::take(&mut *junk.lock().unwrap());
                    if !j.is_empty() {
                        put(to, &j, &c[2]);
                    }
                }
                let mut fds = [
                    PollFd::new(robot.as_fd(), PollFlags::POLLIN),
                    PollFd::new(ground.as_fd(), PollFlags::POLLIN),
                ];
                let _ = nix::poll::poll(&mut fds, PollTimeout::from(10u16));
                let ready: Vec<bool> = fds
                    .iter()
                    .map(|f| f.revents().is_some_and(|r| r.contains(PollFlags::POLLIN)))
                    .collect();
                if ready[1] {
                    if let Ok(n) = ground.read(&mut buf) {
                        c[0].fetch_add(n as u64, Ordering::Relaxed);
                        put(&mut robot, &buf[..n], &c[2]);
                    }
                }
                if ready[0] {
                    if let Ok(n) = robot.read(&mut buf) {
                        c[1].fetch_add(n as u64, Ordering::Relaxed);
                        put(&mut ground, &buf[..n], &c[2]);
                    }
                }
            }
        });
        Cable {
            stop,
            junk_up,
            junk_down,
            carried,
            thread: Some(thread),
        }
    }
}

impl Drop for Cable {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// Writes into a pty master; what its full input queue does not take is lost (counted),
/// as on a line nobody reads.
fn put(to: &mut File, mut b: &[u8], lost: &AtomicU64) {
    let t0 = Instant::now();
    while !b.is_empty() {
        match to.write(b) {
            Ok(n) => b = &b[n..],
            Err(e) if e.kind() == std::io::ErrorKind::WouldBlock && t0.elapsed() < Duration::from_millis(50) => {
                std::thread::sleep(Duration::from_millis(1));
            }
            Err(_) => {
                lost.fetch_add(b.len() as u64, Ordering::Relaxed);
                return;
            }
        }
    }
}

/// The workspace's `ground` binary, built for this test's profile (once).
fn ground_bin() -> PathBuf {
    let exe = std::env::current_exe().unwrap();
    let profile_dir = exe.parent().and_then(Path::parent).unwrap().to_path_buf();
    let profile = match profile_dir.file_name().and_then(|n| n.to_str()) {
        Some("debug") | None => "dev".to_string(),
        Some(p) => p.to_string(),
    };
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let out = Command::new(env!("CARGO"))
        .args(["build", "-q", "-p", "ground", "--bin", "ground", "--profile", &profile])
        .arg("--target-dir")
        .arg(profile_dir.parent().unwrap())
        .current_dir(root)
        .output()
        .expect("running cargo to build the ground binary");
    assert!(
        out.status.success(),
        "building the ground binary failed:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    profile_dir.join("ground")
}

fn ground(bin: &Path, dir: &Path, args: &[&str]) -> (Option<i32>, String, Duration) {
    let t0 = Instant::now();
    let o: Output = Command::new(bin)
        .current_dir(dir)
        .env("MMIC_GROUND_LOCK_DIR", dir.join("locks"))
        .args(args)
        .output()
        .expect("running ground");
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    (o.status.code(), text, t0.elapsed())
}

struct Obsw(Child);

impl Drop for Obsw {
    fn drop(&mut self) {
        let _ = Command::new("kill").args(["-TERM", &self.0.id().to_string()]).status();
        let t0 = Instant::now();
        while t0.elapsed() < Duration::from_secs(2) && matches!(self.0.try_wait(), Ok(None)) {
            std::thread::sleep(Duration::from_millis(5));
        }
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// The TM packets of the obsw's `--tm-log`, as (service, subservice, source data).
fn tm_log(path: &Path) -> Vec<(u8, u8, Vec<u8>)> {
    let text = std::fs::read_to_string(path).unwrap_or_default();
    let data = 6 + 7 + mib::config::TIMESTAMP_LEN;
    text.lines()
        .map(|l| {
            (0..l.len() / 2)
                .filter_map(|i| u8::from_str_radix(&l[2 * i..2 * i + 2], 16).ok())
                .collect::<Vec<u8>>()
        })
        .filter(|p| p.len() >= data + 2)
        .map(|p| (p[7], p[8], p[data..p.len() - 2].to_vec()))
        .collect()
}

/// The last value of HK parameter `param` in structure `sid` in the TM log.
fn last_hk(tms: &[(u8, u8, Vec<u8>)], sid: u16, param: u16) -> Option<i64> {
    tms.iter()
        .rev()
        .filter(|(s, ss, d)| (*s, *ss) == (3, 25) && d.len() >= 2 && d[..2] == sid.to_be_bytes())
        .find_map(|(_, _, d)| mib_wire::codec::decode_hk(d).ok().and_then(|r| r.get(param)))
}

fn wait_for(limit: Duration, what: &str, mut f: impl FnMut() -> bool) {
    let t0 = Instant::now();
    while !f() {
        assert!(t0.elapsed() < limit, "timed out waiting for {what}");
        std::thread::sleep(Duration::from_millis(50));
    }
}

// verifies: LINK-STREAM-05, LINK-STREAM-02
#[test]
fn ground_ping_send_and_run_over_a_serial_line_with_junk_injected() {
    let bin = ground_bin();
    let dir = std::env::temp_dir().join(format!("obsw-frames-serial-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let keys = dir.join("TEST-KEYS");
    let k = keys.to_str().unwrap();
    let (code, t, _) = ground(&bin, &dir, &["keys", "create", k, "--robot", "1"]);
    assert_eq!(code, Some(0), "{t}");

    let (robot_line, ground_line) = (pty(), pty());
    let log = dir.join("tm.log");
    let rd = keys.join("robot-1");
    let s = |p: PathBuf| p.to_str().unwrap().to_string();
    let mut child = Command::new(env!("CARGO_BIN_EXE_obsw"))
        .args(["--robot", "1", "--sim-ctl", "127.0.0.1:0"])
        .args(["--udp", "127.0.0.1:0", "--tcp", "127.0.0.1:0"])
        .args(["--frame-serial", robot_line.path.to_str().unwrap()])
        .args([
            "--tc-key",
            &s(rd.join("tc-spi1.key")),
            "--tm-key",
            &s(rd.join("tm-spi17.key")),
        ])
        .args(["--link-state", &s(rd.join("obsw-link.state"))])
        .args(["--speed", "20", "--initial-state", "Xneg", "--tm-log", &s(log.clone())])
        .stdout(Stdio::piped())
        .stderr(File::create(dir.join("obsw.stderr")).unwrap())
        .spawn()
        .expect("start obsw");
    let mut ready = String::new();
    BufReader::new(child.stdout.take().unwrap())
        .read_line(&mut ready)
        .unwrap();
    let obsw = Obsw(child);
    assert!(
        ready.contains("frame_serial="),
        "{ready:?}: {}",
        std::fs::read_to_string(dir.join("obsw.stderr")).unwrap_or_default()
    );
    let cable = Cable::start(
        robot_line.master.try_clone().unwrap(),
        ground_line.master.try_clone().unwrap(),
    );
    let gpath = ground_line.path.to_str().unwrap().to_string();
    let links = ["--keys", k, "--robot", "1", "--serial", &gpath];
    let with = |pre: &[&str], post: &[&str]| -> Vec<String> {
        pre.iter()
            .chain(links.iter())
            .chain(post.iter())
            .map(|a| a.to_string())
            .collect()
    };
    let go = |args: Vec<String>| {
        let a: Vec<&str> = args.iter().map(String::as_str).collect();
        ground(&bin, &dir, &a)
    };

    // 1. Ping over the serial line (the first reply includes COP-1's initialisation).
    let (code, t, took) = go(with(&["--no-archive", "ping"], &["-c", "20", "--interval", "0.05"]));
    assert_eq!(code, Some(0), "{t}");
    let mut rtt: Vec<f64> = t
        .lines()
        .filter_map(|l| l.split("reply in ").nth(1)?.strip_suffix(" ms")?.parse().ok())
        .collect();
    assert_eq!(rtt.len(), 20, "{t}");
    let first = rtt.remove(0);
    rtt.sort_by(f64::total_cmp);
    eprintln!(
        "ground ping -c 20 over the pty pair: {took:?}; first reply {first} ms, then median {} ms (min {}, max {})",
        rtt[rtt.len() / 2],
        rtt[0],
        rtt[rtt.len() - 1]
    );

    // Junk on the robot's line while no ground is there: 200 bytes that are no COBS frame,
    // then a well-formed COBS frame of 2000 bytes (longer than any TC frame).
    let junk: Vec<u8> = (0..200u32).map(|i| (i.wrapping_mul(97) % 255 + 1) as u8).collect();
    let mut big = vec![0u8; mmic_link::stream::encoded_len(2000)];
    let n = mmic_link::stream::encode(&[0x55; 2000], &mut big).unwrap();
    big.truncate(n);
    cable.junk_up.lock().unwrap().extend(junk.iter().chain(&big));

    // 2. A hazardous TC, confirmed.
    let node = format!("node={}", mib::modes::node::ROBOT);
    let (code, t, _) = go(with(
        &["--no-archive", "send"],
        &["MODE_SET", &node, "mode=operational", "submode=0", "--confirm"],
    ));
    assert_eq!(code, Some(0), "{t}");
    assert!(t.contains("completion ok"), "{t}");

    // A short COBS frame that decodes to no TC frame (the frame layer refuses it); junk
    // towards the ground during the plan (before, the ground's open would discard it).
    let mut small = vec![0u8; mmic_link::stream::encoded_len(30)];
    let n = mmic_link::stream::encode(&[0xA7; 30], &mut small).unwrap();
    cable.junk_up.lock().unwrap().extend_from_slice(&small[..n]);

    // 3. A short plan.
    let plan = dir.join("p.toml");
    std::fs::write(
        &plan,
        "name = \"serial\"\n[[robot]]\nnumber = 1\ninitial_state = \"Xneg\"\n\
         [[step]]\nid = \"op\"\nrobot = 1\naction = \"mode\"\nmode = \"operational\"\nconfirm = true\n\
         [[step]]\nid = \"turn\"\nrobot = 1\naction = \"reconfigure\"\nfrom = \"Xneg\"\nto = \"Xpos\"\n\
         [[step]]\nid = \"standby\"\nrobot = 1\naction = \"mode\"\nmode = \"standby\"\nconfirm = true\n",
    )
    .unwrap();
    let (code, t, took) = {
        let (junk_down, junk, carried) = (cable.junk_down.clone(), junk.clone(), cable.carried.clone());
        let up0 = carried[0].load(Ordering::Relaxed);
        let inject = std::thread::spawn(move || {
            // Once the ground sends (its port is open and flushed), junk towards it.
            let t0 = Instant::now();
            while carried[0].load(Ordering::Relaxed) == up0 && t0.elapsed() < Duration::from_secs(20) {
                std::thread::sleep(Duration::from_millis(5));
            }
            junk_down.lock().unwrap().extend(junk);
        });
        let r = go(with(&["run", plan.to_str().unwrap(), "--plain"], &[]));
        inject.join().unwrap();
        r
    };
    assert_eq!(code, Some(0), "{t}");
    assert!(t.contains("3 of 3 steps done") && t.contains("0 resends"), "{t}");
    let frames_line = t.lines().find(|l| l.contains("frames robot 1:"));
    assert!(frames_line.is_some(), "{t}");
    eprintln!("{}", frames_line.unwrap_or_default());
    let tm_refused: u64 = frames_line
        .and_then(|l| l.split(" alerts, ").nth(1)?.split(' ').next()?.parse().ok())
        .unwrap_or(0);
    assert!(tm_refused >= 1, "the junk towards the ground was counted: {t}");
    eprintln!("ground run (3 steps) over the pty pair: {took:?}");

    // HK after all of it (every 10 s on board = 0.5 s at --speed 20).
    let hk_before = tm_log(&log).iter().filter(|(s, ss, _)| (*s, *ss) == (3, 25)).count();
    wait_for(Duration::from_secs(10), "two more HK rounds after the plan", || {
        tm_log(&log).iter().filter(|(s, ss, _)| (*s, *ss) == (3, 25)).count() > hk_before + 4
    });
    let [up, down, lost] = [0, 1, 2].map(|i| cable.carried[i].load(Ordering::Relaxed));
    eprintln!("cable: {up} bytes up, {down} bytes down, {lost} bytes lost (no reader)");
    drop(cable);
    drop(obsw);
    let tms = tm_log(&log);

    // Judged from the obsw's TM: the pings answered, each TC accepted exactly once.
    // (`ground run` ends its plan with a PING of its own.)
    let pongs = tms.iter().filter(|(s, ss, _)| (*s, *ss) == (17, 2)).count();
    assert!(pongs >= 20, "{pongs} ping replies");
    let mut accepted = std::collections::BTreeMap::new();
    for (s, ss, d) in &tms {
        if (*s, *ss) == (1, 1) && d.len() >= 4 {
            *accepted.entry(d[..4].to_vec()).or_insert(0) += 1;
        }
    }
    assert!(accepted.values().all(|&n| n == 1), "a TC accepted twice: {accepted:?}");
    // ping ×20, MODE_SET, the plan's two MODE_SETs and RECONFIGURE, at least.
    assert!(accepted.len() >= 24, "{accepted:?}");
    let completed = tms.iter().filter(|(s, ss, _)| (*s, *ss) == (1, 7)).count();
    assert!(completed >= 24, "{completed} completions");

    // The junk was counted: the two frames the framing dropped in IO_TC_DROPPED, the
    // short frame by the receive pipeline (a length or CRC refusal), and nothing ran.
    let dropped = last_hk(&tms, mib::hk::sid::PLATFORM_IO, pid::IO_TC_DROPPED);
    assert!(dropped.is_some_and(|d| d >= 2), "IO_TC_DROPPED {dropped:?}");
    let refused: i64 = [
        pid::LINK_REJ_BAD_CRC,
        pid::LINK_REJ_BAD_LENGTH,
        pid::LINK_REJ_BAD_HEADER,
        pid::LINK_REJ_BARE_PACKET,
    ]
    .iter()
    .filter_map(|p| last_hk(&tms, mib::hk::sid::SPACE_LINK, *p))
    .sum();
    assert!(
        refused >= 1,
        "the short junk frame refused by the frame layer: {refused}"
    );
    eprintln!(
        "obsw: IO_TC_DROPPED {dropped:?}, frame-layer refusals {refused}, TCs accepted {}",
        accepted.len()
    );
    let stderr = std::fs::read_to_string(dir.join("obsw.stderr")).unwrap_or_default();
    assert!(stderr.contains("one COBS frame per frame"), "{stderr}");
    let _ = std::fs::remove_dir_all(&dir);
}
