//! Every command example of docs/operator-guide.md (its fenced `sh` blocks), run in the
//! order of the guide on loopback against real `obsw` processes, with its exit code and
//! key output lines checked. A command the test cannot run says so in the guide itself
//! (its comment contains "not run by the doc test"). A new or changed example fails this
//! test until it has an expectation below: an example cannot go stale silently.
//!
//! The guide's robots live at their default space-link ports; the test starts its own
//! obsw per robot over the space link (frames, COP-1, SDLS) on free ports with its own
//! test keys (given to the ground as `$MMIC_KEYS`, as the guide says to) and rewrites
//! `--robot N[=ADDR]` to `--robot N=FRAME_PORT --tm-listen N=TM_ADDR` (and `sim -r N`
//! to its control port), so it never depends on, or disturbs, robots an operator runs
//! on the default ports.

use std::collections::BTreeMap;
use std::io::BufRead;
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

mod common;
use common::{free_port, obsw_bin, tmpdir, Obsw, GROUND};

/// What a documented command must do.
struct Expect {
    code: i32,
    says: &'static [&'static str],
    /// Start fresh robots (initial states of the demo plan) before it.
    fresh: bool,
    /// Send SIGINT once a stderr line contains this.
    interrupt_at: Option<&'static str>,
}

const fn ok(says: &'static [&'static str]) -> Expect {
    Expect {
        code: 0,
        says,
        fresh: false,
        interrupt_at: None,
    }
}

const fn code(code: i32, says: &'static [&'static str]) -> Expect {
    Expect {
        code,
        says,
        fresh: false,
        interrupt_at: None,
    }
}

fn expectations() -> BTreeMap<&'static str, Expect> {
    BTreeMap::from([
        (
            "target/release/ground demo",
            ok(&["10 of 10 steps done", "quality 100% over", " 0 resends"]),
        ),
        ("target/release/ground --help", ok(&["Usage: ground"])),
        (
            "ground keys create keys --robot 1 --robot 2",
            ok(&["created keys/robot-1/tc-spi1.key", "created keys/robot-2/tm-spi17.key"]),
        ),
        (
            "ground keys show keys",
            ok(&["SPI 1 ", "SPI 17 ", "sha256 ", "mode 600"]),
        ),
        (
            "ground ping --robot 1 --robot 2",
            ok(&["talking to robot 1 at", "reply in"]),
        ),
        ("ground plan check plans/demo.toml", ok(&["ok — plan \"demo\""])),
        (
            "ground run plans/demo.toml --robot 1=127.0.0.1:7501 --robot 2=127.0.0.1:7502",
            ok(&["10 of 10 steps done", "faults: none", " 0 resends"]),
        ),
        (
            "ground mode --robot 2 operational --confirm",
            ok(&["completion ok", "robot 2: mode OPERATIONAL"]),
        ),
        (
            "ground send --robot 2 RECONFIGURE from=Xneg to=Xpos",
            ok(&["progress ok step 1", "completion ok"]),
        ),
        (
            "ground watch --robot 1 --no-hk --duration 3",
            ok(&["talking to robot 1 at"]),
        ),
        (
            "ground archive plot V_BAT_A I_BAT --out battery.svg",
            ok(&["points plotted to battery.svg"]),
        ),
        ("ground send --robot 1 HK_ONE_SHOT sid=31", ok(&["completion ok"])),
        (
            "ground send --robot 1 UNBOLT_FACE side=A pairs=3",
            code(3, &["UNBOLT_FACE is hazardous", "(add --confirm)"]),
        ),
        (
            "ground send --robot 1 BOLT_FCE side=A pairs=15",
            code(3, &["did you mean BOLT_FACE?"]),
        ),
        ("ground archive query --type event --severity medium", ok(&["row(s)"])),
        (
            "ground archive query --type verification --since -1h --json",
            ok(&["\"stage\":\"completion\""]),
        ),
        (
            "ground archive export --csv --type hk --param V_BAT_A --out vbat.csv",
            ok(&["row(s) written to vbat.csv"]),
        ),
        (
            "ground archive plot V_BAT_A V_BAT_B --robot 2 --out vbat.png",
            ok(&["points plotted to vbat.png"]),
        ),
        ("ground ping --robot 3 -c 1", code(8, &["robot 3: nothing heard from"])),
        (
            "ground run plans/demo.toml --robot 1 --robot 2 --grace 5",
            Expect {
                code: 6,
                says: &["INTERRUPTED: no new step was sent", "not sent"],
                fresh: true,
                interrupt_at: Some("  done     r1-operational"),
            },
        ),
        (
            "ground run plans/demo.toml --robot 1 --robot 2 --resume",
            ok(&["resuming run", "10 of 10 steps done", "resumed: "]),
        ),
        (
            "ground sim -r 2 battery-sag 9.5",
            ok(&["robot 2 (simulator at 127.0.0.1:", ": ok"]),
        ),
        ("ground sim -r 2 status", ok(&["v_bat: "])),
        ("ground sim -r 2 clear", ok(&[": ok"])),
    ])
}

/// The commands of every fenced `sh` block, comments stripped, in order; `skip` is true
/// for those the guide marks as not run by this test.
fn doc_commands(md: &str) -> Vec<(String, bool)> {
    let mut out = Vec::new();
    let mut inside = false;
    for line in md.lines() {
        let t = line.trim();
        if t.starts_with("```") {
            inside = !inside && t == "```sh";
            continue;
        }
        if !inside || t.is_empty() || t.starts_with('#') {
            continue;
        }
        let (cmd, comment) = t.split_once(" #").unwrap_or((t, ""));
        let cmd = cmd.split_whitespace().collect::<Vec<_>>().join(" ");
        out.push((cmd, comment.contains("not run by the doc test")));
    }
    out
}

/// The commands of every block fenced "```sh yamcs" (the Yamcs chapter: not ground
/// commands), with `\` continuation lines joined.
fn yamcs_commands(md: &str) -> Vec<String> {
    let mut out: Vec<String> = Vec::new();
    let (mut inside, mut continued) = (false, false);
    for line in md.lines() {
        let t = line.trim();
        if t.starts_with("```") {
            inside = !inside && t == "```sh yamcs";
            continue;
        }
        if !inside || t.is_empty() || t.starts_with('#') {
            continue;
        }
        let cmd = t.split_once(" #").map_or(t, |c| c.0);
        let (cmd, more) = match cmd.strip_suffix('\\') {
            Some(c) => (c, true),
            None => (cmd, false),
        };
        match out.last_mut() {
            Some(last) if continued => {
                last.push(' ');
                last.push_str(cmd.trim());
            }
            _ => out.push(cmd.trim().to_string()),
        }
        continued = more;
    }
    out.iter()
        .map(|c| c.split_whitespace().collect::<Vec<_>>().join(" "))
        .collect()
}

// verifies: OPS-DOC-01
#[test]
fn every_yamcs_example_of_the_operator_guide_names_real_subcommands_and_flags() {
    // Running them needs Yamcs (tests/tests/yamcs_e2e.rs starts it with the same script
    // subcommands); here every `scripts/yamcs.sh` subcommand must exist in the script and
    // every `obsw` flag in `obsw --help`, so an example cannot drift from the tools.
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..");
    let md = std::fs::read_to_string(root.join("docs/operator-guide.md")).unwrap();
    let cmds = yamcs_commands(&md);
    assert!(cmds.len() >= 5, "the Yamcs chapter's examples: {cmds:?}");
    let script = std::fs::read_to_string(root.join("scripts/yamcs.sh")).unwrap();
    let help = Command::new(obsw_bin()).arg("--help").output().unwrap();
    let help = String::from_utf8_lossy(&help.stdout).to_string();
    for cmd in &cmds {
        let w: Vec<&str> = cmd.split_whitespace().collect();
        match w.as_slice() {
            ["bash", "scripts/yamcs.sh", sub, ..] => {
                assert!(
                    script.lines().any(|l| l.trim_start().starts_with(&format!("{sub})"))),
                    "`{cmd}`: scripts/yamcs.sh has no subcommand {sub}"
                );
            }
            ["obsw", flags @ ..] => {
                for f in flags.iter().filter(|f| f.starts_with("--")) {
                    assert!(help.contains(f), "`{cmd}`: obsw has no flag {f}");
                }
            }
            _ => panic!("`{cmd}` in a Yamcs block is neither scripts/yamcs.sh nor obsw"),
        }
    }
}

/// The test's robots.
struct Robots {
    obsw: BTreeMap<u8, Obsw>,
    /// Robot 3: nobody listens there (its frame port; its TM address).
    silent: (SocketAddr, SocketAddr),
}

impl Robots {
    /// Robots 1 and 2 over the space link with the test's keys (`keys` holds robots 1-3).
    fn start(keys: &Path) -> Robots {
        let mut obsw = BTreeMap::new();
        for (n, state) in [(1u8, "Xneg"), (2, "Xpos")] {
            obsw.insert(
                n,
                Obsw::start_frames(n, keys, &["--speed", "10", "--seed", "5", "--initial-state", state]),
            );
        }
        let local = || SocketAddr::from(([127, 0, 0, 1], free_port()));
        Robots {
            obsw,
            silent: (local(), local()),
        }
    }
    /// Robot `n`'s frame port and the address its TM frames go to.
    fn addr(&self, n: u8) -> (SocketAddr, SocketAddr) {
        self.obsw
            .get(&n)
            .map_or(self.silent, |o| (o.frame.expect("frames"), o.tm_to.expect("frames")))
    }
}

/// The command's arguments with the guide's robot addresses replaced by the test's.
fn rewrite(words: &[&str], robots: &Robots) -> Vec<String> {
    let sim = words.first() == Some(&"sim");
    // `archive … --robot N` is a filter, not a link.
    if !matches!(
        words.first(),
        Some(&("ping" | "send" | "mode" | "watch" | "run" | "sim"))
    ) {
        return words.iter().map(|w| w.to_string()).collect();
    }
    let mut out = Vec::new();
    let mut it = words.iter();
    while let Some(&w) = it.next() {
        if w == "--robot" || w == "-r" {
            let v = it.next().expect("--robot needs a value");
            let n: u8 = v.split('=').next().unwrap().parse().unwrap();
            out.push(w.to_string());
            if sim {
                out.push(n.to_string());
                if let Some(o) = robots.obsw.get(&n) {
                    out.push("--addr".into());
                    out.push(o.ctl.to_string());
                }
            } else {
                let (frame, tm) = robots.addr(n);
                out.push(format!("{n}={frame}"));
                out.push("--tm-listen".into());
                out.push(format!("{n}={tm}"));
            }
        } else {
            out.push(w.to_string());
        }
    }
    out
}

/// Runs `ground args` in `dir`; returns exit code and stdout + stderr.
fn run(dir: &Path, keys: &Path, args: &[String], interrupt_at: Option<&str>) -> (Option<i32>, String) {
    let mut child = Command::new(GROUND)
        .current_dir(dir)
        .env("OBSW_BIN", obsw_bin())
        .env("MMIC_KEYS", keys)
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("starting ground");
    let err = child.stderr.take().unwrap();
    let (tx, rx) = std::sync::mpsc::channel::<String>();
    let reader = std::thread::spawn(move || {
        for l in std::io::BufReader::new(err).lines().map_while(Result::ok) {
            let _ = tx.send(l);
        }
    });
    let mut stderr = Vec::new();
    if let Some(at) = interrupt_at {
        let t0 = Instant::now();
        while t0.elapsed() < Duration::from_secs(60) {
            if let Ok(l) = rx.recv_timeout(Duration::from_millis(100)) {
                let hit = l.contains(at);
                stderr.push(l);
                if hit {
                    let pid = child.id().to_string();
                    Command::new("kill").args(["-INT", &pid]).status().unwrap();
                    break;
                }
            }
        }
    }
    let mut stdout = String::new();
    if let Some(mut o) = child.stdout.take() {
        std::io::Read::read_to_string(&mut o, &mut stdout).unwrap();
    }
    let code = child.wait().unwrap().code();
    reader.join().unwrap();
    stderr.extend(rx.try_iter());
    (code, format!("{stdout}\n{}", stderr.join("\n")))
}

// verifies: OPS-DOC-01
#[test]
fn every_command_example_of_the_operator_guide_runs_as_documented() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..");
    let md = std::fs::read_to_string(root.join("docs/operator-guide.md")).unwrap();
    let cmds = doc_commands(&md);
    assert!(cmds.len() >= 15, "the guide's examples: {cmds:?}");
    let expect = expectations();
    let dir = tmpdir("ops", "doc-examples");
    std::os::unix::fs::symlink(root.join("plans"), dir.join("plans")).unwrap();
    let keys = common::frame_keys(&dir, &[1, 2, 3]);
    let mut robots = Robots::start(&keys);
    let mut ran = 0;
    for (cmd, skip) in &cmds {
        if *skip {
            continue;
        }
        let e = expect
            .get(cmd.as_str())
            .unwrap_or_else(|| panic!("no expectation for the guide's example `{cmd}`: add one"));
        let words: Vec<&str> = cmd.split_whitespace().collect();
        let args = match words.first() {
            Some(&"ground") | Some(&"target/release/ground") => rewrite(&words[1..], &robots),
            _ => panic!("`{cmd}` is not a ground command: mark it \"not run by the doc test\""),
        };
        if e.fresh {
            drop(robots);
            robots = Robots::start(&keys);
            // `--robot N` in the command: the test's robots are at other ports.
        }
        let args = if e.fresh { rewrite(&words[1..], &robots) } else { args };
        let t0 = Instant::now();
        let (code, out) = run(&dir, &keys, &args, e.interrupt_at);
        assert_eq!(code, Some(e.code), "`{cmd}` (as {args:?}):\n{out}");
        for s in e.says {
            assert!(out.contains(s), "`{cmd}` does not say {s:?}:\n{out}");
        }
        eprintln!("doc example ok in {:.1} s: {cmd}", t0.elapsed().as_secs_f64());
        ran += 1;
    }
    let skipped = cmds.iter().filter(|c| c.1).count();
    assert!(skipped <= 2, "most examples run: {skipped} skipped");
    assert_eq!(ran + skipped, cmds.len());
}
