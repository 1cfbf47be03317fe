//! `docs/ICD.md` must be exactly what `mib_export::icd_markdown()` generates from the MIB.
//! Regenerate it with `UPDATE_ICD=1 cargo test -p mib-export --test icd`.

use std::path::Path;

// verifies: ICD-01
#[test]
fn docs_icd_md_is_generated_from_the_mib() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../docs/ICD.md");
    let want = mib_export::icd_markdown();
    if std::env::var_os("UPDATE_ICD").is_some_and(|v| v == "1") {
        std::fs::write(&path, &want).expect("write docs/ICD.md");
        return;
    }
    let have = std::fs::read_to_string(&path).unwrap_or_default();
    if have != want {
        let line = have
            .lines()
            .zip(want.lines())
            .position(|(a, b)| a != b)
            .map(|i| i + 1)
            .unwrap_or(have.lines().count().min(want.lines().count()) + 1);
        panic!(
            "docs/ICD.md is stale (first difference at line {line}); regenerate it with \
             `UPDATE_ICD=1 cargo test -p mib-export --test icd` and commit it"
        );
    }
}

// verifies: ICD-01
#[test]
fn icd_covers_every_table() {
    let icd = mib_export::icd_markdown();
    for t in mib::tc::TCS {
        assert!(icd.contains(&format!("### TC {}", t.name)), "TC {}", t.name);
    }
    for t in mib::tc::TMS {
        assert!(icd.contains(&format!("`{}`", t.name)), "TM {}", t.name);
    }
    for h in mib::hk::HK_STRUCTS {
        assert!(icd.contains(&format!("### SID {} — {}", h.sid, h.name)));
    }
    for p in mib::params::PARAMS {
        assert!(icd.contains(&format!("| {} | `{}` |", p.id, p.name)), "{}", p.name);
    }
    for e in mib::events::EVENTS {
        assert!(icd.contains(&format!("| 0x{:04X} | `{}` |", e.id, e.name)));
    }
    for f in mib::FailureCode::ALL {
        assert!(icd.contains(&format!("| {} | `{}` |", f.code(), f.name())));
    }
    for n in mib::modes::NODES {
        assert!(icd.contains(&format!("| {} | `{}` |", n.id, n.name)));
    }
    for s in &mib::robot::STATES {
        assert!(icd.contains(&format!("| {} | {} | {} |", s.id, s.label, s.name)));
    }
    for p in &mib::robot::PRIMITIVES {
        assert!(icd.contains(&format!("| {} | {} | {} |", p.id, p.name, p.moving.name())));
    }
    for m in mib::fdir::MONITORS {
        assert!(icd.contains(&format!("| {} | `{}` |", m.id, m.name)));
    }
    for t in mib::tunables::TUNABLES {
        assert!(icd.contains(&format!("| {} | `{}` |", t.id, t.name)));
    }
    // The 15x15 map: one row per state with 15 cells.
    for (i, s) in mib::robot::STATES.iter().enumerate() {
        let prefix = format!("| **{}** {} |", s.label, s.name);
        let row = icd
            .lines()
            .find(|l| l.starts_with(&prefix))
            .unwrap_or_else(|| panic!("map row {}", s.label));
        let cells: Vec<&str> = row[prefix.len()..]
            .split('|')
            .map(str::trim)
            .filter(|c| !c.is_empty())
            .collect();
        assert_eq!(cells.len(), mib::robot::NUM_STATES);
        for (j, c) in cells.iter().enumerate() {
            let p = mib::robot::RECONFIG_MAP[i][j];
            let want = if p == 0 { "·".to_string() } else { p.to_string() };
            assert_eq!(*c, want, "map {i}->{j}");
        }
    }
}
