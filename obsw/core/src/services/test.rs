//! PUS 17 test: the connection test (replaces the paper's heartbeat polling).

use mib::tc::service;
use mib_wire::tm;

use crate::accept::Tc;
use crate::downlink::Downlink;
use crate::failure::Failure;
use crate::request::unknown;
use crate::services::{Component, Contract};
use crate::tm::{TmSink, TmStore};

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Request {
    /// TC[17,1]: answer with TM[17,2].
    Ping,
}

impl Request {
    pub fn parse(tc: &Tc) -> Result<Self, Failure> {
        match tc.subservice {
            1 => Ok(Request::Ping),
            _ => Err(unknown(tc)),
        }
    }
}

/// The connection test has no state: it answers through the downlink.
pub struct Test;

impl Component for Test {
    const CONTRACT: Contract = Contract::new("test", Some(service::TEST), &[]);
    type Request<'a> = Request;
    type Output = ();
    fn handle<S: TmStore>(
        &mut self,
        now: u64,
        r: Request,
        dl: &mut Downlink<S>,
        sink: &mut impl TmSink,
    ) -> Result<(), Failure> {
        match r {
            Request::Ping => dl.emit_tm(now, &tm::PingReply {}, sink),
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use crate::obsw::tests::{obsw, of, send};

    // verifies: PUS-17-01
    #[test]
    fn a_ping_is_answered_in_every_mode() {
        let mut o = obsw();
        assert_eq!(of(&send(&mut o, 5, 1, 17, 1, &[]), 17, 2).len(), 1);
    }
}
