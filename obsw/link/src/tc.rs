//! TC transfer frames (CCSDS 232.0-B-4 §4.1): a zero-copy view [`TcFrame`] and the header
//! [`TcRepr`]. The frame error control field is always present on this mission.
//!
//! ```text
//!  0               1               2               3               4
//! +---+-+-+---+---------------------+-----------+-------------------+---------------+
//! |TFV|B|C|spr|  spacecraft id (10) | VCID (6)  | frame length − 1  | frame seq N(S)|
//! +---+-+-+---+---------------------+-----------+-------------------+---------------+
//! | data field (…)                                                  | FECF (16)     |
//! ```
//! B = bypass flag, C = control command flag. AD: B=0 C=0; BD: B=1 C=0; BC: B=1 C=1.

use core::fmt;

use mib::link::tc_frame::{FECF_LEN, HEADER_LEN, MAX_LEN, MIN_LEN};

use crate::fecf;

mod field {
    use core::ops::Range;
    pub const FLAGS_SCID: Range<usize> = 0..2;
    pub const VCID_LEN: Range<usize> = 2..4;
    pub const SEQ: usize = 4;
    pub const DATA_START: usize = 5;
}

/// Why a TC frame's bytes were refused before any security or COP-1 processing.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TcError {
    /// Fewer bytes than a header, one data byte and the FECF.
    TooShort(usize),
    /// More bytes than the largest TC frame.
    TooLong(usize),
    /// The header's frame length disagrees with the bytes received (one frame per datagram).
    LengthMismatch { header: usize, received: usize },
    /// Transfer frame version not `00`.
    BadVersion(u8),
    /// Control command flag set without the bypass flag (an illegal combination).
    IllegalFrameType,
    /// The frame error control field does not match.
    BadCrc,
}

impl fmt::Display for TcError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            TcError::TooShort(n) => write!(f, "TC frame too short ({n} bytes)"),
            TcError::TooLong(n) => write!(f, "TC frame too long ({n} bytes)"),
            TcError::LengthMismatch { header, received } => {
                write!(f, "TC frame length {header} in header, {received} received")
            }
            TcError::BadVersion(v) => write!(f, "TC frame version {v}"),
            TcError::IllegalFrameType => write!(f, "TC frame control flag without bypass flag"),
            TcError::BadCrc => write!(f, "TC frame CRC mismatch"),
        }
    }
}

impl core::error::Error for TcError {}

/// The three legal TC frame types.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FrameType {
    /// Sequence-controlled data (COP-1 AD service).
    Ad,
    /// Expedited data (bypass).
    Bd,
    /// Control command (Unlock, Set V(R)), bypass.
    Bc,
}

/// A zero-copy view over a TC transfer frame.
#[derive(Debug, Clone)]
pub struct TcFrame<T: AsRef<[u8]>> {
    buffer: T,
}

impl<T: AsRef<[u8]>> TcFrame<T> {
    /// Wraps bytes without checks; getters may panic on short buffers. For emitting only.
    pub const fn new_unchecked(buffer: T) -> Self {
        TcFrame { buffer }
    }

    /// Wraps untrusted bytes: length bounds, the header's length against the bytes, version
    /// and flags are checked, in that order, before any field is used. The FECF is not
    /// checked here (see [`TcFrame::check_fecf`]).
    pub fn new_checked(buffer: T) -> Result<Self, TcError> {
        let len = buffer.as_ref().len();
        if len < MIN_LEN {
            return Err(TcError::TooShort(len));
        }
        if len > MAX_LEN {
            return Err(TcError::TooLong(len));
        }
        let f = TcFrame { buffer };
        if f.frame_len() != len {
            return Err(TcError::LengthMismatch {
                header: f.frame_len(),
                received: len,
            });
        }
        if f.version() != mib::link::TC_TFVN {
            return Err(TcError::BadVersion(f.version()));
        }
        if f.control_command() && !f.bypass() {
            return Err(TcError::IllegalFrameType);
        }
        Ok(f)
    }

    pub fn into_inner(self) -> T {
        self.buffer
    }

    fn word0(&self) -> u16 {
        let b = &self.buffer.as_ref()[field::FLAGS_SCID];
        u16::from_be_bytes([b[0], b[1]])
    }

    fn word1(&self) -> u16 {
        let b = &self.buffer.as_ref()[field::VCID_LEN];
        u16::from_be_bytes([b[0], b[1]])
    }

    pub fn version(&self) -> u8 {
        (self.word0() >> 14) as u8
    }

    pub fn bypass(&self) -> bool {
        self.word0() & 0x2000 != 0
    }

    pub fn control_command(&self) -> bool {
        self.word0() & 0x1000 != 0
    }

    pub fn scid(&self) -> u16 {
        self.word0() & 0x03FF
    }

    pub fn vcid(&self) -> u8 {
        (self.word1() >> 10) as u8
    }

    /// Total frame length in bytes (the header field plus one).
    pub fn frame_len(&self) -> usize {
        usize::from(self.word1() & 0x03FF) + 1
    }

    /// N(S), the frame sequence number.
    pub fn seq(&self) -> u8 {
        self.buffer.as_ref()[field::SEQ]
    }

    pub fn frame_type(&self) -> FrameType {
        match (self.bypass(), self.control_command()) {
            (false, false) => FrameType::Ad,
            (true, false) => FrameType::Bd,
            // (false, true) is refused by new_checked; treat it as BC for unchecked views.
            (_, true) => FrameType::Bc,
        }
    }

    /// The data field: between the header and the FECF.
    pub fn data(&self) -> &[u8] {
        let b = self.buffer.as_ref();
        &b[field::DATA_START..b.len() - FECF_LEN]
    }

    /// The whole frame but the FECF.
    pub fn without_fecf(&self) -> &[u8] {
        let b = self.buffer.as_ref();
        &b[..b.len() - FECF_LEN]
    }

    pub fn fecf(&self) -> u16 {
        let b = self.buffer.as_ref();
        u16::from_be_bytes([b[b.len() - 2], b[b.len() - 1]])
    }

    pub fn check_fecf(&self) -> bool {
        fecf::check(self.buffer.as_ref())
    }
}

impl<T: AsRef<[u8]> + AsMut<[u8]>> TcFrame<T> {
    pub fn data_mut(&mut self) -> &mut [u8] {
        let b = self.buffer.as_mut();
        let end = b.len() - FECF_LEN;
        &mut b[field::DATA_START..end]
    }

    /// Computes and writes the FECF.
    pub fn fill_fecf(&mut self) {
        fecf::seal(self.buffer.as_mut());
    }
}

/// The header of a TC frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TcRepr {
    pub frame_type: FrameType,
    pub scid: u16,
    pub vcid: u8,
    pub seq: u8,
    /// Length of the data field (between header and FECF).
    pub data_len: usize,
}

impl TcRepr {
    pub fn parse<T: AsRef<[u8]>>(frame: &TcFrame<T>) -> TcRepr {
        TcRepr {
            frame_type: frame.frame_type(),
            scid: frame.scid(),
            vcid: frame.vcid(),
            seq: frame.seq(),
            data_len: frame.data().len(),
        }
    }

    pub const fn buffer_len(&self) -> usize {
        HEADER_LEN + self.data_len + FECF_LEN
    }

    /// Writes the header into the first 5 bytes of `frame` (whose length must be
    /// `buffer_len()`; the caller sized it). Fields are masked to their widths.
    pub fn emit<T: AsRef<[u8]> + AsMut<[u8]>>(&self, frame: &mut TcFrame<T>) {
        let (bypass, ctrl) = match self.frame_type {
            FrameType::Ad => (0u16, 0u16),
            FrameType::Bd => (1, 0),
            FrameType::Bc => (1, 1),
        };
        let w0 = (u16::from(mib::link::TC_TFVN) << 14) | (bypass << 13) | (ctrl << 12) | (self.scid & 0x3FF);
        let len_field = (self.buffer_len() - 1) as u16 & 0x3FF;
        let w1 = (u16::from(self.vcid & 0x3F) << 10) | len_field;
        let b = frame.buffer.as_mut();
        b[0..2].copy_from_slice(&w0.to_be_bytes());
        b[2..4].copy_from_slice(&w1.to_be_bytes());
        b[4] = self.seq;
    }
}

/// Writes a clear (no SDLS) TC frame with `data` into `buf`, FECF included; returns its
/// length. `None` when the frame would not fit `buf` or exceed the largest TC frame.
pub fn build_clear(repr_without_len: TcRepr, data: &[u8], buf: &mut [u8]) -> Option<usize> {
    let repr = TcRepr {
        data_len: data.len(),
        ..repr_without_len
    };
    let n = repr.buffer_len();
    if n > MAX_LEN || n > buf.len() || data.is_empty() {
        return None;
    }
    let mut f = TcFrame::new_unchecked(&mut buf[..n]);
    repr.emit(&mut f);
    f.data_mut().copy_from_slice(data);
    f.fill_fecf();
    Some(n)
}

/// COP-1 control commands carried in BC frames (232.0-B-4 §4.1.3.3.3, 232.1-B-2 §4.2.1).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ControlCommand {
    /// `00`: clear the FARM's lockout, wait and retransmit flags.
    Unlock,
    /// `82 00 V*(R)`: set V(R).
    SetVr(u8),
}

/// A BC frame's data field that is neither Unlock nor Set V(R).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct UnknownControlCommand {
    pub first_byte: u8,
    pub len: usize,
}

impl fmt::Display for UnknownControlCommand {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "unknown control command {:#04x} ({} bytes)",
            self.first_byte, self.len
        )
    }
}

impl ControlCommand {
    pub fn parse(data: &[u8]) -> Result<ControlCommand, UnknownControlCommand> {
        match data {
            [0x00] => Ok(ControlCommand::Unlock),
            [0x82, 0x00, vr] => Ok(ControlCommand::SetVr(*vr)),
            other => Err(UnknownControlCommand {
                first_byte: other.first().copied().unwrap_or(0),
                len: other.len(),
            }),
        }
    }

    /// The data field bytes and their count.
    pub fn emit(&self) -> ([u8; 3], usize) {
        match self {
            ControlCommand::Unlock => ([0, 0, 0], 1),
            ControlCommand::SetVr(v) => ([0x82, 0x00, *v], 3),
        }
    }

    /// A complete BC frame for this command into `buf`; returns its length.
    pub fn build_frame(&self, scid: u16, vcid: u8, buf: &mut [u8]) -> Option<usize> {
        let (bytes, n) = self.emit();
        let repr = TcRepr {
            frame_type: FrameType::Bc,
            scid,
            vcid,
            seq: 0,
            data_len: n,
        };
        build_clear(repr, &bytes[..n], buf)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A BC Unlock frame, SCID 0x0AB, VC 0, by hand: 30 AB | 00 05 | 00 | 00 | CRC.
    fn unlock_bytes() -> [u8; 8] {
        let mut f = [0x30, 0xAB, 0x00, 0x07, 0x00, 0x00, 0, 0];
        crate::fecf::seal(&mut f);
        f
    }

    // verifies: LINK-FRAME-01
    #[test]
    fn parse_bc_unlock_byte_array() {
        let b = unlock_bytes();
        let f = TcFrame::new_checked(&b[..]).unwrap();
        assert_eq!(f.version(), 0);
        assert!(f.bypass() && f.control_command());
        assert_eq!(f.scid(), 0x0AB);
        assert_eq!(f.vcid(), 0);
        assert_eq!(f.frame_len(), 8);
        assert_eq!(f.frame_type(), FrameType::Bc);
        assert!(f.check_fecf());
        assert_eq!(ControlCommand::parse(f.data()), Ok(ControlCommand::Unlock));
    }

    // verifies: LINK-FRAME-01
    #[test]
    fn emit_matches_byte_array_and_round_trips() {
        let mut buf = [0u8; 16];
        let n = ControlCommand::Unlock.build_frame(0x0AB, 0, &mut buf).unwrap();
        assert_eq!(&buf[..n], &unlock_bytes());
        let n = ControlCommand::SetVr(0xFE).build_frame(0x0AB, 0, &mut buf).unwrap();
        let f = TcFrame::new_checked(&buf[..n]).unwrap();
        assert_eq!(ControlCommand::parse(f.data()), Ok(ControlCommand::SetVr(0xFE)));
        let repr = TcRepr {
            frame_type: FrameType::Ad,
            scid: 0x3FF,
            vcid: 63,
            seq: 200,
            data_len: 0,
        };
        let n = build_clear(repr, &[1, 2, 3], &mut buf).unwrap();
        let f = TcFrame::new_checked(&buf[..n]).unwrap();
        assert_eq!(TcRepr::parse(&f), TcRepr { data_len: 3, ..repr });
        assert_eq!(f.data(), &[1, 2, 3]);
    }

    // verifies: LINK-FRAME-02
    #[test]
    fn checked_constructor_refuses_bad_lengths_and_flags() {
        let b = unlock_bytes();
        assert_eq!(TcFrame::new_checked(&b[..7]).unwrap_err(), TcError::TooShort(7));
        assert_eq!(
            TcFrame::new_checked(&[0u8; 1025][..]).unwrap_err(),
            TcError::TooLong(1025)
        );
        let mut longer = [0u8; 9];
        longer[..8].copy_from_slice(&b);
        assert_eq!(
            TcFrame::new_checked(&longer[..]).unwrap_err(),
            TcError::LengthMismatch { header: 8, received: 9 }
        );
        // Header claims 1024 bytes, datagram has 8: the CryptoLib CVE class.
        let mut lie = b;
        lie[2] = 0x03;
        lie[3] = 0xFF;
        assert_eq!(
            TcFrame::new_checked(&lie[..]).unwrap_err(),
            TcError::LengthMismatch {
                header: 1024,
                received: 8
            }
        );
        let mut v = b;
        v[0] |= 0x40;
        assert_eq!(TcFrame::new_checked(&v[..]).unwrap_err(), TcError::BadVersion(1));
        let mut c = b;
        c[0] = 0x10 | (c[0] & 0x03);
        assert_eq!(TcFrame::new_checked(&c[..]).unwrap_err(), TcError::IllegalFrameType);
        let mut crc = b;
        crc[5] ^= 1;
        assert!(!TcFrame::new_checked(&crc[..]).unwrap().check_fecf());
    }

    // verifies: LINK-FRAME-01
    #[test]
    fn unknown_control_commands_are_values() {
        assert_eq!(
            ControlCommand::parse(&[0x82, 0x01, 3]),
            Err(UnknownControlCommand {
                first_byte: 0x82,
                len: 3
            })
        );
        assert_eq!(
            ControlCommand::parse(&[]),
            Err(UnknownControlCommand { first_byte: 0, len: 0 })
        );
        assert!(ControlCommand::parse(&[0, 0]).is_err());
    }
}
