//! The Communications Link Control Word (CCSDS 232.0-B-4 §4.2.1, 132.0-B-3 §4.1.5): the
//! FARM-1's report, carried in the operational control field of every TM frame.
//!
//! ```text
//! bit  0    1-2    3-5     6-7   8-13  14-15  16    17    18   19   20   21-22  23   24-31
//!     +----+------+-------+-----+-----+------+-----+-----+----+----+----+------+----+------+
//!     |type|vers. |status |COP  |VCID |spare |noRF |noBL |lock|wait|retr|FARM-B|spr |N(R)  |
//!     +----+------+-------+-----+-----+------+-----+-----+----+----+----+------+----+------+
//! ```

use core::fmt;

/// Why a 32-bit OCF is not a CLCW we understand.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ClcwError {
    /// Control word type 1 (a type-2 report, not a CLCW).
    NotAClcw,
    /// CLCW version other than `00`.
    BadVersion(u8),
}

impl fmt::Display for ClcwError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ClcwError::NotAClcw => write!(f, "OCF holds a type-2 report, not a CLCW"),
            ClcwError::BadVersion(v) => write!(f, "CLCW version {v}"),
        }
    }
}

impl core::error::Error for ClcwError {}

/// COP in effect (2 bits).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CopInEffect {
    None,
    Cop1,
    Unknown(u8),
}

impl From<u8> for CopInEffect {
    fn from(v: u8) -> Self {
        match v & 3 {
            0 => CopInEffect::None,
            1 => CopInEffect::Cop1,
            n => CopInEffect::Unknown(n),
        }
    }
}

impl From<CopInEffect> for u8 {
    fn from(c: CopInEffect) -> u8 {
        match c {
            CopInEffect::None => 0,
            CopInEffect::Cop1 => 1,
            CopInEffect::Unknown(n) => n & 3,
        }
    }
}

/// A decoded CLCW.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Clcw {
    pub status: u8,
    pub cop_in_effect: CopInEffect,
    pub vcid: u8,
    pub no_rf_available: bool,
    pub no_bit_lock: bool,
    pub lockout: bool,
    pub wait: bool,
    pub retransmit: bool,
    /// The two low bits of the FARM-B counter.
    pub farm_b_counter: u8,
    /// N(R): the next expected frame sequence number, V(R). Every N(S) below it is
    /// acknowledged.
    pub report_value: u8,
}

impl Clcw {
    pub fn parse(word: u32) -> Result<Clcw, ClcwError> {
        if word & 0x8000_0000 != 0 {
            return Err(ClcwError::NotAClcw);
        }
        let version = ((word >> 29) & 3) as u8;
        if version != 0 {
            return Err(ClcwError::BadVersion(version));
        }
        Ok(Clcw {
            status: ((word >> 26) & 7) as u8,
            cop_in_effect: CopInEffect::from(((word >> 24) & 3) as u8),
            vcid: ((word >> 18) & 0x3F) as u8,
            no_rf_available: word & (1 << 15) != 0,
            no_bit_lock: word & (1 << 14) != 0,
            lockout: word & (1 << 13) != 0,
            wait: word & (1 << 12) != 0,
            retransmit: word & (1 << 11) != 0,
            farm_b_counter: ((word >> 9) & 3) as u8,
            report_value: (word & 0xFF) as u8,
        })
    }

    pub fn emit(&self) -> u32 {
        (u32::from(self.status & 7) << 26)
            | (u32::from(u8::from(self.cop_in_effect)) << 24)
            | (u32::from(self.vcid & 0x3F) << 18)
            | (u32::from(self.no_rf_available) << 15)
            | (u32::from(self.no_bit_lock) << 14)
            | (u32::from(self.lockout) << 13)
            | (u32::from(self.wait) << 12)
            | (u32::from(self.retransmit) << 11)
            | (u32::from(self.farm_b_counter & 3) << 9)
            | u32::from(self.report_value)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    // verifies: LINK-CLCW-01
    #[test]
    fn clcw_byte_array() {
        // COP-1, VC 0, lockout + retransmit, FARM-B 2, N(R) 0x2A.
        let word = u32::from_be_bytes([0x01, 0x00, 0x2C, 0x2A]);
        let c = Clcw::parse(word).unwrap();
        assert_eq!(c.cop_in_effect, CopInEffect::Cop1);
        assert_eq!(c.vcid, 0);
        assert!(c.lockout && !c.wait && c.retransmit);
        assert_eq!(c.farm_b_counter, 2);
        assert_eq!(c.report_value, 0x2A);
        assert_eq!(c.emit(), word);
        let vc5_wait = u32::from_be_bytes([0x01, 0x14, 0x10, 0x07]);
        let c = Clcw::parse(vc5_wait).unwrap();
        assert_eq!((c.vcid, c.wait, c.lockout, c.report_value), (5, true, false, 7));
        assert_eq!(Clcw::parse(0x8000_0000), Err(ClcwError::NotAClcw));
        assert_eq!(Clcw::parse(0x2000_0000), Err(ClcwError::BadVersion(1)));
    }

    proptest! {
        // verifies: LINK-CLCW-01
        #[test]
        fn clcw_round_trip(word in any::<u32>()) {
            // Every word parses or errs; a parsed word re-emits to itself minus spare bits.
            if let Ok(c) = Clcw::parse(word) {
                let spare = (3 << 16) | (1 << 8);
                prop_assert_eq!(c.emit(), word & !spare);
                prop_assert_eq!(Clcw::parse(c.emit()), Ok(c));
            }
        }
    }
}
