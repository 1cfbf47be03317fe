//! Board A's space-link provisioning and counter area in flash (docs/space-link.md): the keys
//! written by the provisioning step, and the SDLS counters (TC receive IV, TM transmit
//! high-water mark) that must survive a restart so that no replayed TC frame is accepted
//! and no TM nonce is used twice.
//!
//! Layout (three 4 KiB sectors from [`AREA_OFFSET`], inside the `nvs` partition of the
//! default ESP-IDF partition table, which nothing else on board A uses):
//!
//! | sector | what |
//! |---|---|
//! | 0 | key record, written by `tools/provision-keys.sh` (never by the firmware) |
//! | 1, 2 | counter log: 32-byte records, appended; when a sector is full the other one is erased and receives the latest value of every counter first |
//!
//! Key record ([`KEY_RECORD_LEN`] bytes): `"MKY1"`, TC SPI (u16 BE), TM SPI (u16 BE), TC
//! key (32), TM key (32), CRC-32/ISO-HDLC of the 72 bytes before it (LE). An erased or
//! corrupted record, or one with the same key for both directions, is no key: the board
//! then accepts no TC frame.
//!
//! Counter record ([`RECORD_LEN`] bytes): `0xC5`, kind (1 TC receive, 2 TM transmit, 3
//! FARM-1 only), SPI (u16 BE), value (96-bit BE), FARM-1 state (flags: bit 0 present, bit
//! 1 lockout; V(R); FARM-B; one zero byte), write sequence number (u32 BE), 4 zero bytes,
//! CRC-32/ISO-HDLC of the 28 bytes before it (LE). Counters only grow, so at boot the
//! largest valid value of each counter in either sector wins, and the FARM-1 state of the
//! valid record with the highest sequence number: a record cut by a reset (bad CRC) or a
//! sector cut while being erased loses at most that write, which had not returned, so its
//! frame was not used. The receive counter and FARM-1's state are written in one record
//! per authentic TC frame (before its packets execute; `IvStore::record_rx_farm`), FARM-1
//! alone per control frame, the transmit high-water mark once per 1024 TM frames
//! (`mib::link::sdls::IV_RESERVE_BLOCK`).
//! Wear: 127 records per sector, one erase per 127 TC frames alternating over two
//! sectors; at 100 000 erase cycles per sector that is 25 million TC frames.

use crate::spacelink::{Keys, Resume};
use embedded_storage::nor_flash::NorFlash;
use mmic_link::farm::FarmRecord;
use mmic_link::sdls::{IvStore, StoreError};

/// Flash offset of the area (the default partition table's `nvs` partition).
pub const AREA_OFFSET: u32 = 0x9000;
/// Flash sector size of the ESP32-C3's SPI flash.
pub const SECTOR: u32 = 4096;
/// Bytes of the key record.
pub const KEY_RECORD_LEN: usize = 76;
/// Bytes of a counter record.
pub const RECORD_LEN: usize = 32;
/// Counter records per sector (the last slot stays free: a full sector is recognisable).
pub const RECORDS_PER_SECTOR: u32 = SECTOR / RECORD_LEN as u32 - 1;

const KEY_MAGIC: &[u8; 4] = b"MKY1";
const RECORD_MAGIC: u8 = 0xC5;
const KIND_RX: u8 = 1;
const KIND_TX: u8 = 2;
const KIND_FARM: u8 = 3;

fn crc32(bytes: &[u8]) -> u32 {
    crc::Crc::<u32, crc::NoTable>::new(&crc::CRC_32_ISO_HDLC).checksum(bytes)
}

/// The keys of a key record, or `None` (erased, corrupted, or the same key twice).
pub fn parse_keys(rec: &[u8; KEY_RECORD_LEN]) -> Option<Keys> {
    let crc = u32::from_le_bytes([rec[72], rec[73], rec[74], rec[75]]);
    if &rec[..4] != KEY_MAGIC || crc32(&rec[..72]) != crc {
        return None;
    }
    let mut k = Keys {
        tc_spi: u16::from_be_bytes([rec[4], rec[5]]),
        tc_key: [0; 32],
        tm_spi: u16::from_be_bytes([rec[6], rec[7]]),
        tm_key: [0; 32],
    };
    k.tc_key.copy_from_slice(&rec[8..40]);
    k.tm_key.copy_from_slice(&rec[40..72]);
    (k.tc_key != k.tm_key).then_some(k)
}

/// A key record for `keys` (what the provisioning step writes; tests).
pub fn key_record(keys: &Keys) -> [u8; KEY_RECORD_LEN] {
    let mut r = [0u8; KEY_RECORD_LEN];
    r[..4].copy_from_slice(KEY_MAGIC);
    r[4..6].copy_from_slice(&keys.tc_spi.to_be_bytes());
    r[6..8].copy_from_slice(&keys.tm_spi.to_be_bytes());
    r[8..40].copy_from_slice(&keys.tc_key);
    r[40..72].copy_from_slice(&keys.tm_key);
    let crc = crc32(&r[..72]);
    r[72..].copy_from_slice(&crc.to_le_bytes());
    r
}

/// Reads the key record at the start of the area.
pub fn read_keys<F: NorFlash>(flash: &mut F, base: u32) -> Option<Keys> {
    let mut rec = [0u8; KEY_RECORD_LEN];
    flash.read(base, &mut rec).ok()?;
    parse_keys(&rec)
}

/// One counter record's content.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Rec {
    kind: u8,
    spi: u16,
    value: u128,
    farm: Option<FarmRecord>,
    seq: u32,
}

fn record(rec: &Rec) -> [u8; RECORD_LEN] {
    let mut r = [0u8; RECORD_LEN];
    r[0] = RECORD_MAGIC;
    r[1] = rec.kind;
    r[2..4].copy_from_slice(&rec.spi.to_be_bytes());
    r[4..16].copy_from_slice(&rec.value.to_be_bytes()[4..]);
    if let Some(f) = rec.farm {
        r[16] = 1 | (u8::from(f.lockout) << 1);
        r[17] = f.vr;
        r[18] = f.farm_b;
    }
    r[20..24].copy_from_slice(&rec.seq.to_be_bytes());
    let crc = crc32(&r[..28]);
    r[28..].copy_from_slice(&crc.to_le_bytes());
    r
}

/// A valid counter record.
fn parse_record(r: &[u8; RECORD_LEN]) -> Option<Rec> {
    if r[0] != RECORD_MAGIC || crc32(&r[..28]) != u32::from_le_bytes([r[28], r[29], r[30], r[31]]) {
        return None;
    }
    let mut v = [0u8; 16];
    v[4..].copy_from_slice(&r[4..16]);
    Some(Rec {
        kind: r[1],
        spi: u16::from_be_bytes([r[2], r[3]]),
        value: u128::from_be_bytes(v),
        farm: (r[16] & 1 == 1).then_some(FarmRecord {
            vr: r[17],
            lockout: r[16] & 2 != 0,
            farm_b: r[18],
        }),
        seq: u32::from_be_bytes([r[20], r[21], r[22], r[23]]),
    })
}

/// The SDLS counter store in flash (see the module documentation).
pub struct FlashIvStore<F> {
    flash: F,
    /// Offset of the first counter sector.
    base: u32,
    /// Sector written now (0 or 1), and its next free record slot.
    active: u32,
    next: u32,
    /// Latest value per (kind, SPI).
    latest: heapless::Vec<(u8, u16, u128), 4>,
    /// FARM-1 state of the newest record that carries one, and that record's sequence.
    farm: Option<(u32, FarmRecord)>,
    /// Sequence number of the next record.
    seq: u32,
    /// Writes that failed (each refused its frame or TM block).
    pub failures: u32,
    /// Records written since boot (HK LINK_STATE_WRITES).
    pub writes: u32,
    /// A counter sector held a torn or corrupted record at boot (HK LINK_STATE_BAD_SLOT:
    /// 0 none, 1 the sector at 0xA000, 2 the sector at 0xB000; the last one found).
    pub bad_sector: u8,
}

impl<F: NorFlash> FlashIvStore<F> {
    /// Opens the counter log of the area at `base` (key sector at `base`, counter sectors
    /// after it): reads every valid record of both sectors.
    pub fn open(flash: F, base: u32) -> Self {
        let mut s = FlashIvStore {
            flash,
            base: base + SECTOR,
            active: 0,
            next: RECORDS_PER_SECTOR,
            latest: heapless::Vec::new(),
            farm: None,
            seq: 0,
            failures: 0,
            writes: 0,
            bad_sector: 0,
        };
        let mut best: Option<(u32, u32, u32)> = None; // (valid records, sector, free slot)
        for sector in 0..2 {
            let mut valid = 0;
            let mut free = None;
            for slot in 0..RECORDS_PER_SECTOR {
                let mut r = [0u8; RECORD_LEN];
                if s.flash.read(s.slot_offset(sector, slot), &mut r).is_err() {
                    break;
                }
                if let Some(rec) = parse_record(&r) {
                    valid += 1;
                    s.note(&rec);
                } else if r[0] == RECORD_MAGIC {
                    s.bad_sector = sector as u8 + 1;
                } else if free.is_none() && r.iter().all(|b| *b == 0xFF) {
                    free = Some(slot);
                }
            }
            if let Some(f) = free {
                if best.is_none_or(|(n, _, _)| valid > n) {
                    best = Some((valid, sector, f));
                }
            }
        }
        if let Some((_, sector, free)) = best {
            s.active = sector;
            s.next = free;
        }
        s
    }

    fn slot_offset(&self, sector: u32, slot: u32) -> u32 {
        self.base + sector * SECTOR + slot * RECORD_LEN as u32
    }

    fn note(&mut self, rec: &Rec) {
        self.seq = self.seq.max(rec.seq.wrapping_add(1));
        if let Some(f) = rec.farm {
            if self.farm.is_none_or(|(q, _)| rec.seq >= q) {
                self.farm = Some((rec.seq, f));
            }
        }
        if rec.kind == KIND_FARM {
            return;
        }
        let (kind, spi, value) = (rec.kind, rec.spi, rec.value);
        if let Some(e) = self.latest.iter_mut().find(|e| e.0 == kind && e.1 == spi) {
            e.2 = e.2.max(value);
        } else {
            // More than four counters never happen (one TC and one TM SPI per key set,
            // plus a spare of each); a fifth is not kept.
            let _ = self.latest.push((kind, spi, value));
        }
    }

    /// The stored counters of the provisioned SPIs.
    pub fn resume(&self, tc_spi: u16, tm_spi: u16) -> Resume {
        let get = |k, spi| self.latest.iter().find(|e| e.0 == k && e.1 == spi).map(|e| e.2);
        Resume {
            tc_last: get(KIND_RX, tc_spi),
            tm_high_water: get(KIND_TX, tm_spi).unwrap_or(0),
            farm: self.farm.map(|f| f.1),
        }
    }

    /// The flash (tests copy it to simulate a restart).
    pub fn flash(&self) -> &F {
        &self.flash
    }

    /// Appends one record; rolls over to the other sector when this one is full.
    fn append(&mut self, kind: u8, spi: u16, value: u128, farm: Option<FarmRecord>) -> Result<(), StoreError> {
        if self.next >= RECORDS_PER_SECTOR {
            let other = 1 - self.active;
            let from = self.base + other * SECTOR;
            self.flash.erase(from, from + SECTOR).map_err(|_| StoreError)?;
            self.active = other;
            self.next = 0;
            // The latest value of every counter and FARM-1's state first, so that the
            // full sector may be erased at the next rollover.
            let mut i = 0;
            while i < self.latest.len() {
                let (k, s, v) = self.latest[i];
                self.write_slot(k, s, v, None)?;
                i += 1;
            }
            if let Some((_, f)) = self.farm {
                self.write_slot(KIND_FARM, 0, 0, Some(f))?;
            }
        }
        self.write_slot(kind, spi, value, farm)
    }

    fn write_slot(&mut self, kind: u8, spi: u16, value: u128, farm: Option<FarmRecord>) -> Result<(), StoreError> {
        let off = self.slot_offset(self.active, self.next);
        let rec = Rec {
            kind,
            spi,
            value,
            farm,
            seq: self.seq,
        };
        self.next += 1;
        self.flash.write(off, &record(&rec)).map_err(|_| StoreError)?;
        self.writes = self.writes.saturating_add(1);
        self.note(&rec);
        Ok(())
    }

    fn store(&mut self, kind: u8, spi: u16, value: u128, farm: Option<FarmRecord>) -> Result<(), StoreError> {
        let r = self.append(kind, spi, value, farm);
        if r.is_err() {
            self.failures = self.failures.saturating_add(1);
        }
        r
    }
}

impl<F: NorFlash> IvStore for FlashIvStore<F> {
    fn reserve_tx(&mut self, spi: u16, high_water: u128) -> Result<(), StoreError> {
        self.store(KIND_TX, spi, high_water, None)
    }

    fn record_rx(&mut self, spi: u16, last: u128) -> Result<(), StoreError> {
        self.store(KIND_RX, spi, last, None)
    }

    fn record_rx_farm(&mut self, spi: u16, last: u128, farm: FarmRecord) -> Result<(), StoreError> {
        self.store(KIND_RX, spi, last, Some(farm))
    }

    fn record_farm(&mut self, farm: FarmRecord) -> Result<(), StoreError> {
        self.store(KIND_FARM, 0, 0, Some(farm))
    }
}
