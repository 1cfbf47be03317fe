//! Command-line behaviour that needs no OBSW: help, plan check/encode, decode, exit codes.

use std::path::PathBuf;
use std::process::{Command, Output, Stdio};

const GROUND: &str = env!("CARGO_BIN_EXE_ground");
const DEMO: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../plans/demo.toml");

fn ground(args: &[&str]) -> Output {
    Command::new(GROUND).args(args).output().expect("running ground")
}

fn text(o: &Output) -> String {
    format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

fn tmpdir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("ground-cli-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// The subcommands `ground VERB… --help` lists (clap's `Commands:` section, from the
/// binary's own command tree), `help` aside.
fn subcommands(verb: &[&str]) -> Vec<String> {
    let mut args = verb.to_vec();
    args.push("--help");
    let help = String::from_utf8_lossy(&ground(&args).stdout).into_owned();
    help.lines()
        .skip_while(|l| *l != "Commands:")
        .skip(1)
        .take_while(|l| !l.trim().is_empty())
        .filter_map(|l| l.split_whitespace().next())
        .filter(|n| *n != "help")
        .map(str::to_string)
        .collect()
}

/// Every verb of the binary with its sub-verbs (`["plan", "check"]`), derived from clap's
/// command tree so a new verb cannot be left out.
fn every_verb() -> Vec<Vec<String>> {
    let mut leaves = Vec::new();
    let mut todo: Vec<Vec<String>> = subcommands(&[]).into_iter().map(|v| vec![v]).collect();
    while let Some(verb) = todo.pop() {
        let args: Vec<&str> = verb.iter().map(String::as_str).collect();
        let subs = subcommands(&args);
        if subs.is_empty() {
            leaves.push(verb);
        } else {
            todo.extend(subs.into_iter().map(|s| [verb.clone(), vec![s]].concat()));
        }
    }
    leaves.sort();
    leaves
}

// verifies: GND-07
#[test]
fn every_verb_has_help() {
    let verbs = every_verb();
    let known: [&[&str]; 4] = [&["model"], &["collect"], &["keys", "create"], &["alarms", "list"]];
    for known in known {
        assert!(
            verbs.iter().any(|v| v.iter().eq(known.iter())),
            "{known:?} in {verbs:?}"
        );
    }
    for verb in verbs {
        let mut args: Vec<&str> = verb.iter().map(String::as_str).collect();
        args.push("--help");
        let o = ground(&args);
        assert_eq!(o.status.code(), Some(0), "{verb:?}: {}", text(&o));
        assert!(String::from_utf8_lossy(&o.stdout).contains("Usage:"), "{verb:?}");
    }
    assert_eq!(ground(&["frobnicate"]).status.code(), Some(2));
}

// verifies: GND-03
#[test]
fn shipped_plans_check_and_a_bad_plan_lists_every_error() {
    let plans: Vec<String> = std::fs::read_dir(concat!(env!("CARGO_MANIFEST_DIR"), "/../plans"))
        .unwrap()
        .map(|e| e.unwrap().path().display().to_string())
        .filter(|p| p.ends_with(".toml"))
        .collect();
    assert!(plans.len() >= 2 && plans.iter().any(|p| p.ends_with("demo.toml")));
    let mut args = vec!["plan", "check"];
    args.extend(plans.iter().map(String::as_str));
    let o = ground(&args);
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    let dir = tmpdir("bad");
    let bad = dir.join("bad.toml");
    std::fs::write(
        &bad,
        "[[robot]]\nnumber = 1\n[[step]]\nid = \"a\"\nrobot = 9\naction = \"bolt\"\nside = \"Q\"\npairs = \"all\"\n",
    )
    .unwrap();
    let o = ground(&["plan", "check", bad.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(3));
    let t = text(&o);
    assert!(t.contains("bad.toml:5:9: error: robot 9 is not declared"), "{t}");
    assert!(t.contains("bad.toml:7:8: error: `side`"), "{t}");
    assert!(t.contains("2 error(s)"), "{t}");
}

// verifies: GND-02
#[test]
fn encoded_plan_decodes_back_and_corruption_is_counted() {
    let dir = tmpdir("enc");
    let o = ground(&["plan", "encode", DEMO, "--out", dir.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    let f = dir.join("apid_0x102.bin");
    let o = ground(&["decode", f.to_str().unwrap(), "--json"]);
    assert_eq!(o.status.code(), Some(0));
    let names: Vec<String> = String::from_utf8_lossy(&o.stdout)
        .lines()
        .map(|l| {
            serde_json::from_str::<serde_json::Value>(l).unwrap()["name"]
                .as_str()
                .unwrap()
                .to_string()
        })
        .collect();
    assert_eq!(
        names,
        ["MODE_SET", "UNBOLT_FACE", "RECONFIGURE", "BOLT_FACE", "MODE_SET"]
    );
    let listing = std::fs::read_to_string(dir.join("listing.txt")).unwrap();
    assert!(listing.contains("r2-walk | 2 | 0x102 | 2 | TC[8,1] RECONFIGURE | from=1 to=0 | r1-bolt,r2-unbolt"));

    let mut bytes = std::fs::read(&f).unwrap();
    bytes[30] ^= 0xFF;
    bytes.extend_from_slice(&[0xDE, 0xAD]);
    let g = dir.join("corrupt.bin");
    std::fs::write(&g, &bytes).unwrap();
    let o = ground(&["decode", g.to_str().unwrap(), "--strict"]);
    assert_eq!(o.status.code(), Some(3));
    let t = text(&o);
    assert!(
        t.contains("4 packets (4 TC, 0 TM)") && t.contains("2 corrupt stretches"),
        "{t}"
    );
}

// verifies: GND-07
#[test]
fn closed_pipe_is_a_quiet_exit() {
    let dir = tmpdir("pipe");
    let f = dir.join("many.bin");
    let tc = ground::pus::build_tc(1, 0, mib::tc::by_name("PING").unwrap(), &[]).unwrap();
    std::fs::write(&f, tc.bytes.repeat(200_000)).unwrap();
    let mut child = Command::new(GROUND)
        .args(["decode", f.to_str().unwrap()])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    {
        use std::io::Read;
        let mut first = [0u8; 64];
        child.stdout.as_mut().unwrap().read_exact(&mut first).unwrap();
    }
    drop(child.stdout.take());
    let o = child.wait_with_output().unwrap();
    assert_eq!(o.status.code(), Some(0));
    assert!(!String::from_utf8_lossy(&o.stderr).contains("panicked"));
}

// verifies: GND-07
#[test]
fn mib_export_writes_files() {
    let dir = tmpdir("mib");
    for f in ["json", "xtce", "scos"] {
        let o = ground(&["mib", "export", "--format", f, "--out", dir.join(f).to_str().unwrap()]);
        assert_eq!(o.status.code(), Some(0), "{}", text(&o));
        assert!(std::fs::read_dir(dir.join(f)).unwrap().count() >= 1);
    }
    assert_eq!(
        ground(&["mib", "export", "--format", "yaml", "--out", "x"])
            .status
            .code(),
        Some(3)
    );
}

// verifies: GND-03, DD-ROBUST-01
#[test]
fn binary_junk_as_a_plan_is_invalid_input() {
    let d = tmpdir("junk");
    let p = d.join("junk.toml");
    std::fs::write(&p, [0xFFu8, 0xFE, 0x00, 0x9F, 0x80, 0x41]).unwrap();
    for verb in [&["plan", "check"][..], &["run", "--lab-udp", "--no-archive"][..]] {
        let mut args = verb.to_vec();
        args.push(p.to_str().unwrap());
        let o = ground(&args);
        assert_eq!(o.status.code(), Some(3), "{verb:?}: {}", text(&o));
        assert!(text(&o).contains("not UTF-8"), "{}", text(&o));
    }
}

// verifies: GND-03
#[test]
fn plan_check_is_linear_in_the_number_of_errors() {
    let d = tmpdir("many-errors");
    let time_for = |n: usize| {
        let mut src = String::from("name = \"x\"\n[[robot]]\nnumber = 1\ninitial_state = \"Xneg\"\n");
        for i in 0..n {
            src.push_str(&format!(
                "[[step]]\nid = \"s{i}\"\nrobot = 1\naction = \"frobnicate\"\n"
            ));
        }
        let p = d.join(format!("e{n}.toml"));
        std::fs::write(&p, src).unwrap();
        let t0 = std::time::Instant::now();
        let o = ground(&["plan", "check", p.to_str().unwrap()]);
        assert_eq!(o.status.code(), Some(3));
        t0.elapsed().as_secs_f64()
    };
    let small = time_for(2_000);
    let big = time_for(20_000);
    // Ten times the errors, well under a hundred times the time (quadratic was ~100x).
    assert!(
        big < 25.0 * small.max(0.05),
        "2k errors {small:.2} s, 20k errors {big:.2} s"
    );
}

// verifies: GND-07
#[test]
fn a_closed_stderr_is_no_panic() {
    let d = tmpdir("closed-stderr");
    let p = d.join("bad.toml");
    std::fs::write(&p, "name = 1\n").unwrap();
    let mut c = Command::new(GROUND)
        .args(["plan", "check", p.to_str().unwrap()])
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    drop(c.stderr.take());
    let st = c.wait().unwrap();
    assert_ne!(st.code(), Some(101), "panicked on a closed stderr");
    assert_eq!(st.code(), Some(3));
}

// verifies: GND-07
#[test]
fn send_names_the_allowed_sides() {
    let o = ground(&[
        "send",
        "--lab-udp",
        "--no-archive",
        "--robot",
        "1=127.0.0.1:9",
        "MOVE_ARM",
        "side=C",
        "pwm_us=1500",
    ]);
    assert_eq!(o.status.code(), Some(3), "{}", text(&o));
    assert!(text(&o).contains("the sides are A (0) and B (1)"), "{}", text(&o));
}
