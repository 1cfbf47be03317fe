//! What a platform tells its housekeeping about the PDUs that pass its entity
//! (`docs/files.md`, "Housekeeping and events"), beside the entity's own
//! [`Counters`](crate::entity::Counters): the transactions that begin — a metadata PDU the
//! entity took or sent, once per transaction however often it is sent again — with their
//! class and file length, the PDUs sent, and the NAKs each way. The host obsw feeds it
//! from its packet loop; board A does the same with its own I/O.

use spacepackets::cfdp::pdu::metadata::MetadataPduReader;
use spacepackets::cfdp::pdu::FileDirectiveType;
use spacepackets::cfdp::{PduType, TransmissionMode};
use spacepackets::util::UnsignedEnum;

use crate::entity::{well_formed, Class, Finished};

/// A transaction that began.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Opened {
    /// Transaction ID: the entity that started it and its sequence number.
    pub source: u16,
    pub seq: u16,
    /// This entity started it (its metadata PDU was sent, not taken).
    pub sent: bool,
    pub class: Class,
    /// The file's length as the metadata says (0: no file, a request).
    pub length: u64,
}

/// The counts and the last transaction opened each way (see the module's documentation).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Watch {
    /// PDUs the entity sent.
    pub pdus_sent: u32,
    /// Transactions opened by the peer / by this entity.
    pub opened_received: u32,
    pub opened_sent: u32,
    /// NAK PDUs sent / taken.
    pub naks_sent: u32,
    pub naks_received: u32,
    /// The last transaction opened each way: taken (index 0), sent (1).
    last: [Option<Opened>; 2],
}

/// What a PDU is to the watch.
enum Kind {
    Metadata(Opened),
    Nak,
    Other,
}

fn kind(raw: &[u8], sent: bool) -> Kind {
    let Some(h) = well_formed(raw) else {
        return Kind::Other;
    };
    if h.pdu_type() != PduType::FileDirective {
        return Kind::Other;
    }
    let conf = h.common_pdu_conf();
    match raw
        .get(h.header_len())
        .and_then(|d| FileDirectiveType::try_from(*d).ok())
    {
        Some(FileDirectiveType::NakPdu) => Kind::Nak,
        Some(FileDirectiveType::MetadataPdu) => match MetadataPduReader::from_bytes(raw) {
            Ok(md) => Kind::Metadata(Opened {
                source: conf.source_id().value() as u16,
                seq: conf.transaction_seq_num.value() as u16,
                sent,
                class: match conf.trans_mode {
                    TransmissionMode::Unacknowledged => Class::One,
                    TransmissionMode::Acknowledged => Class::Two,
                },
                length: md.metadata_params().file_size,
            }),
            Err(_) => Kind::Other,
        },
        _ => Kind::Other,
    }
}

impl Watch {
    /// A PDU the entity took (its `received` counter rose, no handler refused it): the
    /// transaction it opens, if it is the metadata PDU of a new one.
    pub fn taken(&mut self, raw: &[u8]) -> Option<Opened> {
        match kind(raw, false) {
            Kind::Nak => {
                self.naks_received = self.naks_received.wrapping_add(1);
                None
            }
            Kind::Metadata(o) => self.open(o),
            Kind::Other => None,
        }
    }

    /// A PDU the entity sent: the transaction it opens, if it is the metadata PDU of a new
    /// one.
    pub fn sent(&mut self, raw: &[u8]) -> Option<Opened> {
        self.pdus_sent = self.pdus_sent.wrapping_add(1);
        match kind(raw, true) {
            Kind::Nak => {
                self.naks_sent = self.naks_sent.wrapping_add(1);
                None
            }
            Kind::Metadata(o) => self.open(o),
            Kind::Other => None,
        }
    }

    fn open(&mut self, o: Opened) -> Option<Opened> {
        let last = &mut self.last[usize::from(o.sent)];
        if last.is_some_and(|l| (l.source, l.seq) == (o.source, o.seq)) {
            // Its metadata again (class 2 sends it again when asked; a link may repeat it).
            return None;
        }
        *last = Some(o);
        if o.sent {
            self.opened_sent = self.opened_sent.wrapping_add(1);
        } else {
            self.opened_received = self.opened_received.wrapping_add(1);
        }
        Some(o)
    }

    /// The file bytes a finished transaction moved, from the entity's progress that way
    /// (`Entity::progress` received, `Entity::sent_progress` sent): at most its file's
    /// length when the watch saw it open.
    pub fn bytes(&self, f: &Finished, progress: u64) -> u64 {
        match self.last[usize::from(f.sent)] {
            Some(o) if (o.source, o.seq) == (f.source, f.seq) => progress.min(o.length),
            _ => progress,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::store::MemStore;
    use crate::{Entity, Parts};

    type Mem = MemStore<4, 4000>;

    /// The PDUs an entity has waiting.
    fn drain<S: crate::FlatStore>(e: &mut Entity<'_, S>) -> std::vec::Vec<std::vec::Vec<u8>> {
        core::iter::from_fn(|| e.pop()).map(|p| p.to_vec()).collect()
    }

    // verifies: FILE-EV-01
    #[test]
    fn a_transaction_opens_once_each_way_with_its_class_and_length_and_naks_are_counted() {
        let (ground, _robot) = (Parts::new(Mem::new(1 << 20)), Parts::new(Mem::new(1 << 20)));
        let name = crate::FileName::new("a.bin").unwrap();
        ground.store.create(&name).unwrap();
        ground.store.write(&name, 0, &[7; 3000]).unwrap();
        let mut g = Entity::new(0, 1, &ground);
        let (mut wg, mut wr) = (Watch::default(), Watch::default());
        g.put(0, "a.bin", "b.bin", Class::Two).unwrap();
        g.poll(0);
        let pdus = drain(&mut g);
        let opened: std::vec::Vec<_> = pdus.iter().filter_map(|p| wg.sent(p)).collect();
        assert_eq!(
            opened,
            [Opened {
                source: 0,
                seq: 0,
                sent: true,
                class: Class::Two,
                length: 3000
            }]
        );
        assert_eq!((wg.pdus_sent as usize, wg.opened_sent), (pdus.len(), 1));
        // The robot takes the metadata, and its copy again: one transaction.
        let md = &pdus[0];
        let mut taken = std::vec::Vec::new();
        for p in [md].into_iter().chain(&pdus[..]) {
            taken.extend(wr.taken(p));
        }
        assert_eq!(taken.len(), 1, "{taken:?}");
        assert_eq!((taken[0].source, taken[0].seq, taken[0].sent), (0, 0, false));
        assert_eq!(wr.opened_received, 1);
        // A NAK each way; a malformed PDU is nothing.
        let mut nak = [0u8; 64];
        let n = nak_pdu(&mut nak);
        assert!(wr.sent(&nak[..n]).is_none() && wg.taken(&nak[..n]).is_none());
        assert_eq!((wr.naks_sent, wg.naks_received), (1, 1));
        assert!(wr.taken(&[0x20, 0, 0, 1]).is_none());
        assert_eq!(wr.naks_received, 0);
        // Bytes of an ended transaction: the progress, at most the file's length.
        let f = Finished {
            source: 0,
            seq: 0,
            sent: false,
            condition: spacepackets::cfdp::ConditionCode::NoError,
            complete: true,
            retained: true,
        };
        assert_eq!(wr.bytes(&f, 5000), 3000);
        assert_eq!(wr.bytes(&f, 946), 946);
        assert_eq!(wr.bytes(&Finished { seq: 9, ..f }, 5000), 5000, "not the one seen");
    }

    /// A NAK PDU from the robot (entity 1) to the ground (0), transaction 0/0.
    fn nak_pdu(buf: &mut [u8]) -> usize {
        use spacepackets::cfdp::pdu::nak::NakPduCreator;
        use spacepackets::cfdp::pdu::{CommonPduConfig, PduHeader};
        use spacepackets::util::UnsignedByteFieldU16;
        let mut conf = CommonPduConfig::new_with_byte_fields(
            UnsignedByteFieldU16::new(0),
            UnsignedByteFieldU16::new(1),
            UnsignedByteFieldU16::new(0),
        )
        .unwrap();
        conf.direction = spacepackets::cfdp::Direction::TowardsSender;
        let segments = [(0u32, 946u32)];
        let nak = NakPduCreator::new_normal_file_size(PduHeader::new_for_file_directive(conf, 0), 0, 3000, &segments)
            .unwrap();
        nak.write_to_bytes(buf).unwrap()
    }
}
