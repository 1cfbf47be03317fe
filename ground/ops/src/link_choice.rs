//! How the ground reaches its robots, chosen once for every front end (`run`, `send`,
//! `ping`, `mode`, `watch`, `model`, `collect`): the space link (TC/TM frames, COP-1,
//! SDLS) by default; the bare-packet links only as a lab mode named so on the command
//! line, and only to robots on loopback addresses.

use std::collections::BTreeMap;
use std::net::SocketAddr;
use std::path::PathBuf;

use crate::link::{FrameOptions, Transport};

/// Environment variable naming the key directory when `--keys` is not given.
pub const KEYS_ENV: &str = "MMIC_KEYS";

/// How the robots are reached, as the binary's link flags (`--keys`, `--tm-listen`,
/// `--spi`, `--tm-sdls`, `--serial`, `--lab-udp`, `--lab-tcp`) give it; [`LinkChoice::resolve`]
/// turns it into a transport and its frame options.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct LinkChoice {
    /// Key directory of the space link: robot N uses `keys/robot-N/`. Needed unless a lab
    /// link is chosen.
    pub keys: Option<PathBuf>,
    /// Local address robot N's TM frames arrive at, per robot (the obsw's
    /// `--frame-tm-to`); default [`crate::link::default_tm_listen`].
    pub tm_listen: Vec<(u8, SocketAddr)>,
    /// The space link's TC SPI: 1, or 2 after a key change.
    pub spi: u16,
    /// SDLS on the robot's TM frames (the robot's `--tm-sdls`).
    pub tm_sdls: ground_link::TmSecurity,
    /// The space link over a serial device or Unix socket (`--serial [N=]PATH`, see
    /// [`parse_serial`]): robot N's TC and TM frames as COBS frames on that byte stream
    /// (board A's ground link) instead of UDP. Without N: the one robot given.
    pub serial: Vec<(Option<u8>, PathBuf)>,
    /// Lab mode: bare space packets, one per UDP datagram (robots on loopback only).
    pub lab_udp: bool,
    /// Lab mode: bare space packets over TCP with COBS framing (robots on loopback only).
    pub lab_tcp: bool,
}

/// Why the link flags cannot be used.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum LinkChoiceError {
    #[error(
        "the space link needs its keys: give --keys DIR (or set {KEYS_ENV}); `ground keys create DIR` makes them. \
         For the unauthenticated lab link to a robot on loopback use --lab-udp or --lab-tcp"
    )]
    NoKeys,
    #[error("--{flag}: robot {robot} at {addr} is not on a loopback address; bare packets are for the lab only")]
    LabNotLoopback {
        flag: &'static str,
        robot: u8,
        addr: SocketAddr,
    },
    #[error("--tm-listen is an option of the space link; it does not go with --{flag}")]
    TmListenWithLab { flag: &'static str },
    #[error("--serial is the space link over a serial line; it does not go with --{flag}")]
    SerialWithLab { flag: &'static str },
    #[error("--serial {path}: with several robots say which one, --serial N=PATH")]
    SerialWhichRobot { path: String },
    #[error("--serial {robot}=...: robot {robot} is not one of the robots given")]
    SerialUnknownRobot { robot: u8 },
    #[error("--serial: robot {robot} is given two serial ports")]
    SerialTwice { robot: u8 },
}

/// Reads a `--serial` value: `N=PATH` (robot N) or `PATH` (the one robot given).
pub fn parse_serial(s: &str) -> Result<(Option<u8>, PathBuf), String> {
    if let Some((n, path)) = s.split_once('=') {
        if let Ok(n) = n.parse::<u8>() {
            if mib::apid::robot_apid(n).is_none() {
                return Err(format!(
                    "\"{s}\": robot numbers are {}..={}",
                    mib::apid::ROBOT_MIN,
                    mib::apid::ROBOT_MAX
                ));
            }
            if path.is_empty() {
                return Err(format!("\"{s}\": the path of the serial device is missing"));
            }
            return Ok((Some(n), PathBuf::from(path)));
        }
    }
    if s.is_empty() {
        return Err("the path of the serial device is missing".into());
    }
    Ok((None, PathBuf::from(s)))
}

impl Default for LinkChoice {
    /// The command line's defaults: the space link, keys from nowhere yet, TC SPI 1,
    /// encrypted TM.
    fn default() -> LinkChoice {
        LinkChoice {
            keys: None,
            tm_listen: Vec::new(),
            spi: 1,
            tm_sdls: ground_link::TmSecurity::Encrypt,
            serial: Vec::new(),
            lab_udp: false,
            lab_tcp: false,
        }
    }
}

impl LinkChoice {
    /// Robot `n`'s address when `--robot N` gives none: on loopback, its space-link port
    /// (`mib::host_config::frame_port`, obsw --frame-udp's default), or with a lab flag its
    /// bare-packet port (`mib::host_config::robot_port`, obsw --udp's default).
    pub fn default_addr(&self, n: u8) -> SocketAddr {
        let transport = match (self.lab_udp, self.lab_tcp) {
            (true, _) => Transport::Udp,
            (false, true) => Transport::Tcp,
            (false, false) => Transport::Frames,
        };
        crate::link::default_addr(n, transport)
    }

    /// The transport and, over frames, its keys and TM addresses, for these robots.
    pub fn resolve(&self, robots: &[(u8, SocketAddr)]) -> Result<(Transport, Option<FrameOptions>), LinkChoiceError> {
        let lab = match (self.lab_udp, self.lab_tcp) {
            (true, _) => Some((Transport::Udp, "lab-udp")),
            (false, true) => Some((Transport::Tcp, "lab-tcp")),
            (false, false) => None,
        };
        match lab {
            Some((transport, flag)) => {
                if !self.tm_listen.is_empty() {
                    return Err(LinkChoiceError::TmListenWithLab { flag });
                }
                if !self.serial.is_empty() {
                    return Err(LinkChoiceError::SerialWithLab { flag });
                }
                if let Some(&(robot, addr)) = robots.iter().find(|(_, a)| !a.ip().is_loopback()) {
                    return Err(LinkChoiceError::LabNotLoopback { flag, robot, addr });
                }
                Ok((transport, None))
            }
            None => {
                let keys = self.keys.clone().ok_or(LinkChoiceError::NoKeys)?;
                let mut serial = BTreeMap::new();
                for (robot, path) in &self.serial {
                    let robot = match (robot, robots) {
                        (Some(n), _) if robots.iter().any(|(r, _)| r == n) => *n,
                        (Some(n), _) => return Err(LinkChoiceError::SerialUnknownRobot { robot: *n }),
                        (None, [(n, _)]) => *n,
                        (None, _) => {
                            return Err(LinkChoiceError::SerialWhichRobot {
                                path: path.display().to_string(),
                            })
                        }
                    };
                    if serial.insert(robot, path.clone()).is_some() {
                        return Err(LinkChoiceError::SerialTwice { robot });
                    }
                }
                Ok((
                    Transport::Frames,
                    Some(FrameOptions {
                        tm_listen: self.tm_listen.iter().copied().collect(),
                        tc_spi: self.spi,
                        tm_security: self.tm_sdls,
                        serial,
                        ..FrameOptions::new(keys)
                    }),
                ))
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn local(port: u16) -> SocketAddr {
        SocketAddr::from(([127, 0, 0, 1], port))
    }

    // verifies: OPS-LINK-DEFAULT-01
    #[test]
    fn frames_are_the_default_and_need_keys() {
        let none = LinkChoice::default();
        assert_eq!(none.resolve(&[(1, local(7301))]), Err(LinkChoiceError::NoKeys));
        assert!(LinkChoiceError::NoKeys.to_string().contains("--keys DIR"));
        assert_eq!(none.default_addr(2), local(7502));
        let keyed = LinkChoice {
            keys: Some("k".into()),
            tm_listen: vec![(1, local(9401))],
            ..LinkChoice::default()
        };
        let (t, f) = keyed.resolve(&[(1, local(7301))]).unwrap();
        assert_eq!(t, Transport::Frames);
        let f = f.unwrap();
        assert_eq!(f.keys, PathBuf::from("k"));
        assert_eq!(f.tm_listen.get(&1), Some(&local(9401)));
    }

    // verifies: OPS-LINK-DEFAULT-01
    #[test]
    fn the_lab_links_are_explicit_and_loopback_only() {
        let udp = LinkChoice {
            lab_udp: true,
            ..LinkChoice::default()
        };
        assert_eq!(udp.resolve(&[(1, local(7301))]), Ok((Transport::Udp, None)));
        assert_eq!(udp.default_addr(2), local(7302));
        let tcp = LinkChoice {
            lab_tcp: true,
            keys: Some("ignored".into()),
            ..LinkChoice::default()
        };
        assert_eq!(tcp.resolve(&[(2, local(7302))]), Ok((Transport::Tcp, None)));
        let remote: SocketAddr = "10.0.0.7:7301".parse().unwrap();
        let e = udp.resolve(&[(1, local(7301)), (3, remote)]).unwrap_err();
        assert_eq!(
            e,
            LinkChoiceError::LabNotLoopback {
                flag: "lab-udp",
                robot: 3,
                addr: remote
            }
        );
        assert!(e.to_string().contains("robot 3 at 10.0.0.7:7301"));
        let with_listen = LinkChoice {
            lab_udp: true,
            tm_listen: vec![(1, local(9401))],
            ..LinkChoice::default()
        };
        assert!(matches!(
            with_listen.resolve(&[(1, local(7301))]),
            Err(LinkChoiceError::TmListenWithLab { .. })
        ));
    }

    // verifies: LINK-STREAM-04
    #[test]
    fn serial_ports_are_named_per_robot_and_only_on_the_space_link() {
        assert_eq!(parse_serial("/dev/ttyACM0"), Ok((None, PathBuf::from("/dev/ttyACM0"))));
        assert_eq!(
            parse_serial("2=/dev/ttyACM1"),
            Ok((Some(2), PathBuf::from("/dev/ttyACM1")))
        );
        assert_eq!(
            parse_serial("./a=b"),
            Ok((None, PathBuf::from("./a=b"))),
            "not a robot number: a path"
        );
        assert!(parse_serial("0=/dev/x").is_err() && parse_serial("3=").is_err() && parse_serial("").is_err());
        let one = LinkChoice {
            keys: Some("k".into()),
            serial: vec![(None, "/dev/ttyACM0".into())],
            ..LinkChoice::default()
        };
        let (t, f) = one.resolve(&[(1, local(7501))]).unwrap();
        assert_eq!(t, Transport::Frames);
        assert_eq!(f.unwrap().serial.get(&1), Some(&PathBuf::from("/dev/ttyACM0")));
        assert_eq!(
            one.resolve(&[(1, local(7501)), (2, local(7502))]),
            Err(LinkChoiceError::SerialWhichRobot {
                path: "/dev/ttyACM0".into()
            })
        );
        let two = LinkChoice {
            serial: vec![(Some(2), "/dev/ttyACM1".into())],
            ..one.clone()
        };
        let f = two.resolve(&[(1, local(7501)), (2, local(7502))]).unwrap().1.unwrap();
        assert_eq!(f.serial.len(), 1, "robot 1 stays on UDP");
        assert_eq!(
            two.resolve(&[(1, local(7501))]),
            Err(LinkChoiceError::SerialUnknownRobot { robot: 2 })
        );
        let twice = LinkChoice {
            serial: vec![(Some(1), "a".into()), (None, "b".into())],
            ..one.clone()
        };
        assert_eq!(
            twice.resolve(&[(1, local(7501))]),
            Err(LinkChoiceError::SerialTwice { robot: 1 })
        );
        let lab = LinkChoice {
            lab_tcp: true,
            ..one.clone()
        };
        assert_eq!(
            lab.resolve(&[(1, local(7301))]),
            Err(LinkChoiceError::SerialWithLab { flag: "lab-tcp" })
        );
        let no_keys = LinkChoice { keys: None, ..one };
        assert_eq!(no_keys.resolve(&[(1, local(7501))]), Err(LinkChoiceError::NoKeys));
    }
}
