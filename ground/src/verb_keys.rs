//! `ground keys`: create and show the space link's key files (see `ground::keys`). A key is
//! never printed: `show` gives each file's direction, SPI, mode and SHA-256 fingerprint.

use std::path::PathBuf;

use anyhow::Result;
use clap::Subcommand;
use ground::keys::{self, Direction};

use crate::exit::{self, coded};
use crate::output::out;

#[derive(Subcommand, Debug)]
pub(crate) enum KeysCmd {
    /// Create random keys for each robot's link: DIR/robot-N/tc-spi{1,2}.key and
    /// tm-spi{17,18}.key (raw 32 bytes, as Yamcs reads them; mode 0600). Existing key
    /// files are never overwritten.
    Create {
        dir: PathBuf,
        /// Robot number; repeat per robot [default: 1, unless --team alone]. Each robot
        /// gets its own keys.
        #[arg(long = "robot", short = 'r')]
        robots: Vec<u8>,
        /// Also create DIR/team.key, the one key all robots of a team share for their
        /// team packets (`obsw --team-key`); never a link key.
        #[arg(long)]
        team: bool,
    },
    /// List the key files under DIR: direction, SPI, mode, fingerprint (never the key).
    Show { dir: PathBuf },
}

pub(crate) fn keys(c: &KeysCmd) -> Result<u8> {
    match c {
        KeysCmd::Create { dir, robots, team } => {
            let robots = match (robots.is_empty(), team) {
                (true, true) => Vec::new(),
                (true, false) => vec![1],
                (false, _) => robots.clone(),
            };
            for &r in &robots {
                if mib::apid::robot_apid(r).is_none() {
                    return Err(coded(exit::USAGE, format!("robot {r} is not a robot number")));
                }
            }
            for &r in &robots {
                let made = keys::create_robot_keys(dir, r).map_err(|e| coded(exit::ERROR, e.to_string()))?;
                for p in made {
                    out(&format!("created {}", p.display()))?;
                }
                out(&format!(
                    "robot {r}: obsw --robot {r} --keys {d} (TC frames on 127.0.0.1:{fp}, TM frames to 127.0.0.1:{tp}); ground … --keys {d} --robot {r}",
                    d = dir.display(),
                    fp = mib::host_config::frame_port(r),
                    tp = mib::host_config::tm_frame_port(r),
                ))?;
            }
            if *team {
                let p = keys::create_team_key(dir).map_err(|e| coded(exit::ERROR, e.to_string()))?;
                out(&format!("created {}", p.display()))?;
                out(&format!(
                    "team: obsw --team-udp ADDR --peer N=ADDR ... --team-state FILE --team-key {} (the same file on every robot of the team)",
                    p.display()
                ))?;
            }
            Ok(exit::OK)
        }
        KeysCmd::Show { dir } => {
            let list = keys::describe(dir).map_err(|e| coded(exit::ERROR, e.to_string()))?;
            if list.is_empty() {
                return Err(coded(
                    exit::INVALID,
                    format!("no key files (*.key) in {}", dir.display()),
                ));
            }
            for k in list {
                let dirn = match k.direction {
                    Direction::Tc => "TC (ground to robot)",
                    Direction::Tm => "TM (robot to ground)",
                    Direction::Team => "team (robot to robot)",
                };
                let fp = match &k.fingerprint {
                    Some(f) => format!("sha256 {f}"),
                    None => format!("NOT A KEY: {} bytes, 32 expected", k.len),
                };
                let mode = match k.mode {
                    Some(m) if m & 0o077 != 0 => format!("mode {m:03o} (readable by others!)"),
                    Some(m) => format!("mode {m:03o}"),
                    None => String::new(),
                };
                let spi = match k.direction {
                    Direction::Tc | Direction::Tm => format!("  SPI {}", k.spi),
                    Direction::Team => String::new(),
                };
                out(format!("{}  {dirn}{spi}  {fp}  {mode}", k.path.display()).trim_end())?;
            }
            Ok(exit::OK)
        }
    }
}
