//! Every `match` over a kind the program adds to (contact and friction laws, joint kinds,
//! clearance geometries, constraint primitives, drive profiles, effects) names each variant: a
//! catch-all arm (`_ =>`) would let a new variant through unhandled, where the compiler should
//! stop it. This test reads the solver's sources (outside unit tests and comments), and for
//! every catch-all arm looks at the arms of its own `match`: none may name a variant of these
//! enums.

use std::path::{Path, PathBuf};

/// The enums new variants are added to (book/src/how-to/extend.md).
const KINDS: [&str; 13] = [
    "NormalLaw::",
    "FrictionLaw::",
    "NormalSpec::",
    "FrictionSpec::",
    "ContactModel::",
    "JointKind::",
    "RevoluteModel::",
    "Geometry::",
    "Prim::",
    "Profile::",
    "ProfileSpec::",
    "Effect::",
    "JointEffect::",
];

fn collect(dir: &Path, out: &mut Vec<PathBuf>) {
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            if p.file_name().is_some_and(|n| n != "tests") {
                collect(&p, out);
            }
        } else if p.extension().is_some_and(|x| x == "rs") && !p.ends_with("tests.rs") {
            out.push(p);
        }
    }
}

/// The code of `text` before its unit tests, `//` comments removed.
fn code(text: &str) -> Vec<String> {
    let mut out = Vec::new();
    for line in text.lines() {
        if line.trim_start().starts_with("#[cfg(test)]") {
            break;
        }
        out.push(line.split("//").next().unwrap().to_string());
    }
    out
}

/// The catch-all arms whose `match` also names a variant of [`KINDS`]: `(line, kind)`.
fn offenders(lines: &[String]) -> Vec<(usize, &'static str)> {
    let mut found = Vec::new();
    for (i, l) in lines.iter().enumerate() {
        let t = l.trim_start();
        if !t.starts_with("_ =>") {
            continue;
        }
        let indent = l.len() - t.len();
        // The arms of the same match: back to the line of its `match`, at the same indent.
        for prev in lines[..i].iter().rev() {
            let pt = prev.trim_start();
            let pindent = prev.len() - pt.len();
            if pindent < indent && pt.contains("match ") {
                break;
            }
            if pindent == indent
                && let Some(k) = KINDS
                    .iter()
                    .find(|k| pt.starts_with(**k) || pt.contains(&format!("| {k}")))
            {
                found.push((i + 1, *k));
                break;
            }
        }
    }
    found
}

#[test]
fn no_match_over_an_extendable_kind_has_a_catch_all_arm() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    collect(&src, &mut files);
    let mut bad = Vec::new();
    for f in &files {
        let lines = code(&std::fs::read_to_string(f).unwrap());
        for (line, kind) in offenders(&lines) {
            bad.push(format!(
                "{}:{line}: `_ =>` in a match over {kind}",
                f.strip_prefix(&src).unwrap().display()
            ));
        }
    }
    assert!(bad.is_empty(), "catch-all arms:\n  {}", bad.join("\n  "));
    // The scan sees what it should: a catch-all after a variant arm is found.
    let sample: Vec<String> = [
        "match g {",
        "    Geometry::Spherical { .. } => 1,",
        "    _ => 2,",
        "}",
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    assert_eq!(offenders(&sample), vec![(3, "Geometry::")]);
}
