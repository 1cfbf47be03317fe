//! Fault injection (paper Table 8) and the text control protocol of the simulator.
//!
//! The ground reaches the simulator over a control channel separate from the flight TC
//! path (the host binary wires a UDP socket to [`SimCommand`]). One command per line:
//!
//! | line | effect |
//! |---|---|
//! | `stuck-arm a` / `stuck-arm b` | the arm does not move (stall current) |
//! | `obstacle a` / `obstacle b` | the arm is blocked by an obstacle (overcurrent) |
//! | `battery-sag 9.5` | the battery reads the given voltage (volts, 0..20) |
//! | `dead-hip-encoder` | the hip encoder reads a stuck garbage angle |
//! | `cut-cable` | the A–B serial cable is cut (no bytes either way) |
//! | `misplaced-voxel` | board B's IMU sees another face than the one gripped |
//! | `fastener-jam` | every bolting/unbolting attempt fails |
//! | `link-loss 0.1` / `link-corrupt 0.01` | per-byte loss / corruption probability |
//! | `clear` | clear every fault |
//! | `clear stuck-arm` (any fault name) | clear every fault of that kind |
//!
//! Blank lines and lines starting with `#` are ignored by [`parse_script`].

use mib::robot::Side;
use std::fmt;
use std::str::FromStr;

/// An injected fault.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Fault {
    StuckArm(Side),
    /// Obstacle in the arm's way: blocked with overcurrent while commanded to move.
    Obstacle(Side),
    BatterySag {
        volts: f32,
    },
    /// Encoder reads garbage, stuck far from the truth.
    DeadHipEncoder,
    CutCable,
    /// The IMU of side B sees another face than the gripped one: state mismatch.
    MisplacedVoxel,
    /// Bolting and unbolting fail at every attempt.
    FastenerJam,
}

/// Kind of a fault (without arguments), for clearing.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum FaultKind {
    StuckArm,
    Obstacle,
    BatterySag,
    DeadHipEncoder,
    CutCable,
    MisplacedVoxel,
    FastenerJam,
}

impl FaultKind {
    pub const ALL: [FaultKind; 7] = [
        FaultKind::StuckArm,
        FaultKind::Obstacle,
        FaultKind::BatterySag,
        FaultKind::DeadHipEncoder,
        FaultKind::CutCable,
        FaultKind::MisplacedVoxel,
        FaultKind::FastenerJam,
    ];
    pub const fn name(self) -> &'static str {
        match self {
            FaultKind::StuckArm => "stuck-arm",
            FaultKind::Obstacle => "obstacle",
            FaultKind::BatterySag => "battery-sag",
            FaultKind::DeadHipEncoder => "dead-hip-encoder",
            FaultKind::CutCable => "cut-cable",
            FaultKind::MisplacedVoxel => "misplaced-voxel",
            FaultKind::FastenerJam => "fastener-jam",
        }
    }
    pub fn from_name(s: &str) -> Option<FaultKind> {
        FaultKind::ALL.into_iter().find(|k| k.name().eq_ignore_ascii_case(s))
    }
}

impl Fault {
    pub const fn kind(&self) -> FaultKind {
        match self {
            Fault::StuckArm(_) => FaultKind::StuckArm,
            Fault::Obstacle(_) => FaultKind::Obstacle,
            Fault::BatterySag { .. } => FaultKind::BatterySag,
            Fault::DeadHipEncoder => FaultKind::DeadHipEncoder,
            Fault::CutCable => FaultKind::CutCable,
            Fault::MisplacedVoxel => FaultKind::MisplacedVoxel,
            Fault::FastenerJam => FaultKind::FastenerJam,
        }
    }
}

impl fmt::Display for Fault {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let side = |s: &Side| if *s == Side::A { "a" } else { "b" };
        match self {
            Fault::StuckArm(s) => write!(f, "stuck-arm {}", side(s)),
            Fault::Obstacle(s) => write!(f, "obstacle {}", side(s)),
            Fault::BatterySag { volts } => write!(f, "battery-sag {volts}"),
            other => f.write_str(other.kind().name()),
        }
    }
}

/// A line of the control protocol.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SimCommand {
    Inject(Fault),
    Clear(FaultKind),
    ClearAll,
    SetLinkLoss(f64),
    SetLinkCorrupt(f64),
}

/// Why a control line was refused.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum ParseError {
    Empty,
    UnknownCommand(String),
    MissingArgument {
        command: &'static str,
        expected: &'static str,
    },
    BadSide(String),
    BadNumber {
        command: &'static str,
        value: String,
        expected: &'static str,
    },
    UnexpectedArgument {
        command: String,
        arg: String,
    },
    /// `clear` parsed as a fault.
    NotAFault(String),
}

impl fmt::Display for ParseError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ParseError::Empty => write!(f, "empty command"),
            ParseError::UnknownCommand(c) => write!(
                f,
                "unknown command '{c}' (expected stuck-arm, obstacle, battery-sag, dead-hip-encoder, cut-cable, misplaced-voxel, fastener-jam, link-loss, link-corrupt or clear)"
            ),
            ParseError::MissingArgument { command, expected } => {
                write!(f, "'{command}' needs an argument: {expected}")
            }
            ParseError::BadSide(s) => write!(f, "bad side '{s}': expected 'a' or 'b'"),
            ParseError::BadNumber {
                command,
                value,
                expected,
            } => write!(f, "'{command}': bad value '{value}', expected {expected}"),
            ParseError::UnexpectedArgument { command, arg } => {
                write!(f, "'{command}' takes no argument '{arg}'")
            }
            ParseError::NotAFault(c) => write!(f, "'{c}' is a command, not a fault"),
        }
    }
}

impl std::error::Error for ParseError {}

fn side(cmd: &'static str, arg: Option<&str>) -> Result<Side, ParseError> {
    match arg {
        None => Err(ParseError::MissingArgument {
            command: cmd,
            expected: "side 'a' or 'b'",
        }),
        Some(s) if s.eq_ignore_ascii_case("a") => Ok(Side::A),
        Some(s) if s.eq_ignore_ascii_case("b") => Ok(Side::B),
        Some(s) => Err(ParseError::BadSide(s.to_string())),
    }
}

fn number(cmd: &'static str, arg: Option<&str>, lo: f64, hi: f64, expected: &'static str) -> Result<f64, ParseError> {
    let a = arg.ok_or(ParseError::MissingArgument { command: cmd, expected })?;
    match a.parse::<f64>() {
        Ok(v) if v.is_finite() && v >= lo && v <= hi => Ok(v),
        _ => Err(ParseError::BadNumber {
            command: cmd,
            value: a.to_string(),
            expected,
        }),
    }
}

impl FromStr for SimCommand {
    type Err = ParseError;
    fn from_str(line: &str) -> Result<Self, ParseError> {
        let mut it = line.split_whitespace();
        let cmd = it.next().ok_or(ParseError::Empty)?.to_ascii_lowercase();
        let arg = it.next();
        let parsed = match cmd.as_str() {
            "stuck-arm" => SimCommand::Inject(Fault::StuckArm(side("stuck-arm", arg)?)),
            "obstacle" => SimCommand::Inject(Fault::Obstacle(side("obstacle", arg)?)),
            "battery-sag" => SimCommand::Inject(Fault::BatterySag {
                volts: number("battery-sag", arg, 0.0, 20.0, "volts between 0 and 20")? as f32,
            }),
            "link-loss" => {
                SimCommand::SetLinkLoss(number("link-loss", arg, 0.0, 1.0, "a probability between 0 and 1")?)
            }
            "link-corrupt" => {
                SimCommand::SetLinkCorrupt(number("link-corrupt", arg, 0.0, 1.0, "a probability between 0 and 1")?)
            }
            "clear" => match arg {
                None => SimCommand::ClearAll,
                Some(k) => {
                    SimCommand::Clear(FaultKind::from_name(k).ok_or_else(|| ParseError::UnknownCommand(k.to_string()))?)
                }
            },
            other => {
                let kind = FaultKind::from_name(other).ok_or_else(|| ParseError::UnknownCommand(other.to_string()))?;
                if let Some(a) = arg {
                    return Err(ParseError::UnexpectedArgument {
                        command: other.to_string(),
                        arg: a.to_string(),
                    });
                }
                SimCommand::Inject(match kind {
                    FaultKind::DeadHipEncoder => Fault::DeadHipEncoder,
                    FaultKind::CutCable => Fault::CutCable,
                    FaultKind::MisplacedVoxel => Fault::MisplacedVoxel,
                    FaultKind::FastenerJam => Fault::FastenerJam,
                    // faults with arguments are matched above
                    k => {
                        return Err(ParseError::MissingArgument {
                            command: k.name(),
                            expected: "an argument",
                        })
                    }
                })
            }
        };
        let extra = match parsed {
            SimCommand::Inject(Fault::StuckArm(_) | Fault::Obstacle(_) | Fault::BatterySag { .. })
            | SimCommand::SetLinkLoss(_)
            | SimCommand::SetLinkCorrupt(_)
            | SimCommand::Clear(_) => it.next(),
            _ => arg,
        };
        if let Some(e) = extra {
            return Err(ParseError::UnexpectedArgument {
                command: cmd,
                arg: e.to_string(),
            });
        }
        Ok(parsed)
    }
}

impl FromStr for Fault {
    type Err = ParseError;
    fn from_str(line: &str) -> Result<Self, ParseError> {
        match line.parse::<SimCommand>()? {
            SimCommand::Inject(f) => Ok(f),
            _ => Err(ParseError::NotAFault(line.trim().to_string())),
        }
    }
}

/// Parses a script of control lines (blank lines and `#` comments skipped); the error
/// names the 1-based line.
pub fn parse_script(text: &str) -> Result<Vec<SimCommand>, (usize, ParseError)> {
    text.lines()
        .enumerate()
        .map(|(i, l)| (i + 1, l.trim()))
        .filter(|(_, l)| !l.is_empty() && !l.starts_with('#'))
        .map(|(n, l)| l.parse().map_err(|e| (n, e)))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    // verifies: MMIC-SIM-01
    #[test]
    fn control_protocol_parses_every_table8_fault() {
        let cases = [
            ("stuck-arm a", Fault::StuckArm(Side::A)),
            ("STUCK-ARM B", Fault::StuckArm(Side::B)),
            ("obstacle b", Fault::Obstacle(Side::B)),
            ("battery-sag 9.5", Fault::BatterySag { volts: 9.5 }),
            ("dead-hip-encoder", Fault::DeadHipEncoder),
            ("cut-cable", Fault::CutCable),
            ("  misplaced-voxel  ", Fault::MisplacedVoxel),
            ("fastener-jam", Fault::FastenerJam),
        ];
        for (line, f) in cases {
            assert_eq!(line.parse::<Fault>(), Ok(f), "{line}");
            // Display round-trips
            assert_eq!(f.to_string().parse::<Fault>(), Ok(f));
        }
        assert_eq!("clear".parse::<SimCommand>(), Ok(SimCommand::ClearAll));
        assert_eq!(
            "clear obstacle".parse::<SimCommand>(),
            Ok(SimCommand::Clear(FaultKind::Obstacle))
        );
        assert_eq!(
            "link-loss 0.25".parse::<SimCommand>(),
            Ok(SimCommand::SetLinkLoss(0.25))
        );
    }

    // verifies: MMIC-SIM-01
    #[test]
    fn control_protocol_errors_name_what_is_wrong() {
        let e = |l: &str| l.parse::<SimCommand>().unwrap_err().to_string();
        assert!(e("stuck-arm").contains("side 'a' or 'b'"));
        assert!(e("stuck-arm c").contains("bad side 'c'"));
        assert!(e("battery-sag lots").contains("bad value 'lots'"));
        assert!(e("battery-sag 99").contains("between 0 and 20"));
        assert!(e("explode").contains("unknown command 'explode'"));
        assert!(e("cut-cable now").contains("takes no argument 'now'"));
        assert!(e("obstacle a b").contains("takes no argument 'b'"));
        assert!(e("").contains("empty"));
        assert!(e("link-loss 2").contains("probability"));
        assert!("clear"
            .parse::<Fault>()
            .unwrap_err()
            .to_string()
            .contains("not a fault"));
        let err = parse_script("# test\ncut-cable\n\nbogus\n").unwrap_err();
        assert_eq!(err.0, 4);
    }
}

#[cfg(test)]
mod fuzz {
    use super::*;
    use proptest::prelude::*;
    proptest! {
        // verifies: MMIC-SIM-01
        #[test]
        fn control_lines_never_panic(line in ".{0,60}") {
            let _ = line.parse::<SimCommand>();
            let _ = line.parse::<Fault>();
        }
        // verifies: MMIC-SIM-01
        #[test]
        fn control_words_never_panic(words in proptest::collection::vec(
            prop_oneof![Just("stuck-arm"), Just("obstacle"), Just("battery-sag"), Just("clear"),
                Just("a"), Just("b"), Just("9.5"), Just("-1"), Just("NaN"), Just("inf"), Just("cut-cable")], 0..4)) {
            let line = words.join(" ");
            if let Ok(SimCommand::Inject(f)) = line.parse::<SimCommand>() {
                prop_assert_eq!(f.to_string().parse::<Fault>(), Ok(f));
            }
        }
    }
}
