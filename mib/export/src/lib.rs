//! Exporters of the MIB to the formats ground systems read: a std crate beside the flight
//! MIB, which stays no_std and holds the tables only.
//!
//! - [`scos_tables`]: SCOS-2000 MIB ASCII tables (tab-separated `.dat` files);
//! - [`xtce_document`]: XTCE 1.2 XML (telemetry containers and telecommands);
//! - [`json_document`]: the whole MIB as JSON;
//! - [`icd_markdown`]: the interface control document (`docs/ICD.md`);
//! - [`memory::partitions_csv`], [`memory::memory_map_txt`]: the boards' partition table
//!   and the memory map the size report reads;
//! - [`yamcs_instance`]: a complete Yamcs instance (configuration, MDB, event templates)
//!   for a set of robots.
//!
//! The APID-dependent exports (SCOS-2000, XTCE) are generated for the default robot
//! ([`mib::apid::DEFAULT_ROBOT`], APID 0x101); the `*_for` variants take another robot
//! number. Everything is derived from the MIB tables; the only layout knowledge kept
//! here is the byte layout of the CCSDS and PUS-C headers ([`headers`]), which is checked
//! against the sat-rs encoder by the integration tests.

use std::path::{Path, PathBuf};
use std::str::FromStr;

mod flavour;
pub mod headers;
mod icd;
mod json;
pub mod memory;
mod scos;
pub mod text;
pub mod urdf;
mod xml;
mod xtce;
pub mod yamcs;

pub use icd::icd_markdown;
pub use json::json_document;
pub use scos::{scos_columns, scos_tables, scos_tables_for, ScosNames};
pub use xtce::{xtce_document, xtce_document_for};
pub use yamcs::{yamcs_instance, RobotSet, YamcsRobot, YamcsSetup};

/// The robot states in which the limits of `p` apply (`limits_in`, `limits_if`), as
/// lists of (parameter ID, raw value) that must all match: one per root mode of
/// `limits_in` (without `MODE` if the limits hold in every mode), each with the
/// condition of `limits_if`. Empty when the limits always apply. XTCE turns each list
/// into a context alarm, SCOS-2000 into checks made relevant by `OCP_RLCHK`/`OCP_VALPAR`.
pub fn limit_contexts(p: &mib::params::ParamDef) -> Vec<Vec<(u16, i64)>> {
    let cond: Vec<(u16, i64)> = p.limits_if().iter().map(|c| (c.param, c.raw)).collect();
    if p.limits.is_none() {
        return Vec::new();
    }
    if p.limits_in == mib::modes::ModeSet::ALL {
        return if cond.is_empty() { Vec::new() } else { vec![cond] };
    }
    p.limits_in
        .modes()
        .map(|m| {
            let mut v = vec![(mib::params::pid::MODE, i64::from(m))];
            v.extend(cond.iter().copied());
            v
        })
        .collect()
}

/// Export format of `ground mib export --format`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Format {
    /// SCOS-2000 MIB ASCII tables, one `.dat` file per table.
    Scos,
    /// One XTCE 1.2 XML file.
    Xtce,
    /// One JSON file with the whole MIB.
    Json,
    /// A Yamcs instance for these robots (`yamcs` = the default robot, `yamcs:1-3,7`), over
    /// the space link (TC/TM frames, COP-1, SDLS).
    Yamcs(RobotSet),
    /// Lab only: the same instance over bare space packets on UDP (`yamcs-lab[:ROBOTS]`).
    YamcsLab(RobotSet),
}

impl Format {
    pub const ALL: [Format; 5] = [
        Format::Scos,
        Format::Xtce,
        Format::Json,
        Format::Yamcs(RobotSet::one(mib::apid::DEFAULT_ROBOT)),
        Format::YamcsLab(RobotSet::one(mib::apid::DEFAULT_ROBOT)),
    ];
    pub const fn name(self) -> &'static str {
        match self {
            Format::Scos => "scos",
            Format::Xtce => "xtce",
            Format::Json => "json",
            Format::Yamcs(_) => "yamcs",
            Format::YamcsLab(_) => "yamcs-lab",
        }
    }
}

impl core::fmt::Display for Format {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(self.name())
    }
}

/// Error of [`Format::from_str`].
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct UnknownFormat(pub String);

impl core::fmt::Display for UnknownFormat {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(
            f,
            "unknown export format '{}' (expected scos, xtce, json, yamcs or yamcs:ROBOTS such as yamcs:1-3,7, or yamcs-lab[:ROBOTS] for bare packets in the lab)",
            self.0
        )
    }
}

impl std::error::Error for UnknownFormat {}

impl FromStr for Format {
    type Err = UnknownFormat;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.trim().to_ascii_lowercase().as_str() {
            "scos" | "scos2000" | "scos-2000" => Ok(Format::Scos),
            "xtce" | "xml" => Ok(Format::Xtce),
            "json" => Ok(Format::Json),
            "yamcs" => Ok(Format::Yamcs(RobotSet::one(mib::apid::DEFAULT_ROBOT))),
            "yamcs-lab" => Ok(Format::YamcsLab(RobotSet::one(mib::apid::DEFAULT_ROBOT))),
            other => {
                let (robots, make): (&str, fn(RobotSet) -> Format) = if let Some(r) = other.strip_prefix("yamcs:") {
                    (r, Format::Yamcs)
                } else if let Some(r) = other.strip_prefix("yamcs-lab:") {
                    (r, Format::YamcsLab)
                } else {
                    return Err(UnknownFormat(s.to_string()));
                };
                robots.parse().map(make).map_err(|e| UnknownFormat(format!("{s}: {e}")))
            }
        }
    }
}

/// File name of the XTCE export.
pub const XTCE_FILE: &str = "mmic-i.xtce.xml";
/// File name of the JSON export.
pub const JSON_FILE: &str = "mmic-i.mib.json";

/// Writes the export `format` into `dir` (created if missing) and returns the paths
/// written, in order.
pub fn write_all(format: Format, dir: &Path) -> std::io::Result<Vec<PathBuf>> {
    std::fs::create_dir_all(dir)?;
    let files: Vec<(String, String)> = match format {
        Format::Scos => scos_tables().into_iter().map(|(n, c)| (n.to_string(), c)).collect(),
        Format::Xtce => vec![(XTCE_FILE.to_string(), xtce_document())],
        Format::Json => vec![(JSON_FILE.to_string(), json_document())],
        Format::Yamcs(robots) => yamcs_instance(&YamcsSetup::with_links(robots, yamcs::Links::Frames)),
        Format::YamcsLab(robots) => yamcs_instance(&YamcsSetup::with_links(robots, yamcs::Links::LabPackets)),
    };
    let mut out = Vec::with_capacity(files.len());
    for (name, content) in files {
        let path = dir.join(name);
        if let Some(parent) = path.parent() {
            std::fs::create_dir_all(parent)?;
        }
        std::fs::write(&path, content)?;
        out.push(path);
    }
    Ok(out)
}

/// Engineering value of a calibration coefficient as text, without trailing noise
/// (shortest representation that round-trips).
pub(crate) fn num(v: f64) -> String {
    if v == v.trunc() && v.abs() < 1e15 {
        format!("{}", v as i64)
    } else {
        format!("{v}")
    }
}

/// Truncates to at most `n` characters (SCOS-2000 column widths).
pub(crate) fn trunc(s: &str, n: usize) -> String {
    s.chars().take(n).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    // verifies: ICD-04
    #[test]
    fn format_parses_case_insensitively_and_rejects_others() {
        assert_eq!("SCOS".parse::<Format>(), Ok(Format::Scos));
        assert_eq!("xtce".parse::<Format>(), Ok(Format::Xtce));
        assert_eq!(" json ".parse::<Format>(), Ok(Format::Json));
        assert!("yaml".parse::<Format>().is_err());
        for f in Format::ALL {
            assert_eq!(f.name().parse::<Format>(), Ok(f));
        }
    }
    // verifies: YAMCS-EXPORT-01
    #[test]
    fn yamcs_format_takes_robots_and_writes_the_instance_tree() {
        let Ok(Format::Yamcs(set)) = "Yamcs:1-2,5".parse::<Format>() else {
            panic!("yamcs:ROBOTS parses")
        };
        assert_eq!(set.iter().collect::<Vec<_>>(), [1, 2, 5]);
        assert!("yamcs:0".parse::<Format>().is_err());
        assert!("yamcs:".parse::<Format>().is_err());
        let Ok(Format::YamcsLab(lab)) = "yamcs-lab:3".parse::<Format>() else {
            panic!("yamcs-lab:ROBOTS parses")
        };
        assert_eq!(lab.iter().collect::<Vec<_>>(), [3]);
        assert!("yamcs-lab:0".parse::<Format>().is_err());
        let dir = std::env::temp_dir().join(format!("mib-yamcs-export-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let files = write_all(Format::Yamcs(set), &dir).unwrap();
        for f in [
            "etc/yamcs.yaml",
            "etc/yamcs.mmic.yaml",
            "etc/processor.yaml",
            "etc/events.json",
            yamcs::CFDP_SQL_FILE,
        ] {
            assert!(files.contains(&dir.join(f)), "{f}");
        }
        for n in [1, 2, 5] {
            assert!(dir.join(yamcs::mdb_file(n)).is_file());
        }
        assert_eq!(files.len(), 8);
        let _ = std::fs::remove_dir_all(&dir);
    }
    // verifies: ICD-04
    #[test]
    fn numbers_print_without_noise() {
        assert_eq!(num(1.0), "1");
        assert_eq!(num(0.01), "0.01");
        assert_eq!(num(-3.0), "-3");
        assert_eq!(trunc("abcdef", 3), "abc");
    }
}

#[cfg(test)]
mod limit_context_tests {
    use super::*;
    use mib::params::{by_id, pid, PARAMS};

    // verifies: ALM-COND-01
    #[test]
    fn limit_states_fit_one_relevance_parameter_and_name_the_condition() {
        for p in PARAMS {
            for c in limit_contexts(p) {
                assert_eq!(c.len(), 1, "{}: SCOS-2000 OCP_RLCHK takes one parameter", p.name);
            }
        }
        let hip = by_id(pid::HIP_DEVIATION).unwrap();
        assert_eq!(limit_contexts(hip), vec![vec![(pid::ACTIVE_PRIMITIVE, 0)]]);
        let v_reg = by_id(pid::V_REG).unwrap();
        assert_eq!(limit_contexts(v_reg), vec![vec![(pid::MODE, 1)], vec![(pid::MODE, 2)]]);
        assert!(limit_contexts(by_id(pid::V_BAT_A).unwrap()).is_empty());
    }
}
