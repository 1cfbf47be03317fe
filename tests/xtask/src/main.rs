//! `cargo run -p xtask -- review [--fast] [--skip-firmware] [--quiet]`
//!
//! Builds, tests and measures the workspace and writes the flight-readiness review
//! package: `target/review/index.html` (self-contained, printable) and
//! `target/review/review.json` (the same data for machines). `--fast` (CI) runs the
//! tests once and checks traceability only: no coverage, firmware, clippy or cargo-deny.
//!
//! Exit status: 0 when every test passed and traceability holds (every requirement has
//! a test, every tag names a known requirement and a real test, untraced tests within
//! the policy of docs/requirements.toml); 1 otherwise; 2 on a usage or tool error.
//! The full review also fails when a requirement is not verified.

#![forbid(unsafe_code)]

mod evidence;
mod extras;
mod report;
mod tags;
mod tests_run;
mod trace;

use anyhow::{Context, Result};
use report::*;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use tests_run::Outcome;

struct Args {
    fast: bool,
    skip_firmware: bool,
    quiet: bool,
}

fn usage() -> ! {
    eprintln!(
        "usage: cargo run -p xtask -- review [--fast] [--skip-firmware] [--quiet]\n\
         \n  --fast           traceability and test results only (CI): no coverage, firmware,\n\
         \x20                  clippy, cargo-deny\n\
         \x20 --skip-firmware  full review without the firmware build and QEMU tests\n\
         \x20 --quiet          do not echo the test output"
    );
    std::process::exit(2)
}

fn parse_args() -> Args {
    let mut a = std::env::args().skip(1);
    if a.next().as_deref() != Some("review") {
        usage();
    }
    let mut args = Args {
        fast: false,
        skip_firmware: false,
        quiet: false,
    };
    for x in a {
        match x.as_str() {
            "--fast" => args.fast = true,
            "--skip-firmware" => args.skip_firmware = true,
            "--quiet" => args.quiet = true,
            _ => usage(),
        }
    }
    args
}

fn workspace_root() -> PathBuf {
    // tests/xtask → workspace root
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .ancestors()
        .nth(2)
        .map(Path::to_path_buf)
        .unwrap_or_else(|| PathBuf::from("."))
}

fn main() {
    let args = parse_args();
    match run(&args) {
        Ok(true) => {}
        Ok(false) => std::process::exit(1),
        Err(e) => {
            eprintln!("review: error: {e:#}");
            std::process::exit(2)
        }
    }
}

fn run(args: &Args) -> Result<bool> {
    let started = std::time::Instant::now();
    let root = workspace_root();
    let out_dir = root.join("target/review");
    std::fs::create_dir_all(&out_dir)?;
    let reqfile = trace::load(&root.join("docs/requirements.toml"))?;
    let pkgs = tests_run::workspace_packages(&root)?;
    // What the tests need (the XTCE cross-check's Python venv) and, for the full review,
    // the review tools; both scripts are idempotent.
    extras::script(&root, "scripts/python-env.sh")?;
    if !args.fast {
        extras::script(&root, "scripts/review-setup.sh")?;
    }

    // Coverage: the one test run is instrumented (cargo llvm-cov show-env), so every test
    // runs exactly once and the same run gives results and coverage.
    let mut env: Vec<(String, String)> = Vec::new();
    let mut coverage_note = String::new();
    let cov_on = !args.fast && extras::llvm_cov_available(&root);
    if cov_on {
        env = extras::llvm_cov_env(&root)?;
    } else if !args.fast {
        coverage_note = "cargo-llvm-cov is not installed (run scripts/review-setup.sh): no coverage".into();
    }

    let bins = tests_run::build_and_list(&root, &pkgs, &env)?;
    let run = tests_run::run_all(
        &root,
        &pkgs,
        &bins,
        &env,
        !args.fast,
        !args.quiet,
        &out_dir.join("tests.log"),
    )?;
    let tr = trace::trace(&pkgs, &bins, &reqfile.requirements, tests_run::exe_name);

    // --- results per test
    let mut tests: Vec<TestRow> = Vec::new();
    for b in &bins {
        let exe = tests_run::exe_name(b);
        let outs = run.outcomes.get(&exe);
        for name in &b.tests {
            let key = trace::TestKey {
                package: b.package.clone(),
                exe: exe.clone(),
                name: name.clone(),
            };
            let outcome = outs.and_then(|o| o.get(name)).copied().unwrap_or(Outcome::NotRun);
            let reqs: Vec<String> = tr
                .verifies
                .get(&key)
                .map(|s| s.iter().cloned().collect())
                .unwrap_or_default();
            let traced_pkg = !reqfile.policy.untraced_packages.contains(&b.package);
            tests.push(TestRow {
                package: b.package.clone(),
                target: format!("{} ({})", b.target, b.kind),
                name: name.clone(),
                outcome,
                requirements: reqs,
                traced: traced_pkg,
            });
        }
    }

    // --- requirements with their tests and status
    let mut requirements = Vec::new();
    for r in &reqfile.requirements {
        let mut rt: Vec<ReqTest> = tests
            .iter()
            .filter(|t| t.requirements.contains(&r.id))
            .map(|t| ReqTest {
                package: t.package.clone(),
                name: t.name.clone(),
                outcome: t.outcome,
            })
            .collect();
        rt.sort_by(|a, b| (&a.package, &a.name).cmp(&(&b.package, &b.name)));
        rt.dedup_by(|a, b| a.package == b.package && a.name == b.name && a.outcome == b.outcome);
        // A requirement verified by analysis, inspection or demonstration (ECSS-E-ST-10-02C)
        // gets its status from its evidence, once the firmware step has run (below).
        let status = if r.method != "test" {
            "not run"
        } else if rt.is_empty() {
            "no test"
        } else if rt.iter().any(|t| t.outcome == Outcome::Failed) {
            "failed"
        } else if rt.iter().all(|t| t.outcome == Outcome::Passed) {
            "verified"
        } else {
            "not run"
        };
        requirements.push(ReqRow {
            id: r.id.clone(),
            text: r.text.clone(),
            source: r.source.clone(),
            method: r.method.clone(),
            criticality: r.criticality.clone(),
            tests: rt,
            evidence: Vec::new(),
            status: status.to_string(),
        });
    }

    // --- traceability findings
    let mut dup = BTreeMap::new();
    for r in &reqfile.requirements {
        *dup.entry(r.id.clone()).or_insert(0) += 1;
    }
    let duplicates: Vec<String> = dup.into_iter().filter(|(_, n)| *n > 1).map(|(k, _)| k).collect();
    let untraced: Vec<String> = tests
        .iter()
        .filter(|t| t.traced && t.requirements.is_empty())
        .map(|t| format!("{} :: {}", t.package, t.name))
        .collect();
    let no_test: Vec<String> = requirements
        .iter()
        .filter(|r| r.tests.is_empty() && r.method == "test")
        .map(|r| r.id.clone())
        .collect();
    let failed: Vec<String> = tests
        .iter()
        .filter(|t| t.outcome == Outcome::Failed)
        .map(|t| format!("{} :: {}", t.package, t.name))
        .collect();
    let not_run = tests.iter().filter(|t| t.outcome == Outcome::NotRun).count();
    let mut trace_findings: Vec<String> = Vec::new();
    for r in reqfile
        .requirements
        .iter()
        .filter(|r| r.method != "test" && r.evidence.is_empty())
    {
        trace_findings.push(format!(
            "requirement {} (verified by {}) names no evidence (docs/review.md: evidence)",
            r.id, r.method
        ));
    }
    for r in &no_test {
        trace_findings.push(format!("requirement {r} has no test"));
    }
    for (tag, id) in &tr.unknown_ids {
        trace_findings.push(format!(
            "{}:{}: tag names unknown requirement {id}",
            rel(&root, &tag.file),
            tag.line
        ));
    }
    for tag in &tr.dangling {
        trace_findings.push(format!(
            "{}:{}: tag above fn {} which is no test libtest lists",
            rel(&root, &tag.file),
            tag.line,
            tag.fn_name
        ));
    }
    for o in &tr.orphans {
        trace_findings.push(format!(
            "{}:{}: tag not followed by a function: {}",
            rel(&root, &o.file),
            o.line,
            o.text
        ));
    }
    for d in &duplicates {
        trace_findings.push(format!("requirement ID {d} defined more than once"));
    }
    let untraced_over = untraced.len() > reqfile.policy.max_untraced_tests;
    if untraced_over {
        trace_findings.push(format!(
            "{} tests without a requirement, policy allows {} (docs/requirements.toml [policy])",
            untraced.len(),
            reqfile.policy.max_untraced_tests
        ));
    }

    let mut checks = vec![Check {
        name: "traceability".into(),
        findings: trace_findings.len(),
        details: trace_findings.clone(),
    }];
    checks.push(Check {
        name: "tests without a requirement (policy tolerance)".into(),
        findings: untraced.len(),
        details: untraced
            .iter()
            .cloned()
            .chain(std::iter::once(format!(
                "tolerated by policy: {} — {}",
                reqfile.policy.max_untraced_tests, reqfile.policy.untraced_note
            )))
            .collect(),
    });

    // --- full review extras
    let mut coverage = Vec::new();
    let mut uncovered = Vec::new();
    let mut budgets = Vec::new();
    let mut firmware = FirmwareInfo::default();
    let mut validation = Vec::new();
    if !args.fast {
        if cov_on {
            match extras::coverage(&root, &pkgs, &env) {
                Ok((c, u)) => {
                    coverage = c;
                    uncovered = u;
                }
                Err(e) => coverage_note = format!("coverage report failed: {e:#}"),
            }
        }
        if args.skip_firmware {
            firmware.note = "firmware step skipped (--skip-firmware): no flash/RAM, QEMU or instruction-count figures in this package".into();
        } else {
            firmware = extras::firmware(&root, &out_dir);
        }
        budgets = extras::budgets(&firmware);
        checks.extend(extras::static_checks(&root, &pkgs));
        validation = extras::validation(&run.outputs, &tests);
    }

    // --- requirements verified by demonstration, analysis or inspection: their evidence
    let fw_log = firmware.ran.then(|| {
        (
            firmware.ok,
            std::fs::read_to_string(out_dir.join("firmware.log")).unwrap_or_default(),
        )
    });
    let mut runs = evidence::Runs::new(!args.fast, fw_log, &out_dir);
    for (r, row) in reqfile.requirements.iter().zip(requirements.iter_mut()) {
        if r.method == "test" {
            continue;
        }
        let (status, shown) = evidence::status(&root, r, row, &mut runs);
        row.status = status;
        row.evidence = shown.into_iter().map(|s| s.text).collect();
    }
    let verified = requirements.iter().filter(|r| r.status == "verified").count();
    validation.extend(extras::validation_rows(&root, &requirements)?);
    checks.push(extras::unsafe_check(&root, &pkgs));
    checks.push(extras::fuzz_check(&root, &tests));
    let fdir = extras::fdir_table(&reqfile.requirements, &requirements);
    let anomalies = extras::anomalies(&root.join("docs/anomalies.toml"))?;

    let summary = Summary {
        mode: if args.fast { "fast".into() } else { "full".into() },
        requirements: requirements.len(),
        verified,
        verified_pct: pct(verified, requirements.len()),
        requirements_without_tests: no_test.len(),
        tests: tests.len(),
        tests_passed: tests.iter().filter(|t| t.outcome == Outcome::Passed).count(),
        tests_failed: failed.len(),
        tests_ignored: tests.iter().filter(|t| t.outcome == Outcome::Ignored).count(),
        tests_not_run: not_run,
        tests_without_requirements: untraced.len(),
        tags: tr.tags,
        tags_matched_by_name_only: tr.fuzzy,
        doc_tests: run.doc_tests.len(),
        doc_tests_failed: run.doc_tests.iter().filter(|d| d.2 == Outcome::Failed).count(),
        test_run_seconds: run.seconds,
        total_seconds: 0.0,
        worst_margin: budgets
            .iter()
            .filter(|b: &&Budget| !b.informational)
            .filter_map(|b: &Budget| b.margin_pct.map(|m| (m, b.item.clone())))
            .min_by(|a, b| a.0.total_cmp(&b.0))
            .map(|(m, i)| format!("{m:.1} % ({i})")),
        coverage_note,
        git: extras::git_describe(&root),
        generated: extras::now_utc(),
    };
    let mut pkg = Package {
        summary,
        requirements,
        tests,
        coverage,
        uncovered,
        budgets,
        firmware,
        fdir,
        checks,
        validation,
        anomalies,
    };
    pkg.summary.total_seconds = started.elapsed().as_secs_f64();
    std::fs::write(out_dir.join("review.json"), serde_json::to_string_pretty(&pkg)?)?;
    std::fs::write(out_dir.join("index.html"), report::html(&pkg))?;

    let s = &pkg.summary;
    eprintln!(
        "== review ({}): {} requirements, {} verified ({:.1} %), {} without tests; {} tests: {} passed, {} failed, {} ignored, {} not run; {} without a requirement (policy {}); {:.0} s",
        s.mode, s.requirements, s.verified, s.verified_pct, s.requirements_without_tests, s.tests,
        s.tests_passed, s.tests_failed, s.tests_ignored, s.tests_not_run, s.tests_without_requirements,
        reqfile.policy.max_untraced_tests, s.total_seconds
    );
    for f in &trace_findings {
        eprintln!("   traceability: {f}");
    }
    for t in &untraced {
        eprintln!("   test without a requirement: {t}");
    }
    for t in &failed {
        eprintln!("   FAILED: {t}");
    }
    if !args.fast {
        for r in pkg.requirements.iter().filter(|r| r.status != "verified") {
            eprintln!(
                "   NOT VERIFIED: {} ({}, {}): {}",
                r.id,
                r.method,
                r.status,
                r.evidence.join(" | ")
            );
        }
    }
    if let Some(w) = &s.worst_margin {
        eprintln!("   worst budget margin: {w}");
    }
    for c in &pkg.coverage {
        eprintln!(
            "   coverage {}: lines {:.1} %, regions {:.1} %",
            c.krate, c.lines_pct, c.regions_pct
        );
    }
    eprintln!("   package: {}", rel(&root, &out_dir.join("index.html")));
    let ok = failed.is_empty() && run.exit_ok && trace_findings.is_empty() && s.doc_tests_failed == 0;
    let ok = ok && (args.fast || pkg.summary.verified == pkg.summary.requirements);
    // A known advisory against a dependency is a finding of its own (full form).
    let advisories = pkg.checks.iter().find(|c| c.name == extras::ADVISORIES);
    for d in advisories
        .filter(|c| c.findings > 0)
        .map_or(&[][..], |c| &c.details[..])
    {
        eprintln!("   ADVISORY: {d}");
    }
    let ok = ok && advisories.is_none_or(|c| c.findings == 0);
    // A resource below the GSFC-STD-1000 flight margin (30 %) is a finding of its own.
    let below: Vec<&Budget> = pkg
        .budgets
        .iter()
        .filter(|b| !b.informational && b.margin_pct.is_some_and(|m| m < extras::FLIGHT_MARGIN_PCT))
        .collect();
    for b in &below {
        eprintln!(
            "   BUDGET below the {} % flight margin: {} — margin {:.1} % ({})",
            extras::FLIGHT_MARGIN_PCT,
            b.item,
            b.margin_pct.unwrap_or_default(),
            b.source
        );
    }
    let ok = ok && below.is_empty();
    if !run.exit_ok && failed.is_empty() {
        eprintln!(
            "   cargo test exited with failure (see {})",
            rel(&root, &out_dir.join("tests.log"))
        );
    }
    Ok(ok)
}

pub fn pct(n: usize, d: usize) -> f64 {
    if d == 0 {
        0.0
    } else {
        100.0 * n as f64 / d as f64
    }
}

pub fn rel(root: &Path, p: &Path) -> String {
    p.strip_prefix(root).unwrap_or(p).display().to_string()
}

/// Context for `?` in helpers.
pub fn read(p: &Path) -> Result<String> {
    std::fs::read_to_string(p).with_context(|| p.display().to_string())
}
