//! The collector's TOML configuration (see `docs/collector.md` for the reference), read
//! with every error located as file:line:column.

use std::collections::BTreeMap;
use std::net::{SocketAddr, ToSocketAddrs};
use std::ops::Range;
use std::path::{Path, PathBuf};

use serde::Deserialize;

use crate::link::{FrameOptions, Transport};

/// Longest pause between reconnection attempts ([`mib::config::GROUND_RECONNECT_CAP_MS`]).
pub const MAX_BACKOFF_CAP_MS: u64 = mib::config::GROUND_RECONNECT_CAP_MS as u64;

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
            loss_timeout_ms: mib::config::LINK_LOSS_MS as u64,
            max_backoff_ms: MAX_BACKOFF_CAP_MS,
            lease_renew_ms: super::onboard::LEASE_RENEW_MS as u64,
            gap_settle_ms: mib::config::GAP_SETTLE_MS as u64,
            gap_retry_ms: mib::config::GAP_RETRY_MS as u64,
            gap_max_tries: mib::config::GAP_MAX_TRIES,
            stale_hk_intervals: mib::config::STALE_HK_INTERVALS,
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
mod tests {
    use super::*;

    // verifies: GND-11
    #[test]
    fn a_full_config_reads() {
        let c = parse(
            "c.toml",
            r#"
transport = "lab-udp"
retain = "30d"
[link]
loss_timeout_ms = 4000
max_backoff_ms = 2000
[gaps]
retry_ms = 2000
max_tries = 4
[alarms]
stale_hk_intervals = 3
event_min_severity = "high"
[[robot]]
number = 1
addr = "127.0.0.1:9001"
hk_interval_ms = 100
[[robot]]
number = 2
transport = "lab-tcp"
"#,
        )
        .unwrap();
        assert_eq!(c.robots.len(), 2);
        assert_eq!(c.robots[0].addr, "127.0.0.1:9001".parse().unwrap());
        assert_eq!(c.robots[1].transport, Transport::Tcp);
        assert_eq!(c.robots[1].addr, default_addr(2, Transport::Tcp));
        assert_eq!(c.retain_ms, Some(30 * 86_400_000));
        assert_eq!(c.max_backoff_ms, 2000);
        assert_eq!(c.event_min_severity, mib::events::Severity::High);
        // The link-loss rule of every front end, with the configured floor.
        let loss = |hk| {
            crate::tracker::LinkWatch::new(hk, 0)
                .with_floor(c.loss_timeout_ms)
                .loss_after_ms()
        };
        assert_eq!(loss(1000), 4000);
        assert_eq!(loss(2000), 5000);
    }

    // verifies: OPS-LINK-DEFAULT-01
    #[test]
    fn robots_use_the_space_link_unless_a_lab_link_is_named_and_local() {
        let e = parse("c.toml", "[[robot]]\nnumber = 1\n").unwrap_err().to_string();
        assert!(e.contains("robot 1 over frames: the file needs keys"), "{e}");
        let c = parse("c.toml", "keys = \"k\"\n[[robot]]\nnumber = 1\n").unwrap();
        assert_eq!(c.robots[0].transport, Transport::Frames);
        let f = c.robots[0].frames.as_ref().unwrap();
        assert_eq!((f.tc_spi, f.tm_security), (1, ground_link::TmSecurity::Encrypt));
        let c = parse(
            "c.toml",
            "keys = \"k\"\ntc_spi = 2\ntm_sdls = \"clear\"\n[[robot]]\nnumber = 1\n",
        )
        .unwrap();
        let f = c.robots[0].frames.as_ref().unwrap();
        assert_eq!((f.tc_spi, f.tm_security), (2, ground_link::TmSecurity::Clear));
        let e = parse("c.toml", "keys = \"k\"\ntc_spi = 3\ntm_sdls = \"open\"\n")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("c.toml:2:10: tc_spi = 3") && e.contains("c.toml:3:11: tm_sdls"),
            "{e}"
        );
        let e = parse("c.toml", "transport = \"udp\"\n").unwrap_err().to_string();
        assert!(e.contains("\"lab-udp\""), "{e}");
        let e = parse(
            "c.toml",
            "transport = \"lab-udp\"\n[[robot]]\nnumber = 1\naddr = \"10.1.2.3:7301\"\n",
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("c.toml:3:10: robot 1 at 10.1.2.3:7301: a lab link"), "{e}");
    }

    // verifies: LINK-STREAM-04, GND-11
    #[test]
    fn a_robot_takes_the_space_link_over_a_serial_line_only_over_frames() {
        let c = parse(
            "cfg/c.toml",
            "keys = \"k\"\n[[robot]]\nnumber = 1\nserial = \"/dev/ttyACM0\"\n[[robot]]\nnumber = 2\nserial = \"sock\"\n[[robot]]\nnumber = 3\n",
        )
        .unwrap();
        let serial = |i: usize| {
            c.robots[i]
                .frames
                .as_ref()
                .map(|f| f.serial.clone())
                .unwrap_or_default()
        };
        assert_eq!(serial(0).get(&1), Some(&PathBuf::from("/dev/ttyACM0")));
        assert_eq!(serial(0).len(), 1);
        // Relative to the file's folder, like keys.
        assert_eq!(serial(1).get(&2), Some(&PathBuf::from("cfg/sock")));
        assert!(serial(2).is_empty(), "robot 3 stays on UDP");
        let e = parse(
            "c.toml",
            "keys = \"k\"\n[[robot]]\nnumber = 1\ntransport = \"lab-udp\"\nserial = \"/dev/a\"\n\
             [[robot]]\nnumber = 2\ntm_listen = \"127.0.0.1:9000\"\nserial = \"/dev/b\"\n[[robot]]\nnumber = 3\nserial = \"\"\n",
        )
        .unwrap_err();
        let text = e.to_string();
        assert!(text.contains("c.toml:5:10: robot 1: serial is the space link over a serial line; it does not go with a lab transport"), "{text}");
        assert!(
            text.contains("c.toml:9:10: robot 2: serial carries its TM frames too; it does not go with tm_listen"),
            "{text}"
        );
        assert!(
            text.contains("c.toml:12:10: robot 3: the path of the serial device is missing"),
            "{text}"
        );
        assert_eq!(e.errors.len(), 3, "{text}");
    }

    // verifies: GND-11
    #[test]
    fn every_error_has_its_line_and_column() {
        let e = parse(
            "c.toml",
            "retain = \"30 days\"\n[link]\nmax_backoff_ms = 9000\n[[robot]]\nnumber = 300\n[[robot]]\nnumber = 1\ntransport = \"x\"\n",
        )
        .unwrap_err();
        let text = e.to_string();
        assert!(text.contains("c.toml:1:10: retain"), "{text}");
        assert!(text.contains("c.toml:3:18: max_backoff_ms"), "{text}");
        assert!(text.contains("c.toml:5:10: robot number 300"), "{text}");
        assert!(text.contains("c.toml:8:13: transport"), "{text}");
        assert_eq!(e.errors.len(), 4);
    }

    // verifies: ALM-CFG-01, GND-11
    #[test]
    fn an_unknown_key_or_a_wrong_type_does_not_hide_the_other_errors() {
        // Issue 26: one unknown key used to be the only error shown of seven.
        let src = "retain = \"30 days\"\nretian = \"1d\"\n[link]\nmax_backoff_ms = 9000\nloss_timeout_ms = \"x\"\n\
                   [alarms]\nlimit = true\n[[robot]]\nnumber = 300\n[[robot]]\nnumber = 1\ntransport = \"x\"\naddres = \"y\"\n\
                   [[robot]]\nname = \"no number\"\n";
        let e = parse("c.toml", src).unwrap_err();
        let text = e.to_string();
        for want in [
            "c.toml:1:10: retain",
            "c.toml:2:1: unknown field `retian`",
            "c.toml:4:18: max_backoff_ms",
            "c.toml:5:19: invalid type",
            "c.toml:7:1: unknown field `limit`",
            "c.toml:9:10: robot number 300",
            "c.toml:12:13: transport",
            "c.toml:13:1: unknown field `addres`",
            "missing field `number`",
        ] {
            assert!(text.contains(want), "{want:?} not in:\n{text}");
        }
        assert_eq!(e.errors.len(), 9, "{text}");
    }

    // verifies: ALM-MSG-01
    #[test]
    fn durations_are_shown_in_the_largest_exact_unit() {
        for s in ["3m", "30d", "12h", "45s", "500ms", "2w", "90m"] {
            assert_eq!(format_duration_ms(parse_duration_ms(s).unwrap()), s);
        }
        assert_eq!(format_duration_ms(parse_duration_ms("36h").unwrap()), "36h");
        assert_eq!(format_duration_ms(parse_duration_ms("7d").unwrap()), "1w");
    }

    // verifies: GND-11
    #[test]
    fn unknown_keys_and_bad_toml_are_located() {
        let e = parse("c.toml", "[link]\nloss_timeout = 5\n").unwrap_err();
        assert_eq!((e.errors[0].line, e.errors[0].column), (2, 1));
        assert!(e.errors[0].message.contains("unknown field"), "{}", e);
        let e = parse("c.toml", "[[robot]]\nnumber = 1\nnumber = 2\n").unwrap_err();
        assert_eq!(e.errors[0].line, 3);
        let e = parse("c.toml", "[[robot]]\nnumber = 1\n[[robot]]\nnumber = 1\n").unwrap_err();
        assert!(e.to_string().contains("c.toml:4:10: robot 1 is listed twice"));
    }

    // verifies: GND-11, GND-19
    #[test]
    fn plans_are_checked_and_their_errors_located() {
        let dir = std::env::temp_dir().join(format!("collect-cfg-plans-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(
            dir.join("ok.toml"),
            "name = \"ping\"\n[[robot]]\nnumber = 1\n[[step]]\nid = \"p\"\nrobot = 1\naction = \"command\"\ntc = \"PING\"\n",
        )
        .unwrap();
        std::fs::write(
            dir.join("bad.toml"),
            "name = \"bad\"\n[[robot]]\nnumber = 1\n[[step]]\nid = \"p\"\nrobot = 1\naction = \"fly\"\n",
        )
        .unwrap();
        let cfg_file = dir.join("c.toml");
        let file = cfg_file.display().to_string();
        let c = parse(&file, "plans = [\"ok.toml\"]\n").unwrap();
        assert_eq!(
            c.plans,
            vec![PlanCfg {
                name: "ping".into(),
                path: dir.join("ok.toml")
            }]
        );
        let e = parse(
            &file,
            "plans = [\"ok.toml\", \"bad.toml\", \"none.toml\", \"ok.toml\"]\n",
        )
        .unwrap_err();
        let text = e.to_string();
        assert_eq!(e.errors.len(), 3, "{text}");
        assert!(
            text.contains(&format!("{file}:1:21: plan {}", dir.join("bad.toml").display())),
            "{text}"
        );
        // The plan's own error, located in the plan file.
        assert!(
            text.contains(&format!("{}:7:", dir.join("bad.toml").display())),
            "{text}"
        );
        assert!(
            text.contains(&format!(
                "{file}:1:33: plan {}: cannot read",
                dir.join("none.toml").display()
            )),
            "{text}"
        );
        assert!(
            text.contains(&format!("{file}:1:46: plan \"ping\"")) && text.contains("listed twice"),
            "{text}"
        );
        let _ = std::fs::remove_dir_all(&dir);
    }

    // verifies: GND-11
    #[test]
    fn durations_read() {
        assert_eq!(parse_duration_ms("30d"), Some(2_592_000_000));
        assert_eq!(parse_duration_ms("90m"), Some(5_400_000));
        assert_eq!(parse_duration_ms("500ms"), Some(500));
        assert_eq!(parse_duration_ms("0s"), None);
        assert_eq!(parse_duration_ms("d"), None);
        assert_eq!(parse_duration_ms("5x"), None);
    }
}
