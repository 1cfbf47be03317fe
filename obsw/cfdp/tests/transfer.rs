//! Two entities (ground 0, robot 1) over an in-memory link that loses, duplicates and
//! corrupts PDUs with a seeded generator; the clock advances by hand.

mod common;

use common::Rng;
use mmic_cfdp::spacepackets::cfdp::pdu::FileDirectiveType;
use mmic_cfdp::store::MemStore;
use mmic_cfdp::{Class, Entity, FileName, Parts};

/// Directive codes, as spacepackets defines them (CCSDS 727.0-B-5 table 5-4).
const EOF: u8 = FileDirectiveType::EofPdu as u8;
const FINISHED: u8 = FileDirectiveType::FinishedPdu as u8;
const ACK: u8 = FileDirectiveType::AckPdu as u8;
const NAK: u8 = FileDirectiveType::NakPdu as u8;

type Mem = MemStore<8, 120_000>;

/// The RAM stores hold their files inline: run on a stack that fits them.
fn big_stack(f: impl FnOnce() + Send + 'static) {
    std::thread::Builder::new()
        .stack_size(64 << 20)
        .spawn(f)
        .unwrap()
        .join()
        .unwrap();
}

thread_local! {
    static CLOCK: std::cell::Cell<u64> = const { std::cell::Cell::new(0) };
}

fn now() -> u64 {
    CLOCK.with(|c| c.get())
}

/// Moves PDUs both ways until both entities are idle (or `limit_ms` passes); `loss`
/// (and a quarter of it as duplicates) applies to the downlink, b to a. Returns the time
/// taken.
fn run(a: &mut Entity<Mem>, b: &mut Entity<Mem>, loss: f64, seed: u64, limit_ms: u64) -> u64 {
    let mut rng = Rng(seed);
    // The entities' clock never goes back: carry on from where the last run stopped.
    let start = CLOCK.with(|c| c.get());
    let mut now = start;
    while now < start + limit_ms {
        now += 10;
        a.poll(now);
        b.poll(now);
        for _ in 0..64 {
            let mut moved = false;
            while let Some(p) = a.pop() {
                moved = true;
                // Ground to robot: COP-1 retransmits every lost or refused TC frame, so the
                // uplink delivers each PDU once, in order (docs/space-link.md).
                deliver(&mut rng, 0.0, now, &p, b);
            }
            while let Some(p) = b.pop() {
                moved = true;
                deliver(&mut rng, loss, now, &p, a);
            }
            if !moved {
                break;
            }
        }
        if a.idle() && b.idle() {
            CLOCK.with(|c| c.set(now));
            return now - start;
        }
    }
    panic!(
        "not idle after {limit_ms} ms: a {:?} b {:?}",
        a.counters(),
        b.counters()
    );
}

fn deliver(rng: &mut Rng, loss: f64, now: u64, p: &[u8], to: &mut Entity<Mem>) {
    if rng.unit() < loss {
        return;
    }
    // A corrupted PDU never gets here: the frame's CRC and SDLS MAC refuse its frame, so
    // corruption is loss (the end-to-end test runs through a relay that corrupts frames).
    to.receive(now, p);
    if rng.unit() < loss / 4.0 {
        to.receive(now, p);
    }
}

fn file(len: usize, seed: u8) -> Vec<u8> {
    (0..len)
        .map(|i| (i as u8).wrapping_mul(31).wrapping_add(seed) ^ (i >> 8) as u8)
        .collect()
}

fn put_file(p: &Parts<Mem>, name: &str, data: &[u8]) {
    let n = FileName::new(name).unwrap();
    p.store.create(&n).unwrap();
    p.store.write(&n, 0, data).unwrap();
}

fn read_file(p: &Parts<Mem>, name: &str) -> Option<Vec<u8>> {
    let n = FileName::new(name).unwrap();
    let len = p.store.len(&n).unwrap()? as usize;
    let mut v = vec![0; len];
    p.store.read(&n, 0, &mut v).unwrap();
    Some(v)
}

// verifies: FILE-CFDP-04
#[test]
fn class_1_and_2_puts_and_gets_arrive_byte_identical_on_a_clean_link() {
    big_stack(|| {
        let (gp, rp) = (Parts::new(Mem::new(2_000_000)), Parts::new(Mem::new(2_000_000)));
        let mut g = Entity::new(0, 1, &gp);
        let mut r = Entity::new(1, 0, &rp);
        let up = file(50_000, 1);
        put_file(&gp, "up.bin", &up);
        for (class, name) in [(Class::One, "up1.bin"), (Class::Two, "up2.bin")] {
            g.put(now(), "up.bin", name, class).unwrap();
            run(&mut g, &mut r, 0.0, 1, 60_000);
            let got = read_file(&rp, name);
            assert!(
                got.as_deref() == Some(&up[..]),
                "{class:?}: {:?} bytes; {:?} {:?} {:?}",
                got.map(|g| g.len()),
                g.counters(),
                r.counters(),
                g.take_finished()
            );
            let f = g.take_finished().expect("sender's finished");
            assert!(f.sent && f.complete, "{f:?}");
        }
        let down = file(70_001, 7);
        put_file(&rp, "log.bin", &down);
        for (class, name) in [(Class::One, "down1.bin"), (Class::Two, "down2.bin")] {
            g.get(now(), "log.bin", name, class).unwrap();
            run(&mut g, &mut r, 0.0, 2, 60_000);
            assert!(read_file(&gp, name).as_deref() == Some(&down[..]), "{class:?}");
        }
        assert_eq!(r.counters().refused, 0);
        assert_eq!(g.counters().failed + r.counters().failed, 0);
    });
}

// verifies: FILE-CFDP-05
#[test]
fn class_2_recovers_lost_and_duplicated_downlink_pdus_both_ways() {
    big_stack(|| {
        let (gp, rp) = (Parts::new(Mem::new(2_000_000)), Parts::new(Mem::new(2_000_000)));
        let mut g = Entity::new(0, 1, &gp);
        let mut r = Entity::new(1, 0, &rp);
        let up = file(100_000, 3);
        put_file(&gp, "up.bin", &up);
        g.put(now(), "up.bin", "up.bin", Class::Two).unwrap();
        run(&mut g, &mut r, 0.2, 11, 600_000);
        let got = read_file(&rp, "up.bin");
        assert!(
            got.as_deref() == Some(&up[..]),
            "{:?} {:?} {:?} {:?} {:?}",
            got.map(|g| g.len()),
            g.counters(),
            r.counters(),
            std::iter::from_fn(|| g.take_finished()).collect::<Vec<_>>(),
            std::iter::from_fn(|| r.take_finished()).collect::<Vec<_>>()
        );
        let down = file(100_000, 9);
        put_file(&rp, "tm.bin", &down);
        g.get(now(), "tm.bin", "tm.bin", Class::Two).unwrap();
        run(&mut g, &mut r, 0.2, 12, 600_000);
        let got = read_file(&gp, "tm.bin");
        assert!(
            got.as_deref() == Some(&down[..]),
            "{:?} {:?} {:?} {:?} {:?}",
            got.map(|g| g.len()),
            g.counters(),
            r.counters(),
            g.take_finished(),
            r.take_finished()
        );
    });
}

// verifies: FILE-STORE-03
#[test]
fn listing_delete_and_rename_act_on_the_peers_store() {
    big_stack(|| {
        let (gp, rp) = (Parts::new(Mem::new(2_000_000)), Parts::new(Mem::new(10_000)));
        let mut g = Entity::new(0, 1, &gp);
        let mut r = Entity::new(1, 0, &rp);
        put_file(&rp, "a.txt", b"alpha");
        put_file(&rp, "b.txt", b"bravo!");
        g.filestore(now(), "a.txt", Some("c.txt")).unwrap();
        run(&mut g, &mut r, 0.0, 1, 60_000);
        g.filestore(now(), "b.txt", None).unwrap();
        run(&mut g, &mut r, 0.0, 1, 60_000);
        g.list(now(), "dir.lst").unwrap();
        run(&mut g, &mut r, 0.0, 1, 60_000);
        let l = String::from_utf8(read_file(&gp, "dir.lst").unwrap()).unwrap();
        assert_eq!(l, "c.txt 5\nfree 9995\n");
        // A name that would leave the store is refused at the robot, nothing changes.
        assert!(g.filestore(now(), "../c.txt", None).is_err(), "refused before sending");
        assert_eq!(r.counters().fs_done, 2);
    });
}

/// Directive code of a file directive PDU (`None` for file data).
fn directive(p: &[u8]) -> Option<u8> {
    let (h, hl) = spacepackets::cfdp::pdu::PduHeader::from_bytes(p).ok()?;
    (h.pdu_type() == spacepackets::cfdp::PduType::FileDirective).then(|| p[hl])
}

// verifies: FILE-CFDP-05
#[test]
fn a_finished_pdu_that_overtakes_a_lost_eof_ack_ends_the_put_without_a_retry() {
    big_stack(|| {
        let (gp, rp) = (Parts::new(Mem::new(200_000)), Parts::new(Mem::new(200_000)));
        let mut g = Entity::new(0, 1, &gp);
        let mut r = Entity::new(1, 0, &rp);
        let up = file(3_000, 9);
        put_file(&gp, "up.bin", &up);
        g.put(now(), "up.bin", "up.bin", Class::Two).unwrap();
        let start = now();
        let mut t = start;
        let mut lost_acks = 0;
        // Everything arrives but the robot's ACK of the EOF; no timer may expire.
        while t < start + mib::cfdp::ACK_TIMER_MS / 2 && !(g.idle() && r.idle()) {
            t += 10;
            g.poll(t);
            r.poll(t);
            while let Some(p) = g.pop() {
                r.receive(t, &p);
            }
            while let Some(p) = r.pop() {
                if directive(&p) == Some(ACK) && g.counters().completed == 0 && lost_acks == 0 {
                    lost_acks += 1;
                    continue;
                }
                g.receive(t, &p);
            }
        }
        CLOCK.with(|c| c.set(t));
        assert_eq!(lost_acks, 1, "the EOF's ACK was dropped");
        let f = g.take_finished().expect("the put ended before the positive ACK timer");
        assert!(f.sent && f.complete, "{f:?}");
        assert_eq!(read_file(&rp, "up.bin").as_deref(), Some(&up[..]));
        assert_eq!(g.counters().eof_ack_by_finished, 1, "{:?}", g.counters());
    });
}

// verifies: FILE-CFDP-05
#[test]
fn a_put_to_a_silent_peer_ends_reported_as_not_complete() {
    big_stack(|| {
        let gp = Parts::new(Mem::new(200_000));
        let mut g = Entity::new(0, 1, &gp);
        put_file(&gp, "up.bin", &file(3_000, 3));
        let start = now();
        g.put(start, "up.bin", "up.bin", Class::Two).unwrap();
        let mut t = start;
        let mut f = None;
        while f.is_none() && t < start + 2 * mib::cfdp::INACTIVITY_MS {
            t += 100;
            g.poll(t);
            while g.pop().is_some() {}
            f = g.take_finished();
        }
        CLOCK.with(|c| c.set(t));
        let f = f.expect("the put ended");
        assert!(f.sent && !f.complete, "{f:?}");
        assert!(
            matches!(
                f.condition,
                spacepackets::cfdp::ConditionCode::InactivityDetected
                    | spacepackets::cfdp::ConditionCode::PositiveAckLimitReached
            ),
            "{f:?}"
        );
        // One put, one failure (HK FILES counts it).
        assert_eq!(g.counters().failed, 1, "{:?}", g.counters());
        assert_eq!(g.counters().completed, 0);
    });
}

// verifies: FILE-CFDP-05
#[test]
fn a_finished_pdu_sent_again_after_a_lost_ack_is_acknowledged_again_by_the_ended_sender() {
    big_stack(|| {
        let (gp, rp) = (Parts::new(Mem::new(200_000)), Parts::new(Mem::new(200_000)));
        let mut g = Entity::new(0, 1, &gp);
        let mut r = Entity::new(1, 0, &rp);
        let down = file(5_000, 4);
        put_file(&rp, "down.bin", &down);
        r.put(now(), "down.bin", "down.bin", Class::Two).unwrap();
        let start = now();
        let mut t = start;
        let (mut lost_acks, mut finished_sent) = (0, 0);
        // The robot's first ACK of the ground's Finished is lost on the downlink; the ground
        // sends its Finished again after its positive ACK timer.
        while t < start + 6 * mib::cfdp::ACK_TIMER_MS && !(g.idle() && r.idle()) {
            t += 10;
            g.poll(t);
            r.poll(t);
            while let Some(p) = g.pop() {
                finished_sent += usize::from(directive(&p) == Some(FINISHED));
                r.receive(t, &p);
            }
            while let Some(p) = r.pop() {
                if directive(&p) == Some(ACK) && lost_acks == 0 {
                    lost_acks += 1;
                    continue;
                }
                g.receive(t, &p);
            }
        }
        CLOCK.with(|c| c.set(t));
        assert_eq!(lost_acks, 1, "the Finished PDU's ACK was dropped");
        assert!(g.idle() && r.idle(), "ended: g {:?} r {:?}", g.counters(), r.counters());
        assert_eq!(
            finished_sent,
            2,
            "one Finished PDU again, then its ACK: {:?}",
            g.counters()
        );
        let f = g.take_finished().expect("the ground's receiving transaction ended");
        assert!(!f.sent && f.complete, "{f:?}");
        assert_eq!(g.counters().faults, 0, "{:?}", g.counters());
        assert_eq!(read_file(&gp, "down.bin").as_deref(), Some(&down[..]));
    });
}

// verifies: FILE-CFDP-06
#[test]
fn a_file_cut_short_is_never_kept_under_its_name_and_a_restart_discards_the_rest() {
    big_stack(|| {
        let (gp, rp) = (Parts::new(Mem::new(200_000)), Parts::new(Mem::new(200_000)));
        let mut g = Entity::new(0, 1, &gp);
        let mut r = Entity::new(1, 0, &rp);
        put_file(&gp, "up.bin", &file(20_000, 4));
        put_file(&rp, "up.bin", b"the old version");
        let start = now();
        g.put(start, "up.bin", "up.bin", Class::Two).unwrap();
        // The link dies after the metadata and some data: the robot abandons on inactivity.
        let (mut t, mut sent) = (start, 0);
        let (mut ended, mut looked) = (None, false);
        while ended.is_none() && t < start + 2 * mib::cfdp::INACTIVITY_MS {
            t += 10;
            g.poll(t);
            r.poll(t);
            while let Some(p) = g.pop() {
                if sent < 6 {
                    r.receive(t, &p);
                    sent += 1;
                }
            }
            while r.pop().is_some() {}
            if sent == 6 && !looked {
                looked = true;
                let mut names = Vec::new();
                rp.store.list(&mut |n, _| names.push(n.as_str().to_string())).unwrap();
                assert!(
                    names.iter().any(|n| n.starts_with("partial-0-")),
                    "received under a staging name: {names:?} {:?}",
                    r.counters()
                );
            }
            ended = r.take_finished();
        }
        CLOCK.with(|c| c.set(t));
        let f = ended.expect("the robot ended the transfer");
        assert!(!f.complete, "{f:?}");
        assert_eq!(
            read_file(&rp, "up.bin").as_deref(),
            Some(&b"the old version"[..]),
            "the old file stays"
        );
        assert_eq!(read_file(&rp, "partial-0-0"), None, "the partial file is removed");
        // A reset in the middle leaves a staging file; the next start removes it.
        put_file(&rp, "partial-0-7", b"half");
        assert_eq!(Entity::new(1, 0, &rp).discard_partial(), 1);
        assert_eq!(read_file(&rp, "partial-0-7"), None);
        assert!(read_file(&rp, "up.bin").is_some());
    });
}

// The robot's NAK goes down, where nothing but its NAK timer recovers a lost one; the
// ground answers with file data in BD frames at once. A lost NAK costs one NAK timer
// (NAK_TIMER_MS, the link's round trip, not Yamcs' 4 s), and answers still coming in after
// that timer's period hold its next NAK back.
// verifies: FILE-BD-02
#[test]
fn the_robots_nak_lost_on_the_downlink_is_sent_again_after_its_own_timer_not_while_answers_arrive() {
    big_stack(|| {
        let (gp, rp) = (Parts::new(Mem::new(200_000)), Parts::new(Mem::new(200_000)));
        let mut g = Entity::new(0, 1, &gp);
        let mut r = Entity::new(1, 0, &rp);
        let seg = mib::cfdp::MAX_SEGMENT_LEN;
        let up = file(40 * seg, 5);
        put_file(&gp, "up.bin", &up);
        g.put(now(), "up.bin", "up.bin", Class::Two).unwrap();
        let start = now();
        let mut t = start;
        let (mut naks, mut nak_times) = (0, Vec::new());
        // Answers to the second NAK reach the robot one per `slow` ms.
        let slow = mib::cfdp::NAK_QUIET_MS - 50;
        let mut late: std::collections::VecDeque<(u64, Vec<u8>)> = Default::default();
        let mut sent = std::collections::HashSet::new();
        while t < start + 20_000 && !(g.idle() && r.idle()) {
            t += 10;
            g.poll(t);
            r.poll(t);
            while let Some(p) = g.pop() {
                if directive(&p).is_none() {
                    let (_, hl) = spacepackets::cfdp::pdu::PduHeader::from_bytes(&p).unwrap();
                    let off = u32::from_be_bytes(p[hl..hl + 4].try_into().unwrap()) as usize;
                    // The first sending of the last ten segments is lost on the uplink.
                    if sent.insert(off) && off >= 30 * seg {
                        continue;
                    }
                    if naks >= 2 {
                        let at = late.back().map_or(t, |(a, _)| *a) + slow;
                        late.push_back((at, p.to_vec()));
                        continue;
                    }
                }
                r.receive(t, &p);
            }
            while late.front().is_some_and(|(a, _)| *a <= t) {
                let (_, p) = late.pop_front().unwrap();
                r.receive(t, &p);
            }
            while let Some(p) = r.pop() {
                if directive(&p) == Some(NAK) {
                    naks += 1;
                    nak_times.push(t);
                    // The first NAK of the deferred procedure is lost.
                    if naks == 1 {
                        continue;
                    }
                }
                g.receive(t, &p);
            }
        }
        CLOCK.with(|c| c.set(t));
        assert_eq!(read_file(&rp, "up.bin").as_deref(), Some(&up[..]), "byte-identical");
        assert!(nak_times.len() >= 2, "{nak_times:?}");
        let gap = nak_times[1] - nak_times[0];
        assert!(
            (mib::cfdp::NAK_TIMER_MS..mib::cfdp::YAMCS_NAK_TIMER_MS).contains(&gap),
            "the lost NAK sent again after the robot's timer: {nak_times:?}"
        );
        // Ten answers at `slow` intervals take longer than the timer: no NAK among them.
        let answers_end = nak_times[1] + 10 * slow;
        assert!(
            nak_times[2..].iter().all(|&n| n >= answers_end),
            "a NAK while the answers came in: {nak_times:?}"
        );
    });
}

// `ground file put` holds its BD file data until COP-1 has delivered the metadata: it
// must know the metadata PDU when it sees one.
// verifies: FILE-BD-01
#[test]
fn a_put_opens_with_a_metadata_pdu_and_only_that_pdu_is_taken_for_one() {
    big_stack(|| {
        let gp = Parts::new(Mem::new(200_000));
        let mut g = Entity::new(0, 1, &gp);
        put_file(&gp, "up.bin", &file(3 * mib::cfdp::MAX_SEGMENT_LEN, 1));
        g.put(now(), "up.bin", "up.bin", Class::Two).unwrap();
        g.poll(now() + 10);
        let first = g.pop().expect("the metadata");
        assert!(mmic_cfdp::entity::is_metadata(&first));
        let data = g.pop().expect("file data");
        assert!(directive(&data).is_none() && !mmic_cfdp::entity::is_metadata(&data));
        assert!(!mmic_cfdp::entity::is_metadata(&first[..3]), "a short PDU");
    });
}

/// The segment requests of a NAK PDU.
fn nak_requests(p: &[u8]) -> Vec<(u64, u64)> {
    let nak = spacepackets::cfdp::pdu::nak::NakPduReader::from_bytes(p).unwrap();
    nak.get_segment_requests_iterator().into_iter().flatten().collect()
}

// A ground held up by its scheduler takes a burst of downlink PDUs in one go: more gaps
// than its outbox holds immediate NAKs, then the EOF. Each gap must be recorded once and
// the EOF taken whole (acknowledged or not), so that one NAK after the EOF asks for each
// missing byte once and its answers end the transfer; cfdp-rs 0.3's handler left the
// overlapping gaps of its stopped procedure in every NAK, and the robot resent only the
// first segment of each such request: a 256 KiB `get` through the relay took 117 s.
// verifies: FILE-CFDP-05
#[test]
fn a_burst_with_more_gaps_than_the_outbox_holds_is_asked_for_once_and_ends_the_get() {
    big_stack(|| {
        let (gp, rp) = (Parts::new(Mem::new(200_000)), Parts::new(Mem::new(200_000)));
        let mut g = Entity::new(0, 1, &gp);
        let mut r = Entity::new(1, 0, &rp);
        let seg = mib::cfdp::MAX_SEGMENT_LEN;
        let down = file(100 * seg + 17, 9);
        put_file(&rp, "log.bin", &down);
        g.get(now(), "log.bin", "log.bin", Class::Two).unwrap();
        let start = now();
        let mut t = start;
        let mut burst: Vec<Vec<u8>> = Vec::new();
        let mut sent = std::collections::HashSet::new();
        let mut naks: Vec<Vec<(u64, u64)>> = Vec::new();
        while t < start + 30_000 && !(g.idle() && r.idle()) {
            t += 10;
            g.poll(t);
            r.poll(t);
            while let Some(p) = g.pop() {
                if directive(&p) == Some(NAK) {
                    naks.push(nak_requests(&p));
                }
                r.receive(t, &p);
            }
            while let Some(p) = r.pop() {
                if directive(&p).is_none() {
                    let (_, hl) = spacepackets::cfdp::pdu::PduHeader::from_bytes(&p).unwrap();
                    let off = u32::from_be_bytes(p[hl..hl + 4].try_into().unwrap()) as usize;
                    // Every third segment's first sending is lost: 33 gaps.
                    if sent.insert(off) && (off / seg) % 3 == 1 {
                        continue;
                    }
                }
                burst.push(p.to_vec());
            }
            // The ground takes what came down every 600 ms, all at once, and only then
            // sends what its entity made.
            if t.is_multiple_of(600) {
                for p in burst.drain(..) {
                    g.receive(t, &p);
                }
            }
        }
        CLOCK.with(|c| c.set(t));
        assert_eq!(read_file(&gp, "log.bin").as_deref(), Some(&down[..]), "byte-identical");
        for (i, n) in naks.iter().enumerate() {
            let mut sorted = n.clone();
            sorted.sort();
            assert!(
                sorted.windows(2).all(|w| w[0].1 <= w[1].0),
                "NAK {i} asks for bytes twice: {n:?}"
            );
        }
        // The data, the deferred NAK's answers, the Finished and its ACK: a few bursts.
        assert!(t - start < 6_000, "{} ms; NAKs {naks:?}", t - start);
    });
}

// A NAK whose segment requests overlap (a peer's own, or one request covering segments an
// earlier one already queued): every segment asked for is sent again once, the ones after
// an already queued one too.
// verifies: FILE-CFDP-05
#[test]
fn overlapping_segment_requests_of_a_nak_are_each_sent_again_once() {
    big_stack(|| {
        let (gp, rp) = (Parts::new(Mem::new(200_000)), Parts::new(Mem::new(200_000)));
        let mut g = Entity::new(0, 1, &gp);
        let mut r = Entity::new(1, 0, &rp);
        let seg = mib::cfdp::MAX_SEGMENT_LEN as u64;
        let down = file(20 * seg as usize, 3);
        put_file(&rp, "log.bin", &down);
        g.get(now(), "log.bin", "log.bin", Class::Two).unwrap();
        let mut t = now();
        let mut eof = None;
        // The robot's transaction never reaches the ground: it sends its file and its EOF,
        // then waits.
        while eof.is_none() && t < now() + 10_000 {
            t += 10;
            g.poll(t);
            r.poll(t);
            while let Some(p) = g.pop() {
                r.receive(t, &p);
            }
            while let Some(p) = r.pop() {
                let (h, _) = spacepackets::cfdp::pdu::PduHeader::from_bytes(&p).unwrap();
                if spacepackets::util::UnsignedEnum::value(&h.common_pdu_conf().source_id()) == 1 {
                    if directive(&p) == Some(EOF) {
                        eof = Some(*h.common_pdu_conf());
                    }
                    continue;
                }
                g.receive(t, &p);
            }
        }
        let mut conf = eof.expect("the robot's EOF");
        conf.direction = spacepackets::cfdp::Direction::TowardsSender;
        let s = 4 * seg;
        let requests = [(s as u32, (s + seg) as u32), (s as u32, (s + 3 * seg) as u32)];
        let nak = spacepackets::cfdp::pdu::nak::NakPduCreator::new_normal_file_size(
            spacepackets::cfdp::pdu::PduHeader::new_for_file_directive(conf, 0),
            0,
            down.len() as u32,
            &requests,
        )
        .unwrap();
        let mut buf = [0u8; 256];
        let n = spacepackets::cfdp::pdu::WritablePduPacket::write_to_bytes(&nak, &mut buf).unwrap();
        r.receive(t, &buf[..n]);
        let mut resent = Vec::new();
        for _ in 0..10 {
            t += 10;
            r.poll(t);
            while let Some(p) = r.pop() {
                if directive(&p).is_none() {
                    let (_, hl) = spacepackets::cfdp::pdu::PduHeader::from_bytes(&p).unwrap();
                    resent.push(u32::from_be_bytes(p[hl..hl + 4].try_into().unwrap()) as u64);
                }
            }
        }
        CLOCK.with(|c| c.set(t));
        assert_eq!(resent, [s, s + seg, s + 2 * seg]);
    });
}

// Through the relay a quarter of the robot's PDUs are lost, again on each round trip: the
// ground asks again as soon as the answer to its NAK's last request arrived (the sender
// answers in order: the rest was lost) instead of after `NAK_QUIET_MS` of silence, and a
// segment asked for a second time comes down twice.
// verifies: FILE-CFDP-05
#[test]
fn the_next_nak_follows_the_answer_to_the_last_request_and_a_segment_asked_for_again_comes_twice() {
    big_stack(|| {
        let (gp, rp) = (Parts::new(Mem::new(200_000)), Parts::new(Mem::new(200_000)));
        let mut g = Entity::new(0, 1, &gp);
        let mut r = Entity::new(1, 0, &rp);
        let seg = mib::cfdp::MAX_SEGMENT_LEN;
        let down = file(12 * seg, 7);
        put_file(&rp, "log.bin", &down);
        g.get(now(), "log.bin", "log.bin", Class::Two).unwrap();
        let start = now();
        let mut t = start;
        let mut sends: std::collections::HashMap<usize, usize> = Default::default();
        let (mut last_answer_at, mut naks) = (None, Vec::new());
        while t < start + 20_000 && !(g.idle() && r.idle()) {
            t += 10;
            g.poll(t);
            r.poll(t);
            while let Some(p) = g.pop() {
                if directive(&p) == Some(NAK) {
                    naks.push((t, nak_requests(&p)));
                }
                r.receive(t, &p);
            }
            while let Some(p) = r.pop() {
                if directive(&p).is_none() {
                    let (_, hl) = spacepackets::cfdp::pdu::PduHeader::from_bytes(&p).unwrap();
                    let off = u32::from_be_bytes(p[hl..hl + 4].try_into().unwrap()) as usize;
                    let n = sends.entry(off).or_default();
                    *n += 1;
                    // Segments 4 and 5 are lost on their first sending, segment 4 on its
                    // second too; the answer to the first NAK's last request (5) arrives.
                    if (off == 4 * seg && *n <= 2) || (off == 5 * seg && *n == 1) {
                        continue;
                    }
                    if off == 5 * seg {
                        last_answer_at = Some(t);
                    }
                }
                g.receive(t, &p);
            }
        }
        CLOCK.with(|c| c.set(t));
        assert_eq!(read_file(&gp, "log.bin").as_deref(), Some(&down[..]), "byte-identical");
        let (s4, s5) = ((4 * seg) as u64, (5 * seg) as u64);
        assert_eq!(naks[0].1, [(s4, s5 + seg as u64)], "first NAK: {naks:?}");
        assert_eq!(naks[1].1, [(s4, s5)], "second NAK: {naks:?}");
        let answered = last_answer_at.expect("segment 5 came down again");
        assert!(
            naks[1].0 - answered < mib::cfdp::NAK_QUIET_MS / 3,
            "the second NAK {} ms after the answer to the first's last request",
            naks[1].0 - answered
        );
        assert_eq!(
            sends[&(4 * seg)],
            4,
            "segment 4: once, once again, then twice: {sends:?}"
        );
        assert_eq!(sends[&(5 * seg)], 2, "segment 5 asked for once again: {sends:?}");
    });
}

// A copy of a segment that arrives after the file was found complete (the relay duplicates
// frames, a segment asked for again comes twice) changes nothing: the file is already under
// its final name, and the transaction still ends complete with no fault.
// verifies: FILE-CFDP-05
#[test]
fn file_data_after_the_file_is_complete_is_dropped_and_the_put_still_ends_complete() {
    big_stack(|| {
        let (gp, rp) = (Parts::new(Mem::new(200_000)), Parts::new(Mem::new(200_000)));
        let mut g = Entity::new(0, 1, &gp);
        let mut r = Entity::new(1, 0, &rp);
        let up = file(5 * mib::cfdp::MAX_SEGMENT_LEN + 3, 11);
        put_file(&gp, "up.bin", &up);
        g.put(now(), "up.bin", "up.bin", Class::Two).unwrap();
        let start = now();
        let mut t = start;
        let (mut first_data, mut replayed) = (None, false);
        while t < start + 10_000 && !(g.idle() && r.idle()) {
            t += 10;
            g.poll(t);
            r.poll(t);
            while let Some(p) = g.pop() {
                if directive(&p).is_none() && first_data.is_none() {
                    first_data = Some(p.to_vec());
                }
                r.receive(t, &p);
            }
            while let Some(p) = r.pop() {
                if directive(&p) == Some(FINISHED) && !replayed {
                    // The robot found the file complete: a copy of its first segment now.
                    r.receive(t, first_data.as_deref().unwrap());
                    replayed = true;
                }
                g.receive(t, &p);
            }
        }
        CLOCK.with(|c| c.set(t));
        assert!(replayed);
        assert_eq!(read_file(&rp, "up.bin").as_deref(), Some(&up[..]), "byte-identical");
        let f = r.take_finished().expect("the robot's report");
        assert!(f.complete, "{f:?}");
        let c = r.counters();
        assert_eq!((c.faults, c.completed, c.failed), (0, 1, 0), "{c:?}");
        assert!(c.stray >= 1, "{c:?}");
        let f = g.take_finished().expect("the ground's report");
        assert!(f.complete, "{f:?}");
    });
}

// The robot's metadata and Finished PDUs go down twice (a quarter of the downlink is lost
// through the relay; a lost metadata PDU costs the ground every segment before the next
// copy), the ground's once (COP-1 delivers them); a repeated one acts once.
// verifies: FILE-CFDP-05
#[test]
fn the_robots_metadata_and_finished_pdus_go_down_twice_and_act_once() {
    big_stack(|| {
        let (gp, rp) = (Parts::new(Mem::new(200_000)), Parts::new(Mem::new(200_000)));
        let mut g = Entity::new(0, 1, &gp);
        let mut r = Entity::new(1, 0, &rp);
        let data = file(3 * mib::cfdp::MAX_SEGMENT_LEN + 5, 13);
        put_file(&gp, "up.bin", &data);
        put_file(&rp, "log.bin", &data);
        let count = |pdus: &[Vec<u8>], d: u8, src: u64| {
            pdus.iter()
                .filter(|p| {
                    let (h, _) = spacepackets::cfdp::pdu::PduHeader::from_bytes(p).unwrap();
                    directive(p) == Some(d)
                        && spacepackets::util::UnsignedEnum::value(&h.common_pdu_conf().source_id()) == src
                })
                .count()
        };
        for get in [false, true] {
            if get {
                g.get(now(), "log.bin", "down.bin", Class::Two).unwrap();
            } else {
                g.put(now(), "up.bin", "up.bin", Class::Two).unwrap();
            }
            let start = now();
            let mut t = start;
            let (mut up, mut down, mut polls) = (Vec::new(), Vec::new(), Vec::new());
            while t < start + 10_000 && !(g.idle() && r.idle()) {
                t += 10;
                g.poll(t);
                r.poll(t);
                while let Some(p) = g.pop() {
                    up.push(p.to_vec());
                    r.receive(t, &p);
                }
                while let Some(p) = r.pop() {
                    down.push(p.to_vec());
                    polls.push(t);
                    g.receive(t, &p);
                }
            }
            // The copies leave in another control period than the first (another frame).
            let when = |d: u8| {
                let mut ts: Vec<u64> = (0..down.len())
                    .filter(|&i| count(&down[i..=i], d, if get { 1 } else { 0 }) == 1)
                    .map(|i| polls[i])
                    .collect();
                ts.dedup();
                ts.len()
            };
            CLOCK.with(|c| c.set(t));
            const METADATA: u8 = FileDirectiveType::MetadataPdu as u8;
            if get {
                // The request (a ground transaction) once; the robot's put of the file twice.
                assert_eq!(count(&up, METADATA, 0), 1);
                assert_eq!(count(&down, METADATA, 1), 2);
                assert_eq!(when(METADATA), 2, "the two copies in two periods");
                assert_eq!(read_file(&gp, "down.bin").as_deref(), Some(&data[..]));
            } else {
                assert_eq!(count(&up, METADATA, 0), 1);
                assert_eq!(count(&down, FINISHED, 0), 2, "the robot's Finished of the put");
                assert_eq!(when(FINISHED), 2, "the two copies in two periods");
                assert_eq!(read_file(&rp, "up.bin").as_deref(), Some(&data[..]));
            }
        }
        let (gc, rc) = (g.counters(), r.counters());
        assert_eq!(
            (gc.faults, gc.failed, rc.faults, rc.failed),
            (0, 0, 0, 0),
            "{gc:?} {rc:?}"
        );
        let reports: Vec<_> = std::iter::from_fn(|| g.take_finished()).collect();
        assert!(reports.iter().all(|f| f.complete), "{reports:?}");
    });
}

// A receiver that ends the transaction while the sender still sends its file data (its
// store refused a write: Finished "filestore rejection" before the sender's EOF). 727.0-B-5
// has the sender take a Finished PDU at any time: it answers with the ACK and ends the
// transaction with the Finished's condition. cfdp-rs 0.3 refuses a Finished before its
// EOF's ACK step; the entity ends the put itself, reported as not complete with the
// receiver's condition, never as delivered, and the rest of the file is not sent (before,
// the ground sent all 50 000 bytes and refused the robot's Finished 29 times until its EOF).
// verifies: FILE-CFDP-09
#[test]
fn a_finished_pdu_while_the_sender_still_sends_ends_the_put_not_complete_with_its_condition() {
    use mmic_cfdp::spacepackets::cfdp::ConditionCode;
    big_stack(|| {
        // The robot's store takes 3 000 bytes: the fourth segment is refused.
        let (gp, rp) = (Parts::new(Mem::new(2_000_000)), Parts::new(Mem::new(3_000)));
        let mut g = Entity::new(0, 1, &gp);
        let mut r = Entity::new(1, 0, &rp);
        put_file(&gp, "big.bin", &file(50_000, 3));
        let mut t = now();
        g.put(t, "big.bin", "big.bin", Class::Two).unwrap();
        // Poll by poll, each PDU at once both ways, until the robot's Finished has reached
        // the ground: the ground is still sending then (50 000 bytes, 3 segments a poll).
        let mut robot_finished = false;
        for _ in 0..20 {
            t += 10;
            g.poll(t);
            while let Some(p) = g.pop() {
                r.receive(t, &p);
            }
            r.poll(t);
            while let Some(p) = r.pop() {
                robot_finished |= directive(&p) == Some(FINISHED);
                g.receive(t, &p);
            }
            if robot_finished {
                break;
            }
        }
        assert!(robot_finished, "the robot sent no Finished: {:?}", r.counters());
        assert!(
            g.sent_progress().0 < 50_000,
            "the ground had sent its whole file already ({})",
            g.sent_progress().0
        );
        // The put ended there: no file data after it, nothing refused by the handler.
        let sent = g.sent_progress().0;
        assert!(g.idle(), "the ground still sends: {:?}", g.counters());
        CLOCK.with(|c| c.set(t));
        run(&mut g, &mut r, 0.0, 5, 60_000);
        assert_eq!(g.sent_progress().0, sent, "file data sent after the robot's Finished");
        assert_eq!(g.counters().handler_errors, 0, "{:?}", g.counters());
        let f = g.take_finished().expect("the put ended");
        assert!(!f.complete, "reported complete: {f:?}");
        assert_eq!(f.condition, ConditionCode::FilestoreRejection, "{f:?}");
        assert!(g.take_finished().is_none(), "a second end of the same put");
        assert_eq!(read_file(&rp, "big.bin"), None);
    });
}
