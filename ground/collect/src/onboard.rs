//! Everything the collector needs to know about the obsw's side of the link, in one
//! place: how to subscribe and renew the lease, how to ask the on-board store for a
//! range, how to read the store's end report, how to recognise a reboot.
//!
//! The TCs are looked up by MIB name at run time, so the collector uses store retrieval
//! by sequence-count range (TC[15,128] `STORE_DOWNLINK_SEQ`) when the MIB has it and
//! falls back to the whole-store downlink otherwise; the archive keeps each packet once
//! either way.

use mib::tc::TcDef;

use crate::pus::{self, BuiltTc, Tm};

use super::tracker::Pos;

/// How often the lease of the downlink subscription is renewed (every accepted TC
/// renews it; a ping is the cheapest): the MIB's ground heartbeat, well inside the
/// obsw's `SUBSCRIPTION_LEASE_MS`.
pub const LEASE_RENEW_MS: i64 = mib::ground_config::GROUND_HEARTBEAT_MS as i64;
const _: () = assert!(3 * LEASE_RENEW_MS < mib::host_config::SUBSCRIPTION_LEASE_MS as i64);

/// On-board APID of a robot.
pub fn apid(robot: u8) -> Option<u16> {
    mib::apid::robot_apid(robot)
}

fn def(name: &str) -> Option<&'static TcDef> {
    mib::tc::by_name(name)
}

/// The TC that subscribes to (or renews) the downlink: a connection test.
pub fn subscribe_tc(robot: u8, seq: u16) -> Option<BuiltTc> {
    pus::build_tc(robot, seq, def("PING")?, &[]).ok()
}

/// Asks for the modes of the whole mode tree (TM[200,6] for the robot node and every
/// descendant), so the dashboard's mode tree is complete without waiting for a change.
pub fn mode_announce_tc(robot: u8, seq: u16) -> Option<BuiltTc> {
    pus::build_tc(robot, seq, def("MODE_ANNOUNCE")?, &[mib::modes::node::ROBOT as i64]).ok()
}

/// Asks for the module report TM[210,3] (REPORT_MODULES).
pub fn report_modules_tc(robot: u8, seq: u16) -> Option<BuiltTc> {
    pus::build_tc(robot, seq, def("REPORT_MODULES")?, &[]).ok()
}

/// Asks for the team status report TM[211,2] (TEAM_STATUS_REQUEST).
pub fn team_status_tc(robot: u8, seq: u16) -> Option<BuiltTc> {
    pus::build_tc(robot, seq, def("TEAM_STATUS_REQUEST")?, &[]).ok()
}

/// The source data of a module report TM[210,3] (the set is rebuilt from it by
/// `mib::modules::report`).
pub fn module_report(tm: &Tm) -> Option<Vec<u8>> {
    let Some(mib_wire::Tm::ModuleReport(r)) = tm.body.report() else {
        return None;
    };
    let mut b = vec![0; r.buffer_len()];
    let n = r.emit(&mut b).ok()?;
    b.truncate(n);
    Some(b)
}

/// Sets the collection interval of a housekeeping structure.
pub fn hk_interval_tc(robot: u8, seq: u16, sid: u16, interval_ms: u32) -> Option<BuiltTc> {
    pus::build_tc(robot, seq, def("HK_SET_INTERVAL")?, &[sid as i64, interval_ms as i64]).ok()
}

/// Asks the on-board store for the packets of `apid` with sequence counts
/// `first..=last` (mod 2^14): by their on-board time `window` (unix ms, both ends
/// included; TC[15,9]) when it is known — a store holding more than 2^14 packets holds
/// every count more than once, a window only the ones asked for — else by count
/// (TC[15,128]). `true` in the result: a range request; `false`: the MIB has no range
/// retrieval and the whole store is asked for.
pub fn store_range_tc(
    robot: u8,
    seq: u16,
    apid: u16,
    (first, last): (u16, u16),
    window: Option<(i64, i64)>,
) -> Option<(BuiltTc, bool)> {
    if let (Some((from, to)), Some(d)) = (window, def("STORE_DOWNLINK_TIME")) {
        let args = ground_ops::live::store_time_args(from, to);
        return pus::build_tc(robot, seq, d, &args).ok().map(|t| (t, true));
    }
    if let Some(d) = def("STORE_DOWNLINK_SEQ") {
        return pus::build_tc(robot, seq, d, &[apid as i64, first as i64, last as i64])
            .ok()
            .map(|t| (t, true));
    }
    let d = def("STORE_DOWNLINK")?;
    pus::build_tc(robot, seq, d, &[]).ok().map(|t| (t, false))
}

/// Sequence count and on-board time of a packet whose headers and CRC are good (it
/// was delivered intact) even if its body does not match the MIB.
pub fn intact_position(raw: &[u8]) -> Option<(u16, Pos)> {
    let (apid, seq, obt_ms) = pus::intact_position(raw)?;
    Some((apid, Pos { seq, obt_ms }))
}

/// The restart, store-end and position readings are the tracker's ([`ground_ops::live`]).
pub use ground_ops::live::{is_boot, store_done, StoreDone};

#[cfg(test)]
mod tests {
    use super::*;

    // verifies: GND-12, PUS-15-01
    #[test]
    fn subscription_and_store_requests_build_from_the_mib() {
        let t = subscribe_tc(1, 5).unwrap();
        assert_eq!((t.def.service, t.def.subservice, t.seq), (17, 1, 5));
        let (t, _) = store_range_tc(1, 6, 0x101, (10, 20), None).unwrap();
        assert_eq!((t.def.service, t.def.subservice), (15, 128));
        let (t, _) = store_range_tc(1, 6, 0x101, (10, 20), Some((1_790_000_000_000, 1_790_000_001_000))).unwrap();
        assert_eq!((t.def.service, t.def.subservice), (15, 9));
        let h = hk_interval_tc(2, 7, 1, 100).unwrap();
        assert_eq!(h.args, vec![1, 100]);
    }
}
