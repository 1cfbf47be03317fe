//! The module database, descriptors and configuration hash against their documentation
//! (docs/modules.md): the documented example bytes and hashes are computed, not copied,
//! and every slot and database entry is described.

use mib::modules::config::{config_hash, CONFIGS};
use mib::modules::db::{physically_valid, MODULE_DB};
use mib::modules::{default_set, slot, ModuleSet, SLOTS};
use std::path::Path;

fn doc() -> String {
    let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("../docs/modules.md");
    std::fs::read_to_string(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

/// The value written after `marker` in the doc (up to the next backtick).
fn documented(doc: &str, marker: &str) -> String {
    match doc.find(marker) {
        Some(at) => doc[at + marker.len()..]
            .split('`')
            .next()
            .unwrap_or("")
            .trim()
            .to_string(),
        None => format!("(no `{marker}` in docs/modules.md)"),
    }
}

/// full.toml's set: default build, serials 1000 + slot, boards at firmware 1.0.
fn full() -> ModuleSet {
    default_set(1000)
}

/// locomotion-only.toml's set: serials 2000 + slot, no bolters.
fn loco() -> ModuleSet {
    let mut s = default_set(2000);
    s[slot::BOLTER_A as usize] = None;
    s[slot::BOLTER_B as usize] = None;
    s
}

fn gripper_rev_b() -> ModuleSet {
    let mut s = full();
    for (sl, serial) in [(slot::GRIPPER_A, 3101), (slot::GRIPPER_B, 3102)] {
        let d = s[sl as usize].as_mut().unwrap();
        let def = mib::modules::lookup(d.ty, 0, 2).unwrap();
        d.revision = 2;
        d.serial = serial;
        d.cal = def.cal_default;
    }
    for b in [slot::BOARD_A, slot::BOARD_B] {
        s[b as usize].as_mut().unwrap().cal.0[0] = 0x0101;
    }
    s
}

// verifies: MOD-CFG-02, MOD-DESC-01
#[test]
fn documented_hashes_and_descriptor_bytes_are_the_computed_ones() {
    let d = doc();
    let mut stale = Vec::new();
    for (marker, set) in [
        ("hash of full.toml: `", full()),
        ("hash of locomotion-only.toml: `", loco()),
        ("hash of gripper-rev-b.toml: `", gripper_rev_b()),
    ] {
        let h = format!("{:#010x}", config_hash(&set));
        println!("{marker}{h}`");
        stale.push((documented(&d, marker), h, marker));
    }
    let g = full()[slot::GRIPPER_A as usize].unwrap().to_bytes();
    let hex: Vec<String> = g.iter().map(|b| format!("{b:02x}")).collect();
    let hex = hex.join(" ");
    println!("gripper A descriptor of full.toml: `{hex}`");
    stale.push((
        documented(&d, "gripper A descriptor of full.toml: `"),
        hex,
        "descriptor",
    ));
    for (doc_value, computed, what) in stale {
        assert_eq!(doc_value, computed, "docs/modules.md is stale for {what}");
    }
}

// verifies: MOD-DB-01, MOD-DB-02
#[test]
fn every_slot_configuration_and_database_entry_is_documented() {
    let d = doc();
    for s in SLOTS {
        assert!(
            d.contains(&format!("| {} | {} |", s.id, s.name)),
            "slot {} not in the doc's table",
            s.name
        );
    }
    for c in CONFIGS {
        assert!(d.contains(c.name), "configuration {}", c.name);
    }
    for e in MODULE_DB {
        let row = format!("| {} | {} | {} |", e.ty.name(), e.variant, e.revision);
        assert!(d.contains(&row), "database row `{row}` not in the doc");
        assert!(physically_valid(&e.inertial));
    }
    // The documented total mass is the database's.
    let mass: f64 = full()
        .iter()
        .flatten()
        .map(|desc| {
            let e = mib::modules::lookup(desc.ty, desc.variant, desc.revision).unwrap();
            e.inertial.mass_kg + e.part.map(|p| p.inertial.mass_kg).unwrap_or(0.0)
        })
        .sum();
    println!("full robot's mass: `{mass:.3} kg`");
    assert_eq!(documented(&d, "full robot's mass: `"), format!("{mass:.3} kg"));
}

/// The documentation row of one database entry's calibration ranges.
fn cal_range_row(e: &mib::modules::ModuleDef) -> String {
    let words: Vec<String> =
        e.ty.cal_names()
            .iter()
            .zip(e.cal_range.iter())
            .filter(|(n, _)| !n.is_empty())
            .map(|(n, (lo, hi))| format!("{n} {lo}..{hi}"))
            .collect();
    format!(
        "| {} | {} | {} | {} |",
        e.ty.name(),
        e.variant,
        e.revision,
        words.join(", ")
    )
}

// verifies: MOD-CAL-01
#[test]
fn the_documented_calibration_ranges_are_the_databases() {
    let d = doc();
    let rows: Vec<String> = MODULE_DB.iter().map(cal_range_row).collect();
    for row in &rows {
        println!("{row}");
    }
    for row in &rows {
        assert!(
            d.contains(row.as_str()),
            "calibration range row `{row}` not in docs/modules.md"
        );
    }
}
