//! One job per file and no import circle: no module of `src/` imports, through any chain of
//! `crate::` paths, a module that imports it (the check of `scripts/module_cycles.py`).

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// Module path (`["algorithms", "crba"]`, `[]` for the root) of every `.rs` file under `dir`.
fn modules(dir: &Path, base: &Path, out: &mut BTreeMap<Vec<String>, PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            modules(&path, base, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            let rel = path.strip_prefix(base).unwrap().with_extension("");
            let mut segs: Vec<String> = rel.iter().map(|s| s.to_string_lossy().into_owned()).collect();
            if matches!(segs.last().map(String::as_str), Some("lib" | "mod")) {
                segs.pop();
            }
            out.insert(segs, path);
        }
    }
}

/// The `crate::` paths of one line of code, `use crate::a::{b, c::d}` giving `a::b` and `a::c::d`.
fn crate_paths(code: &str) -> Vec<Vec<String>> {
    let ident = |c: char| c.is_alphanumeric() || c == '_' || c == ':';
    let split = |s: &str| s.split("::").filter(|p| !p.is_empty()).map(str::to_string).collect::<Vec<_>>();
    let mut out = Vec::new();
    for (at, _) in code.match_indices("crate::") {
        let rest = &code[at + "crate::".len()..];
        let head: String = rest.chars().take_while(|&c| ident(c)).collect();
        let after = &rest[head.len()..];
        if let Some(group) = after.strip_prefix('{') {
            let group = &group[..group.find('}').unwrap_or(group.len())];
            for item in group.split(',').map(|i| i.split(" as ").next().unwrap_or("").trim()).filter(|i| !i.is_empty()) {
                let mut p = split(&head);
                if item != "self" {
                    p.extend(split(item));
                }
                out.push(p);
            }
        } else {
            out.push(split(&head));
        }
    }
    out
}

/// The first import circle among the modules under `src`, as a chain of files, and the number
/// of imports between modules.
fn first_circle(src: &Path) -> (Option<String>, usize) {
    let mut files = BTreeMap::new();
    modules(src, src, &mut files);
    // items re-exported at the root, by name: the module they come from
    let root = std::fs::read_to_string(&files[&Vec::<String>::new()]).unwrap();
    let root_code: String = root.lines().map(|l| l.split("//").next().unwrap_or("")).collect::<Vec<_>>().join(" ");
    let mut reexports: BTreeMap<String, Vec<String>> = BTreeMap::new();
    for stmt in root_code.split(';').filter_map(|s| s.trim().strip_prefix("pub use ")) {
        let (module, items) = match stmt.find("::{") {
            Some(k) => (&stmt[..k], stmt[k + 3..].trim_end_matches('}').to_string()),
            None => stmt.rsplit_once("::").map(|(m, i)| (m, i.to_string())).unwrap(),
        };
        for item in items.split(',').map(|i| i.split(" as ").last().unwrap_or("").trim()).filter(|i| !i.is_empty()) {
            reexports.insert(item.to_string(), module.split("::").map(str::to_string).collect());
        }
    }
    // the import graph, module file to module file
    let mut edges: BTreeMap<Vec<String>, BTreeSet<Vec<String>>> = BTreeMap::new();
    for (module, path) in files.iter().filter(|(m, _)| !m.is_empty()) {
        let text = std::fs::read_to_string(path).unwrap();
        let targets = edges.entry(module.clone()).or_default();
        for line in text.lines() {
            for mut segs in crate_paths(line.split("//").next().unwrap_or("")) {
                if let Some(from) = segs.first().and_then(|s| reexports.get(s)) {
                    segs.splice(0..1, from.iter().cloned());
                }
                let target = (0..=segs.len()).rev().map(|k| segs[..k].to_vec()).find(|p| files.contains_key(p)).unwrap_or_default();
                if &target != module {
                    targets.insert(target);
                }
            }
        }
    }
    let count = edges.values().map(BTreeSet::len).sum::<usize>();
    // a path back to `start` from one of its imports is a circle
    for start in edges.keys() {
        let mut stack: Vec<(Vec<String>, Vec<Vec<String>>)> = edges[start].iter().map(|t| (t.clone(), vec![start.clone(), t.clone()])).collect();
        let mut seen = BTreeSet::new();
        while let Some((at, trail)) = stack.pop() {
            if &at == start {
                return (Some(trail.iter().map(|m| files[m].strip_prefix(src).unwrap().display().to_string()).collect::<Vec<_>>().join(" -> ")), count);
            }
            if seen.insert(at.clone()) {
                for next in edges.get(&at).into_iter().flatten() {
                    let mut t = trail.clone();
                    t.push(next.clone());
                    stack.push((next.clone(), t));
                }
            }
        }
    }
    (None, count)
}

#[test]
fn no_module_imports_a_module_that_imports_it() {
    let (circle, imports) = first_circle(&Path::new(env!("CARGO_MANIFEST_DIR")).join("src"));
    assert!(imports > 40, "the scan found only {imports} imports between modules");
    assert_eq!(circle, None, "import circle");
}

/// The diagnosis crate is checked by the same scan: its stages import downwards only.
#[test]
fn no_module_of_the_diagnosis_imports_a_module_that_imports_it() {
    let (circle, imports) = first_circle(&Path::new(env!("CARGO_MANIFEST_DIR")).join("../simgap-diag/src"));
    assert!(imports > 100, "the scan found only {imports} imports between modules");
    assert_eq!(circle, None, "import circle");
}

#[test]
fn the_check_finds_a_circle_through_a_root_reexport() {
    // a.rs imports b's item through the root's re-export, b.rs imports a: a circle
    let dir = std::env::temp_dir().join(format!("simgap-layering-{}", std::process::id()));
    std::fs::create_dir_all(dir.join("algorithms")).unwrap();
    for (file, text) in [
        ("lib.rs", "pub mod algorithms;\npub mod model;\npub use algorithms::crba::{mass_matrix, mass_matrix_into};\n"),
        ("algorithms/mod.rs", "pub mod crba;\n"),
        ("algorithms/crba.rs", "use crate::model::Model; // uses crate::nothing in a comment\npub fn mass_matrix() {}\n"),
        ("model.rs", "pub struct Model;\nfn f() { crate::mass_matrix(); }\n"),
    ] {
        std::fs::write(dir.join(file), text).unwrap();
    }
    let (circle, imports) = first_circle(&dir);
    std::fs::remove_dir_all(&dir).unwrap();
    assert_eq!(imports, 2);
    let circle = circle.expect("the circle crba -> model -> crba is found");
    assert!(circle.contains("algorithms/crba.rs") && circle.contains("model.rs"), "{circle}");
}
