//! The robot-link flags every verb that talks to robots shares (`--robot`, the space link's
//! keys and SPIs, the lab links), the session they open and the archive beside it.

use std::net::SocketAddr;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use clap::Args;
use ground::archive::{self, Archive};
use ground::collect::parse_robot_arg;
use ground::link::{FrameOptions, Transport};
use ground::link_choice::{LinkChoice, KEYS_ENV};
use ground::ops::Session;

use crate::exit::{self, coded};
use crate::output::err_line;

/// Robot links: `N=HOST:PORT`, or `N` for 127.0.0.1:(7300+N), over the space link unless
/// a lab flag says otherwise ([`ground::link_choice`]).
#[derive(Args, Debug, Clone)]
pub(crate) struct Links {
    /// Robot link `N=HOST:PORT`: the robot's space-link port (obsw --frame-udp), or with a
    /// lab flag its --udp/--tcp port. Just `N`: 127.0.0.1:7500+N (the obsw's default
    /// --frame-udp), with a lab flag 127.0.0.1:7300+N. Repeat per robot. Required by
    /// ping, send, mode and watch; `run` adds the plan's robots.
    #[arg(long = "robot", short = 'r', value_parser = parse_robot_arg)]
    pub(crate) robots: Vec<(u8, Option<SocketAddr>)>,
    #[command(flatten)]
    pub(crate) link: LinkFlags,
}

/// The link flags shared by every verb that talks to robots ([`LinkChoice`]).
#[derive(Args, Debug, Clone)]
pub(crate) struct LinkFlags {
    /// Key directory of the space link (`ground keys create DIR`): robot N uses
    /// DIR/robot-N/. Needed unless a lab link is chosen.
    #[arg(long, value_name = "DIR", env = KEYS_ENV)]
    keys: Option<PathBuf>,
    /// Local address robot N's TM frames arrive at, `N=HOST:PORT` (the obsw's
    /// --frame-tm-to); default 127.0.0.1:7600+N (0.0.0.0 for a remote robot). Repeat per robot.
    #[arg(long = "tm-listen", value_parser = ground::collect::parse_robot, value_name = "N=HOST:PORT")]
    tm_listen: Vec<(u8, SocketAddr)>,
    /// The space link's TC SPI: 1, or 2 after a key change (`LINK_SPI_SELECT`; the
    /// key folder holds both keys).
    #[arg(long, value_name = "1|2", default_value_t = mib::link::sdls::TC_SPIS[0], value_parser = parse_tc_spi)]
    spi: u16,
    /// SDLS on the robot's TM frames, as its `--tm-sdls`: encrypt (the default) or clear.
    #[arg(long, value_name = "encrypt|clear", default_value = "encrypt", value_parser = parse_tm_sdls)]
    tm_sdls: ground_link::TmSecurity,
    /// Lab mode: bare (unauthenticated) space packets, one per UDP datagram, instead of
    /// the space link; robots on loopback addresses only (obsw --lab-bare-packets).
    #[arg(long, conflicts_with = "lab_tcp")]
    lab_udp: bool,
    /// Lab mode: bare (unauthenticated) space packets over TCP with COBS framing;
    /// robots on loopback addresses only (obsw --lab-bare-packets).
    #[arg(long)]
    lab_tcp: bool,
    /// The space link over a serial device (raw mode; board A's USB ground link, e.g.
    /// /dev/ttyACM0) or a Unix socket (QEMU -serial unix:), one COBS frame per transfer
    /// frame, instead of UDP: `N=PATH`, or `PATH` with one robot. Repeat per robot.
    #[arg(long, value_name = "[N=]PATH", value_parser = ground_ops::link_choice::parse_serial)]
    serial: Vec<(Option<u8>, PathBuf)>,
}

fn parse_tc_spi(s: &str) -> Result<u16, String> {
    let spis = mib::link::sdls::TC_SPIS;
    s.parse()
        .ok()
        .filter(|n| spis.contains(n))
        .ok_or_else(|| format!("\"{s}\": the TC SPIs are {spis:?}"))
}

fn parse_tm_sdls(s: &str) -> Result<ground_link::TmSecurity, String> {
    ground_link::TmSecurity::from_name(s).ok_or_else(|| format!("\"{s}\": encrypt or clear"))
}

impl LinkFlags {
    /// The library's link choice these flags make.
    pub(crate) fn choice(&self) -> LinkChoice {
        LinkChoice {
            keys: self.keys.clone(),
            tm_listen: self.tm_listen.clone(),
            spi: self.spi,
            tm_sdls: self.tm_sdls,
            serial: self.serial.clone(),
            lab_udp: self.lab_udp,
            lab_tcp: self.lab_tcp,
        }
    }

    /// Robot `n`'s address when `--robot N` gives none ([`LinkChoice::default_addr`]).
    pub(crate) fn default_addr(&self, n: u8) -> SocketAddr {
        self.choice().default_addr(n)
    }
}

impl Links {
    /// The robots given with `--robot`, at their default addresses (for the link chosen)
    /// where none is given.
    pub(crate) fn addresses(&self) -> Vec<(u8, SocketAddr)> {
        self.robots
            .iter()
            .map(|&(n, addr)| (n, addr.unwrap_or_else(|| self.link.default_addr(n))))
            .collect()
    }

    /// The transport and frame options for these robots (usage errors exit 2).
    pub(crate) fn choice(&self, robots: &[(u8, SocketAddr)]) -> Result<(Transport, Option<FrameOptions>)> {
        self.link
            .choice()
            .resolve(robots)
            .map_err(|e| coded(exit::USAGE, e.to_string()))
    }

    /// Says which robots the verb talks to and how, then opens the archive (if wanted)
    /// and a session to them.
    pub(crate) fn open(
        &self,
        robots: &[(u8, SocketAddr)],
        archive_path: Option<&Path>,
    ) -> Result<(Session, Option<Archive>)> {
        let (transport, frames) = self.choice(robots)?;
        say_links(robots, transport, frames.as_ref());
        open_session(robots, transport, frames.as_ref(), archive_path)
    }
}

/// Says which robots a verb talks to, and how.
pub(crate) fn say_links(links: &[(u8, SocketAddr)], transport: Transport, frames: Option<&FrameOptions>) {
    let l: Vec<String> = links
        .iter()
        .map(|(r, a)| match frames.and_then(|f| f.serial.get(r)) {
            Some(path) => format!("robot {r} on serial {}", path.display()),
            None => format!("robot {r} at {a}"),
        })
        .collect();
    err_line!("talking to {} ({})", l.join(", "), transport.name());
}

/// The robots given with `--robot` (at least one: which robot is never guessed).
pub(crate) fn robots_given(l: &Links) -> Result<Vec<(u8, SocketAddr)>> {
    if l.robots.is_empty() {
        return Err(coded(
            exit::USAGE,
            "give --robot N (robot N at its default port on 127.0.0.1) or --robot N=HOST:PORT",
        ));
    }
    Ok(l.addresses())
}

/// The one robot of `l`, announced, with a session to it (and the archive, if any).
pub(crate) fn open_one(l: &Links, archive_path: Option<&Path>) -> Result<(u8, Session, Option<Archive>)> {
    let (robot, addr) = one_robot(l)?;
    let (s, arch) = l.open(&[(robot, addr)], archive_path)?;
    Ok((robot, s, arch))
}

pub(crate) fn one_robot(l: &Links) -> Result<(u8, SocketAddr)> {
    match robots_given(l)?.as_slice() {
        [one] => Ok(*one),
        _ => Err(coded(exit::USAGE, "give exactly one --robot")),
    }
}

/// Opens the archive (if wanted) and a session to the given robots.
pub(crate) fn open_session(
    links: &[(u8, SocketAddr)],
    transport: Transport,
    frames: Option<&FrameOptions>,
    archive_path: Option<&Path>,
) -> Result<(Session, Option<Archive>)> {
    if links.is_empty() {
        return Err(coded(exit::INVALID, "no robot given (use --robot N=HOST:PORT)"));
    }
    let archive = archive_path
        .map(|p| Archive::open(p).with_context(|| format!("opening archive {}", p.display())))
        .transpose()?;
    let path = archive_path.map(Path::to_path_buf);
    let session = Session::connect_with(links, transport, frames, archive.as_ref().map(|a| a.sender()), |apid| {
        Some(ground::ops::first_tc_seq(
            path.as_deref().and_then(|p| archive::next_seq(p, apid)),
        ))
    })
    .map_err(|e| match &e {
        // Another ground process commands the robot (ground::robot_lock): refused.
        ground::ops::OpsError::Connect { err, .. } if err.kind() == std::io::ErrorKind::AddrInUse => {
            coded(exit::INVALID, e.to_string())
        }
        _ => coded(exit::NO_ANSWER, e.to_string()),
    })?;
    Ok((session, archive))
}

pub(crate) fn close_archive(a: Option<Archive>) -> Result<()> {
    if let Some(a) = a {
        a.close().context("closing the archive")?;
    }
    Ok(())
}
