//! No module cycles, and every arrow with the layers: for each crate of the workspace, every
//! `crate::`, `super::` and `self::` path in its sources (inline ones as well as `use` lines) is
//! an arrow from the module it is written in to the module it names. Arrows between the
//! children of one module must form no cycle, and arrows between a crate's top-level modules
//! must run down the layers its root file (`lib.rs`, or `main.rs` for a binary) states:
//!
//! ```text
//! //! # Layers
//! //! ```text
//! //! cli
//! //! merge   check
//! //! spatial
//! //! ```
//! ```
//!
//! one line per layer, top first: a module may use the modules of its own line and of the lines
//! below, never those above. Every top-level module is on exactly one line. An arrow between a
//! module and one inside it (a parent and its child) is no arrow between layers. Test modules
//! (`#[cfg(test)] mod …`) are no part of the layers: a message's golden test beside its code
//! may read it as the message enum above it does.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// The workspace's crates: their folders and root files.
fn crates() -> Vec<(String, PathBuf)> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).parent().unwrap();
    let manifest = std::fs::read_to_string(root.join("Cargo.toml")).unwrap();
    let members = manifest
        .split("members = [")
        .nth(1)
        .and_then(|s| s.split(']').next())
        .expect("the workspace's members");
    let mut out = Vec::new();
    for m in members.split(',') {
        let m = m.trim().trim_matches('"');
        if m.is_empty() {
            continue;
        }
        let dir = root.join(m);
        for file in ["src/lib.rs", "src/main.rs"] {
            if dir.join(file).exists() {
                out.push((format!("{m}/{file}"), dir.join(file)));
            }
        }
    }
    assert!(out.len() >= 8, "found only {out:?}");
    out
}

/// The source without comments, strings and character literals (each replaced by spaces, so
/// that lines keep their numbers).
fn code_only(text: &str) -> String {
    let c: Vec<char> = text.chars().collect();
    let mut out = String::with_capacity(text.len());
    let blank = |ch: char| if ch == '\n' { '\n' } else { ' ' };
    let mut i = 0;
    while i < c.len() {
        let next = c.get(i + 1).copied();
        if c[i] == '/' && next == Some('/') {
            while i < c.len() && c[i] != '\n' {
                out.push(' ');
                i += 1;
            }
        } else if c[i] == '/' && next == Some('*') {
            let mut depth = 0;
            while i < c.len() {
                if c[i] == '/' && c.get(i + 1) == Some(&'*') {
                    depth += 1;
                    out.push_str("  ");
                    i += 2;
                } else if c[i] == '*' && c.get(i + 1) == Some(&'/') {
                    depth -= 1;
                    out.push_str("  ");
                    i += 2;
                    if depth == 0 {
                        break;
                    }
                } else {
                    out.push(blank(c[i]));
                    i += 1;
                }
            }
        } else if c[i] == 'r'
            && (next == Some('"') || next == Some('#'))
            && (i == 0 || !is_ident(c[i - 1]))
        {
            // a raw string: r"…", r#"…"#
            let mut j = i + 1;
            let mut hashes = 0;
            while c.get(j) == Some(&'#') {
                hashes += 1;
                j += 1;
            }
            if c.get(j) != Some(&'"') {
                out.push(c[i]);
                i += 1;
                continue;
            }
            j += 1;
            loop {
                if j >= c.len() {
                    break;
                }
                if c[j] == '"' && (0..hashes).all(|h| c.get(j + 1 + h) == Some(&'#')) {
                    j += 1 + hashes;
                    break;
                }
                j += 1;
            }
            for &ch in &c[i..j.min(c.len())] {
                out.push(blank(ch));
            }
            i = j;
        } else if c[i] == '"' {
            out.push(' ');
            i += 1;
            while i < c.len() && c[i] != '"' {
                if c[i] == '\\' {
                    out.push(' ');
                    i += 1;
                }
                if i < c.len() {
                    out.push(blank(c[i]));
                    i += 1;
                }
            }
            out.push(' ');
            i += 1;
        } else if c[i] == '\'' {
            // a character literal ('a', '\n', '\u{..}') or a lifetime ('a)
            if next == Some('\\') {
                let mut j = i + 2;
                while j < c.len() && c[j] != '\'' {
                    j += 1;
                }
                out.extend(std::iter::repeat_n(' ', j + 1 - i));
                i = j + 1;
            } else if c.get(i + 2) == Some(&'\'') {
                out.push_str("   ");
                i += 3;
            } else {
                out.push(c[i]);
                i += 1;
            }
        } else {
            out.push(c[i]);
            i += 1;
        }
    }
    out
}

fn is_ident(ch: char) -> bool {
    ch.is_alphanumeric() || ch == '_'
}

/// The code with every `#[cfg(test)] mod name { … }` and `#[cfg(test)] mod name;` blanked
/// (lines kept).
fn without_test_modules(code: &str) -> String {
    let mut out: Vec<char> = code.chars().collect();
    let attr: Vec<char> = "#[cfg(test)]".chars().collect();
    let mut i = 0;
    while i + attr.len() <= out.len() {
        if out[i..i + attr.len()] != attr[..] {
            i += 1;
            continue;
        }
        let mut j = i + attr.len();
        while j < out.len() && out[j].is_whitespace() {
            j += 1;
        }
        let rest: String = out[j..out.len().min(j + 4)].iter().collect();
        if rest != "mod " {
            i += 1;
            continue;
        }
        while j < out.len() && out[j] != '{' && out[j] != ';' {
            j += 1;
        }
        if j < out.len() && out[j] == '{' {
            let mut depth = 0;
            while j < out.len() {
                match out[j] {
                    '{' => depth += 1,
                    '}' => depth -= 1,
                    _ => {}
                }
                j += 1;
                if depth == 0 {
                    break;
                }
            }
        } else {
            j = (j + 1).min(out.len());
        }
        for ch in &mut out[i..j] {
            if *ch != '\n' {
                *ch = ' ';
            }
        }
        i = j;
    }
    out.into_iter().collect()
}

/// One module file: its path of module names from the crate's root and its code.
struct Module {
    path: Vec<String>,
    file: PathBuf,
    code: String,
}

/// Every module of a crate, from its root file by its `mod name;` declarations.
fn modules(root: &Path) -> Vec<Module> {
    let mut out = Vec::new();
    let mut todo = vec![(Vec::new(), root.to_path_buf())];
    while let Some((path, file)) = todo.pop() {
        let code = without_test_modules(&code_only(&std::fs::read_to_string(&file).unwrap()));
        // where its children's files are
        let stem = file.file_stem().unwrap().to_str().unwrap();
        let dir = if path.is_empty() || stem == "mod" {
            file.parent().unwrap().to_path_buf()
        } else {
            file.parent().unwrap().join(stem)
        };
        for name in declared(&code) {
            let child = [
                dir.join(format!("{name}.rs")),
                dir.join(&name).join("mod.rs"),
            ]
            .into_iter()
            .find(|f| f.exists())
            .unwrap_or_else(|| panic!("mod {name} of {} has no file", file.display()));
            let mut p = path.clone();
            p.push(name);
            todo.push((p, child));
        }
        out.push(Module { path, file, code });
    }
    out
}

/// The identifiers of `code` with their byte offsets.
fn words(code: &str) -> Vec<(usize, &str)> {
    let mut out = Vec::new();
    let mut start = None;
    for (i, ch) in code.char_indices() {
        match (is_ident(ch), start) {
            (true, None) => start = Some(i),
            (false, Some(s)) => {
                out.push((s, &code[s..i]));
                start = None;
            }
            _ => {}
        }
    }
    if let Some(s) = start {
        out.push((s, &code[s..]));
    }
    out
}

/// The modules `code` declares in files of their own (`mod name;`).
fn declared(code: &str) -> Vec<String> {
    let w = words(code);
    let mut out = Vec::new();
    for (k, &(_, word)) in w.iter().enumerate() {
        if word != "mod" {
            continue;
        }
        let Some(&(at, name)) = w.get(k + 1) else {
            continue;
        };
        let rest = code[at + name.len()..].trim_start();
        if rest.starts_with(';') {
            out.push(name.to_string());
        }
    }
    out
}

/// The module path `code` is in at byte `at`: the inline `mod name { … }` blocks around it.
fn inline_path(code: &str, at: usize) -> Vec<String> {
    let mut stack: Vec<(String, usize)> = Vec::new();
    let mut depth = 0usize;
    let mut pending: Option<String> = None;
    let bytes = code.as_bytes();
    let w = words(code);
    let mut wi = 0;
    for (i, &b) in bytes.iter().enumerate().take(at) {
        while wi < w.len() && w[wi].0 == i {
            if w[wi].1 == "mod"
                && let Some(&(after, name)) = w.get(wi + 1)
                && code[after + name.len()..].trim_start().starts_with('{')
            {
                pending = Some(name.to_string());
            }
            wi += 1;
        }
        match b {
            b'{' => {
                depth += 1;
                if let Some(name) = pending.take() {
                    stack.push((name, depth));
                }
            }
            b'}' => {
                if stack.last().is_some_and(|(_, d)| *d == depth) {
                    stack.pop();
                }
                depth = depth.saturating_sub(1);
            }
            _ => {}
        }
    }
    stack.into_iter().map(|(n, _)| n).collect()
}

/// The paths in `text` (after `crate::`, `super::` or `self::` at byte `from`): each as its
/// segments, groups (`{a, b::c}`) expanded.
fn paths_at(text: &str, from: usize) -> Vec<Vec<String>> {
    let rest = &text[from..];
    let mut out = Vec::new();
    let mut segs = Vec::new();
    let mut i = 0;
    let b = rest.as_bytes();
    loop {
        while i < b.len() && (b[i] as char).is_whitespace() {
            i += 1;
        }
        if i < b.len() && b[i] == b'{' {
            // a group: each item, to its matching comma at depth 0
            let mut depth = 0;
            let mut start = i + 1;
            let mut j = i;
            while j < b.len() {
                match b[j] {
                    b'{' => depth += 1,
                    b'}' => {
                        depth -= 1;
                        if depth == 0 {
                            break;
                        }
                    }
                    b',' if depth == 1 => {
                        for p in paths_at(&rest[..j], start) {
                            let mut full = segs.clone();
                            full.extend(p);
                            out.push(full);
                        }
                        start = j + 1;
                    }
                    _ => {}
                }
                j += 1;
            }
            for p in paths_at(&rest[..j.min(b.len())], start) {
                let mut full = segs.clone();
                full.extend(p);
                out.push(full);
            }
            return out;
        }
        let s = i;
        while i < b.len() && is_ident(b[i] as char) {
            i += 1;
        }
        if i == s {
            break;
        }
        segs.push(rest[s..i].to_string());
        let after = rest[i..].trim_start();
        if after.starts_with("::") {
            i = rest.len() - after.len() + 2;
        } else {
            break;
        }
    }
    out.push(segs);
    out
}

/// An arrow: from a module to another, written at a file's line.
#[derive(Debug, Clone)]
struct Arrow {
    from: Vec<String>,
    to: Vec<String>,
    at: String,
}

/// Every arrow of a crate's modules.
fn arrows(mods: &[Module]) -> Vec<Arrow> {
    let known: BTreeSet<Vec<String>> = mods.iter().map(|m| m.path.clone()).collect();
    // names the root re-exports from a module (`pub use module::{A, B}`)
    let root = mods.iter().find(|m| m.path.is_empty()).unwrap();
    let mut reexports: BTreeMap<String, Vec<String>> = BTreeMap::new();
    for (at, w) in words(&root.code) {
        if w != "use" || !root.code[..at].trim_end().ends_with("pub") {
            continue;
        }
        for p in paths_at(&root.code, at + 3) {
            let p: Vec<String> = p.into_iter().skip_while(|s| s == "crate").collect();
            if let (Some(first), Some(last)) = (p.first(), p.last())
                && known.contains(&vec![first.clone()])
            {
                reexports.insert(last.clone(), vec![first.clone()]);
            }
        }
    }
    let mut out = Vec::new();
    for m in mods {
        let w = words(&m.code);
        for (k, &(at, word)) in w.iter().enumerate() {
            if !matches!(word, "crate" | "super" | "self") {
                continue;
            }
            let before = m.code[..at].trim_end();
            // `$crate::` of macros, and a path's later segment (`a::super::`) are not starts
            if before.ends_with('$') || before.ends_with("::") {
                continue;
            }
            if !m.code[at + word.len()..].trim_start().starts_with("::") {
                continue;
            }
            let here: Vec<String> = m
                .path
                .iter()
                .cloned()
                .chain(inline_path(&m.code, at))
                .collect();
            let mut base = match word {
                "crate" => Vec::new(),
                "self" => here.clone(),
                _ => here[..here.len().saturating_sub(1)].to_vec(),
            };
            let _ = k;
            let start = at + word.len() + m.code[at + word.len()..].find("::").unwrap() + 2;
            for p in paths_at(&m.code, start) {
                let mut segs = p.as_slice();
                // further `super::`
                while segs.first().is_some_and(|s| s == "super") {
                    base.pop();
                    segs = &segs[1..];
                }
                let mut full = base.clone();
                full.extend(segs.iter().cloned());
                // the longest known module the path names
                let mut to: Vec<String> = (0..=full.len())
                    .rev()
                    .map(|n| full[..n].to_vec())
                    .find(|p| known.contains(p))
                    .unwrap_or_default();
                if to.is_empty()
                    && let Some(first) = full.first()
                    && let Some(m) = reexports.get(first)
                {
                    to = m.clone();
                }
                let line = m.code[..at].matches('\n').count() + 1;
                out.push(Arrow {
                    from: m.path.clone(),
                    to,
                    at: format!("{}:{line}", m.file.display()),
                });
            }
        }
    }
    out
}

/// The arrow between the two children of one module that `a` → `b` amounts to (`None` when
/// one lies inside the other).
fn between(a: &[String], b: &[String]) -> Option<(Vec<String>, String, String)> {
    let common = a.iter().zip(b).take_while(|(x, y)| x == y).count();
    if common == a.len() || common == b.len() {
        return None;
    }
    Some((a[..common].to_vec(), a[common].clone(), b[common].clone()))
}

/// The layers a root file states (top first), `None` when it states none.
fn layers(root_code_with_docs: &str) -> Option<Vec<Vec<String>>> {
    let mut lines = root_code_with_docs.lines().map(str::trim);
    lines.find(|l| l.starts_with("//!") && l.trim_start_matches("//!").trim() == "# Layers")?;
    lines.find(|l| l.trim_start_matches("//!").trim() == "```text")?;
    let mut out = Vec::new();
    for l in lines {
        let l = l.trim_start_matches("//!").trim();
        if l == "```" {
            return Some(out);
        }
        let names: Vec<String> = l
            .split(|c: char| !is_ident(c))
            .filter(|s| !s.is_empty())
            .map(String::from)
            .collect();
        if !names.is_empty() {
            out.push(names);
        }
    }
    None
}

/// The strongly connected parts of more than one node of a graph (Tarjan).
fn cycles(
    nodes: &BTreeSet<String>,
    edges: &BTreeMap<String, BTreeSet<String>>,
) -> Vec<Vec<String>> {
    struct State<'a> {
        edges: &'a BTreeMap<String, BTreeSet<String>>,
        index: BTreeMap<String, usize>,
        low: BTreeMap<String, usize>,
        stack: Vec<String>,
        on: BTreeSet<String>,
        out: Vec<Vec<String>>,
    }
    fn visit(s: &mut State<'_>, v: &str) {
        let i = s.index.len();
        s.index.insert(v.into(), i);
        s.low.insert(v.into(), i);
        s.stack.push(v.into());
        s.on.insert(v.into());
        for w in s.edges.get(v).cloned().unwrap_or_default() {
            if !s.index.contains_key(&w) {
                visit(s, &w);
                let lw = s.low[&w];
                let lv = s.low.get_mut(v).unwrap();
                *lv = (*lv).min(lw);
            } else if s.on.contains(&w) {
                let iw = s.index[&w];
                let lv = s.low.get_mut(v).unwrap();
                *lv = (*lv).min(iw);
            }
        }
        if s.low[v] == s.index[v] {
            let mut part = Vec::new();
            while let Some(w) = s.stack.pop() {
                s.on.remove(&w);
                let done = w == v;
                part.push(w);
                if done {
                    break;
                }
            }
            if part.len() > 1 {
                part.sort();
                s.out.push(part);
            }
        }
    }
    let mut s = State {
        edges,
        index: BTreeMap::new(),
        low: BTreeMap::new(),
        stack: Vec::new(),
        on: BTreeSet::new(),
        out: Vec::new(),
    };
    for v in nodes {
        if !s.index.contains_key(v) {
            visit(&mut s, v);
        }
    }
    s.out
}

/// Per parent module, the arrows between its children (from, to) with where each is written.
type Graphs = BTreeMap<Vec<String>, BTreeMap<(String, String), Vec<String>>>;

/// What is wrong with one crate's modules: cycles, arrows against its layers, modules its
/// layers leave out or name wrongly.
fn problems(name: &str, root: &Path) -> Vec<String> {
    let mods = modules(root);
    let mut out = Vec::new();
    let mut graphs: Graphs = BTreeMap::new();
    for a in arrows(&mods) {
        if let Some((parent, x, y)) = between(&a.from, &a.to) {
            graphs
                .entry(parent)
                .or_default()
                .entry((x, y))
                .or_default()
                .push(a.at);
        }
    }
    for (parent, edges) in &graphs {
        let mut nodes = BTreeSet::new();
        let mut adj: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
        for (x, y) in edges.keys() {
            nodes.insert(x.clone());
            nodes.insert(y.clone());
            adj.entry(x.clone()).or_default().insert(y.clone());
        }
        for c in cycles(&nodes, &adj) {
            let written: Vec<String> = edges
                .iter()
                .filter(|((x, y), _)| c.contains(x) && c.contains(y))
                .map(|((x, y), at)| format!("{x} → {y} at {}", at.join(", ")))
                .collect();
            out.push(format!(
                "{name}: a cycle between the modules {c:?} of `{}`: {}",
                parent.join("::"),
                written.join("; ")
            ));
        }
    }
    let text = std::fs::read_to_string(root).unwrap();
    let top: BTreeSet<String> = mods
        .iter()
        .filter(|m| m.path.len() == 1)
        .map(|m| m.path[0].clone())
        .collect();
    let Some(layers) = layers(&text) else {
        if top.len() > 1 {
            out.push(format!(
                "{name}: its {} modules have no `# Layers` section",
                top.len()
            ));
        }
        return out;
    };
    let mut layer_of = BTreeMap::new();
    for (i, l) in layers.iter().enumerate() {
        for m in l {
            if !top.contains(m) {
                out.push(format!(
                    "{name}: its layers name `{m}`, which is no module of it"
                ));
            }
            if layer_of.insert(m.clone(), i).is_some() {
                out.push(format!("{name}: its layers name `{m}` twice"));
            }
        }
    }
    for m in &top {
        if !layer_of.contains_key(m) {
            out.push(format!("{name}: its layers leave out the module `{m}`"));
        }
    }
    if let Some(edges) = graphs.get(&Vec::new()) {
        for ((x, y), at) in edges {
            if let (Some(lx), Some(ly)) = (layer_of.get(x), layer_of.get(y))
                && ly < lx
            {
                out.push(format!(
                    "{name}: `{x}` uses `{y}`, a layer above it, at {}",
                    at.join(", ")
                ));
            }
        }
    }
    out
}

/// The layers the layout table of docs/architecture.md gives the crate in folder `folder`: its row
/// `` | `folder` | … | a → b, c → d | `` (the last cell: layers top first, modules of a layer
/// split by commas).
fn readme_layers(readme: &str, folder: &str) -> Option<Vec<Vec<String>>> {
    let row = readme
        .lines()
        .find(|l| l.starts_with(&format!("| `{folder}` |")))?;
    let cell = row.trim_end().trim_end_matches('|').rsplit('|').next()?;
    Some(
        cell.split('→')
            .map(|layer| {
                layer
                    .split(',')
                    .map(|m| m.trim().trim_matches('`').to_string())
                    .filter(|m| !m.is_empty())
                    .collect()
            })
            .collect(),
    )
}

/// The layout table of docs/architecture.md states every crate's layers as its root file does.
#[test]
fn the_readmes_layout_table_states_each_crates_layers() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).parent().unwrap();
    let readme = std::fs::read_to_string(root.join("docs/architecture.md")).unwrap();
    let mut wrong = Vec::new();
    for (name, file) in crates() {
        let Some(stated) = layers(&std::fs::read_to_string(&file).unwrap()) else {
            continue;
        };
        let folder = name
            .trim_end_matches("/src/lib.rs")
            .trim_end_matches("/src/main.rs");
        let sorted = |l: &[Vec<String>]| -> Vec<Vec<String>> {
            l.iter()
                .map(|x| {
                    let mut x = x.clone();
                    x.sort();
                    x
                })
                .collect()
        };
        match readme_layers(&readme, folder) {
            Some(table) if sorted(&table) == sorted(&stated) => {}
            Some(table) => wrong.push(format!(
                "{folder}: docs/architecture.md {table:?}, {name} {stated:?}"
            )),
            None => wrong.push(format!(
                "{folder}: no row in the layout table of docs/architecture.md"
            )),
        }
    }
    assert!(wrong.is_empty(), "{}", wrong.join("\n"));
}

#[test]
fn no_crate_has_a_module_cycle_or_an_arrow_against_its_layers() {
    let mut all = Vec::new();
    for (name, root) in crates() {
        all.extend(problems(&name, &root));
    }
    assert!(all.is_empty(), "{}", all.join("\n"));
}

/// The checker itself: a cycle closed by an inline path, a grouped `use`, `super::` from a
/// child file, and an arrow up the layers are each found; comments and strings are not code.
#[test]
fn the_checker_finds_inline_paths_groups_and_arrows_up_the_layers() {
    let t = tempfile::tempdir().unwrap();
    let d = t.path();
    std::fs::create_dir_all(d.join("b")).unwrap();
    std::fs::write(
        d.join("lib.rs"),
        "//! # Layers\n//! ```text\n//! a\n//! b c\n//! ```\nmod a;\nmod b;\nmod c;\n",
    )
    .unwrap();
    std::fs::write(d.join("a.rs"), "use crate::{b::{x, y}, c};\n").unwrap();
    std::fs::write(d.join("b.rs"), "mod inner;\nfn f() { let _ = '{'; }\n").unwrap();
    std::fs::write(d.join("b/inner.rs"), "fn g() { super::super::c::h(); }\n").unwrap();
    std::fs::write(
        d.join("c.rs"),
        "fn h() { crate::a::k(); } // crate::b::x\nconst S: &str = \"crate::b\";\n",
    )
    .unwrap();
    let found = problems("t", &d.join("lib.rs"));
    let text = found.join("\n");
    assert!(
        found
            .iter()
            .any(|p| p.contains("`c` uses `a`, a layer above it")),
        "{text}"
    );
    // a → b (a group), b → c (from b's child file, by super::super), c → a (inline)
    assert!(
        found
            .iter()
            .any(|p| p.contains("a cycle between the modules [\"a\", \"b\", \"c\"]")),
        "{text}"
    );
    // a comment and a string are no arrows
    assert!(!text.contains("c → b"), "{text}");
    // without the arrow up, nothing
    std::fs::write(d.join("c.rs"), "fn h() {}\n").unwrap();
    assert!(problems("t", &d.join("lib.rs")).is_empty());
    std::fs::write(d.join("c.rs"), "fn h() { crate::d::x(); }\n").unwrap();
    std::fs::write(
        d.join("lib.rs"),
        "//! # Layers\n//! ```text\n//! a\n//! b\n//! ```\nmod a;\nmod b;\nmod c;\n",
    )
    .unwrap();
    let found = problems("t", &d.join("lib.rs"));
    assert!(
        found.iter().any(|p| p.contains("leave out the module `c`")),
        "{found:?}"
    );
}

/// The crates' layers as docs/architecture.md draws them (the `text` block under its heading
/// "The crates' layers"), top first: each line's `scanner-…` names.
fn crate_layers(doc: &str) -> Vec<Vec<String>> {
    let mut lines = doc.lines();
    lines
        .find(|l| l.starts_with('#') && l.contains("The crates' layers"))
        .expect("docs/architecture.md has a heading \"The crates' layers\"");
    lines
        .find(|l| l.trim() == "```text")
        .expect("a text block under it");
    lines
        .take_while(|l| l.trim() != "```")
        .map(|l| {
            l.split(|c: char| !(c.is_ascii_alphanumeric() || c == '-'))
                .filter(|w| w.starts_with("scanner-"))
                .map(String::from)
                .collect::<Vec<_>>()
        })
        .filter(|l| !l.is_empty())
        .collect()
}

/// A crate's name and the workspace crates its manifest depends on outside its tests (the
/// `[dependencies]` tables, a target's too).
fn manifest_deps(manifest: &str) -> (String, Vec<String>) {
    let mut name = String::new();
    let mut deps = Vec::new();
    let mut section = String::new();
    for line in manifest.lines().map(str::trim) {
        if line.starts_with('[') {
            section = line.to_string();
            continue;
        }
        if section == "[package]" && line.starts_with("name") {
            name = line.split('"').nth(1).unwrap_or_default().to_string();
        }
        let normal = section == "[dependencies]"
            || (section.starts_with("[target.") && section.ends_with(".dependencies]"));
        if normal && line.starts_with("scanner-") {
            deps.push(line.split(['.', ' ', '=']).next().unwrap().to_string());
        }
    }
    (name, deps)
}

/// Every crate of the workspace is drawn once in docs/architecture.md's crate layers, and every
/// crate depends only on crates of lower lines: the wire at the bottom imports nothing of the
/// scanner, the core nothing of the head or the host.
#[test]
fn the_crates_depend_only_on_crates_below_them() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).parent().unwrap();
    let doc = std::fs::read_to_string(root.join("docs/architecture.md")).unwrap();
    let layers = crate_layers(&doc);
    let line_of = |c: &str| layers.iter().position(|l| l.iter().any(|x| x == c));
    let manifest = std::fs::read_to_string(root.join("Cargo.toml")).unwrap();
    let members: Vec<&str> = manifest
        .split("members = [")
        .nth(1)
        .and_then(|s| s.split(']').next())
        .unwrap()
        .split(',')
        .map(|m| m.trim().trim_matches('"'))
        .filter(|m| !m.is_empty())
        .collect();
    let mut wrong = Vec::new();
    let mut drawn = 0;
    for m in &members {
        let (name, deps) =
            manifest_deps(&std::fs::read_to_string(root.join(m).join("Cargo.toml")).unwrap());
        let Some(line) = line_of(&name) else {
            wrong.push(format!("{name} ({m}) is not drawn in the crate layers"));
            continue;
        };
        drawn += 1;
        for d in deps {
            match line_of(&d) {
                Some(l) if l > line => {}
                _ => wrong.push(format!("{name} depends on {d}, not on a lower line")),
            }
        }
    }
    assert_eq!(
        drawn,
        layers.iter().map(Vec::len).sum::<usize>(),
        "a crate drawn twice, or one drawn that is no member: {layers:?}"
    );
    assert!(wrong.is_empty(), "{}", wrong.join("\n"));
    // The wire is the floor: no scanner crate in its manifest, none named in its sources.
    let wire = root.join("scanner-core/wire");
    let (name, deps) = manifest_deps(&std::fs::read_to_string(wire.join("Cargo.toml")).unwrap());
    assert_eq!((name.as_str(), deps.len()), ("scanner-wire", 0), "{deps:?}");
    for m in modules(&wire.join("src/lib.rs")) {
        assert!(
            !m.code.contains("scanner_"),
            "{}: the wire names a scanner crate",
            m.file.display()
        );
    }
}

#[test]
fn the_crate_layer_check_reads_manifests_and_the_drawing() {
    let (name, deps) = manifest_deps(
        "[package]\nname = \"a\"\n[dependencies]\nscanner-core.workspace = true\nserde = \"1\"\n\
         [dev-dependencies]\nscanner-alloc.workspace = true\n\
         [target.'cfg(unix)'.dependencies]\nscanner-io = { path = \"x\" }\n",
    );
    assert_eq!(name, "a");
    assert_eq!(deps, ["scanner-core", "scanner-io"]);
    let layers = crate_layers(
        "## The crates' layers\n```text\nscanner-host   scanner-device\n  │\nscanner-wire\n```\n",
    );
    assert_eq!(
        layers,
        [vec!["scanner-host", "scanner-device"], vec!["scanner-wire"]]
    );
}
