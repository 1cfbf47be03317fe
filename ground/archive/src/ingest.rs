//! Writing: raw packets once under their unique key, parameter values into column
//! chunks, events and verification reports into their tables, and the per-stream
//! position and per-robot health beside them — all of one batch in one transaction, so
//! a crash leaves either the whole batch or none of it.

use std::collections::{HashMap, HashSet};

use super::adapter::{self, Content};
use super::codec;
use super::db::{Db, Dialect, Val};
use super::schema::{chunk_columns, CHUNK_MAX, CHUNK_SPAN_MS};
use super::{ArchiveError, ArchiveStats, Record};
use ground_pus::BuiltTc;

/// Packets per multi-row INSERT on PostgreSQL (7 parameters each, well under its 65,535).
/// A batch is cut into statements of these sizes, largest first, so that only these few
/// statements are ever prepared (and cached) whatever the batch sizes.
const PG_ROWS: [usize; 5] = [1000, 250, 50, 10, 1];

/// A packet's unique key: (robot, APID, on-board ms, sequence count).
type Key = (i64, i64, i64, i64);

/// Open chunks kept per robot and parameter (samples arriving out of time order, e.g. a
/// store dump beside live TM, go to the one they extend).
const OPEN_PER_PARAM: usize = 4;

/// Writes a chunk row into the chunk table `$table`.
macro_rules! upsert_chunk {
    ($table:literal) => {
        concat!(
            "INSERT INTO ",
            $table,
            " (",
            chunk_columns!(),
            ") VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7) ON CONFLICT (robot, param, t0, cid) \
             DO UPDATE SET t1 = excluded.t1, n = excluded.n, data = excluded.data"
        )
    };
}

/// A chunk being filled. It lives in `hk_open` (a small table, so the rewrite after each
/// batch touches a few pages however large the archive grows) and moves to `hk_chunk`
/// once it is closed: full, pushed out, or at a clean stop.
#[derive(Clone, Debug)]
struct OpenChunk {
    cid: i64,
    t0: i64,
    last_t: i64,
    enc: codec::ChunkEncoder,
    /// Samples not yet written.
    dirty: bool,
}

impl OpenChunk {
    fn key(&self, robot: u8, param: u16) -> [Val; 4] {
        [
            Val::Int(robot as i64),
            Val::Int(param as i64),
            Val::Int(self.t0),
            Val::Int(self.cid),
        ]
    }
}

#[derive(Default)]
struct StreamAcc {
    seq: i64,
    obt_ms: i64,
    t_ms: i64,
    packets: i64,
    duplicates: i64,
}

#[derive(Default)]
struct HealthAcc {
    last_heard_ms: i64,
    last_obt_ms: i64,
    packets: i64,
}

/// The ingest state of one writer.
pub struct Ingest {
    open: HashMap<(u8, u16), Vec<OpenChunk>>,
    /// Chunks taken out of `open` (full or pushed out), to be moved to `hk_chunk`.
    closed: Vec<(u8, u16, OpenChunk)>,
    cid_state: u64,
    pub stats: ArchiveStats,
}

impl Default for Ingest {
    fn default() -> Self {
        Self::new()
    }
}

fn args_json(tc: &BuiltTc) -> String {
    let m: serde_json::Map<String, serde_json::Value> = tc
        .def
        .args
        .iter()
        .zip(&tc.args)
        .map(|(a, v)| (a.name.to_string(), serde_json::Value::from(*v)))
        .collect();
    serde_json::Value::Object(m).to_string()
}

impl Ingest {
    pub fn new() -> Ingest {
        let nanos = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_nanos() as u64);
        Ingest {
            open: HashMap::new(),
            closed: Vec::new(),
            cid_state: nanos ^ ((std::process::id() as u64) << 32),
            stats: ArchiveStats::default(),
        }
    }

    /// A chunk id unique among writers (splitmix64 of time, process and a counter).
    fn next_cid(&mut self) -> i64 {
        self.cid_state = self.cid_state.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.cid_state;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        ((z ^ (z >> 31)) >> 1) as i64
    }

    fn add_sample(&mut self, robot: u8, param: u16, t: i64, v: i64) {
        let key = (robot, param);
        let chunks = self.open.entry(key).or_default();
        let best = chunks
            .iter_mut()
            .enumerate()
            .filter(|(_, c)| c.last_t <= t && t - c.t0 < CHUNK_SPAN_MS)
            .max_by_key(|(_, c)| c.last_t)
            .map(|(i, _)| i);
        let idx = match best {
            Some(i) => i,
            None => {
                if chunks.len() >= OPEN_PER_PARAM {
                    let (oldest, _) = chunks
                        .iter()
                        .enumerate()
                        .min_by_key(|(_, c)| c.last_t)
                        .unwrap_or((0, &chunks[0]));
                    let c = chunks.swap_remove(oldest);
                    self.closed.push((robot, param, c));
                }
                let cid = self.next_cid();
                let chunks = self.open.entry(key).or_default();
                chunks.push(OpenChunk {
                    cid,
                    t0: t,
                    last_t: t,
                    enc: codec::ChunkEncoder::default(),
                    dirty: false,
                });
                chunks.len() - 1
            }
        };
        let Some(chunks) = self.open.get_mut(&key) else {
            return;
        };
        let c = &mut chunks[idx];
        c.enc.push(t, v);
        c.last_t = t;
        c.dirty = true;
        if c.enc.len() >= CHUNK_MAX {
            let full = chunks.swap_remove(idx);
            self.closed.push((robot, param, full));
        }
    }

    /// Writes one batch in one transaction (retried when PostgreSQL reports a deadlock
    /// between concurrent writers). `syncs` of the batch are answered after the commit.
    pub fn write_batch(&mut self, db: &mut dyn Db, batch: &[Record]) -> Result<(), ArchiveError> {
        let mut attempt = 0;
        loop {
            let begin = match db.dialect() {
                Dialect::Sqlite => "BEGIN IMMEDIATE",
                Dialect::Postgres => "BEGIN",
            };
            db.batch(begin)?;
            let before = self.stats.clone();
            match self.write_in_tx(db, batch).and_then(|()| Ok(db.batch("COMMIT")?)) {
                Ok(()) => {
                    self.after_commit();
                    self.stats.transactions += 1;
                    for r in batch {
                        if let Record::Sync(s) = r {
                            let _ = s.send(());
                        }
                    }
                    return Ok(());
                }
                Err(e) => {
                    let _ = db.batch("ROLLBACK");
                    // What is in memory was not committed: start new chunks.
                    self.open.clear();
                    self.closed.clear();
                    self.stats = before;
                    attempt += 1;
                    let retry = matches!(&e, ArchiveError::Db(d) if d.retryable);
                    if !retry || attempt >= 8 {
                        return Err(e);
                    }
                    std::thread::sleep(std::time::Duration::from_millis(5 << attempt.min(6)));
                }
            }
        }
    }

    /// Writes everything inside an open transaction (used by migrations too).
    pub fn write_in_tx(&mut self, db: &mut dyn Db, batch: &[Record]) -> Result<(), ArchiveError> {
        // PostgreSQL: the batch's packets go in with a few multi-row statements (a round
        // trip per packet would bound ingest to the server's latency); SQLite: one cached
        // statement per packet is as fast and keeps the statement cache small.
        let mut fresh = match db.dialect() {
            Dialect::Postgres => Some(insert_packets(db, batch)?),
            Dialect::Sqlite => None,
        };
        let mut streams: HashMap<(u8, u16), StreamAcc> = HashMap::new();
        let mut health: HashMap<u8, HealthAcc> = HashMap::new();
        for r in batch {
            match r {
                Record::Sync(_) => {}
                Record::Tc {
                    t_ms,
                    tc,
                    step,
                    attempt,
                } => {
                    db.exec(
                        "INSERT INTO tc (t_ms, robot, apid, seq, service, subservice, name, args, step, attempt, raw) \
                         VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11)",
                        &[
                            Val::Int(*t_ms),
                            mib::apid::apid_robot(tc.apid).map(|r| r as i64).into(),
                            Val::Int(tc.apid as i64),
                            Val::Int(tc.seq as i64),
                            Val::Int(tc.def.service as i64),
                            Val::Int(tc.def.subservice as i64),
                            tc.def.name.into(),
                            args_json(tc).into(),
                            step.clone().into(),
                            Val::Int(*attempt as i64),
                            Val::Blob(tc.bytes.clone()),
                        ],
                    )?;
                    self.stats.tc += 1;
                }
                Record::Tm {
                    t_ms,
                    link_robot,
                    raw,
                    decoded,
                } => {
                    let tm = match decoded {
                        Ok(tm) => tm,
                        Err(e) => {
                            self.bad(db, *t_ms, *link_robot, &e.to_string(), raw)?;
                            continue;
                        }
                    };
                    let Some(robot) = tm.robot.or(*link_robot) else {
                        self.bad(
                            db,
                            *t_ms,
                            *link_robot,
                            &format!("APID {:#x} is not a robot's", tm.apid),
                            raw,
                        )?;
                        continue;
                    };
                    let obt = tm.time.unix_ms();
                    let h = health.entry(robot).or_default();
                    h.last_heard_ms = h.last_heard_ms.max(*t_ms);
                    h.last_obt_ms = h.last_obt_ms.max(obt);
                    h.packets += 1;
                    let key = [
                        Val::Int(robot as i64),
                        Val::Int(tm.apid as i64),
                        Val::Int(obt),
                        Val::Int(tm.seq as i64),
                    ];
                    let new = match fresh.as_mut() {
                        // Stored by this batch's statement; a second copy in the same batch
                        // finds the key taken.
                        Some(f) => f.remove(&(robot as i64, tm.apid as i64, obt, tm.seq as i64)),
                        None => {
                            db.exec(
                                "INSERT INTO packet (robot, apid, obt_ms, seq, t_ms, link_robot, raw) \
                                 VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7) ON CONFLICT DO NOTHING",
                                &[
                                    key[0].clone(),
                                    key[1].clone(),
                                    key[2].clone(),
                                    key[3].clone(),
                                    Val::Int(*t_ms),
                                    link_robot.map(|r| r as i64).into(),
                                    Val::Blob(raw.clone()),
                                ],
                            )? == 1
                        }
                    };
                    let s = streams.entry((robot, tm.apid)).or_insert(StreamAcc {
                        obt_ms: i64::MIN,
                        ..Default::default()
                    });
                    if !new {
                        s.duplicates += 1;
                        self.stats.duplicates += 1;
                        continue;
                    }
                    s.packets += 1;
                    if obt >= s.obt_ms {
                        s.obt_ms = obt;
                        s.seq = tm.seq as i64;
                        s.t_ms = *t_ms;
                    }
                    self.stats.tm += 1;
                    self.stats.raw_bytes += raw.len() as u64;
                    match adapter::content(tm) {
                        Content::Hk { values, .. } => {
                            for (param, v) in values {
                                self.add_sample(robot, param, obt, v);
                            }
                            self.stats.hk_rows += 1;
                        }
                        Content::Event(e) => {
                            db.exec(
                                "INSERT INTO event (robot, apid, seq, obt_ms, t_ms, event_id, name, severity, level, fault, params, description) \
                                 VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, ?12)",
                                &[
                                    key[0].clone(),
                                    key[1].clone(),
                                    key[3].clone(),
                                    key[2].clone(),
                                    Val::Int(*t_ms),
                                    Val::Int(e.event_id as i64),
                                    e.name.into(),
                                    e.severity.into(),
                                    Val::Int(e.level as i64),
                                    Val::Int(e.fault as i64),
                                    e.params.into(),
                                    e.description.into(),
                                ],
                            )?;
                            self.stats.events += 1;
                        }
                        Content::Verification(v) => {
                            db.exec(
                                "INSERT INTO verification (robot, apid, seq, obt_ms, t_ms, req_apid, req_seq, stage, success, step, code, code_name, failure) \
                                 VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, ?12, ?13)",
                                &[
                                    key[0].clone(),
                                    key[1].clone(),
                                    key[3].clone(),
                                    key[2].clone(),
                                    Val::Int(*t_ms),
                                    Val::Int(v.req_apid as i64),
                                    Val::Int(v.req_seq as i64),
                                    v.stage.into(),
                                    Val::Int(v.success as i64),
                                    v.step.map(|s| s as i64).into(),
                                    v.code.map(|c| c as i64).into(),
                                    v.code_name.into(),
                                    v.failure.into(),
                                ],
                            )?;
                            self.stats.verification += 1;
                        }
                        Content::Other => {}
                    }
                }
            }
        }
        self.write_chunks(db)?;
        let g = db.dialect().greatest();
        for ((robot, apid), s) in streams {
            db.exec(
                &format!(
                    "INSERT INTO stream (robot, apid, seq, obt_ms, t_ms, packets, duplicates) \
                     VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7) ON CONFLICT (robot, apid) DO UPDATE SET \
                     seq = CASE WHEN excluded.obt_ms >= stream.obt_ms THEN excluded.seq ELSE stream.seq END, \
                     t_ms = CASE WHEN excluded.obt_ms >= stream.obt_ms THEN excluded.t_ms ELSE stream.t_ms END, \
                     obt_ms = {g}(stream.obt_ms, excluded.obt_ms), \
                     packets = stream.packets + excluded.packets, \
                     duplicates = stream.duplicates + excluded.duplicates"
                ),
                &[
                    Val::Int(robot as i64),
                    Val::Int(apid as i64),
                    Val::Int(s.seq),
                    Val::Int(if s.obt_ms == i64::MIN { 0 } else { s.obt_ms }),
                    Val::Int(s.t_ms),
                    Val::Int(s.packets),
                    Val::Int(s.duplicates),
                ],
            )?;
        }
        for (robot, h) in health {
            db.exec(
                &format!(
                    "INSERT INTO health (robot, last_heard_ms, last_obt_ms, packets) VALUES (?1, ?2, ?3, ?4) \
                     ON CONFLICT (robot) DO UPDATE SET \
                     last_heard_ms = {g}(health.last_heard_ms, excluded.last_heard_ms), \
                     last_obt_ms = {g}(health.last_obt_ms, excluded.last_obt_ms), \
                     packets = health.packets + excluded.packets"
                ),
                &[
                    Val::Int(robot as i64),
                    Val::Int(h.last_heard_ms),
                    Val::Int(h.last_obt_ms),
                    Val::Int(h.packets),
                ],
            )?;
        }
        Ok(())
    }

    fn bad(
        &mut self,
        db: &mut dyn Db,
        t_ms: i64,
        link_robot: Option<u8>,
        reason: &str,
        raw: &[u8],
    ) -> Result<(), ArchiveError> {
        db.exec(
            "INSERT INTO bad_packet (t_ms, link_robot, reason, raw) VALUES (?1, ?2, ?3, ?4)",
            &[
                Val::Int(t_ms),
                link_robot.map(|r| r as i64).into(),
                reason.into(),
                Val::Blob(raw.to_vec()),
            ],
        )?;
        self.stats.tm_corrupt += 1;
        Ok(())
    }

    fn write_chunks(&mut self, db: &mut dyn Db) -> Result<(), ArchiveError> {
        let write = |db: &mut dyn Db, sql: &str, robot: u8, param: u16, c: &OpenChunk| -> Result<(), ArchiveError> {
            let [r, p, t0, cid] = c.key(robot, param);
            db.exec(
                sql,
                &[
                    r,
                    p,
                    t0,
                    cid,
                    Val::Int(c.last_t),
                    Val::Int(c.enc.len() as i64),
                    Val::Blob(c.enc.bytes()),
                ],
            )?;
            Ok(())
        };
        for (robot, param, c) in &self.closed {
            write(db, upsert_chunk!("hk_chunk"), *robot, *param, c)?;
            // Its row in `hk_open`, if an earlier batch wrote one (a no-op otherwise).
            db.exec(
                "DELETE FROM hk_open WHERE robot = ?1 AND param = ?2 AND t0 = ?3 AND cid = ?4",
                &c.key(*robot, *param),
            )?;
        }
        for ((robot, param), chunks) in &self.open {
            for c in chunks.iter().filter(|c| c.dirty) {
                write(db, upsert_chunk!("hk_open"), *robot, *param, c)?;
            }
        }
        Ok(())
    }

    /// Marks everything written as clean (after a commit).
    pub fn after_commit(&mut self) {
        self.closed.clear();
        for chunks in self.open.values_mut() {
            for c in chunks.iter_mut() {
                c.dirty = false;
            }
        }
    }

    /// Closes every open chunk at a clean stop: moves them to `hk_chunk` in one
    /// transaction, so that `hk_open` holds only chunks a writer is filling (and those of
    /// a writer that was killed, which read like any other).
    pub fn close_all(&mut self, db: &mut dyn Db) -> Result<(), ArchiveError> {
        self.take_all();
        self.write_batch(db, &[])
    }

    /// [`Ingest::close_all`] inside the caller's transaction (a migration).
    pub fn close_all_in_tx(&mut self, db: &mut dyn Db) -> Result<(), ArchiveError> {
        self.take_all();
        self.write_chunks(db)?;
        self.closed.clear();
        Ok(())
    }

    fn take_all(&mut self) {
        for ((robot, param), chunks) in self.open.drain() {
            self.closed.extend(chunks.into_iter().map(|c| (robot, param, c)));
        }
    }
}

/// Inserts the decodable packets of `batch` with multi-row statements, skipping keys
/// already stored; returns the keys this call stored.
fn insert_packets(db: &mut dyn Db, batch: &[Record]) -> Result<HashSet<Key>, ArchiveError> {
    let mut stored = HashSet::new();
    let rows: Vec<[Val; 7]> = batch
        .iter()
        .filter_map(|r| match r {
            Record::Tm {
                t_ms,
                link_robot,
                raw,
                decoded: Ok(tm),
            } => {
                let robot = tm.robot.or(*link_robot)?;
                Some([
                    Val::Int(robot as i64),
                    Val::Int(tm.apid as i64),
                    Val::Int(tm.time.unix_ms()),
                    Val::Int(tm.seq as i64),
                    Val::Int(*t_ms),
                    link_robot.map(|r| r as i64).into(),
                    Val::Blob(raw.clone()),
                ])
            }
            Record::Tm { .. } | Record::Tc { .. } | Record::Sync(_) => None,
        })
        .collect();
    let mut rest = &rows[..];
    while !rest.is_empty() {
        let n = PG_ROWS.into_iter().find(|&n| n <= rest.len()).unwrap_or(1);
        let (page, tail) = rest.split_at(n);
        rest = tail;
        let mut sql = String::from("INSERT INTO packet (robot, apid, obt_ms, seq, t_ms, link_robot, raw) VALUES ");
        for i in 0..page.len() {
            let b = i * 7;
            if i > 0 {
                sql.push(',');
            }
            sql.push_str(&format!(
                "(?{}, ?{}, ?{}, ?{}, ?{}, ?{}, ?{})",
                b + 1,
                b + 2,
                b + 3,
                b + 4,
                b + 5,
                b + 6,
                b + 7
            ));
        }
        sql.push_str(" ON CONFLICT DO NOTHING RETURNING robot, apid, obt_ms, seq");
        let params: Vec<Val> = page.iter().flat_map(|r| r.iter().cloned()).collect();
        db.rows(&sql, &params, &mut |r| {
            let k = |i: usize| r[i].int().unwrap_or(-1);
            stored.insert((k(0), k(1), k(2), k(3)));
            Ok(())
        })?;
    }
    Ok(stored)
}
