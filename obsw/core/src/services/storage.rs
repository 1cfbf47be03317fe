//! PUS 15 on-board storage: every TM packet is also kept in the store (a ring that
//! overwrites the oldest packets, counted) until it is downlinked or deleted.

use mib::tc::service;

use crate::accept::Tc;
use crate::failure::Failure;
use crate::obsw::Obsw;
use crate::request::unknown;
use crate::tm::{TmSink, TmStore};

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Request {
    /// TC[15,1]
    Enable,
    /// TC[15,2]
    Disable,
    /// TC[15,9]: downlink the whole store, then TM[15,19].
    Downlink,
    /// TC[15,11]
    Delete,
}

impl Request {
    pub fn parse(tc: &Tc) -> Result<Self, Failure> {
        Ok(match tc.subservice {
            1 => Request::Enable,
            2 => Request::Disable,
            9 => Request::Downlink,
            11 => Request::Delete,
            _ => return Err(unknown(tc)),
        })
    }
}

impl<S: TmStore> Obsw<S> {
    pub(crate) fn storage_request(&mut self, now: u64, r: Request, sink: &mut impl TmSink) -> Result<(), Failure> {
        match r {
            Request::Enable => self.dl.store_enabled = true,
            Request::Disable => self.dl.store_enabled = false,
            Request::Downlink => self.downlink_store(now, sink)?,
            Request::Delete => self.dl.store.clear(),
        }
        Ok(())
    }

    fn downlink_store(&mut self, now: u64, sink: &mut impl TmSink) -> Result<(), Failure> {
        if !self.dl.store_enabled {
            return Err(Failure::store_disabled());
        }
        let mut buf = [0u8; mib::config::MAX_PACKET_LEN];
        let mut count: u32 = 0;
        while let Some(n) = self.dl.store.pop(&mut buf) {
            sink.send_tm(&buf[..n]);
            count += 1;
        }
        // Nothing downlinked is stored again: disable while reporting the end.
        self.dl.store_enabled = false;
        self.emit(now, service::STORAGE, 19, &count.to_be_bytes(), sink);
        self.dl.store_enabled = true;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use crate::obsw::tests::{failure, kind, obsw, of, send};
    use mib::FailureCode;

    #[test]
    fn downlink_replays_stored_packets_unchanged_and_a_disabled_store_refuses() {
        let mut o = obsw();
        let first = send(&mut o, 1, 1, 17, 1, &[]);
        let pkts = send(&mut o, 2, 2, 15, 9, &[]);
        for p in &first {
            assert!(pkts.contains(p), "replayed with its original sequence count and time");
        }
        let end = of(&pkts, 15, 19);
        assert!(u32::from_be_bytes(kind(&end[0]).2[..4].try_into().unwrap()) >= first.len() as u32);
        send(&mut o, 3, 3, 15, 2, &[]);
        let pkts = send(&mut o, 4, 4, 15, 9, &[]);
        assert_eq!(
            failure(&of(&pkts, 1, 4)[0]),
            (FailureCode::STORE_DISABLED.code(), vec![])
        );
    }
}
