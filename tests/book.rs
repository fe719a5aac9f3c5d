//! The book (`book/src`, built by mdBook) cannot rot: these tests read its markdown as mdBook does
//! and hold it to what the repository and the program are.
//!
//! - Every chapter of `SUMMARY.md` exists, and every page is a chapter or included by one.
//! - Every link resolves: to a page and a heading id on it, to an image or file under `book/src`,
//!   or, through the repository URL `https://github.com/jointplay/jointplay/blob/main/PATH`, to a
//!   file of the checkout.
//! - Every `{{#include}}` names an existing file, and every included scene or study is checked by
//!   `jointplay check` as a user would run it.
//! - Every ```` ```toml ```` block is valid TOML and every ```` ```python ```` block compiles;
//!   every TOML example written in a page is laid over the scene or study it names and checked by
//!   `jointplay check`.
//! - The command-line reference (`reference/cli-help.md`) is the program's own `--help` text
//!   (`JOINTPLAY_BLESS=1 cargo test --test book` rewrites it).
//! - The tutorial's commands run, in order, page by page, and succeed.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Component, Path, PathBuf};
use std::process::Command;

const REPOSITORY: &str = "https://github.com/jointplay/jointplay/";

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn src() -> PathBuf {
    root().join("book/src")
}

fn bin() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_jointplay"));
    c.env("HDF5_USE_FILE_LOCKING", "FALSE");
    c
}

/// `a/b/../c` to `a/c`, without touching the file system.
fn normalize(path: &Path) -> PathBuf {
    let mut out = PathBuf::new();
    for c in path.components() {
        match c {
            Component::ParentDir => {
                out.pop();
            }
            Component::CurDir => {}
            other => out.push(other),
        }
    }
    out
}

/// Every markdown file under `book/src`, relative to it.
fn pages() -> Vec<PathBuf> {
    fn walk(dir: &Path, base: &Path, out: &mut Vec<PathBuf>) {
        let mut entries: Vec<_> = std::fs::read_dir(dir).unwrap().flatten().collect();
        entries.sort_by_key(|e| e.path());
        for e in entries {
            let p = e.path();
            if p.is_dir() {
                walk(&p, base, out);
            } else if p.extension().is_some_and(|x| x == "md") {
                out.push(p.strip_prefix(base).unwrap().to_path_buf());
            }
        }
    }
    let mut out = Vec::new();
    walk(&src(), &src(), &mut out);
    out
}

/// The chapters of `SUMMARY.md`, in reading order.
fn chapters() -> Vec<PathBuf> {
    let summary = std::fs::read_to_string(src().join("SUMMARY.md")).unwrap();
    links(&strip_code(&summary))
        .into_iter()
        .filter(|l| l.ends_with(".md"))
        .map(PathBuf::from)
        .collect()
}

/// A fenced code block: its info string, its text and the line it starts on.
struct Block {
    info: String,
    text: String,
    line: usize,
    /// The last non-blank line before the fence (a `<!-- check: FILE -->` annotation).
    before: String,
}

fn blocks(md: &str) -> Vec<Block> {
    let mut out = Vec::new();
    let mut open: Option<(String, usize, String, usize)> = None; // fence, line, info, indent
    let mut text = String::new();
    let mut last = String::new();
    let mut before = String::new();
    for (i, line) in md.lines().enumerate() {
        let trimmed = line.trim_start();
        let fence: String = trimmed
            .chars()
            .take_while(|&c| c == '`' || c == '~')
            .collect();
        match &open {
            None if fence.len() >= 3 => {
                let info = trimmed[fence.len()..].trim().to_string();
                open = Some((fence, i + 1, info, line.len() - trimmed.len()));
                text.clear();
                before.clone_from(&last);
            }
            Some((f, start, info, _)) if fence.len() >= f.len() && trimmed.trim() == fence => {
                out.push(Block {
                    info: info.clone(),
                    text: std::mem::take(&mut text),
                    line: *start,
                    before: std::mem::take(&mut before),
                });
                open = None;
            }
            Some((_, _, _, indent)) => {
                let cut = line.len().min(*indent);
                let cut = if line[..cut].trim().is_empty() {
                    cut
                } else {
                    0
                };
                text.push_str(&line[cut..]);
                text.push('\n');
            }
            None => {}
        }
        if open.is_none() && !line.trim().is_empty() {
            last = line.trim().to_string();
        }
    }
    out
}

/// What to keep of inline code outside the fenced blocks.
#[derive(Clone, Copy, PartialEq)]
enum Inline {
    /// Nothing: links in code are not links.
    Drop,
    /// Its text without the backticks: a heading's id includes it.
    Text,
}

/// The markdown outside its fenced blocks, inline code dropped or kept as text.
fn outside_fences(md: &str, inline: Inline) -> String {
    let mut out = String::new();
    let mut fence: Option<String> = None;
    for line in md.lines() {
        let trimmed = line.trim_start();
        let f: String = trimmed
            .chars()
            .take_while(|&c| c == '`' || c == '~')
            .collect();
        match &fence {
            None if f.len() >= 3 => fence = Some(f),
            Some(open) if f.len() >= open.len() && trimmed.trim() == f => fence = None,
            Some(_) => {}
            None => {
                let mut in_code = false;
                for c in line.chars() {
                    if c == '`' {
                        in_code = !in_code;
                    } else if !in_code || inline == Inline::Text {
                        out.push(c);
                    }
                }
                out.push('\n');
            }
        }
    }
    out
}

/// The markdown without its fenced blocks and inline code, where links are not links.
fn strip_code(md: &str) -> String {
    outside_fences(md, Inline::Drop)
}

/// Link targets: inline `[text](target)` and `![alt](target)`, and reference definitions
/// `[label]: target`.
fn links(md: &str) -> Vec<String> {
    let mut out = Vec::new();
    let bytes = md.as_bytes();
    let mut i = 0;
    while i + 1 < bytes.len() {
        if bytes[i] == b']' && bytes[i + 1] == b'(' {
            let start = i + 2;
            let mut depth = 1;
            let mut j = start;
            while j < bytes.len() && depth > 0 {
                match bytes[j] {
                    b'(' => depth += 1,
                    b')' => depth -= 1,
                    b'\n' => break,
                    _ => {}
                }
                j += 1;
            }
            if depth == 0 {
                let target = md[start..j - 1].split_whitespace().next().unwrap_or("");
                let target = target.trim_start_matches('<').trim_end_matches('>');
                if !target.is_empty() {
                    out.push(target.to_string());
                }
            }
            i = j;
        } else {
            i += 1;
        }
    }
    for line in md.lines() {
        let t = line.trim_start();
        if let Some(rest) = t.strip_prefix('[')
            && let Some(close) = rest.find("]:")
            && !rest[..close].contains('[')
            && let Some(target) = rest[close + 2..].split_whitespace().next()
        {
            out.push(target.to_string());
        }
    }
    out
}

/// mdBook's heading id: inline markup dropped, lower case, whitespace to `-`, and only letters,
/// digits, `-` and `_` kept; `{#id}` sets it explicitly.
fn heading_id(heading: &str) -> String {
    if let Some(open) = heading.rfind("{#")
        && heading.trim_end().ends_with('}')
    {
        return heading[open + 2..heading.trim_end().len() - 1].to_string();
    }
    // [text](url) to text
    let mut text = String::new();
    let mut rest = heading;
    while let Some(open) = rest.find('[') {
        text.push_str(&rest[..open]);
        let after = &rest[open + 1..];
        match (after.find("]("), after.find(')')) {
            (Some(close), Some(end)) if end > close => {
                text.push_str(&after[..close]);
                rest = &after[end + 1..];
            }
            _ => {
                text.push('[');
                rest = after;
            }
        }
    }
    text.push_str(rest);
    text.chars()
        .filter_map(|c| {
            if c.is_whitespace() {
                Some('-')
            } else if c.is_alphanumeric() || c == '_' || c == '-' {
                Some(c.to_lowercase().next().unwrap())
            } else {
                None
            }
        })
        .collect()
}

/// The `{{#include PATH[:...]}}` directives of a page: the path as written and its range part.
fn includes(md: &str) -> Vec<(String, Option<String>)> {
    let mut out = Vec::new();
    let mut rest = md;
    while let Some(open) = rest.find("{{#include ") {
        let after = &rest[open + "{{#include ".len()..];
        let Some(close) = after.find("}}") else { break };
        // `\{{#include ...}}` is mdBook's escape: the text itself, shown.
        if rest[..open].ends_with('\\') {
            rest = &after[close..];
            continue;
        }
        let arg = after[..close].trim();
        let (path, range) = match arg.split_once(':') {
            Some((p, r)) => (p.to_string(), Some(r.to_string())),
            None => (arg.to_string(), None),
        };
        out.push((path, range));
        rest = &after[close..];
    }
    out
}

/// A page as mdBook renders it: its included markdown files spliced in (whole files only).
fn expanded(page: &Path) -> String {
    let md = std::fs::read_to_string(src().join(page)).unwrap();
    let mut out = md.clone();
    for (path, range) in includes(&md) {
        if path.ends_with(".md") && range.is_none() {
            let file = normalize(&src().join(page).parent().unwrap().join(&path));
            let text = std::fs::read_to_string(&file).unwrap_or_default();
            out = out.replace(&format!("{{{{#include {path}}}}}"), &text);
        }
    }
    out
}

/// The heading ids of a page, numbered as mdBook numbers repeated ones.
fn heading_ids(page: &Path) -> BTreeSet<String> {
    let mut seen: BTreeMap<String, usize> = BTreeMap::new();
    let mut ids = BTreeSet::new();
    for line in outside_fences(&expanded(page), Inline::Text).lines() {
        let t = line.trim_start();
        if t.starts_with('#') {
            let text = t.trim_start_matches('#');
            if text.starts_with(' ') {
                let id = heading_id(text.trim());
                let n = seen.entry(id.clone()).or_insert(0);
                ids.insert(if *n == 0 {
                    id.clone()
                } else {
                    format!("{id}-{n}")
                });
                *n += 1;
            }
        }
    }
    ids
}

#[test]
fn every_chapter_exists_and_every_page_is_reachable() {
    let chapters: BTreeSet<PathBuf> = chapters().into_iter().collect();
    assert!(chapters.len() > 10, "SUMMARY.md lists {chapters:?}");
    let mut problems = Vec::new();
    for c in &chapters {
        if !src().join(c).is_file() {
            problems.push(format!(
                "SUMMARY.md: chapter {} does not exist",
                c.display()
            ));
        }
    }
    let mut included = BTreeSet::new();
    for page in pages() {
        let md = std::fs::read_to_string(src().join(&page)).unwrap();
        for (path, _) in includes(&md) {
            included.insert(normalize(&page.parent().unwrap().join(path)));
        }
    }
    for page in pages() {
        if page != Path::new("SUMMARY.md") && !chapters.contains(&page) && !included.contains(&page)
        {
            problems.push(format!(
                "{}: neither a chapter of SUMMARY.md nor included by one",
                page.display()
            ));
        }
    }
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}

#[test]
fn every_link_resolves() {
    let mut problems = Vec::new();
    let mut checked = 0;
    for page in pages() {
        let dir = page.parent().unwrap().to_path_buf();
        let md = expanded(&page);
        for target in links(&strip_code(&md)) {
            checked += 1;
            let whence = format!("{}: link {target}", page.display());
            if let Some(rest) = target.strip_prefix(REPOSITORY) {
                let path = rest
                    .strip_prefix("blob/main/")
                    .or_else(|| rest.strip_prefix("tree/main/"));
                match path {
                    Some(p) => {
                        let p = p.split('#').next().unwrap();
                        if !root().join(p).exists() {
                            problems.push(format!("{whence}: no {p} in the repository"));
                        }
                    }
                    None if rest.is_empty() => {}
                    None => problems.push(format!("{whence}: not a blob/main or tree/main URL")),
                }
                continue;
            }
            if target.contains("://") || target.starts_with("mailto:") {
                continue;
            }
            let (path, anchor) = match target.split_once('#') {
                Some((p, a)) => (p, Some(a)),
                None => (target.as_str(), None),
            };
            let file = if path.is_empty() {
                page.clone()
            } else {
                normalize(&dir.join(path))
            };
            // The API documentation is built beside the book (scripts/book) from the workspace's
            // crates.
            if let Ok(api) = file.strip_prefix("api") {
                let krate = api
                    .components()
                    .next()
                    .map(|c| c.as_os_str().to_string_lossy());
                let known = ["jointplay_solver", "jointplay_analysis", "jointplay"];
                if !krate.is_some_and(|k| known.contains(&k.as_ref())) {
                    problems.push(format!("{whence}: not a workspace crate's API page"));
                }
                continue;
            }
            if !src().join(&file).exists() {
                problems.push(format!("{whence}: {} does not exist", file.display()));
                continue;
            }
            if let Some(anchor) = anchor
                && file.extension().is_some_and(|x| x == "md")
                && !heading_ids(&file).contains(anchor)
            {
                problems.push(format!(
                    "{whence}: no heading with id `{anchor}` in {}",
                    file.display()
                ));
            }
        }
    }
    assert!(checked > 50, "only {checked} links found");
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}

/// Every included file exists; every included TOML scene, study or analysis is one the program
/// accepts.
#[test]
fn every_included_file_exists_and_every_included_scene_or_study_checks() {
    let mut problems = Vec::new();
    let mut tomls = BTreeSet::new();
    for page in pages() {
        let md = std::fs::read_to_string(src().join(&page)).unwrap();
        for (path, _) in includes(&md) {
            let file = normalize(&src().join(&page).parent().unwrap().join(&path));
            if !file.is_file() {
                problems.push(format!("{}: include {path}: no such file", page.display()));
            } else if file.extension().is_some_and(|x| x == "toml") {
                tomls.insert(file);
            }
        }
    }
    for file in &tomls {
        let out = bin().arg("check").arg(file).output().unwrap();
        if !out.status.success() {
            problems.push(format!(
                "jointplay check {}: {}",
                file.display(),
                String::from_utf8_lossy(&out.stderr)
            ));
        }
    }
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}

fn language(info: &str) -> &str {
    info.split([',', ' ']).next().unwrap_or("")
}

#[test]
fn every_toml_block_parses_and_every_python_block_compiles() {
    let mut problems = Vec::new();
    let mut python = Vec::new();
    for page in pages() {
        let md = std::fs::read_to_string(src().join(&page)).unwrap();
        for b in blocks(&md) {
            let at = format!("{}:{}", page.display(), b.line);
            if b.text.contains("{{#include") {
                continue; // the included file is checked itself
            }
            match language(&b.info) {
                "toml" => match b.text.parse::<toml::Table>() {
                    Err(e) => problems.push(format!("{at}: not TOML: {e}")),
                    Ok(t) => {
                        if ["bodies", "cases", "analysis"]
                            .iter()
                            .any(|k| t.contains_key(*k))
                            && t.contains_key("name")
                        {
                            problems.push(format!(
                                "{at}: a whole scene or study inline: include it from a file \
                                 that the book's test checks"
                            ));
                        }
                    }
                },
                "python" => python.push((at, b.text)),
                _ => {}
            }
        }
    }
    if !python.is_empty() {
        let mut script = String::from("import ast, sys\nbad = []\n");
        for (at, text) in &python {
            script.push_str(&format!(
                "try:\n    ast.parse({text:?})\nexcept SyntaxError as e:\n    bad.append({at:?} + ': ' + str(e))\n",
                text = text,
                at = at
            ));
        }
        script.push_str("print('\\n'.join(bad)); sys.exit(1 if bad else 0)\n");
        let out = Command::new("python3")
            .arg("-c")
            .arg(&script)
            .output()
            .expect("python3 (a prerequisite of scripts/setup) runs");
        if !out.status.success() {
            problems.push(format!(
                "python blocks that do not compile:\n{}{}",
                String::from_utf8_lossy(&out.stdout),
                String::from_utf8_lossy(&out.stderr)
            ));
        }
    }
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}

/// The command-line reference, generated from the program's `--help` texts.
fn cli_help() -> String {
    let help = |args: &[&str]| {
        let out = bin().args(args).arg("--help").output().unwrap();
        assert!(out.status.success(), "jointplay {args:?} --help");
        String::from_utf8(out.stdout).unwrap()
    };
    let top = help(&[]);
    let mut md = String::from(
        "<!-- Generated from the program's --help texts by tests/book.rs \
         (JOINTPLAY_BLESS=1 cargo test --test book); do not edit. -->\n\n",
    );
    md.push_str(&format!("### `jointplay`\n\n```text\n{}```\n", top));
    let commands: Vec<String> = top
        .split("Commands:")
        .nth(1)
        .expect("a Commands: section")
        .split("\n\n")
        .next()
        .unwrap()
        .lines()
        .filter_map(|l| {
            // A command's line starts with two spaces and its name; continuation lines are
            // indented further.
            let name = l.strip_prefix("  ")?;
            (!name.starts_with(' ')).then(|| name.split_whitespace().next().unwrap().to_string())
        })
        .filter(|c| c != "help")
        .collect();
    assert!(commands.len() >= 5, "{commands:?}");
    for c in commands {
        md.push_str(&format!(
            "\n### `jointplay {c}`\n\n```text\n{}```\n",
            help(&[&c])
        ));
    }
    md
}

#[test]
fn the_command_line_reference_is_the_programs_help() {
    let file = src().join("reference/cli-help.md");
    let now = cli_help();
    if std::env::var_os("JOINTPLAY_BLESS").is_some() {
        std::fs::write(&file, &now).unwrap();
    }
    let committed = std::fs::read_to_string(&file).unwrap_or_default();
    assert!(
        committed == now,
        "{} differs from the program's --help texts: rerun with JOINTPLAY_BLESS=1 and commit it",
        file.display()
    );
}

/// Splits a command line as a POSIX shell would for the simple words the tutorial uses: quotes
/// group, backslash-newline continues.
fn words(line: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut word = String::new();
    let mut quote: Option<char> = None;
    let mut any = false;
    for c in line.chars() {
        match (quote, c) {
            (Some(q), c) if c == q => quote = None,
            (Some(_), c) => word.push(c),
            (None, '\'' | '"') => {
                quote = Some(c);
                any = true;
            }
            (None, c) if c.is_whitespace() => {
                if any || !word.is_empty() {
                    out.push(std::mem::take(&mut word));
                }
                any = false;
            }
            (None, '#') if word.is_empty() && !any => break,
            (None, c) => word.push(c),
        }
    }
    if any || !word.is_empty() {
        out.push(word);
    }
    out
}

/// The tutorial's commands: every line of a ```` ```sh ```` block of a tutorial chapter that
/// starts with `jointplay `, in reading order.
fn tutorial_commands() -> Vec<(PathBuf, Vec<String>)> {
    let mut out = Vec::new();
    for page in chapters() {
        if !page.starts_with("tutorial") {
            continue;
        }
        let md = std::fs::read_to_string(src().join(&page)).unwrap();
        for b in blocks(&md) {
            if !matches!(language(&b.info), "sh" | "bash" | "console") {
                continue;
            }
            let joined = b.text.replace("\\\n", " ");
            for line in joined.lines() {
                let line = line.trim().trim_start_matches("$ ");
                if line.starts_with("jointplay ") {
                    out.push((page.clone(), words(line)));
                }
            }
        }
    }
    out
}

#[test]
fn the_tutorial_runs() {
    let commands = tutorial_commands();
    assert!(commands.len() >= 5, "tutorial commands: {commands:?}");
    // The reader's working directory: the repository's folders the tutorial names, and room for
    // its outputs.
    let dir = tempfile::tempdir().unwrap();
    for name in ["book", "data", "analyses"] {
        std::os::unix::fs::symlink(root().join(name), dir.path().join(name)).unwrap();
    }
    for (page, words) in commands {
        let out = bin()
            .args(&words[1..])
            .current_dir(dir.path())
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{}: `{}` failed:\n{}{}",
            page.display(),
            words.join(" "),
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        );
    }
}

#[test]
fn the_checks_read_markdown_as_mdbook_does() {
    assert_eq!(
        heading_id("Is it chaos? Lyapunov exponents and the 0-1 test"),
        "is-it-chaos-lyapunov-exponents-and-the-0-1-test"
    );
    assert_eq!(heading_id("The `[solver]` table"), "the-solver-table");
    assert_eq!(heading_id("Drives {#drives}"), "drives");
    assert_eq!(
        links("see [a](x.md#b) and ![i](f/i.png \"t\")\n[r]: https://e.org/x\n"),
        ["x.md#b", "f/i.png", "https://e.org/x"]
    );
    assert_eq!(
        words("jointplay run 'a b' --out out/x # comment"),
        ["jointplay", "run", "a b", "--out", "out/x"]
    );
    let b = blocks("text\n```toml\na = 1\n```\n````md\n```\n````\n");
    assert_eq!(b.len(), 2);
    assert_eq!(
        (b[0].info.as_str(), b[0].text.as_str()),
        ("toml", "a = 1\n")
    );
    assert_eq!(b[1].text, "```\n");
    assert!(includes("shown: \\{{#include z.toml}}").is_empty());
    assert_eq!(
        includes("{{#include ../x.toml:3:9}} and {{#include y.md}}"),
        [
            ("../x.toml".to_string(), Some("3:9".to_string())),
            ("y.md".to_string(), None)
        ]
    );
}

/// The README is a front page: short, and every link of it leads to a file of the checkout (the
/// book's pages among them).
#[test]
fn the_front_page_is_short_and_its_links_resolve() {
    let readme = std::fs::read_to_string(root().join("README.md")).unwrap();
    let lines = readme.lines().count();
    assert!(
        lines <= 200,
        "README.md has {lines} lines: the rest belongs in the book"
    );
    let mut problems = Vec::new();
    for target in links(&strip_code(&readme)) {
        if target.contains("://") {
            continue;
        }
        let path = target.split('#').next().unwrap();
        if !root().join(path).exists() {
            problems.push(format!("README.md: link {target}: no {path}"));
        }
    }
    // The test command .ci/run runs is the README's.
    let ci = std::fs::read_to_string(root().join(".ci/run")).unwrap();
    let command = "scripts/setup && cargo test --workspace";
    assert!(readme.contains(command) && ci.contains(command));
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}

/// `base` with `fragment` laid over it: tables merged key by key, arrays of tables merged by
/// their `name` (an element of the same name replaced, others appended), other values replaced.
fn overlay(base: &mut toml::Table, fragment: &toml::Table) {
    for (k, v) in fragment {
        match (base.get_mut(k), v) {
            (Some(toml::Value::Table(b)), toml::Value::Table(f)) => overlay(b, f),
            (Some(toml::Value::Array(b)), toml::Value::Array(f))
                if f.iter().all(|e| e.get("name").is_some()) =>
            {
                for e in f {
                    match b.iter().position(|x| x.get("name") == e.get("name")) {
                        Some(i) => b[i] = e.clone(),
                        None => b.push(e.clone()),
                    }
                }
            }
            _ => {
                base.insert(k.clone(), v.clone());
            }
        }
    }
}

/// Every TOML example written in a page (not included from a file) is a part of a scene or a
/// study, and says which: `<!-- check: FILE -->` on the line before it names a file it fits
/// (relative to the page). Laid over that file (or, with `<!-- check: FILE, replacing -->`, its
/// tables put in the place of the file's), it must be accepted by `jointplay check`. An example
/// that is no file of the program says so: `<!-- not a jointplay file: WHAT -->`.
#[test]
fn every_toml_example_checks_in_the_file_it_belongs_to() {
    let dir = tempfile::tempdir().unwrap();
    let mut problems = Vec::new();
    let mut checked = 0;
    for page in pages() {
        let md = std::fs::read_to_string(src().join(&page)).unwrap();
        for (n, b) in blocks(&md).into_iter().enumerate() {
            if language(&b.info) != "toml" || b.text.contains("{{#include") {
                continue;
            }
            let at = format!("{}:{}", page.display(), b.line);
            if b.before.starts_with("<!-- not a jointplay file:") {
                continue;
            }
            let Some(base) = b
                .before
                .strip_prefix("<!-- check:")
                .and_then(|r| r.strip_suffix("-->"))
                .map(str::trim)
            else {
                problems.push(format!(
                    "{at}: a TOML example needs `<!-- check: FILE -->` on the line before it (the \
                     scene or study it is a part of), or `<!-- not a jointplay file: WHAT -->`"
                ));
                continue;
            };
            // `FILE, replacing`: the example's tables take the place of the file's whole.
            let (base, replacing) = match base.strip_suffix(", replacing") {
                Some(b) => (b, true),
                None => (base, false),
            };
            let base = normalize(&src().join(&page).parent().unwrap().join(base));
            let (Ok(text), Ok(fragment)) = (
                std::fs::read_to_string(&base),
                b.text.parse::<toml::Table>(),
            ) else {
                problems.push(format!(
                    "{at}: {} or the example does not read",
                    base.display()
                ));
                continue;
            };
            let mut doc: toml::Table = text.parse().unwrap();
            if replacing {
                for (k, v) in &fragment {
                    doc.insert(k.clone(), v.clone());
                }
            } else {
                overlay(&mut doc, &fragment);
            }
            // A study names its scene relative to itself.
            let here = base.parent().unwrap();
            if let Some(toml::Value::Table(study)) = doc.get_mut("study")
                && let Some(toml::Value::String(scene)) = study.get_mut("scene")
            {
                *scene = here.join(&*scene).display().to_string();
            }
            let file = dir.path().join(format!("example-{checked}-{n}.toml"));
            std::fs::write(&file, toml::to_string(&doc).unwrap()).unwrap();
            checked += 1;
            let out = bin().arg("check").arg(&file).output().unwrap();
            if !out.status.success() {
                problems.push(format!(
                    "{at}: laid over {}, `jointplay check` says: {}",
                    base.display(),
                    String::from_utf8_lossy(&out.stderr).trim()
                ));
            }
        }
    }
    assert!(checked >= 10, "only {checked} TOML examples checked");
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}
