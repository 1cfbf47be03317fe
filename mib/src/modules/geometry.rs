//! Metric geometry of the voxel lattice and of the robot in the 15 configuration states.
//!
//! **Voxel frame**: origin at the centre of the reference voxel, X and Y in the working
//! plane (as in [`crate::robot`]), Z out of the plane, gravity −Y. The voxel is a cube of
//! pitch [`PITCH_M`]; a face's mid-plane lies at ±pitch/2 along its axis.
//!
//! **Robot** (rigid chain gripper A – arm A – hip – arm B – gripper B): the clamp frame
//! `G` of a gripper has its origin at the clamp centre on the face's mid-plane, `z` along
//! the arm toward the hip, `y` along the hip axis (world +Z), `x = y × z`. An arm
//! extension `q` places the hip `q` along `z` of the side's `G`; the hip turns side B
//! about world −Z by the hip angle (robot.rs: +90° when B's face is A's face turned
//! counter-clockwise). Derived figures, one per state kind:
//!
//! - *stretch*: the grippers at the centres of opposite faces, both arms at
//!   [`ARM_REACH_M`] = pitch/2, the hip at the voxel centre;
//! - *turn*: the grippers at the centres of the two faces, both arms at pitch/2, hip
//!   ±90°, the hip at the voxel centre;
//! - *matched*: both arms contracted (0), hip 0, the hip at the face centre and both
//!   clamp centres there; with a rigid chain the two grippers' `z` axes are opposite
//!   at hip 0 (they face each other in a stretch), so gripper A clamps the face from
//!   inside the reference voxel and gripper B from the neighbouring voxel: the robot
//!   straddles the face through its opening.

use crate::robot::{Face, StateKind, NUM_STATES, STATES};

/// Voxel pitch (edge of the cubic unit cell), m. Our choice: the paper gives none; a
/// 12-inch cell, the size commonly quoted for ARMADAS-type lattices, leaves room for
/// the contracted robot (≈ 0.17 m long with its end bodies) to turn inside one voxel.
pub const PITCH_M: f64 = 0.3048;
/// Thickness of a face plate; its mid-plane is the face plane of the checks.
pub const FACE_PLATE_M: f64 = 0.004;
/// Side of the square opening in each face through which the robot passes.
pub const FACE_OPENING_M: f64 = 0.200;
/// Arm extension of a stretch or turn state (both arms): half a pitch.
pub const ARM_REACH_M: f64 = PITCH_M / 2.0;

/// How a gripper holds its face.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Approach {
    /// From inside the reference voxel (`z` of `G` = the face's inward normal).
    Inward,
    /// From the neighbouring voxel through the face (`z` of `G` = outward normal).
    Outward,
}

impl Approach {
    pub const fn name(self) -> &'static str {
        match self {
            Approach::Inward => "inward",
            Approach::Outward => "outward",
        }
    }
}

/// Expected pose of a gripper's clamp frame in the voxel frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GripperPose {
    pub face: Face,
    pub approach: Approach,
    pub position: [f64; 3],
    pub z_axis: [f64; 3],
    pub y_axis: [f64; 3],
}

/// Joint positions of a state: hip angle (rad, robot.rs sign), arm extensions (m).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StateJoints {
    pub hip_rad: f64,
    pub arm_a_m: f64,
    pub arm_b_m: f64,
}

/// Joint positions and expected gripper poses of one configuration state.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StatePose {
    pub state: u8,
    pub joints: StateJoints,
    pub a: GripperPose,
    pub b: GripperPose,
    /// Where the hip axis crosses the working plane.
    pub hip_point: [f64; 3],
}

/// Inward unit normal of a face as a 3-vector.
pub const fn inward(face: Face) -> [f64; 3] {
    let (x, y) = face.inward_normal();
    [x as f64, y as f64, 0.0]
}

/// Centre of a face's mid-plane in the voxel frame.
pub const fn face_centre(face: Face) -> [f64; 3] {
    let n = inward(face);
    [-n[0] * PITCH_M / 2.0, -n[1] * PITCH_M / 2.0, 0.0]
}

const fn neg(v: [f64; 3]) -> [f64; 3] {
    [-v[0], -v[1], -v[2]]
}

const Y_AXIS: [f64; 3] = [0.0, 0.0, 1.0];

/// Joint positions and expected gripper poses of state `id` (`None` beyond the 15).
pub const fn state_pose(id: u8) -> Option<StatePose> {
    if id as usize >= NUM_STATES {
        return None;
    }
    let s = &STATES[id as usize];
    let hip_rad = s.hip_cdeg() as f64 / 100.0 * core::f64::consts::PI / 180.0;
    let a = GripperPose {
        face: s.a,
        approach: Approach::Inward,
        position: face_centre(s.a),
        z_axis: inward(s.a),
        y_axis: Y_AXIS,
    };
    let (arm, b, hip_point) = match s.kind() {
        StateKind::Matched => (
            0.0,
            GripperPose {
                face: s.a,
                approach: Approach::Outward,
                position: face_centre(s.a),
                z_axis: neg(inward(s.a)),
                y_axis: Y_AXIS,
            },
            face_centre(s.a),
        ),
        StateKind::Stretch | StateKind::Turn => (
            ARM_REACH_M,
            GripperPose {
                face: s.b,
                approach: Approach::Inward,
                position: face_centre(s.b),
                z_axis: inward(s.b),
                y_axis: Y_AXIS,
            },
            [0.0, 0.0, 0.0],
        ),
    };
    Some(StatePose {
        state: id,
        joints: StateJoints {
            hip_rad,
            arm_a_m: arm,
            arm_b_m: arm,
        },
        a,
        b,
        hip_point,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dist(p: [f64; 3], q: [f64; 3]) -> f64 {
        ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2)).sqrt()
    }

    /// The planar chain evaluated by hand: hip = G_A + q_a z_A; z_B = rotation of −z_A
    /// about world −Z by the hip angle; G_B = hip − q_b z_B.
    fn chain(p: &StatePose) -> ([f64; 3], [f64; 3]) {
        let za = p.a.z_axis;
        let hip = [
            p.a.position[0] + p.joints.arm_a_m * za[0],
            p.a.position[1] + p.joints.arm_a_m * za[1],
            0.0,
        ];
        let (c, s) = (p.joints.hip_rad.cos(), -p.joints.hip_rad.sin());
        let v = [-za[0], -za[1]];
        let zb = [c * v[0] - s * v[1], s * v[0] + c * v[1], 0.0];
        let gb = [
            hip[0] - p.joints.arm_b_m * zb[0],
            hip[1] - p.joints.arm_b_m * zb[1],
            0.0,
        ];
        (gb, zb)
    }

    // verifies: MOD-GEO-01
    #[test]
    fn every_state_pose_is_reached_by_the_rigid_chain() {
        for id in 0..NUM_STATES as u8 {
            let p = state_pose(id).unwrap();
            let s = &STATES[id as usize];
            assert_eq!((p.a.face, p.b.face), (s.a, s.b));
            let (gb, zb) = chain(&p);
            assert!(dist(gb, p.b.position) < 1e-9, "state {}: B at {gb:?}", s.name);
            assert!(dist(zb, p.b.z_axis) < 1e-9, "state {}: z_B {zb:?}", s.name);
            // Positions lie on the face planes, inside the faces.
            for g in [p.a, p.b] {
                let n = inward(g.face);
                let along = g.position[0] * n[0] + g.position[1] * n[1];
                assert!((along + PITCH_M / 2.0).abs() < 1e-12);
            }
            match s.kind() {
                StateKind::Matched => assert_eq!(p.joints.arm_a_m, 0.0),
                StateKind::Stretch | StateKind::Turn => {
                    assert!(dist(p.hip_point, [0.0; 3]) < 1e-12);
                    assert_eq!(p.joints.arm_b_m, ARM_REACH_M);
                }
            }
        }
        assert!(state_pose(NUM_STATES as u8).is_none());
        // A wrong joint value leaves the face: the hand chain can tell.
        let mut p = state_pose(3).unwrap();
        p.joints.arm_b_m += 0.001;
        assert!(dist(chain(&p).0, p.b.position) > 0.0009);
    }
}
