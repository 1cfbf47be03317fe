//! ESP-IDF's OTA data: which application slot the second-stage bootloader starts, and the
//! rollback of an image that never confirms itself.
//!
//! The `otadata` partition holds two sectors; each begins with one `esp_ota_select_entry_t`
//! (32 bytes, little-endian): `ota_seq` u32, `seq_label` [u8; 20] (unused, left erased),
//! `ota_state` u32, `crc` u32 = CRC-32 of the four bytes of `ota_seq` as ESP-IDF computes it
//! (`bootloader_common_ota_select_crc`: `esp_rom_crc32_le(UINT32_MAX, &ota_seq, 4)`, i.e.
//! the reflected CRC-32 polynomial with initial value 0 and the result inverted). A record
//! is in force when `ota_seq` is not 0xFFFFFFFF, its CRC holds and its state is neither
//! INVALID nor ABORTED; of two in force the higher `ota_seq` wins; it boots slot
//! `(ota_seq − 1) mod 2`; with none in force slot 0 boots (`bootloader_common_get_active_otadata`,
//! `bootloader_utility_get_selected_boot_partition`).
//!
//! With rollback enabled (`CONFIG_BOOTLOADER_APP_ROLLBACK_ENABLE`) the bootloader turns a
//! record in force found NEW into PENDING_VERIFY before it starts the slot, and one found
//! PENDING_VERIFY (started once, never confirmed) into ABORTED, then chooses again. Each of
//! those, and the image's own confirmation, rewrites the record in its own sector (erase,
//! then write); an activation writes the *other* sector (`esp_rewrite_ota_data`). This
//! module does exactly these writes ([`boot`], [`activate`], [`confirm`]), so that
//! ESP-IDF's bootloader and this code read each other's records.
//!
//! Power-fail safety follows from where the bytes go: a record is erased and written in its
//! own sector only, the CRC (its last field) is written last, and the other sector is
//! never touched by a state change; a cut at any byte leaves either the record written,
//! or one that is not in force, and the choice falls to the other sector's record — the
//! slot that ran before. The unit tests cut every operation at every byte.

use crc::{Algorithm, Crc};
use mib::update::ota::{state, ENTRY_LEN, SECOND_SECTOR, SLOTS};

use crate::flash::{Flash, FlashError};

/// ESP-IDF's `esp_rom_crc32_le(UINT32_MAX, ..)`: the ROM's CRC-32 inverts the value it is
/// given on entry and its result on exit, so the register starts at 0.
const ESP_CRC: Algorithm<u32> = Algorithm {
    width: 32,
    poly: 0x04c1_1db7,
    init: 0,
    refin: true,
    refout: true,
    xorout: 0xffff_ffff,
    check: 0xd202_d277,
    residue: 0xdebb_20e3,
};

/// The CRC of a record: over the little-endian bytes of `ota_seq` only.
pub fn crc(seq: u32) -> u32 {
    Crc::<u32>::new(&ESP_CRC).checksum(&seq.to_le_bytes())
}

/// `ota_state` of a record.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OtaState {
    New,
    PendingVerify,
    Valid,
    Invalid,
    Aborted,
    Undefined,
    /// A value ESP-IDF does not define (a record part written, or damaged).
    Unknown(u32),
}

impl OtaState {
    pub const fn from_raw(v: u32) -> Self {
        match v {
            state::NEW => OtaState::New,
            state::PENDING_VERIFY => OtaState::PendingVerify,
            state::VALID => OtaState::Valid,
            state::INVALID => OtaState::Invalid,
            state::ABORTED => OtaState::Aborted,
            state::UNDEFINED => OtaState::Undefined,
            other => OtaState::Unknown(other),
        }
    }
    pub const fn raw(self) -> u32 {
        match self {
            OtaState::New => state::NEW,
            OtaState::PendingVerify => state::PENDING_VERIFY,
            OtaState::Valid => state::VALID,
            OtaState::Invalid => state::INVALID,
            OtaState::Aborted => state::ABORTED,
            OtaState::Undefined => state::UNDEFINED,
            OtaState::Unknown(v) => v,
        }
    }
}

/// One `esp_ota_select_entry_t`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Entry {
    pub seq: u32,
    pub label: [u8; 20],
    pub state: OtaState,
    pub crc: u32,
}

impl Entry {
    /// A record choosing `seq` in `state`, with its CRC (label erased, as ESP-IDF leaves it).
    pub fn new(seq: u32, state: OtaState) -> Self {
        Entry {
            seq,
            label: [0xFF; 20],
            state,
            crc: crc(seq),
        }
    }

    pub fn parse(b: &[u8; ENTRY_LEN]) -> Self {
        let u = |o: usize| u32::from_le_bytes([b[o], b[o + 1], b[o + 2], b[o + 3]]);
        let mut label = [0; 20];
        label.copy_from_slice(&b[4..24]);
        Entry {
            seq: u(0),
            label,
            state: OtaState::from_raw(u(24)),
            crc: u(28),
        }
    }

    pub fn emit(&self) -> [u8; ENTRY_LEN] {
        let mut b = [0xFF; ENTRY_LEN];
        b[0..4].copy_from_slice(&self.seq.to_le_bytes());
        b[4..24].copy_from_slice(&self.label);
        b[24..28].copy_from_slice(&self.state.raw().to_le_bytes());
        b[28..32].copy_from_slice(&self.crc.to_le_bytes());
        b
    }

    /// In force (`bootloader_common_ota_select_valid`).
    pub fn in_force(&self) -> bool {
        self.seq != u32::MAX
            && !matches!(self.state, OtaState::Invalid | OtaState::Aborted)
            && self.crc == crc(self.seq)
    }

    /// The application slot this record boots.
    pub fn slot(&self) -> u8 {
        (self.seq.wrapping_sub(1) % SLOTS) as u8
    }
}

/// Both records as read from the partition.
pub type Records = [Entry; 2];

/// Reads both records.
pub fn read(flash: &mut dyn Flash) -> Result<Records, FlashError> {
    let mut a = [0; ENTRY_LEN];
    let mut b = [0; ENTRY_LEN];
    flash.read(0, &mut a)?;
    flash.read(SECOND_SECTOR, &mut b)?;
    Ok([Entry::parse(&a), Entry::parse(&b)])
}

/// The record in force (`bootloader_common_get_active_otadata`): the higher `ota_seq` of
/// those in force, the first on a tie.
pub fn active(r: &Records) -> Option<usize> {
    match (r[0].in_force(), r[1].in_force()) {
        (true, true) => Some(if r[0].seq >= r[1].seq { 0 } else { 1 }),
        (true, false) => Some(0),
        (false, true) => Some(1),
        (false, false) => None,
    }
}

/// Erases sector `i` of the partition and writes `e` at its start.
fn write_record(flash: &mut dyn Flash, i: usize, e: &Entry) -> Result<(), FlashError> {
    let at = if i == 0 { 0 } else { SECOND_SECTOR };
    flash.erase(at, at + SECOND_SECTOR)?;
    flash.write(at, &e.emit())
}

/// What the bootloader decided.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Boot {
    /// The slot it starts.
    pub slot: u8,
    /// The state of the record that chose it (`None`: no record in force, slot 0 by default).
    pub state: Option<OtaState>,
    /// A slot whose image never confirmed and was abandoned at this boot.
    pub aborted: Option<u8>,
}

/// The second-stage bootloader's choice with rollback enabled, and the record writes it
/// makes: a record in force found PENDING_VERIFY becomes ABORTED and the choice is made
/// again; one found NEW becomes PENDING_VERIFY. A failed write leaves the records as they
/// were and the slot already chosen still boots (as ESP-IDF: it logs and carries on).
pub fn boot(flash: &mut dyn Flash) -> Result<Boot, FlashError> {
    let mut r = read(flash)?;
    let mut aborted = None;
    // Two records: at most one abort can change the choice before none is pending.
    for _ in 0..2 {
        let Some(i) = active(&r) else { break };
        if r[i].state != OtaState::PendingVerify {
            break;
        }
        r[i].state = OtaState::Aborted;
        aborted = Some(r[i].slot());
        write_record(flash, i, &r[i])?;
    }
    let Some(i) = active(&r) else {
        return Ok(Boot {
            slot: 0,
            state: None,
            aborted,
        });
    };
    if r[i].state == OtaState::New {
        r[i].state = OtaState::PendingVerify;
        write_record(flash, i, &r[i])?;
    }
    Ok(Boot {
        slot: r[i].slot(),
        state: Some(r[i].state),
        aborted,
    })
}

/// `esp_ota_set_boot_partition` with rollback: a record choosing `slot` in state NEW, in
/// the sector that does not hold the record in force, with ESP-IDF's next sequence number.
pub fn activate(flash: &mut dyn Flash, slot: u8) -> Result<(), FlashError> {
    if u32::from(slot) >= SLOTS {
        return Err(FlashError::OutOfBounds);
    }
    let r = read(flash)?;
    let first = (u32::from(slot) + 1) % SLOTS;
    let (seq, sector) = match active(&r) {
        Some(i) => {
            // The smallest `first + k·SLOTS` not below the sequence in force.
            let cur = r[i].seq;
            let k = cur.saturating_sub(first).div_ceil(SLOTS);
            (first + k * SLOTS, 1 - i)
        }
        None => (u32::from(slot) + 1, 0),
    };
    write_record(flash, sector, &Entry::new(seq, OtaState::New))
}

/// `esp_ota_mark_app_valid_cancel_rollback`: the record in force becomes VALID (rewritten in
/// its own sector). False when there was nothing to confirm (no record in force, or it is
/// already VALID).
pub fn confirm(flash: &mut dyn Flash) -> Result<bool, FlashError> {
    let mut r = read(flash)?;
    let Some(i) = active(&r) else { return Ok(false) };
    if r[i].state == OtaState::Valid {
        return Ok(false);
    }
    r[i].state = OtaState::Valid;
    write_record(flash, i, &r[i])?;
    Ok(true)
}

/// What the running image learns from the records (after the bootloader's writes).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Running {
    /// The slot the records choose (the one running).
    pub slot: u8,
    /// The state of its record (`None`: no record in force).
    pub state: Option<OtaState>,
    /// The other sector holds a more recent record that was ABORTED: the last activation
    /// rolled back to this slot.
    pub rolled_back_from: Option<u8>,
}

/// Reads the records as the running image sees them.
pub fn running(flash: &mut dyn Flash) -> Result<Running, FlashError> {
    let r = read(flash)?;
    let act = active(&r);
    let (slot, state, seq) = match act {
        Some(i) => (r[i].slot(), Some(r[i].state), r[i].seq),
        None => (0, None, 0),
    };
    let rolled_back_from = r
        .iter()
        .enumerate()
        .filter(|(i, e)| Some(*i) != act && e.state == OtaState::Aborted && e.crc == crc(e.seq) && e.seq > seq)
        .map(|(_, e)| e.slot())
        .next();
    Ok(Running {
        slot,
        state,
        rolled_back_from,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::flash::RamNor;

    type Ota = RamNor<8192>;

    // Known answers from esp-hal's esp-bootloader-esp-idf (src/ota.rs tests), whose bytes
    // were taken from ESP-IDF-written otadata: seq 1 → CRC 0x4743989A, seq 2 → 0x55F63774.
    // verifies: UPD-OTA-01
    #[test]
    fn records_match_esp_idf_bytes() {
        let one = Entry::new(1, OtaState::Valid).emit();
        let mut want = [0xFF; 32];
        want[..4].copy_from_slice(&[1, 0, 0, 0]);
        want[24..].copy_from_slice(&[2, 0, 0, 0, 154, 152, 67, 71]);
        assert_eq!(one, want);
        let two = Entry::new(2, OtaState::New).emit();
        assert_eq!(&two[24..], &[0, 0, 0, 0, 116, 55, 246, 85]);
        assert_eq!(Entry::parse(&two), Entry::new(2, OtaState::New));
        assert_eq!(Entry::parse(&two).slot(), 1);
        assert_eq!(Crc::<u32>::new(&ESP_CRC).checksum(b"123456789"), ESP_CRC.check);
    }

    // verifies: UPD-OTA-01
    #[test]
    fn erased_otadata_boots_slot_0_and_activation_follows_esp_idf_sequence() {
        let mut f = Ota::new();
        assert_eq!(
            boot(&mut f).unwrap(),
            Boot {
                slot: 0,
                state: None,
                aborted: None
            }
        );
        activate(&mut f, 1).unwrap();
        let r = read(&mut f).unwrap();
        // No record in force: ESP-IDF writes sector 0 with seq = slot + 1.
        assert_eq!(r[0], Entry::new(2, OtaState::New));
        let b = boot(&mut f).unwrap();
        assert_eq!((b.slot, b.state), (1, Some(OtaState::PendingVerify)));
        assert!(confirm(&mut f).unwrap());
        activate(&mut f, 0).unwrap();
        let r = read(&mut f).unwrap();
        assert_eq!(
            r[1],
            Entry::new(3, OtaState::New),
            "the other sector, next seq for slot 0"
        );
        activate(&mut f, 1).unwrap();
        assert_eq!(read(&mut f).unwrap()[0], Entry::new(4, OtaState::New));
    }

    // verifies: UPD-OTA-02
    #[test]
    fn an_image_that_never_confirms_is_aborted_at_the_next_boot() {
        let mut f = Ota::new();
        activate(&mut f, 1).unwrap();
        assert_eq!(boot(&mut f).unwrap().slot, 1);
        assert!(confirm(&mut f).unwrap());
        activate(&mut f, 0).unwrap();
        let first = boot(&mut f).unwrap();
        assert_eq!((first.slot, first.state), (0, Some(OtaState::PendingVerify)));
        // Reset without confirming.
        let second = boot(&mut f).unwrap();
        assert_eq!(
            second,
            Boot {
                slot: 1,
                state: Some(OtaState::Valid),
                aborted: Some(0)
            }
        );
        let run = running(&mut f).unwrap();
        assert_eq!(run.rolled_back_from, Some(0));
        assert_eq!(run.slot, 1);
        // And it stays so.
        assert_eq!(boot(&mut f).unwrap().slot, 1);
        // The first update from an erased otadata rolls back to slot 0.
        let mut g = Ota::new();
        activate(&mut g, 1).unwrap();
        boot(&mut g).unwrap();
        let b = boot(&mut g).unwrap();
        assert_eq!((b.slot, b.aborted), (0, Some(1)));
        assert_eq!(running(&mut g).unwrap().rolled_back_from, Some(1));
    }

    /// Runs `op` on a copy of `start` with the power cut after `steps` byte programs and
    /// erases, then boots with the power back: the slot chosen, or `None` when the
    /// operation completed before the cut.
    fn cut(start: &Ota, steps: usize, op: fn(&mut Ota) -> Result<(), FlashError>) -> Option<(u8, Ota)> {
        let mut f = Ota::new();
        f.bytes = start.bytes;
        f.cut_after(Some(steps));
        let done = op(&mut f).is_ok();
        f.cut_after(None);
        if done {
            return None;
        }
        let b = boot(&mut f).expect("boot reads and writes with power");
        // The choice is defined: booting again (a second reset) keeps it, unless the image
        // chosen was left PENDING_VERIFY, which a second boot must abort.
        Some((b.slot, f))
    }

    fn check_every_cut(name: &str, start: &Ota, op: fn(&mut Ota) -> Result<(), FlashError>, allowed: &[u8]) -> usize {
        let mut cuts = 0;
        for steps in 0.. {
            let Some((slot, mut f)) = cut(start, steps, op) else {
                break;
            };
            assert!(
                allowed.contains(&slot),
                "{name}: cut after {steps} steps boots slot {slot}"
            );
            let again = boot(&mut f).unwrap();
            assert!(allowed.contains(&again.slot), "{name}: second boot after cut {steps}");
            cuts += 1;
        }
        assert!(
            cuts >= 33,
            "{name}: an erase and 32 byte writes at least were cut ({cuts})"
        );
        cuts
    }

    // verifies: UPD-OTA-03
    #[test]
    fn a_reset_at_any_byte_of_an_otadata_write_leaves_a_defined_bootable_choice() {
        // Running slot 1 confirmed (seq 2 in sector 0); slot 0 holds the previous image.
        let mut base = Ota::new();
        activate(&mut base, 1).unwrap();
        boot(&mut base).unwrap();
        confirm(&mut base).unwrap();

        // Activation of slot 0: the old choice or the new one.
        check_every_cut("activate", &base, |f| activate(f, 0), &[0, 1]);

        // The bootloader's NEW → PENDING_VERIFY: the new slot, or back to the old one.
        let mut activated = Ota::new();
        activated.bytes = base.bytes;
        activate(&mut activated, 0).unwrap();
        check_every_cut("mark pending", &activated, |f| boot(f).map(|_| ()), &[0, 1]);

        // The image's confirmation: the confirmed slot, or the old one.
        let mut pending = Ota::new();
        pending.bytes = activated.bytes;
        boot(&mut pending).unwrap();
        check_every_cut("confirm", &pending, |f| confirm(f).map(|_| ()), &[0, 1]);

        // The bootloader's abort of an image that never confirmed: only the old slot.
        check_every_cut(
            "abort",
            &pending,
            |f| {
                let b = boot(f)?;
                assert_eq!(b.slot, 1);
                Ok(())
            },
            &[1],
        );
    }

    // verifies: UPD-OTA-01
    #[test]
    fn damaged_records_are_not_in_force() {
        let mut f = Ota::new();
        activate(&mut f, 1).unwrap();
        f.bytes[0] ^= 0x04; // seq changed, CRC no longer holds
        assert_eq!(boot(&mut f).unwrap().slot, 0);
        let mut e = Entry::new(5, OtaState::Invalid);
        assert!(!e.in_force());
        e.state = OtaState::Unknown(7);
        assert!(e.in_force(), "ESP-IDF only refuses INVALID and ABORTED");
        assert!(activate(&mut f, 2).is_err());
    }
}
