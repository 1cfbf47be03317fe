//! Runs the operator dashboard by hand until `ground collect` serves it.
//!
//! ```sh
//! cargo build --bin obsw --example dashboard_demo
//! target/debug/examples/dashboard_demo --robots 2            # real obsw processes
//! target/debug/examples/dashboard_demo --synthetic 50 --hz 10 # synthetic HK (benchmark)
//! ```
//!
//! Options: `--robots N` (obsw processes, robots 1..=N, default 2), `--obsw PATH`
//! (default: next to this example's target folder, then `$OBSW_BIN`), `--speed X`
//! (simulator speed, default 1), `--http ADDR` (default 127.0.0.1:0), `--token T`,
//! `--synthetic N --hz F` (no obsw: N robots with
//! generated HK at F Hz and a day of archived V_BAT_A for robot 1, for the benchmark). Prints one JSON line
//! `{"url": …, "robots": [{"robot": N, "tc": ADDR, "sim_ctl": ADDR}, …]}` when ready,
//! then serves until stdin closes or it is killed.

use std::io::{BufRead, Read};
use std::net::SocketAddr;
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::sync::Arc;
use std::time::Duration;

use anyhow::{anyhow, bail, Context, Result};
use ground::dashboard::{self, feed::LinkFeed, ConfigState, Hub, LinkState, NoArchive};

struct Opts {
    robots: u8,
    obsw: Option<PathBuf>,
    speed: f64,
    http: SocketAddr,
    token: Option<String>,
    synthetic: Option<u8>,
    hz: f64,
}

fn opts() -> Result<Opts> {
    let mut o = Opts {
        robots: 2,
        obsw: None,
        speed: 1.0,
        http: "127.0.0.1:0".parse()?,
        token: None,
        synthetic: None,
        hz: 10.0,
    };
    let mut it = std::env::args().skip(1);
    while let Some(a) = it.next() {
        let mut val = || it.next().ok_or_else(|| anyhow!("{a} needs a value"));
        match a.as_str() {
            "--robots" => o.robots = val()?.parse()?,
            "--obsw" => o.obsw = Some(val()?.into()),
            "--speed" => o.speed = val()?.parse()?,
            "--http" => o.http = val()?.parse()?,
            "--token" => o.token = Some(val()?),
            "--synthetic" => o.synthetic = Some(val()?.parse()?),
            "--hz" => o.hz = val()?.parse()?,
            other => bail!("unknown option {other} (see the file's doc comment)"),
        }
    }
    Ok(o)
}

struct Procs(Vec<Child>);
impl Drop for Procs {
    fn drop(&mut self) {
        for c in &mut self.0 {
            let _ = c.kill();
            let _ = c.wait();
        }
    }
}

fn free_port() -> Result<u16> {
    for _ in 0..50 {
        let t = std::net::TcpListener::bind(("127.0.0.1", 0))?;
        let p = t.local_addr()?.port();
        if std::net::UdpSocket::bind(("127.0.0.1", p)).is_ok() {
            return Ok(p);
        }
    }
    bail!("no free port")
}

fn find_obsw(given: Option<PathBuf>) -> Result<PathBuf> {
    if let Some(p) = given {
        return Ok(p);
    }
    if let Ok(me) = std::env::current_exe() {
        // target/<profile>/examples/dashboard_demo → target/<profile>/obsw
        if let Some(p) = me.parent().and_then(|d| d.parent()).map(|d| d.join("obsw")) {
            if p.is_file() {
                return Ok(p);
            }
        }
    }
    std::env::var_os("OBSW_BIN")
        .map(PathBuf::from)
        .ok_or_else(|| anyhow!("cannot find obsw: build it (cargo build --bin obsw) or give --obsw"))
}

fn start_obsw(bin: &PathBuf, robot: u8, speed: f64) -> Result<(Child, SocketAddr, SocketAddr)> {
    let tc: SocketAddr = ([127, 0, 0, 1], free_port()?).into();
    let ctl: SocketAddr = ([127, 0, 0, 1], free_port()?).into();
    let mut child = Command::new(bin)
        .args([
            "--robot",
            &robot.to_string(),
            "--udp",
            &tc.to_string(),
            "--sim-ctl",
            &ctl.to_string(),
        ])
        .args(["--speed", &speed.to_string(), "--seed", &robot.to_string()])
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .with_context(|| format!("starting {}", bin.display()))?;
    let out = child.stdout.take().ok_or_else(|| anyhow!("no stdout"))?;
    let mut lines = std::io::BufReader::new(out).lines();
    match lines.next() {
        Some(Ok(l)) if l.starts_with("READY") => {}
        other => bail!("obsw for robot {robot} did not start: {other:?}"),
    }
    std::thread::spawn(move || for _ in lines {});
    Ok((child, tc, ctl))
}

/// Generated HK for the benchmark: every ROBOT_STATUS parameter, a slow battery ramp.
fn synthetic(hub: Hub, robots: u8, hz: f64) {
    let params: Vec<&'static mib::params::ParamDef> = mib::hk::by_sid(mib::hk::sid::ROBOT_STATUS)
        .map(|h| h.params.iter().filter_map(|id| mib::params::by_id(*id)).collect())
        .unwrap_or_default();
    for r in 1..=robots {
        hub.add_robot(r);
        hub.mode(r, "ROBOT", "OPERATIONAL");
        hub.config(r, ConfigState::from_mib(r % mib::robot::NUM_STATES as u8));
    }
    let period = Duration::from_secs_f64(1.0 / hz.max(0.1));
    let mut next = std::time::Instant::now();
    let mut k: u64 = 0;
    loop {
        let now = chrono::Utc::now().timestamp_millis();
        for r in 1..=robots {
            let vals: Vec<(&str, f64)> = params
                .iter()
                .enumerate()
                .map(|(i, p)| {
                    let base = match p.name {
                        "V_BAT_A" | "V_BAT_B" => 11.5 + ((k as f64 + r as f64 * 7.0) / 50.0).sin(),
                        _ => ((k + i as u64 + r as u64) % 100) as f64 / 100.0,
                    };
                    (p.name, base)
                })
                .collect();
            hub.heard(r, now);
            hub.hk(r, now, &vals);
        }
        k += 1;
        next += period;
        let wait = next.saturating_duration_since(std::time::Instant::now());
        std::thread::sleep(wait);
    }
}

/// Archive stand-in for the synthetic feed: one day of V_BAT_A of robot 1 at 10 Hz
/// (864 000 samples ending at start-up, with one outlier and one NaN), decimated with
/// the reference `dashboard::decimate` — so the benchmark's day plot measures the
/// server, the transfer and the drawing, not an archive query.
struct DayArchive {
    samples: Vec<(i64, f64)>,
}

impl DayArchive {
    fn new() -> DayArchive {
        let end = chrono::Utc::now().timestamp_millis();
        let n = 864_000i64;
        let mut samples: Vec<(i64, f64)> = (0..n)
            .map(|i| {
                let t = end - (n - i) * 100;
                (
                    t,
                    11.5 + (i as f64 / 36_000.0).sin() * 0.8 + ((i * 7919) % 100) as f64 / 1000.0,
                )
            })
            .collect();
        samples[400_000].1 = 1000.0;
        samples[500_000].1 = f64::NAN;
        DayArchive { samples }
    }
}

impl dashboard::Series for DayArchive {
    fn decimate(&self, robot: u8, param: &str, t0: i64, t1: i64, columns: usize) -> Vec<(i64, f64, f64)> {
        if robot != 1 || param != "V_BAT_A" {
            return Vec::new();
        }
        dashboard::decimate(&self.samples, t0, t1, columns).0
    }
}

/// Commander for the synthetic feed: records TCs, never sends them anywhere.
struct Refuse;
impl dashboard::Commander for Refuse {
    fn send_tc(&self, _: u8, name: &str, _: &[i64]) -> Result<String, dashboard::CommandError> {
        Err(dashboard::CommandError(format!(
            "synthetic feed: {name} not sent (no robots)"
        )))
    }
    fn ack_alarm(&self, id: u64) -> Result<(), dashboard::CommandError> {
        Err(dashboard::CommandError(format!("synthetic feed: no alarm {id}")))
    }
    fn shelve_alarm(&self, id: u64, _: i64) -> Result<(), dashboard::CommandError> {
        Err(dashboard::CommandError(format!("synthetic feed: no alarm {id}")))
    }
    fn plans(&self) -> Vec<dashboard::PlanInfo> {
        Vec::new()
    }
    fn start_plan(&self, name: &str, _: bool) -> Result<String, dashboard::PlanStartError> {
        Err(dashboard::PlanStartError::Unknown(format!(
            "synthetic feed: no plan {name}"
        )))
    }
}

fn main() -> Result<()> {
    let o = opts()?;
    let hub = Hub::new();
    let _procs;
    let mut listing = Vec::new();
    let commander: Arc<dyn dashboard::Commander> = match o.synthetic {
        Some(n) => {
            _procs = Procs(Vec::new());
            let h = hub.clone();
            std::thread::spawn(move || synthetic(h, n, o.hz));
            Arc::new(Refuse)
        }
        None => {
            let bin = find_obsw(o.obsw.clone())?;
            let mut procs = Procs(Vec::new());
            let mut links = Vec::new();
            for r in 1..=o.robots {
                let (child, tc, ctl) = start_obsw(&bin, r, o.speed)?;
                procs.0.push(child);
                links.push((r, tc));
                listing.push(serde_json::json!({"robot": r, "tc": tc.to_string(), "sim_ctl": ctl.to_string()}));
            }
            _procs = procs;
            for &(r, _) in &links {
                hub.link(r, LinkState::Connecting);
            }
            Arc::new(LinkFeed::start(hub.clone(), &links)?)
        }
    };
    let series: Arc<dyn dashboard::Series> = match o.synthetic {
        Some(_) => Arc::new(DayArchive::new()),
        None => Arc::new(NoArchive),
    };
    let running = dashboard::spawn(o.http, o.token.clone(), hub, commander, series)?;
    let mut url = format!("http://{}/", running.local_addr());
    if let Some(t) = &o.token {
        url.push_str(&format!("?token={t}"));
    }
    println!("{}", serde_json::json!({"url": url, "robots": listing}));
    eprintln!("dashboard at {url} (close stdin or Ctrl-C to stop)");
    // Serve until stdin closes (the test harness closes it) or the process is killed.
    let mut sink = Vec::new();
    let _eof_or_error = std::io::stdin().read_to_end(&mut sink);
    running.stop();
    Ok(())
}
