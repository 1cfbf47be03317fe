//! Writes the seed corpora under `tests/fuzz/corpus/<target>/` from the project's own
//! code: TCs from the MIB's definitions, TM the OBSW sends while the simulator runs, TC
//! frames sealed with the test keys, A–B frames board B sends, team messages, and the
//! repository's plan and module-set files. Run from the repository root:
//! `cargo +nightly run --manifest-path tests/fuzz/Cargo.toml --example seeds`.
//! Deterministic: the same tree gives the same files.

use std::fs;
use std::path::{Path, PathBuf};

use heapless::Vec as HVec;
use mmic_domain::ablink::{Message as AbMessage, ModuleCmd};
use mmic_domain::board_b::{BoardB, BoardBOut};
use mmic_domain::types::SensorsB;
use mmic_fuzz::{pus_tc::tc, push_record};
use mmic_link::clcw::Clcw;
use mmic_link::downlink::{TmFramer, TmVc};
use mmic_link::sdls::{build_tc, MemoryIvStore, TxSa};
use mmic_link::tc::{ControlCommand, FrameType, TcRepr};
use mmic_link::test_keys::{TEST_KEY_TC_A, TEST_KEY_TC_B, TEST_KEY_TM_A, TEST_KEY_TM_B};
use mmic_team::{Body, Directive, Message as TeamMessage, PlanRef, TeamFunction};
use obsw_core::obsw::{Config, Obsw};
use obsw_core::tm::{RingStore, TmSink};

struct Corpus {
    dir: PathBuf,
}

impl Corpus {
    fn new(root: &Path, target: &str) -> Corpus {
        let dir = root.join(target);
        fs::create_dir_all(&dir).expect("corpus folder");
        Corpus { dir }
    }
    fn put(&self, name: &str, bytes: &[u8]) {
        fs::write(self.dir.join(name), bytes).expect("write seed");
    }
}

/// One valid TC per MIB definition (arguments at their minimum), sequence count = index.
fn mib_tcs() -> Vec<(String, Vec<u8>)> {
    mib::tc::TCS
        .iter()
        .enumerate()
        .map(|(i, d)| {
            let args: Vec<i64> = d.args.iter().map(|a| a.min).collect();
            let mut app = vec![0u8; 64];
            let n = mib_wire::codec::encode_args(d, &args, &mut app).expect("MIB minimum arguments encode");
            (
                d.name.to_ascii_lowercase(),
                tc(i as u16, d.service, d.subservice, &app[..n]),
            )
        })
        .collect()
}

#[derive(Default)]
struct Sink(Vec<Vec<u8>>);
impl TmSink for Sink {
    fn send_tm(&mut self, p: &[u8]) {
        self.0.push(p.to_vec());
    }
}

/// The TM the OBSW sends in its first 1.5 s against the simulator, after a ping.
fn real_tm() -> Vec<Vec<u8>> {
    let mut o = Box::new(Obsw::new(
        Config {
            robot: 1,
            epoch_unix_ms: 1_790_000_000_000,
        },
        RingStore::<8192>::default(),
    ));
    let mut sim = mmic_sim::Sim::new(mmic_sim::SimConfig::default());
    let mut sink = Sink::default();
    let mut link = Vec::new();
    o.handle_tc(0, &tc(0, 17, 1, &[]), &mut sink);
    for k in 1..=150 {
        let s = sim.sensors_a();
        let out = o.tick(k * 10, &s, &link, &mut sink);
        link.clear();
        sim.step(10, &out.actuators, &out.link_tx, &mut link);
    }
    sink.0
}

fn sealed(sa: &mut TxSa, st: &mut MemoryIvStore, ty: FrameType, ns: u8, payload: &[u8]) -> Vec<u8> {
    let h = TcRepr {
        frame_type: ty,
        scid: mib::link::SCID,
        vcid: mib::link::tc_vc::COMMAND,
        seq: ns,
        data_len: 0,
    };
    let mut buf = [0u8; 1024];
    let n = build_tc(sa, st, h, payload, &mut buf).expect("frame fits");
    buf[..n].to_vec()
}

fn control(c: ControlCommand) -> Vec<u8> {
    let mut buf = [0u8; 16];
    let n = c
        .build_frame(mib::link::SCID, mib::link::tc_vc::COMMAND, &mut buf)
        .expect("BC frame fits");
    buf[..n].to_vec()
}

fn tc_frame_rx(root: &Path, tcs: &[(String, Vec<u8>)]) {
    let c = Corpus::new(root, "tc_frame_rx");
    let ping = &tcs.iter().find(|(n, _)| n == "ping").expect("PING in the MIB").1;
    // A ground with a key this robot does not hold: real frames, refused at the MAC.
    let (mut foreign, mut fst) = (TxSa::resume(1, &TEST_KEY_TC_B, 0), MemoryIvStore::default());
    let mut s = Vec::new();
    push_record(&mut s, 1, &[[0u8, 0].as_slice(), ping].concat());
    c.put("ad_ping", &s);
    // A session: AD 0, 1, a gap (3), a BD frame, the buffer released, Set V(R), Unlock.
    let mut s = Vec::new();
    for (i, (_, p)) in tcs.iter().take(3).enumerate() {
        push_record(&mut s, 1, &[[0u8, i as u8].as_slice(), p].concat());
    }
    push_record(&mut s, 1, &[[4u8, 3].as_slice(), &tcs[3].1].concat());
    push_record(&mut s, 2, &[[2u8].as_slice(), &tcs[4].1].concat());
    push_record(&mut s, 3, &[]);
    push_record(&mut s, 0, &control(ControlCommand::SetVr(7)));
    push_record(&mut s, 1, &[[0u8, 7].as_slice(), ping].concat());
    push_record(&mut s, 0, &control(ControlCommand::Unlock));
    c.put("session_ad_gap_bd_setvr_unlock", &s);
    // Raw datagrams alone.
    let foreign_ad = sealed(&mut foreign, &mut fst, FrameType::Ad, 0, ping);
    let raws: [(&str, Vec<u8>); 6] = [
        ("raw_foreign_key_ad", foreign_ad.clone()),
        (
            "raw_foreign_key_bd",
            sealed(&mut foreign, &mut fst, FrameType::Bd, 0, &tcs[1].1),
        ),
        ("raw_setvr", control(ControlCommand::SetVr(200))),
        ("raw_unlock", control(ControlCommand::Unlock)),
        ("raw_bare_packet", ping.clone()),
        ("raw_truncated_frame", foreign_ad[..12].to_vec()),
    ];
    for (name, d) in raws {
        let mut s = Vec::new();
        push_record(&mut s, 0, &d);
        c.put(name, &s);
    }
    // Two packets in one frame, and a payload to be wrapped into a packet by the harness.
    let mut s = Vec::new();
    push_record(&mut s, 1, &[[0u8, 0].as_slice(), &tcs[0].1, &tcs[2].1].concat());
    push_record(
        &mut s,
        1,
        &[[1u8, 1].as_slice(), b"wrapped by the harness".as_slice()].concat(),
    );
    c.put("two_packets_and_wrapped", &s);
}

fn pus_tc(root: &Path, tcs: &[(String, Vec<u8>)]) {
    let c = Corpus::new(root, "pus_tc");
    for (k, chunk) in tcs.chunks(8).enumerate() {
        let mut s = Vec::new();
        for (_, p) in chunk {
            // Tag 2: ticks after each TC, so the long-running ones make progress.
            push_record(&mut s, 2, p);
        }
        c.put(&format!("mib_tcs_{k}"), &s);
    }
    let mut s = Vec::new();
    let mut bad_crc = tcs[0].1.clone();
    *bad_crc.last_mut().expect("non-empty") ^= 0xFF;
    push_record(&mut s, 0, &bad_crc);
    push_record(&mut s, 4, &tcs[1].1);
    push_record(&mut s, 4, &tcs[1].1);
    push_record(&mut s, 1, &tcs[2].1[..tcs[2].1.len() - 3]);
    c.put("bad_crc_duplicate_truncated", &s);
}

fn cobs(frame: &[u8]) -> Vec<u8> {
    let mut out = vec![0u8; mmic_stream::encoded_len(frame.len())];
    let n = mmic_stream::encode(frame, &mut out).expect("buffer of encoded_len");
    out.truncate(n);
    out
}

fn cobs_deframer(root: &Path, tcs: &[(String, Vec<u8>)], tm_frame: &[u8]) {
    let c = Corpus::new(root, "cobs_deframer");
    c.put("one_tc", &cobs(&tcs[0].1));
    c.put("two_tcs", &[cobs(&tcs[0].1), cobs(&tcs[5].1)].concat());
    c.put(
        "garbage_then_tc",
        &[b"\x13\x37garbage".as_slice(), &cobs(&tcs[1].1)].concat(),
    );
    c.put("tm_frame_oversize", &cobs(tm_frame));
    let mut cut = cobs(&tcs[2].1);
    cut.truncate(cut.len() / 2);
    c.put("cut_then_tc", &[cut, cobs(&tcs[3].1)].concat());
}

fn ab_link(root: &Path) {
    let c = Corpus::new(root, "ab_link");
    // Board B's own output: acks, heartbeats and module chunks, from a B with the full
    // robot's table.
    let mut b = BoardB::new();
    let input = mmic_sim::modules::ModuleSetSpec::full().discovery_input();
    b.set_modules(input.table_b.as_deref().unwrap_or(&[]), input.probes_b);
    let sensors = SensorsB {
        v_bat: 2900,
        grav: [0, 0, 1000],
        arm_switch: true,
        ..SensorsB::default()
    };
    let mut out = BoardBOut::default();
    let mut cmd: HVec<u8, 256> = HVec::new();
    AbMessage::Command {
        seq: 1,
        cmd: ModuleCmd::Power {
            arm: 1,
            grip: 1,
            bolter: 0,
        },
    }
    .encode(&mut cmd)
    .expect("fits");
    let mut from_b = Vec::new();
    for k in 0..30u64 {
        let rx: &[u8] = if k == 0 { &cmd } else { &[] };
        b.tick(k * 10, &sensors, rx, &mut out);
        from_b.extend_from_slice(&out.tx);
    }
    let mut s = Vec::new();
    push_record(&mut s, 0, &from_b);
    c.put("board_b_output", &s);
    let mut s = Vec::new();
    push_record(&mut s, 1, &cmd);
    push_record(&mut s, 1, &cmd);
    c.put("command_and_resend_to_b", &s);
    let mut s = Vec::new();
    for sel in [[0u8, 0x05, 0xDC], [3, 1, 1], [2, 1, 2], [4, 0, 0], [6, 0, 0]] {
        push_record(&mut s, 2, &sel);
    }
    push_record(&mut s, 0, &from_b[..from_b.len().min(200)]);
    c.put("a_commands_b", &s);
}

fn team(root: &Path) {
    let c = Corpus::new(root, "team_packet");
    let plan = PlanRef {
        id: 7,
        hash: 0xDEAD_BEEF,
    };
    let msg = |sender: u8, term: u32, body: Body| TeamMessage {
        term,
        sender,
        plan,
        progress: 2,
        body,
    };
    let msgs = [
        ("request_vote", msg(2, 1, Body::RequestVote)),
        (
            "vote",
            msg(
                3,
                1,
                Body::Vote {
                    candidate: 1,
                    granted: true,
                },
            ),
        ),
        (
            "heartbeat_hold",
            msg(
                2,
                2,
                Body::LeaderHeartbeat {
                    stamp: 1234,
                    directive: Directive::Hold,
                },
            ),
        ),
        (
            "heartbeat_continue",
            msg(
                2,
                2,
                Body::LeaderHeartbeat {
                    stamp: 1300,
                    directive: Directive::Continue {
                        step: 3,
                        function: TeamFunction::BoltFace,
                    },
                },
            ),
        ),
        ("heartbeat_ack", msg(3, 2, Body::HeartbeatAck { stamp: 1234, ok: true })),
    ];
    let emit = |m: &TeamMessage| {
        let mut b = vec![0u8; m.buffer_len()];
        let n = m.emit(&mut b).expect("fits");
        b.truncate(n);
        b
    };
    let mut session = Vec::new();
    for (name, m) in &msgs {
        let mut s = Vec::new();
        push_record(&mut s, 0, &emit(m));
        c.put(name, &s);
        push_record(&mut session, 0, &emit(m));
        push_record(&mut session, 1, &[0x02, 0x00]);
    }
    push_record(&mut session, 2, &[]);
    push_record(&mut session, 1, &[0x10, 0x00]);
    c.put("session", &session);
}

fn copy_files(root: &Path, target: &str, files: &[PathBuf]) {
    let c = Corpus::new(root, target);
    for f in files {
        let name = f.file_name().expect("file name").to_string_lossy().into_owned();
        c.put(&name, &fs::read(f).expect("read seed file"));
    }
}

fn toml_files(dir: &str) -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = fs::read_dir(dir)
        .expect("folder of the repository")
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .collect();
    v.sort();
    v
}

/// A TM frame of the robot's framer (for the COBS seeds).
fn tm_frames(packets: &[Vec<u8>]) -> Vec<Vec<u8>> {
    let mut dl = TmFramer::mission();
    let (mut sa, mut st) = (TxSa::resume(17, &TEST_KEY_TM_A, 0), MemoryIvStore::default());
    let clcw = Clcw::parse(0x0100_0000).expect("CLCW");
    let mut frames = Vec::new();
    for p in packets {
        let _ = dl.send(TmVc::Realtime, p, clcw, &mut sa, &mut st, |f| frames.push(f.to_vec()));
    }
    let _ = dl.flush(TmVc::Realtime, clcw, &mut sa, &mut st, |f| frames.push(f.to_vec()));
    frames
}

fn ground_tm_frames(root: &Path, tm: &[Vec<u8>]) {
    let c = Corpus::new(root, "ground_tm_frames");
    // CLCW words: COP-1 in effect, VC 0, N(R) = 0, then retransmit, then N(R) = 1.
    let clcw0 = 0x0100_0000u32.to_be_bytes();
    let clcw_rt = 0x0100_0800u32.to_be_bytes();
    let clcw1 = 0x0100_0001u32.to_be_bytes();
    let mut s = Vec::new();
    for _ in 0..4 {
        push_record(&mut s, 2, &clcw0);
        push_record(&mut s, 3, &[0, 100]);
    }
    for p in tm.iter().take(3) {
        push_record(&mut s, 1, &[clcw0.as_slice(), &[0], p].concat());
    }
    push_record(&mut s, 2, &clcw_rt);
    push_record(&mut s, 2, &clcw1);
    c.put("idle_settle_then_tm", &s);
    // Frames of a robot with another TM key (refused at the MAC), COBS on the line.
    let mut dl = TmFramer::mission();
    let (mut sa, mut st) = (TxSa::resume(17, &TEST_KEY_TM_B, 0), MemoryIvStore::default());
    let clcw = Clcw::parse(0x0100_0000).expect("CLCW");
    let mut frames = Vec::new();
    let _ = dl.send(TmVc::Realtime, &tm[0], clcw, &mut sa, &mut st, |f| {
        frames.push(f.to_vec())
    });
    let _ = dl.flush(TmVc::Realtime, clcw, &mut sa, &mut st, |f| frames.push(f.to_vec()));
    let mut s = Vec::new();
    for f in &frames {
        push_record(&mut s, 0, &cobs(f));
    }
    push_record(&mut s, 1, &[clcw0.as_slice(), &[1], &tm[1]].concat());
    c.put("foreign_key_frame_then_replay_vc", &s);
    let mut s = Vec::new();
    push_record(
        &mut s,
        1,
        &[clcw0.as_slice(), &[2], b"wrapped by the harness".as_slice()].concat(),
    );
    push_record(&mut s, 0, &[0, 0x13, 0x37, 0]);
    c.put("wrapped_and_junk", &s);
}

fn mib_wire(root: &Path, tcs: &[(String, Vec<u8>)], tm: &[Vec<u8>]) {
    let c = Corpus::new(root, "mib_wire");
    for (name, p) in tcs.iter().step_by(4) {
        c.put(&format!("tc_{name}"), p);
    }
    let mut seen = std::collections::BTreeSet::new();
    for p in tm {
        // One TM per (service, subservice, first two source bytes: SID or event ID).
        let key = (p[7], p[8], p.get(20).copied(), p.get(21).copied());
        if p.len() > 8 && seen.insert(key) && seen.len() <= 12 {
            c.put(&format!("tm_{}_{}_{}", p[7], p[8], seen.len()), p);
        }
    }
}

fn main() {
    let root = PathBuf::from("tests/fuzz/corpus");
    assert!(Path::new("mib").is_dir(), "run from the repository root");
    let tcs = mib_tcs();
    let tm = real_tm();
    assert!(!tm.is_empty(), "the OBSW sent TM");
    let frames = tm_frames(&tm[..1]);
    tc_frame_rx(&root, &tcs);
    pus_tc(&root, &tcs);
    cobs_deframer(&root, &tcs, &frames[0]);
    ab_link(&root);
    team(&root);
    copy_files(&root, "plan_file", &toml_files("plans"));
    copy_files(&root, "module_set_file", &toml_files("plans/modules"));
    ground_tm_frames(&root, &tm);
    mib_wire(&root, &tcs, &tm);
    let _ = TEST_KEY_TC_A;
}
