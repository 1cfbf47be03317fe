//! `ground file put|get|ls|rm|mv`: files to and from a robot's file store over CFDP
//! (docs/files.md), on the space link only (SDLS and COP-1: nothing unauthenticated
//! reaches the store). The ground runs the same CFDP entity as the robot (`mmic_cfdp`)
//! over a directory: the local file's folder for `put`, a private staging folder for what
//! comes down, so that a file is only renamed into place once CFDP says it arrived
//! complete (checksum verified) — a failed transfer never leaves a file taken as good.

use std::collections::VecDeque;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use anyhow::{Context, Result};
use clap::{Args, Subcommand, ValueEnum};
use ground::keys;
use ground::link::Transport;
use ground::robot_lock::RobotLock;
use mmic_cfdp::dir::DirStore;
use mmic_cfdp::packet::{self, Direction};
use mmic_cfdp::trace::Describe;
use mmic_cfdp::{Class, Entity, FileName, Finished, Parts};

use crate::exit::{self, coded};
use crate::links::{one_robot, Links};
use crate::output::err_line;

#[derive(Subcommand, Debug)]
pub(crate) enum FileCmd {
    /// Send a local file to the robot's file store.
    Put {
        #[command(flatten)]
        opts: FileOpts,
        /// The local file (its name must be a valid store name unless REMOTE is given).
        local: PathBuf,
        /// Its name in the robot's store [default: the local file's name].
        remote: Option<String>,
    },
    /// Fetch a file of the robot's store.
    Get {
        #[command(flatten)]
        opts: FileOpts,
        /// The name in the robot's store.
        remote: String,
        /// Where to write it [default: REMOTE in the current folder]; replaced only when
        /// the file arrived complete.
        local: Option<PathBuf>,
    },
    /// List the robot's store: name and length of each file, then the free bytes.
    Ls {
        #[command(flatten)]
        opts: FileOpts,
    },
    /// Delete a file of the robot's store.
    Rm {
        #[command(flatten)]
        opts: FileOpts,
        name: String,
    },
    /// Rename a file of the robot's store (refused when TO exists).
    Mv {
        #[command(flatten)]
        opts: FileOpts,
        from: String,
        to: String,
    },
}

/// CFDP transmission class.
#[derive(Clone, Copy, Debug, ValueEnum)]
pub(crate) enum ClassArg {
    /// Unacknowledged: no retransmission; the checksum still decides.
    #[value(name = "1")]
    One,
    /// Acknowledged: NAKs, retransmission, EOF and Finished acknowledged.
    #[value(name = "2")]
    Two,
}

#[derive(Args, Debug)]
pub(crate) struct FileOpts {
    #[command(flatten)]
    links: Links,
    /// CFDP class of the file transfer.
    #[arg(long, value_enum, default_value = "2")]
    class: ClassArg,
    /// Give up after this many seconds.
    #[arg(long, default_value_t = 600.0)]
    timeout: f64,
    /// Show a progress line on stderr (bytes, percent, rate) [default: when stderr is a
    /// terminal].
    #[arg(long)]
    progress: bool,
    /// Print every CFDP PDU sent and received on stderr: ms since the start, the direction
    /// (`>` up, `<` down), the transaction and the PDU's kind and fields.
    #[arg(long)]
    trace: bool,
}

impl FileOpts {
    fn class(&self) -> Class {
        match self.class {
            ClassArg::One => Class::One,
            ClassArg::Two => Class::Two,
        }
    }
}

/// A name for the robot's store, checked before anything is sent (exit 3 when bad).
fn store_name(what: &str, s: &str) -> Result<FileName> {
    FileName::new(s).map_err(|e| coded(exit::INVALID, format!("{what} {s:?}: {e}")))
}

/// The frame link to the one robot of `opts`, the lock that makes this process its only
/// commander, the robot and the file keeping the ground's next CFDP transaction sequence
/// number for it (transaction IDs must not repeat across ground runs).
fn open_link(opts: &FileOpts) -> Result<(ground_link::GroundFrameLink, RobotLock, u8, PathBuf)> {
    let (robot, addr) = one_robot(&opts.links)?;
    let (transport, frames) = opts.links.choice(&[(robot, addr)])?;
    let frames = match (transport, frames) {
        (Transport::Frames, Some(f)) => f,
        _ => {
            return Err(coded(
                exit::USAGE,
                "files travel on the space link only (--keys DIR), not on a lab link",
            ))
        }
    };
    if opts.timeout.is_nan() || opts.timeout <= 0.0 {
        return Err(coded(
            exit::USAGE,
            format!("--timeout {}: must be a positive number of seconds", opts.timeout),
        ));
    }
    let lock = RobotLock::acquire(robot, addr).map_err(|e| coded(exit::INVALID, format!("robot {robot}: {e}")))?;
    let dir = keys::robot_dir(&frames.keys, robot);
    let listen = frames.listen(robot, addr);
    let mut cfg = ground_link::Config::from_key_dir(addr, listen, &dir, &keys::ground_state_path(&dir), frames.tc_spi)
        .map_err(|e| coded(exit::INVALID, format!("robot {robot}'s keys in {}: {e}", dir.display())))?;
    cfg.tm_security = frames.tm_security;
    let fl = match frames.serial.get(&robot) {
        Some(path) => ground_link::GroundFrameLink::open_serial(cfg, path),
        None => ground_link::GroundFrameLink::open(cfg),
    }
    .map_err(|e| coded(exit::ERROR, format!("frame link of robot {robot}: {e}")))?;
    err_line!(
        "robot {robot} at {addr} (space link, CFDP entity {})",
        mib::cfdp::robot_entity_id(robot)
    );
    Ok((fl, lock, robot, dir.join("ground-cfdp.seq")))
}

/// The ground's entity on one frame link.
struct Session<'a> {
    fl: ground_link::GroundFrameLink,
    /// `--trace`: every PDU in and out on stderr.
    trace: bool,
    entity: Entity<'a, DirStore>,
    start: Instant,
    deadline: Instant,
    seq: u16,
    /// Bytes received so far, last reported.
    shown: u64,
    parts: &'a Parts<DirStore>,
    seq_file: PathBuf,
    /// The progress line: shown, and when it was last drawn.
    progress: Option<Progress>,
    /// Finished transactions not yet asked for: a `get`'s file may arrive complete before
    /// the robot's Finished PDU of the request itself does (its EOF ACK lost), and that
    /// report must still be there when [`Session::incoming_done`] looks for it.
    reports: Vec<Finished>,
    /// The metadata PDU's packet while COP-1 has not yet delivered it, and the file data
    /// made meanwhile: file data travels in BD frames, outside COP-1's order, and the
    /// robot drops file data of a transaction whose metadata it has not seen.
    metadata: Option<ground_link::PacketId>,
    held: VecDeque<Vec<u8>>,
    /// When the entity may next make PDUs ([`Session::pace`]).
    next_poll: u64,
}

/// Longest wait at the end for FOP-1 to have the last PDUs acknowledged.
const DRAIN: Duration = Duration::from_secs(5);

impl Drop for Session<'_> {
    /// The last PDUs (an ACK of the robot's Finished, say) reach the robot before the
    /// process ends, and the sequence number is kept.
    fn drop(&mut self) {
        let until = Instant::now() + DRAIN;
        while self.fl.pending() > 0 && Instant::now() < until {
            if self.fl.recv(Duration::from_millis(5)).is_err() {
                break;
            }
        }
        self.keep_seq();
    }
}

/// Packets of the CFDP APID FOP-1 may hold before the entity makes more: two windows.
const LINK_BACKLOG: usize = 2 * mib::link::cop1::FOP_SLIDING_WINDOW as usize;

/// The entity makes PDUs once per robot control period, as the robot's does: its file
/// data (`mib::cfdp::SEGMENTS_PER_POLL` a call) goes out in BD frames with nothing else
/// to pace it, at the rate the robot's entity sends its own.
const POLL_MS: u64 = mib::config::CONTROL_PERIOD_MS as u64;

impl<'a> Session<'a> {
    fn new(
        fl: ground_link::GroundFrameLink,
        robot: u8,
        seq_file: PathBuf,
        parts: &'a Parts<DirStore>,
        opts: &FileOpts,
    ) -> Self {
        let start = Instant::now();
        if let Some(seq) = std::fs::read_to_string(&seq_file)
            .ok()
            .and_then(|t| t.trim().parse().ok())
        {
            parts.set_next_seq(seq);
        }
        Session {
            parts,
            seq_file,
            fl,
            entity: Entity::new(mib::cfdp::GROUND_ENTITY_ID, mib::cfdp::robot_entity_id(robot), parts),
            start,
            deadline: start + Duration::from_secs_f64(opts.timeout),
            trace: opts.trace,
            seq: 0,
            shown: 0,
            progress: None,
            reports: Vec::new(),
            metadata: None,
            held: VecDeque::new(),
            next_poll: 0,
        }
    }

    /// Draws a progress line while files move (`--progress`, or stderr a terminal).
    fn show_progress(&mut self, on: bool) {
        use std::io::IsTerminal;
        if on || std::io::stderr().is_terminal() {
            self.progress = Some(Progress::default());
        }
    }

    fn now(&self) -> u64 {
        self.start.elapsed().as_millis() as u64
    }

    /// Keeps the next transaction sequence number (written beside, then renamed). Called
    /// once a transaction has started, so that a ground killed during it (SIGKILL: no `Drop`)
    /// and run again never repeats its ID — the robot drops a repeated ID as a late PDU of a
    /// finished transaction.
    fn keep_seq(&self) {
        let tmp = self.seq_file.with_extension("seq.new");
        let kept =
            std::fs::write(&tmp, self.parts.next_seq().to_string()).and_then(|_| std::fs::rename(&tmp, &self.seq_file));
        if let Err(e) = kept {
            err_line!(
                "ground: {}: {e} (the next run may repeat a transaction ID)",
                self.seq_file.display()
            );
        }
    }

    /// Runs the link and the entity until `done` says a finished transaction ends it.
    fn until(&mut self, what: &str, mut done: impl FnMut(&Finished) -> bool) -> Result<Finished> {
        self.keep_seq();
        let mut buf = [0u8; mib::cfdp::MAX_PACKET_LEN];
        loop {
            while let Some(f) = self.entity.take_finished() {
                self.reports.push(f);
            }
            if let Some(i) = self.reports.iter().position(&mut done) {
                return Ok(self.reports.remove(i));
            }
            if Instant::now() > self.deadline {
                return Err(coded(
                    exit::NO_ANSWER,
                    format!("{what}: no end of the transfer before --timeout"),
                ));
            }
            let packets = self
                .fl
                .recv(Duration::from_millis(5))
                .map_err(|e| coded(exit::NO_ANSWER, format!("{what}: {e}")))?;
            let now = self.now();
            let failed = |e| coded(exit::NO_ANSWER, format!("{what}: {e}"));
            // What the entity makes goes out after each packet: a burst of packets (a
            // ground held up by its scheduler) makes more immediate NAKs than its outbox
            // holds.
            for p in packets.iter().filter(|p| packet::apid(p) == Some(mib::cfdp::APID)) {
                if self.trace {
                    if let Some(pdu) = packet::unwrap(Direction::Down, p) {
                        eprintln!("{now:>7} < {}", Describe(pdu));
                    }
                }
                self.entity.receive_packet(now, Direction::Down, p);
                self.flush(&mut buf).map_err(failed)?;
            }
            self.pace(now).map_err(failed)?;
            self.flush(&mut buf).map_err(failed)?;
            // The file going out, else the one coming in.
            let (done, total) = match self.entity.sent_progress() {
                (d, t) if t > 0 => (d, t),
                _ => (self.entity.progress(), self.entity.incoming_len()),
            };
            match self.progress.as_mut() {
                Some(p) => p.draw(what, done, total),
                None if done >= self.shown + (256 << 10) => {
                    err_line!("{what}: {} KiB of {} KiB", done >> 10, total >> 10);
                    self.shown = done;
                }
                None => {}
            }
        }
    }

    /// Sends the PDUs the entity made, each in its packet.
    fn flush(&mut self, buf: &mut [u8]) -> Result<(), ground_link::LinkError> {
        while let Some(pdu) = self.entity.pop() {
            if self.trace {
                eprintln!("{:>7} > {}", self.now(), Describe(&pdu));
            }
            if let Some(n) = packet::wrap(Direction::Up, self.seq, &pdu, buf) {
                self.seq = self.seq.wrapping_add(1) & 0x3FFF;
                self.send(&pdu, &buf[..n])?;
            }
        }
        Ok(())
    }

    /// Lets the entity make PDUs (and run its timers) once per control period, while COP-1
    /// has room, and none while its file data waits for the metadata to be delivered.
    fn pace(&mut self, now: u64) -> Result<(), ground_link::LinkError> {
        if self.metadata.is_some_and(|id| !self.fl.is_pending(id)) {
            self.metadata = None;
            while let Some(p) = self.held.pop_front() {
                self.fl.send_bypass(&p)?;
            }
        }
        if now >= self.next_poll && self.held.is_empty() && self.fl.pending() < LINK_BACKLOG {
            self.next_poll = now + POLL_MS;
            self.entity.poll(now);
        }
        Ok(())
    }

    /// One uplink PDU in its packet: class 2 file data in a BD frame (held while the
    /// transaction's metadata is not yet delivered), everything else to COP-1.
    fn send(&mut self, pdu: &[u8], p: &[u8]) -> Result<(), ground_link::LinkError> {
        if mib::cfdp::is_bypass_file_data(p) {
            if self.metadata.is_some() {
                self.held.push_back(p.to_vec());
                return Ok(());
            }
            return self.fl.send_bypass(p);
        }
        let id = self.fl.send_packet(p)?;
        if mmic_cfdp::entity::is_metadata(pdu) {
            self.metadata = Some(id);
        }
        Ok(())
    }

    /// Runs until our request transaction (sent) has finished; an error unless complete.
    fn request_done(&mut self, what: &str) -> Result<()> {
        let f = self.until(what, |f| f.sent)?;
        if !f.complete {
            return Err(coded(
                exit::FAILED,
                format!("{what}: the robot did not take the request ({:?})", f.condition),
            ));
        }
        Ok(())
    }

    /// Runs until a transaction from the robot has finished; an error unless complete.
    fn incoming_done(&mut self, what: &str) -> Result<()> {
        let f = self.until(what, |f| !f.sent)?;
        if !f.complete {
            return Err(coded(
                exit::FAILED,
                format!(
                    "{what}: the file did not arrive complete ({:?}); nothing was kept",
                    f.condition
                ),
            ));
        }
        Ok(())
    }
}

/// A progress line on stderr, redrawn at most every 200 ms and ended with a newline.
struct Progress {
    start: Instant,
    drawn: Option<Instant>,
}

impl Default for Progress {
    fn default() -> Self {
        Progress {
            start: Instant::now(),
            drawn: None,
        }
    }
}

impl Progress {
    fn draw(&mut self, what: &str, done: u64, total: u64) {
        if total == 0 || self.drawn.is_some_and(|t| t.elapsed() < Duration::from_millis(200)) {
            return;
        }
        self.drawn = Some(Instant::now());
        let secs = self.start.elapsed().as_secs_f64().max(1e-3);
        eprint!(
            "\r{what}: {} / {} KiB {:>3} % {:>6.1} kB/s\x1b[K",
            done >> 10,
            total >> 10,
            done.min(total) * 100 / total,
            done as f64 / secs / 1000.0
        );
    }
}

impl Drop for Progress {
    fn drop(&mut self) {
        if self.drawn.is_some() {
            eprintln!();
        }
    }
}

/// A private folder beside `near` for what comes down, removed when dropped.
struct Staging(PathBuf);

impl Staging {
    fn new(near: &Path) -> Result<Staging> {
        let p = near.join(format!(".ground-file-{}", std::process::id()));
        std::fs::create_dir_all(&p).with_context(|| format!("creating {}", p.display()))?;
        Ok(Staging(p))
    }
}

impl Drop for Staging {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

fn staging_parts(near: &Path) -> Result<(Staging, Parts<DirStore>)> {
    let st = Staging::new(near)?;
    let parts = Parts::new(DirStore::open(&st.0, u64::MAX).context("staging folder")?);
    Ok((st, parts))
}

/// The robot's listing, fetched into the staging folder: (name, length) lines and the free
/// bytes.
fn listing(s: &mut Session, st: &Staging) -> Result<(Vec<(String, u64)>, u64)> {
    let name = mib::cfdp::LISTING_NAME;
    let _ = std::fs::remove_file(st.0.join(name));
    s.entity
        .list(s.now(), name)
        .map_err(|e| coded(exit::INVALID, format!("ls: {e}")))?;
    s.request_done("ls")?;
    s.incoming_done("ls")?;
    let text = std::fs::read_to_string(st.0.join(name)).context("reading the listing")?;
    let mut files = Vec::new();
    let mut free = None;
    for line in text.lines() {
        match line.split_once(' ') {
            Some(("free", n)) => free = n.parse().ok(),
            Some((f, n)) => files.push((f.to_string(), n.parse().unwrap_or(0))),
            None => {}
        }
    }
    let free = free.ok_or_else(|| coded(exit::ERROR, "the robot's listing has no free-space line"))?;
    Ok((files, free))
}

pub(crate) fn file(cmd: &FileCmd) -> Result<u8> {
    match cmd {
        FileCmd::Put { opts, local, remote } => put(opts, local, remote.as_deref()),
        FileCmd::Get { opts, remote, local } => get(opts, remote, local.as_deref()),
        FileCmd::Ls { opts } => ls(opts),
        FileCmd::Rm { opts, name } => rm_mv(opts, name, None),
        FileCmd::Mv { opts, from, to } => rm_mv(opts, from, Some(to)),
    }
}

fn put(opts: &FileOpts, local: &Path, remote: Option<&str>) -> Result<u8> {
    let meta = std::fs::metadata(local).map_err(|e| coded(exit::INVALID, format!("{}: {e}", local.display())))?;
    if !meta.is_file() {
        return Err(coded(exit::INVALID, format!("{}: not a regular file", local.display())));
    }
    if meta.len() > mib::cfdp::MAX_FILE_LEN {
        return Err(coded(
            exit::INVALID,
            format!(
                "{}: {} bytes, the store takes files of at most {}",
                local.display(),
                meta.len(),
                mib::cfdp::MAX_FILE_LEN
            ),
        ));
    }
    let local_name = local
        .file_name()
        .and_then(|n| n.to_str())
        .ok_or_else(|| coded(exit::INVALID, format!("{}: no file name", local.display())))?;
    // The ground's own store is the local file's folder: its name must pass the same checks.
    let src = store_name("local file name (rename it, or copy it to a valid name)", local_name)?;
    let dest = store_name("remote name", remote.unwrap_or(local_name))?;
    let (fl, _lock, robot, seq_file) = open_link(opts)?;
    let folder = local
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let parts = Parts::new(DirStore::open(folder, u64::MAX).context("the local folder")?);
    let mut s = Session::new(fl, robot, seq_file, &parts, opts);
    s.show_progress(opts.progress);
    let t0 = Instant::now();
    s.entity
        .put(s.now(), src.as_str(), dest.as_str(), opts.class())
        .map_err(|e| coded(exit::INVALID, format!("put: {e}")))?;
    let f = s.until("put", |f| f.sent)?;
    // The progress line ends before the outcome is printed.
    s.progress = None;
    if !f.complete {
        return Err(coded(
            exit::FAILED,
            format!("put {dest}: not delivered ({:?})", f.condition),
        ));
    }
    let c = s.fl.counters;
    println!(
        "put {} -> robot {robot}:{dest}: {} bytes in {:.1} s, complete; TC frames: {} BD, {} AD ({} sent again)",
        local.display(),
        meta.len(),
        t0.elapsed().as_secs_f64(),
        c.bd_frames_sent,
        c.ad_frames_sent,
        c.retransmissions
    );
    Ok(exit::OK)
}

fn get(opts: &FileOpts, remote: &str, local: Option<&Path>) -> Result<u8> {
    let src = store_name("remote name", remote)?;
    let target = local.map(Path::to_path_buf).unwrap_or_else(|| PathBuf::from(remote));
    if target.is_dir() {
        return Err(coded(
            exit::INVALID,
            format!("{}: a folder; give the file's path", target.display()),
        ));
    }
    let folder = target
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."))
        .to_path_buf();
    if !folder.is_dir() {
        return Err(coded(exit::INVALID, format!("{}: no such folder", folder.display())));
    }
    let (fl, _lock, robot, seq_file) = open_link(opts)?;
    let (st, parts) = staging_parts(&folder)?;
    let mut s = Session::new(fl, robot, seq_file, &parts, opts);
    s.show_progress(opts.progress);
    let t0 = Instant::now();
    let frames0 = (s.fl.counters.tm.frames, s.fl.counters.tm.idle_frames);
    s.entity
        .get(s.now(), src.as_str(), src.as_str(), opts.class())
        .map_err(|e| coded(exit::INVALID, format!("get: {e}")))?;
    s.request_done("get")?;
    s.incoming_done("get")?;
    s.progress = None;
    let got = st.0.join(src.as_str());
    let len = std::fs::metadata(&got).map(|m| m.len()).unwrap_or(0);
    std::fs::rename(&got, &target).with_context(|| format!("writing {}", target.display()))?;
    // The link's cost of the file: every TM frame that came in during the transfer (file
    // data, NAK answers, housekeeping, idle frames), 1024 bytes each.
    let tm = &s.fl.counters.tm;
    let frames = u64::from(tm.frames.wrapping_sub(frames0.0)) + u64::from(tm.idle_frames.wrapping_sub(frames0.1));
    println!(
        "get robot {robot}:{src} -> {}: {len} bytes in {:.1} s, complete; {frames} TM frames of {} bytes received",
        target.display(),
        t0.elapsed().as_secs_f64(),
        mib::link::tm_frame::LEN
    );
    Ok(exit::OK)
}

fn ls(opts: &FileOpts) -> Result<u8> {
    let (fl, _lock, robot, seq_file) = open_link(opts)?;
    let (st, parts) = staging_parts(&std::env::temp_dir())?;
    let mut s = Session::new(fl, robot, seq_file, &parts, opts);
    let (files, free) = listing(&mut s, &st)?;
    for (n, l) in &files {
        println!("{l:>10}  {n}");
    }
    println!("{} files, {free} bytes free", files.len());
    Ok(exit::OK)
}

fn rm_mv(opts: &FileOpts, name: &str, to: Option<&str>) -> Result<u8> {
    let name = store_name("remote name", name)?;
    let to = to.map(|t| store_name("new name", t)).transpose()?;
    let what = if to.is_some() { "mv" } else { "rm" };
    let (fl, _lock, robot, seq_file) = open_link(opts)?;
    let (st, parts) = staging_parts(&std::env::temp_dir())?;
    let mut s = Session::new(fl, robot, seq_file, &parts, opts);
    let (before, _) = listing(&mut s, &st)?;
    let had = |n: &FileName| before.iter().any(|(f, _)| f == n.as_str());
    if !had(&name) {
        return Err(coded(
            exit::FAILED,
            format!("{what} {name}: robot {robot} has no such file"),
        ));
    }
    if let Some(t) = to.as_ref().filter(|t| had(t)) {
        return Err(coded(
            exit::FAILED,
            format!("mv {name} {t}: robot {robot} has a file {t} already"),
        ));
    }
    s.entity
        .filestore(s.now(), name.as_str(), to.as_ref().map(FileName::as_str))
        .map_err(|e| coded(exit::INVALID, format!("{what}: {e}")))?;
    s.request_done(what)?;
    // CFDP's answer to a filestore request travels in the Finished PDU, which cfdp-rs 0.3
    // does not fill: the listing tells what the store holds now.
    let (files, _) = listing(&mut s, &st)?;
    let has = |n: &FileName| files.iter().any(|(f, _)| f == n.as_str());
    let ok = match &to {
        None => !has(&name),
        Some(t) => !has(&name) && has(t),
    };
    if !ok {
        return Err(coded(
            exit::FAILED,
            match &to {
                None => format!("rm {name}: refused by robot {robot}"),
                Some(t) => format!("mv {name} {t}: refused by robot {robot}"),
            },
        ));
    }
    match &to {
        None => println!("rm robot {robot}:{name}: removed"),
        Some(t) => println!("mv robot {robot}:{name} -> {t}: renamed"),
    }
    Ok(exit::OK)
}
