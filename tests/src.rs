//! Harness for the end-to-end tests in `tests/tests/`: starts the real `obsw` binary on
//! free loopback ports and talks PUS to it over UDP or TCP.

pub mod relay;

use std::io::{BufRead, BufReader, Read, Write};
use std::net::{SocketAddr, TcpStream, UdpSocket};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};
use std::time::{Duration, Instant};

use arbitrary_int::{u11, u14};
use satrs::spacepackets::ecss::tc::{AckFlags, PusTcCreator, PusTcSecondaryHeader};
use satrs::spacepackets::ecss::tm::PusTmReader;
use satrs::spacepackets::ecss::{CreatorConfig, MessageTypeId};
use satrs::spacepackets::{CcsdsPacket, SpHeader};

/// Path of a workspace binary (`obsw`, `ground`, `relay`) for the tests to start:
/// `$<NAME>_BIN` if set, else target/<profile>/NAME beside the test executable — built
/// first (once per test process) with the same target directory and profile, so a test
/// run by its exact name on a fresh checkout finds a binary, and never a stale one.
pub fn bin(name: &str) -> PathBuf {
    if let Ok(p) = std::env::var(format!("{}_BIN", name.to_uppercase())) {
        return PathBuf::from(p);
    }
    let exe = std::env::current_exe().expect("test executable path");
    // target/<profile>/deps/test-xxxx -> target/<profile>/NAME
    let profile_dir = exe
        .parent()
        .and_then(|d| d.parent())
        .expect("test executable under target/<profile>/deps");
    let path = profile_dir.join(name);
    ensure_built(name, profile_dir);
    path
}

/// Runs `cargo build --workspace --bins` once per binary and process, into the
/// target directory and profile the test executable itself was built in. Cargo makes this
/// a no-op when the binary is up to date (a fraction of a second).
fn ensure_built(name: &str, profile_dir: &std::path::Path) {
    use std::collections::BTreeSet;
    use std::sync::Mutex;
    static BUILT: Mutex<BTreeSet<String>> = Mutex::new(BTreeSet::new());
    let mut built = BUILT.lock().unwrap_or_else(|e| e.into_inner());
    if built.contains(name) {
        return;
    }
    let target_dir = profile_dir.parent().expect("target directory");
    let profile = match profile_dir.file_name().and_then(|n| n.to_str()) {
        Some("debug") | None => "dev".to_string(),
        Some(p) => p.to_string(),
    };
    let cargo = std::env::var_os("CARGO").unwrap_or_else(|| "cargo".into());
    let out = Command::new(cargo)
        // The whole workspace's binaries, as CI's build step and the review build them: the
        // same feature set, so this is a no-op after them (building one package alone would
        // resolve features differently and rebuild its libraries).
        .args(["build", "-q", "--workspace", "--bins", "--profile", &profile])
        .arg("--target-dir")
        .arg(target_dir)
        .current_dir(concat!(env!("CARGO_MANIFEST_DIR"), "/.."))
        .output()
        .unwrap_or_else(|e| panic!("cannot run cargo to build {name}: {e}"));
    assert!(
        out.status.success(),
        "building {name} (cargo build --workspace --bins) failed:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    built.insert(name.to_string());
}

/// A running `obsw` process; killed on drop.
pub struct Obsw {
    child: Child,
    pub udp: SocketAddr,
    pub tcp: SocketAddr,
    pub sim_ctl: SocketAddr,
    pub apid: u16,
    /// The frame port it bound (`--frame-udp`, from its READY line): give `--frame-udp
    /// 127.0.0.1:0` and read the port here — no free port probed and bound later, which
    /// another process may take in between.
    pub frame_udp: Option<SocketAddr>,
    /// Its clock's time base (READY `epoch_ms`, `speed`): on-board time T (Unix ms) was
    /// wall-clock time `epoch_ms + (T - epoch_ms) / speed`.
    pub epoch_ms: u64,
    pub speed: f64,
}

impl Obsw {
    /// Starts `obsw` for robot 1 on free ports with extra arguments.
    pub fn start(extra: &[&str]) -> Obsw {
        Self::start_robot(1, extra)
    }

    pub fn start_robot(robot: u8, extra: &[&str]) -> Obsw {
        let path = bin("obsw");
        let mut child = Command::new(&path)
            .args([
                "--robot",
                &robot.to_string(),
                "--udp",
                "127.0.0.1:0",
                "--tcp",
                "127.0.0.1:0",
                "--sim-ctl",
                "127.0.0.1:0",
            ])
            .args(if extra.contains(&"--frame-udp") {
                &[][..]
            } else {
                &["--lab-bare-packets"][..]
            })
            .args(extra)
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .unwrap_or_else(|e| panic!("cannot start {}: {e}", path.display()));
        let mut line = String::new();
        BufReader::new(child.stdout.take().expect("stdout"))
            .read_line(&mut line)
            .expect("READY line");
        let field = |k: &str| -> String {
            line.split_whitespace()
                .find_map(|w| w.strip_prefix(&format!("{k}=")))
                .unwrap_or_else(|| panic!("no {k} in {line:?}"))
                .to_string()
        };
        let apid = u16::from_str_radix(field("apid").trim_start_matches("0x"), 16).expect("apid");
        let frame_udp = line
            .split_whitespace()
            .find_map(|w| w.strip_prefix("frame_udp="))
            .map(|a| a.parse().expect("frame_udp address"));
        Obsw {
            frame_udp,
            udp: field("udp").parse().unwrap(),
            tcp: field("tcp").parse().unwrap(),
            sim_ctl: field("sim_ctl").parse().unwrap(),
            apid,
            epoch_ms: field("epoch_ms").parse().expect("epoch_ms"),
            speed: field("speed").parse().expect("speed"),
            child,
        }
    }

    /// Robot 1 over UDP transfer frames with the keys `ground keys create` made in `keys`
    /// (its `robot-1` folder: TC SPI 1, TM SPI 17, the link state file), TM frames to
    /// `tm_to`, on a frame port it binds itself ([`Obsw::frame_udp`]), with `extra`
    /// arguments.
    pub fn start_frames(keys: &Path, tm_to: SocketAddr, extra: &[&str]) -> Obsw {
        let rd = keys.join("robot-1");
        let p = |f: &str| rd.join(f).display().to_string();
        let (tc, tm, st, to) = (
            p("tc-spi1.key"),
            p("tm-spi17.key"),
            p("obsw-link.state"),
            tm_to.to_string(),
        );
        let mut args = vec![
            "--frame-udp",
            "127.0.0.1:0",
            "--frame-tm-to",
            &to,
            "--tc-key",
            &tc,
            "--tm-key",
            &tm,
            "--link-state",
            &st,
        ];
        args.extend_from_slice(extra);
        let o = Obsw::start(&args);
        assert!(o.frame_udp.is_some(), "READY names the frame port");
        o
    }

    /// The frame port (an obsw started over frames).
    pub fn frame(&self) -> SocketAddr {
        self.frame_udp.expect("an obsw started with --frame-udp")
    }

    /// The wall-clock time (Unix ms) of on-board time `board_unix_ms` of this obsw, so that
    /// time stamps of robots run faster than real time compare.
    pub fn wall_ms(&self, board_unix_ms: i64) -> f64 {
        let e = self.epoch_ms as f64;
        e + (board_unix_ms as f64 - e) / self.speed
    }

    /// Process ID of the obsw.
    pub fn pid(&self) -> u32 {
        self.child.id()
    }

    /// Its exit status, if it exits within `limit`.
    pub fn wait_exit(&mut self, limit: Duration) -> Option<std::process::ExitStatus> {
        let t0 = std::time::Instant::now();
        loop {
            if let Ok(Some(s)) = self.child.try_wait() {
                return Some(s);
            }
            if t0.elapsed() >= limit {
                return None;
            }
            std::thread::sleep(Duration::from_millis(5));
        }
    }

    /// Kills the obsw with SIGKILL (no chance to flush or say goodbye).
    pub fn kill9(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }

    /// Sends a simulator-control line and returns the reply.
    pub fn sim(&self, line: &str) -> String {
        let s = UdpSocket::bind("127.0.0.1:0").unwrap();
        s.set_read_timeout(Some(Duration::from_secs(2))).unwrap();
        s.send_to(line.as_bytes(), self.sim_ctl).unwrap();
        let mut buf = [0u8; 512];
        let n = s.recv(&mut buf).expect("sim-ctl reply");
        String::from_utf8_lossy(&buf[..n]).to_string()
    }
}

impl Drop for Obsw {
    /// SIGTERM first (the obsw stops at its next control period and exits 0, so an
    /// instrumented build writes its coverage profile), SIGKILL after 2 s.
    fn drop(&mut self) {
        if let Ok(None) = self.child.try_wait() {
            let pid = self.child.id().to_string();
            let _ = std::process::Command::new("kill").args(["-TERM", &pid]).status();
            self.wait_exit(Duration::from_secs(2));
        }
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// A decoded TM packet.
#[derive(Clone, Debug)]
pub struct Tm {
    pub service: u8,
    pub subservice: u8,
    pub seq: u16,
    pub apid: u16,
    pub data: Vec<u8>,
    pub raw: Vec<u8>,
    pub at: Instant,
}

impl Tm {
    pub fn parse(raw: &[u8]) -> Option<Tm> {
        let tm = PusTmReader::new(raw, mib::config::TIMESTAMP_LEN).ok()?;
        Some(Tm {
            service: tm.service_type_id(),
            subservice: tm.message_subtype_id(),
            seq: tm.seq_count().value(),
            apid: tm.apid().value(),
            data: tm.source_data().to_vec(),
            raw: raw.to_vec(),
            at: Instant::now(),
        })
    }
    /// Request ID of a TM[1,x] (the one type, `mib_wire::RequestId`).
    pub fn request(&self) -> Option<mib_wire::RequestId> {
        if self.service != 1 {
            return None;
        }
        mib_wire::RequestId::of_tc(&self.data).ok()
    }
    /// Failure code of a TM[1,2/4/6/8].
    pub fn failure_code(&self) -> Option<u16> {
        let off = if self.subservice == 6 { 5 } else { 4 };
        (self.service == 1 && self.subservice.is_multiple_of(2) && self.data.len() >= off + 2)
            .then(|| u16::from_be_bytes([self.data[off], self.data[off + 1]]))
    }
    /// Step of a TM[1,5/6].
    pub fn step(&self) -> Option<u8> {
        (self.service == 1 && (self.subservice == 5 || self.subservice == 6)).then(|| self.data[4])
    }
    /// Event ID of a TM[5,x].
    pub fn event_id(&self) -> Option<u16> {
        (self.service == 5 && self.subservice <= 4 && self.data.len() >= 2)
            .then(|| u16::from_be_bytes([self.data[0], self.data[1]]))
    }
    /// Structure ID of a TM[3,25].
    pub fn sid(&self) -> Option<u16> {
        (self.service == 3 && self.subservice == 25 && self.data.len() >= 2)
            .then(|| u16::from_be_bytes([self.data[0], self.data[1]]))
    }
    /// A raw HK parameter value.
    pub fn hk(&self, param: u16) -> Option<i64> {
        mib_wire::codec::decode_hk(&self.data).ok()?.get(param)
    }
}

/// Builds a PUS-C TC with all acknowledgement flags.
pub fn tc(apid: u16, seq: u16, service: u8, subservice: u8, app: &[u8]) -> Vec<u8> {
    let sp = SpHeader::new_for_unseg_tc(u11::new(apid), u14::new(seq), 0);
    let sec = PusTcSecondaryHeader::new(MessageTypeId::new(service, subservice), AckFlags::ALL, 0);
    let mut buf = vec![0u8; 2048];
    let n = PusTcCreator::new(sp, sec, app, CreatorConfig::default())
        .write_to_bytes(&mut buf)
        .expect("tc");
    buf.truncate(n);
    buf
}

/// Builds a TC by MIB name with range-checked arguments.
pub fn tc_named(apid: u16, seq: u16, name: &str, args: &[i64]) -> Vec<u8> {
    let def = mib::tc::by_name(name).unwrap_or_else(|| panic!("no TC {name}"));
    let mut app = vec![0u8; 64];
    let n = mib_wire::codec::encode_args(def, args, &mut app).expect("args");
    tc(apid, seq, def.service, def.subservice, &app[..n])
}

/// The request ID fields of a TC as they appear in TM[1,x].
pub fn request_of(tc: &[u8]) -> mib_wire::RequestId {
    mib_wire::RequestId::of_tc(tc).expect("a TC of at least 4 bytes")
}

/// The MIB definition of a well-formed TC (`None` for bytes that are no TC of the MIB:
/// a damaged copy, an unknown service or function).
pub fn tc_def(tc: &[u8]) -> Option<&'static mib::tc::TcDef> {
    let p = mib_wire::header::TcPacket::parse(tc).ok()?;
    let function = match p.app_data {
        [hi, lo, ..] if p.service == mib::tc::service::FUNCTION => Some(u16::from_be_bytes([*hi, *lo])),
        _ => None,
    };
    mib::tc::lookup(p.service, p.subservice, function)
}

/// Why a failure report breaks the MIB: its code is neither an acceptance failure nor in
/// the failure list of the TC `def` it answers (what the ICD and Yamcs show operators).
pub fn unlisted_failure(def: &mib::tc::TcDef, tm: &Tm) -> Option<String> {
    let code = tm.failure_code()?;
    (!def.may_fail_with(code)).then(|| {
        format!(
            "TM[1,{}] answers {} with failure {} ({code}), which is not in its MIB failure list",
            tm.subservice,
            def.name,
            mib::FailureCode::from_code(code).name()
        )
    })
}

/// A ground link over UDP or TCP.
pub enum Link {
    Udp(UdpSocket, SocketAddr),
    Tcp(TcpStream, Box<TcpRx>),
}

/// The TCP receive side: the one COBS deframer (`mmic_link::stream::Deframer`, whose
/// counters keep what it dropped) and the frames it completed, not yet read.
pub struct TcpRx {
    pub deframer: mmic_link::stream::Deframer<{ mib::config::MAX_PACKET_LEN }>,
    pub frames: std::collections::VecDeque<Vec<u8>>,
}

impl TcpRx {
    fn new() -> Box<Self> {
        Box::new(TcpRx {
            deframer: mmic_link::stream::Deframer::new(),
            frames: std::collections::VecDeque::new(),
        })
    }
}

pub struct Client {
    pub link: Link,
    pub apid: u16,
    seq: u16,
    /// Every TM received so far, in order.
    pub log: Vec<Tm>,
    /// The MIB definition of each TC sent, by request ID (the latest TC of an ID): every
    /// failure report received for one is checked against its failure list.
    sent: Vec<(mib_wire::RequestId, &'static mib::tc::TcDef)>,
}

impl Client {
    pub fn udp(o: &Obsw) -> Client {
        let s = UdpSocket::bind("127.0.0.1:0").unwrap();
        Client {
            link: Link::Udp(s, o.udp),
            apid: o.apid,
            seq: 0,
            log: Vec::new(),
            sent: Vec::new(),
        }
    }
    pub fn tcp(o: &Obsw) -> Client {
        let s = TcpStream::connect(o.tcp).unwrap();
        s.set_nodelay(true).unwrap();
        Client {
            link: Link::Tcp(s, TcpRx::new()),
            apid: o.apid,
            seq: 0,
            log: Vec::new(),
            sent: Vec::new(),
        }
    }
    pub fn next_seq(&mut self) -> u16 {
        self.seq = mib::headers::SeqCount::new(self.seq).next().get();
        self.seq
    }
    pub fn send_raw(&mut self, raw: &[u8]) {
        if let Ok(r) = mib_wire::RequestId::of_tc(raw) {
            self.sent.retain(|(s, _)| *s != r);
            if let Some(def) = tc_def(raw) {
                self.sent.push((r, def));
            }
        }
        match &mut self.link {
            Link::Udp(s, to) => {
                s.send_to(raw, *to).unwrap();
            }
            Link::Tcp(s, _) => {
                let mut f = vec![0u8; mmic_link::stream::encoded_len(raw.len())];
                let n = mmic_link::stream::encode(raw, &mut f).unwrap();
                s.write_all(&f[..n]).unwrap();
            }
        }
    }
    /// Sends a TC by MIB name; returns the raw TC.
    pub fn send(&mut self, name: &str, args: &[i64]) -> Vec<u8> {
        let seq = self.next_seq();
        let raw = tc_named(self.apid, seq, name, args);
        self.send_raw(&raw);
        raw
    }
    /// Subscribes to the downlink (UDP: TM goes only to grounds whose TC was accepted)
    /// with a ping, and waits for its completion.
    pub fn subscribe(&mut self) {
        let raw = self.send("PING", &[]);
        self.wait_done(&raw, Duration::from_secs(5))
            .expect("ping answered: subscribed to the downlink");
    }
    /// Receives TM for up to `timeout`, appending to the log; returns what arrived.
    pub fn recv_for(&mut self, timeout: Duration) -> Vec<Tm> {
        let deadline = Instant::now() + timeout;
        let mut got = Vec::new();
        while let Some(t) = self.recv_one(deadline) {
            got.push(t);
        }
        got
    }
    fn recv_one(&mut self, deadline: Instant) -> Option<Tm> {
        let mut buf = vec![0u8; 4096];
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            if left.is_zero() {
                return None;
            }
            match &mut self.link {
                Link::Udp(s, _) => {
                    s.set_read_timeout(Some(left.max(Duration::from_millis(1)))).unwrap();
                    if let Ok(n) = s.recv(&mut buf) {
                        if let Some(t) = Tm::parse(&buf[..n]) {
                            self.received(&t);
                            return Some(t);
                        }
                    }
                }
                Link::Tcp(s, rx) => {
                    if let Some(frame) = rx.frames.pop_front() {
                        if let Some(t) = Tm::parse(&frame) {
                            self.received(&t);
                            return Some(t);
                        }
                        continue;
                    }
                    s.set_read_timeout(Some(left.max(Duration::from_millis(1)))).unwrap();
                    if let Ok(n) = s.read(&mut buf) {
                        if n == 0 {
                            return None;
                        }
                        let TcpRx { deframer, frames } = &mut **rx;
                        // A dropped frame stays counted in `deframer.counters`.
                        deframer.feed(&buf[..n], |f| {
                            if let Ok(f) = f {
                                frames.push_back(f.to_vec());
                            }
                        });
                    }
                }
            }
        }
    }
    /// Logs a TM; a failure report for a TC this client sent must carry a code of that
    /// TC's MIB failure list (every end-to-end test checks what it observes).
    fn received(&mut self, t: &Tm) {
        let def = t
            .request()
            .and_then(|r| self.sent.iter().find(|(s, _)| *s == r))
            .map(|(_, d)| *d);
        if let Some(why) = def.and_then(|d| unlisted_failure(d, t)) {
            panic!("{why}\n{}", self.summary());
        }
        self.log.push(t.clone());
    }
    /// Waits until a TM matching `pred` arrives (or the timeout passes).
    pub fn wait_for(&mut self, timeout: Duration, mut pred: impl FnMut(&Tm) -> bool) -> Option<Tm> {
        let deadline = Instant::now() + timeout;
        while let Some(t) = self.recv_one(deadline) {
            if pred(&t) {
                return Some(t);
            }
        }
        None
    }
    /// Waits for the completion (TM[1,7] or a failure) of a TC.
    pub fn wait_done(&mut self, tc: &[u8], timeout: Duration) -> Option<Tm> {
        let r = request_of(tc);
        let done = |t: &Tm| t.request() == Some(r) && matches!(t.subservice, 2 | 4 | 6 | 7 | 8);
        // A report that already arrived while waiting for something else counts.
        if let Some(t) = self.log.iter().find(|t| done(t)) {
            return Some(t.clone());
        }
        self.wait_for(timeout, done)
    }
    /// A readable digest of everything received except HK, for assertion messages.
    pub fn summary(&self) -> String {
        let mut out = String::new();
        for t in self.log.iter().filter(|t| t.service != 3) {
            let what = match (t.service, t.event_id(), t.request()) {
                (5, Some(id), _) => {
                    let name = mib::events::by_id(id).map_or("?", |e| e.name);
                    format!("EV {name} {:02x?}", &t.data[2..])
                }
                (1, _, Some(r)) => format!("TM[1,{}] seq {} code {:?}", t.subservice, r.seq(), t.failure_code()),
                _ => format!(
                    "TM[{},{}] {:02x?}",
                    t.service,
                    t.subservice,
                    &t.data[..t.data.len().min(16)]
                ),
            };
            out.push_str(&what);
            out.push('\n');
        }
        out
    }
    /// Verification reports of a TC seen so far.
    pub fn verifications(&self, tc: &[u8]) -> Vec<u8> {
        let r = request_of(tc);
        self.log
            .iter()
            .filter(|t| t.request() == Some(r))
            .map(|t| t.subservice)
            .collect()
    }
}

/// A fresh scratch folder `$TMPDIR/<prefix>-<pid>-<name>` (emptied first).
pub fn tmpdir(prefix: &str, name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("{prefix}-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// A local port free now for both UDP and TCP, for a *child process* to bind later (the
/// ground's `--tm-listen`, the obsw's `--udp`/`--tcp`/`--sim-ctl`).
///
/// Chosen **below the kernel's ephemeral range** (32768–60999 on Linux): every socket these
/// tests, the obsw and the ground bind to port 0 gets its port from that range, so none of
/// them can take this one before the child binds it (CI once lost a test to exactly that:
/// the ground's TM port taken by another test's socket — "Address already in use"). Test
/// processes start at different points of the range (their process id) and take each port
/// once (a counter), and a port is handed out only while both a TCP listener and a UDP
/// socket can bind it.
pub fn free_port() -> u16 {
    use std::sync::atomic::{AtomicU32, Ordering};
    const LOW: u32 = 10_000;
    const SPAN: u32 = 22_000; // ports 10000..31999
    static NEXT: AtomicU32 = AtomicU32::new(0);
    let start = std::process::id().wrapping_mul(2_654_435_761) % SPAN;
    loop {
        let n = NEXT.fetch_add(1, Ordering::Relaxed);
        let port = (LOW + (start + n) % SPAN) as u16;
        let tcp = std::net::TcpListener::bind(("127.0.0.1", port));
        if tcp.is_ok() && UdpSocket::bind(("127.0.0.1", port)).is_ok() {
            return port;
        }
    }
}

/// [`free_port`] as a local UDP address.
pub fn free_udp() -> SocketAddr {
    ([127, 0, 0, 1], free_port()).into()
}

/// Runs the real `ground` in `dir` with `args` (stdin closed) to its end.
pub fn ground(dir: &Path, args: &[&str]) -> Output {
    Command::new(bin("ground"))
        .current_dir(dir)
        .args(args)
        .stdin(Stdio::null())
        .output()
        .expect("run ground")
}

/// A finished process's stdout then stderr.
pub fn text(o: &Output) -> String {
    format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

/// Robot 1's keys made by the real `ground keys create` in `dir/TEST-KEYS` (the folder
/// for `--keys` and [`Obsw::start_frames`]).
pub fn create_keys(dir: &Path) -> PathBuf {
    let keys = dir.join("TEST-KEYS");
    let k = ground(
        dir,
        &["--no-archive", "keys", "create", keys.to_str().unwrap(), "--robot", "1"],
    );
    assert!(k.status.success(), "{}", text(&k));
    keys
}

/// Every TM packet an obsw sent (its `--tm-log`: one packet in hex per line).
pub fn read_tm_log(path: &Path) -> Vec<Tm> {
    std::fs::read_to_string(path)
        .unwrap_or_default()
        .lines()
        .filter_map(|l| {
            let b: Option<Vec<u8>> = (0..l.len() / 2)
                .map(|i| u8::from_str_radix(l.get(2 * i..2 * i + 2)?, 16).ok())
                .collect();
            Tm::parse(&b?)
        })
        .collect()
}
