//! PUS 17 test: the connection test (replaces the paper's heartbeat polling).

use mib_wire::tm;

use crate::accept::Tc;
use crate::failure::Failure;
use crate::obsw::Obsw;
use crate::request::unknown;
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

impl<S: TmStore> Obsw<S> {
    pub(crate) fn test_request(&mut self, now: u64, r: Request, sink: &mut impl TmSink) {
        match r {
            Request::Ping => self.emit_tm(now, tm::PingReply {}, sink),
        }
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
