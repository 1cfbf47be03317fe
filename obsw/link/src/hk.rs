//! The SPACE_LINK housekeeping values (HK SID 22, `LINK_AD_ACCEPTED` ..
//! `LINK_REJ_BD_CONTENT`) and the link events their changes raise: one layout for the
//! host obsw and board A, the parameter offsets taken from the MIB.

use mib::params::pid;

use crate::clcw::Clcw;
use crate::downlink::TxCounters;
use crate::rx::RxCounters;

/// Number of SPACE_LINK counter parameters.
pub const SPACE_LINK_PARAMS: usize = (pid::LINK_REJ_BD_CONTENT - pid::LINK_AD_ACCEPTED + 1) as usize;

/// Offset of parameter `id` in the SPACE_LINK values.
const fn at(id: u16) -> usize {
    (id - pid::LINK_AD_ACCEPTED) as usize
}

/// The refusal counters; their offsets are the `reason` codes of `LINK_FRAME_REJECTED`.
const REFUSALS: [usize; 15] = [
    at(pid::LINK_REJ_BARE_PACKET),
    at(pid::LINK_REJ_BAD_CRC),
    at(pid::LINK_REJ_BAD_LENGTH),
    at(pid::LINK_REJ_BAD_HEADER),
    at(pid::LINK_REJ_WRONG_SCID),
    at(pid::LINK_REJ_UNKNOWN_VC),
    at(pid::LINK_REJ_SDLS_SHORT),
    at(pid::LINK_REJ_UNKNOWN_SPI),
    at(pid::LINK_REJ_REPLAY),
    at(pid::LINK_REJ_BAD_MAC),
    at(pid::LINK_REJ_STORE_FAILED),
    at(pid::LINK_REJ_UNKNOWN_CONTROL),
    at(pid::LINK_REJ_NOT_PACKETS),
    at(pid::LINK_REJ_CONTROL_STATE),
    at(pid::LINK_REJ_BD_CONTENT),
];

/// Offset of the control-frame counter (`LINK_CONTROL_FRAMES`).
const CONTROL_FRAMES: usize = at(pid::LINK_CONTROL_FRAMES);

/// The SPACE_LINK values in MIB order. `tm_sdls_failed`: TM frames not sent because SDLS
/// failed, beyond the framer's own count (board A: frames with no key).
pub fn space_link_values(
    rx: &RxCounters,
    clcw: Clcw,
    tx: &TxCounters,
    tm_sdls_failed: u32,
) -> [u32; SPACE_LINK_PARAMS] {
    let s = |v: &[u32]| v.iter().fold(0u32, |a, b| a.saturating_add(*b));
    let mut hk = [0u32; SPACE_LINK_PARAMS];
    hk[at(pid::LINK_AD_ACCEPTED)] = rx.ad_accepted;
    hk[at(pid::LINK_BD_ACCEPTED)] = rx.bd_accepted;
    hk[CONTROL_FRAMES] = s(&[rx.unlock, rx.set_vr]);
    hk[at(pid::LINK_PACKETS)] = rx.packets;
    hk[at(pid::LINK_REJ_BARE_PACKET)] = rx.bare_packet;
    hk[at(pid::LINK_REJ_BAD_CRC)] = rx.bad_crc;
    hk[at(pid::LINK_REJ_BAD_LENGTH)] = rx.bad_length;
    hk[at(pid::LINK_REJ_BAD_HEADER)] = rx.bad_header;
    hk[at(pid::LINK_REJ_WRONG_SCID)] = rx.wrong_scid;
    hk[at(pid::LINK_REJ_UNKNOWN_VC)] = rx.unknown_vc;
    hk[at(pid::LINK_REJ_SDLS_SHORT)] = rx.sdls_too_short;
    hk[at(pid::LINK_REJ_UNKNOWN_SPI)] = rx.unknown_spi;
    hk[at(pid::LINK_REJ_REPLAY)] = rx.replay;
    hk[at(pid::LINK_REJ_BAD_MAC)] = rx.bad_mac;
    hk[at(pid::LINK_REJ_STORE_FAILED)] = rx.counter_store_failed;
    hk[at(pid::LINK_REJ_UNKNOWN_CONTROL)] = rx.unknown_control;
    hk[at(pid::LINK_REJ_NOT_PACKETS)] = rx.not_packets;
    hk[at(pid::LINK_FARM_DISCARDED)] = s(&[rx.farm_e2, rx.farm_e3, rx.farm_e4, rx.farm_e5]);
    hk[at(pid::LINK_CLCW)] = clcw.emit();
    hk[at(pid::LINK_TM_FRAMES)] = tx.frames;
    hk[at(pid::LINK_TM_IDLE_FRAMES)] = tx.idle_frames;
    hk[at(pid::LINK_TM_SDLS_FAILED)] = tx.sdls_failed.saturating_add(tm_sdls_failed);
    hk[at(pid::LINK_REJ_CONTROL_STATE)] = rx.control_refused;
    hk[at(pid::LINK_REJ_BD_CONTENT)] = rx.bd_content;
    hk
}

/// `LINK_CONTROL_FRAME`'s `command` and `vr` for the last control frame executed
/// (0 Unlock, 1 Set V(R) with its V(R); none yet: 0, 0).
pub fn control_event_fields(last: Option<crate::tc::ControlCommand>) -> (u8, u8) {
    match last {
        Some(crate::tc::ControlCommand::SetVr(v)) => (1, v),
        Some(crate::tc::ControlCommand::Unlock) | None => (0, 0),
    }
}

/// What changed between two SPACE_LINK reports, as the link events say it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LinkChange {
    /// A refusal counter moved: `reason` is its offset (`LINK_FRAME_REJECTED`'s code).
    Rejected { reason: u8, total: u32 },
    /// BC control frames were executed (`LINK_CONTROL_FRAME`).
    ControlFrames { total: u32 },
}

/// The changes from `before` to `now`: one per refusal reason that moved (in parameter
/// order), then one for control frames.
pub fn changes<'a>(
    now: &'a [u32; SPACE_LINK_PARAMS],
    before: &'a [u32; SPACE_LINK_PARAMS],
) -> impl Iterator<Item = LinkChange> + 'a {
    let rejected = REFUSALS
        .iter()
        .filter(|&&r| now[r] != before[r])
        .map(|&r| LinkChange::Rejected {
            reason: r as u8,
            total: now[r],
        });
    let control = (now[CONTROL_FRAMES] != before[CONTROL_FRAMES]).then_some(LinkChange::ControlFrames {
        total: now[CONTROL_FRAMES],
    });
    rejected.chain(control)
}

#[cfg(test)]
mod tests {
    use super::*;

    // verifies: LINK-HK-01
    #[test]
    fn values_follow_the_mib_and_changes_name_each_moved_refusal_once() {
        let mut rx = RxCounters::default();
        let tx = TxCounters::default();
        let clcw = crate::farm::Farm::new(0, mib::link::cop1::FARM_WINDOW_WIDTH).clcw();
        let before = space_link_values(&rx, clcw, &tx, 0);
        rx.replay = 3;
        rx.set_vr = 1;
        rx.control_refused = 2;
        let now = space_link_values(&rx, clcw, &tx, 0);
        assert_eq!(now[at(pid::LINK_REJ_REPLAY)], 3);
        let got: heapless::Vec<LinkChange, 8> = changes(&now, &before).collect();
        assert_eq!(
            got.as_slice(),
            [
                LinkChange::Rejected {
                    reason: (pid::LINK_REJ_REPLAY - pid::LINK_AD_ACCEPTED) as u8,
                    total: 3
                },
                LinkChange::Rejected {
                    reason: (pid::LINK_REJ_CONTROL_STATE - pid::LINK_AD_ACCEPTED) as u8,
                    total: 2
                },
                LinkChange::ControlFrames { total: 1 },
            ]
        );
        assert_eq!(changes(&now, &now).count(), 0);
    }
}
