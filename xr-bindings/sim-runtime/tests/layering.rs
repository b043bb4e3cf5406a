//! The runtime's modules are layered: `lib.rs` (the loader's entry points and the name ->
//! function dispatch) on top, the per-area entry points under it, and the shared state and
//! plain data types at the bottom. No module may reach, through the modules it refers to, back
//! to itself.
//!
//! The graph is read from the source: in each `src/*.rs` file, every path that starts at the
//! crate root (`crate::X`, `super::X` from a top-level module, `use super::{X, ..}`) is an edge
//! to module `X`, or to `lib` when `X` is an item of the crate root; in `lib.rs`, a path that
//! starts with a child module's name (`session::lookup`) is an edge too. Comments, strings and
//! paths inside a file's own inline modules (`mod tests { use super::*; }`) do not count.

use std::collections::{BTreeMap, BTreeSet};

/// A module graph: each module and the modules it refers to.
type Graph = BTreeMap<String, BTreeSet<String>>;

/// `src` with comments, string literals and character literals blanked out (lines kept).
fn code_only(src: &str) -> String {
    let c: Vec<char> = src.chars().collect();
    let mut out = String::with_capacity(src.len());
    let blank = |out: &mut String, ch: char| out.push(if ch == '\n' { '\n' } else { ' ' });
    let mut i = 0;
    while i < c.len() {
        let at = |k: usize| c.get(k).copied().unwrap_or('\0');
        if at(i) == '/' && at(i + 1) == '/' {
            while i < c.len() && c[i] != '\n' {
                blank(&mut out, c[i]);
                i += 1;
            }
        } else if at(i) == '/' && at(i + 1) == '*' {
            let mut depth = 0;
            loop {
                if i >= c.len() {
                    break;
                }
                if at(i) == '/' && at(i + 1) == '*' {
                    depth += 1;
                    out.push_str("  ");
                    i += 2;
                } else if at(i) == '*' && at(i + 1) == '/' {
                    depth -= 1;
                    out.push_str("  ");
                    i += 2;
                    if depth == 0 {
                        break;
                    }
                } else {
                    blank(&mut out, c[i]);
                    i += 1;
                }
            }
        } else if at(i) == 'r'
            && (at(i + 1) == '"' || (at(i + 1) == '#' && matches!(at(i + 2), '"' | '#')))
            && !at(i.wrapping_sub(1)).is_alphanumeric()
        {
            // A raw string: r"..", r#".."#, ...
            let mut hashes = 0;
            let mut j = i + 1;
            while at(j) == '#' {
                hashes += 1;
                j += 1;
            }
            j += 1;
            while j < c.len() {
                if c[j] == '"' && (1..=hashes).all(|h| at(j + h) == '#') {
                    j += 1 + hashes;
                    break;
                }
                j += 1;
            }
            for &ch in &c[i..j.min(c.len())] {
                blank(&mut out, ch);
            }
            i = j;
        } else if at(i) == '"' {
            blank(&mut out, c[i]);
            i += 1;
            while i < c.len() && c[i] != '"' {
                if c[i] == '\\' {
                    blank(&mut out, c[i]);
                    i += 1;
                }
                if i < c.len() {
                    blank(&mut out, c[i]);
                    i += 1;
                }
            }
            if i < c.len() {
                blank(&mut out, c[i]);
                i += 1;
            }
        } else if at(i) == '\'' {
            // A character literal ('x', '\n', '\'', '\u{..}'), or else a lifetime.
            let end = if at(i + 1) == '\\' {
                (i + 3..c.len()).find(|&k| c[k] == '\'')
            } else if at(i + 2) == '\'' {
                Some(i + 2)
            } else {
                None
            };
            match end {
                Some(e) => {
                    for &ch in &c[i..=e] {
                        blank(&mut out, ch);
                    }
                    i = e + 1;
                }
                None => {
                    out.push(c[i]);
                    i += 1;
                }
            }
        } else {
            out.push(c[i]);
            i += 1;
        }
    }
    out
}

/// Identifiers, `::` and single punctuation characters, in order.
fn tokens(code: &str) -> Vec<String> {
    let c: Vec<char> = code.chars().collect();
    let mut t = Vec::new();
    let mut i = 0;
    while i < c.len() {
        if c[i].is_alphanumeric() || c[i] == '_' {
            let start = i;
            while i < c.len() && (c[i].is_alphanumeric() || c[i] == '_') {
                i += 1;
            }
            t.push(c[start..i].iter().collect());
        } else if c[i] == ':' && c.get(i + 1) == Some(&':') {
            t.push("::".to_string());
            i += 2;
        } else if c[i].is_whitespace() {
            i += 1;
        } else {
            t.push(c[i].to_string());
            i += 1;
        }
    }
    t
}

/// The modules (or `lib`, for a crate-root item) that the source of module `me` refers to.
fn references(me: &str, src: &str, modules: &BTreeSet<String>) -> BTreeSet<String> {
    let t = tokens(&code_only(src));
    let tok = |k: usize| t.get(k).map_or("", String::as_str);
    let is_root = me == "lib";
    let mut out = BTreeSet::new();
    let add = |name: &str, out: &mut BTreeSet<String>| {
        let target = if modules.contains(name) { name } else { "lib" };
        if target != me {
            out.insert(target.to_string());
        }
    };
    // Brace depth, and the depths at which the file's inline modules' bodies began.
    let mut depth = 0usize;
    let mut inline: Vec<usize> = Vec::new();
    let mut i = 0;
    while i < t.len() {
        match tok(i) {
            "{" => {
                if tok(i.wrapping_sub(2)) == "mod" && i >= 2 {
                    inline.push(depth);
                }
                depth += 1;
            }
            "}" => {
                depth = depth.saturating_sub(1);
                if inline.last() == Some(&depth) {
                    inline.pop();
                }
            }
            _ => {}
        }
        let starts_path = tok(i.wrapping_sub(1)) != "::" || i == 0;
        if !starts_path || tok(i + 1) != "::" {
            i += 1;
            continue;
        }
        // Where the path starts: the crate root, or (`super`) some enclosing module.
        let mut k = i;
        let at_root = match tok(i) {
            "crate" => {
                k += 2;
                true
            }
            "super" => {
                let mut ups = 0;
                while tok(k) == "super" && tok(k + 1) == "::" {
                    ups += 1;
                    k += 2;
                }
                // From the file's module (depth 0 of inline modules), one `super` is the root;
                // `lib.rs` is the root itself.
                let level = inline.len() as i64 - ups;
                !is_root && level == -1
            }
            name if is_root && modules.contains(name) => {
                add(name, &mut out);
                false
            }
            _ => false,
        };
        if at_root {
            if tok(k) == "{" {
                // `use crate::{a, b::c, d::{e, f}}`: the first name of each element.
                let mut d = 0;
                let mut first = true;
                let mut j = k;
                loop {
                    match tok(j) {
                        "{" => {
                            d += 1;
                            if d == 1 {
                                first = true;
                            }
                        }
                        "}" => {
                            d -= 1;
                            if d == 0 {
                                break;
                            }
                        }
                        "," if d == 1 => first = true,
                        "" => break,
                        name if d == 1 && first => {
                            first = false;
                            add(if name == "self" { "lib" } else { name }, &mut out);
                        }
                        _ => {}
                    }
                    j += 1;
                }
            } else if !tok(k).is_empty() {
                add(tok(k), &mut out);
            }
        }
        i = k.max(i + 1);
    }
    out
}

/// The graph of a crate whose `src/` holds these files (name without `.rs`, text).
fn graph(files: &[(String, String)]) -> Graph {
    let modules: BTreeSet<String> = files.iter().map(|(n, _)| n.clone()).collect();
    files
        .iter()
        .map(|(name, src)| (name.clone(), references(name, src, &modules)))
        .collect()
}

/// A cycle of the graph (its first module repeated at the end), if it has one.
fn find_cycle(g: &Graph) -> Option<Vec<String>> {
    #[derive(Clone, Copy, PartialEq)]
    enum Mark {
        New,
        Open,
        Done,
    }
    fn visit(
        g: &Graph,
        n: &str,
        marks: &mut BTreeMap<String, Mark>,
        stack: &mut Vec<String>,
    ) -> Option<Vec<String>> {
        marks.insert(n.to_string(), Mark::Open);
        stack.push(n.to_string());
        for m in g.get(n).into_iter().flatten() {
            match marks.get(m).copied().unwrap_or(Mark::New) {
                Mark::Open => {
                    let from = stack.iter().position(|s| s == m).unwrap_or(0);
                    let mut cycle = stack[from..].to_vec();
                    cycle.push(m.clone());
                    return Some(cycle);
                }
                Mark::New => {
                    if let Some(c) = visit(g, m, marks, stack) {
                        return Some(c);
                    }
                }
                Mark::Done => {}
            }
        }
        stack.pop();
        marks.insert(n.to_string(), Mark::Done);
        None
    }
    let mut marks = BTreeMap::new();
    for n in g.keys() {
        if marks.get(n).copied().unwrap_or(Mark::New) == Mark::New
            && let Some(c) = visit(g, n, &mut marks, &mut Vec::new())
        {
            return Some(c);
        }
    }
    None
}

/// The groups of modules that all reach one another (each holds a cycle), largest first.
fn tangles(g: &Graph) -> Vec<BTreeSet<String>> {
    let reach = |from: &str| {
        let mut seen = BTreeSet::new();
        let mut todo = vec![from.to_string()];
        while let Some(n) = todo.pop() {
            for m in g.get(&n).into_iter().flatten() {
                if seen.insert(m.clone()) {
                    todo.push(m.clone());
                }
            }
        }
        seen
    };
    let reached: BTreeMap<&String, BTreeSet<String>> = g.keys().map(|n| (n, reach(n))).collect();
    let mut groups: Vec<BTreeSet<String>> = Vec::new();
    for n in g.keys() {
        if !reached[n].contains(n) || groups.iter().any(|grp| grp.contains(n)) {
            continue;
        }
        let grp = g
            .keys()
            .filter(|m| reached[n].contains(*m) && reached[*m].contains(n))
            .cloned()
            .collect();
        groups.push(grp);
    }
    groups.sort_by_key(|grp| std::cmp::Reverse(grp.len()));
    groups
}

fn describe(g: &Graph) -> String {
    g.iter()
        .map(|(n, to)| {
            let to: Vec<&str> = to.iter().map(String::as_str).collect();
            format!("  {n} -> {}\n", to.join(", "))
        })
        .collect()
}

fn crate_sources() -> Vec<(String, String)> {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files: Vec<(String, String)> = std::fs::read_dir(&dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .filter_map(Result::ok)
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|x| x == "rs"))
        .map(|p| {
            let name = p
                .file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_default();
            let text =
                std::fs::read_to_string(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
            (name, text)
        })
        .collect();
    files.sort();
    files
}

#[test]
fn the_runtime_modules_form_no_import_cycle() {
    let files = crate_sources();
    assert!(
        files.iter().any(|(n, _)| n == "lib") && files.len() > 3,
        "src/ not found or nearly empty: {:?}",
        files.iter().map(|f| &f.0).collect::<Vec<_>>()
    );
    let g = graph(&files);
    // The reader found the dispatch's references to the areas below it.
    assert!(
        g.get("lib").is_some_and(|to| to.len() >= 3),
        "lib.rs refers to almost no module: the reader is broken\n{}",
        describe(&g)
    );
    if let Some(cycle) = find_cycle(&g) {
        let groups: Vec<String> = tangles(&g)
            .iter()
            .map(|grp| grp.iter().cloned().collect::<Vec<_>>().join(", "))
            .collect();
        panic!(
            "module cycle: {}\nmodules that reach one another: {}\nthe module graph:\n{}",
            cycle.join(" -> "),
            groups.join("; "),
            describe(&g)
        );
    }
    println!("the module graph:\n{}", describe(&g));
}

#[test]
fn the_reader_sees_every_kind_of_reference_and_finds_a_cycle() {
    let f = |n: &str, s: &str| (n.to_string(), s.to_string());
    let files = [
        f(
            "lib",
            "mod a; mod b; mod c; mod d;\npub use a::X;\nfn f() { d::go() }\nstruct R;",
        ),
        // `super::` from a top-level module is the root: `R` is a root item.
        f(
            "a",
            "use super::{R, b::Y};\n// crate::d in a comment\nfn s() { \"crate::d\"; }",
        ),
        f(
            "b",
            "fn g() { crate::c::h() }\nmod tests { use super::*; use super::super::c; }",
        ),
        f("c", "use crate::{self as me, d};"),
        f("d", "fn go() { let x = 'a'; let y: &'static str = \"\"; }"),
    ];
    let g = graph(&files);
    let to = |n: &str| -> Vec<&str> { g[n].iter().map(String::as_str).collect() };
    assert_eq!(to("lib"), ["a", "d"]);
    assert_eq!(to("a"), ["b", "lib"]);
    assert_eq!(to("b"), ["c"]);
    assert_eq!(to("c"), ["d", "lib"]);
    assert!(to("d").is_empty());
    let cycle = find_cycle(&g).expect("lib -> a -> lib");
    assert_eq!(cycle.first(), cycle.last());
    assert!(cycle.len() >= 3, "{cycle:?}");
    assert_eq!(tangles(&g).len(), 1);
    assert_eq!(tangles(&g)[0].len(), 4, "{:?}", tangles(&g));
    // Without `a`'s reference to a root item, `c`'s `self` still closes lib -> a -> b -> c ->
    // lib; without that too, there is no cycle.
    let mut files = files.to_vec();
    files[1].1 = "use super::b::Y;".to_string();
    assert!(find_cycle(&graph(&files)).is_some());
    files[3].1 = "use crate::d;".to_string();
    assert_eq!(
        find_cycle(&graph(&files)),
        None,
        "{}",
        describe(&graph(&files))
    );
}
