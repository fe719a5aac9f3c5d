//! The committed work-precision table of the Duffing oscillator
//! (book/src/results/precision/precision-duffing.md) is what the program computes: the study is
//! run again and its table must equal the committed one digit for digit, apart from the columns
//! of wall time and its rate. Errors, evaluation counts and step counts are exact and repeat on
//! any machine; when this fails the program changed the results: run
//! `jointplay precision analyses/precision/duffing.toml --out book/src/results/precision` and
//! commit the table (book/src/results/work-precision.md says what it shows).

use std::path::PathBuf;
use std::process::Command;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// The table's lines without the wall-time columns.
fn deterministic(md: &str) -> Vec<String> {
    let mut drop: Vec<usize> = Vec::new();
    let mut out = Vec::new();
    for line in md.lines() {
        if !line.starts_with('|') {
            drop.clear();
            out.push(line.trim_end().to_string());
            continue;
        }
        let cells: Vec<&str> = line.trim_matches('|').split('|').map(str::trim).collect();
        if cells.contains(&"wall time (s)") {
            drop = cells
                .iter()
                .enumerate()
                .filter(|(_, c)| c.starts_with("wall time") || **c == "RHS/s")
                .map(|(i, _)| i)
                .collect();
        }
        let kept: Vec<&str> = cells
            .iter()
            .enumerate()
            .filter(|(i, _)| !drop.contains(i))
            .map(|(_, c)| *c)
            .collect();
        out.push(kept.join("|"));
    }
    out
}

#[test]
fn committed_duffing_work_precision_table_matches_the_program() {
    let committed =
        std::fs::read_to_string(root().join("book/src/results/precision/precision-duffing.md"))
            .unwrap();
    let dir = tempfile::tempdir().unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_jointplay"))
        .current_dir(root())
        .args([
            "precision",
            "analyses/precision/duffing.toml",
            "-q",
            "--no-plots",
            "--out",
        ])
        .arg(dir.path())
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let now = std::fs::read_to_string(dir.path().join("precision-duffing.md")).unwrap();
    let (a, b) = (deterministic(&committed), deterministic(&now));
    assert!(a.len() > 20, "{a:?}");
    for (i, (x, y)) in a.iter().zip(&b).enumerate() {
        assert_eq!(x, y, "line {} of the table", i + 1);
    }
    assert_eq!(a.len(), b.len());
}
