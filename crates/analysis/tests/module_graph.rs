//! The analysis crate's modules form layers that point one way, and no cycle:
//!
//! ```text
//! execute                       the one entry point of the program and the Python package
//! figures                       drawn from written files and the outcomes studies return
//! study/                        specs, loading, one run, the sweep executor, continuation, ...
//! storage/                      every file kind, crash-safe writes, verified reads
//! measures/                     sections, Lyapunov, the 0-1 test, chaos, periodic orbits
//! flow/                         flows of mechanisms and built-in systems, tangents, observables
//! progress                      progress and stop requests, shared by every layer
//! ```
//!
//! A module may use modules of its own layer and of the layers below it, never above; within a
//! layer, its files import each other without a cycle. This test reads the sources, resolves
//! every module path outside comments and unit tests (`crate::a::b`, `crate::a::{b, c::d}`,
//! `super::`, and a `mod.rs` naming its own child modules) to the file that holds it, and fails
//! with the violating import or the cycle.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// The layers, lowest first: a module's layer is that of its first path segment.
const LAYERS: [&str; 7] = [
    "progress", "flow", "measures", "storage", "study", "figures", "execute",
];

fn layer(module: &str) -> usize {
    let first = module.split("::").next().unwrap();
    LAYERS
        .iter()
        .position(|l| *l == first)
        .unwrap_or_else(|| panic!("module `{module}` belongs to no layer: add it to LAYERS"))
}

fn collect(dir: &Path, out: &mut Vec<PathBuf>) {
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            collect(&p, out);
        } else if p.extension().is_some_and(|x| x == "rs") {
            out.push(p);
        }
    }
}

/// `flow/mod.rs` is module `flow`, `flow/tangent.rs` is `flow::tangent`, `lib.rs` is the root "".
fn module_of(src: &Path, file: &Path) -> String {
    let rel = file.strip_prefix(src).unwrap().with_extension("");
    let mut parts: Vec<String> = rel
        .components()
        .map(|c| c.as_os_str().to_string_lossy().into_owned())
        .collect();
    if parts.last().is_some_and(|p| p == "mod" || p == "lib") {
        parts.pop();
    }
    parts.join("::")
}

/// The code of a file before its unit tests, with `//` comments removed.
fn code(text: &str) -> String {
    let mut out = String::new();
    for line in text.lines() {
        if line.trim_start().starts_with("#[cfg(test)]") {
            break;
        }
        out.push_str(line.split("//").next().unwrap());
        out.push('\n');
    }
    out
}

fn ident(s: &str) -> String {
    s.chars()
        .take_while(|c| c.is_ascii_alphanumeric() || *c == '_')
        .collect()
}

/// The paths after `prefix::` in `code`, with `{a, b::c}` groups expanded (one level).
fn paths_after(code: &str, prefix: &str) -> Vec<Vec<String>> {
    let mut found = Vec::new();
    let pat = format!("{prefix}::");
    let mut rest = code;
    while let Some(i) = rest.find(&pat) {
        // A whole word: `crate::`, not `mycrate::`.
        let before = rest[..i].chars().last();
        rest = &rest[i + pat.len()..];
        if before.is_some_and(|c| c.is_ascii_alphanumeric() || c == '_') {
            continue;
        }
        found.extend(path_at(rest));
    }
    found
}

/// The path segments at the start of `s` (`a::b::{c, d}` gives `[a, b, c]` and `[a, b, d]`).
fn path_at(s: &str) -> Vec<Vec<String>> {
    let mut segs = Vec::new();
    let mut rest = s;
    loop {
        if rest.starts_with('{') {
            let end = rest.find('}').unwrap_or(rest.len());
            let mut out = Vec::new();
            for part in rest[1..end].split(',') {
                for tail in path_at(part.trim()) {
                    let mut p = segs.clone();
                    p.extend(tail);
                    out.push(p);
                }
            }
            if out.is_empty() {
                out.push(segs);
            }
            return out;
        }
        let name = ident(rest);
        if name.is_empty() {
            break;
        }
        rest = &rest[name.len()..];
        segs.push(name);
        match rest.strip_prefix("::") {
            Some(r) => rest = r,
            None => break,
        }
    }
    vec![segs]
}

/// The longest module of `modules` that `path` (absolute segments) names.
fn resolve(path: &[String], modules: &BTreeSet<String>) -> Option<String> {
    (1..=path.len())
        .rev()
        .map(|n| path[..n].join("::"))
        .find(|m| modules.contains(m))
}

fn graph() -> BTreeMap<String, BTreeSet<String>> {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    collect(&src, &mut files);
    let modules: BTreeSet<String> = files.iter().map(|f| module_of(&src, f)).collect();
    let mut graph: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    for f in &files {
        let m = module_of(&src, f);
        if m.is_empty() {
            continue;
        }
        let text = code(&std::fs::read_to_string(f).unwrap());
        let mut refs: Vec<Vec<String>> = paths_after(&text, "crate");
        // `super::x` from `a::b` (file `a/b.rs` or `a/b/mod.rs`) names `a::x`.
        let segs: Vec<String> = m.split("::").map(str::to_string).collect();
        let is_dir_module = f.file_name().is_some_and(|n| n == "mod.rs");
        let parent: Vec<String> = segs[..segs.len() - 1].to_vec();
        for p in paths_after(&text, "super") {
            let mut abs = parent.clone();
            abs.extend(p);
            refs.push(abs);
        }
        // A `mod.rs` naming its children (`tangent::MechTangent`), and `self::child`.
        if is_dir_module {
            for child in modules.iter().filter_map(|c| {
                c.strip_prefix(&format!("{m}::"))
                    .filter(|rest| !rest.contains("::"))
            }) {
                for p in paths_after(&text, child).into_iter().chain(
                    paths_after(&text, "self")
                        .into_iter()
                        .filter(|p| p.first().is_some_and(|s| s == child)),
                ) {
                    let mut abs = segs.clone();
                    if p.first().is_none_or(|s| s != child) {
                        abs.push(child.to_string());
                    }
                    abs.extend(p);
                    refs.push(abs);
                }
            }
        }
        let entry = graph.entry(m.clone()).or_default();
        for r in refs {
            if let Some(target) = resolve(&r, &modules)
                && target != m
                && !target.is_empty()
            {
                entry.insert(target);
            }
        }
    }
    graph
}

/// The strongly connected components with more than one module (Tarjan): each is a set of
/// modules that import each other in a cycle.
fn cycles(graph: &BTreeMap<String, BTreeSet<String>>) -> Vec<Vec<String>> {
    struct Tarjan<'g> {
        graph: &'g BTreeMap<String, BTreeSet<String>>,
        index: BTreeMap<&'g str, usize>,
        low: BTreeMap<&'g str, usize>,
        stack: Vec<&'g str>,
        found: Vec<Vec<String>>,
    }
    impl<'g> Tarjan<'g> {
        fn visit(&mut self, v: &'g str) {
            let i = self.index.len();
            self.index.insert(v, i);
            self.low.insert(v, i);
            self.stack.push(v);
            for w in self.graph.get(v).into_iter().flatten() {
                let w = w.as_str();
                if !self.index.contains_key(w) {
                    self.visit(w);
                    let lw = self.low[w];
                    let lv = self.low.get_mut(v).unwrap();
                    *lv = (*lv).min(lw);
                } else if self.stack.contains(&w) {
                    let iw = self.index[w];
                    let lv = self.low.get_mut(v).unwrap();
                    *lv = (*lv).min(iw);
                }
            }
            if self.low[v] == self.index[v] {
                let mut comp = Vec::new();
                while let Some(w) = self.stack.pop() {
                    comp.push(w.to_string());
                    if w == v {
                        break;
                    }
                }
                if comp.len() > 1 {
                    comp.sort();
                    self.found.push(comp);
                }
            }
        }
    }
    let mut t = Tarjan {
        graph,
        index: BTreeMap::new(),
        low: BTreeMap::new(),
        stack: Vec::new(),
        found: Vec::new(),
    };
    for m in graph.keys() {
        if !t.index.contains_key(m.as_str()) {
            t.visit(m);
        }
    }
    t.found
}

#[test]
fn analysis_layers_point_one_way() {
    let graph = graph();
    let mut upward = Vec::new();
    for (m, deps) in &graph {
        for d in deps {
            if layer(d) > layer(m) {
                upward.push(format!("{m} -> {d}"));
            }
        }
    }
    assert!(
        upward.is_empty(),
        "imports from a lower layer into a higher one:\n  {}",
        upward.join("\n  ")
    );
    // The parser found the imports it should (a test that reads nothing would pass).
    assert!(graph["study::analysis::load"].contains("flow"));
    assert!(graph["flow::tangent"].contains("flow::systems"));
}

#[test]
fn analysis_modules_form_no_import_cycle() {
    let graph = graph();
    let found = cycles(&graph);
    let text: Vec<String> = found
        .iter()
        .map(|c| {
            c.iter()
                .map(|m| {
                    let inner: Vec<&str> = graph[m]
                        .iter()
                        .filter(|d| c.contains(d))
                        .map(String::as_str)
                        .collect();
                    format!("{m} -> {}", inner.join(", "))
                })
                .collect::<Vec<_>>()
                .join("; ")
        })
        .collect();
    assert!(
        found.is_empty(),
        "import cycles among analysis modules (each line: a cycle's modules and their imports \
         inside it):\n  {}",
        text.join("\n  ")
    );
}

/// Files are written and read in the storage layer only: above it (studies, figures, the entry
/// point) no code outside unit tests calls the `hdf5` crate; it hands storage plain data and gets
/// plain data back.
#[test]
fn only_storage_calls_hdf5() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    collect(&src, &mut files);
    let storage = layer("storage");
    let mut found = Vec::new();
    let mut storage_calls = 0;
    for f in &files {
        let module = module_of(&src, f);
        if module.is_empty() {
            continue;
        }
        let text = code(&std::fs::read_to_string(f).unwrap());
        let calls = text.matches("hdf5::").count();
        if layer(&module) > storage && calls > 0 {
            found.push(format!("{module}: {calls} uses of hdf5::"));
        }
        if module.starts_with("storage") {
            storage_calls += calls;
        }
    }
    assert!(
        found.is_empty(),
        "HDF5 calls above the storage layer (move the reading or writing into storage/, handing \
         it plain data):\n  {}",
        found.join("\n  ")
    );
    // The scan sees the calls where they belong (a test that reads nothing would pass).
    assert!(storage_calls > 100, "{storage_calls}");
}
