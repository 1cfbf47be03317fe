//! One command policy on every CLI path: a hazardous TC is refused
//! without explicit confirmation, before anything is sent; names are read by one
//! function with a "did you mean".

use std::net::UdpSocket;
use std::time::Duration;

mod common;
use common::{ground, text, tmpdir, Obsw};

/// A UDP socket standing in for a robot: counts what reaches it.
fn listener() -> (UdpSocket, String) {
    let s = UdpSocket::bind("127.0.0.1:0").unwrap();
    s.set_read_timeout(Some(Duration::from_millis(300))).unwrap();
    let a = format!("1={}", s.local_addr().unwrap());
    (s, a)
}

fn received(s: &UdpSocket) -> usize {
    let mut buf = [0u8; 2048];
    let mut n = 0;
    while s.recv(&mut buf).is_ok() {
        n += 1;
    }
    n
}

// verifies: OPS-POLICY-01
#[test]
fn a_hazardous_tc_is_refused_without_confirmation_on_the_command_line() {
    let dir = tmpdir("ops", "hazard-cli");
    let (sock, r) = listener();
    for args in [
        vec!["send", "--lab-udp", "--robot", &r, "UNBOLT_FACE", "side=A", "pairs=15"],
        vec!["send", "--lab-udp", "--robot", &r, "STORE_DELETE"],
        vec!["mode", "--lab-udp", "--robot", &r, "standby"],
    ] {
        let mut a = vec!["--no-archive"];
        a.extend(args);
        let out = ground(&dir, &a);
        let t = text(&out);
        assert_eq!(out.status.code(), Some(3), "{a:?}: {t}");
        assert!(
            t.contains("is hazardous (") && t.contains("refused without confirmation (add --confirm)"),
            "{a:?}: {t}"
        );
    }
    assert_eq!(received(&sock), 0, "nothing was sent");
    // Confirmed, it goes out: the obsw refuses it in STANDBY, so it was sent and judged.
    let o = Obsw::start(1, &["--speed", "20"]);
    let r = format!("1={}", o.addr);
    let out = ground(
        &dir,
        &[
            "--no-archive",
            "send",
            "--lab-udp",
            "--robot",
            &r,
            "UNBOLT_FACE",
            "side=A",
            "pairs=15",
            "--confirm",
        ],
    );
    assert_eq!(out.status.code(), Some(4), "{}", text(&out));
    assert!(text(&out).contains("NOT_ALLOWED_IN_MODE"), "{}", text(&out));
}

// verifies: OPS-POLICY-01
#[test]
fn a_hazardous_plan_step_is_refused_without_confirm() {
    let dir = tmpdir("ops", "hazard-plan");
    let plan = dir.join("p.toml");
    std::fs::write(
        &plan,
        r#"name = "p"
[[robot]]
number = 1
[[step]]
id = "op"
robot = 1
action = "mode"
mode = "operational"
[[step]]
id = "unbolt"
robot = 1
action = "unbolt"
side = "A"
pairs = [1]
confirm = false
"#,
    )
    .unwrap();
    let (sock, r) = listener();
    let out = ground(
        &dir,
        &["--no-archive", "run", "--lab-udp", "p.toml", "--plain", "--robot", &r],
    );
    let t = text(&out);
    assert_eq!(out.status.code(), Some(3), "{t}");
    assert!(t.contains("step \"op\": MODE_SET is hazardous"), "{t}");
    assert!(t.contains("step \"unbolt\": UNBOLT_FACE is hazardous"), "{t}");
    assert!(t.contains("add `confirm = true` to the step"), "{t}");
    assert_eq!(received(&sock), 0, "nothing was sent");
    let out = ground(&dir, &["plan", "check", "p.toml"]);
    let t = text(&out);
    assert_eq!(out.status.code(), Some(3), "{t}");
    assert!(
        t.contains("p.toml:4:1: error: step \"op\": MODE_SET is hazardous"),
        "{t}"
    );
    assert!(t.contains("p.toml: 2 error(s)"), "{t}");
}

// verifies: OPS-POLICY-02
#[test]
fn mistyped_names_get_a_suggestion_on_the_command_line_and_in_plans() {
    let dir = tmpdir("ops", "did-you-mean");
    let (_sock, r) = listener();
    for (args, says) in [
        (
            vec!["send", "--lab-udp", "--robot", &r, "BOLT_FCE", "side=A"],
            "did you mean BOLT_FACE?",
        ),
        (
            vec![
                "send",
                "--lab-udp",
                "--robot",
                &r,
                "RECONFIGURE",
                "form=Xneg",
                "to=Xpos",
            ],
            "did you mean from?",
        ),
        (
            vec![
                "send",
                "--lab-udp",
                "--robot",
                &r,
                "RECONFIGURE",
                "from=Xnge",
                "to=Xpos",
            ],
            "did you mean Xneg?",
        ),
    ] {
        let mut a = vec!["--no-archive"];
        a.extend(args);
        let out = ground(&dir, &a);
        assert_eq!(out.status.code(), Some(3), "{a:?}: {}", text(&out));
        assert!(text(&out).contains(says), "{a:?}: {}", text(&out));
    }
    std::fs::write(
        dir.join("p.toml"),
        r#"name = "p"
[[robot]]
number = 1
[[step]]
id = "a"
robot = 1
action = "command"
tc = "HK_SET_INTERVL"
[[step]]
id = "b"
robot = 1
action = "command"
tc = "HK_SET_INTERVAL"
args = { sid = 1, interval = 100 }
[[step]]
id = "c"
robot = 1
action = "command"
tc = "HK_SET_INTERVAL"
args = { sid = 1, interval_ms = "fast" }
"#,
    )
    .unwrap();
    let out = ground(&dir, &["plan", "check", "p.toml"]);
    let t = text(&out);
    assert_eq!(out.status.code(), Some(3), "{t}");
    assert!(t.contains("did you mean HK_SET_INTERVAL?"), "{t}");
    assert!(t.contains("did you mean interval_ms?"), "{t}");
    assert!(t.contains("interval_ms = \"fast\": not a number"), "{t}");
}
