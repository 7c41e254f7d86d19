//! Layering: inside each crate below, no module imports a module that (directly or through
//! others) imports it back. A circle means two concepts cannot be read, tested or moved
//! apart. The graph is read from the sources: every `crate::a::b` path in code (comments
//! and the unit-test module left out) is an arrow from the file's module to `a::b`, or to
//! the longest prefix of it that is a module.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// Crates whose module graph must have no circle.
const LAYERED: [&str; 6] = [
    "calib-core",
    "sim",
    "console",
    "formats",
    "firmware-app",
    "diagnose",
];

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            rust_files(&p, out);
        } else if p.extension().is_some_and(|x| x == "rs") {
            out.push(p);
        }
    }
}

/// `src/a/b.rs` and `src/a/b/mod.rs` are module `a::b`; `lib.rs` and `main.rs` the root "".
fn module_of(src: &Path, file: &Path) -> String {
    let rel = file.strip_prefix(src).unwrap().with_extension("");
    let mut parts: Vec<String> = rel
        .components()
        .map(|c| c.as_os_str().to_string_lossy().into_owned())
        .collect();
    if matches!(
        parts.last().map(String::as_str),
        Some("mod" | "lib" | "main")
    ) {
        parts.pop();
    }
    parts.join("::")
}

/// The code of a file: line comments removed, and the unit-test module (by convention the
/// last item) cut off.
fn code(text: &str) -> String {
    let body = text.split("#[cfg(test)]\nmod tests").next().unwrap_or("");
    body.lines()
        .map(|l| l.split("//").next().unwrap_or(""))
        .collect::<Vec<_>>()
        .join("\n")
}

/// Paths after `crate::`, with `use crate::{a, b::c}` groups expanded.
fn crate_paths(code: &str) -> Vec<Vec<String>> {
    let ident = |c: char| c.is_ascii_alphanumeric() || c == '_';
    let mut out = Vec::new();
    let mut rest = code;
    while let Some(i) = rest.find("crate::") {
        rest = &rest[i + "crate::".len()..];
        if let Some(group) = rest.strip_prefix('{') {
            let end = group.find('}').unwrap_or(group.len());
            for item in group[..end].split(',') {
                let path: Vec<String> = item
                    .trim()
                    .split("::")
                    .map(|s| s.chars().take_while(|&c| ident(c)).collect())
                    .filter(|s: &String| !s.is_empty())
                    .collect();
                out.push(path);
            }
            continue;
        }
        let mut path = Vec::new();
        let mut r = rest;
        loop {
            let name: String = r.chars().take_while(|&c| ident(c)).collect();
            if name.is_empty() {
                break;
            }
            r = &r[name.len()..];
            path.push(name);
            match r.strip_prefix("::") {
                Some(next) => r = next,
                None => break,
            }
        }
        out.push(path);
    }
    out
}

fn graph(krate: &str) -> BTreeMap<String, BTreeSet<String>> {
    let src = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("..")
        .join(krate)
        .join("src");
    let mut files = Vec::new();
    rust_files(&src, &mut files);
    let texts: BTreeMap<String, String> = files
        .iter()
        .map(|f| (module_of(&src, f), std::fs::read_to_string(f).unwrap()))
        .collect();
    let mut g: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    for (m, text) in &texts {
        let edges = g.entry(m.clone()).or_default();
        for path in crate_paths(&code(text)) {
            // The longest prefix that is a module of this crate.
            let target = (1..=path.len())
                .rev()
                .map(|k| path[..k].join("::"))
                .find(|c| texts.contains_key(c));
            if let Some(t) = target {
                // A parent using its child, or a child its parent, is one concept.
                let nested = m.starts_with(&format!("{t}::")) || t.starts_with(&format!("{m}::"));
                if &t != m && !nested && !m.is_empty() {
                    edges.insert(t);
                }
            }
        }
    }
    g
}

/// Strongly connected components with more than one module (Tarjan).
fn circles(g: &BTreeMap<String, BTreeSet<String>>) -> Vec<Vec<String>> {
    struct State<'a> {
        g: &'a BTreeMap<String, BTreeSet<String>>,
        index: BTreeMap<&'a str, usize>,
        low: BTreeMap<&'a str, usize>,
        stack: Vec<&'a str>,
        on: BTreeSet<&'a str>,
        out: Vec<Vec<String>>,
    }
    fn visit<'a>(s: &mut State<'a>, v: &'a str) {
        let n = s.index.len();
        s.index.insert(v, n);
        s.low.insert(v, n);
        s.stack.push(v);
        s.on.insert(v);
        let g = s.g;
        for w in g.get(v).into_iter().flatten() {
            let w = w.as_str();
            if !s.index.contains_key(w) {
                visit(s, w);
                let lw = s.low[w];
                let lv = s.low.get_mut(v).unwrap();
                *lv = (*lv).min(lw);
            } else if s.on.contains(w) {
                let iw = s.index[w];
                let lv = s.low.get_mut(v).unwrap();
                *lv = (*lv).min(iw);
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
                s.out.push(c);
            }
        }
    }
    let mut s = State {
        g,
        index: BTreeMap::new(),
        low: BTreeMap::new(),
        stack: Vec::new(),
        on: BTreeSet::new(),
        out: Vec::new(),
    };
    for v in g.keys() {
        if !s.index.contains_key(v.as_str()) {
            visit(&mut s, v);
        }
    }
    s.out
}

#[test]
fn the_reader_finds_a_planted_circle() {
    let mut g = BTreeMap::new();
    let edge = |a: &str, b: &str| (a.to_string(), BTreeSet::from([b.to_string()]));
    g.extend([
        edge("a", "b"),
        edge("b", "c"),
        edge("c", "a"),
        edge("d", "a"),
    ]);
    let c = circles(&g);
    assert_eq!(c.len(), 1);
    assert_eq!(c[0].len(), 3);
    assert_eq!(
        crate_paths("use crate::{x::Y, z};\nlet a = crate::p::q::r(1);"),
        vec![
            vec!["x".to_string(), "Y".to_string()],
            vec!["z".to_string()],
            vec!["p".to_string(), "q".to_string(), "r".to_string()]
        ]
    );
}

#[test]
fn no_module_circle_inside_the_layered_crates() {
    for krate in LAYERED {
        let g = graph(krate);
        // The reader must see the crate's structure at all: each has several modules
        // with arrows between them.
        let arrows: usize = g.values().map(BTreeSet::len).sum();
        assert!(
            g.len() >= 4 && arrows >= 3,
            "{krate}: {} modules, {arrows} arrows",
            g.len()
        );
        assert_eq!(circles(&g), Vec::<Vec<String>>::new(), "{krate}");
    }
}
