//! The mode tree (PUS 200): robot → side A, side B, hip → arm, gripper, bolter.
//!
//! The robot node is commanded; every other node's commanded mode follows from it
//! (`mib::modes::child_mode`). Leaves report their actual mode back once the hardware
//! confirms it (the caller supplies that check); an assembly reaches its mode when all
//! of its children have; the robot when all of its children have. satrs's `mode_tree`
//! module needs `std`, so this bounded tree uses its `ModeAndSubmode` type with the
//! MIB's node table instead.

use mib::modes::{child_mode, module_mode, robot_mode, NodeDef, NodeKind, NODES};
use mib::params::{pid, NotSupplied, Supplied};
use satrs::mode::ModeAndSubmode;

pub const N_NODES: usize = NODES.len();

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct NodeMode {
    pub commanded: u32,
    pub actual: u32,
}

/// A mode change that one node went through (for MODE_CHANGED events).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Change {
    pub node: u32,
    pub from: u32,
    pub to: u32,
}

pub struct ModeTree {
    nodes: [NodeMode; N_NODES],
    /// Robot submode (idle / busy).
    pub submode: u16,
    /// Leaves whose module discovery found absent (bit = node index): always OFF.
    absent: u32,
}

const _: () = assert!(N_NODES <= 32, "the absent mask is a u32");

impl Default for ModeTree {
    fn default() -> Self {
        Self::new()
    }
}

impl ModeTree {
    /// Boot state: standby, every module off (paper: start-up enters standby).
    pub fn new() -> Self {
        ModeTree {
            nodes: [NodeMode {
                commanded: robot_mode::STANDBY,
                actual: robot_mode::STANDBY,
            }; N_NODES],
            submode: 0,
            absent: 0,
        }
    }

    /// Marks a leaf's module absent (module discovery): it is commanded OFF whatever the
    /// robot's mode, so it takes no part in transitions. Nodes that are not leaves are
    /// never absent.
    pub fn set_absent(&mut self, node: u32, absent: bool) {
        let Some(i) = Self::index(node) else { return };
        if matches!(NODES[i].kind, NodeKind::Root | NodeKind::Assembly) {
            return;
        }
        if absent {
            self.absent |= 1 << i;
            self.nodes[i].commanded = module_mode::OFF;
        } else {
            self.absent &= !(1 << i);
        }
    }

    pub fn index(node: u32) -> Option<usize> {
        NODES.iter().position(|n| n.id == node)
    }

    pub fn def(i: usize) -> &'static NodeDef {
        &NODES[i]
    }

    /// Actual mode of the robot node.
    pub fn root(&self) -> u32 {
        self.nodes[0].actual
    }

    /// The parameters the MIB names the mode tree the source of ([`Source::Modes`]).
    ///
    /// [`Source::Modes`]: mib::params::Source::Modes
    pub fn param(&self, id: u16) -> Supplied {
        match id {
            pid::MODE => Ok(Some(i64::from(self.root()))),
            _ => Err(NotSupplied(id)),
        }
    }

    /// Commanded mode of the robot node.
    pub fn root_target(&self) -> u32 {
        self.nodes[0].commanded
    }

    /// True while some node has not reached its commanded mode.
    pub fn in_transition(&self) -> bool {
        self.nodes.iter().any(|n| n.actual != n.commanded)
    }

    pub fn get(&self, node: u32) -> Option<NodeMode> {
        Self::index(node).map(|i| self.nodes[i])
    }

    pub fn mode_and_submode(&self, node: u32) -> Option<ModeAndSubmode> {
        let i = Self::index(node)?;
        let sub = if i == 0 { self.submode } else { 0 };
        Some(ModeAndSubmode::new(self.nodes[i].actual, sub))
    }

    /// Commands the robot node; every descendant gets the mode the root mode implies.
    pub fn command(&mut self, root_mode: u32) {
        for (i, n) in NODES.iter().enumerate() {
            self.nodes[i].commanded = if n.kind == NodeKind::Root {
                root_mode
            } else if self.absent & (1 << i) != 0 {
                module_mode::OFF
            } else {
                child_mode(root_mode, n.kind)
            };
        }
    }

    /// Commanded mode of a leaf (what the actuators must do now).
    pub fn commanded(&self, node: u32) -> u32 {
        Self::index(node).map_or(module_mode::OFF, |i| self.nodes[i].commanded)
    }

    /// Lets each leaf take its commanded mode if `confirmed(node)` says the hardware
    /// agrees; assemblies follow their children. The robot node is only advanced when
    /// `root_ready` (e.g. homing and the hip check are done). Changes go to `changes`.
    pub fn update(
        &mut self,
        mut confirmed: impl FnMut(&NodeDef, u32) -> bool,
        root_ready: bool,
        changes: &mut heapless::Vec<Change, N_NODES>,
    ) {
        // Leaves first, then assemblies, then the root: NODES is ordered root, then
        // first-level nodes, then leaves, so walk it backwards.
        for i in (0..N_NODES).rev() {
            let n = &NODES[i];
            let nm = self.nodes[i];
            if nm.actual == nm.commanded {
                continue;
            }
            let children_done = NODES
                .iter()
                .enumerate()
                .filter(|(_, c)| c.parent == Some(n.id))
                .all(|(j, _)| self.nodes[j].actual == self.nodes[j].commanded);
            let ready = match n.kind {
                NodeKind::Root => children_done && root_ready,
                NodeKind::Assembly => children_done,
                NodeKind::Arm | NodeKind::Gripper | NodeKind::Bolter | NodeKind::Hip => confirmed(n, nm.commanded),
            };
            if ready {
                self.nodes[i].actual = nm.commanded;
                let _ = changes.push(Change {
                    node: n.id,
                    from: nm.actual,
                    to: nm.commanded,
                });
            }
        }
    }

    /// Forces every node to its commanded mode at once (used when power is removed:
    /// switching off cannot fail).
    pub fn settle(&mut self, changes: &mut heapless::Vec<Change, N_NODES>) {
        self.update(|_, _| true, true, changes);
    }

    /// IDs of `node` and all its descendants, depth-first, bounded by the table size.
    pub fn subtree(node: u32) -> heapless::Vec<u32, N_NODES> {
        let mut out: heapless::Vec<u32, N_NODES> = heapless::Vec::new();
        if Self::index(node).is_none() {
            return out;
        }
        let _ = out.push(node);
        let mut k = 0;
        while k < out.len() {
            let parent = out[k];
            for c in NODES.iter().filter(|c| c.parent == Some(parent)) {
                let _ = out.push(c.id);
            }
            k += 1;
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use mib::modes::node;

    // verifies: MMIC-MODE-02
    #[test]
    fn safed_propagates_hold_to_hip_and_arms_and_root_waits_for_children() {
        let mut t = ModeTree::new();
        t.command(robot_mode::SAFED);
        assert_eq!(t.commanded(node::HIP), module_mode::HOLD);
        assert_eq!(t.commanded(node::BOLTER_A), module_mode::OFF);
        let mut ch = heapless::Vec::new();
        // Hardware confirms nothing yet: only nodes already in their mode stay.
        t.update(|n, _| n.kind == NodeKind::Bolter, true, &mut ch);
        assert_eq!(t.root(), robot_mode::STANDBY);
        assert!(t.in_transition());
        ch.clear();
        t.update(|_, _| true, true, &mut ch);
        assert_eq!(t.root(), robot_mode::SAFED);
        assert!(!t.in_transition());
        assert!(ch.iter().any(|c| c.node == node::ROBOT && c.to == robot_mode::SAFED));
        assert!(ch.iter().any(|c| c.node == node::ARM_B && c.to == module_mode::HOLD));
    }

    // verifies: MMIC-MODE-04
    #[test]
    fn subtree_of_side_a_is_side_and_its_three_modules() {
        let s = ModeTree::subtree(node::SIDE_A);
        assert_eq!(&s[..], &[node::SIDE_A, node::ARM_A, node::GRIPPER_A, node::BOLTER_A]);
        assert_eq!(ModeTree::subtree(node::ROBOT).len(), N_NODES);
        assert!(ModeTree::subtree(99).is_empty());
    }
}
