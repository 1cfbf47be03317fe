//! `ground model` (docs/modules.md): the robot's URDF from a live robot's module report and from
//! a module-set file; the two agree for the same robot, and a robot the model cannot be
//! built for (an arm missing) is refused with a clear error.

mod common;

use common::{ground, text, tmpdir, Obsw};

fn joints(urdf: &str) -> Vec<String> {
    urdf.lines()
        .filter_map(|l| l.trim().strip_prefix("<joint name=\""))
        .map(|l| {
            let f: Vec<&str> = l.split('"').collect();
            format!("{}:{}", f[0], f.get(2).copied().unwrap_or(""))
        })
        .collect()
}

// verifies: MOD-GROUND-01
#[test]
fn the_model_of_a_live_locomotion_only_robot_equals_the_model_of_its_module_set_file() {
    let dir = tmpdir("model", "live");
    let set = format!("{}/../plans/modules/locomotion-only.toml", env!("CARGO_MANIFEST_DIR"));
    let o = Obsw::start(1, &["--speed", "5", "--modules", &set]);
    let r = format!("1={}", o.addr);
    let live = ground(&dir, &["--no-archive", "model", "--lab-udp", "--robot", &r]);
    assert_eq!(live.status.code(), Some(0), "{}", text(&live));
    let live = String::from_utf8_lossy(&live.stdout).to_string();
    let file = ground(&dir, &["--no-archive", "model", "--modules", &set]);
    assert_eq!(file.status.code(), Some(0), "{}", text(&file));
    let file = String::from_utf8_lossy(&file.stdout).to_string();
    // The hip is revolute, the arms prismatic; no bolter tool frames on this robot.
    let j = joints(&live);
    assert!(j.iter().any(|s| s == "hip_joint:revolute"), "{j:?}");
    assert!(j.iter().any(|s| s == "arm_a_joint:prismatic"), "{j:?}");
    assert!(!live.contains("bolter_a_tool"), "a locomotion-only robot has no bolter");
    // Same robot, same model (the robot's name aside): the serials and the configuration
    // hash in the live report are those of the file.
    assert_eq!(j, joints(&file));
    assert!(live.contains("Configuration hash 0x8e67d216"), "{live}");
    assert!(file.contains("Configuration hash 0x8e67d216"), "{file}");
}

// verifies: MOD-GROUND-01
#[test]
fn a_robot_without_an_arm_has_no_model_and_a_bad_file_is_named() {
    let dir = tmpdir("model", "refused");
    let set = format!("{}/../plans/modules/missing-arm-b.toml", env!("CARGO_MANIFEST_DIR"));
    let o = ground(&dir, &["--no-archive", "model", "--modules", &set]);
    assert_eq!(o.status.code(), Some(3), "{}", text(&o));
    assert!(text(&o).contains("arm_b is absent"), "{}", text(&o));
    let o = ground(&dir, &["--no-archive", "model", "--modules", "no-such-set.toml"]);
    assert_eq!(o.status.code(), Some(3), "{}", text(&o));
    assert!(text(&o).contains("no-such-set.toml"), "{}", text(&o));
    let o = ground(&dir, &["--no-archive", "model"]);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
}
