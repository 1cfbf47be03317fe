//! mib_wire::codec and the MIB tables on the target: byte layouts checked against frames
//! written out by hand from the ICD, and round trips.

use crate::harness::{Test, TestResult};
use crate::tests;
use crate::{check, check_eq, ok};
use mib::events::eid;
use mib::hk::{self, sid};
use mib::params::pid;
use mib::tc::{self, function};
use mib_wire::codec::{self, ArgError, CodecError};

pub const TESTS: &[Test] = tests![
    codec_b_link_hk_matches_hand_layout,
    codec_every_hk_structure_round_trips,
    codec_hk_decode_rejects_bad_input,
    codec_low_battery_event_layout,
    codec_reconfigure_args_layout_and_ranges,
    mib_low_battery_monitor_is_10v_for_half_a_second,
    mib_fault_table_recovery_modes,
];

fn codec_b_link_hk_matches_hand_layout() -> TestResult {
    let def = ok!(hk::by_sid(sid::B_LINK));
    let mut buf = [0u8; 64];
    let n = ok!(codec::encode_hk(
        def,
        |id| match id {
            pid::B_LINK_OK => 1,
            pid::B_HB_AGE_MS => 0x1234,
            pid::B_HB_RX => 0x0102_0304,
            pid::B_FRAME_ERRORS => 5,
            pid::B_RETRIES => 0xFFFF_FFFF,
            pid::B_ACK_MISSED => 0,
            _ => 99,
        },
        &mut buf,
    ));
    let expect: [u8; 21] = [
        0x00, 0x02, // sid
        0x01, // B_LINK_OK
        0x12, 0x34, // B_HB_AGE_MS
        0x01, 0x02, 0x03, 0x04, // B_HB_RX
        0x00, 0x00, 0x00, 0x05, // B_FRAME_ERRORS
        0xFF, 0xFF, 0xFF, 0xFF, // B_RETRIES
        0x00, 0x00, 0x00, 0x00, // B_ACK_MISSED
    ];
    check_eq!(&buf[..n], &expect[..]);
    let rep = ok!(codec::decode_hk(&expect));
    check_eq!(rep.get(pid::B_HB_RX), Some(0x0102_0304));
    check_eq!(rep.get(pid::B_RETRIES), Some(0xFFFF_FFFF));
    Ok(())
}

/// A value per parameter that depends on the ID and fits the parameter's type.
fn pattern(id: u16, bits: usize, signed: bool) -> i64 {
    let v = (id as i64).wrapping_mul(2_654_435_761) & ((1i64 << bits.min(31)) - 1);
    if signed {
        v - (1i64 << (bits.min(31) - 1))
    } else {
        v
    }
}

fn codec_every_hk_structure_round_trips() -> TestResult {
    for def in hk::HK_STRUCTS {
        let mut buf = [0u8; 256];
        let n = ok!(codec::encode_hk(
            def,
            |id| {
                let p = mib::params::by_id(id).map(|p| p.ptype);
                match p {
                    Some(t) => pattern(id, t.bits(), t.signed()),
                    None => 0,
                }
            },
            &mut buf,
        ));
        let size: usize = 2 + def
            .params
            .iter()
            .map(|id| mib::params::by_id(*id).map(|p| p.ptype.size()).unwrap_or(0))
            .sum::<usize>();
        check_eq!(n, size, "length of sid {}", def.sid);
        let rep = ok!(codec::decode_hk(&buf[..n]));
        let mut count = 0;
        for (p, v) in rep.values() {
            let t = p.ptype;
            let want = pattern(p.id, t.bits(), t.signed()).clamp(t.min(), t.max());
            check_eq!(v, want, "param {}", p.id);
            count += 1;
        }
        check_eq!(count, def.params.len());
    }
    Ok(())
}

fn codec_hk_decode_rejects_bad_input() -> TestResult {
    check_eq!(
        codec::decode_hk(&[0x00, 0x63]).err(),
        Some(CodecError::UnknownSid(0x63))
    );
    check!(codec::decode_hk(&[0x00]).is_err());
    let def = ok!(hk::by_sid(sid::ROBOT_STATUS));
    let mut buf = [0u8; 256];
    let n = ok!(codec::encode_hk(def, |_| 7, &mut buf));
    check!(matches!(
        codec::decode_hk(&buf[..n - 1]),
        Err(CodecError::LengthMismatch { .. })
    ));
    check!(codec::encode_hk(def, |_| 7, &mut buf[..8]).is_err());
    Ok(())
}

fn codec_low_battery_event_layout() -> TestResult {
    let def = ok!(mib::events::by_id(eid::LOW_BATTERY));
    let mut buf = [0u8; 16];
    let n = ok!(codec::encode_event(def, &[20, 2700, 2730], &mut buf));
    check_eq!(&buf[..n], &[0x01, 0x04, 0x00, 0x14, 0x0A, 0x8C, 0x0A, 0xAA][..]);
    let ev = ok!(codec::decode_event(&buf[..n]));
    check_eq!(ev.param("limit"), Some(2730));
    check!(codec::decode_event(&buf[..n - 1]).is_err());
    Ok(())
}

fn codec_reconfigure_args_layout_and_ranges() -> TestResult {
    let def = ok!(tc::lookup(8, 1, Some(function::RECONFIGURE)));
    let mut buf = [0u8; 8];
    let n = ok!(codec::encode_args(def, &[3, 14], &mut buf));
    check_eq!(&buf[..n], &[0x00, 0x01, 3, 14][..]);
    let (v, rest) = ok!(codec::decode_args(def, &buf[2..n]));
    check_eq!((v[0], v[1], rest.len()), (3, 14, 0));
    check_eq!(
        codec::encode_args(def, &[0, 15], &mut buf).err(),
        Some(ArgError::OutOfRange { index: 1, value: 15 })
    );
    check_eq!(
        codec::decode_args(def, &[1]).err(),
        Some(ArgError::Length { got: 3, expected: 4 })
    );
    Ok(())
}

fn mib_low_battery_monitor_is_10v_for_half_a_second() -> TestResult {
    let m = ok!(mib::fdir::MONITORS.iter().find(|m| m.event == eid::LOW_BATTERY));
    // 10 V through the 15 V / 4095-count divider: 10 * 4095 / 15 = 2730 counts.
    check_eq!(m.low, 2730);
    check_eq!(m.persistence as u32 * mib::config::CONTROL_PERIOD_MS, 500);
    Ok(())
}

fn mib_fault_table_recovery_modes() -> TestResult {
    use mib::fdir::{action_for, Timing};
    use mib::modes::robot_mode::{SAFED, STANDBY};
    let expect = [
        (eid::BOLT_FAILURE, STANDBY, Timing::Immediate),
        (eid::INITIAL_STATE_MISMATCH, STANDBY, Timing::Immediate),
        (eid::LOW_BATTERY, STANDBY, Timing::AfterMotion),
        (eid::ASSEMBLY_SYSTEM_FAULT, STANDBY, Timing::AfterMotion),
        (eid::ARM_NOT_CONTRACTED, SAFED, Timing::Immediate),
        (eid::OPERATIONAL_OVERCURRENT, SAFED, Timing::Immediate),
        (eid::COMM_LOSS_HEARTBEAT, SAFED, Timing::Immediate),
        (eid::COMM_LOSS_NO_ACK, SAFED, Timing::Immediate),
    ];
    for (ev, mode, timing) in expect {
        let a = ok!(action_for(ev));
        check_eq!((a.mode, a.timing), (mode, timing), "event 0x{:04X}", ev);
    }
    check!(action_for(eid::STATE_REACHED).is_none());
    Ok(())
}
