//! Output that tells the truth ("a clean link looks clean"):
//! `demo` on loopback, a closed pipe on every verb that prints, `sim`'s replies.

use std::path::Path;
use std::process::{Command, Stdio};

mod common;
use common::{ground, obsw_bin, text, tmpdir, Obsw, GROUND};

// verifies: OPS-LINK-01
#[test]
fn demo_on_loopback_has_no_resends_full_link_quality_and_leaves_no_temp_folder() {
    let dir = tmpdir("ops", "demo");
    let tmp = dir.join("tmp");
    std::fs::create_dir_all(&tmp).unwrap();
    let out = Command::new(GROUND)
        .current_dir(&dir)
        .env("TMPDIR", &tmp)
        .args(["demo", "--plain", "--obsw", obsw_bin().to_str().unwrap()])
        .output()
        .unwrap();
    let t = text(&out);
    assert_eq!(out.status.code(), Some(0), "{t}");
    let links: Vec<&str> = t.lines().filter(|l| l.starts_with("link robot ")).collect();
    assert_eq!(links.len(), 2, "{t}");
    for l in links {
        assert!(l.contains("quality 100% over"), "{l}\n{t}");
        assert!(l.ends_with(" 0 resends"), "{l}\n{t}");
    }
    assert!(!t.contains("resend "), "no resend at all: {t}");
    let left: Vec<_> = std::fs::read_dir(&tmp).unwrap().collect();
    assert!(left.is_empty(), "left behind: {left:?}");
}

// verifies: OPS-DEMO-PORTS-01
#[test]
fn demo_over_each_lab_link_talks_to_the_port_its_obsw_reported() {
    // The obsws bind port 0 for --udp and --tcp (two different ports): the demo finds the
    // robots only at the port its link's READY field names.
    for lab in ["--lab-udp", "--lab-tcp"] {
        let dir = tmpdir("ops", &format!("demo{lab}"));
        let out = ground(
            &dir,
            &[
                "--no-archive",
                "demo",
                lab,
                "--plain",
                "--obsw",
                obsw_bin().to_str().unwrap(),
            ],
        );
        let t = text(&out);
        assert_eq!(out.status.code(), Some(0), "{lab}: {t}");
        assert!(t.contains("10 of 10 steps done"), "{lab}: {t}");
        for r in [1, 2] {
            assert!(
                t.contains(&format!("demo: robot {r} OBSW, bare-packet port at 127.0.0.1:")),
                "{lab}: {t}"
            );
        }
    }
}

/// Runs `ground args` in `dir` with its standard output closed by the reader before it
/// writes anything; returns the exit code and stderr.
fn closed_pipe(dir: &Path, args: &[&str]) -> (Option<i32>, String) {
    let mut child = Command::new(GROUND)
        .current_dir(dir)
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stdout.take());
    let out = child.wait_with_output().unwrap();
    (out.status.code(), String::from_utf8_lossy(&out.stderr).to_string())
}

// verifies: OPS-OUT-01
#[test]
fn a_closed_pipe_is_a_quiet_exit_0_on_every_verb_that_prints() {
    let dir = tmpdir("ops", "pipe");
    let o = Obsw::start(1, &["--speed", "20", "--initial-state", "Xneg"]);
    let r = format!("1={}", o.addr);
    let plans = Path::new(env!("CARGO_MANIFEST_DIR")).join("../plans");
    let demo = plans.join("demo.toml");
    let demo = demo.to_str().unwrap();
    std::fs::write(
        dir.join("one.toml"),
        "name = \"one\"\n[[robot]]\nnumber = 1\n[[step]]\nid = \"p\"\nrobot = 1\naction = \"command\"\ntc = \"PING\"\n",
    )
    .unwrap();
    // An archive with TC, TM, verification, HK and events in it.
    let out = ground(
        &dir,
        &["ping", "--lab-udp", "--robot", &r, "-c", "3", "--interval", "0.5"],
    );
    assert_eq!(out.status.code(), Some(0), "{}", text(&out));
    let out = ground(&dir, &["plan", "encode", demo, "--out", "enc"]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out));
    let ctl = o.ctl.to_string();
    let verbs: Vec<Vec<&str>> = vec![
        vec!["plan", "check", demo],
        vec!["plan", "check", "--json", demo],
        vec!["plan", "encode", demo, "--out", "enc2"],
        vec!["decode", "enc/apid_0x101.bin"],
        vec!["decode", "--json", "enc/apid_0x101.bin"],
        vec!["mib", "export", "--format", "json", "--out", "mib"],
        vec!["archive", "query", "--type", "tc"],
        vec!["archive", "query", "--type", "hk", "--json"],
        vec!["archive", "export", "--csv", "--type", "tc"],
        vec!["archive", "export", "--csv", "--type", "hk"],
        vec!["archive", "status"],
        vec!["archive", "latest"],
        vec!["archive", "gaps"],
        vec!["archive", "check"],
        vec!["ping", "--lab-udp", "--robot", &r, "-c", "1"],
        vec!["send", "--lab-udp", "--robot", &r, "PING"],
        vec!["watch", "--lab-udp", "--robot", &r, "--duration", "1.5"],
        vec!["run", "--lab-udp", "one.toml", "--plain", "--robot", &r],
        vec!["sim", "--addr", &ctl, "status"],
        vec!["--help"],
    ];
    for v in verbs {
        let (code, err) = closed_pipe(&dir, &v);
        assert_eq!(code, Some(0), "{v:?}: {err}");
        assert!(
            !err.contains("Broken pipe") && !err.contains("panicked"),
            "{v:?}: {err}"
        );
    }
}

// verifies: OPS-OUT-01
#[test]
fn sim_names_what_it_talked_to_and_prints_readable_text() {
    let dir = tmpdir("ops", "sim");
    let b = Obsw::start(2, &["--speed", "20"]);
    let ctl = b.ctl.to_string();
    let out = ground(&dir, &["sim", "--addr", &ctl, "status"]);
    let t = text(&out);
    assert_eq!(out.status.code(), Some(0), "{t}");
    assert!(t.starts_with(&format!("simulator at {ctl}: ok")), "{t}");
    assert!(!t.contains("robot 1"), "{t}");
    assert!(!t.contains('{') && !t.contains("Some("), "no Rust debug dump: {t}");
    assert!(t.lines().any(|l| l.trim_start().starts_with("v_bat: ")), "{t}");
    let out = ground(&dir, &["sim", "--robot", "2", "--addr", &ctl, "clear", "link-loss"]);
    let t = text(&out);
    assert_eq!(out.status.code(), Some(4), "{t}");
    assert!(t.contains("robot 2 (simulator at"), "{t}");
    assert!(
        t.contains("'link-loss' is not a fault") && t.contains("`link-loss 0`"),
        "{t}"
    );
    assert!(!t.contains("unknown command"), "{t}");
}
