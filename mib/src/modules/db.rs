//! The module database: one entry per (type, variant, revision) with its frames,
//! joint, inertial, calibration defaults and compatibility.
//!
//! ## Frames (metres, radians; see `docs/modules.md` and [`super::geometry`])
//! Every entry's `mount` places the module's frame in its parent's frame:
//!
//! | type | parent | frame |
//! |---|---|---|
//! | gripper | — (it is the side's end body) | clamp frame `G`: origin at the clamp centre on the face's mid-plane, `z` from the face toward the hip, `y` = hip axis (world +Z), `x = y × z` |
//! | board, bolter | gripper `G` | board / bolter body |
//! | imu, adc | board | the chip |
//! | arm | gripper `G` | arm link frame = the hip point, axes of `G`; the prismatic joint moves it along `+z` of `G` |
//! | hip | arm of the root side | hip link frame at the hip point, axes of the far side's `G` |
//! | encoder | hip | the sensor, on the hip axis |
//!
//! The inertial of an entry is given in the module's own frame: mass (kg), centre of
//! mass, inertia about the centre of mass (kg·m², `ixx iyy izz ixy ixz iyz`).

use super::descriptor::{Calibration, CAL_DEFAULT};
use super::ModuleType;

/// A rigid placement: translation, then roll-pitch-yaw (URDF convention).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Frame {
    pub xyz: [f64; 3],
    pub rpy: [f64; 3],
}

impl Frame {
    pub const IDENTITY: Frame = Frame::at(0.0, 0.0, 0.0);
    pub const fn at(x: f64, y: f64, z: f64) -> Frame {
        Frame {
            xyz: [x, y, z],
            rpy: [0.0, 0.0, 0.0],
        }
    }
}

/// Mass properties of one rigid body.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Inertial {
    pub mass_kg: f64,
    pub com: [f64; 3],
    /// `ixx, iyy, izz, ixy, ixz, iyz` about the centre of mass, axes of the body frame.
    pub inertia: [f64; 6],
}

/// Inertia of a solid box `a × b × c` (along x, y, z) of mass `m`.
pub const fn box_inertia(m: f64, a: f64, b: f64, c: f64) -> [f64; 6] {
    [
        m * (b * b + c * c) / 12.0,
        m * (a * a + c * c) / 12.0,
        m * (a * a + b * b) / 12.0,
        0.0,
        0.0,
        0.0,
    ]
}

/// Inertia of a solid cylinder of radius `r`, length `h` along z, mass `m`.
pub const fn cylinder_z_inertia(m: f64, r: f64, h: f64) -> [f64; 6] {
    let t = m * (3.0 * r * r + h * h) / 12.0;
    [t, t, m * r * r / 2.0, 0.0, 0.0, 0.0]
}

/// The module's own joint.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum JointKind {
    Fixed,
    /// Rotation about `axis` (unit, in the joint frame), limits in rad, effort N·m,
    /// velocity rad/s.
    Revolute {
        axis: [f64; 3],
        lower: f64,
        upper: f64,
        effort: f64,
        velocity: f64,
    },
    /// Translation along `axis`, limits in m, effort N, velocity m/s.
    Prismatic {
        axis: [f64; 3],
        lower: f64,
        upper: f64,
        effort: f64,
        velocity: f64,
    },
}

/// A second body of a module: the gripper's jaw (moved by the module's joint) or the
/// bolter's driver bit (fixed; its frame is the bolter tool frame).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Part {
    /// Appended to the module's link name (`gripper_a` + `_jaw`).
    pub suffix: &'static str,
    /// Placement in the module's frame.
    pub frame: Frame,
    pub inertial: Inertial,
}

/// What a module needs from the board it is wired to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Compat {
    /// Board revisions (inclusive range) the module works with.
    pub board_rev_min: u8,
    pub board_rev_max: u8,
    /// Oldest board firmware (`major << 8 | minor`) that drives it.
    pub fw_min: u16,
}

/// One database entry.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ModuleDef {
    pub ty: ModuleType,
    pub variant: u8,
    pub revision: u8,
    pub part_name: &'static str,
    /// Placement of the module's frame in its parent's (table in the module doc).
    pub mount: Frame,
    /// The module's joint: arm (prismatic, the arm link moves along `+z` of `G`), hip
    /// (revolute, sign per model root, see the URDF exporter), gripper (its jaw).
    pub joint: JointKind,
    pub inertial: Inertial,
    pub part: Option<Part>,
    pub cal_default: Calibration,
    /// Accepted range (inclusive) of each calibration word; `(0, 0)` for unused words.
    /// A descriptor word outside its range makes the module set invalid
    /// ([`resolve_calibration`]).
    pub cal_range: CalRange,
    pub compat: Compat,
}

/// Inclusive `(min, max)` of each of the eight calibration words.
pub type CalRange = [(i16, i16); 8];

const UNUSED: (i16, i16) = (0, 0);
/// Hip: home within ±5° (the states assume the hip at 0 when contracted), currents.
const HIP_CAL_RANGE: CalRange = [
    (-500, 500),
    (100, 1000),
    (1000, 4000),
    UNUSED,
    UNUSED,
    UNUSED,
    UNUSED,
    UNUSED,
];
/// Arm: contracted and extended pulse widths (disjoint, so contracted < extended), home
/// anywhere the servo is driven, currents.
const ARM_CAL_RANGE: CalRange = [
    (900, 1200),
    (1800, 2100),
    (900, 2100),
    (100, 1000),
    (1000, 4000),
    UNUSED,
    UNUSED,
    UNUSED,
];
/// Gripper rev 1: closed, open, home (µs), currents (mA).
const GRIPPER1_CAL_RANGE: CalRange = [
    (1000, 1300),
    (1700, 2100),
    (900, 2100),
    (100, 1000),
    (500, 2500),
    UNUSED,
    UNUSED,
    UNUSED,
];
/// Gripper rev 2: its narrower PWM range (end stops at 1120 and 1880 µs).
const GRIPPER2_CAL_RANGE: CalRange = [
    (1120, 1300),
    (1700, 1880),
    (1120, 1880),
    (100, 1000),
    (500, 2500),
    UNUSED,
    UNUSED,
    UNUSED,
];
/// Bolter: push and lock thresholds within the PUS 20 tunables' ranges
/// (`BOLT_PUSH_THRESHOLD_MA` 200..2400, `BOLT_LOCK_THRESHOLD_MA` 400..2450), currents.
const BOLTER_CAL_RANGE: CalRange = [
    (200, 2400),
    (400, 2450),
    (100, 1000),
    (1000, 4000),
    UNUSED,
    UNUSED,
    UNUSED,
    UNUSED,
];
const IMU_CAL_RANGE: CalRange = [
    (-200, 200),
    (-200, 200),
    (-200, 200),
    UNUSED,
    UNUSED,
    UNUSED,
    UNUSED,
    UNUSED,
];
const ADC_CAL_RANGE: CalRange = [(-5000, 5000), (-50, 50), UNUSED, UNUSED, UNUSED, UNUSED, UNUSED, UNUSED];
/// Encoder: zero 0..4095 counts (12 bits), direction −1 or +1 (0 is refused).
const ENCODER_CAL_RANGE: CalRange = [(0, 4095), (-1, 1), UNUSED, UNUSED, UNUSED, UNUSED, UNUSED, UNUSED];
/// Board: firmware version 1.0 .. 127.255.
const BOARD_CAL_RANGE: CalRange = [(0x0100, 0x7FFF), UNUSED, UNUSED, UNUSED, UNUSED, UNUSED, UNUSED, UNUSED];

/// A calibration word outside its database range.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CalError {
    /// Word index (0..8, [`ModuleType::cal_names`]).
    pub word: u8,
    pub value: i16,
    pub min: i16,
    pub max: i16,
}

impl core::fmt::Display for CalError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(
            f,
            "calibration word {} = {} outside {}..={}",
            self.word, self.value, self.min, self.max
        )
    }
}

impl core::error::Error for CalError {}

/// The calibration a module runs with: each word of `cal` that is [`CAL_DEFAULT`] takes
/// the database default of `def`; every word must then lie in `def.cal_range` (the
/// encoder direction must also be non-zero). The first bad word is the error.
pub fn resolve_calibration(def: &ModuleInfo, cal: &Calibration) -> Result<Calibration, CalError> {
    let mut out = [0i16; 8];
    for (i, o) in out.iter_mut().enumerate() {
        let v = if cal.0[i] == CAL_DEFAULT {
            def.cal_default.0[i]
        } else {
            cal.0[i]
        };
        let (min, max) = def.cal_range[i];
        let zero_direction = def.ty == ModuleType::Encoder && i == 1 && v == 0;
        if v < min || v > max || zero_direction {
            return Err(CalError {
                word: i as u8,
                value: v,
                min,
                max,
            });
        }
        *o = v;
    }
    Ok(Calibration(out))
}

const PI: f64 = core::f64::consts::PI;
/// Arm stroke (m): at least the reach of a stretch ([`super::geometry::ARM_REACH_M`]).
pub const ARM_STROKE_M: f64 = 0.160;
const COMPAT_ANY: Compat = Compat {
    board_rev_min: 1,
    board_rev_max: 2,
    fw_min: 0x0100,
};

const fn inertial(mass_kg: f64, com: [f64; 3], inertia: [f64; 6]) -> Inertial {
    Inertial { mass_kg, com, inertia }
}

/// The module database, sorted by (type code, variant, revision).
pub const MODULE_DB: &[ModuleDef] = &[
    ModuleDef {
        ty: ModuleType::Hip,
        variant: 0,
        revision: 1,
        part_name: "hip: continuous servo with PI control, magnet for the AS5600",
        mount: Frame::IDENTITY,
        joint: JointKind::Revolute {
            axis: [0.0, 1.0, 0.0],
            lower: -120.0 * PI / 180.0,
            upper: 120.0 * PI / 180.0,
            effort: 2.0,
            velocity: 30.0 * PI / 180.0,
        },
        inertial: inertial(0.260, [0.0, 0.0, 0.0], box_inertia(0.260, 0.050, 0.060, 0.050)),
        part: None,
        cal_default: Calibration([0, 400, 3000, 0, 0, 0, 0, 0]),
        cal_range: HIP_CAL_RANGE,
        compat: COMPAT_ANY,
    },
    ModuleDef {
        ty: ModuleType::Arm,
        variant: 0,
        revision: 1,
        part_name: "telescopic extension arm, 160 mm stroke, positional servo",
        mount: Frame::IDENTITY,
        joint: JointKind::Prismatic {
            axis: [0.0, 0.0, 1.0],
            lower: 0.0,
            upper: ARM_STROKE_M,
            effort: 20.0,
            velocity: 0.08,
        },
        // The tube hangs from the hip toward its gripper (−z of the arm link frame).
        inertial: inertial(0.120, [0.0, 0.0, -0.060], cylinder_z_inertia(0.120, 0.012, 0.120)),
        part: None,
        cal_default: Calibration([1000, 2000, 1000, 400, 3000, 0, 0, 0]),
        cal_range: ARM_CAL_RANGE,
        compat: COMPAT_ANY,
    },
    ModuleDef {
        ty: ModuleType::Gripper,
        variant: 0,
        revision: 1,
        part_name: "servo clamp gripper, rev 1",
        mount: Frame::IDENTITY,
        joint: JointKind::Revolute {
            axis: [0.0, 1.0, 0.0],
            lower: 0.0,
            upper: 0.52,
            effort: 1.5,
            velocity: 1.0,
        },
        inertial: inertial(0.180, [0.0, 0.0, 0.030], box_inertia(0.180, 0.060, 0.050, 0.060)),
        part: Some(Part {
            suffix: "_jaw",
            frame: Frame::at(0.0, 0.0, 0.010),
            inertial: inertial(0.020, [0.015, 0.0, 0.0], box_inertia(0.020, 0.040, 0.012, 0.010)),
        }),
        cal_default: Calibration([1100, 1900, 1100, 400, 1500, 0, 0, 0]),
        cal_range: GRIPPER1_CAL_RANGE,
        compat: COMPAT_ANY,
    },
    ModuleDef {
        ty: ModuleType::Gripper,
        variant: 0,
        revision: 2,
        part_name: "servo clamp gripper, rev 2: stiffer jaw spring, narrower PWM range",
        mount: Frame::IDENTITY,
        joint: JointKind::Revolute {
            axis: [0.0, 1.0, 0.0],
            lower: 0.0,
            upper: 0.61,
            effort: 1.8,
            velocity: 1.0,
        },
        inertial: inertial(0.195, [0.0, 0.0, 0.032], box_inertia(0.195, 0.060, 0.052, 0.064)),
        part: Some(Part {
            suffix: "_jaw",
            frame: Frame::at(0.0, 0.0, 0.010),
            inertial: inertial(0.024, [0.016, 0.0, 0.0], box_inertia(0.024, 0.042, 0.012, 0.011)),
        }),
        cal_default: Calibration([1150, 1850, 1150, 450, 1600, 0, 0, 0]),
        cal_range: GRIPPER2_CAL_RANGE,
        // The narrower PWM range and the higher holding current need firmware 1.1.
        compat: Compat {
            board_rev_min: 1,
            board_rev_max: 2,
            fw_min: 0x0101,
        },
    },
    ModuleDef {
        ty: ModuleType::Bolter,
        variant: 0,
        revision: 1,
        part_name: "bolter: 4 fastener pairs through the ADG1604 multiplexer",
        mount: Frame::at(0.065, 0.0, 0.030),
        joint: JointKind::Fixed,
        inertial: inertial(0.210, [0.0, 0.0, 0.0], box_inertia(0.210, 0.050, 0.040, 0.060)),
        // Tool frame: the driver bit's tip on the face's mid-plane, z pointing into the face.
        part: Some(Part {
            suffix: "_tool",
            frame: Frame {
                xyz: [0.0, 0.0, -0.030],
                rpy: [PI, 0.0, 0.0],
            },
            inertial: inertial(0.008, [0.0, 0.0, -0.012], cylinder_z_inertia(0.008, 0.004, 0.024)),
        }),
        cal_default: Calibration([1200, 1800, 200, 2500, 0, 0, 0, 0]),
        cal_range: BOLTER_CAL_RANGE,
        compat: COMPAT_ANY,
    },
    ModuleDef {
        ty: ModuleType::Imu,
        variant: 0,
        revision: 1,
        part_name: "MPU-6000 6-axis IMU",
        // Axes of the board = axes of G (the domain's board frame in stretch and turn).
        mount: Frame::at(0.010, 0.0, 0.002),
        joint: JointKind::Fixed,
        inertial: inertial(0.0005, [0.0, 0.0, 0.0], box_inertia(0.0005, 0.004, 0.004, 0.001)),
        part: None,
        cal_default: Calibration([0; 8]),
        cal_range: IMU_CAL_RANGE,
        compat: COMPAT_ANY,
    },
    ModuleDef {
        ty: ModuleType::Adc,
        variant: 0,
        revision: 1,
        part_name: "ADS7828 8-channel 12-bit ADC",
        mount: Frame::at(-0.015, 0.0, 0.002),
        joint: JointKind::Fixed,
        inertial: inertial(0.0005, [0.0, 0.0, 0.0], box_inertia(0.0005, 0.005, 0.006, 0.001)),
        part: None,
        cal_default: Calibration([0; 8]),
        cal_range: ADC_CAL_RANGE,
        compat: COMPAT_ANY,
    },
    ModuleDef {
        ty: ModuleType::Encoder,
        variant: 0,
        revision: 1,
        part_name: "AS5600 magnetic absolute encoder",
        mount: Frame::at(0.0, 0.032, 0.0),
        joint: JointKind::Fixed,
        inertial: inertial(0.003, [0.0, 0.0, 0.0], box_inertia(0.003, 0.015, 0.002, 0.015)),
        part: None,
        cal_default: Calibration([2048, 1, 0, 0, 0, 0, 0, 0]),
        cal_range: ENCODER_CAL_RANGE,
        compat: COMPAT_ANY,
    },
    ModuleDef {
        ty: ModuleType::BoardA,
        variant: 0,
        revision: 1,
        part_name: "controller board A (ESP32, MPU-6000, ADS7828, ground link)",
        mount: Frame::at(0.0, 0.0, 0.075),
        joint: JointKind::Fixed,
        inertial: inertial(0.045, [0.0, 0.0, 0.0], box_inertia(0.045, 0.070, 0.050, 0.0016)),
        part: None,
        cal_default: Calibration([0x0100, 0, 0, 0, 0, 0, 0, 0]),
        cal_range: BOARD_CAL_RANGE,
        compat: COMPAT_ANY,
    },
    ModuleDef {
        ty: ModuleType::BoardB,
        variant: 0,
        revision: 1,
        part_name: "controller board B (ESP32, MPU-6000, ADS7828, subordinate)",
        mount: Frame::at(0.0, 0.0, 0.075),
        joint: JointKind::Fixed,
        inertial: inertial(0.045, [0.0, 0.0, 0.0], box_inertia(0.045, 0.070, 0.050, 0.0016)),
        part: None,
        cal_default: Calibration([0x0100, 0, 0, 0, 0, 0, 0, 0]),
        cal_range: BOARD_CAL_RANGE,
        compat: COMPAT_ANY,
    },
];

/// What the robot's own software needs of a database entry: identity, calibration
/// defaults and ranges, compatibility. With feature `descriptions` (every std build) it is
/// the whole [`ModuleDef`]; without it (the firmware) the geometry, inertia and part
/// names the URDF export uses are left out, and [`MODULE_INFO`] is built from
/// [`MODULE_DB`] at compile time, so the image stores none of them (REV-ANOM-12).
#[cfg(feature = "descriptions")]
pub type ModuleInfo = ModuleDef;

/// What the robot's own software needs of a database entry (see the std form).
#[cfg(not(feature = "descriptions"))]
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ModuleInfo {
    pub ty: ModuleType,
    pub variant: u8,
    pub revision: u8,
    pub cal_default: Calibration,
    pub cal_range: CalRange,
    pub compat: Compat,
}

/// The entries [`lookup`] and [`default_def`] search.
#[cfg(feature = "descriptions")]
pub const MODULE_INFO: &[ModuleInfo] = MODULE_DB;

/// The entries [`lookup`] and [`default_def`] search: [`MODULE_DB`] without geometry.
#[cfg(not(feature = "descriptions"))]
pub const MODULE_INFO: &[ModuleInfo] = &{
    const N: usize = MODULE_DB.len();
    let mut out = [ModuleInfo {
        ty: ModuleType::Unknown(0),
        variant: 0,
        revision: 0,
        cal_default: Calibration([0; 8]),
        cal_range: [(0, 0); 8],
        compat: COMPAT_ANY,
    }; N];
    let mut i = 0;
    while i < N {
        let d = &MODULE_DB[i];
        out[i] = ModuleInfo {
            ty: d.ty,
            variant: d.variant,
            revision: d.revision,
            cal_default: d.cal_default,
            cal_range: d.cal_range,
            compat: d.compat,
        };
        i += 1;
    }
    out
};

/// The database entry of (type, variant, revision).
pub fn lookup(ty: ModuleType, variant: u8, revision: u8) -> Option<&'static ModuleInfo> {
    MODULE_INFO
        .iter()
        .find(|d| d.ty == ty && d.variant == variant && d.revision == revision)
}

/// The newest revision of variant 0 of `ty` (the default build).
pub fn default_def(ty: ModuleType) -> Option<&'static ModuleInfo> {
    MODULE_INFO
        .iter()
        .filter(|d| d.ty == ty && d.variant == 0)
        .min_by_key(|d| d.revision)
}

/// Whether `def` works on a board of revision `board_rev` running firmware `fw`.
pub const fn compatible(def: &ModuleInfo, board_rev: u8, fw: u16) -> bool {
    board_rev >= def.compat.board_rev_min && board_rev <= def.compat.board_rev_max && fw >= def.compat.fw_min
}

/// Arm extension (m) commanded by pulse width `pwm_us` under `cal` (linear between
/// contracted = 0 and extended = [`super::geometry::ARM_REACH_M`]); `None` when the
/// calibration is degenerate.
pub fn arm_extension_m(cal: &Calibration, pwm_us: u16) -> Option<f64> {
    let c = cal.0[0] as f64;
    let e = cal.0[1] as f64;
    if (e - c).abs() < 1.0 {
        return None;
    }
    Some((pwm_us as f64 - c) / (e - c) * super::geometry::ARM_REACH_M)
}

/// Real eigenvalues of a symmetric 3×3 matrix (closed form), ascending. std only: the
/// physical-validity check runs in tests and exporters, no_std builds need no trigonometry.
#[cfg(any(test, feature = "std"))]
fn sym_eigenvalues(i: &[f64; 6]) -> [f64; 3] {
    let (a, b, c, d, e, f) = (i[0], i[1], i[2], i[3], i[4], i[5]);
    // Matrix [[a, d, e], [d, b, f], [e, f, c]].
    let p1 = d * d + e * e + f * f;
    let q = (a + b + c) / 3.0;
    let p2 = (a - q) * (a - q) + (b - q) * (b - q) + (c - q) * (c - q) + 2.0 * p1;
    if p2 <= 0.0 {
        return [q, q, q];
    }
    let p = (p2 / 6.0).sqrt();
    let (ba, bb, bc, bd, be, bf) = ((a - q) / p, (b - q) / p, (c - q) / p, d / p, e / p, f / p);
    let r = (ba * (bb * bc - bf * bf) - bd * (bd * bc - bf * be) + be * (bd * bf - bb * be)) / 2.0;
    let r = r.clamp(-1.0, 1.0);
    let phi = r.acos() / 3.0;
    let e1 = q + 2.0 * p * phi.cos();
    let e3 = q + 2.0 * p * (phi + 2.0 * PI / 3.0).cos();
    let e2 = 3.0 * q - e1 - e3;
    // Ascending, by hand: three values (the slice sort's code is kilobytes on the board).
    let (lo, hi) = if e1 <= e2 { (e1, e2) } else { (e2, e1) };
    if e3 < lo {
        [e3, lo, hi]
    } else if e3 < hi {
        [lo, e3, hi]
    } else {
        [lo, hi, e3]
    }
}

/// Whether an inertial is physically valid: mass > 0, inertia positive definite and the
/// principal moments satisfy the triangle inequality.
#[cfg(any(test, feature = "std"))]
pub fn physically_valid(i: &Inertial) -> bool {
    if i.mass_kg.partial_cmp(&0.0) != Some(core::cmp::Ordering::Greater) {
        return false;
    }
    let e = sym_eigenvalues(&i.inertia);
    e[0] > 0.0 && e[0] + e[1] >= e[2] * (1.0 - 1e-12)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::modules::{ModuleType, SLOTS};

    // verifies: MOD-DB-01
    #[test]
    fn every_slot_type_has_a_default_and_entries_are_unique() {
        for s in SLOTS {
            assert!(default_def(s.ty).is_some(), "{} has no database entry", s.name);
        }
        for (i, a) in MODULE_DB.iter().enumerate() {
            for b in &MODULE_DB[i + 1..] {
                assert!(
                    (a.ty, a.variant, a.revision) != (b.ty, b.variant, b.revision),
                    "duplicate {:?}",
                    a.ty
                );
            }
            assert_eq!(lookup(a.ty, a.variant, a.revision), Some(a));
        }
        assert_eq!(lookup(ModuleType::Gripper, 0, 9), None);
    }

    // verifies: MOD-DB-02
    #[test]
    fn every_inertial_is_physically_valid() {
        for d in MODULE_DB {
            assert!(physically_valid(&d.inertial), "{:?} rev {}", d.ty, d.revision);
            if let Some(p) = d.part {
                assert!(physically_valid(&p.inertial), "{:?}{}", d.ty, p.suffix);
            }
        }
        // The check can fail: a rod-like inertia violating the triangle inequality,
        // a negative moment, a zero mass.
        let bad = Inertial {
            mass_kg: 1.0,
            com: [0.0; 3],
            inertia: [1.0, 1.0, 3.0, 0.0, 0.0, 0.0],
        };
        assert!(!physically_valid(&bad));
        assert!(!physically_valid(&Inertial {
            inertia: [1.0, -1.0, 1.0, 0.0, 0.0, 0.0],
            ..bad
        }));
        assert!(!physically_valid(&Inertial { mass_kg: 0.0, ..bad }));
        // Off-diagonal terms rotate the principal axes but keep a valid body valid.
        assert!(physically_valid(&Inertial {
            inertia: [2.0, 2.0, 2.0, 0.5, 0.2, 0.1],
            ..bad
        }));
    }

    // verifies: MOD-CAL-01
    #[test]
    fn defaults_resolve_within_their_ranges_and_out_of_range_words_are_refused() {
        for d in MODULE_DB {
            // Every default is inside its own range, and "default" words resolve to it.
            assert_eq!(resolve_calibration(d, &d.cal_default), Ok(d.cal_default), "{:?}", d.ty);
            assert_eq!(resolve_calibration(d, &Calibration::DEFAULT), Ok(d.cal_default));
            // Unused words are (0, 0); used ones have a real range.
            for (i, name) in d.ty.cal_names().iter().enumerate() {
                assert_eq!(name.is_empty(), d.cal_range[i] == UNUSED, "{:?} word {i}", d.ty);
            }
        }
        let r2 = lookup(ModuleType::Gripper, 0, 2).unwrap();
        // Rev 1's closed pulse width is below rev 2's end stop: refused for rev 2.
        let mut c = Calibration::DEFAULT;
        c.0[0] = 1100;
        assert_eq!(
            resolve_calibration(r2, &c),
            Err(CalError {
                word: 0,
                value: 1100,
                min: 1120,
                max: 1300
            })
        );
        // One word given, the others default.
        c.0[0] = 1160;
        assert_eq!(
            resolve_calibration(r2, &c).map(|c| c.0),
            Ok([1160, 1850, 1150, 450, 1600, 0, 0, 0])
        );
        // An unused word must be 0; the encoder's direction must not be 0.
        let mut c = r2.cal_default;
        c.0[7] = 1;
        assert_eq!(resolve_calibration(r2, &c).map_err(|e| e.word), Err(7));
        let enc = lookup(ModuleType::Encoder, 0, 1).unwrap();
        assert_eq!(
            resolve_calibration(enc, &Calibration([2048, 0, 0, 0, 0, 0, 0, 0])).map_err(|e| e.word),
            Err(1)
        );
        assert!(resolve_calibration(enc, &Calibration([4096, 1, 0, 0, 0, 0, 0, 0])).is_err());
        assert!(resolve_calibration(enc, &Calibration([4095, -1, 0, 0, 0, 0, 0, 0])).is_ok());
    }

    // verifies: MOD-DB-03
    #[test]
    fn two_gripper_revisions_differ_in_calibration_and_compatibility() {
        let r1 = lookup(ModuleType::Gripper, 0, 1).unwrap();
        let r2 = lookup(ModuleType::Gripper, 0, 2).unwrap();
        assert_ne!(r1.cal_default, r2.cal_default);
        assert!(compatible(r1, 1, 0x0100));
        assert!(!compatible(r2, 1, 0x0100));
        assert!(compatible(r2, 1, 0x0101));
        assert!(!compatible(r2, 3, 0x0200));
        // The arm calibration maps the MIB's servo set points onto the geometry.
        let arm = default_def(ModuleType::Arm).unwrap();
        let ext = |us| arm_extension_m(&arm.cal_default, us).unwrap();
        assert_eq!(ext(crate::robot::servo::ARM_CONTRACTED_US), 0.0);
        assert!((ext(crate::robot::servo::ARM_EXTENDED_US) - super::super::geometry::ARM_REACH_M).abs() < 1e-12);
        match arm.joint {
            JointKind::Prismatic { upper, .. } => assert!(upper >= super::super::geometry::ARM_REACH_M),
            other => panic!("arm joint {other:?}"),
        }
    }
}
