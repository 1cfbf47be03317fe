//! Team messages on the inter-robot link: a small owned [`Message`] with checked
//! [`Message::parse`] and [`Message::emit`] (smoltcp's Repr pattern; the messages are a few
//! fixed-length fields, so no zero-copy view is kept).
//!
//! Layout (big-endian), common header of [`HEADER_LEN`] bytes:
//!
//! | off | len | field     |
//! |-----|-----|-----------|
//! | 0   | 1   | version ([`mib::team::WIRE_VERSION`]) |
//! | 1   | 1   | type ([`MsgType`]) |
//! | 2   | 4   | term |
//! | 6   | 1   | sender robot number |
//! | 7   | 2   | plan ID |
//! | 9   | 4   | plan hash |
//! | 13  | 2   | progress (plan steps completed) |
//!
//! Bodies: RequestVote none; Vote `candidate u8, granted u8 (0/1)`; LeaderHeartbeat
//! `stamp u32, directive u8, step u16, function u16` (step and function 0 for HOLD);
//! HeartbeatAck `stamp u32, ok u8 (0/1)`. Every message has an exact length.

use core::fmt;
use mib::tc::function;

/// Robot number (1..=254, as in `mib::apid`).
pub type RobotId = u8;

/// Common header length.
pub const HEADER_LEN: usize = mib::team::WIRE_HEADER_LEN;
/// Longest message.
pub const MAX_LEN: usize = mib::team::WIRE_MAX_LEN;

/// The plan a robot follows: its ID and the hash of its content.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Default)]
pub struct PlanRef {
    pub id: u16,
    pub hash: u32,
}

/// Message type codes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum MsgType {
    RequestVote,
    Vote,
    LeaderHeartbeat,
    HeartbeatAck,
    Unknown(u8),
}

impl From<u8> for MsgType {
    fn from(v: u8) -> Self {
        match v {
            1 => MsgType::RequestVote,
            2 => MsgType::Vote,
            3 => MsgType::LeaderHeartbeat,
            4 => MsgType::HeartbeatAck,
            n => MsgType::Unknown(n),
        }
    }
}

impl From<MsgType> for u8 {
    fn from(t: MsgType) -> u8 {
        match t {
            MsgType::RequestVote => 1,
            MsgType::Vote => 2,
            MsgType::LeaderHeartbeat => 3,
            MsgType::HeartbeatAck => 4,
            MsgType::Unknown(n) => n,
        }
    }
}

/// A PUS 8 function a leader may order as the next plan step. UNBOLT_FACE and UNBOLT_PAIR
/// have no variant: a leader cannot express them, and a message carrying their codes is a
/// parse error ([`WireError::ForbiddenFunction`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum TeamFunction {
    Reconfigure,
    BoltFace,
    Home,
    MoveArm,
    MoveGripper,
    RotateHip,
    BoltPair,
    Stop,
}

impl TeamFunction {
    /// The PUS 8 function ID (`mib::tc::function`).
    pub const fn code(self) -> u16 {
        match self {
            TeamFunction::Reconfigure => function::RECONFIGURE,
            TeamFunction::BoltFace => function::BOLT_FACE,
            TeamFunction::Home => function::HOME,
            TeamFunction::MoveArm => function::MOVE_ARM,
            TeamFunction::MoveGripper => function::MOVE_GRIPPER,
            TeamFunction::RotateHip => function::ROTATE_HIP,
            TeamFunction::BoltPair => function::BOLT_PAIR,
            TeamFunction::Stop => function::STOP,
        }
    }

    /// The team function of a PUS 8 function ID; unbolting and unknown IDs are errors.
    pub const fn from_code(code: u16) -> Result<Self, WireError> {
        match code {
            function::RECONFIGURE => Ok(TeamFunction::Reconfigure),
            function::BOLT_FACE => Ok(TeamFunction::BoltFace),
            function::HOME => Ok(TeamFunction::Home),
            function::MOVE_ARM => Ok(TeamFunction::MoveArm),
            function::MOVE_GRIPPER => Ok(TeamFunction::MoveGripper),
            function::ROTATE_HIP => Ok(TeamFunction::RotateHip),
            function::BOLT_PAIR => Ok(TeamFunction::BoltPair),
            function::STOP => Ok(TeamFunction::Stop),
            function::UNBOLT_FACE | function::UNBOLT_PAIR => Err(WireError::ForbiddenFunction(code)),
            n => Err(WireError::UnknownFunction(n)),
        }
    }
}

/// What a leader orders. HOLD is the default; CONTINUE names the next plan step and must
/// lie inside the ground's authorisation on the leader *and* on the follower.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Directive {
    /// Finish the current primitive and hold (STANDBY if both grippers hold, else SAFED).
    Hold,
    /// Execute plan step `step` (1-based), which must be the PUS 8 function `function`.
    Continue { step: u16, function: TeamFunction },
}

const DIRECTIVE_HOLD: u8 = 1;
const DIRECTIVE_CONTINUE: u8 = 2;

/// Body of a team message.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Body {
    /// The sender stands as candidate for `term`.
    RequestVote,
    /// The sender's answer to `candidate`'s request for `term`.
    Vote { candidate: RobotId, granted: bool },
    /// The leader of `term` asserts its leadership and orders `directive`. `stamp` is the
    /// leader's clock (ms, truncated to 32 bits) when it sent the heartbeat.
    LeaderHeartbeat { stamp: u32, directive: Directive },
    /// A follower's acknowledgement of the heartbeat sent at `stamp`; `ok` is false when the
    /// follower is in a higher term (the header then carries that term).
    HeartbeatAck { stamp: u32, ok: bool },
}

impl Body {
    pub const fn msg_type(&self) -> MsgType {
        match self {
            Body::RequestVote => MsgType::RequestVote,
            Body::Vote { .. } => MsgType::Vote,
            Body::LeaderHeartbeat { .. } => MsgType::LeaderHeartbeat,
            Body::HeartbeatAck { .. } => MsgType::HeartbeatAck,
        }
    }

    const fn len(&self) -> usize {
        match self {
            Body::RequestVote => 0,
            Body::Vote { .. } => 2,
            Body::LeaderHeartbeat { .. } => 9,
            Body::HeartbeatAck { .. } => 5,
        }
    }
}

/// A team message (owned representation).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Message {
    pub term: u32,
    pub sender: RobotId,
    pub plan: PlanRef,
    pub progress: u16,
    pub body: Body,
}

/// Why bytes are not a team message.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum WireError {
    /// Shorter than the header.
    Truncated {
        len: usize,
    },
    /// Length does not match the type.
    BadLength {
        msg_type: u8,
        len: usize,
    },
    BadVersion(u8),
    UnknownType(u8),
    UnknownDirective(u8),
    /// A boolean byte other than 0 or 1, or padding that is not zero.
    BadField(u8),
    /// UNBOLT_FACE / UNBOLT_PAIR: never accepted from a leader.
    ForbiddenFunction(u16),
    UnknownFunction(u16),
    /// Sender number outside 1..=254.
    BadSender(u8),
    /// The output buffer is too small.
    BufferTooSmall {
        need: usize,
        have: usize,
    },
}

impl fmt::Display for WireError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            WireError::Truncated { len } => write!(f, "team message truncated ({len} bytes)"),
            WireError::BadLength { msg_type, len } => {
                write!(f, "team message type {msg_type} with wrong length {len}")
            }
            WireError::BadVersion(v) => write!(f, "team message version {v} not supported"),
            WireError::UnknownType(t) => write!(f, "unknown team message type {t}"),
            WireError::UnknownDirective(d) => write!(f, "unknown directive {d}"),
            WireError::BadField(b) => write!(f, "invalid flag or padding byte {b}"),
            WireError::ForbiddenFunction(c) => write!(f, "function {c} is never ordered by a leader"),
            WireError::UnknownFunction(c) => write!(f, "unknown function {c}"),
            WireError::BadSender(s) => write!(f, "sender {s} is not a robot number"),
            WireError::BufferTooSmall { need, have } => {
                write!(f, "buffer of {have} bytes, {need} needed")
            }
        }
    }
}

impl core::error::Error for WireError {}

mod field {
    use core::ops::Range;
    pub const VERSION: usize = 0;
    pub const TYPE: usize = 1;
    pub const TERM: Range<usize> = 2..6;
    pub const SENDER: usize = 6;
    pub const PLAN_ID: Range<usize> = 7..9;
    pub const PLAN_HASH: Range<usize> = 9..13;
    pub const PROGRESS: Range<usize> = 13..15;
    pub const BODY: usize = 15;
}

fn be16(b: &[u8]) -> u16 {
    let mut a = [0u8; 2];
    a.copy_from_slice(b);
    u16::from_be_bytes(a)
}

fn be32(b: &[u8]) -> u32 {
    let mut a = [0u8; 4];
    a.copy_from_slice(b);
    u32::from_be_bytes(a)
}

fn flag(b: u8) -> Result<bool, WireError> {
    match b {
        0 => Ok(false),
        1 => Ok(true),
        n => Err(WireError::BadField(n)),
    }
}

impl Message {
    /// Bytes [`Message::emit`] writes.
    pub const fn buffer_len(&self) -> usize {
        HEADER_LEN + self.body.len()
    }

    /// Parse untrusted bytes. Never panics; every length is checked before use.
    pub fn parse(bytes: &[u8]) -> Result<Message, WireError> {
        if bytes.len() < HEADER_LEN {
            return Err(WireError::Truncated { len: bytes.len() });
        }
        let version = bytes[field::VERSION];
        if version != mib::team::WIRE_VERSION {
            return Err(WireError::BadVersion(version));
        }
        let type_code = bytes[field::TYPE];
        let sender = bytes[field::SENDER];
        if mib::apid::robot_apid(sender).is_none() {
            return Err(WireError::BadSender(sender));
        }
        let body = &bytes[field::BODY..];
        let expect = match MsgType::from(type_code) {
            MsgType::RequestVote => 0,
            MsgType::Vote => 2,
            MsgType::LeaderHeartbeat => 9,
            MsgType::HeartbeatAck => 5,
            MsgType::Unknown(n) => return Err(WireError::UnknownType(n)),
        };
        if body.len() != expect {
            return Err(WireError::BadLength {
                msg_type: type_code,
                len: bytes.len(),
            });
        }
        let body = match MsgType::from(type_code) {
            MsgType::RequestVote => Body::RequestVote,
            MsgType::Vote => Body::Vote {
                candidate: body[0],
                granted: flag(body[1])?,
            },
            MsgType::LeaderHeartbeat => {
                let stamp = be32(&body[0..4]);
                let step = be16(&body[5..7]);
                let code = be16(&body[7..9]);
                let directive = match body[4] {
                    DIRECTIVE_HOLD => {
                        if step != 0 || code != 0 {
                            return Err(WireError::BadField(body[4]));
                        }
                        Directive::Hold
                    }
                    DIRECTIVE_CONTINUE => Directive::Continue {
                        step,
                        function: TeamFunction::from_code(code)?,
                    },
                    d => return Err(WireError::UnknownDirective(d)),
                };
                Body::LeaderHeartbeat { stamp, directive }
            }
            MsgType::HeartbeatAck => Body::HeartbeatAck {
                stamp: be32(&body[0..4]),
                ok: flag(body[4])?,
            },
            MsgType::Unknown(n) => return Err(WireError::UnknownType(n)),
        };
        Ok(Message {
            term: be32(&bytes[field::TERM]),
            sender,
            plan: PlanRef {
                id: be16(&bytes[field::PLAN_ID]),
                hash: be32(&bytes[field::PLAN_HASH]),
            },
            progress: be16(&bytes[field::PROGRESS]),
            body,
        })
    }

    /// Write the message into `buf`; returns the number of bytes written.
    pub fn emit(&self, buf: &mut [u8]) -> Result<usize, WireError> {
        let n = self.buffer_len();
        if buf.len() < n {
            return Err(WireError::BufferTooSmall {
                need: n,
                have: buf.len(),
            });
        }
        let buf = &mut buf[..n];
        buf[field::VERSION] = mib::team::WIRE_VERSION;
        buf[field::TYPE] = self.body.msg_type().into();
        buf[field::TERM].copy_from_slice(&self.term.to_be_bytes());
        buf[field::SENDER] = self.sender;
        buf[field::PLAN_ID].copy_from_slice(&self.plan.id.to_be_bytes());
        buf[field::PLAN_HASH].copy_from_slice(&self.plan.hash.to_be_bytes());
        buf[field::PROGRESS].copy_from_slice(&self.progress.to_be_bytes());
        let body = &mut buf[field::BODY..];
        match self.body {
            Body::RequestVote => {}
            Body::Vote { candidate, granted } => {
                body[0] = candidate;
                body[1] = u8::from(granted);
            }
            Body::LeaderHeartbeat { stamp, directive } => {
                body[0..4].copy_from_slice(&stamp.to_be_bytes());
                let (code, step, function) = match directive {
                    Directive::Hold => (DIRECTIVE_HOLD, 0u16, 0u16),
                    Directive::Continue { step, function } => (DIRECTIVE_CONTINUE, step, function.code()),
                };
                body[4] = code;
                body[5..7].copy_from_slice(&step.to_be_bytes());
                body[7..9].copy_from_slice(&function.to_be_bytes());
            }
            Body::HeartbeatAck { stamp, ok } => {
                body[0..4].copy_from_slice(&stamp.to_be_bytes());
                body[4] = u8::from(ok);
            }
        }
        Ok(n)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// A leader heartbeat of robot 2, term 7, plan 0x0102/0xDEADBEEF, progress 3,
    /// stamp 1000, CONTINUE step 4 = BOLT_PAIR (8).
    const HEARTBEAT: [u8; 24] = [
        0x01, 0x03, 0x00, 0x00, 0x00, 0x07, 0x02, 0x01, 0x02, 0xDE, 0xAD, 0xBE, 0xEF, 0x00, 0x03, 0x00, 0x00, 0x03,
        0xE8, 0x02, 0x00, 0x04, 0x00, 0x08,
    ];

    fn heartbeat() -> Message {
        Message {
            term: 7,
            sender: 2,
            plan: PlanRef {
                id: 0x0102,
                hash: 0xDEAD_BEEF,
            },
            progress: 3,
            body: Body::LeaderHeartbeat {
                stamp: 1000,
                directive: Directive::Continue {
                    step: 4,
                    function: TeamFunction::BoltPair,
                },
            },
        }
    }

    // verifies: TEAM-WIRE-01
    #[test]
    fn heartbeat_parses_emits_and_round_trips() {
        assert_eq!(Message::parse(&HEARTBEAT), Ok(heartbeat()));
        let mut buf = [0u8; MAX_LEN];
        let n = heartbeat().emit(&mut buf).unwrap();
        assert_eq!(&buf[..n], &HEARTBEAT[..]);
        let mut small = [0u8; 10];
        assert!(matches!(
            heartbeat().emit(&mut small),
            Err(WireError::BufferTooSmall { need: 24, have: 10 })
        ));
    }

    // verifies: TEAM-WIRE-01
    #[test]
    fn every_body_round_trips() {
        let bodies = [
            Body::RequestVote,
            Body::Vote {
                candidate: 3,
                granted: true,
            },
            Body::LeaderHeartbeat {
                stamp: u32::MAX,
                directive: Directive::Hold,
            },
            Body::HeartbeatAck { stamp: 5, ok: false },
        ];
        for body in bodies {
            let m = Message { body, ..heartbeat() };
            let mut buf = [0u8; MAX_LEN + 1];
            let n = m.emit(&mut buf).unwrap();
            assert_eq!(n, m.buffer_len());
            assert_eq!(Message::parse(&buf[..n]), Ok(m));
            // One byte more or less is a length error.
            assert!(Message::parse(&buf[..n - 1]).is_err());
            assert!(Message::parse(&buf[..n + 1]).is_err());
        }
    }

    // verifies: TEAM-WIRE-02, TEAM-AUTH-03
    #[test]
    fn malformed_and_unbolt_are_errors() {
        let mut b = HEARTBEAT;
        b[0] = 2;
        assert_eq!(Message::parse(&b), Err(WireError::BadVersion(2)));
        let mut b = HEARTBEAT;
        b[1] = 9;
        assert_eq!(Message::parse(&b), Err(WireError::UnknownType(9)));
        let mut b = HEARTBEAT;
        b[6] = 0;
        assert_eq!(Message::parse(&b), Err(WireError::BadSender(0)));
        let mut b = HEARTBEAT;
        b[19] = 7;
        assert_eq!(Message::parse(&b), Err(WireError::UnknownDirective(7)));
        for unbolt in [function::UNBOLT_FACE, function::UNBOLT_PAIR] {
            let mut b = HEARTBEAT;
            b[22..24].copy_from_slice(&unbolt.to_be_bytes());
            assert_eq!(Message::parse(&b), Err(WireError::ForbiddenFunction(unbolt)));
        }
        let mut b = HEARTBEAT;
        b[22..24].copy_from_slice(&99u16.to_be_bytes());
        assert_eq!(Message::parse(&b), Err(WireError::UnknownFunction(99)));
        assert_eq!(Message::parse(&HEARTBEAT[..3]), Err(WireError::Truncated { len: 3 }));
        // HOLD with a non-zero step is malformed.
        let mut b = HEARTBEAT;
        b[19] = DIRECTIVE_HOLD;
        assert!(matches!(Message::parse(&b), Err(WireError::BadField(_))));
    }

    proptest! {
        // verifies: TEAM-WIRE-02
        #[test]
        fn random_bytes_never_panic_and_valid_ones_round_trip(
            bytes in proptest::collection::vec(any::<u8>(), 0..40)
        ) {
            if let Ok(m) = Message::parse(&bytes) {
                let mut buf = [0u8; MAX_LEN];
                let n = m.emit(&mut buf).unwrap();
                prop_assert_eq!(&buf[..n], &bytes[..]);
            }
        }
    }
}
