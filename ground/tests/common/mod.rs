//! Shared by the ground test suites (each uses part of it):
//! - the real `obsw` ([`Obsw::start`]) and the real `ground` binary ([`ground`]);
//! - a throwaway PostgreSQL server that a suite starts itself
//!   (`scripts/postgres-test.sh`: Debian's package, a temporary data directory, a Unix
//!   socket; stopped when the test process ends).
#![allow(dead_code)]

use std::io::{BufRead, Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};
use std::sync::OnceLock;
use std::time::{Duration, Instant};

pub const GROUND: &str = env!("CARGO_BIN_EXE_ground");

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// The directory of the workspace's binaries for this test's profile, after building
/// them (once per test process, a no-op when up to date), so a test never runs a stale
/// obsw or relay after a change to the MIB or the core. The workspace's binaries, as CI
/// and the review build them: the same feature set, so no library is rebuilt here.
fn workspace_bins() -> &'static Path {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        // <target>/<profile>/deps/<test>-<hash>
        let exe = std::env::current_exe().unwrap();
        let profile_dir = exe.parent().and_then(Path::parent).unwrap();
        let profile = match profile_dir.file_name().and_then(|n| n.to_str()) {
            Some("debug") | None => "dev".to_string(),
            Some(p) => p.to_string(),
        };
        let out = Command::new(env!("CARGO"))
            .args(["build", "-q", "--workspace", "--bins", "--profile", &profile])
            .arg("--target-dir")
            .arg(profile_dir.parent().unwrap())
            .current_dir(root())
            .output()
            .expect("running cargo to build the workspace's binaries");
        assert!(
            out.status.success(),
            "building the workspace's binaries failed:\n{}",
            String::from_utf8_lossy(&out.stderr)
        );
        profile_dir.to_path_buf()
    })
}

/// The obsw binary: `$OBSW_BIN`, or the workspace's ([`workspace_bins`]).
pub fn obsw_bin() -> PathBuf {
    match std::env::var_os("OBSW_BIN") {
        Some(p) => PathBuf::from(p),
        None => workspace_bins().join("obsw"),
    }
}

/// A localhost port free for both TCP and UDP, out of every socket's way until a child
/// binds it: the end-to-end harness's one allocator.
pub use e2e_tests::free_port;

/// A running obsw (killed when dropped): TCs on `addr` (UDP and TCP), simulator control
/// on `ctl`.
pub struct Obsw {
    pub child: Child,
    pub addr: SocketAddr,
    pub ctl: SocketAddr,
    /// The frame port (`--frame-udp`), when started with [`Obsw::start_frames`].
    pub frame: Option<SocketAddr>,
    /// The ground's TM frame address (`--frame-tm-to`).
    pub tm_to: Option<SocketAddr>,
}

/// Test keys for robot `robot` under `dir/keys` (`ground keys create`, random keys);
/// returns the key directory (give it to `ground --keys`).
pub fn frame_keys(dir: &Path, robots: &[u8]) -> PathBuf {
    let keys = dir.join("TEST-KEYS");
    let mut args = vec!["keys".to_string(), "create".into(), keys.to_str().unwrap().into()];
    for r in robots {
        args.push("--robot".into());
        args.push(r.to_string());
    }
    let a: Vec<&str> = args.iter().map(String::as_str).collect();
    let o = ground(dir, &a);
    assert!(o.status.success(), "ground keys create: {}", text(&o));
    keys
}

impl Obsw {
    /// Starts robot `robot`'s obsw with the frame endpoint too: TC frames on a free port,
    /// TM frames to a free local port, keys from `keys/robot-N` (see [`frame_keys`]), its
    /// SDLS counters in `keys/robot-N/obsw-link.state`.
    pub fn start_frames(robot: u8, keys: &Path, extra: &[&str]) -> Obsw {
        let frame: SocketAddr = ([127, 0, 0, 1], free_port()).into();
        let tm_to: SocketAddr = ([127, 0, 0, 1], free_port()).into();
        Obsw::start_frames_at(robot, keys, frame, tm_to, extra)
    }

    /// [`Obsw::start_frames`] with the frame port and the TM frame destination given.
    pub fn start_frames_at(robot: u8, keys: &Path, frame: SocketAddr, tm_to: SocketAddr, extra: &[&str]) -> Obsw {
        let rd = keys.join(format!("robot-{robot}"));
        let p = |f: &str| rd.join(f).to_str().unwrap().to_string();
        let (tc, tm, st) = (p("tc-spi1.key"), p("tm-spi17.key"), p("obsw-link.state"));
        let (fs, ts) = (frame.to_string(), tm_to.to_string());
        let mut args: Vec<&str> = vec![
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
        ];
        args.extend_from_slice(extra);
        let mut o = Obsw::start(robot, &args);
        o.frame = Some(frame);
        o.tm_to = Some(tm_to);
        o
    }

    /// The ground's link flags for this obsw's frame endpoint: `--frames --keys KEYS
    /// --robot N=FRAME --tm-listen N=TM_TO`.
    pub fn frame_args(&self, robot: u8, keys: &Path) -> Vec<String> {
        vec![
            "--keys".into(),
            keys.to_str().unwrap().into(),
            "--robot".into(),
            format!("{robot}={}", self.frame.expect("started with start_frames")),
            "--tm-listen".into(),
            format!("{robot}={}", self.tm_to.expect("started with start_frames")),
        ]
    }

    /// Starts robot `robot`'s obsw with `extra` arguments and waits for its READY line:
    /// the bare-packet lab link unless `extra` gives the frame link.
    pub fn start(robot: u8, extra: &[&str]) -> Obsw {
        let addr: SocketAddr = ([127, 0, 0, 1], free_port()).into();
        let ctl: SocketAddr = ([127, 0, 0, 1], free_port()).into();
        let mut child = Command::new(obsw_bin())
            .args(["--robot", &robot.to_string(), "--udp", &addr.to_string()])
            .args(["--tcp", &addr.to_string(), "--sim-ctl", &ctl.to_string()])
            .args(lab_unless_frames(extra))
            .args(extra)
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .expect("starting obsw");
        let out = child.stdout.take().unwrap();
        let mut lines = std::io::BufReader::new(out).lines();
        let ready = lines.next().and_then(Result::ok).unwrap_or_default();
        assert!(ready.starts_with("READY"), "obsw did not start: {ready:?}");
        std::thread::spawn(move || for _ in lines {});
        Obsw {
            child,
            addr,
            ctl,
            frame: None,
            tm_to: None,
        }
    }
}

impl Drop for Obsw {
    /// SIGTERM first (the obsw exits 0 at its next control period, so an instrumented
    /// build writes its coverage profile), SIGKILL after 2 s.
    fn drop(&mut self) {
        let pid = self.child.id().to_string();
        let _ = Command::new("kill")
            .args(["-TERM", &pid])
            .stderr(Stdio::null())
            .status();
        let t0 = std::time::Instant::now();
        while t0.elapsed().as_secs() < 2 && matches!(self.child.try_wait(), Ok(None)) {
            std::thread::sleep(std::time::Duration::from_millis(5));
        }
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// A fresh temporary directory `ground-<suite>-<pid>-<name>`.
pub fn tmpdir(suite: &str, name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("ground-{suite}-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Runs the real `ground` in `dir`.
pub fn ground(dir: &Path, args: &[&str]) -> Output {
    Command::new(GROUND)
        .current_dir(dir)
        .args(args)
        .output()
        .expect("running ground")
}

/// stdout then stderr of a finished command.
pub fn text(o: &Output) -> String {
    format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

/// URL of the suite's PostgreSQL server (database `postgres`).
pub fn pg_server() -> &'static str {
    static URL: OnceLock<String> = OnceLock::new();
    URL.get_or_init(|| {
        let dir = format!("/tmp/ground-pg-{}", std::process::id());
        let out = Command::new("bash")
            .arg(root().join("scripts/postgres-test.sh"))
            .args(["start", &dir, &std::process::id().to_string()])
            .output()
            .expect("running scripts/postgres-test.sh");
        assert!(
            out.status.success(),
            "starting PostgreSQL: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        String::from_utf8(out.stdout).unwrap().trim().to_string()
    })
}

/// A fresh database on the suite's server.
pub fn pg_db(name: &str) -> String {
    let base = pg_server();
    let mut c = postgres::Client::connect(base, postgres::NoTls).unwrap();
    c.batch_execute(&format!("DROP DATABASE IF EXISTS {name}")).unwrap();
    c.batch_execute(&format!("CREATE DATABASE {name}")).unwrap();
    base.replace("/postgres?", &format!("/{name}?"))
}

/// Drops a database made by [`pg_db`].
pub fn pg_drop(name: &str) {
    let mut c = postgres::Client::connect(pg_server(), postgres::NoTls).unwrap();
    c.batch_execute(&format!("DROP DATABASE IF EXISTS {name} WITH (FORCE)"))
        .unwrap();
}

/// A child process killed when dropped (a collector, a relay).
pub struct Proc(pub Child);

impl Drop for Proc {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// One HTTP/1.1 request; returns the status and the JSON body (`Null` if none). Status
/// 0: nobody answered (not listening yet).
pub fn http(addr: SocketAddr, method: &str, path: &str, body: Option<serde_json::Value>) -> (u16, serde_json::Value) {
    let Ok(mut s) = TcpStream::connect(addr) else {
        return (0, serde_json::Value::Null);
    };
    s.set_read_timeout(Some(Duration::from_secs(30))).unwrap();
    let body = body.map(|b| b.to_string()).unwrap_or_default();
    let mut req = format!(
        "{method} {path} HTTP/1.1\r\nHost: localhost\r\nConnection: close\r\nContent-Length: {}\r\n",
        body.len()
    );
    if !body.is_empty() {
        req.push_str("Content-Type: application/json\r\n");
    }
    req.push_str("\r\n");
    req.push_str(&body);
    // Reset while writing: not the server we want yet (the port `free_port` chose was
    // taken for a moment by another test's listener) — the same as not listening yet;
    // the caller's `wait_for` asks again.
    if s.write_all(req.as_bytes()).is_err() {
        return (0, serde_json::Value::Null);
    }
    let mut out = String::new();
    let _ = s.read_to_string(&mut out);
    let status = out.get(9..12).and_then(|x| x.parse().ok()).unwrap_or(0);
    let text = out.split_once("\r\n\r\n").map(|x| x.1).unwrap_or("");
    (status, serde_json::from_str(text).unwrap_or(serde_json::Value::Null))
}

/// Polls `f` until it returns `Some`, for at most `secs` seconds (the machine is shared).
pub fn wait_for<T>(secs: u64, what: &str, mut f: impl FnMut() -> Option<T>) -> T {
    let end = Instant::now() + Duration::from_secs(secs);
    loop {
        if let Some(v) = f() {
            return v;
        }
        assert!(Instant::now() < end, "timed out waiting for {what}");
        std::thread::sleep(Duration::from_millis(100));
    }
}

/// The project's lossy relay (`e2e-tests`' `relay` binary), built with the obsw.
pub fn relay_bin() -> PathBuf {
    workspace_bins().join("relay")
}

/// A running `ground` child: its stderr lines arrive on a channel as they are written (to
/// wait for progress), its stdout is collected for the end.
pub struct Running {
    child: Child,
    lines: std::sync::mpsc::Receiver<String>,
    stdout: Option<std::thread::JoinHandle<String>>,
    seen: Vec<String>,
}

impl Running {
    pub fn start<S: AsRef<std::ffi::OsStr>>(dir: &Path, args: &[S]) -> Running {
        let mut child = Command::new(GROUND)
            .current_dir(dir)
            .args(args)
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .expect("starting ground");
        let err = child.stderr.take().unwrap();
        let mut out = child.stdout.take().unwrap();
        let (tx, lines) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            for l in std::io::BufReader::new(err).lines().map_while(Result::ok) {
                let _ = tx.send(l);
            }
        });
        // Drained all along, so a chatty child never blocks on a full pipe.
        let stdout = std::thread::spawn(move || {
            let mut s = String::new();
            let _ = out.read_to_string(&mut s);
            s
        });
        Running {
            child,
            lines,
            stdout: Some(stdout),
            seen: Vec::new(),
        }
    }

    /// Waits (at most `limit`) for a stderr line containing `what`; panics with every line
    /// seen so far otherwise.
    pub fn wait_for(&mut self, what: &str, limit: Duration) {
        let t0 = Instant::now();
        while t0.elapsed() < limit {
            if let Ok(l) = self.lines.recv_timeout(Duration::from_millis(100)) {
                let hit = l.contains(what);
                self.seen.push(l);
                if hit {
                    return;
                }
            }
        }
        panic!("no line with {what:?} within {limit:?}:\n{}", self.seen.join("\n"));
    }

    /// Sends SIGINT, as Ctrl-C does.
    pub fn interrupt(&self) {
        self.signal("-INT");
    }

    pub fn signal(&self, sig: &str) {
        let st = Command::new("kill")
            .args([sig, &self.child.id().to_string()])
            .status()
            .unwrap();
        assert!(st.success());
    }

    /// Sends SIGKILL and reaps the child.
    pub fn kill(mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }

    /// Waits for the exit: exit code, stdout, and every stderr line.
    pub fn finish(mut self) -> (Option<i32>, String, String) {
        let code = self.child.wait().unwrap().code();
        let out = self
            .stdout
            .take()
            .map(|h| h.join().unwrap_or_default())
            .unwrap_or_default();
        while let Ok(l) = self.lines.recv_timeout(Duration::from_millis(200)) {
            self.seen.push(l);
        }
        (code, out, self.seen.join("\n"))
    }
}

impl Drop for Running {
    fn drop(&mut self) {
        if let Ok(None) = self.child.try_wait() {
            let _ = self.child.kill();
            let _ = self.child.wait();
        }
    }
}

/// The obsw's lab flag for the bare-packet link, unless `args` choose the frame link.
pub fn lab_unless_frames(args: &[&str]) -> &'static [&'static str] {
    if args.contains(&"--frame-udp") {
        &[]
    } else {
        &["--lab-bare-packets"]
    }
}
