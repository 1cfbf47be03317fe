//! The control period's CPU budget and the stack of its deepest path, on the code the
//! images run (this binary is built with the images' optimisation level). Board A's link
//! spreads its SDLS work over periods (`fw_core::spacelink::SDLS_WORK_PER_PERIOD`): this
//! test runs the link's periods for the largest TC frame (1 024 bytes) arriving while a
//! full TM frame and a partly filled one wait for their encryption, measures every
//! period's link work (`FrameLink::receive` and `end_period`: the MAC check, decryption,
//! FARM-1, the counter record, the packet executed, the TM frames built and encrypted)
//! and adds to the largest the worst `Obsw::tick` and the worst `Obsw::handle_tc` of
//! `t_obsw` (the one packet a period may execute, counted again in full; or the file
//! service's worst period, `t_files`, when larger: the largest file data packet, a
//! checksum paced at `mib::cfdp::CHECKSUM_BYTES_PER_POLL`, an EOF's period), and the worst
//! period's store work in board A's flash store (`t_store`: its writes and the worst period
//! of a paced PUS 15 replay from a full store). Both sums must be
//! inside `mib::config::PERIOD_INSTRUCTION_BUDGET` (50 % of a 10 ms period at 160 MHz
//! and the assumed 2 cycles per instruction): the run fails otherwise. The OBSW and the
//! link sit in statics as in board A's image, so the stack measured here is the path's own.

use crate::harness::{self, Test, TestResult};
use crate::t_framelink::{test_keys, uplink, MockFlash};
use crate::tests;
use crate::{check, ok};
use aes_gcm::aes::cipher::{BlockEncrypt, KeyInit};
use core::mem::MaybeUninit;
use core::ptr::addr_of_mut;
use embedded_storage::nor_flash::NorFlash;
use fw_core::config;
use fw_core::files::NoFiles;
use fw_core::link::{ByteQueue, Counters, TcChannel};
use fw_core::link_store::{self, FlashIvStore};
use fw_core::spacelink::{FrameLink, SDLS_WORK_PER_PERIOD};
use mib::config::{PERIOD_INSTRUCTIONS, PERIOD_INSTRUCTION_BUDGET};
use mmic_link::sdls::{build_tc, MemoryIvStore, TxSa};
use mmic_link::tc::{FrameType, TcRepr};
use mmic_link::test_keys::TEST_KEY_TC_A;
use obsw_core::obsw::{Config, Obsw};
use obsw_core::tm::RingStore;
use portable_atomic::{AtomicU64, Ordering};

pub const TESTS: &[Test] = tests![control_period_with_the_largest_tc_frame_measured];

type Store = RingStore<{ config::TM_STORE_BYTES }>;
type Link = FrameLink<FlashIvStore<MockFlash>>;
static mut OBSW: MaybeUninit<Obsw<Store>> = MaybeUninit::uninit();
static mut LINK: MaybeUninit<Link> = MaybeUninit::uninit();

fn instret() -> u64 {
    riscv::register::minstret::read64()
}

/// Periods the scenario may take (the TC frames in 3 and 2, the TM frames in 3 each).
const MAX_PERIODS: usize = 16;

// verifies: FW-CPU-01
fn control_period_with_the_largest_tc_frame_measured() -> TestResult {
    static TCS: TcChannel = TcChannel::new();
    static UP: Counters = Counters::new();
    static TM: ByteQueue<{ config::TM_DOWNLINK_BYTES }> = ByteQueue::new();
    static DOWN: Counters = Counters::new();

    let mut flash = MockFlash::erased();
    ok!(flash.write(0, &link_store::key_record(&test_keys())).ok());
    let keys = ok!(link_store::read_keys(&mut flash, 0));
    let store = FlashIvStore::open(flash, 0);
    let resume = store.resume(keys.tc_spi, keys.tm_spi);
    // Statics, as board A keeps them (written once here; this test is their only user).
    // SAFETY: the test runs once on the one hart; nothing else refers to these statics.
    let (obsw, fl) = unsafe {
        let obsw = (*addr_of_mut!(OBSW)).write(Obsw::new(
            Config {
                robot: 1,
                epoch_unix_ms: 0,
            },
            Store::default(),
        ));
        let fl = (*addr_of_mut!(LINK)).write(FrameLink::new(Some(&keys), resume, store));
        (obsw, fl)
    };

    // The largest frame the link takes (1024 bytes): a PING with 974 bytes of data
    // (refused by PUS 17 after it was decrypted and verified in full), N(S) 0.
    let mut tc_sa = TxSa::resume(1, &TEST_KEY_TC_A, 0);
    let mut ground_store = MemoryIvStore::default();
    let mut big = [0u8; 1024];
    let nb = ok!(crate::t_packets::build(7, 17, 1, &[0x5A; 974], &mut big));
    let mut frame = [0u8; 1024];
    let ad = TcRepr {
        frame_type: FrameType::Ad,
        scid: mib::link::SCID,
        vcid: mib::link::tc_vc::COMMAND,
        seq: 0,
        data_len: 0,
    };
    let len = ok!(build_tc(&mut tc_sa, &mut ground_store, ad, &big[..nb], &mut frame).ok());
    check!(len == mib::link::tc_frame::MAX_LEN, "frame of {} bytes", len);

    // TM waiting when the frame comes: 12 packets of 91 bytes (a ROBOT_STATUS report's
    // size) fill one TM frame and start the next.
    let mut hk = [0u8; 91];
    let nh = ok!(crate::t_packets::build(9, 17, 1, &[0xA5; 78], &mut hk));
    let start = instret();
    for _ in 0..12 {
        fl.send_tm(&hk[..nh], &TM, &DOWN);
    }
    let per_packet = (instret() - start) / 12;
    uplink(&frame[..len], &TCS, &UP);
    // Then a frame whose MAC check ends on a period's boundary (768 bytes of ciphertext:
    // 48 blocks), so that one period runs a whole period's work of CTR, the frame's
    // acceptance (FARM-1, the counter record) and its packet: the busiest TC period.
    let mut aligned = [0u8; 1024];
    let na = ok!(crate::t_packets::build(8, 17, 1, &[0x5A; 755], &mut aligned));
    check!(na == SDLS_WORK_PER_PERIOD * 16, "packet of {} bytes", na);
    let mut frame2 = [0u8; 1024];
    let len2 = ok!(build_tc(
        &mut tc_sa,
        &mut ground_store,
        TcRepr { seq: 1, ..ad },
        &aligned[..na],
        &mut frame2
    )
    .ok());
    uplink(&frame2[..len2], &TCS, &UP);

    let ((), stack) = harness::stack_depth(|| {
        for (i, slot) in PERIODS.iter().enumerate() {
            let now = 10 * (i as u64 + 1);
            let t0 = instret();
            fl.receive(now, obsw, &mut NoFiles, &TCS, &TM, &DOWN);
            fl.end_period(now, obsw, &TM, &DOWN);
            slot.store(instret() - t0, Ordering::Relaxed);
            TM_FRAMES.fetch_add(encrypted_tm_frames(&TM), Ordering::Relaxed);
            if obsw.space_link[0] >= 1 && ACCEPTED_IN.load(Ordering::Relaxed) == 0 {
                ACCEPTED_IN.store(i as u64 + 1, Ordering::Relaxed);
            }
            if !fl.ep.busy() && TCS.is_empty() {
                break;
            }
        }
    });
    let periods: heapless::Vec<u64, MAX_PERIODS> = PERIODS
        .iter()
        .map(|p| p.load(Ordering::Relaxed))
        .take_while(|&p| p > 0)
        .collect();
    let link = periods.iter().copied().max().unwrap_or(0);
    let accepted_in = ACCEPTED_IN.load(Ordering::Relaxed);
    let tm_frames = TM_FRAMES.load(Ordering::Relaxed);
    check!(obsw.space_link[0] == 2, "both frames were accepted (LINK_AD_ACCEPTED)");
    check!(
        tm_frames >= 2,
        "the waiting TM went out in encrypted frames ({})",
        tm_frames
    );
    check!(!fl.ep.busy(), "the link finished its work in {} periods", MAX_PERIODS);

    // The software AES block cipher's share of the busiest period: at most the period's
    // work blocks through AES, and the tag's block.
    let aes_blocks = SDLS_WORK_PER_PERIOD as u64 + 1;
    let aes = aes_gcm::aes::Aes256::new(&TEST_KEY_TC_A.into());
    let mut buf = [aes_gcm::aes::Block::default(); 2];
    let start = instret();
    for _ in 0..aes_blocks.div_ceil(2) {
        aes.encrypt_blocks(&mut buf);
    }
    let aes_cost = instret() - start;

    // What a frame's SDLS work is made of, per 16-byte block: AES (above), GHASH (a MAC
    // check of 1 024 bytes that fails: 64 blocks, the lengths block and the tag's AES
    // block) and the FECF's table CRC-16 over a whole frame.
    let gcm = mmic_link::gcm::Gcm::new(&TEST_KEY_TC_A);
    let mut data = [0x5Au8; 1024];
    let start = instret();
    let mut job = gcm.begin_decrypt(&[0; 12], &[], data.len(), &[0; 16]);
    let refused = job.step(&gcm, &mut data, usize::MAX);
    let ghash = (instret() - start).saturating_sub(aes_cost / aes_blocks) / 65;
    check!(refused == mmic_link::gcm::Progress::Refused, "a wrong tag is refused");
    let start = instret();
    let crc = mmic_link::fecf::crc16(core::hint::black_box(&data));
    let crc_cost = instret() - start;
    let start = instret();
    let bitwise = crate::t_packets::crc16_reference(core::hint::black_box(&data));
    let bitwise_cost = instret() - start;
    check!(bitwise == crc, "the table CRC is the bit-by-bit one");
    let mut copy = [0u8; 1024];
    let start = instret();
    copy.copy_from_slice(core::hint::black_box(&data));
    let copy_cost = instret() - start;
    core::hint::black_box(&copy);
    semihosting::println!(
        "    per 16-byte block: software AES-256 {} instructions, GHASH {}; CRC-16 of a 1 024-byte frame {} with the table, {} bit by bit; a 1 024-byte copy {}",
        aes_cost / aes_blocks,
        ghash,
        crc_cost,
        bitwise_cost,
        copy_cost
    );

    let tick = harness::WORST_TICK.load(Ordering::Relaxed);
    let tc = harness::WORST_TC.load(Ordering::Relaxed);
    check!(tick > 1000, "t_obsw ran before and recorded the worst tick ({})", tick);
    check!(tc > 1000, "t_obsw ran before and recorded the worst handle_tc ({})", tc);
    // The period's one packet may be the file service's work instead (`t_files`: the
    // largest file data packet written to the store, a paced checksum, an EOF's period,
    // each with the service's poll).
    let file_data = harness::WORST_FILE_DATA.load(Ordering::Relaxed);
    check!(
        file_data > 1000,
        "t_files ran before and recorded a file data period ({})",
        file_data
    );
    let file = file_data.max(harness::WORST_FILE_PERIOD.load(Ordering::Relaxed));
    // The file service polls every period: after a TC it reads nothing of the store
    // (`FileService::tc_handled`), its timers and directives only.
    let quiet_poll = harness::WORST_FILE_QUIET_POLL.load(Ordering::Relaxed);
    check!(quiet_poll > 0, "t_files ran before and measured a poll after a packet");
    let tc = tc + quiet_poll;
    let packet = tc.max(file);
    // The tick's and the TC's own TM packets go into the open TM frame on the board
    // (`t_obsw`'s sink only records them, its work not counted): the most one tick and one
    // TC sent, at the measured cost per packet.
    let tick_packets = harness::MOST_TICK_PACKETS.load(Ordering::Relaxed);
    let tc_packets = harness::MOST_TC_PACKETS.load(Ordering::Relaxed);
    let framing = (tick_packets + tc_packets) * per_packet;
    let period = tick + framing + packet + link;
    // Their store writes into board A's flash store, beyond the RAM ring `t_obsw` has, with
    // the store's end of period (`t_store`'s worst period): inside the enforced figure.
    let store = harness::STORE_WRITES_EXTRA.load(Ordering::Relaxed);
    check!(store > 0, "t_store ran before and measured the store writes");
    // A paced PUS 15 replay from a full flash store runs in the same period: its worst
    // period's reading and the packets it sent, into the open TM frame (`t_store`).
    let replay_read = harness::REPLAY_READ_WORST.load(Ordering::Relaxed);
    let replay_sent = harness::REPLAY_MOST_SENT.load(Ordering::Relaxed);
    check!(replay_read > 0, "t_store ran before and measured a paced replay");
    let replay = replay_read + replay_sent * per_packet;
    let with_store = period + store + replay;
    // The ESP32-C3's AES accelerator instead (analysis, not run: QEMU has none; a bring-up
    // item): per block four key-independent word writes, the start, a busy poll over its
    // 14-round latency and four reads, with the driver's call around it. It shortens the
    // periods that run CTR by at most this much; GHASH (the MAC check's periods) stays.
    let accelerator_saves = aes_cost.saturating_sub(aes_blocks * AES_ACCELERATOR_INSTRUCTIONS_PER_BLOCK);
    let pct = |x: u64| x as f64 * 100.0 / PERIOD_INSTRUCTIONS as f64;
    let budget = PERIOD_INSTRUCTION_BUDGET as u64;
    semihosting::println!("    link work per period (instructions): {:?}", periods.as_slice());
    semihosting::println!(
        "    a {}-byte TM packet into the open TM frame (the frame it fills built, not encrypted): {} instructions",
        nh,
        per_packet
    );
    semihosting::println!(
        "    largest TC frame accepted in period {} of {}, {} encrypted TM frames; {} GCM work blocks per period",
        accepted_in,
        periods.len(),
        tm_frames,
        SDLS_WORK_PER_PERIOD,
    );
    semihosting::println!(
        "    control period, software AES (measured): worst tick {} + its and the TC's TM packets into the frame {} ({} + {} packets) + worst handle_tc with the file service's poll after it {} (or the file service's worst period of a put, a get or an EOF {}: a file data packet written or a segment read and sent, a paced checksum, the EOF) + busiest link period {} = {} instructions, {:.1} % of the {} a period holds at {} cycles/instruction (budget {} %, margin {} instructions, {:.1} points)",
        tick,
        framing,
        tick_packets,
        tc_packets,
        tc,
        file,
        link,
        period,
        pct(period),
        PERIOD_INSTRUCTIONS,
        mib::config::ASSUMED_CYCLES_PER_INSTRUCTION,
        mib::config::PERIOD_CPU_BUDGET_PCT,
        budget as i64 - period as i64,
        mib::config::PERIOD_CPU_BUDGET_PCT as f64 - pct(period),
    );
    semihosting::println!(
        "    software AES-256 in a period: at most {} instructions ({} blocks); the AES accelerator (analysis, {} instructions per block) would save up to {} of them in a period that runs CTR, none in one that runs GHASH",
        aes_cost,
        aes_blocks,
        AES_ACCELERATOR_INSTRUCTIONS_PER_BLOCK,
        accelerator_saves,
    );
    semihosting::println!(
        "    stack high-water of the TC frame and TM framing path (OBSW and link in statics): {} bytes",
        stack
    );
    check!(stack > 256, "stack measurement ran ({} bytes)", stack);
    check!(
        stack < harness::STACK_PROBE_BYTES,
        "stack deeper than the painted {} bytes",
        harness::STACK_PROBE_BYTES
    );
    semihosting::println!(
        "    with the period's store work in board A's flash store (t_store, enforced): {} + store writes {} + a paced replay's worst period from a full store {} (reading {} + {} packets into the frame) = {} instructions, {:.1} % of the period: {} the {} % budget",
        period,
        store,
        replay,
        replay_read,
        replay_sent,
        with_store,
        pct(with_store),
        if with_store <= budget { "inside" } else { "OVER" },
        mib::config::PERIOD_CPU_BUDGET_PCT,
    );
    // A file's checksum is summed `CHECKSUM_BYTES_PER_POLL` a period (the sender during
    // its file data, the receiver holding the EOF), whatever the file's size: that sum at
    // the measured cost per KiB, in place of the period's packet (enforced), and the
    // periods the board store's largest file takes.
    let per_kib = harness::CHECKSUM_PER_KIB.load(Ordering::Relaxed);
    check!(per_kib > 0, "t_files ran before and measured the checksum");
    let paced = (mib::cfdp::CHECKSUM_BYTES_PER_POLL as u64).div_ceil(1024) * per_kib;
    let with_sum = (with_store - packet) + paced.max(packet);
    let largest = mib::cfdp::BOARD_STORE_BYTES as u64;
    semihosting::println!(
        "    a file's checksum paced at {} bytes a period ({} instructions a KiB from the RAM store): {} instructions a period, with the rest of the period {} instructions, {:.1} % of the period: {} the {} % budget (enforced); the board store's largest file ({} KiB) summed in {} periods",
        mib::cfdp::CHECKSUM_BYTES_PER_POLL,
        per_kib,
        paced,
        with_sum,
        pct(with_sum),
        verdict(with_sum),
        mib::config::PERIOD_CPU_BUDGET_PCT,
        largest / 1024,
        largest.div_ceil(mib::cfdp::CHECKSUM_BYTES_PER_POLL as u64),
    );
    semihosting::println!(
        "    control period CPU budget {} instructions, with the store work: software AES {} (the AES accelerator, analysis, only lowers it)",
        PERIOD_INSTRUCTION_BUDGET,
        verdict(with_store),
    );
    check!(
        period <= budget,
        "control period {} instructions over the budget of {}",
        period,
        budget
    );
    check!(
        with_store <= budget,
        "control period with its store work {} instructions over the budget of {}",
        with_store,
        budget
    );
    check!(
        with_sum <= budget,
        "control period with a paced checksum {} instructions over the budget of {}",
        with_sum,
        budget
    );
    Ok(())
}

/// Each period's link work, out of the closure whose stack is measured.
static PERIODS: [AtomicU64; MAX_PERIODS] = [const { AtomicU64::new(0) }; MAX_PERIODS];
/// The period (1-based) in which the TC frame was accepted.
static ACCEPTED_IN: AtomicU64 = AtomicU64::new(0);
/// Encrypted TM frames the periods sent.
static TM_FRAMES: AtomicU64 = AtomicU64::new(0);

/// Instructions per AES block on the ESP32-C3's accelerator, by analysis (ESP32-C3 TRM,
/// AES accelerator, typical mode): 4 text-register writes, the trigger, a busy poll of the
/// state register over the AES-256 latency, 4 result reads, with esp-hal's call and loop
/// around them. Not measured: QEMU has no accelerator; a board's cycle counter measures
/// it at bring-up.
const AES_ACCELERATOR_INSTRUCTIONS_PER_BLOCK: u64 = 100;

/// "inside" or "OVER" the period's CPU budget.
fn verdict(instructions: u64) -> &'static str {
    if instructions <= PERIOD_INSTRUCTION_BUDGET as u64 {
        "inside"
    } else {
        "OVER"
    }
}

/// TM frames in the downlink queue that are not idle frames (VC 7, in clear).
fn encrypted_tm_frames<const N: usize>(q: &ByteQueue<N>) -> u64 {
    let mut bytes = [0u8; 4 * config::GROUND_FRAME_MAX];
    let n = fw_core::link::drain(q, &mut bytes);
    let mut deframer: mmic_stream::Deframer<{ mib::link::tm_frame::LEN }> = mmic_stream::Deframer::new();
    let mut frames = 0;
    for &b in &bytes[..n] {
        if let Some(Ok(f)) = deframer.push(b) {
            // TM primary header: version (2 bits), SCID (10), VCID (3), OCF flag (1).
            if f.len() > 1 && (f[1] >> 1) & 7 != mib::link::tm_vc::IDLE {
                frames += 1;
            }
        }
    }
    frames
}
