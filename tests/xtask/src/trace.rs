//! Requirements (docs/requirements.toml) and their traceability to the tests that
//! verify them (tags in the test sources, matched to the exact names libtest lists).

use crate::tags::{self, Orphan, Tag};
use crate::tests_run::{Binary, Package};
use anyhow::{Context, Result};
use serde::{Deserialize, Serialize};
use std::collections::{BTreeMap, BTreeSet};
use std::path::{Component, Path, PathBuf};

#[derive(Clone, Debug, Deserialize, Serialize)]
pub struct Requirement {
    pub id: String,
    pub text: String,
    pub source: String,
    pub method: String,
    pub criticality: String,
    /// FDIR rows this requirement demonstrates: fault event names or `MON:<monitor name>`.
    #[serde(default)]
    pub fdir: Vec<String>,
    /// What shows a requirement verified by demonstration, analysis or inspection
    /// (`crate::evidence`).
    #[serde(default)]
    pub evidence: Vec<crate::evidence::Evidence>,
}

#[derive(Clone, Debug, Default, Deserialize, Serialize)]
pub struct Policy {
    /// Tests without a requirement tolerated by `review --fast` (a ratchet: lower it as
    /// tests get tagged; 0 is the goal).
    #[serde(default)]
    pub max_untraced_tests: usize,
    /// Why the tolerance is not 0 (shown in the package).
    #[serde(default)]
    pub untraced_note: String,
    /// Packages whose tests are not traced (the review tool's own tests, for example).
    #[serde(default)]
    pub untraced_packages: Vec<String>,
}

#[derive(Clone, Debug, Deserialize)]
pub struct RequirementsFile {
    #[serde(default)]
    pub policy: Policy,
    #[serde(rename = "requirement")]
    pub requirements: Vec<Requirement>,
}

/// Extra requirement files, one per area of the product (`docs/requirements/*.toml`): only
/// `[[requirement]]` blocks; the policy stays in the main file.
#[derive(Clone, Debug, Deserialize)]
struct AreaFile {
    #[serde(rename = "requirement", default)]
    requirements: Vec<Requirement>,
}

/// Loads the main requirements file and every `*.toml` in the `requirements/` folder beside
/// it (sorted by name). A requirement ID defined twice is an error naming both files.
pub fn load(path: &Path) -> Result<RequirementsFile> {
    let s = std::fs::read_to_string(path).with_context(|| format!("{}", path.display()))?;
    let mut f: RequirementsFile = toml::from_str(&s).with_context(|| format!("{}", path.display()))?;
    let mut origin: BTreeMap<String, PathBuf> = f
        .requirements
        .iter()
        .map(|r| (r.id.clone(), path.to_path_buf()))
        .collect();
    let dir = path.with_file_name("requirements");
    let mut extra: Vec<PathBuf> = match std::fs::read_dir(&dir) {
        Ok(rd) => rd
            .flatten()
            .map(|e| e.path())
            .filter(|p| p.extension().is_some_and(|x| x == "toml"))
            .collect(),
        Err(_) => Vec::new(),
    };
    extra.sort();
    for p in extra {
        let s = std::fs::read_to_string(&p).with_context(|| format!("{}", p.display()))?;
        let a: AreaFile = toml::from_str(&s).with_context(|| format!("{}", p.display()))?;
        for r in a.requirements {
            if let Some(first) = origin.get(&r.id) {
                anyhow::bail!(
                    "requirement {} is defined in {} and again in {}",
                    r.id,
                    first.display(),
                    p.display()
                );
            }
            origin.insert(r.id.clone(), p.clone());
            f.requirements.push(r);
        }
    }
    Ok(f)
}

/// One test of one binary.
#[derive(Clone, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub struct TestKey {
    pub package: String,
    pub exe: String,
    pub name: String,
}

#[derive(Debug, Default)]
pub struct Trace {
    /// test → requirement IDs
    pub verifies: BTreeMap<TestKey, BTreeSet<String>>,
    /// tags whose function is not a test libtest lists
    pub dangling: Vec<Tag>,
    pub orphans: Vec<Orphan>,
    /// tags naming an ID that is not in the requirements file
    pub unknown_ids: Vec<(Tag, String)>,
    /// tags resolved by the fallback (function name only)
    pub fuzzy: usize,
    pub tags: usize,
}

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(rd) = std::fs::read_dir(dir) else {
        return;
    };
    for e in rd.flatten() {
        let p = e.path();
        let name = e.file_name().to_string_lossy().into_owned();
        if p.is_dir() {
            if name == "target" || name.starts_with('.') {
                continue;
            }
            rust_files(&p, out);
        } else if name.ends_with(".rs") {
            out.push(p);
        }
    }
}

/// Module path of `file` inside a target whose root file is `root`.
fn module_path(root: &Path, file: &Path) -> Option<Vec<String>> {
    if file == root {
        return Some(Vec::new());
    }
    let dir = root.parent()?;
    let rel = file.strip_prefix(dir).ok()?;
    let mut parts: Vec<String> = rel
        .components()
        .filter_map(|c| match c {
            Component::Normal(s) => Some(s.to_string_lossy().into_owned()),
            _ => None,
        })
        .collect();
    let last = parts.pop()?;
    let stem = last.strip_suffix(".rs")?.to_string();
    if stem != "mod" {
        parts.push(stem);
    }
    Some(parts)
}

fn package_of<'a>(pkgs: &'a [Package], file: &Path) -> Option<&'a Package> {
    pkgs.iter()
        .filter(|p| file.starts_with(&p.dir))
        .max_by_key(|p| p.dir.components().count())
}

pub fn trace(pkgs: &[Package], bins: &[Binary], reqs: &[Requirement], exe_name: impl Fn(&Binary) -> String) -> Trace {
    let known: BTreeSet<&str> = reqs.iter().map(|r| r.id.as_str()).collect();
    let mut t = Trace::default();
    for pkg in pkgs {
        let mut files = Vec::new();
        rust_files(&pkg.dir, &mut files);
        files.sort();
        for f in files {
            if package_of(pkgs, &f).map(|p| &p.name) != Some(&pkg.name) {
                continue; // a nested package's file
            }
            let Ok(src) = std::fs::read_to_string(&f) else {
                continue;
            };
            if !src.contains(tags::MARKER) {
                continue;
            }
            let (tags_found, orphans) = tags::scan(&f, &src);
            t.orphans.extend(orphans);
            for tag in tags_found {
                t.tags += 1;
                for id in &tag.ids {
                    if !known.contains(id.as_str()) {
                        t.unknown_ids.push((tag.clone(), id.clone()));
                    }
                }
                let ids: BTreeSet<String> = tag.ids.iter().filter(|i| known.contains(i.as_str())).cloned().collect();
                let pbins: Vec<&Binary> = bins.iter().filter(|b| b.package == pkg.name).collect();
                let mut hits: Vec<TestKey> = Vec::new();
                for b in &pbins {
                    let under_tests = f.starts_with(pkg.dir.join("tests"));
                    let is_test_target = b.kind == "test";
                    if under_tests != is_test_target {
                        continue;
                    }
                    let Some(mut path) = module_path(&b.src_path, &f) else {
                        continue;
                    };
                    path.extend(tag.inline_mods.iter().cloned());
                    path.push(tag.fn_name.clone());
                    let full = path.join("::");
                    if b.tests.contains(&full) {
                        hits.push(TestKey {
                            package: pkg.name.clone(),
                            exe: exe_name(b),
                            name: full,
                        });
                    }
                }
                if hits.is_empty() {
                    // Fallback: the function name (with its inline modules) as a suffix.
                    let mut suffix = tag.inline_mods.clone();
                    suffix.push(tag.fn_name.clone());
                    let suffix = suffix.join("::");
                    for b in &pbins {
                        for n in &b.tests {
                            if *n == suffix || n.ends_with(&format!("::{suffix}")) {
                                hits.push(TestKey {
                                    package: pkg.name.clone(),
                                    exe: exe_name(b),
                                    name: n.clone(),
                                });
                            }
                        }
                    }
                    if !hits.is_empty() {
                        t.fuzzy += 1;
                    }
                }
                if hits.is_empty() {
                    t.dangling.push(tag);
                    continue;
                }
                for h in hits {
                    t.verifies.entry(h).or_default().extend(ids.iter().cloned());
                }
            }
        }
    }
    t
}

#[cfg(test)]
mod tests {
    use super::*;

    // verifies: REV-TRACE-01
    #[test]
    fn module_paths_follow_the_file_layout() {
        let root = Path::new("/w/p/src/lib.rs");
        assert_eq!(module_path(root, root), Some(vec![]));
        assert_eq!(
            module_path(root, Path::new("/w/p/src/services/hk.rs")),
            Some(vec!["services".to_string(), "hk".to_string()])
        );
        assert_eq!(
            module_path(root, Path::new("/w/p/src/services/mod.rs")),
            Some(vec!["services".to_string()])
        );
        let it = Path::new("/w/p/tests/e2e.rs");
        assert_eq!(module_path(it, it), Some(vec![]));
        assert_eq!(module_path(root, Path::new("/elsewhere/x.rs")), None);
    }
}
