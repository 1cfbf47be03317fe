//! Test like you fly: the QEMU board (`firmware/qemu-board`: board A's control period,
//! frame link and flash store as the image composes them, on QEMU's `virt` machine)
//! driven by the real `ground` binary over its serial transport (`--serial`, the
//! collector's `serial =`), the bytes board A's USB serial carries, on the machine's
//! 16550 UART.
//!
//! The UART is a Unix socket QEMU connects to; this test is the cable between it and
//! the socket the ground connects to (`Cable`): it copies the bytes both ways, keeps the
//! ground's COBS frames (to replay one), can cut the line, and takes the board's new
//! connection when QEMU is started again — a cable that stays plugged into the ground
//! while the board reboots. In order:
//!
//! 1. `ground run` flies a one-robot plan (the checkout without the steps the QEMU
//!    robot cannot do, see `PLAN`) to completion; its HK is archived.
//!    Then `ground file put` of a small file and `ground file get` of it back, byte-exact
//!    (board A's file service over its flash file store), and again after the restart
//!    below: the file survives the SIGKILL, and the restarted board opens its transaction
//!    with a sequence number it never used (kept in its store). The file service's
//!    counters come down in HK FILES (archived by the collector in 2).
//! 2. `ground collect` follows the board; a TC frame the cable kept from the plan is
//!    sent again: the board refuses it as a replay, counted in SPACE_LINK HK
//!    (LINK_REJ_REPLAY) and evented (LINK_FRAME_REJECTED, reason 12).
//! 3. The line is cut; half-way through the outage QEMU is killed with SIGKILL and
//!    started again on the same flash file; the line comes back. The collector must
//!    fill the outage from the board's flash store: every sequence count from the first
//!    archived packet to the last is in the archive once (at most the one packet the
//!    kill cut between sending and storing may be missing), and the counts go on across
//!    the restart.
//!
//! Ignored in the workspace run: it needs the QEMU board's image and
//! `qemu-system-riscv32`. `scripts/firmware-ci.sh` builds the image and runs it:
//! `QEMU_BOARD_ELF=… cargo test -p e2e-tests --test qemu_board_e2e -- --ignored`.

use std::collections::BTreeMap;
use std::io::{BufRead, BufReader, Read, Write};
use std::os::unix::net::{UnixListener, UnixStream};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use e2e_tests::{bin, Tm};

/// The checkout plan (`plans/checkout.toml`) without its reconfiguration and bolting:
/// the QEMU robot's sensors do not move (`firmware/qemu-board/src/robot.rs`), so a hip
/// rotation or a bolt cannot complete on it.
const PLAN: &str = r#"
name = "qemu-checkout"
description = "HK at 5 Hz, operational, home, side B gripper and arm debug moves, HK back, standby"

[[robot]]
number = 1
initial_state = "Xneg"

[[step]]
id = "hk-fast"
robot = 1
action = "command"
tc = "HK_SET_INTERVAL"
args = { sid = 1, interval_ms = 200 }

[[step]]
id = "operational"
robot = 1
action = "mode"
confirm = true
mode = "operational"

[[step]]
id = "home"
robot = 1
action = "home"

[[step]]
id = "grip-b-open"
robot = 1
action = "move-gripper"
confirm = true
side = "B"
pwm = 1900

[[step]]
id = "arm-b-out"
robot = 1
action = "move-arm"
confirm = true
side = "B"
pwm = 1300

[[step]]
id = "arm-b-in"
robot = 1
action = "move-arm"
confirm = true
side = "B"
pwm = 1000

[[step]]
id = "grip-b-close"
robot = 1
action = "move-gripper"
confirm = true
side = "B"
pwm = 1100

[[step]]
id = "hk-normal"
robot = 1
action = "command"
tc = "HK_SET_INTERVAL"
args = { sid = 1, interval_ms = 1000 }

[[step]]
id = "standby"
robot = 1
action = "mode"
confirm = true
mode = "standby"
"#;
const PLAN_STEPS: usize = 9;

/// Seconds of the outage (the kill in its middle): 16, or `$QEMU_BOARD_OUTAGE_S` (the
/// 10-minute case is run by hand with 600).
fn outage_s() -> u64 {
    std::env::var("QEMU_BOARD_OUTAGE_S")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(16)
}

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// The QEMU board's image: `$QEMU_BOARD_ELF`, or where firmware-ci.sh builds it.
fn board_elf() -> PathBuf {
    std::env::var_os("QEMU_BOARD_ELF")
        .map(PathBuf::from)
        .unwrap_or_else(|| root().join("firmware/target/qemu-tests/riscv32imc-unknown-none-elf/release/qemu-board"))
}

struct Proc(Child);

impl Drop for Proc {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// The board under QEMU, its UART connected to `uart` (a Unix socket the cable listens
/// on), in `dir` (which holds the flash file). Returns once it printed READY.
fn start_board(dir: &Path, uart: &Path) -> (Proc, String) {
    let elf = board_elf();
    assert!(
        elf.is_file(),
        "no QEMU board image at {} (build firmware/qemu-board, or set QEMU_BOARD_ELF)",
        elf.display()
    );
    let mut child = Command::new("qemu-system-riscv32")
        .current_dir(dir)
        .args([
            "-machine",
            "virt",
            "-cpu",
            "rv32",
            "-m",
            "64M",
            "-nographic",
            "-monitor",
            "none",
        ])
        .args(["-bios", "none", "-semihosting-config", "enable=on,target=native"])
        .arg("-chardev")
        .arg(format!("socket,id=uart,path={}", uart.display()))
        .args(["-serial", "chardev:uart", "-kernel"])
        .arg(&elf)
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .expect("starting qemu-system-riscv32");
    let mut out = BufReader::new(child.stdout.take().expect("QEMU's stdout"));
    let proc = Proc(child);
    let mut line = String::new();
    let t0 = Instant::now();
    while !line.starts_with("READY") {
        line.clear();
        if out.read_line(&mut line).unwrap_or(0) == 0 || t0.elapsed() > Duration::from_secs(30) {
            panic!("the QEMU board did not start: {line:?}");
        }
    }
    // The rest of its output (a panic message) goes to the test's output.
    std::thread::spawn(move || {
        for l in out.lines().map_while(Result::ok) {
            println!("qemu-board: {l}");
        }
    });
    (proc, line.trim().to_string())
}

#[derive(Default)]
struct Line {
    board: Option<UnixStream>,
    ground: Option<UnixStream>,
    /// Bytes dropped both ways while set.
    cut: bool,
    /// The ground's stream is between two frames (the last byte was the 0x00 delimiter).
    up_between_frames: bool,
    /// The ground's COBS frames (without delimiters), and the one being received.
    up_frames: Vec<Vec<u8>>,
    up_partial: Vec<u8>,
}

/// The serial cable between the board's UART socket and the ground's socket.
#[derive(Clone)]
struct Cable(Arc<Mutex<Line>>);

impl Cable {
    fn start(board: UnixListener, ground: UnixListener) -> Cable {
        let cable = Cable(Arc::new(Mutex::new(Line {
            up_between_frames: true,
            ..Line::default()
        })));
        for (listener, up) in [(board, false), (ground, true)] {
            let c = cable.clone();
            std::thread::spawn(move || {
                for s in listener.incoming().map_while(Result::ok) {
                    let writer = s.try_clone().expect("socket clone");
                    {
                        let mut l = c.line();
                        if up {
                            l.ground = Some(writer);
                        } else {
                            l.board = Some(writer);
                        }
                    }
                    let c2 = c.clone();
                    std::thread::spawn(move || c2.pump(s, up));
                }
            });
        }
        cable
    }

    fn line(&self) -> std::sync::MutexGuard<'_, Line> {
        self.0.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Copies what `from` sends to the other side until it closes.
    fn pump(&self, mut from: UnixStream, up: bool) {
        let mut buf = [0u8; 4096];
        loop {
            let n = match from.read(&mut buf) {
                Ok(0) | Err(_) => return,
                Ok(n) => n,
            };
            let mut l = self.line();
            if up {
                for &b in &buf[..n] {
                    if b == 0 {
                        if !l.up_partial.is_empty() {
                            let f = std::mem::take(&mut l.up_partial);
                            l.up_frames.push(f);
                        }
                    } else {
                        l.up_partial.push(b);
                    }
                }
                l.up_between_frames = buf[n - 1] == 0;
            }
            if l.cut {
                continue;
            }
            let to = if up { l.board.as_mut() } else { l.ground.as_mut() };
            if let Some(s) = to {
                let _ = s.write_all(&buf[..n]);
            }
        }
    }

    fn set_cut(&self, cut: bool) {
        self.line().cut = cut;
    }

    /// The longest frame the ground sent (an AD frame with its SDLS header and trailer:
    /// longer than the clear control frames).
    fn longest_up_frame(&self) -> Vec<u8> {
        let l = self.line();
        l.up_frames
            .iter()
            .max_by_key(|f| f.len())
            .cloned()
            .expect("the ground sent frames")
    }

    /// Sends `frame` (COBS-encoded, as captured) to the board between two of the
    /// ground's frames.
    fn inject(&self, frame: &[u8]) {
        let t0 = Instant::now();
        loop {
            {
                let mut l = self.line();
                if l.up_between_frames {
                    if let Some(s) = l.board.as_mut() {
                        s.write_all(&[0]).unwrap();
                        s.write_all(frame).unwrap();
                        s.write_all(&[0]).unwrap();
                        return;
                    }
                }
            }
            assert!(t0.elapsed() < Duration::from_secs(10), "no frame boundary to inject at");
            std::thread::sleep(Duration::from_millis(2));
        }
    }
}

/// The sequence numbers of the transactions the robot opened, from `ground file --trace`'s
/// lines of the metadata PDUs it received ("<time> < tx <source>/<seq> metadata").
fn robot_transactions(trace: &str) -> Vec<u32> {
    let robot = mib::cfdp::robot_entity_id(1).to_string();
    let mut seqs: Vec<u32> = trace
        .lines()
        .filter_map(|l| {
            let (_, rest) = l.split_once(" < tx ")?;
            let (id, what) = rest.split_once(' ')?;
            let (source, seq) = id.split_once('/')?;
            (source == robot && what.starts_with("metadata")).then(|| seq.parse().ok())?
        })
        .collect();
    seqs.dedup();
    seqs
}

fn hex(s: &str) -> Option<Vec<u8>> {
    let s = s.trim();
    (0..s.len())
        .step_by(2)
        .map(|i| s.get(i..i + 2).and_then(|b| u8::from_str_radix(b, 16).ok()))
        .collect()
}

/// (sequence count, on-board CDS days, ms of day): one TM packet.
type Key = (u16, u16, u32);

/// Every archived TM packet of robot 1 with the number of rows it has.
fn archived(dir: &Path) -> BTreeMap<Key, (u32, Tm)> {
    let out = Command::new(bin("ground"))
        .current_dir(dir)
        .args(["--archive", "a.db", "archive", "query", "--type", "tm", "--json"])
        .output()
        .expect("ground archive query");
    assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
    let mut all = BTreeMap::new();
    for line in String::from_utf8_lossy(&out.stdout).lines() {
        let v: serde_json::Value = serde_json::from_str(line).expect("one JSON object a line");
        let Some(raw) = v["raw"].as_str().and_then(hex) else {
            continue;
        };
        let (Ok(p), Some(tm)) = (mib_wire::header::TmPacket::parse(&raw), Tm::parse(&raw)) else {
            continue;
        };
        let e = all
            .entry((p.primary.seq_count, p.time.days, p.time.ms_of_day))
            .or_insert((0, tm));
        e.0 += 1;
    }
    all
}

fn wait_for<T>(secs: u64, what: &str, mut f: impl FnMut() -> Option<T>) -> T {
    let t0 = Instant::now();
    loop {
        if let Some(v) = f() {
            return v;
        }
        assert!(t0.elapsed() < Duration::from_secs(secs), "{what}: not within {secs} s");
        std::thread::sleep(Duration::from_millis(500));
    }
}

/// The replay refusals the board reported: (LINK_FRAME_REJECTED events with reason
/// replay, the largest LINK_REJ_REPLAY in SPACE_LINK HK).
fn replay_refusals(arch: &BTreeMap<Key, (u32, Tm)>) -> (usize, i64) {
    use mib::events::eid;
    use mib::params::pid;
    let events = arch
        .values()
        .filter(|(_, t)| t.event_id() == Some(eid::LINK_FRAME_REJECTED))
        .filter_map(|(_, t)| mib_wire::codec::decode_event(&t.data).ok()?.param("reason"))
        .filter(|r| *r == i64::from(pid::LINK_REJ_REPLAY - 120))
        .count();
    let hk = arch
        .values()
        .filter(|(_, t)| t.sid() == Some(mib::hk::sid::SPACE_LINK))
        .filter_map(|(_, t)| t.hk(pid::LINK_REJ_REPLAY))
        .max()
        .unwrap_or(0);
    (events, hk)
}

// verifies: FW-QEMU-01, FILE-STORE-10, FILE-HK-01
#[test]
#[ignore = "needs the QEMU board image and qemu-system-riscv32: scripts/firmware-ci.sh builds and runs it"]
fn the_qemu_board_flies_a_plan_with_the_real_ground_refuses_a_replay_and_keeps_its_store_across_a_kill() {
    let dir = std::env::temp_dir().join(format!("qemu-board-e2e-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let ground = |args: &[&str]| {
        let out = Command::new(bin("ground"))
            .current_dir(&dir)
            .args(args)
            .output()
            .expect("running ground");
        let text = format!(
            "{}{}",
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        );
        (out.status.code(), text)
    };

    // Provisioning as for board A: the ground's keys, the key record from the
    // provisioning tool, written at the key area's offset of an erased 4 MB flash.
    let (code, text) = ground(&["keys", "create", "keys", "--robot", "1"]);
    assert_eq!(code, Some(0), "{text}");
    let record = dir.join("key-record.bin");
    let st = Command::new("bash")
        .arg(root().join("firmware/tools/provision-keys.sh"))
        .args([
            dir.join("keys").to_str().unwrap(),
            "1",
            "--out",
            record.to_str().unwrap(),
        ])
        .status()
        .expect("provision-keys.sh");
    assert!(st.success(), "provision-keys.sh failed");
    let mut flash = vec![0xFFu8; mib::memory::FLASH_BYTES as usize];
    let rec = std::fs::read(&record).unwrap();
    let at = mib::memory::LINK_STATE.offset as usize;
    flash[at..at + rec.len()].copy_from_slice(&rec);
    std::fs::write(dir.join("qemu-board.flash"), &flash).unwrap();

    let (uart, line_end) = (dir.join("uart.sock"), dir.join("ground.sock"));
    let cable = Cable::start(
        UnixListener::bind(&uart).unwrap(),
        UnixListener::bind(&line_end).unwrap(),
    );
    let (mut board, ready) = start_board(&dir, &uart);
    assert_eq!(ready, "READY robot 1 store 0 packets");

    // 1. The plan, to completion, over the serial line.
    std::fs::write(dir.join("plan.toml"), PLAN).unwrap();
    let t0 = Instant::now();
    let (code, text) = ground(&[
        "--archive",
        "a.db",
        "run",
        "plan.toml",
        "--keys",
        "keys",
        "--robot",
        "1",
        "--serial",
        "ground.sock",
    ]);
    assert_eq!(code, Some(0), "ground run:\n{text}");
    assert!(
        text.contains(&format!("{PLAN_STEPS} of {PLAN_STEPS} steps done, 0 failed")),
        "ground run:\n{text}"
    );
    println!("plan: {PLAN_STEPS} steps in {:.1} s", t0.elapsed().as_secs_f64());
    let hk_after_plan = archived(&dir).values().filter(|(_, t)| t.sid().is_some()).count();
    assert!(hk_after_plan >= 10, "{hk_after_plan} HK packets archived by the run");

    // 1b. Files: `ground file put` of a small file (class 2: its file data in BD frames)
    // and `ground file get` of it back, through board A's file service and its flash file
    // store (as in board A's image).
    let data: Vec<u8> = (0..6_000u32)
        .map(|i| (i.wrapping_mul(2_654_435_761) >> 13) as u8)
        .collect();
    std::fs::write(dir.join("up.bin"), &data).unwrap();
    let link = [
        "--robot",
        "1",
        "--keys",
        "keys",
        "--serial",
        "ground.sock",
        "--timeout",
        "120",
    ];
    let t0 = Instant::now();
    let (code, text) = ground(&[&["file", "put"][..], &link, &["up.bin", "table.bin"]].concat());
    assert_eq!(code, Some(0), "ground file put:\n{text}");
    let put_s = t0.elapsed().as_secs_f64();
    let t0 = Instant::now();
    let (code, text) = ground(&[&["file", "get", "--trace"][..], &link, &["table.bin", "down.bin"]].concat());
    assert_eq!(code, Some(0), "ground file get:\n{text}");
    let get_s = t0.elapsed().as_secs_f64();
    let get_tx = robot_transactions(&text);
    assert_eq!(get_tx.len(), 1, "one transaction from the robot for the get:\n{text}");
    assert_eq!(
        std::fs::read(dir.join("down.bin")).unwrap(),
        data,
        "the file that came down differs from the one put"
    );
    println!(
        "files: put {} bytes in {put_s:.1} s, got them back byte-exact in {get_s:.1} s",
        data.len()
    );

    // 2. The collector on the same line; a captured TC frame sent again.
    // Tries per hole: 8, more for a longer outage — the board paces a replay by its
    // downlink's room (a range goes on over as many periods as it needs), so a long
    // outage takes a while to come down and its later holes wait their turn.
    let max_tries = 8.max(outage_s() / 10);
    std::fs::write(
        dir.join("c.toml"),
        format!(
            "keys = \"keys\"\n[gaps]\nretry_ms = 1500\nmax_tries = {max_tries}\n[[robot]]\nnumber = 1\nserial = \"ground.sock\"\n"
        ),
    )
    .unwrap();
    let log = std::fs::File::create(dir.join("collect.log")).unwrap();
    let mut collector = Proc(
        Command::new(bin("ground"))
            .current_dir(&dir)
            .args(["--archive", "a.db", "collect", "--plain", "--config", "c.toml"])
            .stdout(Stdio::null())
            .stderr(Stdio::from(log))
            .spawn()
            .expect("starting ground collect"),
    );
    let collect_log = || std::fs::read_to_string(dir.join("collect.log")).unwrap_or_default();
    let newest = |arch: &BTreeMap<Key, (u32, Tm)>| arch.keys().map(|k| k.0).max();
    let before = newest(&archived(&dir));
    wait_for(30, "the collector archives new HK", || {
        let arch = archived(&dir);
        (newest(&arch) > before.map(|s| s + 3)).then_some(())
    });
    // The file service reported the put (received) and the get (sent) in HK FILES, which
    // the collector archives (every 5 s): a board that reports nothing has no values.
    let files_hk = |p: u16| {
        archived(&dir)
            .values()
            .filter(|(_, t)| t.sid() == Some(mib::hk::sid::FILES))
            .filter_map(|(_, t)| t.hk(p))
            .max()
    };
    let (completed, received, sent) = wait_for(30, "HK FILES with the put and the get", || {
        use mib::params::pid;
        let c = files_hk(pid::FILE_TX_COMPLETED)?;
        let r = files_hk(pid::FILE_TX_RECEIVED)?;
        let s = files_hk(pid::FILE_TX_SENT)?;
        (c >= 2 && r >= 1 && s >= 1).then_some((c, r, s))
    });
    let stored = files_hk(mib::params::pid::FILE_STORE_FILES);
    assert!(
        stored >= Some(1),
        "HK FILES: {stored:?} files in the store after the put"
    );
    println!("HK FILES: {completed} transactions completed, {received} received, {sent} sent, {stored:?} files stored");
    // The collector filled the archive from the board's store: the transfer events too.
    let file_events = |id: u16| -> Vec<(i64, i64)> {
        archived(&dir)
            .values()
            .filter(|(_, t)| t.event_id() == Some(id))
            .filter_map(|(_, t)| {
                let e = mib_wire::codec::decode_event(&t.data).ok()?;
                Some((e.param("source")?, e.param("seq")?))
            })
            .collect()
    };
    let started = file_events(mib::events::eid::FILE_TRANSFER_STARTED);
    let done = file_events(mib::events::eid::FILE_TRANSFER_COMPLETED);
    let failed = file_events(mib::events::eid::FILE_TRANSFER_FAILED);
    println!("FILE_TRANSFER_STARTED {started:?}, COMPLETED {done:?}, FAILED {failed:?}");
    assert!(
        started.contains(&(1, i64::from(get_tx[0]))) && done.contains(&(1, i64::from(get_tx[0]))),
        "the board's transaction of the get started and completed, evented"
    );
    assert!(
        started.len() >= 3 && done.len() >= 3,
        "the put, the get's request and the board's put evented"
    );
    assert!(failed.is_empty(), "no transfer failed");
    let (events0, hk0) = replay_refusals(&archived(&dir));
    assert_eq!((events0, hk0), (0, 0), "no replay refused before the replay");
    let replayed = cable.longest_up_frame();
    cable.inject(&replayed);
    // SPACE_LINK HK comes every 10 s by default.
    let (events, hk) = wait_for(30, "the replay refused, evented and counted in HK", || {
        let r = replay_refusals(&archived(&dir));
        (r.0 >= 1 && r.1 >= 1).then_some(r)
    });
    println!(
        "replayed frame ({} COBS bytes): {events} LINK_FRAME_REJECTED (replay), LINK_REJ_REPLAY = {hk}",
        replayed.len()
    );

    // 3. The outage, the kill in its middle, the restart on the same flash.
    let outage = outage_s();
    let arch = archived(&dir);
    let last_before_cut = newest(&arch).expect("archived TM");
    cable.set_cut(true);
    let cut_at = Instant::now();
    std::thread::sleep(Duration::from_secs(outage / 2));
    board.0.kill().expect("SIGKILL to QEMU");
    let _ = board.0.wait();
    let (board2, ready) = start_board(&dir, &uart);
    board = board2;
    let held: usize = ready
        .strip_prefix("READY robot 1 store ")
        .and_then(|r| r.strip_suffix(" packets"))
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("READY line {ready:?}"));
    assert!(held > 0, "the store kept nothing across the kill: {ready}");
    if let Some(d) = Duration::from_secs(outage).checked_sub(cut_at.elapsed()) {
        std::thread::sleep(d);
    }
    cable.set_cut(false);
    let back = Instant::now();

    // The collector sees the hole and asks the store for it: wait until every count
    // from the first archived packet to the newest is there (at most the one packet a
    // kill between sending and storing loses).
    let fill_s = 90 + outage / 2;
    let deadline = Instant::now() + Duration::from_secs(fill_s);
    let (arch, missing) = loop {
        let arch = archived(&dir);
        let seqs: std::collections::BTreeSet<u16> = arch.keys().map(|k| k.0).collect();
        let (first, last) = match (seqs.first(), seqs.last()) {
            (Some(f), Some(l)) => (*f, *l),
            _ => (0, 0),
        };
        let missing: Vec<u16> = (first..=last).filter(|s| !seqs.contains(s)).collect();
        if last >= last_before_cut.wrapping_add(outage as u16) && missing.len() <= 1 {
            break (arch, missing);
        }
        if Instant::now() > deadline {
            let (_, gaps) = ground(&["--archive", "a.db", "archive", "gaps"]);
            panic!(
                "the outage not filled from the board's store within {fill_s} s: seq {first}..={last}, {} missing ({:?}…)\n{gaps}\n{}",
                missing.len(),
                &missing[..missing.len().min(10)],
                collect_log()
            );
        }
        std::thread::sleep(Duration::from_millis(500));
    };
    let filled_s = back.elapsed().as_secs_f64();
    let twice: Vec<_> = arch.iter().filter(|(_, (n, _))| *n > 1).map(|(k, _)| *k).collect();
    assert!(twice.is_empty(), "archived twice: {twice:?}\n{}", collect_log());
    let mut counts: Vec<u16> = arch.keys().map(|k| k.0).collect();
    counts.sort_unstable();
    counts.dedup();
    assert_eq!(counts.len(), arch.len(), "one packet per sequence count");
    let outage_hk = arch
        .iter()
        .filter(|(k, (_, t))| k.0 > last_before_cut && t.service == 3 && t.subservice == 25)
        .count();
    assert!(
        outage_hk as u64 >= outage / 2,
        "{outage_hk} HK packets after the cut in the archive"
    );
    // The reboot is in the archive: a second BOOT event, with a later sequence count.
    let boots = arch
        .values()
        .filter(|(_, t)| t.event_id() == Some(mib::events::eid::BOOT))
        .count();
    assert!(boots >= 1, "the restarted board's BOOT event archived");
    // TM the board's downlink could not take: none, the store's replays included — they
    // are paced by the downlink's room (obsw_core::services::storage).
    let platform_io = |pid| {
        arch.values()
            .filter(|(_, t)| t.sid() == Some(mib::hk::sid::PLATFORM_IO))
            .filter_map(|(_, t)| t.hk(pid))
            .max()
            .unwrap_or(0)
    };
    let tm_dropped = platform_io(mib::params::pid::IO_TM_DROPPED);
    println!(
        "IO_TM_DROPPED at most {tm_dropped} in PLATFORM_IO HK; IO_STACK_HIGH_WATER at most {} bytes",
        platform_io(mib::params::pid::IO_STACK_HIGH_WATER)
    );
    assert_eq!(tm_dropped, 0, "TM dropped by the board's downlink\n{}", collect_log());
    println!(
        "outage {outage} s with a SIGKILL of QEMU in its middle: store held {held} packets at the restart; \
         archive: seq {}..={} ({} packets, {} HK after the cut), {} missing {:?}, 0 duplicates, filled {filled_s:.1} s after the line came back",
        counts[0],
        counts[counts.len() - 1],
        arch.len(),
        outage_hk,
        missing.len(),
        missing
    );

    let _ = Command::new("kill")
        .args(["-TERM", &collector.0.id().to_string()])
        .status();
    let _ = collector.0.wait();
    // The file put before the kill is still in the board's flash file store.
    let (code, text) = ground(&[&["file", "get", "--trace"][..], &link, &["table.bin", "after.bin"]].concat());
    assert_eq!(code, Some(0), "ground file get after the restart:\n{text}");
    // The restarted board goes on from the sequence number its store kept: the ground
    // never sees a transaction ID again.
    let after_tx = robot_transactions(&text);
    assert_eq!(after_tx.len(), 1, "one transaction from the robot for the get:\n{text}");
    assert!(
        after_tx[0] > get_tx[0],
        "the get after the restart reused or went back on the robot's sequence number: {get_tx:?} then {after_tx:?}"
    );
    assert_eq!(
        std::fs::read(dir.join("after.bin")).unwrap(),
        data,
        "the file that came down after the restart differs from the one put"
    );
    println!(
        "files: the file put before the SIGKILL came back byte-exact after the restart (robot transaction {} before, {} after)",
        get_tx[0], after_tx[0]
    );
    drop(board);
    let _ = std::fs::remove_dir_all(&dir);
}
