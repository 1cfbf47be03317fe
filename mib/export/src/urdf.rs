//! URDF of a robot from its module set and the module database (`docs/modules.md`, "URDF").
//!
//! The kinematic tree, rooted at one side's gripper clamp frame (`G`, see
//! [`mib::modules::geometry`]):
//!
//! ```text
//! gripper_r ─┬─ gripper_r_jaw            (gripper's joint, as the database says)
//!            ├─ board_r ─┬─ imu_r        (fixed)
//!            │           └─ adc_r        (fixed)
//!            ├─ bolter_r ── bolter_r_tool (fixed; tool frame = driver bit tip)
//!            └─ arm_r_joint (prismatic +z, 0 = contracted) ── arm_r
//!                 └─ hip_joint (revolute) ── hip ─┬─ encoder (fixed)
//!                                                 └─ arm_f (fixed)
//!                     └─ arm_f_joint (prismatic −z) ── gripper_f ─ … as side r
//! ```
//!
//! `r` is the root side, `f` the other. The hip joint turns the far side by the hip
//! angle of [`mib::robot::StateDef::hip_cdeg`] (same sign for both roots: its axis is
//! −y in the joint frame for root A, +y for root B). Absent modules (bolters, sensors)
//! are left out; grippers, arms, the hip and the boards are needed for a model. Every
//! link carries the inertial of its database entry.

use mib::modules::db::{lookup, Frame, Inertial, JointKind, ModuleDef};
use mib::modules::geometry::state_pose;
use mib::modules::{slot, Board, Descriptor, ModuleSet, SLOTS};
use std::fmt::Write;

/// Why no URDF can be written for a module set.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum UrdfError {
    /// A module the kinematic chain needs is absent (slot name).
    Missing(&'static str),
    /// The module's (type, variant, revision) is not in the database.
    NotInDatabase {
        slot: &'static str,
        variant: u8,
        revision: u8,
    },
}

impl std::fmt::Display for UrdfError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            UrdfError::Missing(s) => write!(f, "module {s} is absent: no kinematic model without it"),
            UrdfError::NotInDatabase {
                slot,
                variant,
                revision,
            } => write!(
                f,
                "module {slot}: variant {variant} revision {revision} is not in the module database"
            ),
        }
    }
}

impl std::error::Error for UrdfError {}

/// Joint names of the model.
pub mod joint {
    pub const ARM_A: &str = "arm_a_joint";
    pub const ARM_B: &str = "arm_b_joint";
    pub const HIP: &str = "hip_joint";
}

/// Joint positions (name, value in rad or m) of configuration state `state`: hip, both
/// arms (the gripper jaws stay at 0 = closed). `None` beyond the 15 states.
pub fn state_joint_positions(state: u8) -> Option<[(&'static str, f64); 3]> {
    let p = state_pose(state)?;
    Some([
        (joint::HIP, p.joints.hip_rad),
        (joint::ARM_A, p.joints.arm_a_m),
        (joint::ARM_B, p.joints.arm_b_m),
    ])
}

struct Entry {
    name: &'static str,
    desc: Descriptor,
    def: &'static ModuleDef,
}

fn entry(set: &ModuleSet, s: u8) -> Result<Option<Entry>, UrdfError> {
    let sd = &SLOTS[s as usize];
    match set[s as usize] {
        None => Ok(None),
        Some(desc) => match lookup(desc.ty, desc.variant, desc.revision) {
            Some(def) => Ok(Some(Entry {
                name: sd.name,
                desc,
                def,
            })),
            None => Err(UrdfError::NotInDatabase {
                slot: sd.name,
                variant: desc.variant,
                revision: desc.revision,
            }),
        },
    }
}

fn needed(set: &ModuleSet, s: u8) -> Result<Entry, UrdfError> {
    entry(set, s)?.ok_or(UrdfError::Missing(SLOTS[s as usize].name))
}

fn v3(v: [f64; 3]) -> String {
    format!("{} {} {}", v[0], v[1], v[2])
}

fn origin(f: &Frame) -> String {
    format!("<origin xyz=\"{}\" rpy=\"{}\"/>", v3(f.xyz), v3(f.rpy))
}

fn link(out: &mut String, name: &str, i: &Inertial, comment: Option<&Entry>) {
    if let Some(e) = comment {
        let _ = writeln!(
            out,
            "  <!-- {}: {} variant {} revision {} serial {} port {} - {} -->",
            e.name,
            e.desc.ty.name(),
            e.desc.variant,
            e.desc.revision,
            e.desc.serial,
            e.desc.port,
            e.def.part_name
        );
    }
    let [ixx, iyy, izz, ixy, ixz, iyz] = i.inertia;
    let com = origin(&Frame::at(i.com[0], i.com[1], i.com[2]));
    let _ = writeln!(
        out,
        "  <link name=\"{name}\">\n    <inertial>\n      {com}\n      <mass value=\"{}\"/>\n      \
         <inertia ixx=\"{ixx}\" ixy=\"{ixy}\" ixz=\"{ixz}\" iyy=\"{iyy}\" iyz=\"{iyz}\" izz=\"{izz}\"/>\n    \
         </inertial>",
        i.mass_kg
    );
    if let Some(b) = equivalent_box(i) {
        let _ = writeln!(
            out,
            "    <visual>\n      {com}\n      <geometry><box size=\"{}\"/></geometry>\n    </visual>",
            v3(b)
        );
    }
    let _ = writeln!(out, "  </link>");
}

/// Edges of the solid box with the same mass and (diagonal) inertia: the visual of a link,
/// exact for the parts the database models as boxes. `None` when the inertia is not
/// diagonal or not a box's.
fn equivalent_box(i: &Inertial) -> Option<[f64; 3]> {
    let [ixx, iyy, izz, ixy, ixz, iyz] = i.inertia;
    if ixy != 0.0 || ixz != 0.0 || iyz != 0.0 || i.mass_kg <= 0.0 {
        return None;
    }
    let k = 6.0 / i.mass_kg;
    let sq = [k * (iyy + izz - ixx), k * (ixx + izz - iyy), k * (ixx + iyy - izz)];
    if sq.iter().any(|v| *v <= 0.0) {
        return None;
    }
    Some([sq[0].sqrt(), sq[1].sqrt(), sq[2].sqrt()])
}

fn joint_xml(out: &mut String, name: &str, kind: &JointKind, axis_sign: f64, parent: &str, child: &str, at: &Frame) {
    let (ty, axis, limit) = match *kind {
        JointKind::Fixed => ("fixed", None, None),
        JointKind::Revolute {
            axis,
            lower,
            upper,
            effort,
            velocity,
        } => ("revolute", Some(axis), Some((lower, upper, effort, velocity))),
        JointKind::Prismatic {
            axis,
            lower,
            upper,
            effort,
            velocity,
        } => ("prismatic", Some(axis), Some((lower, upper, effort, velocity))),
    };
    let _ = writeln!(out, "  <joint name=\"{name}\" type=\"{ty}\">");
    let _ = writeln!(
        out,
        "    <parent link=\"{parent}\"/>\n    <child link=\"{child}\"/>\n    {}",
        origin(at)
    );
    if let Some(a) = axis {
        let _ = writeln!(
            out,
            "    <axis xyz=\"{}\"/>",
            // `+ 0.0` turns a negated zero into 0 (no "-0" in the file).
            v3([a[0] * axis_sign + 0.0, a[1] * axis_sign + 0.0, a[2] * axis_sign + 0.0])
        );
    }
    if let Some((lower, upper, effort, velocity)) = limit {
        let _ = writeln!(
            out,
            "    <limit lower=\"{lower}\" upper=\"{upper}\" effort=\"{effort}\" velocity=\"{velocity}\"/>"
        );
    }
    let _ = writeln!(out, "  </joint>");
}

fn fixed(out: &mut String, name: &str, parent: &str, child: &str, at: &Frame) {
    joint_xml(out, name, &JointKind::Fixed, 1.0, parent, child, at);
}

struct SideSlots {
    gripper: u8,
    board: u8,
    imu: u8,
    adc: u8,
    bolter: u8,
    arm: u8,
}

const fn side_slots(side: Board) -> SideSlots {
    match side {
        Board::A => SideSlots {
            gripper: slot::GRIPPER_A,
            board: slot::BOARD_A,
            imu: slot::IMU_A,
            adc: slot::ADC_A,
            bolter: slot::BOLTER_A,
            arm: slot::ARM_A,
        },
        Board::B => SideSlots {
            gripper: slot::GRIPPER_B,
            board: slot::BOARD_B,
            imu: slot::IMU_B,
            adc: slot::ADC_B,
            bolter: slot::BOLTER_B,
            arm: slot::ARM_B,
        },
    }
}

/// The side's end body: gripper (with its jaw), board with IMU and ADC, bolter with tool.
fn end_body(out: &mut String, set: &ModuleSet, side: Board) -> Result<(), UrdfError> {
    let ss = side_slots(side);
    let g = needed(set, ss.gripper)?;
    link(out, g.name, &g.def.inertial, Some(&g));
    if let Some(p) = g.def.part {
        let child = format!("{}{}", g.name, p.suffix);
        link(out, &child, &p.inertial, None);
        joint_xml(
            out,
            &format!("{child}_joint"),
            &g.def.joint,
            1.0,
            g.name,
            &child,
            &p.frame,
        );
    }
    let b = needed(set, ss.board)?;
    link(out, b.name, &b.def.inertial, Some(&b));
    fixed(out, &format!("{}_mount", b.name), g.name, b.name, &b.def.mount);
    for s in [ss.imu, ss.adc] {
        if let Some(e) = entry(set, s)? {
            link(out, e.name, &e.def.inertial, Some(&e));
            fixed(out, &format!("{}_mount", e.name), b.name, e.name, &e.def.mount);
        }
    }
    if let Some(e) = entry(set, ss.bolter)? {
        link(out, e.name, &e.def.inertial, Some(&e));
        fixed(out, &format!("{}_mount", e.name), g.name, e.name, &e.def.mount);
        if let Some(p) = e.def.part {
            let child = format!("{}{}", e.name, p.suffix);
            link(out, &child, &p.inertial, None);
            fixed(out, &format!("{child}_mount"), e.name, &child, &p.frame);
        }
    }
    Ok(())
}

/// Why no model can be made from a module report.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ModelError {
    Report(mib::modules::report::ReportError),
    Urdf(UrdfError),
}

impl std::fmt::Display for ModelError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ModelError::Report(e) => e.fmt(f),
            ModelError::Urdf(e) => e.fmt(f),
        }
    }
}

impl std::error::Error for ModelError {}

/// The URDF of the robot a module report body describes (what `ground model` does with a
/// live or archived report): the report is checked (lengths, CRCs, slots, hash) first.
pub fn urdf_from_report(report: &[u8], root: Board, robot_name: &str) -> Result<String, ModelError> {
    let r = mib::modules::report::ModuleReport::parse(report).map_err(ModelError::Report)?;
    urdf(&r.set, root, robot_name).map_err(ModelError::Urdf)
}

/// The robot's URDF, rooted at side `root`'s gripper clamp frame.
pub fn urdf(set: &ModuleSet, root: Board, robot_name: &str) -> Result<String, UrdfError> {
    let far = root.other();
    let (rs, fs) = (side_slots(root), side_slots(far));
    let arm_r = needed(set, rs.arm)?;
    let arm_f = needed(set, fs.arm)?;
    let hip = needed(set, slot::HIP)?;
    let mut out = String::new();
    let _ = writeln!(
        out,
        "<?xml version=\"1.0\"?>\n<!-- MMIC-I model written by mib_export::urdf from the module set and the \
         module database; rooted at gripper {} (clamp frame: origin on the face mid-plane, z toward the hip, \
         y = hip axis). Configuration hash {:#010x}. -->\n<robot name=\"{robot_name}\">",
        root.name().to_ascii_lowercase(),
        mib::modules::config_hash(set)
    );
    end_body(&mut out, set, root)?;
    let g_r = SLOTS[rs.gripper as usize].name;
    link(&mut out, arm_r.name, &arm_r.def.inertial, Some(&arm_r));
    joint_xml(
        &mut out,
        &format!("{}_joint", arm_r.name),
        &arm_r.def.joint,
        1.0,
        g_r,
        arm_r.name,
        &arm_r.def.mount,
    );
    link(&mut out, hip.name, &hip.def.inertial, Some(&hip));
    // The far side's frames are the root side's turned half a turn about y (the two
    // clamp frames face each other in a stretch); the hip angle turns them further about
    // world −Z, which is −y of the root's frames (root A) or +y (root B).
    let hip_at = Frame {
        xyz: hip.def.mount.xyz,
        rpy: [0.0, std::f64::consts::PI, 0.0],
    };
    let sign = match root {
        Board::A => -1.0,
        Board::B => 1.0,
    };
    joint_xml(
        &mut out,
        joint::HIP,
        &hip.def.joint,
        sign,
        arm_r.name,
        hip.name,
        &hip_at,
    );
    if let Some(e) = entry(set, slot::ENCODER)? {
        link(&mut out, e.name, &e.def.inertial, Some(&e));
        fixed(&mut out, &format!("{}_mount", e.name), hip.name, e.name, &e.def.mount);
    }
    link(&mut out, arm_f.name, &arm_f.def.inertial, Some(&arm_f));
    fixed(
        &mut out,
        &format!("{}_mount", arm_f.name),
        hip.name,
        arm_f.name,
        &arm_f.def.mount,
    );
    let g_f = SLOTS[fs.gripper as usize].name;
    // Extending the far arm moves its gripper away from the hip: −z of its frames.
    joint_xml(
        &mut out,
        &format!("{}_joint", arm_f.name),
        &arm_f.def.joint,
        -1.0,
        arm_f.name,
        g_f,
        &Frame::IDENTITY,
    );
    end_body(&mut out, set, far)?;
    out.push_str("</robot>\n");
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use mib::modules::{default_set, NUM_SLOTS};

    fn count(s: &str, pat: &str) -> usize {
        s.matches(pat).count()
    }

    // verifies: MOD-URDF-01
    #[test]
    fn full_and_locomotion_only_models_have_the_expected_links_and_joints() {
        let full = default_set(1000);
        let x = urdf(&full, Board::A, "mmic_i").unwrap();
        let doc = roxmltree::Document::parse(&x).expect("well-formed XML");
        let links = doc.descendants().filter(|n| n.has_tag_name("link")).count();
        assert_eq!(links, 18);
        assert_eq!(count(&x, "<inertial>"), links, "every link has an inertial");
        assert_eq!(count(&x, "type=\"prismatic\""), 2);
        assert_eq!(count(&x, "type=\"revolute\""), 3, "hip and two gripper jaws");
        assert!(x.contains("<link name=\"bolter_a_tool\">"));
        assert!(!x.contains("-0 "), "no negative zeros");
        // Box-modelled parts get their own box back as visual (the board: 70 × 50 × 1.6 mm).
        let board = doc
            .descendants()
            .find(|n| n.has_tag_name("link") && n.attribute("name") == Some("board_a"))
            .unwrap();
        let size: Vec<f64> = board
            .descendants()
            .find(|n| n.has_tag_name("box"))
            .and_then(|n| n.attribute("size"))
            .unwrap()
            .split(' ')
            .map(|v| v.parse().unwrap())
            .collect();
        for (got, want) in size.iter().zip([0.070, 0.050, 0.0016]) {
            assert!((got - want).abs() < 1e-9, "{size:?}");
        }
        // The first link is the root: gripper A.
        let first = doc.descendants().find(|n| n.has_tag_name("link")).unwrap();
        assert_eq!(first.attribute("name"), Some("gripper_a"));
        let mut loco = full;
        loco[slot::BOLTER_A as usize] = None;
        loco[slot::BOLTER_B as usize] = None;
        let y = urdf(&loco, Board::B, "mmic_i").unwrap();
        assert_eq!(count(&y, "<link "), 14);
        assert!(!y.contains("bolter"));
        let first = roxmltree::Document::parse(&y)
            .unwrap()
            .descendants()
            .find(|n| n.has_tag_name("link"))
            .and_then(|n| n.attribute("name").map(str::to_string));
        assert_eq!(first.as_deref(), Some("gripper_b"));
    }

    // verifies: MOD-URDF-01
    #[test]
    fn missing_chain_module_or_unknown_revision_is_an_error() {
        let mut set = default_set(1);
        set[slot::ARM_B as usize] = None;
        assert_eq!(urdf(&set, Board::A, "x"), Err(UrdfError::Missing("arm_b")));
        let mut set = default_set(1);
        if let Some(d) = set[slot::GRIPPER_A as usize].as_mut() {
            d.revision = 9;
        }
        assert_eq!(
            urdf(&set, Board::A, "x"),
            Err(UrdfError::NotInDatabase {
                slot: "gripper_a",
                variant: 0,
                revision: 9
            })
        );
        assert_eq!(set.len(), NUM_SLOTS);
        assert!(state_joint_positions(15).is_none());
        let j = state_joint_positions(7).unwrap();
        assert_eq!(j[0].0, joint::HIP);
        assert!((j[0].1 - std::f64::consts::FRAC_PI_2).abs() < 1e-12);
    }
}
