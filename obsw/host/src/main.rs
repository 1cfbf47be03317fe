//! `obsw`: the MMIC-I on-board software on a host, against the MMIC-I simulator.
//!
//! It runs the same `obsw-core` and `mmic-domain` code as the firmware. TCs arrive on
//! UDP and TCP (COBS-framed); TM goes back to every TCP client, to every UDP ground
//! that subscribed with an accepted TC and to the fixed `--tm-dest` addresses (see `net`). Simulated time runs `--speed` times faster than the wall clock.
//!
//! With `--frame-udp` the space link runs beside it (see `frames`): TC transfer frames
//! through SDLS and FARM-1, TM frames to `--frame-tm-to` (or both ways on a serial line
//! with `--frame-serial`); the bare-packet link is then off
//! unless `--lab-bare-packets` keeps it (loopback only).

mod config_state;
mod durable;
mod files;
mod frames;
mod net;
mod plan_state;
mod store_file;
mod team;
mod update;

use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use anyhow::{bail, Context, Result};
use clap::Parser;
use serde::Deserialize;

use mib::config;
use mmic_sim::{Sim, SimCommand, SimConfig};
use obsw_core::flash_store::MibFlashStore;
use obsw_core::obsw::{Config, LinkEvent, Obsw};
use obsw_core::services::modules::AcceptedConfig;
use store_file::HostFlash;

use net::{Input, Origin};

/// Command-line options. Every option can also be given in the `--config` TOML file
/// (same names, with underscores); the command line wins.
#[derive(Parser, Debug)]
#[command(
    name = "obsw",
    version,
    about = "MMIC-I on-board software (host build) with its simulator",
    long_about = "MMIC-I on-board software (host build) running against the MMIC-I simulator.\n\nTCs: CCSDS space packets with a PUS-C secondary header and CRC, as UDP datagrams or over TCP framed with COBS (0x00, COBS(packet), 0x00; a receiver takes a frame without the leading 0x00 too). TM: to every connected TCP client, to every UDP ground subscribed by an accepted TC (a lease renewed by each accepted TC; rejected or malformed datagrams never change who gets TM) and to every fixed --tm-dest (e.g. Yamcs' TM link). Space link (docs/space-link.md): with --frame-udp, one TC transfer frame per datagram (CRC, SDLS AES-256-GCM with --tc-key, FARM-1) and fixed-length TM frames (SDLS with --tm-key, CLCW, idle frames) to --frame-tm-to, counters in --link-state; or the same frames over a serial line with --frame-serial PATH (one COBS frame per frame, as board A's ground link); the bare-packet link is on only with --lab-bare-packets (loopback only); one of the two links must be chosen. The robot boots in STANDBY.\n\nOnce module discovery is done (board B's half in, or after its wait: at most 1 s of simulated time after boot; OPERATIONAL is refused before), one line `READY robot=N apid=0x... udp=ADDR tcp=ADDR sim_ctl=ADDR` is printed on stdout.\n\nSimulator control (fault injection; not the flight TC path): UDP text lines to --sim-ctl: `stuck-arm a|b`, `obstacle a|b`, `battery-sag VOLTS`, `dead-hip-encoder`, `cut-cable`, `misplaced-voxel`, `fastener-jam`, `clear [FAULT]`, `link-loss P`, `link-corrupt P`, `status`. Each gets one reply line starting with `ok` or `error`."
)]
struct Args {
    /// Robot number 1..=254; the APID is 0x100 + N and the default ports follow from it.
    #[arg(long)]
    robot: Option<u8>,
    /// UDP address for TCs [default: 127.0.0.1:(7300 + robot)].
    #[arg(long)]
    udp: Option<SocketAddr>,
    /// TCP address for TCs (COBS framing) [default: same as --udp].
    #[arg(long)]
    tcp: Option<SocketAddr>,
    /// UDP address of the simulator control channel [default: 127.0.0.1:(7400 + robot)].
    #[arg(long)]
    sim_ctl: Option<SocketAddr>,
    /// Simulated seconds per wall-clock second [default: 1].
    #[arg(long)]
    speed: Option<f64>,
    /// Seed of the simulator's random numbers (bolt outcomes, link errors) [default: 1].
    #[arg(long)]
    seed: Option<u64>,
    /// Configuration state the simulated robot starts in: name ("Xneg"), letter ("a") or ID [default: Xneg].
    #[arg(long)]
    initial_state: Option<String>,
    /// Probability that a byte on the simulated A-B serial link is lost [default: 0].
    #[arg(long)]
    link_loss: Option<f64>,
    /// Probability that a byte on the simulated A-B serial link is corrupted [default: 0].
    #[arg(long)]
    link_corrupt: Option<f64>,
    /// Stop after this many simulated seconds (default: run until killed).
    #[arg(long)]
    duration: Option<f64>,
    /// Module-set file of the simulated robot (plans/modules/*.toml) [default: the full robot].
    #[arg(long)]
    modules: Option<PathBuf>,
    /// File holding the module configuration the ground accepted (ACCEPT_CONFIG), kept
    /// across restarts (written to a temporary file, synced, renamed). Missing or corrupt:
    /// nothing accepted (event CONFIG_STATE_LOST). Without it the factory configuration
    /// (the full robot) is accepted at start and an ACCEPT_CONFIG holds until the process ends.
    #[arg(long)]
    config_state: Option<PathBuf>,
    /// File holding the on-board plan (PUS 18) and how far it got, kept across restarts
    /// (written like --team-state after every change). A plan running at a restart comes
    /// back suspended: the ground resumes it (the step in flight runs again) or skips it.
    #[arg(long, value_name = "PATH")]
    plan_state: Option<PathBuf>,
    /// File of the on-board TM store (PUS 15), kept across restarts: a NOR flash image of
    /// `mib::memory::store::SIZE` bytes, created erased if missing [default: DIR/robot-N/
    /// tm-store.bin with --keys DIR, else tm-store-robot-N.bin beside --link-state;
    /// neither: the store is in memory and lost at exit].
    #[arg(long, value_name = "PATH")]
    tm_store: Option<PathBuf>,
    /// Test aid: write every TM packet the obsw sends to this file, one line of hex each.
    #[arg(long)]
    tm_log: Option<PathBuf>,
    /// The file store (docs/files.md): files the ground puts and gets over CFDP on the
    /// space link, in this directory (created if missing) [default: DIR/robot-N/files with
    /// --keys DIR, else files-robot-N beside --link-state; neither: no file service].
    #[arg(long, value_name = "DIR")]
    files: Option<PathBuf>,
    /// Software update (docs/update.md): the slots folder of the boot launcher `obsw-boot`
    /// (which sets it); without it the update TCs are refused UPDATE_UNAVAILABLE.
    #[arg(long, value_name = "DIR", env = "OBSW_SLOTS")]
    slots: Option<PathBuf>,
    /// The ground's update public key (64 hexadecimal digits; `ground update keygen`).
    #[arg(long, value_name = "FILE", env = "OBSW_UPDATE_KEY")]
    update_key: Option<PathBuf>,
    /// Space link with the key folder of `ground keys create DIR`: the keys and state of
    /// robot N from DIR/robot-N/ (tc-spi1.key, tm-spi17.key, obsw-link.state), TC frames on
    /// 127.0.0.1:(7500 + N) and TM frames to 127.0.0.1:(7600 + N) unless the options below
    /// say otherwise.
    #[arg(long, value_name = "DIR")]
    keys: Option<PathBuf>,
    /// Space link: UDP address taking one TC transfer frame per datagram (CCSDS 232.0-B-4,
    /// COP-1, SDLS). Needs --frame-tm-to, --tc-key, --tm-key and --link-state (or --keys).
    #[arg(long)]
    frame_udp: Option<SocketAddr>,
    /// Space link: the ground's UDP address receiving the TM frames (fixed; grounds do not
    /// subscribe on the frame link).
    #[arg(long)]
    frame_tm_to: Option<SocketAddr>,
    /// Space link over a byte stream instead of UDP, as board A's serial ground link: TC
    /// and TM frames, one COBS frame each, on this serial device (put in raw mode), pty or
    /// Unix socket (connected to). Replaces --frame-udp and --frame-tm-to.
    #[arg(long, value_name = "PATH", conflicts_with_all = ["frame_udp", "frame_tm_to"])]
    frame_serial: Option<PathBuf>,
    /// Space link: file with the raw 32-byte AES-256 key of TC SPI 1 (ground → robot).
    #[arg(long)]
    tc_key: Option<PathBuf>,
    /// Space link: file with the raw 32-byte AES-256 key of TM SPI 17 (robot → ground).
    #[arg(long)]
    tm_key: Option<PathBuf>,
    /// Space link: SDLS on the TM frames of VC0/VC1 — `encrypt` (AES-256-GCM under the TM
    /// SPI, the default) or `clear` (no SDLS on TM, for grounds without it: TM readable and
    /// forgeable on the path; TC frames stay authenticated). The ground must match.
    #[arg(long, value_name = "encrypt|clear", value_parser = frames::parse_tm_sdls)]
    tm_sdls: Option<mmic_link::downlink::TmSecurity>,
    /// Lab mode: the bare-packet link (unauthenticated space packets on --udp/--tcp, TM
    /// to their senders and to --tm-dest), alone or beside the frame link; loopback
    /// addresses only. Without it and without --frame-udp the obsw refuses to start.
    #[arg(long)]
    lab_bare_packets: bool,
    /// Space link: SDLS counter state file (created if missing; written and synced before
    /// a counter is used, so no nonce is reused and no replay accepted across restarts).
    #[arg(long)]
    link_state: Option<PathBuf>,
    /// Fixed UDP destination of all TM, besides the subscribers (repeatable): a mission
    /// control system such as Yamcs, whose TM link listens on its own port and sends TCs
    /// from another one, so it never subscribes. No lease: TM flows from boot, with or
    /// without TCs. Lab and loopback use: the datagrams go out of the --udp socket.
    #[arg(long = "tm-dest", value_name = "ADDR")]
    tm_dest: Vec<SocketAddr>,
    /// Team coordination without the ground (docs/team.md): UDP address of this robot's
    /// inter-robot link (team packets, APID 0x0E0, TM[211,1]). Needs --team-state and
    /// --team-key (or --lab-team-bare); the other robots are given by --peer.
    #[arg(long)]
    team_udp: Option<SocketAddr>,
    /// Team key: file with the raw 32-byte AES-256 key shared by the team (same format as
    /// the space link's key files); every team datagram is authenticated and encrypted.
    #[arg(long)]
    team_key: Option<PathBuf>,
    /// Lab mode: team packets without authentication (no --team-key); loopback addresses
    /// only (--team-udp and every --peer).
    #[arg(long)]
    lab_team_bare: bool,
    /// Another robot's inter-robot address, `N=ADDR` (repeatable).
    #[arg(long = "peer", value_name = "N=ADDR")]
    peer: Vec<String>,
    /// File holding the team's durable term and vote (written and synced before any
    /// team packet of the same decision is sent).
    #[arg(long)]
    team_state: Option<PathBuf>,
    /// Test aid: the team roster at boot, robot numbers in order of preference
    /// (`1,2,3`); normally the ground uploads it with TEAM_ROSTER [210,4].
    #[arg(long)]
    team_roster: Option<String>,
    /// TOML file with any of the options above.
    #[arg(long)]
    config: Option<PathBuf>,
}

/// The inter-robot link's settings (`--team-udp`, `--peer`, `--team-state`, `--team-key`,
/// `--lab-team-bare`, `--team-roster`).
struct TeamSettings {
    listen: SocketAddr,
    peers: Vec<(u8, SocketAddr)>,
    state: PathBuf,
    /// `None`: lab bare mode.
    key: Option<PathBuf>,
    roster: Option<Vec<u8>>,
}

/// The team options, from the command line or else the `--config` file.
fn team_settings(a: &Args, f: &FileConfig) -> Result<Option<TeamSettings>> {
    let peer_list = if a.peer.is_empty() {
        f.peer.clone().unwrap_or_default()
    } else {
        a.peer.clone()
    };
    let state = a.team_state.clone().or(f.team_state.clone());
    let key = a.team_key.clone().or(f.team_key.clone());
    let roster_text = a.team_roster.clone().or(f.team_roster.clone());
    let lab_bare = a.lab_team_bare || f.lab_team_bare.unwrap_or(false);
    let Some(listen) = a.team_udp.or(f.team_udp) else {
        if !peer_list.is_empty() || state.is_some() || roster_text.is_some() || key.is_some() || lab_bare {
            bail!("--peer, --team-state, --team-key, --lab-team-bare and --team-roster need --team-udp");
        }
        return Ok(None);
    };
    let Some(state) = state else {
        bail!("--team-udp needs --team-state (term and vote must be durable before a vote is sent)");
    };
    let peers = peer_list
        .iter()
        .map(|p| team::parse_peer(p))
        .collect::<Result<Vec<_>>>()?;
    match (&key, lab_bare) {
        (Some(_), true) => bail!("--team-key and --lab-team-bare exclude each other"),
        (None, false) => bail!(
            "--team-udp needs --team-key FILE (team packets are authenticated like the ground link), or --lab-team-bare on loopback addresses"
        ),
        (None, true) => {
            if !listen.ip().is_loopback() || peers.iter().any(|(_, p)| !p.ip().is_loopback()) {
                bail!("--lab-team-bare: unauthenticated team packets are for the lab, loopback addresses only");
            }
        }
        (Some(_), false) => {}
    }
    let roster = match &roster_text {
        Some(r) => Some(
            r.split(',')
                .map(|n| n.trim().parse::<u8>().with_context(|| format!("--team-roster {r:?}")))
                .collect::<Result<Vec<_>>>()?,
        ),
        None => None,
    };
    Ok(Some(TeamSettings {
        listen,
        peers,
        state,
        key,
        roster,
    }))
}

#[derive(Deserialize, Default, Debug)]
#[serde(deny_unknown_fields)]
struct FileConfig {
    robot: Option<u8>,
    udp: Option<SocketAddr>,
    tcp: Option<SocketAddr>,
    sim_ctl: Option<SocketAddr>,
    speed: Option<f64>,
    seed: Option<u64>,
    initial_state: Option<String>,
    link_loss: Option<f64>,
    link_corrupt: Option<f64>,
    duration: Option<f64>,
    frame_udp: Option<SocketAddr>,
    frame_tm_to: Option<SocketAddr>,
    frame_serial: Option<PathBuf>,
    keys: Option<PathBuf>,
    tc_key: Option<PathBuf>,
    tm_key: Option<PathBuf>,
    tm_sdls: Option<String>,
    link_state: Option<PathBuf>,
    tm_dest: Option<Vec<SocketAddr>>,
    lab_bare_packets: Option<bool>,
    modules: Option<PathBuf>,
    config_state: Option<PathBuf>,
    plan_state: Option<PathBuf>,
    tm_store: Option<PathBuf>,
    files: Option<PathBuf>,
    team_udp: Option<SocketAddr>,
    peer: Option<Vec<String>>,
    team_state: Option<PathBuf>,
    team_key: Option<PathBuf>,
    lab_team_bare: Option<bool>,
    team_roster: Option<String>,
}

struct Settings {
    robot: u8,
    udp: SocketAddr,
    tcp: SocketAddr,
    sim_ctl: SocketAddr,
    speed: f64,
    seed: u64,
    initial_state: u8,
    link_loss: f64,
    link_corrupt: f64,
    duration: Option<f64>,
    tm_log: Option<PathBuf>,
    /// The store file (`--tm-store` or its default); `None`: in memory.
    tm_store: Option<PathBuf>,
    /// The file store directory (`--files` or its default); `None`: no file service.
    files: Option<PathBuf>,
    /// The launcher's slots folder and the update key (`None`: no update service).
    slots: Option<PathBuf>,
    update_key: Option<PathBuf>,
    frames: Option<frames::FrameConfig>,
    tm_dest: Vec<SocketAddr>,
    /// The bare-packet link is on (lab mode, --lab-bare-packets).
    bare: bool,
    modules: mmic_sim::modules::ModuleSetSpec,
    /// `--config-state` (docs/modules.md).
    config_state: Option<PathBuf>,
    /// `--plan-state` (docs/plan-format.md, "On board").
    plan_state: Option<PathBuf>,
    team: Option<TeamSettings>,
}

fn settings(a: Args) -> Result<Settings> {
    let f: FileConfig = match &a.config {
        Some(p) => {
            let text =
                std::fs::read_to_string(p).with_context(|| format!("cannot read config file {}", p.display()))?;
            toml::from_str(&text).map_err(|e| anyhow::anyhow!("{}: {}", p.display(), e))?
        }
        None => FileConfig::default(),
    };
    let team = team_settings(&a, &f)?;
    let robot = a.robot.or(f.robot).unwrap_or(mib::apid::DEFAULT_ROBOT);
    if mib::apid::robot_apid(robot).is_none() {
        bail!(
            "--robot {robot}: robot numbers are {}..={}",
            mib::apid::ROBOT_MIN,
            mib::apid::ROBOT_MAX
        );
    }
    let local = |port: u16| SocketAddr::from(([127, 0, 0, 1], port));
    let udp = a.udp.or(f.udp).unwrap_or(local(mib::host_config::robot_port(robot)));
    let tcp = a.tcp.or(f.tcp).unwrap_or(udp);
    let sim_ctl = a
        .sim_ctl
        .or(f.sim_ctl)
        .unwrap_or(local(mib::host_config::SIM_CTL_BASE_PORT + robot as u16));
    let speed = a.speed.or(f.speed).unwrap_or(1.0);
    if !(speed.is_finite() && speed > 0.0 && speed <= 100_000.0) {
        bail!("--speed {speed}: must be a number in (0, 100000]");
    }
    let state_text = a.initial_state.or(f.initial_state).unwrap_or_else(|| "Xneg".into());
    let initial_state = match state_text.parse::<u8>() {
        Ok(id) if (id as usize) < mib::robot::NUM_STATES => id,
        Ok(id) => bail!("--initial-state {id}: state IDs are 0..={}", mib::robot::NUM_STATES - 1),
        Err(_) => mib::robot::state_by_name(&state_text)
            .map(|s| s.id)
            .with_context(|| format!("--initial-state {state_text:?}: not a state name, letter or ID"))?,
    };
    let prob = |name: &str, v: Option<f64>| -> Result<f64> {
        let v = v.unwrap_or(0.0);
        if !(0.0..=1.0).contains(&v) {
            bail!("--{name} {v}: must be a probability in [0, 1]");
        }
        Ok(v)
    };
    let link_loss = prob("link-loss", a.link_loss.or(f.link_loss))?;
    let link_corrupt = prob("link-corrupt", a.link_corrupt.or(f.link_corrupt))?;
    let duration = a.duration.or(f.duration);
    if let Some(d) = duration {
        if !(d.is_finite() && d > 0.0) {
            bail!("--duration {d}: must be a positive number of seconds");
        }
    }
    // --keys DIR: every frame option not given takes its default from robot N's folder
    // and ports.
    let keys = a.keys.or(f.keys).map(|d| d.join(format!("robot-{robot}")));
    let from_keys = |file: &str| keys.as_ref().map(|d| d.join(file));
    let file_tm_sdls = f
        .tm_sdls
        .as_deref()
        .map(|t| frames::parse_tm_sdls(t).map_err(|e| anyhow::anyhow!("tm_sdls in the --config file: {e}")))
        .transpose()?;
    let tm_sdls = a.tm_sdls.or(file_tm_sdls).unwrap_or_default();
    let serial = a.frame_serial.or(f.frame_serial);
    let (frame_udp, frame_tm_to) = (a.frame_udp.or(f.frame_udp), a.frame_tm_to.or(f.frame_tm_to));
    if serial.is_some() && (frame_udp.is_some() || frame_tm_to.is_some()) {
        bail!("--frame-serial replaces --frame-udp and --frame-tm-to: give one transport");
    }
    // The UDP addresses by default from --keys; none with --frame-serial.
    let udp_defaults = serial.is_none();
    let udp_default = |port: u16| keys.as_ref().filter(|_| udp_defaults).map(|_| local(port));
    let wire = match (
        serial,
        frame_udp.or_else(|| udp_default(mib::host_config::frame_port(robot))),
        frame_tm_to.or_else(|| udp_default(mib::host_config::tm_frame_port(robot))),
    ) {
        (Some(path), _, _) => Some(frames::FrameWire::Serial(path)),
        (None, Some(listen), Some(tm_to)) => Some(frames::FrameWire::Udp { listen, tm_to }),
        (None, None, None) => None,
        (None, _, _) => bail!("the frame link over UDP needs both --frame-udp and --frame-tm-to"),
    };
    let frames = match (
        wire,
        a.tc_key.or(f.tc_key).or_else(|| from_keys("tc-spi1.key")),
        a.tm_key.or(f.tm_key).or_else(|| from_keys("tm-spi17.key")),
        a.link_state.or(f.link_state).or_else(|| from_keys("obsw-link.state")),
    ) {
        (None, None, None, None) => None,
        (Some(wire), Some(tc_key), Some(tm_key), Some(state)) => Some(frames::FrameConfig {
            wire,
            tc_key,
            tm_key,
            state,
            tm_sdls,
        }),
        _ => bail!(
            "the frame link needs all of --frame-udp and --frame-tm-to (or --frame-serial), --tc-key, --tm-key and --link-state"
        ),
    };
    let tm_dest = if a.tm_dest.is_empty() {
        f.tm_dest.clone().unwrap_or_default()
    } else {
        a.tm_dest.clone()
    };
    let lab_bare_packets = a.lab_bare_packets || f.lab_bare_packets.unwrap_or(false);
    if lab_bare_packets && !(udp.ip().is_loopback() && tcp.ip().is_loopback()) {
        bail!("--lab-bare-packets: the bare-packet link is for the lab, loopback addresses only (--udp {udp}, --tcp {tcp})");
    }
    if frames.is_none() && !lab_bare_packets {
        bail!(
            "no ground link chosen: give the space link (--frame-udp, --frame-tm-to, --tc-key, --tm-key, --link-state) \
             or, in the lab on loopback addresses, --lab-bare-packets (unauthenticated space packets)"
        );
    }
    let bare = lab_bare_packets;
    if !bare && !tm_dest.is_empty() {
        bail!("--tm-dest sends bare (unauthenticated) packets: with --frame-udp it needs --lab-bare-packets");
    }
    let modules = match a.modules.or(f.modules) {
        Some(p) => mmic_sim::modules::ModuleSetSpec::load(&p).map_err(|e| anyhow::anyhow!("--modules: {e}"))?,
        None => mmic_sim::modules::ModuleSetSpec::full(),
    };
    let tm_store = a
        .tm_store
        .or(f.tm_store)
        .or_else(|| from_keys("tm-store.bin"))
        .or_else(|| {
            frames
                .as_ref()
                .map(|fc| fc.state.with_file_name(format!("tm-store-robot-{robot}.bin")))
        });
    let files = a.files.or(f.files).or_else(|| from_keys("files")).or_else(|| {
        frames
            .as_ref()
            .map(|fc| fc.state.with_file_name(format!("files-robot-{robot}")))
    });
    Ok(Settings {
        robot,
        udp,
        tcp,
        sim_ctl,
        speed,
        seed: a.seed.or(f.seed).unwrap_or(1),
        initial_state,
        link_loss,
        link_corrupt,
        duration,
        tm_log: a.tm_log,
        tm_store,
        files,
        slots: a.slots,
        update_key: a.update_key,
        frames,
        tm_dest,
        bare,
        modules,
        config_state: a.config_state.or(f.config_state),
        plan_state: a.plan_state.or(f.plan_state),
        team,
    })
}

/// The host's PUS 15 store: the flight store code over a file (or memory).
type HostStore = MibFlashStore<'static, HostFlash>;

/// Opens the store of `path` (or one in memory) for the rest of the process.
fn open_store(path: Option<&std::path::Path>) -> Result<HostStore> {
    let flash = match path {
        Some(p) => store_file::open(p)?,
        None => store_file::memory(),
    };
    let flash: &'static std::cell::RefCell<HostFlash> = Box::leak(Box::new(std::cell::RefCell::new(flash)));
    HostStore::open(flash, 0).map_err(|e| anyhow::anyhow!("TM store: {e:?}"))
}

fn main() {
    env_logger::Builder::from_env(env_logger::Env::default().default_filter_or("warn")).init();
    if let Err(e) = run(Args::parse()) {
        eprintln!("obsw: error: {e:#}");
        std::process::exit(2);
    }
}

fn run(args: Args) -> Result<()> {
    let s = settings(args)?;
    let (mut inputs, mut down, bound) = net::start(s.udp, s.tcp, s.sim_ctl)?;
    for d in &s.tm_dest {
        down.add_fixed(*d)?;
    }
    if let Some(p) = &s.tm_log {
        let f = std::fs::File::create(p).with_context(|| format!("--tm-log {}", p.display()))?;
        down.log_tm_to(f);
    }
    let (udp, tcp, ctl_addr) = (bound.udp, bound.tcp, bound.sim_ctl);
    down.bare = s.bare;
    if s.bare {
        eprintln!(
            "obsw: bare-packet link (lab mode: unauthenticated space packets) on udp={udp} tcp={tcp}{}",
            if s.frames.is_some() {
                ", beside the frame link (--lab-bare-packets)"
            } else {
                ""
            }
        );
    } else {
        eprintln!(
            "obsw: bare-packet link off (frame link only): packets on udp={udp}/tcp={tcp} are dropped and counted"
        );
    }
    let mut frame_note = String::new();
    if let Some(fc) = &s.frames {
        let mut ep = frames::FrameEndpoint::open(fc)?;
        inputs.register_frames(ep.raw_fd())?;
        // The poll tells when the frame socket has datagrams (set in `Inputs::wait_until`).
        ep.track_readiness();
        let (on, to) = match (&fc.wire, ep.local_addr()?) {
            (frames::FrameWire::Udp { tm_to, .. }, Some(addr)) => {
                frame_note = format!(" frame_udp={addr} frame_tm_to={tm_to}");
                (addr.to_string(), format!("to {tm_to}"))
            }
            (frames::FrameWire::Udp { listen, tm_to }, None) => (listen.to_string(), format!("to {tm_to}")),
            (frames::FrameWire::Serial(path), _) => {
                frame_note = format!(" frame_serial={}", path.display());
                (
                    format!("{} (one COBS frame per frame)", path.display()),
                    "back on it".to_string(),
                )
            }
        };
        eprintln!(
            "obsw: space link on {on}: TC frames (COP-1, SDLS SPI {}), TM frames {to} (SDLS SPI {}), counters in {}",
            mib::link::sdls::TC_SPIS[0],
            mib::link::sdls::TM_SPIS[0],
            fc.state.display()
        );
        if fc.tm_sdls == mmic_link::downlink::TmSecurity::Clear {
            eprintln!("obsw: TM frames without SDLS (--tm-sdls clear): readable and forgeable on the path");
        }
        down.frames = Some(ep);
    }
    // The on-board clock's time base: simulated time 0 is wall-clock `epoch` (both read
    // together), so on-board time T is wall time epoch + (T - epoch) / speed. Printed in
    // the READY line, so that time stamps of robots run faster than real time compare.
    let (start, epoch) = {
        let (now, unix) = (
            Instant::now(),
            SystemTime::now().duration_since(UNIX_EPOCH).unwrap_or_default(),
        );
        // Whole milliseconds: the start is moved back by the part below one.
        let sub_ms = Duration::from_nanos(u64::from(unix.subsec_nanos() % 1_000_000));
        (now.checked_sub(sub_ms).unwrap_or(now), unix.as_millis() as u64)
    };
    let mut obsw = Obsw::new(
        Config {
            robot: s.robot,
            epoch_unix_ms: epoch,
        },
        open_store(s.tm_store.as_deref())?,
    );
    if let Some(f) = down.frames.as_ref() {
        obsw.link_keys = f.link_keys();
    }
    let mut team_link = match &s.team {
        Some(t) => {
            let (link, loaded) =
                team::TeamUdp::open(s.robot, t.listen, t.peers.clone(), t.state.clone(), t.key.as_deref())?;
            obsw.team_restore(0, loaded.status, &loaded.record, &mut down);
            if let Some(r) = &t.roster {
                obsw.team_set_roster(0, r)
                    .map_err(|e| anyhow::anyhow!("--team-roster {r:?}: {e}"))?;
            }
            frame_note.push_str(&format!(" team_udp={}", link.local_addr()?));
            eprintln!(
                "obsw: team link on {} with {} peers ({}), term {} roster {:?} from {} ({:?})",
                link.local_addr()?,
                t.peers.len(),
                if link.authenticated() {
                    "AES-256-GCM, --team-key"
                } else {
                    "lab: unauthenticated, --lab-team-bare"
                },
                loaded.record.persisted.term,
                loaded.record.roster,
                t.state.display(),
                loaded.status
            );
            Some(link)
        }
        None => None,
    };
    let mut sim = Sim::new(SimConfig {
        seed: s.seed,
        initial_state: s.initial_state,
        link_loss: s.link_loss,
        link_corrupt: s.link_corrupt,
        ..SimConfig::default()
    });
    sim.set_modules(&s.modules);
    // The configuration the ground accepted: from --config-state (missing or corrupt:
    // nothing accepted), else the factory one, the full robot (an ACCEPT_CONFIG then holds
    // until the process ends).
    let config_lost = match &s.config_state {
        Some(p) => match config_state::load(p) {
            Ok(a) => {
                eprintln!(
                    "obsw: accepted module configuration {:#010x} from {}",
                    a.hash,
                    p.display()
                );
                obsw.set_accepted_config(Some(a));
                None
            }
            Err((why, line)) => {
                log::warn!("{line}");
                eprintln!("obsw: {line}");
                obsw.set_accepted_config(None);
                Some(why)
            }
        },
        None => {
            obsw.set_accepted_config(Some(AcceptedConfig::of(
                &mmic_sim::modules::ModuleSetSpec::full().fitted,
            )));
            None
        }
    };
    // Printed once module discovery is done (below): until then OPERATIONAL is refused
    // (CONFIG_NOT_ACCEPTED, hash 0), so a ground that starts on READY finds the robot's
    // module set known.
    let mut ready = Some(format!(
        "READY robot={} apid=0x{:03X} udp={udp} tcp={tcp} sim_ctl={ctl_addr} speed={} epoch_ms={epoch}{}{frame_note}",
        s.robot,
        obsw.apid(),
        s.speed,
        s.tm_dest.iter().map(|d| format!(" tm_dest={d}")).collect::<String>()
    ));
    eprintln!(
        "obsw: robot {} (APID 0x{:03X}) TC/TM on udp={udp} tcp={tcp}, simulator control on {ctl_addr}, speed x{}",
        s.robot,
        obsw.apid(),
        s.speed
    );

    let period = config::CONTROL_PERIOD_MS as u64;
    let wall_of = |sim_ms: u64| start + Duration::from_secs_f64(sim_ms as f64 / 1000.0 / s.speed);
    let end_ms = s.duration.map(|d| (d * 1000.0) as u64);
    // TCs carry the time of arrival, between the last period and the next.
    let arrival =
        |sim_ms: u64| ((start.elapsed().as_secs_f64() * 1000.0 * s.speed) as u64).clamp(sim_ms, sim_ms + period - 1);
    let mut sim_ms: u64 = 0;
    let mut link_rx: Vec<u8> = Vec::new();
    let mut bad_frames: u32 = 0;
    // Frames the serial link's COBS framing dropped, already in `bad_frames`.
    let mut stream_dropped: u32 = 0;
    // Link counters already reported as events.
    let mut reported = down.counters;
    // SIGTERM or SIGINT: stop at the next control period and exit 0 (the TM log is
    // flushed, and an instrumented build writes its coverage profile).
    let stop = Arc::new(AtomicBool::new(false));
    {
        let stop = stop.clone();
        ctrlc::set_handler(move || stop.store(true, Ordering::SeqCst)).context("installing the signal handler")?;
    }
    // The file service, on the space link only (docs/files.md).
    let file_parts = match (&s.files, &s.frames) {
        (Some(dir), Some(_)) => Some(files::parts(dir)?),
        _ => None,
    };
    let mut file_service = match (&file_parts, &s.files) {
        (Some(p), Some(dir)) => Some(files::Files::new(s.robot, dir, p)),
        _ => None,
    };
    obsw.boot(0, config::reset_cause::POWER_ON, &mut down);
    // Software update on the space link only: the lab's bare packets are not authenticated.
    match (&s.slots, &s.frames, s.bare) {
        (Some(_), Some(_), false) => {
            if let Some(slots) = update::attach(s.slots.as_deref(), s.update_key.as_deref(), s.files.as_deref())? {
                obsw.update.attach(slots);
                obsw.update_boot(0, &mut down);
            }
        }
        (Some(_), _, _) => eprintln!("obsw: --slots ignored: software update needs the space link and no lab link"),
        _ => {}
    }
    if let Some(p) = &s.plan_state {
        plan_state::restore(&mut obsw, p, &mut down);
    }
    if let Some(why) = config_lost {
        obsw.config_state_lost(0, why, &mut down);
    }
    // Board A's table and probes now; board B's half arrives over the A-B link and the
    // control cycle runs discovery (docs/modules.md).
    obsw.start_discovery(0, &sim.modules().table_a, sim.modules().probes_a);
    // Periods run in a row to catch up with the wall clock, inputs left waiting.
    let mut catching_up: u32 = 0;
    loop {
        if !obsw.discovery_pending() {
            if let Some(line) = ready.take() {
                println!("{line}");
            }
        }
        // A process not scheduled for a while is behind the wall clock: the overdue periods
        // run first, so that an input is handled at the simulated time it arrived (its
        // effects are never stamped earlier than that, which keeps robots' time stamps in
        // causal order); at most HOST_CATCH_UP_PERIODS in a row, so a robot that cannot keep
        // up still takes its TCs.
        let behind =
            Instant::now() >= wall_of(sim_ms + period) && catching_up < mib::host_config::HOST_CATCH_UP_PERIODS;
        catching_up = if behind { catching_up + 1 } else { 0 };
        // Inputs already waiting first, but a bounded batch, so that a flood of TCs
        // cannot hold back the control period (and a late period cannot starve TCs).
        let mut handled = 0;
        // TC frames handled whose TM has not been flushed yet.
        let mut frames_unflushed = false;
        while !behind && handled < mib::host_config::HOST_INPUT_BATCH {
            // A LINK_SPI_SELECT just executed takes effect before the next input.
            frames::apply_select(&mut obsw.link_select, down.frames.as_mut());
            let mut any = false;
            let fi = down.frames.as_mut().and_then(frames::FrameEndpoint::next);
            if fi.is_none() && std::mem::take(&mut frames_unflushed) {
                // No further TC frame waiting: the reports of those handled go out now, in
                // as few TM frames as they fill, before the other inputs are looked at.
                if let Some(f) = down.frames.as_mut() {
                    f.flush(Instant::now());
                }
            }
            if let Some(fi) = fi {
                frames_unflushed = true;
                // HK reports the counters including this frame (an HK request it carries too).
                if let Some(f) = down.frames.as_ref() {
                    obsw.space_link = f.hk();
                    obsw.space_link_state = f.hk_state();
                }
                if let frames::FrameInput::Packets(packets) = fi {
                    // COP-1 and SDLS deliver each frame once: no packet duplicate window.
                    for p in packets {
                        if let Some(fs) = file_service.as_mut() {
                            if fs.packet(arrival(sim_ms), &p, &mut obsw, &mut down) {
                                continue;
                            }
                        }
                        obsw.handle_tc_delivered_once(arrival(sim_ms), &p, &mut down);
                    }
                }
                handled += 1;
                any = true;
            }
            if let Some(input) = inputs.next(&mut down) {
                handle_input(
                    input,
                    arrival(sim_ms),
                    &mut obsw,
                    &mut sim,
                    &mut down,
                    &inputs,
                    &mut bad_frames,
                );
                handled += 1;
                any = true;
            }
            // An ACCEPT_CONFIG just executed is stored before the next input.
            config_state::persist(&mut obsw, s.config_state.as_deref(), sim_ms, &mut down);
            plan_state::persist(&mut obsw, s.plan_state.as_deref());
            if !any {
                break;
            }
        }
        if let Some(f) = down.frames.as_mut() {
            f.flush(Instant::now());
        }
        if obsw.update.reset_requested() {
            // The activation's completion (or the self-test's event) went out above.
            std::thread::sleep(update::RESET_DELAY);
            if let Some(f) = down.frames.as_mut() {
                f.flush(Instant::now());
            }
            return Err(update::reset());
        }
        let due = wall_of(sim_ms + period);
        if Instant::now() < due {
            if handled < mib::host_config::HOST_INPUT_BATCH {
                inputs.wait_until(due, &mut down);
            }
            continue;
        }
        sim_ms += period;
        obsw.io.tm_dropped = down.counters.tm_dropped;
        if let Some(t) = team_link.as_ref() {
            obsw.io.tm_dropped = obsw.io.tm_dropped.wrapping_add(t.send_errors);
        }
        report_link_events(&mut obsw, sim_ms, &mut reported, &mut down);
        if let Some(f) = down.frames.as_mut() {
            obsw.space_link = f.hk();
            obsw.space_link_state = f.hk_state();
            obsw.io.tm_dropped = obsw.io.tm_dropped.wrapping_add(f.send_failures);
            // Frames the serial line's framing dropped (oversize, corrupt COBS) count as
            // uplink frames dropped before the OBSW saw them, as on board A.
            let dropped = f.stream_counters().dropped();
            if dropped != stream_dropped {
                bad_frames = bad_frames.wrapping_add(dropped.wrapping_sub(stream_dropped));
                stream_dropped = dropped;
                obsw.io.tc_dropped = bad_frames;
            }
            let events = f.events();
            for ev in events {
                obsw.link_event(sim_ms, ev, &mut down);
            }
        }
        if let Some(fs) = file_service.as_mut() {
            fs.poll(sim_ms, &mut obsw, &mut down);
        }
        let sensors = sim.sensors_a();
        let out = obsw.tick(sim_ms, &sensors, &link_rx, &mut down);
        link_rx.clear();
        sim.step(period as u32, &out.actuators, &out.link_tx, &mut link_rx);
        // ... or one released by the on-board schedule.
        config_state::persist(&mut obsw, s.config_state.as_deref(), sim_ms, &mut down);
        // The plan's progress of this period, before the next period starts a step.
        plan_state::persist(&mut obsw, s.plan_state.as_deref());
        if let Some(t) = team_link.as_mut() {
            let mut buf = [0u8; config::MAX_PACKET_LEN];
            // Team datagrams are inputs too: left waiting while the periods catch up.
            let behind =
                Instant::now() >= wall_of(sim_ms + period) && catching_up < mib::host_config::HOST_CATCH_UP_PERIODS;
            while let Some(n) = (!behind).then(|| t.recv(&mut buf)).flatten() {
                let r = t.rand();
                match t.open_datagram(&mut buf[..n]) {
                    Ok((from, packet)) => {
                        let packet = packet.to_vec();
                        obsw.team_packet(sim_ms, r, from, &packet, t, &mut down);
                    }
                    Err((why, sender)) => obsw.team_rejected(sim_ms, why, sender, &mut down),
                }
            }
            let r = t.rand();
            obsw.team_poll(sim_ms, r, t, &mut down);
            // The on-board plan's progress for the robots whose steps wait on this one's.
            obsw.plan_team(sim_ms, t);
            for _ in 0..t.take_seal_errors() {
                obsw.team_rejected(
                    sim_ms,
                    obsw_core::services::team::TeamReject::StoreFailed,
                    s.robot,
                    &mut down,
                );
            }
        }
        if let Some(f) = down.frames.as_mut() {
            f.flush(Instant::now());
        }
        if end_ms.is_some_and(|e| sim_ms >= e) || stop.load(Ordering::SeqCst) {
            return Ok(());
        }
    }
}

/// Raises one event per kind and control period for what the TCP bounds did since the
/// last period (the core throttles repeats further), so a flood of connections or a
/// stalled client is visible in TM, not only in the counters.
fn report_link_events(
    obsw: &mut Obsw<HostStore>,
    now: u64,
    reported: &mut net::GroundLinkCounters,
    down: &mut net::TmDestinations,
) {
    let c = down.counters;
    if c.tcp_refused != reported.tcp_refused {
        obsw.link_event(now, LinkEvent::TcpRefused { total: c.tcp_refused }, down);
    }
    if c.tcp_slow_dropped != reported.tcp_slow_dropped {
        obsw.link_event(
            now,
            LinkEvent::TcpClientDropped {
                total: c.tcp_slow_dropped,
            },
            down,
        );
    }
    *reported = c;
}

/// Handles one input of the main loop at on-board time `now`.
fn handle_input(
    input: Input,
    now: u64,
    obsw: &mut Obsw<HostStore>,
    sim: &mut Sim,
    down: &mut net::TmDestinations,
    inputs: &net::Inputs,
    bad_frames: &mut u32,
) {
    if !down.bare && matches!(input, Input::Tc(..) | Input::BadFrame | Input::OversizeFrame(..)) {
        // Frame link only: a bare packet executes nothing, changes nothing, is counted.
        *bad_frames += 1;
        obsw.io.tc_dropped = *bad_frames;
        if bad_frames.is_power_of_two() {
            log::warn!("dropped a bare packet: the bare-packet link is off ({bad_frames} so far)");
        }
        return;
    }
    match input {
        Input::Tc(bytes, origin) => {
            let mut refused_from = None;
            if let Origin::Udp(peer) = origin {
                // Only a TC that passes acceptance subscribes its sender (or renews the
                // lease); a refused one is reported to the current subscribers and to
                // its sender, which does not become a subscriber.
                if obsw_core::accept::accept(&bytes, obsw.apid()).is_ok() {
                    down.subscribe(peer, Instant::now());
                } else {
                    refused_from = Some(peer);
                }
            }
            down.reply_to(refused_from);
            obsw.handle_tc(now, &bytes, down);
            down.reply_to(None);
        }
        Input::BadFrame => {
            *bad_frames += 1;
            obsw.io.tc_dropped = *bad_frames;
            log::warn!("dropped a malformed COBS frame on TCP ({bad_frames} so far)");
            // A frame that cannot be decoded has no request ID: report it as a
            // malformed packet through the normal acceptance path.
            obsw.handle_tc(now, &[], down);
        }
        Input::OversizeFrame(len, head) => {
            *bad_frames += 1;
            obsw.io.tc_dropped = *bad_frames;
            log::warn!(
                "refused a TCP frame of {len} bytes (longest packet {}; {bad_frames} bad frames so far)",
                config::MAX_PACKET_LEN
            );
            // TM[1,2] FRAME_TOO_LONG (with the request ID if the frame's head gives it).
            obsw.reject_frame(now, len, &head, down);
        }
        Input::BadSimCtl(len, from) => inputs.reply_sim_ctl(
            from,
            &format!(
                "error line of {len} bytes refused: at most {} bytes of UTF-8 text",
                mib::host_config::SIM_CTL_MAX_LINE
            ),
        ),
        Input::SimCtl(line, from) => inputs.reply_sim_ctl(from, &sim_control(sim, &line)),
    }
}

/// One simulator-control line → one reply line.
fn sim_control(sim: &mut Sim, line: &str) -> String {
    match line.trim() {
        "clear" => {
            sim.clear_all();
            "ok cleared all faults".into()
        }
        "status" => format!("ok {:?}", sim.truth()),
        // A probability is never negative, not even "-0".
        other if other.split_whitespace().skip(1).any(|w| w.starts_with('-')) => {
            format!("error {other:?}: arguments are never negative")
        }
        other => match other.parse::<SimCommand>() {
            Ok(c) => {
                sim.apply(c);
                format!("ok {c:?}")
            }
            Err(e) => format!("error {e}"),
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The settings of these options, with the lab link when no link is named (the
    /// tests of other options do not care which link).
    fn parse(args: &[&str]) -> Result<Settings> {
        let lab: &[&str] = if args.contains(&"--frame-udp") {
            &[]
        } else {
            &["--lab-bare-packets"]
        };
        parse_raw(&[args, lab].concat())
    }

    fn parse_raw(args: &[&str]) -> Result<Settings> {
        settings(Args::try_parse_from([&["obsw"], args].concat()).expect("options parse"))
    }

    const FRAMES: [&str; 10] = [
        "--frame-udp",
        "127.0.0.1:0",
        "--frame-tm-to",
        "127.0.0.1:9",
        "--tc-key",
        "tc.key",
        "--tm-key",
        "tm.key",
        "--link-state",
        "link.state",
    ];

    // verifies: TEAM-SEC-03, TEAM-CONF-01
    #[test]
    fn the_team_link_needs_a_key_or_the_local_lab_flag_and_is_accepted_in_the_config_file() {
        let t = [
            "--team-udp",
            "127.0.0.1:0",
            "--team-state",
            "t.state",
            "--peer",
            "2=127.0.0.1:9",
        ];
        let e = parse(&t).err().expect("no key, no lab flag").to_string();
        assert!(e.contains("--team-key"), "{e}");
        let s = parse(&[&t[..], &["--team-key", "team.key"]].concat()).unwrap();
        let team = s.team.unwrap();
        assert_eq!(team.key.as_deref(), Some(std::path::Path::new("team.key")));
        assert_eq!(team.peers.len(), 1);
        assert!(parse(&[&t[..], &["--lab-team-bare"]].concat())
            .unwrap()
            .team
            .unwrap()
            .key
            .is_none());
        assert!(parse(&[&t[..], &["--lab-team-bare", "--team-key", "k"]].concat()).is_err());
        let far = [
            "--team-udp",
            "127.0.0.1:0",
            "--team-state",
            "t",
            "--peer",
            "2=10.0.0.2:9",
            "--lab-team-bare",
        ];
        assert!(parse(&far).is_err(), "bare team packets only on loopback");
        assert!(parse(&["--peer", "2=127.0.0.1:9"]).is_err(), "--peer needs --team-udp");
        // The same from the --config file; the command line wins.
        let dir = std::env::temp_dir().join(format!("obsw-team-config-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let cfg = dir.join("obsw.toml");
        std::fs::write(
            &cfg,
            "team_udp = \"127.0.0.1:0\"\npeer = [\"2=127.0.0.1:9\", \"3=127.0.0.1:10\"]\nteam_state = \"t.state\"\nteam_key = \"team.key\"\nteam_roster = \"1,2,3\"\n",
        )
        .unwrap();
        let c = cfg.display().to_string();
        let team = parse(&["--config", &c]).unwrap().team.unwrap();
        assert_eq!(team.peers.len(), 2);
        assert_eq!(team.roster, Some(vec![1, 2, 3]));
        assert_eq!(team.key.as_deref(), Some(std::path::Path::new("team.key")));
        let team = parse(&["--config", &c, "--team-key", "other.key"])
            .unwrap()
            .team
            .unwrap();
        assert_eq!(team.key.as_deref(), Some(std::path::Path::new("other.key")));
        std::fs::write(&cfg, "team_udp = \"127.0.0.1:0\"\nteam_state = \"t\"\n").unwrap();
        assert!(parse(&["--config", &c]).is_err(), "the key rule holds for the file too");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// A `--config` file with `text`, its path.
    fn toml_file(text: &str) -> String {
        use std::sync::atomic::{AtomicU32, Ordering};
        static N: AtomicU32 = AtomicU32::new(0);
        let p = std::env::temp_dir().join(format!(
            "obsw-cfg-{}-{}.toml",
            std::process::id(),
            N.fetch_add(1, Ordering::Relaxed)
        ));
        std::fs::write(&p, text).unwrap();
        p.display().to_string()
    }

    // verifies: LINK-HOST-01, OPS-LINK-DEFAULT-02, LINK-STREAM-05
    #[test]
    fn the_frame_link_needs_all_its_options_and_the_lab_mode_is_explicit_and_local() {
        // No link chosen: refused, naming both choices.
        let e = parse_raw(&[]).err().expect("no link").to_string();
        assert!(e.contains("--frame-udp") && e.contains("--lab-bare-packets"), "{e}");
        // --keys DIR: robot N's files and the default ports.
        let s = parse_raw(&["--robot", "3", "--keys", "k"]).unwrap();
        // The TM store file is the robot's too.
        assert_eq!(
            s.tm_store.as_deref(),
            Some(std::path::Path::new("k/robot-3/tm-store.bin"))
        );
        let fc = s.frames.expect("frames from --keys");
        assert!(!s.bare);
        assert_eq!(
            fc.wire,
            frames::FrameWire::Udp {
                listen: "127.0.0.1:7503".parse().unwrap(),
                tm_to: "127.0.0.1:7603".parse().unwrap()
            }
        );
        assert_eq!(fc.tc_key, PathBuf::from("k/robot-3/tc-spi1.key"));
        assert_eq!(fc.tm_key, PathBuf::from("k/robot-3/tm-spi17.key"));
        assert_eq!(fc.state, PathBuf::from("k/robot-3/obsw-link.state"));
        let s = parse_raw(&["--keys", "k", "--frame-udp", "127.0.0.1:9000"]).unwrap();
        assert!(matches!(s.frames.unwrap().wire,
            frames::FrameWire::Udp { listen, .. } if listen == "127.0.0.1:9000".parse().unwrap()));
        // --frame-serial: the keys' files, no UDP addresses; not with --frame-udp.
        let s = parse_raw(&["--keys", "k", "--frame-serial", "/dev/ttyACM0"]).unwrap();
        let fc = s.frames.expect("frames over the serial line");
        assert_eq!(fc.wire, frames::FrameWire::Serial(PathBuf::from("/dev/ttyACM0")));
        assert_eq!(fc.tc_key, PathBuf::from("k/robot-1/tc-spi1.key"));
        assert!(!s.bare);
        assert!(Args::try_parse_from([
            "obsw",
            "--keys",
            "k",
            "--frame-serial",
            "/dev/x",
            "--frame-udp",
            "127.0.0.1:9"
        ])
        .is_err());
        let f = toml_file("frame_serial = \"/dev/x\"\nframe_tm_to = \"127.0.0.1:9\"\nkeys = \"k\"\n");
        assert!(
            parse_raw(&["--config", &f]).is_err(),
            "two transports in the file: refused"
        );
        let f = toml_file("frame_serial = \"/dev/x\"\nkeys = \"k\"\n");
        assert!(matches!(
            parse_raw(&["--config", &f]).unwrap().frames.unwrap().wire,
            frames::FrameWire::Serial(_)
        ));
        let ser = parse_raw(&["--frame-serial", "/dev/x"])
            .err()
            .expect("no keys")
            .to_string();
        assert!(ser.contains("--tc-key"), "{ser}");
        // The lab link alone, on loopback.
        let s = parse_raw(&["--lab-bare-packets"]).unwrap();
        assert!(s.bare && s.frames.is_none());
        assert!(parse_raw(&["--lab-bare-packets", "--udp", "0.0.0.0:7301"]).is_err());
        // The frame link alone: bare packets off.
        let s = parse(&FRAMES).unwrap();
        assert!(!s.bare && s.frames.is_some());
        // Part of the frame options: refused.
        assert!(parse(&FRAMES[..4]).is_err());
        // Lab mode keeps the bare link, on loopback only.
        let with_lab = [&FRAMES[..], &["--lab-bare-packets"]].concat();
        assert!(parse(&with_lab).unwrap().bare);
        let remote = [&with_lab[..], &["--udp", "0.0.0.0:7301"]].concat();
        assert!(parse(&remote).is_err());
        // --tm-dest sends bare packets: beside frames only in lab mode.
        let dest = [&FRAMES[..], &["--tm-dest", "127.0.0.1:10015"]].concat();
        assert!(parse(&dest).is_err());
        assert!(parse(&[&dest[..], &["--lab-bare-packets"]].concat()).is_ok());
    }
}
