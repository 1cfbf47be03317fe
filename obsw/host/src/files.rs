//! The host obsw's file service: its CFDP entity (`mmic_cfdp`, the code the board will run)
//! over a directory (`--files DIR`), fed with the packets of the CFDP APID that the space
//! link delivered and sending its PDUs as TM packets on that APID.
//!
//! Interface: takes space packets of `mib::cfdp::APID` (TC type) from accepted TC frames
//! only — never from the lab's bare-packet link, so nothing unauthenticated reaches the
//! store; supplies TM packets of that APID (on the files VC, `TmSink::send_file`); reports
//! to the obsw's file service component (`obsw_core::services::files`: HK FILES and the
//! FILE_* events) the counters of the entity, its [`Watch`] and the store each control
//! period, and each transaction as it begins and ends.

use std::path::Path;

use anyhow::{Context, Result};
use mmic_cfdp::dir::DirStore;
use mmic_cfdp::packet::{self, Direction};
use mmic_cfdp::watch::Watch;
use mmic_cfdp::{Entity, Parts};
use obsw_core::obsw::Obsw;
use obsw_core::services::files::{cfdp, FileCounters, Report};
use obsw_core::tm::{TmSink, TmStore};

/// Bytes the host store holds: the board's whole flash, so that the host can take any
/// file the link can carry (the board's own area is `mib::cfdp::BOARD_STORE_BYTES`).
pub const HOST_STORE_BYTES: u64 = 4 << 20;

/// Where the next transaction sequence number is kept: in the store's folder under a name
/// no store file can have (store names never start with '.').
const SEQ_FILE: &str = ".cfdp-seq";

/// Opens the store in `dir`, with the sequence number kept there.
pub fn parts(dir: &Path) -> Result<Parts<DirStore>> {
    let store = DirStore::open(dir, HOST_STORE_BYTES).with_context(|| format!("--files {}", dir.display()))?;
    let parts = Parts::new(store);
    if let Some(seq) = std::fs::read_to_string(dir.join(SEQ_FILE))
        .ok()
        .and_then(|t| t.trim().parse().ok())
    {
        parts.set_next_seq(seq);
    }
    Ok(parts)
}

/// The file service (see the module documentation).
pub struct Files<'a> {
    entity: Entity<'a, DirStore>,
    parts: &'a Parts<DirStore>,
    dir: std::path::PathBuf,
    kept_seq: u16,
    /// Its PDUs to the downlink.
    down: cfdp::PduDownlink,
    watch: Watch,
    /// Files in the store and its free bytes, and when they are counted next.
    store: cfdp::StoreLook,
    /// Partly received files removed at start.
    removed: u16,
}

impl<'a> Files<'a> {
    pub fn new(robot: u8, dir: &Path, parts: &'a Parts<DirStore>) -> Self {
        let entity = Entity::new(mib::cfdp::robot_entity_id(robot), mib::cfdp::GROUND_ENTITY_ID, parts);
        // Files whose transfer a reset cut short: never taken for the file they were to be.
        // Counted in HK FILES and evented (FILE_PARTIALS_REMOVED) at the first period.
        let discarded = entity.discard_partial();
        Files {
            parts,
            dir: dir.to_path_buf(),
            kept_seq: parts.next_seq(),
            entity,
            down: cfdp::PduDownlink::default(),
            watch: Watch::default(),
            store: cfdp::StoreLook::default(),
            removed: u16::try_from(discarded).unwrap_or(u16::MAX),
        }
    }

    /// Whether `packet` is the service's (then it was taken, and the PDUs it caused sent).
    pub fn packet<S: TmStore>(
        &mut self,
        now_ms: u64,
        packet: &[u8],
        obsw: &mut Obsw<S>,
        down: &mut impl TmSink,
    ) -> bool {
        if packet::apid(packet) != Some(mib::cfdp::APID) {
            return false;
        }
        // A packet of the APID that is not an uplink PDU packet is refused and counted.
        let before = self.entity.counters();
        self.entity.receive_packet(now_ms, Direction::Up, packet);
        let after = self.entity.counters();
        if after.received != before.received && after.handler_errors == before.handler_errors {
            if let Some(o) = packet::unwrap(Direction::Up, packet).and_then(|pdu| self.watch.taken(pdu)) {
                obsw.files_report(now_ms, Report::Began(cfdp::began(&o)), down);
            }
        }
        self.flush(now_ms, obsw, down);
        // HK asked for in the same frame counts this packet, and a refusal is evented now.
        obsw.files_report(now_ms, Report::Counters(self.counters()), down);
        true
    }

    /// Timers and file data; the PDUs go down as TM packets; the transactions that ended
    /// and this period's counters to the obsw.
    pub fn poll<S: TmStore>(&mut self, now_ms: u64, obsw: &mut Obsw<S>, down: &mut impl TmSink) {
        self.entity.poll(now_ms);
        self.flush(now_ms, obsw, down);
        let mut ended = false;
        while let Some(f) = self.entity.take_finished() {
            obsw.files_report(now_ms, Report::Ended(cfdp::ended(&self.entity, &self.watch, &f)), down);
            ended = true;
        }
        if self.parts.next_seq() != self.kept_seq {
            // Written beside, then renamed: a crash leaves the old number or the new.
            let (tmp, path) = (self.dir.join(".cfdp-seq.new"), self.dir.join(SEQ_FILE));
            let kept =
                std::fs::write(&tmp, self.parts.next_seq().to_string()).and_then(|_| std::fs::rename(&tmp, &path));
            match kept {
                Ok(()) => self.kept_seq = self.parts.next_seq(),
                Err(e) => log::error!("files: {}: {e}", path.display()),
            }
        }
        self.store.update(now_ms, ended, &self.entity);
        obsw.files_report(now_ms, Report::Counters(self.counters()), down);
    }

    /// Sends the PDUs waiting in the outbox (board A's way, `cfdp::PduDownlink`); a
    /// transaction one of them opens to the obsw.
    fn flush<S: TmStore>(&mut self, now_ms: u64, obsw: &mut Obsw<S>, down: &mut impl TmSink) {
        let mut buf = [0u8; mib::cfdp::MAX_PACKET_LEN];
        while let Some(opened) = self.down.send_next(&mut self.entity, &mut self.watch, down, &mut buf) {
            if let Some(o) = opened {
                obsw.files_report(now_ms, Report::Began(cfdp::began(&o)), down);
            }
        }
    }

    /// What the entity, its watch, its downlink and the store counted.
    fn counters(&self) -> FileCounters {
        cfdp::counters(&self.entity, &self.watch, &self.down, &self.store, self.removed)
    }
}
