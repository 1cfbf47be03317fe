//! `ground collect`: the unattended housekeeping collector (see `docs/collector.md`).
//!
//! One thread per robot ([`robot::Worker`]) with its own link; one sink thread that
//! writes the archive ([`store`]); the main thread waits for SIGINT/SIGTERM and shows a
//! live table on a terminal. Touch points with the rest of the ground tool are kept in
//! two files: [`onboard`] (the obsw's protocol) and [`store`] (the archive).

pub mod alarms;
pub mod config;
pub mod dash;
pub mod onboard;
pub mod planrun;
pub mod robot;
pub mod robotcfg;
pub mod store;
/// The sequence tracker is the one of every front end ([`ground_ops::live`]).
pub use ground_ops::live as tracker;

use std::collections::VecDeque;
use std::io::{IsTerminal, Write};
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use ground_archive as archive;
use ground_ops::{link, link_choice, ops, plan};
use ground_pus as pus;

use crate::archive::{now_ms, Store};

use config::{Config, RobotCfg};
use robot::{RobotStatus, Worker};
use store::{SinkCfg, SinkMsg};
use tracker::Pos;

/// Exit code of an invalid configuration (the ground tool's "invalid input").
pub const EXIT_INVALID: u8 = 3;
/// How long the shutdown may take before the collector gives up waiting.
pub const SHUTDOWN_LIMIT: Duration = Duration::from_millis(4_500);
/// Archived positions read per robot and APID at start (holes among them are retrieved).
pub const RESUME_WINDOW: usize = mib::config::TM_STORE_CAPACITY;
/// Gap notes `--status` lists (newest first).
const STATUS_NOTES: usize = 10;

/// What `ground collect` was asked to do (the binary fills it from its flags).
#[derive(Debug, Clone, Default)]
pub struct CollectOptions {
    /// Robot links `(N, address)`; no address: the default of the link chosen
    /// ([`crate::link_choice::LinkChoice::default_addr`]). Added to (or overriding) the
    /// robots of `config`.
    pub robots: Vec<(u8, Option<SocketAddr>)>,
    /// How the robots of `robots` are reached.
    pub link: crate::link_choice::LinkChoice,
    /// TOML configuration (robots, links, retention, alarm settings).
    pub config: Option<PathBuf>,
    /// Check this configuration file and return (errors as file:line:column).
    pub check_config: Option<PathBuf>,
    /// Print when each robot was last heard (from the archive) and return.
    pub status: bool,
    /// With `status`: JSON.
    pub json: bool,
    /// Delete archived data older than this, e.g. 30d (overrides the config's `retain`).
    pub retain: Option<String>,
    /// Plain log lines even on a terminal (no live table).
    pub plain: bool,
    /// Debug log lines.
    pub verbose: bool,
    /// Also serve the operators' dashboard on this address.
    pub http: Option<SocketAddr>,
    /// Access token of the dashboard (required when `http` is not a loopback address).
    pub http_token: Option<String>,
}

/// Why the collector (or its `--status`) stopped with an error. Invalid input (a bad
/// configuration, link flags or duration) is not an error: it is reported on standard
/// error and returned as exit code [`EXIT_INVALID`] (or 2).
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum CollectError {
    /// SIGINT/SIGTERM could not be caught.
    #[error("installing the signal handler")]
    Signal(#[source] ctrlc::Error),
    /// The archive could not be opened at start.
    #[error("archive {loc}")]
    OpenArchive {
        loc: String,
        #[source]
        source: crate::archive::ArchiveError,
    },
    #[error(transparent)]
    Archive(#[from] crate::archive::ArchiveError),
    #[error(transparent)]
    Db(#[from] crate::archive::db::DbError),
    /// The dashboard could not start.
    #[error(transparent)]
    Dashboard(#[from] ground_dashboard::ServeError),
    /// A thread could not start, or standard output could not be written.
    #[error(transparent)]
    Io(#[from] std::io::Error),
}

/// `N` or `N=HOST:PORT` (robot number in the MIB's range; no address: the default of
/// the link chosen, [`crate::link_choice::LinkChoice::default_addr`]), as `--robot` takes it.
pub fn parse_robot_arg(s: &str) -> Result<(u8, Option<SocketAddr>), String> {
    let (n, addr) = match s.split_once('=') {
        Some((n, a)) => (n, Some(a)),
        None => (s, None),
    };
    let n: u8 = n.trim().parse().map_err(|_| format!("\"{n}\" is not a robot number"))?;
    if mib::apid::robot_apid(n).is_none() {
        return Err(format!(
            "robot {n} outside {}..={}",
            mib::apid::ROBOT_MIN,
            mib::apid::ROBOT_MAX
        ));
    }
    let addr = match addr {
        Some(a) => {
            use std::net::ToSocketAddrs;
            Some(
                a.to_socket_addrs()
                    .map_err(|e| format!("address \"{a}\": {e}"))?
                    .next()
                    .ok_or_else(|| format!("address \"{a}\" does not resolve"))?,
            )
        }
        None => None,
    };
    Ok((n, addr))
}

/// `N=HOST:PORT`, the address required (`--tm-listen`).
pub fn parse_robot(s: &str) -> Result<(u8, SocketAddr), String> {
    match parse_robot_arg(s)? {
        (n, Some(a)) => Ok((n, a)),
        (n, None) => Err(format!("give an address: {n}=HOST:PORT")),
    }
}

type Result<T, E = CollectError> = std::result::Result<T, E>;

fn emit(line: &str) -> Result<()> {
    let mut o = std::io::stdout().lock();
    writeln!(o, "{line}")?;
    Ok(())
}

/// Entry of `ground collect`.
pub fn collect_cli(archive: &Path, a: CollectOptions) -> Result<u8> {
    if let Some(f) = &a.check_config {
        return match config::load(f) {
            Ok(c) => {
                emit(&format!(
                    "{}: ok ({} robots, retain {})",
                    f.display(),
                    c.robots.len(),
                    c.retain_ms.map_or("forever".into(), config::format_duration_ms)
                ))?;
                Ok(0)
            }
            Err(e) => {
                eprintln!("{e:#}");
                Ok(EXIT_INVALID)
            }
        };
    }
    if a.status {
        return status(archive, a.json);
    }
    let mut cfg = match &a.config {
        Some(f) => match config::load(f) {
            Ok(c) => c,
            Err(e) => {
                eprintln!("{e:#}");
                return Ok(EXIT_INVALID);
            }
        },
        None => Config::default(),
    };
    for &(n, addr) in &a.robots {
        let addr = addr.unwrap_or_else(|| a.link.default_addr(n));
        let n = &n;
        let addr = &addr;
        cfg.robots.retain(|r| r.number != *n);
        let (transport, frames) = match a.link.resolve(&[(*n, *addr)]) {
            Ok(c) => c,
            Err(e) => {
                eprintln!("ground: error: {e}");
                return Ok(EXIT_INVALID);
            }
        };
        cfg.robots.push(RobotCfg {
            number: *n,
            addr: *addr,
            transport,
            frames,
            hk_interval_ms: None,
            name: None,
        });
    }
    if let Some(r) = &a.retain {
        match config::parse_duration_ms(r) {
            Some(ms) => cfg.retain_ms = Some(ms),
            None => {
                eprintln!("ground: error: --retain {r}: a duration like 30d, 12h, 90m");
                return Ok(EXIT_INVALID);
            }
        }
    }
    if cfg.robots.is_empty() {
        eprintln!("ground: error: no robots: give --robot N=HOST:PORT or a --config with [[robot]] tables");
        return Ok(2);
    }
    let table = std::io::stdout().is_terminal() && !a.plain;
    let ring = Arc::new(Mutex::new(VecDeque::new()));
    init_logging(a.verbose, table.then(|| ring.clone()));
    let http = a.http.map(|addr| (addr, a.http_token.clone()));
    run_with(archive, cfg, table, ring, http)
}

/// Runs the collector until SIGINT or SIGTERM.
pub fn run(archive: &Path, cfg: Config, table: bool, ring: LogRing) -> Result<u8> {
    run_with(archive, cfg, table, ring, None)
}

/// Runs the collector until SIGINT or SIGTERM; with `http`, also serves the dashboard
/// fed by the robot threads (see [`dash`]).
pub fn run_with(
    archive: &Path,
    cfg: Config,
    table: bool,
    ring: LogRing,
    http: Option<(SocketAddr, Option<String>)>,
) -> Result<u8> {
    let stop = Arc::new(AtomicBool::new(false));
    ignore_file_size_signal();
    {
        let stop = stop.clone();
        ctrlc::set_handler(move || stop.store(true, Ordering::SeqCst)).map_err(CollectError::Signal)?;
    }
    // Read where each robot was before the collector (re)started.
    let loc = archive.to_string_lossy();
    let mut st = Store::open(&loc).map_err(|source| CollectError::OpenArchive {
        loc: loc.to_string(),
        source,
    })?;
    let mut histories = Vec::new();
    let mut hashes = Vec::new();
    let mut first_seqs = Vec::new();
    for r in &cfg.robots {
        // Its TCs numbered on after the last one archived (the rule of every front end).
        let archived = onboard::apid(r.number).and_then(|apid| st.next_tc_seq(apid).ok().flatten());
        first_seqs.push(crate::ops::first_tc_seq(archived));
        // The configuration hash last archived: a change while the collector was down
        // is a change too.
        hashes.push(last_config_hash(&mut st, r.number)?);
        let h: Vec<(u16, Vec<Pos>)> = st
            .recent_positions(r.number, RESUME_WINDOW)?
            .into_iter()
            .map(|(apid, v)| (apid, v.into_iter().map(|(seq, obt_ms)| Pos { seq, obt_ms }).collect()))
            .collect();
        if let Some(last) = h.iter().find_map(|(_, v)| v.last()) {
            tracing::info!(
                robot = r.number,
                "robot {}: resuming after sequence count {} (on-board time {})",
                r.number,
                last.seq,
                crate::pus::CdsShort::from_unix_ms(last.obt_ms)
            );
        }
        histories.push(h);
    }
    drop(st);
    let (sink_tx, sink_rx) = crossbeam_channel::unbounded::<SinkMsg>();
    let sink_cfg = SinkCfg {
        path: archive.to_path_buf(),
        retain_ms: cfg.retain_ms,
        prune_every_ms: 3_600_000,
    };
    let sink = std::thread::Builder::new()
        .name("collect-sink".into())
        .spawn(move || store::run_sink(sink_cfg, sink_rx))?;
    let global = Arc::new(cfg.clone());
    let hub = http.as_ref().map(|_| ground_dashboard::Hub::new());
    let mut dash_tx = std::collections::BTreeMap::new();
    let mut workers = Vec::new();
    let mut statuses = Vec::new();
    for (((r, h), hash), first_seq) in cfg.robots.iter().zip(histories).zip(hashes).zip(first_seqs) {
        let status = Arc::new(Mutex::new(RobotStatus {
            robot: r.number,
            addr: r.addr.to_string(),
            ..Default::default()
        }));
        statuses.push(status.clone());
        let mut w = Worker::new(r.clone(), global.clone(), sink_tx.clone(), status, stop.clone(), h)
            .with_config_hash(hash)
            .with_first_seq(first_seq);
        if let Some(hub) = &hub {
            let (tx, rx) = crossbeam_channel::bounded(64);
            dash_tx.insert(r.number, tx);
            w = w.with_dashboard(dash::RobotDash {
                hub: hub.clone(),
                cmds: rx,
            });
        }
        workers.push(
            std::thread::Builder::new()
                .name(format!("robot-{}", r.number))
                .spawn(move || w.run())?,
        );
    }
    // The dashboard: one hub fed by the robot threads, the collector's alarms, the
    // archive's decimation.
    let _dashboard = match (http, hub) {
        (Some((addr, token)), Some(hub)) => {
            let alarms = Arc::new(dash::AlarmSync::new(archive.to_path_buf(), hub.clone()));
            alarms.clone().spawn(stop.clone())?;
            let commander = dash::CollectCommander::new(dash_tx, archive.to_path_buf(), alarms)
                .with_plans(cfg.plans.clone(), hub.clone());
            let series = dash::ArchiveSeries::new(archive.to_path_buf());
            let running = ground_dashboard::spawn(addr, token, hub, Arc::new(commander), Arc::new(series))?;
            tracing::info!("dashboard at http://{}/", running.local_addr());
            Some(running)
        }
        _ => None,
    };
    tracing::info!("collecting from {} robots into {}", cfg.robots.len(), archive.display());
    let started = Instant::now();
    while !stop.load(Ordering::Relaxed) {
        std::thread::sleep(Duration::from_millis(200));
        if table {
            draw(&statuses, &ring, started);
        }
    }
    let t0 = Instant::now();
    tracing::info!("stopping: flushing the archive");
    for w in workers {
        let _ = w.join();
    }
    let (ftx, frx) = crossbeam_channel::bounded(1);
    let _ = sink_tx.send(SinkMsg::Flush(ftx));
    let _ = frx.recv_timeout(SHUTDOWN_LIMIT.saturating_sub(t0.elapsed()));
    drop(sink_tx);
    // The sink ends once the robots' senders are gone; do not wait past the limit.
    let deadline = t0 + SHUTDOWN_LIMIT;
    while !sink.is_finished() && Instant::now() < deadline {
        std::thread::sleep(Duration::from_millis(20));
    }
    if sink.is_finished() {
        if let Ok(st) = sink.join() {
            tracing::info!(
                "stopped: {} TM written, {} not written, {} rows pruned",
                st.tm_written,
                st.pending,
                st.pruned_rows
            );
        }
    } else {
        tracing::error!("the archive did not finish within the shutdown limit");
        return Ok(1);
    }
    if table {
        draw(&statuses, &ring, started);
    }
    Ok(0)
}

/// Module reports looked for among the newest archived packets of a robot at start.
const HASH_SEARCH_PACKETS: i64 = 4096;

/// The newest non-zero configuration hash `robot` reported before the collector
/// (re)started: the newer of its last archived MODULES housekeeping (every 10 s) and the
/// last module report among its newest archived packets.
fn last_config_hash(st: &mut Store, robot: u8) -> Result<Option<u32>> {
    let from_hk = st
        .latest(Some(robot))?
        .into_iter()
        .find(|l| l.param == mib::params::pid::CONFIG_HASH && l.raw != 0)
        .and_then(|l| Some((l.t_ms, u32::try_from(l.raw).ok()?)));
    let mut from_report = None;
    if let Some(apid) = onboard::apid(robot) {
        let rows = crate::archive::db::collect(
            st.db(),
            "SELECT obt_ms, raw FROM packet WHERE robot = ?1 AND apid = ?2 ORDER BY obt_ms DESC LIMIT ?3",
            &[
                crate::archive::Val::Int(i64::from(robot)),
                crate::archive::Val::Int(i64::from(apid)),
                crate::archive::Val::Int(HASH_SEARCH_PACKETS),
            ],
        )?;
        from_report = rows.iter().find_map(|r| {
            let tm = crate::pus::decode_tm(r.get(1)?.blob()?).ok()?;
            let body = onboard::module_report(&tm)?;
            let h = u32::from_be_bytes(body.get(..4)?.try_into().ok()?);
            (h != 0).then_some((r.first()?.int()?, h))
        });
    }
    Ok(match (from_hk, from_report) {
        (Some(a), Some(b)) => Some(if a.0 >= b.0 { a.1 } else { b.1 }),
        (a, b) => a.or(b).map(|x| x.1),
    })
}

/// A file-size limit (RLIMIT_FSIZE, e.g. a quota set with `prlimit`) must surface as a
/// write error the sink handles (alarm, keep in memory, retry), not kill the collector
/// with SIGXFSZ.
#[allow(unsafe_code)]
fn ignore_file_size_signal() {
    use nix::sys::signal::{signal, SigHandler, Signal};
    // SAFETY: installs the "ignore" disposition, no handler code runs.
    if let Err(e) = unsafe { signal(Signal::SIGXFSZ, SigHandler::SigIgn) } {
        tracing::warn!("cannot ignore SIGXFSZ: {e}");
    }
}

// ---------------------------------------------------------------------------
// Logging and the live table

/// Recent log lines kept for the live table.
pub type LogRing = Arc<Mutex<VecDeque<String>>>;
const RING_LINES: usize = 8;

struct RingWriter {
    ring: LogRing,
    buf: Vec<u8>,
}

impl Write for RingWriter {
    fn write(&mut self, b: &[u8]) -> std::io::Result<usize> {
        self.buf.extend_from_slice(b);
        Ok(b.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

impl Drop for RingWriter {
    fn drop(&mut self) {
        let line = String::from_utf8_lossy(&self.buf).trim_end().to_string();
        if let Ok(mut r) = self.ring.lock() {
            r.push_back(line);
            while r.len() > RING_LINES {
                r.pop_front();
            }
        }
    }
}

#[derive(Clone)]
struct RingMake(LogRing);

impl<'a> tracing_subscriber::fmt::MakeWriter<'a> for RingMake {
    type Writer = RingWriter;
    fn make_writer(&'a self) -> Self::Writer {
        RingWriter {
            ring: self.0.clone(),
            buf: Vec::new(),
        }
    }
}

fn init_logging(verbose: bool, ring: Option<LogRing>) {
    let level = if verbose {
        tracing::Level::DEBUG
    } else {
        tracing::Level::INFO
    };
    let b = tracing_subscriber::fmt().with_max_level(level).with_target(false);
    let r = match ring {
        Some(ring) => b.with_ansi(false).without_time().with_writer(RingMake(ring)).try_init(),
        None => b.with_ansi(false).with_writer(std::io::stderr).try_init(),
    };
    if r.is_err() {
        // A subscriber is already installed (tests): keep it.
    }
}

fn age(now: i64, t: Option<i64>) -> String {
    match t {
        None => "-".into(),
        Some(t) => {
            let s = (now - t).max(0) as f64 / 1000.0;
            if s < 100.0 {
                format!("{s:.1}s")
            } else if s < 6000.0 {
                format!("{:.0}m", s / 60.0)
            } else {
                format!("{:.0}h", s / 3600.0)
            }
        }
    }
}

fn draw(statuses: &[Arc<Mutex<RobotStatus>>], ring: &LogRing, started: Instant) {
    let now = now_ms();
    let mut out = String::from("\x1b[H\x1b[J");
    out.push_str(&format!(
        "ground collect: {} robots, up {} s  (Ctrl-C stops)\n",
        statuses.len(),
        started.elapsed().as_secs()
    ));
    out.push_str(&format!(
        "{:>5}  {:<21} {:<10} {:>9} {:>7} {:>6} {:>5} {:>7} {:>8}  {}\n",
        "robot", "address", "link", "packets", "filled", "lost", "holes", "dups", "last HK", "alarms"
    ));
    for s in statuses {
        let Ok(s) = s.lock().map(|g| g.clone()) else { continue };
        out.push_str(&format!(
            "{:>5}  {:<21} {:<10} {:>9} {:>7} {:>6} {:>5} {:>7} {:>8}  {}\n",
            s.robot,
            s.addr,
            s.link.name(),
            s.tm.packets,
            s.tm.filled,
            s.tm.lost,
            s.holes,
            s.tm.duplicates,
            age(now, s.last_hk_ms),
            if s.conditions.is_empty() {
                "-".to_string()
            } else {
                s.conditions.join(" ")
            }
        ));
    }
    if let Ok(r) = ring.lock() {
        out.push('\n');
        for l in r.iter() {
            out.push_str(l);
            out.push('\n');
        }
    }
    let mut o = std::io::stdout().lock();
    let _ = o.write_all(out.as_bytes());
    let _ = o.flush();
}

// ---------------------------------------------------------------------------
// --status and `ground alarms`

/// A UTC time as `--status` and `ground alarms list` show it (`2026-01-31 12:00:00`).
pub fn utc(ms: i64) -> String {
    chrono::DateTime::from_timestamp_millis(ms)
        .map(|t| t.format("%Y-%m-%d %H:%M:%S").to_string())
        .unwrap_or_else(|| ms.to_string())
}

fn status(archive: &Path, json: bool) -> Result<u8> {
    let mut st = Store::open_existing(&archive.to_string_lossy())?;
    let links = st.links()?;
    let alarms = st.alarms(None, false)?;
    let notes = st.gap_notes(None, STATUS_NOTES)?;
    let n_notes = st.gap_note_count(None)?;
    if json {
        let v = serde_json::json!({
            "robots": links, "open_alarms": alarms, "unrecoverable": notes, "unrecoverable_total": n_notes,
        });
        emit(&v.to_string())?;
        return Ok(0);
    }
    let now = now_ms();
    emit(&format!(
        "{:>5}  {:<21} {:<10} {:<20} {:>9} {:>9} {:>7} {:>6} {:>6}",
        "robot", "address", "link", "last heard (UTC)", "ago", "packets", "filled", "lost", "alarms"
    ))?;
    for h in &links {
        let n_alarms = alarms.iter().filter(|a| a.robot == h.robot).count();
        emit(&format!(
            "{:>5}  {:<21} {:<10} {:<20} {:>9} {:>9} {:>7} {:>6} {:>6}",
            h.robot,
            h.addr,
            h.link,
            h.last_heard_ms.map_or("never".into(), utc),
            age(now, h.last_heard_ms),
            h.tm.packets,
            h.tm.filled,
            h.tm.lost,
            n_alarms
        ))?;
    }
    if links.is_empty() {
        emit("no robot has been collected into this archive")?;
    }
    let sys = alarms.iter().filter(|a| a.robot == 0).count();
    if sys > 0 {
        emit(&format!(
            "{sys} open collector alarm(s) (archive): see `ground alarms list`"
        ))?;
    }
    if let Some(u) = links.iter().map(|h| h.updated_ms).max() {
        emit(&format!("collector last wrote its status {} ago", age(now, Some(u))))?;
    }
    if n_notes > 0 {
        emit(&format!(
            "{n_notes} hole(s) that cannot be filled (`ground archive gaps` lists every hole); newest:"
        ))?;
        for n in &notes {
            emit(&format!(
                "  robot {} APID 0x{:03X} after seq {} ({}): {} — {}",
                n.robot,
                n.apid,
                n.after_seq,
                utc(n.after_obt_ms),
                n.reason.name(),
                n.note.as_deref().unwrap_or("")
            ))?;
        }
    }
    Ok(0)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("ground-collect-unit-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    // verifies: GND-11
    #[test]
    fn an_unreadable_or_invalid_configuration_is_a_typed_error_naming_the_file() {
        let dir = scratch("cfg");
        let missing = dir.join("none.toml");
        let e = config::load(&missing).unwrap_err();
        assert!(
            matches!(&e, config::LoadError::Read { path, .. } if *path == missing),
            "{e:?}"
        );
        assert!(
            e.to_string()
                .starts_with(&format!("cannot read {}: ", missing.display())),
            "{e}"
        );
        let bad = dir.join("bad.toml");
        std::fs::write(&bad, "x = \n").unwrap();
        let e = config::load(&bad).unwrap_err();
        assert!(matches!(e, config::LoadError::Invalid(_)), "{e:?}");
        assert!(e.to_string().starts_with(&format!("{}:1:5: ", bad.display())), "{e}");
        let _ = std::fs::remove_dir_all(&dir);
    }

    // verifies: GND-10
    #[test]
    fn status_of_a_missing_archive_is_an_archive_error() {
        let dir = scratch("status");
        let archive = dir.join("none.db");
        let opts = CollectOptions {
            status: true,
            ..CollectOptions::default()
        };
        let e = collect_cli(&archive, opts).unwrap_err();
        assert!(
            matches!(e, CollectError::Archive(crate::archive::ArchiveError::NotFound(_))),
            "{e:?}"
        );
        assert_eq!(e.to_string(), format!("archive {} does not exist", archive.display()));
        assert!(!archive.exists(), "--status never creates an archive");
        let _ = std::fs::remove_dir_all(&dir);
    }
}
