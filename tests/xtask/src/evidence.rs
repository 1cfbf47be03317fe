//! Evidence of the requirements verified by demonstration, analysis or inspection
//! (ECSS-E-ST-10-02C): each names, in `docs/requirements*.toml`, what shows it —
//!
//! - `{ document = "docs/x.md", section = "Heading" }` (inspection): the file exists and
//!   has a Markdown heading containing `section`;
//! - `{ analysis = "path", section = "Heading" }` (analysis): the same check, on the file
//!   holding the analysis (`section` optional);
//! - `{ command = "…", expect = ["…"], tagged_in = "folder" }` (demonstration): the command
//!   ran in this review (full form) and succeeded, its output holds every `expect` string
//!   and, with `tagged_in`, a `test NAME ... ok` line for every test function under that
//!   folder tagged `// verifies: ID` (at least one). `bash scripts/firmware-ci.sh` is the
//!   review's firmware step: its log is read, it is not run twice.
//!
//! A requirement of such a method counts as verified when all its evidence holds and
//! each test tagged with it passed — or is ignored in the workspace run and shown passing
//! in the output of one of its commands.

use crate::report::{ReqRow, ReqTest};
use crate::tests_run::Outcome;
use crate::trace::Requirement;
use std::collections::BTreeMap;
use std::path::Path;
use std::process::Command;

/// One piece of evidence as `requirements.toml` writes it.
#[derive(Clone, Debug, Default, serde::Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields)]
pub struct Evidence {
    pub document: Option<String>,
    pub analysis: Option<String>,
    pub section: Option<String>,
    pub command: Option<String>,
    #[serde(default)]
    pub expect: Vec<String>,
    pub tagged_in: Option<String>,
}

/// The firmware step's command: its output is `target/review/firmware.log`.
pub const FIRMWARE_CI: &str = "bash scripts/firmware-ci.sh";

/// What one piece of evidence showed in this run: `Some(true)` holds, `Some(false)`
/// does not, `None` not run (the fast form runs no command).
#[derive(Clone, Debug)]
pub struct Shown {
    pub ok: Option<bool>,
    pub text: String,
}

/// Commands run (or read) once per review: command → (succeeded, output).
#[derive(Default)]
pub struct Runs {
    pub full: bool,
    /// The firmware step's result, when it ran: (succeeded, log).
    pub firmware: Option<(bool, String)>,
    pub out_dir: std::path::PathBuf,
    done: BTreeMap<String, (bool, String)>,
}

impl Runs {
    pub fn new(full: bool, firmware: Option<(bool, String)>, out_dir: &Path) -> Runs {
        Runs {
            full,
            firmware,
            out_dir: out_dir.to_path_buf(),
            done: BTreeMap::new(),
        }
    }

    /// Output of `command` run at `root` (once; the firmware step's log for firmware-ci).
    fn output(&mut self, root: &Path, command: &str) -> Option<(bool, String)> {
        if command == FIRMWARE_CI {
            return self.firmware.clone();
        }
        if !self.full {
            return None;
        }
        if let Some(r) = self.done.get(command) {
            return Some(r.clone());
        }
        eprintln!("== review: evidence: {command}");
        let log = self.out_dir.join(format!("evidence-{}.log", self.done.len() + 1));
        let r = Command::new("sh")
            .args(["-c", &format!("{command} > '{}' 2>&1", log.display())])
            .current_dir(root)
            .status();
        let text = std::fs::read_to_string(&log).unwrap_or_default();
        let r = (r.is_ok_and(|s| s.success()), text);
        self.done.insert(command.to_string(), r.clone());
        Some(r)
    }
}

/// True when `out` has a libtest-style line `test NAME ... ok` (NAME possibly with a
/// module path before it).
pub fn shows_passed(out: &str, name: &str) -> bool {
    out.lines().any(|l| {
        l.trim()
            .strip_prefix("test ")
            .and_then(|r| r.strip_suffix(" ... ok"))
            .is_some_and(|n| n == name || n.ends_with(&format!("::{name}")))
    })
}

/// Test functions under `dir` (a folder or one file) tagged `// verifies: id`.
pub fn tagged_tests(dir: &Path, id: &str) -> Vec<String> {
    let mut files = Vec::new();
    rust_files(dir, &mut files);
    let mut names = Vec::new();
    for f in files {
        let Ok(text) = std::fs::read_to_string(&f) else {
            continue;
        };
        let lines: Vec<&str> = text.lines().collect();
        for (i, l) in lines.iter().enumerate() {
            let Some(ids) = l.trim().strip_prefix("// verifies:") else {
                continue;
            };
            if !ids.split(',').any(|x| x.trim() == id) {
                continue;
            }
            // The function below the tag (attributes between).
            let name = lines[i + 1..]
                .iter()
                .take(6)
                .find_map(|l| l.split("fn ").nth(1))
                .and_then(|r| r.split(['(', '<', ' ']).next())
                .filter(|n| !n.is_empty());
            if let Some(n) = name {
                names.push(n.to_string());
            }
        }
    }
    names.sort();
    names.dedup();
    names
}

fn rust_files(p: &Path, out: &mut Vec<std::path::PathBuf>) {
    if p.is_file() {
        if p.extension().is_some_and(|e| e == "rs") {
            out.push(p.to_path_buf());
        }
        return;
    }
    let Ok(rd) = std::fs::read_dir(p) else { return };
    let mut entries: Vec<_> = rd.flatten().map(|e| e.path()).collect();
    entries.sort();
    for e in entries {
        if e.file_name().is_some_and(|n| n == "target" || n == ".git") {
            continue;
        }
        rust_files(&e, out);
    }
}

/// A Markdown heading of `text` that contains `section`.
fn has_heading(text: &str, section: &str) -> bool {
    text.lines().any(|l| l.starts_with('#') && l.contains(section))
}

fn file_check(root: &Path, kind: &str, path: &str, section: Option<&str>) -> Shown {
    let what = match section {
        Some(s) => format!("{kind} {path} § \"{s}\""),
        None => format!("{kind} {path}"),
    };
    let (ok, why) = match std::fs::read_to_string(root.join(path)) {
        Err(e) => (false, format!("missing: {e}")),
        Ok(t) if t.trim().is_empty() => (false, "empty".to_string()),
        Ok(t) => match section {
            Some(s) if !has_heading(&t, s) => (false, "no such heading".to_string()),
            _ => (true, String::new()),
        },
    };
    Shown {
        ok: Some(ok),
        text: if ok { what } else { format!("{what}: {why}") },
    }
}

/// Checks one piece of evidence of requirement `id`.
pub fn check(root: &Path, id: &str, e: &Evidence, runs: &mut Runs) -> Shown {
    match (&e.document, &e.analysis, &e.command) {
        (Some(p), None, None) => file_check(root, "document", p, e.section.as_deref()),
        (None, Some(p), None) => file_check(root, "analysis", p, e.section.as_deref()),
        (None, None, Some(c)) => {
            let tagged = e
                .tagged_in
                .as_deref()
                .map(|d| tagged_tests(&root.join(d), id))
                .unwrap_or_default();
            let what = format!("command `{c}`");
            let Some((ran_ok, out)) = runs.output(root, c) else {
                let why = if c == FIRMWARE_CI {
                    "not run (firmware step skipped)"
                } else {
                    "not run (full form only)"
                };
                return Shown {
                    ok: None,
                    text: format!("{what}: {why}"),
                };
            };
            let mut missing: Vec<String> = e
                .expect
                .iter()
                .filter(|x| !out.contains(x.as_str()))
                .map(|x| format!("no \"{x}\" in its output"))
                .collect();
            if e.tagged_in.is_some() && tagged.is_empty() {
                missing.push(format!(
                    "no test tagged {id} under {}",
                    e.tagged_in.as_deref().unwrap_or("")
                ));
            }
            missing.extend(
                tagged
                    .iter()
                    .filter(|n| !shows_passed(&out, n))
                    .map(|n| format!("test {n} did not pass")),
            );
            if !ran_ok {
                missing.insert(0, "exited with failure".into());
            }
            let ok = missing.is_empty();
            let shown = if tagged.is_empty() {
                what
            } else {
                format!("{what}: {}", tagged.join(", "))
            };
            Shown {
                ok: Some(ok),
                text: if ok {
                    shown
                } else {
                    format!("{shown}: {}", missing.join("; "))
                },
            }
        }
        _ => Shown {
            ok: Some(false),
            text: "evidence must name exactly one of document, analysis, command".into(),
        },
    }
}

/// Status of a requirement verified by demonstration, analysis or inspection, and its
/// evidence as shown. `row.tests` are the workspace tests tagged with it.
pub fn status(root: &Path, r: &Requirement, row: &ReqRow, runs: &mut Runs) -> (String, Vec<Shown>) {
    if r.evidence.is_empty() {
        return ("no evidence".into(), Vec::new());
    }
    let shown: Vec<Shown> = r.evidence.iter().map(|e| check(root, &r.id, e, runs)).collect();
    let outputs: Vec<String> = r
        .evidence
        .iter()
        .filter_map(|e| e.command.as_deref())
        .filter_map(|c| runs.output(root, c))
        .filter(|(ok, _)| *ok)
        .map(|(_, o)| o)
        .collect();
    let test_ok = |t: &ReqTest| {
        t.outcome == Outcome::Passed
            || (t.outcome == Outcome::Ignored
                && outputs
                    .iter()
                    .any(|o| shows_passed(o, t.name.rsplit("::").next().unwrap_or(&t.name))))
    };
    let status = if shown.iter().any(|s| s.ok == Some(false)) || row.tests.iter().any(|t| t.outcome == Outcome::Failed)
    {
        "failed"
    } else if shown.iter().any(|s| s.ok.is_none()) || !row.tests.iter().all(test_ok) {
        "not run"
    } else {
        "verified"
    };
    (status.into(), shown)
}

#[cfg(test)]
mod tests {
    use super::*;

    // verifies: REV-EVID-01
    #[test]
    fn every_requirement_of_the_repository_names_evidence_whose_files_hold() {
        // The documents and analyses named in docs/requirements*.toml, checked as the
        // review checks them (commands need the full form: only their shape here).
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
        let reqs = crate::trace::load(&root.join("docs/requirements.toml"))
            .unwrap()
            .requirements;
        let mut runs = Runs::new(false, None, &std::env::temp_dir());
        let mut n = 0;
        for r in reqs.iter().filter(|r| r.method != "test") {
            assert!(!r.evidence.is_empty(), "{} ({}) names no evidence", r.id, r.method);
            for e in &r.evidence {
                let s = check(&root, &r.id, e, &mut runs);
                assert_ne!(s.ok, Some(false), "{}: {}", r.id, s.text);
                if let Some(d) = &e.tagged_in {
                    assert!(
                        !tagged_tests(&root.join(d), &r.id).is_empty(),
                        "{}: no test tagged under {d}",
                        r.id
                    );
                }
                n += 1;
            }
        }
        assert!(n >= 18, "{n} pieces of evidence");
    }

    // verifies: REV-EVID-01
    #[test]
    fn a_test_line_counts_only_when_it_passed() {
        let out = "running 2 tests\ntest a::b::team_model ... ok\ntest other ... FAILED\n";
        assert!(shows_passed(out, "team_model"));
        assert!(!shows_passed(out, "other"));
        assert!(!shows_passed(out, "model"), "a suffix of a name is not the name");
    }

    // verifies: REV-EVID-01
    #[test]
    fn documents_and_commands_are_checked_not_trusted() {
        let dir = std::env::temp_dir().join(format!("xtask-evidence-{}", std::process::id()));
        std::fs::create_dir_all(dir.join("src")).unwrap();
        std::fs::write(dir.join("doc.md"), "# Title\n\n## Model checking\n\ntext\n").unwrap();
        std::fs::write(
            dir.join("src/t.rs"),
            "// verifies: X-01\n#[test]\nfn proves_it() {}\n// verifies: Y-01, X-01\nfn also() {}\n",
        )
        .unwrap();
        let mut runs = Runs::new(true, Some((true, "test proves_it ... ok\n".into())), &dir);
        let doc = |section: &str| Evidence {
            document: Some("doc.md".into()),
            section: Some(section.into()),
            ..Evidence::default()
        };
        assert_eq!(check(&dir, "X-01", &doc("Model checking"), &mut runs).ok, Some(true));
        assert_eq!(check(&dir, "X-01", &doc("Proof"), &mut runs).ok, Some(false));
        let missing = Evidence {
            analysis: Some("nowhere.md".into()),
            ..Evidence::default()
        };
        assert_eq!(check(&dir, "X-01", &missing, &mut runs).ok, Some(false));
        assert_eq!(tagged_tests(&dir, "X-01"), ["also", "proves_it"]);
        // The firmware step's log shows one of the two tagged tests: not enough.
        let fw = Evidence {
            command: Some(FIRMWARE_CI.into()),
            tagged_in: Some("src".into()),
            ..Evidence::default()
        };
        let s = check(&dir, "X-01", &fw, &mut runs);
        assert_eq!(s.ok, Some(false), "{}", s.text);
        assert!(s.text.contains("test also did not pass"), "{}", s.text);
        // A command is run, its exit status and output read.
        let echo = |cmd: &str, expect: &str| Evidence {
            command: Some(cmd.into()),
            expect: vec![expect.into()],
            ..Evidence::default()
        };
        assert_eq!(
            check(&dir, "X-01", &echo("echo all good", "all good"), &mut runs).ok,
            Some(true)
        );
        assert_eq!(
            check(&dir, "X-01", &echo("echo all good; false", "all good"), &mut runs).ok,
            Some(false)
        );
        assert_eq!(
            check(&dir, "X-01", &echo("echo nothing", "all good"), &mut runs).ok,
            Some(false)
        );
        // The fast form runs no command: not run, not verified.
        let mut fast = Runs::new(false, None, &dir);
        assert_eq!(
            check(&dir, "X-01", &echo("echo all good", "all good"), &mut fast).ok,
            None
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
