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
use std::time::Instant;

use anyhow::{anyhow, Context, Result};
use clap::{Args, Parser, Subcommand};
use ground::archive::{self, Archive, Filter, Kind};
use ground::collect::parse_robot;
use ground::link::Transport;
use ground::ops::Session;
use ground::plan;
use ground::pus;

mod demo;
mod plot;
mod verb_live;
mod verb_run;
mod verb_sim;

use verb_live::{mode, ping, send, watch};
use verb_run::run_plan;
pub(crate) use verb_run::{interrupt_flag, plan_policy, unconfirmed};
use verb_sim::sim;

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
    /// Robot link `N=HOST:PORT` (or just `N` for 127.0.0.1:7300+N, robot 1 = 7301); repeat
    /// per robot. Required by ping, send, mode and watch; `run` adds the plan's robots.
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
    /// Continue a run (the latest run of this plan in the archive, or RUN_ID): its
    /// completed steps are not sent again, a TC whose outcome is unknown is resolved
    /// from the robot's reports and on-board store before anything is sent.
    #[arg(long, value_name = "RUN_ID", num_args = 0..=1, default_missing_value = "")]
    resume: Option<String>,
    /// After a first Ctrl-C, longest wait (seconds) for the steps in flight.
    #[arg(long, default_value_t = ground::ops::INTERRUPT_GRACE.as_secs_f64())]
    grace: f64,
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
    /// Confirm a hazardous TC (the MIB's hazard flag); without it one is refused.
    #[arg(long)]
    confirm: bool,
}

#[derive(Args, Debug)]
struct ModeArgs {
    #[command(flatten)]
    links: Links,
    /// standby, operational or safed.
    mode: String,
    #[arg(long, default_value_t = 60.0)]
    timeout: f64,
    /// Confirm the mode change (MODE_SET is hazardous in the MIB); refused without it.
    #[arg(long)]
    confirm: bool,
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
    #[arg(long, short = 'r', required_unless_present = "addr")]
    robot: Option<u8>,
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
    #[arg(long, allow_hyphen_values = true)]
    since: Option<String>,
    /// Until this time (same forms as --since).
    #[arg(long, allow_hyphen_values = true)]
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
        #[arg(long, allow_hyphen_values = true)]
        since: Option<String>,
        #[arg(long, allow_hyphen_values = true)]
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
        /// scos, xtce or json.
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
            Ok(pl) if !unconfirmed(&pl).is_empty() => {
                bad += 1;
                let list = unconfirmed(&pl);
                for (st, e) in &list {
                    let (line, col) = plan::line_col(&src, st.span.start);
                    err_line!("{}:{line}:{col}: error: step \"{}\": {e}", p.display(), st.id);
                }
                err_line!("{}: {} error(s)", p.display(), list.len());
            }
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
                    // The archive's error keeps only the I/O error's text: the writer
                    // remembers a closed pipe so that it stays a quiet exit.
                    let mut o = PipeWatch {
                        inner: std::io::stdout().lock(),
                        closed: false,
                    };
                    let r = store.export_csv(kind, &f, &mut o);
                    if o.closed {
                        return Ok(exit::OK);
                    }
                    r?;
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

/// A writer that notes when its reader went away (EPIPE).
struct PipeWatch<W: Write> {
    inner: W,
    closed: bool,
}

impl<W: Write> Write for PipeWatch<W> {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        let r = self.inner.write(buf);
        self.closed |= matches!(&r, Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe);
        r
    }
    fn flush(&mut self) -> std::io::Result<()> {
        let r = self.inner.flush();
        self.closed |= matches!(&r, Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe);
        r
    }
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
