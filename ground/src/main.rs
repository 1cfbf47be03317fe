//! `ground`: the MMIC-I operators' tool. See `docs/operator-guide.md`.
//!
//! Exit codes (the table in docs/operator-guide.md): 0 success; 1 error (I/O, archive,
//! internal); 2 command-line usage; 3 invalid input or refused before sending (plan, TC
//! name or arguments, an unconfirmed hazardous TC, corrupt packets with
//! `decode --strict`); 4 a TC or plan step failed, was refused or timed out; 5 a robot
//! heard, then lost (link lost; also: no simulator answering); 6 a run interrupted by the
//! operator; 7 replies from another APID (wrong robot at the address); 8 nothing heard
//! from a robot; 130 a second Ctrl-C.

use std::io::Write;
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{Context, Result};
use clap::{Args, Parser, Subcommand};
use ground::archive::{self, Archive};
use ground::collect::parse_robot_arg;
use ground::link::{FrameOptions, Transport};
use ground::link_choice::{LinkChoice, KEYS_ENV};
use ground::ops::Session;

mod demo;
mod plot;
mod verb_archive;
mod verb_collect;
mod verb_decode;
mod verb_keys;
mod verb_live;
mod verb_mib;
mod verb_model;
mod verb_plan;
mod verb_run;
mod verb_sim;

use verb_archive::{archive_cmd, ArchiveCmd};
use verb_decode::{decode, DecodeArgs};
use verb_live::{mode, ping, send, watch, ModeArgs, PingArgs, SendArgs, WatchArgs};
use verb_mib::{mib_export, MibCmd};
use verb_model::{model, ModelArgs};
use verb_plan::{plan_check, plan_encode, PlanCmd};
pub(crate) use verb_run::{interrupt_flag, plan_policy, unconfirmed};
use verb_run::{run_plan, RunArgs};
use verb_sim::{sim, SimArgs};

/// Exit codes (documented in the operator guide).
pub mod exit {
    pub const OK: u8 = 0;
    pub const ERROR: u8 = 1;
    pub const USAGE: u8 = 2;
    pub const INVALID: u8 = 3;
    pub const FAILED: u8 = 4;
    /// A robot heard, then lost (also: no simulator answering); see
    /// `ground::ops::NoAnswer` for 5, 7 and 8.
    pub const NO_ANSWER: u8 = 5;
    /// `ground run` interrupted by Ctrl-C or SIGTERM: summary printed, `--resume` continues.
    pub const INTERRUPTED: u8 = 6;
    /// A second Ctrl-C: exit at once.
    pub const INTERRUPTED_AGAIN: i32 = 130;
}

/// An error with its exit code.
#[derive(Debug)]
pub struct Coded(pub u8, pub String);
impl std::fmt::Display for Coded {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.1)
    }
}
impl std::error::Error for Coded {}

pub fn coded(code: u8, msg: impl Into<String>) -> anyhow::Error {
    anyhow::Error::new(Coded(code, msg.into()))
}

#[derive(Parser, Debug)]
#[command(name = "ground", version, about = "MMIC-I ground tool: plans, live operations, TM decode and archive", long_about = None)]
struct Cli {
    /// Archive written by run, send, ping, mode, watch and demo: an SQLite file, or a
    /// PostgreSQL server as `postgresql://USER@HOST/DB` (see docs/archive.md).
    #[arg(long, global = true, default_value = "ground-archive.db")]
    archive: PathBuf,
    /// Do not write the archive.
    #[arg(long, global = true)]
    no_archive: bool,
    #[command(subcommand)]
    cmd: Cmd,
}

#[derive(Subcommand, Debug)]
enum Cmd {
    /// Check or encode plan files.
    #[command(subcommand)]
    Plan(PlanCmd),
    /// Decode a file of TC and/or TM space packets.
    Decode(DecodeArgs),
    /// Execute a plan against running OBSWs.
    Run(RunArgs),
    /// Connection test (TC[17,1]) to each robot.
    Ping(PingArgs),
    /// Send one TC by its MIB name, e.g. `ground send --robot 1 RECONFIGURE from=0 to=4`.
    Send(SendArgs),
    /// Command a robot's mode (standby, operational, safed).
    Mode(ModeArgs),
    /// Show live decoded TM and events.
    Watch(WatchArgs),
    /// Send a fault-injection line to a simulator's control port.
    Sim(SimArgs),
    /// Query, export or plot the archive.
    #[command(subcommand)]
    Archive(ArchiveCmd),
    /// Export the MIB for other ground systems.
    #[command(subcommand)]
    Mib(MibCmd),
    /// Write a robot's URDF from its module report (live) or a module-set file.
    Model(ModelArgs),
    /// Start two simulated robots, run the demo plan and summarise.
    Demo(demo::DemoArgs),
    /// Follow robots unattended: archive everything, fill gaps, raise alarms.
    Collect(verb_collect::CollectArgs),
    /// List, acknowledge or shelve the collector's alarms.
    #[command(subcommand)]
    Alarms(verb_collect::AlarmsCmd),
    /// Create or show the space link's key files (never prints a key).
    #[command(subcommand)]
    Keys(verb_keys::KeysCmd),
}

/// Robot links: `N=HOST:PORT`, or `N` for 127.0.0.1:(7300+N), over the space link unless
/// a lab flag says otherwise ([`ground::link_choice`]).
#[derive(Args, Debug, Clone)]
struct Links {
    /// Robot link `N=HOST:PORT`: the robot's space-link port (obsw --frame-udp), or with a
    /// lab flag its --udp/--tcp port. Just `N`: 127.0.0.1:7500+N (the obsw's default
    /// --frame-udp), with a lab flag 127.0.0.1:7300+N. Repeat per robot. Required by
    /// ping, send, mode and watch; `run` adds the plan's robots.
    #[arg(long = "robot", short = 'r', value_parser = parse_robot_arg)]
    robots: Vec<(u8, Option<SocketAddr>)>,
    #[command(flatten)]
    link: LinkFlags,
}

/// The link flags shared by every verb that talks to robots ([`LinkChoice`]).
#[derive(Args, Debug, Clone)]
pub(crate) struct LinkFlags {
    /// Key directory of the space link (`ground keys create DIR`): robot N uses
    /// DIR/robot-N/. Needed unless a lab link is chosen.
    #[arg(long, value_name = "DIR", env = KEYS_ENV)]
    keys: Option<PathBuf>,
    /// Local address robot N's TM frames arrive at, `N=HOST:PORT` (the obsw's
    /// --frame-tm-to); default 127.0.0.1:7600+N (0.0.0.0 for a remote robot). Repeat per robot.
    #[arg(long = "tm-listen", value_parser = ground::collect::parse_robot, value_name = "N=HOST:PORT")]
    tm_listen: Vec<(u8, SocketAddr)>,
    /// The space link's TC SPI: 1, or 2 after a key change (`LINK_SPI_SELECT`; the
    /// key folder holds both keys).
    #[arg(long, value_name = "1|2", default_value_t = mib::link::sdls::TC_SPIS[0], value_parser = parse_tc_spi)]
    spi: u16,
    /// SDLS on the robot's TM frames, as its `--tm-sdls`: encrypt (the default) or clear.
    #[arg(long, value_name = "encrypt|clear", default_value = "encrypt", value_parser = parse_tm_sdls)]
    tm_sdls: ground_link::TmSecurity,
    /// Lab mode: bare (unauthenticated) space packets, one per UDP datagram, instead of
    /// the space link; robots on loopback addresses only (obsw --lab-bare-packets).
    #[arg(long, conflicts_with = "lab_tcp")]
    lab_udp: bool,
    /// Lab mode: bare (unauthenticated) space packets over TCP with COBS framing;
    /// robots on loopback addresses only (obsw --lab-bare-packets).
    #[arg(long)]
    lab_tcp: bool,
    /// The space link over a serial device (raw mode; board A's USB ground link, e.g.
    /// /dev/ttyACM0) or a Unix socket (QEMU -serial unix:), one COBS frame per transfer
    /// frame, instead of UDP: `N=PATH`, or `PATH` with one robot. Repeat per robot.
    #[arg(long, value_name = "[N=]PATH", value_parser = ground_ops::link_choice::parse_serial)]
    serial: Vec<(Option<u8>, PathBuf)>,
}

fn parse_tc_spi(s: &str) -> Result<u16, String> {
    let spis = mib::link::sdls::TC_SPIS;
    s.parse()
        .ok()
        .filter(|n| spis.contains(n))
        .ok_or_else(|| format!("\"{s}\": the TC SPIs are {spis:?}"))
}

fn parse_tm_sdls(s: &str) -> Result<ground_link::TmSecurity, String> {
    ground_link::TmSecurity::from_name(s).ok_or_else(|| format!("\"{s}\": encrypt or clear"))
}

impl LinkFlags {
    /// The library's link choice these flags make.
    pub(crate) fn choice(&self) -> LinkChoice {
        LinkChoice {
            keys: self.keys.clone(),
            tm_listen: self.tm_listen.clone(),
            spi: self.spi,
            tm_sdls: self.tm_sdls,
            serial: self.serial.clone(),
            lab_udp: self.lab_udp,
            lab_tcp: self.lab_tcp,
        }
    }

    /// Robot `n`'s address when `--robot N` gives none ([`LinkChoice::default_addr`]).
    pub(crate) fn default_addr(&self, n: u8) -> SocketAddr {
        self.choice().default_addr(n)
    }
}

impl Links {
    /// The robots given with `--robot`, at their default addresses (for the link chosen)
    /// where none is given.
    fn addresses(&self) -> Vec<(u8, SocketAddr)> {
        self.robots
            .iter()
            .map(|&(n, addr)| (n, addr.unwrap_or_else(|| self.link.default_addr(n))))
            .collect()
    }

    /// The transport and frame options for these robots (usage errors exit 2).
    fn choice(&self, robots: &[(u8, SocketAddr)]) -> Result<(Transport, Option<FrameOptions>)> {
        self.link
            .choice()
            .resolve(robots)
            .map_err(|e| coded(exit::USAGE, e.to_string()))
    }

    /// Says which robots the verb talks to and how, then opens the archive (if wanted)
    /// and a session to them.
    fn open(&self, robots: &[(u8, SocketAddr)], archive_path: Option<&Path>) -> Result<(Session, Option<Archive>)> {
        let (transport, frames) = self.choice(robots)?;
        verb_live::say_links(robots, transport, frames.as_ref());
        open_session(robots, transport, frames.as_ref(), archive_path)
    }
}

fn main() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(c) => c,
        Err(e) => {
            let _ = e.print();
            return ExitCode::from(if e.use_stderr() { 2 } else { 0 });
        }
    };
    match run(cli) {
        Ok(code) => ExitCode::from(code),
        Err(e) => {
            if is_broken_pipe(&e) {
                return ExitCode::from(exit::OK);
            }
            let code = e.downcast_ref::<Coded>().map_or(exit::ERROR, |c| c.0);
            err_line!("ground: error: {e:#}");
            ExitCode::from(code)
        }
    }
}

fn is_broken_pipe(e: &anyhow::Error) -> bool {
    e.chain().any(|c| {
        c.downcast_ref::<std::io::Error>()
            .is_some_and(|io| io.kind() == std::io::ErrorKind::BrokenPipe)
    })
}

/// Writes a line to standard error, ignoring a closed stderr (no panic, unlike
/// `eprintln!`).
#[macro_export]
macro_rules! err_line {
    ($($t:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stderr().lock(), $($t)*);
    }};
}

/// Writes a line to standard output; a closed pipe surfaces as an error that `main`
/// turns into a quiet exit.
pub fn out(line: &str) -> Result<()> {
    let mut o = std::io::stdout().lock();
    o.write_all(line.as_bytes())?;
    o.write_all(b"\n")?;
    Ok(())
}

fn run(cli: Cli) -> Result<u8> {
    let archive_path = (!cli.no_archive).then(|| cli.archive.clone());
    match cli.cmd {
        Cmd::Plan(PlanCmd::Check { plans, json }) => plan_check(&plans, json),
        Cmd::Plan(PlanCmd::Encode { plan, out: dir }) => plan_encode(&plan, &dir),
        Cmd::Decode(a) => decode(&a),
        Cmd::Run(a) => run_plan(&a, archive_path.as_deref()),
        Cmd::Ping(a) => ping(&a, archive_path.as_deref()),
        Cmd::Send(a) => send(&a, archive_path.as_deref()),
        Cmd::Mode(a) => mode(&a, archive_path.as_deref()),
        Cmd::Watch(a) => watch(&a, archive_path.as_deref()),
        Cmd::Sim(a) => sim(&a),
        Cmd::Archive(a) => archive_cmd(a, &cli.archive),
        Cmd::Mib(MibCmd::Export { format, out: dir }) => mib_export(&format, &dir),
        Cmd::Model(a) => model(&a, archive_path.as_deref()),
        Cmd::Demo(a) => demo::demo(&a, archive_path.as_deref()),
        Cmd::Collect(a) => verb_collect::collect(&cli.archive, a),
        Cmd::Alarms(a) => verb_collect::alarms(&cli.archive, a),
        Cmd::Keys(a) => verb_keys::keys(&a),
    }
}

/// Opens the archive (if wanted) and a session to the given robots.
pub fn open_session(
    links: &[(u8, SocketAddr)],
    transport: Transport,
    frames: Option<&FrameOptions>,
    archive_path: Option<&Path>,
) -> Result<(Session, Option<Archive>)> {
    if links.is_empty() {
        return Err(coded(exit::INVALID, "no robot given (use --robot N=HOST:PORT)"));
    }
    let archive = archive_path
        .map(|p| Archive::open(p).with_context(|| format!("opening archive {}", p.display())))
        .transpose()?;
    let path = archive_path.map(Path::to_path_buf);
    let session = Session::connect_with(links, transport, frames, archive.as_ref().map(|a| a.sender()), |apid| {
        Some(ground::ops::first_tc_seq(
            path.as_deref().and_then(|p| archive::next_seq(p, apid)),
        ))
    })
    .map_err(|e| match &e {
        // Another ground process commands the robot (ground::robot_lock): refused.
        ground::ops::OpsError::Connect { err, .. } if err.kind() == std::io::ErrorKind::AddrInUse => {
            coded(exit::INVALID, e.to_string())
        }
        _ => coded(exit::NO_ANSWER, e.to_string()),
    })?;
    Ok((session, archive))
}

fn close_archive(a: Option<Archive>) -> Result<()> {
    if let Some(a) = a {
        a.close().context("closing the archive")?;
    }
    Ok(())
}
