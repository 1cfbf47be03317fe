//! Board A ↔ board B protocol over the wired serial link.
//!
//! ## Frame
//! A frame is `0x00 | COBS(payload | crc16) | 0x00`. The payload is
//! `kind u8 | seq u8 | body`; the CRC is CRC-16/CCITT-FALSE (`crc::CRC_16_IBM_3740`)
//! over the payload, big-endian. All multi-byte fields are big-endian. The leading
//! zero resynchronises the receiver after line noise.
//!
//! | kind | direction | body |
//! |---|---|---|
//! | `0x01` Command | A→B | `code u8` + arguments ([`ModuleCmd`]) |
//! | `0x81` Ack | B→A | empty (`seq` = the command's sequence number) |
//! | `0x82` Heartbeat | B→A | [`Heartbeat`], 28 bytes (`seq` counts heartbeats); its `last_seq` also acknowledges |
//! | `0x83` Modules | B→A | [`ModulesChunk`], 32 bytes: B's probe results and one entry of its descriptor table (docs/modules.md) |
//!
//! The framing is the project's one byte-stream codec, `mmic_stream` ([`Message::encode`]
//! uses its encoder, [`FrameDecoder`] its deframer). Untrusted bytes go through
//! [`FrameDecoder`], which never panics: a bad COBS code, CRC, kind, length or value is an
//! error value, and a frame longer than the buffer is dropped up to the next delimiter.

use crate::consts::{LINK_MAX_FRAME, LINK_QUEUE_DEPTH};
use crate::types::BolterDrive;
use heapless::{Deque, Vec};

/// CRC-16/CCITT-FALSE: the MIB's one CRC-16 (`mib::headers::PEC_CRC`).
pub const CRC16: crc::Crc<u16> = mib::headers::PEC_CRC;

pub const KIND_COMMAND: u8 = 0x01;
pub const KIND_ACK: u8 = 0x81;
pub const KIND_HEARTBEAT: u8 = 0x82;
pub const KIND_MODULES: u8 = 0x83;

/// Largest encoded frame on the wire (delimiters included).
pub const MAX_WIRE_FRAME: usize = mmic_stream::encoded_len(LINK_MAX_FRAME);

/// A module command from A to B (side B's modules).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ModuleCmd {
    /// Arm target PWM (µs); B interpolates toward it.
    ArmTarget(u16),
    /// Gripper target PWM (µs).
    GripTarget(u16),
    /// Bolter drive and selected pair (1..=4, 0 = none).
    Bolter { drive: BolterDrive, pair: u8 },
    /// Module modes (`mib::modes::module_mode`: 0 OFF, 1 ON, 2 HOLD).
    Power { arm: u8, grip: u8, bolter: u8 },
    /// Hold every module where it is, bolter off.
    Stop,
    /// At boot, while B's modules are unpowered: the arm and gripper are known (from
    /// A's state estimate) to be at these pulse widths; B starts interpolating there.
    Assume { arm: u16, grip: u16 },
    /// Send the descriptor table again (module discovery, docs/modules.md): A asks when B's
    /// `Modules` frames did not all arrive.
    SendModules,
}

impl ModuleCmd {
    pub const fn code(&self) -> u8 {
        match self {
            ModuleCmd::ArmTarget(_) => 1,
            ModuleCmd::GripTarget(_) => 2,
            ModuleCmd::Bolter { .. } => 3,
            ModuleCmd::Power { .. } => 4,
            ModuleCmd::Stop => 5,
            ModuleCmd::Assume { .. } => 6,
            ModuleCmd::SendModules => 7,
        }
    }
    /// Commands that order the queue: never coalesced across.
    const fn is_barrier(&self) -> bool {
        matches!(self, ModuleCmd::Power { .. } | ModuleCmd::Stop)
    }
    fn emit(&self, out: &mut [u8]) -> usize {
        out[0] = self.code();
        match *self {
            ModuleCmd::ArmTarget(v) | ModuleCmd::GripTarget(v) => {
                out[1..3].copy_from_slice(&v.to_be_bytes());
                3
            }
            ModuleCmd::Bolter { drive, pair } => {
                out[1] = drive.code();
                out[2] = pair;
                3
            }
            ModuleCmd::Power { arm, grip, bolter } => {
                out[1] = arm;
                out[2] = grip;
                out[3] = bolter;
                4
            }
            ModuleCmd::Stop | ModuleCmd::SendModules => 1,
            ModuleCmd::Assume { arm, grip } => {
                out[1..3].copy_from_slice(&arm.to_be_bytes());
                out[3..5].copy_from_slice(&grip.to_be_bytes());
                5
            }
        }
    }
    fn parse(b: &[u8]) -> Result<ModuleCmd, FrameError> {
        let (&code, args) = b.split_first().ok_or(FrameError::BadLength)?;
        let need = |n: usize| {
            if args.len() == n {
                Ok(())
            } else {
                Err(FrameError::BadLength)
            }
        };
        match code {
            1 | 2 => {
                need(2)?;
                let v = u16::from_be_bytes([args[0], args[1]]);
                Ok(if code == 1 {
                    ModuleCmd::ArmTarget(v)
                } else {
                    ModuleCmd::GripTarget(v)
                })
            }
            3 => {
                need(2)?;
                let drive = BolterDrive::from_code(args[0]).ok_or(FrameError::BadValue)?;
                if args[1] > mib::robot::bolter::PAIRS_PER_FACE {
                    return Err(FrameError::BadValue);
                }
                Ok(ModuleCmd::Bolter { drive, pair: args[1] })
            }
            4 => {
                need(3)?;
                if args.iter().any(|&m| m as u32 > mib::modes::module_mode::HOLD) {
                    return Err(FrameError::BadValue);
                }
                Ok(ModuleCmd::Power {
                    arm: args[0],
                    grip: args[1],
                    bolter: args[2],
                })
            }
            5 => {
                need(0)?;
                Ok(ModuleCmd::Stop)
            }
            6 => {
                need(4)?;
                Ok(ModuleCmd::Assume {
                    arm: u16::from_be_bytes([args[0], args[1]]),
                    grip: u16::from_be_bytes([args[2], args[3]]),
                })
            }
            7 => {
                need(0)?;
                Ok(ModuleCmd::SendModules)
            }
            other => Err(FrameError::UnknownCommand(other)),
        }
    }
}

/// Heartbeat flag bits.
pub mod flag {
    /// I_loc above `mib::params::I_LOC_MAX`.
    pub const OC_LOC: u8 = 1 << 0;
    /// I_grip above `mib::params::I_GRIP_MAX`.
    pub const OC_GRIP: u8 = 1 << 1;
    /// I_bo above `mib::params::I_BO_MAX`.
    pub const OC_BO: u8 = 1 << 2;
    /// Arm-contracted switch pushed.
    pub const ARM_SWITCH: u8 = 1 << 3;
}

/// Board B's periodic status (paper Table 4). Currents and voltages are B's
/// moving-averaged raw ADC counts, gravity its moving-averaged IMU vector (milli-g).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Heartbeat {
    pub v_bat: u16,
    pub i_loc: u16,
    pub i_grip: u16,
    pub i_bo: u16,
    pub arm_target: u16,
    pub arm_pwm: u16,
    pub grip_target: u16,
    pub grip_pwm: u16,
    pub grav: [i16; 3],
    /// [`flag`] bits.
    pub flags: u8,
    /// Bolter sync: drive code and selected pair.
    pub bolter_drive: u8,
    pub bolter_pair: u8,
    /// Module modes: arm | grip << 2 | bolter << 4.
    pub modes: u8,
    /// Sequence number of the last command executed (0: none yet). Doubles as an
    /// acknowledgement (paper Table 4) when an `Ack` frame was lost.
    pub last_seq: u8,
    /// Frames board B dropped (bad CRC, framing), low 8 bits of its counter.
    pub rx_errors: u8,
}

impl Heartbeat {
    pub const LEN: usize = 28;
    pub fn arm_switch(&self) -> bool {
        self.flags & flag::ARM_SWITCH != 0
    }
    /// Bolter state byte for `BOLTER_B_STATE`: drive code << 4 | pair.
    pub fn bolter_state(&self) -> u8 {
        (self.bolter_drive << 4) | (self.bolter_pair & 0x0F)
    }
    fn emit(&self, o: &mut [u8]) -> usize {
        let words = [
            self.v_bat,
            self.i_loc,
            self.i_grip,
            self.i_bo,
            self.arm_target,
            self.arm_pwm,
            self.grip_target,
            self.grip_pwm,
            self.grav[0] as u16,
            self.grav[1] as u16,
            self.grav[2] as u16,
        ];
        for (i, w) in words.iter().enumerate() {
            o[2 * i..2 * i + 2].copy_from_slice(&w.to_be_bytes());
        }
        o[22] = self.flags;
        o[23] = self.bolter_drive;
        o[24] = self.bolter_pair;
        o[25] = self.modes;
        o[26] = self.last_seq;
        o[27] = self.rx_errors;
        Self::LEN
    }
    fn parse(b: &[u8]) -> Result<Heartbeat, FrameError> {
        if b.len() != Self::LEN {
            return Err(FrameError::BadLength);
        }
        let w = |i: usize| u16::from_be_bytes([b[2 * i], b[2 * i + 1]]);
        if BolterDrive::from_code(b[23]).is_none() {
            return Err(FrameError::BadValue);
        }
        Ok(Heartbeat {
            v_bat: w(0),
            i_loc: w(1),
            i_grip: w(2),
            i_bo: w(3),
            arm_target: w(4),
            arm_pwm: w(5),
            grip_target: w(6),
            grip_pwm: w(7),
            grav: [w(8) as i16, w(9) as i16, w(10) as i16],
            flags: b[22],
            bolter_drive: b[23],
            bolter_pair: b[24],
            modes: b[25],
            last_seq: b[26],
            rx_errors: b[27],
        })
    }
}

/// Board B's half of module discovery (docs/modules.md), one table entry per frame: B's probe
/// results (2 bytes, [`ModulesChunk::probe_bytes`]) and a `TableAssembler` chunk
/// (`index u8 | count u8 | descriptor`, [`crate::discovery::CHUNK_LEN`] bytes).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ModulesChunk {
    pub probes: crate::discovery::BoardProbes,
    pub chunk: [u8; crate::discovery::CHUNK_LEN],
}

impl ModulesChunk {
    pub const LEN: usize = 2 + crate::discovery::CHUNK_LEN;

    /// Probe results on the wire: `who_am_i u8 | flags u8` (bit 0 the IMU answered,
    /// bit 1 ADC ack, bit 2 encoder ack, bits 4-5 arm switch: 0 absent, 1 pushed,
    /// 2 released).
    pub fn probe_bytes(p: &crate::discovery::BoardProbes) -> [u8; 2] {
        use crate::discovery::ArmSwitch;
        let sw = match p.arm_switch {
            ArmSwitch::Absent => 0u8,
            ArmSwitch::Pushed => 1,
            ArmSwitch::Released => 2,
        };
        let flags =
            u8::from(p.imu_who_am_i.is_some()) | u8::from(p.adc_ack) << 1 | u8::from(p.encoder_ack) << 2 | sw << 4;
        [p.imu_who_am_i.unwrap_or(0), flags]
    }

    fn probes_of(b: [u8; 2]) -> Result<crate::discovery::BoardProbes, FrameError> {
        use crate::discovery::ArmSwitch;
        let [who, flags] = b;
        if flags & 0b1100_1000 != 0 {
            return Err(FrameError::BadValue);
        }
        let arm_switch = match (flags >> 4) & 3 {
            0 => ArmSwitch::Absent,
            1 => ArmSwitch::Pushed,
            2 => ArmSwitch::Released,
            _ => return Err(FrameError::BadValue),
        };
        Ok(crate::discovery::BoardProbes {
            imu_who_am_i: (flags & 1 != 0).then_some(who),
            adc_ack: flags & 2 != 0,
            encoder_ack: flags & 4 != 0,
            arm_switch,
        })
    }

    fn emit(&self, o: &mut [u8]) -> usize {
        o[..2].copy_from_slice(&Self::probe_bytes(&self.probes));
        o[2..Self::LEN].copy_from_slice(&self.chunk);
        Self::LEN
    }

    fn parse(b: &[u8]) -> Result<ModulesChunk, FrameError> {
        if b.len() != Self::LEN {
            return Err(FrameError::BadLength);
        }
        let mut chunk = [0u8; crate::discovery::CHUNK_LEN];
        chunk.copy_from_slice(&b[2..]);
        Ok(ModulesChunk {
            probes: Self::probes_of([b[0], b[1]])?,
            chunk,
        })
    }
}

/// A decoded frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Message {
    Command { seq: u8, cmd: ModuleCmd },
    Ack { seq: u8 },
    Heartbeat { seq: u8, hb: Heartbeat },
    Modules { seq: u8, m: ModulesChunk },
}

/// Why a frame was dropped.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FrameError {
    /// COBS decoding failed (a delimiter inside a COBS block).
    Cobs,
    /// Shorter than kind + seq + CRC.
    TooShort,
    Crc {
        received: u16,
        computed: u16,
    },
    UnknownKind(u8),
    UnknownCommand(u8),
    BadLength,
    BadValue,
    /// Longer than `LINK_MAX_FRAME` once decoded: dropped up to the next delimiter.
    Overflow,
}

impl From<mmic_stream::StreamError> for FrameError {
    fn from(e: mmic_stream::StreamError) -> Self {
        match e {
            mmic_stream::StreamError::Oversize => FrameError::Overflow,
            // `BufferTooSmall` is the encoder's error; the deframer never returns it.
            mmic_stream::StreamError::Corrupt | mmic_stream::StreamError::BufferTooSmall => FrameError::Cobs,
        }
    }
}

// Static text and numbers, not the `Debug` impl: a `Display` that formats through
// `Debug` would link the derived `Debug` code into every image that prints the error.
impl core::fmt::Display for FrameError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            FrameError::Cobs => f.write_str("COBS decoding failed"),
            FrameError::TooShort => f.write_str("frame too short"),
            FrameError::Crc { received, computed } => {
                write!(f, "CRC mismatch: received 0x{received:04X}, computed 0x{computed:04X}")
            }
            FrameError::UnknownKind(k) => write!(f, "unknown frame kind 0x{k:02X}"),
            FrameError::UnknownCommand(c) => write!(f, "unknown command 0x{c:02X}"),
            FrameError::BadLength => f.write_str("bad length"),
            FrameError::BadValue => f.write_str("bad value"),
            FrameError::Overflow => f.write_str("frame longer than LINK_MAX_FRAME"),
        }
    }
}

impl core::error::Error for FrameError {}

/// The output buffer cannot take the frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TxFull;

impl Message {
    /// Payload (without CRC) into `out`; returns its length.
    fn emit_payload(&self, out: &mut [u8; LINK_MAX_FRAME]) -> usize {
        match self {
            Message::Command { seq, cmd } => {
                out[0] = KIND_COMMAND;
                out[1] = *seq;
                2 + cmd.emit(&mut out[2..])
            }
            Message::Ack { seq } => {
                out[0] = KIND_ACK;
                out[1] = *seq;
                2
            }
            Message::Heartbeat { seq, hb } => {
                out[0] = KIND_HEARTBEAT;
                out[1] = *seq;
                2 + hb.emit(&mut out[2..])
            }
            Message::Modules { seq, m } => {
                out[0] = KIND_MODULES;
                out[1] = *seq;
                2 + m.emit(&mut out[2..])
            }
        }
    }

    /// Parses a decoded payload (CRC included). Never panics.
    pub fn parse(p: &[u8]) -> Result<Message, FrameError> {
        if p.len() < 4 {
            return Err(FrameError::TooShort);
        }
        let (body, crc) = p.split_at(p.len() - 2);
        let received = u16::from_be_bytes([crc[0], crc[1]]);
        let computed = CRC16.checksum(body);
        if received != computed {
            return Err(FrameError::Crc { received, computed });
        }
        let (kind, seq, rest) = (body[0], body[1], &body[2..]);
        match kind {
            KIND_COMMAND => Ok(Message::Command {
                seq,
                cmd: ModuleCmd::parse(rest)?,
            }),
            KIND_ACK => {
                if rest.is_empty() {
                    Ok(Message::Ack { seq })
                } else {
                    Err(FrameError::BadLength)
                }
            }
            KIND_HEARTBEAT => Ok(Message::Heartbeat {
                seq,
                hb: Heartbeat::parse(rest)?,
            }),
            KIND_MODULES => Ok(Message::Modules {
                seq,
                m: ModulesChunk::parse(rest)?,
            }),
            k => Err(FrameError::UnknownKind(k)),
        }
    }

    /// Appends the framed message to `out`, or leaves `out` unchanged if it does not fit.
    pub fn encode<const N: usize>(&self, out: &mut Vec<u8, N>) -> Result<(), TxFull> {
        let mut payload = [0u8; LINK_MAX_FRAME];
        let n = self.emit_payload(&mut payload);
        let crc = CRC16.checksum(&payload[..n]);
        payload[n..n + 2].copy_from_slice(&crc.to_be_bytes());
        let mut enc = [0u8; MAX_WIRE_FRAME];
        let m = mmic_stream::encode(&payload[..n + 2], &mut enc).map_err(|_| TxFull)?;
        // heapless checks the room first: `out` is unchanged when the frame does not fit.
        out.extend_from_slice(&enc[..m]).map_err(|_| TxFull)
    }
}

/// Byte-stream receiver: the one deframer (`mmic_stream::Deframer`, decoded buffer of
/// the largest payload + CRC), then [`Message::parse`].
#[derive(Clone, Debug, Default)]
pub struct FrameDecoder {
    de: mmic_stream::Deframer<LINK_MAX_FRAME>,
}

impl FrameDecoder {
    pub const fn new() -> Self {
        FrameDecoder {
            de: mmic_stream::Deframer::new(),
        }
    }
    /// Feeds one byte; returns a frame (or an error) when a delimiter ends one. A frame
    /// longer than `LINK_MAX_FRAME` is [`FrameError::Overflow`], a broken COBS encoding
    /// [`FrameError::Cobs`], an empty COBS frame (`0x01 0x00`) [`FrameError::TooShort`];
    /// delimiters alone are nothing.
    pub fn push(&mut self, byte: u8) -> Option<Result<Message, FrameError>> {
        let garbage = self.de.counters.garbage_bytes;
        if let Some(r) = self.de.push(byte) {
            return Some(r.map_err(FrameError::from).and_then(Message::parse));
        }
        // The deframer ignores an empty frame, counting its code byte as garbage; the A–B
        // link counts it as a bad frame, as a frame too short to parse.
        (self.de.counters.garbage_bytes != garbage).then_some(Err(FrameError::TooShort))
    }
    /// What the deframer saw (frames, dropped frames, garbage bytes).
    pub fn stream_counters(&self) -> mmic_stream::StreamCounters {
        self.de.counters
    }
}

/// Counters kept by A's link manager (the `B_*` parameters).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LinkCounters {
    pub hb_rx: u32,
    pub frame_errors: u32,
    pub retries: u32,
    pub ack_missed: u32,
    pub acks: u32,
    /// Commands dropped because the queue was full (cannot happen with coalescing,
    /// counted to prove it).
    pub queue_dropped: u32,
}

#[derive(Clone, Copy, Debug)]
struct InFlight {
    seq: u8,
    cmd: ModuleCmd,
    sent_ms: u64,
    resends: u8,
}

/// A command B never acknowledged.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct GaveUp {
    pub command: u8,
    pub retries: u8,
}

/// Board A's side of the link: one command in flight at a time (stop-and-wait),
/// resent after `B_ACK_TIMEOUT_MS`, given up after `B_MAX_RETRIES` resends; a queue
/// behind it where a newer command replaces a queued one of the same kind (latest value
/// wins) unless a `Power`/`Stop` lies between them. When the queue is full the oldest
/// queued command is dropped and counted.
#[derive(Clone, Debug)]
pub struct LinkManager {
    queue: Deque<ModuleCmd, LINK_QUEUE_DEPTH>,
    in_flight: Option<InFlight>,
    next_seq: u8,
    decoder: FrameDecoder,
    hb: Option<Heartbeat>,
    last_hb_ms: Option<u64>,
    start_ms: Option<u64>,
    counters: LinkCounters,
    failed: bool,
    /// Board B's descriptor table, rebuilt from its `Modules` frames (docs/modules.md).
    b_table: crate::discovery::TableAssembler,
    /// Board B's probe results (from its latest `Modules` frame).
    b_probes: Option<crate::discovery::BoardProbes>,
}

impl Default for LinkManager {
    fn default() -> Self {
        Self::new()
    }
}

impl LinkManager {
    pub const fn new() -> Self {
        LinkManager {
            queue: Deque::new(),
            in_flight: None,
            next_seq: 1,
            decoder: FrameDecoder::new(),
            hb: None,
            last_hb_ms: None,
            start_ms: None,
            counters: LinkCounters {
                hb_rx: 0,
                frame_errors: 0,
                retries: 0,
                ack_missed: 0,
                acks: 0,
                queue_dropped: 0,
            },
            failed: false,
            b_table: crate::discovery::TableAssembler::new(),
            b_probes: None,
        }
    }

    /// Board B's half of module discovery once its whole table arrived: the table and
    /// B's probe results.
    pub fn board_b_modules(&self) -> Option<(&[u8], crate::discovery::BoardProbes)> {
        Some((self.b_table.table()?, self.b_probes?))
    }

    /// `Modules` frames whose chunk was refused (length, index).
    pub fn modules_refused(&self) -> u16 {
        self.b_table.refused
    }

    /// Queues a command for B.
    pub fn send(&mut self, cmd: ModuleCmd) {
        // coalesce with the newest queued command of the same kind, unless a barrier
        // lies after it
        for queued in self.queue.iter_mut().rev() {
            if queued.code() == cmd.code() {
                *queued = cmd;
                return;
            }
            if queued.is_barrier() || cmd.is_barrier() {
                break;
            }
        }
        if self.queue.is_full() {
            let _ = self.queue.pop_front();
            self.counters.queue_dropped += 1;
        }
        let _ = self.queue.push_back(cmd);
    }

    /// Nothing queued or waiting for an acknowledgement.
    pub fn idle(&self) -> bool {
        self.queue.is_empty() && self.in_flight.is_none()
    }

    /// Handles received bytes. Returns true if a heartbeat arrived.
    pub fn receive(&mut self, now_ms: u64, rx: &[u8]) -> bool {
        self.start_ms.get_or_insert(now_ms);
        let mut got_hb = false;
        for &b in rx {
            match self.decoder.push(b) {
                None => {}
                Some(Err(_)) => self.counters.frame_errors += 1,
                Some(Ok(Message::Ack { seq })) if self.in_flight.is_some_and(|f| f.seq == seq) => {
                    self.in_flight = None;
                    self.counters.acks += 1;
                    self.failed = false;
                }
                // a late ack of a command already given up or resent: ignored
                Some(Ok(Message::Ack { .. })) => {}
                Some(Ok(Message::Heartbeat { hb, .. })) => {
                    if let Some(prev) = &self.hb {
                        // frames B dropped since its last heartbeat
                        self.counters.frame_errors += hb.rx_errors.wrapping_sub(prev.rx_errors) as u32;
                    }
                    if self.in_flight.is_some_and(|f| f.seq == hb.last_seq) {
                        // B executed the command: its Ack frame was lost
                        self.in_flight = None;
                        self.counters.acks += 1;
                        self.failed = false;
                    }
                    self.hb = Some(hb);
                    self.last_hb_ms = Some(now_ms);
                    self.counters.hb_rx += 1;
                    got_hb = true;
                }
                Some(Ok(Message::Modules { m, .. })) => {
                    // A refused chunk is counted by the assembler.
                    let taken = self.b_table.push(&m.chunk).is_ok();
                    self.b_probes = if taken { Some(m.probes) } else { self.b_probes };
                }
                // B never sends commands: a command frame here is a fault of the line
                Some(Ok(Message::Command { .. })) => self.counters.frame_errors += 1,
            }
        }
        got_hb
    }

    /// Sends, resends or gives up. Frames go to `tx`; if `tx` is full the send is
    /// retried next period.
    pub fn transmit<const N: usize>(
        &mut self,
        now_ms: u64,
        ack_timeout_ms: u32,
        max_retries: u8,
        tx: &mut Vec<u8, N>,
    ) -> Option<GaveUp> {
        self.start_ms.get_or_insert(now_ms);
        let mut gave_up = None;
        if let Some(mut f) = self.in_flight {
            if now_ms.saturating_sub(f.sent_ms) >= ack_timeout_ms as u64 {
                if f.resends >= max_retries {
                    self.counters.ack_missed += 1;
                    self.failed = true;
                    gave_up = Some(GaveUp {
                        command: f.cmd.code(),
                        retries: f.resends,
                    });
                    self.in_flight = None;
                } else {
                    let msg = Message::Command { seq: f.seq, cmd: f.cmd };
                    if msg.encode(tx).is_ok() {
                        f.resends += 1;
                        f.sent_ms = now_ms;
                        self.counters.retries += 1;
                    }
                    self.in_flight = Some(f);
                }
            }
        }
        if self.in_flight.is_none() {
            if let Some(cmd) = self.queue.front().copied() {
                let seq = self.next_seq;
                if (Message::Command { seq, cmd }).encode(tx).is_ok() {
                    let _ = self.queue.pop_front();
                    self.next_seq = self.next_seq.wrapping_add(1).max(1);
                    self.in_flight = Some(InFlight {
                        seq,
                        cmd,
                        sent_ms: now_ms,
                        resends: 0,
                    });
                }
            }
        }
        gave_up
    }

    /// The last heartbeat received.
    pub fn heartbeat(&self) -> Option<&Heartbeat> {
        self.hb.as_ref()
    }
    /// Time since the last heartbeat (since the first poll if none arrived yet).
    pub fn hb_age_ms(&self, now_ms: u64) -> u64 {
        match (self.last_hb_ms, self.start_ms) {
            (Some(t), _) | (None, Some(t)) => now_ms.saturating_sub(t),
            (None, None) => 0,
        }
    }
    /// Heartbeat younger than `timeout_ms` and no command given up since the last ack.
    pub fn link_ok(&self, now_ms: u64, timeout_ms: u64) -> bool {
        self.last_hb_ms.is_some() && self.hb_age_ms(now_ms) <= timeout_ms && !self.failed
    }
    pub fn counters(&self) -> &LinkCounters {
        &self.counters
    }
    /// Drops every queued motion command, keeping `Power` commands (the one in flight
    /// is still resent until acked).
    pub fn clear_motion(&mut self) {
        let n = self.queue.len();
        for _ in 0..n {
            if let Some(c) = self.queue.pop_front() {
                if matches!(c, ModuleCmd::Power { .. }) {
                    let _ = self.queue.push_back(c);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn hb() -> Heartbeat {
        Heartbeat {
            v_bat: 3400,
            i_loc: 120,
            i_grip: 250,
            i_bo: 0,
            arm_target: 1000,
            arm_pwm: 1005,
            grip_target: 1100,
            grip_pwm: 1100,
            grav: [-1000, 3, -7],
            flags: flag::ARM_SWITCH,
            bolter_drive: 1,
            bolter_pair: 2,
            modes: 0b01_01_01,
            last_seq: 9,
            rx_errors: 4,
        }
    }

    fn decode_all(bytes: &[u8]) -> std::vec::Vec<Result<Message, FrameError>> {
        let mut d = FrameDecoder::new();
        bytes.iter().filter_map(|&b| d.push(b)).collect()
    }

    // verifies: MMIC-AB-02
    #[test]
    fn ab_frames_round_trip_for_every_message() {
        let msgs = [
            Message::Command {
                seq: 1,
                cmd: ModuleCmd::ArmTarget(2000),
            },
            Message::Command {
                seq: 2,
                cmd: ModuleCmd::GripTarget(1900),
            },
            Message::Command {
                seq: 3,
                cmd: ModuleCmd::Bolter {
                    drive: BolterDrive::RotateLock,
                    pair: 4,
                },
            },
            Message::Command {
                seq: 4,
                cmd: ModuleCmd::Power {
                    arm: 1,
                    grip: 2,
                    bolter: 0,
                },
            },
            Message::Command {
                seq: 0,
                cmd: ModuleCmd::Stop,
            },
            Message::Ack { seq: 200 },
            Message::Heartbeat { seq: 7, hb: hb() },
        ];
        let mut wire: Vec<u8, 512> = Vec::new();
        for m in &msgs {
            m.encode(&mut wire).unwrap();
        }
        let got = decode_all(&wire);
        assert_eq!(got.len(), msgs.len());
        for (g, m) in got.iter().zip(msgs.iter()) {
            assert_eq!(g.as_ref().unwrap(), m);
        }
    }

    // verifies: MMIC-AB-04
    #[test]
    fn ab_frame_layout_is_cobs_of_payload_and_crc() {
        let mut wire: Vec<u8, 64> = Vec::new();
        Message::Ack { seq: 5 }.encode(&mut wire).unwrap();
        // payload 81 05 + CRC-16/CCITT-FALSE(81 05), COBS with no zeros: 05 81 05 c1 c2
        let crc = CRC16.checksum(&[0x81, 0x05]).to_be_bytes();
        assert_eq!(wire.as_slice(), &[0, 5, 0x81, 0x05, crc[0], crc[1], 0]);
        // the catalogue check value of CRC-16/CCITT-FALSE
        assert_eq!(CRC16.checksum(b"123456789"), 0x29B1);
    }

    // verifies: MMIC-AB-04
    #[test]
    fn ab_decoder_reports_crc_errors_and_recovers() {
        let mut wire: Vec<u8, 128> = Vec::new();
        Message::Command {
            seq: 9,
            cmd: ModuleCmd::ArmTarget(1500),
        }
        .encode(&mut wire)
        .unwrap();
        let mut bad = wire.clone();
        bad[3] ^= 0x10;
        let mut stream = std::vec::Vec::new();
        stream.extend_from_slice(&[1, 2, 3]); // noise before
        stream.extend_from_slice(&bad);
        stream.extend_from_slice(&wire);
        let got = decode_all(&stream);
        assert!(got
            .iter()
            .any(|r| matches!(r, Err(FrameError::Crc { .. }) | Err(FrameError::Cobs))));
        assert_eq!(
            got.last().unwrap().as_ref().unwrap(),
            &Message::Command {
                seq: 9,
                cmd: ModuleCmd::ArmTarget(1500)
            }
        );
    }

    // verifies: MMIC-AB-04
    #[test]
    fn ab_decoder_drops_overlong_frames() {
        // A well-formed COBS frame of 300 bytes (longer than LINK_MAX_FRAME decoded), then
        // 300 bytes of junk cut by a delimiter (a broken COBS block), then a good frame.
        let mut big = [0u8; mmic_stream::encoded_len(300)];
        let n = mmic_stream::encode(&[0x55; 300], &mut big).unwrap();
        let mut stream = big[..n].to_vec();
        stream.extend_from_slice(&[0x55u8; 300]);
        stream.push(0);
        let mut wire: Vec<u8, 64> = Vec::new();
        Message::Ack { seq: 1 }.encode(&mut wire).unwrap();
        stream.extend_from_slice(&wire);
        let got = decode_all(&stream);
        assert_eq!(
            got,
            [
                Err(FrameError::Overflow),
                Err(FrameError::Cobs),
                Ok(Message::Ack { seq: 1 })
            ]
        );
    }

    // verifies: MMIC-AB-04
    #[test]
    fn ab_decoder_counts_an_empty_frame_but_not_lone_delimiters() {
        let mut wire: Vec<u8, 64> = Vec::new();
        Message::Ack { seq: 3 }.encode(&mut wire).unwrap();
        let mut stream = std::vec![0u8, 0, 0x01, 0, 0];
        stream.extend_from_slice(&wire);
        let got = decode_all(&stream);
        assert_eq!(got, [Err(FrameError::TooShort), Ok(Message::Ack { seq: 3 })]);
        let mut d = FrameDecoder::new();
        stream.iter().for_each(|&b| {
            let _ = d.push(b);
        });
        assert_eq!(d.stream_counters().frames, 1);
        assert_eq!(d.stream_counters().garbage_bytes, 1);
    }

    /// Simulated loop-back: B acks every command it receives, unless `drop` says the
    /// frame is lost (either direction).
    fn exchange(lm: &mut LinkManager, now: u64, lose: bool) -> Option<GaveUp> {
        let mut tx: Vec<u8, 128> = Vec::new();
        let g = lm.transmit(now, 60, 3, &mut tx);
        if !lose {
            let msgs = decode_all(&tx);
            let mut back: Vec<u8, 128> = Vec::new();
            for m in msgs.into_iter().flatten() {
                if let Message::Command { seq, .. } = m {
                    Message::Ack { seq }.encode(&mut back).unwrap();
                }
            }
            lm.receive(now + 5, &back);
        }
        g
    }

    // verifies: MMIC-AB-03
    #[test]
    fn ab_link_resends_after_ack_timeout_and_counts_retries() {
        let mut lm = LinkManager::new();
        lm.send(ModuleCmd::ArmTarget(1200));
        // first two transmissions lost, third one acknowledged
        let mut t = 0;
        for lose in [true, true, false] {
            assert!(exchange(&mut lm, t, lose).is_none());
            t += 60;
        }
        assert!(lm.idle());
        assert_eq!(lm.counters().retries, 2);
        assert_eq!(lm.counters().acks, 1);
        assert_eq!(lm.counters().ack_missed, 0);
    }

    // verifies: MMIC-FLT-11
    #[test]
    fn ab_link_detects_no_ack_after_max_retries() {
        let mut lm = LinkManager::new();
        lm.send(ModuleCmd::GripTarget(1900));
        let mut gave_up = None;
        let mut t = 0;
        for _ in 0..40 {
            if let Some(g) = exchange(&mut lm, t, true) {
                gave_up = Some(g);
                break;
            }
            t += 10;
        }
        assert_eq!(gave_up, Some(GaveUp { command: 2, retries: 3 }));
        assert_eq!(lm.counters().ack_missed, 1);
        assert_eq!(lm.counters().retries, 3);
        assert!(!lm.link_ok(t, 500));
        // 1 send + 3 resends, 60 ms apart
        assert!((4 * 60..5 * 60).contains(&t), "gave up at {t} ms");
    }

    // verifies: MMIC-AB-07
    #[test]
    fn ab_link_coalesces_queued_commands_but_not_across_barriers() {
        let mut lm = LinkManager::new();
        lm.send(ModuleCmd::ArmTarget(1000)); // goes in flight at the first transmit
        let mut tx: Vec<u8, 128> = Vec::new();
        lm.transmit(0, 60, 3, &mut tx);
        lm.send(ModuleCmd::ArmTarget(1100));
        lm.send(ModuleCmd::ArmTarget(1200)); // replaces 1100
        lm.send(ModuleCmd::Stop);
        lm.send(ModuleCmd::ArmTarget(1300)); // must not replace 1200 (Stop between)
        let q: std::vec::Vec<_> = lm.queue.iter().copied().collect();
        assert_eq!(
            q,
            [ModuleCmd::ArmTarget(1200), ModuleCmd::Stop, ModuleCmd::ArmTarget(1300)]
        );
        for i in 0..20 {
            lm.send(ModuleCmd::GripTarget(1000 + i));
        }
        assert!(lm.queue.len() <= LINK_QUEUE_DEPTH);
        assert_eq!(lm.counters().queue_dropped, 0);
    }

    // verifies: MMIC-AB-03
    #[test]
    fn ab_link_heartbeat_acknowledges_when_the_ack_frame_is_lost_and_reports_b_rx_errors() {
        let mut lm = LinkManager::new();
        lm.send(ModuleCmd::ArmTarget(1300));
        let mut tx: Vec<u8, 128> = Vec::new();
        lm.transmit(0, 60, 3, &mut tx);
        assert!(!lm.idle());
        let mut wire: Vec<u8, 64> = Vec::new();
        let mut h = hb();
        h.last_seq = 1; // the command's sequence number
        h.rx_errors = 250;
        Message::Heartbeat { seq: 0, hb: h }.encode(&mut wire).unwrap();
        lm.receive(20, &wire);
        assert!(lm.idle(), "acknowledged by the heartbeat");
        assert_eq!(lm.counters().acks, 1);
        // B's error counter wraps: 250 -> 3 is 9 more errors
        let mut wire: Vec<u8, 64> = Vec::new();
        h.rx_errors = 3;
        Message::Heartbeat { seq: 1, hb: h }.encode(&mut wire).unwrap();
        lm.receive(70, &wire);
        assert_eq!(lm.counters().frame_errors, 9);
    }

    // verifies: MMIC-AB-02
    #[test]
    fn ab_link_heartbeat_age_and_counters() {
        let mut lm = LinkManager::new();
        assert_eq!(lm.hb_age_ms(0), 0);
        lm.receive(100, &[]);
        assert_eq!(lm.hb_age_ms(350), 250);
        let mut wire: Vec<u8, 64> = Vec::new();
        Message::Heartbeat { seq: 1, hb: hb() }.encode(&mut wire).unwrap();
        assert!(lm.receive(400, &wire));
        assert_eq!(lm.hb_age_ms(450), 50);
        assert_eq!(lm.counters().hb_rx, 1);
        assert_eq!(lm.heartbeat().unwrap().i_loc, 120);
        assert!(lm.link_ok(450, 500));
        assert!(!lm.link_ok(1000, 500));
        lm.receive(500, &[7, 7, 7, 0]);
        assert_eq!(lm.counters().frame_errors, 1);
    }

    proptest! {
        // verifies: MMIC-AB-04
        #[test]
        fn ab_decoding_garbage_never_panics(bytes in proptest::collection::vec(any::<u8>(), 0..600)) {
            let mut d = FrameDecoder::new();
            for b in &bytes {
                let _ = d.push(*b);
            }
            let _ = Message::parse(&bytes);
            let mut lm = LinkManager::new();
            lm.receive(0, &bytes);
        }

        // verifies: MMIC-AB-04
        #[test]
        fn ab_corrupted_frames_are_never_accepted_as_different_messages(
            arm in 900u16..2100, seq: u8, pos in 0usize..16, bit in 0u8..8
        ) {
            let m = Message::Command { seq, cmd: ModuleCmd::ArmTarget(arm) };
            let mut wire: Vec<u8, 64> = Vec::new();
            m.encode(&mut wire).unwrap();
            let i = pos % wire.len();
            wire[i] ^= 1 << bit;
            // a single bit flip is either detected or (if it hit a delimiter and split
            // the frame) yields errors, never a different valid command
            for got in decode_all(&wire).into_iter().flatten() {
                prop_assert_eq!(got, m);
            }
        }
    }
}
