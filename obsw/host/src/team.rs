//! The host's inter-robot link and durable team state (docs/team.md).
//!
//! - Team packets travel as UDP datagrams between obsw processes (`--team-udp`,
//!   `--peer N=ADDR`), **authenticated and encrypted** with AES-256-GCM under the team key
//!   (`--team-key FILE`, 32 raw bytes, the key-file format of the space link), with the
//!   same RustCrypto `aes-gcm` crate as the space link's SDLS (`mmic_link::sdls`):
//!
//!   ```text
//!   | version 1 | IV 12 = sender robot 1 + counter 11 (big-endian) | ciphertext | MAC 16 |
//!   ```
//!   The version and IV are the additional authenticated data. All robots share the team
//!   key; the sender byte in the nonce keeps every robot's nonces apart, and each sender's
//!   counter only grows: its high-water mark is written and synced in blocks of
//!   `TEAM_IV_RESERVE_BLOCK` before a counter of the block is used (the space link's
//!   `FileIvStore`, file `--team-state` + `.iv`). A receiver accepts from a peer (`--peer`)
//!   only a counter above the highest it accepted (written and synced before the packet is
//!   handed on) or one of the `TEAM_REPLAY_WINDOW` below it not yet seen; every refusal is
//!   counted by reason (HK TEAM) and evented (throttled).
//!   Without a key the link is refused unless `--lab-team-bare` (loopback only), which
//!   sends the bare packets as before.
//! - The team record (term, vote, roster, authorisation) is in `--team-state`, written to
//!   a temporary file, synced, renamed over the old one and the directory synced before
//!   `persist` returns, so before any send of the same batch.
//! - The election randomness comes from the OS (`/dev/urandom`).

use std::fs::File;
use std::io::Read;
use std::net::{SocketAddr, UdpSocket};
use std::path::{Path, PathBuf};

use aes_gcm::aead::AeadInPlace;
use aes_gcm::{Aes256Gcm, KeyInit, Nonce, Tag};
use anyhow::{bail, Context, Result};
use mib::link::sdls::{IV_LEN, MAC_LEN};
use mib::team::PlanStep;
use mib::team::{TEAM_IV_RESERVE_BLOCK, TEAM_REPLAY_WINDOW, TEAM_SEC_HEADER_LEN, TEAM_SEC_VERSION};
use mmic_link::persist::{read_key, Dir, FileIvStore};
use mmic_link::sdls::Key;
use mmic_team::{Dest, Persisted, PlanRef};
use obsw_core::services::team::{LoadStatus, StoredAuth, StoredPlan, TeamLink, TeamRecord, TeamReject};

/// Parses `N=ADDR` (a `--peer` value).
pub fn parse_peer(s: &str) -> Result<(u8, SocketAddr)> {
    let (n, a) = s
        .split_once('=')
        .with_context(|| format!("--peer {s:?}: expected N=ADDR"))?;
    let n: u8 = n
        .trim()
        .parse()
        .with_context(|| format!("--peer {s:?}: robot number"))?;
    if mib::apid::robot_apid(n).is_none() {
        bail!(
            "--peer {s:?}: robot numbers are {}..={}",
            mib::apid::ROBOT_MIN,
            mib::apid::ROBOT_MAX
        );
    }
    let a: SocketAddr = a.trim().parse().with_context(|| format!("--peer {s:?}: address"))?;
    Ok((n, a))
}

/// Counters above 2^88 cannot be expressed in the 11 counter bytes of the IV.
const COUNTER_LIMIT: u128 = 1 << 88;

/// The team datagram nonce: sender robot, then the 88-bit counter.
fn nonce(sender: u8, counter: u128) -> [u8; IV_LEN] {
    let mut iv = [0u8; IV_LEN];
    iv[0] = sender;
    iv[1..].copy_from_slice(&counter.to_be_bytes()[16 - (IV_LEN - 1)..]);
    iv
}

/// Receive state of one peer: highest accepted counter and which of the
/// `TEAM_REPLAY_WINDOW` below it were seen (bit i: `last - i`).
#[derive(Clone, Copy, Debug)]
struct RxWindow {
    last: Option<u128>,
    seen: u64,
}

impl RxWindow {
    /// Whether `c` is new (not yet accepted, not too old).
    fn fresh(&self, c: u128) -> bool {
        match self.last {
            None => true,
            Some(l) if c > l => true,
            Some(l) => {
                let d = l - c;
                d < u128::from(TEAM_REPLAY_WINDOW) && self.seen & (1u64 << d) == 0
            }
        }
    }

    /// Marks `c` accepted (it was `fresh`).
    fn accept(&mut self, c: u128) {
        match self.last {
            Some(l) if c <= l => self.seen |= 1u64 << (l - c),
            Some(l) => {
                let shift = c - l;
                self.seen = if shift >= 64 { 0 } else { self.seen << shift };
                self.seen |= 1;
                self.last = Some(c);
            }
            None => {
                self.seen = 1;
                self.last = Some(c);
            }
        }
    }
}

/// The team link's security: AES-256-GCM with the team key, per-sender counters.
pub struct TeamSecurity {
    me: u8,
    cipher: Aes256Gcm,
    store: FileIvStore,
    next: u128,
    reserved: u128,
    rx: Vec<(u8, RxWindow)>,
}

impl TeamSecurity {
    /// Opens the counter file (created empty if missing) and resumes: the own counter at
    /// its stored high-water mark, each peer above its last accepted counter (nothing
    /// below it is accepted after a restart).
    pub fn open(me: u8, key: &Key, counters: &Path, peers: &[u8]) -> Result<TeamSecurity> {
        let store = FileIvStore::open(counters).with_context(|| format!("team counters {}", counters.display()))?;
        let hw = store.get(Dir::Tx, u16::from(me)).unwrap_or(0);
        let rx = peers
            .iter()
            .map(|p| {
                let last = store.get(Dir::Rx, u16::from(*p));
                (*p, RxWindow { last, seen: u64::MAX })
            })
            .collect();
        Ok(TeamSecurity {
            me,
            cipher: Aes256Gcm::new(key.into()),
            store,
            next: hw,
            reserved: hw,
            rx,
        })
    }

    /// The counter the next packet will carry.
    #[cfg(test)]
    fn next_counter(&self) -> u128 {
        self.next
    }

    /// Protects `packet` into `out`; returns the datagram's length.
    pub fn seal(&mut self, packet: &[u8], out: &mut Vec<u8>) -> Result<(), TeamReject> {
        if self.next >= COUNTER_LIMIT {
            return Err(TeamReject::StoreFailed);
        }
        if self.next >= self.reserved {
            let hw = (self.next + u128::from(TEAM_IV_RESERVE_BLOCK)).min(COUNTER_LIMIT);
            self.store
                .put(Dir::Tx, u16::from(self.me), hw)
                .map_err(|_| TeamReject::StoreFailed)?;
            self.reserved = hw;
        }
        let iv = nonce(self.me, self.next);
        self.next += 1;
        out.clear();
        out.push(TEAM_SEC_VERSION);
        out.extend_from_slice(&iv);
        out.extend_from_slice(packet);
        let (head, body) = out.split_at_mut(TEAM_SEC_HEADER_LEN);
        let tag = self
            .cipher
            .encrypt_in_place_detached(Nonce::from_slice(&iv), head, body)
            .map_err(|_| TeamReject::Truncated)?;
        out.extend_from_slice(&tag);
        Ok(())
    }

    /// Verifies and decrypts a datagram in place; returns the sender and the packet.
    /// The sender's new highest counter is durable before the packet is returned.
    pub fn open_datagram<'a>(&mut self, d: &'a mut [u8]) -> Result<(u8, &'a [u8]), (TeamReject, u8)> {
        if d.len() < TEAM_SEC_HEADER_LEN + MAC_LEN + 1 {
            return Err((TeamReject::Truncated, d.get(1).copied().unwrap_or(0)));
        }
        let sender = d[1];
        if d[0] != TEAM_SEC_VERSION {
            return Err((TeamReject::Malformed, sender));
        }
        let Some(w) = self.rx.iter().position(|(p, _)| *p == sender) else {
            return Err((TeamReject::UnknownSender, sender));
        };
        let mut cb = [0u8; 16];
        cb[16 - (IV_LEN - 1)..].copy_from_slice(&d[2..TEAM_SEC_HEADER_LEN]);
        let counter = u128::from_be_bytes(cb);
        if !self.rx[w].1.fresh(counter) {
            return Err((TeamReject::Replay, sender));
        }
        let mac_at = d.len() - MAC_LEN;
        let (head, rest) = d.split_at_mut(TEAM_SEC_HEADER_LEN);
        let (body, tag) = rest.split_at_mut(mac_at - TEAM_SEC_HEADER_LEN);
        let iv = nonce(sender, counter);
        self.cipher
            .decrypt_in_place_detached(Nonce::from_slice(&iv), head, body, Tag::from_slice(tag))
            .map_err(|_| (TeamReject::BadMac, sender))?;
        let win = &mut self.rx[w].1;
        if win.last.is_none_or(|l| counter > l) {
            self.store
                .put(Dir::Rx, u16::from(sender), counter)
                .map_err(|_| (TeamReject::StoreFailed, sender))?;
        }
        win.accept(counter);
        Ok((sender, &d[TEAM_SEC_HEADER_LEN..mac_at]))
    }
}

pub struct TeamUdp {
    sock: UdpSocket,
    peers: Vec<(u8, SocketAddr)>,
    state: PathBuf,
    urandom: File,
    /// `None`: lab bare mode (`--lab-team-bare`).
    security: Option<TeamSecurity>,
    sealed: Vec<u8>,
    /// Team datagrams that could not be sent (added to HK IO_TM_DROPPED).
    pub send_errors: u32,
    /// Packets not sent because the own counter could not be made durable.
    pub seal_errors: u32,
    /// Persists that failed (the core treats each as a reset).
    pub persist_errors: u32,
}

/// A received datagram: the authenticated sender (`None` in lab bare mode) and the packet,
/// or why it was refused and the sender it claimed.
pub type Opened<'a> = Result<(Option<u8>, &'a [u8]), (TeamReject, u8)>;

/// What the host read from `--team-state` at start.
pub struct Loaded {
    pub status: LoadStatus,
    pub record: TeamRecord,
}

impl TeamUdp {
    /// Binds the team socket and reads the team record. A corrupt record is logged, kept
    /// aside as `FILE.corrupt`, and the robot starts from term 0 without roster (never a
    /// panic, never a silent default).
    pub fn open(
        me: u8,
        listen: SocketAddr,
        peers: Vec<(u8, SocketAddr)>,
        state: PathBuf,
        key: Option<&Path>,
    ) -> Result<(TeamUdp, Loaded)> {
        let sock = UdpSocket::bind(listen).with_context(|| format!("--team-udp {listen}"))?;
        sock.set_nonblocking(true)?;
        let loaded = match read_state(&state) {
            Ok(Some(record)) => Loaded {
                status: LoadStatus::Restored,
                record,
            },
            Ok(None) => Loaded {
                status: LoadStatus::None,
                record: TeamRecord::default(),
            },
            Err(e) => {
                let aside = state.with_extension("corrupt");
                let kept = std::fs::rename(&state, &aside).is_ok();
                log::error!(
                    "team state {}: {e:#}; starting from term 0 without roster or authorisation{}",
                    state.display(),
                    if kept {
                        format!(" (the file is kept as {})", aside.display())
                    } else {
                        String::new()
                    }
                );
                Loaded {
                    status: LoadStatus::Corrupt,
                    record: TeamRecord::default(),
                }
            }
        };
        let security = match key {
            Some(k) => {
                let key = read_key(k).with_context(|| "--team-key")?;
                let ids: Vec<u8> = peers.iter().map(|p| p.0).collect();
                Some(TeamSecurity::open(me, &key, &state.with_extension("iv"), &ids)?)
            }
            None => None,
        };
        let urandom = File::open("/dev/urandom").context("opening /dev/urandom")?;
        Ok((
            TeamUdp {
                sock,
                peers,
                state,
                urandom,
                security,
                sealed: Vec::new(),
                send_errors: 0,
                seal_errors: 0,
                persist_errors: 0,
            },
            loaded,
        ))
    }

    pub fn local_addr(&self) -> Result<SocketAddr> {
        Ok(self.sock.local_addr()?)
    }

    /// Packets not sent since the last call because the own counter could not be made
    /// durable.
    pub fn take_seal_errors(&mut self) -> u32 {
        core::mem::take(&mut self.seal_errors)
    }

    pub fn authenticated(&self) -> bool {
        self.security.is_some()
    }

    /// A random number from the OS (election jitter).
    pub fn rand(&mut self) -> u32 {
        let mut b = [0u8; 4];
        match self.urandom.read_exact(&mut b) {
            Ok(()) => u32::from_ne_bytes(b),
            // Jitter only breaks ties; safety never depends on it.
            Err(_) => std::process::id(),
        }
    }

    /// The next datagram received, if any (non-blocking).
    pub fn recv(&mut self, buf: &mut [u8]) -> Option<usize> {
        loop {
            match self.sock.recv_from(buf) {
                Ok((n, _)) => return Some(n),
                Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => return None,
                // ICMP port unreachable of an earlier send to a dead peer: skip it.
                Err(_) => continue,
            }
        }
    }

    /// Authenticates a received datagram: `Ok((Some(sender), packet))`, or in the lab's
    /// bare mode `Ok((None, datagram))`.
    pub fn open_datagram<'a>(&mut self, d: &'a mut [u8]) -> Opened<'a> {
        match self.security.as_mut() {
            Some(s) => s.open_datagram(d).map(|(from, p)| (Some(from), p)),
            None => Ok((None, d)),
        }
    }
}

/// State file, version 2 (text, one field per line, `end` last):
/// ```text
/// mmic-team-state 2
/// term 7
/// voted_for 3            (0 = none)
/// roster 1,2,3           (empty = none)
/// auth PLAN HASH FIRST STEPS EXPIRES_UNIX_MS   (or: auth none)
/// plan ID DONE STEP:FUNCTION:ARG0:ARG1:STATE;...  (or: plan none)
/// end
/// ```
/// Version 1 (`TERM VOTED_FOR` on one line) is still read.
fn encode_state(r: &TeamRecord) -> String {
    let roster: Vec<String> = r.roster.iter().map(u8::to_string).collect();
    let auth = match r.auth {
        Some(a) => format!(
            "{} {} {} {} {}",
            a.plan.id, a.plan.hash, a.first_step, a.max_steps, a.expires_unix_ms
        ),
        None => "none".into(),
    };
    let plan = match &r.plan {
        Some(p) => {
            let steps: Vec<String> = p
                .steps
                .iter()
                .map(|s| {
                    format!(
                        "{}:{}:{}:{}:{}",
                        s.step, s.function, s.args[0], s.args[1], s.initial_state
                    )
                })
                .collect();
            format!("{} {} {}", p.id, p.done, steps.join(";"))
        }
        None => "none".into(),
    };
    format!(
        "mmic-team-state 2\nterm {}\nvoted_for {}\nroster {}\nauth {auth}\nplan {plan}\nend\n",
        r.persisted.term,
        r.persisted.voted_for.unwrap_or(0),
        roster.join(",")
    )
}

fn decode_state(text: &str) -> Result<TeamRecord> {
    let mut lines = text.lines();
    let first = lines.next().unwrap_or("");
    if first != "mmic-team-state 2" {
        // Version 1: "TERM VOTED_FOR".
        let mut it = first.split_whitespace();
        let (Some(t), Some(v), None, None) = (it.next(), it.next(), it.next(), lines.next()) else {
            bail!("neither version 2 (first line 'mmic-team-state 2') nor version 1 ('TERM VOTED_FOR')");
        };
        let v: u8 = v.parse().context("vote")?;
        return Ok(TeamRecord {
            persisted: Persisted {
                term: t.parse().context("term")?,
                voted_for: (v != 0).then_some(v),
            },
            ..TeamRecord::default()
        });
    }
    let mut field = |name: &str| -> Result<&str> {
        let l = lines
            .next()
            .with_context(|| format!("line '{name} …' missing (truncated?)"))?;
        l.strip_prefix(name)
            .and_then(|r| r.strip_prefix(' '))
            .with_context(|| format!("expected '{name} …', found {l:?}"))
    };
    let term: u32 = field("term")?.parse().context("term")?;
    let v: u8 = field("voted_for")?.parse().context("voted_for")?;
    let roster_text = field("roster")?;
    let mut roster = heapless::Vec::new();
    for n in roster_text.split(',').filter(|n| !n.is_empty()) {
        let n: u8 = n.parse().with_context(|| format!("roster {roster_text:?}"))?;
        if roster.push(n).is_err() {
            bail!("roster {roster_text:?}: more than {} robots", mib::team::ROSTER_MAX);
        }
    }
    let auth_text = field("auth")?;
    let auth = if auth_text == "none" {
        None
    } else {
        let f: Vec<&str> = auth_text.split(' ').collect();
        let [id, hash, first, steps, exp] = f[..] else {
            bail!("auth {auth_text:?}: expected PLAN HASH FIRST STEPS EXPIRES_UNIX_MS");
        };
        Some(StoredAuth {
            plan: PlanRef {
                id: id.parse().context("auth plan")?,
                hash: hash.parse().context("auth hash")?,
            },
            first_step: first.parse().context("auth first step")?,
            max_steps: steps.parse().context("auth steps")?,
            expires_unix_ms: exp.parse().context("auth expiry")?,
        })
    };
    let plan_text = field("plan")?;
    let plan = if plan_text == "none" {
        None
    } else {
        let f: Vec<&str> = plan_text.split(' ').collect();
        let [id, done, steps_text] = f[..] else {
            bail!("plan {plan_text:?}: expected ID DONE STEPS");
        };
        let mut steps = heapless::Vec::new();
        for st in steps_text.split(';') {
            let v: Vec<&str> = st.split(':').collect();
            let [step, function, a0, a1, state] = v[..] else {
                bail!("plan step {st:?}: expected STEP:FUNCTION:ARG0:ARG1:STATE");
            };
            let s = PlanStep {
                step: step.parse().context("plan step")?,
                function: function.parse().context("plan function")?,
                args: [a0.parse().context("plan arg0")?, a1.parse().context("plan arg1")?],
                initial_state: state.parse().context("plan initial state")?,
            };
            if steps.push(s).is_err() {
                bail!(
                    "plan {plan_text:?}: more than {} steps",
                    mib::team::MAX_AUTHORISED_STEPS
                );
            }
        }
        Some(StoredPlan {
            id: id.parse().context("plan ID")?,
            steps,
            done: done.parse().context("plan done")?,
        })
    };
    if lines.next() != Some("end") {
        bail!("line 'end' missing (truncated?)");
    }
    Ok(TeamRecord {
        persisted: Persisted {
            term,
            voted_for: (v != 0).then_some(v),
        },
        roster,
        auth,
        plan,
    })
}

/// Reads the team record; `None` if there is no file.
fn read_state(p: &Path) -> Result<Option<TeamRecord>> {
    let text = match std::fs::read_to_string(p) {
        Ok(t) => t,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        Err(e) => return Err(e).with_context(|| format!("--team-state {}", p.display())),
    };
    decode_state(&text).map(Some)
}

fn write_state(p: &Path, r: &TeamRecord) -> std::io::Result<()> {
    crate::durable::replace(p, encode_state(r).as_bytes())
}

impl TeamLink for TeamUdp {
    fn persist(&mut self, r: &TeamRecord) -> bool {
        match write_state(&self.state, r) {
            Ok(()) => true,
            Err(e) => {
                self.persist_errors += 1;
                log::error!("team state {}: {e}", self.state.display());
                false
            }
        }
    }

    fn send(&mut self, to: Dest, packet: &[u8]) -> u32 {
        let mut sent = 0;
        for i in 0..self.peers.len() {
            let (n, addr) = self.peers[i];
            if to != Dest::All && to != Dest::To(n) {
                continue;
            }
            // One counter per datagram: each peer's copy is sealed on its own.
            let data: &[u8] = match self.security.as_mut() {
                Some(s) => match s.seal(packet, &mut self.sealed) {
                    Ok(()) => &self.sealed,
                    Err(_) => {
                        self.seal_errors = self.seal_errors.wrapping_add(1);
                        continue;
                    }
                },
                None => packet,
            };
            // An earlier send to a dead peer leaves an ICMP "port unreachable" pending
            // on the socket, which fails the next send (to any peer) once: try again.
            let ok = self
                .sock
                .send_to(data, addr)
                .or_else(|_| self.sock.send_to(data, addr))
                .is_ok();
            if ok {
                sent += 1;
            } else {
                self.send_errors = self.send_errors.wrapping_add(1);
            }
        }
        sent
    }
}

/// An authorisation as the ground uploaded it, for tests.
#[cfg(test)]
fn stored(a: mmic_team::Authorisation, epoch: u64) -> StoredAuth {
    StoredAuth {
        plan: a.plan,
        first_step: a.first_step,
        max_steps: a.max_steps,
        expires_unix_ms: epoch + a.expires_at,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tmp_dir(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("obsw-team-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    // verifies: TEAM-OBSW-01, TEAM-PERSIST-03
    #[test]
    fn the_state_file_round_trips_and_a_missing_one_is_term_0() {
        let dir = tmp_dir("state");
        let p = dir.join("team.state");
        assert_eq!(read_state(&p).unwrap(), None);
        let mut roster = heapless::Vec::new();
        roster.extend_from_slice(&[1, 2, 3]).unwrap();
        let r = TeamRecord {
            persisted: Persisted {
                term: 7,
                voted_for: Some(3),
            },
            roster,
            auth: Some(stored(
                mmic_team::Authorisation {
                    plan: PlanRef {
                        id: 9,
                        hash: 0xDEAD_BEEF,
                    },
                    first_step: 2,
                    max_steps: 3,
                    expires_at: 60_000,
                },
                1_790_000_000_000,
            )),
            plan: Some(StoredPlan {
                id: 9,
                steps: heapless::Vec::from_slice(&[
                    PlanStep {
                        step: 2,
                        function: mib::tc::function::RECONFIGURE,
                        args: [0, 1],
                        initial_state: 0,
                    },
                    PlanStep {
                        step: 3,
                        function: mib::tc::function::ROTATE_HIP,
                        args: [-9000, 0],
                        initial_state: 1,
                    },
                ])
                .unwrap(),
                done: 1,
            }),
        };
        write_state(&p, &r).unwrap();
        assert_eq!(read_state(&p).unwrap(), Some(r.clone()));
        // Version 1 files are still read (term and vote only).
        std::fs::write(&p, "5 2\n").unwrap();
        let v1 = read_state(&p).unwrap().unwrap();
        assert_eq!(
            (v1.persisted.term, v1.persisted.voted_for, v1.roster.len()),
            (5, Some(2), 0)
        );
        // Corrupt: garbage, a truncated file, a bad number: an error, never term 0.
        std::fs::write(&p, "x").unwrap();
        assert!(read_state(&p).is_err(), "a corrupt state is an error, never term 0");
        let full = encode_state(&r);
        std::fs::write(&p, &full[..full.len() - 4]).unwrap();
        assert!(read_state(&p).is_err(), "truncated");
        std::fs::write(&p, full.replace("roster 1,2,3", "roster 1,x,3")).unwrap();
        assert!(read_state(&p).is_err(), "bad roster");
        assert!(parse_peer("2=127.0.0.1:9000").is_ok());
        assert!(parse_peer("0=127.0.0.1:9000").is_err());
        assert!(parse_peer("2:127.0.0.1").is_err());
        std::fs::remove_dir_all(&dir).unwrap();
    }

    // verifies: TEAM-PERSIST-03
    #[test]
    fn a_corrupt_state_file_is_set_aside_and_the_robot_starts_without_a_roster() {
        let dir = tmp_dir("corrupt");
        let p = dir.join("team.state");
        std::fs::write(&p, "mmic-team-state 2\nterm 4\n").unwrap();
        let (_t, loaded) = TeamUdp::open(1, "127.0.0.1:0".parse().unwrap(), vec![], p.clone(), None).unwrap();
        assert_eq!(loaded.status, LoadStatus::Corrupt);
        assert_eq!(loaded.record, TeamRecord::default());
        assert!(p.with_extension("corrupt").exists(), "kept aside for analysis");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    fn pair(dir: &Path, key: &Key) -> (TeamSecurity, TeamSecurity) {
        let a = TeamSecurity::open(1, key, &dir.join("a.iv"), &[2]).unwrap();
        let b = TeamSecurity::open(2, key, &dir.join("b.iv"), &[1]).unwrap();
        (a, b)
    }

    // verifies: TEAM-SEC-01
    #[test]
    fn sealed_packets_open_and_forged_replayed_truncated_unknown_are_refused() {
        let dir = tmp_dir("sec");
        let key = [7u8; 32];
        let (mut a, mut b) = pair(&dir, &key);
        let mut d = Vec::new();
        a.seal(b"hello team", &mut d).unwrap();
        let good = d.clone();
        let mut x = good.clone();
        assert_eq!(b.open_datagram(&mut x).unwrap(), (1, &b"hello team"[..]));
        // Replayed.
        let mut x = good.clone();
        assert_eq!(b.open_datagram(&mut x).unwrap_err().0, TeamReject::Replay);
        // Altered (any byte: header, ciphertext, MAC).
        for i in 0..good.len() {
            a.seal(b"hello team", &mut d).unwrap();
            let mut x = d.clone();
            x[i] ^= 0x01;
            let r = b.open_datagram(&mut x).unwrap_err().0;
            assert!(
                matches!(
                    r,
                    TeamReject::BadMac | TeamReject::Malformed | TeamReject::UnknownSender
                ),
                "byte {i}: {r:?}"
            );
        }
        // Forged with another key.
        let (mut f, _) = pair(&tmp_dir("sec-forger"), &[8u8; 32]);
        for _ in 0..100 {
            f.seal(b"x", &mut d).unwrap();
        }
        let mut x = d.clone();
        assert_eq!(b.open_datagram(&mut x).unwrap_err().0, TeamReject::BadMac);
        // Truncated.
        let mut x = good[..TEAM_SEC_HEADER_LEN + MAC_LEN].to_vec();
        assert_eq!(b.open_datagram(&mut x).unwrap_err().0, TeamReject::Truncated);
        // Unknown sender (robot 3 is not b's peer), even with the right key.
        let mut c = TeamSecurity::open(3, &key, &dir.join("c.iv"), &[2]).unwrap();
        c.seal(b"x", &mut d).unwrap();
        let mut x = d.clone();
        assert_eq!(b.open_datagram(&mut x).unwrap_err().0, TeamReject::UnknownSender);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    // verifies: TEAM-SEC-02
    #[test]
    fn counters_survive_a_restart_and_reordering_within_the_window_is_accepted() {
        let dir = tmp_dir("restart");
        let key = [9u8; 32];
        let (mut a, mut b) = pair(&dir, &key);
        let mut sent = Vec::new();
        for i in 0..10u8 {
            let mut d = Vec::new();
            a.seal(&[i], &mut d).unwrap();
            sent.push(d);
        }
        // Out of order: 5, then 0..4 (within the window), then 5 again (replay).
        let mut x = sent[5].clone();
        assert!(b.open_datagram(&mut x).is_ok());
        for s in &sent[..5] {
            let mut x = s.clone();
            assert!(b.open_datagram(&mut x).is_ok());
        }
        let mut x = sent[5].clone();
        assert_eq!(b.open_datagram(&mut x).unwrap_err().0, TeamReject::Replay);
        let before = a.next_counter();
        drop(a);
        drop(b);
        // Both restart: the sender resumes above every counter it may have used, the
        // receiver refuses everything at or below the last counter it accepted.
        let (mut a, mut b) = pair(&dir, &key);
        assert!(a.next_counter() >= before, "no counter reused after a restart");
        assert_eq!(a.next_counter(), u128::from(TEAM_IV_RESERVE_BLOCK));
        for s in &sent[..6] {
            let mut x = s.clone();
            assert_eq!(b.open_datagram(&mut x).unwrap_err().0, TeamReject::Replay);
        }
        // 6..9 were never delivered: still above the last accepted, accepted.
        let mut x = sent[9].clone();
        assert!(b.open_datagram(&mut x).is_ok());
        let mut d = Vec::new();
        a.seal(b"after", &mut d).unwrap();
        assert_eq!(b.open_datagram(&mut d).unwrap().1, b"after");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
