use super::*;
use mib::robot::{self, NUM_STATES};

const GOOD: &str = r#"
name = "t"
[[robot]]
number = 1
initial_state = "Xneg"
[[robot]]
number = 2
initial_state = "Xpos"

[[step]]
id = "op1"
robot = 1
action = "mode"
mode = "operational"

[[step]]
id = "op2"
robot = 2
action = "mode"
mode = 1

[[step]]
id = "r1"
robot = 1
action = "reconfigure"
to = "Xpos Xneg"

[[step]]
id = "b2"
robot = 2
action = "bolt"
side = "A"
pairs = "all"
after = ["r1"]

[[step]]
id = "w"
robot = 2
action = "wait"
seconds = 0.5

[[step]]
id = "hk"
robot = 2
action = "command"
tc = "HK_SET_INTERVAL"
args = { sid = 1, interval_ms = 100 }
"#;

// verifies: GND-04
#[test]
fn valid_plan_parses_with_implicit_and_explicit_dependencies() {
    let p = parse(GOOD).unwrap();
    assert_eq!(p.steps.len(), 6);
    let r1 = p.step_index("r1").unwrap();
    assert_eq!(p.steps[r1].action, Action::Reconfigure { from: 0, to: 4 });
    let b2 = p.step_index("b2").unwrap();
    let op2 = p.step_index("op2").unwrap();
    assert_eq!(p.steps[b2].deps, vec![r1, op2]);
    assert_eq!(p.steps[b2].action, Action::Bolt { side: 0, pairs: 15 });
    assert_eq!(p.dependents(r1), vec![b2, b2 + 1, b2 + 2]);
    let enc = encode(&p).unwrap();
    assert_eq!(enc.iter().filter(|e| e.tc.is_some()).count(), 5);
    let hk = enc[5].tc.as_ref().unwrap();
    assert_eq!((hk.apid, hk.seq), (0x102, 2));
}

fn errors(src: &str) -> Vec<Diagnostic> {
    diagnostics("p.toml", src, &parse(src).unwrap_err())
}

/// Asserts that one of `text` is at `at` (`file:line:column`) and says `message`.
fn assert_error_at(text: &[String], at: &str, message: &str) {
    assert!(
        text.iter().any(|t| t.contains(at) && t.contains(message)),
        "{at}: {message:?} not in {text:#?}"
    );
}

/// The errors of `src` as the operator reads them.
fn texts(src: &str) -> Vec<String> {
    errors(src).iter().map(|x| x.to_string()).collect()
}

// verifies: GND-03
#[test]
fn every_error_is_reported_with_line_and_column() {
    let src = r#"[[robot]]
number = 1
initial_state = "Xneg"
[[step]]
id = "a"
robot = 3
action = "fly"
[[step]]
id = "b"
robot = 1
action = "bolt"
side = "C"
pairs = [1, 5]
after = ["nope"]
[[step]]
id = "b"
robot = 1
action = "reconfigure"
from = "Yneg"
to = "Xpos"
colour = "red"
"#;
    let d = errors(src);
    let text: Vec<String> = d.iter().map(|x| x.to_string()).collect();
    let has = |needle: &str| {
        assert!(
            text.iter().any(|t| t.contains(needle)),
            "missing {needle:?} in {text:#?}"
        )
    };
    has("p.toml:6:9: error: robot 3 is not declared");
    has("p.toml:7:10: error: unknown action \"fly\"");
    has("p.toml:12:8: error: `side`: \"C\" is not A or B");
    has("p.toml:13:13: error: `pair` = 5 is outside 1..=4");
    has("p.toml:14:10: error: `after`: no step with id \"nope\"");
    has("step id \"b\" used twice");
    has("p.toml:21:1: error: unknown key `colour`");
    has("p.toml:18:10: error: step \"b\": RECONFIGURE is not accepted in STANDBY mode");
    has("p.toml:19:8: error: step \"b\": from-state Yneg differs from robot 1's state Xneg");
    assert!(d.len() >= 9, "{text:#?}");
}

// verifies: GND-04
#[test]
fn from_state_must_match_previous_to_state_and_be_reachable() {
    let src = r#"[[robot]]
number = 1
initial_state = "Xneg"
[[step]]
id = "m"
robot = 1
action = "mode"
mode = "operational"
[[step]]
id = "a"
robot = 1
action = "reconfigure"
to = "Xpos"
[[step]]
id = "b"
robot = 1
action = "reconfigure"
from = "Yneg"
to = "Xneg"
"#;
    let text = texts(src);
    assert_error_at(
        &text,
        "p.toml:18:8",
        "from-state Yneg differs from robot 1's state Xpos",
    );
}

// verifies: GND-04
#[test]
fn unreachable_reconfiguration_is_an_error() {
    // Find a pair of states more than 3 primitives apart, if the map has one.
    let far = (0..NUM_STATES as u8)
        .flat_map(|a| (0..NUM_STATES as u8).map(move |b| (a, b)))
        .find(|&(a, b)| a != b && reconfig_path(a, b).is_none());
    let Some((a, b)) = far else {
        // Every pair is reachable within 3: check the BFS finds short paths instead.
        assert!(reconfig_path(0, 1).unwrap().len() <= 3);
        return;
    };
    let src = format!(
        "[[robot]]\nnumber = 1\n[[step]]\nid = \"m\"\nrobot = 1\naction = \"mode\"\nmode = \"operational\"\n[[step]]\nid = \"r\"\nrobot = 1\naction = \"reconfigure\"\nfrom = {a}\nto = {b}\n"
    );
    let text = texts(&src);
    assert!(text.iter().any(|t| t.contains("is not reachable")), "{text:#?}");
}

// verifies: GND-04
#[test]
fn bfs_follows_the_reconfiguration_map() {
    // Xneg -> Xpos: extend one side, contract the other (two primitives).
    let p = reconfig_path(0, 1).unwrap();
    assert_eq!(p.len(), 2);
    assert_eq!(reconfig_path(0, 0), Some(vec![]));
    assert_eq!(reconfig_path(0, 99), None);
    for a in 0..NUM_STATES as u8 {
        for b in 0..NUM_STATES as u8 {
            if let Some(p) = reconfig_path(a, b) {
                let mut s = a;
                for prim in &p {
                    s = robot::apply(s, *prim).unwrap();
                }
                assert_eq!(s, b);
                assert!(p.len() <= mib::config::MAX_RECONFIG_PRIMITIVES);
            }
        }
    }
}

// verifies: GND-04
#[test]
fn dependency_cycle_is_reported() {
    let src = r#"[[robot]]
number = 1
[[robot]]
number = 2
[[step]]
id = "x"
robot = 1
action = "wait"
seconds = 1
after = ["y"]
[[step]]
id = "y"
robot = 2
action = "wait"
seconds = 1
after = ["x"]
"#;
    let text = texts(src);
    assert!(text.iter().any(|t| t.contains("dependency cycle")), "{text:#?}");
}

// verifies: GND-03
#[test]
fn syntax_errors_and_bad_command_args_are_located() {
    let d = errors("[[robot]\nnumber = 1\n");
    assert_eq!(d[0].line, 1);
    let src = r#"[[robot]]
number = 1
[[step]]
id = "c"
robot = 1
action = "command"
tc = "HK_SET_INTERVAL"
args = { sid = 1, interval_ms = 1, bogus = 2 }
"#;
    let text = texts(src);
    // The same reader and words as `ground send` (ops::policy), at the value's place.
    assert_error_at(&text, "p.toml:8:33", "interval_ms = 1 outside 10..=3600000");
    assert_error_at(&text, "p.toml:8:36", "has no argument \"bogus\"");
}

// verifies: GND-03
#[test]
fn line_col_counts_characters() {
    assert_eq!(line_col("ab\ncd", 4), (2, 2));
    assert_eq!(line_col("ä\nx", 3), (2, 1));
}
