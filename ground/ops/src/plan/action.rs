//! What a step does ([`Action`]): the TC it sends and its description for people.

use mib::robot;
use mib::tc::{function, TcDef};
use serde::Serialize;

use crate::pus;

/// What a step does.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(tag = "action", rename_all = "kebab-case")]
pub enum Action {
    /// TC[200,1] on the robot node.
    Mode {
        mode: u32,
    },
    Reconfigure {
        from: u8,
        to: u8,
    },
    Bolt {
        side: u8,
        pairs: u8,
    },
    Unbolt {
        side: u8,
        pairs: u8,
    },
    Home,
    /// A ground-side pause; no TC.
    Wait {
        seconds: f64,
    },
    MoveArm {
        side: u8,
        pwm: u16,
    },
    MoveGripper {
        side: u8,
        pwm: u16,
    },
    RotateHip {
        angle_cdeg: i16,
    },
    BoltPair {
        side: u8,
        pair: u8,
    },
    UnboltPair {
        side: u8,
        pair: u8,
    },
    /// Any TC of the MIB by name, with named arguments.
    Command {
        tc: String,
        args: Vec<i64>,
    },
}

impl Action {
    /// The TC this action sends (`None` for a wait).
    pub fn tc(&self) -> Option<(&'static TcDef, Vec<i64>)> {
        let f = |id| mib::tc::lookup(8, 1, Some(id));
        let r = match self {
            Action::Mode { mode } => (
                mib::tc::by_name("MODE_SET")?,
                vec![mib::modes::node::ROBOT as i64, *mode as i64, 0],
            ),
            Action::Reconfigure { from, to } => (f(function::RECONFIGURE)?, vec![*from as i64, *to as i64]),
            Action::Bolt { side, pairs } => (f(function::BOLT_FACE)?, vec![*side as i64, *pairs as i64]),
            Action::Unbolt { side, pairs } => (f(function::UNBOLT_FACE)?, vec![*side as i64, *pairs as i64]),
            Action::Home => (f(function::HOME)?, vec![]),
            Action::Wait { .. } => return None,
            Action::MoveArm { side, pwm } => (f(function::MOVE_ARM)?, vec![*side as i64, *pwm as i64]),
            Action::MoveGripper { side, pwm } => (f(function::MOVE_GRIPPER)?, vec![*side as i64, *pwm as i64]),
            Action::RotateHip { angle_cdeg } => (f(function::ROTATE_HIP)?, vec![*angle_cdeg as i64]),
            Action::BoltPair { side, pair } => (f(function::BOLT_PAIR)?, vec![*side as i64, *pair as i64]),
            Action::UnboltPair { side, pair } => (f(function::UNBOLT_PAIR)?, vec![*side as i64, *pair as i64]),
            Action::Command { tc, args } => (mib::tc::by_name(tc)?, args.clone()),
        };
        Some(r)
    }

    /// Short human description.
    pub fn describe(&self) -> String {
        match self {
            Action::Mode { mode } => format!("mode {}", pus::mode_name(mib::modes::node::ROBOT, *mode)),
            Action::Reconfigure { from, to } => {
                format!("reconfigure {} -> {}", state_name(*from), state_name(*to))
            }
            Action::Bolt { side, pairs } => format!("bolt side {} pairs {}", side_name(*side), pairs_list(*pairs)),
            Action::Unbolt { side, pairs } => {
                format!("unbolt side {} pairs {}", side_name(*side), pairs_list(*pairs))
            }
            Action::Home => "home".into(),
            Action::Wait { seconds } => format!("wait {seconds} s"),
            Action::MoveArm { side, pwm } => format!("move arm {} to {pwm} us", side_name(*side)),
            Action::MoveGripper { side, pwm } => format!("move gripper {} to {pwm} us", side_name(*side)),
            Action::RotateHip { angle_cdeg } => {
                format!("rotate hip to {:.2} deg", mib::params::CAL_CDEG.eng(*angle_cdeg as i64))
            }
            Action::BoltPair { side, pair } => format!("bolt pair {pair} side {}", side_name(*side)),
            Action::UnboltPair { side, pair } => format!("unbolt pair {pair} side {}", side_name(*side)),
            Action::Command { tc, args } => match mib::tc::by_name(tc) {
                Some(def) => {
                    let a: Vec<String> = def
                        .args
                        .iter()
                        .zip(args)
                        .map(|(d, v)| format!("{}={v}", d.name))
                        .collect();
                    format!("{} {}", def.name, a.join(" "))
                }
                None => format!("{tc} {args:?}"),
            },
        }
    }
}

/// Name of a configuration state ("Xneg Xpos"), or `#n`.
pub fn state_name(id: u8) -> String {
    robot::STATES
        .get(id as usize)
        .map_or_else(|| format!("#{id}"), |s| s.name.to_string())
}

fn side_name(s: u8) -> &'static str {
    robot::Side::from_u8(s).map_or("?", |s| s.name())
}

fn pairs_list(mask: u8) -> String {
    let v: Vec<String> = (0..robot::bolter::PAIRS_PER_FACE)
        .filter(|i| mask & (1 << i) != 0)
        .map(|i| (i + 1).to_string())
        .collect();
    v.join(",")
}
