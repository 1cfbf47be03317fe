//! The host obsw's file service: its CFDP entity (`mmic_cfdp`, the code the board will run)
//! over a directory (`--files DIR`), fed with the packets of the CFDP APID that the space
//! link delivered and sending its PDUs as TM packets on that APID.
//!
//! Interface: takes space packets of `mib::cfdp::APID` (TC type) from accepted TC frames
//! only — never from the lab's bare-packet link, so nothing unauthenticated reaches the
//! store; supplies TM packets of that APID (on the files VC, `TmSink::send_file`); its counters
//! ([`mmic_cfdp::entity::Counters`], the store's) are logged when they change.

use std::path::Path;

use anyhow::{Context, Result};
use mmic_cfdp::dir::DirStore;
use mmic_cfdp::entity::Counters;
use mmic_cfdp::packet::{self, Direction};
use mmic_cfdp::store::StoreCounters;
use mmic_cfdp::{Entity, Parts};
use obsw_core::tm::TmSink;

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
    seq: u16,
    logged: (Counters, StoreCounters),
}

impl<'a> Files<'a> {
    pub fn new(robot: u8, dir: &Path, parts: &'a Parts<DirStore>) -> Self {
        let entity = Entity::new(mib::cfdp::robot_entity_id(robot), mib::cfdp::GROUND_ENTITY_ID, parts);
        // Files whose transfer a reset cut short: never taken for the file they were to be.
        let discarded = entity.discard_partial();
        if discarded > 0 {
            log::warn!("files: {discarded} partly received file(s) of an interrupted transfer removed");
        }
        Files {
            parts,
            dir: dir.to_path_buf(),
            kept_seq: parts.next_seq(),
            entity,
            seq: 0,
            logged: Default::default(),
        }
    }

    /// Whether `packet` is the service's (then it was taken).
    pub fn packet(&mut self, now_ms: u64, packet: &[u8]) -> bool {
        if packet::apid(packet) != Some(mib::cfdp::APID) {
            return false;
        }
        // A packet of the APID that is not an uplink PDU packet is refused and counted.
        self.entity.receive_packet(now_ms, Direction::Up, packet);
        true
    }

    /// Timers and file data; the PDUs go down as TM packets.
    pub fn poll(&mut self, now_ms: u64, down: &mut impl TmSink) {
        self.entity.poll(now_ms);
        self.flush(down);
        while let Some(f) = self.entity.take_finished() {
            log::info!(
                "files: transaction {}/{} {} {:?}{}",
                f.source,
                f.seq,
                if f.sent { "sent" } else { "received" },
                f.condition,
                if f.complete { ", complete" } else { ", NOT complete" }
            );
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
        let now = (self.entity.counters(), self.entity.store().counters());
        if now != self.logged {
            log::warn!("files: counters {:?}, store {:?}", now.0, now.1);
            self.logged = now;
        }
    }

    /// Sends the PDUs waiting in the outbox.
    pub fn flush(&mut self, down: &mut impl TmSink) {
        let mut buf = [0u8; mib::cfdp::MAX_PACKET_LEN];
        while let Some(pdu) = self.entity.pop() {
            if let Some(n) = packet::wrap(Direction::Down, self.seq, &pdu, &mut buf) {
                self.seq = self.seq.wrapping_add(1) & 0x3FFF;
                down.send_file(&buf[..n]);
            }
        }
    }
}
