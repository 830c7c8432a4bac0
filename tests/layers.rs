//! The library's layers, read from its source: every `crate::` and `super::` path outside comments
//! and test modules points down the layer order that ARCHITECTURE.md draws, and no two modules
//! import each other, directly or round a loop.
//!
//! The layer of a module is its top-level folder (`src/eval/metrics.rs` is in `eval`); a module is a
//! top-level folder's direct child (`solver::hierarchical`, with everything under it) or a
//! top-level file (`math`). A folder's `mod.rs` re-exporting its children is not a cycle: edges
//! between a module and its own folder are left out of the loop check.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// Bottom first. A module may import from its own layer (without loops) and from layers before it.
const LAYERS: &[&str] =
    &["math", "scene", "geometry", "mesh", "solver", "eval", "present", "studies", "render", "viewer"];

/// The source files of the library (not the binary's `main.rs` and `cli/`, which sit on top).
fn library_files() -> Vec<PathBuf> {
    fn walk(dir: &Path, out: &mut Vec<PathBuf>) {
        let mut entries: Vec<_> = std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().path()).collect();
        entries.sort();
        for p in entries {
            if p.is_dir() {
                walk(&p, out);
            } else if p.extension().is_some_and(|e| e == "rs") {
                out.push(p);
            }
        }
    }
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    walk(&src, &mut files);
    files
        .into_iter()
        .filter(|p| {
            let rel = p.strip_prefix(&src).unwrap();
            rel != Path::new("main.rs") && rel != Path::new("lib.rs") && !rel.starts_with("cli")
        })
        .collect()
}

/// The module path of a file: `src/eval/metrics.rs` → `eval::metrics`, `src/solver/mod.rs` → `solver`.
fn module_path(file: &Path) -> Vec<String> {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let rel = file.strip_prefix(&src).unwrap();
    let mut parts: Vec<String> = rel.iter().map(|c| c.to_string_lossy().into_owned()).collect();
    let last = parts.pop().unwrap();
    let stem = last.trim_end_matches(".rs");
    if stem != "mod" {
        parts.push(stem.to_owned());
    }
    parts
}

/// The code of a file without its comments and without its `#[cfg(test)] mod …` blocks (tests may
/// build fixtures from any layer).
fn code(text: &str) -> String {
    let mut out = String::new();
    let mut lines = text.lines().peekable();
    while let Some(line) = lines.next() {
        let trimmed = line.trim_start();
        if trimmed.starts_with("#[cfg(test)]")
            && lines.peek().is_some_and(|next| next.trim_start().starts_with("mod "))
        {
            break;
        }
        let without_comment = match line.find("//") {
            Some(i) if !line[..i].contains('"') => &line[..i],
            _ => line,
        };
        out.push_str(without_comment);
        out.push('\n');
    }
    out
}

/// Every path the code names from `crate::` or `super::`, resolved to an absolute module path.
fn imports(module: &[String], code: &str) -> Vec<Vec<String>> {
    let mut found = Vec::new();
    let bytes = code.as_bytes();
    let ident = |c: u8| c.is_ascii_alphanumeric() || c == b'_';
    let mut i = 0;
    while i < bytes.len() {
        if (i == 0 || !ident(bytes[i - 1]))
            && (bytes[i..].starts_with(b"crate::") || bytes[i..].starts_with(b"super::"))
        {
            let mut segments = Vec::new();
            let mut j = i;
            while j < bytes.len() {
                let start = j;
                while j < bytes.len() && ident(bytes[j]) {
                    j += 1;
                }
                if start == j {
                    break;
                }
                segments.push(code[start..j].to_owned());
                if bytes[j..].starts_with(b"::") {
                    j += 2;
                } else {
                    break;
                }
            }
            // `super` from `a/b.rs` is `a`; from `a/b/mod.rs` (module `a::b`) also `a`.
            let mut base: Vec<String> = if segments[0] == "crate" { Vec::new() } else { module.to_vec() };
            let mut k = 0;
            if segments[0] == "crate" {
                k = 1;
            } else {
                while k < segments.len() && segments[k] == "super" {
                    base.pop();
                    k += 1;
                }
            }
            base.extend(segments[k..].iter().cloned());
            found.push(base);
            i = j;
        } else {
            i += 1;
        }
    }
    found
}

/// The node a path belongs to: a top-level folder's child, or the top-level file itself; the
/// folder's own `mod.rs` is the folder's name.
fn node(path: &[String], modules: &BTreeSet<Vec<String>>) -> Option<Vec<String>> {
    let first = path.first()?;
    if !LAYERS.contains(&first.as_str()) {
        return None;
    }
    if path.len() >= 2 && modules.contains(&path[..2].to_vec()) {
        Some(path[..2].to_vec())
    } else {
        Some(vec![first.clone()])
    }
}

fn edges() -> BTreeMap<(Vec<String>, Vec<String>), String> {
    let files = library_files();
    let modules: BTreeSet<Vec<String>> =
        files.iter().map(|f| module_path(f)).map(|m| m.into_iter().take(2).collect()).collect();
    let mut out = BTreeMap::new();
    for file in &files {
        let module = module_path(file);
        let text = std::fs::read_to_string(file).unwrap();
        let Some(from) = node(&module, &modules) else { continue };
        for path in imports(&module, &code(&text)) {
            let Some(to) = node(&path, &modules) else { continue };
            if to != from {
                let shown =
                    file.strip_prefix(env!("CARGO_MANIFEST_DIR")).unwrap_or(file).display().to_string();
                out.entry((from.clone(), to)).or_insert_with(|| format!("{shown} names {}", path.join("::")));
            }
        }
    }
    out
}

#[test]
fn every_import_points_down_the_layers() {
    let rank = |m: &Vec<String>| LAYERS.iter().position(|l| *l == m[0]).unwrap();
    let edges = edges();
    let known = |a: &[&str], b: &[&str]| {
        let v = |x: &[&str]| x.iter().map(|s| (*s).to_owned()).collect::<Vec<_>>();
        edges.contains_key(&(v(a), v(b)))
    };
    assert!(
        known(&["eval", "reference"], &["geometry", "accel"])
            && known(&["solver", "hierarchical"], &["scene"]),
        "the checker sees the imports it must: {} edges",
        edges.len()
    );
    let upward: Vec<String> = edges
        .into_iter()
        .filter(|((from, to), _)| rank(to) > rank(from))
        .map(|((from, to), why)| format!("{} -> {}: {why}", from.join("::"), to.join("::")))
        .collect();
    assert!(upward.is_empty(), "imports against the layer order:\n{}", upward.join("\n"));
}

#[test]
fn no_module_imports_itself_round_a_loop() {
    let mut graph: BTreeMap<Vec<String>, BTreeSet<Vec<String>>> = BTreeMap::new();
    let mut why = BTreeMap::new();
    for ((from, to), reason) in edges() {
        // A folder and its own children re-export each other.
        if from.len() != to.len() && from[0] == to[0] {
            continue;
        }
        graph.entry(from.clone()).or_default().insert(to.clone());
        why.insert((from, to), reason);
    }
    // Depth-first search for a back edge; report the loop it closes.
    fn visit(
        n: &Vec<String>,
        graph: &BTreeMap<Vec<String>, BTreeSet<Vec<String>>>,
        state: &mut BTreeMap<Vec<String>, u8>,
        stack: &mut Vec<Vec<String>>,
        loops: &mut Vec<Vec<Vec<String>>>,
    ) {
        state.insert(n.clone(), 1);
        stack.push(n.clone());
        for m in graph.get(n).into_iter().flatten() {
            match state.get(m).copied().unwrap_or(0) {
                0 => visit(m, graph, state, stack, loops),
                1 => {
                    let at = stack.iter().position(|s| s == m).unwrap();
                    loops.push(stack[at..].to_vec());
                }
                _ => {}
            }
        }
        stack.pop();
        state.insert(n.clone(), 2);
    }
    let mut state = BTreeMap::new();
    let mut loops = Vec::new();
    for n in graph.keys() {
        if state.get(n).copied().unwrap_or(0) == 0 {
            visit(n, &graph, &mut state, &mut Vec::new(), &mut loops);
        }
    }
    let described: Vec<String> = loops
        .iter()
        .map(|cycle| {
            let mut steps = Vec::new();
            for (k, a) in cycle.iter().enumerate() {
                let b = &cycle[(k + 1) % cycle.len()];
                steps.push(why[&(a.clone(), b.clone())].clone());
            }
            steps.join("; ")
        })
        .collect();
    assert!(described.is_empty(), "import loops:\n{}", described.join("\n"));
}

/// The checker itself: it resolves `super::` and cuts test modules and comments.
#[test]
fn the_checker_reads_paths_as_rust_does() {
    let module = vec!["solver".to_owned(), "hierarchical".to_owned(), "refine".to_owned()];
    let code = code(
        "use super::super::link::Link; // crate::viewer::x\nuse crate::eval::metrics;\n#[cfg(test)]\nmod tests {\n use crate::studies::bench;\n}\n",
    );
    let found = imports(&module, &code);
    assert_eq!(found[0], ["solver", "link", "Link"]);
    assert_eq!(found[1], ["eval", "metrics"]);
    assert_eq!(found.len(), 2, "comments and test modules are not read: {found:?}");
}

/// The reference is the solvers' independent ruler: it traces its own paths through the BVH and
/// uses none of their form-factor, visibility or hierarchy code (it names `solver::SolvedElement`
/// only to read a solution's elements).
#[test]
fn the_reference_shares_no_kernel_with_the_solvers() {
    let shared: Vec<String> = edges()
        .into_iter()
        .filter(|((from, to), _)| {
            from[..] == ["eval", "reference"]
                && matches!(
                    to.join("::").as_str(),
                    "geometry::form_factor"
                        | "geometry::visibility"
                        | "solver::hierarchical"
                        | "solver::hierarchy"
                        | "solver::link"
                )
        })
        .map(|(_, why)| why)
        .collect();
    assert!(shared.is_empty(), "the reference uses the solvers' kernels:\n{}", shared.join("\n"));
}
