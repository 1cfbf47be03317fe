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

impl RunResult {
    /// Adds another group's results (the groups' binaries are disjoint).
    fn merge(&mut self, other: RunResult) {
        self.outcomes.extend(other.outcomes);
        self.outputs.extend(other.outputs);
        self.doc_tests.extend(other.doc_tests);
        self.exit_ok &= other.exit_ok;
    }
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

/// The package whose tests run beside the others': the end-to-end suites, which mostly wait
/// on sockets, relays and child processes.
const E2E_PACKAGE: &str = "e2e-tests";

/// Every test of the workspace once, in two groups at the same time: the end-to-end
/// package's test executables (built by `build_and_list`, run directly one after the other)
/// and `cargo test --workspace --exclude e2e-tests --no-fail-fast` for the rest (the same
/// feature resolution as the `--workspace` build, so nothing is rebuilt; `-p e2e-tests`
/// would resolve features anew and rebuild 34 units). libtest runs the tests of one
/// executable in parallel either way. `REVIEW_TEST_GROUPS=1` runs the groups one after the
/// other. Output is echoed (when `echo`, each line tagged with its group) and written to
/// `log`, group after group.
pub fn run_all(
    root: &Path,
    pkgs: &[Package],
    bins: &[Binary],
    env: &[(String, String)],
    show_output: bool,
    echo: bool,
    log: &Path,
) -> Result<RunResult> {
    let together = std::env::var("REVIEW_TEST_GROUPS").map_or(true, |v| v.trim() != "1");
    let e2e: Vec<&Binary> = bins.iter().filter(|b| b.package == E2E_PACKAGE).collect();
    eprintln!(
        "== review: running every test once: {} {E2E_PACKAGE} executables | cargo test --workspace --exclude {E2E_PACKAGE} --no-fail-fast ({})",
        e2e.len(),
        if together { "at the same time" } else { "one after the other" },
    );
    let start = std::time::Instant::now();
    let e2e_group = || run_executables(pkgs, &e2e, env, show_output, echo.then_some("e2e"));
    let rest_group = || {
        let args = ["--workspace", "--exclude", E2E_PACKAGE];
        run_cargo_test(root, pkgs, &args, env, show_output, echo.then_some("workspace"))
    };
    let runs: [Result<Group>; 2] = if together {
        std::thread::scope(|s| {
            let a = s.spawn(e2e_group);
            let b = rest_group();
            [
                a.join()
                    .unwrap_or_else(|_| Err(anyhow::anyhow!("the e2e group's runner panicked"))),
                b,
            ]
        })
    } else {
        [e2e_group(), rest_group()]
    };
    let mut logf = std::fs::File::create(log)?;
    let mut res = RunResult {
        exit_ok: true,
        ..RunResult::default()
    };
    for run in runs {
        let (r, lines) = run?;
        for line in lines {
            writeln!(logf, "{line}")?;
        }
        res.merge(r);
    }
    res.seconds = start.elapsed().as_secs_f64();
    Ok(res)
}

/// A group's result and its output lines.
type Group = (RunResult, Vec<String>);

/// Feeds each output line to the parser, keeps it, and echoes it with the group's tag.
struct GroupOutput<'a> {
    parser: LibtestParser<'a>,
    lines: Vec<String>,
    echo_tag: Option<&'a str>,
}

impl<'a> GroupOutput<'a> {
    fn new(pkgs: &'a [Package], echo_tag: Option<&'a str>) -> Self {
        GroupOutput {
            parser: LibtestParser::new(pkgs),
            lines: Vec::new(),
            echo_tag,
        }
    }

    fn line(&mut self, line: String) {
        if let Some(tag) = self.echo_tag {
            println!("[{tag}] {line}");
        }
        self.parser.feed(&line);
        self.lines.push(line);
    }

    fn read(&mut self, out: impl std::io::Read) {
        for line in BufReader::new(out).lines() {
            self.line(line.unwrap_or_default());
        }
    }
}

/// Test executables run directly, one after the other, each in its package's directory (as
/// cargo runs them), introduced by the header line cargo would print.
fn run_executables(
    pkgs: &[Package],
    bins: &[&Binary],
    env: &[(String, String)],
    show_output: bool,
    echo_tag: Option<&str>,
) -> Result<Group> {
    let mut out = GroupOutput::new(pkgs, echo_tag);
    let mut ok = true;
    for b in bins {
        let dir = pkgs
            .iter()
            .find(|p| p.name == b.package)
            .map(|p| p.dir.clone())
            .unwrap_or_default();
        let src = b.src_path.strip_prefix(&dir).unwrap_or(&b.src_path);
        out.line(format!("     Running {} ({})", src.display(), b.exe.display()));
        // stdout and stderr in one stream, as under cargo test.
        let mut cmd = Command::new("sh");
        cmd.args(["-c", "exec \"$0\" \"$@\" 2>&1"]).arg(&b.exe);
        if show_output {
            cmd.arg("--show-output");
        }
        let mut child = cmd
            .envs(env.iter().map(|(k, v)| (k, v)))
            .current_dir(&dir)
            .stdout(Stdio::piped())
            .spawn()
            .with_context(|| format!("running {}", b.exe.display()))?;
        out.read(child.stdout.take().context("stdout")?);
        ok &= child.wait()?.success();
    }
    let mut res = out.parser.finish();
    res.exit_ok = ok;
    Ok((res, out.lines))
}

/// One `cargo test ARGS --no-fail-fast`, parsed.
fn run_cargo_test(
    root: &Path,
    pkgs: &[Package],
    args: &[&str],
    env: &[(String, String)],
    show_output: bool,
    echo_tag: Option<&str>,
) -> Result<Group> {
    let mut cmd = format!("exec cargo test {} --no-fail-fast", args.join(" "));
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
        .with_context(|| format!("cargo test {}", args.join(" ")))?;
    let mut out = GroupOutput::new(pkgs, echo_tag);
    out.read(child.stdout.take().context("stdout")?);
    let mut res = out.parser.finish();
    res.exit_ok = child.wait()?.success();
    Ok((res, out.lines))
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
        // libtest names a `#[should_panic]` test "NAME - should panic" in its result line.
        let name = name.strip_suffix(" - should panic").unwrap_or(name);
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
test codec::tests::d - should panic ... ok

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
        assert_eq!(
            lib["codec::tests::d"],
            Outcome::Passed,
            "a should_panic test by its own name"
        );
        assert_eq!(lib.len(), 4, "the test line inside captured output is no result");
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
    fn executables_run_directly_are_parsed_as_under_cargo_with_their_stderr_and_status() {
        use std::os::unix::fs::PermissionsExt;
        let dir = std::env::temp_dir().join(format!("xtask-run-{}", std::process::id()));
        std::fs::create_dir_all(dir.join("deps")).unwrap();
        let exe = dir.join("deps").join("team_e2e-0f0f");
        std::fs::write(
            &exe,
            "#!/bin/sh\necho \"running 2 tests ($PWD) $1\"\necho 'test a ... ok'\necho 'test b ... FAILED'\necho 'panicked: boom' >&2\nexit 101\n",
        )
        .unwrap();
        std::fs::set_permissions(&exe, std::fs::Permissions::from_mode(0o755)).unwrap();
        let pkgs = [Package {
            name: E2E_PACKAGE.into(),
            id: "e".into(),
            dir: dir.clone(),
            lib_names: vec![],
        }];
        let bin = Binary {
            package: E2E_PACKAGE.into(),
            kind: "test".into(),
            target: "team_e2e".into(),
            src_path: dir.join("tests/team_e2e.rs"),
            exe: exe.clone(),
            tests: vec!["a".into(), "b".into()],
        };
        let (r, lines) = run_executables(&pkgs, &[&bin], &[], true, None).unwrap();
        std::fs::remove_dir_all(&dir).unwrap();
        assert_eq!(r.outcomes["team_e2e-0f0f"]["a"], Outcome::Passed);
        assert_eq!(r.outcomes["team_e2e-0f0f"]["b"], Outcome::Failed);
        assert!(!r.exit_ok, "a failing executable fails the group");
        assert_eq!(lines[0], format!("     Running tests/team_e2e.rs ({})", exe.display()));
        assert!(
            lines[1].contains(&format!("({}) --show-output", dir.display())),
            "{}",
            lines[1]
        );
        assert!(lines.iter().any(|l| l == "panicked: boom"), "stderr is kept");
    }

    // verifies: REV-TRACE-02
    #[test]
    fn executable_keys_are_file_names() {
        assert_eq!(exe_key("target/debug/deps/mib-0123abcd"), "mib-0123abcd");
        assert_eq!(exe_key("/abs/target/debug/deps/icd-99"), "icd-99");
    }
}
