//! The rule cases of the live link: link loss, sequence tracking, gap retrieval.

use mib::ground_config::{GAP_MERGE_DISTANCE, GAP_RANGE_MAX, GAP_REQUESTS_MAX, LINK_LOSS_MS};

use super::*;
use crate::pus::{Tm, TmBody};

fn plan(merge: u16) -> GapPlan {
    GapPlan {
        merge_distance: merge,
        ..GapPlan::default()
    }
}

// ---- link state -------------------------------------------------------------------------

// verifies: OPS-LIVE-LINK-01
#[test]
fn link_is_lost_after_two_and_a_half_hk_intervals_without_tm() {
    let mut w = LinkWatch::new(4_000, 0);
    assert_eq!(w.loss_after_ms(), 10_000);
    assert_eq!(w.on_tm(1_000), Some(LinkState::Connecting));
    assert_eq!(w.tick(11_000, false), None, "10 s of silence is not yet more than 10 s");
    let loss = w.tick(11_001, false).expect("lost");
    assert_eq!((loss.silent_ms, loss.never_heard, loss.closed), (10_001, false, false));
    assert_eq!(w.state(), LinkState::Lost);
}

// verifies: OPS-LIVE-LINK-01
#[test]
fn link_loss_is_never_sooner_than_the_mib_floor() {
    // HK every 100 ms: 2.5 intervals are 250 ms, the floor holds.
    let mut w = LinkWatch::new(100, 0);
    assert_eq!(w.loss_after_ms(), i64::from(LINK_LOSS_MS));
    w.on_tm(0);
    assert_eq!(w.tick(i64::from(LINK_LOSS_MS), false), None);
    assert!(w.tick(i64::from(LINK_LOSS_MS) + 1, false).is_some());
    // At the MIB's default status-HK interval the rule is the floor.
    assert_eq!(LinkWatch::at_mib_interval(0).loss_after_ms(), i64::from(LINK_LOSS_MS));
}

// verifies: OPS-LIVE-LINK-01
#[test]
fn one_lost_hk_report_is_not_a_link_loss() {
    let hk = 2_000;
    let mut w = LinkWatch::new(hk, 0);
    w.on_tm(0);
    // The report at 2 s is lost; the one at 4 s (late by 300 ms of jitter) arrives.
    assert_eq!(w.tick(4_300, false), None);
    assert_eq!(w.on_tm(4_300), None, "still up");
    // Two lost in a row (6.3 s, 8.3 s): lost before the third would come.
    assert!(w.tick(4_300 + 5_001, false).is_some());
}

// verifies: OPS-LIVE-LINK-01
#[test]
fn a_closed_connection_is_a_loss_at_once_reported_once_and_latched_until_tm() {
    let mut w = LinkWatch::new(1_000, 0);
    let loss = w.tick(10, true).expect("closed");
    assert!(loss.closed && loss.never_heard);
    assert_eq!(w.tick(100_000, true), None, "reported once");
    assert_eq!(w.on_tm(100_001), Some(LinkState::Lost), "restored");
    assert_eq!(w.state(), LinkState::Up);
}

// verifies: OPS-LIVE-LINK-01
#[test]
fn a_link_never_heard_is_lost_counted_from_when_watching_restarted() {
    let mut w = LinkWatch::new(1_000, 0);
    w.restart(5_000);
    assert_eq!(w.tick(5_000 + i64::from(LINK_LOSS_MS), false), None);
    let loss = w.tick(5_001 + i64::from(LINK_LOSS_MS), false).expect("lost");
    assert!(loss.never_heard);
    // An operator's larger floor (the collector's loss_timeout_ms) raises it, never lowers.
    assert_eq!(LinkWatch::new(1_000, 0).with_floor(9_000).loss_after_ms(), 9_000);
    assert_eq!(
        LinkWatch::new(1_000, 0).with_floor(10).loss_after_ms(),
        i64::from(LINK_LOSS_MS)
    );
}

// verifies: OPS-LIVE-LINK-02
#[test]
fn frames_keep_a_robot_heard_while_no_tm_packet_arrives() {
    let mut w = LinkWatch::at_mib_interval(0);
    assert_eq!(w.on_tm(0), Some(LinkState::Connecting));
    // No packet for 10 s (every HK report lost), but a valid frame every 100 ms.
    for t in (100..=10_000).step_by(100) {
        w.on_heard(t);
        assert_eq!(w.tick(t + 50, false), None, "heard at {t}");
        assert!(w.heard_within_loss_time(t + 50));
    }
    assert_eq!(w.last_heard_ms(), Some(10_000));
    // A frame older than the last TM changes nothing.
    w.on_tm(10_050);
    assert_eq!(w.on_heard(10_000), None);
    assert_eq!(w.last_heard_ms(), Some(10_050));
    // Then nothing at all: lost once the silence exceeds the loss time, and the loss
    // states that silence, not a shorter one.
    assert_eq!(w.tick(10_050 + i64::from(LINK_LOSS_MS), false), None);
    assert!(!w.heard_within_loss_time(10_051 + i64::from(LINK_LOSS_MS)));
    let loss = w.tick(10_051 + i64::from(LINK_LOSS_MS), false).expect("lost");
    assert_eq!(loss.silent_ms, i64::from(LINK_LOSS_MS) + 1);
    assert!(!loss.never_heard);
    // A frame again restores it.
    assert_eq!(w.on_heard(20_000), Some(LinkState::Lost));
}

// verifies: OPS-LIVE-LINK-03
#[test]
fn a_silence_counts_only_up_to_when_the_ground_listened() {
    let mut w = LinkWatch::at_mib_interval(0);
    w.on_tm(1_000);
    w.on_listened(1_100);
    // The ground did not run from 1.1 s to 10 s (its reader neither): nothing is known of
    // that time, so no loss, however late its own clock.
    assert_eq!(w.tick(10_000, false), None);
    assert!(w.heard_within_loss_time(10_000));
    // Its reader runs again: what waited in the socket (a TM at 10.0 s) comes first.
    w.on_tm(10_000);
    w.on_listened(10_010);
    assert_eq!(w.state(), LinkState::Up);
    // A real silence while the reader listens is still lost after the loss time, and the
    // loss states the silence listened to.
    let end = 10_000 + i64::from(LINK_LOSS_MS);
    w.on_listened(end);
    assert_eq!(w.tick(end + 500, false), None, "not listened past {end} yet");
    w.on_listened(end + 1);
    let loss = w.tick(end + 30, false).expect("lost");
    assert_eq!(loss.silent_ms, i64::from(LINK_LOSS_MS) + 1);
    // An older listened time never moves it back.
    w.on_listened(5_000);
    assert_eq!(w.silence_ms(end + 30), i64::from(LINK_LOSS_MS) + 1);
}

// ---- gap retrieval ----------------------------------------------------------------------

// verifies: OPS-LIVE-GAP-01
#[test]
fn gaps_within_the_merge_distance_are_one_retrieval_and_farther_ones_two() {
    let p = GapPlan::default();
    let d = GAP_MERGE_DISTANCE;
    assert_eq!(p.merge(&[(10, 11), (11 + d, 20 + d)]), vec![(10, 20 + d)]);
    assert_eq!(p.merge(&[(10, 11), (12 + d, 20 + d)]), vec![(10, 11), (12 + d, 20 + d)]);
    // Across the 14-bit wrap.
    assert_eq!(p.merge(&[(0x3FFE, 0x3FFF), (3, 4)]), vec![(0x3FFE, 4)]);
}

// verifies: OPS-LIVE-GAP-01
#[test]
fn a_retrieval_round_is_cut_to_the_range_and_request_limits() {
    let p = GapPlan::default();
    // A long outage: the first GAP_RANGE_MAX counts only.
    assert_eq!(p.round(&[(100, 5_000)], 8), vec![(100, 100 + GAP_RANGE_MAX - 1)]);
    // Across the wrap.
    assert_eq!(p.round(&[(0x3FFF, 2_000)], 8), vec![(0x3FFF, GAP_RANGE_MAX - 2)]);
    // Many far-apart gaps: at most the caller's limit, never more than GAP_REQUESTS_MAX.
    let far: Vec<(u16, u16)> = (0..40u16).map(|k| (k * 100, k * 100)).collect();
    assert_eq!(p.round(&far, 2), vec![(0, 0), (100, 100)]);
    assert_eq!(p.round(&far, usize::MAX).len(), GAP_REQUESTS_MAX);
}

// ---- sequence tracking ------------------------------------------------------------------

fn p(seq: u16, obt: i64) -> Pos {
    Pos { seq, obt_ms: obt }
}

// verifies: OPS-LIVE-SEQ-01
#[test]
fn a_session_tracker_expects_only_from_its_start_not_the_whole_boot() {
    let mut t = ApidTracker::new();
    assert_eq!(t.on_packet(p(500, 500), false, 0), Verdict::New);
    assert_eq!(t.holes(), 0, "what came before the first packet is not wanted");
    // A run that started at 497: the counts before the newest not received are holes.
    t.expect_from(497);
    assert_eq!(t.missing_ranges(), vec![(497, 499)]);
    // Expected before anything was heard: holes from there to the first packet.
    let mut t = ApidTracker::new();
    t.expect_from(0x3FFE);
    assert_eq!(t.on_packet(p(2, 2), false, 0), Verdict::New);
    assert_eq!(t.missing_upto(2), vec![(0x3FFE, 1)]);
    assert_eq!(t.on_packet(p(0x3FFF, 1), false, 0), Verdict::Filled);
    assert_eq!(t.on_packet(p(0x3FFF, 1), false, 0), Verdict::Duplicate);
}

// verifies: OPS-LIVE-SEQ-01, LINK-GND-02
#[test]
fn missing_after_gives_the_gaps_since_a_send_oldest_first_across_the_wrap() {
    let mut t = ApidTracker::new();
    for (i, s) in [0x3FF0, 0x3FF2, 0x3FF5, 3, 4, 7].into_iter().enumerate() {
        t.on_packet(p(s, i as i64), false, 0);
    }
    // Gaps: 3FF1, 3FF3-3FF4, 3FF6-2 (across the wrap, one range as TC[15,128] takes it), 5-6.
    assert_eq!(t.missing_after(0x3FF2), vec![(0x3FF3, 0x3FF4), (0x3FF6, 2), (5, 6)]);
    assert_eq!(t.missing_after(4), vec![(5, 6)]);
    assert_eq!(t.missing_after(7), vec![]);
    assert!(!t.missing_after(0x3FF5).contains(&(0x3FF1, 0x3FF1)));
    assert_eq!(t.missing_upto(4), vec![(0x3FF1, 0x3FF1), (0x3FF3, 0x3FF4), (0x3FF6, 2)]);
}

// verifies: OPS-LIVE-SEQ-01
#[test]
fn holes_found_overwritten_or_after_a_restart_count_as_lost_not_missing() {
    let mut t = ApidTracker::new();
    t.on_packet(p(10, 10), false, 0);
    t.on_packet(p(20, 20), false, 0);
    t.store_oldest(p(15, 15));
    assert_eq!((t.holes(), t.lost_packets), (5, 4));
    // The same count again with a later on-board time: a restart, not a duplicate.
    assert_eq!(t.on_packet(p(20, 99), false, 0), Verdict::Reboot);
    assert_eq!(t.lost_packets, 9);
    assert_eq!(t.missing_ranges(), vec![(0, 19)], "the new boot's first counts");
}

// verifies: OPS-LIVE-SEQ-01, GND-12
#[test]
fn in_order_packets_are_new_and_repeats_duplicates() {
    let mut t = ApidTracker::following_boot();
    for s in 0..10 {
        assert_eq!(
            t.on_packet(p(s, 100 + s as i64), s == 0, 0),
            if s == 0 { Verdict::Reboot } else { Verdict::New }
        );
    }
    assert_eq!(t.on_packet(p(9, 109), false, 0), Verdict::Duplicate);
    assert_eq!(t.on_packet(p(4, 104), false, 0), Verdict::Duplicate);
    assert_eq!(t.holes(), 0);
}

// verifies: OPS-LIVE-SEQ-01, GND-12, GND-02
#[test]
fn lost_packets_become_holes_requested_by_range_and_filled_once() {
    let mut t = ApidTracker::resume(Some(p(10, 1000)));
    assert_eq!(t.on_packet(p(15, 1500), false, 0), Verdict::New);
    assert_eq!(t.holes(), 4);
    assert!(t.due(100, 200, 1000, 3, &plan(0), 8).is_empty(), "settling");
    assert_eq!(t.due(300, 200, 1000, 3, &plan(0), 8), vec![(11, 14)]);
    assert!(t.due(400, 200, 1000, 3, &plan(0), 8).is_empty(), "just requested");
    assert_eq!(t.on_packet(p(12, 1200), false, 500), Verdict::Filled);
    assert_eq!(t.on_packet(p(12, 1200), false, 500), Verdict::Duplicate);
    assert_eq!(t.due(1300, 200, 1000, 3, &plan(0), 8), vec![(11, 11), (13, 14)]);
    assert_eq!(t.filled, 1);
}

// verifies: OPS-LIVE-SEQ-01, GND-12
#[test]
fn first_packet_without_history_asks_for_the_earlier_packets_of_the_boot() {
    let mut t = ApidTracker::following_boot();
    assert_eq!(t.on_packet(p(5, 500), false, 0), Verdict::New);
    assert_eq!(t.due(10, 0, 0, 3, &plan(0), 8), vec![(0, 4)]);
    assert_eq!(t.on_packet(p(0, 100), true, 20), Verdict::Filled);
}

// verifies: OPS-LIVE-SEQ-01, GND-12
#[test]
fn nearby_holes_are_asked_for_in_one_range() {
    let fill = |t: &mut ApidTracker| {
        t.on_packet(p(2, 2), false, 0);
        for s in 100..=200u16 {
            t.on_packet(p(s, s as i64), false, 0);
        }
        t.on_packet(p(202, 202), false, 0);
    };
    let mut t = ApidTracker::resume(Some(p(0, 0)));
    fill(&mut t);
    assert_eq!(t.due(0, 0, 0, 3, &plan(64), 8), vec![(1, 99), (201, 201)]);
    let mut t = ApidTracker::resume(Some(p(0, 0)));
    fill(&mut t);
    assert_eq!(t.due(0, 0, 0, 3, &plan(0), 8), vec![(1, 1), (3, 99), (201, 201)]);
}

// verifies: OPS-LIVE-SEQ-01, GND-12
#[test]
fn a_long_outage_is_asked_for_in_bounded_pieces() {
    let mut t = ApidTracker::resume(Some(p(0, 0)));
    t.on_packet(p(1000, 1000), false, 0);
    assert_eq!(t.due(0, 0, 100, 3, &plan(64), 1), vec![(1, GAP_RANGE_MAX)]);
    assert_eq!(
        t.due(1, 0, 100, 3, &plan(64), 1),
        vec![(GAP_RANGE_MAX + 1, 2 * GAP_RANGE_MAX)]
    );
}

// verifies: OPS-LIVE-SEQ-01, GND-12, PUS-PKT-03
#[test]
fn wrap_of_the_sequence_count_is_not_a_gap() {
    let mut t = ApidTracker::resume(Some(p(16382, 1)));
    assert_eq!(t.on_packet(p(16383, 2), false, 0), Verdict::New);
    assert_eq!(t.on_packet(p(0, 3), false, 0), Verdict::New);
    assert_eq!(t.on_packet(p(2, 4), false, 0), Verdict::New);
    assert_eq!(t.due(1000, 0, 0, 3, &plan(0), 8), vec![(1, 1)]);
    // A gap across the wrap is one run.
    let mut t = ApidTracker::resume(Some(p(16380, 1)));
    t.on_packet(p(3, 9), false, 0);
    assert_eq!(t.due(1000, 0, 0, 3, &plan(0), 8), vec![(16381, 2)]);
}

// verifies: OPS-LIVE-SEQ-01, GND-12, PUS-PKT-03
#[test]
fn reboot_restarting_counts_is_neither_a_16k_gap_nor_duplicates() {
    let mut t = ApidTracker::resume(Some(p(5000, 10_000)));
    t.on_packet(p(5002, 10_200), false, 0);
    assert_eq!(t.holes(), 1);
    // BOOT event with count 0, later on-board time.
    assert_eq!(t.on_packet(p(0, 20_000), true, 0), Verdict::Reboot);
    assert_eq!(t.holes(), 0);
    let lost = t.take_lost();
    assert_eq!(lost.len(), 1);
    assert_eq!((lost[0].first, lost[0].why), (5001, Lost::Rebooted));
    for s in 1..5 {
        assert_eq!(t.on_packet(p(s, 20_000 + s as i64), false, 0), Verdict::New);
    }
    assert_eq!(t.duplicates, 0);
}

// verifies: OPS-LIVE-SEQ-01, GND-12, PUS-15-03
#[test]
fn a_reboot_that_kept_its_store_leaves_the_outage_fillable() {
    let mut t = ApidTracker::resume(Some(p(5000, 10_000)));
    t.on_packet(p(5002, 10_200), false, 0);
    // The obsw went on from its stored counts: its BOOT event is 5100.
    assert_eq!(t.on_packet(p(5100, 20_000), true, 0), Verdict::Reboot);
    assert!(t.take_lost().is_empty(), "nothing declared lost");
    assert_eq!(t.holes(), 1 + 97);
    assert_eq!(t.on_packet(p(5001, 10_100), false, 0), Verdict::Filled);
    assert_eq!(t.on_packet(p(5050, 15_000), false, 0), Verdict::Filled);
    assert_eq!(t.holes(), 96);
}

// verifies: OPS-LIVE-SEQ-01, GND-12
#[test]
fn reboot_seen_without_its_boot_event_leaves_the_first_counts_as_holes() {
    let mut t = ApidTracker::resume(Some(p(7000, 10_000)));
    assert_eq!(t.on_packet(p(3, 30_000), false, 0), Verdict::Reboot);
    assert_eq!(t.due(10, 0, 0, 3, &plan(0), 8), vec![(0, 2)]);
    assert_eq!(t.on_packet(p(0, 29_000), true, 0), Verdict::Filled);
}

// verifies: OPS-LIVE-SEQ-01, GND-12
#[test]
fn holes_never_delivered_are_declared_after_the_retries() {
    let mut t = ApidTracker::resume(Some(p(1, 1)));
    t.on_packet(p(3, 3), false, 0);
    assert_eq!(t.due(0, 0, 10, 2, &plan(0), 8), vec![(2, 2)]);
    assert_eq!(t.due(10, 0, 10, 2, &plan(0), 8), vec![(2, 2)]);
    assert!(t.due(20, 0, 10, 2, &plan(0), 8).is_empty());
    let lost = t.take_lost();
    assert_eq!((lost[0].first, lost[0].count, lost[0].why), (2, 1, Lost::NotDelivered));
    assert_eq!(t.lost_packets, 1);
}

// verifies: OPS-LIVE-SEQ-01, GND-12
#[test]
fn holes_older_than_the_store_are_overwritten() {
    let mut t = ApidTracker::resume(Some(p(100, 100)));
    t.on_packet(p(200, 200), false, 0);
    t.store_oldest(p(150, 150));
    let lost = t.take_lost();
    assert_eq!(
        (lost[0].first, lost[0].last, lost[0].why),
        (101, 149, Lost::Overwritten)
    );
    assert_eq!(t.due(0, 0, 0, 3, &plan(0), 8), vec![(150, 199)]);
}

// verifies: OPS-LIVE-SEQ-01, GND-12
#[test]
fn a_stale_copy_from_before_a_reboot_is_a_duplicate() {
    let mut t = ApidTracker::resume(Some(p(10, 50_000)));
    t.on_packet(p(12, 50_200), false, 0);
    // An old-boot packet with count 11 but a time outside the hole's span.
    assert_eq!(t.on_packet(p(11, 10_000), false, 0), Verdict::Duplicate);
    assert_eq!(t.on_packet(p(11, 50_100), false, 0), Verdict::Filled);
}

// verifies: OPS-LIVE-SEQ-01, GND-12, PUS-15-01
#[test]
fn store_end_report_gives_the_oldest_stored_packet() {
    let t = crate::pus::CdsShort::from_unix_ms(1_000_000);
    let tm = Tm {
        apid: 0x101,
        robot: Some(1),
        seq: 9,
        service: 15,
        subservice: 19,
        name: "STORE_DOWNLINK_DONE",
        msg_counter: 0,
        time: t,
        len: 0,
        body: TmBody::Report(Box::new(mib_wire::Tm::StoreDownlinkDone(
            mib_wire::tm::StoreDownlinkDone {
                packets: 7,
                oldest_time: mib_wire::CdsTime::from_unix_ms(t.unix_ms()),
                oldest_seq: 42,
                overwritten: 3,
            },
        ))),
    };
    let d = store_done(&tm).unwrap();
    assert_eq!(
        d,
        StoreDone {
            packets: 7,
            oldest: Some(Pos {
                seq: 42,
                obt_ms: 1_000_000
            }),
            overwritten: 3
        }
    );
}

// ---- retrieval pacing -------------------------------------------------------------------

/// A report of robot 1 on the TC with sequence count `tc_seq`: TM[1,7] (`sub` 7) or a
/// TM[1,2] acceptance failure (`sub` 2).
fn report(sub: u8, tc_seq: u16) -> Tm {
    let t = crate::pus::CdsShort::from_unix_ms(1_000_000).to_bytes();
    let psc = (0xC000 | tc_seq).to_be_bytes();
    let mut src = vec![0x19, 0x01, psc[0], psc[1]];
    if sub == 2 {
        src.extend_from_slice(&mib::failure::FailureCode::NOT_ALLOWED_IN_MODE.code().to_be_bytes());
        src.push(0);
    }
    crate::pus::decode_tm(&crate::pus::build_tm(0x101, 3, 1, sub, 0, &t, &src)).expect("a verification report")
}

/// The store's end report TM[15,19] of robot 1.
fn end_report() -> Tm {
    let t = crate::pus::CdsShort::from_unix_ms(1_000_000);
    Tm {
        apid: 0x101,
        robot: Some(1),
        seq: 4,
        service: 15,
        subservice: 19,
        name: "STORE_DOWNLINK_DONE",
        msg_counter: 0,
        time: t,
        len: 0,
        body: TmBody::Report(Box::new(mib_wire::Tm::StoreDownlinkDone(
            mib_wire::tm::StoreDownlinkDone {
                packets: 3,
                oldest_time: mib_wire::CdsTime::from_unix_ms(t.unix_ms()),
                oldest_seq: 0,
                overwritten: 0,
            },
        ))),
    }
}

/// The request ID of robot 1's TC with sequence count `seq` (what [`report`] answers).
fn rid(seq: u16) -> crate::pus::RequestId {
    crate::pus::RequestId::from_words(0x1901, 0xC000 | seq)
}

const TIMEOUT: i64 = mib::ground_config::STORE_REQUEST_TIMEOUT_MS as i64;
const MIN_GAP: i64 = mib::ground_config::STORE_REQUEST_MIN_GAP_MS as i64;

// verifies: OPS-PACE-01
#[test]
fn a_retrieval_is_in_flight_until_its_end_report_and_the_next_waits_the_least_gap() {
    let mut p = RetrievalPacer::default();
    assert!(p.may_send(0) && !p.in_flight(0), "nothing sent yet");
    p.on_sent(1_000, [rid(5)]);
    assert!(p.in_flight(1_010) && !p.may_send(1_010));
    // A replayed (old) end report ends nothing; the live one ends it.
    p.on_tm(&end_report(), false);
    assert!(p.in_flight(1_020));
    p.on_tm(&end_report(), true);
    assert!(!p.in_flight(1_020));
    // Ended early, the next still waits the least gap after the last one went out.
    assert!(!p.may_send(1_000 + MIN_GAP - 1));
    assert!(p.may_send(1_000 + MIN_GAP));
    assert_eq!((p.sent, p.timed_out), (1, 0));
}

// verifies: OPS-PACE-01
#[test]
fn a_retrieval_ends_with_its_tcs_completion_or_failure_not_another_tcs() {
    let mut p = RetrievalPacer::default();
    p.on_sent(0, [rid(5)]);
    p.on_tm(&report(7, 6), true);
    assert!(p.in_flight(10), "another TC's completion");
    p.on_tm(&report(7, 5), false);
    assert!(!p.in_flight(10), "its own completion, even replayed from the store");
    p.on_sent(MIN_GAP, [rid(8)]);
    p.on_tm(&report(2, 8), true);
    assert!(!p.in_flight(MIN_GAP + 10), "its acceptance failure");
    assert!(p.may_send(2 * MIN_GAP));
}

// verifies: OPS-PACE-01
#[test]
fn a_retrieval_whose_reports_are_lost_ends_at_the_timeout_counted() {
    let mut p = RetrievalPacer::default();
    p.on_sent(0, [rid(5)]);
    assert!(p.in_flight(TIMEOUT - 1) && !p.may_send(TIMEOUT - 1));
    assert!(!p.in_flight(TIMEOUT) && p.may_send(TIMEOUT));
    p.on_sent(TIMEOUT, [rid(6)]);
    assert_eq!((p.sent, p.timed_out), (2, 1));
    // A send that failed (no TC went) still spaces the next one.
    p.on_sent(2 * TIMEOUT, []);
    assert!(!p.in_flight(2 * TIMEOUT) && !p.may_send(2 * TIMEOUT + MIN_GAP - 1));
    assert_eq!(p.timed_out, 2);
}

// verifies: OPS-PACE-01
#[test]
fn a_round_of_several_ranges_is_one_retrieval_in_flight_until_each_ended() {
    let mut p = RetrievalPacer::new(2_000, 500);
    p.on_sent(0, [rid(5), rid(6)]);
    // The store answers in order: the first end report is the oldest TC's.
    p.on_tm(&end_report(), true);
    assert!(p.in_flight(100), "the second range is still being replayed");
    // The first TC's completion, after its end report, changes nothing.
    p.on_tm(&report(7, 5), true);
    assert!(p.in_flight(100));
    p.on_tm(&report(7, 6), true);
    assert!(!p.in_flight(100));
    assert!(!p.may_send(499) && p.may_send(500));
}

// ---- subscription -------------------------------------------------------------------------

// verifies: OPS-LIVE-LINK-04, GND-SUB-01
#[test]
fn a_heartbeat_is_due_every_retry_period_until_tm_only_a_subscriber_gets_comes() {
    let t = crate::pus::CdsShort::now().to_bytes();
    let tm =
        |svc, sub, src: &[u8]| crate::pus::decode_tm(&crate::pus::build_tm(0x101, 3, svc, sub, 0, &t, src)).unwrap();
    let mut s = Subscription::default();
    assert!(s.retry_due(true, false, None), "nothing sent yet");
    assert!(!s.retry_due(true, false, Some(SUBSCRIBE_RETRY_MS - 1)));
    assert!(s.retry_due(true, false, Some(SUBSCRIBE_RETRY_MS)));
    assert!(!s.retry_due(false, false, None), "TCP and frame links get TM anyway");
    assert!(!s.retry_due(true, true, None), "a lost link is the front end's backoff");
    // A refusal (TM[1,2]) and a connection-test reply reach an unsubscribed sender too.
    s.on_tm(&report(2, 1));
    s.on_tm(&tm(17, 2, &[]));
    assert!(!s.streaming() && s.retry_due(true, false, Some(SUBSCRIBE_RETRY_MS)));
    // A successful acceptance goes to subscribers only.
    s.on_tm(&report(1, 1));
    assert!(s.streaming() && !s.retry_due(true, false, Some(10 * SUBSCRIBE_RETRY_MS)));
    s.lapse();
    assert!(s.retry_due(true, false, Some(SUBSCRIBE_RETRY_MS)));
}
