//! Layering: inside every crate of the workspace (the firmware's `src/` too), no module
//! imports a module that (directly or through others) imports it back, and no module
//! imports upwards, from the crate root or one of its own ancestors. A circle means two
//! concepts cannot be read, tested or moved apart; an upward import means a driver or a
//! parent doubles as a home of shared things (issue 54: `MIN_DT_S` in diagnose's `lib.rs`
//! made 17 imports run back up). The graph is read from the sources: every `crate::a::b`
//! or `super::b` path in code (comments and the unit-test module left out) is an arrow
//! from the file's module to `a::b`, or to the longest prefix of it that is a module; a
//! path with no module prefix points at the root.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// Every crate of the workspace, by folder ("." is the firmware).
const LAYERED: [&str; 12] = [
    ".",
    "calib-core",
    "sim",
    "console",
    "formats",
    "firmware-app",
    "fitkit",
    "calibrate",
    "diagnose",
    "ros2bag",
    "testdata",
    "host-tests",
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
    paths_after(code, "crate::")
}

/// Paths after `prefix` (`crate::` or `super::`), groups expanded. A `crate::` preceded
/// by an identifier character (`$crate::`, `my_crate::`) is not this crate's.
fn paths_after(code: &str, prefix: &str) -> Vec<Vec<String>> {
    let ident = |c: char| c.is_ascii_alphanumeric() || c == '_';
    let mut out = Vec::new();
    let mut rest = code;
    while let Some(i) = rest.find(prefix) {
        let before = rest[..i].chars().next_back();
        rest = &rest[i + prefix.len()..];
        if before.is_some_and(|c| ident(c) || c == '$' || c == ':') {
            continue;
        }
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
        rest = r;
        out.push(path);
    }
    out
}

/// A crate's modules and their arrows: (circle graph, upward imports as
/// (module, target, path)).
struct Graph {
    edges: BTreeMap<String, BTreeSet<String>>,
    upward: Vec<(String, String, String)>,
}

/// `super::` paths of module `m` as paths from the crate root (`a::b` + `super::c` is
/// `a::c`); a file's own `mod.rs`/`lib.rs` module is its path.
fn resolve_super(m: &str, path: &[String]) -> Vec<String> {
    let mut base: Vec<String> = if m.is_empty() {
        Vec::new()
    } else {
        m.split("::").map(String::from).collect()
    };
    base.pop();
    let mut p = path;
    // `super::super::x`
    while p.first().is_some_and(|s| s == "super") {
        base.pop();
        p = &p[1..];
    }
    base.extend(p.iter().cloned());
    base
}

fn graph(krate: &str) -> Graph {
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
    graph_of(&texts)
}

/// The graph of modules given as (module path, source text).
fn graph_of(texts: &BTreeMap<String, String>) -> Graph {
    let mut g = Graph {
        edges: BTreeMap::new(),
        upward: Vec::new(),
    };
    for (m, text) in texts {
        g.edges.entry(m.clone()).or_default();
        let code = code(text);
        let paths = crate_paths(&code)
            .into_iter()
            .chain(
                paths_after(&code, "super::")
                    .into_iter()
                    .map(|p| resolve_super(m, &p)),
            )
            .filter(|p| !p.is_empty() && p[0] != "self");
        for path in paths {
            // The longest prefix that is a module of this crate; none: the root.
            let target = (1..=path.len())
                .rev()
                .map(|k| path[..k].join("::"))
                .find(|c| texts.contains_key(c))
                .unwrap_or_default();
            if m.is_empty() || &target == m {
                continue;
            }
            let ancestor = target.is_empty() || m.starts_with(&format!("{target}::"));
            if ancestor {
                g.upward.push((m.clone(), target, path.join("::")));
                continue;
            }
            // A parent using its child is one concept.
            if !target.starts_with(&format!("{m}::")) {
                g.edges.get_mut(m).unwrap().insert(target);
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
fn the_reader_finds_a_planted_circle_and_an_upward_import() {
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
        crate_paths(
            "use crate::{x::Y, z};\nlet a = crate::p::q::r(1); $crate::no; other_crate::no"
        ),
        vec![
            vec!["x".to_string(), "Y".to_string()],
            vec!["z".to_string()],
            vec!["p".to_string(), "q".to_string(), "r".to_string()]
        ]
    );
    // A planted crate: `a` and `b` import each other, `b` through `super::` from its own
    // child module `b::inner`... and `a::deep` reaches up to `a` and to the root.
    let texts: BTreeMap<String, String> = [
        ("", "pub mod a; pub mod b; pub const SHARED: f64 = 1.0;"),
        ("a", "use crate::b::inner::Thing;"),
        ("b", "pub mod inner;"),
        ("b::inner", "use super::super::a::Other; pub struct Thing;"),
        ("a::deep", "use super::Other; let x = crate::SHARED;"),
    ]
    .into_iter()
    .map(|(m, t)| (m.to_string(), t.to_string()))
    .collect();
    let g = graph_of(&texts);
    let c = circles(&g.edges);
    assert_eq!(c.len(), 1, "{:?}", g.edges);
    let mut found: Vec<String> = c[0].clone();
    found.sort();
    assert_eq!(found, vec!["a".to_string(), "b::inner".to_string()]);
    let up: Vec<(String, String)> = g
        .upward
        .iter()
        .map(|(m, t, _)| (m.clone(), t.clone()))
        .collect();
    assert_eq!(
        up,
        vec![
            ("a::deep".to_string(), "".to_string()),
            ("a::deep".to_string(), "a".to_string())
        ]
    );
}

#[test]
fn no_module_circle_and_no_new_upward_import_in_any_crate() {
    let mut upward = Vec::new();
    let (mut modules, mut arrows) = (0, 0);
    for krate in LAYERED {
        let g = graph(krate);
        modules += g.edges.len();
        arrows += g.edges.values().map(BTreeSet::len).sum::<usize>();
        assert_eq!(circles(&g.edges), Vec::<Vec<String>>::new(), "{krate}");
        for (m, t, p) in g.upward {
            upward.push(format!(
                "{krate}: {m} -> {} ({p})",
                if t.is_empty() { "the root" } else { &t }
            ));
        }
    }
    // The reader must see the structure at all (about 200 modules, 400 arrows).
    assert!(
        modules >= 150 && arrows >= 200,
        "{modules} modules, {arrows} arrows"
    );
    println!("{} upward imports:\n{}", upward.len(), upward.join("\n"));
    // Issue 54's goal is none. Measured when this check was written (calibrate split out,
    // MIN_DT_S and the solver moved to fitkit): 72; 53 once calibrate's children named
    // the modules they import from and its proxy left the library. What is left: mostly
    // children importing their crate root's re-exports (diagnose's verdict constants are
    // defined in its lib.rs), and calibrate's turn_law -> crate::Series, which hides a
    // circle (turn_law -> series -> step -> turn_law). The count may only fall. 40 once
    // diagnose's verdict thresholds moved to their leaf module `thresholds` and the
    // recording stage's artefact types to `recording_stage::artefact` (its checks had
    // brought it to 64).
    const UPWARD_NOW: usize = 40;
    assert!(
        upward.len() <= UPWARD_NOW,
        "{} upward imports (at most {UPWARD_NOW}):\n{}",
        upward.len(),
        upward.join("\n")
    );
}
