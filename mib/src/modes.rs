//! The mode tree (PUS 200): robot → side A, side B, hip → arm, gripper, bolter per side.
//!
//! The root has the paper's three operating modes (Table 7). Every other node has
//! OFF / ON / HOLD, and the root mode implies each child's mode (see [`child_mode`]).

use crate::layout::Names;

crate::named_codes! {
    /// Names of the root modes.
    ROBOT_MODE_NAMES;
    /// Root (robot) modes, paper Table 7.
    pub mod robot_mode {
        pub const STANDBY: u32 = 0;
        pub const OPERATIONAL: u32 = 1;
        pub const SAFED: u32 = 2;
    }
}

crate::named_codes! {
    /// Names of the modes of the non-root nodes.
    MODULE_MODE_NAMES;
    /// Modes of every non-root node.
    pub mod module_mode {
        /// Unpowered (servos back-drivable).
        pub const OFF: u32 = 0;
        /// Powered and commandable.
        pub const ON: u32 = 1;
        /// Powered, holding position; only position-hold commands.
        pub const HOLD: u32 = 2;
    }
}

/// Node IDs (the PUS 200 target ID, u32).
pub mod node {
    pub const ROBOT: u32 = 1;
    pub const SIDE_A: u32 = 2;
    pub const SIDE_B: u32 = 3;
    pub const HIP: u32 = 4;
    pub const ARM_A: u32 = 5;
    pub const GRIPPER_A: u32 = 6;
    pub const BOLTER_A: u32 = 7;
    pub const ARM_B: u32 = 8;
    pub const GRIPPER_B: u32 = 9;
    pub const BOLTER_B: u32 = 10;
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum NodeKind {
    /// The robot: modes STANDBY/OPERATIONAL/SAFED.
    Root,
    /// An assembly of modules (a side).
    Assembly,
    /// Arm servo (holds in safed).
    Arm,
    /// Gripper servo.
    Gripper,
    /// Bolter pair drive.
    Bolter,
    /// Hip continuous servo with encoder (holds in safed).
    Hip,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct NodeDef {
    pub id: u32,
    pub name: &'static str,
    pub parent: Option<u32>,
    pub kind: NodeKind,
}

pub const NODES: &[NodeDef] = &[
    NodeDef {
        id: node::ROBOT,
        name: "ROBOT",
        parent: None,
        kind: NodeKind::Root,
    },
    NodeDef {
        id: node::SIDE_A,
        name: "SIDE_A",
        parent: Some(node::ROBOT),
        kind: NodeKind::Assembly,
    },
    NodeDef {
        id: node::SIDE_B,
        name: "SIDE_B",
        parent: Some(node::ROBOT),
        kind: NodeKind::Assembly,
    },
    NodeDef {
        id: node::HIP,
        name: "HIP",
        parent: Some(node::ROBOT),
        kind: NodeKind::Hip,
    },
    NodeDef {
        id: node::ARM_A,
        name: "ARM_A",
        parent: Some(node::SIDE_A),
        kind: NodeKind::Arm,
    },
    NodeDef {
        id: node::GRIPPER_A,
        name: "GRIPPER_A",
        parent: Some(node::SIDE_A),
        kind: NodeKind::Gripper,
    },
    NodeDef {
        id: node::BOLTER_A,
        name: "BOLTER_A",
        parent: Some(node::SIDE_A),
        kind: NodeKind::Bolter,
    },
    NodeDef {
        id: node::ARM_B,
        name: "ARM_B",
        parent: Some(node::SIDE_B),
        kind: NodeKind::Arm,
    },
    NodeDef {
        id: node::GRIPPER_B,
        name: "GRIPPER_B",
        parent: Some(node::SIDE_B),
        kind: NodeKind::Gripper,
    },
    NodeDef {
        id: node::BOLTER_B,
        name: "BOLTER_B",
        parent: Some(node::SIDE_B),
        kind: NodeKind::Bolter,
    },
];

pub fn node_by_id(id: u32) -> Option<&'static NodeDef> {
    NODES.iter().find(|n| n.id == id)
}

/// Name of a mode of a node kind.
pub const fn mode_name(kind: NodeKind, mode: u32) -> Option<&'static str> {
    let names = match kind {
        NodeKind::Root => ROBOT_MODE_NAMES,
        _ => MODULE_MODE_NAMES,
    };
    let Names::List(list) = names else { return None };
    let mut i = 0;
    while i < list.len() {
        if list[i].0 == mode as i64 {
            return Some(list[i].1);
        }
        i += 1;
    }
    None
}

/// The mode of a node kind named `name` (case-insensitive): "operational" → 1 for the
/// robot, "hold" → 2 for a module. The one parser of mode names for every tool.
pub fn mode_by_name(kind: NodeKind, name: &str) -> Option<u32> {
    let name = name.trim();
    (0..=robot_mode::SAFED.max(module_mode::HOLD))
        .find(|m| mode_name(kind, *m).is_some_and(|n| n.eq_ignore_ascii_case(name)))
}

/// The root (robot) mode named `name` (case-insensitive: "standby", "OPERATIONAL", ...).
pub fn root_mode_by_name(name: &str) -> Option<u32> {
    mode_by_name(NodeKind::Root, name)
}

/// The mode each node is in when the root is in `root_mode` (paper Table 7):
/// standby — no module powered; operational — all powered; safed — hip and arms hold
/// position, grippers hold their grip (releasing would detach the robot), bolters off.
pub const fn child_mode(root_mode: u32, kind: NodeKind) -> u32 {
    match root_mode {
        robot_mode::OPERATIONAL => module_mode::ON,
        robot_mode::SAFED => match kind {
            NodeKind::Bolter => module_mode::OFF,
            _ => module_mode::HOLD,
        },
        _ => module_mode::OFF,
    }
}

/// Root modes that can be commanded by TC[200,1] at the robot node. Non-root nodes are
/// driven by the root; commanding them directly is refused with `INVALID_MODE`.
pub const fn is_commandable_root_mode(mode: u32) -> bool {
    matches!(mode, robot_mode::STANDBY | robot_mode::OPERATIONAL | robot_mode::SAFED)
}

/// A set of root modes: where a TC is accepted (paper Table 7), where a parameter's
/// limits apply.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ModeSet(pub u8);

impl ModeSet {
    pub const STANDBY: ModeSet = ModeSet(1 << robot_mode::STANDBY);
    pub const OPERATIONAL: ModeSet = ModeSet(1 << robot_mode::OPERATIONAL);
    pub const SAFED: ModeSet = ModeSet(1 << robot_mode::SAFED);
    pub const ALL: ModeSet = ModeSet(Self::STANDBY.0 | Self::OPERATIONAL.0 | Self::SAFED.0);
    /// The modes in which the modules are powered (the servo regulator is on).
    pub const OPER_SAFED: ModeSet = ModeSet(Self::OPERATIONAL.0 | Self::SAFED.0);
    pub const fn contains(self, root_mode: u32) -> bool {
        root_mode < 8 && self.0 & (1 << root_mode) != 0
    }
    /// The root modes of the set, in mode order.
    pub fn modes(self) -> impl Iterator<Item = u32> {
        ROOT_MODES.iter().copied().filter(move |m| self.contains(*m))
    }
    /// Names of the modes, lower case, comma separated ("operational, safed").
    pub const fn names(self) -> &'static str {
        match self.0 {
            0 => "none",
            1 => "standby",
            2 => "operational",
            3 => "standby, operational",
            4 => "safed",
            5 => "standby, safed",
            6 => "operational, safed",
            7 => "standby, operational, safed",
            _ => "invalid mode set",
        }
    }
}

/// Every root mode, in mode order.
pub const ROOT_MODES: [u32; 3] = [robot_mode::STANDBY, robot_mode::OPERATIONAL, robot_mode::SAFED];

/// Submode of the robot node: 0 = idle, 1 = executing an action.
pub mod submode {
    pub const IDLE: u16 = 0;
    pub const BUSY: u16 = 1;
}

#[cfg(test)]
mod tests {
    use super::*;
    // verifies: MMIC-MODE-04
    #[test]
    fn tree_is_rooted_and_parents_exist() {
        let roots = NODES.iter().filter(|n| n.parent.is_none()).count();
        assert_eq!(roots, 1);
        for n in NODES {
            if let Some(p) = n.parent {
                assert!(node_by_id(p).is_some());
            }
        }
    }
    // verifies: MMIC-MODE-01
    #[test]
    fn mode_names_parse_back_case_insensitively() {
        for m in ROOT_MODES {
            let n = mode_name(NodeKind::Root, m).unwrap();
            assert_eq!(root_mode_by_name(n), Some(m));
            assert_eq!(root_mode_by_name(&n.to_ascii_lowercase()), Some(m));
        }
        assert_eq!(root_mode_by_name(" Safed "), Some(robot_mode::SAFED));
        assert_eq!(root_mode_by_name("HOLD"), None);
        assert_eq!(root_mode_by_name(""), None);
        assert_eq!(mode_by_name(NodeKind::Arm, "hold"), Some(module_mode::HOLD));
        assert_eq!(
            ModeSet::OPER_SAFED.modes().collect::<Vec<_>>(),
            [robot_mode::OPERATIONAL, robot_mode::SAFED]
        );
        assert_eq!(ModeSet::OPER_SAFED.names(), "operational, safed");
    }
    // verifies: MMIC-MODE-02
    #[test]
    fn safed_keeps_hip_and_arms_powered_and_standby_powers_nothing() {
        assert_eq!(child_mode(robot_mode::SAFED, NodeKind::Hip), module_mode::HOLD);
        assert_eq!(child_mode(robot_mode::SAFED, NodeKind::Arm), module_mode::HOLD);
        assert_eq!(child_mode(robot_mode::SAFED, NodeKind::Bolter), module_mode::OFF);
        for n in NODES.iter().filter(|n| n.kind != NodeKind::Root) {
            assert_eq!(child_mode(robot_mode::STANDBY, n.kind), module_mode::OFF);
            assert_eq!(child_mode(robot_mode::OPERATIONAL, n.kind), module_mode::ON);
        }
    }
}
