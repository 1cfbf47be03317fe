//! Body of the module report TM[210,3] `MODULE_REPORT` (sent at boot and on request): what
//! discovery found, in a layout the ground turns back into a module set (and so into a
//! URDF). Described field by field in `crate::tc::TMS` like every other packet; the
//! descriptor count at offset 10 is the MIB's group count (the number of bits set in the
//! present-slot mask, checked by [`ModuleReport::parse`]).
//!
//! | offset | size | field |
//! |---|---|---|
//! | 0 | 4 | configuration hash (u32) |
//! | 4 | 1 | configuration id (`ConfigId` code; 0 = none: the set is invalid) |
//! | 5 | 1 | reason code (`mmic_domain::discovery::Invalid::code`; 0 = none) |
//! | 6 | 1 | slot the reason names (0xFF = none) |
//! | 7 | 1 | replacement: 0 none accepted, 1 same as accepted, 2 changed |
//! | 8 | 2 | present slots (`SlotSet` bits) |
//! | 10 | 1 | n = number of descriptors (= present slots) |
//! | 11 | 28 × n | the descriptors of the present slots, ascending, each with its CRC |

use super::config::{config_hash, SlotSet};
use super::descriptor::{DescError, Descriptor, DESCRIPTOR_LEN};
use super::{ModuleSet, NUM_SLOTS, SLOTS};
use core::fmt;

/// Header length.
pub const REPORT_HEADER_LEN: usize = 11;
/// Largest report body.
pub const MAX_REPORT_LEN: usize = REPORT_HEADER_LEN + NUM_SLOTS * DESCRIPTOR_LEN;
/// "No slot" in the reason-slot field.
pub const NO_SLOT: u8 = 0xFF;

/// A module report.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ModuleReport {
    pub hash: u32,
    pub config: u8,
    pub reason: u8,
    pub reason_slot: u8,
    pub replacement: u8,
    pub set: ModuleSet,
}

/// Why bytes are not a module report.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ReportError {
    /// Shorter than the header or than the present slots need.
    Truncated { len: usize, needed: usize },
    /// Bytes after the last descriptor.
    Trailing { len: usize, expected: usize },
    /// A present-slot bit beyond the slots.
    BadSlots(u16),
    /// A descriptor failed its checks.
    Descriptor { slot: u8, error: DescError },
    /// A descriptor's type or side does not belong in its slot.
    WrongSlot { slot: u8 },
    /// The hash does not match the descriptors.
    Hash { stated: u32, computed: u32 },
    /// The descriptor count differs from the number of present slots.
    Count { stated: u8, present: u8 },
}

impl fmt::Display for ReportError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ReportError::Truncated { len, needed } => {
                write!(f, "module report truncated: {len} bytes, {needed} needed")
            }
            ReportError::Trailing { len, expected } => {
                write!(f, "module report has {len} bytes, {expected} expected")
            }
            ReportError::BadSlots(m) => write!(f, "module report slot mask {m:#06x} names unknown slots"),
            ReportError::Descriptor { slot, error } => write!(f, "module report slot {slot}: {error}"),
            ReportError::WrongSlot { slot } => write!(f, "module report slot {slot}: descriptor of another slot"),
            ReportError::Count { stated, present } => {
                write!(f, "module report states {stated} descriptors, {present} slots present")
            }
            ReportError::Hash { stated, computed } => {
                write!(
                    f,
                    "module report hash {stated:#010x}, descriptors hash to {computed:#010x}"
                )
            }
        }
    }
}

impl core::error::Error for ReportError {}

fn present(set: &ModuleSet) -> SlotSet {
    let mut p = SlotSet::EMPTY;
    for (i, d) in set.iter().enumerate() {
        if d.is_some() {
            p = p.with(i as u8);
        }
    }
    p
}

impl ModuleReport {
    /// Encoded length.
    pub fn len(&self) -> usize {
        REPORT_HEADER_LEN + present(&self.set).len() as usize * DESCRIPTOR_LEN
    }
    pub fn is_empty(&self) -> bool {
        false
    }

    /// Writes the report into `buf`; returns the length written.
    pub fn emit(&self, buf: &mut [u8]) -> Result<usize, ReportError> {
        let needed = self.len();
        let len = buf.len();
        let out = buf.get_mut(..needed).ok_or(ReportError::Truncated { len, needed })?;
        out[0..4].copy_from_slice(&self.hash.to_be_bytes());
        out[4] = self.config;
        out[5] = self.reason;
        out[6] = self.reason_slot;
        out[7] = self.replacement;
        let p = present(&self.set);
        out[8..10].copy_from_slice(&p.0.to_be_bytes());
        out[10] = p.len() as u8;
        let mut at = REPORT_HEADER_LEN;
        for d in self.set.iter().flatten() {
            out[at..at + DESCRIPTOR_LEN].copy_from_slice(&d.to_bytes());
            at += DESCRIPTOR_LEN;
        }
        Ok(needed)
    }

    /// Parses and checks a report: lengths, every descriptor (CRC, slot) and the hash.
    pub fn parse(bytes: &[u8]) -> Result<ModuleReport, ReportError> {
        if bytes.len() < REPORT_HEADER_LEN {
            return Err(ReportError::Truncated {
                len: bytes.len(),
                needed: REPORT_HEADER_LEN,
            });
        }
        let mask = u16::from_be_bytes([bytes[8], bytes[9]]);
        let slots = SlotSet(mask);
        if !slots.is_subset_of(SlotSet::ALL) {
            return Err(ReportError::BadSlots(mask));
        }
        if u32::from(bytes[10]) != slots.len() {
            return Err(ReportError::Count {
                stated: bytes[10],
                present: slots.len() as u8,
            });
        }
        let expected = REPORT_HEADER_LEN + slots.len() as usize * DESCRIPTOR_LEN;
        if bytes.len() < expected {
            return Err(ReportError::Truncated {
                len: bytes.len(),
                needed: expected,
            });
        }
        if bytes.len() > expected {
            return Err(ReportError::Trailing {
                len: bytes.len(),
                expected,
            });
        }
        let mut set: ModuleSet = [None; NUM_SLOTS];
        let mut at = REPORT_HEADER_LEN;
        for s in slots.iter() {
            let d = Descriptor::parse(&bytes[at..at + DESCRIPTOR_LEN])
                .map_err(|error| ReportError::Descriptor { slot: s, error })?;
            let sd = &SLOTS[s as usize];
            if d.ty != sd.ty || d.side != sd.side {
                return Err(ReportError::WrongSlot { slot: s });
            }
            set[s as usize] = Some(d);
            at += DESCRIPTOR_LEN;
        }
        let stated = u32::from_be_bytes([bytes[0], bytes[1], bytes[2], bytes[3]]);
        let computed = config_hash(&set);
        if stated != computed {
            return Err(ReportError::Hash { stated, computed });
        }
        Ok(ModuleReport {
            hash: stated,
            config: bytes[4],
            reason: bytes[5],
            reason_slot: bytes[6],
            replacement: bytes[7],
            set,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::modules::{default_set, slot};

    fn report() -> ModuleReport {
        let mut set = default_set(1000);
        set[slot::BOLTER_A as usize] = None;
        set[slot::BOLTER_B as usize] = None;
        ModuleReport {
            hash: config_hash(&set),
            config: 2,
            reason: 0,
            reason_slot: NO_SLOT,
            replacement: 1,
            set,
        }
    }

    // verifies: MOD-REP-01
    #[test]
    fn module_report_round_trips_and_is_checked() {
        let r = report();
        let mut buf = [0u8; MAX_REPORT_LEN];
        let n = r.emit(&mut buf).unwrap();
        assert_eq!(n, REPORT_HEADER_LEN + 12 * DESCRIPTOR_LEN);
        assert_eq!(ModuleReport::parse(&buf[..n]), Ok(r));
        assert_eq!(buf[8..10], [0x1f, 0xdf]);
        assert!(matches!(
            ModuleReport::parse(&buf[..n - 1]),
            Err(ReportError::Truncated { .. })
        ));
        assert!(matches!(
            ModuleReport::parse(&buf[..n + 1]),
            Err(ReportError::Trailing { .. })
        ));
        assert!(matches!(
            ModuleReport::parse(&buf[..4]),
            Err(ReportError::Truncated { .. })
        ));
        let mut bad = buf;
        bad[0] ^= 1;
        assert!(matches!(ModuleReport::parse(&bad[..n]), Err(ReportError::Hash { .. })));
        let mut bad = buf;
        bad[REPORT_HEADER_LEN + 3] ^= 1;
        assert!(matches!(
            ModuleReport::parse(&bad[..n]),
            Err(ReportError::Descriptor { slot: 0, .. })
        ));
        let mut bad = buf;
        bad[8] = 0x40;
        assert_eq!(ModuleReport::parse(&bad[..n]), Err(ReportError::BadSlots(0x40df)));
        assert!(r.emit(&mut buf[..20]).is_err());
        // Every truncation and every single bit flip of the body is refused.
        for len in 0..n {
            assert!(ModuleReport::parse(&buf[..len]).is_err());
        }
        for bit in 0..n * 8 {
            let mut b = buf;
            b[bit / 8] ^= 1 << (bit % 8);
            if (4..8).contains(&(bit / 8)) {
                continue; // config, reason, slot, replacement are plain values
            }
            assert!(ModuleReport::parse(&b[..n]).is_err(), "bit {bit}");
        }
    }
}
