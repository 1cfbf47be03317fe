//! TC acceptance: every uplinked byte string goes through [`accept`], which either
//! yields a checked [`Tc`] view or a [`Rejection`] naming the MIB failure code and its
//! data. Nothing here can panic on input.

use mib::tc::{self, service, TcDef};
use mib::FailureCode;
use mib_wire::codec::{self, ArgError, MAX_ARGS};
use mib_wire::header::{HeaderError, Primary, TcPacket};
use mib_wire::RequestId;

use crate::failure::Failure;

/// Shortest PUS-C TC: primary header, secondary header, CRC.
pub use mib_wire::header::MIN_TC_LEN;
/// CCSDS primary header length.
pub use mib_wire::header::PRIMARY_HEADER_LEN as PRIMARY_LEN;

/// PUS-C acknowledgement flags of a TC.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Ack(pub u8);

impl Ack {
    pub const ALL: Ack = Ack(0xF);
    pub fn acceptance(self) -> bool {
        self.0 & 0b1000 != 0
    }
    pub fn start(self) -> bool {
        self.0 & 0b0100 != 0
    }
    pub fn progress(self) -> bool {
        self.0 & 0b0010 != 0
    }
    pub fn completion(self) -> bool {
        self.0 & 0b0001 != 0
    }
}

/// A TC that passed every acceptance check.
#[derive(Clone, Copy, Debug)]
pub struct Tc<'a> {
    pub req: RequestId,
    pub ack: Ack,
    pub service: u8,
    pub subservice: u8,
    pub source_id: u16,
    pub def: &'static TcDef,
    /// Range-checked fixed arguments (PUS 8: after the function ID).
    pub args: [i64; MAX_ARGS],
    /// Variable data after the fixed arguments (TC[11,4] activities).
    pub rest: &'a [u8],
    /// The whole packet.
    pub raw: &'a [u8],
}

/// Why a TC was refused.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Rejection {
    /// `None` when the packet is too short to carry a request ID.
    pub req: Option<RequestId>,
    pub service: u8,
    pub subservice: u8,
    pub failure: Failure,
}

impl Rejection {
    fn new(req: Option<RequestId>, failure: Failure) -> Self {
        Rejection {
            req,
            service: 0,
            subservice: 0,
            failure,
        }
    }
    fn with_type(mut self, service: u8, subservice: u8) -> Self {
        self.service = service;
        self.subservice = subservice;
        self
    }
    pub fn code(&self) -> FailureCode {
        self.failure.code()
    }
}

fn arg_failure(e: ArgError) -> Failure {
    match e {
        ArgError::Length { got, expected } => Failure::bad_arg_length(got, expected),
        ArgError::OutOfRange { index, value } => {
            Failure::arg_out_of_range(index, value.clamp(i32::MIN as i64, i32::MAX as i64) as i32)
        }
    }
}

/// The failure of a packet whose headers `mib_wire::header` refused: the TC type bits
/// first (a TM or a packet without secondary header is "not a PUS TC" whatever else is
/// wrong with it), then the CRC, then the length.
fn header_failure(raw: &[u8], e: HeaderError) -> Failure {
    let expected = |total: usize| if total < MIN_TC_LEN { MIN_TC_LEN } else { total };
    let Ok(p) = Primary::parse(raw) else {
        return Failure::malformed_packet(raw.len(), MIN_TC_LEN);
    };
    if p.version != 0 || !p.is_tc || !p.sec_hdr {
        return Failure::not_a_pus_tc(p.version, p.is_tc, p.sec_hdr);
    }
    match e {
        HeaderError::Crc { received, computed } => Failure::crc_mismatch(received, computed),
        HeaderError::NotPus { .. } | HeaderError::WrongType { .. } => {
            Failure::not_a_pus_tc(p.version, p.is_tc, p.sec_hdr)
        }
        // Truncated, too long, and whatever a later version of the header check refuses.
        _ => Failure::malformed_packet(raw.len(), expected(p.len)),
    }
}

/// Runs every acceptance check on `raw` for the robot with APID `apid`. The headers and
/// the CRC are read once, by `mib_wire::header::TcPacket` (the ground's reader too).
pub fn accept(raw: &[u8], apid: u16) -> Result<Tc<'_>, Rejection> {
    let Ok(req) = RequestId::of_tc(raw) else {
        return Err(Rejection::new(None, Failure::malformed_packet(raw.len(), MIN_TC_LEN)));
    };
    let r = Some(req);
    let p = TcPacket::parse(raw).map_err(|e| Rejection::new(r, header_failure(raw, e)))?;
    // One packet per TC: no bytes after the length the header gives.
    let total = p.primary.len;
    if total != raw.len() {
        return Err(Rejection::new(r, Failure::malformed_packet(raw.len(), total)));
    }
    let ack = Ack(p.ack);
    let (svc, sub, source_id) = (p.service, p.subservice, p.source_id);
    if req.apid() != apid {
        return Err(Rejection::new(r, Failure::wrong_apid(req.apid())).with_type(svc, sub));
    }
    if !tc::service_known(svc) {
        return Err(Rejection::new(r, Failure::unknown_service(svc)).with_type(svc, sub));
    }
    if !tc::subservice_known(svc, sub) {
        return Err(Rejection::new(r, Failure::unknown_subservice(svc, sub)).with_type(svc, sub));
    }
    let app = p.app_data;
    let (def, arg_bytes) = if svc == service::FUNCTION {
        if app.len() < 2 {
            return Err(Rejection::new(r, Failure::bad_arg_length(app.len(), 2)).with_type(svc, sub));
        }
        let f = u16::from_be_bytes([app[0], app[1]]);
        match tc::lookup(svc, sub, Some(f)) {
            Some(d) => (d, &app[2..]),
            None => return Err(Rejection::new(r, Failure::unknown_function(f)).with_type(svc, sub)),
        }
    } else {
        match tc::lookup(svc, sub, None) {
            Some(d) => (d, app),
            None => return Err(Rejection::new(r, Failure::unknown_subservice(svc, sub)).with_type(svc, sub)),
        }
    };
    let (args, rest) = codec::decode_args(def, arg_bytes)
        .map_err(|e: ArgError| Rejection::new(r, arg_failure(e)).with_type(svc, sub))?;
    Ok(Tc {
        req,
        ack,
        service: svc,
        subservice: sub,
        source_id,
        def,
        args,
        rest,
        raw: &raw[..total],
    })
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use arbitrary_int::{u11, u14};
    use satrs::spacepackets::ecss::tc::AckFlags;
    use satrs::spacepackets::ecss::tc::{PusTcCreator, PusTcSecondaryHeader};
    use satrs::spacepackets::ecss::{CreatorConfig, MessageTypeId};
    use satrs::spacepackets::SpHeader;

    pub fn tc_bytes(apid: u16, seq: u16, svc: u8, sub: u8, app: &[u8]) -> std::vec::Vec<u8> {
        let sp = SpHeader::new_for_unseg_tc(u11::new(apid), u14::new(seq), 0);
        let sec = PusTcSecondaryHeader::new(MessageTypeId::new(svc, sub), AckFlags::ALL, 0);
        let tc = PusTcCreator::new(sp, sec, app, CreatorConfig::default());
        let mut buf = [0u8; 1024];
        let n = tc.write_to_bytes(&mut buf).unwrap();
        buf[..n].to_vec()
    }

    fn code(raw: &[u8]) -> FailureCode {
        accept(raw, 0x101).unwrap_err().code()
    }

    // verifies: PUS-1-01
    #[test]
    fn a_valid_ping_is_accepted() {
        let raw = tc_bytes(0x101, 7, 17, 1, &[]);
        let t = accept(&raw, 0x101).unwrap();
        assert_eq!((t.service, t.subservice, t.req.seq()), (17, 1, 7));
        assert!(t.ack.acceptance() && t.ack.completion());
    }

    // verifies: PUS-1-02
    #[test]
    fn every_acceptance_failure_code_is_reachable_from_bytes() {
        let ping = tc_bytes(0x101, 1, 17, 1, &[]);
        assert_eq!(code(&ping[..3]), FailureCode::MALFORMED_PACKET);
        assert!(accept(&ping[..3], 0x101).unwrap_err().req.is_none());
        assert_eq!(code(&ping[..ping.len() - 1]), FailureCode::MALFORMED_PACKET);
        let mut bad_crc = ping.clone();
        *bad_crc.last_mut().unwrap() ^= 0xFF;
        assert_eq!(code(&bad_crc), FailureCode::CRC_MISMATCH);
        let mut tm = ping.clone();
        tm[0] &= !0x10;
        assert_eq!(code(&tm), FailureCode::NOT_A_PUS_TC);
        assert_eq!(code(&tc_bytes(0x102, 1, 17, 1, &[])), FailureCode::WRONG_APID);
        assert_eq!(code(&tc_bytes(0x101, 1, 99, 1, &[])), FailureCode::UNKNOWN_SERVICE);
        assert_eq!(code(&tc_bytes(0x101, 1, 17, 9, &[])), FailureCode::UNKNOWN_SUBSERVICE);
        assert_eq!(code(&tc_bytes(0x101, 1, 8, 1, &[0, 99])), FailureCode::UNKNOWN_FUNCTION);
        assert_eq!(code(&tc_bytes(0x101, 1, 8, 1, &[0, 1, 0])), FailureCode::BAD_ARG_LENGTH);
        let r = accept(&tc_bytes(0x101, 1, 8, 1, &[0, 1, 0, 15]), 0x101).unwrap_err();
        assert_eq!(
            (r.code(), &r.failure.data()[..]),
            (FailureCode::ARG_OUT_OF_RANGE, &[1u8, 0, 0, 0, 15][..])
        );
    }

    proptest::proptest! {
        // verifies: DD-ROBUST-01
        #[test]
        fn random_bytes_never_panic(data in proptest::collection::vec(proptest::num::u8::ANY, 0..300)) {
            let _ = accept(&data, 0x101);
        }
        // verifies: PUS-PKT-01
        #[test]
        fn bit_flips_in_a_valid_tc_are_rejected_or_still_valid(pos in 0usize..15, bit in 0u8..8) {
            let mut raw = tc_bytes(0x101, 3, 8, 1, &[0, 1, 0, 1]);
            let p = pos % raw.len();
            raw[p] ^= 1 << bit;
            // CRC-16 detects every single-bit error.
            proptest::prop_assert!(accept(&raw, 0x101).is_err());
        }
    }
}
