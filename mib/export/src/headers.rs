//! Header tables for the exporters: the no_std definitions live in [`mib::headers`];
//! this adds the offset helpers the exporters use.

pub use mib::headers::*;

/// Length in octets of a list of fields.
pub fn len(fields: &[HeaderField]) -> usize {
    fields_len(fields)
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
pub fn offsets(fields: &[HeaderField]) -> impl Iterator<Item = (u32, &HeaderField)> {
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
    use mib::config;
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
