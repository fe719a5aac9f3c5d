//! The solver's modules import each other without cycles: small shared types sit in leaf modules
//! (`kin`, `coupling`, `workspace`), so each module can be read, tested and replaced on top of
//! the ones below it. This test reads the sources, collects every `crate::<module>` path outside
//! comments (imports and inline paths alike; a file under `src/m/` counts as module `m`) and
//! fails with the cycle when the graph has one.
//!
//! The folders `compile/` (the compiler's passes) and `dynamics/` (the stages of the equations)
//! are checked the same way inside: their files' `super::<file>` and `crate::<folder>::<file>`
//! paths must form no cycle either. `mod.rs` declares and so depends on every file of its
//! folder; a file that reaches back for an item of `mod.rs` (`super::item`) closes a cycle, so
//! what the files share sits in a leaf file of the folder (`compile/ctx.rs`, `compile/rows.rs`,
//! `dynamics/blocks.rs`).

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

fn module_of(src: &Path, file: &Path) -> String {
    let rel = file.strip_prefix(src).unwrap();
    let first = rel
        .components()
        .next()
        .unwrap()
        .as_os_str()
        .to_string_lossy();
    first.trim_end_matches(".rs").to_string()
}

fn collect(dir: &Path, out: &mut Vec<std::path::PathBuf>) {
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            collect(&p, out);
        } else if p.extension().is_some_and(|x| x == "rs") {
            out.push(p);
        }
    }
}

/// `crate::name` references in `text`, ignoring `//` comments (doc links included).
fn references(text: &str) -> BTreeSet<String> {
    let mut found = BTreeSet::new();
    for line in text.lines() {
        let code = line.split("//").next().unwrap();
        let mut rest = code;
        while let Some(i) = rest.find("crate::") {
            rest = &rest[i + 7..];
            let name: String = rest
                .chars()
                .take_while(|c| c.is_ascii_alphanumeric() || *c == '_')
                .collect();
            // `crate::{a, b}` groups.
            if name.is_empty() && rest.starts_with('{') {
                let end = rest.find('}').unwrap_or(rest.len());
                for part in rest[1..end].split(',') {
                    let n: String = part
                        .trim()
                        .chars()
                        .take_while(|c| c.is_ascii_alphanumeric() || *c == '_')
                        .collect();
                    if !n.is_empty() {
                        found.insert(n);
                    }
                }
            } else if !name.is_empty() {
                found.insert(name);
            }
        }
    }
    found
}

#[test]
fn solver_modules_form_no_import_cycle() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    collect(&src, &mut files);
    let mut modules = BTreeSet::new();
    let mut graph: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    for f in &files {
        let m = module_of(&src, f);
        if m == "lib" {
            continue;
        }
        modules.insert(m.clone());
        let text = std::fs::read_to_string(f).unwrap();
        let refs = references(&text);
        let entry = graph.entry(m.clone()).or_default();
        for r in refs {
            if r != m {
                entry.insert(r);
            }
        }
    }
    // Only edges to the crate's own modules (`crate::Error` and the like re-exported by lib.rs
    // come from `error`, a leaf).
    for deps in graph.values_mut() {
        deps.retain(|d| modules.contains(d));
    }
    assert!(
        graph["kin"].is_empty(),
        "kin must stay a leaf: {:?}",
        graph["kin"]
    );
    if let Some(cycle) = find_cycle(&graph) {
        panic!("import cycle among solver modules: {}", cycle.join(" -> "));
    }
    // The graph is not empty: the parser found the imports it should.
    assert!(graph["dynamics"].contains("model") && graph["model"].contains("kin"));
}

/// A cycle of `graph`, depth first, if it has one.
fn find_cycle(graph: &BTreeMap<String, BTreeSet<String>>) -> Option<Vec<String>> {
    fn visit(
        m: &str,
        graph: &BTreeMap<String, BTreeSet<String>>,
        state: &mut BTreeMap<String, u8>,
        path: &mut Vec<String>,
    ) -> Option<Vec<String>> {
        match state.get(m) {
            Some(2) => return None,
            Some(1) => {
                let i = path.iter().position(|p| p == m).unwrap();
                let mut cycle = path[i..].to_vec();
                cycle.push(m.to_string());
                return Some(cycle);
            }
            _ => {}
        }
        state.insert(m.to_string(), 1);
        path.push(m.to_string());
        for d in graph.get(m).into_iter().flatten() {
            if let Some(c) = visit(d, graph, state, path) {
                return Some(c);
            }
        }
        path.pop();
        state.insert(m.to_string(), 2);
        None
    }
    let mut state = BTreeMap::new();
    for m in graph.keys() {
        let mut path = Vec::new();
        if let Some(cycle) = visit(m, graph, &mut state, &mut path) {
            return Some(cycle);
        }
    }
    None
}

/// The names after each `prefix` in `text` outside `//` comments (`prefix{a, b}` groups too).
fn names_after(text: &str, prefix: &str) -> BTreeSet<String> {
    let ident = |s: &str| -> String {
        s.trim()
            .chars()
            .take_while(|c| c.is_ascii_alphanumeric() || *c == '_')
            .collect()
    };
    let mut found = BTreeSet::new();
    for line in text.lines() {
        let mut rest = line.split("//").next().unwrap();
        while let Some(i) = rest.find(prefix) {
            // `super::super::` and longer prefixes leave the folder.
            let before = &rest[..i];
            rest = &rest[i + prefix.len()..];
            if before.ends_with("::") {
                continue;
            }
            if let Some(group) = rest.strip_prefix('{') {
                let end = group.find('}').unwrap_or(group.len());
                found.extend(group[..end].split(',').map(ident).filter(|n| !n.is_empty()));
            } else {
                let n = ident(rest);
                if !n.is_empty() {
                    found.insert(n);
                }
            }
        }
    }
    found
}

/// The import graph of the files of `src/<folder>/`: `mod` for `mod.rs`, the file stem for the
/// others. `mod.rs` depends on every file it declares; another file on each file it names with
/// `super::<file>` or `crate::<folder>::<file>`, and on `mod` when it names an item of `mod.rs`
/// that way.
fn folder_graph(folder: &str) -> BTreeMap<String, BTreeSet<String>> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("src")
        .join(folder);
    let mut files = Vec::new();
    collect(&dir, &mut files);
    let stem = |f: &Path| f.file_stem().unwrap().to_string_lossy().to_string();
    let names: BTreeSet<String> = files.iter().map(|f| stem(f)).collect();
    let mut graph = BTreeMap::new();
    for f in &files {
        let text = std::fs::read_to_string(f).unwrap();
        let m = stem(f);
        let mut deps = BTreeSet::new();
        let mut refs = names_after(&text, &format!("crate::{folder}::"));
        if m == "mod" {
            refs.extend(names_after(&text, "self::"));
            for line in text.lines() {
                let l = line.trim_start();
                let l = l.strip_prefix("pub(crate) ").unwrap_or(l);
                let l = l.strip_prefix("pub ").unwrap_or(l);
                if let Some(n) = l.strip_prefix("mod ") {
                    refs.insert(n.trim_end_matches(';').trim().to_string());
                }
            }
        } else {
            refs.extend(names_after(&text, "super::"));
        }
        for r in refs {
            let target = if names.contains(&r) { r } else { "mod".into() };
            if target != m {
                deps.insert(target);
            }
        }
        graph.insert(m, deps);
    }
    graph
}

#[test]
fn compile_passes_and_dynamics_stages_form_no_import_cycle() {
    for folder in ["compile", "dynamics"] {
        let graph = folder_graph(folder);
        if let Some(cycle) = find_cycle(&graph) {
            panic!("import cycle among {folder}/: {}", cycle.join(" -> "));
        }
        // The parser found the edges it should.
        assert!(graph["mod"].len() + 1 == graph.len(), "{folder}: {graph:?}");
    }
    let c = folder_graph("compile");
    assert!(c["joints"].contains("clearance") && c["clearance"].contains("rows"));
    assert!(c["ctx"].is_empty() && c["rows"].is_empty(), "{c:?}");
    let d = folder_graph("dynamics");
    assert!(
        d["forces"].contains("kinematics") && d["blocks"].is_empty(),
        "{d:?}"
    );
}
