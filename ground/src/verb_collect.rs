//! `ground collect` and `ground alarms`: their flags, filled into the library's
//! [`ground::collect::CollectOptions`], and the alarm list and inputs.

use std::net::SocketAddr;
use std::path::{Path, PathBuf};

use anyhow::Result;
use clap::{Args, Subcommand};
use ground::alarms::{Input, State};
use ground::archive::{now_ms, Store};
use ground::collect::{config, parse_robot_arg, utc, CollectError, CollectOptions, EXIT_INVALID};

use crate::links::LinkFlags;
use crate::output::out;

/// `ground collect` options.
#[derive(Args, Debug, Clone)]
pub(crate) struct CollectArgs {
    /// Robot link `N=HOST:PORT` (or `N` for 127.0.0.1:7300+N); repeat per robot. Adds to
    /// (or overrides) the robots of --config.
    #[arg(long = "robot", short = 'r', value_parser = parse_robot_arg)]
    robots: Vec<(u8, Option<SocketAddr>)>,
    /// How the --robot links are reached: the space link (needs --keys) unless a lab flag.
    #[command(flatten)]
    link: LinkFlags,
    /// TOML configuration (robots, links, retention, alarm settings).
    #[arg(long)]
    config: Option<PathBuf>,
    /// Check a configuration file and exit (errors as file:line:column).
    #[arg(long, value_name = "FILE")]
    check_config: Option<PathBuf>,
    /// Print when each robot was last heard (from the archive) and exit.
    #[arg(long)]
    status: bool,
    /// With --status: JSON.
    #[arg(long)]
    json: bool,
    /// Delete archived data older than this, e.g. 30d (overrides the config's `retain`).
    #[arg(long)]
    retain: Option<String>,
    /// Plain log lines even on a terminal (no live table).
    #[arg(long)]
    plain: bool,
    /// Debug log lines (every store request, every corrupt packet).
    #[arg(long, short = 'v')]
    verbose: bool,
    /// Also serve the operators' dashboard on this address (docs/dashboard.md).
    #[arg(long, value_name = "ADDR")]
    http: Option<SocketAddr>,
    /// Access token of the dashboard (required when --http is not a loopback address).
    #[arg(long, value_name = "TOKEN")]
    http_token: Option<String>,
}

impl CollectArgs {
    fn options(self) -> CollectOptions {
        CollectOptions {
            link: self.link.choice(),
            robots: self.robots,
            config: self.config,
            check_config: self.check_config,
            status: self.status,
            json: self.json,
            retain: self.retain,
            plain: self.plain,
            verbose: self.verbose,
            http: self.http,
            http_token: self.http_token,
        }
    }
}

/// `ground alarms` subcommands.
#[derive(Subcommand, Debug, Clone)]
pub(crate) enum AlarmsCmd {
    /// List alarms that are not closed (with --all, closed ones too).
    List {
        #[arg(long)]
        robot: Option<u8>,
        #[arg(long)]
        all: bool,
        #[arg(long)]
        json: bool,
    },
    /// Acknowledge an alarm.
    Ack { id: i64 },
    /// Shelve an alarm for a while, e.g. `--for 2h`.
    Shelve {
        id: i64,
        #[arg(long = "for", value_name = "DURATION")]
        duration: String,
    },
    /// End a shelve.
    Unshelve { id: i64 },
}

/// Entry of `ground collect`.
pub(crate) fn collect(archive: &Path, a: CollectArgs) -> Result<u8> {
    ground::collect::collect_cli(archive, a.options()).map_err(|e| match e {
        // As an I/O error itself, so that `main` sees a closed pipe.
        CollectError::Io(io) => anyhow::Error::new(io),
        e => anyhow::Error::new(e),
    })
}

/// Entry of `ground alarms`.
pub(crate) fn alarms(archive: &Path, cmd: AlarmsCmd) -> Result<u8> {
    let mut c = Store::open_existing(&archive.to_string_lossy())?;
    let now = now_ms();
    match cmd {
        AlarmsCmd::List { robot, all, json } => {
            let rows = c.alarms(robot, all)?;
            if json {
                for r in &rows {
                    out(&serde_json::to_string(r)?)?;
                }
                return Ok(0);
            }
            out(&format!(
                "{:>5} {:>5}  {:<24} {:<7} {:<13} {:<19} {:<19} {:>5}  {}",
                "id", "robot", "source", "sev", "state", "first (UTC)", "last (UTC)", "count", "message"
            ))?;
            for r in &rows {
                let state = match r.shelved_until_ms {
                    Some(u) if r.state == State::Shelved => format!("shelved<{}", utc(u).get(11..16).unwrap_or("")),
                    _ => r.state.name().to_string(),
                };
                out(&format!(
                    "{:>5} {:>5}  {:<24} {:<7} {:<13} {:<19} {:<19} {:>5}  {}",
                    r.id,
                    if r.robot == 0 { "-".into() } else { r.robot.to_string() },
                    r.source,
                    r.severity,
                    state,
                    utc(r.first_ms),
                    utc(r.last_ms),
                    r.count,
                    r.message
                ))?;
            }
            if rows.is_empty() {
                out(if all { "no alarms" } else { "no open alarms" })?;
            }
            Ok(0)
        }
        AlarmsCmd::Ack { id } => one_input(&mut c, id, Input::Ack, now),
        AlarmsCmd::Unshelve { id } => one_input(&mut c, id, Input::Unshelve, now),
        AlarmsCmd::Shelve { id, duration } => match config::parse_duration_ms(&duration) {
            Some(ms) => one_input(&mut c, id, Input::Shelve { until_ms: now + ms }, now),
            None => {
                eprintln!("ground: error: --for {duration}: a duration like 30m, 2h, 1d");
                Ok(EXIT_INVALID)
            }
        },
    }
}

fn one_input(c: &mut Store, id: i64, input: Input, now: i64) -> Result<u8> {
    match c.alarm_input(id, input, now) {
        Ok(s) => {
            out(&format!("alarm {id}: {}", s.name()))?;
            Ok(0)
        }
        Err(e) => {
            eprintln!("ground: error: {e}");
            Ok(EXIT_INVALID)
        }
    }
}
