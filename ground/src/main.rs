//! `ground`: the MMIC-I operators' tool. See `docs/operator-guide.md`.
//!
//! Exit codes: 0 success; 1 error (I/O, archive, internal); 2 command-line usage;
//! 3 invalid input (plan, TC name or arguments, corrupt packets with `decode --strict`);
//! 4 a TC or plan step failed or was refused; 5 no answer from a robot.

use std::io::Write;
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::{Duration, Instant};

use anyhow::{anyhow, Context, Result};
use clap::{Args, Parser, Subcommand};
use ground::archive::{self, Archive, Filter, Kind};
use ground::collect::config::default_addr;
use ground::collect::parse_robot;
use ground::link::Transport;
use ground::ops::{self, RunOptions, Session, Update};
use ground::plan;
use ground::pus::{self, Packet, Stage, TmBody};

mod demo;
mod plot;

/// Exit codes (documented in the operator guide).
pub mod exit {
    pub const OK: u8 = 0;
    pub const ERROR: u8 = 1;
    pub const INVALID: u8 = 3;
    pub const FAILED: u8 = 4;
    pub const NO_ANSWER: u8 = 5;
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
    /// Start two simulated robots, run the demo plan and summarise.
    Demo(demo::DemoArgs),
    /// Follow robots unattended: archive everything, fill gaps, raise alarms.
    Collect(ground::collect::CollectArgs),
    /// List, acknowledge or shelve the collector's alarms.
    #[command(subcommand)]
    Alarms(ground::collect::AlarmsCmd),
}

#[derive(Subcommand, Debug)]
enum PlanCmd {
    /// Validate plans against the MIB; every error with file:line:column.
    Check {
        #[arg(required = true)]
        plans: Vec<PathBuf>,
        /// Print the parsed plan (or the errors) as JSON.
        #[arg(long)]
        json: bool,
    },
    /// Write the TC stream per robot (one raw file per APID) and a listing.
    Encode {
        plan: PathBuf,
        #[arg(long)]
        out: PathBuf,
    },
}

#[derive(Args, Debug)]
struct DecodeArgs {
    /// File of concatenated space packets ("-" for standard input).
    file: PathBuf,
    /// One JSON object per line.
    #[arg(long)]
    json: bool,
    /// Only decode and count (no per-packet output).
    #[arg(long)]
    summary: bool,
    /// Exit with code 3 if any corrupt bytes were found.
    #[arg(long)]
    strict: bool,
}

/// Robot links: `N=HOST:PORT`, or `N` for 127.0.0.1:(7300+N).
#[derive(Args, Debug, Clone)]
struct Links {
    /// Robot link `N=HOST:PORT` (or just `N` for 127.0.0.1:7300+N, robot 1 = 7301); repeat per robot.
    #[arg(long = "robot", short = 'r', value_parser = parse_robot)]
    robots: Vec<(u8, SocketAddr)>,
    /// Use TCP (COBS framing) instead of UDP.
    #[arg(long)]
    tcp: bool,
}

impl Links {
    fn transport(&self) -> Transport {
        if self.tcp {
            Transport::Tcp
        } else {
            Transport::Udp
        }
    }
}

#[derive(Args, Debug)]
struct RunArgs {
    plan: PathBuf,
    #[command(flatten)]
    links: Links,
    /// Longest a step may take (seconds) unless the step sets `timeout`.
    #[arg(long, default_value_t = 120.0)]
    step_timeout: f64,
    /// No heartbeat connection tests (and so no link-loss watch).
    #[arg(long)]
    no_ping: bool,
    /// Plain log lines instead of the live display.
    #[arg(long)]
    plain: bool,
    /// Print the summary as JSON.
    #[arg(long)]
    json: bool,
    /// Continue an interrupted run: steps whose TC the archive shows completed are not
    /// sent again.
    #[arg(long)]
    resume: bool,
}

#[derive(Args, Debug)]
struct PingArgs {
    #[command(flatten)]
    links: Links,
    /// Pings per robot.
    #[arg(long, short = 'c', default_value_t = 3)]
    count: u32,
    /// Pause between pings (seconds).
    #[arg(long, default_value_t = 0.2)]
    interval: f64,
}

#[derive(Args, Debug)]
struct SendArgs {
    #[command(flatten)]
    links: Links,
    /// TC name from the MIB (e.g. RECONFIGURE, HK_SET_INTERVAL, PING).
    tc: String,
    /// Arguments as NAME=VALUE (state names allowed for from/to).
    args: Vec<String>,
    /// Do not wait for completion.
    #[arg(long)]
    no_wait: bool,
    /// Longest wait for completion (seconds).
    #[arg(long, default_value_t = 60.0)]
    timeout: f64,
}

#[derive(Args, Debug)]
struct ModeArgs {
    #[command(flatten)]
    links: Links,
    /// standby, operational or safed.
    mode: String,
    #[arg(long, default_value_t = 60.0)]
    timeout: f64,
}

#[derive(Args, Debug)]
struct WatchArgs {
    #[command(flatten)]
    links: Links,
    /// One JSON object per packet.
    #[arg(long)]
    json: bool,
    /// Hide housekeeping reports.
    #[arg(long)]
    no_hk: bool,
    /// Stop after this many seconds.
    #[arg(long)]
    duration: Option<f64>,
    /// Stop after this many packets.
    #[arg(long)]
    count: Option<u64>,
}

#[derive(Args, Debug)]
struct SimArgs {
    /// Robot number (control port 127.0.0.1:7400+N unless --addr).
    #[arg(long, short = 'r', default_value_t = mib::apid::DEFAULT_ROBOT)]
    robot: u8,
    /// Simulator control address.
    #[arg(long)]
    addr: Option<SocketAddr>,
    /// The command, e.g. `stuck-arm a`, `battery-sag 9.5`, `clear`.
    #[arg(required = true, num_args = 1..)]
    line: Vec<String>,
}

#[derive(Args, Debug, Clone)]
struct FilterArgs {
    #[arg(long)]
    robot: Option<u8>,
    /// From this time (RFC 3339, "YYYY-MM-DD HH:MM:SS" UTC, Unix ms, or relative like -10m).
    #[arg(long)]
    since: Option<String>,
    /// Until this time (same forms as --since).
    #[arg(long)]
    until: Option<String>,
    /// PUS service (TC and TM).
    #[arg(long)]
    service: Option<u8>,
    /// Lowest event severity: info, low, medium, high.
    #[arg(long)]
    severity: Option<String>,
    /// HK parameter name (repeatable).
    #[arg(long = "param")]
    params: Vec<String>,
    #[arg(long)]
    limit: Option<u64>,
}

impl FilterArgs {
    fn filter(&self) -> Result<Filter> {
        let min_level = match &self.severity {
            None => None,
            Some(s) => Some(
                [
                    mib::events::Severity::Info,
                    mib::events::Severity::Low,
                    mib::events::Severity::Medium,
                    mib::events::Severity::High,
                ]
                .into_iter()
                .find(|v| v.name().eq_ignore_ascii_case(s))
                .ok_or_else(|| coded(exit::INVALID, format!("unknown severity \"{s}\"")))?
                .subservice(),
            ),
        };
        for p in &self.params {
            if mib::params::by_name(p).is_none() {
                return Err(coded(exit::INVALID, format!("unknown HK parameter \"{p}\"")));
            }
        }
        Ok(Filter {
            robot: self.robot,
            since_ms: self.since.as_deref().map(parse_time).transpose()?,
            until_ms: self.until.as_deref().map(parse_time).transpose()?,
            service: self.service,
            min_level,
            params: self.params.clone(),
            limit: self.limit,
        })
    }
}

fn parse_time(s: &str) -> Result<i64> {
    let s = s.trim();
    if let Some(rel) = s.strip_prefix('-') {
        let (num, unit) = rel.split_at(rel.find(|c: char| !c.is_ascii_digit()).unwrap_or(rel.len()));
        if let Ok(n) = num.parse::<i64>() {
            let ms = match unit {
                "s" | "" => 1000,
                "m" => 60_000,
                "h" => 3_600_000,
                "d" => 86_400_000,
                _ => return Err(coded(exit::INVALID, format!("bad time unit in \"{s}\""))),
            };
            return Ok(archive::now_ms() - n * ms);
        }
    }
    if let Ok(ms) = s.parse::<i64>() {
        return Ok(ms);
    }
    if let Ok(t) = chrono::DateTime::parse_from_rfc3339(s) {
        return Ok(t.timestamp_millis());
    }
    for f in ["%Y-%m-%d %H:%M:%S", "%Y-%m-%dT%H:%M:%S", "%Y-%m-%d %H:%M"] {
        if let Ok(t) = chrono::NaiveDateTime::parse_from_str(s, f) {
            return Ok(t.and_utc().timestamp_millis());
        }
    }
    Err(coded(exit::INVALID, format!("cannot read time \"{s}\"")))
}

#[derive(Subcommand, Debug)]
enum ArchiveCmd {
    /// Print archived records.
    Query {
        /// What to list.
        #[arg(long = "type", value_enum, default_value = "tm")]
        kind: Kind,
        #[command(flatten)]
        filter: FilterArgs,
        #[arg(long)]
        json: bool,
    },
    /// Export archived records as CSV.
    Export {
        /// CSV output (the only format).
        #[arg(long, required = true)]
        csv: bool,
        #[arg(long = "type", value_enum, default_value = "hk")]
        kind: Kind,
        #[command(flatten)]
        filter: FilterArgs,
        /// Output file (default: standard output).
        #[arg(long)]
        out: Option<PathBuf>,
    },
    /// Plot HK parameters over time (SVG or PNG by the file extension).
    Plot {
        #[arg(required = true)]
        params: Vec<String>,
        #[arg(long)]
        out: PathBuf,
        #[arg(long)]
        robot: Option<u8>,
        #[arg(long)]
        since: Option<String>,
        #[arg(long)]
        until: Option<String>,
    },
    /// Import a raw packet stream (a capture, a store dump); packets already archived
    /// are counted and not stored again.
    Import {
        file: PathBuf,
        /// Robot whose link the stream came from.
        #[arg(long)]
        robot: u8,
        #[arg(long)]
        json: bool,
    },
    /// Verify every stored packet's CRC and the parameter chunks; list holes.
    Check {
        #[arg(long)]
        robot: Option<u8>,
        #[arg(long)]
        json: bool,
    },
    /// Remaining holes per robot and APID, with why.
    Gaps {
        #[arg(long)]
        robot: Option<u8>,
        #[arg(long)]
        json: bool,
    },
    /// Last archived position per robot/APID, when each robot was last heard, size.
    Status {
        #[arg(long)]
        robot: Option<u8>,
        #[arg(long)]
        json: bool,
    },
    /// The newest value of every HK parameter.
    Latest {
        #[arg(long)]
        robot: Option<u8>,
        #[arg(long)]
        json: bool,
    },
}

#[derive(Subcommand, Debug)]
enum MibCmd {
    /// Write SCOS-2000 tables, XTCE or JSON.
    Export {
        /// scos, xtce, json, or yamcs[:ROBOTS] (a Yamcs instance, e.g. yamcs:1-3).
        #[arg(long)]
        format: String,
        #[arg(long)]
        out: PathBuf,
    },
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
        Cmd::Demo(a) => demo::demo(&a, archive_path.as_deref()),
        Cmd::Collect(a) => ground::collect::collect_cli(&cli.archive, a),
        Cmd::Alarms(a) => ground::collect::alarms_cli(&cli.archive, a),
    }
}

fn load_plan(path: &Path) -> Result<plan::Plan> {
    plan::load(path).map_err(|e| match e {
        plan::LoadError::Io(..) => anyhow!(e),
        plan::LoadError::Invalid(_) => coded(exit::INVALID, e.to_string()),
    })
}

fn plan_check(plans: &[PathBuf], json: bool) -> Result<u8> {
    let mut bad = 0;
    for p in plans {
        let bytes = std::fs::read(p).with_context(|| format!("cannot read {}", p.display()))?;
        let src = match String::from_utf8(bytes) {
            Ok(s) => s,
            Err(e) => {
                bad += 1;
                err_line!(
                    "{}: error: not a plan: not UTF-8 text (invalid byte at offset {})",
                    p.display(),
                    e.utf8_error().valid_up_to()
                );
                continue;
            }
        };
        match plan::parse(&src) {
            Ok(pl) => {
                if json {
                    out(&serde_json::to_string_pretty(&pl)?)?;
                } else {
                    let robots: Vec<String> = pl.robots.iter().map(|r| r.number.to_string()).collect();
                    out(&format!(
                        "{}: ok — plan \"{}\", robots {}, {} steps",
                        p.display(),
                        pl.name,
                        robots.join(", "),
                        pl.steps.len()
                    ))?;
                }
            }
            Err(errs) => {
                bad += 1;
                let d = plan::diagnostics(&p.display().to_string(), &src, &errs);
                if json {
                    out(&serde_json::to_string_pretty(&d)?)?;
                } else {
                    for x in &d {
                        err_line!("{x}");
                    }
                    err_line!("{}: {} error(s)", p.display(), d.len());
                }
            }
        }
    }
    Ok(if bad > 0 { exit::INVALID } else { exit::OK })
}

fn plan_encode(path: &Path, dir: &Path) -> Result<u8> {
    let pl = load_plan(path)?;
    let enc = plan::encode(&pl).map_err(|e| coded(exit::INVALID, e.to_string()))?;
    let files = plan::write_encoded(&pl, &enc, dir).with_context(|| format!("writing {}", dir.display()))?;
    for f in files {
        out(&f.display().to_string())?;
    }
    Ok(exit::OK)
}

fn decode(a: &DecodeArgs) -> Result<u8> {
    use ground::pus::out::{Format, RawItem, RawStream, Writer};
    let data = if a.file.as_os_str() == "-" {
        let mut v = Vec::new();
        std::io::Read::read_to_end(&mut std::io::stdin(), &mut v)?;
        v
    } else {
        std::fs::read(&a.file).with_context(|| format!("cannot read {}", a.file.display()))?
    };
    // Counters: packets by type, bodies that do not follow the MIB (undefined kind or
    // wrong structure), corrupt stretches.
    let (mut tc, mut tm, mut bad_body, mut stretches, mut corrupt_bytes) = (0u64, 0u64, 0u64, 0u64, 0u64);
    let t0 = Instant::now();
    let mut o = std::io::stdout().lock();
    let mut w = Writer::new(if a.json { Format::Json } else { Format::Text });
    for item in RawStream::new(&data) {
        match &item {
            RawItem::Tm { offset, packet } => {
                tm += 1;
                if a.summary {
                    bad_body += u64::from(pus::decode_tm(&data[*offset..*offset + packet.primary.len]).is_err());
                } else {
                    bad_body += u64::from(w.tm(*offset, packet).is_err());
                }
            }
            RawItem::Tc { offset, packet } => {
                tc += 1;
                if a.summary {
                    bad_body += u64::from(pus::decode_tc(&data[*offset..*offset + packet.primary.len]).is_err());
                } else {
                    bad_body += u64::from(w.tc(*offset, packet).is_err());
                }
            }
            RawItem::Corrupt { offset, len, reason } => {
                stretches += 1;
                corrupt_bytes += *len as u64;
                if !a.summary {
                    w.corrupt(*offset, *len, reason);
                }
            }
        }
        w.flush_if_full(&mut o)?;
    }
    w.flush(&mut o)?;
    o.flush()?;
    drop(o);
    let secs = t0.elapsed().as_secs_f64();
    let n = tc + tm;
    err_line!(
        "{n} packets ({tc} TC, {tm} TM), {bad_body} with a body not matching the MIB, {stretches} corrupt stretches ({corrupt_bytes} bytes); {:.0} packets/s",
        if secs > 0.0 { n as f64 / secs } else { 0.0 }
    );
    Ok(if a.strict && (corrupt_bytes > 0 || bad_body > 0) {
        exit::INVALID
    } else {
        exit::OK
    })
}

/// Opens the archive (if wanted) and a session to the given robots.
pub fn open_session(
    links: &[(u8, SocketAddr)],
    transport: Transport,
    archive_path: Option<&Path>,
) -> Result<(Session, Option<Archive>)> {
    if links.is_empty() {
        return Err(coded(exit::INVALID, "no robot given (use --robot N=HOST:PORT)"));
    }
    let archive = archive_path
        .map(|p| Archive::open(p).with_context(|| format!("opening archive {}", p.display())))
        .transpose()?;
    let path = archive_path.map(Path::to_path_buf);
    let session = Session::connect(links, transport, archive.as_ref().map(|a| a.sender()), |apid| {
        path.as_deref().and_then(|p| archive::next_seq(p, apid))
    })
    .map_err(|e| coded(exit::NO_ANSWER, e.to_string()))?;
    Ok((session, archive))
}

fn close_archive(a: Option<Archive>) -> Result<()> {
    if let Some(a) = a {
        a.close().context("closing the archive")?;
    }
    Ok(())
}

fn run_plan(a: &RunArgs, archive_path: Option<&Path>) -> Result<u8> {
    let pl = load_plan(&a.plan)?;
    let mut links = a.links.robots.clone();
    for r in &pl.robots {
        if !links.iter().any(|(n, _)| *n == r.number) {
            links.push((r.number, default_addr(r.number)));
        }
    }
    let (mut session, arch) = open_session(&links, a.links.transport(), archive_path)?;
    let opts = RunOptions {
        step_timeout: Duration::from_secs_f64(a.step_timeout),
        ping_period: (!a.no_ping).then(|| Duration::from_millis(mib::config::GROUND_HEARTBEAT_MS as u64)),
        display: !a.plain && std::io::IsTerminal::is_terminal(&std::io::stderr()),
    };
    let done = if a.resume {
        let p = archive_path.ok_or_else(|| coded(exit::INVALID, "--resume needs the archive (drop --no-archive)"))?;
        completed_steps(p, &pl)?
    } else {
        Vec::new()
    };
    let summary = ops::run_plan(&pl, &mut session, &opts, &done);
    drop(session);
    close_archive(arch)?;
    if a.json {
        out(&serde_json::to_string_pretty(&summary)?)?;
    } else {
        out(summary.text().trim_end())?;
        if let Some(p) = archive_path {
            out(&format!("archive: {}", p.display()))?;
        }
    }
    Ok(if !summary.link_lost.is_empty() {
        exit::NO_ANSWER
    } else if summary.success() {
        exit::OK
    } else {
        exit::FAILED
    })
}

/// Steps of `pl` whose TC the archive shows completed (TM[1,7] for its request ID after
/// it was sent), for `run --resume`.
fn completed_steps(path: &Path, pl: &plan::Plan) -> Result<Vec<usize>> {
    let loc = path.to_string_lossy();
    let mut st = match archive::Store::open_existing(&loc) {
        Ok(st) => st,
        Err(archive::ArchiveError::NotFound(_)) => {
            return Err(coded(exit::INVALID, format!("--resume: archive {loc} does not exist")));
        }
        Err(e) => return Err(anyhow!("--resume: {e}")),
    };
    let mut done = Vec::new();
    for (i, s) in pl.steps.iter().enumerate() {
        let Some((def, _)) = s.action.tc() else { continue };
        if st
            .step_completed(&s.id, s.robot, def.name)
            .map_err(|e| anyhow!("--resume: reading the archive: {e}"))?
        {
            done.push(i);
        }
    }
    // A wait step between completed steps is done too.
    for (i, s) in pl.steps.iter().enumerate() {
        if s.action.tc().is_none() && pl.dependents(i).iter().any(|d| done.contains(d)) {
            done.push(i);
        }
    }
    Ok(done)
}

fn ping(a: &PingArgs, archive_path: Option<&Path>) -> Result<u8> {
    let def = mib::tc::by_name("PING").ok_or_else(|| anyhow!("PING not in the MIB"))?;
    let (mut s, arch) = open_session(&a.links.robots, a.links.transport(), archive_path)?;
    let mut lost = 0u32;
    for k in 0..a.count {
        for &(r, addr) in &a.links.robots {
            s.max_resends = 0;
            let tc = s.send(r, def, &[], Some(r as usize), None)?;
            let t0 = Instant::now();
            let mut got = None;
            while t0.elapsed() < s.ack_timeout * 2 && got.is_none() {
                for u in s.poll(Duration::from_millis(50)) {
                    match u {
                        Update::Tm { robot, tm } if robot == r && tm.body == TmBody::PingReply => {
                            got = Some(t0.elapsed());
                        }
                        Update::GaveUp { robot, .. } if robot == r => {}
                        _ => {}
                    }
                }
            }
            s.forget(&tc);
            match got {
                Some(rtt) => out(&format!(
                    "robot {r} ({addr}) seq {}: reply in {:.1} ms",
                    tc.seq,
                    rtt.as_secs_f64() * 1000.0
                ))?,
                None => {
                    lost += 1;
                    out(&format!(
                        "robot {r} ({addr}) seq {}: no reply within {} ms",
                        tc.seq,
                        (s.ack_timeout * 2).as_millis()
                    ))?
                }
            }
        }
        if k + 1 < a.count {
            std::thread::sleep(Duration::from_secs_f64(a.interval));
        }
    }
    for st in s.robots.values() {
        out(&format!("robot {}: {}", st.robot, st.line()))?;
    }
    drop(s);
    close_archive(arch)?;
    Ok(if lost > 0 { exit::NO_ANSWER } else { exit::OK })
}

/// Reads `NAME=VALUE` arguments for `def`, checking them against the MIB.
fn tc_args(def: &'static mib::tc::TcDef, args: &[String]) -> Result<Vec<i64>> {
    let mut vals: Vec<Option<i64>> = vec![None; def.args.len()];
    for a in args {
        let (k, v) = a
            .split_once('=')
            .ok_or_else(|| coded(exit::INVALID, format!("argument \"{a}\" is not NAME=VALUE")))?;
        let idx = def
            .args
            .iter()
            .position(|d| d.name.eq_ignore_ascii_case(k))
            .ok_or_else(|| {
                let names: Vec<&str> = def.args.iter().map(|d| d.name).collect();
                coded(
                    exit::INVALID,
                    format!("{} has no argument \"{k}\" (arguments: {})", def.name, names.join(", ")),
                )
            })?;
        let d = &def.args[idx];
        let v = v.trim();
        let num = if let Ok(n) = v.parse::<i64>() {
            n
        } else if let Some(h) = v.strip_prefix("0x") {
            i64::from_str_radix(h, 16).map_err(|_| coded(exit::INVALID, format!("bad number \"{v}\"")))?
        } else if let Some(n) = d.names.value_of(v) {
            n
        } else if !d.names.is_none() {
            let mut names = Vec::new();
            d.names.for_each(|n, name| {
                if (d.min..=d.max).contains(&n) {
                    names.push(format!("{name} ({n})"));
                }
            });
            let which = match names.split_last() {
                Some((last, rest)) if names.len() <= 8 && !rest.is_empty() => {
                    format!("the {}s are {} and {last}", d.name, rest.join(", "))
                }
                _ => format!(
                    "it is none of the {} names of {} (see docs/ICD.md)",
                    names.len(),
                    d.name
                ),
            };
            return Err(coded(
                exit::INVALID,
                format!("{}: {} = \"{v}\": {which}", def.name, d.name),
            ));
        } else {
            return Err(coded(exit::INVALID, format!("{}: \"{v}\" is not a number", d.name)));
        };
        if num < d.min || num > d.max {
            return Err(coded(
                exit::INVALID,
                format!("{}: {} = {num} outside {}..={}", def.name, d.name, d.min, d.max),
            ));
        }
        vals[idx] = Some(num);
    }
    vals.iter()
        .zip(def.args)
        .map(|(v, d)| v.ok_or_else(|| coded(exit::INVALID, format!("{}: missing argument {}=…", def.name, d.name))))
        .collect()
}

/// Sends one TC and reports its verification until completion or failure.
fn send_and_follow(
    s: &mut Session,
    robot: u8,
    def: &'static mib::tc::TcDef,
    args: &[i64],
    wait: bool,
    timeout: Duration,
) -> Result<u8> {
    // A dead OBSW or link is reported within LINK_LOSS_MS, not after every resend.
    s.watch_links();
    let tc = s.send(robot, def, args, Some(0), None)?;
    out(&format!(
        "robot {robot}: sent {} seq {} ({} bytes)",
        def.name,
        tc.seq,
        tc.bytes.len()
    ))?;
    let t0 = Instant::now();
    let mut accepted = false;
    while t0.elapsed() < timeout {
        for u in s.poll(Duration::from_millis(100)) {
            match u {
                Update::Verification {
                    tag: Some(0), v, after, ..
                } if v.request.seq() == tc.seq => {
                    out(&format!(
                        "robot {robot}: {} {}{}{} after {:.0} ms",
                        v.stage.name(),
                        if v.success { "ok" } else { "FAILED" },
                        v.step.map_or(String::new(), |st| format!(" step {st}")),
                        v.failure.as_ref().map_or(String::new(), |f| format!(": {f}")),
                        after.unwrap_or_default().as_secs_f64() * 1000.0
                    ))?;
                    if !v.success {
                        return Ok(exit::FAILED);
                    }
                    if v.stage == Stage::Acceptance {
                        accepted = true;
                        if !wait {
                            return Ok(exit::OK);
                        }
                    }
                    if v.stage == Stage::Completion {
                        return Ok(exit::OK);
                    }
                }
                Update::Resent { send, .. } => out(&format!(
                    "robot {robot}: no {} yet, resent the same bytes (send {send})",
                    if accepted { "completion" } else { "acceptance" }
                ))?,
                Update::DamagedCopy { .. } => out(&format!(
                    "robot {robot}: a copy arrived damaged (TM[1,2] CRC), resent the same bytes"
                ))?,
                Update::GaveUp { sends, accepted, .. } => {
                    return Err(coded(
                        exit::NO_ANSWER,
                        if accepted {
                            format!("robot {robot}: accepted, but no completion or failure report after {sends} sends: outcome unknown")
                        } else {
                            format!("robot {robot}: no acceptance after {sends} sends")
                        },
                    ))
                }
                Update::LinkLost { why, .. } => return Err(coded(exit::NO_ANSWER, why)),
                Update::Event { robot: r, event } if r == robot => out(&format!("robot {robot}: event {event}"))?,
                _ => {}
            }
        }
    }
    Err(coded(
        exit::NO_ANSWER,
        format!(
            "robot {robot}: no {} within {:.0} s",
            if accepted { "completion" } else { "acceptance" },
            timeout.as_secs_f64()
        ),
    ))
}

fn one_robot(l: &Links) -> Result<(u8, SocketAddr)> {
    match l.robots.as_slice() {
        [one] => Ok(*one),
        [] => Ok((mib::apid::DEFAULT_ROBOT, default_addr(mib::apid::DEFAULT_ROBOT))),
        _ => Err(coded(exit::INVALID, "give exactly one --robot")),
    }
}

fn send(a: &SendArgs, archive_path: Option<&Path>) -> Result<u8> {
    let def = mib::tc::by_name(&a.tc).ok_or_else(|| {
        coded(
            exit::INVALID,
            format!(
                "\"{}\" is not a TC of the MIB (see `ground mib export --format json`)",
                a.tc
            ),
        )
    })?;
    if def.variable {
        return Err(coded(
            exit::INVALID,
            format!("{} has variable data; not sendable from the command line", def.name),
        ));
    }
    let args = tc_args(def, &a.args)?;
    let (robot, addr) = one_robot(&a.links)?;
    let (mut s, arch) = open_session(&[(robot, addr)], a.links.transport(), archive_path)?;
    let r = send_and_follow(
        &mut s,
        robot,
        def,
        &args,
        !a.no_wait,
        Duration::from_secs_f64(a.timeout),
    );
    drop(s);
    close_archive(arch)?;
    r
}

fn mode(a: &ModeArgs, archive_path: Option<&Path>) -> Result<u8> {
    let def = mib::tc::by_name("MODE_SET").ok_or_else(|| anyhow!("MODE_SET not in the MIB"))?;
    let m = mib::modes::root_mode_by_name(&a.mode)
        .map(i64::from)
        .or_else(|| a.mode.parse().ok())
        .ok_or_else(|| {
            coded(
                exit::INVALID,
                format!("unknown mode \"{}\" (standby, operational, safed)", a.mode),
            )
        })?;
    let (robot, addr) = one_robot(&a.links)?;
    let (mut s, arch) = open_session(&[(robot, addr)], a.links.transport(), archive_path)?;
    let r = send_and_follow(
        &mut s,
        robot,
        def,
        &[mib::modes::node::ROBOT as i64, m, 0],
        true,
        Duration::from_secs_f64(a.timeout),
    );
    if let Some(st) = s.robots.get(&robot) {
        out(&format!("robot {robot}: {}", st.line()))?;
    }
    drop(s);
    close_archive(arch)?;
    r
}

fn watch(a: &WatchArgs, archive_path: Option<&Path>) -> Result<u8> {
    let mut links = a.links.robots.clone();
    if links.is_empty() {
        links.push((mib::apid::DEFAULT_ROBOT, default_addr(mib::apid::DEFAULT_ROBOT)));
    }
    let (mut s, arch) = open_session(&links, a.links.transport(), archive_path)?;
    // The OBSW sends TM to the grounds whose TC it accepted: subscribe with a ping, and
    // renew the lease well before it ends.
    if let Some(ping) = mib::tc::by_name("PING") {
        for &(r, _) in &links {
            s.send(r, ping, &[], None, Some("watch".into()))?;
        }
    }
    let renew = Duration::from_millis(mib::config::SUBSCRIPTION_LEASE_MS as u64 / 3);
    let mut renewed = Instant::now();
    let t0 = Instant::now();
    let mut n = 0u64;
    let result = (|| -> Result<()> {
        loop {
            if renewed.elapsed() >= renew {
                renewed = Instant::now();
                for &(r, _) in &links {
                    // A lost renewal is made good by the next one, a third of a lease later.
                    let _ = s.send_heartbeat(r);
                }
            }
            if a.duration.is_some_and(|d| t0.elapsed().as_secs_f64() >= d) || a.count.is_some_and(|c| n >= c) {
                return Ok(());
            }
            for u in s.poll(Duration::from_millis(200)) {
                let (robot, line, json) = match &u {
                    Update::Verification { robot, v, .. } => (
                        *robot,
                        pus::describe_body(&TmBody::Verification(v.clone())),
                        serde_json::to_value(v)?,
                    ),
                    Update::Hk { robot, hk } => {
                        if a.no_hk {
                            continue;
                        }
                        (
                            *robot,
                            pus::describe_body(&TmBody::Hk(hk.clone())),
                            serde_json::to_value(hk)?,
                        )
                    }
                    Update::Event { robot, event } => (*robot, format!("EVENT {event}"), serde_json::to_value(event)?),
                    Update::Tm { robot, tm } => (
                        *robot,
                        pus::describe(&Packet::Tm(tm.clone())),
                        serde_json::to_value(tm)?,
                    ),
                    Update::Corrupt { robot, error } => (
                        *robot,
                        format!("CORRUPT {error}"),
                        serde_json::json!({"corrupt": error.to_string()}),
                    ),
                    Update::Foreign {
                        robot,
                        apid,
                        service,
                        subservice,
                    } => (
                        *robot,
                        format!("FOREIGN TM[{service},{subservice}] of APID 0x{apid:03X}"),
                        serde_json::json!({"foreign_apid": apid, "service": service, "subservice": subservice}),
                    ),
                    _ => continue,
                };
                n += 1;
                if a.json {
                    out(&serde_json::json!({"robot": robot, "t_ms": archive::now_ms(), "tm": json}).to_string())?;
                } else {
                    out(&format!(
                        "{} robot {robot}: {line}",
                        chrono::Utc::now().format("%H:%M:%S%.3f")
                    ))?;
                }
            }
        }
    })();
    drop(s);
    close_archive(arch)?;
    result.map(|_| exit::OK)
}

/// Sends one line to a simulator control port and returns the reply.
pub fn sim_command(addr: SocketAddr, line: &str, timeout: Duration) -> Result<String> {
    let sock = std::net::UdpSocket::bind((std::net::Ipv4Addr::LOCALHOST, 0))?;
    sock.connect(addr)?;
    sock.set_read_timeout(Some(timeout))?;
    let mut buf = [0u8; 2048];
    for _ in 0..3 {
        sock.send(format!("{line}\n").as_bytes())?;
        match sock.recv(&mut buf) {
            Ok(n) => return Ok(String::from_utf8_lossy(&buf[..n]).trim().to_string()),
            Err(e) if matches!(e.kind(), std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut) => {}
            Err(e) if e.kind() == std::io::ErrorKind::ConnectionRefused => {
                return Err(coded(
                    exit::NO_ANSWER,
                    format!("no simulator at {addr} (connection refused)"),
                ))
            }
            Err(e) => return Err(e.into()),
        }
    }
    Err(coded(exit::NO_ANSWER, format!("no reply from the simulator at {addr}")))
}

/// Simulator control address of robot `n`.
pub fn sim_addr(n: u8) -> SocketAddr {
    (std::net::Ipv4Addr::LOCALHOST, mib::config::SIM_CTL_BASE_PORT + n as u16).into()
}

fn sim(a: &SimArgs) -> Result<u8> {
    let addr = a.addr.unwrap_or_else(|| sim_addr(a.robot));
    let line = a.line.join(" ");
    let reply = sim_command(addr, &line, Duration::from_millis(500))?;
    out(&format!("robot {}: {reply}", a.robot))?;
    if reply.starts_with("ok") {
        Ok(exit::OK)
    } else {
        Ok(exit::FAILED)
    }
}

fn archive_cmd(a: ArchiveCmd, path: &Path) -> Result<u8> {
    if let ArchiveCmd::Import { file, robot, json } = &a {
        return archive_import(path, file, *robot, *json);
    }
    let loc = path.to_string_lossy().to_string();
    if !archive::exists(&loc) {
        return Err(coded(exit::INVALID, format!("no archive at {}", path.display())));
    }
    let mut store = archive::Store::open(&loc).with_context(|| format!("opening archive {loc}"))?;
    match a {
        ArchiveCmd::Query { kind, filter, json } => {
            let rows = store.query(kind, &filter.filter()?)?;
            if json {
                for r in &rows.rows {
                    let obj: serde_json::Map<String, serde_json::Value> =
                        rows.columns.iter().cloned().zip(r.iter().cloned()).collect();
                    out(&serde_json::Value::Object(obj).to_string())?;
                }
            } else {
                out(&rows.columns.join(" | "))?;
                for r in &rows.rows {
                    let cells: Vec<String> = rows
                        .columns
                        .iter()
                        .zip(r)
                        .map(|(c, v)| match (c.as_str(), v) {
                            ("t_ms" | "obt_ms", serde_json::Value::Number(n)) => n
                                .as_i64()
                                .and_then(chrono::DateTime::from_timestamp_millis)
                                .map_or(n.to_string(), |t| t.format("%Y-%m-%dT%H:%M:%S%.3fZ").to_string()),
                            (_, serde_json::Value::String(s)) => s.clone(),
                            (_, serde_json::Value::Null) => "-".into(),
                            (_, v) => v.to_string(),
                        })
                        .collect();
                    out(&cells.join(" | "))?;
                }
                err_line!("{} row(s)", rows.rows.len());
            }
        }
        ArchiveCmd::Export {
            kind,
            filter,
            out: file,
            ..
        } => {
            let f = filter.filter()?;
            match file {
                Some(p) => {
                    let mut o = std::fs::File::create(&p).with_context(|| format!("writing {}", p.display()))?;
                    let n = store.export_csv(kind, &f, &mut o)?;
                    err_line!("{n} row(s) written to {}", p.display());
                }
                None => {
                    let mut o = std::io::stdout().lock();
                    store.export_csv(kind, &f, &mut o)?;
                }
            }
        }
        ArchiveCmd::Plot {
            params,
            out: file,
            robot,
            since,
            until,
        } => {
            let f = FilterArgs {
                robot,
                since,
                until,
                service: None,
                severity: None,
                params: params.clone(),
                limit: None,
            }
            .filter()?;
            let n = plot::plot(&mut store, &params, &f, &file)?;
            out(&format!("{} points plotted to {}", n, file.display()))?;
        }
        ArchiveCmd::Import { .. } => {}
        ArchiveCmd::Check { robot, json } => {
            let rep = store.check(robot)?;
            if json {
                out(&serde_json::to_string(&rep)?)?;
            } else {
                out(&format!(
                    "{} packet(s), {} raw bytes checked",
                    rep.packets, rep.raw_bytes
                ))?;
                for (r, apid, seq, obt, why) in &rep.bad {
                    out(&format!(
                        "BAD robot {r} APID {apid:#x} seq {seq} at {}: {why}",
                        fmt_ms(*obt)
                    ))?;
                }
                for (r, p, stored, expected) in &rep.chunk_mismatch {
                    let name = mib::params::by_id(*p).map_or("?", |d| d.name);
                    out(&format!(
                        "BAD robot {r} parameter {name}: {stored} value(s) in chunks, {expected} in packets"
                    ))?;
                }
                print_gaps(&rep.gaps)?;
                out(if rep.bad.is_empty() && rep.chunk_mismatch.is_empty() {
                    "check: ok"
                } else {
                    "check: FAILED"
                })?;
            }
            if !rep.bad.is_empty() || !rep.chunk_mismatch.is_empty() {
                return Ok(exit::INVALID);
            }
        }
        ArchiveCmd::Gaps { robot, json } => {
            let gaps = store.gaps(robot)?;
            if json {
                for g in &gaps {
                    out(&serde_json::to_string(g)?)?;
                }
            } else {
                print_gaps(&gaps)?;
            }
        }
        ArchiveCmd::Status { robot, json } => {
            let pos = store.positions(robot)?;
            let health = store.health()?;
            let (packets, raw) = store.packet_totals()?;
            let size = store.size_bytes()?;
            if json {
                out(&serde_json::json!({
                    "archive": store.db().location(), "packets": packets, "raw_bytes": raw,
                    "size_bytes": size, "positions": pos, "health": health,
                })
                .to_string())?;
            } else {
                out(&format!(
                    "{}: {packets} packet(s), {raw} raw bytes, {size} bytes on disk ({:.2}x)",
                    store.db().location(),
                    size as f64 / raw.max(1) as f64
                ))?;
                for h in health.iter().filter(|h| robot.is_none_or(|r| r == h.robot)) {
                    out(&format!(
                        "robot {}: last heard {}, newest on-board time {}, {} packet(s) received",
                        h.robot,
                        fmt_ms(h.last_heard_ms),
                        fmt_ms(h.last_obt_ms),
                        h.packets
                    ))?;
                }
                for p in &pos {
                    out(&format!(
                        "robot {} APID {:#x}: last seq {} at {}, {} stored, {} duplicate(s)",
                        p.robot,
                        p.apid,
                        p.seq,
                        fmt_ms(p.obt_ms),
                        p.packets,
                        p.duplicates
                    ))?;
                }
            }
        }
        ArchiveCmd::Latest { robot, json } => {
            for l in store.latest(robot)? {
                if json {
                    out(&serde_json::to_string(&l)?)?;
                } else {
                    out(&format!(
                        "robot {} {:<16} {:>12.4} {:<4} (raw {}) at {}",
                        l.robot,
                        l.name,
                        l.eng,
                        l.unit,
                        l.raw,
                        fmt_ms(l.t_ms)
                    ))?;
                }
            }
        }
    }
    Ok(exit::OK)
}

fn fmt_ms(ms: i64) -> String {
    chrono::DateTime::from_timestamp_millis(ms)
        .map_or(ms.to_string(), |t| t.format("%Y-%m-%dT%H:%M:%S%.3fZ").to_string())
}

fn print_gaps(gaps: &[archive::Gap]) -> Result<()> {
    for g in gaps {
        out(&format!(
            "robot {} APID {:#x}: {} missing after seq {} ({}) before seq {} ({}): {}{}",
            g.robot,
            g.apid,
            g.missing,
            g.after_seq,
            fmt_ms(g.after_obt_ms),
            g.before_seq,
            fmt_ms(g.before_obt_ms),
            g.reason.name(),
            g.note.as_deref().map_or(String::new(), |n| format!(" ({n})"))
        ))?;
    }
    let missing: u64 = gaps.iter().map(|g| g.missing as u64).sum();
    out(&format!("{} hole(s), {missing} packet(s) missing", gaps.len()))
}

fn archive_import(path: &Path, file: &Path, robot: u8, json: bool) -> Result<u8> {
    if !file.exists() {
        return Err(coded(exit::INVALID, format!("no file {}", file.display())));
    }
    let rep = archive::import::import(path, file, robot).with_context(|| format!("importing {}", file.display()))?;
    if json {
        out(&serde_json::to_string(&rep)?)?;
    } else {
        let a = &rep.archive;
        out(&format!(
            "{}: {} TM packet(s) read, {} stored, {} already archived, {} undecodable stretch(es) ({} bytes) kept as corrupt, \
             {} TC skipped, {} of another robot; {:.2} s ({:.0} packets/s)",
            file.display(),
            rep.tm,
            a.tm,
            a.duplicates,
            rep.corrupt_stretches,
            rep.corrupt_bytes,
            rep.tc_skipped,
            rep.other_robot,
            rep.seconds,
            rep.tm as f64 / rep.seconds.max(1e-9)
        ))?;
    }
    Ok(exit::OK)
}

fn mib_export(format: &str, dir: &Path) -> Result<u8> {
    let f: mib::export::Format = format
        .parse()
        .map_err(|e: mib::export::UnknownFormat| coded(exit::INVALID, e.to_string()))?;
    let files = mib::export::write_all(f, dir).with_context(|| format!("writing {}", dir.display()))?;
    for p in files {
        out(&p.display().to_string())?;
    }
    Ok(exit::OK)
}
