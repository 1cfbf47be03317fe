//! The package's data (serialised to review.json) and its HTML rendering (one
//! self-contained page: inline CSS, no scripts, no external assets, printable).

use crate::tests_run::Outcome;
use serde::Serialize;
use std::fmt::Write;

#[derive(Serialize)]
pub struct Package {
    pub summary: Summary,
    pub requirements: Vec<ReqRow>,
    pub tests: Vec<TestRow>,
    pub coverage: Vec<Coverage>,
    pub uncovered: Vec<Uncovered>,
    pub budgets: Vec<Budget>,
    pub firmware: FirmwareInfo,
    pub fdir: Vec<FdirRow>,
    pub checks: Vec<Check>,
    pub validation: Vec<Validation>,
    pub anomalies: Vec<Anomaly>,
}

#[derive(Serialize)]
pub struct Summary {
    pub mode: String,
    pub requirements: usize,
    pub verified: usize,
    pub verified_pct: f64,
    pub requirements_without_tests: usize,
    pub tests: usize,
    pub tests_passed: usize,
    pub tests_failed: usize,
    pub tests_ignored: usize,
    pub tests_not_run: usize,
    pub tests_without_requirements: usize,
    pub tags: usize,
    pub tags_matched_by_name_only: usize,
    pub doc_tests: usize,
    pub doc_tests_failed: usize,
    pub test_run_seconds: f64,
    pub total_seconds: f64,
    pub worst_margin: Option<String>,
    pub coverage_note: String,
    pub git: String,
    pub generated: String,
}

#[derive(Serialize, Clone)]
pub struct ReqTest {
    pub package: String,
    pub name: String,
    pub outcome: Outcome,
}

#[derive(Serialize)]
pub struct ReqRow {
    pub id: String,
    pub text: String,
    pub source: String,
    pub method: String,
    pub criticality: String,
    pub tests: Vec<ReqTest>,
    /// Evidence of a requirement verified by demonstration, analysis or inspection, as
    /// checked in this run (`crate::evidence`).
    pub evidence: Vec<String>,
    pub status: String,
}

#[derive(Serialize)]
pub struct TestRow {
    pub package: String,
    pub target: String,
    pub name: String,
    pub outcome: Outcome,
    pub requirements: Vec<String>,
    /// False for packages the policy excludes from traceability.
    pub traced: bool,
}

#[derive(Serialize)]
pub struct Coverage {
    #[serde(rename = "crate")]
    pub krate: String,
    pub lines_pct: f64,
    pub regions_pct: f64,
    /// None where the toolchain does not support branch coverage (stable Rust).
    pub branches_pct: Option<f64>,
    pub lines: u64,
    pub lines_covered: u64,
}

#[derive(Serialize)]
pub struct Uncovered {
    #[serde(rename = "crate")]
    pub krate: String,
    pub file: String,
    pub lines: String,
    pub first_line: String,
    /// defensive / unreachable / untested
    pub class: String,
    pub reason: String,
}

#[derive(Serialize)]
pub struct Budget {
    pub item: String,
    pub used: Option<f64>,
    pub available: Option<f64>,
    pub unit: String,
    pub margin_pct: Option<f64>,
    /// Against GSFC-STD-1000 (50 % SRR/PDR, 40 % CDR, 30 % flight).
    pub verdict: String,
    pub source: String,
    /// A bound printed beside a budget that is measured another way: never a finding.
    pub informational: bool,
}

#[derive(Serialize, Default)]
pub struct FirmwareInfo {
    pub ran: bool,
    pub ok: bool,
    pub note: String,
    pub size_lines: Vec<String>,
    pub qemu_summary: String,
    pub qemu_tests: Vec<(String, bool)>,
    pub worst_tick_instructions: Option<u64>,
    pub worst_handle_tc_instructions: Option<u64>,
    /// A whole control period under QEMU (t_budget): worst tick, largest TC frame, TM framing.
    pub period_instructions: Option<u64>,
    /// Stack high-water of the TC frame and TM framing path under QEMU (t_budget).
    pub frame_path_stack: Option<u64>,
    /// Deepest stack use of the on-target tests under QEMU (bytes) and how it was measured.
    pub stack_high_water: Option<u64>,
    pub stack_note: String,
    pub seconds: f64,
}

#[derive(Serialize)]
pub struct FdirRow {
    pub kind: String,
    pub name: String,
    pub detection: String,
    pub persistence: String,
    pub event: String,
    pub reaction: String,
    pub recovery: String,
    pub requirements: Vec<String>,
    pub tests: Vec<ReqTest>,
}

#[derive(Serialize)]
pub struct Check {
    pub name: String,
    pub findings: usize,
    pub details: Vec<String>,
}

#[derive(Serialize)]
pub struct Validation {
    pub figure: String,
    pub paper: String,
    pub ours: String,
    pub evidence: String,
    pub agrees: Option<bool>,
}

#[derive(Serialize, serde::Deserialize, Clone)]
pub struct Anomaly {
    pub id: String,
    pub title: String,
    pub severity: String,
    pub status: String,
    #[serde(default)]
    pub description: String,
    #[serde(default)]
    pub disposition: String,
}

pub fn esc(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

fn outcome_cell(o: Outcome) -> &'static str {
    match o {
        Outcome::Passed => "<span class=ok>passed</span>",
        Outcome::Failed => "<span class=bad>FAILED</span>",
        Outcome::Ignored => "<span class=warn>ignored</span>",
        Outcome::NotRun => "<span class=warn>not run</span>",
    }
}

fn status_cell(s: &str) -> String {
    let class = match s {
        "verified" => "ok",
        "failed" | "no test" => "bad",
        _ => "warn",
    };
    format!("<span class={class}>{}</span>", esc(s))
}

fn opt(v: Option<f64>, digits: usize) -> String {
    v.map(|x| format!("{x:.digits$}")).unwrap_or_else(|| "—".into())
}

const CSS: &str = r#"
body{font-family:system-ui,-apple-system,"Segoe UI",Roboto,sans-serif;margin:2em auto;max-width:80em;color:#111;line-height:1.35;padding:0 1em}
h1{font-size:1.6em;margin-bottom:.2em}h2{border-bottom:2px solid #333;margin-top:2em;page-break-after:avoid}
table{border-collapse:collapse;width:100%;margin:.5em 0;font-size:.88em}
th,td{border:1px solid #bbb;padding:.25em .45em;vertical-align:top;text-align:left}
th{background:#eee}tr{page-break-inside:avoid}
td.n{text-align:right;font-variant-numeric:tabular-nums;white-space:nowrap}
code,.mono{font-family:ui-monospace,Menlo,Consolas,monospace;font-size:.92em;word-break:break-all}
.ok{color:#0a6b2c;font-weight:600}.bad{color:#b00020;font-weight:700}.warn{color:#9a6200;font-weight:600}
.kpi{display:flex;flex-wrap:wrap;gap:.8em}.kpi div{border:1px solid #999;padding:.5em .8em;min-width:10em}
.kpi b{display:block;font-size:1.4em}
nav ol{columns:2}
details summary{cursor:pointer}
@media print{nav{display:none}details{display:block}details>summary{display:none}body{max-width:none;margin:0}a{color:inherit;text-decoration:none}}
"#;

pub fn html(p: &Package) -> String {
    let s = &p.summary;
    let mut h = String::new();
    let _ = write!(
        h,
        "<!doctype html><html lang=en><head><meta charset=utf-8><title>MMIC-I flight-readiness review package</title><style>{CSS}</style></head><body>"
    );
    let _ = write!(
        h,
        "<h1>MMIC-I flight software — flight-readiness review package</h1><p>Generated {} from <code>{}</code> by <code>cargo run -p xtask -- review{}</code> ({} mode, {:.0} s). How to read it: <code>docs/review.md</code>. Machine-readable: <code>review.json</code> beside this file.</p>",
        esc(&s.generated),
        esc(&s.git),
        if s.mode == "fast" { " --fast" } else { "" },
        esc(&s.mode),
        s.total_seconds
    );
    h.push_str("<nav><ol><li><a href=#summary>Summary</a><li><a href=#req>Requirements and verification</a><li><a href=#untraced>Tests without requirements</a><li><a href=#cov>Structural coverage</a><li><a href=#budgets>Resource budgets</a><li><a href=#fdir>FDIR table</a><li><a href=#checks>Static analysis and checks</a><li><a href=#val>Validation against the paper</a><li><a href=#anom>Open anomalies</a><li><a href=#tests>All test results</a></ol></nav>");

    // summary
    let _ = write!(h, "<h2 id=summary>1. Summary</h2><div class=kpi>");
    let kpi = |h: &mut String, label: &str, val: String| {
        let _ = write!(h, "<div><b>{}</b>{}</div>", esc(&val), esc(label));
    };
    kpi(&mut h, "requirements", s.requirements.to_string());
    kpi(&mut h, "verified", format!("{} ({:.1} %)", s.verified, s.verified_pct));
    kpi(
        &mut h,
        "requirements without tests",
        s.requirements_without_tests.to_string(),
    );
    kpi(&mut h, "tests run", format!("{} ({} passed)", s.tests, s.tests_passed));
    kpi(
        &mut h,
        "failed / ignored / not run",
        format!("{} / {} / {}", s.tests_failed, s.tests_ignored, s.tests_not_run),
    );
    kpi(
        &mut h,
        "tests without requirements",
        s.tests_without_requirements.to_string(),
    );
    if let Some(w) = &s.worst_margin {
        kpi(&mut h, "worst budget margin", w.clone());
    }
    for c in &p.coverage {
        kpi(
            &mut h,
            &format!("line coverage {}", c.krate),
            format!("{:.1} %", c.lines_pct),
        );
    }
    h.push_str("</div>");
    let _ = write!(
        h,
        "<p>{} requirement tags in the sources ({} resolved by function name only). {} doc tests ({} failed) ran as well; they illustrate APIs and are not traced. Test run {:.0} s.</p>",
        s.tags, s.tags_matched_by_name_only, s.doc_tests, s.doc_tests_failed, s.test_run_seconds
    );
    if !s.coverage_note.is_empty() {
        let _ = write!(h, "<p class=warn>{}</p>", esc(&s.coverage_note));
    }

    // requirements
    let _ = write!(
        h,
        "<h2 id=req>2. Requirements and verification</h2><p>Source of the list: <code>docs/requirements.toml</code>. A requirement is <i>verified</i> only when every test tagged with its ID passed in this run. A test states what it verifies by a comment <code>// verifies: ID</code> directly above the function; the exact name below runs with <code>cargo test -p PACKAGE -- --exact NAME</code>.</p><table><tr><th>ID</th><th>requirement</th><th>source</th><th>method</th><th>crit.</th><th>tests (package :: exact name)</th><th>status</th></tr>"
    );
    for r in &p.requirements {
        let mut tests = String::new();
        for t in &r.tests {
            let _ = write!(
                tests,
                "<div class=mono>{} :: {} {}</div>",
                esc(&t.package),
                esc(&t.name),
                outcome_cell(t.outcome)
            );
        }
        for e in &r.evidence {
            let _ = write!(tests, "<div>evidence: {}</div>", esc(e));
        }
        let _ = write!(
            h,
            "<tr id=\"{id}\"><td class=mono>{id}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{tests}</td><td>{}</td></tr>",
            esc(&r.text),
            esc(&r.source),
            esc(&r.method),
            esc(&r.criticality),
            status_cell(&r.status),
            id = esc(&r.id)
        );
    }
    h.push_str("</table>");

    // untraced
    let untraced: Vec<&TestRow> = p
        .tests
        .iter()
        .filter(|t| t.traced && t.requirements.is_empty())
        .collect();
    let _ = write!(
        h,
        "<h2 id=untraced>3. Tests without requirements ({})</h2>",
        untraced.len()
    );
    if untraced.is_empty() {
        h.push_str("<p class=ok>None.</p>");
    } else {
        h.push_str("<table><tr><th>package</th><th>exact name</th><th>outcome</th></tr>");
        for t in untraced {
            let _ = write!(
                h,
                "<tr><td>{}</td><td class=mono>{}</td><td>{}</td></tr>",
                esc(&t.package),
                esc(&t.name),
                outcome_cell(t.outcome)
            );
        }
        h.push_str("</table>");
    }
    let not_traced_pkgs: Vec<&TestRow> = p.tests.iter().filter(|t| !t.traced).collect();
    if !not_traced_pkgs.is_empty() {
        let _ = write!(
            h,
            "<p>{} tests of the review tool itself are outside the traceability policy.</p>",
            not_traced_pkgs.len()
        );
    }

    // coverage
    h.push_str("<h2 id=cov>4. Structural coverage</h2>");
    if p.coverage.is_empty() {
        let _ = write!(
            h,
            "<p class=warn>Not measured in this run. {}</p>",
            esc(&s.coverage_note)
        );
    } else {
        h.push_str("<p>cargo-llvm-cov (source-based coverage) over the one instrumented test run. Branch coverage needs a nightly toolchain (<code>-Z coverage-options=branch</code>); with stable Rust it is not available and shown as —. Targets (NASA practice): 80 % CDR, 90 % SIR, 100 % TRR. Crates in bold are held to ≥ 90 % lines.</p><table><tr><th>crate</th><th>lines %</th><th>regions %</th><th>branches %</th><th>lines covered / total</th></tr>");
        for c in &p.coverage {
            let strong = matches!(c.krate.as_str(), "obsw-core" | "mmic-domain" | "mib");
            let name = if strong {
                format!("<b>{}</b>", esc(&c.krate))
            } else {
                esc(&c.krate)
            };
            let cls = if strong && c.lines_pct < 90.0 { "bad" } else { "" };
            let _ = write!(
                h,
                "<tr><td>{name}</td><td class=\"n {cls}\">{:.1}</td><td class=n>{:.1}</td><td class=n>{}</td><td class=n>{} / {}</td></tr>",
                c.lines_pct, c.regions_pct, opt(c.branches_pct, 1), c.lines_covered, c.lines
            );
        }
        h.push_str("</table>");
        let _ = write!(
            h,
            "<h3>Uncovered code of obsw-core, mmic-domain and mib ({} ranges)</h3><p>Each uncovered line range, classified from the reviewed list <code>docs/coverage-review.toml</code>: <i>defensive</i> (handles a condition the callers prevent, kept on purpose), <i>unreachable</i> (cannot execute), <i>untested</i> (reachable and not exercised by a test — a gap).</p><details><summary>show the list</summary><table><tr><th>crate</th><th>file</th><th>lines</th><th>first line</th><th>class</th><th>why</th></tr>",
            p.uncovered.len()
        );
        for u in &p.uncovered {
            let cls = if u.class == "untested" { "warn" } else { "" };
            let _ = write!(
                h,
                "<tr><td>{}</td><td class=mono>{}</td><td class=n>{}</td><td class=mono>{}</td><td class={cls}>{}</td><td>{}</td></tr>",
                esc(&u.krate), esc(&u.file), esc(&u.lines), esc(&u.first_line), esc(&u.class), esc(&u.reason)
            );
        }
        h.push_str("</table></details>");
    }

    // budgets
    h.push_str("<h2 id=budgets>5. Resource budgets</h2><p>Margin = (available − used) / available. GSFC-STD-1000 requires 50 % at SRR/PDR, 40 % at CDR, 30 % at flight for CPU and memory.</p><table><tr><th>item</th><th>used</th><th>available</th><th>unit</th><th>margin %</th><th>verdict</th><th>source</th></tr>");
    for b in &p.budgets {
        let cls = match b.margin_pct {
            Some(m) if m >= 50.0 => "ok",
            Some(m) if m >= 30.0 => "warn",
            Some(_) => "bad",
            None => "warn",
        };
        let _ = write!(
            h,
            "<tr><td>{}</td><td class=n>{}</td><td class=n>{}</td><td>{}</td><td class=\"n {cls}\">{}</td><td>{}</td><td>{}</td></tr>",
            esc(&b.item), opt(b.used, 0), opt(b.available, 0), esc(&b.unit), opt(b.margin_pct, 1), esc(&b.verdict), esc(&b.source)
        );
    }
    h.push_str("</table>");
    let fw = &p.firmware;
    if fw.ran {
        let _ = write!(
            h,
            "<p>Firmware step (<code>scripts/firmware-ci.sh</code>): {} in {:.0} s. QEMU: {}.</p><pre class=mono>{}</pre>",
            if fw.ok { "<span class=ok>passed</span>" } else { "<span class=bad>FAILED</span>" },
            fw.seconds,
            esc(&fw.qemu_summary),
            esc(&fw.size_lines.join("\n"))
        );
        if !fw.qemu_tests.is_empty() {
            let _ = write!(h, "<details><summary>{} on-target tests (QEMU riscv32imc)</summary><table><tr><th>test</th><th>outcome</th></tr>", fw.qemu_tests.len());
            for (n, ok) in &fw.qemu_tests {
                let o = if *ok { Outcome::Passed } else { Outcome::Failed };
                let _ = write!(h, "<tr><td class=mono>{}</td><td>{}</td></tr>", esc(n), outcome_cell(o));
            }
            h.push_str("</table></details>");
        }
    }
    if !fw.note.is_empty() {
        let _ = write!(h, "<p class=warn>{}</p>", esc(&fw.note));
    }

    // fdir
    h.push_str("<h2 id=fdir>6. FDIR table (from the MIB)</h2><p>Faults of the paper's Table 8 (<code>mib::fdir::FAULTS</code>) and the PUS 12 monitors (<code>mib::fdir::MONITORS</code>); the demonstrating tests are those of the requirements listed.</p><table><tr><th>kind</th><th>name</th><th>detection</th><th>persistence</th><th>event</th><th>reaction</th><th>recovery</th><th>demonstrated by</th></tr>");
    for f in &p.fdir {
        let mut t = String::new();
        for r in &f.requirements {
            let _ = write!(t, "<div><a href=\"#{0}\" class=mono>{0}</a></div>", esc(r));
        }
        for x in &f.tests {
            let _ = write!(t, "<div class=mono>{} {}</div>", esc(&x.name), outcome_cell(x.outcome));
        }
        if f.tests.is_empty() {
            t.push_str("<span class=bad>no test</span>");
        }
        let _ = write!(
            h,
            "<tr><td>{}</td><td class=mono>{}</td><td>{}</td><td>{}</td><td class=mono>{}</td><td>{}</td><td>{}</td><td>{t}</td></tr>",
            esc(&f.kind), esc(&f.name), esc(&f.detection), esc(&f.persistence), esc(&f.event), esc(&f.reaction), esc(&f.recovery)
        );
    }
    h.push_str("</table>");

    // checks
    h.push_str("<h2 id=checks>7. Static analysis and checks</h2><table><tr><th>check</th><th>findings</th><th>details</th></tr>");
    for c in &p.checks {
        let cls = if c.findings == 0 { "ok" } else { "warn" };
        let mut d = String::new();
        let shown = c.details.len().min(400);
        for x in &c.details[..shown] {
            let _ = write!(d, "<div class=mono>{}</div>", esc(x));
        }
        if c.details.len() > shown {
            let _ = write!(d, "<div>… {} more in review.json</div>", c.details.len() - shown);
        }
        let body = if c.details.len() > 8 {
            format!("<details><summary>{} lines</summary>{d}</details>", c.details.len())
        } else {
            d
        };
        let _ = write!(
            h,
            "<tr><td>{}</td><td class=\"n {cls}\">{}</td><td>{body}</td></tr>",
            esc(&c.name),
            c.findings
        );
    }
    h.push_str("</table>");

    // validation
    h.push_str("<h2 id=val>8. Validation against the paper</h2>");
    if p.validation.is_empty() {
        h.push_str("<p class=warn>Not evaluated in the fast form.</p>");
    } else {
        h.push_str(
            "<table><tr><th>figure</th><th>paper</th><th>this software</th><th>evidence</th><th>agrees</th></tr>",
        );
        for v in &p.validation {
            let a = match v.agrees {
                Some(true) => "<span class=ok>yes</span>",
                Some(false) => "<span class=bad>no</span>",
                None => "<span class=warn>not measured</span>",
            };
            let _ = write!(
                h,
                "<tr><td>{}</td><td>{}</td><td>{}</td><td class=mono>{}</td><td>{a}</td></tr>",
                esc(&v.figure),
                esc(&v.paper),
                esc(&v.ours),
                esc(&v.evidence)
            );
        }
        h.push_str("</table>");
    }

    // anomalies
    h.push_str("<h2 id=anom>9. Open anomalies</h2><p>From <code>docs/anomalies.toml</code>.</p><table><tr><th>ID</th><th>title</th><th>severity</th><th>status</th><th>description</th><th>disposition</th></tr>");
    for a in &p.anomalies {
        let _ = write!(
            h,
            "<tr><td class=mono>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
            esc(&a.id),
            esc(&a.title),
            esc(&a.severity),
            esc(&a.status),
            esc(&a.description),
            esc(&a.disposition)
        );
    }
    h.push_str("</table>");

    // all tests
    let _ = write!(h, "<h2 id=tests>10. All test results ({})</h2><details><summary>show all tests</summary><table><tr><th>package</th><th>target</th><th>exact name</th><th>outcome</th><th>verifies</th></tr>", p.tests.len());
    for t in &p.tests {
        let _ = write!(
            h,
            "<tr><td>{}</td><td>{}</td><td class=mono>{}</td><td>{}</td><td class=mono>{}</td></tr>",
            esc(&t.package),
            esc(&t.target),
            esc(&t.name),
            outcome_cell(t.outcome),
            esc(&t.requirements.join(", "))
        );
    }
    h.push_str("</table></details></body></html>\n");
    h
}
