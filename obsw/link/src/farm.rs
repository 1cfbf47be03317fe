//! FARM-1, the on-board frame acceptance and reporting mechanism of COP-1 (CCSDS 232.1-B-2
//! §6, state table 6-1). A pure state machine: [`Farm::on_event`] takes a validated frame (or
//! a buffer release) and returns what to do with it; [`Farm::clcw`] reports the state.
//! No timers, so no time input.
//!
//! Windows (W = `mib::link::cop1::FARM_WINDOW_WIDTH`, PW = NW = W/2), with
//! d = N(S) − V(R) mod 256:
//! - d = 0: in sequence (E1 accept if buffer space, E2 otherwise);
//! - 1 ≤ d ≤ PW − 1: positive window, a gap (E3, retransmit flag set);
//! - 256 − NW ≤ d ≤ 255: negative window, an old frame (E4, discarded silently);
//! - anything else: lockout area (E5).

use crate::clcw::{Clcw, CopInEffect};
use crate::tc::ControlCommand;

/// FARM-1 states.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FarmState {
    /// S1.
    Open,
    /// S2: no buffer space; the ground must wait.
    Wait,
    /// S3: a frame fell outside both windows; only Unlock leaves it.
    Lockout,
}

/// What the FARM was given: a frame that passed every lower check (CRC, lengths, SDLS), or
/// the release of the back-end buffer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FarmInput {
    /// A type-AD frame with sequence number N(S). `buffer_available`: the host can take its
    /// packets now.
    Ad { ns: u8, buffer_available: bool },
    /// A type-BD frame (accepted in every state).
    Bd,
    /// A type-BC frame with a recognised control command.
    Bc(ControlCommand),
    /// An invalid frame (E9: discarded, no state change). The receiver counts why.
    Invalid,
    /// The back-end buffer has space again (E10).
    BufferRelease,
}

/// The standard's event that `on_event` recognised.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FarmEvent {
    E1,
    E2,
    E3,
    E4,
    E5,
    E6,
    E7,
    E8,
    E9,
    E10,
}

/// What happens to the frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FarmAction {
    /// Deliver the frame's data (AD or BD frame).
    Accept,
    /// Drop the frame (counted by the receiver under the event).
    Discard,
    /// A control command was executed / a buffer release noted; nothing to deliver.
    Done,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FarmEffect {
    pub event: FarmEvent,
    pub action: FarmAction,
}

/// The part of FARM-1 that survives a restart: written with the receive IV of every
/// authentic frame (one durable write, `IvStore::record_rx_farm`) and after every control
/// frame (`IvStore::record_farm`), before the frame has any other effect.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FarmRecord {
    /// V(R), the next expected N(S).
    pub vr: u8,
    /// The lockout flag (Lockout state).
    pub lockout: bool,
    /// The full FARM-B counter.
    pub farm_b: u8,
}

/// FARM-1 for one virtual channel.
#[derive(Clone, Debug)]
pub struct Farm {
    state: FarmState,
    vr: u8,
    lockout: bool,
    wait: bool,
    retransmit: bool,
    farm_b: u8,
    pw: u8,
    nw: u8,
    vcid: u8,
}

impl Farm {
    /// A FARM in Open with V(R) = 0. `window` is W (even, 2..=254; clamped and rounded).
    pub fn new(vcid: u8, window: u8) -> Farm {
        let w = window.clamp(2, 254) & !1;
        Farm {
            state: FarmState::Open,
            vr: 0,
            lockout: false,
            wait: false,
            retransmit: false,
            farm_b: 0,
            pw: w / 2,
            nw: w / 2,
            vcid,
        }
    }

    /// The mission's FARM for the command VC.
    pub fn mission() -> Farm {
        Farm::new(mib::link::tc_vc::COMMAND, mib::link::cop1::FARM_WINDOW_WIDTH)
    }

    pub fn state(&self) -> FarmState {
        self.state
    }

    /// V(R), the next expected N(S).
    pub fn vr(&self) -> u8 {
        self.vr
    }

    /// The full FARM-B counter (the CLCW carries its two low bits).
    pub fn farm_b_counter(&self) -> u8 {
        self.farm_b
    }

    /// What is persisted of this FARM (see [`FarmRecord`]).
    pub fn record(&self) -> FarmRecord {
        FarmRecord {
            vr: self.vr,
            lockout: self.lockout,
            farm_b: self.farm_b,
        }
    }

    /// A FARM resuming from a persisted record after a restart: V(R), the lockout flag and
    /// the FARM-B counter as stored; Lockout when the lockout flag was set (only Unlock
    /// leaves it, as before the restart), Open otherwise. The wait flag starts clear (the
    /// back-end buffer is empty after a restart) and so does the retransmit flag (frames
    /// lost in the restart are retransmitted by the ground's T1; a set flag with nothing
    /// outstanding would be an inconsistent CLCW for its FOP-1).
    pub fn restore(vcid: u8, window: u8, rec: FarmRecord) -> Farm {
        let mut f = Farm::new(vcid, window);
        f.vr = rec.vr;
        f.farm_b = rec.farm_b;
        f.lockout = rec.lockout;
        f.state = if rec.lockout {
            FarmState::Lockout
        } else {
            FarmState::Open
        };
        f
    }

    /// The mission's FARM resuming from `rec` ([`Farm::restore`]).
    pub fn mission_restored(rec: FarmRecord) -> Farm {
        Farm::restore(mib::link::tc_vc::COMMAND, mib::link::cop1::FARM_WINDOW_WIDTH, rec)
    }

    /// Whether a control command in clear is taken in the present state: only what
    /// resynchronisation needs, where it helps. Unlock in Lockout (the only way out) and
    /// in Wait; Set V(R) only to the present V(R), in Open or Wait (it clears the wait and
    /// retransmit flags that the ground's Initiate-AD-with-Set-V(R) waits on). The
    /// standard's table (E7, E8) also takes Unlock in Open and a Set V(R) that moves V(R);
    /// in clear, those are what a forged or replayed frame would use to make FARM-1 drop
    /// (or acknowledge) frames of the real ground, and neither ground needs them: FOP-1
    /// initialising with a CLCW check takes V(S) from N(R). See docs/space-link.md.
    pub fn takes(&self, cmd: ControlCommand) -> bool {
        match cmd {
            ControlCommand::Unlock => self.state != FarmState::Open,
            ControlCommand::SetVr(v) => self.state != FarmState::Lockout && v == self.vr,
        }
    }

    pub fn on_event(&mut self, input: FarmInput) -> FarmEffect {
        use FarmAction::*;
        use FarmEvent::*;
        use FarmState::*;
        let (event, action) = match input {
            FarmInput::Ad { ns, buffer_available } => {
                let d = ns.wrapping_sub(self.vr);
                if d == 0 {
                    // In Wait the back-end buffer is unavailable until E10 (wait flag).
                    if buffer_available && self.state == Open {
                        self.vr = self.vr.wrapping_add(1);
                        self.retransmit = false;
                        (E1, Accept)
                    } else {
                        if self.state == Open {
                            self.retransmit = true;
                            self.wait = true;
                            self.state = Wait;
                        }
                        (
                            if buffer_available && self.state == Lockout {
                                E1
                            } else {
                                E2
                            },
                            Discard,
                        )
                    }
                } else if d < self.pw {
                    if self.state == Open {
                        self.retransmit = true;
                    }
                    (E3, Discard)
                } else if d >= 0u8.wrapping_sub(self.nw) {
                    (E4, Discard)
                } else {
                    if self.state != Lockout {
                        self.lockout = true;
                        self.state = Lockout;
                    }
                    (E5, Discard)
                }
            }
            FarmInput::Bd => {
                self.farm_b = self.farm_b.wrapping_add(1);
                (E6, Accept)
            }
            FarmInput::Bc(ControlCommand::Unlock) => {
                self.farm_b = self.farm_b.wrapping_add(1);
                self.retransmit = false;
                self.wait = false;
                self.lockout = false;
                self.state = Open;
                (E7, Done)
            }
            FarmInput::Bc(ControlCommand::SetVr(v)) => {
                self.farm_b = self.farm_b.wrapping_add(1);
                if self.state != Lockout {
                    self.retransmit = false;
                    self.wait = false;
                    self.vr = v;
                    self.state = Open;
                }
                (E8, Done)
            }
            FarmInput::Invalid => (E9, Discard),
            FarmInput::BufferRelease => {
                self.wait = false;
                if self.state == Wait {
                    self.state = Open;
                }
                (E10, Done)
            }
        };
        FarmEffect { event, action }
    }

    /// The CLCW reporting this FARM.
    pub fn clcw(&self) -> Clcw {
        Clcw {
            status: 0,
            cop_in_effect: CopInEffect::Cop1,
            vcid: self.vcid,
            no_rf_available: false,
            no_bit_lock: false,
            lockout: self.lockout,
            wait: self.wait,
            retransmit: self.retransmit,
            farm_b_counter: self.farm_b & 3,
            report_value: self.vr,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use FarmAction::*;
    use FarmEvent::*;

    fn ad(ns: u8) -> FarmInput {
        FarmInput::Ad {
            ns,
            buffer_available: true,
        }
    }

    fn farm_at(vr: u8) -> Farm {
        let mut f = Farm::new(0, 20);
        f.on_event(FarmInput::Bc(ControlCommand::SetVr(vr)));
        f
    }

    fn wait_farm() -> Farm {
        let mut f = farm_at(5);
        f.on_event(FarmInput::Ad {
            ns: 5,
            buffer_available: false,
        });
        assert_eq!(f.state(), FarmState::Wait);
        f
    }

    fn lockout_farm() -> Farm {
        let mut f = farm_at(5);
        f.on_event(ad(100));
        assert_eq!(f.state(), FarmState::Lockout);
        f
    }

    // verifies: LINK-FARM-01
    #[test]
    fn farm_e1_ad_frame_in_sequence_accepted_in_open() {
        let mut f = farm_at(7);
        f.retransmit = true;
        assert_eq!(
            f.on_event(ad(7)),
            FarmEffect {
                event: E1,
                action: Accept
            }
        );
        assert_eq!(f.vr(), 8);
        assert!(!f.clcw().retransmit);
        assert_eq!(f.clcw().report_value, 8);
        assert_eq!(f.state(), FarmState::Open);
    }

    // verifies: LINK-FARM-01
    #[test]
    fn farm_e1_at_the_8_bit_wrap() {
        let mut f = farm_at(255);
        assert_eq!(f.on_event(ad(255)).action, Accept);
        assert_eq!(f.vr(), 0);
        assert_eq!(f.on_event(ad(0)).action, Accept);
        assert_eq!(f.vr(), 1);
        // 255 is now behind (negative window), not a gap.
        assert_eq!(f.on_event(ad(255)).event, E4);
    }

    // verifies: LINK-FARM-01
    #[test]
    fn farm_e2_in_sequence_without_buffer_enters_wait() {
        let mut f = farm_at(5);
        let e = f.on_event(FarmInput::Ad {
            ns: 5,
            buffer_available: false,
        });
        assert_eq!(
            e,
            FarmEffect {
                event: E2,
                action: Discard
            }
        );
        assert_eq!(f.state(), FarmState::Wait);
        let c = f.clcw();
        assert!(c.wait && c.retransmit && !c.lockout);
        assert_eq!(c.report_value, 5);
        // In Wait, even with space reported, the frame is discarded until E10.
        assert_eq!(f.on_event(ad(5)).action, Discard);
        assert_eq!(f.state(), FarmState::Wait);
        let mut l = lockout_farm();
        assert_eq!(
            l.on_event(FarmInput::Ad {
                ns: 5,
                buffer_available: false
            })
            .action,
            Discard
        );
        assert_eq!(l.state(), FarmState::Lockout);
    }

    // verifies: LINK-FARM-01
    #[test]
    fn farm_e3_positive_window_gap_sets_retransmit() {
        let mut f = farm_at(5);
        assert_eq!(
            f.on_event(ad(6)),
            FarmEffect {
                event: E3,
                action: Discard
            }
        );
        assert!(f.clcw().retransmit);
        assert_eq!(f.vr(), 5);
        // PW − 1 = 9 ahead is still the positive window.
        assert_eq!(f.on_event(ad(14)).event, E3);
        assert_eq!(f.state(), FarmState::Open);
        // Across the wrap.
        let mut g = farm_at(250);
        assert_eq!(g.on_event(ad(3)).event, E3);
        let mut w = wait_farm();
        assert_eq!(w.on_event(ad(6)).event, E3);
        assert_eq!(w.state(), FarmState::Wait);
    }

    // verifies: LINK-FARM-01
    #[test]
    fn farm_e4_negative_window_frame_discarded_silently() {
        let mut f = farm_at(5);
        assert_eq!(
            f.on_event(ad(4)),
            FarmEffect {
                event: E4,
                action: Discard
            }
        );
        assert!(!f.clcw().retransmit);
        // NW = 10 behind, across the wrap.
        assert_eq!(f.on_event(ad(251)).event, E4);
        assert_eq!(f.state(), FarmState::Open);
    }

    // verifies: LINK-FARM-01
    #[test]
    fn farm_e5_outside_both_windows_locks_out() {
        let mut f = farm_at(5);
        // PW = 10 ahead is already the lockout area; 11 behind too.
        assert_eq!(
            f.on_event(ad(15)),
            FarmEffect {
                event: E5,
                action: Discard
            }
        );
        assert_eq!(f.state(), FarmState::Lockout);
        assert!(f.clcw().lockout);
        let mut g = farm_at(5);
        assert_eq!(g.on_event(ad(250)).event, E5);
        // In Lockout even an in-sequence frame is discarded.
        assert_eq!(f.on_event(ad(5)).action, Discard);
        let mut w = wait_farm();
        assert_eq!(w.on_event(ad(200)).event, E5);
        assert_eq!(w.state(), FarmState::Lockout);
    }

    // verifies: LINK-FARM-01
    #[test]
    fn farm_e6_bd_frame_accepted_in_every_state() {
        for mut f in [farm_at(1), wait_farm(), lockout_farm()] {
            let s = f.state();
            let b = f.farm_b_counter();
            assert_eq!(
                f.on_event(FarmInput::Bd),
                FarmEffect {
                    event: E6,
                    action: Accept
                }
            );
            assert_eq!(f.state(), s);
            assert_eq!(f.farm_b_counter(), b.wrapping_add(1));
            assert_eq!(f.clcw().farm_b_counter, b.wrapping_add(1) & 3);
        }
    }

    // verifies: LINK-FARM-01
    #[test]
    fn farm_e7_unlock_returns_to_open_from_every_state() {
        for mut f in [farm_at(1), wait_farm(), lockout_farm()] {
            let vr = f.vr();
            assert_eq!(f.on_event(FarmInput::Bc(ControlCommand::Unlock)).event, E7);
            assert_eq!(f.state(), FarmState::Open);
            let c = f.clcw();
            assert!(!c.lockout && !c.wait && !c.retransmit);
            assert_eq!(f.vr(), vr);
        }
    }

    // verifies: LINK-FARM-01
    #[test]
    fn farm_e8_set_vr_in_open_and_wait_not_in_lockout() {
        let mut f = farm_at(1);
        assert_eq!(f.on_event(FarmInput::Bc(ControlCommand::SetVr(77))).event, E8);
        assert_eq!(f.vr(), 77);
        let mut w = wait_farm();
        w.on_event(FarmInput::Bc(ControlCommand::SetVr(9)));
        assert_eq!((w.state(), w.vr()), (FarmState::Open, 9));
        assert!(!w.clcw().wait);
        let mut l = lockout_farm();
        let b = l.farm_b_counter();
        l.on_event(FarmInput::Bc(ControlCommand::SetVr(9)));
        assert_eq!((l.state(), l.vr()), (FarmState::Lockout, 5));
        assert_eq!(l.farm_b_counter(), b + 1);
    }

    // verifies: LINK-FARM-01
    #[test]
    fn farm_e9_invalid_frame_changes_nothing() {
        for mut f in [farm_at(1), wait_farm(), lockout_farm()] {
            let before = f.clcw();
            assert_eq!(
                f.on_event(FarmInput::Invalid),
                FarmEffect {
                    event: E9,
                    action: Discard
                }
            );
            assert_eq!(f.clcw(), before);
        }
    }

    // verifies: LINK-FARM-01
    #[test]
    fn farm_e10_buffer_release_leaves_wait() {
        let mut w = wait_farm();
        assert_eq!(w.on_event(FarmInput::BufferRelease).event, E10);
        assert_eq!(w.state(), FarmState::Open);
        assert!(!w.clcw().wait);
        assert!(w.clcw().retransmit); // until the frame comes again
        assert_eq!(w.on_event(ad(5)).action, Accept);
        let mut l = lockout_farm();
        l.on_event(FarmInput::BufferRelease);
        assert_eq!(l.state(), FarmState::Lockout);
        let mut o = farm_at(1);
        o.on_event(FarmInput::BufferRelease);
        assert_eq!(o.state(), FarmState::Open);
    }
}
