//! `ground archive …`: query, export, plot, import, check, gaps, status and latest values
//! of the archive.

use std::io::Write;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use clap::{Args, Subcommand};
use ground::archive::{self, Filter};

use crate::exit::{self, coded};
use crate::output::{err_line, out};
use crate::plot;

#[derive(Args, Debug, Clone)]
pub(crate) struct FilterArgs {
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

pub(crate) fn parse_time(s: &str) -> Result<i64> {
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

/// `--type` of `archive query` / `export`: the archive's [`archive::Kind`], parsed here so
/// that the archive library needs no clap.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub(crate) enum KindArg {
    Tc,
    Tm,
    Verification,
    Event,
    Hk,
    Alarm,
    /// TM that did not decode when it arrived.
    Corrupt,
}

impl From<KindArg> for archive::Kind {
    fn from(k: KindArg) -> archive::Kind {
        match k {
            KindArg::Tc => archive::Kind::Tc,
            KindArg::Tm => archive::Kind::Tm,
            KindArg::Verification => archive::Kind::Verification,
            KindArg::Event => archive::Kind::Event,
            KindArg::Hk => archive::Kind::Hk,
            KindArg::Alarm => archive::Kind::Alarm,
            KindArg::Corrupt => archive::Kind::Corrupt,
        }
    }
}

#[derive(Subcommand, Debug)]
pub(crate) enum ArchiveCmd {
    /// Print archived records.
    Query {
        /// What to list.
        #[arg(long = "type", value_enum, default_value = "tm")]
        kind: KindArg,
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
        kind: KindArg,
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

pub(crate) fn archive_cmd(a: ArchiveCmd, path: &Path) -> Result<u8> {
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
            let rows = store.query(kind.into(), &filter.filter()?)?;
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
            let kind = archive::Kind::from(kind);
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
pub(crate) struct PipeWatch<W: Write> {
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

pub(crate) fn fmt_ms(ms: i64) -> String {
    chrono::DateTime::from_timestamp_millis(ms)
        .map_or(ms.to_string(), |t| t.format("%Y-%m-%dT%H:%M:%S%.3fZ").to_string())
}

pub(crate) fn print_gaps(gaps: &[archive::Gap]) -> Result<()> {
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

pub(crate) fn archive_import(path: &Path, file: &Path, robot: u8, json: bool) -> Result<u8> {
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
