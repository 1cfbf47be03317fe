//! `ground demo`: starts one `obsw` per robot of the demo plan (with its simulator, at
//! a high `--speed`), runs the plan with the live display, prints the summary and the
//! archive path, and stops the OBSWs.
//!
//! By default over the space link (TC/TM frames, COP-1, SDLS): the demo makes random
//! test keys for each robot in its temporary folder (removed at the end) and says so.
//! `--lab-udp` and `--lab-tcp` use the bare-packet lab links instead.

use std::io::BufRead;
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::Duration;

use anyhow::{anyhow, Context, Result};
use clap::Args;
use ground::link::{BoundSocket, FrameOptions, Transport};
use ground::ops::{self, RunOptions};
use ground::plan;

/// The shipped demo plan (`plans/demo.toml`).
pub const DEMO_PLAN: &str = include_str!("../../plans/demo.toml");

#[derive(Args, Debug)]
pub struct DemoArgs {
    /// The obsw binary [default: next to this executable, then $OBSW_BIN, then PATH].
    #[arg(long)]
    obsw: Option<PathBuf>,
    /// Simulated seconds per wall-clock second.
    #[arg(long, default_value_t = 20.0)]
    speed: f64,
    /// Seed of the simulators (robot N uses seed + N).
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Run another plan instead of the shipped demo.
    #[arg(long)]
    plan: Option<PathBuf>,
    /// Lab mode: bare space packets over TCP instead of the frame link.
    #[arg(long, conflicts_with = "lab_udp")]
    lab_tcp: bool,
    /// Lab mode: bare space packets over UDP instead of the frame link.
    #[arg(long)]
    lab_udp: bool,
    /// Plain log lines instead of the live display.
    #[arg(long)]
    plain: bool,
}

/// A temporary directory removed (with its content) when dropped.
pub struct TempDir(pub PathBuf);

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// Running OBSW processes, stopped on drop.
pub struct Obsws(pub Vec<(u8, Child)>);

impl Drop for Obsws {
    fn drop(&mut self) {
        for (_, c) in &mut self.0 {
            let _ = c.kill();
            let _ = c.wait();
        }
    }
}

/// Finds the obsw binary: `--obsw`, then next to the running executable, then
/// `$OBSW_BIN`, then `obsw` on the PATH.
pub fn find_obsw(given: Option<&Path>) -> Result<PathBuf> {
    if let Some(p) = given {
        return Ok(p.to_path_buf());
    }
    let exe_name = format!("obsw{}", std::env::consts::EXE_SUFFIX);
    if let Ok(me) = std::env::current_exe() {
        if let Some(dir) = me.parent() {
            for d in [Some(dir), dir.parent()].into_iter().flatten() {
                let p = d.join(&exe_name);
                if p.is_file() {
                    return Ok(p);
                }
            }
        }
    }
    if let Some(p) = std::env::var_os("OBSW_BIN") {
        return Ok(PathBuf::from(p));
    }
    if let Some(paths) = std::env::var_os("PATH") {
        for d in std::env::split_paths(&paths) {
            let p = d.join(&exe_name);
            if p.is_file() {
                return Ok(p);
            }
        }
    }
    Err(crate::exit::coded(
        crate::exit::ERROR,
        "cannot find the obsw binary: build it (`cargo build --release`) or give --obsw PATH",
    ))
}

/// How the ground talks to a demo obsw.
enum ObswLink {
    Frames(ObswFrames),
    /// Bare packets over UDP (`--lab-udp`).
    LabUdp,
    /// Bare packets over TCP (`--lab-tcp`).
    LabTcp,
}

/// The frame endpoint of a demo obsw.
struct ObswFrames {
    /// The robot's key directory (`KEYS/robot-N`).
    keys: PathBuf,
    /// The ground's TM frame address (`--frame-tm-to`).
    tm_to: SocketAddr,
    /// The obsw's SDLS counter file.
    state: PathBuf,
}

/// The address the ground talks to in an obsw's READY line: `frame_udp=` over the space
/// link, else `udp=` or `tcp=` of the lab link.
fn ready_addr(line: &str, link: &ObswLink) -> Option<SocketAddr> {
    let key = match link {
        ObswLink::Frames(_) => "frame_udp=",
        ObswLink::LabUdp => "udp=",
        ObswLink::LabTcp => "tcp=",
    };
    line.split_whitespace()
        .find_map(|w| w.strip_prefix(key))
        .and_then(|a| a.parse().ok())
}

/// Starts one obsw for `robot` and waits for its READY line. Every port the obsw opens is
/// its own choice (port 0), read back from READY — none probed here and bound later by the
/// obsw, which another process may take in between. Returns the address the ground talks
/// to ([`ready_addr`]).
fn start_obsw(
    bin: &Path,
    robot: u8,
    speed: f64,
    seed: u64,
    initial_state: Option<u8>,
    log: &Path,
    link: &ObswLink,
) -> Result<(Child, SocketAddr)> {
    let any = "127.0.0.1:0";
    let mut cmd = Command::new(bin);
    cmd.arg("--robot")
        .arg(robot.to_string())
        .arg("--udp")
        .arg(any)
        .arg("--tcp")
        .arg(any)
        .arg("--sim-ctl")
        .arg(any)
        .arg("--speed")
        .arg(speed.to_string())
        .arg("--seed")
        .arg(seed.to_string());
    if let Some(s) = initial_state {
        cmd.arg("--initial-state").arg(s.to_string());
    }
    match link {
        ObswLink::Frames(f) => {
            cmd.arg("--frame-udp")
                .arg(any)
                .arg("--frame-tm-to")
                .arg(f.tm_to.to_string())
                .arg("--tc-key")
                .arg(ground::keys::tc_key_path(&f.keys))
                .arg("--tm-key")
                .arg(ground::keys::tm_key_path(&f.keys))
                .arg("--link-state")
                .arg(&f.state);
        }
        ObswLink::LabUdp | ObswLink::LabTcp => {
            cmd.arg("--lab-bare-packets");
        }
    }
    let errlog = std::fs::File::create(log).with_context(|| format!("creating {}", log.display()))?;
    let mut child = cmd
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::from(errlog))
        .spawn()
        .with_context(|| format!("starting {}", bin.display()))?;
    let stdout = child.stdout.take().ok_or_else(|| anyhow!("no stdout"))?;
    let (tx, rx) = crossbeam_channel::bounded(1);
    std::thread::spawn(move || {
        let mut sent = false;
        for line in std::io::BufReader::new(stdout).lines() {
            let Ok(line) = line else { break };
            if !sent && line.starts_with("READY") {
                let _ = tx.send(line);
                sent = true;
            }
        }
    });
    let fail = |child: &mut Child, why: String| {
        let _ = child.kill();
        let _ = child.wait();
        anyhow!("obsw for robot {robot} did not start: {why}")
    };
    match rx.recv_timeout(Duration::from_secs(10)) {
        Ok(line) => match ready_addr(&line, link) {
            Some(addr) => Ok((child, addr)),
            None => Err(fail(&mut child, format!("no address in its READY line: {line}"))),
        },
        Err(_) => {
            let err = std::fs::read_to_string(log).unwrap_or_default();
            Err(fail(&mut child, err.lines().last().unwrap_or("no output").to_string()))
        }
    }
}

pub fn demo(a: &DemoArgs, archive_path: Option<&Path>) -> Result<u8> {
    let (name, src) = match &a.plan {
        Some(p) => (
            p.display().to_string(),
            std::fs::read_to_string(p).with_context(|| format!("cannot read {}", p.display()))?,
        ),
        None => ("plans/demo.toml".to_string(), DEMO_PLAN.to_string()),
    };
    let pl = plan::parse(&src).map_err(|errs| {
        let d = plan::diagnostics(&name, &src, &errs);
        let lines: Vec<String> = d.iter().map(|x| x.to_string()).collect();
        crate::exit::coded(crate::exit::INVALID, lines.join("\n"))
    })?;
    crate::verb_run::plan_policy(&name, &pl)?;
    let bin = find_obsw(a.obsw.as_deref())?;
    // The OBSWs' logs live as long as the demo (their last line is shown if one does not
    // start); nothing is left behind.
    let logdir = TempDir(std::env::temp_dir().join(format!("ground-demo-{}", std::process::id())));
    std::fs::create_dir_all(&logdir.0)?;
    let logdir = &logdir.0;
    crate::output::err_line!(
        "demo: plan \"{}\" ({} steps, robots {}); starting {} OBSW(s) from {} at speed x{}",
        pl.name,
        pl.steps.len(),
        pl.robots
            .iter()
            .map(|r| r.number.to_string())
            .collect::<Vec<_>>()
            .join(", "),
        pl.robots.len(),
        bin.display(),
        a.speed
    );
    let transport = if a.lab_tcp {
        Transport::Tcp
    } else if a.lab_udp {
        Transport::Udp
    } else {
        Transport::Frames
    };
    let mut frames = (transport == Transport::Frames).then(|| FrameOptions::new(logdir.join("TEST-KEYS-demo-only")));
    if let Some(f) = &mut frames {
        for r in &pl.robots {
            ground::keys::create_robot_keys(&f.keys, r.number).map_err(|e| anyhow!("demo test keys: {e}"))?;
            // Bound now, handed to the session: the port stays taken from here on.
            let sock = BoundSocket::bind(([127, 0, 0, 1], 0).into()).context("binding a TM frame socket")?;
            f.tm_sockets.insert(r.number, sock);
        }
        crate::output::err_line!(
            "demo: space link (TC/TM frames, COP-1, SDLS AES-256-GCM) with TEST KEYS made for this demo only in {} (random, deleted at the end)",
            f.keys.display()
        );
    }
    let mut procs = Obsws(Vec::new());
    let mut links = Vec::new();
    for r in &pl.robots {
        let log = logdir.join(format!("obsw-{}.log", r.number));
        // `frames` is there exactly when the transport is the space link.
        let link = match (&frames, transport) {
            (Some(f), _) => ObswLink::Frames(ObswFrames {
                keys: ground::keys::robot_dir(&f.keys, r.number),
                tm_to: f.listen(r.number, ([127, 0, 0, 1], 0).into()),
                state: logdir.join(format!("obsw-{}-link.state", r.number)),
            }),
            (None, Transport::Tcp) => ObswLink::LabTcp,
            (None, Transport::Udp | Transport::Frames) => ObswLink::LabUdp,
        };
        let (child, addr) = start_obsw(
            &bin,
            r.number,
            a.speed,
            a.seed + r.number as u64,
            r.initial_state,
            &log,
            &link,
        )?;
        crate::output::err_line!(
            "demo: robot {} OBSW, {} at {addr}",
            r.number,
            match link {
                ObswLink::Frames(_) => "frame port",
                ObswLink::LabUdp | ObswLink::LabTcp => "bare-packet port",
            }
        );
        procs.0.push((r.number, child));
        links.push((r.number, addr));
    }
    let (mut session, arch) = crate::links::open_session(&links, transport, frames.as_ref(), archive_path)?;
    session.run_id = Some(ops::runs::new_run_id());
    let opts = RunOptions {
        display: !a.plain && std::io::IsTerminal::is_terminal(&std::io::stderr()),
        stop: Some(crate::verb_run::interrupt_flag()),
        // The demo booted the robots: their TM is complete from their first packet.
        tm_from_boot: true,
        ..RunOptions::default()
    };
    let summary = ops::run_plan(&pl, &mut session, &opts, &ops::Resume::default());
    drop(session);
    drop(procs);
    let stats = match arch {
        Some(a) => Some(a.close().context("closing the archive")?),
        None => None,
    };
    crate::output::out(summary.text().trim_end())?;
    match (archive_path, stats) {
        (Some(p), Some(st)) => crate::output::out(&format!(
            "archive: {} ({} TC, {} TM, {} events, {} verification reports)",
            std::fs::canonicalize(p).unwrap_or_else(|_| p.to_path_buf()).display(),
            st.tc,
            st.tm,
            st.events,
            st.verification
        ))?,
        _ => crate::output::out("archive: disabled (--no-archive)")?,
    }
    Ok(if summary.interrupted {
        crate::exit::INTERRUPTED
    } else if summary.success() {
        crate::exit::OK
    } else {
        crate::exit::FAILED
    })
}
