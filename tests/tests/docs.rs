//! The documents as a maker meets them: the README stays a front door, every measured figure is
//! stated once (the pages link it to `docs/figures.md`, where its command and machine are, and
//! each link must show the value given there), every link between the pages leads somewhere,
//! and `docs/troubleshooting.md` covers every refusal the head and the calibration can print.
//! `scripts/check-docs` runs these with `maker_docs`, which runs the documents' commands.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// The README and every page of docs/, as (path from the repository's root, text).
fn documents() -> Vec<(String, String)> {
    let mut out = vec![(
        "README.md".to_string(),
        std::fs::read_to_string(repo().join("README.md")).unwrap(),
    )];
    let mut pages: Vec<PathBuf> = std::fs::read_dir(repo().join("docs"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "md"))
        .collect();
    pages.sort();
    for p in pages {
        let name = format!("docs/{}", p.file_name().unwrap().to_string_lossy());
        out.push((name, std::fs::read_to_string(&p).unwrap()));
    }
    out
}

/// The registry's figures: id → value, from the rows `| <a id="ID"></a>… | VALUE | what | command
/// | machine |`; a row with an empty cell or an id given twice is a problem.
fn registry(text: &str, problems: &mut Vec<String>) -> BTreeMap<String, String> {
    let mut out = BTreeMap::new();
    for (n, line) in text.lines().enumerate() {
        let Some(rest) = line.strip_prefix("| <a id=\"") else {
            continue;
        };
        let Some((id, _)) = rest.split_once('"') else {
            problems.push(format!(
                "docs/figures.md:{}: an id without its quote",
                n + 1
            ));
            continue;
        };
        let cells: Vec<&str> = line
            .trim()
            .trim_matches('|')
            .split(" | ")
            .map(str::trim)
            .collect();
        if cells.len() != 5 || cells.iter().any(|c| c.is_empty()) {
            problems.push(format!(
                "docs/figures.md:{}: figure {id} needs five cells (figure, value, what, command, machine)",
                n + 1
            ));
            continue;
        }
        if !cells[3].contains('`') {
            problems.push(format!(
                "docs/figures.md:{}: figure {id} names no command",
                n + 1
            ));
        }
        if out.insert(id.to_string(), cells[1].to_string()).is_some() {
            problems.push(format!(
                "docs/figures.md:{}: figure {id} is given twice",
                n + 1
            ));
        }
    }
    out
}

/// Every markdown link in `text`: (line number, shown text, target).
fn links(text: &str) -> Vec<(usize, String, String)> {
    let mut out = Vec::new();
    let mut fenced = false;
    for (n, line) in text.lines().enumerate() {
        if line.trim_start().starts_with("```") {
            fenced = !fenced;
            continue;
        }
        if fenced {
            continue;
        }
        let mut rest = line;
        while let Some(i) = rest.find("](") {
            let Some(open) = rest[..i].rfind('[') else {
                rest = &rest[i + 2..];
                continue;
            };
            let shown = &rest[open + 1..i];
            let after = &rest[i + 2..];
            let Some(close) = after.find(')') else { break };
            out.push((n + 1, shown.to_string(), after[..close].to_string()));
            rest = &after[close + 1..];
        }
    }
    out
}

/// What the figure checker finds wrong.
#[derive(Debug, Clone, PartialEq, Eq)]
enum FigureProblem {
    /// A row of the registry that is not one (its line and why).
    Row(String),
    /// A link to a figure the registry does not hold.
    Unknown {
        page: String,
        line: usize,
        id: String,
    },
    /// A link that shows another value than the registry's.
    Differs {
        page: String,
        line: usize,
        id: String,
        shown: String,
    },
    /// A registered figure's value written out without its link.
    Unlinked {
        page: String,
        line: usize,
        id: String,
    },
    /// A registered figure no page states.
    Unused(String),
}

/// Whether `value` stands in `line` at byte `at` as a figure of its own (not the end of a longer
/// number or range, not the start of one).
fn stands_alone(line: &str, at: usize, value: &str) -> bool {
    let before = line[..at].chars().next_back();
    let after = line[at + value.len()..].chars().next();
    !before.is_some_and(|c| c.is_ascii_digit() || ".,–−+-".contains(c))
        && !after.is_some_and(|c| c.is_ascii_digit())
}

/// What the checker finds wrong with the figures of `docs` against the registry's text: links to
/// unknown figures or with other values, and a registered value written out anywhere — in a
/// sentence or deep in a page's table — without its link.
fn figure_problems(docs: &[(String, String)], figures: &str) -> Vec<FigureProblem> {
    let mut rows = Vec::new();
    let known = registry(figures, &mut rows);
    let mut problems: Vec<FigureProblem> = rows.into_iter().map(FigureProblem::Row).collect();
    let mut used = BTreeSet::new();
    for (name, text) in docs {
        if name.ends_with("figures.md") {
            continue;
        }
        let mut linked_at: BTreeSet<(usize, String)> = BTreeSet::new();
        for (line, shown, target) in links(text) {
            let Some((file, id)) = target.split_once('#') else {
                continue;
            };
            if !file.ends_with("figures.md") {
                continue;
            }
            used.insert(id.to_string());
            linked_at.insert((line, shown.clone()));
            match known.get(id) {
                None => problems.push(FigureProblem::Unknown {
                    page: name.clone(),
                    line,
                    id: id.to_string(),
                }),
                Some(value) if value != &shown => problems.push(FigureProblem::Differs {
                    page: name.clone(),
                    line,
                    id: id.to_string(),
                    shown,
                }),
                Some(_) => {}
            }
        }
        let mut fenced = false;
        for (n, line) in text.lines().enumerate() {
            if line.trim_start().starts_with("```") {
                fenced = !fenced;
            }
            if fenced {
                continue;
            }
            for (id, value) in &known {
                // A bare count ("50") is too common a number to tell; a value with its unit is.
                let has_unit = value
                    .chars()
                    .any(|c| !(c.is_ascii_digit() || c == '.' || c == ' '));
                if !value.chars().any(|c| c.is_ascii_digit()) || !has_unit {
                    continue;
                }
                let unlinked = line.match_indices(value.as_str()).any(|(at, _)| {
                    let in_link = line[..at].ends_with('[')
                        && line[at + value.len()..].starts_with("](")
                        && linked_at.contains(&(n + 1, value.clone()));
                    stands_alone(line, at, value) && !in_link
                });
                if unlinked {
                    problems.push(FigureProblem::Unlinked {
                        page: name.clone(),
                        line: n + 1,
                        id: id.clone(),
                    });
                }
            }
        }
    }
    for id in known.keys().filter(|id| !used.contains(*id)) {
        problems.push(FigureProblem::Unused(id.clone()));
    }
    problems
}

#[test]
fn every_figure_is_stated_with_the_value_its_command_gave() {
    let docs = documents();
    let figures = &docs
        .iter()
        .find(|(n, _)| n == "docs/figures.md")
        .expect("docs/figures.md")
        .1;
    let problems = figure_problems(&docs, figures);
    assert!(problems.is_empty(), "{problems:#?}");
    let mut none = Vec::new();
    assert!(
        registry(figures, &mut none).len() >= 10,
        "the registry holds the headline figures"
    );
}

/// The checker itself: a figure stated with another value, an unknown id, a figure stated
/// nowhere, a row without its command and a value written out without its link (in a table
/// too) are each found; a longer number that ends in a figure's digits is not that figure.
#[test]
fn the_figure_checker_finds_a_figure_stated_twice_differently() {
    let figures = "| figure | value | what | command | machine |\n|---|---|---|---|---|\n\
        | <a id=\"a\"></a>`a` | 5.07 s | the merge | `cargo bench` | dev |\n\
        | <a id=\"b\"></a>`b` | 2 | unused | `x` | any |\n\
        | <a id=\"c\"></a>`c` | 3 | no command | typed | any |\n";
    let docs = vec![
        (
            "README.md".to_string(),
            "merges in [5.07 s](docs/figures.md#a) and [3](docs/figures.md#c); 15.07 s, 1/3"
                .to_string(),
        ),
        (
            "docs/360.md".to_string(),
            "the bench: [11.3 s](figures.md#a); [1](figures.md#zz)\n| merge | 5.07 s |".to_string(),
        ),
    ];
    let problems = figure_problems(&docs, figures);
    let page = |p: &str| p.to_string();
    for want in [
        FigureProblem::Differs {
            page: page("docs/360.md"),
            line: 1,
            id: "a".into(),
            shown: "11.3 s".into(),
        },
        FigureProblem::Unknown {
            page: page("docs/360.md"),
            line: 1,
            id: "zz".into(),
        },
        FigureProblem::Unlinked {
            page: page("docs/360.md"),
            line: 2,
            id: "a".into(),
        },
        FigureProblem::Unused("b".into()),
    ] {
        assert!(problems.contains(&want), "{want:?} not in {problems:?}");
    }
    assert!(
        problems
            .iter()
            .any(|p| matches!(p, FigureProblem::Row(r) if r.contains("figure c names no command"))),
        "{problems:?}"
    );
    assert!(
        !problems.iter().any(|p| matches!(p,
            FigureProblem::Unknown { page, .. }
            | FigureProblem::Differs { page, .. }
            | FigureProblem::Unlinked { page, .. } if page == "README.md")),
        "{problems:?}"
    );
}

#[test]
fn the_readme_is_a_front_door() {
    let readme = std::fs::read_to_string(repo().join("README.md")).unwrap();
    let lines = readme.lines().count();
    assert!(lines <= 250, "README.md has {lines} lines, at most 250");
    // The two commands come before anything else is explained.
    let scan = readme.find("./scripts/scan-rig").expect("the scan command");
    let test = readme.find("./scripts/test").expect("the test command");
    let first_section = readme.find("\n## ").unwrap();
    let second_section = first_section + 4 + readme[first_section + 4..].find("\n## ").unwrap();
    assert!(
        scan < second_section && test < second_section,
        "the two commands first"
    );
}

/// GitHub's anchor of a heading: lower case, punctuation dropped, spaces to hyphens.
fn slug(heading: &str) -> String {
    heading
        .trim()
        .to_lowercase()
        .chars()
        .filter(|c| c.is_alphanumeric() || *c == ' ' || *c == '-' || *c == '_')
        .map(|c| if c == ' ' { '-' } else { c })
        .collect()
}

/// The anchors a page offers: its headings' slugs and its `<a id>`s.
fn anchors(text: &str) -> BTreeSet<String> {
    let mut out = BTreeSet::new();
    let mut fenced = false;
    for line in text.lines() {
        if line.trim_start().starts_with("```") {
            fenced = !fenced;
        }
        if !fenced && line.starts_with('#') {
            out.insert(slug(line.trim_start_matches('#')));
        }
        let mut rest = line;
        while let Some(i) = rest.find("<a id=\"") {
            let after = &rest[i + 7..];
            let Some(end) = after.find('"') else { break };
            out.insert(after[..end].to_string());
            rest = &after[end..];
        }
    }
    out
}

#[test]
fn every_link_between_the_documents_leads_somewhere() {
    let mut broken = Vec::new();
    for (name, text) in documents() {
        let dir = repo().join(&name).parent().unwrap().to_path_buf();
        for (line, _, target) in links(&text) {
            if target.contains("://") || target.starts_with("mailto:") {
                continue;
            }
            let (file, anchor) = match target.split_once('#') {
                Some((f, a)) => (f, Some(a)),
                None => (target.as_str(), None),
            };
            let path = if file.is_empty() {
                repo().join(&name)
            } else {
                dir.join(file)
            };
            if !path.exists() {
                broken.push(format!("{name}:{line}: {target}: no such file"));
                continue;
            }
            if let Some(anchor) = anchor
                && path.extension().is_some_and(|x| x == "md")
                && !anchors(&std::fs::read_to_string(&path).unwrap()).contains(anchor)
            {
                broken.push(format!("{name}:{line}: {target}: no such heading"));
            }
        }
    }
    assert!(broken.is_empty(), "{}", broken.join("\n"));
}

/// The variants of `enum name` in the source file `path` (the lines that start a variant, four
/// spaces in).
fn variants(path: &str, name: &str) -> Vec<String> {
    let text = std::fs::read_to_string(repo().join(path)).unwrap();
    let start = text
        .find(&format!("pub enum {name} {{"))
        .unwrap_or_else(|| panic!("no enum {name} in {path}"));
    let body = &text[start..];
    let body = &body[..body.find("\n}").unwrap()];
    body.lines()
        .skip(1)
        .filter_map(|l| {
            let l = l.strip_prefix("    ")?;
            let first = l.chars().next()?;
            if !first.is_ascii_uppercase() {
                return None;
            }
            let end = l
                .find(|c: char| !c.is_alphanumeric() && c != '_')
                .unwrap_or(l.len());
            Some(l[..end].to_string())
        })
        .collect()
}

/// Every error the head, the calibration and the merge can print, and every reason a frame is
/// skipped, has its entry: each entry names the variants it covers as `Enum::Variant`.
#[test]
fn troubleshooting_covers_every_refusal_of_the_head_and_the_calibration() {
    let page = std::fs::read_to_string(repo().join("docs/troubleshooting.md")).unwrap();
    let enums = [
        ("scanner-device/src/source/mod.rs", "SourceError"),
        ("scanner-device/src/source/convert.rs", "ConvertError"),
        ("scanner-device/src/session.rs", "SessionError"),
        ("scanner-device/src/temporal.rs", "TemporalError"),
        ("scanner-device/src/axis.rs", "AxisError"),
        ("scanner-device/src/motor.rs", "MotorError"),
        ("scanner-device/calib/src/import/mod.rs", "ImportError"),
        ("scanner-device/calib/src/fixed.rs", "FixedError"),
        ("scanner-host/src/lasers.rs", "LasersError"),
        ("scanner-device/calib/src/file.rs", "FixedUnusable"),
        ("scanner-device/src/calibrate.rs", "CalibrateError"),
        ("scanner-device/src/cli/scan/refusal.rs", "ScanRefusal"),
        ("scanner-device/src/cli/scan/refusal.rs", "ScanFailed"),
        ("scanner-device/calib/src/file.rs", "CovarianceError"),
        ("scanner-host/merge/src/error.rs", "MergeError"),
        ("scanner-host/merge/src/error.rs", "RegisterError"),
        ("scanner-host/merge/src/error.rs", "FuseError"),
        ("scanner-device/src/link.rs", "LinkError"),
        ("scanner-device/calib/src/file.rs", "FileError"),
        ("scanner-device/calib/src/disc.rs", "DiscMiss"),
        ("scanner-device/calib/src/board.rs", "BoardError"),
        ("scanner-core/io/src/image_file.rs", "ImageFileError"),
        ("scanner-device/calib/src/error.rs", "CalibError"),
        ("scanner-core/src/error.rs", "GeomError"),
        ("scanner-core/src/stripe/report.rs", "StripeError"),
        ("scanner-core/src/stripe/frame.rs", "FrameError"),
        ("scanner-device/jpeg/src/error.rs", "JpegError"),
        ("scanner-core/io/src/link_spec.rs", "SpecError"),
        ("scanner-core/wire/src/status.rs", "Skip"),
        ("scanner-core/wire/src/error.rs", "WireError"),
    ];
    let mut missing = Vec::new();
    let mut count = 0;
    for (path, name) in enums {
        let found = variants(path, name);
        assert!(!found.is_empty(), "{name} has no variants in {path}?");
        for v in found {
            count += 1;
            let named = format!("{name}::{v}");
            if !page.contains(&named) {
                missing.push(named);
            }
        }
    }
    assert!(
        missing.is_empty(),
        "docs/troubleshooting.md does not cover: {}",
        missing.join(", ")
    );
    assert!(count > 80, "{count} variants read: the reader lost some");
}
