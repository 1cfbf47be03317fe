//! Every command example of docs/collector.md, docs/dashboard.md and docs/archive.md is
//! run, so an example cannot go stale.
//!
//! An *example* is a line of a fenced code block in those documents (blank lines and
//! `#` comment lines aside), or an inline code span that is a whole command line
//! (starting with `bash `, `cargo test ` or `NAME=VALUE bash `). Rules, all explicit:
//! - [`RUN`] names every example the tests run, by document and the start of its line.
//!   The runners take the line from the document (not a copy of it), apply the listed
//!   substitutions — documented addresses, paths and alarm IDs become those of the
//!   loopback robots (the real `obsw`), a temporary folder and the alarms just raised —
//!   and check key lines of the output.
//! - A block right after a visible note `> Not run by the doc tests: REASON` is not run;
//!   [`NOT_RUN`] lists those blocks (document and first line), and any other such note is
//!   an error: nothing is skipped silently.
//! - `cargo build …` lines are not run (the tests run after the build); their bin
//!   targets are checked to exist. Inline `cargo test -p ground --test NAME [FILTER]`
//!   spans name this suite's own tests: the test file and a test starting with FILTER
//!   must exist.
//! - An inline span in a section (from one heading to the next) that says
//!   `(Not run by the doc tests: REASON)` is not run; [`NOT_RUN_INLINE`] lists those
//!   spans (benchmarks, Chromium, the npm registry).
//!
//! [`every_example_is_run_or_listed_as_not_run`] fails on an example that is neither,
//! and on an entry of [`RUN`] that matches no example (an example changed or removed).

use std::io::{Read, Write};
use std::net::{SocketAddr, TcpStream, UdpSocket};
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::Duration;

mod common;
use common::{free_port, http, pg_db, pg_drop, wait_for, Obsw, Proc, GROUND};

const DOCS: [&str; 3] = ["collector.md", "dashboard.md", "archive.md"];

/// (document, start of the example line) of every example the tests below run.
const RUN: &[(&str, &str)] = &[
    (
        "collector.md",
        "ground --archive /var/lib/mmic/archive.db collect --keys",
    ),
    (
        "collector.md",
        "ground --archive /var/lib/mmic/archive.db collect --config",
    ),
    ("collector.md", "ground collect --check-config /etc/mmic/collector.toml"),
    (
        "collector.md",
        "ground --archive /var/lib/mmic/archive.db collect --status",
    ),
    ("collector.md", "ground --archive /var/lib/mmic/archive.db alarms list"),
    ("collector.md", "ground --archive /var/lib/mmic/archive.db alarms ack"),
    (
        "collector.md",
        "ground --archive /var/lib/mmic/archive.db alarms shelve",
    ),
    ("dashboard.md", "ground collect --keys /etc/mmic/keys"),
    ("dashboard.md", "cargo build --bin obsw --bin ground"),
    (
        "dashboard.md",
        "target/debug/ground keys create keys --robot 1 --robot 2",
    ),
    ("dashboard.md", "target/debug/obsw --robot 1 --keys keys &"),
    (
        "dashboard.md",
        "target/debug/ground collect --keys keys --robot 1 --robot 2 --http",
    ),
    (
        "dashboard.md",
        "target/debug/ground sim --addr 127.0.0.1:7401 battery-sag",
    ),
    ("archive.md", "ground --archive ground-archive.db"),
    ("archive.md", "ground --archive 'postgresql://ground@db.example/mmic'"),
    (
        "archive.md",
        "ground --archive 'postgresql://ground@/mmic?host=/run/postgresql'",
    ),
];

/// (document, first line) of the blocks a visible note says are not run, and why.
const NOT_RUN: &[(&str, &str, &str)] = &[
    (
        "collector.md",
        "cargo build --release -p ground",
        "installs a systemd service as root",
    ),
    (
        "archive.md",
        "sudo -u postgres createuser ground",
        "creates a role and a database on the machine's PostgreSQL as root",
    ),
];

const NOTE: &str = "> Not run by the doc tests:";

/// Inline spans not run: (document, span, why). Their section carries the visible note.
const NOT_RUN_INLINE: &[(&str, &str, &str)] = &[
    (
        "collector.md",
        "bash ground/bench/collect_bench.sh ROBOTS MINUTES",
        "benchmark, up to hours",
    ),
    ("dashboard.md", "bash scripts/web-build.sh", "needs the npm registry"),
    (
        "dashboard.md",
        "bash scripts/web-build.sh --check",
        "needs the npm packages",
    ),
    ("dashboard.md", "bash scripts/web-test.sh", "installs Chromium"),
    (
        "dashboard.md",
        "bash ground/bench/dashboard_bench.sh 50 10 20",
        "benchmark on 50 robots",
    ),
    ("archive.md", "bash ground/bench/archive_bench.sh", "benchmark"),
    (
        "archive.md",
        "ARCHIVE_BENCH_PG=1 bash ground/bench/archive_bench.sh 100000 3",
        "benchmark",
    ),
];

/// An inline command span: (document, span, the text of its section).
fn inline_examples() -> Vec<(&'static str, String, String)> {
    let mut out = Vec::new();
    for doc in DOCS {
        let text = std::fs::read_to_string(root().join("docs").join(doc)).unwrap();
        let mut sections: Vec<String> = vec![String::new()];
        let mut in_block = false;
        for l in text.lines() {
            if l.trim().starts_with("```") {
                in_block = !in_block;
                continue;
            }
            if in_block {
                continue;
            }
            if l.starts_with('#') {
                sections.push(String::new());
            }
            let cur = sections.last_mut().unwrap();
            cur.push_str(l.trim());
            cur.push(' ');
        }
        for sec in sections {
            let spans: Vec<&str> = sec.split('`').skip(1).step_by(2).collect();
            for span in spans {
                let env_bash = span.split_once(' ').is_some_and(|(a, b)| {
                    a.contains('=')
                        && a.chars().next().is_some_and(|c| c.is_ascii_uppercase())
                        && b.starts_with("bash ")
                });
                if span.starts_with("bash ") || span.starts_with("cargo test ") || env_bash {
                    out.push((doc, span.to_string(), sec.clone()));
                }
            }
        }
    }
    out
}

// verifies: ALM-DOC-01
#[test]
fn every_inline_command_is_checked_or_listed_as_not_run() {
    let ex = inline_examples();
    assert!(ex.len() >= NOT_RUN_INLINE.len(), "{ex:?}");
    let mut checked = 0;
    for (doc, span, section) in &ex {
        if let Some(rest) = span.strip_prefix("cargo test -p ground --test ") {
            let mut w = rest.split_whitespace();
            let file = root().join("ground/tests").join(format!("{}.rs", w.next().unwrap()));
            let src =
                std::fs::read_to_string(&file).unwrap_or_else(|e| panic!("{doc}: `{span}`: {}: {e}", file.display()));
            if let Some(filter) = w.next() {
                assert!(
                    src.contains(&format!("fn {filter}")),
                    "{doc}: `{span}`: no test {filter}"
                );
            }
            checked += 1;
            continue;
        }
        assert!(
            NOT_RUN_INLINE.iter().any(|(d, s, _)| d == doc && s == span),
            "{doc}: `{span}` is neither checked nor listed in NOT_RUN_INLINE"
        );
        assert!(
            section.to_ascii_lowercase().contains("not run by the doc tests"),
            "{doc}: `{span}`: its section has no visible \"Not run by the doc tests\" note"
        );
    }
    for (d, s, why) in NOT_RUN_INLINE {
        assert!(
            ex.iter().any(|(doc, span, _)| doc == d && span == s),
            "{d}: `{s}` ({why}) is no longer in the document: update NOT_RUN_INLINE"
        );
    }
    assert!(checked >= 4, "the cargo test lines were not found: {ex:?}");
}

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// One example: its document, its line (without a trailing `# comment`), and the note
/// above its block if the block is not run.
#[derive(Debug)]
struct Example {
    doc: &'static str,
    line: String,
    not_run: Option<String>,
    block_first: String,
}

fn examples() -> Vec<Example> {
    let mut out = Vec::new();
    for doc in DOCS {
        let text = std::fs::read_to_string(root().join("docs").join(doc)).unwrap();
        let mut in_block = false;
        let mut note: Option<String> = None;
        let mut last_text = String::new();
        let mut first: Option<String> = None;
        for l in text.lines() {
            let t = l.trim();
            if t.starts_with("```") {
                in_block = !in_block;
                if in_block {
                    note = last_text.strip_prefix(NOTE).map(|r| r.trim().to_string());
                    first = None;
                }
                continue;
            }
            if !in_block {
                if !t.is_empty() {
                    last_text = t.to_string();
                }
                continue;
            }
            if t.is_empty() || t.starts_with('#') {
                continue;
            }
            let line = t.split("  #").next().unwrap_or(t).trim().to_string();
            let first_line = first.get_or_insert_with(|| line.clone()).clone();
            out.push(Example {
                doc,
                line,
                not_run: note.clone(),
                block_first: first_line,
            });
        }
    }
    out
}

/// The example of `doc` starting with `start` (exactly one, in a block that is run).
fn example(doc: &str, start: &str) -> String {
    let all: Vec<String> = examples()
        .into_iter()
        .filter(|e| e.doc == doc && e.line.starts_with(start) && e.not_run.is_none())
        .map(|e| e.line)
        .collect();
    assert_eq!(all.len(), 1, "{doc}: examples starting with {start:?}: {all:?}");
    all[0].clone()
}

// verifies: ALM-DOC-01
#[test]
fn every_example_is_run_or_listed_as_not_run() {
    let ex = examples();
    assert!(ex.len() >= RUN.len(), "{ex:#?}");
    let mut not_run = Vec::new();
    for e in &ex {
        let run: Vec<_> = RUN
            .iter()
            .filter(|(d, s)| *d == e.doc && e.line.starts_with(s))
            .collect();
        match &e.not_run {
            Some(why) => {
                assert!(
                    NOT_RUN.iter().any(|(d, f, _)| *d == e.doc && *f == e.block_first),
                    "{}: block {:?} is marked \"{NOTE} {why}\" but not listed in NOT_RUN",
                    e.doc,
                    e.block_first
                );
                not_run.push(format!("{}: {} ({why})", e.doc, e.line));
            }
            None => assert_eq!(run.len(), 1, "{}: example {:?} is not run by a test", e.doc, e.line),
        }
    }
    for (d, s) in RUN {
        assert!(
            ex.iter()
                .any(|e| e.doc == *d && e.line.starts_with(s) && e.not_run.is_none()),
            "{d}: no example starts with {s:?} any more: update RUN and its runner"
        );
    }
    for (d, f, why) in NOT_RUN {
        assert!(
            ex.iter()
                .any(|e| e.doc == *d && e.block_first == *f && e.not_run.is_some()),
            "{d}: no block starting {f:?} marked \"{NOTE} …\" ({why})"
        );
    }
    println!("not run (listed in NOT_RUN, noted in the documents):");
    for n in not_run {
        println!("  {n}");
    }
}

/// Splits a shell line into words (single and double quotes, no expansion).
fn words(line: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut cur = String::new();
    let mut quote: Option<char> = None;
    let mut any = false;
    for c in line.chars() {
        match (quote, c) {
            (Some(q), c) if c == q => quote = None,
            (Some(_), c) => cur.push(c),
            (None, '\'' | '"') => {
                quote = Some(c);
                any = true;
            }
            (None, c) if c.is_whitespace() => {
                if any || !cur.is_empty() {
                    out.push(std::mem::take(&mut cur));
                }
                any = false;
            }
            (None, c) => cur.push(c),
        }
    }
    if any || !cur.is_empty() {
        out.push(cur);
    }
    out
}

/// `line` with each (from, to) replaced, run in `dir` with the `ground` under test.
fn command(dir: &Path, line: &str, subst: &[(&str, String)]) -> Command {
    let mut l = line.to_string();
    for (from, to) in subst {
        l = l.replace(from, to);
    }
    let w = words(&l);
    let prog = match w[0].as_str() {
        "ground" | "target/debug/ground" => PathBuf::from(GROUND),
        other => panic!("no rule to run {other:?} ({line})"),
    };
    let mut c = Command::new(prog);
    c.current_dir(dir).args(&w[1..]);
    c
}

fn run(dir: &Path, line: &str, subst: &[(&str, String)]) -> (Option<i32>, String) {
    let o: Output = command(dir, line, subst).output().unwrap();
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    (o.status.code(), text)
}

fn spawn(dir: &Path, line: &str, subst: &[(&str, String)], log: &str) -> Proc {
    let log = std::fs::File::create(dir.join(log)).unwrap();
    Proc(
        command(dir, line, subst)
            .stdout(Stdio::null())
            .stderr(Stdio::from(log))
            .spawn()
            .unwrap(),
    )
}

fn sigterm(p: &mut Proc) -> Option<i32> {
    Command::new("kill")
        .args(["-TERM", &p.0.id().to_string()])
        .status()
        .unwrap();
    for _ in 0..100 {
        if let Ok(Some(s)) = p.0.try_wait() {
            return s.code();
        }
        std::thread::sleep(Duration::from_millis(100));
    }
    None
}

fn tmpdir(name: &str) -> PathBuf {
    common::tmpdir("doc-examples", name)
}

/// Waits until the collector's log in `dir` says robots 1 and 2 are up (then `--status`
/// has something to show).
fn links_up(dir: &Path, log: &str) {
    wait_for(30, "collector links up", || {
        let l = std::fs::read_to_string(dir.join(log)).unwrap_or_default();
        (l.contains("robot 1: link up") && l.contains("robot 2: link up")).then_some(())
    });
}

/// The collector chapter's first block, against two loopback robots: follow them from
/// the command line, check the configuration, follow them from the example
/// configuration, raise alarms with a battery sag, list, acknowledge and shelve them.
// verifies: ALM-DOC-01
#[test]
fn collector_examples_run_against_two_loopback_robots() {
    let dir = tmpdir("collector");
    // Over the space link, as documented: the robots with test keys on free ports.
    let keys = common::frame_keys(&dir, &[1, 2]);
    let r1 = Obsw::start_frames(1, &keys, &[]);
    let r2 = Obsw::start_frames(2, &keys, &[]);
    let (f1, f2) = (r1.frame.unwrap().to_string(), r2.frame.unwrap().to_string());
    let (t1, t2) = (r1.tm_to.unwrap().to_string(), r2.tm_to.unwrap().to_string());
    let example_cfg = std::fs::read_to_string(root().join("docs/collector.example.toml")).unwrap();
    let cfg = example_cfg
        .replace("\"127.0.0.1:7501\"", &format!("\"{f1}\""))
        .replace("\"127.0.0.1:7502\"", &format!("\"{f2}\""))
        .replace("\"127.0.0.1:7601\"", &format!("\"{t1}\""))
        .replace("\"127.0.0.1:7602\"", &format!("\"{t2}\""))
        .replace("keys = \"../keys\"", &format!("keys = \"{}\"", keys.display()))
        .replace("../plans/", &format!("{}/", root().join("plans").display()));
    std::fs::write(dir.join("collector.toml"), cfg).unwrap();
    let mut subst: Vec<(&str, String)> = vec![
        ("/var/lib/mmic/archive.db", dir.join("archive.db").display().to_string()),
        (
            "/etc/mmic/collector.toml",
            dir.join("collector.toml").display().to_string(),
        ),
        ("/etc/mmic/keys", keys.display().to_string()),
        ("10.0.0.11:7501", f1.clone()),
        ("10.0.0.12:7502", f2.clone()),
        ("0.0.0.0:7601", t1.clone()),
        ("0.0.0.0:7602", t2.clone()),
    ];
    let ex = |s: &str| example("collector.md", s);

    // --check-config: ok on the example configuration, file:line:column and exit 3 on a
    // broken one.
    let check = ex("ground collect --check-config /etc/mmic/collector.toml");
    let (code, out) = run(&dir, &check, &subst);
    assert_eq!(code, Some(0), "{out}");
    assert!(out.contains("collector.toml: ok (2 robots, retain 30d)"), "{out}");
    std::fs::write(dir.join("broken.toml"), "retain = \"soon\"\n[[robot]]\nnumbr = 1\n").unwrap();
    let broken: Vec<(&str, String)> = vec![(
        "/etc/mmic/collector.toml",
        dir.join("broken.toml").display().to_string(),
    )];
    let (code, out) = run(&dir, &check, &broken);
    assert_eq!(code, Some(3), "{out}");
    assert!(
        out.contains("broken.toml:1:10: retain") && out.contains("broken.toml:3:1: unknown field"),
        "{out}"
    );

    // Following the robots from the command line; --status sees both up.
    let status = ex("ground --archive /var/lib/mmic/archive.db collect --status");
    let mut c = spawn(
        &dir,
        &ex("ground --archive /var/lib/mmic/archive.db collect --keys"),
        &subst,
        "c1.log",
    );
    links_up(&dir, "c1.log");
    wait_for(30, "both robots up in --status", || {
        let (_, out) = run(&dir, &status, &subst);
        let up = out.lines().filter(|l| l.contains(" up ")).count();
        (up == 2).then_some(())
    });
    assert_eq!(sigterm(&mut c), Some(0), "SIGTERM ends the collector with exit 0");

    // Following them from the configuration; a battery sag raises alarms.
    let mut c = spawn(
        &dir,
        &ex("ground --archive /var/lib/mmic/archive.db collect --config"),
        &subst,
        "c2.log",
    );
    links_up(&dir, "c2.log");
    let (_, out) = wait_for(30, "robots up again", || {
        let r = run(&dir, &status, &subst);
        (r.1.lines().filter(|l| l.contains(" up ")).count() == 2).then_some(r)
    });
    assert!(out.contains("collector last wrote its status"), "{out}");
    UdpSocket::bind("127.0.0.1:0")
        .unwrap()
        .send_to(b"battery-sag 9.2\n", r1.ctl)
        .unwrap();
    let list = ex("ground --archive /var/lib/mmic/archive.db alarms list");
    let out = wait_for(30, "V_BAT_A and LOW_BATTERY alarms", || {
        let (_, out) = run(&dir, &list, &subst);
        let has = |src: &str| out.lines().any(|l| l.split_whitespace().nth(2) == Some(src));
        (has("V_BAT_A") && has("LOW_BATTERY")).then_some(out)
    });
    assert!(out.lines().next().unwrap_or("").contains("source"), "{out}");
    // The IDs of the documented `ack 12` and `shelve 13`: the two alarms just raised.
    // Columns: id, robot, source, … (an event's message may name a parameter too).
    let id_of = |source: &str| {
        out.lines()
            .map(|l| l.split_whitespace().collect::<Vec<_>>())
            .find(|w| w.get(2) == Some(&source))
            .map(|w| w[0].to_string())
            .unwrap_or_else(|| panic!("no {source} alarm: {out}"))
    };
    let (v_bat, low_bat) = (id_of("V_BAT_A"), id_of("LOW_BATTERY"));
    subst.push(("alarms ack 12", format!("alarms ack {v_bat}")));
    subst.push(("alarms shelve 13", format!("alarms shelve {low_bat}")));
    let (code, out) = run(
        &dir,
        &ex("ground --archive /var/lib/mmic/archive.db alarms ack"),
        &subst,
    );
    assert_eq!(code, Some(0), "{out}");
    let (code, out) = run(
        &dir,
        &ex("ground --archive /var/lib/mmic/archive.db alarms shelve"),
        &subst,
    );
    assert_eq!(code, Some(0), "{out}");
    let (_, out) = run(&dir, &list, &subst);
    let state = |id: &str| {
        out.lines()
            .find(|l| l.split_whitespace().next() == Some(id))
            .unwrap_or_else(|| panic!("alarm {id} not listed: {out}"))
            .to_string()
    };
    assert!(state(&v_bat).contains("acknowledged"), "{out}");
    assert!(state(&low_bat).contains("shelved"), "{out}");
    assert_eq!(sigterm(&mut c), Some(0));
}

/// `GET path` of the dashboard: (status, body).
fn get(addr: SocketAddr, path: &str) -> (u16, String) {
    let Ok(mut s) = TcpStream::connect(addr) else {
        return (0, String::new());
    };
    s.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
    write!(s, "GET {path} HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n\r\n").unwrap();
    let mut out = String::new();
    let _ = s.read_to_string(&mut out);
    let status = out.get(9..12).and_then(|x| x.parse().ok()).unwrap_or(0);
    (
        status,
        out.split_once("\r\n\r\n").map(|x| x.1.to_string()).unwrap_or_default(),
    )
}

/// Waits until the dashboard at `web` shows `n` robots with the link up, and serves the page.
fn dashboard_up(web: SocketAddr, n: usize) {
    wait_for(30, "robots up on the dashboard", || {
        let (st, s) = std::panic::catch_unwind(|| http(web, "GET", "/api/snapshot", None)).ok()?;
        let r = s["robots"].as_array()?;
        (st == 200 && r.len() == n && r.iter().all(|r| r["link"] == "up")).then_some(())
    });
    let (st, page) = get(web, "/");
    assert_eq!(st, 200);
    assert!(page.contains("<html") || page.contains("<!doctype"), "{page}");
}

/// The dashboard chapter: its first block against two loopback robots, and the "try it
/// against simulated robots" block (obsw with its default ports, 7300 + N and 7400 + N,
/// run for robot numbers whose ports are free here).
// verifies: ALM-DOC-01
#[test]
fn dashboard_examples_run_against_simulated_robots() {
    let ex = |s: &str| example("dashboard.md", s);
    // First block.
    let dir = tmpdir("dashboard");
    let keys = common::frame_keys(&dir, &[1, 2]);
    let r1 = Obsw::start_frames(1, &keys, &[]);
    let r2 = Obsw::start_frames(2, &keys, &[]);
    let web: SocketAddr = ([127, 0, 0, 1], free_port()).into();
    let subst = vec![
        ("/etc/mmic/keys", keys.display().to_string()),
        ("10.0.0.11:7501", r1.frame.unwrap().to_string()),
        ("10.0.0.12:7502", r2.frame.unwrap().to_string()),
        ("0.0.0.0:7601", r1.tm_to.unwrap().to_string()),
        ("0.0.0.0:7602", r2.tm_to.unwrap().to_string()),
        ("127.0.0.1:8080", web.to_string()),
    ];
    let mut c = spawn(&dir, &ex("ground collect --keys /etc/mmic/keys"), &subst, "c.log");
    dashboard_up(web, 2);
    assert_eq!(sigterm(&mut c), Some(0));
    drop((r1, r2));

    // `cargo build --bin obsw --bin ground`: both bin targets exist (not run: this test
    // runs after the build).
    let build = ex("cargo build --bin obsw --bin ground");
    let meta = Command::new(env!("CARGO"))
        .args(["metadata", "--no-deps", "--format-version", "1"])
        .current_dir(root())
        .output()
        .unwrap();
    let meta: serde_json::Value = serde_json::from_slice(&meta.stdout).unwrap();
    let bins: Vec<String> = meta["packages"]
        .as_array()
        .unwrap()
        .iter()
        .flat_map(|p| p["targets"].as_array().unwrap().iter())
        .filter(|t| t["kind"][0] == "bin")
        .map(|t| t["name"].as_str().unwrap().to_string())
        .collect();
    for w in words(&build).windows(2).filter(|w| w[0] == "--bin") {
        assert!(bins.contains(&w[1]), "{build}: no bin target {:?}", w[1]);
    }

    // `ground keys create keys --robot 1 --robot 2`, `target/debug/obsw --robot 1 --keys
    // keys &` (robot 2 the same), then the collector with `--keys keys --robot 1 --robot
    // 2`: the robots' default ports follow from their numbers. Run with two numbers whose
    // default ports (7300 + N, 7400 + N, 7500 + N, 7600 + N) are free here, so the test
    // does not take 7501/7502 from robots running on this machine.
    let free = |n: u8| {
        [7300, 7400, 7500, 7600]
            .iter()
            .map(|b| b + n as u16)
            .all(|p| UdpSocket::bind(("127.0.0.1", p)).is_ok() && std::net::TcpListener::bind(("127.0.0.1", p)).is_ok())
    };
    let nums: Vec<u8> = (200..=254).filter(|n| free(*n)).take(2).collect();
    assert_eq!(nums.len(), 2, "no free default ports for two robots");
    let robots_subst = vec![(
        "--robot 1 --robot 2",
        format!("--robot {} --robot {}", nums[0], nums[1]),
    )];
    let (code, out) = run(
        &dir,
        &ex("target/debug/ground keys create keys --robot 1 --robot 2"),
        &robots_subst,
    );
    assert_eq!(code, Some(0), "{out}");
    let line = ex("target/debug/obsw --robot 1 --keys keys &");
    assert!(line.contains("target/debug/obsw --robot 2 --keys keys &"), "{line}");
    let obsw = common::obsw_bin();
    let mut robots = Vec::new();
    for n in &nums {
        let mut child = Command::new(&obsw)
            .current_dir(&dir)
            .args(["--robot", &n.to_string(), "--keys", "keys"])
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .unwrap();
        let mut first = String::new();
        let mut out = child.stdout.take().unwrap();
        let mut b = [0u8; 1];
        while out.read(&mut b).unwrap_or(0) == 1 && b[0] != b'\n' {
            first.push(b[0] as char);
        }
        // The documented comment: "frames 7501/7502, TM to 7601/7602, sim-ctl 7401/7402"
        // for robots 1 and 2.
        assert!(first.starts_with("READY"), "{first}");
        for want in [
            format!("frame_udp=127.0.0.1:{}", 7500 + *n as u16),
            format!("frame_tm_to=127.0.0.1:{}", 7600 + *n as u16),
            format!("sim_ctl=127.0.0.1:{}", 7400 + *n as u16),
        ] {
            assert!(first.contains(&want), "{first} lacks {want}");
        }
        std::thread::spawn(move || {
            let mut sink = Vec::new();
            let _ = out.read_to_end(&mut sink);
        });
        robots.push(Proc(child));
    }
    let web: SocketAddr = ([127, 0, 0, 1], free_port()).into();
    let subst = vec![
        (
            "--robot 1 --robot 2",
            format!("--robot {} --robot {}", nums[0], nums[1]),
        ),
        ("127.0.0.1:8080", web.to_string()),
    ];
    let mut c = spawn(
        &dir,
        &ex("target/debug/ground collect --keys keys --robot 1 --robot 2 --http"),
        &subst,
        "c2.log",
    );
    dashboard_up(web, 2);
    // `ground sim --addr 127.0.0.1:7401 battery-sag 9.2`: robot 1's simulator control
    // port, here 7400 + the first robot's number; the page then shows the alarm.
    let sim = ex("target/debug/ground sim --addr 127.0.0.1:7401 battery-sag");
    let subst = vec![("127.0.0.1:7401", format!("127.0.0.1:{}", 7400 + nums[0] as u16))];
    let (code, out) = run(&dir, &sim, &subst);
    assert_eq!(code, Some(0), "{out}");
    assert!(out.contains("ok"), "{out}");
    wait_for(30, "the battery alarm on the page", || {
        let (_, s) = http(web, "GET", "/api/snapshot", None);
        s["alarms"]
            .as_array()?
            .iter()
            .any(|a| a["robot"] == nums[0] && a["severity"] == "high")
            .then_some(())
    });
    assert_eq!(sigterm(&mut c), Some(0));
}

/// The archive chapter's location block: the same command (`archive status` for `…`)
/// on an SQLite file and on PostgreSQL (the suite's throwaway server, reached through a
/// Unix socket like the documented `?host=` form).
// verifies: ALM-DOC-01
#[test]
fn archive_examples_run_on_sqlite_and_postgresql() {
    let ex = |s: &str| example("archive.md", s);
    let dir = tmpdir("archive");
    // A few HK packets to archive.
    let def = mib::hk::by_sid(mib::hk::sid::ROBOT_STATUS).unwrap();
    let mut stream = Vec::new();
    for i in 0..20u16 {
        let mut src = [0u8; 512];
        let n = mib_wire::codec::encode_hk(def, |id| i64::from(id) + i64::from(i), &mut src).unwrap();
        let t = 1_767_225_600_000 + i64::from(i) * 1000;
        let cds = ground::pus::CdsShort::from_unix_ms(t).to_bytes();
        stream.extend(ground::pus::build_tm(0x101, i, 3, 25, 0, &cds, &src[..n]));
    }
    std::fs::write(dir.join("hk.bin"), stream).unwrap();
    let url = pg_db("docexamples");
    let cases = [
        (ex("ground --archive ground-archive.db"), None),
        (
            ex("ground --archive 'postgresql://ground@db.example/mmic'"),
            Some("postgresql://ground@db.example/mmic"),
        ),
        (
            ex("ground --archive 'postgresql://ground@/mmic?host=/run/postgresql'"),
            Some("postgresql://ground@/mmic?host=/run/postgresql"),
        ),
    ];
    for (i, (line, doc_url)) in cases.iter().enumerate() {
        assert!(line.ends_with('…'), "{line}: the block shows where the command goes");
        let mut subst: Vec<(&str, String)> = Vec::new();
        if let Some(u) = doc_url {
            subst.push((u, url.clone()));
        }
        // The first run on each archive imports; the same packets again add nothing.
        let import = line.replace('…', "archive import hk.bin --robot 1");
        let (code, out) = run(&dir, &import, &subst);
        assert_eq!(code, Some(0), "{line}: {out}");
        let status = line.replace('…', "archive status");
        let (code, out) = run(&dir, &status, &subst);
        assert_eq!(code, Some(0), "{line}: {out}");
        assert!(out.contains("20 packet(s)"), "case {i} {line}: {out}");
        assert!(out.contains("robot 1 APID 0x101: last seq 19"), "{line}: {out}");
    }
    assert!(dir.join("ground-archive.db").exists(), "SQLite is the file named");
    pg_drop("docexamples");
}
