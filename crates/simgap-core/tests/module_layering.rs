//! One job per file and no import circle: in no crate of the workspace (`crates/*/src`, the
//! umbrella's `src/`, the bindings' `python/src`) and not in the Python package `python/simgap`
//! does a file import, through any chain of imports, a file that imports it; nor does a
//! top-level module (a stage) import, through any chain, a stage that imports it.
//!
//! An import is a path in code (comments and `#[cfg(test)] mod tests` left out) starting with
//! `crate::`, `super::` or `self::`, a `use` of one with its groups expanded (`use
//! crate::{a::b, c::{d, e}}`), or an item the crate root re-exports (`crate::mass_matrix`); in
//! Python, `from . import x`, `from .a import x`, `from simgap.a import x` and `import
//! simgap.a`, at any indentation (lazy imports and `if TYPE_CHECKING:` ones count). An import
//! names the deepest module file its path reaches. A module reading its own folder (an
//! ancestor: `super::Item` of `a/mod.rs` from `a/b.rs`) is its context, not an import, as a
//! folder declares the files it holds.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// A module's path below its crate or package root (`["algorithms", "crba"]`, `[]` for the root).
type Module = Vec<String>;

/// The modules of a crate or package (each with its file) and the imports between them.
struct Graph {
    /// Every module with its file.
    files: BTreeMap<Module, PathBuf>,
    /// For each module, the modules it imports (neither itself nor an ancestor).
    edges: BTreeMap<Module, BTreeSet<Module>>,
    /// Where the files are, to name them in a circle.
    base: PathBuf,
}

/// What the scan found in one crate or package.
#[derive(Debug)]
struct Layering {
    /// Imports between modules (file to file).
    imports: usize,
    /// The first circle among files, as a chain of files.
    file_circle: Option<String>,
    /// The first circle among top-level modules (stages), as a chain of stages.
    stage_circle: Option<String>,
}

/// Every file with extension `ext` under `dir`, recursively.
fn files_under(dir: &Path, ext: &str, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            files_under(&path, ext, out);
        } else if path.extension().is_some_and(|e| e == ext) {
            out.push(path);
        }
    }
}

/// The module path of a file below `base`, dropping a last segment in `roots` (`lib`, `main`,
/// `mod`; `__init__`).
fn module_of(path: &Path, base: &Path, roots: &[&str]) -> Module {
    let rel = path.strip_prefix(base).unwrap().with_extension("");
    let mut segs: Module = rel.iter().map(|s| s.to_string_lossy().into_owned()).collect();
    if segs.last().is_some_and(|s| roots.contains(&s.as_str())) {
        segs.pop();
    }
    segs
}

/// Splits `text` at the commas outside braces.
fn split_top(text: &str) -> Vec<&str> {
    let (mut depth, mut start, mut out) = (0usize, 0, Vec::new());
    for (i, c) in text.char_indices() {
        match c {
            '{' => depth += 1,
            '}' => depth = depth.saturating_sub(1),
            ',' if depth == 0 => {
                out.push(&text[start..i]);
                start = i + 1;
            }
            _ => {}
        }
    }
    out.push(&text[start..]);
    out
}

/// The paths of a use tree, groups expanded, each with the name it binds: `a::{b, c::{d as e,
/// self}}` gives `a::b` (`b`), `a::c::d` (`e`) and `a::c` (`c`); a glob (`a::*`) names `a`.
fn expand(tree: &str) -> Vec<(Module, String)> {
    let tree = tree.trim();
    let (head, group, alias) = match tree.find('{') {
        Some(k) => (&tree[..k], Some(&tree[k + 1..tree.rfind('}').unwrap_or(tree.len())]), None),
        None => match tree.split_once(" as ") {
            Some((path, alias)) => (path, None, Some(alias.trim())),
            None => (tree, None, None),
        },
    };
    let prefix: Module = head.split("::").map(str::trim).filter(|s| !s.is_empty() && *s != "*").map(str::to_string).collect();
    let Some(group) = group else {
        let name = alias.map(str::to_string).or_else(|| prefix.last().cloned()).unwrap_or_default();
        return vec![(prefix, name)];
    };
    let mut out = Vec::new();
    for item in split_top(group).into_iter().map(str::trim).filter(|i| !i.is_empty()) {
        for (tail, name) in expand(item) {
            let mut p = prefix.clone();
            p.extend(tail.into_iter().filter(|s| s != "self"));
            let name = if name == "self" { p.last().cloned().unwrap_or_default() } else { name };
            out.push((p, name));
        }
    }
    out
}

/// The paths in `code` that start with `crate::`, `super::` or `self::`, groups expanded, each
/// with its keyword(s) first (`["super", "super", "a", "b"]`).
fn keyword_paths(code: &str) -> Vec<Module> {
    let ident = |c: char| c.is_alphanumeric() || c == '_';
    let mut out = Vec::new();
    let mut at = 0;
    while let Some(k) = ["crate::", "super::", "self::"].iter().filter_map(|kw| code[at..].find(kw).map(|p| at + p)).min() {
        // the start of a path: not the tail of a longer one, nor `$crate` of a macro
        let before = code[..k].chars().next_back();
        let starts = !before.is_some_and(|c| ident(c) || c == ':' || c == '$');
        let mut end = k;
        if starts {
            // the path: identifiers and `::`, then a balanced group
            let rest = &code[k..];
            let mut len = rest.find(|c: char| !(ident(c) || c == ':')).unwrap_or(rest.len());
            if rest[len..].starts_with('{') {
                let mut depth = 0;
                for (i, c) in rest[len..].char_indices() {
                    depth += match c {
                        '{' => 1,
                        '}' => -1,
                        _ => 0,
                    };
                    if depth == 0 {
                        len += i + 1;
                        break;
                    }
                }
            }
            out.extend(expand(&rest[..len]).into_iter().map(|(p, _)| p));
            end = k + len;
        }
        at = end.max(k + 1);
        while !code.is_char_boundary(at) {
            at += 1;
        }
    }
    out
}

/// `text` without `//` comments (doc comments too: a doc link is no import) and without a
/// trailing `#[cfg(test)] mod tests { ... }` (its `super` is the file itself).
fn rust_code(text: &str) -> String {
    let tests = text.match_indices("#[cfg(test)]").map(|(k, _)| k).find(|&k| text[k + "#[cfg(test)]".len()..].trim_start().starts_with("mod tests"));
    let text = &text[..tests.unwrap_or(text.len())];
    text.lines().map(|l| l.split("//").next().unwrap_or("")).collect::<Vec<_>>().join("\n")
}

/// The import graph of the Rust crate whose sources are under `src`.
fn rust_graph(src: &Path) -> Graph {
    let mut paths = Vec::new();
    files_under(src, "rs", &mut paths);
    let files: BTreeMap<Module, PathBuf> = paths.iter().map(|p| (module_of(p, src, &["lib", "main", "mod"]), p.clone())).collect();
    // items re-exported at the root, by name: the module they come from
    let mut reexports: BTreeMap<String, Module> = BTreeMap::new();
    for root in ["lib.rs", "main.rs"].map(|f| src.join(f)).iter().filter(|p| p.exists()) {
        let code = rust_code(&std::fs::read_to_string(root).unwrap());
        for stmt in code.split(';').filter_map(|s| s.trim().strip_prefix("pub use ")) {
            for (path, name) in expand(stmt.trim_start_matches("crate::").trim_start_matches("self::")) {
                reexports.insert(name, path[..path.len().saturating_sub(1)].to_vec());
            }
        }
    }
    // the import graph, module file to module file
    let mut edges: BTreeMap<Module, BTreeSet<Module>> = BTreeMap::new();
    for (module, path) in files.iter().filter(|(m, _)| !m.is_empty()) {
        let code = rust_code(&std::fs::read_to_string(path).unwrap());
        let targets = edges.entry(module.clone()).or_default();
        for segs in keyword_paths(&code) {
            // the path from the crate root
            let mut full: Module = match segs[0].as_str() {
                "crate" => Vec::new(),
                "self" => module.clone(),
                _ => module[..module.len() - 1].to_vec(),
            };
            let mut rest = &segs[1..];
            while rest.first().is_some_and(|s| s == "super") {
                full.pop();
                rest = &rest[1..];
            }
            if segs[0] == "crate" && !rest.is_empty() && !files.contains_key(&rest[..1]) {
                if let Some(from) = reexports.get(&rest[0]) {
                    full.extend(from.iter().cloned());
                }
            }
            full.extend(rest.iter().cloned());
            // the deepest module file it reaches, unless the module itself or an ancestor
            let target = (0..=full.len()).rev().map(|k| full[..k].to_vec()).find(|p| files.contains_key(p)).unwrap_or_default();
            if !module.starts_with(&target) {
                targets.insert(target);
            }
        }
    }
    Graph { files, edges, base: src.to_path_buf() }
}

/// The import graph of the Python package under `package` (its name is the folder's).
fn python_graph(package: &Path) -> Graph {
    let name = package.file_name().unwrap().to_string_lossy().into_owned();
    let mut paths = Vec::new();
    files_under(package, "py", &mut paths);
    let files: BTreeMap<Module, PathBuf> = paths.iter().map(|p| (module_of(p, package, &["__init__"]), p.clone())).collect();
    let mut edges: BTreeMap<Module, BTreeSet<Module>> = BTreeMap::new();
    for (module, path) in files.iter().filter(|(m, _)| !m.is_empty()) {
        let text = std::fs::read_to_string(path).unwrap();
        // code without docstrings and comments, continued lines joined
        let mut code = String::new();
        for (k, part) in text.split("\"\"\"").enumerate() {
            if k % 2 == 0 {
                code.push_str(part);
            }
        }
        let code: Vec<String> = code.lines().map(|l| l.split('#').next().unwrap_or("").to_string()).collect();
        let code = code.join("\n").replace("(\n", "(").replace(",\n", ",");
        // the package a relative import starts from: the file's own for `__init__.py`
        let is_package = path.file_name().is_some_and(|f| f == "__init__.py");
        let here: Module = if is_package { module.clone() } else { module[..module.len() - 1].to_vec() };
        let targets = edges.entry(module.clone()).or_default();
        for line in code.lines().map(str::trim) {
            let (from, names): (Module, Vec<String>) = if let Some(rest) = line.strip_prefix("from ") {
                let Some((source, names)) = rest.split_once(" import ") else { continue };
                let dots = source.len() - source.trim_start_matches('.').len();
                let tail: Module = source[dots..].split('.').filter(|s| !s.is_empty()).map(str::to_string).collect();
                let base = if dots > 0 {
                    here[..here.len().saturating_sub(dots - 1)].to_vec()
                } else if tail.first() == Some(&name) {
                    Vec::new()
                } else {
                    continue;
                };
                let tail = if dots > 0 { tail } else { tail[1..].to_vec() };
                let names = names.trim_matches(|c| c == '(' || c == ')' || c == ' ').split(',').map(|n| n.split(" as ").next().unwrap_or("").trim().to_string()).collect();
                ([base, tail].concat(), names)
            } else if let Some(rest) = line.strip_prefix("import ") {
                let Some(dotted) = rest.split(" as ").next().and_then(|d| d.trim().strip_prefix(&format!("{name}."))) else { continue };
                (dotted.split('.').map(str::to_string).collect(), Vec::new())
            } else {
                continue;
            };
            // a name is a module of the package, or an item of the module imported from
            let mut reached: Vec<Module> = names.iter().map(|n| [from.clone(), vec![n.clone()]].concat()).filter(|m| files.contains_key(m)).collect();
            if reached.len() < names.len() || names.is_empty() {
                reached.push((0..=from.len()).rev().map(|k| from[..k].to_vec()).find(|p| files.contains_key(p)).unwrap_or_default());
            }
            targets.extend(reached.into_iter().filter(|t| !module.starts_with(t)));
        }
    }
    Graph { files, edges, base: package.to_path_buf() }
}

/// The first circle of `edges`, as the chain of its nodes (the first node repeated at the end).
fn first_circle(edges: &BTreeMap<Module, BTreeSet<Module>>) -> Option<Vec<Module>> {
    // a path back to `start` from one of its imports is a circle
    for start in edges.keys() {
        let mut stack: Vec<(Module, Vec<Module>)> = edges[start].iter().map(|t| (t.clone(), vec![start.clone(), t.clone()])).collect();
        let mut seen = BTreeSet::new();
        while let Some((at, trail)) = stack.pop() {
            if &at == start {
                return Some(trail);
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
    None
}

/// The circles of a graph, among files and among stages (top-level modules, the root left out).
fn layering(graph: &Graph) -> Layering {
    let imports = graph.edges.values().map(BTreeSet::len).sum::<usize>();
    let file_circle =
        first_circle(&graph.edges).map(|c| c.iter().map(|m| graph.files[m].strip_prefix(&graph.base).unwrap().display().to_string()).collect::<Vec<_>>().join(" -> "));
    // the stage graph: an import between files of two stages is one between the stages
    let mut stages: BTreeMap<Module, BTreeSet<Module>> = BTreeMap::new();
    for (from, targets) in &graph.edges {
        for to in targets.iter().filter(|t| !t.is_empty() && !from.is_empty() && t[0] != from[0]) {
            stages.entry(from[..1].to_vec()).or_default().insert(to[..1].to_vec());
        }
    }
    let stage_circle = first_circle(&stages).map(|c| c.iter().map(|m| m[0].clone()).collect::<Vec<_>>().join(" -> "));
    Layering { imports, file_circle, stage_circle }
}

/// The workspace's root (two folders above this crate).
fn workspace() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// Asserts that the crate or package scanned has at least `min_imports` imports between its
/// files (so that the scan sees them) and no circle among files or stages.
fn assert_no_circle(what: &str, graph: &Graph, min_imports: usize) {
    let l = layering(graph);
    assert!(l.imports >= min_imports, "{what}: the scan found only {} imports between modules", l.imports);
    assert_eq!((l.file_circle, l.stage_circle), (None, None), "{what}: import circle (files, stages)");
}

#[test]
fn simgap_core_has_no_import_circle() {
    assert_no_circle("simgap-core", &rust_graph(&workspace().join("crates/simgap-core/src")), 41);
}

#[test]
fn simgap_sim_has_no_import_circle() {
    assert_no_circle("simgap-sim", &rust_graph(&workspace().join("crates/simgap-sim/src")), 80);
}

/// The diagnosis crate: its stages import downwards only.
#[test]
fn simgap_diag_has_no_import_circle() {
    assert_no_circle("simgap-diag", &rust_graph(&workspace().join("crates/simgap-diag/src")), 101);
}

#[test]
fn simgap_log_has_no_import_circle() {
    assert_no_circle("simgap-log", &rust_graph(&workspace().join("crates/simgap-log/src")), 18);
}

/// The umbrella package: the command-line tool.
#[test]
fn simgap_cli_has_no_import_circle() {
    assert_no_circle("src", &rust_graph(&workspace().join("src")), 4);
}

#[test]
fn simgap_python_bindings_have_no_import_circle() {
    assert_no_circle("python/src", &rust_graph(&workspace().join("python/src")), 10);
}

#[test]
fn python_package_has_no_import_circle() {
    assert_no_circle("python/simgap", &python_graph(&workspace().join("python/simgap")), 20);
}

/// A scratch folder removed when dropped.
struct Scratch(PathBuf);

impl Scratch {
    /// A new folder holding `files` (path, text).
    fn with(tag: &str, files: &[(&str, &str)]) -> Scratch {
        let dir = std::env::temp_dir().join(format!("simgap-layering-{tag}-{}", std::process::id()));
        for (file, text) in files {
            let path = dir.join(file);
            std::fs::create_dir_all(path.parent().unwrap()).unwrap();
            std::fs::write(path, text).unwrap();
        }
        Scratch(dir)
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

#[test]
fn the_check_finds_a_circle_through_a_root_reexport() {
    // a.rs imports b's item through the root's re-export, b.rs imports a: a circle
    let dir = Scratch::with(
        "reexport",
        &[
            ("lib.rs", "pub mod algorithms;\npub mod model;\npub use algorithms::crba::{mass_matrix, mass_matrix_into};\n"),
            ("algorithms/mod.rs", "pub mod crba;\n"),
            ("algorithms/crba.rs", "use crate::model::Model; // uses crate::nothing in a comment\npub fn mass_matrix() {}\n"),
            ("model.rs", "pub struct Model;\nfn f() { crate::mass_matrix(); }\n"),
        ],
    );
    let l = layering(&rust_graph(&dir.0));
    assert_eq!(l.imports, 2);
    let circle = l.file_circle.expect("the circle crba -> model -> crba is found");
    assert!(circle.contains("algorithms/crba.rs") && circle.contains("model.rs"), "{circle}");
    assert!(l.stage_circle.is_some_and(|c| c.contains("algorithms") && c.contains("model")));
}

#[test]
fn the_check_finds_a_circle_through_super_paths() {
    // two files of one folder import each other through `super::`: a circle of files
    let dir = Scratch::with(
        "super",
        &[
            ("lib.rs", "mod stage;\n"),
            ("stage/mod.rs", "mod fit;\nmod score;\npub struct Shared;\n"),
            ("stage/fit.rs", "use super::score::rank;\nuse super::Shared; // the folder itself: no import\npub fn fit() {}\n"),
            ("stage/score.rs", "pub fn rank() { super::super::stage::fit::fit(); }\n"),
        ],
    );
    let l = layering(&rust_graph(&dir.0));
    assert_eq!(l.imports, 2, "fit -> score and score -> fit, not fit -> the folder");
    let circle = l.file_circle.expect("the circle fit -> score -> fit is found");
    assert!(circle.contains("stage/fit.rs") && circle.contains("stage/score.rs"), "{circle}");
    assert_eq!(l.stage_circle, None, "one stage");
}

#[test]
fn the_check_finds_a_circle_through_grouped_uses() {
    // a grouped use, nested, reaches the other file: a circle of files and of stages
    let dir = Scratch::with(
        "grouped",
        &[
            ("lib.rs", "mod prepare;\nmod select;\n"),
            ("prepare/mod.rs", "mod width;\n"),
            ("prepare/width.rs", "use crate::{error::Error, select::{plausible::{range, bounds}, Options}};\n"),
            ("select/mod.rs", "pub mod plausible;\npub struct Options;\n"),
            ("select/plausible.rs", "use crate::{prepare::{width}};\npub fn range() {}\npub fn bounds() {}\n"),
        ],
    );
    let l = layering(&rust_graph(&dir.0));
    let circle = l.file_circle.expect("the circle width -> plausible -> width is found");
    assert!(circle.contains("prepare/width.rs") && circle.contains("select/plausible.rs"), "{circle}");
    assert!(l.stage_circle.is_some_and(|c| c.contains("prepare") && c.contains("select")));
}

#[test]
fn the_check_finds_a_circle_between_stages_alone() {
    // no two files import each other, but stage a's files import b's and b's import a's
    let dir = Scratch::with(
        "stages",
        &[
            ("lib.rs", "mod a;\nmod b;\n"),
            ("a/mod.rs", "mod one;\nmod two;\n"),
            ("a/one.rs", "use crate::b::three::f;\n"),
            ("a/two.rs", "pub fn g() {}\n"),
            ("b/mod.rs", "mod three;\n"),
            ("b/three.rs", "pub fn f() { crate::a::two::g(); }\n"),
        ],
    );
    let l = layering(&rust_graph(&dir.0));
    assert_eq!(l.file_circle, None);
    let circle = l.stage_circle.expect("the circle a -> b -> a is found");
    assert!(circle.contains('a') && circle.contains('b'), "{circle}");
}

#[test]
fn the_check_finds_a_circle_of_python_modules() {
    // report imports result for a type, result imports report lazily: a circle
    let dir = Scratch::with(
        "python",
        &[
            ("pkg/__init__.py", "from .fleet import report\n"),
            ("pkg/fleet/__init__.py", "\"\"\"from pkg.fleet import result (a docstring, no import)\"\"\"\nfrom .result import Result\n"),
            ("pkg/fleet/report.py", "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from .result import Result\n"),
            ("pkg/fleet/result.py", "class Result:\n    def to_html(self):\n        from . import report\n"),
        ],
    );
    let l = layering(&python_graph(&dir.0.join("pkg")));
    let circle = l.file_circle.expect("the circle report -> result -> report is found");
    assert!(circle.contains("fleet/report.py") && circle.contains("fleet/result.py"), "{circle}");
}
