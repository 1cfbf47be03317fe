//! Test discovery and execution: the workspace's test binaries from
//! `cargo test --no-run --message-format=json`, their exact test names from
//! `<binary> --list`, and one `cargo test --workspace --no-fail-fast` run whose libtest
//! text output is parsed per binary (`Running ... (<executable>)` headers).

use anyhow::{bail, Context, Result};
use serde::Serialize;
use std::collections::BTreeMap;
use std::io::{BufRead, BufReader, Write};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

#[derive(Clone, Debug)]
pub struct Package {
    pub name: String,
    pub id: String,
    pub dir: PathBuf,
    /// Library target names (doc-test headers use them).
    pub lib_names: Vec<String>,
}

#[derive(Clone, Debug)]
pub struct Binary {
    pub package: String,
    pub kind: String,
    pub target: String,
    pub src_path: PathBuf,
    pub exe: PathBuf,
    pub tests: Vec<String>,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Outcome {
    Passed,
    Failed,
    Ignored,
    NotRun,
}

#[derive(Debug, Default)]
pub struct RunResult {
    /// exe file name → test name → outcome
    pub outcomes: BTreeMap<String, BTreeMap<String, Outcome>>,
    /// test name → captured output (only with `--show-output`)
    pub outputs: BTreeMap<String, String>,
    /// doc tests: (package, name, outcome)
    pub doc_tests: Vec<(String, String, Outcome)>,
    pub exit_ok: bool,
    pub seconds: f64,
}

pub fn workspace_packages(root: &Path) -> Result<Vec<Package>> {
    let out = Command::new("cargo")
        .args(["metadata", "--no-deps", "--format-version", "1"])
        .current_dir(root)
        .output()
        .context("cargo metadata")?;
    if !out.status.success() {
        bail!("cargo metadata failed: {}", String::from_utf8_lossy(&out.stderr));
    }
    let v: serde_json::Value = serde_json::from_slice(&out.stdout)?;
    let mut pkgs = Vec::new();
    for p in v["packages"].as_array().context("packages")? {
        let manifest = PathBuf::from(p["manifest_path"].as_str().unwrap_or_default());
        let lib_names = p["targets"]
            .as_array()
            .into_iter()
            .flatten()
            .filter(|t| {
                t["kind"]
                    .as_array()
                    .is_some_and(|k| k.iter().any(|k| k == "lib" || k == "rlib"))
            })
            .filter_map(|t| t["name"].as_str().map(|s| s.replace('-', "_")))
            .collect();
        pkgs.push(Package {
            name: p["name"].as_str().unwrap_or_default().to_string(),
            id: p["id"].as_str().unwrap_or_default().to_string(),
            dir: manifest.parent().map(Path::to_path_buf).unwrap_or_default(),
            lib_names,
        });
    }
    Ok(pkgs)
}

/// Builds every test binary of the workspace (once) and lists its tests.
pub fn build_and_list(root: &Path, pkgs: &[Package], env: &[(String, String)]) -> Result<Vec<Binary>> {
    // The end-to-end tests start the workspace's binaries (obsw): build them first.
    eprintln!("== review: building the workspace's binaries (cargo build --workspace --bins)");
    let st = Command::new("cargo")
        .args(["build", "--workspace", "--bins"])
        .envs(env.iter().map(|(k, v)| (k, v)))
        .current_dir(root)
        .status()
        .context("cargo build")?;
    if !st.success() {
        bail!("cargo build --workspace --bins failed");
    }
    eprintln!("== review: building test binaries (cargo test --workspace --no-run)");
    let mut child = Command::new("cargo")
        .args([
            "test",
            "--workspace",
            "--no-run",
            "--message-format=json-render-diagnostics",
        ])
        .envs(env.iter().map(|(k, v)| (k, v)))
        .current_dir(root)
        .stdout(Stdio::piped())
        .spawn()
        .context("cargo test --no-run")?;
    let stdout = child.stdout.take().context("stdout")?;
    let mut bins = Vec::new();
    for line in BufReader::new(stdout).lines() {
        let line = line?;
        let Ok(v) = serde_json::from_str::<serde_json::Value>(&line) else {
            continue;
        };
        if v["reason"] != "compiler-artifact" || v["profile"]["test"] != true {
            continue;
        }
        let Some(exe) = v["executable"].as_str() else {
            continue;
        };
        let pid = v["package_id"].as_str().unwrap_or_default();
        let Some(pkg) = pkgs.iter().find(|p| p.id == pid) else {
            continue;
        };
        bins.push(Binary {
            package: pkg.name.clone(),
            kind: v["target"]["kind"][0].as_str().unwrap_or("?").to_string(),
            target: v["target"]["name"].as_str().unwrap_or("?").to_string(),
            src_path: PathBuf::from(v["target"]["src_path"].as_str().unwrap_or_default()),
            exe: PathBuf::from(exe),
            tests: Vec::new(),
        });
    }
    let status = child.wait()?;
    if !status.success() {
        bail!("building the test binaries failed");
    }
    for b in &mut bins {
        let dir = pkgs
            .iter()
            .find(|p| p.name == b.package)
            .map(|p| p.dir.clone())
            .unwrap_or_else(|| root.to_path_buf());
        let out = Command::new(&b.exe)
            .args(["--list", "--format", "terse"])
            .envs(env.iter().map(|(k, v)| (k, v)))
            .current_dir(dir)
            .output()
            .with_context(|| format!("{} --list", b.exe.display()))?;
        for l in String::from_utf8_lossy(&out.stdout).lines() {
            if let Some(name) = l.strip_suffix(": test") {
                b.tests.push(name.to_string());
            }
        }
    }
    Ok(bins)
}

fn exe_key(p: &str) -> String {
    Path::new(p)
        .file_name()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default()
}

pub fn exe_name(b: &Binary) -> String {
    exe_key(&b.exe.to_string_lossy())
}

/// One `cargo test --workspace --no-fail-fast` run; output is echoed (when `echo`) and
/// written to `log`.
pub fn run_all(
    root: &Path,
    pkgs: &[Package],
    env: &[(String, String)],
    show_output: bool,
    echo: bool,
    log: &Path,
) -> Result<RunResult> {
    eprintln!("== review: running every test once (cargo test --workspace --no-fail-fast)");
    let start = std::time::Instant::now();
    let mut cmd = String::from("exec cargo test --workspace --no-fail-fast");
    if show_output {
        cmd.push_str(" -- --show-output");
    }
    cmd.push_str(" 2>&1");
    let mut child = Command::new("sh")
        .args(["-c", &cmd])
        .envs(env.iter().map(|(k, v)| (k, v)))
        .env("CARGO_TERM_COLOR", "never")
        .current_dir(root)
        .stdout(Stdio::piped())
        .spawn()
        .context("cargo test")?;
    let stdout = child.stdout.take().context("stdout")?;
    let mut logf = std::fs::File::create(log)?;
    let mut parser = LibtestParser::new(pkgs);
    for line in BufReader::new(stdout).lines() {
        let line = line.unwrap_or_default();
        writeln!(logf, "{line}")?;
        if echo {
            println!("{line}");
        }
        parser.feed(&line);
    }
    let mut res = parser.finish();
    res.exit_ok = child.wait()?.success();
    res.seconds = start.elapsed().as_secs_f64();
    Ok(res)
}

/// Parses `cargo test`'s merged stdout/stderr line by line.
pub struct LibtestParser<'a> {
    pkgs: &'a [Package],
    res: RunResult,
    /// exe key of the binary running now
    current: Option<String>,
    doc_pkg: Option<String>,
    capture: Option<(String, String)>,
}

impl<'a> LibtestParser<'a> {
    pub fn new(pkgs: &'a [Package]) -> Self {
        LibtestParser {
            pkgs,
            res: RunResult::default(),
            current: None,
            doc_pkg: None,
            capture: None,
        }
    }

    fn end_capture(&mut self) {
        if let Some((n, o)) = self.capture.take() {
            self.res.outputs.insert(n, o);
        }
    }

    pub fn feed(&mut self, line: &str) {
        let t = line.trim();
        if let Some(rest) = t.strip_prefix("Running ") {
            if let (Some(a), Some(b)) = (rest.rfind('('), rest.rfind(')')) {
                self.current = Some(exe_key(&rest[a + 1..b]));
                self.doc_pkg = None;
            }
            self.end_capture();
            return;
        }
        if let Some(krate) = t.strip_prefix("Doc-tests ") {
            let krate = krate.trim().replace('-', "_");
            self.doc_pkg = self
                .pkgs
                .iter()
                .find(|p| p.lib_names.contains(&krate))
                .map(|p| p.name.clone())
                .or(Some(krate));
            self.current = None;
            self.end_capture();
            return;
        }
        if let Some(name) = t.strip_prefix("---- ").and_then(|r| r.strip_suffix(" stdout ----")) {
            self.end_capture();
            self.capture = Some((name.to_string(), String::new()));
            return;
        }
        if t == "successes:" || t == "failures:" || t.starts_with("test result:") {
            self.end_capture();
        }
        if let Some((_, o)) = self.capture.as_mut() {
            o.push_str(line);
            o.push('\n');
            return;
        }
        let Some((name, verdict)) = line.strip_prefix("test ").and_then(|r| r.rsplit_once(" ... ")) else {
            return;
        };
        let verdict = verdict.trim();
        let outcome = if verdict == "ok" {
            Outcome::Passed
        } else if verdict.starts_with("FAILED") {
            Outcome::Failed
        } else if verdict.starts_with("ignored") {
            Outcome::Ignored
        } else {
            return;
        };
        if let Some(p) = &self.doc_pkg {
            self.res.doc_tests.push((p.clone(), name.to_string(), outcome));
        } else if let Some(exe) = &self.current {
            self.res
                .outcomes
                .entry(exe.clone())
                .or_default()
                .insert(name.to_string(), outcome);
        }
    }

    pub fn finish(mut self) -> RunResult {
        self.end_capture();
        self.res
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    // verifies: REV-TRACE-02
    #[test]
    fn libtest_lines_are_attached_to_their_binary_and_outputs_captured() {
        let pkgs = [Package {
            name: "mib".into(),
            id: "x".into(),
            dir: PathBuf::from("/w/mib"),
            lib_names: vec!["mib".into()],
        }];
        let log = "\
     Running unittests src/lib.rs (target/debug/deps/mib-aa11)
running 3 tests
test codec::tests::a ... ok
test codec::tests::b ... FAILED
test codec::tests::c ... ignored, slow

failures:

---- codec::tests::b stdout ----
test inside output ... ok
assertion failed

failures:
    codec::tests::b

test result: FAILED. 1 passed; 1 failed; 1 ignored
     Running tests/icd.rs (target/debug/deps/icd-bb22)
test a ... ok
   Doc-tests mib
test mib/src/lib.rs - codec (line 3) ... ok
";
        let mut p = LibtestParser::new(&pkgs);
        for l in log.lines() {
            p.feed(l);
        }
        let r = p.finish();
        let lib = &r.outcomes["mib-aa11"];
        assert_eq!(lib["codec::tests::a"], Outcome::Passed);
        assert_eq!(lib["codec::tests::b"], Outcome::Failed);
        assert_eq!(lib["codec::tests::c"], Outcome::Ignored);
        assert_eq!(lib.len(), 3, "the test line inside captured output is no result");
        assert_eq!(r.outcomes["icd-bb22"]["a"], Outcome::Passed);
        assert!(r.outputs["codec::tests::b"].contains("assertion failed"));
        assert_eq!(
            r.doc_tests,
            vec![(
                "mib".to_string(),
                "mib/src/lib.rs - codec (line 3)".to_string(),
                Outcome::Passed
            )]
        );
    }

    // verifies: REV-TRACE-02
    #[test]
    fn executable_keys_are_file_names() {
        assert_eq!(exe_key("target/debug/deps/mib-0123abcd"), "mib-0123abcd");
        assert_eq!(exe_key("/abs/target/debug/deps/icd-99"), "icd-99");
    }
}
