//! The generated URDF loaded in Pinocchio (PyPI `pin`, in the repository's `.venv`):
//! for each of the 15 configuration states, forward kinematics must put each gripper on
//! the face of the lattice the MIB says (0.5 mm, 0.5°); every mass positive, every
//! inertia positive definite and satisfying the triangle inequality. The Python script
//! (`tests/py/check_urdf.py`) decides on its own which face a frame lies on; this test
//! gives it the joint values and the expected faces from the MIB and asserts on its
//! report. Deliberately wrong joint values and a broken inertia must be reported.

use mib::modules::geometry::{state_pose, Approach, PITCH_M};
use mib::modules::{default_set, slot, Board, ModuleSet};
use mib::robot::{StateKind, NUM_STATES, STATES};
use mib_export::urdf::{joint, state_joint_positions, urdf};
use serde_json::{json, Value};
use std::path::{Path, PathBuf};
use std::process::Command;

const TOL_M: f64 = 0.0005;
const TOL_DEG: f64 = 0.5;

fn python() -> PathBuf {
    let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../.venv/bin/python");
    assert!(
        p.exists(),
        "{} is missing: run `bash scripts/python-env.sh` (installs pin 4.1.0) first",
        p.display()
    );
    p
}

fn work_dir(tag: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("mmic-urdf-{}-{tag}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn approach(a: Approach) -> &'static str {
    a.name()
}

/// One case per state; `tweak` may change the joint values of a case (by state id).
fn cases(root: Board, with_bolters: bool, tweak: &dyn Fn(u8, &mut Value)) -> Vec<Value> {
    let mut out = Vec::new();
    for id in 0..NUM_STATES as u8 {
        let p = state_pose(id).unwrap();
        let (r, f, rname, fname) = match root {
            Board::A => (p.a, p.b, "gripper_a", "gripper_b"),
            Board::B => (p.b, p.a, "gripper_b", "gripper_a"),
        };
        let mut joints = serde_json::Map::new();
        for (n, v) in state_joint_positions(id).unwrap() {
            joints.insert(n.to_string(), json!(v));
        }
        let mut expect = serde_json::Map::new();
        expect.insert(
            rname.into(),
            json!({"face": r.face.name(), "approach": approach(r.approach)}),
        );
        expect.insert(
            fname.into(),
            json!({"face": f.face.name(), "approach": approach(f.approach)}),
        );
        if with_bolters && STATES[id as usize].kind() == StateKind::Matched {
            // Bolting happens in matched states: both tool frames on the gripped face.
            for t in ["bolter_a_tool", "bolter_b_tool"] {
                expect.insert(t.into(), json!({"face": p.a.face.name()}));
            }
        }
        let mut joints = Value::Object(joints);
        tweak(id, &mut joints);
        out.push(json!({
            "name": format!("{} {}", STATES[id as usize].label, STATES[id as usize].name),
            "joints": joints,
            "root": {"face": r.face.name(), "approach": approach(r.approach)},
            "expect": expect,
            "gravity_frames": ["imu_a", "imu_b"],
        }));
    }
    out
}

fn run(tag: &str, urdf_text: &str, root: Board, cases: Vec<Value>) -> Value {
    let dir = work_dir(tag);
    let urdf_path = dir.join("robot.urdf");
    std::fs::write(&urdf_path, urdf_text).unwrap();
    let spec = json!({
        "urdf": urdf_path,
        "root_link": match root { Board::A => "gripper_a", Board::B => "gripper_b" },
        "pitch": PITCH_M, "tol_m": TOL_M, "tol_deg": TOL_DEG, "cases": cases,
    });
    let spec_path = dir.join("cases.json");
    std::fs::write(&spec_path, serde_json::to_vec_pretty(&spec).unwrap()).unwrap();
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/py/check_urdf.py");
    let out = Command::new(python()).arg(&script).arg(&spec_path).output().unwrap();
    assert!(
        out.status.success(),
        "check_urdf.py failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    // MMIC_URDF_KEEP=1 keeps the URDF, the cases and the report for inspection.
    if std::env::var_os("MMIC_URDF_KEEP").is_some() {
        std::fs::write(dir.join("report.json"), &out.stdout).unwrap();
        println!("kept {}", dir.display());
    } else {
        let _ = std::fs::remove_dir_all(&dir);
    }
    serde_json::from_slice(&out.stdout).expect("JSON report")
}

fn locomotion_only() -> ModuleSet {
    let mut set = default_set(2000);
    set[slot::BOLTER_A as usize] = None;
    set[slot::BOLTER_B as usize] = None;
    set
}

/// Asserts every case and every frame of the report is on its expected face; returns
/// the largest plane and axis errors.
fn assert_all_on_face(report: &Value, what: &str) -> (f64, f64) {
    let cases = report["cases"].as_array().unwrap();
    assert_eq!(cases.len(), NUM_STATES, "{what}");
    let (mut dmax, mut amax) = (0.0f64, 0.0f64);
    for c in cases {
        assert_eq!(
            c["errors"].as_array().unwrap().len(),
            0,
            "{what} {}: {}",
            c["name"],
            c["errors"]
        );
        assert_eq!(c["within_limits"], json!(true), "{what} {}", c["name"]);
        for (frame, r) in c["frames"].as_object().unwrap() {
            assert_eq!(r["ok"], json!(true), "{what} {} {frame}: {r}", c["name"]);
            assert!(r["y_err_deg"].as_f64().unwrap() <= TOL_DEG || frame.contains("tool"));
            dmax = dmax.max(r["plane_err_m"].as_f64().unwrap());
            amax = amax.max(r["axis_err_deg"].as_f64().unwrap());
        }
    }
    (dmax, amax)
}

/// Mass of a module set from the database (each module's body and its second part).
fn db_mass(set: &ModuleSet) -> f64 {
    set.iter()
        .flatten()
        .map(|d| {
            let e = mib::modules::lookup(d.ty, d.variant, d.revision).unwrap();
            e.inertial.mass_kg + e.part.map(|p| p.inertial.mass_kg).unwrap_or(0.0)
        })
        .sum()
}

fn assert_masses_valid(report: &Value, links: usize, what: &str) {
    let l = report["links"].as_array().unwrap();
    assert_eq!(l.len(), links, "{what}: links in the URDF");
    for r in l.iter().chain(report["bodies"].as_array().unwrap()) {
        assert_eq!(r["ok"], json!(true), "{what}: {r}");
    }
    assert_eq!(report["nq"], json!(5), "{what}: hip, two arms, two jaws");
}

// verifies: MOD-URDF-02, MOD-URDF-03
#[test]
fn full_robot_grippers_on_the_mib_faces_in_all_15_states_both_roots() {
    let set = default_set(1000);
    for root in [Board::A, Board::B] {
        let text = urdf(&set, root, "mmic_i").unwrap();
        let report = run(
            &format!("full-{}", root.name()),
            &text,
            root,
            cases(root, true, &|_, _| {}),
        );
        let (d, a) = assert_all_on_face(&report, &format!("full, root {}", root.name()));
        assert_masses_valid(&report, 18, "full");
        let total = report["total_mass"].as_f64().unwrap();
        assert!((total - db_mass(&set)).abs() < 1e-9, "Pinocchio {total} kg");
        println!(
            "full robot, root {}: largest plane error {d:.3e} m, axis error {a:.3e} deg",
            root.name()
        );
    }
}

// verifies: MOD-URDF-02, MOD-URDF-03
#[test]
fn locomotion_only_robot_grippers_on_the_mib_faces_in_all_15_states() {
    let set = locomotion_only();
    let text = urdf(&set, Board::A, "mmic_i_loco").unwrap();
    let report = run("loco", &text, Board::A, cases(Board::A, false, &|_, _| {}));
    assert_all_on_face(&report, "locomotion-only");
    assert_masses_valid(&report, 14, "locomotion-only");
    let total = report["total_mass"].as_f64().unwrap();
    assert!((total - db_mass(&set)).abs() < 1e-9, "Pinocchio {total} kg");
    assert!(total < db_mass(&default_set(1000)));
}

// verifies: MOD-URDF-02
#[test]
fn wrong_joint_values_are_reported_off_the_face() {
    let set = default_set(1000);
    let text = urdf(&set, Board::A, "mmic_i").unwrap();
    // State d ("Xneg Xpos", stretch): arm B 1 mm too long; state h ("Xneg Yneg", turn):
    // hip 1° short; state a (matched): hip at +90° as in a turn.
    let tweak = |id: u8, j: &mut Value| {
        let add = |j: &mut Value, name: &str, dv: f64| {
            let v = j[name].as_f64().unwrap();
            j[name] = json!(v + dv);
        };
        match id {
            3 => add(j, joint::ARM_B, 0.001),
            7 => add(j, joint::HIP, -1f64.to_radians()),
            0 => add(j, joint::HIP, std::f64::consts::FRAC_PI_2),
            _ => {}
        }
    };
    let report = run("wrong", &text, Board::A, cases(Board::A, false, &tweak));
    for c in report["cases"].as_array().unwrap() {
        let name = c["name"].as_str().unwrap();
        let b = &c["frames"]["gripper_b"];
        let wrong = name.starts_with("d ") || name.starts_with("h ") || name.starts_with("a ");
        assert_eq!(b["ok"], json!(!wrong), "{name}: {b}");
        if name.starts_with("d ") {
            // 1 mm along the normal: off the Xpos plane by 1 mm, no other face.
            assert!((b["plane_err_m"].as_f64().unwrap() - 0.001).abs() < 1e-6, "{b}");
            assert_eq!(b["found"], Value::Null);
        }
        if name.starts_with("h ") {
            assert!(b["axis_err_deg"].as_f64().unwrap() > 0.9, "{b}");
        }
    }
}

// verifies: MOD-URDF-03
#[test]
fn a_broken_inertia_is_reported_by_the_independent_check() {
    let set = default_set(1000);
    let text = urdf(&set, Board::A, "mmic_i").unwrap();
    // The hip's inertia made rod-like (izz > ixx + iyy) and a mass of zero elsewhere.
    let hip_at = text.find("<link name=\"hip\">").unwrap();
    let izz_at = hip_at + text[hip_at..].find("izz=\"").unwrap() + 5;
    let end = izz_at + text[izz_at..].find('"').unwrap();
    let mut broken = format!("{}1.0{}", &text[..izz_at], &text[end..]);
    let enc_at = broken.find("<link name=\"encoder\">").unwrap();
    let m_at = enc_at + broken[enc_at..].find("<mass value=\"").unwrap() + 13;
    let m_end = m_at + broken[m_at..].find('"').unwrap();
    broken = format!("{}0{}", &broken[..m_at], &broken[m_end..]);
    let report = run("broken", &broken, Board::A, Vec::new());
    let bad: Vec<&str> = report["links"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|r| r["ok"] != json!(true))
        .map(|r| r["name"].as_str().unwrap())
        .collect();
    assert_eq!(bad, ["hip", "encoder"]);
}

/// What `mmic_domain::imu` says a board gripped to `face` reads (docs/domain.md: board
/// frame z = inward normal, y = world Z; gravity world −Y): `[−nx, 0, −ny]` g.
fn domain_gravity_mg(face: mib::robot::Face) -> [f64; 3] {
    let (nx, ny) = face.inward_normal();
    [-1000.0 * nx as f64, 0.0, -1000.0 * ny as f64]
}

// verifies: MOD-GEO-02
#[test]
fn imu_frames_read_the_domain_gravity_except_board_b_in_matched_states() {
    let set = default_set(1000);
    let text = urdf(&set, Board::A, "mmic_i").unwrap();
    let report = run("imu", &text, Board::A, cases(Board::A, false, &|_, _| {}));
    let close = |v: &Value, w: [f64; 3]| {
        let v: Vec<f64> = v.as_array().unwrap().iter().map(|x| x.as_f64().unwrap()).collect();
        v.iter().zip(w).all(|(a, b)| (a - b).abs() < 1e-6)
    };
    for (id, c) in report["cases"].as_array().unwrap().iter().enumerate() {
        let s = &STATES[id];
        let g = &c["gravity_mg"];
        assert!(
            close(&g["imu_a"], domain_gravity_mg(s.a)),
            "{}: imu_a {}",
            s.name,
            g["imu_a"]
        );
        match s.kind() {
            StateKind::Stretch | StateKind::Turn => {
                assert!(
                    close(&g["imu_b"], domain_gravity_mg(s.b)),
                    "{}: imu_b {}",
                    s.name,
                    g["imu_b"]
                );
            }
            // docs/modules.md, open finding 2: the rigid robot's board B faces the other
            // way in a matched state and reads the gravity the domain gives the opposite face.
            StateKind::Matched => {
                assert!(
                    close(&g["imu_b"], domain_gravity_mg(s.a.opposite())),
                    "{}: imu_b {}",
                    s.name,
                    g["imu_b"]
                );
            }
        }
    }
}
