//! The crate's layers, read from its source: no module of a lower layer names one of a
//! higher layer, and no import cycle spans two of `src/`'s top-level modules. Comments are
//! not imports; test code is (a test that needs a higher layer belongs up there).
//!
//! Layers, top to bottom: the command line (the binary); `ui`, `xr`, `haptics`; `session`;
//! `registry`; `procedures`; then the generic layers that may not name those above: `render`,
//! `imaging`, `assess`, `trace`, `verify`, `models`, `sim`, `collision`, `mesh`, `gpu`, `scenario`,
//! `params`.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// The layers that must not be named from below, and the lower layers that must not name
/// them (the list).
const HIGH: [&str; 7] = [
    "procedures",
    "registry",
    "session",
    "ui",
    "xr",
    "haptics",
    "cli",
];
const LOW: [&str; 14] = [
    "render",
    "imaging",
    "rng",
    "assess",
    "trace",
    "verify",
    "scenario",
    "params",
    "sim",
    "models",
    "collision",
    "mesh",
    "diagnostics",
    "gpu",
];

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for e in entries.flatten() {
        let p = e.path();
        if p.is_dir() {
            rust_files(&p, out);
        } else if p.extension().is_some_and(|x| x == "rs") {
            out.push(p);
        }
    }
}

/// The top-level module a file of `src/` belongs to (`sim` for `src/sim/world.rs`).
fn module_of(src: &Path, file: &Path) -> String {
    let rel = file.strip_prefix(src).unwrap_or(file);
    let first = rel
        .components()
        .next()
        .map(|c| c.as_os_str().to_string_lossy().to_string())
        .unwrap_or_default();
    first.trim_end_matches(".rs").to_string()
}

/// The text with `//` comments removed (doc comments included; string literals that hold
/// `//` are rare enough in this crate to ignore).
fn without_comments(text: &str) -> String {
    text.lines()
        .map(|l| match l.find("//") {
            Some(i) => &l[..i],
            None => l,
        })
        .collect::<Vec<_>>()
        .join("\n")
}

/// The top-level modules `text` names: `crate::name` paths, and names inside
/// `use crate::{...}` groups.
fn named_modules(text: &str, modules: &BTreeSet<String>) -> BTreeSet<String> {
    let mut out = BTreeSet::new();
    let mut rest = text;
    while let Some(i) = rest.find("crate::") {
        let after = &rest[i + "crate::".len()..];
        if let Some(group) = after.strip_prefix('{') {
            // A group: the first name of each item at depth one.
            let mut depth = 1;
            let mut items = vec![String::new()];
            for c in group.chars() {
                match c {
                    '{' => depth += 1,
                    '}' => depth -= 1,
                    ',' if depth == 1 => items.push(String::new()),
                    _ => {}
                }
                if depth == 0 {
                    break;
                }
                if let Some(item) = items.last_mut() {
                    item.push(c);
                }
            }
            for item in items {
                let name: String = item
                    .trim_start_matches([',', ' ', '\n', '\t'])
                    .chars()
                    .take_while(|c| c.is_alphanumeric() || *c == '_')
                    .collect();
                if modules.contains(&name) {
                    out.insert(name);
                }
            }
        } else {
            let name: String = after
                .chars()
                .take_while(|c| c.is_alphanumeric() || *c == '_')
                .collect();
            if modules.contains(&name) {
                out.insert(name);
            }
        }
        rest = after;
    }
    out
}

/// Every module's imports of other top-level modules, with one file that makes each.
fn import_graph() -> BTreeMap<String, BTreeMap<String, PathBuf>> {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    rust_files(&src, &mut files);
    files.sort();
    let modules: BTreeSet<String> = files
        .iter()
        .map(|f| module_of(&src, f))
        .filter(|m| m != "lib" && m != "main")
        .collect();
    let mut graph: BTreeMap<String, BTreeMap<String, PathBuf>> = BTreeMap::new();
    for f in &files {
        let from = module_of(&src, f);
        if from == "lib" || from == "main" {
            continue;
        }
        let text = std::fs::read_to_string(f).expect("readable source");
        for to in named_modules(&without_comments(&text), &modules) {
            if to != from {
                graph
                    .entry(from.clone())
                    .or_default()
                    .entry(to)
                    .or_insert_with(|| f.clone());
            }
        }
    }
    graph
}

#[test]
fn no_lower_layer_names_a_higher_one() {
    let graph = import_graph();
    let mut wrong = Vec::new();
    for low in LOW {
        for (to, file) in graph.get(low).into_iter().flatten() {
            if HIGH.contains(&to.as_str()) {
                wrong.push(format!("{low} -> {to} ({})", file.display()));
            }
        }
    }
    assert!(wrong.is_empty(), "imports upward:\n{}", wrong.join("\n"));
}

/// Tarjan's strongly connected components of the graph; those of two or more modules are
/// cycles.
fn cycles(graph: &BTreeMap<String, BTreeMap<String, PathBuf>>) -> Vec<Vec<String>> {
    struct State<'a> {
        graph: &'a BTreeMap<String, BTreeMap<String, PathBuf>>,
        index: BTreeMap<&'a str, usize>,
        low: BTreeMap<&'a str, usize>,
        stack: Vec<&'a str>,
        on: BTreeSet<&'a str>,
        out: Vec<Vec<String>>,
    }
    fn visit<'a>(s: &mut State<'a>, v: &'a str) {
        let i = s.index.len();
        s.index.insert(v, i);
        s.low.insert(v, i);
        s.stack.push(v);
        s.on.insert(v);
        let graph = s.graph;
        for w in graph.get(v).into_iter().flat_map(|m| m.keys()) {
            let w = w.as_str();
            if !s.index.contains_key(w) {
                visit(s, w);
                let lw = s.low[w];
                let lv = s.low[v];
                s.low.insert(v, lv.min(lw));
            } else if s.on.contains(w) {
                let iw = s.index[w];
                let lv = s.low[v];
                s.low.insert(v, lv.min(iw));
            }
        }
        if s.low[v] == s.index[v] {
            let mut c = Vec::new();
            while let Some(w) = s.stack.pop() {
                s.on.remove(w);
                c.push(w.to_string());
                if w == v {
                    break;
                }
            }
            if c.len() > 1 {
                c.sort();
                s.out.push(c);
            }
        }
    }
    let mut s = State {
        graph,
        index: BTreeMap::new(),
        low: BTreeMap::new(),
        stack: Vec::new(),
        on: BTreeSet::new(),
        out: Vec::new(),
    };
    for v in graph.keys() {
        if !s.index.contains_key(v.as_str()) {
            visit(&mut s, v);
        }
    }
    s.out
}

#[test]
fn no_import_cycle_spans_two_modules() {
    let graph = &import_graph();
    let found = cycles(graph);
    let explain: Vec<String> = found
        .iter()
        .map(|c| {
            let edges: Vec<String> = c
                .iter()
                .flat_map(|a| {
                    c.iter().filter_map(move |b| {
                        let f = graph.get(a)?.get(b)?;
                        Some(format!("  {a} -> {b} ({})", f.display()))
                    })
                })
                .collect();
            format!("{}\n{}", c.join(", "), edges.join("\n"))
        })
        .collect();
    assert!(found.is_empty(), "cycles:\n{}", explain.join("\n"));
}

/// The reader itself: a group, nested groups and a plain path are all seen; a comment is
/// not an import.
#[test]
fn the_reader_finds_paths_and_groups_but_not_comments() {
    let modules: BTreeSet<String> = ["sim", "mesh", "models", "render"].map(String::from).into();
    let text = "use crate::{mesh::TriMesh, sim::{Clock, World}};\n\
                fn f() { crate::models::x(); }\n\
                // crate::render::y\n";
    let got = named_modules(&without_comments(text), &modules);
    let want: BTreeSet<String> = ["mesh", "models", "sim"].map(String::from).into();
    assert_eq!(got, want);
    let mut g: BTreeMap<String, BTreeMap<String, PathBuf>> = BTreeMap::new();
    for (a, b) in [("a", "b"), ("b", "c"), ("c", "a"), ("c", "d")] {
        g.entry(a.into())
            .or_default()
            .insert(b.into(), PathBuf::new());
    }
    assert_eq!(cycles(&g), vec![vec!["a", "b", "c"]]);
}
