//! Board A's frame link (`fw_core::spacelink::FrameLink`) and its key and counter area in
//! flash (`fw_core::link_store`) on the target: authenticated TC frames through the
//! serial uplink path (COBS → TC queue → TcReceiver → `Obsw::handle_tc`), executed once;
//! a replay and a wrong MAC refused, counted in SPACE_LINK and evented; TM frames out,
//! verified and demultiplexed by the ground's `TmReceiver` under the TM test key; the
//! counters and FARM-1's V(R) surviving a restart in the (mock) flash; the worst TC
//! frame's instruction count.

use crate::harness::{Test, TestResult};
use crate::tests;
use crate::{check, check_eq, ok};
use embedded_storage::nor_flash::{ErrorType, NorFlash, NorFlashErrorKind, ReadNorFlash};
use fw_core::config;
use fw_core::files::NoFiles;
use fw_core::link::{self, ByteQueue, Counters, TcChannel};
use fw_core::link_store::{self, FlashIvStore, KEY_RECORD_LEN, RECORDS_PER_SECTOR, SECTOR};
use fw_core::spacelink::{FrameLink, Keys};
use mib::params::pid;
use mmic_link::downlink::TmReceiver;
use mmic_link::sdls::{build_tc, IvStore, MemoryIvStore, RxSa, RxSas, TxSa};
use mmic_link::tc::{FrameType, TcRepr};
use mmic_link::test_keys::{TEST_KEY_TC_A, TEST_KEY_TC_B, TEST_KEY_TM_A};
use mmic_stream::{encode, Deframer};
use obsw_core::obsw::{Config, Obsw};
use obsw_core::tm::RingStore;

pub const TESTS: &[Test] = tests![
    framelink_key_record_round_trip_and_refusals,
    framelink_counter_log_rolls_over_and_survives_restart,
    framelink_authenticated_tc_executes_once_replay_and_wrong_mac_refused,
    framelink_bare_packets_control_frames_and_idle_frames,
];

/// RAM-backed NOR flash with NOR semantics (a write only clears bits; erase sets 0xFF).
#[derive(Clone)]
pub struct MockFlash {
    pub mem: [u8; 3 * SECTOR as usize],
    pub erases: u32,
}

impl MockFlash {
    pub fn erased() -> Self {
        MockFlash {
            mem: [0xFF; 3 * SECTOR as usize],
            erases: 0,
        }
    }
}

impl ErrorType for MockFlash {
    type Error = NorFlashErrorKind;
}

impl ReadNorFlash for MockFlash {
    const READ_SIZE: usize = 1;
    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Self::Error> {
        let o = offset as usize;
        let src = self.mem.get(o..o + bytes.len()).ok_or(NorFlashErrorKind::OutOfBounds)?;
        bytes.copy_from_slice(src);
        Ok(())
    }
    fn capacity(&self) -> usize {
        self.mem.len()
    }
}

impl NorFlash for MockFlash {
    const WRITE_SIZE: usize = 4;
    const ERASE_SIZE: usize = SECTOR as usize;
    fn erase(&mut self, from: u32, to: u32) -> Result<(), Self::Error> {
        if !from.is_multiple_of(SECTOR) || !to.is_multiple_of(SECTOR) {
            return Err(NorFlashErrorKind::NotAligned);
        }
        let r = self
            .mem
            .get_mut(from as usize..to as usize)
            .ok_or(NorFlashErrorKind::OutOfBounds)?;
        r.fill(0xFF);
        self.erases += 1;
        Ok(())
    }
    fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), Self::Error> {
        if !offset.is_multiple_of(4) || !bytes.len().is_multiple_of(4) {
            return Err(NorFlashErrorKind::NotAligned);
        }
        let o = offset as usize;
        let dst = self
            .mem
            .get_mut(o..o + bytes.len())
            .ok_or(NorFlashErrorKind::OutOfBounds)?;
        for (d, s) in dst.iter_mut().zip(bytes) {
            *d &= *s;
        }
        Ok(())
    }
}

pub(crate) fn test_keys() -> Keys {
    Keys {
        tc_spi: 1,
        tc_key: TEST_KEY_TC_A,
        tm_spi: 17,
        tm_key: TEST_KEY_TM_A,
    }
}

// verifies: FW-LINK-03
fn framelink_key_record_round_trip_and_refusals() -> TestResult {
    let k = test_keys();
    let rec = link_store::key_record(&k);
    check!(link_store::parse_keys(&rec) == Some(k));
    // Magic, CRC (little-endian CRC-32/ISO-HDLC of the 72 bytes before it) by hand.
    check_eq!(&rec[..4], b"MKY1");
    check_eq!(&rec[4..8], &[0, 1, 0, 17]);
    let crc = crate::t_support::crc32_bitwise(&rec[..72]);
    check_eq!(&rec[72..], &crc.to_le_bytes());
    // Erased flash, any flipped bit, the same key for both directions: no key.
    check!(link_store::parse_keys(&[0xFF; KEY_RECORD_LEN]).is_none());
    for bit in [0usize, 40, 8 * 8 + 3, 8 * 50, 8 * 75 + 7] {
        let mut bad = rec;
        bad[bit / 8] ^= 1 << (bit % 8);
        check!(link_store::parse_keys(&bad).is_none(), "bit {} flipped accepted", bit);
    }
    let same = link_store::key_record(&Keys {
        tm_key: TEST_KEY_TC_A,
        ..k
    });
    check!(link_store::parse_keys(&same).is_none());
    // Read from the area as the board does at boot.
    let mut flash = MockFlash::erased();
    check!(link_store::read_keys(&mut flash, 0).is_none());
    ok!(flash.write(0, &rec).ok());
    check!(link_store::read_keys(&mut flash, 0) == Some(k));
    Ok(())
}

// verifies: FW-LINK-04
fn framelink_counter_log_rolls_over_and_survives_restart() -> TestResult {
    let mut store = FlashIvStore::open(MockFlash::erased(), 0);
    check_eq!(store.resume(1, 17), Default::default());
    ok!(store.reserve_tx(17, 1024).ok());
    let farm = mmic_link::farm::FarmRecord {
        vr: 7,
        lockout: false,
        farm_b: 3,
    };
    // More records than two sectors hold: two rollovers.
    let n = 2 * RECORDS_PER_SECTOR as u128 + 40;
    for iv in 0..n {
        ok!(store
            .record_rx_farm(1, iv, mmic_link::farm::FarmRecord { vr: iv as u8, ..farm })
            .ok());
    }
    check_eq!(store.flash().erases, 2);
    let r = FlashIvStore::open(store.flash().clone(), 0).resume(1, 17);
    check_eq!(r.tc_last, Some(n - 1));
    check_eq!(r.tm_high_water, 1024);
    check_eq!(r.farm.map(|f| f.vr), Some((n - 1) as u8));
    // A record cut by a reset (its CRC does not match): the one before it counts.
    let mut torn = store.flash().clone();
    let mut reopened = FlashIvStore::open(torn.clone(), 0);
    ok!(reopened.record_rx(1, n + 5).ok());
    torn = reopened.flash().clone();
    // Find the record just written (value n + 5) and cut its last word.
    let want = (n + 5).to_be_bytes();
    let last =
        ok!((0..torn.mem.len() / 32)
            .find(|i| torn.mem[i * 32] == 0xC5 && torn.mem[i * 32 + 4..i * 32 + 16] == want[4..]));
    torn.mem[last * 32 + 28] ^= 0xFF;
    let opened = FlashIvStore::open(torn, 0);
    check_eq!(opened.resume(1, 17).tc_last, Some(n - 1));
    // Reported in HK (LINK_STATE_BAD_SLOT): the sector of the cut record.
    check_eq!(opened.bad_sector, if last * 32 < 2 * SECTOR as usize { 1 } else { 2 });
    // A failing flash refuses (the frame is then refused, never used unrecorded).
    let mut full = FlashIvStore::open(MockFlash::erased(), 2 * SECTOR);
    check!(full.record_rx(1, 0).is_err());
    check_eq!(full.failures, 1);
    Ok(())
}

/// A PUS TC[17,1] ping with sequence count `seq` (the robot's APID).
fn ping(seq: u16, buf: &mut [u8]) -> Option<usize> {
    crate::t_packets::build(seq, 17, 1, &[], buf)
}

/// COBS-frames `frame` into the uplink queue through the uplink path the task runs.
pub(crate) fn uplink(frame: &[u8], tcs: &TcChannel, stats: &Counters) {
    let mut cobs = [0u8; config::GROUND_FRAME_MAX];
    let n = encode(frame, &mut cobs).unwrap_or(0);
    let mut deframer: Deframer<{ config::GROUND_RX_BUF }> = Deframer::new();
    // In 64-byte pieces, as the USB driver delivers them.
    for chunk in cobs[..n].chunks(config::UART_READ_CHUNK) {
        link::uplink_bytes(&mut deframer, chunk, tcs, stats);
    }
}

/// What the ground made of the downlink: TM (service, subtype) pairs and the last CLCW.
#[derive(Default)]
struct Ground {
    tm: heapless::Vec<(u8, u8, u16), 64>,
    clcw_nr: Option<u8>,
    frames: u32,
    rejected: u32,
}

fn downlink<const N: usize>(q: &ByteQueue<N>, rx: &mut TmReceiver<1>, store: &mut MemoryIvStore, g: &mut Ground) {
    let mut bytes = [0u8; 4 * config::GROUND_FRAME_MAX];
    let n = link::drain(q, &mut bytes);
    let mut deframer: Deframer<{ mib::link::tm_frame::LEN }> = Deframer::new();
    let mut frame = [0u8; mib::link::tm_frame::LEN];
    for &b in &bytes[..n] {
        let len = match deframer.push(b) {
            Some(Ok(f)) => {
                frame[..f.len()].copy_from_slice(f);
                f.len()
            }
            Some(Err(_)) => {
                g.rejected += 1;
                continue;
            }
            None => continue,
        };
        let tm = &mut g.tm;
        match rx.receive(store, &mut frame[..len], |_, p| {
            if p.len() > 8 {
                // PUS-C TM secondary header: service at byte 7, subtype at byte 8.
                let _ = tm.push((p[7], p[8], u16::from_be_bytes([p[2], p[3]]) & 0x3FFF));
            }
        }) {
            Ok(c) => {
                g.frames += 1;
                g.clcw_nr = Some(c.report_value);
            }
            Err(_) => g.rejected += 1,
        }
    }
}

fn count(g: &Ground, svc: u8, sub: u8) -> usize {
    g.tm.iter().filter(|t| t.0 == svc && t.1 == sub).count()
}

fn instret() -> u64 {
    riscv::register::minstret::read64()
}

// verifies: FW-LINK-01, FW-LINK-02, FW-LINK-04, FW-LINK-05
fn framelink_authenticated_tc_executes_once_replay_and_wrong_mac_refused() -> TestResult {
    static TCS: TcChannel = TcChannel::new();
    static UP: Counters = Counters::new();
    static TM: ByteQueue<{ 4 * config::GROUND_FRAME_MAX }> = ByteQueue::new();
    static DOWN: Counters = Counters::new();
    const BUDGET: u64 = 160_000_000 / 2 / 1000 * mib::config::CONTROL_PERIOD_MS as u64 / 2;

    // Provisioning: the key record in the area, read back as the board does at boot.
    let mut flash = MockFlash::erased();
    ok!(flash.write(0, &link_store::key_record(&test_keys())).ok());
    let keys = ok!(link_store::read_keys(&mut flash, 0));
    let store = FlashIvStore::open(flash, 0);
    let resume = store.resume(keys.tc_spi, keys.tm_spi);
    let mut fl = FrameLink::new(Some(&keys), resume, store);
    let mut obsw = Obsw::new(
        Config {
            robot: 1,
            epoch_unix_ms: 0,
        },
        RingStore::<8192>::default(),
    );

    // The ground: TC SA 1 (test key), TM receiver SA 17 (test key).
    let mut tc_sa = TxSa::resume(1, &TEST_KEY_TC_A, 0);
    let mut ground_store = MemoryIvStore::default();
    let mut tm_sas: RxSas<1> = RxSas::default();
    check!(tm_sas.insert(RxSa::new(17, &TEST_KEY_TM_A, 4096)).is_ok());
    let mut tm_rx = TmReceiver::new(mib::link::SCID, tm_sas);
    let mut tm_store = MemoryIvStore::default();
    let mut g = Ground::default();

    let mut pkt = [0u8; 32];
    let n = ok!(ping(5, &mut pkt));
    let ad = |ns: u8| TcRepr {
        frame_type: FrameType::Ad,
        scid: mib::link::SCID,
        vcid: mib::link::tc_vc::COMMAND,
        seq: ns,
        data_len: 0,
    };
    let mut frame = [0u8; 128];
    let len = ok!(build_tc(&mut tc_sa, &mut ground_store, ad(0), &pkt[..n], &mut frame).ok());
    let captured = frame;

    // Period 1: the authentic frame.
    uplink(&frame[..len], &TCS, &UP);
    let (small_frame, _) = settle(&mut fl, &mut obsw, 10, &TCS, &TM, &DOWN);
    downlink(&TM, &mut tm_rx, &mut tm_store, &mut g);
    check_eq!(count(&g, 17, 2), 1, "ping executed once");
    check_eq!(count(&g, 1, 1), 1);
    check_eq!(count(&g, 1, 7), 1);
    check_eq!(g.clcw_nr, Some(1), "CLCW N(R) after one AD frame");
    check_eq!(g.rejected, 0);
    check_eq!(obsw.space_link[0], 1, "LINK_AD_ACCEPTED");
    check_eq!(
        (obsw.link_keys.tm, obsw.link_keys.tc),
        (1, 1),
        "keys of TM SPI 17, TC SPI 1"
    );
    // LINK_TM_SPI, LINK_TC_SPIS, LINK_STATE_WRITES (the frame's IV + FARM-1 record and the
    // first TM IV block), LINK_STATE_BAD_SLOT.
    check_eq!(obsw.space_link_state, [17, 1, 2, 0]);
    // The receive IV and FARM-1's V(R) are in flash before the ping ran.
    let r = FlashIvStore::open(fl.store().flash().clone(), 0).resume(1, 17);
    check_eq!(r.tc_last, Some(0));
    check_eq!(r.farm.map(|f| f.vr), Some(1));

    // Period 2: the captured frame replayed → refused, counted, evented, not executed.
    let mut again = captured;
    uplink(&again[..len], &TCS, &UP);
    check_eq!(count(&g, 5, 2), 0);
    settle(&mut fl, &mut obsw, 20, &TCS, &TM, &DOWN);
    downlink(&TM, &mut tm_rx, &mut tm_store, &mut g);
    check_eq!(count(&g, 17, 2), 1, "replay not executed");
    let rej_replay = (pid::LINK_REJ_REPLAY - pid::LINK_AD_ACCEPTED) as usize;
    check_eq!(obsw.space_link[rej_replay], 1, "LINK_REJ_REPLAY");
    check_eq!(
        count(&g, 5, 2),
        1,
        "one LINK_FRAME_REJECTED event (TM[5,2], low severity)"
    );

    // Period 3: a frame under the wrong key (N(S) 1) → bad MAC, not executed.
    let mut wrong_sa = TxSa::resume(1, &TEST_KEY_TC_B, 100);
    let n2 = ok!(ping(6, &mut pkt));
    let len2 = ok!(build_tc(&mut wrong_sa, &mut ground_store, ad(1), &pkt[..n2], &mut again).ok());
    uplink(&again[..len2], &TCS, &UP);
    settle(&mut fl, &mut obsw, 30, &TCS, &TM, &DOWN);
    downlink(&TM, &mut tm_rx, &mut tm_store, &mut g);
    check_eq!(count(&g, 17, 2), 1, "wrong key not executed");
    let rej_mac = (pid::LINK_REJ_BAD_MAC - pid::LINK_AD_ACCEPTED) as usize;
    check_eq!(obsw.space_link[rej_mac], 1, "LINK_REJ_BAD_MAC");
    check_eq!(count(&g, 5, 2), 2);
    check_eq!(g.clcw_nr, Some(1), "refused frames leave V(R)");

    // Period 4: the next authentic frame (N(S) 1), the largest the link takes: a PING
    // with 960 bytes of data (refused by PUS 17, but decrypted and verified in full).
    let mut big = [0u8; 1024];
    let data = [0x5Au8; 960];
    let nb = ok!(crate::t_packets::build(7, 17, 1, &data, &mut big));
    let mut bigframe = [0u8; 1024];
    let lb = ok!(build_tc(&mut tc_sa, &mut ground_store, ad(1), &big[..nb], &mut bigframe).ok());
    uplink(&bigframe[..lb], &TCS, &UP);
    let (big_frame, _) = settle(&mut fl, &mut obsw, 40, &TCS, &TM, &DOWN);
    downlink(&TM, &mut tm_rx, &mut tm_store, &mut g);
    check_eq!(obsw.space_link[0], 2, "LINK_AD_ACCEPTED");
    check_eq!(g.clcw_nr, Some(2));

    // After a restart (a new link from the same flash): V(R) continues at 2 and the
    // captured frame is still a replay.
    let resume = FlashIvStore::open(fl.store().flash().clone(), 0).resume(1, 17);
    let mut fl2 = FrameLink::new(Some(&keys), resume, FlashIvStore::open(fl.store().flash().clone(), 0));
    check_eq!(fl2.ep.rx.farm.vr(), 2);
    let replay = captured;
    uplink(&replay[..len], &TCS, &UP);
    settle(&mut fl2, &mut obsw, 50, &TCS, &TM, &DOWN);
    check_eq!(fl2.ep.rx.counters.replay, 1);
    check_eq!(fl2.ep.rx.counters.ad_accepted, 0);
    check_eq!(UP.get().overflow + UP.get().frame_errors, 0);

    semihosting::println!(
        "    TC frame through SDLS + FARM-1 + handle_tc: ping {} instructions, 1024-byte frame {} (budget {})",
        small_frame,
        big_frame,
        BUDGET
    );
    check!(small_frame > 1000, "instruction counter not running");
    check!(big_frame < BUDGET, "largest TC frame takes {} instructions", big_frame);
    Ok(())
}

// verifies: FW-LINK-02, FW-LINK-05
fn framelink_bare_packets_control_frames_and_idle_frames() -> TestResult {
    static TCS: TcChannel = TcChannel::new();
    static UP: Counters = Counters::new();
    static TM: ByteQueue<{ 4 * config::GROUND_FRAME_MAX }> = ByteQueue::new();
    static DOWN: Counters = Counters::new();
    let store = FlashIvStore::open(MockFlash::erased(), 0);
    let mut fl = FrameLink::new(Some(&test_keys()), Default::default(), store);
    let mut obsw = Obsw::new(
        Config {
            robot: 1,
            epoch_unix_ms: 0,
        },
        RingStore::<8192>::default(),
    );
    let mut tm_sas: RxSas<1> = RxSas::default();
    check!(tm_sas.insert(RxSa::new(17, &TEST_KEY_TM_A, 4096)).is_ok());
    let mut tm_rx = TmReceiver::new(mib::link::SCID, tm_sas);
    let mut tm_store = MemoryIvStore::default();
    let mut g = Ground::default();
    let off = |p: u16| (p - pid::LINK_AD_ACCEPTED) as usize;

    // A bare PUS TC (the old link's format) on the frame link: refused, counted, evented,
    // not executed.
    let mut pkt = [0u8; 32];
    let n = ok!(ping(9, &mut pkt));
    uplink(&pkt[..n], &TCS, &UP);
    settle(&mut fl, &mut obsw, 10, &TCS, &TM, &DOWN);
    downlink(&TM, &mut tm_rx, &mut tm_store, &mut g);
    check_eq!(obsw.space_link[off(pid::LINK_REJ_BARE_PACKET)], 1);
    check_eq!(count(&g, 17, 2), 0);
    check_eq!(count(&g, 5, 2), 1);

    // Seven Set V(R) control frames (in clear): to 9, refused (they would move V(R) away
    // from the ground's), then to 0, the present V(R), taken; one event per period. No
    // durable write for any of them.
    let mut bc = [0u8; 16];
    let repr = TcRepr {
        frame_type: FrameType::Bc,
        scid: mib::link::SCID,
        vcid: mib::link::tc_vc::COMMAND,
        seq: 0,
        data_len: 3,
    };
    let len = repr.buffer_len();
    repr.emit(&mut mmic_link::tc::TcFrame::new_unchecked(&mut bc[..len]));
    let writes = fl.store().writes;
    for i in 0..7u64 {
        bc[5..8].copy_from_slice(&[0x82, 0x00, if i < 2 { 9 } else { 0 }]);
        mmic_link::fecf::seal(&mut bc[..len]);
        uplink(&bc[..len], &TCS, &UP);
        fl.receive(100 + 10 * i, &mut obsw, &mut NoFiles, &TCS, &TM, &DOWN);
        fl.end_period(100 + 10 * i, &mut obsw, &TM, &DOWN);
    }
    downlink(&TM, &mut tm_rx, &mut tm_store, &mut g);
    check_eq!(obsw.space_link[off(pid::LINK_CONTROL_FRAMES)], 5);
    check_eq!(obsw.space_link[off(pid::LINK_REJ_CONTROL_STATE)], 2);
    check_eq!(fl.ep.rx.farm.vr(), 0);
    check_eq!(fl.store().writes, writes);
    check_eq!(g.clcw_nr, Some(0), "the CLCW goes out after each control frame");

    // Nothing to send once the control frames' event reports went out (their encryption
    // takes periods): an idle frame with the CLCW once 100 ms passed without a frame.
    let (_, last) = settle(&mut fl, &mut obsw, 170, &TCS, &TM, &DOWN);
    downlink(&TM, &mut tm_rx, &mut tm_store, &mut g);
    let frames = g.frames;
    let idle = tm_rx.counters.idle_frames;
    fl.end_period(last + 40, &mut obsw, &TM, &DOWN);
    downlink(&TM, &mut tm_rx, &mut tm_store, &mut g);
    check_eq!(g.frames, frames, "no idle frame within 100 ms");
    fl.end_period(last + 120, &mut obsw, &TM, &DOWN);
    downlink(&TM, &mut tm_rx, &mut tm_store, &mut g);
    check_eq!(tm_rx.counters.idle_frames, idle + 1);
    check_eq!(g.clcw_nr, Some(0));
    Ok(())
}

/// Control periods from `now` (1 ms apart) until the link has nothing left in work and
/// the uplink queue is empty (at most 16): the TC frame path's instructions, summed, and
/// the time of the last period.
pub fn settle<St, S, const N: usize>(
    fl: &mut FrameLink<St>,
    obsw: &mut Obsw<S>,
    now: u64,
    tcs: &TcChannel,
    tm: &ByteQueue<N>,
    down: &Counters,
) -> (u64, u64)
where
    St: mmic_link::sdls::IvStore + mmic_link::endpoint::StoreStats,
    S: obsw_core::tm::TmStore,
{
    let mut receive = 0;
    let mut last = now;
    for t in now..now + 16 {
        last = t;
        let start = instret();
        fl.receive(t, obsw, &mut NoFiles, tcs, tm, down);
        receive += instret() - start;
        fl.end_period(t, obsw, tm, down);
        if !fl.ep.busy() && tcs.is_empty() {
            break;
        }
    }
    (receive, last)
}
