//! Board B: the subordinate. It moves side B's modules when A tells it to, acknowledges
//! every command, and sends A a heartbeat every `mib::config::B_HEARTBEAT_PERIOD_MS`
//! with its moving-averaged sensors, module targets and PWM, gravity vector, overcurrent
//! flags, bolter sync state and arm switch. Runs on its own schedule: `tick` may be
//! called at any period.

use crate::ablink::{flag, FrameDecoder, Heartbeat, Message, ModuleCmd, ModulesChunk};
use crate::consts::LINK_TX_CAP;
use crate::control::Interpolator;
use crate::discovery::{BoardProbes, TableAssembler};
use crate::filter::{to_i16, to_u16, Ma};
use crate::types::{mux_bits, BolterDrive, SensorsB, SideActuators};
use heapless::Vec;
use mib::config::B_HEARTBEAT_PERIOD_MS;
use mib::modes::module_mode::{HOLD, OFF, ON};
use mib::modules::descriptor::{TABLE_HEADER_LEN, TABLE_MAGIC};
use mib::modules::DESCRIPTOR_LEN;
use mib::params::{CAL_AMP, I_BO_MAX, I_GRIP_MAX, I_LOC_MAX};
use mib::robot::servo;

/// What board B drives after a tick, and the bytes it sends to A.
#[derive(Clone, Debug, Default)]
pub struct BoardBOut {
    pub side: SideActuators,
    /// Bolter multiplexer bits.
    pub mux: u8,
    pub tx: Vec<u8, LINK_TX_CAP>,
}

/// Counters of board B (diagnostics).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct BoardBCounters {
    pub commands: u32,
    pub duplicates: u32,
    pub frame_errors: u32,
    pub heartbeats: u32,
    pub tx_overflow: u32,
}

/// Board B's firmware logic.
#[derive(Clone, Debug)]
pub struct BoardB {
    arm: Interpolator,
    grip: Interpolator,
    arm_mode: u32,
    grip_mode: u32,
    bolter_mode: u32,
    bolter_drive: BolterDrive,
    bolter_pair: u8,
    decoder: FrameDecoder,
    f_v_bat: Ma,
    f_i_loc: Ma,
    f_i_grip: Ma,
    f_i_bo: Ma,
    f_grav: [Ma; 3],
    arm_switch: bool,
    last_seq: Option<u8>,
    next_hb_ms: Option<u64>,
    hb_seq: u8,
    last_tick: Option<u64>,
    counters: BoardBCounters,
    /// Module discovery (docs/modules.md): B's descriptor table (flash copy) and probe results.
    modules: Option<BoardModules>,
}

/// Board B's half of module discovery, sent to A one table entry per period.
#[derive(Clone, Debug)]
struct BoardModules {
    table: Vec<u8, { mib::modules::descriptor::MAX_TABLE_LEN }>,
    probes: BoardProbes,
    /// Entries sent so far.
    sent: u16,
}

/// Passes over B's table it sends after boot (repeats cover frames lost on the line).
pub const MODULE_TABLE_PASSES: u16 = 3;

impl Default for BoardB {
    fn default() -> Self {
        Self::new()
    }
}

impl BoardB {
    /// Board B at boot: modules unpowered, interpolators at the home position
    /// (arm contracted, gripper closed).
    pub fn new() -> Self {
        BoardB {
            arm: Interpolator::servo(servo::ARM_CONTRACTED_US),
            grip: Interpolator::servo(servo::GRIP_CLOSED_US),
            arm_mode: OFF,
            grip_mode: OFF,
            bolter_mode: OFF,
            bolter_drive: BolterDrive::Off,
            bolter_pair: 0,
            decoder: FrameDecoder::new(),
            f_v_bat: Ma::new(),
            f_i_loc: Ma::new(),
            f_i_grip: Ma::new(),
            f_i_bo: Ma::new(),
            f_grav: [Ma::new(), Ma::new(), Ma::new()],
            arm_switch: false,
            last_seq: None,
            next_hb_ms: None,
            hb_seq: 0,
            last_tick: None,
            counters: BoardBCounters::default(),
            modules: None,
        }
    }

    /// Gives board B its descriptor table (as read from its flash) and probe results:
    /// from its next tick it sends A one `Modules` frame per period, entry by entry,
    /// [`MODULE_TABLE_PASSES`] times. A table whose header is unreadable (magic,
    /// count, length) cannot be split into entries and is not sent (A then finds
    /// board B silent). Longer than a table can be: ignored likewise.
    pub fn set_modules(&mut self, table: &[u8], probes: BoardProbes) {
        self.modules = Vec::from_slice(table)
            .ok()
            .map(|table| BoardModules { table, probes, sent: 0 });
    }

    /// The next `Modules` frame due, if any.
    fn modules_chunk(&self) -> Option<ModulesChunk> {
        let m = self.modules.as_ref()?;
        let t = &m.table;
        if t.len() < TABLE_HEADER_LEN || t[0..2] != TABLE_MAGIC {
            return None;
        }
        let count = t[3];
        if count == 0 || t.len() != TABLE_HEADER_LEN + count as usize * DESCRIPTOR_LEN {
            return None;
        }
        if m.sent >= MODULE_TABLE_PASSES * count as u16 {
            return None;
        }
        let index = (m.sent % count as u16) as u8;
        let at = TABLE_HEADER_LEN + index as usize * DESCRIPTOR_LEN;
        let desc: &[u8; DESCRIPTOR_LEN] = t.get(at..at + DESCRIPTOR_LEN)?.try_into().ok()?;
        Some(ModulesChunk {
            probes: m.probes,
            chunk: TableAssembler::chunk(index, count, desc),
        })
    }

    /// Board B whose arm and gripper are known to be at the given pulse widths.
    pub fn with_positions(arm_us: u16, grip_us: u16) -> Self {
        let mut b = Self::new();
        b.arm.reset_to(arm_us);
        b.grip.reset_to(grip_us);
        b
    }

    pub fn counters(&self) -> &BoardBCounters {
        &self.counters
    }

    fn execute(&mut self, cmd: ModuleCmd) {
        match cmd {
            ModuleCmd::ArmTarget(v) => {
                if self.arm_mode != OFF {
                    self.arm.set_target(v);
                }
            }
            ModuleCmd::GripTarget(v) => {
                if self.grip_mode != OFF {
                    self.grip.set_target(v);
                }
            }
            ModuleCmd::Bolter { drive, pair } => {
                if self.bolter_mode == ON {
                    self.bolter_drive = drive;
                    self.bolter_pair = pair;
                } else {
                    self.bolter_drive = BolterDrive::Off;
                }
            }
            ModuleCmd::Power { arm, grip, bolter } => {
                let (arm, grip, bolter) = (arm as u32, grip as u32, bolter as u32);
                // hold only on entering HOLD/OFF: a repeated Power must not cancel a
                // move commanded since (single-module moves are allowed in HOLD)
                if arm != self.arm_mode && (arm == HOLD || arm == OFF) {
                    self.arm.hold();
                }
                if grip != self.grip_mode && (grip == HOLD || grip == OFF) {
                    self.grip.hold();
                }
                if bolter != ON {
                    self.bolter_drive = BolterDrive::Off;
                }
                self.arm_mode = arm;
                self.grip_mode = grip;
                self.bolter_mode = bolter;
            }
            ModuleCmd::Stop => {
                self.arm.hold();
                self.grip.hold();
                self.bolter_drive = BolterDrive::Off;
            }
            ModuleCmd::Assume { arm, grip } => {
                if self.arm_mode == OFF {
                    self.arm.reset_to(arm);
                }
                if self.grip_mode == OFF {
                    self.grip.reset_to(grip);
                }
            }
            ModuleCmd::SendModules => {
                if let Some(m) = self.modules.as_mut() {
                    m.sent = 0;
                }
            }
        }
    }

    fn heartbeat(&self) -> Heartbeat {
        let i_loc = to_u16(self.f_i_loc.value());
        let i_grip = to_u16(self.f_i_grip.value());
        let i_bo = to_u16(self.f_i_bo.value());
        let raw = |a: f64| CAL_AMP.raw(a) as u16;
        let mut flags = 0;
        if i_loc > raw(I_LOC_MAX) {
            flags |= flag::OC_LOC;
        }
        if i_grip > raw(I_GRIP_MAX) {
            flags |= flag::OC_GRIP;
        }
        if i_bo > raw(I_BO_MAX) {
            flags |= flag::OC_BO;
        }
        if self.arm_switch {
            flags |= flag::ARM_SWITCH;
        }
        Heartbeat {
            v_bat: to_u16(self.f_v_bat.value()),
            i_loc,
            i_grip,
            i_bo,
            arm_target: self.arm.target(),
            arm_pwm: self.arm.current(),
            grip_target: self.grip.target(),
            grip_pwm: self.grip.current(),
            grav: [
                to_i16(self.f_grav[0].value()),
                to_i16(self.f_grav[1].value()),
                to_i16(self.f_grav[2].value()),
            ],
            flags,
            bolter_drive: self.bolter_drive.code(),
            bolter_pair: self.bolter_pair,
            modes: (self.arm_mode as u8 & 3) | ((self.grip_mode as u8 & 3) << 2) | ((self.bolter_mode as u8 & 3) << 4),
            last_seq: self.last_seq.unwrap_or(0),
            rx_errors: self.counters.frame_errors as u8,
        }
    }

    /// One period of board B: sample sensors, execute received commands (ack each),
    /// interpolate, send the heartbeat when due.
    pub fn tick(&mut self, now_ms: u64, sensors: &SensorsB, rx: &[u8], out: &mut BoardBOut) {
        out.tx.clear();
        let dt = match self.last_tick {
            Some(t) => now_ms.saturating_sub(t).min(1000) as u32,
            None => 0,
        };
        self.last_tick = Some(now_ms);
        self.f_v_bat.push(sensors.v_bat as i32);
        self.f_i_loc.push(sensors.i_loc as i32);
        self.f_i_grip.push(sensors.i_grip as i32);
        self.f_i_bo.push(sensors.i_bo as i32);
        for (f, &g) in self.f_grav.iter_mut().zip(sensors.grav.iter()) {
            f.push(g as i32);
        }
        self.arm_switch = sensors.arm_switch;

        for &b in rx {
            match self.decoder.push(b) {
                None => {}
                Some(Ok(Message::Command { seq, cmd })) => {
                    if self.last_seq == Some(seq) {
                        // A resent a command whose ack was lost: ack again, do not redo
                        self.counters.duplicates += 1;
                    } else {
                        self.execute(cmd);
                        self.counters.commands += 1;
                        self.last_seq = Some(seq);
                    }
                    if (Message::Ack { seq }).encode(&mut out.tx).is_err() {
                        self.counters.tx_overflow += 1;
                    }
                }
                Some(Ok(_)) | Some(Err(_)) => self.counters.frame_errors += 1,
            }
        }

        if self.arm_mode != OFF {
            self.arm.tick(dt);
        }
        if self.grip_mode != OFF {
            self.grip.tick(dt);
        }

        let due = *self.next_hb_ms.get_or_insert(now_ms);
        if now_ms >= due {
            let hb = self.heartbeat();
            let seq = self.hb_seq;
            self.hb_seq = self.hb_seq.wrapping_add(1);
            if (Message::Heartbeat { seq, hb }).encode(&mut out.tx).is_ok() {
                self.counters.heartbeats += 1;
            } else {
                self.counters.tx_overflow += 1;
            }
            let period = B_HEARTBEAT_PERIOD_MS as u64;
            let mut next = due + period;
            if next <= now_ms {
                next = now_ms + period;
            }
            self.next_hb_ms = Some(next);
        }

        if let Some(m) = self.modules_chunk() {
            if (Message::Modules { seq: 0, m }).encode(&mut out.tx).is_ok() {
                if let Some(bm) = self.modules.as_mut() {
                    bm.sent += 1;
                }
            } else {
                // Retried next period.
                self.counters.tx_overflow += 1;
            }
        }

        out.side = SideActuators {
            arm_pwm: (self.arm_mode != OFF).then(|| self.arm.current()),
            grip_pwm: (self.grip_mode != OFF).then(|| self.grip.current()),
            bolter: if self.bolter_mode == ON {
                self.bolter_drive
            } else {
                BolterDrive::Off
            },
        };
        out.mux = mux_bits(self.bolter_pair);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cmd(seq: u8, c: ModuleCmd) -> Vec<u8, 64> {
        let mut v = Vec::new();
        Message::Command { seq, cmd: c }.encode(&mut v).unwrap();
        v
    }
    fn msgs(bytes: &[u8]) -> std::vec::Vec<Message> {
        let mut d = FrameDecoder::new();
        bytes.iter().filter_map(|&b| d.push(b)).map(|r| r.unwrap()).collect()
    }

    // verifies: MMIC-AB-01
    #[test]
    fn board_b_acks_every_command_executes_once_and_heartbeats_periodically() {
        let mut b = BoardB::new();
        let mut out = BoardBOut::default();
        let s = SensorsB {
            v_bat: 3300,
            grav: [-1000, 0, 0],
            arm_switch: true,
            ..Default::default()
        };
        b.tick(0, &s, &[], &mut out);
        assert!(matches!(msgs(&out.tx)[..], [Message::Heartbeat { .. }]));
        assert_eq!(out.side.arm_pwm, None, "unpowered at boot");
        b.tick(
            10,
            &s,
            &cmd(
                1,
                ModuleCmd::Power {
                    arm: 1,
                    grip: 1,
                    bolter: 1,
                },
            ),
            &mut out,
        );
        assert_eq!(msgs(&out.tx), [Message::Ack { seq: 1 }]);
        b.tick(20, &s, &cmd(2, ModuleCmd::ArmTarget(1100)), &mut out);
        assert_eq!(msgs(&out.tx), [Message::Ack { seq: 2 }]);
        // the same command again (lost ack): acked, not executed twice
        b.tick(30, &s, &cmd(2, ModuleCmd::ArmTarget(1100)), &mut out);
        assert_eq!(msgs(&out.tx), [Message::Ack { seq: 2 }]);
        assert_eq!(b.counters().duplicates, 1);
        assert_eq!(out.side.arm_pwm, Some(1010));
        let mut hbs = 0;
        let mut last = None;
        for t in (40..=1040).step_by(10) {
            b.tick(t, &s, &[], &mut out);
            for m in msgs(&out.tx) {
                if let Message::Heartbeat { hb, .. } = m {
                    hbs += 1;
                    last = Some(hb);
                }
            }
        }
        assert_eq!(hbs, 20, "one heartbeat per 50 ms");
        let hb = last.unwrap();
        assert_eq!(hb.arm_target, 1100);
        assert_eq!(hb.arm_pwm, 1100);
        assert!(hb.arm_switch());
        assert_eq!(hb.v_bat, 3300);
        assert_eq!(hb.grav, [-1000, 0, 0]);
        assert_eq!(hb.last_seq, 2);
    }

    // verifies: MMIC-AB-05
    #[test]
    fn board_b_flags_overcurrent_from_filtered_currents() {
        let mut b = BoardB::new();
        let mut out = BoardBOut::default();
        let s = SensorsB {
            i_loc: 3500,
            i_bo: 100,
            ..Default::default()
        };
        let mut last = None;
        for t in (0..600).step_by(10) {
            b.tick(t, &s, &[], &mut out);
            for m in msgs(&out.tx) {
                if let Message::Heartbeat { hb, .. } = m {
                    last = Some(hb);
                }
            }
        }
        let hb = last.unwrap();
        assert_ne!(hb.flags & flag::OC_LOC, 0);
        assert_eq!(hb.flags & flag::OC_BO, 0);
    }

    // verifies: MMIC-AB-01
    #[test]
    fn board_b_repeated_power_command_does_not_cancel_a_move() {
        let mut b = BoardB::new();
        let mut out = BoardBOut::default();
        let s = SensorsB::default();
        b.tick(
            0,
            &s,
            &cmd(
                1,
                ModuleCmd::Power {
                    arm: 2,
                    grip: 2,
                    bolter: 0,
                },
            ),
            &mut out,
        );
        b.tick(10, &s, &cmd(2, ModuleCmd::ArmTarget(1500)), &mut out);
        b.tick(
            20,
            &s,
            &cmd(
                3,
                ModuleCmd::Power {
                    arm: 2,
                    grip: 2,
                    bolter: 0,
                },
            ),
            &mut out,
        );
        for t in (30..2000).step_by(10) {
            b.tick(t, &s, &[], &mut out);
        }
        assert_eq!(out.side.arm_pwm, Some(1500), "HOLD accepts an explicit move");
        // entering HOLD from ON does stop a move
        b.tick(
            2000,
            &s,
            &cmd(
                4,
                ModuleCmd::Power {
                    arm: 1,
                    grip: 1,
                    bolter: 0,
                },
            ),
            &mut out,
        );
        b.tick(2010, &s, &cmd(5, ModuleCmd::ArmTarget(1000)), &mut out);
        b.tick(
            2020,
            &s,
            &cmd(
                6,
                ModuleCmd::Power {
                    arm: 2,
                    grip: 2,
                    bolter: 0,
                },
            ),
            &mut out,
        );
        for t in (2030..3000).step_by(10) {
            b.tick(t, &s, &[], &mut out);
        }
        let held = out.side.arm_pwm.unwrap();
        assert!(held > 1480 && held < 1500, "{held}");
    }

    // verifies: MMIC-AB-06
    #[test]
    fn board_b_hold_and_off_refuse_motion_and_bolter_needs_on() {
        let mut b = BoardB::new();
        let mut out = BoardBOut::default();
        let s = SensorsB::default();
        b.tick(
            0,
            &s,
            &cmd(
                1,
                ModuleCmd::Power {
                    arm: 0,
                    grip: 2,
                    bolter: 2,
                },
            ),
            &mut out,
        );
        b.tick(10, &s, &cmd(2, ModuleCmd::ArmTarget(2000)), &mut out);
        b.tick(
            20,
            &s,
            &cmd(
                3,
                ModuleCmd::Bolter {
                    drive: BolterDrive::Descend,
                    pair: 1,
                },
            ),
            &mut out,
        );
        assert_eq!(out.side.arm_pwm, None);
        assert_eq!(out.side.grip_pwm, Some(servo::GRIP_CLOSED_US));
        assert_eq!(out.side.bolter, BolterDrive::Off);
    }

    // verifies: MOD-OBSW-07
    #[test]
    fn board_b_sends_its_descriptor_table_and_probes_and_a_rebuilds_them() {
        use crate::ablink::LinkManager;
        use crate::discovery::ArmSwitch;
        use mib::modules::descriptor::{emit_table, MAX_TABLE_LEN};
        use mib::modules::{default_set, Board, SLOTS};
        let set = default_set(1000);
        let descs: std::vec::Vec<_> = set
            .iter()
            .enumerate()
            .filter(|(i, _)| SLOTS[*i].board == Board::B)
            .filter_map(|(_, d)| *d)
            .collect();
        let mut table = [0u8; MAX_TABLE_LEN];
        let n = emit_table(&descs, &mut table).unwrap();
        let probes = BoardProbes {
            imu_who_am_i: Some(0x68),
            adc_ack: true,
            encoder_ack: false,
            arm_switch: ArmSwitch::Pushed,
        };
        let mut b = BoardB::new();
        b.set_modules(&table[..n], probes);
        let mut a = LinkManager::new();
        let mut out = BoardBOut::default();
        let s = SensorsB::default();
        let mut frames = 0;
        for t in 0..100u64 {
            b.tick(t * 10, &s, &[], &mut out);
            frames += msgs(&out.tx)
                .iter()
                .filter(|m| matches!(m, Message::Modules { .. }))
                .count();
            a.receive(t * 10, &out.tx);
            if t + 1 == descs.len() as u64 {
                assert_eq!(a.board_b_modules(), Some((&table[..n], probes)), "one entry per period");
            }
        }
        assert_eq!(frames, descs.len() * MODULE_TABLE_PASSES as usize, "then it stops");
        assert_eq!(a.modules_refused(), 0);
        // A corrupted entry travels as it is (discovery reports its CRC), an unreadable
        // header is not sent.
        let mut bad = table;
        bad[TABLE_HEADER_LEN + 3] ^= 0x10;
        let mut b = BoardB::new();
        b.set_modules(&bad[..n], probes);
        let mut a = LinkManager::new();
        for t in 0..10u64 {
            b.tick(t * 10, &s, &[], &mut out);
            a.receive(t * 10, &out.tx);
        }
        assert_eq!(a.board_b_modules().map(|(t, _)| t.to_vec()), Some(bad[..n].to_vec()));
        bad[0] = b'X';
        let mut b = BoardB::new();
        b.set_modules(&bad[..n], probes);
        b.tick(0, &s, &[], &mut out);
        assert!(!msgs(&out.tx).iter().any(|m| matches!(m, Message::Modules { .. })));
    }

    // verifies: MOD-OBSW-07
    #[test]
    fn modules_frames_round_trip_and_bad_probe_bits_are_refused() {
        use crate::ablink::ModulesChunk;
        use crate::discovery::ArmSwitch;
        for sw in [ArmSwitch::Absent, ArmSwitch::Pushed, ArmSwitch::Released] {
            for (imu, adc) in [(None, false), (Some(0x68), true), (Some(0x12), false)] {
                let m = ModulesChunk {
                    probes: BoardProbes {
                        imu_who_am_i: imu,
                        adc_ack: adc,
                        encoder_ack: adc,
                        arm_switch: sw,
                    },
                    chunk: [7; crate::discovery::CHUNK_LEN],
                };
                let mut v: Vec<u8, 64> = Vec::new();
                Message::Modules { seq: 3, m }.encode(&mut v).unwrap();
                assert_eq!(msgs(&v), [Message::Modules { seq: 3, m }]);
            }
        }
        // Arm-switch code 3 is not a state.
        let mut payload = std::vec![crate::ablink::KIND_MODULES, 0, 0x68, 0x31];
        payload.extend_from_slice(&[0; crate::discovery::CHUNK_LEN]);
        let crc = crate::ablink::CRC16.checksum(&payload);
        payload.extend_from_slice(&crc.to_be_bytes());
        assert_eq!(Message::parse(&payload), Err(crate::ablink::FrameError::BadValue));
    }
}
