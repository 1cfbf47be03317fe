//! Byte layout of the CCSDS primary header, the PUS-C TM and TC secondary headers and
//! the packet error control, as `satrs::spacepackets` (0.17) writes them, and the
//! lengths and constants every packet shares (one place: the wire crate, the exporters
//! and the ground read them here). The exporters (XTCE containers, SCOS-2000 offsets,
//! ICD tables) read the field tables; the integration tests check them against packets
//! built by the real encoder.

use crate::config::TIMESTAMP_LEN;

/// One header field, most significant bit first.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct HeaderField {
    /// Name (also the XTCE parameter name).
    pub name: &'static str,
    pub bits: u32,
    /// Value the field always has, if fixed.
    pub fixed: Option<u32>,
    pub desc: crate::types::Text,
}

const fn f(name: &'static str, bits: u32, fixed: Option<u32>, desc: &'static str) -> HeaderField {
    HeaderField {
        name,
        bits,
        fixed,
        desc: crate::types::text(desc),
    }
}

/// PUS version number of PUS-C (ECSS-E-ST-70-41C).
pub const PUS_C_VERSION: u32 = 2;
/// P-field of a CDS time code with 16-bit day segment and no sub-millisecond field.
pub const CDS_SHORT_PFIELD: u32 = 0x40;

/// CCSDS space packet primary header (6 bytes).
pub const PRIMARY_HEADER: &[HeaderField] = &[
    f("VERSION", 3, Some(0), "packet version number (0)"),
    f("PKT_TYPE", 1, None, "packet type: 0 telemetry, 1 telecommand"),
    f("SEC_HDR_FLG", 1, Some(1), "secondary header flag (always 1)"),
    f("PKT_APID", 11, None, "application process ID: 0x100 + robot number"),
    f("SEQ_FLGS", 2, Some(3), "sequence flags (3 = unsegmented)"),
    f("SRC_SEQ_CTR", 14, None, "packet sequence count (per APID)"),
    f(
        "PKT_LEN",
        16,
        None,
        "packet data length: octets after the primary header minus 1",
    ),
];

/// The TM secondary header's service field: its name is the parameter the XTCE and Yamcs
/// exports match TM containers on (and the input that has every verifier judged on each
/// TM packet).
pub const TM_SERVICE: &str = "TM_SERVICE";

/// PUS-C TM secondary header with the CDS short time stamp (14 bytes).
pub const TM_SEC_HEADER: &[HeaderField] = &[
    f(
        "TM_PUS_VERSION",
        4,
        Some(PUS_C_VERSION),
        "PUS version number (2 = PUS-C)",
    ),
    f("TM_TIME_REF", 4, None, "spacecraft time reference status"),
    f(TM_SERVICE, 8, None, "service type ID"),
    f("TM_SUBSERVICE", 8, None, "message subtype ID"),
    f("TM_MSG_COUNTER", 16, None, "message type counter"),
    f("TM_DEST_ID", 16, None, "destination ID (ground = 0)"),
    f(
        "TM_TIME_PFIELD",
        8,
        Some(CDS_SHORT_PFIELD),
        "CDS time code P-field (0x40: 16-bit days, ms of day)",
    ),
    f("TM_TIME_DAYS", 16, None, "CDS days since 1958-01-01"),
    f("TM_TIME_MS", 32, None, "CDS milliseconds of day"),
];

/// PUS-C TC secondary header (5 bytes).
pub const TC_SEC_HEADER: &[HeaderField] = &[
    f(
        "TC_PUS_VERSION",
        4,
        Some(PUS_C_VERSION),
        "PUS version number (2 = PUS-C)",
    ),
    f(
        "TC_ACK_FLAGS",
        4,
        None,
        "acknowledgement flags: 0b1000 acceptance, 0b0100 start, 0b0010 progress, 0b0001 completion",
    ),
    f("TC_SERVICE", 8, None, "service type ID"),
    f("TC_SUBSERVICE", 8, None, "message subtype ID"),
    f("TC_SOURCE_ID", 16, None, "source ID (ground = 0)"),
];

/// The one CRC-16 of the project: CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF, no
/// reflection; the `crc` catalogue's `CRC_16_IBM_3740`) — the packets' error control
/// ([`PEC`]), checked by obsw-core's acceptance and written by `mib_wire::header`, and the
/// A–B link frames (`mmic_domain::ablink`).
pub const PEC_CRC: crc::Crc<u16> = crc::Crc::<u16>::new(&crc::CRC_16_IBM_3740);

/// Packet error control: CRC-16/CCITT-FALSE over the whole packet before it.
pub const PEC: HeaderField = f(
    "PEC",
    16,
    None,
    "CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF) over all preceding octets",
);

/// Length in octets of a list of header fields.
pub const fn fields_len(fields: &[HeaderField]) -> usize {
    let mut bits = 0;
    let mut i = 0;
    while i < fields.len() {
        bits += fields[i].bits;
        i += 1;
    }
    (bits / 8) as usize
}

/// Length of the CCSDS primary header (6).
pub const PRIMARY_HEADER_LEN: usize = fields_len(PRIMARY_HEADER);

/// `a == b` in a `const` context (the MIB's compile-time lookups by name).
pub(crate) const fn const_str_eq(a: &str, b: &str) -> bool {
    let (a, b) = (a.as_bytes(), b.as_bytes());
    if a.len() != b.len() {
        return false;
    }
    let mut i = 0;
    while i < a.len() {
        if a[i] != b[i] {
            return false;
        }
        i += 1;
    }
    true
}

/// Width of the packet sequence count (the primary header's `SRC_SEQ_CTR`).
const SEQ_COUNT_BITS: u32 = {
    let mut i = 0;
    let mut bits = 0;
    while i < PRIMARY_HEADER.len() {
        if const_str_eq(PRIMARY_HEADER[i].name, "SRC_SEQ_CTR") {
            bits = PRIMARY_HEADER[i].bits;
        }
        i += 1;
    }
    bits
};
const _: () = assert!(SEQ_COUNT_BITS == 14, "CCSDS 133.0-B-2: a 14-bit sequence count");

/// A packet sequence count: 14 bits, wrapping (per APID). The one type for the counter the
/// obsw stamps on TM, the ground on TCs, and for every distance between two counts.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct SeqCount(u16);

impl SeqCount {
    /// Number of distinct counts (16384).
    pub const MODULUS: u16 = 1 << SEQ_COUNT_BITS;
    /// Mask of the count's bits in the packet sequence control word.
    pub const MASK: u16 = Self::MODULUS - 1;
    /// The count of `raw` (its low 14 bits: the packet sequence control's count).
    pub const fn new(raw: u16) -> Self {
        SeqCount(raw & Self::MASK)
    }
    pub const fn get(self) -> u16 {
        self.0
    }
    /// The count after this one (16383 is followed by 0).
    pub const fn next(self) -> Self {
        SeqCount((self.0 + 1) & Self::MASK)
    }
    /// How many counts `self` is after `earlier`, modulo 16384.
    pub const fn since(self, earlier: SeqCount) -> u16 {
        self.0.wrapping_sub(earlier.0) & Self::MASK
    }
    /// The count before this one (0 is preceded by 16383).
    pub const fn prev(self) -> Self {
        SeqCount(self.0.wrapping_sub(1) & Self::MASK)
    }
    /// The count `n` after this one, modulo 16384 (`n` may exceed the modulus).
    pub const fn add(self, n: u16) -> Self {
        SeqCount(self.0.wrapping_add(n) & Self::MASK)
    }
}
/// Length of the PUS-C TC secondary header (5: version/ack, service, subservice, source ID).
pub const TC_SEC_HEADER_LEN: usize = fields_len(TC_SEC_HEADER);
/// Length of the PUS-C TM secondary header without the time stamp (7: version/time ref,
/// service, subservice, message counter, destination ID).
pub const TM_SEC_HEADER_LEN: usize = fields_len(TM_SEC_HEADER) - TIMESTAMP_LEN;
/// Length of the packet error control (2).
pub const CRC_LEN: usize = (PEC.bits / 8) as usize;
/// Days from the CCSDS epoch (1958-01-01) to the Unix epoch (1970-01-01).
pub const CCSDS_TO_UNIX_DAYS: i64 = 4383;
/// Milliseconds in a day.
pub const MS_PER_DAY: i64 = 86_400_000;

// The TM secondary header ends with the time stamp (p-field, days, ms of day): the
// configured CDS short time stamp.
const _: () = {
    let n = TM_SEC_HEADER.len();
    let bits = TM_SEC_HEADER[n - 3].bits + TM_SEC_HEADER[n - 2].bits + TM_SEC_HEADER[n - 1].bits;
    assert!(bits as usize == TIMESTAMP_LEN * 8);
};

#[cfg(test)]
mod tests {
    use super::*;

    // verifies: CODEC-SEQ-01
    #[test]
    fn the_sequence_count_is_the_primary_headers_14_bits_and_wraps() {
        assert_eq!((SeqCount::MODULUS, SeqCount::MASK), (16384, 0x3FFF));
        assert_eq!(SeqCount::new(0xC000 | 5).get(), 5, "sequence flags are not the count");
        assert_eq!(SeqCount::new(16383).next(), SeqCount::new(0));
        assert_eq!(SeqCount::new(2).since(SeqCount::new(16382)), 4);
        assert_eq!(SeqCount::new(7).since(SeqCount::new(7)), 0);
        // The field the MIB describes is what the type masks.
        let f = PRIMARY_HEADER.iter().find(|f| f.name == "SRC_SEQ_CTR").unwrap();
        assert_eq!(1u32 << f.bits, u32::from(SeqCount::MODULUS));
    }

    // verifies: CODEC-SEQ-01
    #[test]
    fn prev_and_add_wrap_like_next_and_since() {
        assert_eq!(SeqCount::new(0).prev(), SeqCount::new(16383));
        assert_eq!(SeqCount::new(9).prev(), SeqCount::new(8));
        assert_eq!(SeqCount::new(16380).add(6), SeqCount::new(2));
        assert_eq!(SeqCount::new(5).add(u16::MAX), SeqCount::new(4), "n beyond the modulus");
        for raw in [0u16, 1, 100, 16383] {
            let s = SeqCount::new(raw);
            assert_eq!(s.next().prev(), s);
            assert_eq!(s.add(1), s.next());
            assert_eq!(s.add(0), s);
            for n in [0u16, 1, 7, 8191, 16383] {
                assert_eq!(s.add(n).since(s), n, "since undoes add");
            }
        }
    }
}
