//! A one-line account of a PDU for a trace of what an entity sent and received (`ground
//! file ... --trace`): its transaction and kind, with the fields that tell a transfer's
//! story (a segment's offset and length, a NAK's requests, an ACK's directive). Only a PDU
//! [`crate::entity::well_formed`] takes is described; anything else is "refused".

use core::fmt;

use spacepackets::cfdp::pdu::ack::AckPdu;
use spacepackets::cfdp::pdu::eof::EofPdu;
use spacepackets::cfdp::pdu::file_data::FileDataPdu;
use spacepackets::cfdp::pdu::finished::FinishedPduReader;
use spacepackets::cfdp::pdu::nak::NakPduReader;
use spacepackets::cfdp::pdu::FileDirectiveType;
use spacepackets::cfdp::PduType;
use spacepackets::util::UnsignedEnum;

use crate::entity::well_formed;

/// A PDU, displayed as one line.
pub struct Describe<'a>(pub &'a [u8]);

impl fmt::Display for Describe<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let raw = self.0;
        let Some(h) = well_formed(raw) else {
            return write!(f, "refused ({} bytes)", raw.len());
        };
        let c = h.common_pdu_conf();
        write!(f, "tx {}/{} ", c.source_id().value(), c.transaction_seq_num.value())?;
        if h.pdu_type() == PduType::FileData {
            return match FileDataPdu::from_bytes(raw) {
                Ok(d) => write!(f, "file data {}+{}", d.offset(), d.file_data().len()),
                Err(_) => write!(f, "file data ?"),
            };
        }
        let hl = h.header_len();
        match FileDirectiveType::try_from(raw[hl]) {
            Ok(FileDirectiveType::MetadataPdu) => write!(f, "metadata"),
            Ok(FileDirectiveType::EofPdu) => match EofPdu::from_bytes(raw) {
                Ok(e) => write!(f, "EOF {:?} size {}", e.condition_code(), e.file_size()),
                Err(_) => write!(f, "EOF ?"),
            },
            Ok(FileDirectiveType::FinishedPdu) => match FinishedPduReader::from_bytes(raw) {
                Ok(x) => write!(f, "Finished {:?} {:?}", x.condition_code(), x.delivery_code()),
                Err(_) => write!(f, "Finished ?"),
            },
            Ok(FileDirectiveType::AckPdu) => match AckPdu::from_bytes(raw) {
                Ok(a) => write!(f, "ACK of {:?}", a.directive_code_of_acked_pdu()),
                Err(_) => write!(f, "ACK ?"),
            },
            Ok(FileDirectiveType::NakPdu) => match NakPduReader::from_bytes(raw) {
                Ok(n) => {
                    write!(f, "NAK {}..{}", n.start_of_scope(), n.end_of_scope())?;
                    for (a, b) in n.get_segment_requests_iterator().into_iter().flatten() {
                        write!(f, " {a}-{b}")?;
                    }
                    Ok(())
                }
                Err(_) => write!(f, "NAK ?"),
            },
            Ok(d @ (FileDirectiveType::PromptPdu | FileDirectiveType::KeepAlivePdu)) => write!(f, "{d:?}"),
            Err(_) => write!(f, "directive {:#x}", raw[hl]),
        }
    }
}
