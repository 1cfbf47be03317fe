//! CCSDS space packet and PUS-C headers, the packet error control (CRC-16/CCITT-FALSE)
//! and the CDS short time stamp: the parts every packet shares.

use crate::{CdsTime, Error};
use mib::config::{MAX_PACKET_LEN, TIMESTAMP_LEN};

// Header lengths, PUS version, CDS p-field and the CCSDS epoch come from the MIB's header
// tables (`mib::headers`), the one place they are defined.
pub use mib::headers::{
    CCSDS_TO_UNIX_DAYS, CRC_LEN, MS_PER_DAY, PRIMARY_HEADER_LEN, TC_SEC_HEADER_LEN, TM_SEC_HEADER_LEN,
};
/// Shortest TC: headers and CRC.
pub const MIN_TC_LEN: usize = PRIMARY_HEADER_LEN + TC_SEC_HEADER_LEN + CRC_LEN;
/// Shortest TM: headers, time stamp and CRC.
pub const MIN_TM_LEN: usize = PRIMARY_HEADER_LEN + TM_SEC_HEADER_LEN + TIMESTAMP_LEN + CRC_LEN;
/// PUS-C version number in the secondary headers.
pub const PUS_C: u8 = mib::headers::PUS_C_VERSION as u8;
/// P-field of our CDS short time stamps (16-bit days, no sub-milliseconds).
pub const CDS_PFIELD: u8 = mib::headers::CDS_SHORT_PFIELD as u8;

/// CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF), the PUS packet error control: the MIB's
/// one CRC-16 (`mib::headers::PEC_CRC`, the `crc` crate).
pub fn crc16(data: &[u8]) -> u16 {
    mib::headers::PEC_CRC.checksum(data)
}

impl CdsTime {
    pub const ZERO: CdsTime = CdsTime {
        pfield: CDS_PFIELD,
        days: 0,
        ms_of_day: 0,
    };
    /// Milliseconds since the Unix epoch.
    pub const fn unix_ms(&self) -> i64 {
        (self.days as i64 - CCSDS_TO_UNIX_DAYS) * MS_PER_DAY + self.ms_of_day as i64
    }
    /// The time stamp of a Unix time (saturated to the 16-bit day range).
    pub const fn from_unix_ms(ms: i64) -> CdsTime {
        let mut days = ms.div_euclid(MS_PER_DAY) + CCSDS_TO_UNIX_DAYS;
        if days < 0 {
            days = 0;
        } else if days > u16::MAX as i64 {
            days = u16::MAX as i64;
        }
        CdsTime {
            pfield: CDS_PFIELD,
            days: days as u16,
            ms_of_day: ms.rem_euclid(MS_PER_DAY) as u32,
        }
    }
    /// Milliseconds since the CCSDS epoch (ordering key of time stamps).
    pub const fn ccsds_ms(&self) -> u64 {
        self.days as u64 * MS_PER_DAY as u64 + self.ms_of_day as u64
    }
    pub fn to_bytes(&self) -> [u8; TIMESTAMP_LEN] {
        let d = self.days.to_be_bytes();
        let m = self.ms_of_day.to_be_bytes();
        [self.pfield, d[0], d[1], m[0], m[1], m[2], m[3]]
    }
}

/// The fixed fields of a CCSDS primary header.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Primary {
    pub version: u8,
    pub is_tc: bool,
    pub sec_hdr: bool,
    pub apid: u16,
    pub seq_flags: u8,
    pub seq_count: u16,
    /// Total packet length (data length field + 7).
    pub len: usize,
}

impl Primary {
    /// Reads the primary header at the start of `b` (no check beyond its 6 bytes).
    pub fn parse(b: &[u8]) -> Result<Primary, Error> {
        let h = b.get(..PRIMARY_HEADER_LEN).ok_or(Error::Truncated {
            field: "primary header",
        })?;
        Ok(Primary {
            version: h[0] >> 5,
            is_tc: h[0] & 0x10 != 0,
            sec_hdr: h[0] & 0x08 != 0,
            apid: u16::from_be_bytes([h[0] & 0x07, h[1]]),
            seq_flags: h[2] >> 6,
            seq_count: u16::from_be_bytes([h[2] & 0x3F, h[3]]),
            len: u16::from_be_bytes([h[4], h[5]]) as usize + PRIMARY_HEADER_LEN + 1,
        })
    }
    fn write(&self, out: &mut [u8]) {
        let data_len = (self.len - PRIMARY_HEADER_LEN - 1) as u16;
        let id = ((self.version as u16 & 7) << 13)
            | ((self.is_tc as u16) << 12)
            | ((self.sec_hdr as u16) << 11)
            | (self.apid & 0x7FF);
        let psc = ((self.seq_flags as u16 & 3) << 14) | (self.seq_count & 0x3FFF);
        out[..2].copy_from_slice(&id.to_be_bytes());
        out[2..4].copy_from_slice(&psc.to_be_bytes());
        out[4..6].copy_from_slice(&data_len.to_be_bytes());
    }
}

/// Why a packet's headers are refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum HeaderError {
    /// Fewer bytes than the header or the length field promise.
    Truncated { need: usize, have: usize },
    /// Length field beyond the mission's largest packet.
    TooLong { len: usize },
    /// Not CCSDS version 0, no secondary header, or not PUS-C.
    NotPus { reason: &'static str },
    /// A TC where a TM was expected or the other way round.
    WrongType { is_tc: bool },
    /// Packet error control mismatch.
    Crc { received: u16, computed: u16 },
}

impl core::fmt::Display for HeaderError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            HeaderError::Truncated { need, have } => write!(f, "truncated packet: need {need} bytes, have {have}"),
            HeaderError::TooLong { len } => write!(f, "packet length {len} exceeds {MAX_PACKET_LEN}"),
            HeaderError::NotPus { reason } => write!(f, "not a PUS-C packet: {reason}"),
            HeaderError::WrongType { is_tc: true } => write!(f, "packet is a TC, TM expected"),
            HeaderError::WrongType { is_tc: false } => write!(f, "packet is a TM, TC expected"),
            HeaderError::Crc { received, computed } => {
                write!(f, "CRC mismatch: received 0x{received:04X}, computed 0x{computed:04X}")
            }
        }
    }
}

impl core::error::Error for HeaderError {}

/// Checks the primary header of the packet at the start of `b` (version, secondary
/// header, PUS-C, length within the mission's limit and the buffer). Returns it; the
/// packet is `b[..p.len]`. The CRC is not checked here.
pub fn check_primary(b: &[u8]) -> Result<Primary, HeaderError> {
    let p = Primary::parse(b).map_err(|_| HeaderError::Truncated {
        need: PRIMARY_HEADER_LEN,
        have: b.len(),
    })?;
    if p.version != 0 {
        return Err(HeaderError::NotPus {
            reason: "CCSDS version is not 0",
        });
    }
    if !p.sec_hdr {
        return Err(HeaderError::NotPus {
            reason: "no secondary header",
        });
    }
    if p.len > MAX_PACKET_LEN {
        return Err(HeaderError::TooLong { len: p.len });
    }
    let min = if p.is_tc { MIN_TC_LEN } else { MIN_TM_LEN };
    if p.len < min {
        return Err(HeaderError::Truncated { need: min, have: p.len });
    }
    if b.len() < p.len {
        return Err(HeaderError::Truncated {
            need: p.len,
            have: b.len(),
        });
    }
    if b[PRIMARY_HEADER_LEN] >> 4 != PUS_C {
        return Err(HeaderError::NotPus {
            reason: "PUS version is not C",
        });
    }
    Ok(p)
}

fn check_crc(raw: &[u8]) -> Result<(), HeaderError> {
    let n = raw.len();
    let received = u16::from_be_bytes([raw[n - 2], raw[n - 1]]);
    let computed = crc16(&raw[..n - 2]);
    if received != computed {
        return Err(HeaderError::Crc { received, computed });
    }
    Ok(())
}

/// A TM packet's headers and its source data.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TmPacket<'a> {
    pub primary: Primary,
    pub service: u8,
    pub subservice: u8,
    pub msg_counter: u16,
    pub dest_id: u16,
    pub time: CdsTime,
    pub source: &'a [u8],
}

impl<'a> TmPacket<'a> {
    /// Checks headers and CRC of the TM at the start of `b` (trailing bytes ignored).
    pub fn parse(b: &'a [u8]) -> Result<TmPacket<'a>, HeaderError> {
        let p = check_primary(b)?;
        if p.is_tc {
            return Err(HeaderError::WrongType { is_tc: true });
        }
        let raw = &b[..p.len];
        check_crc(raw)?;
        let s = &raw[PRIMARY_HEADER_LEN..];
        let t = &s[TM_SEC_HEADER_LEN..TM_SEC_HEADER_LEN + TIMESTAMP_LEN];
        Ok(TmPacket {
            primary: p,
            service: s[1],
            subservice: s[2],
            msg_counter: u16::from_be_bytes([s[3], s[4]]),
            dest_id: u16::from_be_bytes([s[5], s[6]]),
            time: CdsTime {
                pfield: t[0],
                days: u16::from_be_bytes([t[1], t[2]]),
                ms_of_day: u32::from_be_bytes([t[3], t[4], t[5], t[6]]),
            },
            source: &raw[PRIMARY_HEADER_LEN + TM_SEC_HEADER_LEN + TIMESTAMP_LEN..p.len - CRC_LEN],
        })
    }
}

/// The header fields of a TM to emit.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TmHeader {
    pub apid: u16,
    pub seq_count: u16,
    pub service: u8,
    pub subservice: u8,
    pub msg_counter: u16,
    pub dest_id: u16,
    pub time: CdsTime,
}

/// Writes a complete TM (headers, source data written by `body`, CRC) into `out`;
/// returns its length. `body` gets the source data area and returns the bytes used.
pub fn emit_tm(
    h: &TmHeader,
    out: &mut [u8],
    body: impl FnOnce(&mut [u8]) -> Result<usize, Error>,
) -> Result<usize, Error> {
    let hdr = PRIMARY_HEADER_LEN + TM_SEC_HEADER_LEN + TIMESTAMP_LEN;
    let cap = out.len().min(MAX_PACKET_LEN);
    if cap < hdr + CRC_LEN {
        return Err(Error::BufferTooShort {
            need: hdr + CRC_LEN,
            have: out.len(),
        });
    }
    let n = body(&mut out[hdr..cap - CRC_LEN])?;
    let len = hdr + n + CRC_LEN;
    Primary {
        version: 0,
        is_tc: false,
        sec_hdr: true,
        apid: h.apid,
        seq_flags: 3,
        seq_count: h.seq_count,
        len,
    }
    .write(out);
    let s = &mut out[PRIMARY_HEADER_LEN..];
    s[0] = PUS_C << 4;
    s[1] = h.service;
    s[2] = h.subservice;
    s[3..5].copy_from_slice(&h.msg_counter.to_be_bytes());
    s[5..7].copy_from_slice(&h.dest_id.to_be_bytes());
    s[7..14].copy_from_slice(&h.time.to_bytes());
    let crc = crc16(&out[..len - CRC_LEN]);
    out[len - CRC_LEN..len].copy_from_slice(&crc.to_be_bytes());
    Ok(len)
}

/// A TC packet's headers and its application data.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TcPacket<'a> {
    pub primary: Primary,
    /// Acknowledgement flags (low 4 bits of the first secondary-header byte).
    pub ack: u8,
    pub service: u8,
    pub subservice: u8,
    pub source_id: u16,
    pub app_data: &'a [u8],
}

impl<'a> TcPacket<'a> {
    /// Checks headers and CRC of the TC at the start of `b` (trailing bytes ignored).
    pub fn parse(b: &'a [u8]) -> Result<TcPacket<'a>, HeaderError> {
        let p = check_primary(b)?;
        if !p.is_tc {
            return Err(HeaderError::WrongType { is_tc: false });
        }
        let raw = &b[..p.len];
        check_crc(raw)?;
        let s = &raw[PRIMARY_HEADER_LEN..];
        Ok(TcPacket {
            primary: p,
            ack: s[0] & 0x0F,
            service: s[1],
            subservice: s[2],
            source_id: u16::from_be_bytes([s[3], s[4]]),
            app_data: &raw[PRIMARY_HEADER_LEN + TC_SEC_HEADER_LEN..p.len - CRC_LEN],
        })
    }
}

/// The header fields of a TC to emit.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TcHeader {
    pub apid: u16,
    pub seq_count: u16,
    pub ack: u8,
    pub service: u8,
    pub subservice: u8,
    pub source_id: u16,
}

/// Writes a complete TC (headers, application data written by `body`, CRC).
pub fn emit_tc(
    h: &TcHeader,
    out: &mut [u8],
    body: impl FnOnce(&mut [u8]) -> Result<usize, Error>,
) -> Result<usize, Error> {
    let hdr = PRIMARY_HEADER_LEN + TC_SEC_HEADER_LEN;
    let cap = out.len().min(MAX_PACKET_LEN);
    if cap < hdr + CRC_LEN {
        return Err(Error::BufferTooShort {
            need: hdr + CRC_LEN,
            have: out.len(),
        });
    }
    let n = body(&mut out[hdr..cap - CRC_LEN])?;
    let len = hdr + n + CRC_LEN;
    Primary {
        version: 0,
        is_tc: true,
        sec_hdr: true,
        apid: h.apid,
        seq_flags: 3,
        seq_count: h.seq_count,
        len,
    }
    .write(out);
    let s = &mut out[PRIMARY_HEADER_LEN..];
    s[0] = (PUS_C << 4) | (h.ack & 0x0F);
    s[1] = h.service;
    s[2] = h.subservice;
    s[3..5].copy_from_slice(&h.source_id.to_be_bytes());
    let crc = crc16(&out[..len - CRC_LEN]);
    out[len - CRC_LEN..len].copy_from_slice(&crc.to_be_bytes());
    Ok(len)
}

#[cfg(test)]
mod tests {
    use super::*;
    /// Bit by bit, as the standard defines it.
    fn crc16_bitwise(data: &[u8]) -> u16 {
        let mut c: u16 = 0xFFFF;
        for b in data {
            c ^= (*b as u16) << 8;
            for _ in 0..8 {
                c = if c & 0x8000 != 0 { (c << 1) ^ 0x1021 } else { c << 1 };
            }
        }
        c
    }
    // verifies: PUS-PKT-01
    #[test]
    fn crc_matches_the_ccitt_false_check_value_and_the_bitwise_definition() {
        assert_eq!(crc16(b"123456789"), 0x29B1);
        let data: Vec<u8> = (0..1000u32)
            .map(|i| (i.wrapping_mul(2_654_435_761) >> 13) as u8)
            .collect();
        for n in 0..data.len() {
            assert_eq!(crc16(&data[..n]), crc16_bitwise(&data[..n]), "{n} bytes");
        }
    }
    // verifies: PUS-PKT-04, ICD-06
    #[test]
    fn tm_emit_then_parse_gives_the_headers_back() {
        let h = TmHeader {
            apid: 0x101,
            seq_count: 5,
            service: 17,
            subservice: 2,
            msg_counter: 9,
            dest_id: 0,
            time: CdsTime::from_unix_ms(1_700_000_000_123),
        };
        let mut buf = [0u8; 64];
        let n = emit_tm(&h, &mut buf, |_| Ok(0)).unwrap();
        assert_eq!(n, MIN_TM_LEN);
        let p = TmPacket::parse(&buf[..n]).unwrap();
        assert_eq!(
            (p.primary.apid, p.primary.seq_count, p.service, p.subservice),
            (0x101, 5, 17, 2)
        );
        assert_eq!(p.time, h.time);
        assert_eq!(p.time.unix_ms(), 1_700_000_000_123);
        buf[n - 1] ^= 1;
        assert!(matches!(TmPacket::parse(&buf[..n]), Err(HeaderError::Crc { .. })));
    }
}
