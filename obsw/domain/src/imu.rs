//! The IMU model shared by the simulator and the estimator.
//!
//! Board frame of a side gripped to a face: `z` = inward normal of the face, `y` =
//! world Z (out of the working plane), `x = y × z` (along the face, in the plane).
//! Gravity is world −Y, 1 g = 1000 milli-g. With the inward normal `n = (nx, ny)`,
//! `x = (−ny, nx)`, so gravity reads `[−nx, 0, −ny]` g:
//!
//! | face | gravity (mg) |
//! |---|---|
//! | Xpos | [1000, 0, 0] |
//! | Ypos | [0, 0, 1000] |
//! | Xneg | [−1000, 0, 0] |
//! | Yneg | [0, 0, −1000] |

use crate::consts::{EST_FACE_MIN_DOT_MG, EST_G_MAX_MG, EST_G_MIN_MG};
use mib::robot::Face;

/// 1 g in milli-g.
pub const ONE_G_MG: i16 = 1000;

/// Gravity in the frame of a board gripped to `face` (milli-g).
pub const fn gravity_in_board_frame(face: Face) -> [i16; 3] {
    let (nx, ny) = face.inward_normal();
    [-(nx as i16) * ONE_G_MG, 0, -(ny as i16) * ONE_G_MG]
}

/// The face whose gravity vector matches a measured one, if exactly one is close
/// enough (dot product ≥ `EST_FACE_MIN_DOT_MG`) and the magnitude is plausible.
pub fn face_from_gravity(g: [i16; 3]) -> Option<Face> {
    let (x, y, z) = (g[0] as i32, g[1] as i32, g[2] as i32);
    let mag2 = x * x + y * y + z * z;
    if !(EST_G_MIN_MG * EST_G_MIN_MG..=EST_G_MAX_MG * EST_G_MAX_MG).contains(&mag2) {
        return None;
    }
    let mut best: Option<Face> = None;
    for f in Face::ALL {
        let e = gravity_in_board_frame(f);
        let dot = (x * e[0] as i32 + y * e[1] as i32 + z * e[2] as i32) / ONE_G_MG as i32;
        if dot >= EST_FACE_MIN_DOT_MG {
            // Two faces can never both exceed cos(37°) with orthogonal/opposite axes.
            best = Some(f);
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;
    // verifies: MMIC-AV-04
    #[test]
    fn imu_model_gives_four_distinct_unit_vectors_recognised_back() {
        for f in Face::ALL {
            let g = gravity_in_board_frame(f);
            assert_eq!(face_from_gravity(g), Some(f));
            for o in Face::ALL.iter().filter(|&&o| o != f) {
                assert_ne!(gravity_in_board_frame(*o), g);
            }
        }
        assert_eq!(gravity_in_board_frame(Face::Xpos), [1000, 0, 0]);
        assert_eq!(gravity_in_board_frame(Face::Yneg), [0, 0, -1000]);
    }
    // verifies: MMIC-AV-04
    #[test]
    fn imu_rejects_free_fall_tilt_and_overrange() {
        assert_eq!(face_from_gravity([0, 0, 0]), None);
        assert_eq!(face_from_gravity([707, 0, 707]), None); // 45° between two faces
        assert_eq!(face_from_gravity([2000, 0, 0]), None);
        assert_eq!(face_from_gravity([950, 40, -60]), Some(Face::Xpos));
    }
}
