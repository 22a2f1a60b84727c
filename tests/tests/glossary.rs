//! The glossary of docs/architecture.md matches the code: every name it gives exists (a crate,
//! a module, a type, a function or a constant of the workspace), none is given twice, and no two
//! public types of the workspace's libraries share a name — one meaning per word.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// The workspace's members (folders), from its manifest.
fn members() -> Vec<String> {
    let manifest = std::fs::read_to_string(root().join("Cargo.toml")).unwrap();
    manifest
        .split("members = [")
        .nth(1)
        .and_then(|s| s.split(']').next())
        .unwrap()
        .split(',')
        .map(|m| m.trim().trim_matches('"').to_string())
        .filter(|m| !m.is_empty())
        .collect()
}

/// Every `.rs` file under `dir`, recursively.
fn sources(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for e in entries.flatten() {
        let p = e.path();
        if p.is_dir() {
            sources(&p, out);
        } else if p.extension().is_some_and(|x| x == "rs") {
            out.push(p);
        }
    }
}

/// The library and binary sources of every member (`src/`, not tests, benches or examples).
fn product_sources() -> Vec<(PathBuf, String)> {
    let mut files = Vec::new();
    for m in members() {
        sources(&root().join(&m).join("src"), &mut files);
    }
    files
        .into_iter()
        .map(|f| {
            let text = std::fs::read_to_string(&f).unwrap();
            (f, text)
        })
        .collect()
}

/// The items a source declares: (keyword, name, whether `pub`), from lines such as
/// `pub(crate) struct Name`, `pub fn name(`, `mod name;`.
fn declared(text: &str) -> Vec<(String, String, bool)> {
    let mut out = Vec::new();
    for line in text.lines() {
        let l = line.trim_start();
        let (public, rest) = if let Some(r) = l.strip_prefix("pub ") {
            (true, r)
        } else if let Some(r) = l.strip_prefix("pub(crate) ") {
            (false, r)
        } else {
            (false, l)
        };
        for kw in [
            "struct", "enum", "trait", "type", "mod", "fn", "const", "static",
        ] {
            if let Some(r) = rest.strip_prefix(kw).and_then(|r| r.strip_prefix(' ')) {
                let name: String = r
                    .chars()
                    .take_while(|c| c.is_alphanumeric() || *c == '_')
                    .collect();
                if !name.is_empty() {
                    out.push((kw.to_string(), name, public));
                }
            }
        }
    }
    out
}

/// The glossary's rows: (word, the names its last column gives in backticks).
fn glossary(doc: &str) -> Vec<(String, Vec<String>)> {
    let start = doc
        .find("\n## Glossary")
        .expect("docs/architecture.md has a Glossary");
    let section = &doc[start + 1..];
    let end = section[3..].find("\n## ").map_or(section.len(), |e| e + 3);
    section[..end]
        .lines()
        .filter(|l| l.starts_with("| ") && !l.starts_with("| word") && !l.starts_with("|---"))
        .map(|l| {
            let cells: Vec<&str> = l.trim().trim_matches('|').split(" | ").collect();
            let names = cells
                .last()
                .unwrap()
                .split('`')
                .skip(1)
                .step_by(2)
                .map(String::from)
                .collect();
            (cells[0].trim().to_string(), names)
        })
        .collect()
}

/// Names given twice in the glossary, and names that are no crate and no item of the code.
fn glossary_problems(
    rows: &[(String, Vec<String>)],
    crates: &[String],
    items: &[(String, String, bool)],
) -> (Vec<String>, Vec<String>) {
    let mut seen: BTreeMap<&str, &str> = BTreeMap::new();
    let (mut twice, mut missing) = (Vec::new(), Vec::new());
    for (word, names) in rows {
        for n in names {
            if let Some(other) = seen.insert(n, word) {
                twice.push(format!("{n} ({other}, {word})"));
            }
            let exists = crates.contains(n) || items.iter().any(|(_, name, _)| name == n);
            if !exists {
                missing.push(format!("{n} ({word})"));
            }
        }
    }
    (twice, missing)
}

/// The package names of the workspace's members.
fn crate_names() -> Vec<String> {
    members()
        .iter()
        .map(|m| {
            let manifest = std::fs::read_to_string(root().join(m).join("Cargo.toml")).unwrap();
            manifest
                .lines()
                .find_map(|l| l.strip_prefix("name = \""))
                .and_then(|l| l.strip_suffix('"'))
                .unwrap()
                .to_string()
        })
        .collect()
}

#[test]
fn every_name_of_the_glossary_exists_once() {
    let doc = std::fs::read_to_string(root().join("docs/architecture.md")).unwrap();
    let rows = glossary(&doc);
    assert!(rows.len() >= 20, "{rows:?}");
    let items: Vec<_> = product_sources()
        .iter()
        .flat_map(|(_, t)| declared(t))
        .collect();
    let (twice, missing) = glossary_problems(&rows, &crate_names(), &items);
    assert!(twice.is_empty(), "given twice: {twice:?}");
    assert!(missing.is_empty(), "not in the code: {missing:?}");
}

/// Types every binary has one of: its command line (clap's `Args` and `Command`).
const PER_BINARY: [&str; 2] = ["Args", "Command"];

#[test]
fn no_two_public_types_share_a_name() {
    let mut by_name: BTreeMap<String, Vec<String>> = BTreeMap::new();
    for (file, text) in product_sources() {
        for (kw, name, public) in declared(&text) {
            if public && ["struct", "enum", "trait", "type"].contains(&kw.as_str()) {
                by_name
                    .entry(name)
                    .or_default()
                    .push(file.strip_prefix(root()).unwrap().display().to_string());
            }
        }
    }
    let shared: Vec<_> = by_name
        .into_iter()
        .filter(|(n, files)| files.len() > 1 && !PER_BINARY.contains(&n.as_str()))
        .collect();
    assert!(shared.is_empty(), "{shared:#?}");
}

/// The checker itself: a name given twice, a name the code lacks, and the declarations it reads.
#[test]
fn the_glossary_checker_finds_names_twice_and_missing() {
    let doc = "x\n## Glossary\n\n| word | what | in the code |\n|---|---|---|\n\
        | frame | a picture | `Frame`, `scanner-core` |\n| view | a scan | `View`, `Frame`, `Nowhere` |\n\
        \n## Next\n| not | a | `Row` |\n";
    let rows = glossary(doc);
    assert_eq!(rows.len(), 2, "{rows:?}");
    let items =
        declared("pub struct Frame {\npub(crate) enum View {\n    fn helper() {}\nmod depth;\n");
    assert_eq!(
        items,
        [
            ("struct".into(), "Frame".into(), true),
            ("enum".into(), "View".into(), false),
            ("fn".into(), "helper".into(), false),
            ("mod".into(), "depth".into(), false),
        ]
    );
    let (twice, missing) = glossary_problems(&rows, &["scanner-core".into()], &items);
    assert_eq!(twice, ["Frame (frame, view)"]);
    assert_eq!(missing, ["Nowhere (view)"]);
}
