//! Reading: queries, exports, the plot decimation, the latest values, the integrity check.

use std::io::Write;

use mib::headers::SeqCount;
use serde::Serialize;

use super::adapter;
use super::codec;
use super::db::{collect, scalar, Db, Val};
use super::schema::{CHUNKS, CHUNK_SPAN_MS};
use super::{connect, ArchiveError, Filter, Kind, RobotSeries, Rows};
use ground_pus::{self as pus, decode_tm};

/// A connection for reading (and for the small updates of alarms, gap notes).
pub struct Store {
    pub(crate) db: Box<dyn Db>,
}

/// One pixel column of a decimated series (engineering values).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Column {
    /// Start of the column's time slot (ms).
    pub t_ms: i64,
    /// Times of the column's first and last sample (ms): a plot tells a hole in the data
    /// from a slot that is merely empty.
    pub t_first_ms: i64,
    pub t_last_ms: i64,
    pub min: f64,
    pub max: f64,
    pub first: f64,
    pub last: f64,
    pub n: u32,
}

/// The newest value of one parameter of one robot.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Latest {
    pub robot: u8,
    pub param: u16,
    pub name: &'static str,
    pub t_ms: i64,
    pub raw: i64,
    pub eng: f64,
    pub unit: &'static str,
}

/// When a robot was last heard.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct Health {
    pub robot: u8,
    /// Ground time of the last TM received (stored or duplicate).
    pub last_heard_ms: i64,
    /// Newest on-board time seen.
    pub last_obt_ms: i64,
    pub packets: i64,
}

/// Result of `archive check`.
#[derive(Clone, Debug, Default, Serialize)]
pub struct CheckReport {
    pub packets: u64,
    pub raw_bytes: u64,
    /// Packets whose CRC or key does not match their bytes: `(robot, apid, seq, obt_ms, why)`.
    pub bad: Vec<(u8, u16, u16, i64, String)>,
    /// Parameters whose chunked values do not match the HK packets stored:
    /// `(robot, param, samples in chunks, values in packets)`.
    pub chunk_mismatch: Vec<(u8, u16, u64, u64)>,
    pub gaps: Vec<super::Gap>,
}

fn robot_of(v: &Val) -> u8 {
    v.int().and_then(|r| u8::try_from(r).ok()).unwrap_or(u8::MAX)
}

fn json(v: &Val) -> serde_json::Value {
    match v {
        Val::Null => serde_json::Value::Null,
        Val::Int(i) => (*i).into(),
        Val::Real(r) => (*r).into(),
        Val::Text(t) => t.clone().into(),
        Val::Blob(b) => pus::hex(b).into(),
    }
}

fn param_def(name: &str) -> Result<&'static mib::params::ParamDef, ArchiveError> {
    mib::params::by_name(name).ok_or_else(|| ArchiveError::NotFound(format!("unknown HK parameter \"{name}\"")))
}

impl Store {
    /// Opens (creating or migrating if needed) the archive at `loc`.
    pub fn open(loc: &str) -> Result<Store, ArchiveError> {
        Ok(Store { db: connect(loc)? })
    }

    /// Opens the archive at `loc` if there is one (never creates a file).
    pub fn open_existing(loc: &str) -> Result<Store, ArchiveError> {
        if !super::exists(loc) {
            return Err(ArchiveError::NotFound(format!("archive {loc} does not exist")));
        }
        Self::open(loc)
    }

    /// The backend connection (for tests and tools).
    pub fn db(&mut self) -> &mut dyn Db {
        self.db.as_mut()
    }

    /// Bytes on disk (SQLite files, PostgreSQL relations with their indexes).
    pub fn size_bytes(&mut self) -> Result<u64, ArchiveError> {
        Ok(self.db.size_bytes()?)
    }

    /// `(packets, raw bytes)` of the stored TM.
    pub fn packet_totals(&mut self) -> Result<(u64, u64), ArchiveError> {
        let r = collect(
            self.db.as_mut(),
            "SELECT COUNT(*), COALESCE(SUM(length(raw)), 0) FROM packet",
            &[],
        )?;
        let row = r.first().cloned().unwrap_or_default();
        Ok((
            row.first().and_then(Val::int).unwrap_or(0) as u64,
            row.get(1).and_then(Val::int).unwrap_or(0) as u64,
        ))
    }

    /// Sequence count after the last TC archived for `apid`.
    pub fn next_tc_seq(&mut self, apid: u16) -> Result<Option<u16>, ArchiveError> {
        let v = scalar(
            self.db.as_mut(),
            "SELECT seq FROM tc WHERE apid = ?1 ORDER BY id DESC LIMIT 1",
            &[Val::Int(apid as i64)],
        )?;
        Ok(v.and_then(|v| v.int()).map(|s| SeqCount::new(s as u16).next().get()))
    }

    /// Sequence count of the TM of `robot`'s `apid` received last (by ground time; the
    /// newest on-board time among those received at that time): where a ground that
    /// stopped left the robot's TM, even when the archive holds TM of an earlier boot or
    /// process with a later on-board clock (which [`Store::positions`] would give).
    pub fn last_received_seq(&mut self, robot: u8, apid: u16) -> Result<Option<u16>, ArchiveError> {
        let v = scalar(
            self.db.as_mut(),
            "SELECT seq FROM packet WHERE robot = ?1 AND apid = ?2 ORDER BY t_ms DESC, obt_ms DESC LIMIT 1",
            &[Val::Int(robot as i64), Val::Int(apid as i64)],
        )?;
        Ok(v.and_then(|v| v.int()).map(|s| SeqCount::new(s as u16).get()))
    }

    /// Robots with TM in the archive.
    pub fn robots(&mut self) -> Result<Vec<u8>, ArchiveError> {
        let rows = collect(self.db.as_mut(), "SELECT robot FROM health ORDER BY robot", &[])?;
        Ok(rows.iter().map(|r| robot_of(&r[0])).collect())
    }

    /// When each robot was last heard.
    pub fn health(&mut self) -> Result<Vec<Health>, ArchiveError> {
        let rows = collect(
            self.db.as_mut(),
            "SELECT robot, last_heard_ms, last_obt_ms, packets FROM health ORDER BY robot",
            &[],
        )?;
        Ok(rows
            .iter()
            .map(|r| Health {
                robot: robot_of(&r[0]),
                last_heard_ms: r[1].int().unwrap_or(0),
                last_obt_ms: r[2].int().unwrap_or(0),
                packets: r[3].int().unwrap_or(0),
            })
            .collect())
    }

    /// Raw samples `(on-board ms, raw value)` of one parameter of one robot in
    /// `[since, until]`, in time order.
    pub fn samples(
        &mut self,
        robot: u8,
        param: u16,
        since: Option<i64>,
        until: Option<i64>,
    ) -> Result<Vec<(i64, i64)>, ArchiveError> {
        let lo = since.unwrap_or(i64::MIN / 4);
        let hi = until.unwrap_or(i64::MAX / 4);
        let mut out: Vec<(i64, i64)> = Vec::new();
        let mut damaged = None;
        self.db.rows(
            &format!(
                "SELECT data FROM {CHUNKS} c WHERE robot = ?1 AND param = ?2 AND t0 >= ?3 AND t0 <= ?4 AND t1 >= ?5 \
                 ORDER BY t0"
            ),
            &[
                Val::Int(robot as i64),
                Val::Int(param as i64),
                Val::Int(lo.saturating_sub(CHUNK_SPAN_MS)),
                Val::Int(hi),
                Val::Int(lo),
            ],
            &mut |r| {
                match r[0].blob().map(codec::decode) {
                    Some(Ok((t, v))) => out.extend(t.into_iter().zip(v).filter(|(t, _)| *t >= lo && *t <= hi)),
                    Some(Err(e)) => damaged = Some(e.to_string()),
                    None => damaged = Some("chunk without data".into()),
                }
                Ok(())
            },
        )?;
        if let Some(d) = damaged {
            return Err(ArchiveError::Damaged(format!("robot {robot} parameter {param}: {d}")));
        }
        if !out.windows(2).all(|w| w[0].0 <= w[1].0) {
            out.sort_by_key(|p| p.0);
        }
        Ok(out)
    }

    /// First and last on-board time of a parameter of a robot, if it has samples.
    pub fn param_span(&mut self, robot: u8, param: u16) -> Result<Option<(i64, i64)>, ArchiveError> {
        let r = collect(
            self.db.as_mut(),
            &format!("SELECT MIN(t0), MAX(t1) FROM {CHUNKS} c WHERE robot = ?1 AND param = ?2"),
            &[Val::Int(robot as i64), Val::Int(param as i64)],
        )?;
        Ok(r.first().and_then(|r| Some((r[0].int()?, r[1].int()?))))
    }

    /// One HK parameter's series per robot: `(robot, [(t_ms, eng)])`.
    pub fn hk_series(&mut self, param: &str, f: &Filter) -> Result<Vec<RobotSeries>, ArchiveError> {
        let def = param_def(param)?;
        let robots = match f.robot {
            Some(r) => vec![r],
            None => self.robots()?,
        };
        let mut out = Vec::new();
        for r in robots {
            let s = self.samples(r, def.id, f.since_ms, f.until_ms)?;
            if !s.is_empty() {
                out.push((r, s.into_iter().map(|(t, v)| (t, def.calib.eng(v))).collect()));
            }
        }
        Ok(out)
    }

    /// Server-side decimation for plots: `columns` pixel columns over `[t0, t1]`, each
    /// with the min, max, first and last engineering value in it (empty columns left
    /// out).
    pub fn decimate(
        &mut self,
        robot: u8,
        param: &str,
        t0: i64,
        t1: i64,
        columns: usize,
    ) -> Result<Vec<Column>, ArchiveError> {
        let def = param_def(param)?;
        let s = self.samples(robot, def.id, Some(t0), Some(t1))?;
        Ok(decimate_samples(&s, |v| def.calib.eng(v), t0, t1, columns))
    }

    /// The newest value of every parameter of `robot` (or of every robot).
    pub fn latest(&mut self, robot: Option<u8>) -> Result<Vec<Latest>, ArchiveError> {
        let robots = match robot {
            Some(r) => vec![r],
            None => self.robots()?,
        };
        let mut out = Vec::new();
        for r in robots {
            let rows = collect(
                self.db.as_mut(),
                &format!(
                    "SELECT c.param, c.data FROM {CHUNKS} c JOIN \
                     (SELECT param, MAX(t1) AS t1 FROM {CHUNKS} a WHERE robot = ?1 GROUP BY param) m \
                     ON c.param = m.param AND c.t1 = m.t1 WHERE c.robot = ?1 ORDER BY c.param"
                ),
                &[Val::Int(r as i64)],
            )?;
            for row in rows {
                let Some(param) = row[0].int().and_then(|p| u16::try_from(p).ok()) else {
                    continue;
                };
                let Some(def) = mib::params::by_id(param) else {
                    continue;
                };
                let (t, v) = codec::decode(row[1].blob().unwrap_or_default())
                    .map_err(|e| ArchiveError::Damaged(format!("robot {r} parameter {param}: {e}")))?;
                if let Some((t, v)) = t.into_iter().zip(v).max_by_key(|p| p.0) {
                    if out.last().is_some_and(|l: &Latest| l.robot == r && l.param == param) {
                        continue;
                    }
                    out.push(Latest {
                        robot: r,
                        param,
                        name: def.name,
                        t_ms: t,
                        raw: v,
                        eng: def.calib.eng(v),
                        unit: def.unit,
                    });
                }
            }
        }
        Ok(out)
    }

    /// Runs a filtered query.
    pub fn query(&mut self, kind: Kind, f: &Filter) -> Result<Rows, ArchiveError> {
        match kind {
            Kind::Tm => self.query_tm(f),
            Kind::Hk => {
                let mut rows = Rows {
                    columns: HK_COLUMNS.iter().map(|s| s.to_string()).collect(),
                    rows: Vec::new(),
                };
                self.each_hk(f, &mut |t, robot, def, raw| {
                    rows.rows.push(vec![
                        t.into(),
                        robot.into(),
                        def.id.into(),
                        def.name.into(),
                        raw.into(),
                        def.calib.eng(raw).into(),
                        def.unit.into(),
                    ]);
                })?;
                Ok(rows)
            }
            Kind::Tc | Kind::Verification | Kind::Event | Kind::Alarm | Kind::Corrupt => self.query_table(kind, f),
        }
    }

    /// Calls `each(t_ms, robot, param, raw)` for the HK samples the filter selects, in
    /// time order (at most `f.limit`).
    fn each_hk(
        &mut self,
        f: &Filter,
        each: &mut dyn FnMut(i64, u8, &'static mib::params::ParamDef, i64),
    ) -> Result<(), ArchiveError> {
        let defs: Vec<&'static mib::params::ParamDef> = if f.params.is_empty() {
            mib::params::PARAMS.iter().collect()
        } else {
            f.params.iter().map(|p| param_def(p)).collect::<Result<_, _>>()?
        };
        let robots = match f.robot {
            Some(r) => vec![r],
            None => self.robots()?,
        };
        let mut series = Vec::new();
        for r in robots {
            for d in &defs {
                let s = self.samples(r, d.id, f.since_ms, f.until_ms)?;
                if !s.is_empty() {
                    series.push((r, *d, s));
                }
            }
        }
        let limit = f.limit.unwrap_or(u64::MAX);
        if series.len() == 1 {
            let (r, d, s) = &series[0];
            for (t, v) in s.iter().take(limit.min(usize::MAX as u64) as usize) {
                each(*t, *r, d, *v);
            }
            return Ok(());
        }
        // Merge the series by time.
        let mut all: Vec<(i64, usize, i64)> = Vec::new();
        for (i, (_, _, s)) in series.iter().enumerate() {
            all.extend(s.iter().map(|(t, v)| (*t, i, *v)));
        }
        all.sort_by_key(|p| (p.0, p.1));
        for (t, i, v) in all.into_iter().take(limit.min(usize::MAX as u64) as usize) {
            each(t, series[i].0, series[i].1, v);
        }
        Ok(())
    }

    /// Writes a query's rows as CSV to `out`; returns the number of rows. HK rows are
    /// written straight from the decoded chunks.
    pub fn export_csv(&mut self, kind: Kind, f: &Filter, out: &mut dyn Write) -> Result<u64, ArchiveError> {
        if kind != Kind::Hk {
            let rows = self.query(kind, f)?;
            out.write_all(super::to_csv(&rows).as_bytes())?;
            return Ok(rows.rows.len() as u64);
        }
        let mut w = std::io::BufWriter::with_capacity(1 << 16, out);
        writeln!(w, "{}", HK_COLUMNS.join(","))?;
        let mut n = 0u64;
        let mut err = None;
        self.each_hk(f, &mut |t, robot, def, raw| {
            if err.is_none() {
                if let Err(e) = writeln!(
                    w,
                    "{t},{robot},{},{},{raw},{},{}",
                    def.id,
                    def.name,
                    def.calib.eng(raw),
                    def.unit
                ) {
                    err = Some(e);
                }
                n += 1;
            }
        })?;
        if let Some(e) = err {
            return Err(e.into());
        }
        w.flush()?;
        Ok(n)
    }

    fn query_tm(&mut self, f: &Filter) -> Result<Rows, ArchiveError> {
        let mut sql = String::from("SELECT robot, apid, seq, obt_ms, t_ms, link_robot, raw FROM packet WHERE 1=1");
        let mut args = Vec::new();
        filters(&mut sql, &mut args, f, "obt_ms");
        sql.push_str(" ORDER BY obt_ms, robot, apid, seq");
        let columns = [
            "t_ms",
            "obt_ms",
            "robot",
            "apid",
            "seq",
            "service",
            "subservice",
            "name",
            "ok",
            "decoded",
            "raw",
        ];
        let mut rows = Vec::new();
        let limit = f.limit.unwrap_or(u64::MAX) as usize;
        self.db.rows(&sql, &args, &mut |r| {
            if rows.len() >= limit {
                return Ok(());
            }
            let raw = r[6].blob().unwrap_or_default();
            let (service, sub, name, ok, body) = match decode_tm(raw) {
                Ok(tm) => (
                    tm.service.into(),
                    tm.subservice.into(),
                    tm.name.into(),
                    1.into(),
                    adapter::body_json(&tm),
                ),
                Err(e) => (
                    raw.get(7).map_or(serde_json::Value::Null, |s| (*s).into()),
                    raw.get(8).map_or(serde_json::Value::Null, |s| (*s).into()),
                    serde_json::Value::Null,
                    0.into(),
                    e.to_string().into(),
                ),
            };
            if f.service.is_some_and(|s| service != s) {
                return Ok(());
            }
            rows.push(vec![
                json(&r[4]),
                json(&r[3]),
                json(&r[0]),
                json(&r[1]),
                json(&r[2]),
                service,
                sub,
                name,
                ok,
                body,
                pus::hex(raw).into(),
            ]);
            Ok(())
        })?;
        Ok(Rows {
            columns: columns.iter().map(|s| s.to_string()).collect(),
            rows,
        })
    }

    fn query_table(&mut self, kind: Kind, f: &Filter) -> Result<Rows, ArchiveError> {
        let (table, columns, time) = match kind {
            Kind::Tc => (
                "tc",
                "id, t_ms, robot, apid, seq, service, subservice, name, args, step, attempt, raw",
                "t_ms",
            ),
            Kind::Verification => (
                "verification",
                "id, t_ms, obt_ms, robot, apid, seq, req_apid, req_seq, stage, success, step, code, code_name, failure",
                "obt_ms",
            ),
            Kind::Event => (
                "event",
                "id, t_ms, robot, event_id, name, severity, fault, params, description, obt_ms, apid, seq",
                "obt_ms",
            ),
            Kind::Alarm => ("alarm", super::alarms::COLUMNS, "last_ms"),
            Kind::Corrupt => ("bad_packet", "id, t_ms, link_robot, reason, raw", "t_ms"),
            Kind::Tm | Kind::Hk => unreachable_kind(kind)?,
        };
        let mut sql = format!("SELECT {columns} FROM {table} WHERE 1=1");
        let mut args = Vec::new();
        let f2 = Filter {
            robot: if kind == Kind::Corrupt { None } else { f.robot },
            ..f.clone()
        };
        filters(&mut sql, &mut args, &f2, time);
        if kind == Kind::Corrupt {
            if let Some(r) = f.robot {
                args.push(Val::Int(r as i64));
                sql.push_str(&format!(" AND link_robot = ?{}", args.len()));
            }
        }
        if let (Some(s), Kind::Tc) = (f.service, kind) {
            args.push(Val::Int(s as i64));
            sql.push_str(&format!(" AND service = ?{}", args.len()));
        }
        if let (Some(l), Kind::Event) = (f.min_level, kind) {
            args.push(Val::Int(l as i64));
            sql.push_str(&format!(" AND level >= ?{}", args.len()));
        }
        sql.push_str(&format!(" ORDER BY {time}, id"));
        if let Some(l) = f.limit {
            sql.push_str(&format!(" LIMIT {l}"));
        }
        let names: Vec<String> = columns.split(',').map(|c| c.trim().to_string()).collect();
        let mut rows = Vec::new();
        self.db.rows(&sql, &args, &mut |r| {
            rows.push(r.iter().map(json).collect());
            Ok(())
        })?;
        Ok(Rows { columns: names, rows })
    }

    /// Verifies every stored packet (CRC, key against its bytes), the parameter chunks
    /// against the HK packets, and lists the holes.
    pub fn check(&mut self, robot: Option<u8>) -> Result<CheckReport, ArchiveError> {
        let mut rep = CheckReport::default();
        let mut counts: std::collections::HashMap<(u8, u16), u64> = std::collections::HashMap::new();
        let mut sql = String::from("SELECT robot, apid, seq, obt_ms, raw FROM packet WHERE 1=1");
        let mut args = Vec::new();
        filters(
            &mut sql,
            &mut args,
            &Filter {
                robot,
                ..Default::default()
            },
            "obt_ms",
        );
        self.db.rows(&sql, &args, &mut |r| {
            let (rb, apid, seq, obt) = (
                robot_of(&r[0]),
                r[1].int().unwrap_or(-1) as u16,
                r[2].int().unwrap_or(-1) as u16,
                r[3].int().unwrap_or(0),
            );
            let raw = r[4].blob().unwrap_or_default();
            rep.packets += 1;
            rep.raw_bytes += raw.len() as u64;
            match decode_tm(raw) {
                Err(e) => rep.bad.push((rb, apid, seq, obt, e.to_string())),
                Ok(tm) if tm.apid != apid || tm.seq != seq || tm.time.unix_ms() != obt => rep.bad.push((
                    rb,
                    apid,
                    seq,
                    obt,
                    format!(
                        "stored under APID {apid:#x} seq {seq} time {obt} but the packet says APID {:#x} seq {} time {}",
                        tm.apid,
                        tm.seq,
                        tm.time.unix_ms()
                    ),
                )),
                Ok(tm) => {
                    if let adapter::Content::Hk { values, .. } = adapter::content(&tm) {
                        for (p, _) in values {
                            *counts.entry((rb, p)).or_default() += 1;
                        }
                    }
                }
            }
            Ok(())
        })?;
        let mut sql = format!("SELECT robot, param, SUM(n) FROM {CHUNKS} c WHERE 1=1");
        let mut args = Vec::new();
        if let Some(r) = robot {
            args.push(Val::Int(r as i64));
            sql.push_str(" AND robot = ?1");
        }
        sql.push_str(" GROUP BY robot, param");
        let sql = sql.replace("SUM(n)", "CAST(SUM(n) AS BIGINT)");
        for r in collect(self.db.as_mut(), &sql, &args)? {
            let key = (robot_of(&r[0]), r[1].int().unwrap_or(-1) as u16);
            let stored = r[2].int().unwrap_or(0) as u64;
            let expected = counts.remove(&key).unwrap_or(0);
            if stored != expected {
                rep.chunk_mismatch.push((key.0, key.1, stored, expected));
            }
        }
        for ((r, p), n) in counts {
            rep.chunk_mismatch.push((r, p, 0, n));
        }
        rep.chunk_mismatch.sort();
        rep.gaps = self.gaps(robot)?;
        Ok(rep)
    }
}

const HK_COLUMNS: [&str; 7] = ["t_ms", "robot", "param", "name", "raw", "eng", "unit"];

fn unreachable_kind(kind: Kind) -> Result<(&'static str, &'static str, &'static str), ArchiveError> {
    Err(ArchiveError::NotFound(format!("{kind:?} is not a table query")))
}

/// Appends robot and time filters.
fn filters(sql: &mut String, args: &mut Vec<Val>, f: &Filter, time: &str) {
    if let Some(r) = f.robot {
        args.push(Val::Int(r as i64));
        sql.push_str(&format!(" AND robot = ?{}", args.len()));
    }
    if let Some(t) = f.since_ms {
        args.push(Val::Int(t));
        sql.push_str(&format!(" AND {time} >= ?{}", args.len()));
    }
    if let Some(t) = f.until_ms {
        args.push(Val::Int(t));
        sql.push_str(&format!(" AND {time} <= ?{}", args.len()));
    }
}

/// Min/max per pixel column over `[t0, t1]` of time-ordered raw samples.
pub fn decimate_samples(s: &[(i64, i64)], eng: impl Fn(i64) -> f64, t0: i64, t1: i64, columns: usize) -> Vec<Column> {
    let columns = columns.max(1) as i128;
    let span = (t1 as i128 - t0 as i128 + 1).max(1);
    let mut out: Vec<Column> = Vec::new();
    let mut cur: Option<(i128, Column)> = None;
    for &(t, v) in s {
        if t < t0 || t > t1 {
            continue;
        }
        let col = ((t as i128 - t0 as i128) * columns / span).min(columns - 1);
        let e = eng(v);
        match &mut cur {
            Some((c, acc)) if *c == col => {
                acc.min = acc.min.min(e);
                acc.max = acc.max.max(e);
                acc.last = e;
                acc.t_last_ms = t;
                acc.n += 1;
            }
            _ => {
                if let Some((_, acc)) = cur.take() {
                    out.push(acc);
                }
                let start = t0 as i128 + col * span / columns;
                cur = Some((
                    col,
                    Column {
                        t_ms: start as i64,
                        t_first_ms: t,
                        t_last_ms: t,
                        min: e,
                        max: e,
                        first: e,
                        last: e,
                        n: 1,
                    },
                ));
            }
        }
    }
    if let Some((_, acc)) = cur {
        out.push(acc);
    }
    out
}
