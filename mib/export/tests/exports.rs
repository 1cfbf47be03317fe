//! Well-formedness of the exports: SCOS-2000 tables (column counts, widths, references
//! between tables, coverage of the MIB), XTCE (parses as XML, references resolve, every
//! HK parameter, container and TC is there), JSON (round trip against the tables) and
//! `write_all`.

use mib::events::EVENTS;
use mib::hk::HK_STRUCTS;
use mib::params::{ParamDef, PARAMS};
use mib::tc::{TCS, TMS};
use mib_export::{self as export, Format, ScosNames};
use std::collections::{BTreeMap, BTreeSet};

/// Column counts of the SCOS-2000 MIB ICD, written down independently of the
/// exporter's own column lists.
const COLUMNS: &[(&str, usize)] = &[
    ("vdf.dat", 5),
    ("pid.dat", 16),
    ("pic.dat", 7),
    ("tpcf.dat", 3),
    ("pcf.dat", 24),
    ("plf.dat", 8),
    ("caf.dat", 8),
    ("cap.dat", 3),
    ("ocf.dat", 5),
    ("ocp.dat", 7),
    ("tcp.dat", 2),
    ("pcpc.dat", 3),
    ("pcdf.dat", 8),
    ("ccf.dat", 21),
    ("cdf.dat", 10),
    ("cpc.dat", 17),
    ("prf.dat", 7),
    ("prv.dat", 3),
];

type Rows = Vec<Vec<String>>;

fn tables() -> BTreeMap<&'static str, Rows> {
    export::scos_tables()
        .into_iter()
        .map(|(name, content)| {
            let rows = content
                .lines()
                .map(|l| l.split('\t').map(str::to_string).collect())
                .collect();
            (name, rows)
        })
        .collect()
}

fn col(table: &str, name: &str) -> usize {
    export::scos_columns(table)
        .unwrap()
        .iter()
        .position(|c| *c == name)
        .unwrap_or_else(|| panic!("{table} has no column {name}"))
}

fn values(t: &BTreeMap<&str, Rows>, table: &str, column: &str) -> Vec<String> {
    let i = col(table, column);
    t[table].iter().map(|r| r[i].clone()).collect()
}

fn set(v: Vec<String>) -> BTreeSet<String> {
    v.into_iter().filter(|s| !s.is_empty()).collect()
}

/// The states in which the limits of `p` apply, from the MIB's fields (not from the
/// exporters' helper): (relevance parameter named by `name`, raw value), one per root
/// mode of `limits_in` or the condition of `limits_if`; ("", "") when always.
fn want_states(p: &ParamDef, name: impl Fn(u16) -> String) -> Vec<(String, String)> {
    match (p.limits_in == mib::modes::ModeSet::ALL, p.limits_if()) {
        (true, None) => vec![(String::new(), String::new())],
        (true, Some(c)) => vec![(name(c.param), c.raw.to_string())],
        (false, None) => p
            .limits_in
            .modes()
            .map(|m| (name(mib::params::pid::MODE), m.to_string()))
            .collect(),
        (false, Some(_)) => panic!("{}: mode and condition together do not fit SCOS-2000", p.name),
    }
}

// verifies: ICD-02
#[test]
fn scos_tables_have_the_icd_column_counts_and_no_stray_characters() {
    let t = tables();
    let names: Vec<&str> = t.keys().copied().collect();
    for (file, n) in COLUMNS {
        assert!(names.contains(file), "{file} missing");
        assert_eq!(export::scos_columns(file).map(|c| c.len()), Some(*n), "{file}");
        assert!(!t[file].is_empty(), "{file} is empty");
        for r in &t[*file] {
            assert_eq!(r.len(), *n, "{file}: {r:?}");
            for cell in r {
                assert!(
                    cell.is_ascii() && !cell.chars().any(|c| c.is_control()),
                    "{file}: {cell:?}"
                );
            }
        }
    }
    assert_eq!(t.len(), COLUMNS.len());
}

// verifies: ICD-02
#[test]
fn scos_names_and_texts_fit_their_columns() {
    let t = tables();
    // (table, column, max characters) from the SCOS-2000 MIB ICD.
    let widths = [
        ("pcf.dat", "PCF_NAME", 8),
        ("pcf.dat", "PCF_DESCR", 24),
        ("pcf.dat", "PCF_UNIT", 4),
        ("pcf.dat", "PCF_CURTX", 10),
        ("pid.dat", "PID_DESCR", 64),
        ("pid.dat", "PID_EVID", 17),
        ("tpcf.dat", "TPCF_NAME", 12),
        ("plf.dat", "PLF_NAME", 8),
        ("caf.dat", "CAF_NUMBR", 10),
        ("caf.dat", "CAF_DESCR", 32),
        ("ocf.dat", "OCF_NAME", 8),
        ("ccf.dat", "CCF_CNAME", 8),
        ("ccf.dat", "CCF_DESCR", 24),
        ("ccf.dat", "CCF_DESCR2", 64),
        ("ccf.dat", "CCF_PKTID", 8),
        ("cdf.dat", "CDF_CNAME", 8),
        ("cdf.dat", "CDF_DESCR", 24),
        ("cdf.dat", "CDF_PNAME", 8),
        ("cpc.dat", "CPC_PNAME", 8),
        ("cpc.dat", "CPC_DESCR", 24),
        ("cpc.dat", "CPC_UNIT", 4),
        ("cpc.dat", "CPC_PRFREF", 10),
        ("prf.dat", "PRF_NUMBR", 10),
        ("tcp.dat", "TCP_ID", 8),
        ("pcpc.dat", "PCPC_PNAME", 8),
        ("pcdf.dat", "PCDF_PNAME", 8),
    ];
    for (table, column, w) in widths {
        for v in values(&t, table, column) {
            assert!(v.chars().count() <= w, "{table} {column}: '{v}' longer than {w}");
        }
    }
    // Keys are unique.
    for (table, column) in [
        ("pcf.dat", "PCF_NAME"),
        ("pid.dat", "PID_SPID"),
        ("tpcf.dat", "TPCF_SPID"),
        ("ccf.dat", "CCF_CNAME"),
        ("cpc.dat", "CPC_PNAME"),
        ("caf.dat", "CAF_NUMBR"),
        ("prf.dat", "PRF_NUMBR"),
        ("ocf.dat", "OCF_NAME"),
    ] {
        let v = values(&t, table, column);
        assert_eq!(set(v.clone()).len(), v.len(), "{table} {column} not unique");
    }
}

// verifies: ICD-02, ALM-COND-01, ALM-PERSIST-01
#[test]
fn scos_references_between_tables_resolve() {
    let t = tables();
    let pcf = set(values(&t, "pcf.dat", "PCF_NAME"));
    let spids = set(values(&t, "pid.dat", "PID_SPID"));
    let caf = set(values(&t, "caf.dat", "CAF_NUMBR"));
    let cpc = set(values(&t, "cpc.dat", "CPC_PNAME"));
    let prf = set(values(&t, "prf.dat", "PRF_NUMBR"));
    let ccf = set(values(&t, "ccf.dat", "CCF_CNAME"));
    let tcp = set(values(&t, "tcp.dat", "TCP_ID"));
    let pcpc = set(values(&t, "pcpc.dat", "PCPC_PNAME"));
    let checks: [(&str, &str, &BTreeSet<String>); 13] = [
        ("tpcf.dat", "TPCF_SPID", &spids),
        ("plf.dat", "PLF_SPID", &spids),
        ("plf.dat", "PLF_NAME", &pcf),
        ("pcf.dat", "PCF_CURTX", &caf),
        ("cap.dat", "CAP_NUMBR", &caf),
        ("ocf.dat", "OCF_NAME", &pcf),
        ("ocp.dat", "OCP_NAME", &pcf),
        ("ccf.dat", "CCF_PKTID", &tcp),
        ("cdf.dat", "CDF_CNAME", &ccf),
        ("cdf.dat", "CDF_PNAME", &cpc),
        ("cpc.dat", "CPC_PRFREF", &prf),
        ("prv.dat", "PRV_NUMBR", &prf),
        ("pcdf.dat", "PCDF_PNAME", &pcpc),
    ];
    for (table, column, target) in checks {
        for v in set(values(&t, table, column)) {
            assert!(target.contains(&v), "{table} {column} = {v} refers to nothing");
        }
    }
    // Every TPCF row has a PID row and vice versa; every monitored parameter has an OCP
    // row per OCF_NBOOL.
    assert_eq!(set(values(&t, "tpcf.dat", "TPCF_SPID")), spids);
    let ocp_names = values(&t, "ocp.dat", "OCP_NAME");
    for r in &t["ocf.dat"] {
        let n: usize = r[col("ocf", "OCF_NBOOL")].parse().unwrap();
        assert_eq!(ocp_names.iter().filter(|x| **x == r[0]).count(), n);
    }
    // A limit that holds only in some robot states is relevant per state (OCP_RLCHK on
    // the MODE parameter or on the parameter of the MIB's condition, OCP_VALPAR its raw
    // value); every other limit always. Every check waits for the MIB's persistence.
    for p in PARAMS.iter().filter(|p| p.limits.is_some()) {
        let n = mib_export::ScosNames::tm_param(p.id);
        let ocf = t["ocf.dat"].iter().find(|r| r[0] == n).unwrap();
        assert_eq!(
            ocf[col("ocf", "OCF_NBCHCK")],
            mib::params::GROUND_LIMIT_PERSISTENCE.to_string(),
            "{}",
            p.name
        );
        let rows: Vec<&Vec<String>> = t["ocp.dat"].iter().filter(|r| r[0] == n).collect();
        let mut got: Vec<(String, String)> = rows
            .iter()
            .map(|r| (r[col("ocp", "OCP_RLCHK")].clone(), r[col("ocp", "OCP_VALPAR")].clone()))
            .collect();
        got.dedup();
        assert_eq!(got, want_states(p, mib_export::ScosNames::tm_param), "{}", p.name);
    }
    // A hazardous TC is critical.
    for tc in TCS {
        let r = t["ccf.dat"]
            .iter()
            .find(|r| r[0] == mib_export::ScosNames::command(tc))
            .unwrap();
        let want = if tc.hazard.is_some() { "Y" } else { "N" };
        assert_eq!(r[col("ccf", "CCF_CRITICAL")], want, "{}", tc.name);
    }
    // PIC covers every (type, subtype) of PID.
    let pic: BTreeSet<(String, String)> = t["pic.dat"].iter().map(|r| (r[0].clone(), r[1].clone())).collect();
    for r in &t["pid.dat"] {
        assert!(pic.contains(&(r[0].clone(), r[1].clone())), "no pic for {r:?}");
    }
    // CCF_NPARS = CDF elements with a parameter.
    for r in &t["ccf.dat"] {
        let n = t["cdf.dat"]
            .iter()
            .filter(|d| d[0] == r[0] && !d[col("cdf", "CDF_PNAME")].is_empty())
            .count();
        assert_eq!(r[col("ccf", "CCF_NPARS")], n.to_string(), "{}", r[0]);
    }
}

// verifies: ICD-02
#[test]
fn scos_tables_describe_every_packet_parameter_and_command_of_robot_one() {
    let t = tables();
    let apid = mib::apid::robot_apid(1).unwrap().to_string();
    let pid = &t["pid.dat"];
    let (ty, st, ap, pi1, spid) = (
        col("pid", "PID_TYPE"),
        col("pid", "PID_STYPE"),
        col("pid", "PID_APID"),
        col("pid", "PID_PI1_VAL"),
        col("pid", "PID_SPID"),
    );
    assert!(pid.iter().all(|r| r[ap] == apid));
    let find = |s: u8, sub: u8, p1: u16| {
        pid.iter()
            .find(|r| r[ty] == s.to_string() && r[st] == sub.to_string() && r[pi1] == p1.to_string())
    };
    let tpcf_size: BTreeMap<String, String> = t["tpcf.dat"].iter().map(|r| (r[0].clone(), r[2].clone())).collect();
    let plf = &t["plf.dat"];
    for h in HK_STRUCTS {
        let r = find(3, 25, h.sid).unwrap_or_else(|| panic!("no pid row for SID {}", h.sid));
        let s = &r[spid];
        // Every parameter is placed at its offset; the last one ends where the PEC starts.
        let rows: Vec<&Vec<String>> = plf.iter().filter(|p| &p[1] == s).collect();
        assert_eq!(rows.len(), h.params.len() + 1);
        let mut off = export::headers::tm_source_data_offset() + 2;
        for (id, row) in h.params.iter().zip(&rows[1..]) {
            assert_eq!(row[0], ScosNames::tm_param(*id));
            assert_eq!(row[2], off.to_string());
            off += mib::params::by_id(*id).unwrap().ptype.size();
        }
        assert_eq!(tpcf_size[s], (off + 2).to_string());
        assert_eq!(rows[0][0], ScosNames::SID);
        assert_eq!(rows[0][2], export::headers::tm_source_data_offset().to_string());
    }
    for e in EVENTS {
        let r = find(5, e.severity.subservice(), e.id).unwrap_or_else(|| panic!("no pid row for {}", e.name));
        assert_eq!(plf.iter().filter(|p| p[1] == r[spid]).count(), e.params.len() + 1);
    }
    for tm in TMS {
        assert!(
            pid.iter()
                .any(|r| r[ty] == tm.service.to_string() && r[st] == tm.subservice.to_string()),
            "TM[{},{}] missing",
            tm.service,
            tm.subservice
        );
    }
    let pcf = set(values(&t, "pcf.dat", "PCF_NAME"));
    for p in PARAMS {
        assert!(pcf.contains(&ScosNames::tm_param(p.id)), "{}", p.name);
    }
    // Calibrated parameters point at a two-point curve reproducing the calibration.
    let curtx = col("pcf", "PCF_CURTX");
    for p in PARAMS.iter().filter(|p| !p.calib.is_identity()) {
        let row = t["pcf.dat"].iter().find(|r| r[0] == ScosNames::tm_param(p.id)).unwrap();
        let points: Vec<(f64, f64)> = t["cap.dat"]
            .iter()
            .filter(|c| c[0] == row[curtx])
            .map(|c| (c[1].parse().unwrap(), c[2].parse().unwrap()))
            .collect();
        assert_eq!(points.len(), 2, "{}", p.name);
        for (x, y) in points {
            assert!((p.calib.eng(x as i64) - y).abs() < 1e-9, "{}", p.name);
        }
    }
    // Every TC, with its type, subtype, APID and arguments; PUS 8 carries the function ID
    // as a fixed element.
    let cdf = &t["cdf.dat"];
    for tc in TCS {
        let name = ScosNames::command(tc);
        let r = t["ccf.dat"]
            .iter()
            .find(|r| r[0] == name)
            .unwrap_or_else(|| panic!("{}", tc.name));
        assert_eq!(r[col("ccf", "CCF_TYPE")], tc.service.to_string());
        assert_eq!(r[col("ccf", "CCF_STYPE")], tc.subservice.to_string());
        assert_eq!(r[col("ccf", "CCF_APID")], apid);
        assert_eq!(r[col("ccf", "CCF_DESCR")], tc.name);
        let els: Vec<&Vec<String>> = cdf.iter().filter(|d| d[0] == name).collect();
        let fixed = usize::from(tc.service == 8);
        assert_eq!(els.len(), tc.args.len() + fixed, "{}", tc.name);
        if tc.service == 8 {
            assert_eq!(els[0][1], "F");
            assert_eq!(els[0][col("cdf", "CDF_VALUE")], tc.function.to_string());
            assert_eq!(els[0][col("cdf", "CDF_PNAME")], ScosNames::FUNCTION);
        }
        for (a, el) in tc.args.iter().zip(&els[fixed..]) {
            assert_eq!(el[1], "E");
            assert_eq!(el[col("cdf", "CDF_ELLEN")], a.ptype.bits().to_string());
            let rng = t["cpc.dat"]
                .iter()
                .find(|c| c[0] == el[col("cdf", "CDF_PNAME")])
                .unwrap()[col("cpc", "CPC_PRFREF")]
            .clone();
            let prv = t["prv.dat"].iter().find(|v| v[0] == rng).unwrap();
            assert_eq!(
                (prv[1].as_str(), prv[2].as_str()),
                (a.min.to_string().as_str(), a.max.to_string().as_str())
            );
        }
    }
    // Other robots differ in APID and SPID only.
    let t2 = export::scos_tables_for(2);
    let pid2 = &t2.iter().find(|(n, _)| *n == "pid.dat").unwrap().1;
    assert!(pid2.lines().all(|l| l.split('\t').nth(2) == Some("258")));
    let pcf2 = &t2.iter().find(|(n, _)| *n == "pcf.dat").unwrap().1;
    assert_eq!(
        pcf2,
        &export::scos_tables()
            .into_iter()
            .find(|(n, _)| *n == "pcf.dat")
            .unwrap()
            .1
    );
}

fn xtce_doc() -> String {
    export::xtce_document()
}

// verifies: ICD-03, ALM-COND-01, ALM-PERSIST-01
#[test]
fn xtce_is_xml_in_the_xtce_1_2_namespace_and_references_resolve() {
    let text = xtce_doc();
    let doc = roxmltree::Document::parse(&text).expect("XTCE parses as XML");
    let root = doc.root_element();
    assert_eq!(root.tag_name().name(), "SpaceSystem");
    assert_eq!(
        root.tag_name().namespace(),
        Some("http://www.omg.org/spec/XTCE/20180204")
    );
    let named = |tag: &str| -> BTreeSet<String> {
        doc.descendants()
            .filter(|n| n.tag_name().name() == tag)
            .filter_map(|n| n.attribute("name").map(str::to_string))
            .collect()
    };
    let params = named("Parameter");
    let containers = named("SequenceContainer");
    let ptypes: BTreeSet<String> = doc
        .descendants()
        .filter(|n| n.tag_name().name().ends_with("ParameterType"))
        .filter_map(|n| n.attribute("name").map(str::to_string))
        .collect();
    let atypes: BTreeSet<String> = doc
        .descendants()
        .filter(|n| n.tag_name().name().ends_with("ArgumentType"))
        .filter_map(|n| n.attribute("name").map(str::to_string))
        .collect();
    for n in doc.descendants() {
        if let Some(r) = n.attribute("parameterTypeRef") {
            assert!(ptypes.contains(r), "type {r}");
        }
        if let Some(r) = n.attribute("argumentTypeRef") {
            assert!(atypes.contains(r), "argument type {r}");
        }
        if let Some(r) = n.attribute("parameterRef") {
            assert!(params.contains(r), "parameter {r}");
        }
        if n.tag_name().name() == "BaseContainer"
            && n.parent().map(|p| p.tag_name().name()) == Some("SequenceContainer")
        {
            assert!(containers.contains(n.attribute("containerRef").unwrap()));
        }
    }
    // Every HK parameter, with its calibrator if it has one.
    for p in PARAMS {
        assert!(params.contains(p.name), "{}", p.name);
        let ty = doc
            .descendants()
            .find(|n| n.attribute("name") == Some(&format!("{}_Type", p.name)))
            .unwrap();
        let poly: Vec<(f64, i32)> = ty
            .descendants()
            .filter(|n| n.tag_name().name() == "Term")
            .map(|n| {
                (
                    n.attribute("coefficient").unwrap().parse().unwrap(),
                    n.attribute("exponent").unwrap().parse().unwrap(),
                )
            })
            .collect();
        if p.calib.is_identity() {
            assert!(poly.is_empty());
        } else {
            assert_eq!(poly, vec![(p.calib.offset, 0), (p.calib.scale, 1)], "{}", p.name);
            assert!(ty
                .descendants()
                .any(|n| n.tag_name().name() == "Unit" && n.text() == Some(p.unit)));
        }
        let enc = ty
            .descendants()
            .find(|n| n.tag_name().name() == "IntegerDataEncoding")
            .unwrap();
        assert_eq!(enc.attribute("sizeInBits"), Some(p.ptype.bits().to_string().as_str()));
    }
    // Every HK structure: a container restricted on service 3 / subservice 25 (through
    // HK_REPORT) and its SID, listing the parameters in order, then the PEC.
    for h in HK_STRUCTS {
        let c = doc
            .descendants()
            .find(|n| {
                n.tag_name().name() == "SequenceContainer" && n.attribute("name") == Some(&format!("HK_{}", h.name))
            })
            .unwrap();
        let entries: Vec<&str> = c
            .descendants()
            .filter(|n| n.tag_name().name() == "ParameterRefEntry")
            .filter_map(|n| n.attribute("parameterRef"))
            .collect();
        let mut want: Vec<&str> = h
            .params
            .iter()
            .map(|id| mib::params::by_id(*id).unwrap().name)
            .collect();
        want.push("PEC");
        assert_eq!(entries, want);
        let base = c
            .descendants()
            .find(|n| n.tag_name().name() == "BaseContainer")
            .unwrap();
        assert_eq!(base.attribute("containerRef"), Some("HK_REPORT"));
        let cmp = base
            .descendants()
            .find(|n| n.tag_name().name() == "Comparison")
            .unwrap();
        assert_eq!(cmp.attribute("parameterRef"), Some("HK_SID"));
        assert_eq!(cmp.attribute("value"), Some(h.sid.to_string().as_str()));
    }
    let hk_report = doc
        .descendants()
        .find(|n| n.attribute("name") == Some("HK_REPORT") && n.tag_name().name() == "SequenceContainer")
        .unwrap();
    let crit: BTreeMap<&str, &str> = hk_report
        .descendants()
        .filter(|n| n.tag_name().name() == "Comparison")
        .map(|n| (n.attribute("parameterRef").unwrap(), n.attribute("value").unwrap()))
        .collect();
    assert_eq!(crit.get("TM_SERVICE"), Some(&"3"));
    assert_eq!(crit.get("TM_SUBSERVICE"), Some(&"25"));
    // Limits that hold only in some robot states: context alarms matching MODE and the
    // MIB's condition parameter, no default alarm; every alarm waits for the persistence.
    let persistence = mib::params::GROUND_LIMIT_PERSISTENCE.to_string();
    for p in PARAMS.iter().filter(|p| p.limits.is_some()) {
        let ty = doc
            .descendants()
            .find(|n| n.attribute("name") == Some(&format!("{}_Type", p.name)))
            .unwrap();
        let default = ty.children().find(|n| n.tag_name().name() == "DefaultAlarm");
        let alarms: Vec<_> = ty
            .descendants()
            .filter(|n| ["DefaultAlarm", "ContextAlarm"].contains(&n.tag_name().name()))
            .collect();
        assert!(!alarms.is_empty(), "{}", p.name);
        for a in &alarms {
            assert_eq!(a.attribute("minViolations"), Some(persistence.as_str()), "{}", p.name);
        }
        let contexts: Vec<(String, String)> = ty
            .descendants()
            .filter(|n| n.tag_name().name() == "ContextAlarm")
            .map(|c| {
                let cmps: Vec<_> = c
                    .descendants()
                    .filter(|n| n.tag_name().name() == "Comparison")
                    .collect();
                assert_eq!(cmps.len(), 1, "{}", p.name);
                let cmp = cmps[0];
                assert_eq!(cmp.attribute("useCalibratedValue"), Some("false"));
                assert_eq!(cmp.attribute("comparisonOperator"), Some("=="));
                (
                    cmp.attribute("parameterRef").unwrap().to_string(),
                    cmp.attribute("value").unwrap().to_string(),
                )
            })
            .collect();
        let want = want_states(p, |id| mib::params::by_id(id).unwrap().name.to_string());
        if want == [(String::new(), String::new())] {
            assert!(default.is_some() && contexts.is_empty(), "{}", p.name);
        } else {
            assert!(default.is_none(), "{}", p.name);
            assert_eq!(contexts, want, "{}", p.name);
        }
    }
    for e in EVENTS {
        assert!(containers.contains(&format!("EVT_{}", e.name)));
    }
    // Every TC as a MetaCommand with its arguments and valid ranges.
    for tc in TCS {
        let mc = doc
            .descendants()
            .find(|n| n.tag_name().name() == "MetaCommand" && n.attribute("name") == Some(tc.name))
            .unwrap_or_else(|| panic!("{}", tc.name));
        let args: Vec<&str> = mc
            .descendants()
            .filter(|n| n.tag_name().name() == "Argument")
            .filter_map(|n| n.attribute("name"))
            .collect();
        assert_eq!(args, tc.args.iter().map(|a| a.name).collect::<Vec<_>>());
        for a in tc.args {
            let ty = doc
                .descendants()
                .find(|n| n.attribute("name") == Some(&format!("{}_{}_Type", tc.name, a.name)))
                .unwrap();
            if a.names.is_none() {
                let r = ty.descendants().find(|n| n.tag_name().name() == "ValidRange").unwrap();
                assert_eq!(r.attribute("minInclusive"), Some(a.min.to_string().as_str()));
                assert_eq!(r.attribute("maxInclusive"), Some(a.max.to_string().as_str()));
            } else {
                // An enumerated argument: its named values within its range.
                assert_eq!(ty.tag_name().name(), "EnumeratedArgumentType", "{} {}", tc.name, a.name);
                let values: Vec<(i64, &str)> = ty
                    .descendants()
                    .filter(|n| n.tag_name().name() == "Enumeration")
                    .map(|n| {
                        (
                            n.attribute("value").unwrap().parse().unwrap(),
                            n.attribute("label").unwrap(),
                        )
                    })
                    .collect();
                let mut want = Vec::new();
                a.names.for_each(|v, n| {
                    if (a.min..=a.max).contains(&v) {
                        want.push((v, n));
                    }
                });
                assert_eq!(values, want, "{} {}", tc.name, a.name);
            }
        }
        // A hazardous TC is critical.
        let sig = mc
            .children()
            .find(|n| n.tag_name().name() == "DefaultSignificance")
            .map(|n| (n.attribute("consequenceLevel"), n.attribute("reasonForWarning")));
        assert_eq!(sig, tc.hazard.map(|h| (Some("critical"), Some(h))), "{}", tc.name);
        let fixed = mc.descendants().find(|n| n.tag_name().name() == "FixedValueEntry");
        if tc.service == 8 {
            assert_eq!(
                fixed.and_then(|f| f.attribute("binaryValue")),
                Some(format!("{:04X}", tc.function).as_str())
            );
        } else {
            assert!(fixed.is_none());
        }
    }
}

// verifies: ICD-04, ALM-COND-01
#[test]
fn json_round_trips_against_the_tables() {
    let text = export::json_document();
    let v: serde_json::Value = serde_json::from_str(&text).expect("JSON parses");
    let ids = |key: &str, field: &str| -> Vec<i64> {
        v[key]
            .as_array()
            .unwrap()
            .iter()
            .map(|x| x[field].as_i64().unwrap())
            .collect()
    };
    assert_eq!(
        ids("parameters", "id"),
        PARAMS.iter().map(|p| p.id as i64).collect::<Vec<_>>()
    );
    assert_eq!(
        ids("hk_structures", "sid"),
        HK_STRUCTS.iter().map(|h| h.sid as i64).collect::<Vec<_>>()
    );
    assert_eq!(
        ids("events", "id"),
        EVENTS.iter().map(|e| e.id as i64).collect::<Vec<_>>()
    );
    assert_eq!(
        ids("failure_codes", "code"),
        mib::FailureCode::ALL
            .iter()
            .map(|c| c.code() as i64)
            .collect::<Vec<_>>()
    );
    assert_eq!(v["telecommands"].as_array().unwrap().len(), TCS.len());
    for (j, t) in v["telecommands"].as_array().unwrap().iter().zip(TCS) {
        assert_eq!(j["name"], t.name);
        assert_eq!(j["service"], t.service);
        assert_eq!(j["subservice"], t.subservice);
        assert_eq!(j["function"], t.function);
        assert_eq!(j["args"].as_array().unwrap().len(), t.args.len());
        assert_eq!(j["hazard"].as_str(), t.hazard, "{}", t.name);
        for (ja, a) in j["args"].as_array().unwrap().iter().zip(t.args) {
            assert_eq!(ja["names"].is_null(), a.names.is_none(), "{} {}", t.name, a.name);
        }
    }
    let v_reg = v["parameters"]
        .as_array()
        .unwrap()
        .iter()
        .find(|p| p["name"] == "V_REG")
        .unwrap();
    assert_eq!(v_reg["limits_in"], "operational, safed");
    assert_eq!(v_reg["limits_if"], serde_json::Value::Null);
    let hip = v["parameters"]
        .as_array()
        .unwrap()
        .iter()
        .find(|p| p["name"] == "HIP_DEVIATION")
        .unwrap();
    assert_eq!(hip["limits_if"]["param_name"], "ACTIVE_PRIMITIVE");
    assert_eq!(hip["limits_if"]["raw"], 0);
    assert_eq!(hip["limit_persistence"], mib::params::GROUND_LIMIT_PERSISTENCE);
    assert_eq!(v["telemetry"].as_array().unwrap().len(), TMS.len());
    assert_eq!(ids("states", "id").len(), mib::robot::NUM_STATES);
    assert_eq!(ids("primitives", "id").len(), mib::robot::NUM_PRIMITIVES);
    assert_eq!(
        ids("tunables", "id"),
        mib::tunables::TUNABLES.iter().map(|t| t.id as i64).collect::<Vec<_>>()
    );
    assert_eq!(
        v["mode_tree"]["nodes"].as_array().unwrap().len(),
        mib::modes::NODES.len()
    );
    assert_eq!(
        v["fdir"]["monitors"].as_array().unwrap().len(),
        mib::fdir::MONITORS.len()
    );
    assert_eq!(v["fdir"]["faults"].as_array().unwrap().len(), mib::fdir::FAULTS.len());
    let map: Vec<Vec<u8>> = serde_json::from_value(v["reconfig_map"].clone()).unwrap();
    assert_eq!(
        map,
        mib::robot::RECONFIG_MAP.iter().map(|r| r.to_vec()).collect::<Vec<_>>()
    );
    let p = &v["parameters"][0];
    assert_eq!(p["calibration"]["scale"].as_f64(), Some(PARAMS[0].calib.scale));
    assert_eq!(v["packet_layout"]["tm_source_data_offset"], 20);
    // The configuration by the side it binds: flight, ground, host.
    let config = v["config"].as_object().unwrap();
    assert_eq!(config.keys().collect::<Vec<_>>(), ["flight", "ground", "host"]);
    assert_eq!(
        v["config"]["flight"]["control_period_ms"],
        mib::config::CONTROL_PERIOD_MS
    );
    assert_eq!(
        v["config"]["ground"]["ground_ack_timeout_ms"],
        mib::ground_config::GROUND_ACK_TIMEOUT_MS
    );
    assert_eq!(v["config"]["host"]["default_port"], mib::host_config::DEFAULT_PORT);
}

// verifies: ICD-04
#[test]
fn write_all_writes_each_format_into_the_directory() {
    let dir = std::path::PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("export-write-all");
    let _ = std::fs::remove_dir_all(&dir);
    let scos = export::write_all(Format::Scos, &dir).unwrap();
    assert_eq!(scos.len(), COLUMNS.len());
    for (p, (name, content)) in scos.iter().zip(export::scos_tables()) {
        assert_eq!(p.file_name().unwrap().to_str(), Some(name));
        assert_eq!(std::fs::read_to_string(p).unwrap(), content);
    }
    let x = export::write_all("xtce".parse().unwrap(), &dir).unwrap();
    assert_eq!(x.len(), 1);
    assert_eq!(std::fs::read_to_string(&x[0]).unwrap(), export::xtce_document());
    let j = export::write_all(Format::Json, &dir).unwrap();
    assert_eq!(std::fs::read_to_string(&j[0]).unwrap(), export::json_document());
    // A file where the directory should be is an error, not a panic.
    let blocker = dir.join("blocker");
    std::fs::write(&blocker, b"x").unwrap();
    assert!(export::write_all(Format::Json, &blocker.join("sub")).is_err());
}

/// Names of the public numeric constants declared in the MIB's sources (`pub const NAME:
/// u32 = …` and the other number types), read line by line — independently of the build
/// script's parse — up to each file's tests.
fn declared_constants() -> Vec<String> {
    fn walk(dir: &std::path::Path, out: &mut Vec<std::path::PathBuf>) {
        for e in std::fs::read_dir(dir).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                walk(&p, out);
            } else if p.extension().is_some_and(|x| x == "rs") {
                out.push(p);
            }
        }
    }
    let mut files = Vec::new();
    walk(
        &std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../src"),
        &mut files,
    );
    let types = [
        "u8", "u16", "u32", "u64", "usize", "i8", "i16", "i32", "i64", "f32", "f64",
    ];
    let mut names = Vec::new();
    for f in files {
        let text = std::fs::read_to_string(&f).unwrap();
        for line in text.lines().take_while(|l| l.trim() != "#[cfg(test)]") {
            let Some(rest) = line.trim_start().strip_prefix("pub const ") else {
                continue;
            };
            let Some((name, rest)) = rest.split_once(':') else {
                continue;
            };
            let ty = rest
                .trim_start()
                .split(|c: char| !c.is_ascii_alphanumeric())
                .next()
                .unwrap_or("");
            if types.contains(&ty)
                && name
                    .chars()
                    .all(|c| c.is_ascii_uppercase() || c.is_ascii_digit() || c == '_')
            {
                names.push(name.to_string());
            }
        }
    }
    names.sort();
    names
}

// verifies: ICD-07
#[test]
fn json_carries_every_number_the_mib_declares() {
    let v: serde_json::Value = serde_json::from_str(&export::json_document()).unwrap();
    let constants = v["constants"].as_object().expect("a constants section");
    let mut exported: Vec<String> = constants
        .values()
        .flat_map(|m| m.as_object().unwrap().keys())
        .map(|k| k.rsplit("::").next().unwrap_or(k).to_string()) // `SeqCount::MASK`
        .collect();
    exported.sort();
    assert_eq!(exported, declared_constants());
    assert!(exported.len() > 300, "{}", exported.len());
    let c = |module: &str, name: &str| constants[module][name]["value"].clone();
    assert_eq!(c("team", "GROUND_LOSS_TIMEOUT_MS"), mib::team::GROUND_LOSS_TIMEOUT_MS);
    assert_eq!(c("config", "CONTROL_PERIOD_MS"), mib::config::CONTROL_PERIOD_MS);
    assert!(c("link::sdls", "TC_SPIS").is_null(), "arrays are not numbers");
    assert_eq!(c("modules::geometry", "PITCH_M"), mib::modules::geometry::PITCH_M);
    assert_eq!(c("headers", "SeqCount::MODULUS"), mib::headers::SeqCount::MODULUS);
    let desc = constants["team"]["GROUND_LOSS_TIMEOUT_MS"]["desc"].as_str().unwrap();
    assert!(desc.starts_with("The ground is declared lost"), "{desc}");
}
