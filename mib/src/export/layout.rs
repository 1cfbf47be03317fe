//! Byte layout of the CCSDS primary header, the PUS-C TM and TC secondary headers and
//! the packet error control, as `satrs::spacepackets` (0.17) writes them. The exporters
//! (XTCE containers, SCOS-2000 offsets, ICD tables) all read these tables; the
//! integration tests check them against packets built by the real encoder.

/// One header field, most significant bit first.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Field {
    /// Name (also the XTCE parameter name).
    pub name: &'static str,
    pub bits: u32,
    /// Value the field always has, if fixed.
    pub fixed: Option<u32>,
    pub desc: &'static str,
}

const fn f(name: &'static str, bits: u32, fixed: Option<u32>, desc: &'static str) -> Field {
    Field {
        name,
        bits,
        fixed,
        desc,
    }
}

/// PUS version number of PUS-C (ECSS-E-ST-70-41C).
pub const PUS_C_VERSION: u32 = 2;
/// P-field of a CDS time code with 16-bit day segment and no sub-millisecond field.
pub const CDS_SHORT_PFIELD: u32 = 0x40;

/// CCSDS space packet primary header (6 bytes).
pub const PRIMARY_HEADER: &[Field] = &[
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

/// PUS-C TM secondary header with the CDS short time stamp (14 bytes).
pub const TM_SEC_HEADER: &[Field] = &[
    f(
        "TM_PUS_VERSION",
        4,
        Some(PUS_C_VERSION),
        "PUS version number (2 = PUS-C)",
    ),
    f("TM_TIME_REF", 4, None, "spacecraft time reference status"),
    f("TM_SERVICE", 8, None, "service type ID"),
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
pub const TC_SEC_HEADER: &[Field] = &[
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

/// Packet error control: CRC-16/CCITT-FALSE over the whole packet before it.
pub const PEC: Field = f(
    "PEC",
    16,
    None,
    "CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF) over all preceding octets",
);

/// Length in octets of a list of fields.
pub fn len(fields: &[Field]) -> usize {
    (fields.iter().map(|f| f.bits).sum::<u32>() / 8) as usize
}

/// Octets from the start of a TM packet to its source data.
pub fn tm_source_data_offset() -> usize {
    len(PRIMARY_HEADER) + len(TM_SEC_HEADER)
}

/// Octets from the start of a TC packet to its application data.
pub fn tc_app_data_offset() -> usize {
    len(PRIMARY_HEADER) + len(TC_SEC_HEADER)
}

/// Octets of the TM data field header (secondary header including the time stamp).
pub fn tm_data_field_header_len() -> usize {
    len(TM_SEC_HEADER)
}

/// Length of the time stamp inside the TM secondary header.
pub fn tm_time_len() -> usize {
    (TM_SEC_HEADER
        .iter()
        .filter(|f| f.name.starts_with("TM_TIME_") && f.name != "TM_TIME_REF")
        .map(|f| f.bits)
        .sum::<u32>()
        / 8) as usize
}

/// Total length of a TM packet whose source data has `n` octets.
pub fn tm_packet_len(n: usize) -> usize {
    tm_source_data_offset() + n + len(&[PEC])
}

/// Bit offset of each field from the start of the list.
pub fn offsets(fields: &[Field]) -> impl Iterator<Item = (u32, &Field)> {
    let mut off = 0;
    fields.iter().map(move |f| {
        let o = off;
        off += f.bits;
        (o, f)
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config;
    // verifies: MMIC-FW-01
    #[test]
    fn header_lengths_match_ccsds_and_pus_c() {
        assert_eq!(len(PRIMARY_HEADER), 6);
        assert_eq!(len(TM_SEC_HEADER), 7 + config::TIMESTAMP_LEN);
        assert_eq!(tm_time_len(), config::TIMESTAMP_LEN);
        assert_eq!(len(TC_SEC_HEADER), 5);
        assert_eq!(tm_source_data_offset(), 20);
        assert_eq!(tc_app_data_offset(), 11);
        assert_eq!(tm_packet_len(2), 24);
        assert_eq!(offsets(PRIMARY_HEADER).last().map(|(o, _)| o), Some(32));
    }
}
