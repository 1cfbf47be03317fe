//! The collector's TOML configuration (see `docs/collector.md` for the reference), read
//! with every error located as file:line:column.

use std::collections::BTreeMap;
use std::net::{SocketAddr, ToSocketAddrs};
use std::ops::Range;
use std::path::{Path, PathBuf};

use serde::Deserialize;

use crate::link::{FrameOptions, Transport};

/// Longest pause between reconnection attempts ([`mib::ground_config::GROUND_RECONNECT_CAP_MS`]).
pub const MAX_BACKOFF_CAP_MS: u64 = mib::ground_config::GROUND_RECONNECT_CAP_MS as u64;

#[derive(Deserialize, Debug, Default)]
#[serde(deny_unknown_fields)]
struct FileCfg {
    /// Default transport: "frames" (the default), or a lab link "lab-udp" or "lab-tcp".
    transport: Option<toml::Spanned<String>>,
    /// Key directory of the frame link (`ground keys create`), relative to this file's
    /// folder; robot N uses KEYS/robot-N/.
    keys: Option<toml::Spanned<String>>,
    /// The space link's TC SPI, 1 or 2 (after a key change, `LINK_SPI_SELECT`).
    tc_spi: Option<toml::Spanned<u16>>,
    /// SDLS on the robots' TM frames: "encrypt" (the default) or "clear" (their `--tm-sdls`).
    tm_sdls: Option<toml::Spanned<String>>,
    /// Delete archived data older than this ("30d", "12h", "90m", "45s").
    retain: Option<toml::Spanned<String>>,
    /// Plan files the dashboard offers (relative to this file's folder).
    #[serde(default)]
    plans: Vec<toml::Spanned<String>>,
    #[serde(default)]
    link: LinkFile,
    #[serde(default)]
    gaps: GapsFile,
    #[serde(default)]
    alarms: AlarmsFile,
    #[serde(default)]
    robot: Vec<RobotFile>,
}

#[derive(Deserialize, Debug, Default)]
#[serde(deny_unknown_fields)]
struct LinkFile {
    loss_timeout_ms: Option<toml::Spanned<u64>>,
    max_backoff_ms: Option<toml::Spanned<u64>>,
    lease_renew_ms: Option<toml::Spanned<u64>>,
}

#[derive(Deserialize, Debug, Default)]
#[serde(deny_unknown_fields)]
struct GapsFile {
    settle_ms: Option<u64>,
    retry_ms: Option<toml::Spanned<u64>>,
    max_tries: Option<toml::Spanned<u32>>,
}

#[derive(Deserialize, Debug, Default)]
#[serde(deny_unknown_fields)]
struct AlarmsFile {
    stale_hk_intervals: Option<toml::Spanned<u32>>,
    event_min_severity: Option<toml::Spanned<String>>,
    limits: Option<bool>,
}

#[derive(Deserialize, Debug)]
#[serde(deny_unknown_fields)]
struct RobotFile {
    number: toml::Spanned<i64>,
    addr: Option<toml::Spanned<String>>,
    transport: Option<toml::Spanned<String>>,
    /// Over frames: the local address this robot's TM frames arrive at.
    tm_listen: Option<toml::Spanned<String>>,
    /// The space link over this serial device or Unix socket instead of UDP (the CLI's
    /// `--serial N=PATH`), relative to this file's folder.
    serial: Option<toml::Spanned<String>>,
    hk_interval_ms: Option<toml::Spanned<u32>>,
    name: Option<String>,
}

/// One robot to follow.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RobotCfg {
    pub number: u8,
    pub addr: SocketAddr,
    pub transport: Transport,
    /// Keys and TM address of the frame link (with [`Transport::Frames`]).
    pub frames: Option<FrameOptions>,
    /// ROBOT_STATUS collection interval commanded at each subscription (ms).
    pub hk_interval_ms: Option<u32>,
    pub name: Option<String>,
}

/// A plan the dashboard offers (`plans = [...]`), checked when the configuration is read.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PlanCfg {
    /// The plan's `name`, by which the page starts it.
    pub name: String,
    pub path: PathBuf,
}

/// Everything the collector runs with.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Config {
    pub robots: Vec<RobotCfg>,
    /// Plans the dashboard can start (`ground collect --http`).
    pub plans: Vec<PlanCfg>,
    pub retain_ms: Option<i64>,
    pub loss_timeout_ms: u64,
    pub max_backoff_ms: u64,
    pub lease_renew_ms: u64,
    pub gap_settle_ms: u64,
    pub gap_retry_ms: u64,
    pub gap_max_tries: u32,
    pub stale_hk_intervals: u32,
    pub event_min_severity: mib::events::Severity,
    pub limits: bool,
}

impl Default for Config {
    fn default() -> Self {
        Config {
            robots: Vec::new(),
            plans: Vec::new(),
            retain_ms: None,
            loss_timeout_ms: mib::ground_config::LINK_LOSS_MS as u64,
            max_backoff_ms: MAX_BACKOFF_CAP_MS,
            lease_renew_ms: super::onboard::LEASE_RENEW_MS as u64,
            gap_settle_ms: mib::ground_config::GAP_SETTLE_MS as u64,
            gap_retry_ms: mib::ground_config::GAP_RETRY_MS as u64,
            gap_max_tries: mib::ground_config::GAP_MAX_TRIES,
            stale_hk_intervals: mib::ground_config::STALE_HK_INTERVALS,
            event_min_severity: mib::events::Severity::Medium,
            limits: true,
        }
    }
}

/// One configuration error with its place.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct CfgError {
    pub line: usize,
    pub column: usize,
    pub message: String,
}

/// All errors of a configuration file, each shown as `file:line:column: message`.
#[derive(Clone, Debug)]
pub struct CfgErrors {
    pub file: String,
    pub errors: Vec<CfgError>,
}

impl std::fmt::Display for CfgErrors {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        for (i, e) in self.errors.iter().enumerate() {
            if i > 0 {
                writeln!(f)?;
            }
            write!(f, "{}:{}:{}: {}", self.file, e.line, e.column, e.message)?;
        }
        Ok(())
    }
}

impl std::error::Error for CfgErrors {}

/// Parses a duration such as "30d", "12h", "90m", "45s" or "500ms" into ms.
pub fn parse_duration_ms(s: &str) -> Option<i64> {
    let s = s.trim();
    let split = s.find(|c: char| !c.is_ascii_digit())?;
    let (num, unit) = s.split_at(split);
    let n: i64 = num.parse().ok()?;
    let mul = match unit.trim() {
        "ms" => 1,
        "s" => 1_000,
        "m" => 60_000,
        "h" => 3_600_000,
        "d" => 86_400_000,
        "w" => 7 * 86_400_000,
        _ => return None,
    };
    n.checked_mul(mul).filter(|v| *v > 0)
}

/// A duration in the largest unit of [`parse_duration_ms`] that holds it exactly
/// ("3m", "30d", "500ms"): how the collector shows a retention period.
pub fn format_duration_ms(ms: i64) -> String {
    const UNITS: [(&str, i64); 5] = [
        ("w", 7 * 86_400_000),
        ("d", 86_400_000),
        ("h", 3_600_000),
        ("m", 60_000),
        ("s", 1_000),
    ];
    match UNITS.iter().find(|(_, u)| ms != 0 && ms % u == 0) {
        Some((name, u)) => format!("{}{name}", ms / u),
        None => format!("{ms}ms"),
    }
}

fn unknown_transport(t: &str) -> String {
    format!("transport \"{t}\": use \"frames\" (the default) or a lab link, \"lab-udp\" or \"lab-tcp\"")
}

fn transport_of(s: &str) -> Option<Transport> {
    match s.to_ascii_lowercase().as_str() {
        "lab-udp" => Some(Transport::Udp),
        "lab-tcp" => Some(Transport::Tcp),
        "frames" => Some(Transport::Frames),
        _ => None,
    }
}

/// Default address of robot `n` over a transport (defined with the links, in ground-ops).
pub use crate::link::default_addr;

struct Cx<'a> {
    src: &'a str,
    errors: Vec<CfgError>,
}

impl Cx<'_> {
    fn err(&mut self, span: Range<usize>, message: impl Into<String>) {
        let (line, column) = crate::plan::line_col(self.src, span.start);
        self.errors.push(CfgError {
            line,
            column,
            message: message.into(),
        });
    }
}

/// Deserializes `src`, recording every error in `cx`: after an error (an unknown key,
/// a value of the wrong type, a missing field) the entry it points at is left out and
/// the rest is read again, so one error does not hide the others. `None` if the text is
/// not TOML or an error points at nothing that can be left out.
fn read_all(src: &str, cx: &mut Cx<'_>) -> Option<FileCfg> {
    let (mut doc, errors) = toml::de::DeTable::parse_recoverable(src);
    if !errors.is_empty() {
        for e in errors {
            cx.err(e.span().unwrap_or(0..0), e.message().to_string());
        }
        return None;
    }
    loop {
        match FileCfg::deserialize(toml::de::Deserializer::from(doc.clone())) {
            Ok(f) => return Some(f),
            Err(e) => {
                let span = e.span().unwrap_or(0..0);
                cx.err(span.clone(), e.message().to_string());
                if !leave_out(doc.get_mut(), span.start) {
                    return None;
                }
            }
        }
    }
}

/// Removes from `t` the innermost entry (key and value, or array element) whose text
/// holds byte offset `at`; false if there is none. Every sub-table is searched: the
/// span of a `[table]` value need not cover its keys.
fn leave_out(t: &mut toml::de::DeTable<'_>, at: usize) -> bool {
    use toml::de::DeValue;
    let holds = |span: Range<usize>| span.contains(&at);
    let mut hit = None;
    for (k, v) in t.iter_mut() {
        let inner = match v.get_mut() {
            DeValue::Table(sub) => leave_out(sub, at),
            DeValue::Array(items) => {
                let mut found = false;
                let mut drop = None;
                for (i, item) in items.iter_mut().enumerate() {
                    let span = item.span();
                    if let DeValue::Table(sub) = item.get_mut() {
                        if leave_out(sub, at) {
                            found = true;
                            break;
                        }
                    }
                    if holds(span) {
                        drop = Some(i);
                        break;
                    }
                }
                if let Some(i) = drop {
                    let mut kept = toml::de::DeArray::new();
                    for (j, item) in items.iter().enumerate() {
                        if j != i {
                            kept.push(item.clone());
                        }
                    }
                    *items = kept;
                    found = true;
                }
                found
            }
            _ => false,
        };
        if inner {
            return true;
        }
        if holds(k.span()) || holds(v.span()) {
            hit = Some(k.clone());
            break;
        }
    }
    match hit {
        Some(k) => t.remove(&k).is_some(),
        None => false,
    }
}

/// Reads a configuration text; `file` names it in errors.
pub fn parse(file: &str, src: &str) -> Result<Config, CfgErrors> {
    let mut cx = Cx {
        src,
        errors: Vec::new(),
    };
    let Some(f) = read_all(src, &mut cx) else {
        return Err(CfgErrors {
            file: file.into(),
            errors: cx.errors,
        });
    };
    let mut c = Config::default();
    let default_transport = match &f.transport {
        Some(t) => transport_of(t.get_ref()).unwrap_or_else(|| {
            cx.err(t.span(), unknown_transport(t.get_ref()));
            Transport::Frames
        }),
        None => Transport::Frames,
    };
    let tc_spi = match &f.tc_spi {
        None => mib::link::sdls::TC_SPIS[0],
        Some(v) if mib::link::sdls::TC_SPIS.contains(v.get_ref()) => *v.get_ref(),
        Some(v) => {
            cx.err(v.span(), format!("tc_spi = {}: the TC SPIs are 1 and 2", v.get_ref()));
            mib::link::sdls::TC_SPIS[0]
        }
    };
    let tm_security = match &f.tm_sdls {
        None => ground_link::TmSecurity::Encrypt,
        Some(t) => ground_link::TmSecurity::from_name(t.get_ref()).unwrap_or_else(|| {
            cx.err(
                t.span(),
                format!("tm_sdls = \"{}\": \"encrypt\" or \"clear\"", t.get_ref()),
            );
            ground_link::TmSecurity::Encrypt
        }),
    };
    if let Some(r) = &f.retain {
        match parse_duration_ms(r.get_ref()) {
            Some(ms) => c.retain_ms = Some(ms),
            None => cx.err(
                r.span(),
                format!("retain \"{}\": a duration like \"30d\", \"12h\", \"90m\"", r.get_ref()),
            ),
        }
    }
    if let Some(v) = &f.link.loss_timeout_ms {
        c.loss_timeout_ms = *v.get_ref();
    }
    if let Some(v) = &f.link.max_backoff_ms {
        if *v.get_ref() == 0 || *v.get_ref() > MAX_BACKOFF_CAP_MS {
            cx.err(
                v.span(),
                format!("max_backoff_ms = {}: must be 1..={MAX_BACKOFF_CAP_MS}", v.get_ref()),
            );
        } else {
            c.max_backoff_ms = *v.get_ref();
        }
    }
    if let Some(v) = &f.link.lease_renew_ms {
        if !(100..=60_000).contains(v.get_ref()) {
            cx.err(
                v.span(),
                format!("lease_renew_ms = {}: must be 100..=60000", v.get_ref()),
            );
        } else {
            c.lease_renew_ms = *v.get_ref();
        }
    }
    if let Some(v) = f.gaps.settle_ms {
        c.gap_settle_ms = v;
    }
    if let Some(v) = &f.gaps.retry_ms {
        if *v.get_ref() < 100 {
            cx.err(v.span(), "retry_ms must be at least 100");
        } else {
            c.gap_retry_ms = *v.get_ref();
        }
    }
    if let Some(v) = &f.gaps.max_tries {
        if *v.get_ref() == 0 {
            cx.err(v.span(), "max_tries must be at least 1");
        } else {
            c.gap_max_tries = *v.get_ref();
        }
    }
    if let Some(v) = &f.alarms.stale_hk_intervals {
        if *v.get_ref() < 2 {
            cx.err(v.span(), "stale_hk_intervals must be at least 2");
        } else {
            c.stale_hk_intervals = *v.get_ref();
        }
    }
    if let Some(v) = &f.alarms.event_min_severity {
        use mib::events::Severity as S;
        match [S::Low, S::Medium, S::High]
            .into_iter()
            .find(|s| s.name().eq_ignore_ascii_case(v.get_ref()))
        {
            Some(s) => c.event_min_severity = s,
            None => cx.err(
                v.span(),
                format!("event_min_severity \"{}\": low, medium or high", v.get_ref()),
            ),
        }
    }
    if let Some(l) = f.alarms.limits {
        c.limits = l;
    }
    let base = Path::new(file).parent().unwrap_or(Path::new(""));
    for p in &f.plans {
        let path = base.join(p.get_ref());
        match crate::plan::load(&path) {
            Ok(plan) => {
                if c.plans.iter().any(|q| q.name == plan.name) {
                    cx.err(
                        p.span(),
                        format!("plan \"{}\" ({}) is listed twice", plan.name, path.display()),
                    );
                } else {
                    c.plans.push(PlanCfg { name: plan.name, path });
                }
            }
            Err(e) => match e.diagnostics() {
                Some(d) => {
                    let lines: Vec<String> = d.iter().map(|x| x.to_string()).collect();
                    cx.err(
                        p.span(),
                        format!(
                            "plan {} has {} error(s):\n{}",
                            path.display(),
                            d.len(),
                            lines.join("\n")
                        ),
                    )
                }
                None => {
                    let why = e.io_error().map_or_else(|| e.to_string(), |io| io.to_string());
                    cx.err(p.span(), format!("plan {}: cannot read it: {why}", path.display()))
                }
            },
        }
    }
    let mut seen: BTreeMap<u8, ()> = BTreeMap::new();
    for r in &f.robot {
        let n = *r.number.get_ref();
        let Some(number) = u8::try_from(n).ok().filter(|n| mib::apid::robot_apid(*n).is_some()) else {
            cx.err(
                r.number.span(),
                format!(
                    "robot number {n} outside {}..={}",
                    mib::apid::ROBOT_MIN,
                    mib::apid::ROBOT_MAX
                ),
            );
            continue;
        };
        if seen.insert(number, ()).is_some() {
            cx.err(r.number.span(), format!("robot {number} is listed twice"));
            continue;
        }
        let transport = match &r.transport {
            None => default_transport,
            Some(t) => match transport_of(t.get_ref()) {
                Some(t) => t,
                None => {
                    cx.err(t.span(), unknown_transport(t.get_ref()));
                    continue;
                }
            },
        };
        let addr = match &r.addr {
            None => default_addr(number, transport),
            Some(a) => match a.get_ref().to_socket_addrs().ok().and_then(|mut i| i.next()) {
                Some(s) => s,
                None => {
                    cx.err(
                        a.span(),
                        format!("address \"{}\" is not HOST:PORT or does not resolve", a.get_ref()),
                    );
                    continue;
                }
            },
        };
        let hk_interval_ms = match &r.hk_interval_ms {
            Some(v) if !(mib::hk::MIN_INTERVAL_MS..=mib::hk::MAX_INTERVAL_MS).contains(v.get_ref()) => {
                cx.err(
                    v.span(),
                    format!(
                        "hk_interval_ms = {} outside {}..={}",
                        v.get_ref(),
                        mib::hk::MIN_INTERVAL_MS,
                        mib::hk::MAX_INTERVAL_MS
                    ),
                );
                continue;
            }
            Some(v) => Some(*v.get_ref()),
            None => None,
        };
        let tm_listen = match &r.tm_listen {
            None => None,
            Some(a) => match a.get_ref().to_socket_addrs().ok().and_then(|mut i| i.next()) {
                Some(s) => Some(s),
                None => {
                    cx.err(
                        a.span(),
                        format!("tm_listen \"{}\" is not HOST:PORT or does not resolve", a.get_ref()),
                    );
                    continue;
                }
            },
        };
        if let Some(p) = &r.serial {
            if transport != Transport::Frames {
                cx.err(
                    p.span(),
                    format!("robot {number}: serial is the space link over a serial line; it does not go with a lab transport"),
                );
                continue;
            }
            if r.tm_listen.is_some() {
                cx.err(
                    p.span(),
                    format!("robot {number}: serial carries its TM frames too; it does not go with tm_listen"),
                );
                continue;
            }
            if p.get_ref().is_empty() {
                cx.err(
                    p.span(),
                    format!("robot {number}: the path of the serial device is missing"),
                );
                continue;
            }
        }
        if transport != Transport::Frames && !addr.ip().is_loopback() {
            cx.err(
                r.number.span(),
                format!("robot {number} at {addr}: a lab link (bare packets) is for robots on loopback addresses only"),
            );
            continue;
        }
        let frames = if transport == Transport::Frames {
            let Some(k) = &f.keys else {
                cx.err(
                    r.number.span(),
                    format!("robot {number} over frames: the file needs keys = \"DIR\" (ground keys create DIR)"),
                );
                continue;
            };
            let folder = Path::new(file).parent().unwrap_or(Path::new(""));
            let keys = folder.join(k.get_ref());
            Some(FrameOptions {
                tm_listen: tm_listen.map(|a| (number, a)).into_iter().collect(),
                serial: r
                    .serial
                    .as_ref()
                    .map(|p| (number, folder.join(p.get_ref())))
                    .into_iter()
                    .collect(),
                tc_spi,
                tm_security,
                ..FrameOptions::new(keys)
            })
        } else {
            None
        };
        c.robots.push(RobotCfg {
            number,
            addr,
            transport,
            frames,
            hk_interval_ms,
            name: r.name.clone(),
        });
    }
    if cx.errors.is_empty() {
        Ok(c)
    } else {
        Err(CfgErrors {
            file: file.into(),
            errors: cx.errors,
        })
    }
}

/// Why a configuration file could not be used.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum LoadError {
    #[error("cannot read {}: {err}", path.display())]
    Read { path: PathBuf, err: std::io::Error },
    /// Every error of the file, located as file:line:column.
    #[error(transparent)]
    Invalid(#[from] CfgErrors),
}

/// Reads and parses a configuration file.
pub fn load(path: &Path) -> Result<Config, LoadError> {
    let src = std::fs::read_to_string(path).map_err(|err| LoadError::Read {
        path: path.to_path_buf(),
        err,
    })?;
    Ok(parse(&path.display().to_string(), &src)?)
}

#[cfg(test)]
mod tests;
