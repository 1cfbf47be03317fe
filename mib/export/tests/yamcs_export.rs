//! Static checks of the generated Yamcs instance (the running Yamcs is checked by
//! tests/tests/yamcs_e2e.rs): the MDB's references resolve, commands carry the MIB's
//! acknowledgement flags and no header field as an operator argument, every event has a
//! template over its own parameters, the ID fields are enumerations of the MIB's values,
//! and mode fields are named per node kind.

use std::collections::BTreeSet;

use mib::events::EVENTS;
use mib::hk::HK_STRUCTS;
use mib::tc::TCS;
use mib_export::xtce_document_for;
use mib_export::yamcs::{events_json, yamcs_instance, yamcs_xtce, YamcsSetup, MODULE_MODES};

fn is(n: &roxmltree::Node, tag: &str) -> bool {
    n.is_element() && n.tag_name().name() == tag
}

/// Qualified names of every parameter of a document (`/SS/.../NAME`).
fn parameters(doc: &roxmltree::Document) -> BTreeSet<String> {
    doc.descendants()
        .filter(|n| is(n, "Parameter"))
        .map(|p| {
            let mut path: Vec<&str> = p
                .ancestors()
                .filter(|a| is(a, "SpaceSystem"))
                .filter_map(|a| a.attribute("name"))
                .collect();
            path.reverse();
            format!("/{}/{}", path.join("/"), p.attribute("name").unwrap())
        })
        .collect()
}

// verifies: YAMCS-XTCE-01, YAMCS-CMD-01
#[test]
fn mdb_references_resolve_and_commands_hide_header_fields() {
    for robot in [1u8, 7, 254] {
        let text = yamcs_xtce(robot);
        let doc = roxmltree::Document::parse(&text).unwrap();
        let root = format!("/MMIC_I_ROBOT_{robot}");
        let params = parameters(&doc);
        let resolve = |r: &str| {
            if r.starts_with('/') {
                r.to_string()
            } else {
                format!("{root}/{r}")
            }
        };
        let mut refs = 0;
        for n in doc.descendants().filter(|n| n.is_element()) {
            for attr in ["parameterRef"] {
                if let Some(r) = n.attribute(attr) {
                    if r.starts_with("/yamcs/") {
                        continue;
                    }
                    assert!(params.contains(&resolve(r)), "robot {robot}: {r} is not a parameter");
                    refs += 1;
                }
            }
        }
        assert!(refs > 1000, "{refs} references checked");
        // The generic XTCE's parameters are all there, with the same names.
        let generic_text = xtce_document_for(robot);
        let generic = roxmltree::Document::parse(&generic_text).unwrap();
        let ours = parameters(&generic);
        assert!(
            ours.is_subset(&params),
            "Yamcs MDB lacks {:?}",
            ours.difference(&params)
        );

        let cmds: Vec<_> = doc.descendants().filter(|n| is(n, "MetaCommand")).collect();
        let base = cmds.iter().find(|c| c.attribute("name") == Some("PUS_TC")).unwrap();
        let fixed: BTreeSet<&str> = base
            .descendants()
            .filter(|n| is(n, "FixedValueEntry"))
            .filter_map(|n| n.attribute("name"))
            .collect();
        assert!(fixed.contains("SRC_SEQ_CTR") && fixed.contains("PKT_LEN"), "{fixed:?}");
        let verifiers: Vec<_> = base
            .descendants()
            .filter(|n| n.is_element() && n.tag_name().name().ends_with("Verifier"))
            .filter_map(|n| n.attribute("name"))
            .collect();
        assert_eq!(verifiers, ["Acceptance", "Start", "Completion"]);
        for t in TCS {
            let c = cmds
                .iter()
                .find(|c| c.attribute("name") == Some(t.name))
                .unwrap_or_else(|| panic!("{} missing", t.name));
            let assigned = |arg: &str| {
                c.descendants()
                    .find(|n| is(n, "ArgumentAssignment") && n.attribute("argumentName") == Some(arg))
                    .and_then(|n| n.attribute("argumentValue"))
                    .map(str::to_string)
            };
            assert_eq!(assigned("TC_ACK_FLAGS"), Some(t.ack_flags().to_string()), "{}", t.name);
            assert_eq!(assigned("PKT_APID"), Some((0x100 + robot as u16).to_string()));
            // The operator's arguments are the MIB's arguments, nothing else.
            let args: Vec<&str> = c
                .descendants()
                .filter(|n| is(n, "Argument"))
                .filter_map(|n| n.attribute("name"))
                .collect();
            let mib_args: Vec<&str> = t.args.iter().map(|a| a.name).collect();
            assert_eq!(args, mib_args, "{}", t.name);
        }
    }
}

// verifies: YAMCS-EVT-01
#[test]
fn ids_are_enumerated_and_every_event_has_a_template_over_its_parameters() {
    let text = yamcs_xtce(1);
    let doc = roxmltree::Document::parse(&text).unwrap();
    let labels = |tname: &str| -> BTreeSet<(i64, String)> {
        let t = doc
            .descendants()
            .find(|n| is(n, "EnumeratedParameterType") && n.attribute("name") == Some(tname))
            .unwrap_or_else(|| panic!("{tname} is not enumerated"));
        t.descendants()
            .filter(|n| is(n, "Enumeration"))
            .map(|e| {
                (
                    e.attribute("value").unwrap().parse().unwrap(),
                    e.attribute("label").unwrap().to_string(),
                )
            })
            .collect()
    };
    let ev = labels("EVENT_ID_Type");
    for e in EVENTS {
        assert!(ev.contains(&(e.id as i64, e.name.to_string())), "{}", e.name);
    }
    let sids = labels("HK_SID_Type");
    for h in HK_STRUCTS {
        assert!(sids.contains(&(h.sid as i64, h.name.to_string())), "{}", h.name);
    }

    let templates: serde_json::Value = serde_json::from_str(&events_json(&[1, 3])).unwrap();
    let list = templates.as_array().unwrap();
    assert_eq!(list.len(), 2 * EVENTS.len());
    for (robot, e) in [1u8, 3].into_iter().flat_map(|r| EVENTS.iter().map(move |e| (r, e))) {
        let key = format!("{}-{}", e.name, 0x100 + robot as u16);
        let t = list
            .iter()
            .find(|t| t["eventId"] == key.as_str())
            .unwrap_or_else(|| panic!("no template for {key}"));
        let text = t["template"].as_str().unwrap();
        assert!(text.starts_with(&format!("robot {robot}: ")), "{text}");
        let refs: Vec<&str> = text.split('{').skip(1).filter_map(|s| s.split('}').next()).collect();
        assert_eq!(refs.len(), e.params.len(), "{text}");
        for (r, p) in refs.iter().zip(e.params) {
            assert_eq!(*r, mib_export::yamcs::event_param(e, p.name), "{}", e.name);
        }
    }
}

// verifies: YAMCS-EVT-01
#[test]
fn mode_fields_of_events_and_mode_reports_are_named_per_node_kind() {
    let text = yamcs_xtce(1);
    let doc = roxmltree::Document::parse(&text).unwrap();
    let module_ss = doc
        .descendants()
        .find(|n| is(n, "SpaceSystem") && n.attribute("name") == Some(MODULE_MODES))
        .expect("module-mode space system");
    let names_in = |scope: roxmltree::Node, tname: &str| -> Vec<String> {
        scope
            .descendants()
            .find(|n| is(n, "EnumeratedParameterType") && n.attribute("name") == Some(tname))
            .unwrap_or_else(|| panic!("{tname}"))
            .descendants()
            .filter(|n| is(n, "Enumeration"))
            .map(|e| e.attribute("label").unwrap().to_string())
            .collect()
    };
    let mut split = 0;
    let tm_modes = mib::tc::TMS
        .iter()
        .filter(|t| t.service == 200)
        .map(|t| (t.name, "mode"))
        .collect::<Vec<_>>();
    assert_eq!(tm_modes.len(), 2, "MODE_REPLY and MODE_CANT_REACH");
    let event_modes = EVENTS.iter().flat_map(|e| {
        e.params
            .iter()
            .filter(|p| p.names == mib::layout::Names::Mode)
            .map(move |p| (e.name, p.name))
    });
    for (owner, field) in event_modes.chain(tm_modes) {
        let t = format!("{owner}_{field}_Type");
        let robot: Vec<String> = names_in(doc.root_element(), &t);
        let module: Vec<String> = names_in(module_ss, &t);
        let kind_names = |k| {
            (0..8)
                .filter_map(|m| mib::modes::mode_name(k, m).map(str::to_string))
                .collect::<Vec<_>>()
        };
        assert_eq!(robot, kind_names(mib::modes::NodeKind::Root), "{t}");
        assert_eq!(module, kind_names(mib::modes::NodeKind::Arm), "{t}");
        split += 1;
    }
    assert!(split >= 3, "{split} mode fields");
    // Every event container with mode fields has a robot and a module child.
    let instance = yamcs_instance(&YamcsSetup::for_robots("1".parse().unwrap()));
    assert!(instance
        .iter()
        .any(|(p, c)| p.ends_with(".xml") && c.contains("EVT_MODE_CHANGED_MODULE")));
}
